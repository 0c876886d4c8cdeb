//! rosbag2's bag metadata (version 9): `metadata.yaml` and the MCAP `rosbag2` metadata record.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::qos::Qos;

/// The metadata version rosbag2 in ROS 2 Jazzy writes.
pub const VERSION: u32 = 9;
/// The ROS distribution whose conventions the bag follows.
pub const ROS_DISTRO: &str = "jazzy";

/// A span of time, as rosbag2 writes it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Nanoseconds {
    pub nanoseconds: u64,
}

/// A point in time, as rosbag2 writes it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SinceEpoch {
    pub nanoseconds_since_epoch: u64,
}

/// One topic of the bag.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TopicMetadata {
    pub name: String,
    #[serde(rename = "type")]
    pub type_name: String,
    pub serialization_format: String,
    pub offered_qos_profiles: Vec<Qos>,
    pub type_description_hash: String,
}

/// A topic with its message count.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TopicInformation {
    pub topic_metadata: TopicMetadata,
    pub message_count: u64,
}

/// One storage file of the bag.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileInformation {
    pub path: String,
    pub starting_time: SinceEpoch,
    pub duration: Nanoseconds,
    pub message_count: u64,
}

/// `rosbag2_storage::BagMetadata`, keys in rosbag2's order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BagMetadata {
    pub version: u32,
    pub storage_identifier: String,
    pub duration: Nanoseconds,
    pub starting_time: SinceEpoch,
    pub message_count: u64,
    pub topics_with_message_count: Vec<TopicInformation>,
    pub compression_format: String,
    pub compression_mode: String,
    pub relative_file_paths: Vec<String>,
    pub files: Vec<FileInformation>,
    pub custom_data: Option<BTreeMap<String, String>>,
    pub ros_distro: String,
}

#[derive(Serialize)]
struct MetadataFile<'a> {
    rosbag2_bagfile_information: &'a BagMetadata,
}

impl BagMetadata {
    /// The metadata of a bag of one MCAP file, `file_name`, holding `topics` whose messages
    /// span `times` (first and last receive time, ns since the epoch; `None`: no messages).
    pub fn of_one_file(
        file_name: &str,
        topics: Vec<TopicInformation>,
        times: Option<(u64, u64)>,
    ) -> BagMetadata {
        let (start, end) = times.unwrap_or((0, 0));
        let duration = Nanoseconds {
            nanoseconds: end.saturating_sub(start),
        };
        let starting_time = SinceEpoch {
            nanoseconds_since_epoch: start,
        };
        let message_count = topics.iter().map(|t| t.message_count).sum();
        BagMetadata {
            version: VERSION,
            storage_identifier: "mcap".to_string(),
            duration,
            starting_time,
            message_count,
            topics_with_message_count: topics,
            compression_format: String::new(),
            compression_mode: String::new(),
            relative_file_paths: vec![file_name.to_string()],
            files: vec![FileInformation {
                path: file_name.to_string(),
                starting_time,
                duration,
                message_count,
            }],
            custom_data: None,
            ros_distro: ROS_DISTRO.to_string(),
        }
    }

    /// The `metadata.yaml` text.
    pub fn to_file_yaml(&self) -> String {
        serde_yaml::to_string(&MetadataFile {
            rosbag2_bagfile_information: self,
        })
        .expect("bag metadata serializes to YAML")
    }

    /// The `serialized_metadata` value of the MCAP `rosbag2` metadata record (no top key).
    pub fn to_record_yaml(&self) -> String {
        serde_yaml::to_string(self)
            .expect("bag metadata serializes to YAML")
            .trim_end()
            .to_string()
    }
}

/// The storage files a `metadata.yaml` names, for finding the MCAP file of a bag directory.
/// `metadata.yaml` is not what rosbag2 writes (the message says which key).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct MetadataError(pub String);

impl From<String> for MetadataError {
    fn from(message: String) -> Self {
        MetadataError(message)
    }
}

impl From<&str> for MetadataError {
    fn from(message: &str) -> Self {
        MetadataError(message.to_string())
    }
}

pub fn relative_file_paths(yaml: &str) -> Result<Vec<String>, MetadataError> {
    waam_yaml::check(yaml).map_err(|e| format!("metadata.yaml: {e}"))?;
    let value: serde_yaml::Value =
        serde_yaml::from_str(yaml).map_err(|e| format!("metadata.yaml: {e}"))?;
    let info = value
        .get("rosbag2_bagfile_information")
        .ok_or("metadata.yaml: no rosbag2_bagfile_information key")?;
    let paths = info
        .get("relative_file_paths")
        .and_then(|p| p.as_sequence())
        .ok_or("metadata.yaml: rosbag2_bagfile_information.relative_file_paths is not a list")?;
    paths
        .iter()
        .map(|p| {
            p.as_str()
                .map(str::to_string)
                .ok_or_else(|| "metadata.yaml: a relative_file_paths entry is not a string".into())
        })
        .collect()
}
