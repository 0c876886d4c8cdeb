//! Running `waam` and handling its recordings (bag, bag_python, replay, replay_publish,
//! layer_motion, ros_node, ...).

use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The `waam` binary, as a command to run: the only place the tests name it.
pub fn waam() -> Command {
    Command::new(env!("CARGO_BIN_EXE_waam"))
}

/// `waam ARGS` run from the repository root (relative paths in ARGS are the repo's), its
/// output (cli_motion, export, robustness).
pub fn run_at_root(args: &[&str]) -> Output {
    waam()
        .args(args)
        .current_dir(super::root())
        .output()
        .unwrap()
}

/// `waam ARGS` with `RUST_LOG=warn`, its output (planner, torch).
pub fn run_quiet(args: &[&str]) -> Output {
    waam()
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .expect("the waam binary runs")
}

/// Runs `command`, panicking with its stderr unless it succeeds; its stdout.
pub fn run_ok(command: &mut Command) -> String {
    let out = command.output().unwrap();
    assert!(
        out.status.success(),
        "{:?} failed: {}",
        command,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// The JSON object a `--json` run prints on its last line (a summary may come before it).
pub fn last_json(stdout: &str) -> serde_json::Value {
    let line = stdout.lines().last().unwrap_or_default();
    serde_json::from_str(line).unwrap_or_else(|_| panic!("no JSON at the end of: {stdout}"))
}

/// Copies a recording message by message, passing each message's CDR bytes through
/// `doctor(topic, bytes)`; a message it maps to `None` is left out.
pub fn copy_bag(from: &Path, to: &Path, doctor: impl Fn(&str, &[u8]) -> Option<Vec<u8>>) {
    let bag = waam_rosbag::Bag::open(from).unwrap();
    let recorder = waam_rosbag::Recorder::create(to).unwrap();
    for m in &bag.messages {
        let t = bag.topic_of(m);
        let Some(data) = doctor(&t.name, &m.data) else {
            continue;
        };
        recorder
            .record_raw(
                &t.name,
                &t.type_name,
                &t.definition,
                &t.type_hash,
                &t.offered_qos,
                m.log_time,
                &data,
            )
            .unwrap();
    }
    recorder.finish().unwrap();
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

/// Whether `unshare -n` works here (root, and a kernel that allows network namespaces).
pub fn have_netns() -> bool {
    Command::new("unshare")
        .args(["-n", "ip", "link", "set", "lo", "up"])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Runs `script` (bash) with `$W` = the waam binary, isolated from other DDS traffic: as
/// root in a private network namespace (`unshare -n`) where only loopback exists, otherwise
/// on loopback-only discovery; either way on a domain id of its own (from the pid).
pub fn run_isolated(dir: &Path, script: &str) -> std::process::Output {
    let setup = "ip link set lo up; ip link set lo multicast on; \
                 ip route add 224.0.0.0/4 dev lo 2>/dev/null || true\n";
    let path = dir.join("run.sh");
    let domain = 100 + std::process::id() % 100;
    if have_netns() {
        std::fs::write(&path, format!("set -e\n{setup}{script}")).unwrap();
        Command::new("unshare")
            .args(["-n", "bash"])
            .arg(&path)
            .env("W", env!("CARGO_BIN_EXE_waam"))
            .env("ROS_DOMAIN_ID", domain.to_string())
            .env("RUST_LOG", "warn")
            .output()
            .unwrap()
    } else {
        std::fs::write(&path, format!("set -e\n{script}")).unwrap();
        Command::new("bash")
            .arg(&path)
            .env("W", env!("CARGO_BIN_EXE_waam"))
            .env("ROS_DOMAIN_ID", domain.to_string())
            .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
            .env("RUST_LOG", "warn")
            .output()
            .unwrap()
    }
}
