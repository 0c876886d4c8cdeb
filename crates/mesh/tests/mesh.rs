//! STL reading, mesh checks and voxelization (fixtures: tests/data/make_stl.py).
//! (`waam voxelize` through the binary: `tests/cli/mesh.rs`.)

use std::path::PathBuf;

use proptest::prelude::*;
use waam_mesh::{
    read_stl, voxelize, voxelize_indexed, MeshError, TriangleMesh, Units, VoxelizeOptions,
    WindowRule,
};
use waam_part::{Part, Window};

fn data(name: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .join("tests/data")
        .join(name)
}

fn read(name: &str) -> Result<TriangleMesh, MeshError> {
    read_stl(&std::fs::read(data(name)).unwrap(), Units::Mm)
}

fn pitch(p: [f64; 3]) -> VoxelizeOptions {
    VoxelizeOptions::new("t", p)
}

/// The 12 triangles of an axis-aligned box, outward.
fn box_mesh(lo: [f64; 3], hi: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let v: Vec<[f64; 3]> = (0..8)
        .map(|i| {
            [
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            ]
        })
        .collect();
    let quads = [
        [0, 2, 3, 1], // z = lo
        [4, 5, 7, 6], // z = hi
        [0, 1, 5, 4], // y = lo
        [2, 6, 7, 3], // y = hi
        [0, 4, 6, 2], // x = lo
        [1, 3, 7, 5], // x = hi
    ];
    let t = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    (v, t)
}

#[test]
fn a_box_fills_its_grid_in_ascii_and_binary() {
    for file in ["box_ascii.stl", "box_binary.stl"] {
        let v = voxelize(&read(file).unwrap(), &pitch([6.0, 6.0, 2.5])).unwrap();
        assert_eq!(v.grid, [6, 4, 4], "{file}");
        assert_eq!(v.part.len(), 96, "{file}");
        assert_eq!(v.part.origin_mm, [10.0, -5.0, 3.0]);
        assert!(v.warnings.is_empty());
    }
}

#[test]
fn a_square_tube_gives_the_blocks_of_s3_ring() {
    let text = std::fs::read_to_string(
        PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
            .join("config/parts/s3-ring.yaml"),
    )
    .unwrap();
    let ring = Part::parse(&text).unwrap();
    for file in ["tube_ascii.stl", "tube_binary.stl"] {
        let v = voxelize(&read(file).unwrap(), &pitch([6.0, 6.0, 2.5])).unwrap();
        assert_eq!(v.part.len(), 24, "{file}");
        assert_eq!(v.part.blocks(), ring.blocks(), "{file}");
    }
}

#[test]
fn a_round_ring_keeps_the_centres_inside_its_polygons() {
    let mesh = read("ring_binary.stl").unwrap();
    let p = [6.0, 6.0, 2.5];
    let v = voxelize(&mesh, &pitch(p)).unwrap();
    // Independent expectation: the same 48-gons (as f32, like the file), 2D point tests.
    let polygon = |r: f64| -> Vec<[f64; 2]> {
        (0..48)
            .map(|i| {
                let a = 2.0 * std::f64::consts::PI * i as f64 / 48.0;
                [(r * a.cos()) as f32 as f64, (r * a.sin()) as f32 as f64]
            })
            .collect()
    };
    let inside = |poly: &[[f64; 2]], x: f64, y: f64| {
        (0..poly.len()).all(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]) > 0.0
        })
    };
    let (outer, inner) = (polygon(30.0), polygon(18.0));
    let o = v.part.origin_mm;
    let mut expected = 0;
    for j in 0..v.grid[1] {
        for i in 0..v.grid[0] {
            let (x, y) = (
                o[0] + (i as f64 + 0.5) * p[0],
                o[1] + (j as f64 + 0.5) * p[1],
            );
            if inside(&outer, x, y) && !inside(&inner, x, y) {
                expected += 1;
                assert!(v.part.index_of([i as i64, j as i64, 0]).is_some());
            }
        }
    }
    assert_eq!(v.grid[2], 4);
    assert_eq!(v.part.len(), expected * 4);
    // Sanity: about the ring's area over a block's footprint, per layer.
    let area = std::f64::consts::PI * (30.0f64.powi(2) - 18.0f64.powi(2));
    assert!(
        (expected as f64 - area / 36.0).abs() < 0.15 * area / 36.0,
        "{expected}"
    );
}

#[test]
fn broken_meshes_and_garbage_get_clear_errors() {
    let e = voxelize(&read("open_box.stl").unwrap(), &pitch([6.0, 6.0, 2.5]))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("open mesh: 4 boundary edge(s), first between vertex ("),
        "{e}"
    );
    let e = voxelize(&read("flipped_box.stl").unwrap(), &pitch([6.0, 6.0, 2.5]))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("inconsistently oriented mesh: 3 edge(s)") && e.contains("flipped"),
        "{e}"
    );
    let e = read_stl(b"\x00\x01garbage\xff", Units::Mm)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("not an STL file:"), "{e}");
    let e = read_stl(b"", Units::Mm).unwrap_err().to_string();
    assert!(e.starts_with("not an STL file: 0 bytes"), "{e}");
}

#[test]
fn a_tiny_pitch_is_refused_not_allocated() {
    let mesh = read("box_binary.stl").unwrap();
    let e = voxelize(&mesh, &pitch([1e-9, 1e-9, 1e-9])).unwrap_err();
    assert!(matches!(e, MeshError::TooLarge { .. }), "{e}");
    assert!(
        e.to_string().contains("more than the limit of 20000000"),
        "{e}"
    );
    let e = voxelize(&mesh, &pitch([6.0, f64::NAN, 1.0])).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("block pitch: entries must be finite"),
        "{e}"
    );
    let e = voxelize(&mesh, &pitch([100.0, 100.0, 100.0])).unwrap_err();
    assert!(matches!(e, MeshError::NoBlocks { .. }), "{e}");
}

#[test]
fn metres_and_millimetres_agree_and_windows_apply() {
    let (v, t) = box_mesh([0.0; 3], [0.024, 0.012, 0.005]);
    let mut options = pitch([6.0, 6.0, 2.5]);
    options.max_fragments = 2;
    let w = |min_s, max_s| Window { min_s, max_s };
    options.windows = vec![
        WindowRule::everywhere(w(1.0, 9.0)),
        WindowRule::block([3, 1, 1], w(2.0, 4.0)),
    ];
    let m = voxelize_indexed(&v, &t, Units::M, &options).unwrap();
    let (vmm, _) = box_mesh([0.0; 3], [24.0, 12.0, 5.0]);
    let mm = voxelize_indexed(&vmm, &t, Units::Mm, &options).unwrap();
    assert_eq!(m.part.blocks(), mm.part.blocks());
    assert_eq!(m.part.len(), 16);
    assert_eq!(m.part.windows().len(), 16);
    let last = m.part.index_of([3, 1, 1]).unwrap();
    assert_eq!(m.part.window_of(last), Some(w(2.0, 4.0)));
    options
        .windows
        .push(WindowRule::block([9, 9, 9], w(0.0, 1.0)));
    let e = voxelize_indexed(&v, &t, Units::M, &options).unwrap_err();
    assert_eq!(
        e.to_string(),
        "window 3: the box [9,9,9]..[9,9,9] holds no block of the part"
    );
}

#[test]
fn an_inside_out_mesh_voxelizes_with_a_warning() {
    let (v, mut t) = box_mesh([0.0; 3], [12.0, 12.0, 5.0]);
    for tri in &mut t {
        tri.swap(1, 2);
    }
    let out = voxelize_indexed(&v, &t, Units::Mm, &pitch([6.0, 6.0, 2.5])).unwrap();
    assert_eq!(out.part.len(), 8);
    assert!(out.warnings[0].contains("inside out"));
}

/// Centres of a box, counted the way the perturbation decides ties: a centre c belongs
/// to [lo, hi) along every axis (the point c + ε lies inside exactly then).
fn expected_cells(lo: [f64; 3], hi: [f64; 3], origin: [f64; 3], p: [f64; 3], n: u64) -> usize {
    (0..3)
        .map(|d| {
            (0..n)
                .filter(|&i| {
                    let c = origin[d] + (i as f64 + 0.5) * p[d];
                    lo[d] <= c && c < hi[d]
                })
                .count()
        })
        .product()
}

#[test]
fn centres_on_shared_faces_belong_to_exactly_one_of_two_touching_boxes() {
    // Centres at integers + 0 on a grid with origin -0.5: many lie exactly on faces.
    let origin = [-0.5; 3];
    let mut options = pitch([1.0; 3]);
    options.origin_mm = Some(origin);
    let count = |lo, hi| {
        let (v, t) = box_mesh(lo, hi);
        voxelize_indexed(&v, &t, Units::Mm, &options)
            .map(|v| v.part.len())
            .unwrap_or(0)
    };
    let whole = count([0.0; 3], [6.0, 4.0, 3.0]);
    assert_eq!(whole, 6 * 4 * 3);
    assert_eq!(
        count([0.0; 3], [2.0, 4.0, 3.0]) + count([2.0, 0.0, 0.0], [6.0, 4.0, 3.0]),
        whole
    );
    assert_eq!(
        count([0.0; 3], [6.0, 4.0, 1.0]) + count([0.0, 0.0, 1.0], [6.0, 4.0, 3.0]),
        whole
    );
}

proptest! {
    #![proptest_config(ProptestConfig {
        failure_persistence: None,
        ..ProptestConfig::with_cases(200)
    })]

    /// Random boxes on random grids: exactly the centres inside (ties by the perturbation).
    #[test]
    fn random_boxes_match_a_direct_count(
        lo in prop::array::uniform3(-50.0f64..50.0),
        size in prop::array::uniform3(0.5f64..20.0),
        p in prop::array::uniform3(0.3f64..4.0),
        shift in prop::array::uniform3(0.0f64..3.0),
        snap in any::<bool>(),
    ) {
        // With `snap`, corners and centres fall on a quarter-millimetre lattice: many ties.
        let q = |x: f64| if snap { (x * 4.0).round() / 4.0 } else { x };
        let lo = lo.map(q);
        let hi: [f64; 3] = std::array::from_fn(|d| lo[d] + q(size[d]).max(0.25));
        let p = p.map(|x| if snap { q(x).max(0.5) } else { x });
        let origin: [f64; 3] = std::array::from_fn(|d| lo[d] - q(shift[d]));
        let (v, t) = box_mesh(lo, hi);
        let mut options = pitch(p);
        options.origin_mm = Some(origin);
        let n = (0..3).map(|d| ((hi[d] - origin[d]) / p[d]).ceil() as u64 + 1).max().unwrap();
        let expected = expected_cells(lo, hi, origin, p, n);
        match voxelize_indexed(&v, &t, Units::Mm, &options) {
            Ok(out) => prop_assert_eq!(out.part.len(), expected),
            Err(MeshError::NoBlocks { .. }) => prop_assert_eq!(expected, 0),
            Err(e) => prop_assert!(false, "{}", e),
        }
    }

    /// A box turned about z by a random angle: exactly the centres inside the turned box.
    #[test]
    fn turned_boxes_match_a_direct_count(
        angle in 0.0f64..std::f64::consts::TAU,
        size in prop::array::uniform3(1.0f64..15.0),
        p in prop::array::uniform3(0.5f64..3.0),
    ) {
        let (c, s) = (angle.cos(), angle.sin());
        let (v, t) = box_mesh([0.0; 3], size);
        let turned: Vec<[f64; 3]> = v.iter().map(|q| [c * q[0] - s * q[1], s * q[0] + c * q[1], q[2]]).collect();
        let result = voxelize_indexed(&turned, &t, Units::Mm, &pitch(p));
        let (blocks, grid) = match &result {
            Ok(out) => (out.part.blocks().to_vec(), out.grid),
            Err(MeshError::NoBlocks { nx, ny, nz }) => (Vec::new(), [*nx, *ny, *nz]),
            Err(e) => return Err(TestCaseError::fail(e.to_string())),
        };
        let o: [f64; 3] = std::array::from_fn(|d| turned.iter().map(|q| q[d]).fold(f64::INFINITY, f64::min));
        let mut expected = 0;
        for k in 0..grid[2] {
            for j in 0..grid[1] {
                for i in 0..grid[0] {
                    let x = o[0] + (i as f64 + 0.5) * p[0];
                    let y = o[1] + (j as f64 + 0.5) * p[1];
                    let z = o[2] + (k as f64 + 0.5) * p[2];
                    let (u, w) = (c * x + s * y, -s * x + c * y);
                    let inside = (0.0..size[0]).contains(&u) && (0.0..size[1]).contains(&w) && (0.0..size[2]).contains(&z);
                    if inside {
                        expected += 1;
                        prop_assert!(blocks.contains(&[i as i64, j as i64, k as i64]));
                    }
                }
            }
        }
        prop_assert_eq!(blocks.len(), expected);
    }

    /// Random soups of vertices and triangles, with odd pitches: an answer, never a panic.
    #[test]
    fn no_panic_on_random_meshes(
        vertices in prop::collection::vec(prop::array::uniform3(-1e3f64..1e3), 0..12),
        triangles in prop::collection::vec(prop::array::uniform3(0u32..14), 0..20),
        p in prop::array::uniform3(prop_oneof![Just(1e-9f64), 0.1f64..100.0, Just(f64::NAN)]),
    ) {
        let _ = voxelize_indexed(&vertices, &triangles, Units::Mm, &pitch(p));
    }
}
