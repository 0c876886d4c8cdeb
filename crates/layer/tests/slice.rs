//! Slicing meshes into layer graphs: extruded hand-made layers come back as themselves;
//! sections that are not wall structures give errors naming the height and the place.

use waam_layer::slice::{
    extrude, section, slice_mesh, stl_text, LayerParams, SliceError, SliceOptions,
};
use waam_layer::Layer;
use waam_mesh::{read_stl, TriangleMesh, Units};

const RIB_WEB: &str = include_str!("../../../config/layers/rib-web-3x3.yaml");
const HONEYCOMB: &str = include_str!("../../../config/layers/honeycomb-12.yaml");
const PAPER: &str = include_str!("../../../config/layers/paper-16mm.yaml");

fn options(h: f64, w: Option<f64>) -> SliceOptions {
    SliceOptions {
        name: "part".into(),
        layer_height_mm: h,
        wall_width_mm: w,
        params: LayerParams::default(),
    }
}

/// Same nodes (within `tol` mm), same walls (by node positions), same width (within `tol`).
fn assert_same_graph(got: &Layer, want: &Layer, tol: f64) {
    assert!(
        (got.wall_width_mm - want.wall_width_mm).abs() <= tol,
        "width {} vs {}",
        got.wall_width_mm,
        want.wall_width_mm
    );
    assert_eq!(
        got.nodes.len(),
        want.nodes.len(),
        "node count of {}",
        got.name
    );
    let map: Vec<usize> = (0..want.nodes.len())
        .map(|i| {
            let p = want.point(i);
            let found: Vec<usize> = (0..got.nodes.len())
                .filter(|&k| {
                    let q = got.point(k);
                    (p[0] - q[0]).abs() <= tol && (p[1] - q[1]).abs() <= tol
                })
                .collect();
            assert_eq!(
                found.len(),
                1,
                "node {} at {p:?}: found {found:?}",
                want.nodes[i].id
            );
            found[0]
        })
        .collect();
    let key = |[a, b]: [usize; 2]| [a.min(b), a.max(b)];
    let mut want_segs: Vec<[usize; 2]> = want
        .segments
        .iter()
        .map(|&[a, b]| key([map[a], map[b]]))
        .collect();
    let mut got_segs: Vec<[usize; 2]> = got.segments.iter().map(|&s| key(s)).collect();
    want_segs.sort_unstable();
    got_segs.sort_unstable();
    assert_eq!(got_segs, want_segs, "segments of {}", got.name);
}

/// Extrude → STL text → read → slice, every layer equal to the original.
fn round_trip(text: &str, height: f64, layer_height: f64, w: Option<f64>) -> Vec<Layer> {
    let layer = Layer::parse(text).unwrap();
    let mesh = extrude(&layer, height);
    mesh.check()
        .expect("the extruded prism is a closed, oriented mesh");
    let stl = stl_text(&mesh, "t");
    let read = read_stl(stl.as_bytes(), Units::Mm).unwrap();
    let layers = slice_mesh(&read, &options(layer_height, w)).unwrap();
    assert_eq!(layers.len(), (height / layer_height).round() as usize);
    for (k, l) in layers.iter().enumerate() {
        assert!((l.z_mm - (k as f64 + 0.5) * layer_height).abs() < 1e-9);
        assert_same_graph(&l.layer, &layer, 1e-3);
    }
    layers.into_iter().map(|l| l.layer).collect()
}

#[test]
fn the_rib_web_slices_into_the_hand_made_grid() {
    let layers = round_trip(RIB_WEB, 8.0, 2.0, None);
    assert_eq!(layers[0].segments.len(), 24);
    assert_eq!(layers[0].wall_width_mm, 4.0);
}

#[test]
fn the_honeycomb_and_the_paper_layer_slice_back() {
    round_trip(HONEYCOMB, 2.0, 1.0, Some(2.0));
    round_trip(PAPER, 3.0, 1.5, None);
}

#[test]
fn dead_ends_crossings_and_a_plain_wall_slice_back() {
    let params = PAPER.split("process:").nth(1).unwrap();
    // A cross with a tee: dead ends on four sides, one crossing, one tee.
    let cross = format!(
        "name: cross\nwall_width_mm: 3.0\nnodes:\n  - {{id: c, x: 0.0, y: 0.0}}\n  - {{id: e, x: 15.0, y: 0.0}}\n  - {{id: w, x: -12.0, y: 0.0}}\n  - {{id: n, x: 0.0, y: 20.0}}\n  - {{id: s, x: 0.0, y: -10.0}}\n  - {{id: t, x: 0.0, y: 10.0}}\n  - {{id: te, x: 9.0, y: 10.0}}\nsegments:\n  - [c, e]\n  - [w, c]\n  - [c, t]\n  - [t, n]\n  - [s, c]\n  - [t, te]\nprocess:{params}"
    );
    round_trip(&cross, 4.0, 2.0, None);
    let wall = format!(
        "name: wall\nwall_width_mm: 5.0\nnodes:\n  - {{id: a, x: 0.0, y: 0.0}}\n  - {{id: b, x: 30.0, y: 10.0}}\nsegments:\n  - [a, b]\nprocess:{params}"
    );
    round_trip(&wall, 2.0, 1.0, Some(5.0));
}

/// A box from (x0, y0, z0) to (x1, y1, z1), outward-facing triangles.
fn cuboid(lo: [f64; 3], hi: [f64; 3]) -> TriangleMesh {
    let v = |i: usize| {
        [
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ]
    };
    let quads = [
        [0, 2, 3, 1], // bottom
        [4, 5, 7, 6], // top
        [0, 1, 5, 4], // y = lo
        [2, 6, 7, 3], // y = hi
        [0, 4, 6, 2], // x = lo
        [1, 3, 7, 5], // x = hi
    ];
    let mut m = TriangleMesh {
        vertices: (0..8).map(v).collect(),
        triangles: Vec::new(),
    };
    for q in quads {
        m.triangles.push([q[0], q[1], q[2]]);
        m.triangles.push([q[0], q[2], q[3]]);
    }
    m
}

#[test]
fn a_blob_is_not_a_wall_and_the_error_names_height_and_place() {
    // A 4 mm wall, and beside it a 20 x 20 mm block: far wider than a wall.
    let mut mesh = cuboid([0.0, 0.0, 0.0], [40.0, 4.0, 6.0]);
    let blob = cuboid([0.0, 10.0, 0.0], [20.0, 30.0, 6.0]);
    let n = mesh.vertices.len() as u32;
    mesh.vertices.extend(&blob.vertices);
    mesh.triangles
        .extend(blob.triangles.iter().map(|t| t.map(|i| i + n)));
    let e = slice_mesh(&mesh, &options(2.0, Some(4.0))).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.starts_with("section at z = 1.000 mm: not a wall structure"),
        "{msg}"
    );
    assert!(msg.contains("20.000 mm across"), "{msg}");
    match e {
        SliceError::Section { x, y, .. } => {
            assert!(
                (0.0..=20.0).contains(&x) && (10.0..=30.0).contains(&y),
                "{x} {y}"
            )
        }
        other => panic!("{other:?}"),
    }
    // The wall alone slices into one straight wall with two dead ends.
    let wall = cuboid([0.0, 0.0, 0.0], [40.0, 4.0, 6.0]);
    let layers = slice_mesh(&wall, &options(2.0, None)).unwrap();
    assert_eq!(layers.len(), 3);
    let l = &layers[2].layer;
    assert_eq!(
        (l.nodes.len(), l.segments.len(), l.wall_width_mm),
        (2, 1, 4.0)
    );
    assert_eq!([l.point(0), l.point(1)], [[2.0, 2.0], [38.0, 2.0]]);
}

#[test]
fn an_open_contour_is_named() {
    let mut mesh = cuboid([0.0, 0.0, 0.0], [40.0, 4.0, 6.0]);
    // Drop one side triangle of the x = hi face: the outline is open there.
    mesh.triangles.remove(10);
    let e = slice_mesh(&mesh, &options(2.0, None)).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.starts_with("section at z = 1.000 mm: open contour"),
        "{msg}"
    );
    assert!(msg.contains("near (40.000,"), "{msg}");
    assert!(section(&mesh, 1.0).is_err());
}

#[test]
fn walls_of_different_widths_and_bad_heights_are_refused() {
    // An L of a 4 mm and a 6 mm wall.
    let mut mesh = cuboid([0.0, 0.0, 0.0], [40.0, 4.0, 2.0]);
    let other = cuboid([50.0, 0.0, 0.0], [56.0, 30.0, 2.0]);
    let n = mesh.vertices.len() as u32;
    mesh.vertices.extend(&other.vertices);
    mesh.triangles
        .extend(other.triangles.iter().map(|t| t.map(|i| i + n)));
    let msg = slice_mesh(&mesh, &options(2.0, None))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("mm wide where the others are"), "{msg}");
    for h in [0.0, -1.0, f64::NAN] {
        assert!(matches!(
            slice_mesh(&mesh, &options(h, None)),
            Err(SliceError::LayerHeight(_))
        ));
    }
    assert!(matches!(
        slice_mesh(&mesh, &options(5.0, None)),
        Err(SliceError::TooThin { .. })
    ));
}

/// Unit voxels: a hollow square tube (12 x 12 mm, 2 mm walls) and an L of 2 mm walls, 6 mm
/// tall.
fn voxel_parts() -> [(&'static str, Vec<[i64; 3]>); 2] {
    let cells = |keep: fn(i64, i64) -> bool| -> Vec<[i64; 3]> {
        let mut v = Vec::new();
        for x in 0..12 {
            for y in 0..12 {
                for z in 0..6 {
                    if keep(x, y) {
                        v.push([x, y, z]);
                    }
                }
            }
        }
        v
    };
    [
        (
            "tube",
            cells(|x, y| !(2..10).contains(&x) || !(2..10).contains(&y)),
        ),
        ("L", cells(|x, y| x < 2 || y < 2)),
    ]
}

/// A voxel-faceted mesh (every face split into unit squares: vertices every millimetre),
/// cut at 2 mm layers through its vertices (z = 1, 3, 5), slices into the same layer graphs
/// as cut between them (2.2 mm layers: z = 1.1, 3.3).
#[test]
fn a_voxel_mesh_cut_through_its_vertices_slices_as_between_them() {
    for (name, cells) in voxel_parts() {
        let mesh = waam_slice::shapes::voxels(&cells);
        mesh.check().expect("a closed, oriented voxel mesh");
        let through = slice_mesh(&mesh, &options(2.0, None))
            .unwrap_or_else(|e| panic!("{name} at 2 mm layers: {e}"));
        let between = slice_mesh(&mesh, &options(2.2, None))
            .unwrap_or_else(|e| panic!("{name} at 2.2 mm layers: {e}"));
        assert_eq!((through.len(), between.len()), (3, 2), "{name}");
        for (k, l) in through.iter().enumerate() {
            assert_eq!(
                l.z_mm,
                1.0 + 2.0 * k as f64,
                "{name}: a plane through vertices"
            );
            assert_same_graph(&l.layer, &between[0].layer, 1e-9);
        }
        let l = &between[1].layer;
        assert_eq!(l.wall_width_mm, 2.0, "{name}");
        let mut points: Vec<[f64; 2]> = (0..l.nodes.len()).map(|v| l.point(v)).collect();
        points.sort_by(|a, b| a.partial_cmp(b).unwrap());
        match name {
            // Four walls crossing at the corners.
            "tube" => {
                assert_eq!(points, [[1.0, 1.0], [1.0, 11.0], [11.0, 1.0], [11.0, 11.0]]);
                assert_eq!(l.segments.len(), 4);
            }
            // Two walls crossing at the corner, each with a dead end a half width in.
            _ => {
                assert_eq!(points, [[1.0, 1.0], [1.0, 11.0], [11.0, 1.0]]);
                assert_eq!(l.segments.len(), 2);
            }
        }
    }
}
