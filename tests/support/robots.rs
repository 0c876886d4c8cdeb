//! The robots of the tests: ours (`urdf/`) and an ABB arm (`tests/data/`). Shared by the
//! library crates' tests and the CLI's: each includes it (`#[path]`) in its own `common`
//! module, which supplies `root()`, the repository root.

use nalgebra::Isometry3;
use waam_motion::robot::{parse_xyz_rpy, Robot, TcpChoice};

use super::root;

/// The ABB arm's `tool0` has x out of the flange: the torch points along it.
pub const ABB_TCP: &str = "0.35 0 0 0 1.5707963267948966 0";

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
