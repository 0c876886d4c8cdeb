//! A conforming triangle mesh of the layer's walls.
//!
//! Each segment becomes a straight strip of width w, cut across at (about) the torch's
//! step length, two cells across, each cell split into two right triangles by a diagonal
//! that points to the strip's middle (the middle cell is halved when their number is
//! odd): a pattern that keeps every mirror symmetry of the layer and has no obtuse angle,
//! so the stepper stays monotone (see `fem`). Where walls meet,
//! the strips stop at the junction depth and a fan of triangles around the layer node
//! fills the joint. `refinement` splits every triangle into four, as often as asked.
//! Nodes are finally renumbered by reverse Cuthill–McKee so the Cholesky factor stays thin.

use std::collections::{HashMap, VecDeque};

use super::format::{angle_gap, Layer};

/// A triangle mesh: node coordinates (mm), counter-clockwise triangles, boundary edges.
#[derive(Debug, Clone)]
pub struct Mesh {
    pub points: Vec<[f64; 2]>,
    pub triangles: Vec<[usize; 3]>,
    /// Edges that belong to one triangle only: the wall outline, where the Robin term acts.
    pub boundary: Vec<[usize; 2]>,
}

/// Merges points closer than 1e-5 mm, so neighbouring pieces share nodes even when the
/// layer's coordinates were rounded (a hexagon's 120° written with six decimals).
struct Builder {
    points: Vec<[f64; 2]>,
    index: HashMap<(i64, i64), Vec<usize>>,
    triangles: Vec<[usize; 3]>,
}

const MERGE_MM: f64 = 1e-5;

impl Builder {
    fn point(&mut self, p: [f64; 2]) -> usize {
        let cell = 10.0 * MERGE_MM;
        let key = ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64);
        for dx in -1..=1 {
            for dy in -1..=1 {
                if let Some(ids) = self.index.get(&(key.0 + dx, key.1 + dy)) {
                    for &i in ids {
                        let q = self.points[i];
                        if (p[0] - q[0]).abs() <= MERGE_MM && (p[1] - q[1]).abs() <= MERGE_MM {
                            return i;
                        }
                    }
                }
            }
        }
        self.points.push(p);
        self.index
            .entry(key)
            .or_default()
            .push(self.points.len() - 1);
        self.points.len() - 1
    }

    fn triangle(&mut self, a: usize, b: usize, c: usize) {
        let (p, q, r) = (self.points[a], self.points[b], self.points[c]);
        let area2 = (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]);
        if area2.abs() < 1e-12 {
            return; // a degenerate sliver adds nothing
        }
        self.triangles
            .push(if area2 > 0.0 { [a, b, c] } else { [a, c, b] });
    }
}

fn add(p: [f64; 2], d: [f64; 2], t: f64) -> [f64; 2] {
    [p[0] + t * d[0], p[1] + t * d[1]]
}

impl Mesh {
    /// Meshes the walls of a layer, with `layer.process.mesh_refinement` refinements.
    pub fn new(layer: &Layer) -> Mesh {
        Mesh::with_refinement(layer, layer.process.mesh_refinement)
    }

    /// Meshes the walls with the given number of uniform refinements.
    pub fn with_refinement(layer: &Layer, refinement: u32) -> Mesh {
        let w = layer.wall_width_mm;
        let half = 0.5 * w;
        let step = layer.process.weld_speed_mm_s * layer.process.time_step_s;
        let depth: Vec<f64> = (0..layer.nodes.len())
            .map(|v| layer.junction_depth(v))
            .collect();
        let mut b = Builder {
            points: Vec::new(),
            index: HashMap::new(),
            triangles: Vec::new(),
        };
        // Strips.
        for (s, &[na, nb]) in layer.segments.iter().enumerate() {
            let (pa, len) = (layer.point(na), layer.length(s));
            let u = layer.direction_from(s, na);
            let n = [-u[1], u[0]];
            let (t0, t1) = (depth[na], len - depth[nb]);
            let cells = (((t1 - t0) / step).round() as usize).max(1);
            let mut stations: Vec<f64> = (0..=cells)
                .map(|k| t0 + (t1 - t0) * k as f64 / cells as f64)
                .collect();
            if cells % 2 == 1 {
                // Halve the middle cell so the pattern below mirrors about the midpoint.
                let k = cells / 2;
                stations.insert(k + 1, 0.5 * (stations[k] + stations[k + 1]));
            }
            let middle = 0.5 * (t0 + t1);
            for k in 0..stations.len() - 1 {
                let (ta, tb) = (stations[k], stations[k + 1]);
                // Right triangles: each cell's diagonal runs from the centre line at the
                // station nearer the strip's middle to the wall edge at the other station.
                let (tc, te) = if 0.5 * (ta + tb) < middle {
                    (tb, ta)
                } else {
                    (ta, tb)
                };
                for side in [-half, half] {
                    let c_near = b.point(add(pa, u, tc));
                    let c_far = b.point(add(pa, u, te));
                    let e_near = b.point(add(add(pa, u, tc), n, side));
                    let e_far = b.point(add(add(pa, u, te), n, side));
                    b.triangle(c_near, c_far, e_far);
                    b.triangle(c_near, e_far, e_near);
                }
            }
        }
        // Junction fans.
        for (v, &d) in depth.iter().enumerate() {
            let pv = layer.point(v);
            let angles = layer.sorted_angles(v);
            let mut ring: Vec<[f64; 2]> = Vec::new();
            for k in 0..angles.len() {
                let s = angles[k].1;
                let u = layer.direction_from(s, v);
                let n = [-u[1], u[0]];
                let end = add(pv, u, d);
                ring.push(add(end, n, -half));
                ring.push(end);
                ring.push(add(end, n, half));
                // The gap to the next strip counter-clockwise.
                let gap = angle_gap(&angles, k);
                let next = layer.direction_from(angles[(k + 1) % angles.len()].1, v);
                let next_n = [-next[1], next[0]];
                let bisector = {
                    let a = angles[k].0 + 0.5 * gap;
                    [a.cos(), a.sin()]
                };
                let pi = std::f64::consts::PI;
                if gap < pi - 1e-9 {
                    // Inner corner where the two wall edges cross, unless the strips touch.
                    let along = half / (0.5 * gap).tan();
                    if along < d - 1e-4 * half {
                        ring.push(add(pv, bisector, half / (0.5 * gap).sin()));
                    }
                } else if gap > pi + 1e-9 && gap <= 1.5 * pi + 1e-9 {
                    // Outer mitre corner.
                    ring.push(add(pv, bisector, half / (0.5 * gap).sin()));
                } else if gap > 1.5 * pi + 1e-9 {
                    // Wide outside (a dead end): square off behind the node.
                    ring.push(add(add(pv, u, -half), n, half));
                    ring.push(add(add(pv, next, -half), next_n, -half));
                }
            }
            let centre = b.point(pv);
            let ids: Vec<usize> = ring.iter().map(|&p| b.point(p)).collect();
            for k in 0..ids.len() {
                let (p, q) = (ids[k], ids[(k + 1) % ids.len()]);
                if p != q {
                    b.triangle(centre, p, q);
                }
            }
        }
        let mut mesh = Mesh {
            points: b.points,
            triangles: b.triangles,
            boundary: Vec::new(),
        };
        for _ in 0..refinement {
            mesh.refine();
        }
        mesh.renumber();
        mesh.find_boundary();
        mesh
    }

    /// Splits every triangle into four through its edge midpoints.
    fn refine(&mut self) {
        let mut mids: HashMap<(usize, usize), usize> = HashMap::new();
        let mut points = self.points.clone();
        let mut mid = |a: usize, b: usize, points: &mut Vec<[f64; 2]>| {
            *mids.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (points[a], points[b]);
                points.push([0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]);
                points.len() - 1
            })
        };
        let mut triangles = Vec::with_capacity(4 * self.triangles.len());
        for &[a, b, c] in &self.triangles {
            let (ab, bc, ca) = (
                mid(a, b, &mut points),
                mid(b, c, &mut points),
                mid(c, a, &mut points),
            );
            triangles.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        self.points = points;
        self.triangles = triangles;
    }

    fn find_boundary(&mut self) {
        let mut count: HashMap<(usize, usize), (usize, [usize; 2])> = HashMap::new();
        for t in &self.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                count.entry((a.min(b), a.max(b))).or_insert((0, [a, b])).0 += 1;
            }
        }
        let mut boundary: Vec<[usize; 2]> = count
            .into_values()
            .filter(|(c, _)| *c == 1)
            .map(|(_, e)| e)
            .collect();
        boundary.sort_unstable();
        self.boundary = boundary;
    }

    /// Reverse Cuthill–McKee renumbering (from a pseudo-peripheral node, per component).
    fn renumber(&mut self) {
        let n = self.points.len();
        let mut adj = vec![Vec::new(); n];
        for t in &self.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                adj[a].push(b);
                adj[b].push(a);
            }
        }
        for a in adj.iter_mut() {
            a.sort_unstable();
            a.dedup();
        }
        let bfs_last = |start: usize, seen: &mut Vec<bool>| {
            let mut queue = VecDeque::from([start]);
            seen[start] = true;
            let mut last = start;
            while let Some(v) = queue.pop_front() {
                last = v;
                for &w in &adj[v] {
                    if !seen[w] {
                        seen[w] = true;
                        queue.push_back(w);
                    }
                }
            }
            last
        };
        let mut order = Vec::with_capacity(n);
        let mut placed = vec![false; n];
        for root in 0..n {
            if placed[root] {
                continue;
            }
            let mut seen = placed.clone();
            let far = bfs_last(root, &mut seen);
            let mut seen = placed.clone();
            let start = bfs_last(far, &mut seen);
            let mut queue = VecDeque::from([start]);
            placed[start] = true;
            while let Some(v) = queue.pop_front() {
                order.push(v);
                let mut next: Vec<usize> = adj[v].iter().copied().filter(|&w| !placed[w]).collect();
                next.sort_by_key(|&w| adj[w].len());
                for w in next {
                    placed[w] = true;
                    queue.push_back(w);
                }
            }
        }
        order.reverse();
        let mut new_of = vec![0; n];
        for (new, &old) in order.iter().enumerate() {
            new_of[old] = new;
        }
        self.points = order.iter().map(|&old| self.points[old]).collect();
        for t in self.triangles.iter_mut() {
            for v in t.iter_mut() {
                *v = new_of[*v];
            }
        }
    }

    /// Area of triangle t (mm²).
    pub fn area(&self, t: usize) -> f64 {
        let [a, b, c] = self.triangles[t];
        let (p, q, r) = (self.points[a], self.points[b], self.points[c]);
        0.5 * ((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))
    }

    /// Total meshed area (mm²).
    pub fn total_area(&self) -> f64 {
        (0..self.triangles.len()).map(|t| self.area(t)).sum()
    }

    /// The mesh node nearest to a point.
    pub fn nearest(&self, p: [f64; 2]) -> usize {
        (0..self.points.len())
            .min_by(|&a, &b| {
                let da = (self.points[a][0] - p[0]).powi(2) + (self.points[a][1] - p[1]).powi(2);
                let db = (self.points[b][0] - p[0]).powi(2) + (self.points[b][1] - p[1]).powi(2);
                da.total_cmp(&db)
            })
            .unwrap_or(0)
    }
}
