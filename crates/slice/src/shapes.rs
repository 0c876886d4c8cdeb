//! Generated meshes for tests and examples: revolved profiles (rings, flanged tubes) and
//! sets of unit voxels, all closed, with outward counter-clockwise triangles.

use waam_mesh::TriangleMesh;

type P = [f64; 3];

fn push(soup: &mut Vec<[P; 3]>, t: [P; 3], outward: P) {
    let u = [t[1][0] - t[0][0], t[1][1] - t[0][1], t[1][2] - t[0][2]];
    let v = [t[2][0] - t[0][0], t[2][1] - t[0][1], t[2][2] - t[0][2]];
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let dot = n[0] * outward[0] + n[1] * outward[1] + n[2] * outward[2];
    soup.push(if dot >= 0.0 { t } else { [t[0], t[2], t[1]] });
}

/// A closed profile in the (r, z) half-plane (r > 0, any orientation) revolved about the z
/// axis in `segments` facets.
pub fn revolve(profile: &[[f64; 2]], segments: usize) -> TriangleMesh {
    // Orientation of the profile: outward normals of a counter-clockwise profile point right.
    let n = profile.len();
    let twice_area: f64 = (0..n)
        .map(|i| {
            let (a, b) = (profile[i], profile[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum();
    let sign = if twice_area >= 0.0 { 1.0 } else { -1.0 };
    let mut soup = Vec::new();
    let at = |p: [f64; 2], k: usize| {
        let t = std::f64::consts::TAU * (k % segments) as f64 / segments as f64;
        [p[0] * t.cos(), p[0] * t.sin(), p[1]]
    };
    for i in 0..n {
        let (a, b) = (profile[i], profile[(i + 1) % n]);
        let (nr, nz) = (sign * (b[1] - a[1]), -sign * (b[0] - a[0]));
        for k in 0..segments {
            let t = std::f64::consts::TAU * (k as f64 + 0.5) / segments as f64;
            let out = [nr * t.cos(), nr * t.sin(), nz];
            let (p, q, r, s) = (at(a, k), at(b, k), at(b, k + 1), at(a, k + 1));
            push(&mut soup, [p, q, r], out);
            push(&mut soup, [p, r, s], out);
        }
    }
    TriangleMesh::from_soup(&soup).expect("a generated mesh is sound")
}

/// A ring (tube) of radii `r_in..r_out`, `height` tall, standing on z = 0.
pub fn ring(r_in: f64, r_out: f64, height: f64, segments: usize) -> TriangleMesh {
    revolve(
        &[[r_in, 0.0], [r_out, 0.0], [r_out, height], [r_in, height]],
        segments,
    )
}

/// A tube `r_in..r_tube`, `height` tall, on a flange `r_in..r_flange`, `flange` thick.
pub fn flanged_tube(
    r_in: f64,
    r_tube: f64,
    r_flange: f64,
    flange: f64,
    height: f64,
    segments: usize,
) -> TriangleMesh {
    revolve(
        &[
            [r_in, 0.0],
            [r_flange, 0.0],
            [r_flange, flange],
            [r_tube, flange],
            [r_tube, height],
            [r_in, height],
        ],
        segments,
    )
}

/// Unit voxels at integer positions, every face split into unit squares (so vertices lie
/// every 1 mm, as in a voxel-faceted export).
pub fn voxels(cells: &[[i64; 3]]) -> TriangleMesh {
    let set: std::collections::HashSet<[i64; 3]> = cells.iter().copied().collect();
    let mut soup = Vec::new();
    for &c in cells {
        for axis in 0..3 {
            for dir in [-1i64, 1] {
                let mut nb = c;
                nb[axis] += dir;
                if set.contains(&nb) {
                    continue;
                }
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let corner = |du: i64, dv: i64| {
                    let mut p = c.map(|x| x as f64);
                    if dir > 0 {
                        p[axis] += 1.0;
                    }
                    p[u] += du as f64;
                    p[v] += dv as f64;
                    p
                };
                let (a, b, cc, d) = (corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1));
                let mut out = [0.0; 3];
                out[axis] = dir as f64;
                push(&mut soup, [a, b, cc], out);
                push(&mut soup, [a, cc, d], out);
            }
        }
    }
    TriangleMesh::from_soup(&soup).expect("a generated mesh is sound")
}
