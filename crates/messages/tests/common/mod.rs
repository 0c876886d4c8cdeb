//! This crate's test helpers: the repository root and the layers the tests share with the
//! other crates' and the CLI's (`tests/support/` at the root).
#![allow(dead_code)] // each test file uses a different subset

#[path = "../../../../tests/support/layers.rs"]
mod layers;

pub use layers::*;

use std::path::PathBuf;

/// The repository root (two folders above this crate).
pub fn root() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}
