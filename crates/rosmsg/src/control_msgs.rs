//! `control_msgs/action/FollowJointTrajectory` (ROS 2 Jazzy, control_msgs 5.x): the action a
//! `joint_trajectory_controller` or MotoROS2 serves. Field order follows the Jazzy `.action`
//! file exactly, so the CDR matches a C++ peer. These types are only sent and received by the
//! node's execution client (and the tests' action server), never recorded, so they carry no
//! `ros2msg` definition or type hash; the nested types only this action uses
//! (MultiDOFJointTrajectory, Transform, Twist, the tolerances) live here too.

use serde::{Deserialize, Serialize};

use super::builtin_interfaces::Duration;
use super::geometry_msgs::{Quaternion, Vector3};
use super::std_msgs::Header;
use super::trajectory_msgs::{JointTrajectory, JointTrajectoryPoint};

/// geometry_msgs/Transform.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    pub translation: Vector3,
    pub rotation: Quaternion,
}

/// geometry_msgs/Twist.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    pub linear: Vector3,
    pub angular: Vector3,
}

/// trajectory_msgs/MultiDOFJointTrajectoryPoint.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MultiDOFJointTrajectoryPoint {
    pub transforms: Vec<Transform>,
    pub velocities: Vec<Twist>,
    pub accelerations: Vec<Twist>,
    pub time_from_start: Duration,
}

/// trajectory_msgs/MultiDOFJointTrajectory.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MultiDOFJointTrajectory {
    pub header: Header,
    pub joint_names: Vec<String>,
    pub points: Vec<MultiDOFJointTrajectoryPoint>,
}

/// control_msgs/JointTolerance (0 = the controller's default, -1 = no tolerance).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointTolerance {
    pub name: String,
    pub position: f64,
    pub velocity: f64,
    pub acceleration: f64,
}

/// control_msgs/JointComponentTolerance.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointComponentTolerance {
    pub joint_name: String,
    pub component: u16,
    pub position: f64,
    pub velocity: f64,
    pub acceleration: f64,
}

/// The goal of FollowJointTrajectory.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FollowJointTrajectoryGoal {
    pub trajectory: JointTrajectory,
    pub multi_dof_trajectory: MultiDOFJointTrajectory,
    pub path_tolerance: Vec<JointTolerance>,
    pub component_path_tolerance: Vec<JointComponentTolerance>,
    pub goal_tolerance: Vec<JointTolerance>,
    pub component_goal_tolerance: Vec<JointComponentTolerance>,
    pub goal_time_tolerance: Duration,
}
#[cfg(feature = "ros2-client")]
impl ros2_client::Message for FollowJointTrajectoryGoal {}

/// The result of FollowJointTrajectory.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FollowJointTrajectoryResult {
    pub error_code: i32,
    pub error_string: String,
}
#[cfg(feature = "ros2-client")]
impl ros2_client::Message for FollowJointTrajectoryResult {}

impl FollowJointTrajectoryResult {
    pub const SUCCESSFUL: i32 = 0;
    pub const INVALID_GOAL: i32 = -1;
    pub const INVALID_JOINTS: i32 = -2;
    pub const OLD_HEADER_TIMESTAMP: i32 = -3;
    pub const PATH_TOLERANCE_VIOLATED: i32 = -4;
    pub const GOAL_TOLERANCE_VIOLATED: i32 = -5;
}

/// The feedback of FollowJointTrajectory.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FollowJointTrajectoryFeedback {
    pub header: Header,
    pub joint_names: Vec<String>,
    pub desired: JointTrajectoryPoint,
    pub actual: JointTrajectoryPoint,
    pub error: JointTrajectoryPoint,
    pub multi_dof_joint_names: Vec<String>,
    pub multi_dof_desired: MultiDOFJointTrajectoryPoint,
    pub multi_dof_actual: MultiDOFJointTrajectoryPoint,
    pub multi_dof_error: MultiDOFJointTrajectoryPoint,
}
#[cfg(feature = "ros2-client")]
impl ros2_client::Message for FollowJointTrajectoryFeedback {}
