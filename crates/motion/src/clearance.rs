//! Moves with the arc off (transit, approach, retract, wait) against the part as built:
//! the TCP's straight line between two poses must not enter a block welded so far, nor go
//! below the plate's surface; and with a torch, the torch's cylinders (nozzle, body,
//! wrist: [`Torch::cylinders`]) in the pose's own orientation, sampled along the move
//! ([`SAMPLE_MM`]), must not enter one either. The toolpath routes transits above the
//! tallest block welded so far plus `clearance_mm` (and the torch's reach below the TCP);
//! this check makes sure no such move is ever returned.

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use rustc_hash::FxHashSet;
use thiserror::Error;

use crate::toolpath::{PoseKind, Toolpath};
use waam_access::{Cylinder, Torch};
use waam_part::{Block, BlockDisplay, Part};

/// The torch is sampled along a move so that no point of it travels more than this
/// between two samples, mm; each sampled cylinder is widened and lengthened by half of it.
/// Every point of the moving torch is then within `SAMPLE_MM / 2` of where it is at one of
/// the two samples around it, so the widened cylinders at the samples contain the whole
/// swept torch: a block cannot slip between two samples. (The price: along moves the
/// torch keeps `SAMPLE_MM / 2` from every block rather than touching it.)
pub const SAMPLE_MM: f64 = 0.2;

/// Faces may be touched (a retract starts on the top of the block just welded): a block is
/// entered only deeper than this, mm.
const TOUCH_MM: f64 = 1e-3;

/// A move with the arc off that passes through the part as built.
#[derive(Debug, Error, PartialEq)]
#[error("the {what} move ending at pose {pose} (weld path {}) passes through {obstacle}", .fragment + 1)]
pub struct Collision {
    pub what: &'static str,
    pub pose: usize,
    pub fragment: usize,
    /// "block [x,y,z]" or "the plate", and with the torch which part of it meets it.
    pub obstacle: String,
}

/// Whether the segment `a`–`b` enters the box `lo`–`hi` (slab test).
pub fn segment_enters_box(a: &Point3<f64>, b: &Point3<f64>, lo: [f64; 3], hi: [f64; 3]) -> bool {
    let d: Vector3<f64> = b - a;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for i in 0..3 {
        if d[i].abs() < 1e-15 {
            if a[i] <= lo[i] || a[i] >= hi[i] {
                return false;
            }
        } else {
            let (mut u, mut v) = ((lo[i] - a[i]) / d[i], (hi[i] - a[i]) / d[i]);
            if u > v {
                std::mem::swap(&mut u, &mut v);
            }
            t0 = t0.max(u);
            t1 = t1.min(v);
            if t0 >= t1 {
                return false;
            }
        }
    }
    true
}

/// Checks every arc-off move of a block plan's toolpath against the blocks welded before
/// it and the plate (`plate`: the part frame in the toolpath's frame): the TCP's line, and
/// with a `torch` its cylinders sampled along the move ([`SAMPLE_MM`]).
pub fn check_moves(
    part: &Part,
    fragments: &[Vec<usize>],
    tp: &Toolpath,
    plate: &Isometry3<f64>,
    torch: Option<&Torch>,
) -> Result<(), Collision> {
    let to_part = plate.inverse();
    // A pose in the part frame, translation in mm.
    let in_part = |k: usize| -> (Point3<f64>, UnitQuaternion<f64>) {
        let pose = to_part * tp.poses[k].pose;
        (
            Point3::from(pose.translation.vector * 1000.0),
            pose.rotation,
        )
    };
    let cylinders = torch.map(Torch::cylinders).unwrap_or_default();
    // The farthest any torch point is from the TCP: how far it swings when the torch turns.
    let lever = cylinders
        .iter()
        .map(|c| c.to_mm.hypot(c.radius_mm))
        .fold(0.0, f64::max);
    let offs: Vec<usize> = (0..tp.poses.len())
        .filter(|&k| tp.poses[k].kind == PoseKind::ArcOff)
        .collect();
    let mut built = Built::new(part);
    for k in 1..tp.poses.len() {
        let (prev, pose) = (&tp.poses[k - 1], &tp.poses[k]);
        if prev.arc_on {
            continue;
        }
        let what = match pose.kind {
            PoseKind::Approach | PoseKind::ArcOn => "approach",
            PoseKind::Retract => "retract",
            _ => "transit",
        };
        let collision = |obstacle: String| Collision {
            what,
            pose: k,
            fragment: pose.fragment,
            obstacle,
        };
        // Welded so far: every path whose arc went off before this move.
        let done = offs.iter().filter(|&&off| off < k).count();
        built.up_to(part, fragments, done);
        let ((a, ra), (b, mut rb)) = (in_part(k - 1), in_part(k));
        // The same rotation on the near side of the quaternion sphere: slerp turns the
        // short way.
        if ra.coords.dot(&rb.coords) < 0.0 {
            rb = UnitQuaternion::new_unchecked(-rb.into_inner());
        }
        if a.z.min(b.z) < built.plate_z - TOUCH_MM {
            return Err(collision("the plate".into()));
        }
        let welded = fragments[..done.min(fragments.len())].iter().flatten();
        if let Some(hit) = built.tcp_enters(part, welded.copied(), &a, &b) {
            return Err(collision(hit));
        }
        if cylinders.is_empty() {
            continue;
        }
        // Samples: the TCP on the straight line, the orientation turning at a constant
        // rate (as the toolpath interpolates), no torch point moving more than SAMPLE_MM.
        let sweep = (b - a).norm() + ra.angle_to(&rb) * lever;
        let n = (sweep / SAMPLE_MM).ceil().max(1.0) as usize;
        for i in 0..=n {
            let t = i as f64 / n as f64;
            let tcp = a + (b - a) * t;
            // Half a turn has no one shortest way (the toolpath turns by max_step_deg at
            // most between poses, so it does not occur): keep the start's orientation.
            let rot = ra.try_slerp(&rb, t, 1e-12).unwrap_or(ra);
            if let Some(hit) = torch_hit(part, &built, &cylinders, &tcp, &rot, 0.5 * SAMPLE_MM) {
                return Err(collision(hit));
            }
        }
    }
    Ok(())
}

/// What is welded so far: blocks by grid position, or a graph part's beads.
struct Built {
    fragments: usize,
    blocks: FxHashSet<Block>,
    /// The highest layer built (None: nothing yet).
    top: Option<i64>,
    /// z of the plate's top in the part frame, mm (a graph part's `base_z_mm`).
    plate_z: f64,
    /// A graph part's beads welded so far.
    beads: Option<Beads>,
}

impl Built {
    fn new(part: &Part) -> Built {
        Built {
            fragments: 0,
            blocks: FxHashSet::default(),
            top: None,
            plate_z: part.bead_part().map_or(0.0, |b| b.base_z_mm),
            beads: part.bead_part().map(|_| Beads::default()),
        }
    }

    /// Adds the blocks (nodes) of the first `done` fragments.
    fn up_to(&mut self, part: &Part, fragments: &[Vec<usize>], done: usize) {
        let done = done.min(fragments.len());
        for f in &fragments[self.fragments.min(done)..done] {
            for &b in f {
                match (&mut self.beads, part.bead_part()) {
                    (Some(beads), Some(graph)) => beads.add(graph, b),
                    _ => {
                        let block = part.block(b);
                        self.top = self.top.max(Some(block[2]));
                        self.blocks.insert(block);
                    }
                }
            }
        }
        self.fragments = self.fragments.max(done);
    }

    /// What the TCP's straight line from `a` to `b` enters ("block [x,y,z]" of the
    /// `welded` blocks, first in weld order; "node 12").
    fn tcp_enters(
        &self,
        part: &Part,
        mut welded: impl Iterator<Item = usize>,
        a: &Point3<f64>,
        b: &Point3<f64>,
    ) -> Option<String> {
        if let Some(beads) = &self.beads {
            let (lo, hi) = (a.coords.inf(&b.coords), a.coords.sup(&b.coords));
            return beads
                .near([lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z])
                .find(|q| {
                    let (a, b) = (q.local(a), q.local(b));
                    let (lo, hi) = q.shrunk(TOUCH_MM);
                    segment_enters_box(&a, &b, lo, hi)
                })
                .map(|q| format!("node {}", q.node));
        }
        let half = part.block_mm.map(|v| 0.5 * v - TOUCH_MM);
        welded.find_map(|i| {
            let block = part.block(i);
            let c = part.centre_mm(block);
            let lo = [c[0] - half[0], c[1] - half[1], c[2] - half[2]];
            let hi = [c[0] + half[0], c[1] + half[1], c[2] + half[2]];
            segment_enters_box(a, b, lo, hi).then(|| format!("block {}", BlockDisplay(block)))
        })
    }
}

/// A graph part's beads welded so far, as boxes along their centre lines (one per segment
/// of a node's piece: the segment widened to W, from the layer's bottom to its top),
/// looked up by a grid of [`BEAD_CELL_MM`] cells.
#[derive(Default)]
struct Beads {
    boxes: Vec<BeadBox>,
    grid: rustc_hash::FxHashMap<(i64, i64), Vec<u32>>,
    /// The highest top of a bead built (−∞: nothing yet).
    top: Option<f64>,
}

/// The side of the cells [`Beads`] are looked up by, mm.
const BEAD_CELL_MM: f64 = 20.0;

/// One segment of a bead as a box in its own frame: x along the segment from `origin`,
/// y across it, z up (part frame, mm).
struct BeadBox {
    node: usize,
    origin: [f64; 2],
    dir: [f64; 2],
    len: f64,
    half_w: f64,
    z: [f64; 2],
}

impl BeadBox {
    /// A point of the part frame in the box's frame.
    fn local(&self, p: &Point3<f64>) -> Point3<f64> {
        let (dx, dy) = (p.x - self.origin[0], p.y - self.origin[1]);
        let [c, s] = self.dir;
        Point3::new(dx * c + dy * s, -dx * s + dy * c, p.z)
    }

    /// A direction of the part frame in the box's frame.
    fn local_dir(&self, v: &Vector3<f64>) -> Vector3<f64> {
        let [c, s] = self.dir;
        Vector3::new(v.x * c + v.y * s, -v.x * s + v.y * c, v.z)
    }

    /// The box, shrunk by `by` on every side (`by` < 0: grown).
    fn shrunk(&self, by: f64) -> ([f64; 3], [f64; 3]) {
        (
            [by, -self.half_w + by, self.z[0] + by],
            [self.len - by, self.half_w - by, self.z[1] - by],
        )
    }
}

impl Beads {
    fn add(&mut self, part: &waam_part::BeadPart, node: usize) {
        let d = &part.nodes[node];
        let [w, h] = part.bead_mm;
        let z0 = part.base_z_mm + d.layer as f64 * h;
        let piece = part.beads[d.bead].piece_mm(d.from_mm, d.to_mm);
        self.top = Some(self.top.map_or(z0 + h, |t| t.max(z0 + h)));
        for seg in piece.windows(2) {
            let (p, q) = (seg[0], seg[1]);
            let len = (q[0] - p[0]).hypot(q[1] - p[1]);
            if len < 1e-9 {
                continue;
            }
            let i = self.boxes.len() as u32;
            let bb = BeadBox {
                node,
                origin: p,
                dir: [(q[0] - p[0]) / len, (q[1] - p[1]) / len],
                len,
                half_w: 0.5 * w,
                z: [z0, z0 + h],
            };
            let r = 0.5 * w;
            let (x0, x1) = (p[0].min(q[0]) - r, p[0].max(q[0]) + r);
            let (y0, y1) = (p[1].min(q[1]) - r, p[1].max(q[1]) + r);
            for cx in cell(x0)..=cell(x1) {
                for cy in cell(y0)..=cell(y1) {
                    self.grid.entry((cx, cy)).or_default().push(i);
                }
            }
            self.boxes.push(bb);
        }
    }

    /// The boxes whose cells meet the box `lo`–`hi` and that reach up to `lo.z`, each
    /// once.
    fn near(&self, lo: [f64; 3], hi: [f64; 3]) -> impl Iterator<Item = &BeadBox> {
        let mut found: Vec<u32> = Vec::new();
        if self.top.is_some_and(|t| lo[2] < t) {
            for cx in cell(lo[0])..=cell(hi[0]) {
                for cy in cell(lo[1])..=cell(hi[1]) {
                    found.extend(self.grid.get(&(cx, cy)).into_iter().flatten());
                }
            }
        }
        found.sort_unstable();
        found.dedup();
        found
            .into_iter()
            .map(|i| &self.boxes[i as usize])
            .filter(move |b| b.z[1] > lo[2] && b.z[0] < hi[2])
    }
}

/// The grid cell of a coordinate, mm.
fn cell(v: f64) -> i64 {
    (v / BEAD_CELL_MM).floor() as i64
}

/// What the torch (its `cylinders`, each widened by `margin` mm around and at both ends)
/// meets with its TCP at `tcp` (part frame, mm) turned by `rot` (z: the wire, out of the
/// torch): "the plate" or "block [x,y,z] (the torch's nozzle)"; `None`: it is clear.
fn torch_hit(
    part: &Part,
    built: &Built,
    cylinders: &[Cylinder],
    tcp: &Point3<f64>,
    rot: &UnitQuaternion<f64>,
    margin: f64,
) -> Option<String> {
    let up = -(rot * Vector3::z());
    for (i, c) in cylinders.iter().enumerate() {
        let name = ["nozzle", "body", "wrist"]
            .get(i)
            .copied()
            .unwrap_or("torch");
        let from = tcp + up * (c.from_mm - margin);
        let len = c.to_mm - c.from_mm + 2.0 * margin;
        let r = c.radius_mm + margin;
        // The cylinder's bounding box, axis by axis: the ends, widened by r·sin of the
        // angle between the axis and that coordinate axis.
        let to = from + up * len;
        let bound = |d: usize| {
            let w = r * (1.0 - up[d] * up[d]).max(0.0).sqrt();
            (from[d].min(to[d]) - w, from[d].max(to[d]) + w)
        };
        if bound(2).0 < built.plate_z - TOUCH_MM {
            return Some(format!("the plate (the torch's {name})"));
        }
        if let Some(beads) = &built.beads {
            let lo: [f64; 3] = std::array::from_fn(|d| bound(d).0);
            let hi: [f64; 3] = std::array::from_fn(|d| bound(d).1);
            let hit = beads.near(lo, hi).find(|q| {
                let (blo, bhi) = q.shrunk(0.0);
                cylinder_meets_box(
                    &q.local(&from),
                    &q.local_dir(&up),
                    len,
                    r - TOUCH_MM,
                    blo,
                    bhi,
                )
            });
            if let Some(q) = hit {
                return Some(format!("node {} (the torch's {name})", q.node));
            }
            continue;
        }
        let range = |d: usize| {
            let (lo, hi) = bound(d);
            let (o, p) = (part.origin_mm[d], part.block_mm[d]);
            (((lo - o) / p).floor() as i64, ((hi - o) / p).floor() as i64)
        };
        let (rx, ry, rz) = (range(0), range(1), range(2));
        if built.top.is_none_or(|top| rz.0 > top) {
            continue; // above everything built (a transit at safe height)
        }
        // Few blocks stand near a torch at safe height: look them up only when the box
        // holds fewer cells than there are blocks.
        let cells = [rx, ry, rz]
            .iter()
            .map(|&(lo, hi)| (hi - lo + 1).max(0) as u128)
            .product::<u128>();
        let candidates: Vec<Block> = if cells <= built.blocks.len() as u128 {
            let mut v = Vec::new();
            for x in rx.0..=rx.1 {
                for y in ry.0..=ry.1 {
                    for z in rz.0..=rz.1 {
                        if built.blocks.contains(&[x, y, z]) {
                            v.push([x, y, z]);
                        }
                    }
                }
            }
            v
        } else {
            let inside = |b: &Block| {
                (rx.0..=rx.1).contains(&b[0])
                    && (ry.0..=ry.1).contains(&b[1])
                    && (rz.0..=rz.1).contains(&b[2])
            };
            built.blocks.iter().copied().filter(inside).collect()
        };
        for block in candidates {
            let centre = part.centre_mm(block);
            let lo: [f64; 3] = std::array::from_fn(|d| centre[d] - 0.5 * part.block_mm[d]);
            let hi: [f64; 3] = std::array::from_fn(|d| centre[d] + 0.5 * part.block_mm[d]);
            if cylinder_meets_box(&from, &up, len, r - TOUCH_MM, lo, hi) {
                return Some(format!(
                    "block {} (the torch's {name})",
                    BlockDisplay(block)
                ));
            }
        }
    }
    None
}

/// Whether the solid cylinder from `base` along the unit `axis` for `len`, of radius `r`,
/// overlaps the box `lo`–`hi`. Exact: the box cut to the slab between the cylinder's end
/// planes is a convex polytope (its corners: the box's corners inside the slab and its
/// edges' crossings of the two planes); it meets the cylinder exactly when its shadow on
/// the plane across the axis comes within `r` of the axis.
pub fn cylinder_meets_box(
    base: &Point3<f64>,
    axis: &Vector3<f64>,
    len: f64,
    r: f64,
    lo: [f64; 3],
    hi: [f64; 3],
) -> bool {
    // A frame across the axis.
    let helper = if axis.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = axis.cross(&helper).normalize();
    let v = axis.cross(&u);
    let corner = |i: usize| -> Vector3<f64> {
        let p = Vector3::new(
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ) - base.coords;
        Vector3::new(p.dot(&u), p.dot(&v), p.dot(axis))
    };
    let corners: Vec<Vector3<f64>> = (0..8).map(corner).collect();
    let mut shadow: Vec<[f64; 2]> = Vec::new();
    for c in &corners {
        if (0.0..=len).contains(&c.z) {
            shadow.push([c.x, c.y]);
        }
    }
    // The box's 12 edges join corners that differ in one bit.
    for i in 0..8 {
        for bit in [1, 2, 4] {
            let j = i | bit;
            if j == i {
                continue;
            }
            let (p, q) = (corners[i], corners[j]);
            for plane in [0.0, len] {
                if (p.z - plane) * (q.z - plane) < 0.0 {
                    let t = (plane - p.z) / (q.z - p.z);
                    let x = p + (q - p) * t;
                    shadow.push([x.x, x.y]);
                }
            }
        }
    }
    if shadow.is_empty() {
        return false;
    }
    distance_to_hull(&shadow) < r
}

/// Distance from the origin to the convex hull of `points` (0 inside it).
fn distance_to_hull(points: &[[f64; 2]]) -> f64 {
    let mut pts = points.to_vec();
    pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    pts.dedup();
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    // Andrew's monotone chain, counter-clockwise.
    let mut hull: Vec<[f64; 2]> = Vec::new();
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    if hull.is_empty() {
        hull.push(pts[0]);
    }
    let seg = |a: [f64; 2], b: [f64; 2]| {
        let d = [b[0] - a[0], b[1] - a[1]];
        let l2 = d[0] * d[0] + d[1] * d[1];
        let t = if l2 > 0.0 {
            (-(a[0] * d[0] + a[1] * d[1]) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (a[0] + t * d[0]).hypot(a[1] + t * d[1])
    };
    let n = hull.len();
    if n >= 3 && (0..n).all(|i| cross(hull[i], hull[(i + 1) % n], [0.0, 0.0]) >= 0.0) {
        return 0.0;
    }
    (0..n)
        .map(|i| seg(hull[i], hull[(i + 1) % n]))
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cylinder_meets_a_box_exactly_when_it_overlaps_it() {
        let (lo, hi) = ([0.0; 3], [1.0; 3]);
        let up = Vector3::z();
        let p = Point3::new;
        // Beside the box: clear until the radius reaches its face.
        assert!(!cylinder_meets_box(
            &p(2.0, 0.5, 0.0),
            &up,
            1.0,
            0.99,
            lo,
            hi
        ));
        assert!(cylinder_meets_box(
            &p(2.0, 0.5, 0.0),
            &up,
            1.0,
            1.01,
            lo,
            hi
        ));
        // Above the box: the flat end does not reach down, however wide.
        assert!(!cylinder_meets_box(
            &p(0.5, 0.5, 1.01),
            &up,
            5.0,
            50.0,
            lo,
            hi
        ));
        assert!(cylinder_meets_box(
            &p(0.5, 0.5, 0.99),
            &up,
            5.0,
            0.1,
            lo,
            hi
        ));
        // Off a corner, diagonally: the corner is at √2·0.5 from the axis through (1.5, 1.5).
        assert!(!cylinder_meets_box(
            &p(1.5, 1.5, 0.0),
            &up,
            1.0,
            0.70,
            lo,
            hi
        ));
        assert!(cylinder_meets_box(
            &p(1.5, 1.5, 0.0),
            &up,
            1.0,
            0.72,
            lo,
            hi
        ));
        // Tilted 45° past the box's top edge (x = 1, z = 1), the axis 0.1 from it.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let d = Vector3::new(h, 0.0, -h);
        let base = p(1.0 + 0.1 * h - 2.0 * h, 0.5, 1.0 + 0.1 * h + 2.0 * h);
        assert!(!cylinder_meets_box(&base, &d, 10.0, 0.05, lo, hi));
        assert!(cylinder_meets_box(&base, &d, 10.0, 0.2, lo, hi));
        // A box wholly inside a wide cylinder.
        assert!(cylinder_meets_box(
            &p(0.5, 0.5, -1.0),
            &up,
            3.0,
            10.0,
            lo,
            hi
        ));
    }

    #[test]
    fn the_slab_test_sees_crossings_and_not_touches() {
        let (lo, hi) = ([0.0; 3], [1.0; 3]);
        let p = |x, y, z| Point3::new(x, y, z);
        assert!(segment_enters_box(
            &p(-1.0, 0.5, 0.5),
            &p(2.0, 0.5, 0.5),
            lo,
            hi
        ));
        assert!(segment_enters_box(
            &p(0.5, 0.5, 0.5),
            &p(0.5, 0.5, 0.6),
            lo,
            hi
        ));
        assert!(!segment_enters_box(
            &p(-1.0, 0.5, 1.0),
            &p(2.0, 0.5, 1.0),
            lo,
            hi
        ));
        assert!(!segment_enters_box(
            &p(-1.0, 0.5, 2.0),
            &p(2.0, 0.5, 1.5),
            lo,
            hi
        ));
        assert!(!segment_enters_box(
            &p(-1.0, -1.0, 0.5),
            &p(-0.1, 2.0, 0.5),
            lo,
            hi
        ));
    }
}
