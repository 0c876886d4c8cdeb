//! Weld moves follow material: a weld path moves within a layer between nodes along a
//! bead or beside each other with the arc on, the torch going straight from where one
//! piece ends to where the next starts. The line must stay on the layer's section, or
//! the torch would weld across a hollow.

use waam_mesh::TriangleMesh;
use waam_part::ContactKind;
use waam_slice::{section, shapes, slice, Polygon, SliceOptions};

/// A box from corner `min` to corner `max`, outward counter-clockwise triangles.
fn cuboid(min: [f64; 3], max: [f64; 3]) -> TriangleMesh {
    let corner = |i: usize| {
        [
            if i & 1 == 0 { min[0] } else { max[0] },
            if i & 2 == 0 { min[1] } else { max[1] },
            if i & 4 == 0 { min[2] } else { max[2] },
        ]
    };
    let mut soup = Vec::new();
    for axis in 0..3 {
        // u, v, axis right-handed: a, b, c, d counter-clockwise seen from +axis.
        let (u, v) = (1 << ((axis + 1) % 3), 1 << ((axis + 2) % 3));
        for side in [0, 1 << axis] {
            let (a, b, c, d) = (side, side | u, side | u | v, side | v);
            let (a, b, c, d) = (corner(a), corner(b), corner(c), corner(d));
            if side == 0 {
                soup.extend([[a, c, b], [a, d, c]]);
            } else {
                soup.extend([[a, b, c], [a, c, d]]);
            }
        }
    }
    TriangleMesh::from_soup(&soup).unwrap()
}

/// Closed bodies in one mesh, as an STL of several bodies is; they may overlap.
fn together(bodies: &[TriangleMesh]) -> TriangleMesh {
    let mut mesh = TriangleMesh::default();
    for b in bodies {
        let first = mesh.vertices.len() as u32;
        mesh.vertices.extend_from_slice(&b.vertices);
        mesh.triangles
            .extend(b.triangles.iter().map(|t| t.map(|i| i + first)));
    }
    mesh
}

/// How far the straight line from `a` to `b` leaves the section, mm (0 when it stays
/// on it): the largest distance from the section of 64 points along it.
fn off_section(sec: &[Polygon], a: [f64; 2], b: [f64; 2]) -> f64 {
    let rings = || {
        sec.iter()
            .flat_map(|p| std::iter::once(&p.outer).chain(&p.holes))
    };
    let inside_ring = |r: &[[f64; 2]], q: [f64; 2]| {
        let mut inside = false;
        for (i, &u) in r.iter().enumerate() {
            let v = r[(i + 1) % r.len()];
            if (u[1] > q[1]) != (v[1] > q[1])
                && q[0] < u[0] + (q[1] - u[1]) / (v[1] - u[1]) * (v[0] - u[0])
            {
                inside = !inside;
            }
        }
        inside
    };
    let to_edge = |q: [f64; 2], u: [f64; 2], v: [f64; 2]| {
        let d = [v[0] - u[0], v[1] - u[1]];
        let l2 = d[0] * d[0] + d[1] * d[1];
        let t = if l2 > 0.0 {
            (((q[0] - u[0]) * d[0] + (q[1] - u[1]) * d[1]) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (q[0] - u[0] - t * d[0]).hypot(q[1] - u[1] - t * d[1])
    };
    (0..=64)
        .map(|k| {
            let t = k as f64 / 64.0;
            let q = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
            let on = sec
                .iter()
                .any(|p| inside_ring(&p.outer, q) && !p.holes.iter().any(|h| inside_ring(h, q)));
            if on {
                return 0.0;
            }
            rings()
                .flat_map(|r| (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()])))
                .map(|(u, v)| to_edge(q, u, v))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

/// A tube (r 30 / 24) with a rib across it whose corners touch its inner wall: two
/// closed bodies that overlap, as `scripts/round_shapes.py` makes it. A weld path moves
/// within a layer between nodes along a bead or beside each other, the torch going
/// straight from where one piece ends to where the next starts: whichever ends those
/// are, the line stays on the section within W/2, and the rib's ends reach the ring by
/// such moves, so neither needs an arc start of its own.
#[test]
fn weld_moves_of_a_ribbed_tube_stay_on_its_section() {
    let (w, h) = (6.0, 2.5);
    let rib_x = (24.0f64 * 24.0 - 3.0 * 3.0).sqrt();
    let mesh = together(&[
        shapes::ring(24.0, 30.0, 2.0 * h, 128),
        cuboid([-rib_x, -3.0, 0.0], [rib_x, 3.0, 2.0 * h]),
    ]);
    let s = slice(&mesh, &SliceOptions::new("ribbed", [w, h])).unwrap();
    let p = &s.part;
    let sections: Vec<Vec<Polygon>> = (0..2)
        .map(|l| section(&mesh, (l as f64 + 0.5) * h, 0.05).unwrap())
        .collect();
    for (l, sec) in sections.iter().enumerate() {
        let area: f64 = sec.iter().map(Polygon::area_mm2).sum();
        assert!(area > 1250.0, "layer {l}: {area} mm2, the ring and the rib");
        // The measure sees a line across the hollow, rib end to the ring's far side (about
        // 6 mm off).
        assert!(off_section(sec, [rib_x, 0.0], [0.0, 27.0]) > 0.5 * w);
    }
    let ends = |n: usize| {
        let d = &p.nodes[n];
        let piece = p.beads[d.bead].piece_mm(d.from_mm, d.to_mm);
        [piece[0], piece[piece.len() - 1]]
    };
    let mut rib_to_ring = 0;
    for c in p.contacts.iter().filter(|c| c.kind != ContactKind::Stacked) {
        let sec = &sections[p.nodes[c.a].layer as usize];
        for a in ends(c.a) {
            for b in ends(c.b) {
                let off = off_section(sec, a, b);
                assert!(
                    off <= 0.5 * w,
                    "{:?} move {} -> {}: {a:?} -> {b:?} leaves the section by {off} mm",
                    c.kind,
                    c.a,
                    c.b
                );
            }
        }
        let (ba, bb) = (p.nodes[c.a].bead, p.nodes[c.b].bead);
        if p.beads[ba].closed != p.beads[bb].closed {
            rib_to_ring += 1;
        }
    }
    // Each layer: both ends of the rib beside the ring.
    assert!(rib_to_ring >= 4, "{rib_to_ring} moves between rib and ring");
}

/// Two tubes, r 30 / 24 and r 37 / 31, stand 1 mm apart: their centre lines are 7 mm
/// (1.17·W) apart, near enough for a beside contact, but no material joins them, so no heat
/// passes and no weld path may cross the gap (it would weld them together). Closed up
/// (r 35 / 30), they are one 11 mm wall of two rings side by side.
#[test]
fn tubes_apart_do_not_touch_and_tubes_together_do() {
    let (w, h) = (6.0, 2.5);
    let beside = |outer: [f64; 2]| {
        let mesh = together(&[
            shapes::ring(24.0, 30.0, 2.0 * h, 128),
            shapes::ring(outer[0], outer[1], 2.0 * h, 128),
        ]);
        let s = slice(&mesh, &SliceOptions::new("tubes", [w, h])).unwrap();
        // Closed up, the tubes share a face: no slivers between them get beads.
        assert_eq!(s.layers[0].beads, 2, "{:?}", s.layers[0]);
        assert!(s.layers[0].covered > 0.95, "{:?}", s.layers[0]);
        let p = s.part;
        p.contacts
            .iter()
            .filter(|c| c.kind == ContactKind::Beside)
            .count()
    };
    assert_eq!(beside([31.0, 37.0]), 0, "1 mm apart");
    assert!(beside([30.0, 35.0]) > 0, "together");
}
