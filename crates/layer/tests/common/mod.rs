//! This crate's test helpers: the repository root, and the helpers its tests share with the
//! other crates' and the CLI's (`tests/support/` at the root, with the sample parts in
//! `config/parts` and `tests/data`).
#![allow(dead_code, unused_imports)] // each test file uses a different subset

#[path = "../../../../tests/support/layers.rs"]
mod layers;
#[path = "../../../../tests/support/parts.rs"]
mod parts;
#[path = "../../../../tests/support/robots.rs"]
mod robots;

pub use layers::*;
pub use parts::*;
pub use robots::*;

use std::path::PathBuf;

/// The repository root (two folders above this crate).
pub fn root() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}
