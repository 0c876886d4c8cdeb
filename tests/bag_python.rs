//! Recordings read by the Python tools cells use: `mcap` + `mcap-ros2-support` decode every
//! message from the schemas in the file, `rosbags` opens the directory as a rosbag2 bag with
//! MCAP storage. The venv comes from `scripts/py-venv.sh`; the test script exports its python
//! as `WAAM_BAG_PYTHON`.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

mod common;

/// The venv's python, or `None` when the caller asked to skip (`WAAM_SKIP_PY=1`).
fn python() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("WAAM_BAG_PYTHON") {
        return Some(PathBuf::from(p));
    }
    if std::env::var("WAAM_SKIP_PY").as_deref() == Ok("1") {
        eprintln!("WAAM_SKIP_PY=1: skipping the Python reader test");
        return None;
    }
    panic!(
        "WAAM_BAG_PYTHON is not set. Run the tests through scripts/test.sh, or \
         `export WAAM_BAG_PYTHON=$(scripts/py-venv.sh | tail -1)` first \
         (or set WAAM_SKIP_PY=1 to skip the Python reader tests)."
    );
}

fn script(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/py")
        .join(name)
}

fn run_python(python: &Path, args: &[&std::ffi::OsStr]) -> Value {
    let out = Command::new(python).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{} failed:\n{}\n{}",
        args[0].to_string_lossy(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn python_readers_decode_every_message_of_a_session() {
    let Some(python) = python() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("session");
    let stdout = common::run::run_ok(
        common::run::waam()
            .args(["bag", "sample", "--rounds", "3"])
            .arg(&dir),
    );
    let expected = tmp.path().join("expected.json");
    std::fs::write(&expected, &stdout).unwrap();
    let report = run_python(
        &python,
        &[
            script("check_session.py").as_os_str(),
            dir.as_os_str(),
            expected.as_os_str(),
        ],
    );
    assert_eq!(report["problems"], Value::Array(vec![]));
    assert_eq!(report["mcap"]["/waam_planner/plan/weld_plan"], 3);
    assert_eq!(report["rosbags"]["/waam_planner/planner/heat"], 3 * 4);
}

#[test]
fn python_mcap_reads_a_killed_recording_like_we_do() {
    let Some(python) = python() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("killed");
    let flushed = common::run::kill_a_recording(&dir, 300);
    let file = dir.join("killed_0.mcap");
    let ours = waam_rosbag::Bag::open(&file).unwrap();
    assert!(ours.truncated.is_some());
    let theirs = run_python(
        &python,
        &[script("read_truncated.py").as_os_str(), file.as_os_str()],
    );
    let n = theirs["messages"].as_u64().unwrap();
    assert!(n >= flushed, "python read {n} of {flushed} flushed");
    assert_eq!(n, ours.messages.len() as u64, "{theirs}");
    assert_eq!(
        theirs["last_log_time"].as_u64(),
        ours.messages.last().map(|m| m.log_time)
    );
}

/// A real planning session (`waam plan --robot --record`): the part, statuses, every
/// candidate's verdict, the motion and the heat frames decode with both Python readers, in
/// the counts the planner reported.
#[test]
fn python_readers_decode_a_planning_session_with_motion() {
    let Some(python) = python() else { return };
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("session");
    let stdout = common::run::run_ok(
        common::run::waam()
            .args(["-q", "plan", "--json", "--robot"])
            .arg(root.join("urdf/waam_robot.urdf"))
            .arg("--record")
            .arg(&dir)
            .arg(root.join("config/parts/s3-ring.yaml")),
    );
    let report = common::run::last_json(&stdout);
    let candidates = report["stats"]["candidates"].as_u64().unwrap();
    // The heat frames are as many as the simulation makes; everything else is known.
    let heat = waam_rosbag::Bag::open(&dir)
        .unwrap()
        .topics
        .iter()
        .find(|t| t.name == "/waam_planner/planner/heat")
        .map_or(0, |t| t.count);
    assert!(heat > 0, "no heat frames recorded");
    let expected = serde_json::json!({
        "/waam_planner/part": {"type": "std_msgs/msg/String", "count": 1},
        "/waam_planner/status": {"type": "diagnostic_msgs/msg/DiagnosticArray", "count": 2},
        "/waam_planner/planner/candidates":
            {"type": "waam_interfaces/msg/PlanCandidate", "count": candidates},
        "/waam_planner/plan/joint_trajectory":
            {"type": "trajectory_msgs/msg/JointTrajectory", "count": 1},
        "/waam_planner/plan/poses": {"type": "geometry_msgs/msg/PoseArray", "count": 1},
        "/waam_planner/plan/path": {"type": "nav_msgs/msg/Path", "count": 1},
        "/waam_planner/plan/markers": {"type": "visualization_msgs/msg/MarkerArray", "count": 1},
        "/waam_planner/plan/weld_plan": {"type": "waam_interfaces/msg/WeldPlan", "count": 1},
        "/waam_planner/planner/heat": {"type": "sensor_msgs/msg/PointCloud2", "count": heat},
        "/tf_static": {"type": "tf2_msgs/msg/TFMessage", "count": 1},
        "/robot_description": {"type": "std_msgs/msg/String", "count": 1},
    });
    let expected_file = tmp.path().join("expected.json");
    std::fs::write(&expected_file, expected.to_string()).unwrap();
    let report = run_python(
        &python,
        &[
            script("check_session.py").as_os_str(),
            dir.as_os_str(),
            expected_file.as_os_str(),
        ],
    );
    assert_eq!(report["problems"], Value::Array(vec![]));
    assert_eq!(
        report["rosbags"]["/waam_planner/planner/candidates"],
        candidates
    );
}
