//! The toolpath of a graph-part plan: the torch follows the beads' centre lines.
//!
//! Each fragment (node ids in weld order) becomes one weld pass. A node's piece of its bead
//! is the centre line from `from_mm` to `to_mm`, walked forwards or backwards so that
//! consecutive nodes of one bead join end to start (across the seam of a closed bead too).
//! Between nodes that do not join (a step beside or up) the torch welds a connection: along
//! the previous bead's centre line where the next piece starts on it (within W/2) at most a
//! node ahead, or along the next bead's where the previous piece ended on it at most a node
//! before its start, z rising with the length welded (a spiral tube climbs on a helix, not
//! a chord inside its circle); else straight. The torch target is the top of the bead's
//! layer, `base_z_mm + (layer + 1)·H`, as a block plan's is the top centre of the block.
//! Transit, approach, arc on/off and retract are the block plan's
//! ([`super::build_routes`]).
//!
//! Timing: with the process settings' `weld_speed_mm_s`, that speed throughout. Without it,
//! node i takes the graph thermal model's deposit time `block_time_s · V_i / V0`
//! (`V0 = W·W·H`, `docs/graph-thermal-model.md`): a constant weld speed `W / block_time_s`
//! on nodes sliced as `W·H·length`, as a block plan welds one block width per block time.
//! Node i's time covers its piece and the connection to the next node, so that node i + 1
//! is deposited (the torch reaches the start of its piece) exactly that time after node i,
//! as the thermal model deposits them.

use nalgebra::{Isometry3, Point3};
use waam_part::{Bead, BeadPart, Deposit};

use super::{build_routes, ProcessSettings, Route, Toolpath, ToolpathError};

/// The frame of [`Toolpath::frame`] when the poses are in the part frame (no robot): the
/// mesh's own coordinates, as the ROS node's `part` frame.
pub const PART_FRAME: &str = "part";

/// Where a toolpath's poses are given.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ToolpathFrame<'a> {
    /// The part frame ([`PART_FRAME`]): no robot, the process settings' plate is not used.
    Part,
    /// The robot's base link: the part frame placed by the process settings' plate.
    Robot { base_link: &'a str },
}

impl ToolpathFrame<'_> {
    /// The part frame in this frame, and the frame's name.
    pub fn placement(self, settings: &ProcessSettings) -> (Isometry3<f64>, String) {
        match self {
            ToolpathFrame::Part => (Isometry3::identity(), PART_FRAME.to_string()),
            ToolpathFrame::Robot { base_link } => {
                (settings.plate.isometry(), base_link.to_string())
            }
        }
    }
}

/// The toolpath of a graph plan (fragments of node ids), in `frame`. Errors: no fragments,
/// an empty fragment, a node id the part does not have, a toolpath over the pose budget.
pub fn toolpath_of_graph_plan(
    part: &BeadPart,
    fragments: &[Vec<usize>],
    settings: &ProcessSettings,
    frame: ToolpathFrame,
) -> Result<Toolpath, ToolpathError> {
    let routes = routes_of_graph_plan(part, fragments, settings.weld_speed_mm_s)?;
    let (plate, name) = frame.placement(settings);
    build_routes(&routes, settings, plate, &name)
}

/// One route per fragment (see the module's description).
pub(crate) fn routes_of_graph_plan(
    part: &BeadPart,
    fragments: &[Vec<usize>],
    weld_speed_mm_s: Option<f64>,
) -> Result<Vec<Route>, ToolpathError> {
    if fragments.is_empty() {
        return Err(ToolpathError::NoPasses);
    }
    let beads: Vec<Line> = part.beads.iter().map(Line::new).collect();
    let [w, h] = part.bead_mm;
    let v0 = w * w * h;
    let mut routes = Vec::with_capacity(fragments.len());
    for (f, frag) in fragments.iter().enumerate() {
        if frag.is_empty() {
            return Err(ToolpathError::EmptyPass(f));
        }
        if let Some(k) = frag.iter().position(|&n| n >= part.nodes.len()) {
            return Err(ToolpathError::UnknownNode {
                pass: f,
                point: k,
                node: frag[k],
                nodes: part.nodes.len(),
            });
        }
        let nodes: Vec<&Deposit> = frag.iter().map(|&n| &part.nodes[n]).collect();
        let z = |d: &Deposit| part.base_z_mm + (d.layer as f64 + 1.0) * h;
        let mut points: Vec<Point3<f64>> = Vec::new();
        let mut marks: Vec<(usize, bool)> = Vec::new();
        // The node whose time each step (into a station) counts against.
        let mut span_of: Vec<usize> = Vec::new();
        // Where the previous piece ended.
        let mut end: Option<End> = None;
        for (k, d) in nodes.iter().enumerate() {
            let forward = direction(&beads, &nodes, k, end.map(|e| (e.bead, e.at_mm)), &points);
            let line = &beads[d.bead];
            let (from, to) = (line.clamp(d.from_mm), line.clamp(d.to_mm));
            let mut piece = line.piece(from, to);
            if !forward {
                piece.reverse();
            }
            let piece: Vec<Point3<f64>> = piece
                .into_iter()
                .map(|[x, y]| Point3::new(x, y, z(d)))
                .collect();
            match points.last() {
                // The pieces join: the previous piece's end is this node's deposit point.
                Some(last) if (piece[0] - last).norm() < JOIN_MM => {
                    *marks.last_mut().expect("marks follow points") = (k, true);
                }
                // A step beside or up: along a centre line where one leads there (see
                // `connection`), else straight; on the previous node's time.
                _ => {
                    if let (Some(&last), Some(prev)) = (points.last(), end) {
                        let next = End {
                            bead: d.bead,
                            at_mm: if forward { from } else { to },
                            forward,
                            piece_mm: to - from,
                        };
                        for p in connection(&beads, w, (prev, last), (next, piece[0])) {
                            points.push(p);
                            marks.push((k - 1, false));
                            span_of.push(k - 1);
                        }
                    }
                    points.push(piece[0]);
                    marks.push((k, true));
                    span_of.push(k.saturating_sub(1));
                }
            }
            for p in &piece[1..] {
                points.push(*p);
                marks.push((k, false));
                span_of.push(k);
            }
            end = Some(End {
                bead: d.bead,
                at_mm: if forward { to } else { from },
                forward,
                piece_mm: to - from,
            });
        }
        let step_mm: Vec<f64> = (0..points.len())
            .map(|i| match i {
                0 => 0.0,
                _ => (points[i] - points[i - 1]).norm(),
            })
            .collect();
        let step_s = match weld_speed_mm_s {
            Some(v) => step_mm.iter().map(|d| d / v).collect(),
            None => {
                let mut span_mm = vec![0.0; nodes.len()];
                for (i, d) in step_mm.iter().enumerate().skip(1) {
                    span_mm[span_of[i]] += d;
                }
                let time = |k: usize| part.thermal.block_time_s * nodes[k].volume_mm3 / v0;
                (0..points.len())
                    .map(|i| match i {
                        0 => 0.0,
                        _ => time(span_of[i]) * step_mm[i] / span_mm[span_of[i]],
                    })
                    .collect()
            }
        };
        routes.push(Route {
            points_mm: points,
            step_s,
            marks,
            // The torch turns over two bead widths of path: the centre lines' short
            // segments and corners would turn it faster than the arm's joints can.
            heading_window_mm: w,
        });
    }
    Ok(routes)
}

/// Two pieces closer than this (mm) join without a connection; a vertex this close to a
/// piece's end is left out of the piece (the slicer's centre lines are rounded to 0.1 µm,
/// so pieces cut from them end a few nanometres off their vertices).
const JOIN_MM: f64 = 1e-3;

/// Whether node `k` of a fragment is walked from `from_mm` to `to_mm`: so that it starts
/// where the previous piece of its bead ended; else so that it ends where the next piece
/// of its bead starts; else starting at the end nearer the torch (after a step), or ending
/// nearer the next node; else forwards.
fn direction(
    beads: &[Line],
    nodes: &[&Deposit],
    k: usize,
    end: Option<(usize, f64)>,
    points: &[Point3<f64>],
) -> bool {
    let d = nodes[k];
    let line = &beads[d.bead];
    let (from, to) = (line.clamp(d.from_mm), line.clamp(d.to_mm));
    if let Some((_, s)) = end.filter(|&(b, _)| b == d.bead) {
        if line.same_place(s, from) {
            return true;
        }
        if line.same_place(s, to) {
            return false;
        }
    }
    if let Some(next) = nodes.get(k + 1).filter(|n| n.bead == d.bead) {
        let ends = [line.clamp(next.from_mm), line.clamp(next.to_mm)];
        if ends.iter().any(|&e| line.same_place(to, e)) {
            return true;
        }
        if ends.iter().any(|&e| line.same_place(from, e)) {
            return false;
        }
    }
    let dist = |s: f64, q: [f64; 2]| {
        let p = line.at(s);
        (p[0] - q[0]).hypot(p[1] - q[1])
    };
    if let Some(p) = points.last() {
        return dist(from, [p.x, p.y]) <= dist(to, [p.x, p.y]);
    }
    if let Some(next) = nodes.get(k + 1) {
        let c = [next.centre_mm[0], next.centre_mm[1]];
        return dist(to, c) <= dist(from, c);
    }
    true
}

/// A piece's end (of the previous node) or start (of the next), where a connection meets it.
#[derive(Debug, Clone, Copy)]
struct End {
    bead: usize,
    /// Its arc length on the bead's centre line.
    at_mm: f64,
    /// Whether the piece is walked from `from_mm` to `to_mm`.
    forward: bool,
    /// The piece's length.
    piece_mm: f64,
}

/// The stations strictly between `a` (where the previous piece ended, at `pa`) and `b`
/// (where the next starts, at `pb`) of the weld from one to the other; none for a straight
/// weld. Where `pb` lies near the previous bead's centre line ahead of `a` (in its walking
/// direction), or `pa` near the next bead's behind `b`, the torch follows that line in xy
/// (the nearer fit), z rising linearly with the path's length: a helix on a ring, where a
/// straight climb would cut a chord inside it. Near: within W/2 of the line, i.e. on that
/// bead's deposit (beads beside each other are W apart, so a step between them finds no
/// line); and no farther along than the longer piece, as the node above or beside the
/// next one is. A step down stays straight, so the climb never dips below `pa`.
fn connection(
    beads: &[Line],
    w: f64,
    (a, pa): (End, Point3<f64>),
    (b, pb): (End, Point3<f64>),
) -> Vec<Point3<f64>> {
    if pb.z < pa.z {
        return Vec::new();
    }
    let reach = a.piece_mm.max(b.piece_mm);
    let ahead = beads[a.bead].fit(a.at_mm, a.forward, reach, [pb.x, pb.y], 0.5 * w);
    let behind = beads[b.bead].fit(b.at_mm, !b.forward, reach, [pa.x, pa.y], 0.5 * w);
    let xy = match (ahead, behind) {
        (Some(f), Some(g)) if g.0 < f.0 => g.1.into_iter().rev().collect(),
        (Some(f), _) => f.1,
        (None, Some(g)) => g.1.into_iter().rev().collect(),
        (None, None) => return Vec::new(),
    };
    // z by the share of the path's length in xy walked.
    let mut at = Vec::with_capacity(xy.len());
    let mut s = 0.0;
    let mut prev = [pa.x, pa.y];
    for p in &xy {
        s += (p[0] - prev[0]).hypot(p[1] - prev[1]);
        at.push(s);
        prev = *p;
    }
    let total = s + (pb.x - prev[0]).hypot(pb.y - prev[1]);
    xy.iter()
        .zip(at)
        .map(|(p, s)| Point3::new(p[0], p[1], pa.z + (pb.z - pa.z) * s / total))
        .collect()
}

/// A bead's centre line with the arc length at each vertex; a closed bead repeats its
/// first point at the end.
struct Line {
    points: Vec<[f64; 2]>,
    at_mm: Vec<f64>,
    closed: bool,
}

impl Line {
    fn new(bead: &Bead) -> Line {
        let mut points = bead.points.clone();
        if bead.closed {
            points.push(bead.points[0]);
        }
        let mut at_mm = Vec::with_capacity(points.len());
        let mut s = 0.0;
        for (i, p) in points.iter().enumerate() {
            if i > 0 {
                let q = points[i - 1];
                s += (p[0] - q[0]).hypot(p[1] - q[1]);
            }
            at_mm.push(s);
        }
        Line {
            points,
            at_mm,
            closed: bead.closed,
        }
    }

    fn length(&self) -> f64 {
        *self.at_mm.last().expect("a bead has points")
    }

    /// The reader allows `to_mm` a rounding error beyond the length.
    fn clamp(&self, s: f64) -> f64 {
        s.clamp(0.0, self.length())
    }

    /// Whether two arc lengths are one place (the seam of a closed bead: 0 and its length).
    fn same_place(&self, a: f64, b: f64) -> bool {
        let eps = 1e-6 * self.length().max(1.0);
        (a - b).abs() <= eps || (self.closed && ((a - b).abs() - self.length()).abs() <= eps)
    }

    /// The point at arc length `s`.
    fn at(&self, s: f64) -> [f64; 2] {
        let i = self
            .at_mm
            .partition_point(|&a| a <= s)
            .clamp(1, self.points.len() - 1);
        let (a, b) = (self.points[i - 1], self.points[i]);
        let len = self.at_mm[i] - self.at_mm[i - 1];
        let t = if len > 0.0 {
            ((s - self.at_mm[i - 1]) / len).clamp(0.0, 1.0)
        } else {
            0.0
        };
        [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]
    }

    /// The centre line from `from` to `to` (from < to): its ends and the vertices between,
    /// but none within [`JOIN_MM`] of an end: the torch would turn on the spot there (the
    /// heading of a step of nanometres), which no robot joint follows.
    fn piece(&self, from: f64, to: f64) -> Vec<[f64; 2]> {
        let eps = JOIN_MM;
        let mut out = vec![self.at(from)];
        for (p, &s) in self.points.iter().zip(&self.at_mm) {
            if s > from + eps && s < to - eps {
                out.push(*p);
            }
        }
        out.push(self.at(to));
        out
    }

    /// The centre line from arc length `s` on, forwards or backwards, for `len` mm or to
    /// its end (a closed bead: around its seam, at most one lap): (distance walked, point)
    /// at `s`, at the vertices between (none within [`JOIN_MM`] of either end) and at the
    /// end.
    fn walk(&self, s: f64, forward: bool, len: f64) -> Vec<(f64, [f64; 2])> {
        let total = self.length();
        let room = match (self.closed, forward) {
            (true, _) => total,
            (false, true) => total - s,
            (false, false) => s,
        };
        let len = len.min(room).max(0.0);
        let at = |d: f64| {
            let t = if forward { s + d } else { s - d };
            self.at(if self.closed { t.rem_euclid(total) } else { t })
        };
        let mut ds: Vec<f64> = self
            .at_mm
            .iter()
            .map(|&v| {
                let d = if forward { v - s } else { s - v };
                if self.closed {
                    d.rem_euclid(total)
                } else {
                    d
                }
            })
            .filter(|&d| d > JOIN_MM && d < len - JOIN_MM)
            .collect();
        ds.sort_by(f64::total_cmp);
        // A closed bead's first and last points are one vertex.
        ds.dedup_by(|x, y| (*x - *y).abs() < JOIN_MM);
        let mut out = vec![(0.0, self.at(s))];
        out.extend(ds.into_iter().map(|d| (d, at(d))));
        if len > JOIN_MM {
            out.push((len, at(len)));
        }
        out
    }

    /// Whether `q` lies within `near` of the line walked from `s` for `len` mm (see
    /// [`Line::walk`]): the distance, and the points of the walk up to the one nearest `q`
    /// (without `s`'s own, nor one within [`JOIN_MM`] of `q`).
    fn fit(
        &self,
        s: f64,
        forward: bool,
        len: f64,
        q: [f64; 2],
        near: f64,
    ) -> Option<(f64, Vec<[f64; 2]>)> {
        let walk = self.walk(s, forward, len);
        let mut best: Option<(f64, usize, f64, [f64; 2])> = None;
        for (i, seg) in walk.windows(2).enumerate() {
            let ((d0, a), (d1, b)) = (seg[0], seg[1]);
            let ab = [b[0] - a[0], b[1] - a[1]];
            let l2 = ab[0] * ab[0] + ab[1] * ab[1];
            let t = if l2 > 0.0 {
                (((q[0] - a[0]) * ab[0] + (q[1] - a[1]) * ab[1]) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let p = [a[0] + ab[0] * t, a[1] + ab[1] * t];
            let off = (q[0] - p[0]).hypot(q[1] - p[1]);
            if best.is_none_or(|b| off < b.0) {
                best = Some((off, i, d0 + (d1 - d0) * t, p));
            }
        }
        let (off, i, d, p) = best.filter(|b| b.0 <= near)?;
        let mut path: Vec<[f64; 2]> = walk[1..=i]
            .iter()
            .filter(|v| v.0 < d - JOIN_MM)
            .map(|v| v.1)
            .collect();
        if d > JOIN_MM && off > JOIN_MM {
            path.push(p);
        }
        Some((off, path))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::toolpath::PoseKind;
    use std::f64::consts::TAU;
    use waam_part::ThermalParams;

    const R: f64 = 33.0;
    const W: f64 = 6.0;
    const H: f64 = 2.5;

    /// Rings of radius R (128 vertices: the polygon is within 0.04 mm of the circle), one
    /// per layer, cut into pieces of about W, listed layer by layer.
    fn rings(layers: u32) -> BeadPart {
        let mut part = BeadPart {
            name: "ring".into(),
            max_fragments: 2,
            bead_mm: [W, H],
            base_z_mm: 0.0,
            beads: Vec::new(),
            nodes: Vec::new(),
            contacts: Vec::new(),
            windows: Vec::new(),
            thermal: ThermalParams::default(),
            warnings: Vec::new(),
        };
        for layer in 0..layers {
            add_ring(&mut part, R, layer);
        }
        part
    }

    /// A ring of radius `r` on `layer` as the next bead, cut into pieces of about W from
    /// angle 0 counter-clockwise.
    fn add_ring(part: &mut BeadPart, r: f64, layer: u32) {
        let points: Vec<[f64; 2]> = (0..128)
            .map(|i| {
                let a = TAU * i as f64 / 128.0;
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        let bead = Bead {
            layer,
            closed: true,
            points,
        };
        let len = bead.length_mm();
        let n = (len / W).round() as usize;
        let line = Line::new(&bead);
        for i in 0..n {
            let (from_mm, to_mm) = (len * i as f64 / n as f64, len * (i + 1) as f64 / n as f64);
            let c = line.at(0.5 * (from_mm + to_mm));
            part.nodes.push(Deposit {
                bead: part.beads.len(),
                from_mm,
                to_mm,
                layer,
                centre_mm: [c[0], c[1], (layer as f64 + 0.5) * H],
                volume_mm3: W * H * (to_mm - from_mm),
                surface_mm2: 1.0,
                substrate_mm2: 0.0,
            });
        }
        part.beads.push(bead);
    }

    fn part_frame(part: &BeadPart, fragments: &[Vec<usize>]) -> Toolpath {
        toolpath_of_graph_plan(
            part,
            fragments,
            &ProcessSettings::default(),
            ToolpathFrame::Part,
        )
        .unwrap()
    }

    /// Positions of the poses with the arc on, mm.
    fn welded(tp: &Toolpath) -> Vec<Point3<f64>> {
        tp.poses
            .iter()
            .filter(|p| p.arc_on)
            .map(|p| Point3::from(p.pose.translation.vector * 1000.0))
            .collect()
    }

    #[test]
    fn a_ring_is_welded_on_its_circle_along_its_tangent() {
        let part = rings(1);
        let n = part.nodes.len();
        // Start in the middle: the fragment crosses the bead's seam.
        let frag: Vec<usize> = (0..n).map(|i| (i + n / 3) % n).collect();
        let tp = part_frame(&part, &[frag]);
        assert_eq!(tp.frame, PART_FRAME);
        let s = ProcessSettings::default();
        let on = welded(&tp);
        assert!(on.len() > 128, "{} poses", on.len());
        for p in &on {
            let r = p.x.hypot(p.y);
            assert!((r - R).abs() < 0.1, "{p} is {r} mm from the centre");
            assert!((p.z - H).abs() < 1e-9, "{p}: the top of layer 0");
        }
        let mut travel = 0.0;
        for w in on.windows(2) {
            let d = w[1] - w[0];
            assert!(d.norm() <= s.max_step_mm + 1e-9);
            travel += d.norm();
            if d.norm() < 1e-9 {
                continue; // the dwells
            }
            // Counter-clockwise: along the tangent at the step's middle.
            let m = nalgebra::center(&w[0], &w[1]);
            let tangent = nalgebra::Vector3::new(-m.y, m.x, 0.0).normalize();
            assert!(
                d.normalize().dot(&tangent) > (3.0f64).to_radians().cos(),
                "{d}"
            );
        }
        let circle = TAU * R;
        assert!(
            (travel - circle).abs() < 0.5,
            "{travel} mm welded, {circle}"
        );
        // The torch leans along the tangent (push) and points down.
        for p in tp.poses.iter().filter(|p| p.arc_on) {
            let z = p.pose.rotation * nalgebra::Vector3::z();
            assert!(z.z < -0.9);
            let t = p.pose.translation.vector;
            let tangent = nalgebra::Vector3::new(-t.y, t.x, 0.0).normalize();
            let lean = nalgebra::Vector3::new(z.x, z.y, 0.0).normalize();
            assert!(lean.dot(&tangent) > (4.0f64).to_radians().cos(), "{lean}");
        }
        // Every node is deposited once, one deposit time after the other.
        let times = tp.executed_times();
        assert_eq!(times.deposits_s.len(), 1);
        let d = &times.deposits_s[0];
        assert_eq!(d.len(), n);
        let block = part.thermal.block_time_s;
        let node_s = block * part.nodes[0].volume_mm3 / (W * W * H);
        assert!((d[1] - d[0] - s.arc_on_dwell_s - node_s).abs() < 1e-9);
        for w in d[1..].windows(2) {
            assert!((w[1] - w[0] - node_s).abs() < 1e-9, "{w:?}");
        }
        // That is W per block time.
        assert!((node_s - (TAU * R / n as f64) / W * block).abs() < 0.05);
    }

    #[test]
    fn pieces_cut_a_hair_off_the_vertices_do_not_turn_the_torch_on_the_spot() {
        // Cut at every other vertex, 10 nm off (as rounded slicer output is): no weld step
        // of nanometres (where the torch's heading would turn at once) is left.
        let mut part = rings(1);
        let line = Line::new(&part.beads[0]);
        let cuts: Vec<f64> = (0..=64).map(|i| line.at_mm[2 * i] + 1e-5).collect();
        let template = part.nodes[0].clone();
        part.nodes = cuts
            .windows(2)
            .map(|c| Deposit {
                from_mm: c[0],
                to_mm: c[1].min(line.length()),
                ..template.clone()
            })
            .collect();
        let frag: Vec<usize> = (0..part.nodes.len()).collect();
        let tp = part_frame(&part, &[frag]);
        let on = welded(&tp);
        for w in on.windows(2) {
            let d = (w[1] - w[0]).norm();
            assert!(d == 0.0 || d >= JOIN_MM, "a weld step of {d} mm");
        }
    }

    #[test]
    fn a_fragment_in_reverse_walks_the_beads_backwards() {
        let part = rings(1);
        let n = part.nodes.len();
        let frag: Vec<usize> = (0..n).rev().map(|i| (i + 5) % n).collect();
        let tp = part_frame(&part, &[frag]);
        let on = welded(&tp);
        let mut travel = 0.0;
        for w in on.windows(2) {
            let d = w[1] - w[0];
            travel += d.norm();
            if d.norm() > 1e-9 {
                let m = nalgebra::center(&w[0], &w[1]);
                assert!(d.x * -m.y + d.y * m.x < 0.0, "clockwise");
            }
        }
        assert!((travel - TAU * R).abs() < 0.5);
    }

    #[test]
    fn a_two_layer_spiral_climbs_and_never_goes_down() {
        let part = rings(2);
        let frag: Vec<usize> = (0..part.nodes.len()).collect();
        let tp = part_frame(&part, &[frag]);
        let on = welded(&tp);
        assert!(on.windows(2).all(|w| w[1].z >= w[0].z));
        assert!((on[0].z - H).abs() < 1e-9);
        assert!((on.last().unwrap().z - 2.0 * H).abs() < 1e-9);
        // One up move, welded: the arc stays on.
        let arcs = tp
            .poses
            .iter()
            .filter(|p| p.kind == PoseKind::ArcOn)
            .count();
        assert_eq!(arcs, 1);
        for p in &on {
            assert!((p.x.hypot(p.y) - R).abs() < 0.1);
        }
    }

    #[test]
    fn a_spiral_climbs_along_its_circle_one_node_ahead() {
        // Each layer starts one node (6.5 mm) ahead of where the one below ended, both ways
        // round: a straight climb would cut a chord 6.5^2 / (8 R) = 0.16 mm inside the ring.
        let part = rings(3);
        let n = part.nodes.len() / 3;
        let ccw = |l: usize, i: usize| l * n + (i + l) % n;
        let cw = |l: usize, i: usize| l * n + (2 * n - 1 - i - l) % n;
        for order in [&ccw as &dyn Fn(usize, usize) -> usize, &cw] {
            let frag: Vec<usize> = (0..3)
                .flat_map(|l| (0..n).map(move |i| (l, i)))
                .map(|(l, i)| order(l, i))
                .collect();
            let frags = [frag];
            let tp = part_frame(&part, &frags);
            let on = welded(&tp);
            for p in &on {
                let r = p.x.hypot(p.y);
                assert!((r - R).abs() < 0.1, "{p} is {r} mm from the centre");
            }
            // Up only, from the top of layer 0 to the top of layer 2.
            assert!(on.windows(2).all(|w| w[1].z >= w[0].z));
            assert!((on[0].z - H).abs() < 1e-9);
            assert!((on.last().unwrap().z - 3.0 * H).abs() < 1e-9);
            // A climb is a helix: z rises with the path's length, stations on the way.
            let route = &routes_of_graph_plan(&part, &frags, None).unwrap()[0];
            let climb: Vec<&Point3<f64>> = route
                .points_mm
                .iter()
                .filter(|p| p.z > H + 1e-9 && p.z < 2.0 * H - 1e-9)
                .collect();
            assert!(climb.len() >= 2, "{climb:?}");
            // Every node is deposited one deposit time after the one before.
            let times = tp.executed_times();
            let d = &times.deposits_s[0];
            assert_eq!(d.len(), 3 * n);
            let node_s = part.thermal.block_time_s * part.nodes[0].volume_mm3 / (W * W * H);
            for w in d[1..].windows(2) {
                assert!((w[1] - w[0] - node_s).abs() < 1e-9, "{w:?}");
            }
        }
    }

    #[test]
    fn a_step_to_another_bead_or_across_is_straight() {
        // Beside: from a ring to the one W outside it, one node ahead.
        let mut part = rings(1);
        add_ring(&mut part, R + W, 0);
        let (n0, n1) = (part.beads[0].length_mm() / W, part.beads[1].length_mm() / W);
        let (n0, n1) = (n0.round() as usize, n1.round() as usize);
        let beside: Vec<usize> = (0..n0).chain((0..n1).map(|i| n0 + (i + 1) % n1)).collect();
        // Up, across: the layer above starts half a lap away.
        let up = rings(2);
        let n = up.nodes.len() / 2;
        let across: Vec<usize> = (0..n).chain((0..n).map(|i| n + (i + n / 2) % n)).collect();
        for (part, frag) in [(&part, beside), (&up, across)] {
            let frags = [frag];
            let route = &routes_of_graph_plan(part, &frags, None).unwrap()[0];
            let pts = &route.points_mm;
            let k = frags[0]
                .iter()
                .position(|&i| part.nodes[i].bead == 1)
                .unwrap();
            let first = route.marks.iter().position(|&m| m == (k, true)).unwrap();
            // The station before the next node's first is the previous node's last.
            let (a, b) = (pts[first - 1], pts[first]);
            let bead = |p: Point3<f64>, b: usize| {
                let r = part.beads[b].points[0][0];
                (p.x.hypot(p.y) - r).abs() < 0.1
                    && (p.z - (part.beads[b].layer as f64 + 1.0) * H).abs() < 1e-9
            };
            // From the end of ring 0's last piece (angle 0) straight to the next bead.
            assert!((a - Point3::new(R, 0.0, H)).norm() < 1e-6, "{a}");
            assert!(bead(b, 1), "{a} -> {b}");
        }
    }

    #[test]
    fn two_fragments_have_one_transit_between_them() {
        let part = rings(2);
        let n = part.nodes.len() / 2;
        let frags = vec![(0..n).collect(), (n..2 * n).collect::<Vec<usize>>()];
        let tp = part_frame(&part, &frags);
        let kinds: Vec<PoseKind> = tp.poses.iter().map(|p| p.kind).collect();
        let count = |k: PoseKind| kinds.iter().filter(|&&x| x == k).count();
        assert_eq!((count(PoseKind::ArcOn), count(PoseKind::ArcOff)), (2, 2));
        // Runs of transit poses: before the first pass, between the two, after the last.
        let runs = kinds
            .windows(2)
            .filter(|w| w[0] != PoseKind::Transit && w[1] == PoseKind::Transit)
            .count()
            + usize::from(kinds[0] == PoseKind::Transit);
        assert_eq!(runs, 3, "{kinds:?}");
        let off = kinds.iter().position(|&k| k == PoseKind::ArcOff).unwrap();
        let on2 = kinds.iter().rposition(|&k| k == PoseKind::ArcOn).unwrap();
        assert!(kinds[off..on2].contains(&PoseKind::Transit));
        assert!(tp.poses[off..on2].iter().all(|p| !p.arc_on));
        // Beside or up moves only inside a fragment: the second starts on layer 1.
        let second = &tp.poses[on2];
        assert!((second.pose.translation.z * 1000.0 - 2.0 * H).abs() < 1e-9);
    }

    #[test]
    fn robot_frame_places_the_part_by_the_plate_and_weld_speed_is_kept() {
        let part = rings(1);
        let frag: Vec<usize> = (0..part.nodes.len()).collect();
        let s = ProcessSettings {
            weld_speed_mm_s: Some(8.0),
            ..ProcessSettings::default()
        };
        let tp = toolpath_of_graph_plan(
            &part,
            &[frag],
            &s,
            ToolpathFrame::Robot {
                base_link: "base_link",
            },
        )
        .unwrap();
        assert_eq!(tp.frame, "base_link");
        let plate = s.plate.isometry();
        let on: Vec<_> = tp.poses.iter().filter(|p| p.arc_on).collect();
        for w in on.windows(2) {
            let d = (w[1].pose.translation.vector - w[0].pose.translation.vector).norm();
            let dt = w[1].time_s - w[0].time_s;
            if d > 1e-9 {
                assert!((d * 1000.0 / dt - 8.0).abs() < 1e-6);
            }
        }
        let p = plate.inverse() * on[0].pose;
        assert!((p.translation.vector.xy().norm() * 1000.0 - R).abs() < 0.1);
    }

    #[test]
    fn bad_fragments_are_refused() {
        let part = rings(1);
        let s = ProcessSettings::default();
        let go = |f: &[Vec<usize>]| toolpath_of_graph_plan(&part, f, &s, ToolpathFrame::Part);
        assert_eq!(go(&[]), Err(ToolpathError::NoPasses));
        assert_eq!(go(&[vec![0], vec![]]), Err(ToolpathError::EmptyPass(1)));
        let e = go(&[vec![0, 999]]).unwrap_err();
        assert!(e.to_string().contains("node 999"), "{e}");
    }
}
