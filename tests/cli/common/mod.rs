//! The one helper module of the CLI's tests (`tests/cli/`, one binary): the sample parts with
//! valid plans, the layers and the robots ([`parts`], [`layers`], [`robots`], shared with the library crates' tests,
//! `tests/support/`), [`planner`] for the planner tests, [`run`] for running `waam` (the one
//! `fn waam`) and reading its recordings.
#![allow(dead_code)] // each test module uses a different subset

#[path = "../../support/layers.rs"]
mod layers;
#[path = "../../support/parts.rs"]
mod parts;
#[path = "../../support/planner.rs"]
pub mod planner;
#[path = "../../support/robots.rs"]
mod robots;
pub mod run;

pub use layers::*;
pub use parts::*;
pub use robots::*;

use std::path::PathBuf;

/// The repository root (the `waam` package's directory).
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}
