//! ROS 2 message types the node publishes and the recorder writes, as plain Rust structs.
//!
//! Each struct lists its fields in the order of its ROS 2 definition, so serde + `cdr-encoding`
//! give exactly the CDR bytes an `rclcpp` / `rclpy` peer sends. Each type knows its ROS name,
//! its complete `ros2msg` definition as rosbag2 stores it in MCAP, and its RIHS01 type hash.
//! The standard definitions are the ROS 2 Jazzy `.msg` files, vendored in `crates/rosmsg/src/defs/`;
//! ours live in the colcon package `ros/waam_interfaces/`.

use serde::de::DeserializeOwned;
use serde::Serialize;

pub mod builtin_interfaces;
pub mod control_msgs;
pub mod definition;
pub mod diagnostic_msgs;
pub mod dispatch;
pub mod geometry_msgs;
pub mod nav_msgs;
pub mod rcl_interfaces;
pub mod sensor_msgs;
pub mod shape_msgs;
pub mod std_msgs;
pub mod tf2_msgs;
pub mod trajectory_msgs;
pub mod visualization_msgs;
pub mod waam_interfaces;

/// The 4-byte encapsulation header of little-endian plain CDR (`CDR_LE`), as ROS 2 sends it.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// A ROS 2 message type.
pub trait RosMessage: Serialize + DeserializeOwned {
    /// Full ROS name, e.g. `std_msgs/msg/String`.
    const TYPE_NAME: &'static str;
    /// RIHS01 type hash (REP 2011), e.g. `RIHS01_df66…`.
    const TYPE_HASH: &'static str;

    /// The complete `ros2msg` definition (this type, then every dependency once) as rosbag2
    /// writes it into an MCAP schema record.
    fn definition() -> String {
        definition::full_text(Self::TYPE_NAME)
            .expect("every RosMessage type has its definition and dependencies vendored")
    }

    /// The type name as `ros2-client` wants it for creating a topic.
    #[cfg(feature = "ros2-client")]
    fn message_type_name() -> ros2_client::MessageTypeName {
        let (package, name) = definition::split_type_name(Self::TYPE_NAME)
            .expect("RosMessage::TYPE_NAME is pkg/msg/Name");
        ros2_client::MessageTypeName::new(package, name)
    }
}

/// A message could not be turned into CDR or back.
#[derive(Debug, thiserror::Error)]
pub enum CdrError {
    #[error("cannot serialize {type_name} to CDR: {source}")]
    Serialize {
        type_name: &'static str,
        source: cdr_encoding::Error,
    },
    #[error("{type_name}: message of {len} bytes is too short for the CDR encapsulation header")]
    TooShort { type_name: &'static str, len: usize },
    #[error(
        "{type_name}: unsupported CDR encapsulation {header:02x?} (expected CDR_LE or CDR_BE)"
    )]
    Encapsulation {
        type_name: &'static str,
        header: [u8; 2],
    },
    #[error("cannot decode {type_name} from CDR: {source}")]
    Deserialize {
        type_name: &'static str,
        source: cdr_encoding::Error,
    },
}

/// Serializes a message as ROS 2 sends it: CDR_LE encapsulation header, then the CDR body.
pub fn to_cdr<M: RosMessage>(message: &M) -> Result<Vec<u8>, CdrError> {
    let mut out = Vec::with_capacity(256);
    out.extend_from_slice(&CDR_LE_HEADER);
    cdr_encoding::to_writer::<M, byteorder::LittleEndian, _>(&mut out, message).map_err(
        |source| CdrError::Serialize {
            type_name: M::TYPE_NAME,
            source,
        },
    )?;
    Ok(out)
}

/// Decodes a message with its encapsulation header (little- or big-endian plain CDR).
pub fn from_cdr<M: RosMessage>(bytes: &[u8]) -> Result<M, CdrError> {
    if bytes.len() < 4 {
        return Err(CdrError::TooShort {
            type_name: M::TYPE_NAME,
            len: bytes.len(),
        });
    }
    let body = &bytes[4..];
    let decoded = match [bytes[0], bytes[1]] {
        [0x00, 0x01] => cdr_encoding::from_bytes::<M, byteorder::LittleEndian>(body),
        [0x00, 0x00] => cdr_encoding::from_bytes::<M, byteorder::BigEndian>(body),
        header => {
            return Err(CdrError::Encapsulation {
                type_name: M::TYPE_NAME,
                header,
            })
        }
    };
    decoded
        .map(|(message, _)| message)
        .map_err(|source| CdrError::Deserialize {
            type_name: M::TYPE_NAME,
            source,
        })
}

/// A message type generic code can handle at run time (decode, and with the `ros2-client`
/// feature publish): see [`dispatch`].
#[cfg(feature = "ros2-client")]
pub trait AnyMessage: RosMessage + ros2_client::Message + Clone + Send + 'static {}
#[cfg(feature = "ros2-client")]
impl<M: RosMessage + ros2_client::Message + Clone + Send + 'static> AnyMessage for M {}
/// A message type generic code can handle at run time: see [`dispatch`].
#[cfg(not(feature = "ros2-client"))]
pub trait AnyMessage: RosMessage + Clone + Send + 'static {}
#[cfg(not(feature = "ros2-client"))]
impl<M: RosMessage + Clone + Send + 'static> AnyMessage for M {}

/// Implements [`RosMessage`] (and `ros2_client::Message`, so the node can publish it).
macro_rules! ros_message {
    ($rust:ty, $name:literal, $hash:literal) => {
        impl $crate::RosMessage for $rust {
            const TYPE_NAME: &'static str = $name;
            const TYPE_HASH: &'static str = $hash;
        }
        #[cfg(feature = "ros2-client")]
        impl ros2_client::Message for $rust {}
    };
}
pub(crate) use ros_message;

#[cfg(test)]
mod tests;
