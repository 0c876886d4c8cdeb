//! The layers of the tests: a bundled layer file's heat model and a valid trail of it, fast.
//! Shared by the library crates' tests and the CLI's: each includes it (`#[path]`) in its own
//! `common` module, which supplies `root()`, the repository root.

use std::time::Duration;

use waam_layer::{search, Layer, Model, SearchOptions, SearchResult};

use super::root;

/// The heat model of the layer file `file` (relative to the repository root).
pub fn layer_model(file: &str) -> Model {
    let text = std::fs::read_to_string(root().join(file)).unwrap();
    Model::new(&Layer::parse(&text).unwrap()).unwrap()
}

/// A valid trail fast (the optimum is not what these tests are about).
pub fn quick_search(model: &Model) -> SearchResult {
    let r = search(
        model,
        &SearchOptions {
            time_limit: Some(Duration::from_millis(300)),
            ..SearchOptions::default()
        },
    );
    model.check_trail(&r.trail).unwrap();
    r
}
