//! Thick-wall layers through the binary (`waam layer plan --json --out`), and the layer
//! plots (`waam-plot`, downstream of `waam-layer`); the layer library's own tests are
//! `crates/layer/tests/layer.rs`.

use waam_layer::{search, Layer, Model, SearchOptions};

const PAPER: &str = include_str!("../../config/layers/paper-16mm.yaml");

fn paper() -> Layer {
    Layer::parse(PAPER).expect("the bundled paper layer reads")
}

#[test]
fn plots_are_png_files_of_the_requested_size() {
    let model = Model::new(&paper()).unwrap();
    let r = search(&model, &SearchOptions::default());
    let dir = tempfile::tempdir().unwrap();
    let (trail_png, temp_png) = (dir.path().join("trail.png"), dir.path().join("temp.png"));
    waam_plot::layer::plot_trail(&model, &r.trail, &trail_png, (640, 480)).unwrap();
    let node = model.mesh.nearest([8.0, 8.0]);
    waam_plot::layer::plot_temperature(&model, &r.trail, node, &temp_png, (800, 500)).unwrap();
    for (path, (w, h)) in [(trail_png, (640u32, 480u32)), (temp_png, (800, 500))] {
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        let width = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
        let height = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
        assert_eq!((width, height), (w, h));
        assert!(bytes.len() > 5000, "{} looks empty", path.display());
    }
    let missing = dir.path().join("x.png");
    let err = waam_plot::layer::plot_temperature(&model, &r.trail, 10_000_000, &missing, (10, 10));
    assert!(err.unwrap_err().to_string().contains("does not exist"));
}

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
