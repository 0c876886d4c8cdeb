//! What the robot welds is what was checked (#13), through the binary: `waam motion` refuses
//! a plan the torch cannot weld unless `--no-torch`, and `waam plan` with a slow robot learns
//! from the transit and says so; the library side is `crates/pipeline/tests/access.rs`.

use crate::common;

use common::root;
use common::run::waam;

#[test]
fn waam_motion_refuses_a_plan_the_torch_cannot_weld_unless_no_torch() {
    let part = root().join("config/parts/ex3-h-column.yaml");
    let plan = common::plan_path("ex3-h-column");
    let out = std::env::temp_dir().join(format!("waam-access-motion-{}", std::process::id()));
    let run = |extra: &[&str]| {
        waam()
            .args(["-q", "motion"])
            .arg(&part)
            .arg(&plan)
            .args(["--robot", "urdf/waam_robot.urdf", "--out"])
            .arg(&out)
            .args(extra)
            .current_dir(root())
            .output()
            .unwrap()
    };
    let refused = run(&[]);
    let stdout = String::from_utf8_lossy(&refused.stdout);
    assert_eq!(refused.status.code(), Some(1), "{stdout}");
    assert!(
        stdout.contains("TORCH BLOCKED")
            && stdout.contains("cannot reach block [1,2,0] (deposit 65 of 168)")
            && stdout.contains("block [0,0,5], deposited before it, stands in its way"),
        "{stdout}"
    );
    assert!(!out.join("trajectory.yaml").exists());
    let welded = run(&["--no-torch"]);
    assert_eq!(
        welded.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&welded.stderr)
    );
    assert!(out.join("trajectory.yaml").exists());
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn waam_plan_with_a_slow_robot_learns_from_the_transit_and_says_so() {
    let run = waam()
        .args([
            "plan",
            "tests/data/two-pads.yaml",
            "--robot",
            "urdf/waam_robot.urdf",
        ])
        .args([
            "--limits",
            "tests/data/slow_joint_limits.yaml",
            "--print-plan",
        ])
        .current_dir(root())
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr),
    );
    assert_eq!(run.status.code(), Some(0), "{stdout}{stderr}");
    assert!(
        stderr.contains("of the candidates fail on the time line the robot welds them on"),
        "{stderr}"
    );
    assert!(
        stdout.contains("plan: 2 fragment(s)") && stdout.contains("MOTION:"),
        "{stdout}"
    );
}
