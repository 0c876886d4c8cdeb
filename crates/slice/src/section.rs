//! The section of a triangle mesh by a horizontal plane, as polygons with holes.
//!
//! Planes through vertices, edges and faces are decided by one symbolic rule: a vertex
//! with z >= the plane counts as above. So every triangle gives 0 or 1 segment (a face in
//! the plane gives none), every segment runs between two edges that cross the plane, and
//! an edge's crossing point is computed from its two vertices in one canonical order
//! (below, then above): both triangles of an edge get the bit-identical point. Segments are
//! chained by the crossing edge they share (exact keys, no tolerance), so a closed manifold
//! mesh gives closed loops whatever the plane meets; chains left open (small gaps of CAD
//! exports) are joined end to start within a tolerance. Segments are oriented with the
//! solid on their left (outward normals), and the loops are resolved into polygons with
//! holes by a non-zero union, which also merges overlapping shells.

use rustc_hash::FxHashMap;

use waam_mesh::TriangleMesh;

use crate::poly::{self, from64, to64};
use crate::SliceError;
use clipper2_rust::Paths64;

/// A polygon with holes, millimetres: the outer boundary counter-clockwise, holes clockwise.
#[derive(Debug, Clone, PartialEq)]
pub struct Polygon {
    pub outer: Vec<[f64; 2]>,
    pub holes: Vec<Vec<[f64; 2]>>,
}

impl Polygon {
    /// Area in mm² (outer minus holes).
    pub fn area_mm2(&self) -> f64 {
        let a = |p: &[[f64; 2]]| {
            let n = p.len();
            (0..n)
                .map(|i| {
                    let (u, v) = (p[i], p[(i + 1) % n]);
                    u[0] * v[1] - v[0] * u[1]
                })
                .sum::<f64>()
                / 2.0
        };
        a(&self.outer).abs() - self.holes.iter().map(|h| a(h).abs()).sum::<f64>()
    }
}

/// The section of `mesh` at height `z_mm`: polygons with holes. Open chains whose ends are
/// at most `join_mm` apart are joined; a chain that stays open is an error naming the
/// height and the place.
pub fn section(mesh: &TriangleMesh, z_mm: f64, join_mm: f64) -> Result<Vec<Polygon>, SliceError> {
    let paths = section_paths(mesh, z_mm, join_mm)?;
    Ok(poly::regions(&paths)
        .into_iter()
        .map(|r| {
            let mut loops = r.iter().map(from64);
            Polygon {
                outer: loops.next().unwrap_or_default(),
                holes: loops.collect(),
            }
        })
        .collect())
}

/// A segment from the crossing of edge `from` to the crossing of edge `to`.
struct Segment {
    from: (u32, u32),
    to: (u32, u32),
    a: [f64; 2],
    b: [f64; 2],
}

/// The section as clipper paths (union of the loops, non-zero fill).
pub(crate) fn section_paths(
    mesh: &TriangleMesh,
    z: f64,
    join_mm: f64,
) -> Result<Paths64, SliceError> {
    let paths: Paths64 = section_loops(mesh, z, join_mm)?
        .iter()
        .map(|l| to64(l))
        .filter(|p| p.len() >= 3)
        .collect();
    let union = poly::union(&paths);
    if join_mm <= 0.0 {
        return Ok(union);
    }
    // Bodies that share a face (a tube against a tube, an assembly in one STL) cut it into
    // two loops that agree only to the 0.1 µm grid: their union keeps slivers between
    // them, holes far thinner than a micrometre that the fill would ring with beads (two
    // tubes side by side: 19 beads, 89 % covered). Closing by join_mm / 2 removes gaps up
    // to join_mm, as open contours that close are joined. A section it leaves with as
    // many loops is kept as it was (the closing would move where its loops start, and so
    // where every bead is cut into nodes).
    let closed = poly::offset(&poly::offset(&union, 0.5 * join_mm), -0.5 * join_mm);
    Ok(if closed.len() == union.len() {
        union
    } else {
        closed
    })
}

/// The section of `mesh` at height `z` as the closed loops the mesh cuts, before any union:
/// the solid on the left of each loop (outer boundaries counter-clockwise, holes
/// clockwise), the crossing points exact in `f64` (not on clipper's 0.1 µm grid), collinear
/// and repeated points kept. Open chains are joined within `join_mm`, else an error names
/// the place. [`section`] is these loops resolved into polygons; the thick-wall slicer
/// (`waam-layer`) measures its walls on them.
pub fn section_loops(
    mesh: &TriangleMesh,
    z: f64,
    join_mm: f64,
) -> Result<Vec<Vec<[f64; 2]>>, SliceError> {
    let v = &mesh.vertices;
    let above = |i: u32| v[i as usize][2] >= z;
    // The crossing of the edge between a vertex below and one above, in that order.
    let cross = |lo: u32, hi: u32| -> ((u32, u32), [f64; 2]) {
        let (p, q) = (v[lo as usize], v[hi as usize]);
        let t = (z - p[2]) / (q[2] - p[2]);
        (
            (lo, hi),
            [p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])],
        )
    };
    let mut segments = Vec::new();
    for tri in &mesh.triangles {
        let up = tri.map(above);
        let odd = match up {
            [a, b, c] if a == b && b == c => continue,
            [a, b, _] if a == b => 2,
            [a, _, c] if a == c => 1,
            _ => 0,
        };
        let (a, b, c) = (tri[odd], tri[(odd + 1) % 3], tri[(odd + 2) % 3]);
        let edge = |x: u32, y: u32| if above(x) { cross(y, x) } else { cross(x, y) };
        // Walking a, b, c (counter-clockwise seen from outside): with `a` alone above the
        // plane, the solid lies left of the crossing on ab -> the crossing on ca.
        let (p, q) = (edge(a, b), edge(c, a));
        let ((from, pa), (to, pb)) = if up[odd] { (p, q) } else { (q, p) };
        segments.push(Segment {
            from,
            to,
            a: pa,
            b: pb,
        });
    }
    chain(&segments, z, join_mm)
}

/// Segments chained into closed loops of points.
fn chain(segments: &[Segment], z: f64, join_mm: f64) -> Result<Vec<Vec<[f64; 2]>>, SliceError> {
    const NONE: usize = usize::MAX;
    let mut starting: FxHashMap<(u32, u32), usize> = FxHashMap::default();
    for (i, s) in segments.iter().enumerate() {
        // A second segment leaving the same edge (non-manifold) starts a chain of its own.
        starting.entry(s.from).or_insert(i);
    }
    let mut next = vec![NONE; segments.len()];
    let mut has_prev = vec![false; segments.len()];
    for (i, s) in segments.iter().enumerate() {
        if let Some(&j) = starting.get(&s.to) {
            if !has_prev[j] {
                next[i] = j;
                has_prev[j] = true;
            }
        }
    }
    let mut used = vec![false; segments.len()];
    let mut loops = Vec::new();
    let mut open: Vec<Vec<[f64; 2]>> = Vec::new();
    // Open chains first (from their heads), then what is left lies on cycles.
    let heads: Vec<usize> = (0..segments.len()).filter(|&i| !has_prev[i]).collect();
    for start in heads.into_iter().chain(0..segments.len()) {
        if used[start] {
            continue;
        }
        let mut pts = vec![segments[start].a];
        let mut i = start;
        let closed = loop {
            used[i] = true;
            pts.push(segments[i].b);
            match next[i] {
                NONE => break false,
                j if j == start => break true,
                j if used[j] => break false,
                j => i = j,
            }
        };
        if closed {
            pts.pop();
            loops.push(pts);
        } else {
            open.push(pts);
        }
    }
    join_open(open, &mut loops, z, join_mm)?;
    Ok(loops)
}

/// Joins open chains end to start (nearest first) within `join_mm`; closes a chain whose
/// end comes back near its start.
fn join_open(
    mut open: Vec<Vec<[f64; 2]>>,
    loops: &mut Vec<Vec<[f64; 2]>>,
    z: f64,
    join_mm: f64,
) -> Result<(), SliceError> {
    let dist = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    while let Some(mut chain) = open.pop() {
        loop {
            let end = *chain.last().expect("a chain has points");
            let to_self = dist(end, chain[0]);
            let best = open
                .iter()
                .enumerate()
                .map(|(k, c)| (dist(end, c[0]), k))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            match best {
                Some((d, k)) if d <= join_mm && d < to_self => {
                    let more = open.swap_remove(k);
                    chain.extend(more);
                }
                _ if to_self <= join_mm => {
                    loops.push(chain);
                    break;
                }
                _ => {
                    let gap = best.map_or(to_self, |(d, _)| d.min(to_self));
                    return Err(SliceError::Open {
                        z_mm: z,
                        at: end,
                        gap_mm: gap,
                    });
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes as testmesh;

    #[test]
    fn planes_through_vertices_edges_and_faces_of_a_voxel_mesh_give_the_right_polygon() {
        // An L of unit voxels (3 x 2 at the bottom, 1 x 2 on top of its left end), all
        // faces split into unit squares: the planes z = 1 and z = 2 run through vertices,
        // edges and whole faces.
        let mesh = testmesh::voxels(&[
            [0, 0, 0],
            [1, 0, 0],
            [2, 0, 0],
            [0, 1, 0],
            [1, 1, 0],
            [2, 1, 0],
            [0, 0, 1],
            [0, 1, 1],
        ]);
        for (z, area) in [(0.5, 6.0), (1.0, 6.0), (1.5, 2.0), (2.0, 2.0)] {
            let s = section(&mesh, z, 0.0).unwrap();
            assert_eq!(s.len(), 1, "z = {z}: {s:?}");
            assert!((s[0].area_mm2() - area).abs() < 1e-9, "z = {z}: {s:?}");
            assert!(s[0].holes.is_empty());
        }
        // The rule puts a plane through a face on the face's lower side: at the bottom face
        // nothing is cut, at the top face the solid below it is.
        assert!(section(&mesh, 0.0, 0.0).unwrap().is_empty());
        assert!(section(&mesh, 2.5, 0.0).unwrap().is_empty());
        // A ring of voxels around a hole, cut through its vertices.
        let mut ring = Vec::new();
        for x in 0..3 {
            for y in 0..3 {
                if (x, y) != (1, 1) {
                    ring.push([x, y, 0]);
                }
            }
        }
        let s = section(&testmesh::voxels(&ring), 1.0, 0.0).unwrap();
        assert_eq!((s.len(), s[0].holes.len()), (1, 1), "{s:?}");
        assert!((s[0].area_mm2() - 8.0).abs() < 1e-9);
    }

    #[test]
    fn small_gaps_are_joined_and_large_ones_named() {
        let mut mesh = testmesh::ring(10.0, 16.0, 5.0, 48);
        // Drop one outer wall triangle: the outer loop opens at z = 2.5.
        let gone = mesh
            .triangles
            .iter()
            .position(|t| {
                let r = |i: u32| mesh.vertices[i as usize][0].hypot(mesh.vertices[i as usize][1]);
                t.iter().all(|&i| (r(i) - 16.0).abs() < 1e-9)
            })
            .unwrap();
        mesh.triangles.remove(gone);
        let e = section(&mesh, 2.5, 0.01).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("section at z = 2.5 mm: a contour stays open near"),
            "{e}"
        );
        assert_eq!(section(&mesh, 2.5, 5.0).unwrap().len(), 1);
    }
}
