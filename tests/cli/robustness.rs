//! No input makes `waam` panic, through the binary: `waam plot` on poses and times at the
//! ends of f64, `plan --max-fragments 0`; the readers' own robustness tests are
//! `crates/ros/tests/robustness.rs`.

use std::time::Instant;

use crate::common::run::run_at_root;

/// Issue #18, P4: a toolpath pose at .inf, 1e308 or .nan tripped a plotters assertion in
/// `waam plot`; now it is a one-line error naming the pose, exit 2.
#[test]
fn a_toolpath_pose_at_inf_or_nan_is_refused_by_plot_naming_the_pose() {
    for bad in [".inf", "1.0e308", ".nan", "-.inf"] {
        let dir = tempfile::tempdir().unwrap();
        let yaml = format!(
            "frame: world\nposes:\n\
             - {{time: 0.0, position: [0.1, 0.2, 0.3], orientation: [0, 0, 0, 1], arc_on: false, fragment: 0}}\n\
             - {{time: 1.0, position: [0.1, {bad}, 0.3], orientation: [0, 0, 0, 1], arc_on: true, fragment: 0}}\n"
        );
        std::fs::write(dir.path().join("toolpath.yaml"), yaml).unwrap();
        let t = Instant::now();
        let out = run_at_root(&["plot", dir.path().to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad}: {err}");
        assert!(err.contains("toolpath pose 1:"), "{bad}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{bad}: {err}");
        assert!(t.elapsed().as_secs() < 10, "{bad}: {:?}", t.elapsed());
    }
}

/// Issue #18, H3: `block_time_s: 1e308` made `waam plot` loop for ever in plotters' axis
/// code; now the time axis is checked first and the error names the thermal keys.
#[test]
fn a_block_time_of_1e308_makes_plot_refuse_the_time_axis() {
    let dir = tempfile::tempdir().unwrap();
    let part = "name: h3\nblock_mm: [6, 6, 2.5]\nmax_fragments: 1\nblocks: [[0,0,0],[1,0,0]]\n\
                t85: [{block: [1,0,0], min_s: 0, max_s: 100}]\nthermal: {block_time_s: 1.0e308}\n";
    std::fs::write(dir.path().join("part.yaml"), part).unwrap();
    std::fs::write(
        dir.path().join("plan.yaml"),
        "fragments:\n  - [[0,0,0],[1,0,0]]\n",
    )
    .unwrap();
    let t = Instant::now();
    let out = run_at_root(&["plot", dir.path().to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("time (s) axis") && err.contains("thermal.block_time_s = 1e308"),
        "{err}"
    );
    assert!(t.elapsed().as_secs() < 20, "{:?}", t.elapsed());
}

/// Issue #18: `plan --max-fragments 0` said "every plan breaks a window" (exit 1); it is
/// bad input (exit 2) naming the option.
#[test]
fn max_fragments_zero_is_bad_input() {
    let out = run_at_root(&[
        "plan",
        "config/parts/s1-wall.yaml",
        "--max-fragments",
        "0",
        "-q",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--max-fragments") && err.contains("at least 1"),
        "{err}"
    );
}
