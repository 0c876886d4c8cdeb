//! What RViz and Foxglove need to draw robot, part, path and heat together: the URDF in use on
//! `robot_description` (std_msgs/String, latched, as robot_state_publisher offers it) and, on
//! `/tf_static`, the part frame and the TCP tied to the robot: base link → [`PART_FRAME`] (the
//! plate pose of the process settings) and tip link → [`TCP_FRAME`].
//!
//! The robot's own links come from robot_state_publisher (this description + /joint_states).

use nalgebra::Isometry3;
use ros2_client::Node;

use super::io::{latched_qos, IoError, Output};
use super::names::NodeNames;
use super::params::NodeParams;
use super::pipeline::PlanningPipeline;
use waam_messages::planning::PART_FRAME;
use waam_pipeline::Cell;
use waam_rosbag::qos::Qos;
use waam_rosbag::Recorder;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::geometry_msgs::{Quaternion, Transform, TransformStamped, Vector3};
use waam_rosmsg::std_msgs::{Header, String as RosString};
use waam_rosmsg::tf2_msgs::TFMessage;

/// The tool centre point: the frame the toolpath poses are the poses of.
pub const TCP_FRAME: &str = "waam_tcp";

/// Topic of the URDF (relative: `/<namespace>/robot_description`, as robot_state_publisher).
pub const ROBOT_DESCRIPTION: &str = "robot_description";
pub const TF_STATIC: &str = "/tf_static";

/// The URDF file `robot.urdf` names cannot be read.
#[derive(Debug, thiserror::Error)]
#[error("robot.urdf {path}: {source}")]
pub struct UrdfError {
    pub path: String,
    pub source: std::io::Error,
}

/// The URDF text the parameters name (the bundled robot when `robot.urdf` is "").
pub fn urdf_text(params: &NodeParams) -> Result<String, UrdfError> {
    if params.robot.urdf.is_empty() {
        Ok(waam_pipeline::BUNDLED_URDF.to_string())
    } else {
        std::fs::read_to_string(&params.robot.urdf).map_err(|source| UrdfError {
            path: params.robot.urdf.clone(),
            source,
        })
    }
}

/// base → part and tip → TCP of a pipeline's cell, stamped `stamp`.
pub fn static_transforms(pipeline: &PlanningPipeline, stamp: Time) -> TFMessage {
    cell_transforms(&pipeline.cell, stamp)
}

/// base → part (the plate pose of the process settings) and tip → TCP of `cell`.
pub fn cell_transforms(cell: &Cell, stamp: Time) -> TFMessage {
    let robot = &cell.robot;
    let plate = cell.settings.plate.isometry();
    TFMessage {
        transforms: vec![
            transform(stamp, &robot.base_link, PART_FRAME, &plate),
            transform(stamp, &robot.tip_link, TCP_FRAME, &robot.tcp),
        ],
    }
}

fn transform(stamp: Time, parent: &str, child: &str, pose: &Isometry3<f64>) -> TransformStamped {
    let t = pose.translation.vector;
    let q = pose.rotation.coords;
    TransformStamped {
        header: Header::new(stamp, parent.to_string()),
        child_frame_id: child.to_string(),
        transform: Transform {
            translation: Vector3 {
                x: t.x,
                y: t.y,
                z: t.z,
            },
            rotation: Quaternion {
                x: q.x,
                y: q.y,
                z: q.z,
                w: q.w,
            },
        },
    }
}

/// The publishers of the robot description and the static transforms.
pub struct CellFrames {
    description: Output<RosString>,
    tf_static: Output<TFMessage>,
}

impl CellFrames {
    pub fn new(node: &mut Node, names: &NodeNames) -> Result<CellFrames, IoError> {
        Ok(CellFrames {
            description: Output::new(
                node,
                names,
                ROBOT_DESCRIPTION,
                latched_qos(),
                Qos::latched(),
            )?,
            tf_static: Output::new(node, names, TF_STATIC, latched_qos(), Qos::latched())?,
        })
    }

    /// Publishes (and records) the URDF and the static transforms of `pipeline`'s cell.
    pub fn publish(&self, urdf: &str, pipeline: &PlanningPipeline, recorder: Option<&Recorder>) {
        self.description.publish(
            &RosString {
                data: urdf.to_string(),
            },
            recorder,
        );
        self.tf_static
            .publish(&static_transforms(pipeline, Time::now()), recorder);
    }
}

/// The node's default cell: the bundled robot and process settings ([`Cell::bundled`]).
/// Recordings made without a robot tie their part frame to it, as the node with its default
/// parameters does.
pub fn bundled_cell() -> Cell {
    Cell::bundled()
}

/// Records what the node publishes for viewers: `/tf_static` of `cell` and, when given, the
/// URDF on `/robot_description` (`waam plan --record`: the same frames as the node's).
pub fn record_cell(
    recorder: &Recorder,
    cell: &Cell,
    urdf: Option<&str>,
    stamp: Time,
) -> Result<(), waam_rosbag::BagError> {
    if let Some(urdf) = urdf {
        recorder.record_at(
            &format!("/{ROBOT_DESCRIPTION}"),
            &Qos::latched(),
            stamp,
            &RosString {
                data: urdf.to_string(),
            },
        )?;
    }
    recorder.record_at(
        TF_STATIC,
        &Qos::latched(),
        stamp,
        &cell_transforms(cell, stamp),
    )
}
