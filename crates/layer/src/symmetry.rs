//! Symmetries of a layer: rotations and reflections about the centroid of its nodes that
//! map nodes onto nodes, segments onto segments and the *mesh* onto itself (so the
//! discrete model, not only the drawing, is invariant). Each is given as a permutation
//! of directed segments (index 2 s + reversed).

use std::collections::{HashMap, HashSet};

use super::mesh::Mesh;
use super::model::Model;

/// The symmetry group (identity included) as permutations of directed segments.
pub fn symmetries(model: &Model) -> Vec<Vec<usize>> {
    let layer = &model.layer;
    let n = layer.nodes.len() as f64;
    let c = [
        layer.nodes.iter().map(|p| p.x).sum::<f64>() / n,
        layer.nodes.iter().map(|p| p.y).sum::<f64>() / n,
    ];
    let scale = layer
        .nodes
        .iter()
        .map(|p| (p.x - c[0]).abs().max((p.y - c[1]).abs()))
        .fold(1.0, f64::max);
    let tol = 1e-6 * scale;
    let key = |p: [f64; 2]| ((p[0] / tol).round() as i64, (p[1] / tol).round() as i64);
    let node_at: HashMap<(i64, i64), usize> = (0..layer.nodes.len())
        .map(|i| (key(layer.point(i)), i))
        .collect();
    let seg_at: HashMap<(usize, usize), usize> = layer
        .segments
        .iter()
        .enumerate()
        .map(|(s, &[a, b])| ((a, b), s))
        .collect();
    let mut group = Vec::new();
    for k in 0..24 {
        for reflect in [false, true] {
            let phi = (k as f64 * 15.0).to_radians();
            let (sn, cs) = phi.sin_cos();
            let map = |p: [f64; 2]| {
                let (x, mut y) = (p[0] - c[0], p[1] - c[1]);
                if reflect {
                    y = -y;
                }
                [c[0] + cs * x - sn * y, c[1] + sn * x + cs * y]
            };
            let lookup = |p: [f64; 2]| {
                let q = map(p);
                let (kx, ky) = key(q);
                // Tolerate rounding at a grid-cell border.
                for dx in -1..=1 {
                    for dy in -1..=1 {
                        if let Some(&i) = node_at.get(&(kx + dx, ky + dy)) {
                            return Some(i);
                        }
                    }
                }
                None
            };
            let Some(node_map) = (0..layer.nodes.len())
                .map(|i| lookup(layer.point(i)))
                .collect::<Option<Vec<usize>>>()
            else {
                continue;
            };
            let mut perm = vec![0; 2 * layer.segments.len()];
            let mut ok = true;
            for (s, &[a, b]) in layer.segments.iter().enumerate() {
                let (ga, gb) = (node_map[a], node_map[b]);
                if let Some(&t) = seg_at.get(&(ga, gb)) {
                    perm[2 * s] = 2 * t;
                    perm[2 * s + 1] = 2 * t + 1;
                } else if let Some(&t) = seg_at.get(&(gb, ga)) {
                    perm[2 * s] = 2 * t + 1;
                    perm[2 * s + 1] = 2 * t;
                } else {
                    ok = false;
                    break;
                }
            }
            if ok && mesh_invariant(&model.mesh, &map, tol) && !group.contains(&perm) {
                group.push(perm);
            }
        }
    }
    group
}

fn mesh_invariant(mesh: &Mesh, map: &dyn Fn([f64; 2]) -> [f64; 2], tol: f64) -> bool {
    let key = |p: [f64; 2]| ((p[0] / tol).round() as i64, (p[1] / tol).round() as i64);
    let at: HashMap<(i64, i64), usize> = (0..mesh.points.len())
        .map(|i| (key(mesh.points[i]), i))
        .collect();
    let find = |p: [f64; 2]| {
        let (kx, ky) = key(map(p));
        for dx in -1..=1 {
            for dy in -1..=1 {
                if let Some(&i) = at.get(&(kx + dx, ky + dy)) {
                    return Some(i);
                }
            }
        }
        None
    };
    let Some(image) = mesh
        .points
        .iter()
        .map(|&p| find(p))
        .collect::<Option<Vec<usize>>>()
    else {
        return false;
    };
    let sorted = |t: [usize; 3]| {
        let mut t = t;
        t.sort_unstable();
        t
    };
    let tris: HashSet<[usize; 3]> = mesh.triangles.iter().map(|&t| sorted(t)).collect();
    mesh.triangles
        .iter()
        .all(|&t| tris.contains(&sorted(t.map(|i| image[i]))))
}
