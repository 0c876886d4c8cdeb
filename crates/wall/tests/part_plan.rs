//! A thick-wall part through `waam_wall`: sliced layers planned bottom up with the bundled
//! robot, every layer's files, motion and recording, and `part-plan.yaml`.

use std::path::{Path, PathBuf};
use std::time::Duration;

use waam_layer::part::{PartManifest, PartOptions};
use waam_layer::slice::LayerParams;
use waam_layer::SearchOptions;
use waam_messages::topics;
use waam_pipeline::CellSource;
use waam_rosbag::{Bag, Recorder};
use waam_wall::{plan_part_to_dir, slice_to_dir, PartRun, WallError};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn three_layers_are_planned_moved_recorded_and_summarised() {
    let (_, mut layers) =
        PartManifest::read_dir(&root().join("config/layers/rib-web-3x3")).unwrap();
    layers.truncate(3);
    let cell = CellSource::default().load().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plan");
    let recorder = Recorder::create(&dir.path().join("bag")).unwrap();
    let options = PartOptions {
        search: SearchOptions {
            time_limit: Some(Duration::from_millis(100)),
            ..SearchOptions::default()
        },
        ..PartOptions::default()
    };
    let mut heard = Vec::new();
    let plan = plan_part_to_dir(
        &layers,
        &PartRun {
            out: &out,
            options: &options,
            cell: Some((&cell.settings, &cell.robot)),
            recorder: Some(&recorder),
        },
        |d| heard.push((d.index, d.total, d.line.start.clone(), d.motion.is_some())),
    )
    .unwrap();
    recorder.finish().unwrap();
    assert!(!plan.motion_failed);
    assert_eq!(plan.layers.len(), 3);
    assert_eq!(heard.len(), 3);
    for (k, (index, total, start, moved)) in heard.iter().enumerate() {
        assert_eq!((*index, *total, *moved), (k, 3, true));
        assert_eq!(start, &plan.summary[k].start);
    }
    let summary: serde_yaml::Value =
        serde_yaml::from_str(&std::fs::read_to_string(&plan.path).unwrap()).unwrap();
    let lines = summary.as_sequence().unwrap();
    assert_eq!(lines.len(), 3);
    for (k, l) in lines.iter().enumerate() {
        assert_eq!(l["dir"].as_str(), Some(format!("layer-{k:03}").as_str()));
        assert_eq!(l["z_mm"].as_f64(), Some(layers[k].0));
        // 3 deadheading moves: 4 arc starts.
        assert_eq!(l["motion"]["passes"].as_u64(), Some(4), "layer {k}");
        if k > 0 {
            assert_ne!(l["start"], lines[k - 1]["start"], "layer {k}");
            assert!(l["initial_max_c"].as_f64().unwrap() > 100.0, "layer {k}");
        }
        for f in [
            "layer.yaml",
            "trail.yaml",
            "toolpath.yaml",
            "trajectory.yaml",
        ] {
            let p = out.join(format!("layer-{k:03}")).join(f);
            assert!(p.is_file(), "{}", p.display());
        }
    }
    assert_eq!(lines[0]["initial_max_c"].as_f64(), Some(20.0));
    let bag = Bag::open(&dir.path().join("bag")).unwrap();
    assert_eq!(bag.count(topics::LAYER), 3);
    assert_eq!(bag.count(topics::JOINT_TRAJECTORY), 3);
}

#[test]
fn without_a_cell_there_is_no_motion_and_no_motion_file() {
    let (_, mut layers) =
        PartManifest::read_dir(&root().join("config/layers/rib-web-3x3")).unwrap();
    layers.truncate(1);
    let dir = tempfile::tempdir().unwrap();
    let options = PartOptions::default();
    let plan = plan_part_to_dir(
        &layers,
        &PartRun {
            out: dir.path(),
            options: &options,
            cell: None,
            recorder: None,
        },
        |_| {},
    )
    .unwrap();
    assert!(plan.summary[0].motion.is_none());
    assert!(dir.path().join("layer-000/trail.yaml").is_file());
    assert!(!dir.path().join("layer-000/toolpath.yaml").exists());
}

#[test]
fn slicing_names_the_mesh_it_cannot_read_or_slice() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.stl");
    let e = slice_to_dir(&missing, 2.0, None, LayerParams::default(), dir.path()).unwrap_err();
    assert!(matches!(e, WallError::ReadMesh { .. }), "{e:?}");
    assert!(e.to_string().contains("missing.stl"), "{e}");

    let stl = root().join("config/rib-web-3x3.stl");
    let e = slice_to_dir(&stl, -1.0, None, LayerParams::default(), dir.path()).unwrap_err();
    assert!(matches!(e, WallError::Slice { .. }), "{e:?}");
    assert!(e.to_string().contains("rib-web-3x3.stl"), "{e}");
}

#[test]
fn a_sliced_mesh_is_a_part_directory_that_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let stl = root().join("config/rib-web-3x3.stl");
    let (manifest, sliced) =
        slice_to_dir(&stl, 2.0, None, LayerParams::default(), dir.path()).unwrap();
    let (read, layers) = PartManifest::read_dir(dir.path()).unwrap();
    assert_eq!(read, manifest);
    assert_eq!(layers.len(), sliced.len());
    for ((z, l), s) in layers.iter().zip(&sliced) {
        assert_eq!(*z, s.z_mm);
        assert_eq!(l.segments, s.layer.segments);
    }
}
