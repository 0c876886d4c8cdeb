//! From a type name known only at run time (a recorded topic's) to the Rust type: a visitor
//! is called with the static type, so generic code (a typed publisher, a decoder) runs for it.

use super::builtin_interfaces::{Duration, Time};
use super::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use super::geometry_msgs::{
    Point, Pose, PoseArray, PoseStamped, Quaternion, Transform, TransformStamped, Vector3,
};
use super::nav_msgs::Path;
use super::rcl_interfaces::Log;
use super::sensor_msgs::{CompressedImage, JointState, PointCloud2, PointField, Temperature};
use super::shape_msgs::{Mesh, MeshTriangle};
use super::std_msgs::{Bool, ColorRGBA, Float64, Header, String as RosString};
use super::tf2_msgs::TFMessage;
use super::trajectory_msgs::{JointTrajectory, JointTrajectoryPoint};
use super::visualization_msgs::{Marker, MarkerArray, MeshFile, UVCoordinate};
use super::waam_interfaces::{
    Block, PlanCandidate, PlanStatistics, WeldFragment, WeldPlan, WeldPoint,
};
use super::{AnyMessage, RosMessage};

/// Code to run for one message type.
pub trait TypeVisitor {
    type Output;
    fn visit<M>(self) -> Self::Output
    where
        M: AnyMessage;
}

macro_rules! dispatch {
    ($name:expr, $visitor:expr, [$($t:ty),* $(,)?]) => {
        match $name {
            $(n if n == <$t as RosMessage>::TYPE_NAME => Some($visitor.visit::<$t>()),)*
            _ => None,
        }
    };
}

/// Runs `visitor` for the type named `type_name` (`pkg/msg/Name`); `None` for a type this
/// crate does not know.
pub fn visit_type<V: TypeVisitor>(type_name: &str, visitor: V) -> Option<V::Output> {
    dispatch!(
        type_name,
        visitor,
        [
            Time,
            Duration,
            Header,
            RosString,
            Bool,
            Float64,
            ColorRGBA,
            Point,
            Quaternion,
            Pose,
            PoseArray,
            PoseStamped,
            Vector3,
            Transform,
            TransformStamped,
            TFMessage,
            Path,
            JointTrajectory,
            JointTrajectoryPoint,
            Marker,
            MarkerArray,
            UVCoordinate,
            MeshFile,
            CompressedImage,
            PointCloud2,
            PointField,
            JointState,
            Temperature,
            DiagnosticArray,
            DiagnosticStatus,
            KeyValue,
            Mesh,
            MeshTriangle,
            Log,
            Block,
            WeldFragment,
            WeldPoint,
            PlanStatistics,
            WeldPlan,
            PlanCandidate,
        ]
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Name;
    impl TypeVisitor for Name {
        type Output = &'static str;
        fn visit<M: RosMessage>(self) -> &'static str {
            M::TYPE_NAME
        }
    }

    #[test]
    fn every_type_name_reaches_its_type() {
        for name in [
            "std_msgs/msg/String",
            "waam_interfaces/msg/WeldPlan",
            "sensor_msgs/msg/PointCloud2",
            "sensor_msgs/msg/Temperature",
            "rcl_interfaces/msg/Log",
        ] {
            assert_eq!(visit_type(name, Name), Some(name));
        }
        assert_eq!(visit_type("foo_msgs/msg/Bar", Name), None);
    }
}
