//! `std_msgs`: header, string, bool, colour.

use serde::{Deserialize, Serialize};

use super::builtin_interfaces::Time;
use super::ros_message;

/// Time stamp and coordinate frame of a message.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: std::string::String,
}
ros_message!(
    Header,
    "std_msgs/msg/Header",
    "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01"
);

impl Header {
    pub fn new(stamp: Time, frame_id: impl Into<std::string::String>) -> Header {
        Header {
            stamp,
            frame_id: frame_id.into(),
        }
    }
}

/// A string (the node's part input carries a part document in one).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct String {
    pub data: std::string::String,
}
ros_message!(
    String,
    "std_msgs/msg/String",
    "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
);

impl From<&str> for String {
    fn from(data: &str) -> String {
        String { data: data.into() }
    }
}

/// A boolean (arc on/off).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Bool {
    pub data: bool,
}
ros_message!(
    Bool,
    "std_msgs/msg/Bool",
    "RIHS01_feb91e995ff9ebd09c0cb3d2aed18b11077585839fb5db80193b62d74528f6c9"
);

/// A number (the wire feed override, relative to nominal).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Float64 {
    pub data: f64,
}
ros_message!(
    Float64,
    "std_msgs/msg/Float64",
    "RIHS01_705ba9c3d1a09df43737eb67095534de36fd426c0587779bda2bc51fe790182a"
);

/// A colour, components in `[0, 1]`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ColorRGBA {
    pub r: f32,
    pub g: f32,
    pub b: f32,
    pub a: f32,
}
ros_message!(
    ColorRGBA,
    "std_msgs/msg/ColorRGBA",
    "RIHS01_77a7a5b9ae477306097665106e0413ba74440245b1f3d0c6d6405fe5c7813fe8"
);
