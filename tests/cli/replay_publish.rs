//! `waam replay BAG --publish`: the recorded messages go out on ROS 2 topics with their
//! types and QoS, and a subscriber (`waam bag echo`, a separate process on its own DDS
//! participant) receives them as recorded.
//!
//! Isolation: as root, everything runs in a private network namespace (`unshare -n`) where
//! only loopback exists; otherwise on loopback-only discovery. Either way on a domain id of
//! its own, so no other DDS traffic on the machine is reached.

use serde_json::Value;
use waam_rosbag::Bag;
use waam_rosmsg::waam_interfaces::WeldPlan;

use crate::common;
use common::run::{run_isolated, waam};

#[test]
fn a_recording_plays_back_to_subscribers_as_recorded() {
    let tmp = tempfile::tempdir().unwrap();
    let bag_dir = tmp.path().join("session");
    let out = waam()
        .args(["bag", "sample", "--rounds", "2"])
        .arg(&bag_dir)
        .output()
        .unwrap();
    assert!(out.status.success());
    let d = tmp.path().display();
    let script = format!(
        r#"
"$W" bag echo /waam_planner/plan/weld_plan --type waam_interfaces/msg/WeldPlan --count 2 --timeout 30 > {d}/plans.jsonl &
P=$!
"$W" bag echo /joint_states --type sensor_msgs/msg/JointState --count 2 --timeout 30 --best-effort > {d}/joints.jsonl &
J=$!
"$W" replay {bag} --publish --delay 2 > {d}/replay.txt
wait $P
wait $J
"#,
        bag = bag_dir.display()
    );
    let out = run_isolated(tmp.path(), &script);
    let read = |name: &str| std::fs::read_to_string(tmp.path().join(name)).unwrap_or_default();
    assert!(
        out.status.success(),
        "{}\nreplay: {}\nstderr: {}",
        out.status,
        read("replay.txt"),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        read("replay.txt").contains("published 34 message(s) on 13 topic(s)"),
        "{}",
        read("replay.txt")
    );
    // The plans arrive whole and in order: the same content as recorded.
    let recorded: Vec<Value> = Bag::open(&bag_dir)
        .unwrap()
        .decode_all::<WeldPlan>()
        .unwrap()
        .into_iter()
        .map(|(_, _, plan)| serde_json::to_value(plan).unwrap())
        .collect();
    let received: Vec<Value> = read("plans.jsonl")
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(received, recorded);
    assert_eq!(read("joints.jsonl").lines().count(), 2);
}
