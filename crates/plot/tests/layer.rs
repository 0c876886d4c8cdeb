//! The layer plots: PNG files of the requested size, a missing directory named.

use waam_layer::{search, Layer, Model, SearchOptions};

const PAPER: &str = include_str!("../../../config/layers/paper-16mm.yaml");

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
