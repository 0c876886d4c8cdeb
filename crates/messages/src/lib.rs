//! The domain as ROS 2 messages, without DDS.
//!
//! Parts, plans, thermal checks and motion know nothing of ROS; `waam-rosmsg` and
//! `waam-rosbag` know nothing of parts. Here domain values become messages (one builder per
//! message type), `~/status` gets its one shape, the simulated heat becomes point clouds,
//! planning and layer sessions are recorded to rosbag2/MCAP, and recordings are re-planned
//! and compared. Nothing here links `ros2-client`: the node that publishes all this over DDS
//! is `waam-ros`.

pub mod convert;
pub mod heat;
pub mod layer;
pub mod planning;
pub mod replay;
pub mod sample;
pub mod scan;
pub mod sensor;
pub mod status;
pub mod tf_buffer;
pub mod wire_feed;

/// The topics of node `waam_planner` (`~/name` resolves to `/waam_planner/name`). Recordings
/// made by `waam plan --record` use the same names, so replay treats both alike.
pub mod topics {
    /// `std_msgs/msg/String`: a part document.
    pub const PART: &str = "/waam_planner/part";
    /// `std_msgs/msg/String`: a layer document (`waam layer plan --record`,
    /// docs/layer-format.md).
    pub const LAYER: &str = "/waam_planner/layer";
    /// `shape_msgs/msg/Mesh`: a part mesh (metres).
    pub const PART_MESH: &str = "/waam_planner/part_mesh";
    /// `trajectory_msgs/msg/JointTrajectory`.
    pub const JOINT_TRAJECTORY: &str = "/waam_planner/plan/joint_trajectory";
    /// `geometry_msgs/msg/PoseArray`.
    pub const POSES: &str = "/waam_planner/plan/poses";
    /// `nav_msgs/msg/Path`.
    pub const PATH: &str = "/waam_planner/plan/path";
    /// `visualization_msgs/msg/MarkerArray`.
    pub const MARKERS: &str = "/waam_planner/plan/markers";
    /// `waam_interfaces/msg/WeldPlan`.
    pub const WELD_PLAN: &str = "/waam_planner/plan/weld_plan";
    /// `diagnostic_msgs/msg/DiagnosticArray`.
    pub const STATUS: &str = "/waam_planner/status";
    /// `std_msgs/msg/Bool`.
    pub const ARC_ON: &str = "/waam_planner/arc_on";
    /// `sensor_msgs/msg/JointState` (dry run).
    pub const JOINT_STATES: &str = "/joint_states";
    /// `rcl_interfaces/msg/Log`.
    pub const ROSOUT: &str = "/rosout";
    /// `waam_interfaces/msg/PlanCandidate`: the planner's verdict per candidate plan.
    pub const CANDIDATES: &str = "/waam_planner/planner/candidates";
    /// `sensor_msgs/msg/PointCloud2`: simulated temperatures of the chosen plan (its blocks,
    /// or a layer's mesh nodes).
    pub const HEAT: &str = "/waam_planner/planner/heat";
}
#[cfg(test)]
mod tests;
