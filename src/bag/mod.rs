//! Recording to and reading from rosbag2 bags with MCAP storage, laid out as rosbag2 (ROS 2
//! Jazzy) writes them, so `ros2 bag info/play`, Foxglove and Python readers open them:
//!
//! - `DIR/metadata.yaml`: rosbag2 metadata version 9 with per-topic offered QoS;
//! - `DIR/<DIR name>_0.mcap`: profile `ros2`, one `ros2msg` schema per type (the complete
//!   definition), `cdr` messages, channel metadata `offered_qos_profiles` and
//!   `topic_type_hash`, the `rosbag2` metadata record, zstd chunks with message indexes, and
//!   a summary with statistics and chunk indexes.
//!
//! Chunks are bounded in size and age and each closed chunk is flushed to disk with a fresh
//! `metadata.yaml`, so a recording killed mid-run stays readable up to its last closed chunk;
//! [`Bag::open`] reads such a file and reports it as truncated.

use std::path::{Path, PathBuf};

pub mod heat;
pub mod metadata;
pub mod planning;
pub mod qos;
pub mod reader;
pub mod recorder;
pub mod sample;
pub mod writer;

pub use qos::Qos;
pub use reader::{Bag, RecordedMessage, TopicInfo, Truncation};
pub use recorder::Recorder;
pub use writer::{BagOptions, BagSummary, BagWriter};

use crate::msgs::CdrError;

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

/// A bag could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: already exists (a recording goes into a new directory)", .0.display())]
    Exists(PathBuf),
    #[error("{}: not a usable bag directory name", .0.display())]
    BadPath(PathBuf),
    #[error("{}: not an MCAP file (no MCAP magic at the start)", .0.display())]
    NotMcap(PathBuf),
    #[error("{}: {reason}", path.display())]
    Mcap { path: PathBuf, reason: String },
    #[error("{}: {reason}", path.display())]
    Corrupt { path: PathBuf, reason: String },
    #[error("topic {topic} is recorded as {recorded}, cannot record {given} on it")]
    TopicType {
        topic: String,
        recorded: String,
        given: String,
    },
    #[error("topic {0} was not declared")]
    UnknownTopic(String),
    #[error("the recording is already finished")]
    Finished,
    #[error(transparent)]
    Cdr(#[from] CdrError),
    #[error("message on {topic} at {log_time} ns: {source}")]
    Decode {
        topic: String,
        log_time: u64,
        source: CdrError,
    },
}

impl BagError {
    fn mcap(path: &Path, error: mcap::McapError) -> BagError {
        BagError::Mcap {
            path: path.to_path_buf(),
            reason: error.to_string(),
        }
    }
}

#[cfg(test)]
mod tests;
