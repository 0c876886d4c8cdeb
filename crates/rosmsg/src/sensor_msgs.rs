//! `sensor_msgs`: point clouds (the simulated heat of a build, a layer height scan), joint
//! states, images, temperatures (a pyrometer).

use serde::{Deserialize, Serialize};

use super::ros_message;
use super::std_msgs::Header;

/// A point cloud: `width * height` points of `point_step` bytes each, laid out by `fields`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PointCloud2 {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub fields: Vec<PointField>,
    pub is_bigendian: bool,
    pub point_step: u32,
    pub row_step: u32,
    pub data: Vec<u8>,
    pub is_dense: bool,
}
ros_message!(
    PointCloud2,
    "sensor_msgs/msg/PointCloud2",
    "RIHS01_9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5"
);

/// One field of a point cloud's points.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PointField {
    pub name: String,
    /// Byte offset within a point.
    pub offset: u32,
    /// One of the datatype constants below.
    pub datatype: u8,
    pub count: u32,
}
ros_message!(
    PointField,
    "sensor_msgs/msg/PointField",
    "RIHS01_5c6a4750728c2bcfbbf7037225b20b02d4429634732146b742dee1726637ef01"
);

impl PointField {
    pub const INT8: u8 = 1;
    pub const UINT8: u8 = 2;
    pub const INT16: u8 = 3;
    pub const UINT16: u8 = 4;
    pub const INT32: u8 = 5;
    pub const UINT32: u8 = 6;
    pub const FLOAT32: u8 = 7;
    pub const FLOAT64: u8 = 8;
}

/// Joint positions (rad), velocities (rad/s) and efforts of named joints.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    pub header: Header,
    pub name: Vec<String>,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
}
ros_message!(
    JointState,
    "sensor_msgs/msg/JointState",
    "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
);

/// A compressed image (part of `visualization_msgs/Marker` since Jazzy; we leave it empty).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CompressedImage {
    pub header: Header,
    pub format: String,
    pub data: Vec<u8>,
}
ros_message!(
    CompressedImage,
    "sensor_msgs/msg/CompressedImage",
    "RIHS01_15640771531571185e2efc8a100baf923961a4d15d5569652e6cb6691e8e371a"
);

/// One temperature reading (a pyrometer aimed at the torch), degrees Celsius.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Temperature {
    pub header: Header,
    pub temperature: f64,
    /// 0: unknown.
    pub variance: f64,
}
ros_message!(
    Temperature,
    "sensor_msgs/msg/Temperature",
    "RIHS01_72514a14126ab9f8a9abec974c78e5610a367b59db5da355ff1fb982d5bad4b8"
);
