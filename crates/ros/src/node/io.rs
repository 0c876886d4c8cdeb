//! The node's topics: typed publishers that also record what they send, inputs that record
//! what they receive, and logging to `tracing` and `/rosout` at once.

use std::sync::Arc;

use ros2_client::rosout::RosoutRaw;
use ros2_client::{Node, NodeLoggingHandle, Publisher, QosProfile, Subscription};

use super::names::NodeNames;
use super::params::TopicParams;
use super::ros::RosEnvError;
use waam_messages::status::JobStatus;
use waam_rosbag::qos::Qos;
use waam_rosbag::Recorder;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::DiagnosticArray;
use waam_rosmsg::geometry_msgs::PoseArray;
use waam_rosmsg::nav_msgs::Path;
use waam_rosmsg::rcl_interfaces::Log;
use waam_rosmsg::sensor_msgs::JointState;
use waam_rosmsg::shape_msgs::Mesh;
use waam_rosmsg::std_msgs::{Bool, Float64, String as RosString};
use waam_rosmsg::trajectory_msgs::JointTrajectory;
use waam_rosmsg::visualization_msgs::MarkerArray;
use waam_rosmsg::waam_interfaces::WeldPlan;
use waam_rosmsg::RosMessage;

/// Inputs: Reliable, Volatile, keep last 10.
pub fn input_qos() -> QosProfile {
    QosProfile::publisher_default().history(ros2_client::qos::History::KeepLast { depth: 10 })
}

/// Plan outputs: Reliable, TransientLocal, keep last 1 — a late subscriber (RViz started
/// after planning) still gets the last plan. Reliable writes wait for the send window
/// instead of failing, since a trajectory can span many fragments.
pub fn latched_qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability(ros2_client::qos::Reliability::Reliable {
            when_full: ros2_client::qos::WhenFull::Wait(std::time::Duration::from_secs(5)),
        })
        .durability(ros2_client::qos::Durability::TransientLocal)
        .history(ros2_client::qos::History::KeepLast { depth: 1 })
}

/// Sensors (scans, temperatures): Best effort, Volatile, keep last 10 — matches sensor
/// drivers that publish best effort (`SensorDataQoS`) as well as reliable ones.
pub fn sensor_qos() -> QosProfile {
    input_qos().reliability(ros2_client::qos::Reliability::BestEffort)
}

/// `/tf` as tf2's listener takes it: Reliable, Volatile, keep last 100.
pub fn tf_qos() -> QosProfile {
    input_qos().history(ros2_client::qos::History::KeepLast { depth: 100 })
}

/// `/tf_static` as tf2's listener takes it: also TransientLocal, so transforms published
/// once before the node started still arrive.
pub fn tf_static_qos() -> QosProfile {
    tf_qos().durability(ros2_client::qos::Durability::TransientLocal)
}

/// Streams (arc state, joint states): Reliable, Volatile, keep last 10.
pub fn stream_qos() -> QosProfile {
    input_qos()
}

/// A publisher with its resolved topic name and the QoS it offers (for the recording).
pub struct Output<M: RosMessage> {
    pub topic: String,
    publisher: Publisher<M>,
    offered: Qos,
}

impl<M: RosMessage + Clone> Output<M> {
    pub fn new(
        node: &mut Node,
        names: &NodeNames,
        name: &str,
        qos: QosProfile,
        offered: Qos,
    ) -> Result<Self, IoError> {
        let full = names.resolve(name)?;
        let topic = node
            .create_topic(&full, M::message_type_name(), &qos)
            .map_err(|e| IoError::Create(full.to_string(), e.to_string()))?;
        let publisher = node
            .create_publisher::<M>(&topic, None)
            .map_err(|e| IoError::Create(full.to_string(), e.to_string()))?;
        Ok(Output {
            topic: full.to_string(),
            publisher,
            offered,
        })
    }

    /// How many subscriptions are matched to this topic.
    pub fn subscribers(&self, node: &Node) -> usize {
        self.publisher.get_subscription_count(node)
    }

    /// Records (when recording) and publishes `message`; a failure is logged, not fatal.
    pub fn publish(&self, message: &M, recorder: Option<&Recorder>) {
        if let Some(r) = recorder {
            if let Err(e) = r.record(&self.topic, &self.offered, message) {
                tracing::warn!("recording {}: {e}", self.topic);
            }
        }
        if let Err(e) = self.publisher.publish(message.clone()) {
            tracing::warn!("publishing on {} failed: {e}", self.topic);
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum IoError {
    #[error(transparent)]
    Name(#[from] RosEnvError),
    #[error("cannot create topic {0}: {1}")]
    Create(String, String),
}

/// Every topic the node writes, the rosout logger and the recorder.
pub struct Outputs {
    pub joint_trajectory: Output<JointTrajectory>,
    pub poses: Output<PoseArray>,
    pub path: Output<Path>,
    pub markers: Output<MarkerArray>,
    pub weld_plan: Output<WeldPlan>,
    pub status: Output<DiagnosticArray>,
    pub arc_on: Output<Bool>,
    /// With the closed loop: the wire feed each weld path strikes at, relative to nominal,
    /// and its feed per deposit.
    pub wire_feed: Output<Float64>,
    pub wire_feed_schedule: Output<JointTrajectory>,
    /// Dry run only.
    pub joint_states: Option<Output<JointState>>,
    logger: NodeLoggingHandle,
    node_name: String,
    pub recorder: Option<Recorder>,
}

/// Log levels of [`Outputs::log`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    Info,
    Warn,
    Error,
}

impl Outputs {
    pub fn new(
        node: &mut Node,
        names: &NodeNames,
        topics: &TopicParams,
        dry_run: bool,
        recorder: Option<Recorder>,
    ) -> Result<Outputs, IoError> {
        Ok(Outputs {
            joint_trajectory: Output::new(
                node,
                names,
                &topics.joint_trajectory,
                latched_qos(),
                Qos::latched(),
            )?,
            poses: Output::new(node, names, &topics.poses, latched_qos(), Qos::latched())?,
            path: Output::new(node, names, &topics.path, latched_qos(), Qos::latched())?,
            markers: Output::new(node, names, &topics.markers, latched_qos(), Qos::latched())?,
            weld_plan: Output::new(
                node,
                names,
                &topics.weld_plan,
                latched_qos(),
                Qos::latched(),
            )?,
            status: Output::new(node, names, &topics.status, latched_qos(), Qos::latched())?,
            arc_on: Output::new(node, names, &topics.arc_on, stream_qos(), Qos::reliable(10))?,
            wire_feed: Output::new(
                node,
                names,
                &topics.wire_feed,
                stream_qos(),
                Qos::reliable(10),
            )?,
            wire_feed_schedule: Output::new(
                node,
                names,
                &topics.wire_feed_schedule,
                stream_qos(),
                Qos::reliable(10),
            )?,
            joint_states: if dry_run {
                Some(Output::new(
                    node,
                    names,
                    &topics.joint_states,
                    stream_qos(),
                    Qos::reliable(10),
                )?)
            } else {
                None
            },
            logger: node.logging_handle(),
            node_name: node.fully_qualified_name(),
            recorder,
        })
    }

    /// Publishes (and records) `status` on `~/status`, reported by this node.
    pub fn publish_status(&self, status: &JobStatus) {
        self.status.publish(
            &status.to_msg(Time::now(), &self.node_name),
            self.recorder.as_ref(),
        );
    }

    /// Logs to `tracing` and to `/rosout` (recording the rosout record too).
    pub fn log(&self, level: Level, message: &str) {
        let (ros_level, code) = match level {
            Level::Info => {
                tracing::info!("{message}");
                (ros2_client::ros2::LogLevel::Info, Log::INFO)
            }
            Level::Warn => {
                tracing::warn!("{message}");
                (ros2_client::ros2::LogLevel::Warn, Log::WARN)
            }
            Level::Error => {
                tracing::error!("{message}");
                (ros2_client::ros2::LogLevel::Error, Log::ERROR)
            }
        };
        let stamp = Time::now();
        self.logger.rosout_raw(
            ros2_client::builtin_interfaces::Time::now(),
            ros_level,
            self.logger.base_name(),
            message,
            file!(),
            waam_messages::convert::NODE_NAME,
            line!(),
        );
        if let Some(r) = &self.recorder {
            let record = Log {
                stamp,
                level: code,
                name: self.node_name.trim_start_matches('/').replace('/', "."),
                msg: message.to_string(),
                file: file!().to_string(),
                function: waam_messages::convert::NODE_NAME.to_string(),
                line: line!(),
            };
            if let Err(e) = r.record("/rosout", &Qos::rosout(), &record) {
                tracing::warn!("recording /rosout: {e}");
            }
        }
    }
}

/// The node's two inputs.
pub struct Inputs {
    pub part_topic: String,
    pub part: Subscription<RosString>,
    pub mesh_topic: String,
    pub mesh: Subscription<Mesh>,
}

impl Inputs {
    pub fn new(
        node: &mut Node,
        names: &NodeNames,
        topics: &TopicParams,
    ) -> Result<Inputs, IoError> {
        let (part_topic, part) = subscribe::<RosString>(node, names, &topics.part, input_qos())?;
        let (mesh_topic, mesh) = subscribe::<Mesh>(node, names, &topics.part_mesh, input_qos())?;
        Ok(Inputs {
            part_topic,
            part,
            mesh_topic,
            mesh,
        })
    }
}

/// A subscription to `name` (resolved and remapped) with `qos`, and its full topic name.
pub fn subscribe<M: RosMessage + 'static>(
    node: &mut Node,
    names: &NodeNames,
    name: &str,
    qos: QosProfile,
) -> Result<(String, Subscription<M>), IoError> {
    let full = names.resolve(name)?;
    let topic = node
        .create_topic(&full, M::message_type_name(), &qos)
        .map_err(|e| IoError::Create(full.to_string(), e.to_string()))?;
    let sub = node
        .create_subscription::<M>(&topic, None)
        .map_err(|e| IoError::Create(full.to_string(), e.to_string()))?;
    Ok((full.to_string(), sub))
}

/// Shared handle to the outputs, for the event loop and the execution thread.
pub type SharedOutputs = Arc<Outputs>;
