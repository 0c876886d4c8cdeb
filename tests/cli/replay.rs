//! `waam replay` on recordings made by `waam plan --record`: identical plans, a doctored
//! recording, a truncated one, and a re-planned session recorded again.

use std::path::Path;

use serde_json::Value;
use waam_messages::topics;
use waam_rosbag::Bag;
use waam_rosmsg::std_msgs::String as RosString;
use waam_rosmsg::to_cdr;

use crate::common;
use common::run::{copy_bag, run_ok, waam};

const PART: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/config/parts/s1-wall.yaml");

fn record_plan(dir: &Path) {
    run_ok(waam().args(["-q", "plan", PART, "--record"]).arg(dir));
}

fn replay(bag: &Path, extra: &[&str]) -> (i32, Value) {
    let out = waam()
        .args(["replay", "--json"])
        .args(extra)
        .arg(bag)
        .output()
        .unwrap();
    let json = serde_json::from_slice(&out.stdout).unwrap_or_else(|_| {
        panic!(
            "no JSON: {}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    });
    (out.status.code().unwrap(), json)
}

/// Copies a recording, passing each part document through `doctor`.
fn copy_doctored(from: &Path, to: &Path, doctor: impl Fn(&str) -> String) {
    copy_bag(from, to, |topic, data| {
        if topic == topics::PART {
            let part: RosString = waam_rosmsg::from_cdr(data).unwrap();
            Some(to_cdr(&RosString::from(doctor(&part.data).as_str())).unwrap())
        } else {
            Some(data.to_vec())
        }
    });
}

#[test]
fn a_recorded_plan_replays_identically_and_a_doctored_part_does_not() {
    let tmp = tempfile::tempdir().unwrap();
    let recorded = tmp.path().join("recorded");
    record_plan(&recorded);
    let (code, report) = replay(&recorded, &[]);
    assert_eq!(code, 0, "{report}");
    assert_eq!(report["identical"], 1);
    assert_eq!(report["different"], 0);
    assert_eq!(report["cases"][0]["part"], "s1-wall");

    // One block of the top layer removed from the recorded part.
    let doctored = tmp.path().join("doctored");
    copy_doctored(&recorded, &doctored, |text| {
        let at = text.rfind("    ####").expect("the top layer");
        format!("{}    ###.{}", &text[..at], &text[at + 8..])
    });
    let (code, report) = replay(&doctored, &[]);
    assert_eq!(code, 1, "{report}");
    assert_eq!(report["different"], 1);
    let details: Vec<&str> = report["cases"][0]["details"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d.as_str().unwrap())
        .collect();
    assert!(
        details
            .iter()
            .any(|d| d.starts_with("first differing block: fragment")),
        "{details:?}"
    );
    // The text report says so too.
    let out = waam().arg("replay").arg(&doctored).output().unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("part 1 (s1-wall): DIFFERENT"), "{text}");
    assert!(text.contains("0 identical, 1 different"), "{text}");
}

#[test]
fn a_part_that_no_longer_reads_is_a_difference() {
    let tmp = tempfile::tempdir().unwrap();
    let recorded = tmp.path().join("recorded");
    record_plan(&recorded);
    let broken = tmp.path().join("broken");
    copy_doctored(&recorded, &broken, |text| {
        text.replace("max_fragments: 2", "max_fragments: -1")
    });
    let (code, report) = replay(&broken, &[]);
    assert_eq!(code, 1, "{report}");
    let detail = report["cases"][0]["details"][0].as_str().unwrap();
    assert!(
        detail.contains("re-planning finds none") && detail.contains("max_fragments"),
        "{detail}"
    );
}

#[test]
fn a_truncated_recording_is_replayed_and_said_to_be_truncated() {
    let tmp = tempfile::tempdir().unwrap();
    let recorded = tmp.path().join("recorded");
    record_plan(&recorded);
    // Cut the summary and footer off, as a killed process would leave it.
    let file = recorded.join("recorded_0.mcap");
    let bytes = std::fs::read(&file).unwrap();
    std::fs::write(&file, &bytes[..bytes.len() - 40]).unwrap();
    let (code, report) = replay(&recorded, &[]);
    assert_eq!(code, 0, "{report}");
    assert!(report["truncated"].is_string(), "{report}");
    assert_eq!(report["identical"], 1);
    let out = waam().arg("replay").arg(&recorded).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("is truncated"));
}

#[test]
fn the_replanned_session_is_recorded_and_replays_identically() {
    let tmp = tempfile::tempdir().unwrap();
    let recorded = tmp.path().join("recorded");
    record_plan(&recorded);
    let again = tmp.path().join("again");
    let (code, _) = replay(&recorded, &["--record", again.to_str().unwrap()]);
    assert_eq!(code, 0);
    let original = Bag::open(&recorded).unwrap();
    let copy = Bag::open(&again).unwrap();
    let names = |b: &Bag| {
        let mut t: Vec<(String, u64)> =
            b.topics.iter().map(|t| (t.name.clone(), t.count)).collect();
        t.sort();
        t
    };
    assert_eq!(names(&original), names(&copy));
    let (code, report) = replay(&again, &[]);
    assert_eq!(code, 0, "{report}");
    assert_eq!(report["identical"], 1);
}

#[test]
fn a_bag_without_parts_is_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("empty");
    let out = waam()
        .args(["bag", "sample", "--rounds", "1"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(out.status.success());
    // The sample has parts; strip them.
    let stripped = tmp.path().join("stripped");
    copy_bag(&dir, &stripped, |topic, data| {
        (topic != topics::PART && topic != topics::PART_MESH).then(|| data.to_vec())
    });
    let out = waam().arg("replay").arg(&stripped).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("holds no part"));
}

#[test]
fn a_part_planned_from_an_stl_mesh_replays_from_its_voxelized_document() {
    let tmp = tempfile::tempdir().unwrap();
    let recorded = tmp.path().join("mesh");
    let stl = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/box_binary.stl");
    run_ok(
        waam()
            .args([
                "-q", "plan", stl, "--pitch", "6 6 2.5", "-k", "4", "--record",
            ])
            .arg(&recorded),
    );
    let bag = Bag::open(&recorded).unwrap();
    let part: RosString = bag.decode_all::<RosString>().unwrap().remove(0).2;
    assert!(part.data.contains("name:"), "{}", part.data);
    let (code, report) = replay(&recorded, &[]);
    assert_eq!(code, 0, "{report}");
    assert_eq!(report["identical"], 1);
}

#[test]
fn replay_plans_with_the_recorded_settings() {
    let tmp = tempfile::tempdir().unwrap();
    let recorded = tmp.path().join("eager");
    run_ok(
        waam()
            .args([
                "-q",
                "plan",
                PART,
                "--acyclicity",
                "eager",
                "--max-fragments",
                "3",
                "--record",
            ])
            .arg(&recorded),
    );
    let (code, report) = replay(&recorded, &[]);
    assert_eq!(code, 0, "{report}");
    assert_eq!(report["identical"], 1);
}

/// Issue #18: a truncated recording that kept a part but none of its outcomes left
/// nothing to compare, and replay exited 0 as if it had passed; now it is exit 2.
#[test]
fn a_recording_with_nothing_to_compare_is_not_a_pass() {
    let tmp = tempfile::tempdir().unwrap();
    let recorded = tmp.path().join("recorded");
    record_plan(&recorded);
    let parts_only = tmp.path().join("parts_only");
    copy_bag(&recorded, &parts_only, |topic, data| {
        (topic == topics::PART).then(|| data.to_vec())
    });
    let (code, report) = replay(&parts_only, &[]);
    assert_eq!(code, 2, "{report}");
    assert_eq!(report["skipped"], 1, "{report}");
    assert_eq!(report["identical"], 0, "{report}");
}
