//! `tf2_msgs`: transforms between frames, as `/tf` and `/tf_static` carry them.

use serde::{Deserialize, Serialize};

use super::geometry_msgs::TransformStamped;
use super::ros_message;

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TFMessage {
    pub transforms: Vec<TransformStamped>,
}
ros_message!(
    TFMessage,
    "tf2_msgs/msg/TFMessage",
    "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"
);
