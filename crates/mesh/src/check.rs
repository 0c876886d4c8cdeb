//! Building a [`TriangleMesh`] (vertices shared by exact coordinates) and checking that
//! it bounds a solid: every edge in exactly two triangles, run in opposite directions.

use std::collections::HashMap;

use robust::{orient2d, Coord};

use super::{MeshError, TriangleMesh, Units, MAX_COORD_MM};

/// Hash key of a coordinate: its bits, with -0.0 and 0.0 the same point.
fn key(v: [f64; 3]) -> [u64; 3] {
    v.map(|c| if c == 0.0 { 0 } else { c.to_bits() })
}

fn check_point(triangle: usize, v: [f64; 3]) -> Result<(), MeshError> {
    if v.iter().any(|c| !c.is_finite()) {
        return Err(MeshError::NonFinite {
            triangle,
            vertex: v,
        });
    }
    if v.iter().any(|c| c.abs() > MAX_COORD_MM) {
        return Err(MeshError::OutOfRange {
            triangle,
            vertex: v,
        });
    }
    Ok(())
}

impl TriangleMesh {
    /// A mesh from separate triangles (mm); corners at equal coordinates become one vertex.
    pub fn from_soup(triangles: &[[[f64; 3]; 3]]) -> Result<TriangleMesh, MeshError> {
        let mut mesh = TriangleMesh::default();
        let mut index: HashMap<[u64; 3], u32> = HashMap::new();
        for (t, corners) in triangles.iter().enumerate() {
            let mut tri = [0u32; 3];
            for (c, &v) in corners.iter().enumerate() {
                check_point(t + 1, v)?;
                tri[c] = *index.entry(key(v)).or_insert_with(|| {
                    mesh.vertices.push(v);
                    (mesh.vertices.len() - 1) as u32
                });
            }
            mesh.triangles.push(tri);
        }
        Ok(mesh)
    }

    /// A mesh from vertices and triangles of vertex indices in `units` (e.g. a ROS
    /// `shape_msgs/Mesh` in metres). Duplicated vertices are merged by coordinates.
    pub fn from_indexed(
        vertices: &[[f64; 3]],
        triangles: &[[u32; 3]],
        units: Units,
    ) -> Result<TriangleMesh, MeshError> {
        let scale = units.to_mm();
        let mut soup = Vec::with_capacity(triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            let mut corners = [[0.0; 3]; 3];
            for (c, &i) in tri.iter().enumerate() {
                let v = vertices.get(i as usize).ok_or(MeshError::BadIndex {
                    triangle: t + 1,
                    index: i,
                    vertices: vertices.len(),
                })?;
                corners[c] = v.map(|x| x * scale);
            }
            soup.push(corners);
        }
        TriangleMesh::from_soup(&soup)
    }

    /// Min and max corner of the vertices (the mesh must have at least one vertex).
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for v in &self.vertices {
            for d in 0..3 {
                lo[d] = lo[d].min(v[d]);
                hi[d] = hi[d].max(v[d]);
            }
        }
        (lo, hi)
    }

    /// The corners of triangle `t` (0-based).
    pub fn corners(&self, t: usize) -> [[f64; 3]; 3] {
        self.triangles[t].map(|i| self.vertices[i as usize])
    }

    /// Checks that the mesh bounds a solid: finite in-range coordinates, no triangle of
    /// zero area, every edge shared by exactly two triangles that run it in opposite
    /// directions. The first problem found is the error (triangles numbered from 1).
    pub fn check(&self) -> Result<(), MeshError> {
        if self.triangles.is_empty() {
            return Err(MeshError::Empty);
        }
        for t in 0..self.triangles.len() {
            for &i in &self.triangles[t] {
                if i as usize >= self.vertices.len() {
                    return Err(MeshError::BadIndex {
                        triangle: t + 1,
                        index: i,
                        vertices: self.vertices.len(),
                    });
                }
                check_point(t + 1, self.vertices[i as usize])?;
            }
            let corners = self.corners(t);
            if zero_area(corners) {
                return Err(MeshError::Degenerate {
                    triangle: t + 1,
                    corners,
                });
            }
        }
        self.check_edges()
    }

    fn check_edges(&self) -> Result<(), MeshError> {
        // Undirected edge (low, high) -> triangles running it low -> high, and high -> low.
        let mut edges: HashMap<(u32, u32), (Vec<u32>, Vec<u32>)> = HashMap::new();
        for (t, tri) in self.triangles.iter().enumerate() {
            for c in 0..3 {
                let (a, b) = (tri[c], tri[(c + 1) % 3]);
                let entry = edges.entry((a.min(b), a.max(b))).or_default();
                if a < b { &mut entry.0 } else { &mut entry.1 }.push(t as u32);
            }
        }
        let point = |i: u32| self.vertices[i as usize];
        // Each kind of problem is reported at the edge of the lowest triangle: deterministic.
        let mut open = Vec::new();
        let mut crowded = Vec::new();
        let mut flipped = Vec::new();
        for (&(a, b), (up, down)) in &edges {
            let first = up.iter().chain(down).min().copied().unwrap_or(0);
            match (up.len(), down.len()) {
                (1, 1) => {}
                (u, d) if u + d == 1 => open.push((first, a, b)),
                (u, d) if u + d > 2 => crowded.push((first, a, b, u + d)),
                _ => {
                    let pair = if up.len() == 2 { up } else { down };
                    flipped.push((pair[0].min(pair[1]), a, b, pair[0].max(pair[1])));
                }
            }
        }
        if let Some(&(t, a, b)) = open.iter().min() {
            return Err(MeshError::Open {
                count: open.len(),
                a: point(a),
                b: point(b),
                triangle: t as usize + 1,
            });
        }
        if let Some(&(_, a, b, uses)) = crowded.iter().min() {
            return Err(MeshError::NonManifold {
                count: crowded.len(),
                a: point(a),
                b: point(b),
                uses,
            });
        }
        if let Some(&(first, a, b, second)) = flipped.iter().min() {
            return Err(MeshError::Flipped {
                count: flipped.len(),
                a: point(a),
                b: point(b),
                first: first as usize + 1,
                second: second as usize + 1,
            });
        }
        Ok(())
    }
}

/// Whether a triangle has zero area (exactly: all three coordinate projections collinear).
pub(super) fn zero_area(c: [[f64; 3]; 3]) -> bool {
    (0..3).all(|d| {
        let (u, v) = (d, (d + 1) % 3);
        let p = |i: usize| Coord {
            x: c[i][u],
            y: c[i][v],
        };
        orient2d(p(0), p(1), p(2)) == 0.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit tetrahedron, outward counter-clockwise.
    fn tetra() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let v = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        (v, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    }

    fn check(v: &[[f64; 3]], t: &[[u32; 3]]) -> Result<(), MeshError> {
        TriangleMesh::from_indexed(v, t, Units::Mm)?.check()
    }

    #[test]
    fn a_closed_tetrahedron_passes() {
        let (v, t) = tetra();
        check(&v, &t).unwrap();
    }

    #[test]
    fn each_defect_is_named() {
        let (v, t) = tetra();
        let e = check(&v, &t[..3]).unwrap_err().to_string();
        assert_eq!(
            e,
            "open mesh: 3 boundary edge(s), first between vertex (0, 1, 0) and (1, 0, 0) (triangle 1)"
        );
        let mut flipped = t.clone();
        flipped[3] = [1, 3, 2];
        let e = check(&v, &flipped).unwrap_err().to_string();
        assert!(
            e.starts_with("inconsistently oriented mesh: 3 edge(s) run the same way")
                && e.contains("(triangles 1 and 4: one of them is flipped)"),
            "{e}"
        );
        let mut doubled = t.clone();
        doubled.extend([[0, 1, 2], [0, 2, 1]]);
        let e = check(&v, &doubled).unwrap_err().to_string();
        assert!(
            e.starts_with("non-manifold mesh: 3 edge(s) shared by more than two"),
            "{e}"
        );
        let e = check(&v, &[[0, 1, 9]]).unwrap_err().to_string();
        assert_eq!(
            e,
            "triangle 1: vertex index 9 is out of range (the mesh has 4 vertices)"
        );
        let e = check(&[[0.0; 3], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]], &[[0, 1, 2]])
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "degenerate triangle 1: its corners (0, 0, 0), (1, 1, 1), (2, 2, 2) have zero area"
        );
        let e = check(&[[0.0; 3], [1e12, 0.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2]])
            .unwrap_err()
            .to_string();
        assert!(e.contains("out of range"), "{e}");
        assert_eq!(TriangleMesh::default().check(), Err(MeshError::Empty));
    }

    #[test]
    fn negative_zero_is_zero() {
        let (mut v, t) = tetra();
        // Duplicate vertex 0 as -0.0 and use it in one triangle: still closed.
        v.push([-0.0, 0.0, -0.0]);
        let mut t2 = t.clone();
        t2[0] = [4, 2, 1];
        check(&v, &t2).unwrap();
    }
}
