//! Contour slicing: a triangle mesh cut into layers of weld beads, as a graph part.
//!
//! Round parts (tubes, nozzles, flanges) voxelize into staircases that no plan follows; a
//! cell welds them as beads along their contours. [`slice`] cuts a mesh at every layer's
//! mid-height ([`section`]), fills each section with beads ([`fill`](mod@fill): one centre
//! line for a thin wall, contour rings, a raster core), cuts the beads into deposits about a
//! bead width long and finds their contacts ([`graph`](mod@graph)), and measures how well the
//! beads cover each section ([`LayerReport`]). The result is a
//! [`BeadPart`](waam_part::BeadPart).
//!
//! Polygon work (union, offsetting, line clipping) is done by `clipper2-rust`, a pure-Rust
//! port of Clipper2 (see [`poly`]).

pub mod fill;
pub mod graph;
pub mod poly;
pub mod section;
pub mod shapes;

use std::time::{Duration, Instant};

use thiserror::Error;

use waam_mesh::TriangleMesh;
use waam_part::beads::{MAX_BEAD_MM, MAX_COORD_MM};
use waam_part::{Bead, BeadPart, ThermalParams};

pub use section::{section, Polygon};

/// The most layers a slice may have.
pub const MAX_LAYERS: usize = 100_000;
/// The most nodes a sliced part may have (a graph part of more is beyond any planner).
pub const MAX_NODES: usize = 2_000_000;

/// Why a mesh cannot be sliced. Triangles are numbered from 1.
#[derive(Debug, Error, PartialEq)]
pub enum SliceError {
    #[error("--bead: {0}")]
    Bead(String),
    #[error("the mesh has no triangles")]
    Empty,
    #[error("triangle {triangle}: vertex index {index} is out of range (the mesh has {vertices} vertices)")]
    BadIndex {
        triangle: usize,
        index: u32,
        vertices: usize,
    },
    #[error("triangle {triangle}: vertex {vertex:?} has a non-finite coordinate")]
    NonFinite { triangle: usize, vertex: [f64; 3] },
    #[error(
        "triangle {triangle}: vertex {vertex:?} is out of range (|coordinate| > {MAX_COORD_MM} mm)"
    )]
    OutOfRange { triangle: usize, vertex: [f64; 3] },
    #[error("section at z = {z_mm} mm: a contour stays open near ({:.3}, {:.3}): the nearest loose end is {gap_mm:.3} mm away (the mesh has a hole there)", at[0], at[1])]
    Open {
        z_mm: f64,
        at: [f64; 2],
        gap_mm: f64,
    },
    #[error(
        "the mesh is {height_mm} mm tall: {layers} layers of {h_mm} mm, more than {MAX_LAYERS}"
    )]
    TooManyLayers {
        height_mm: f64,
        h_mm: f64,
        layers: f64,
    },
    #[error("the part would have more than {MAX_NODES} nodes (at layer {layer}, z = {z_mm} mm): use wider beads")]
    TooManyNodes { layer: u32, z_mm: f64 },
    #[error("no layer of the mesh holds a bead ({layers} layers of {h_mm} mm): the part is thinner than 0.04 bead widths, or flat")]
    NoBeads { layers: usize, h_mm: f64 },
}

/// How to slice a mesh.
#[derive(Debug, Clone)]
pub struct SliceOptions {
    pub name: String,
    /// Bead width W and layer height H, mm.
    pub bead_mm: [f64; 2],
    /// k of the part.
    pub max_fragments: usize,
    /// Contour rounds before a core is rastered.
    pub perimeters: usize,
    /// Open contour ends at most this far apart (mm) are joined: CAD exports have gaps.
    pub join_mm: f64,
    pub thermal: ThermalParams,
}

impl SliceOptions {
    /// Defaults: k = 1, 3 perimeters, gaps up to 0.05 mm joined, default thermal model.
    pub fn new(name: impl Into<String>, bead_mm: [f64; 2]) -> SliceOptions {
        SliceOptions {
            name: name.into(),
            bead_mm,
            max_fragments: 1,
            perimeters: 3,
            join_mm: 0.05,
            thermal: ThermalParams::default(),
        }
    }
}

/// What one layer became, and how well its beads cover its section.
#[derive(Debug, Clone, PartialEq)]
pub struct LayerReport {
    pub layer: u32,
    pub z_mm: f64,
    pub section_mm2: f64,
    pub beads: usize,
    pub closed_beads: usize,
    pub nodes: usize,
    /// Fraction of the section covered by the beads widened to W.
    pub covered: f64,
    /// Fraction of the widened beads' area that lies outside the section.
    pub outside: f64,
}

/// A sliced mesh: the graph part and a report per layer.
#[derive(Debug, Clone)]
pub struct Sliced {
    pub part: BeadPart,
    pub layers: Vec<LayerReport>,
    pub elapsed: Duration,
}

impl Sliced {
    /// Layers whose section is not empty.
    fn solid(&self) -> impl Iterator<Item = &LayerReport> {
        self.layers.iter().filter(|l| l.section_mm2 > 0.0)
    }

    /// Mean over layers of the covered fraction.
    pub fn mean_covered(&self) -> f64 {
        let (sum, n) = self
            .solid()
            .fold((0.0, 0usize), |(s, n), l| (s + l.covered, n + 1));
        if n == 0 {
            0.0
        } else {
            sum / n as f64
        }
    }

    /// The least covered layer.
    pub fn worst_covered(&self) -> Option<&LayerReport> {
        self.solid().min_by(|a, b| a.covered.total_cmp(&b.covered))
    }

    /// The layer with the largest fraction of bead outside the section.
    pub fn worst_outside(&self) -> Option<&LayerReport> {
        self.solid().max_by(|a, b| a.outside.total_cmp(&b.outside))
    }

    /// Node count, contact count by kind (along, beside, stacked).
    pub fn counts(&self) -> (usize, [usize; 3]) {
        let mut k = [0; 3];
        for c in &self.part.contacts {
            k[c.kind as usize] += 1;
        }
        (self.part.nodes.len(), k)
    }
}

fn check_mesh(mesh: &TriangleMesh) -> Result<(), SliceError> {
    if mesh.triangles.is_empty() {
        return Err(SliceError::Empty);
    }
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for &i in tri {
            let Some(&v) = mesh.vertices.get(i as usize) else {
                return Err(SliceError::BadIndex {
                    triangle: t + 1,
                    index: i,
                    vertices: mesh.vertices.len(),
                });
            };
            if v.iter().any(|c| !c.is_finite()) {
                return Err(SliceError::NonFinite {
                    triangle: t + 1,
                    vertex: v,
                });
            }
            if v.iter().any(|c| c.abs() > MAX_COORD_MM) {
                return Err(SliceError::OutOfRange {
                    triangle: t + 1,
                    vertex: v,
                });
            }
        }
    }
    Ok(())
}

/// Slices a mesh (millimetres, z up, standing on its lowest point) into a graph part.
/// Layer i is cut at z = min z + (i + 0.5)·H.
pub fn slice(mesh: &TriangleMesh, opts: &SliceOptions) -> Result<Sliced, SliceError> {
    let start = Instant::now();
    let [w, h] = opts.bead_mm;
    for (name, x) in [("W", w), ("H", h)] {
        if !(x.is_finite() && x > 0.0 && x <= MAX_BEAD_MM) {
            return Err(SliceError::Bead(format!(
                "{name} must be a number > 0 and <= {MAX_BEAD_MM} mm, got {x}"
            )));
        }
    }
    if opts.max_fragments == 0 {
        return Err(SliceError::Bead("k must be at least 1".into()));
    }
    check_mesh(mesh)?;
    let used = mesh
        .triangles
        .iter()
        .flatten()
        .map(|&i| mesh.vertices[i as usize][2]);
    let (zmin, zmax) = used.fold((f64::MAX, f64::MIN), |(lo, hi), z| (lo.min(z), hi.max(z)));
    let layers = ((zmax - zmin) / h - 0.5).ceil().max(0.0);
    if layers > MAX_LAYERS as f64 {
        return Err(SliceError::TooManyLayers {
            height_mm: zmax - zmin,
            h_mm: h,
            layers,
        });
    }
    let layers = layers as usize;
    let mut beads: Vec<Bead> = Vec::new();
    // Per bead: the connected region of its layer's section it fills.
    let mut regions: Vec<usize> = Vec::new();
    let mut reports = Vec::with_capacity(layers);
    let mut approx_nodes = 0usize;
    for i in 0..layers {
        let z = zmin + (i as f64 + 0.5) * h;
        let layer = i as u32;
        let sec = section::section_paths(mesh, z, opts.join_mm)?;
        let raw = fill::fill(&sec, w, opts.perimeters, layer);
        let (closed, open): (Vec<_>, Vec<_>) = raw.iter().partition(|b| b.closed);
        let to = |v: &[&fill::RawBead]| -> clipper2_rust::Paths64 {
            v.iter().map(|b| poly::to64(&b.points)).collect()
        };
        let band = poly::buffer_lines(&to(&closed), &to(&open), 0.5 * w);
        let section_mm2 = poly::area_mm2(&sec);
        let band_mm2 = poly::area_mm2(&band);
        let covered = if section_mm2 > 0.0 {
            poly::area_mm2(&poly::intersection(&band, &sec)) / section_mm2
        } else {
            0.0
        };
        let outside = if band_mm2 > 0.0 {
            poly::area_mm2(&poly::difference(&band, &sec)) / band_mm2
        } else {
            0.0
        };
        let (n_beads, n_closed) = (closed.len() + open.len(), closed.len());
        let mut nodes = 0;
        for b in raw {
            let bead = Bead {
                layer,
                closed: b.closed,
                points: b.points,
            };
            let len = bead.length_mm();
            if len <= 0.0 {
                continue;
            }
            nodes += ((len / w).round() as usize).max(if bead.closed { 3 } else { 1 });
            beads.push(bead);
            regions.push(b.region);
        }
        approx_nodes += nodes;
        if approx_nodes > MAX_NODES {
            return Err(SliceError::TooManyNodes { layer, z_mm: z });
        }
        reports.push(LayerReport {
            layer,
            z_mm: z,
            section_mm2,
            beads: n_beads,
            closed_beads: n_closed,
            nodes,
            covered,
            outside,
        });
    }
    if beads.is_empty() {
        return Err(SliceError::NoBeads { layers, h_mm: h });
    }
    let (nodes, contacts) = graph::build(&beads, &regions, w, h, zmin);
    let part = BeadPart {
        name: opts.name.clone(),
        max_fragments: opts.max_fragments,
        bead_mm: [w, h],
        base_z_mm: zmin,
        beads,
        nodes,
        contacts,
        windows: Vec::new(),
        thermal: opts.thermal,
        warnings: Vec::new(),
    };
    Ok(Sliced {
        part,
        layers: reports,
        elapsed: start.elapsed(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use waam_part::ContactKind;

    /// A square tube whose 6 mm wall takes three 2 mm beads: two contour rings and the
    /// middle one. Eroded by a bead, the wall is a ring with wider corners than sides; taken
    /// by its narrowest place it fell into four corner loops and the sides went unwelded
    /// (80 % covered).
    #[test]
    fn a_square_tube_wall_is_three_rings_not_corner_loops() {
        let mut cells = Vec::new();
        for z in 0..3 {
            for y in 0..24 {
                for x in 0..24 {
                    if !((6..18).contains(&x) && (6..18).contains(&y)) {
                        cells.push([x, y, z]);
                    }
                }
            }
        }
        let s = slice(
            &shapes::voxels(&cells),
            &SliceOptions::new("tube", [2.0, 1.0]),
        )
        .unwrap();
        for l in &s.layers {
            assert_eq!((l.beads, l.closed_beads), (3, 3), "{l:?}");
            assert!(l.covered >= 0.95 && l.outside <= 0.01, "{l:?}");
        }
    }

    #[test]
    fn a_flanged_tube_is_covered_and_its_graph_reads_back() {
        // Flange r 30..56, 5 mm thick; tube r 30..36, 30 mm tall; W 6, H 2.5.
        let mesh = shapes::flanged_tube(30.0, 36.0, 56.0, 5.0, 30.0, 96);
        let s = slice(&mesh, &SliceOptions::new("nozzle", [6.0, 2.5])).unwrap();
        assert_eq!(s.layers.len(), 12);
        // The flange: 26 mm = 4.33 W: 2 + 2 rings and a thin core ring; the tube: one ring.
        assert_eq!(s.layers[0].beads, 5, "{:?}", s.layers[0]);
        assert!(s.layers[2..]
            .iter()
            .all(|l| l.beads == 1 && l.closed_beads == 1));
        let worst = s.worst_covered().unwrap();
        assert!(s.mean_covered() >= 0.92, "{}", s.mean_covered());
        assert!(worst.covered >= 0.85, "{worst:?}");
        assert!(s.worst_outside().unwrap().outside <= 0.20);
        // Tube ring r = 33: 207 mm, 35 pieces of about W.
        assert_eq!(s.layers[5].nodes, 35);
        let p = &s.part;
        let back = BeadPart::parse(&p.to_yaml()).unwrap();
        assert_eq!(&back, p);
        // Every tube node stands on one or two nodes of the layer below; moves go up only.
        let moves = p.moves();
        for (u, n) in p.nodes.iter().enumerate() {
            if n.layer >= 3 {
                let below = moves.stands_on(u);
                assert!((1..=3).contains(&below.len()), "node {u}: {below:?}");
            }
        }
        // Flange rings lie side by side.
        assert!(p.contacts.iter().any(|c| c.kind == ContactKind::Beside));
        // A plan: each layer's ring in order, one fragment per layer, k = layers... is valid
        // when the part allows it.
        let mut part = p.clone();
        part.max_fragments = p.nodes.len();
        let frags: Vec<Vec<usize>> = (0..p.nodes.len()).map(|i| vec![i]).collect();
        let plan = waam_part::GraphPlan {
            part: None,
            fragments: frags,
        };
        assert_eq!(plan.validate(&part, &part.moves()), Ok(()));
    }

    #[test]
    fn bad_meshes_and_beads_are_errors_not_panics() {
        let mut mesh = shapes::ring(10.0, 16.0, 5.0, 24);
        let o = SliceOptions::new("r", [6.0, 2.5]);
        assert_eq!(
            slice(&TriangleMesh::default(), &o).unwrap_err(),
            SliceError::Empty
        );
        assert!(matches!(
            slice(&mesh, &SliceOptions::new("r", [0.0, 2.5])),
            Err(SliceError::Bead(_))
        ));
        assert!(matches!(
            slice(&mesh, &SliceOptions::new("r", [6.0, 1e-300])),
            Err(SliceError::TooManyLayers { .. })
        ));
        mesh.vertices[0][1] = f64::NAN;
        assert!(matches!(
            slice(&mesh, &o),
            Err(SliceError::NonFinite { .. })
        ));
        mesh.vertices[0][1] = 1e300;
        assert!(matches!(
            slice(&mesh, &o),
            Err(SliceError::OutOfRange { .. })
        ));
        mesh.triangles[0][0] = 9999;
        assert!(matches!(slice(&mesh, &o), Err(SliceError::BadIndex { .. })));
    }
}
