//! ROS 2 interop: `waam node` against rclpy from ROS 2 Jazzy's PyPI wheels.
//!
//! Each test runs one script of `tests/ros/` with the venv's Python. The venv comes from
//! `scripts/ros-venv.sh`, which the project's test script runs and whose path it passes in
//! `WAAM_ROS_VENV`. Without it these tests fail with a message saying so, unless
//! `WAAM_SKIP_ROS=1` asks to skip them.
//!
//! Isolation: as root, each script runs in a private network namespace (`unshare -n`) where
//! only loopback exists; otherwise on loopback-only discovery. Either way with a domain id of
//! its own, so parallel tests and other DDS traffic on the machine never meet.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicU16, Ordering};
use std::sync::OnceLock;

/// The venv's Python, or `None` when the ROS tests are to be skipped.
fn ros_python() -> Option<PathBuf> {
    match std::env::var_os("WAAM_ROS_VENV") {
        Some(venv) => {
            let python = Path::new(&venv).join("bin/python");
            assert!(
                python.exists(),
                "WAAM_ROS_VENV={} has no bin/python: run scripts/ros-venv.sh",
                Path::new(&venv).display()
            );
            Some(python)
        }
        None if std::env::var("WAAM_SKIP_ROS").as_deref() == Ok("1") => {
            eprintln!("skipped: WAAM_SKIP_ROS=1");
            None
        }
        None => panic!(
            "the ROS 2 interop tests need rclpy: run `scripts/ros-venv.sh` and set \
             WAAM_ROS_VENV to the path it prints (scripts/test.sh does both), or set \
             WAAM_SKIP_ROS=1 to skip them"
        ),
    }
}

/// Whether `unshare -n` works here (root, and a kernel that allows network namespaces).
fn have_netns() -> bool {
    static NETNS: OnceLock<bool> = OnceLock::new();
    *NETNS.get_or_init(|| {
        Command::new("unshare")
            .args(["-n", "ip", "link", "set", "lo", "up"])
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

/// A domain id no other test of this run uses (and, by the pid, unlikely any other run).
fn fresh_domain_id() -> u16 {
    static NEXT: AtomicU16 = AtomicU16::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    1 + (std::process::id() as u16 % 40) * 5 + n % 5 + (n / 5) * 200 % 230
}

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Runs `tests/ros/SCRIPT` (Python) isolated, with `WAAM_BIN` set; panics with its output
/// unless it exits 0. `None` when the ROS tests are skipped.
fn run_script(script: &str, args: &[&str]) -> Option<Output> {
    let python = ros_python()?;
    let script_path = repo().join("tests/ros").join(script);
    let mut command = if have_netns() {
        let mut c = Command::new("unshare");
        c.arg("-n")
            .arg(repo().join("tests/ros/netns.sh"))
            .arg(&python);
        c
    } else {
        eprintln!("note: no network namespace (not root?): using loopback-only discovery");
        Command::new(&python)
    };
    let domain = fresh_domain_id();
    command
        .arg(&script_path)
        .args(args)
        .current_dir(repo())
        .env("WAAM_BIN", env!("CARGO_BIN_EXE_waam"))
        .env("ROS_DOMAIN_ID", domain.to_string())
        .env("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        .env_remove("ROS_LOCALHOST_ONLY")
        .env_remove("ROS_STATIC_PEERS");
    let output = command
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", python.display()));
    let text = format!(
        "{script} (domain {domain}) exited with {}\n--- stdout ---\n{}\n--- stderr ---\n{}",
        output.status,
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(output.status.success(), "{text}");
    eprintln!("{text}");
    Some(output)
}

#[test]
fn rclpy_part_reaches_the_node() {
    run_script("echo.py", &[]);
}
