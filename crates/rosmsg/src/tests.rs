//! Unit tests of the message types: definitions, type hashes, CDR bytes.

use std::collections::BTreeMap;

use sha2::{Digest, Sha256};

use super::builtin_interfaces::{Duration, Time};
use super::definition::{self, fields, msg_text, split_type_name, DELIMITER};
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
use super::{from_cdr, to_cdr, RosMessage};

/// rosidl's field type id of a primitive `.msg` type (type_description_interfaces/FieldType).
fn primitive_type_id(ty: &str) -> Option<u8> {
    Some(match ty {
        "int8" => 2,
        "uint8" | "char" => 3,
        "int16" => 4,
        "uint16" => 5,
        "int32" => 6,
        "uint32" => 7,
        "int64" => 8,
        "uint64" => 9,
        "float32" => 10,
        "float64" => 11,
        "bool" => 15,
        "byte" => 16,
        "string" => 17,
        "wstring" => 18,
        _ => return None,
    })
}

/// The type description of one type as rosidl hashes it (fields only, no default values).
fn description_json(type_name: &str) -> (String, Vec<String>) {
    let (package, name) = split_type_name(type_name).unwrap();
    let mut nested = Vec::new();
    let mut out = format!("{{\"type_name\": \"{package}/msg/{name}\", \"fields\": [");
    for (i, field) in fields(msg_text(type_name).unwrap()).iter().enumerate() {
        let (base, nested_name) = match field.nested_type(package) {
            Some(dep) => {
                let (p, n) = split_type_name(&dep).unwrap();
                nested.push(format!("{p}/msg/{n}"));
                (1, format!("{p}/msg/{n}"))
            }
            None => (primitive_type_id(&field.base_type).unwrap(), String::new()),
        };
        let (type_id, capacity) = match field.array {
            None => (base, 0),
            Some(Some(n)) => (base + 48, n),
            Some(None) => (base + 144, 0),
        };
        if i > 0 {
            out.push_str(", ");
        }
        out.push_str(&format!(
            "{{\"name\": \"{}\", \"type\": {{\"type_id\": {type_id}, \"capacity\": {capacity}, \
             \"string_capacity\": 0, \"nested_type_name\": \"{nested_name}\"}}}}",
            field.name
        ));
    }
    out.push_str("]}");
    (out, nested)
}

/// RIHS01 hash of a type (REP 2011): sha256 of its type description and those of every type it
/// references (sorted by name), as rosidl_generator_type_description serializes them.
fn rihs01(type_name: &str) -> String {
    let (root, mut todo) = description_json(type_name);
    let mut referenced = BTreeMap::new();
    while let Some(dep) = todo.pop() {
        if let std::collections::btree_map::Entry::Vacant(slot) = referenced.entry(dep) {
            let (json, more) = description_json(slot.key());
            slot.insert(json);
            todo.extend(more);
        }
    }
    let refs: Vec<String> = referenced.into_values().collect();
    let text = format!(
        "{{\"type_description\": {root}, \"referenced_type_descriptions\": [{}]}}",
        refs.join(", ")
    );
    let digest = Sha256::digest(text.as_bytes());
    let hex: String = digest.iter().map(|b| format!("{b:02x}")).collect();
    format!("RIHS01_{hex}")
}

macro_rules! for_all_types {
    ($f:ident) => {
        $f::<Time>();
        $f::<Duration>();
        $f::<Header>();
        $f::<RosString>();
        $f::<Bool>();
        $f::<Float64>();
        $f::<ColorRGBA>();
        $f::<Point>();
        $f::<Quaternion>();
        $f::<Pose>();
        $f::<PoseArray>();
        $f::<PoseStamped>();
        $f::<Vector3>();
        $f::<Transform>();
        $f::<TransformStamped>();
        $f::<TFMessage>();
        $f::<Path>();
        $f::<JointTrajectory>();
        $f::<JointTrajectoryPoint>();
        $f::<Marker>();
        $f::<MarkerArray>();
        $f::<UVCoordinate>();
        $f::<MeshFile>();
        $f::<CompressedImage>();
        $f::<PointCloud2>();
        $f::<PointField>();
        $f::<JointState>();
        $f::<Temperature>();
        $f::<DiagnosticArray>();
        $f::<DiagnosticStatus>();
        $f::<KeyValue>();
        $f::<Mesh>();
        $f::<MeshTriangle>();
        $f::<Log>();
        $f::<Block>();
        $f::<WeldFragment>();
        $f::<WeldPoint>();
        $f::<PlanStatistics>();
        $f::<WeldPlan>();
        $f::<PlanCandidate>();
    };
}

#[test]
fn type_hashes_match_the_definitions() {
    fn check<M: RosMessage>() {
        assert_eq!(rihs01(M::TYPE_NAME), M::TYPE_HASH, "{}", M::TYPE_NAME);
    }
    for_all_types!(check);
}

#[test]
fn every_definition_resolves_with_its_dependencies() {
    fn check<M: RosMessage + Default>() {
        let text = M::definition();
        assert!(text.starts_with(msg_text(M::TYPE_NAME).unwrap()));
        // Every nested field type appears exactly once as a `MSG:` block.
        let blocks: Vec<&str> = text
            .lines()
            .filter_map(|l| l.strip_prefix("MSG: "))
            .collect();
        let mut unique = blocks.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), blocks.len(), "{}: {blocks:?}", M::TYPE_NAME);
    }
    fn check_all<M: RosMessage + Default>() {
        check::<M>()
    }
    macro_rules! with_default {
        ($($t:ty),*) => { $(check_all::<$t>();)* };
    }
    with_default!(
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
        PlanCandidate
    );
}

#[test]
fn full_text_follows_rosbag2_layout() {
    // Depth first, sorted within each definition, each dependency once, blank line before
    // each delimiter (the .msg texts end with a newline).
    let text = PoseArray::definition();
    let expected = format!(
        "{}\n{DELIMITER}\nMSG: geometry_msgs/Pose\n{}\n{DELIMITER}\nMSG: geometry_msgs/Point\n{}\n\
         {DELIMITER}\nMSG: geometry_msgs/Quaternion\n{}\n{DELIMITER}\nMSG: std_msgs/Header\n{}\n\
         {DELIMITER}\nMSG: builtin_interfaces/Time\n{}",
        msg_text("geometry_msgs/PoseArray").unwrap(),
        msg_text("geometry_msgs/Pose").unwrap(),
        msg_text("geometry_msgs/Point").unwrap(),
        msg_text("geometry_msgs/Quaternion").unwrap(),
        msg_text("std_msgs/Header").unwrap(),
        msg_text("builtin_interfaces/Time").unwrap(),
    );
    assert_eq!(text, expected);
    // Marker pulls in sensor_msgs/CompressedImage and the bare-named UVCoordinate / MeshFile.
    let marker = Marker::definition();
    for dep in [
        "MSG: sensor_msgs/CompressedImage\n",
        "MSG: visualization_msgs/UVCoordinate\n",
        "MSG: visualization_msgs/MeshFile\n",
        "MSG: builtin_interfaces/Duration\n",
        "MSG: std_msgs/ColorRGBA\n",
    ] {
        assert!(marker.contains(dep), "{dep}");
    }
}

#[test]
fn unknown_types_are_named_in_the_error() {
    let err = definition::full_text("foo_msgs/msg/Bar").unwrap_err();
    assert!(err.to_string().contains("foo_msgs/msg/Bar"), "{err}");
    let err = definition::full_text("not a type").unwrap_err();
    assert!(err.to_string().contains("not a type"), "{err}");
}

#[test]
fn cdr_bytes_are_what_ros_sends() {
    let bytes = to_cdr(&RosString { data: "hi".into() }).unwrap();
    assert_eq!(bytes, [0, 1, 0, 0, 3, 0, 0, 0, b'h', b'i', 0]);
    // Time (two 4-byte integers), then a string: length counting the terminating NUL.
    let p = Header {
        stamp: Time { sec: 1, nanosec: 2 },
        frame_id: "a".into(),
    };
    let bytes = to_cdr(&p).unwrap();
    assert_eq!(
        bytes,
        [0, 1, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, b'a', 0]
    );
    // A uint8 followed by a string: padding to 4 bytes, counted from the start of the body.
    let log = Log {
        level: Log::INFO,
        ..Default::default()
    };
    let bytes = to_cdr(&log).unwrap();
    assert_eq!(
        &bytes[4..20],
        [0, 0, 0, 0, 0, 0, 0, 0, 20, 0, 0, 0, 1, 0, 0, 0]
    );
    let bytes = to_cdr(&MeshTriangle {
        vertex_indices: [1, 2, 3],
    })
    .unwrap();
    assert_eq!(bytes, [0, 1, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 3, 0, 0, 0]);
    // A pyrometer reading as rclpy serializes it (Jazzy): the float64s are aligned to 8,
    // and rclpy leaves its two padding bytes (here 100, 100) uninitialised.
    let rclpy = [
        0, 1, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, b'p', 0, 100, 100, 0, 0, 0, 0, 0, 0, 248,
        63, 0, 0, 0, 0, 0, 0, 208, 63,
    ];
    let reading = Temperature {
        header: Header::new(Time { sec: 1, nanosec: 2 }, "p"),
        temperature: 1.5,
        variance: 0.25,
    };
    assert_eq!(from_cdr::<Temperature>(&rclpy).unwrap(), reading);
    let mut ours = rclpy;
    ours[18..20].fill(0);
    assert_eq!(to_cdr(&reading).unwrap(), ours);
}

#[test]
fn messages_round_trip_through_cdr() {
    let plan = WeldPlan {
        header: Header::new(Time::from_nanos(1_700_000_000_123_456_789), "base_link"),
        part_name: "wall".into(),
        block_pitch: 0.005,
        fragments: vec![WeldFragment {
            blocks: vec![Block { x: 0, y: 1, z: 2 }, Block { x: 1, y: 1, z: 2 }],
        }],
        points: vec![WeldPoint {
            pose: Pose::default(),
            time_from_start: Duration::from_secs_f64(1.5),
            kind: WeldPoint::ARC_ON,
            arc_on: true,
            fragment: 0,
            block: 0,
            speed: 0.01,
        }],
        weld_speed: 0.01,
        transit_speed: 0.1,
        worst_margin_s: f64::INFINITY,
        statistics: PlanStatistics {
            candidates: 7,
            learned_clause_mean: 3.5,
            ..Default::default()
        },
    };
    assert_eq!(from_cdr::<WeldPlan>(&to_cdr(&plan).unwrap()).unwrap(), plan);

    let marker = Marker {
        type_: Marker::CUBE,
        text: "arc on".into(),
        colors: vec![ColorRGBA {
            r: 1.0,
            g: 0.5,
            b: 0.0,
            a: 1.0,
        }],
        ..Default::default()
    };
    let array = MarkerArray {
        markers: vec![marker.clone(), marker],
    };
    assert_eq!(
        from_cdr::<MarkerArray>(&to_cdr(&array).unwrap()).unwrap(),
        array
    );
    let status = DiagnosticArray {
        header: Header::default(),
        status: vec![DiagnosticStatus {
            level: DiagnosticStatus::ERROR,
            name: "waam_planner".into(),
            message: "bad part".into(),
            hardware_id: String::new(),
            values: vec![KeyValue::new("line", 3)],
        }],
    };
    assert_eq!(
        from_cdr::<DiagnosticArray>(&to_cdr(&status).unwrap()).unwrap(),
        status
    );
}

#[test]
fn truncated_or_foreign_cdr_is_an_error() {
    let bytes = to_cdr(&RosString {
        data: "hello".into(),
    })
    .unwrap();
    let err = from_cdr::<RosString>(&bytes[..6]).unwrap_err();
    assert!(err.to_string().contains("std_msgs/msg/String"), "{err}");
    assert!(from_cdr::<RosString>(&bytes[..2]).is_err());
    assert!(from_cdr::<RosString>(&[0, 7, 0, 0, 1, 0, 0, 0, 0]).is_err());
}

#[test]
fn time_and_duration_conversions() {
    assert_eq!(
        Duration::from_secs_f64(-0.5),
        Duration {
            sec: -1,
            nanosec: 500_000_000
        }
    );
    assert_eq!(Duration::from_secs_f64(2.25).as_secs_f64(), 2.25);
    let t = Time::from_nanos(3_000_000_007);
    assert_eq!(t, Time { sec: 3, nanosec: 7 });
    assert_eq!(t.to_nanos(), 3_000_000_007);
    assert_eq!(Time::from_nanos(i64::MAX).sec, i32::MAX);
}

/// The kind of value a `.msg` field holds, coarse enough to compare with a serde value.
fn field_kind(field: &definition::Field) -> &'static str {
    if field.array.is_some() {
        return "sequence";
    }
    match field.base_type.as_str() {
        "float32" | "float64" => "float",
        "bool" => "bool",
        "string" | "wstring" => "string",
        t if primitive_type_id(t).is_some() => "integer",
        _ => "message",
    }
}

fn value_kind(value: &serde_yaml::Value) -> &'static str {
    use serde_yaml::Value;
    match value {
        Value::Number(n) if n.is_f64() => "float",
        Value::Number(_) => "integer",
        Value::Bool(_) => "bool",
        Value::String(_) => "string",
        Value::Sequence(_) => "sequence",
        Value::Mapping(_) => "message",
        _ => "other",
    }
}

#[test]
fn rust_fields_match_the_msg_files_in_order_and_kind() {
    // serde_yaml keeps struct fields in declaration order, which is the CDR order.
    fn check<M: RosMessage + Default>() {
        let value = serde_yaml::to_value(M::default()).unwrap();
        let serde_yaml::Value::Mapping(map) = value else {
            panic!("{} is not a struct", M::TYPE_NAME)
        };
        let rust: Vec<(String, &str)> = map
            .iter()
            .map(|(k, v)| (k.as_str().unwrap().to_string(), value_kind(v)))
            .collect();
        let msg: Vec<(String, &str)> = fields(msg_text(M::TYPE_NAME).unwrap())
            .iter()
            .map(|f| (f.name.clone(), field_kind(f)))
            .collect();
        assert_eq!(rust, msg, "{}", M::TYPE_NAME);
    }
    for_all_types!(check);
}
