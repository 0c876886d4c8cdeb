//! The sample parts with valid plans (`tests/data/plans/`, each checked VALID by `waam check`).
//! Shared by the library crates' tests and the CLI's: each includes it (`#[path]`) in its own
//! `common` module, which supplies `root()`, the repository root.

use std::path::PathBuf;

use waam_part::graph::WeldGraph;
use waam_part::plan::Plan;
use waam_part::Part;

use super::root;

/// The sample parts that have valid plans (s4-tee-k1 has none).
pub const PARTS: [&str; 9] = [
    "s1-wall",
    "s2-corner",
    "s3-ring",
    "s5-ledge",
    "s6-channel",
    "s7-pad",
    "ex1-plate-boss",
    "ex2-bracket",
    "ex3-h-column",
];

pub fn part(name: &str) -> Part {
    let path = root().join("config/parts").join(format!("{name}.yaml"));
    Part::from_bytes(&std::fs::read(&path).unwrap()).unwrap()
}

pub fn plan_path(name: &str) -> PathBuf {
    root().join("tests/data/plans").join(format!("{name}.yaml"))
}

/// The part and its plan as fragments of block indices.
pub fn part_and_plan(name: &str) -> (Part, Vec<Vec<usize>>) {
    let part = part(name);
    let plan = Plan::from_bytes(&std::fs::read(plan_path(name)).unwrap(), false).unwrap();
    let fragments = plan.validate(&part, &WeldGraph::new(&part)).unwrap();
    (part, fragments)
}
