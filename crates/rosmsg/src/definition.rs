//! Message definitions: the vendored `.msg` texts and the complete `ros2msg` text that rosbag2
//! writes into an MCAP schema (rosbag2_cpp's `LocalMessageDefinitionSource`): the root
//! definition verbatim, then, depth first and in sorted order within each definition, every
//! dependency not seen yet, each preceded by `\n` + 80 `=` + `\nMSG: pkg/Name\n`.

use std::collections::{BTreeSet, HashSet};

/// The `.msg` file of every type we use, keyed by `pkg/Name`.
const DEFINITIONS: &[(&str, &str)] = &[
    (
        "builtin_interfaces/Duration",
        include_str!("defs/builtin_interfaces/Duration.msg"),
    ),
    (
        "builtin_interfaces/Time",
        include_str!("defs/builtin_interfaces/Time.msg"),
    ),
    (
        "diagnostic_msgs/DiagnosticArray",
        include_str!("defs/diagnostic_msgs/DiagnosticArray.msg"),
    ),
    (
        "diagnostic_msgs/DiagnosticStatus",
        include_str!("defs/diagnostic_msgs/DiagnosticStatus.msg"),
    ),
    (
        "diagnostic_msgs/KeyValue",
        include_str!("defs/diagnostic_msgs/KeyValue.msg"),
    ),
    (
        "geometry_msgs/Point",
        include_str!("defs/geometry_msgs/Point.msg"),
    ),
    (
        "geometry_msgs/Pose",
        include_str!("defs/geometry_msgs/Pose.msg"),
    ),
    (
        "geometry_msgs/PoseArray",
        include_str!("defs/geometry_msgs/PoseArray.msg"),
    ),
    (
        "geometry_msgs/PoseStamped",
        include_str!("defs/geometry_msgs/PoseStamped.msg"),
    ),
    (
        "geometry_msgs/Quaternion",
        include_str!("defs/geometry_msgs/Quaternion.msg"),
    ),
    (
        "geometry_msgs/Transform",
        include_str!("defs/geometry_msgs/Transform.msg"),
    ),
    (
        "geometry_msgs/TransformStamped",
        include_str!("defs/geometry_msgs/TransformStamped.msg"),
    ),
    (
        "geometry_msgs/Vector3",
        include_str!("defs/geometry_msgs/Vector3.msg"),
    ),
    ("nav_msgs/Path", include_str!("defs/nav_msgs/Path.msg")),
    (
        "rcl_interfaces/Log",
        include_str!("defs/rcl_interfaces/Log.msg"),
    ),
    (
        "sensor_msgs/CompressedImage",
        include_str!("defs/sensor_msgs/CompressedImage.msg"),
    ),
    (
        "sensor_msgs/JointState",
        include_str!("defs/sensor_msgs/JointState.msg"),
    ),
    (
        "sensor_msgs/PointCloud2",
        include_str!("defs/sensor_msgs/PointCloud2.msg"),
    ),
    (
        "sensor_msgs/PointField",
        include_str!("defs/sensor_msgs/PointField.msg"),
    ),
    (
        "sensor_msgs/Temperature",
        include_str!("defs/sensor_msgs/Temperature.msg"),
    ),
    ("shape_msgs/Mesh", include_str!("defs/shape_msgs/Mesh.msg")),
    (
        "shape_msgs/MeshTriangle",
        include_str!("defs/shape_msgs/MeshTriangle.msg"),
    ),
    ("std_msgs/Bool", include_str!("defs/std_msgs/Bool.msg")),
    (
        "std_msgs/ColorRGBA",
        include_str!("defs/std_msgs/ColorRGBA.msg"),
    ),
    (
        "std_msgs/Float64",
        include_str!("defs/std_msgs/Float64.msg"),
    ),
    ("std_msgs/Header", include_str!("defs/std_msgs/Header.msg")),
    ("std_msgs/String", include_str!("defs/std_msgs/String.msg")),
    (
        "tf2_msgs/TFMessage",
        include_str!("defs/tf2_msgs/TFMessage.msg"),
    ),
    (
        "trajectory_msgs/JointTrajectory",
        include_str!("defs/trajectory_msgs/JointTrajectory.msg"),
    ),
    (
        "trajectory_msgs/JointTrajectoryPoint",
        include_str!("defs/trajectory_msgs/JointTrajectoryPoint.msg"),
    ),
    (
        "visualization_msgs/Marker",
        include_str!("defs/visualization_msgs/Marker.msg"),
    ),
    (
        "visualization_msgs/MarkerArray",
        include_str!("defs/visualization_msgs/MarkerArray.msg"),
    ),
    (
        "visualization_msgs/MeshFile",
        include_str!("defs/visualization_msgs/MeshFile.msg"),
    ),
    (
        "visualization_msgs/UVCoordinate",
        include_str!("defs/visualization_msgs/UVCoordinate.msg"),
    ),
    (
        "waam_interfaces/Block",
        include_str!("../../../ros/waam_interfaces/msg/Block.msg"),
    ),
    (
        "waam_interfaces/PlanCandidate",
        include_str!("../../../ros/waam_interfaces/msg/PlanCandidate.msg"),
    ),
    (
        "waam_interfaces/PlanStatistics",
        include_str!("../../../ros/waam_interfaces/msg/PlanStatistics.msg"),
    ),
    (
        "waam_interfaces/WeldFragment",
        include_str!("../../../ros/waam_interfaces/msg/WeldFragment.msg"),
    ),
    (
        "waam_interfaces/WeldPlan",
        include_str!("../../../ros/waam_interfaces/msg/WeldPlan.msg"),
    ),
    (
        "waam_interfaces/WeldPoint",
        include_str!("../../../ros/waam_interfaces/msg/WeldPoint.msg"),
    ),
];

/// Primitive `.msg` field types (no definition of their own).
const PRIMITIVES: &[&str] = &[
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
    "uint32", "int64", "uint64", "string", "wstring",
];

/// The delimiter line rosbag2 puts before each dependency.
pub const DELIMITER: &str =
    "================================================================================";

/// A type name was not understood or its definition is not vendored.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DefinitionError {
    #[error("type name {0:?} is not of the form pkg/Name or pkg/msg/Name")]
    BadName(String),
    #[error("no message definition for {0} (not one of the vendored .msg files)")]
    Unknown(String),
}

/// Splits `pkg/msg/Name` or `pkg/Name` into (`pkg`, `Name`).
pub fn split_type_name(type_name: &str) -> Result<(&str, &str), DefinitionError> {
    let parts: Vec<&str> = type_name.split('/').collect();
    let ok = |s: &str| {
        s.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
            && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
    };
    match parts.as_slice() {
        [pkg, name] | [pkg, "msg", name] if ok(pkg) && ok(name) => Ok((pkg, name)),
        _ => Err(DefinitionError::BadName(type_name.to_string())),
    }
}

/// The vendored `.msg` text of one type (`pkg/Name` or `pkg/msg/Name`).
pub fn msg_text(type_name: &str) -> Result<&'static str, DefinitionError> {
    let (pkg, name) = split_type_name(type_name)?;
    DEFINITIONS
        .iter()
        .find(|(key, _)| key.split_once('/') == Some((pkg, name)))
        .map(|(_, text)| *text)
        .ok_or_else(|| DefinitionError::Unknown(type_name.to_string()))
}

/// One field of a `.msg` definition (constants are not fields).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    /// Type as written, without array suffix: `float64`, `geometry_msgs/Pose`, `Pose`.
    pub base_type: String,
    /// `None` for a scalar, `Some(None)` for an unbounded sequence, `Some(Some(n))` for `T[n]`.
    pub array: Option<Option<usize>>,
    pub name: String,
}

impl Field {
    /// Whether the base type is a primitive (no nested definition).
    pub fn is_primitive(&self) -> bool {
        PRIMITIVES.contains(&self.base_type.as_str())
    }

    /// The nested type as `pkg/Name`, resolving a bare name against `package`.
    pub fn nested_type(&self, package: &str) -> Option<String> {
        if self.is_primitive() {
            None
        } else if self.base_type.contains('/') {
            Some(self.base_type.clone())
        } else {
            Some(format!("{package}/{}", self.base_type))
        }
    }
}

/// The fields of a `.msg` text, in order: comments, blank lines and constants skipped.
pub fn fields(text: &str) -> Vec<Field> {
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.split('#').next().unwrap_or("").trim();
        let mut words = line.split_whitespace();
        let (Some(ty), Some(rest)) = (words.next(), words.next()) else {
            continue;
        };
        if rest.contains('=') || line[ty.len()..].trim_start().contains('=') {
            continue; // a constant: `uint8 OK=0`
        }
        let (base_type, array) = match ty.split_once('[') {
            Some((base, bound)) => {
                let bound = bound.trim_end_matches(']');
                (base, Some(bound.parse::<usize>().ok()))
            }
            None => (ty, None),
        };
        out.push(Field {
            base_type: base_type.to_string(),
            array,
            name: rest.to_string(),
        });
    }
    out
}

/// Dependencies of a `.msg` text as rosbag2 finds them: the leading word of every line that
/// starts (after blanks) with a type name followed by blanks, bare names resolved against the
/// text's own package, primitives dropped; sorted, as rosbag2 keeps them in a `std::set`.
fn dependencies(text: &str, package: &str) -> BTreeSet<String> {
    let mut deps = BTreeSet::new();
    for line in text.split('\n') {
        let line = line.trim_start();
        let word_end = line
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '/'))
            .unwrap_or(line.len());
        let word = &line[..word_end];
        if word.is_empty() {
            continue;
        }
        let mut rest = &line[word_end..];
        if rest.starts_with('[') {
            match rest.find(']') {
                Some(close) => rest = &rest[close + 1..],
                None => continue,
            }
        }
        if !rest.starts_with(|c: char| c.is_whitespace()) || PRIMITIVES.contains(&word) {
            continue;
        }
        if word.contains('/') {
            deps.insert(word.to_string());
        } else {
            deps.insert(format!("{package}/{word}"));
        }
    }
    deps
}

/// The complete `ros2msg` definition of `type_name` (`pkg/msg/Name`) as rosbag2 writes it.
pub fn full_text(type_name: &str) -> Result<String, DefinitionError> {
    fn append(
        type_name: &str,
        seen: &mut HashSet<String>,
        depth: u32,
    ) -> Result<String, DefinitionError> {
        if depth == 0 {
            return Err(DefinitionError::BadName(format!(
                "{type_name} (nested too deep)"
            )));
        }
        let (package, _) = split_type_name(type_name)?;
        let text = msg_text(type_name)?;
        let mut out = text.to_string();
        for dep in dependencies(text, package) {
            if seen.insert(dep.clone()) {
                out.push('\n');
                out.push_str(DELIMITER);
                out.push_str("\nMSG: ");
                out.push_str(&dep);
                out.push('\n');
                out.push_str(&append(&dep, seen, depth - 1)?);
            }
        }
        Ok(out)
    }
    append(type_name, &mut HashSet::new(), 50)
}
