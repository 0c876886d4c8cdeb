//! `waam bag` on recordings made by a separate `waam` process: a finished session and one
//! killed with SIGKILL mid-recording, read with our own reader.

use std::path::Path;

use serde_json::Value;

mod recording;
use recording::{kill_a_recording, waam};

fn info_json(bag: &Path) -> Value {
    let out = waam()
        .args(["bag", "info", "--json"])
        .arg(bag)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn info_reports_a_finished_session() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("session");
    let out = waam()
        .args(["bag", "sample", "--rounds", "2"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let written: Value = serde_json::from_slice(&out.stdout).unwrap();
    let info = info_json(&dir);
    assert_eq!(info["truncated"], Value::Null);
    assert_eq!(info["ros_distro"], "jazzy");
    assert_eq!(info["profile"], "ros2");
    let topics = info["topics"].as_array().unwrap();
    assert_eq!(topics.len(), written.as_object().unwrap().len());
    for t in topics {
        let w = &written[t["name"].as_str().unwrap()];
        assert_eq!(t["type"], w["type"]);
        assert_eq!(t["count"], w["count"]);
    }
    let text = waam().args(["bag", "info"]).arg(&dir).output().unwrap();
    let text = String::from_utf8(text.stdout).unwrap();
    assert!(text.contains("Storage id:        mcap"), "{text}");
    assert!(text.contains(
        "Topic: /waam_planner/plan/weld_plan | Type: waam_interfaces/msg/WeldPlan | Count: 2 | Serialization Format: cdr"
    ), "{text}");
    assert!(!text.contains("Truncated"), "{text}");
}

#[test]
fn a_recording_killed_with_sigkill_reads_up_to_its_last_chunk() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("killed");
    let flushed = kill_a_recording(&dir, 300);
    let info = info_json(&dir);
    let truncated = &info["truncated"];
    assert!(truncated.is_object(), "not reported as truncated: {info}");
    let read = info["message_count"].as_u64().unwrap();
    // Everything flushed before the last metadata.yaml refresh is readable (a chunk closed
    // after that refresh adds more).
    assert!(read >= flushed, "read {read} of {flushed} flushed messages");
    assert!(info["chunks"].as_u64().unwrap() >= 1, "{info}");
    let text = waam().args(["bag", "info"]).arg(&dir).output().unwrap();
    assert!(text.status.success());
    let text = String::from_utf8(text.stdout).unwrap();
    assert!(text.contains("Truncated:         yes"), "{text}");
}

#[test]
fn info_names_a_file_that_is_not_a_bag() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("x.mcap");
    std::fs::write(&file, b"hello").unwrap();
    let out = waam().args(["bag", "info"]).arg(&file).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("x.mcap") && err.contains("not an MCAP file"),
        "{err}"
    );
    let out = waam()
        .args(["bag", "info"])
        .arg(tmp.path().join("missing"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
}
