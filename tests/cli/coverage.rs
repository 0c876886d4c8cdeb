//! The bead coverage check (`scripts/bead_coverage.py`): an STL sliced into beads, planned
//! and exported as G-code is checked by a program that slices the mesh itself (trimesh)
//! and widens every run of arc-on moves to a bead (shapely): at least 92 % of every layer's
//! section covered on average, 85 % in each layer, at most 20 % of the beads outside.
//! Runs with `WAAM_COVERAGE_PYTHON` (the venv of `scripts/coverage-venv.sh`, which
//! `scripts/test.sh` exports); skipped without it.

use std::ffi::{OsStr, OsString};
use std::path::Path;

use crate::common::run::run_at_root;

/// Plans `mesh` as 6 x 2.5 mm beads with at most `k` weld paths, exports G-code into `dir`
/// and checks its coverage; the per-layer report (panics naming the mesh below the bar).
fn plan_export_cover(python: &OsStr, mesh: &str, k: &str, dir: &Path) -> serde_json::Value {
    let d = dir.to_str().unwrap();
    let out = run_at_root(&[
        "plan", mesh, "--bead", "6 2.5", "-k", k, "--first", "-q", "--out", d,
    ]);
    assert!(
        out.status.success(),
        "{mesh}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = run_at_root(&["export", d, "--format", "gcode"]);
    assert!(
        out.status.success(),
        "{mesh}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let gcode = dir.join("WAAM.gcode");
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
        "{mesh}: coverage below the thresholds: {stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(stdout.trim()).unwrap()
}

fn coverage_python() -> Option<OsString> {
    let python = std::env::var_os("WAAM_COVERAGE_PYTHON");
    if python.is_none() {
        eprintln!("WAAM_COVERAGE_PYTHON is not set: skipping the bead coverage check");
    }
    python
}

#[test]
fn a_round_tube_sliced_planned_and_exported_covers_its_sections() {
    let Some(python) = coverage_python() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let report = plan_export_cover(&python, "tests/data/round_tube.stl", "2", dir.path());
    // Four layers of 2.5 mm in the 10 mm tube, each checked.
    let layers = report["layers"].as_array().expect("per-layer figures");
    assert_eq!(layers.len(), 4, "{report}");
}

/// Parts the slicer was not written for (`scripts/round_shapes.py`): an elliptical cup, a
/// cone wall leaning in, a plate with round bosses, a tube with a rib across it, two tubes
/// 1 mm apart.
#[test]
fn other_round_parts_cover_their_sections() {
    let Some(python) = coverage_python() else {
        return;
    };
    let shapes = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(&python)
        .current_dir(crate::common::root())
        .arg("scripts/round_shapes.py")
        .arg(shapes.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for (name, k, layers) in [
        ("elliptical_cup", "3", 16),
        ("leaning_cone", "2", 18),
        ("plate_bosses", "6", 10),
        ("ribbed_tube", "4", 16),
        ("double_tube", "2", 4),
    ] {
        let mesh = shapes.path().join(format!("{name}.stl"));
        let dir = tempfile::tempdir().unwrap();
        let report = plan_export_cover(&python, mesh.to_str().unwrap(), k, dir.path());
        let checked = report["layers"].as_array().expect("per-layer figures");
        assert_eq!(checked.len(), layers, "{name}: {report}");
        if name == "ribbed_tube" {
            ribbed_tube_section_holds_the_rib(checked);
        }
        if name == "double_tube" {
            // No material joins the tubes: one weld path each, none stepping across the
            // gap (main welded both as one, across the gap every layer: 0.3 % outside).
            let plan = std::fs::read_to_string(dir.path().join("plan.yaml")).unwrap();
            let paths = plan.lines().filter(|l| l.starts_with("  - [")).count();
            assert_eq!(paths, 2, "{plan}");
            for l in checked {
                assert!(l["outside"].as_f64().unwrap() < 1e-3, "double tube: {l}");
            }
        }
    }
}

/// The ribbed tube is two closed bodies that overlap (a tube r 30/24, a 6 mm rib whose
/// corners touch its inner wall, both 128-gons as `round_shapes.py` makes them): every
/// section is the ring and the rib. The checker once lost the rib (trimesh's `polygons_full`
/// nested it under the tube) and counted it as welded outside: 23 % outside, though no
/// weld left the material. Its beads cover it, with little outside.
fn ribbed_tube_section_holds_the_rib(layers: &[serde_json::Value]) {
    let gon = |r: f64| 0.5 * 128.0 * r * r * (std::f64::consts::TAU / 128.0).sin();
    let rib = 2.0 * (24.0f64 * 24.0 - 3.0 * 3.0).sqrt() * 6.0;
    let expected = gon(30.0) - gon(24.0) + rib;
    for l in layers {
        let area = l["section_mm2"].as_f64().unwrap();
        assert!(
            (area - expected).abs() < 0.01 * expected,
            "ribbed tube: section {area} mm2, the ring and the rib are {expected}: {l}"
        );
        let outside = l["outside"].as_f64().unwrap();
        assert!(outside <= 0.05, "ribbed tube: {l}");
    }
}
