//! Voxelization: a block belongs to the part when its centre lies inside the mesh.
//!
//! "Inside" is the winding number of the closed mesh around the centre, non-zero, counted
//! along a vertical ray: each triangle whose xy-projection holds the centre and that lies
//! above it adds the sign of its normal's z. The ray is cast per grid column, so the work
//! is one pass over the triangles plus one over the cells.
//!
//! Centres exactly on a face, edge or vertex are decided by symbolic perturbation: the
//! centre is taken as moved by (ε, ε², ε³) with ε → 0. Every predicate is evaluated
//! exactly (`robust`'s adaptive orient2d/orient3d) and a tie is broken by the perturbation,
//! so each centre gets one definite, deterministic answer, and two meshes that share a
//! face split the centres on it between them without loss or overlap.

use robust::{orient2d, orient3d, Coord, Coord3D};

use super::{MeshError, Point, TriangleMesh, Units, VoxelizeOptions};
use waam_part::{Block, BlockDisplay, Part};

/// A voxelized mesh.
#[derive(Debug, Clone)]
pub struct Voxelized {
    pub part: Part,
    /// Grid size in blocks along x, y, z.
    pub grid: [u64; 3],
    /// Triangles of the mesh.
    pub triangles: usize,
    /// Remarks (e.g. an inside-out mesh).
    pub warnings: Vec<String>,
}

/// Voxelizes an in-memory mesh given as vertices and triangles of vertex indices, in
/// `units` (the ROS node passes `shape_msgs/Mesh` in metres).
pub fn voxelize_indexed(
    vertices: &[[f64; 3]],
    triangles: &[[u32; 3]],
    units: Units,
    options: &VoxelizeOptions,
) -> Result<Voxelized, MeshError> {
    voxelize(
        &TriangleMesh::from_indexed(vertices, triangles, units)?,
        options,
    )
}

/// Checks the mesh ([`TriangleMesh::check`]) and turns it into a part: the blocks of the
/// grid (pitch `block_mm`, block (0,0,0) with its min corner at the origin) whose centres
/// lie inside the mesh.
pub fn voxelize(mesh: &TriangleMesh, options: &VoxelizeOptions) -> Result<Voxelized, MeshError> {
    mesh.check()?;
    let pitch = options.block_mm;
    if pitch.iter().any(|p| !p.is_finite() || *p <= 0.0) {
        return Err(MeshError::Pitch(format!(
            "entries must be finite and > 0, got {pitch:?}"
        )));
    }
    let (lo, hi) = mesh.bounds();
    let origin = options.origin_mm.unwrap_or(lo);
    for d in 0..3 {
        if !origin[d].is_finite() || origin[d] > lo[d] {
            return Err(MeshError::Pitch(format!(
                "the grid origin {} must be finite and at or below the mesh's min corner {} \
                 (blocks have no negative coordinates)",
                Point(origin),
                Point(lo)
            )));
        }
    }
    let counts: [f64; 3] =
        std::array::from_fn(|d| ((hi[d] - origin[d]) / pitch[d]).ceil().max(1.0));
    let cells = counts[0] * counts[1] * counts[2];
    if cells > options.max_cells as f64 {
        return Err(MeshError::TooLarge {
            grid: counts,
            cells,
            limit: options.max_cells,
        });
    }
    let grid = Grid {
        origin,
        pitch,
        n: counts.map(|c| c as usize),
    };
    let winding = grid.winding(mesh);
    let [nx, ny, nz] = grid.n;
    let mut blocks: Vec<Block> = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let column = &winding[(j * nx + i) * (nz + 1)..][..nz + 1];
            let mut w = 0;
            for (k, dw) in column[..nz].iter().enumerate() {
                w += dw;
                if w != 0 {
                    blocks.push([i as i64, j as i64, k as i64]);
                }
            }
        }
    }
    let grid_size = grid.n.map(|c| c as u64);
    if blocks.is_empty() {
        let [nx, ny, nz] = grid_size;
        return Err(MeshError::NoBlocks { nx, ny, nz });
    }
    let mut warnings = Vec::new();
    if signed_volume(mesh) < 0.0 {
        warnings.push(
            "the mesh is inside out (its triangles face inwards); voxelized all the same"
                .to_string(),
        );
    }
    let mut part = Part::from_blocks(
        options.name.clone(),
        pitch,
        origin,
        options.max_fragments,
        blocks,
    )?;
    part.thermal = options.thermal;
    for (w, rule) in options.windows.iter().enumerate() {
        let bad = |message: String| MeshError::Window {
            index: w + 1,
            message,
        };
        let win = rule.window;
        if !(win.min_s.is_finite()
            && win.max_s.is_finite()
            && 0.0 <= win.min_s
            && win.min_s <= win.max_s)
        {
            return Err(bad(format!(
                "need finite 0 <= min_s <= max_s, got min_s={} max_s={}",
                win.min_s, win.max_s
            )));
        }
        let inside = |b: &Block| (0..3).all(|d| rule.min[d] <= b[d] && b[d] <= rule.max[d]);
        let targets: Vec<usize> = (0..part.len())
            .filter(|&i| inside(&part.block(i)))
            .collect();
        if targets.is_empty() {
            return Err(bad(format!(
                "the box {}..{} holds no block of the part",
                BlockDisplay(rule.min),
                BlockDisplay(rule.max)
            )));
        }
        for i in targets {
            part.set_window(i, win);
        }
    }
    Ok(Voxelized {
        part,
        grid: grid_size,
        triangles: mesh.triangles.len(),
        warnings,
    })
}

struct Grid {
    origin: [f64; 3],
    pitch: [f64; 3],
    n: [usize; 3],
}

impl Grid {
    /// Centre of cell `i` along axis `d` (the same formula as `Part::centre_mm`).
    fn centre(&self, d: usize, i: usize) -> f64 {
        self.origin[d] + (i as f64 + 0.5) * self.pitch[d]
    }

    /// The cells along axis `d` whose centres may lie in `[lo, hi]` (one cell of slack:
    /// the exact tests decide).
    fn span(&self, d: usize, lo: f64, hi: f64) -> std::ops::Range<usize> {
        let at = |x: f64| (x - self.origin[d]) / self.pitch[d] - 0.5;
        let first = (at(lo).floor() - 1.0).max(0.0);
        let last = (at(hi).ceil() + 1.0).min(self.n[d] as f64 - 1.0);
        if last < first {
            return 0..0;
        }
        first as usize..last as usize + 1
    }

    /// Per column (x fastest), `nz + 1` winding-number increments: the winding number of
    /// cell k is the sum of the column's first k + 1 entries.
    fn winding(&self, mesh: &TriangleMesh) -> Vec<i32> {
        let [nx, ny, nz] = self.n;
        let mut diff = vec![0i32; nx * ny * (nz + 1)];
        for t in 0..mesh.triangles.len() {
            let tri = Tri::new(mesh.corners(t));
            if tri.nz == 0.0 {
                continue; // Vertical: a perturbed vertical ray never meets it.
            }
            let sign = if tri.nz > 0.0 { 1 } else { -1 };
            let (lo, hi) = tri.bounds();
            for j in self.span(1, lo[1], hi[1]) {
                let y = self.centre(1, j);
                for i in self.span(0, lo[0], hi[0]) {
                    let x = self.centre(0, i);
                    if !tri.covers(x, y) {
                        continue;
                    }
                    // Cells below the triangle come first in the column: find how many.
                    let below = partition_point(nz, |k| tri.is_above([x, y, self.centre(2, k)]));
                    let column = (j * nx + i) * (nz + 1);
                    diff[column] += sign;
                    diff[column + below] -= sign;
                }
            }
        }
        diff
    }
}

/// The number of leading `k` in `0..n` for which `pred(k)` holds (pred is monotone).
fn partition_point(n: usize, pred: impl Fn(usize) -> bool) -> usize {
    let (mut lo, mut hi) = (0, n);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if pred(mid) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo
}

/// A triangle with the exact signs of its normal, for the perturbed predicates.
struct Tri {
    c: [[f64; 3]; 3],
    /// Normal (b - a) × (c - a), each component exact in sign (orient2d of a projection).
    nx: f64,
    ny: f64,
    nz: f64,
}

fn orient(c: &[[f64; 3]; 3], u: usize, v: usize) -> f64 {
    let p = |i: usize| Coord {
        x: c[i][u],
        y: c[i][v],
    };
    orient2d(p(0), p(1), p(2))
}

impl Tri {
    fn new(c: [[f64; 3]; 3]) -> Tri {
        Tri {
            nx: orient(&c, 1, 2),
            ny: orient(&c, 2, 0),
            nz: orient(&c, 0, 1),
            c,
        }
    }

    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = self.c[0];
        let mut hi = self.c[0];
        for v in &self.c[1..] {
            for d in 0..3 {
                lo[d] = lo[d].min(v[d]);
                hi[d] = hi[d].max(v[d]);
            }
        }
        (lo, hi)
    }

    /// Whether the xy-projection holds the point (x + ε, y + ε²).
    fn covers(&self, x: f64, y: f64) -> bool {
        let p = Coord { x, y };
        (0..3).all(|e| {
            let (u, v) = (self.c[e], self.c[(e + 1) % 3]);
            let s = orient2d(Coord { x: u[0], y: u[1] }, Coord { x: v[0], y: v[1] }, p);
            // On the edge's line: the perturbation decides (d/dx = u.y - v.y, d/dy = v.x - u.x).
            let s = if s != 0.0 {
                s
            } else if u[1] != v[1] {
                u[1] - v[1]
            } else {
                v[0] - u[0]
            };
            (s > 0.0) == (self.nz > 0.0)
        })
    }

    /// Whether the triangle's plane is above the point p + (ε, ε², ε³) along z
    /// (the triangle must not be vertical).
    fn is_above(&self, p: [f64; 3]) -> bool {
        let q = |v: [f64; 3]| Coord3D {
            x: v[0],
            y: v[1],
            z: v[2],
        };
        // orient3d > 0: p is below the plane seen with a, b, c counter-clockwise.
        let o = orient3d(q(self.c[0]), q(self.c[1]), q(self.c[2]), q(p));
        let s = if self.nz > 0.0 { o } else { -o };
        if s != 0.0 {
            return s > 0.0;
        }
        // p lies on the plane: z_plane(p + δ) - (p_z + ε³) = g_x ε + g_y ε² - ε³, with the
        // plane's slope g = -(n_x, n_y) / n_z.
        let up = |n: f64| (n > 0.0) != (self.nz > 0.0);
        if self.nx != 0.0 {
            up(self.nx)
        } else if self.ny != 0.0 {
            up(self.ny)
        } else {
            false
        }
    }
}

/// Six times the signed volume the mesh encloses (positive for outward triangles),
/// taken about the first vertex so that far-off coordinates keep their precision.
fn signed_volume(mesh: &TriangleMesh) -> f64 {
    let o = mesh.vertices[0];
    (0..mesh.triangles.len())
        .map(|t| {
            let [a, b, c] = mesh
                .corners(t)
                .map(|v| [v[0] - o[0], v[1] - o[1], v[2] - o[2]]);
            a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0])
        })
        .sum()
}
