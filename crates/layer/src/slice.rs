//! Slicing a part (a triangle mesh) into thick-wall layers: horizontal sections, and each
//! section's walls as a layer graph (`docs/layer-format.md`, "Slicing a mesh").
//!
//! A section is the mesh cut by the plane z = const: closed outline loops, oriented with the
//! material on the left, from the contour slicer's section (`waam_slice::section`: one
//! symbolic rule for planes through vertices, edges and faces, so a voxel-faceted mesh cut
//! through its vertices gives the same outline as cut between them). Its walls are found as pairs of antiparallel outline
//! edges that face each other across material no wider than 1.5 wall widths: the wall's
//! centre line is the middle line of the pair over the stretch where both sides overlap,
//! its width their distance. Pieces on one centre line are joined where the material
//! continues between them (across a crossing wall). Nodes are the crossings of centre
//! lines (within a wall width of the walls' ends, in the material) and dead ends (half a
//! wall width in from an end face, where the bead's square cap ends); segments join the
//! consecutive nodes along each centre line.
//!
//! Refused, with the height and the place: an open outline (the mesh has a hole there),
//! outline stretches that no wall explains (a blob wider than 1.5 wall widths), walls of
//! different widths (the format has one), and graphs the layer format refuses.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};
use thiserror::Error;
use waam_mesh::TriangleMesh;

use super::format::{Layer, Material, Node, Process, Source, Temperatures};

/// Why a mesh or one of its sections cannot be sliced into layers.
#[derive(Debug, Error, PartialEq)]
pub enum SliceError {
    #[error("layer height: expected a finite number > 0 mm, got {0}")]
    LayerHeight(f64),
    #[error("wall width: expected a finite number > 0 mm, got {0}")]
    WallWidth(f64),
    #[error("the mesh has no triangles")]
    Empty,
    #[error("the mesh is {height} mm tall: thinner than one layer of {layer_height} mm")]
    TooThin { height: f64, layer_height: f64 },
    #[error("section at z = {z:.3} mm: {message} near ({x:.3}, {y:.3})")]
    Section {
        z: f64,
        x: f64,
        y: f64,
        message: String,
    },
    #[error("section at z = {z:.3} mm: {message}")]
    Layer { z: f64, message: String },
}

/// Process, material, temperature and torch parameters of the sliced layers (the layer
/// format's keys apart from the graph). The default is the bundled `paper-16mm` layer's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayerParams {
    pub process: Process,
    pub material: Material,
    pub temperatures: Temperatures,
    pub source: Source,
}

impl Default for LayerParams {
    fn default() -> Self {
        LayerParams {
            process: Process {
                weld_speed_mm_s: 10.0,
                time_step_s: 0.1,
                transit_speed_mm_s: 50.0,
                mesh_refinement: 0,
            },
            material: Material {
                diffusivity_mm2_s: 5.0,
                robin_mm_s: 0.5,
            },
            temperatures: Temperatures {
                ambient_c: 20.0,
                initial_c: 20.0,
                target_c: 400.0,
            },
            source: Source {
                peak_k_s: 8000.0,
                radii_mm: vec![1.0, 2.0],
                weights: vec![1.0, 0.4],
            },
        }
    }
}

impl LayerParams {
    /// The parameters of an existing layer (a template).
    pub fn of(layer: &Layer) -> LayerParams {
        LayerParams {
            process: layer.process.clone(),
            material: layer.material.clone(),
            temperatures: layer.temperatures.clone(),
            source: layer.source.clone(),
        }
    }
}

/// How to slice.
#[derive(Debug, Clone)]
pub struct SliceOptions {
    /// Layer name prefix: layer k is called `{name}-{k:03}`.
    pub name: String,
    /// Layer height (mm); layer k is cut at z_min + (k + ½)·height.
    pub layer_height_mm: f64,
    /// The expected wall width (mm); `None`: measured (the length-weighted median).
    pub wall_width_mm: Option<f64>,
    pub params: LayerParams,
}

/// One sliced layer: its height and its layer graph.
#[derive(Debug, Clone)]
pub struct SlicedLayer {
    /// Height of the cutting plane (mm).
    pub z_mm: f64,
    pub layer: Layer,
}

/// Slices a mesh into layers (bottom first). Every section must be a wall structure.
pub fn slice_mesh(
    mesh: &TriangleMesh,
    options: &SliceOptions,
) -> Result<Vec<SlicedLayer>, SliceError> {
    let h = options.layer_height_mm;
    if !(h.is_finite() && h > 0.0) {
        return Err(SliceError::LayerHeight(h));
    }
    if let Some(w) = options.wall_width_mm {
        if !(w.is_finite() && w > 0.0) {
            return Err(SliceError::WallWidth(w));
        }
    }
    if mesh.triangles.is_empty() {
        return Err(SliceError::Empty);
    }
    let (lo, hi) = mesh.bounds();
    let count = ((hi[2] - lo[2]) / h + 1e-9).floor() as usize;
    if count == 0 {
        return Err(SliceError::TooThin {
            height: hi[2] - lo[2],
            layer_height: h,
        });
    }
    let mut out = Vec::with_capacity(count);
    for k in 0..count {
        let z = lo[2] + (k as f64 + 0.5) * h;
        let loops = section(mesh, z)?;
        let name = format!("{}-{k:03}", options.name);
        let layer = walls(&loops, z, &name, options.wall_width_mm, &options.params)?;
        tracing::debug!(
            "z = {z:.3} mm: {} nodes, {} segments",
            layer.nodes.len(),
            layer.segments.len()
        );
        out.push(SlicedLayer { z_mm: z, layer });
    }
    Ok(out)
}

/// The closed outline loops of the section at height z, material on the left: the contour
/// slicer's section ([`waam_slice::section::section_loops`], one for both slicers), its
/// collinear points dropped. Open outlines are not joined: the mesh has a hole there.
pub fn section(mesh: &TriangleMesh, z: f64) -> Result<Vec<Vec<[f64; 2]>>, SliceError> {
    let loops = waam_slice::section::section_loops(mesh, z, 0.0).map_err(|e| match e {
        waam_slice::SliceError::Open { at, gap_mm, .. } => SliceError::Section {
            z,
            x: at[0],
            y: at[1],
            message: format!(
                "open contour: the mesh has a hole there (the nearest loose end is {gap_mm:.3} mm away)"
            ),
        },
        other => SliceError::Layer {
            z,
            message: other.to_string(),
        },
    })?;
    let loops: Vec<Vec<[f64; 2]>> = loops
        .iter()
        .map(|ring| simplify(ring))
        .filter(|ring| ring.len() >= 3)
        .collect();
    if loops.is_empty() {
        return Err(SliceError::Layer {
            z,
            message: "the plane does not cut the mesh (no material at this height)".into(),
        });
    }
    Ok(loops)
}

/// Drops repeated outline points (within 1 µm), then those that lie on the line of their
/// neighbours (within 1 µm).
fn simplify(ring: &[[f64; 2]]) -> Vec<[f64; 2]> {
    // A plane through a mesh vertex crosses all its edges there: the point repeats.
    let mut pts: Vec<[f64; 2]> = Vec::with_capacity(ring.len());
    for &p in ring {
        if pts.last().is_none_or(|&q| dist(p, q) >= 1e-6) {
            pts.push(p);
        }
    }
    while pts.len() > 1 && dist(pts[0], pts[pts.len() - 1]) < 1e-6 {
        pts.pop();
    }
    let mut changed = true;
    while changed && pts.len() > 3 {
        changed = false;
        let mut out: Vec<[f64; 2]> = Vec::with_capacity(pts.len());
        let n = pts.len();
        for i in 0..n {
            let prev = out.last().copied().unwrap_or(pts[(i + n - 1) % n]);
            let (p, q) = (pts[i], pts[(i + 1) % n]);
            let len = dist(prev, q);
            let off = if len > 0.0 {
                ((q[0] - prev[0]) * (p[1] - prev[1]) - (q[1] - prev[1]) * (p[0] - prev[0])).abs()
                    / len
            } else {
                0.0
            };
            let between =
                (p[0] - prev[0]) * (q[0] - p[0]) + (p[1] - prev[1]) * (q[1] - p[1]) >= 0.0;
            if (off < 1e-3 && between) || dist(p, prev) < 1e-6 {
                changed = true;
            } else {
                out.push(p);
            }
        }
        pts = out;
    }
    pts
}

/// An outline edge: from a to b, material on the left.
#[derive(Debug, Clone, Copy)]
struct Edge {
    a: [f64; 2],
    b: [f64; 2],
}

impl Edge {
    fn len(&self) -> f64 {
        dist(self.a, self.b)
    }
    fn dir(&self) -> [f64; 2] {
        let l = self.len();
        [(self.b[0] - self.a[0]) / l, (self.b[1] - self.a[1]) / l]
    }
}

/// A piece of wall: centre line through `origin` along unit `dir` (angle in [0, π)),
/// over [s0, s1] along dir, `width` wide.
#[derive(Debug, Clone, Copy)]
struct Piece {
    angle: f64,
    offset: f64,
    s0: f64,
    s1: f64,
    width: f64,
}

impl Piece {
    fn dir(&self) -> [f64; 2] {
        [self.angle.cos(), self.angle.sin()]
    }
    /// The point at parameter s on the centre line.
    fn at(&self, s: f64) -> [f64; 2] {
        let d = self.dir();
        let n = [-d[1], d[0]];
        [s * d[0] + self.offset * n[0], s * d[1] + self.offset * n[1]]
    }
}

/// The layer graph of a section's outline loops.
pub fn walls(
    loops: &[Vec<[f64; 2]>],
    z: f64,
    name: &str,
    wall_width: Option<f64>,
    params: &LayerParams,
) -> Result<Layer, SliceError> {
    let edges: Vec<Edge> = loops
        .iter()
        .flat_map(|r| {
            (0..r.len()).map(move |i| Edge {
                a: r[i],
                b: r[(i + 1) % r.len()],
            })
        })
        .filter(|e| e.len() > 1e-9)
        .collect();
    let inside = |p: [f64; 2]| winding(loops, p) != 0;
    // Facing pairs: antiparallel, material between them, overlapping along their line.
    struct Pair {
        e: usize,
        dist: f64,
        lo: f64,
        hi: f64,
    }
    let mut facing: Vec<Pair> = Vec::new();
    for (i, e) in edges.iter().enumerate() {
        let d = e.dir();
        let n = [-d[1], d[0]]; // into the material
        let s_of = |p: [f64; 2]| p[0] * d[0] + p[1] * d[1];
        for (j, f) in edges.iter().enumerate() {
            if i == j {
                continue;
            }
            let g = f.dir();
            if d[0] * g[0] + d[1] * g[1] > -0.9995 {
                continue;
            }
            let off = |p: [f64; 2]| (p[0] - e.a[0]) * n[0] + (p[1] - e.a[1]) * n[1];
            let (oa, ob) = (off(f.a), off(f.b));
            if (oa - ob).abs() > 1e-3 * (1.0 + oa.abs()) || oa <= 1e-6 {
                continue;
            }
            let (ea, eb) = (s_of(e.a), s_of(e.b));
            let (fa, fb) = (s_of(f.a), s_of(f.b));
            let lo = ea.min(eb).max(fa.min(fb));
            let hi = ea.max(eb).min(fa.max(fb));
            if hi - lo > 1e-6 {
                facing.push(Pair {
                    e: i,
                    dist: 0.5 * (oa + ob),
                    lo,
                    hi,
                });
            }
        }
    }
    // Every edge pairs with its nearest facing edge(s) only: a farther one lies across
    // another wall (material, a hole, material).
    let mut nearest = vec![f64::INFINITY; edges.len()];
    for p in &facing {
        nearest[p.e] = nearest[p.e].min(p.dist);
    }
    let w = match wall_width {
        Some(w) => w,
        None => {
            let mut v: Vec<(f64, f64)> = (0..edges.len())
                .filter(|&i| nearest[i].is_finite())
                .map(|i| (nearest[i], edges[i].len()))
                .collect();
            v.sort_by(|a, b| a.0.total_cmp(&b.0));
            let total: f64 = v.iter().map(|x| x.1).sum();
            let mut acc = 0.0;
            let mut median = f64::NAN;
            for (d, l) in v {
                acc += l;
                if acc >= 0.5 * total {
                    median = d;
                    break;
                }
            }
            if !median.is_finite() {
                let p = loops[0][0];
                return Err(SliceError::Section {
                    z,
                    x: p[0],
                    y: p[1],
                    message: "no two sides of the outline face each other: not a wall".into(),
                });
            }
            median
        }
    };
    let max_width = 1.5 * w;
    let mut pieces: Vec<Piece> = Vec::new();
    let mut covered: Vec<Vec<(f64, f64)>> = vec![Vec::new(); edges.len()];
    for p in &facing {
        if p.dist > max_width || p.dist > nearest[p.e] * (1.0 + 1e-6) + 1e-6 {
            continue;
        }
        let e = &edges[p.e];
        let d = e.dir();
        let s_a = e.a[0] * d[0] + e.a[1] * d[1];
        covered[p.e].push((p.lo - s_a, p.hi - s_a));
        let n = [-d[1], d[0]];
        let mid = [e.a[0] + 0.5 * p.dist * n[0], e.a[1] + 0.5 * p.dist * n[1]];
        // Canonical direction: angle in [0, π).
        let (mut angle, mut flip) = (d[1].atan2(d[0]), false);
        if angle < 0.0 {
            angle += std::f64::consts::PI;
            flip = true;
        }
        if angle >= std::f64::consts::PI - 1e-9 {
            angle -= std::f64::consts::PI;
            flip = !flip;
        }
        let cd = [angle.cos(), angle.sin()];
        let cn = [-cd[1], cd[0]];
        let (lo, hi) = if flip { (-p.hi, -p.lo) } else { (p.lo, p.hi) };
        pieces.push(Piece {
            angle,
            offset: mid[0] * cn[0] + mid[1] * cn[1],
            s0: lo,
            s1: hi,
            width: p.dist,
        });
    }
    // Outline stretches no wall explains: a region wider than a wall.
    for (i, e) in edges.iter().enumerate() {
        let mut iv = covered[i].clone();
        iv.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut at = 0.0;
        let mut gaps = Vec::new();
        for (lo, hi) in iv {
            if lo > at {
                gaps.push((at, lo));
            }
            at = f64::max(at, hi);
        }
        gaps.push((at, e.len()));
        for (lo, hi) in gaps {
            if hi - lo > 2.0 * w + 1e-6 {
                let d = e.dir();
                let m = 0.5 * (lo + hi);
                let (x, y) = (e.a[0] + m * d[0], e.a[1] + m * d[1]);
                let across = if nearest[i].is_finite() {
                    format!("{:.3} mm across", nearest[i])
                } else {
                    "open on one side".to_string()
                };
                return Err(SliceError::Section {
                    z,
                    x,
                    y,
                    message: format!(
                        "not a wall structure: {:.3} mm of outline bound a region {across}, \
                         wider than 1.5 wall widths ({:.3} mm)",
                        hi - lo,
                        max_width
                    ),
                });
            }
        }
    }
    // Join pieces on one centre line where the material continues between them.
    pieces.sort_by(|a, b| {
        a.angle
            .total_cmp(&b.angle)
            .then(a.offset.total_cmp(&b.offset))
            .then(a.s0.total_cmp(&b.s0))
    });
    let same_line = |a: &Piece, b: &Piece| {
        (a.angle - b.angle).abs() < 1e-3 && (a.offset - b.offset).abs() < 0.02 * w
    };
    let mut groups: Vec<Vec<Piece>> = Vec::new();
    for p in pieces {
        match groups.iter_mut().find(|g| same_line(&g[0], &p)) {
            Some(g) => g.push(p),
            None => groups.push(vec![p]),
        }
    }
    let mut wallsv: Vec<Piece> = Vec::new();
    for mut g in groups {
        g.sort_by(|a, b| a.s0.total_cmp(&b.s0));
        let mut cur = g[0];
        let mut wsum = (cur.width * (cur.s1 - cur.s0), cur.s1 - cur.s0);
        for p in g.into_iter().skip(1) {
            let gap_mid = cur.at(0.5 * (cur.s1 + p.s0));
            if p.s0 <= cur.s1 + 1e-6 || (p.s0 - cur.s1 <= max_width && inside(gap_mid)) {
                cur.s1 = cur.s1.max(p.s1);
                wsum.0 += p.width * (p.s1 - p.s0);
                wsum.1 += p.s1 - p.s0;
            } else {
                cur.width = wsum.0 / wsum.1;
                wallsv.push(cur);
                cur = p;
                wsum = (cur.width * (cur.s1 - cur.s0), cur.s1 - cur.s0);
            }
        }
        cur.width = wsum.0 / wsum.1;
        wallsv.push(cur);
    }
    // One width for the layer: every wall within 10 % of the median.
    let mut widths: Vec<f64> = wallsv.iter().map(|p| p.width).collect();
    widths.sort_by(f64::total_cmp);
    let median = widths[widths.len() / 2];
    for p in &wallsv {
        if (p.width - median).abs() > 0.1 * median {
            let c = p.at(0.5 * (p.s0 + p.s1));
            return Err(SliceError::Section {
                z,
                x: c[0],
                y: c[1],
                message: format!(
                    "a wall {:.3} mm wide where the others are {median:.3} mm \
                     (a layer has one wall width)",
                    p.width
                ),
            });
        }
    }
    let width = wallsv.iter().map(|p| p.width * (p.s1 - p.s0)).sum::<f64>()
        / wallsv.iter().map(|p| p.s1 - p.s0).sum::<f64>();
    // Nodes: crossings of centre lines near both walls, in the material.
    let mut nodes: Vec<[f64; 2]> = Vec::new();
    let mut on: Vec<Vec<(f64, usize)>> = vec![Vec::new(); wallsv.len()];
    let node_at = |nodes: &mut Vec<[f64; 2]>, p: [f64; 2]| -> usize {
        if let Some(i) = nodes.iter().position(|&q| dist(p, q) < 0.25 * width) {
            i
        } else {
            nodes.push(p);
            nodes.len() - 1
        }
    };
    let reach = width;
    for i in 0..wallsv.len() {
        for j in i + 1..wallsv.len() {
            let (a, b) = (&wallsv[i], &wallsv[j]);
            let (da, db) = (a.dir(), b.dir());
            let det = da[0] * db[1] - da[1] * db[0];
            if det.abs() < 0.05 {
                continue;
            }
            // a.at(s) = b.at(t): solve s·da − t·db = b.at(0) − a.at(0).
            let (pa, pb) = (a.at(0.0), b.at(0.0));
            let r = [pb[0] - pa[0], pb[1] - pa[1]];
            let s = (r[0] * db[1] - r[1] * db[0]) / det;
            let t = (r[0] * da[1] - r[1] * da[0]) / det;
            if s < a.s0 - reach || s > a.s1 + reach || t < b.s0 - reach || t > b.s1 + reach {
                continue;
            }
            let p = a.at(s);
            if !inside(p) {
                continue;
            }
            let k = node_at(&mut nodes, p);
            on[i].push((s, k));
            on[j].push((t, k));
        }
    }
    // Dead ends: half a wall width in from an end face that no crossing explains.
    for (i, p) in wallsv.iter().enumerate() {
        let mut list = on[i].clone();
        list.sort_by(|a, b| a.0.total_cmp(&b.0));
        let first = list.first().map(|x| x.0);
        let last = list.last().map(|x| x.0);
        if first.is_none_or(|f| p.s0 < f - 0.25 * width) {
            let s = p.s0 + 0.5 * width;
            let k = node_at(&mut nodes, p.at(s));
            on[i].push((s, k));
        }
        if last.is_none_or(|l| p.s1 > l + 0.25 * width) {
            let s = p.s1 - 0.5 * width;
            let k = node_at(&mut nodes, p.at(s));
            on[i].push((s, k));
        }
    }
    // Node ids in reading order (rows from the bottom, left to right; 1 µm rounding).
    let mut order: Vec<usize> = (0..nodes.len()).collect();
    let r = |v: f64| (v * 1000.0).round() as i64;
    order.sort_by_key(|&i| (r(nodes[i][1]), r(nodes[i][0])));
    let mut rank = vec![0; nodes.len()];
    for (k, &i) in order.iter().enumerate() {
        rank[i] = k;
    }
    let mut segments: Vec<[usize; 2]> = Vec::new();
    for list in &mut on {
        list.sort_by(|a, b| a.0.total_cmp(&b.0));
        list.dedup_by_key(|x| x.1);
        for pair in list.windows(2) {
            let (a, b) = (rank[pair[0].1], rank[pair[1].1]);
            if a != b {
                segments.push([a.min(b), a.max(b)]);
            }
        }
    }
    segments.sort_unstable();
    segments.dedup();
    let node_list: Vec<Node> = order
        .iter()
        .enumerate()
        .map(|(k, &i)| Node {
            id: format!("N{}", k + 1),
            x: round6(nodes[i][0]),
            y: round6(nodes[i][1]),
        })
        .collect();
    let doc = LayerDoc {
        name: name.to_string(),
        wall_width_mm: round6(width),
        segments: segments
            .iter()
            .map(|&[a, b]| [node_list[a].id.clone(), node_list[b].id.clone()])
            .collect(),
        nodes: node_list,
        process: params.process.clone(),
        material: params.material.clone(),
        temperatures: params.temperatures.clone(),
        source: params.source.clone(),
    };
    let text = doc.to_yaml();
    Layer::parse(&text).map_err(|e| SliceError::Layer {
        z,
        message: format!("the walls do not make a layer: {e}"),
    })
}

/// A layer file as written (the format's keys, in order).
#[derive(Debug, Clone, Serialize)]
pub struct LayerDoc {
    pub name: String,
    pub wall_width_mm: f64,
    pub nodes: Vec<Node>,
    pub segments: Vec<[String; 2]>,
    pub process: Process,
    pub material: Material,
    pub temperatures: Temperatures,
    pub source: Source,
}

impl LayerDoc {
    /// The document of a layer.
    pub fn of(layer: &Layer) -> LayerDoc {
        LayerDoc {
            name: layer.name.clone(),
            wall_width_mm: layer.wall_width_mm,
            nodes: layer.nodes.clone(),
            segments: layer
                .segments
                .iter()
                .map(|&[a, b]| [layer.nodes[a].id.clone(), layer.nodes[b].id.clone()])
                .collect(),
            process: layer.process.clone(),
            material: layer.material.clone(),
            temperatures: layer.temperatures.clone(),
            source: layer.source.clone(),
        }
    }

    /// The YAML text (flow style for nodes and segments, as the bundled layers).
    pub fn to_yaml(&self) -> String {
        let mut s = format!(
            "name: {}\nwall_width_mm: {:?}\nnodes:\n",
            serde_yaml::to_string(&self.name).unwrap_or_default().trim(),
            self.wall_width_mm
        );
        for n in &self.nodes {
            s += &format!("  - {{id: {}, x: {:?}, y: {:?}}}\n", n.id, n.x, n.y);
        }
        s += "segments:\n";
        for [a, b] in &self.segments {
            s += &format!("  - [{a}, {b}]\n");
        }
        #[derive(Serialize)]
        struct Rest<'a> {
            process: &'a Process,
            material: &'a Material,
            temperatures: &'a Temperatures,
            source: &'a Source,
        }
        s += &serde_yaml::to_string(&Rest {
            process: &self.process,
            material: &self.material,
            temperatures: &self.temperatures,
            source: &self.source,
        })
        .unwrap_or_default();
        s
    }
}

fn round6(v: f64) -> f64 {
    let r = (v * 1e6).round() / 1e6;
    if r == 0.0 {
        0.0
    } else {
        r
    }
}

/// Winding number of the outline loops around p (non-zero: in the material).
fn winding(loops: &[Vec<[f64; 2]>], p: [f64; 2]) -> i32 {
    let mut wn = 0;
    for r in loops {
        for i in 0..r.len() {
            let (a, b) = (r[i], r[(i + 1) % r.len()]);
            let side = (b[0] - a[0]) * (p[1] - a[1]) - (p[0] - a[0]) * (b[1] - a[1]);
            if a[1] <= p[1] {
                if b[1] > p[1] && side > 0.0 {
                    wn += 1;
                }
            } else if b[1] <= p[1] && side < 0.0 {
                wn -= 1;
            }
        }
    }
    wn
}

fn dist(p: [f64; 2], q: [f64; 2]) -> f64 {
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt()
}

fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

trait Corners {
    fn corners_of(&self, tri: &[u32; 3]) -> [[f64; 3]; 3];
}

impl Corners for TriangleMesh {
    fn corners_of(&self, tri: &[u32; 3]) -> [[f64; 3]; 3] {
        tri.map(|v| self.vertices[v as usize])
    }
}

/// A prism mesh of a layer's walls, `height_mm` tall from z = 0: the layer's finite-element
/// mesh as bottom and top, its outline as the sides. For test parts and bundled STLs.
pub fn extrude(layer: &Layer, height_mm: f64) -> TriangleMesh {
    let mesh = super::mesh::Mesh::with_refinement(layer, 0);
    let n = mesh.points.len() as u32;
    let mut out = TriangleMesh::default();
    for z in [0.0, height_mm] {
        for p in &mesh.points {
            out.vertices.push([p[0], p[1], z]);
        }
    }
    let ccw = |t: &[usize; 3]| {
        let (a, b, c) = (mesh.points[t[0]], mesh.points[t[1]], mesh.points[t[2]]);
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) > 0.0
    };
    // Directed boundary edges with the material on the left, from the triangles.
    let mut directed: HashMap<(usize, usize), bool> = HashMap::new();
    for t in &mesh.triangles {
        let t = if ccw(t) { *t } else { [t[0], t[2], t[1]] };
        let [a, b, c] = t.map(|i| i as u32);
        out.triangles.push([a, c, b]); // bottom, facing down
        out.triangles.push([a + n, b + n, c + n]); // top
        for i in 0..3 {
            directed.insert((t[i], t[(i + 1) % 3]), true);
        }
    }
    for &[a, b] in &mesh.boundary {
        let (a, b) = if directed.contains_key(&(a, b)) {
            (a, b)
        } else {
            (b, a)
        };
        let (a, b) = (a as u32, b as u32);
        // The outward side is on the right of a -> b.
        out.triangles.push([a, b, b + n]);
        out.triangles.push([a, b + n, a + n]);
    }
    out
}

/// Writes a mesh as ASCII STL text.
pub fn stl_text(mesh: &TriangleMesh, name: &str) -> String {
    let mut s = format!("solid {name}\n");
    for t in &mesh.triangles {
        let c = mesh.corners_of(t);
        let nrm = cross3(sub3(c[1], c[0]), sub3(c[2], c[0]));
        let l = (nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2])
            .sqrt()
            .max(1e-300);
        s += &format!(
            "  facet normal {} {} {}\n    outer loop\n",
            nrm[0] / l,
            nrm[1] / l,
            nrm[2] / l
        );
        for v in c {
            s += &format!("      vertex {} {} {}\n", v[0], v[1], v[2]);
        }
        s += "    endloop\n  endfacet\n";
    }
    s += &format!("endsolid {name}\n");
    s
}
