//! Test helpers: the sample parts with valid plans (`tests/data/plans/`, each checked
//! VALID by `waam check`) and the robots.
#![allow(dead_code)]

use std::path::PathBuf;

use nalgebra::Isometry3;
use waam::graph::WeldGraph;
use waam::part::Part;
use waam::plan::Plan;
use waam::robot::{parse_xyz_rpy, Robot, TcpChoice};

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The sample parts that have valid plans (s4-tee-k1 has none).
pub const PARTS: [&str; 9] = [
    "s1-wall",
    "s2-corner",
    "s3-ring",
    "s5-ledge",
    "s6-channel",
    "s7-pad",
    "ex1-plate-boss",
    "ex2-bracket",
    "ex3-h-column",
];

/// The ABB arm's `tool0` has x out of the flange: the torch points along it.
pub const ABB_TCP: &str = "0.35 0 0 0 1.5707963267948966 0";

pub fn part(name: &str) -> Part {
    let path = root().join("config/parts").join(format!("{name}.yaml"));
    Part::from_bytes(&std::fs::read(&path).unwrap()).unwrap()
}

pub fn plan_path(name: &str) -> PathBuf {
    root().join("tests/data/plans").join(format!("{name}.yaml"))
}

/// The part and its plan as fragments of block indices.
pub fn part_and_plan(name: &str) -> (Part, Vec<Vec<usize>>) {
    let part = part(name);
    let plan = Plan::from_bytes(&std::fs::read(plan_path(name)).unwrap(), false).unwrap();
    let fragments = plan.validate(&part, &WeldGraph::new(&part)).unwrap();
    (part, fragments)
}

pub fn our_robot() -> Robot {
    let choice = TcpChoice {
        explicit: None,
        default: Isometry3::identity(),
    };
    Robot::from_urdf_file(&root().join("urdf/waam_robot.urdf"), None, choice).unwrap()
}

pub fn abb_robot() -> Robot {
    let choice = TcpChoice {
        explicit: Some(parse_xyz_rpy(ABB_TCP).unwrap()),
        default: Isometry3::identity(),
    };
    Robot::from_urdf_file(&root().join("tests/data/abb_irb1600_12.urdf"), None, choice).unwrap()
}

// --- helpers of the recording tests ---

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub fn waam() -> Command {
    Command::new(env!("CARGO_BIN_EXE_waam"))
}

/// Messages `metadata.yaml` says were on disk at its last refresh.
pub fn flushed_messages(dir: &Path) -> u64 {
    std::fs::read_to_string(dir.join("metadata.yaml"))
        .ok()
        .and_then(|t| serde_yaml::from_str::<serde_yaml::Value>(&t).ok())
        .and_then(|v| v["rosbag2_bagfile_information"]["message_count"].as_u64())
        .unwrap_or(0)
}

/// Starts a recording that runs until killed, waits (bounded) until at least `at_least`
/// messages are flushed, then kills it with SIGKILL. Returns the count flushed before the kill.
pub fn kill_a_recording(dir: &Path, at_least: u64) -> u64 {
    let mut child: Child = waam()
        .args([
            "bag",
            "sample",
            "--rounds",
            "0",
            "--period-ms",
            "2",
            "--chunk-age-ms",
            "50",
        ])
        .arg(dir)
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while flushed_messages(dir) < at_least {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "recording never flushed"
        );
        if let Some(status) = child.try_wait().unwrap() {
            panic!("recording exited early: {status}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    // Let a few more chunks close, then kill mid-chunk.
    std::thread::sleep(Duration::from_millis(150));
    child.kill().unwrap(); // SIGKILL on Unix
    child.wait().unwrap();
    flushed_messages(dir)
}
