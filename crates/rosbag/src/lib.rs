//! Recording to and reading from rosbag2 bags with MCAP storage, laid out as rosbag2 (ROS 2
//! Jazzy) writes them, so `ros2 bag info/play`, Foxglove and Python readers open them:
//!
//! - `DIR/metadata.yaml`: rosbag2 metadata version 9 with per-topic offered QoS;
//! - `DIR/<DIR name>_0.mcap`: profile `ros2`, one `ros2msg` schema per type (the complete
//!   definition), `cdr` messages, channel metadata `offered_qos_profiles` and
//!   `topic_type_hash`, the `rosbag2` metadata record, zstd chunks with message indexes, and
//!   a summary with statistics and chunk indexes.
//!
//! Chunks are bounded in size and age and each closed chunk is flushed to disk with a fresh
//! `metadata.yaml`, so a recording killed mid-run stays readable up to its last closed chunk;
//! [`Recorder::sync`] makes a run's input durable before it is planned. [`Bag::open`] reads
//! such a file and reports it as truncated; [`reindex`] rewrites it complete (summary,
//! indexes, closing magic) for readers that need the index.

use std::path::{Path, PathBuf};

pub mod metadata;
pub mod qos;
pub mod reader;
pub mod recorder;
pub mod reindex;
pub mod writer;

pub use qos::Qos;
pub use reader::{Bag, RecordedMessage, Skipped, TopicInfo, Truncation};
pub use recorder::Recorder;
pub use reindex::{reindex, Reindexed};
pub use writer::{BagOptions, BagSummary, BagWriter};

use waam_rosmsg::CdrError;

/// A bag could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: already exists (a recording goes into a new directory)", .0.display())]
    Exists(PathBuf),
    #[error("{}: not a usable bag directory name", .0.display())]
    BadPath(PathBuf),
    #[error("{}: not an MCAP file (no MCAP magic at the start)", .0.display())]
    NotMcap(PathBuf),
    #[error("{}: {reason}", path.display())]
    Mcap { path: PathBuf, reason: String },
    #[error("{}: {reason}", path.display())]
    Corrupt { path: PathBuf, reason: String },
    #[error("topic {topic} is recorded as {recorded}, cannot record {given} on it")]
    TopicType {
        topic: String,
        recorded: String,
        given: String,
    },
    #[error("topic {0} was not declared")]
    UnknownTopic(String),
    #[error("the recording is already finished")]
    Finished,
    #[error(transparent)]
    Cdr(#[from] CdrError),
    #[error("message on {topic} at {log_time} ns: {source}")]
    Decode {
        topic: String,
        log_time: u64,
        source: CdrError,
    },
}

impl BagError {
    fn mcap(path: &Path, error: mcap::McapError) -> BagError {
        BagError::Mcap {
            path: path.to_path_buf(),
            reason: with_causes(&error),
        }
    }
}

/// An error's message followed by its causes: mcap's I/O error says only "I/O error from
/// writing, or reading a compression stream", and the cause ("No space left on device")
/// is what a user needs.
fn with_causes(error: &dyn std::error::Error) -> String {
    let mut text = error.to_string();
    let mut cause = error.source();
    while let Some(c) = cause {
        let more = c.to_string();
        if !text.contains(&more) {
            text = format!("{text}: {more}");
        }
        cause = c.source();
    }
    text
}

#[cfg(test)]
mod tests;
