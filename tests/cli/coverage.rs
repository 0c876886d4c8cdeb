//! The bead coverage check (`scripts/bead_coverage.py`): an STL sliced into beads, planned
//! and exported as G-code is checked by a program that slices the mesh itself (trimesh)
//! and widens every arc-on move to a bead (shapely): at least 92 % of every layer's
//! section covered on average, 85 % in each layer, at most 20 % of the beads outside.
//! Runs with `WAAM_COVERAGE_PYTHON` (the venv of `scripts/coverage-venv.sh`, which
//! `scripts/test.sh` exports); skipped without it.

use crate::common::run::run_at_root;

#[test]
fn a_round_tube_sliced_planned_and_exported_covers_its_sections() {
    let Some(python) = std::env::var_os("WAAM_COVERAGE_PYTHON") else {
        eprintln!("WAAM_COVERAGE_PYTHON is not set: skipping the bead coverage check");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    let mesh = "tests/data/round_tube.stl";
    let out = run_at_root(&[
        "plan", mesh, "--bead", "6 2.5", "-k", "2", "--first", "-q", "--out", d,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = run_at_root(&["export", d, "--format", "gcode"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let gcode = dir.path().join("WAAM.gcode");
    let out = std::process::Command::new(python)
        .current_dir(crate::common::root())
        .args([
            "scripts/bead_coverage.py",
            mesh,
            gcode.to_str().unwrap(),
            "--bead",
            "6 2.5",
            "--json",
        ])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "coverage below the thresholds: {stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Four layers of 2.5 mm in the 10 mm tube, each checked.
    let report: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    let layers = report["layers"].as_array().expect("per-layer figures");
    assert_eq!(layers.len(), 4, "{report}");
}
