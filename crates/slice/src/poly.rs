//! Thin wrappers over `clipper2-rust`: millimetres in, integer coordinates inside.
//!
//! Clipper works exactly on integers; 10^4 units per mm (0.1 µm) leaves ample headroom
//! (coordinates up to 10^6 mm are 10^10 units) and is far below any weld tolerance.

use clipper2_rust::{
    area, inflate_paths_64, simplify_path, ClipType, Clipper64, EndType, FillRule, JoinType,
    Path64, Paths64, Point64, PolyTree64,
};

/// Integer units per millimetre.
pub const SCALE: f64 = 1.0e4;

pub fn to64(points: &[[f64; 2]]) -> Path64 {
    points
        .iter()
        .map(|p| Point64::new((p[0] * SCALE).round() as i64, (p[1] * SCALE).round() as i64))
        .collect()
}

pub fn from64(path: &Path64) -> Vec<[f64; 2]> {
    path.iter()
        .map(|p| [p.x as f64 / SCALE, p.y as f64 / SCALE])
        .collect()
}

/// Round joins within 0.002 mm of the true arc.
const ARC_TOLERANCE: f64 = 0.002 * SCALE;

/// Closed regions grown (`delta_mm` > 0) or eroded (< 0) with round joins.
pub fn offset(paths: &Paths64, delta_mm: f64) -> Paths64 {
    inflate_paths_64(
        paths,
        delta_mm * SCALE,
        JoinType::Round,
        EndType::Polygon,
        2.0,
        ARC_TOLERANCE,
    )
}

/// Centre lines buffered by `radius_mm` on both sides: closed ones as rings, open ones
/// with round ends.
pub fn buffer_lines(closed: &Paths64, open: &Paths64, radius_mm: f64) -> Paths64 {
    let mut out = inflate_paths_64(
        closed,
        radius_mm * SCALE,
        JoinType::Round,
        EndType::Joined,
        2.0,
        ARC_TOLERANCE,
    );
    out.extend(inflate_paths_64(
        open,
        radius_mm * SCALE,
        JoinType::Round,
        EndType::Round,
        2.0,
        ARC_TOLERANCE,
    ));
    union(&out)
}

fn run(subject: &Paths64, clip: &Paths64, op: ClipType) -> Paths64 {
    let mut c = Clipper64::new();
    c.add_subject(subject);
    if !clip.is_empty() {
        c.add_clip(clip);
    }
    let mut out = Paths64::new();
    c.execute(op, FillRule::NonZero, &mut out, None);
    out
}

/// The union of paths under the non-zero fill rule (overlaps merged, orientation resolved).
pub fn union(paths: &Paths64) -> Paths64 {
    run(paths, &Paths64::new(), ClipType::Union)
}

pub fn intersection(a: &Paths64, b: &Paths64) -> Paths64 {
    run(a, b, ClipType::Intersection)
}

pub fn difference(a: &Paths64, b: &Paths64) -> Paths64 {
    run(a, b, ClipType::Difference)
}

/// Open lines clipped to closed regions.
pub fn clip_lines(lines: &Paths64, regions: &Paths64) -> Paths64 {
    let mut c = Clipper64::new();
    c.add_open_subject(lines);
    c.add_clip(regions);
    let (mut closed, mut open) = (Paths64::new(), Paths64::new());
    c.execute(
        ClipType::Intersection,
        FillRule::NonZero,
        &mut closed,
        Some(&mut open),
    );
    open
}

/// Area in mm² of a set of regions (holes counted negative).
pub fn area_mm2(paths: &Paths64) -> f64 {
    paths.iter().map(area).sum::<f64>().abs() / (SCALE * SCALE)
}

/// The connected regions of a set of paths (union, non-zero): each its outer boundary
/// first, then its holes. An island inside a hole is a region of its own.
pub fn regions(paths: &Paths64) -> Vec<Paths64> {
    let mut c = Clipper64::new();
    c.add_subject(paths);
    let (mut tree, mut open) = (PolyTree64::new(), Paths64::new());
    c.execute_tree(ClipType::Union, FillRule::NonZero, &mut tree, &mut open);
    let mut out = Vec::new();
    let mut stack = vec![0usize];
    while let Some(i) = stack.pop() {
        for &child in tree.nodes[i].children() {
            if tree.is_hole(child) {
                stack.push(child);
            } else {
                let mut region = vec![tree.nodes[child].polygon().clone()];
                for &hole in tree.nodes[child].children() {
                    region.push(tree.nodes[hole].polygon().clone());
                    stack.push(hole);
                }
                out.push(region);
            }
        }
    }
    out
}

/// A path with vertices closer than `eps_mm` to the simplified line removed.
pub fn simplify(path: &Path64, eps_mm: f64, closed: bool) -> Path64 {
    simplify_path(path, eps_mm * SCALE, closed)
}
