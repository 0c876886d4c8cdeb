//! `waam sim-cell` through the binary (#31): the part planned by the pipeline, then welded
//! on a true cell with 25 % lower heat losses — open loop breaks a window, closed loop
//! keeps them all, and brings the height back — and a bad TRUTH.yaml named. The loop itself is tested in
//! `crates/cell/tests/`.

use crate::common::run::run_at_root;

const WALL: &str = "docs/examples/closed-loop/wall.yaml";
const TRUTH: &str = "docs/examples/closed-loop/truth.yaml";

fn sim_cell(extra: &[&str], out: &std::path::Path) -> (Option<i32>, String, String) {
    let out = out.to_str().unwrap();
    let mut args = vec!["sim-cell", WALL, "--truth", TRUTH, "--out", out];
    args.extend_from_slice(extra);
    let run = run_at_root(&args);
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    (run.status.code(), text(&run.stdout), text(&run.stderr))
}

#[test]
fn open_loop_breaks_a_window_on_the_true_cell_that_closed_loop_keeps() {
    let dir = tempfile::tempdir().unwrap();
    let (code, out, err) = sim_cell(&["--open-loop"], &dir.path().join("open"));
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(err.starts_with("planned: 1 weld path(s)"), "{err}");
    assert!(out.contains("TRUE MODEL: window of block"), "{out}");
    // Every bead 10 % low: open loop falls a quarter millimetre further behind each layer;
    // closed loop makes up the first layer's shortfall on the second.
    assert!(
        out.contains("height error per layer, mm: -0.25 -0.50 -0.75 -1.00\n"),
        "{out}"
    );
    let (code, out, err) = sim_cell(&[], &dir.path().join("closed"));
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(out.contains("TRUE MODEL: every t8/5 window kept"), "{out}");
    assert!(
        out.contains("height error per layer, mm: -0.25 +0.00 +0.00 +0.00\n"),
        "{out}"
    );
    assert!(err.contains("replan after"), "{err}");
    let executed = std::fs::read_to_string(dir.path().join("closed/executed.yaml")).unwrap();
    assert!(executed.contains("loop: closed"), "{executed}");
}

#[test]
fn a_truth_file_with_an_unknown_key_is_bad_input_named_by_file_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let truth = dir.path().join("truth.yaml");
    std::fs::write(&truth, "thermal: {bogus: 1}\n").unwrap();
    let out = dir.path().join("out");
    let run = run_at_root(&[
        "sim-cell",
        WALL,
        "--truth",
        truth.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{err}");
    assert!(
        err.contains("truth.yaml") && err.contains("unknown key 'bogus'"),
        "{err}"
    );
    assert!(!out.exists(), "nothing written for bad input");
}

/// The node's options without `--node` are bad input, named, and nothing is run or written
/// (clap's `requires` took `--node`'s default, false, as given).
#[test]
fn a_node_option_without_node_is_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    for (extra, flag) in [
        (&["--thermal-camera"][..], "--thermal-camera"),
        (&["--time-scale", "20"][..], "--time-scale"),
        (&["--ros-args", "-r", "__ns:=/cell1"][..], "--ros-args"),
    ] {
        let out = dir.path().join("out");
        let (code, stdout, err) = sim_cell(extra, &out);
        assert_eq!(code, Some(2), "{extra:?}: {stdout}{err}");
        assert!(err.contains(flag) && err.contains("--node"), "{err}");
        assert!(!out.exists(), "nothing written for bad input");
    }
}

/// `--robot`: each deposit made when the bundled robot's trajectory makes it (dwells and
/// moves included). On the twin walls (the windowed wall welded second) closed loop fits
/// the true losses exactly on that time line, re-plans at the weld-path boundary and keeps
/// every window; open loop breaks one. With `--node` it is bad input (the node follows the
/// planner's robot).
#[test]
fn on_a_robot_closed_loop_keeps_the_windows_open_loop_breaks() {
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &[&str], out: &str| {
        let out = dir.path().join(out);
        let mut args = vec![
            "sim-cell",
            "tests/data/twin-walls.yaml",
            "--truth",
            TRUTH,
            "--robot",
            "urdf/waam_robot.urdf",
        ];
        if !extra.contains(&"--node") {
            args.extend(["--out", out.to_str().unwrap()]);
        }
        args.extend_from_slice(extra);
        let run = run_at_root(&args);
        let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
        (run.status.code(), text(&run.stdout), text(&run.stderr))
    };
    let (code, out, err) = run(&[], "closed");
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(
        err.contains("robot: each deposit made when its trajectory makes it"),
        "{err}"
    );
    assert!(
        err.contains("replan after 24 deposits: loss x0.750, conduction x1.000"),
        "{err}"
    );
    assert!(out.contains("TRUE MODEL: every t8/5 window kept"), "{out}");
    let (code, out, err) = run(&["--open-loop"], "open");
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(out.contains("TRUE MODEL: window of block"), "{out}");
    let (code, out, err) = run(&["--node"], "node");
    assert_eq!(code, Some(2), "{out}{err}");
    assert!(
        err.contains("--robot is for the simulated cell without --node"),
        "{err}"
    );
}
