//! The sample parts with valid plans (`tests/data/plans/`, each checked VALID by `waam check`)
//! and the robots here. Shared by the library crates' tests and the CLI's: each includes it
//! (`#[path]`) in its own `common` module, which supplies `root()`, the repository root.

use std::path::PathBuf;

use nalgebra::Isometry3;
use waam_motion::robot::{parse_xyz_rpy, Robot, TcpChoice};
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

/// The ABB arm's `tool0` has x out of the flange: the torch points along it.
pub const ABB_TCP: &str = "0.35 0 0 0 1.5707963267948966 0";

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

pub fn our_robot() -> Robot {
    let choice = TcpChoice {
        explicit: None,
        default: Isometry3::identity(),
    };
    Robot::from_urdf_file(&root().join("urdf/waam_robot.urdf"), None, choice).unwrap()
}

pub fn abb_robot() -> Robot {
    let choice = TcpChoice {
        explicit: Some(parse_xyz_rpy(ABB_TCP).unwrap()),
        default: Isometry3::identity(),
    };
    Robot::from_urdf_file(&root().join("tests/data/abb_irb1600_12.urdf"), None, choice).unwrap()
}
