//! One layer through `waam_wall::layer` (what `waam layer plan` runs): its files, motion,
//! messages and recording, its JSON, nothing written without a trail, and bad layer files
//! named.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use waam_layer::SearchOptions;
use waam_messages::topics;
use waam_pipeline::CellSource;
use waam_rosbag::{Bag, Recorder};
use waam_wall::layer::{plan_layer, read_layer_dir, LayerInput, LayerRun};

const PAPER: &str = "config/layers/paper-16mm.yaml";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn a_layer_is_planned_written_moved_and_recorded() {
    let input = LayerInput::read(&root().join(PAPER)).unwrap();
    let cell = CellSource::default().load().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let recorder = Recorder::create(&dir.path().join("bag")).unwrap();
    let plan = plan_layer(
        &input,
        &LayerRun {
            out: Some(&out),
            options: SearchOptions::default(),
            deadline: Some(Instant::now() + Duration::from_secs(60)),
            cell: Some((&cell.settings, &cell.robot)),
            recorder: Some(&recorder),
        },
    )
    .unwrap();
    recorder.finish().unwrap();
    let model = &input.model;
    assert!(plan.result.found() && plan.result.proven_optimal);
    assert!(!plan.motion_failed());
    let (tp, _) = plan.motion.as_ref().unwrap().as_ref().unwrap();
    assert!(plan.messages.is_some());
    // The layer document as received, the trail read back as it was found.
    assert_eq!(
        std::fs::read_to_string(out.join("layer.yaml")).unwrap(),
        input.text
    );
    let (read_model, trail) = read_layer_dir(&out).unwrap();
    assert_eq!(read_model.layer.name, model.layer.name);
    assert_eq!(trail.moves, plan.result.trail.moves);
    for file in ["toolpath.yaml", "trajectory.yaml"] {
        assert!(out.join(file).is_file(), "{file}");
    }
    let frames = plan.heat_frames.unwrap();
    assert!(frames > 0 && frames <= waam_messages::layer::MAX_HEAT_FRAMES);
    // The JSON carries the trail move by move and the motion's summary.
    let v = plan.json(model);
    assert_eq!(v["layer"], model.layer.name.as_str());
    assert_eq!(v["proven_optimal"], true);
    assert_eq!(
        v["trail"].as_array().unwrap().len(),
        plan.result.trail.moves.len()
    );
    assert_eq!(v["motion"]["poses"], tp.poses.len());
    // The recording holds the document, the heat and the motion.
    let bag = Bag::open(&dir.path().join("bag")).unwrap();
    assert_eq!(bag.count(topics::LAYER), 1);
    assert_eq!(bag.count(topics::HEAT), frames as u64);
    assert_eq!(bag.count(topics::JOINT_TRAJECTORY), 1);
}

#[test]
fn without_a_trail_nothing_is_written() {
    let input = LayerInput::read(&root().join(PAPER)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    // The deadline has passed before the search starts: it gives up before a first trail.
    let plan = plan_layer(
        &input,
        &LayerRun {
            out: Some(&out),
            options: SearchOptions::default(),
            deadline: Some(Instant::now()),
            cell: None,
            recorder: None,
        },
    )
    .unwrap();
    assert!(!plan.result.found());
    assert!(plan.motion.is_none() && plan.messages.is_none() && plan.heat_frames.is_none());
    assert!(!out.exists());
}

#[test]
fn a_layer_too_large_for_the_memory_limit_is_refused_before_its_search() {
    let input = LayerInput::read(&root().join("config/layers/grid-4x4.yaml")).unwrap();
    let estimate = waam_layer::search::estimated_memory_mb(&input.model);
    assert!(estimate > 0, "the layer needs more than 0 MB");
    let e = plan_layer(
        &input,
        &LayerRun {
            out: None,
            options: SearchOptions {
                max_memory_mb: 0,
                ..SearchOptions::default()
            },
            deadline: None,
            cell: None,
            recorder: None,
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("more than max_memory_mb = 0"), "{e}");
}

#[test]
fn bad_layer_files_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.yaml");
    let e = LayerInput::read(&missing).err().unwrap();
    assert_eq!(
        e.to_string(),
        format!("cannot read layer {}", missing.display())
    );
    let bad = dir.path().join("bad.yaml");
    let text = std::fs::read_to_string(root().join(PAPER)).unwrap();
    std::fs::write(&bad, text.replace("  - [A, B]", "  - [A, Q]")).unwrap();
    let e = LayerInput::read(&bad).err().unwrap();
    assert_eq!(e.to_string(), format!("in layer {}", bad.display()));
    let cause = std::error::Error::source(&e).unwrap().to_string();
    assert!(cause.contains("node Q is not in 'nodes'"), "{cause}");
    // A layer directory without its trail names the file.
    std::fs::write(dir.path().join("layer.yaml"), text).unwrap();
    let e = read_layer_dir(dir.path()).err().unwrap();
    assert_eq!(
        e.to_string(),
        format!("cannot read {}", dir.path().join("trail.yaml").display())
    );
}
