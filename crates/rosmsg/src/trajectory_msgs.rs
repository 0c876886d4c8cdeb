//! `trajectory_msgs`: joint trajectories.

use serde::{Deserialize, Serialize};

use super::builtin_interfaces::Duration;
use super::ros_message;
use super::std_msgs::Header;

/// A joint trajectory: joint names and the points to pass through.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointTrajectory {
    pub header: Header,
    pub joint_names: Vec<String>,
    pub points: Vec<JointTrajectoryPoint>,
}
ros_message!(
    JointTrajectory,
    "trajectory_msgs/msg/JointTrajectory",
    "RIHS01_179b33eba59d676f6d967ac71fe35e7ca2f64b2f3928f4a018cec115e213796e"
);

/// One point of a joint trajectory (radians, rad/s; empty vectors when not given).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointTrajectoryPoint {
    pub positions: Vec<f64>,
    pub velocities: Vec<f64>,
    pub accelerations: Vec<f64>,
    pub effort: Vec<f64>,
    pub time_from_start: Duration,
}
ros_message!(
    JointTrajectoryPoint,
    "trajectory_msgs/msg/JointTrajectoryPoint",
    "RIHS01_de8907036d8bd45aac6f30cc9044a3d4a329c42cbf719aff7d95a584cfa532d7"
);
