//! Thick-wall layers through the binary (`waam layer plan --json --out`, `waam layer
//! plot`); the layer library's own tests are `crates/layer/tests/layer.rs`, the run behind
//! `layer plan` is `crates/wall/tests/layer_plan.rs`, the plots `crates/plot/tests/layer.rs`.

const PAPER: &str = include_str!("../../config/layers/paper-16mm.yaml");

#[test]
fn cli_plan_json_and_out_dir() {
    let dir = tempfile::tempdir().unwrap();
    let out = crate::common::run::waam()
        .args([
            "-q",
            "layer",
            "plan",
            "config/layers/paper-16mm.yaml",
            "--json",
            "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in [
        "objective",
        "proven_optimal",
        "gap",
        "nodes_explored",
        "seconds",
        "trail",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert_eq!(v["proven_optimal"], true);
    assert_eq!(v["trail"].as_array().unwrap().len(), 12);
    assert!(dir.path().join("trail.yaml").exists() && dir.path().join("layer.yaml").exists());
    let plot = crate::common::run::waam()
        .args(["-q", "layer", "plot"])
        .arg(dir.path())
        .args(["--node", "E"])
        .output()
        .unwrap();
    assert_eq!(
        plot.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&plot.stderr)
    );
    assert!(dir.path().join("trail.png").exists() && dir.path().join("temperature.png").exists());
    // Bad input: exit code 2 and the broken rule named.
    let bad = dir.path().join("bad.yaml");
    std::fs::write(&bad, PAPER.replace("  - [A, B]", "  - [A, Q]")).unwrap();
    let out = crate::common::run::waam()
        .args(["-q", "layer", "plan"])
        .arg(&bad)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("node Q is not in 'nodes'"));
}
