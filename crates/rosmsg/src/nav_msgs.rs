//! `nav_msgs`: a path of stamped poses.

use serde::{Deserialize, Serialize};

use super::geometry_msgs::PoseStamped;
use super::ros_message;
use super::std_msgs::Header;

/// A path (RViz draws it as a line).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Path {
    pub header: Header,
    pub poses: Vec<PoseStamped>,
}
ros_message!(
    Path,
    "nav_msgs/msg/Path",
    "RIHS01_1957a5bb3cee5da65c4e52e52b65a93df227efce4c20f8458b36e73066ca334b"
);
