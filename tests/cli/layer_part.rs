//! Thick-wall parts through the binary: a bad section refused with a named error, and a
//! 20-layer part planned end to end (trails, motion, recording); the library's own tests
//! are `crates/layer/tests/layer_part.rs`.

use waam_messages::topics;
use waam_rosbag::Bag;

use crate::common;
use common::run::{run_ok, waam};

#[test]
fn a_blob_section_is_a_one_line_error_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    // A solid 20 x 20 x 4 mm block next to a 4 mm wall, as ASCII STL.
    let mut stl = String::from("solid t\n");
    for (lo, hi) in [([0.0, 0.0], [40.0, 4.0]), ([0.0, 10.0], [20.0, 30.0])] {
        let v = |i: usize| -> [f64; 3] {
            [
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { 0.0 } else { 4.0 },
            ]
        };
        for q in [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ] {
            for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
                stl += "facet normal 0 0 0\nouter loop\n";
                for i in t {
                    let p = v(i);
                    stl += &format!("vertex {} {} {}\n", p[0], p[1], p[2]);
                }
                stl += "endloop\nendfacet\n";
            }
        }
    }
    stl += "endsolid t\n";
    let mesh = dir.path().join("blob.stl");
    std::fs::write(&mesh, stl).unwrap();
    let out = waam()
        .args(["layer", "slice"])
        .arg(&mesh)
        .args(["--layer-height", "2", "--wall-width", "4", "--out"])
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("section at z = 1.000 mm: not a wall structure") && err.contains("near ("),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn a_twenty_layer_sliced_part_is_planned_moved_and_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plan");
    let bag = dir.path().join("bag");
    let stdout = run_ok(
        waam()
            .current_dir(common::root())
            .args([
                "layer",
                "plan-part",
                "config/layers/rib-web-3x3",
                "--time-limit",
                "0.1",
            ])
            .args(["--robot", "urdf/waam_robot.urdf", "--out"])
            .arg(&out)
            .arg("--record")
            .arg(&bag),
    );
    assert_eq!(
        stdout.lines().filter(|l| l.starts_with("layer ")).count(),
        20,
        "{stdout}"
    );
    assert!(stdout.contains("planned 20 layers"), "{stdout}");
    let summary: serde_yaml::Value =
        serde_yaml::from_str(&std::fs::read_to_string(out.join("part-plan.yaml")).unwrap())
            .unwrap();
    let layers = summary.as_sequence().unwrap();
    assert_eq!(layers.len(), 20);
    let mut z_prev = f64::NEG_INFINITY;
    for (k, l) in layers.iter().enumerate() {
        let z = l["z_mm"].as_f64().unwrap();
        assert!(z > z_prev);
        z_prev = z;
        assert!(l["motion"]["poses"].as_u64().unwrap() > 0, "layer {k}");
        // 3 deadheading moves: 4 arc starts.
        assert_eq!(l["motion"]["passes"].as_u64(), Some(4), "layer {k}");
        if k > 0 {
            assert_ne!(l["start"], layers[k - 1]["start"], "layer {k}");
            assert!(l["initial_max_c"].as_f64().unwrap() > 100.0, "layer {k}");
        }
        let d = out.join(format!("layer-{k:03}"));
        for f in [
            "layer.yaml",
            "trail.yaml",
            "toolpath.yaml",
            "trajectory.yaml",
        ] {
            assert!(d.join(f).is_file(), "{}", d.join(f).display());
        }
    }
    assert_eq!(layers[0]["initial_max_c"].as_f64(), Some(20.0));
    // The torch welds each layer at its height: the top layer's poses are 38 mm above the
    // bottom layer's.
    let zs = |k: usize| -> f64 {
        let text =
            std::fs::read_to_string(out.join(format!("layer-{k:03}/toolpath.yaml"))).unwrap();
        let v: serde_yaml::Value = serde_yaml::from_str(&text).unwrap();
        let poses = v["poses"].as_sequence().unwrap();
        let weld = poses
            .iter()
            .find(|p| p["arc_on"].as_bool() == Some(true))
            .unwrap();
        weld["position"][2].as_f64().unwrap()
    };
    assert!(
        (zs(19) - zs(0) - 0.038).abs() < 1e-6,
        "{} {}",
        zs(19),
        zs(0)
    );
    let bag = Bag::open(&bag).unwrap();
    assert_eq!(bag.count(topics::LAYER), 20);
    assert_eq!(bag.count(topics::JOINT_TRAJECTORY), 20);
}
