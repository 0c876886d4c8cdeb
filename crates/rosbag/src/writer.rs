//! Writes a rosbag2 bag directory: `metadata.yaml` and one MCAP file in rosbag2's layout.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use mcap::records::{MessageHeader, Metadata};
use mcap::{Compression, WriteOptions};

use super::metadata::{BagMetadata, TopicInformation, TopicMetadata, ROS_DISTRO};
use super::qos::{self, Qos};
use super::BagError;
use waam_rosmsg::{to_cdr, RosMessage};

/// How big and how old a chunk may grow before it is closed and flushed to disk. A process
/// killed mid-recording loses at most the open chunk: the file stays readable up to the last
/// closed one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BagOptions {
    /// Uncompressed bytes of messages in one chunk (rosbag2's default is 768 KiB).
    pub chunk_bytes: u64,
    /// Longest time a chunk stays open.
    pub chunk_age: Duration,
    /// zstd level (rosbag2's `zstd_fast` preset uses the fastest).
    pub zstd_level: u32,
}

impl Default for BagOptions {
    fn default() -> Self {
        BagOptions {
            chunk_bytes: 768 * 1024,
            chunk_age: Duration::from_secs(1),
            zstd_level: 1,
        }
    }
}

/// What a finished bag holds.
#[derive(Debug, Clone, PartialEq)]
pub struct BagSummary {
    pub dir: PathBuf,
    pub mcap_file: PathBuf,
    pub messages: u64,
    pub topics: usize,
    pub chunks: usize,
}

struct Topic {
    metadata: TopicMetadata,
    channel: u16,
    count: u64,
}

/// Writes one bag. Call [`BagWriter::finish`] at the end; a writer dropped unfinished
/// finishes itself and logs any error.
pub struct BagWriter {
    dir: PathBuf,
    file_name: String,
    mcap: Option<mcap::Writer<BufWriter<File>>>,
    /// A second handle on the MCAP file, for `fsync` (the mcap writer does not lend its own).
    file: File,
    options: BagOptions,
    topics: Vec<Topic>,
    topic_of: HashMap<String, usize>,
    schema_of: HashMap<String, u16>,
    chunk_bytes: u64,
    chunk_opened: Option<Instant>,
    times: Option<(u64, u64)>,
    messages: u64,
}

impl BagWriter {
    /// Creates the bag directory `dir` (it must not exist, like `ros2 bag record -o`) with
    /// `<name>_0.mcap` inside, `<name>` being the directory's own name.
    pub fn create(dir: &Path, options: BagOptions) -> Result<BagWriter, BagError> {
        let io = |source| BagError::Io {
            path: dir.to_path_buf(),
            source,
        };
        if dir.exists() {
            return Err(BagError::Exists(dir.to_path_buf()));
        }
        let name = dir
            .file_name()
            .and_then(|n| n.to_str())
            .filter(|n| !n.is_empty())
            .ok_or_else(|| BagError::BadPath(dir.to_path_buf()))?
            .to_string();
        std::fs::create_dir_all(dir).map_err(io)?;
        let file_name = format!("{name}_0.mcap");
        let path = dir.join(&file_name);
        let io_at = |source| BagError::Io {
            path: path.clone(),
            source,
        };
        let file = File::create(&path).map_err(io_at)?;
        let sync_handle = file.try_clone().map_err(io_at)?;
        let mcap = WriteOptions::new()
            .profile("ros2")
            .library(concat!(
                "waam-planner ",
                env!("CARGO_PKG_VERSION"),
                " (mcap-rs)"
            ))
            .compression(Some(Compression::Zstd))
            .compression_level(options.zstd_level)
            // Chunks are closed by `flush_if_due` alone, so each closed chunk also reaches
            // the operating system at once.
            .chunk_size(None)
            // Whole chunks are assembled in memory and written at once, so a killed process
            // leaves no half-written chunk behind a valid one.
            .disable_seeking(true)
            .calculate_chunk_crcs(false)
            .create(BufWriter::with_capacity(1 << 20, file))
            .map_err(|e| BagError::mcap(&path, e))?;
        let mut writer = BagWriter {
            dir: dir.to_path_buf(),
            file_name,
            mcap: Some(mcap),
            file: sync_handle,
            options,
            topics: Vec::new(),
            topic_of: HashMap::new(),
            schema_of: HashMap::new(),
            chunk_bytes: 0,
            chunk_opened: None,
            times: None,
            messages: 0,
        };
        // Like rosbag2: the metadata record goes in at the start (so even a killed recording
        // names its distribution) and again, complete, at the end.
        writer.write_metadata_record()?;
        writer.flush()?;
        Ok(writer)
    }

    /// The bag directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Whether messages are waiting in a chunk not yet on disk.
    pub fn chunk_is_open(&self) -> bool {
        self.chunk_opened.is_some()
    }

    fn path(&self) -> PathBuf {
        self.dir.join(&self.file_name)
    }

    fn mcap(&mut self) -> Result<&mut mcap::Writer<BufWriter<File>>, BagError> {
        self.mcap.as_mut().ok_or(BagError::Finished)
    }

    /// Declares a topic. Declaring it again with the same type is a no-op; with another type
    /// it is an error (a rosbag2 topic has one type).
    pub fn add_topic(
        &mut self,
        topic: &str,
        type_name: &str,
        definition: &str,
        type_hash: &str,
        offered_qos: &[Qos],
    ) -> Result<(), BagError> {
        if let Some(&i) = self.topic_of.get(topic) {
            let known = &self.topics[i].metadata.type_name;
            if known != type_name {
                return Err(BagError::TopicType {
                    topic: topic.to_string(),
                    recorded: known.clone(),
                    given: type_name.to_string(),
                });
            }
            return Ok(());
        }
        let path = self.path();
        let schema = match self.schema_of.get(type_name) {
            Some(&id) => id,
            None => {
                let id = self
                    .mcap()?
                    .add_schema(type_name, "ros2msg", definition.as_bytes())
                    .map_err(|e| BagError::mcap(&path, e))?;
                self.schema_of.insert(type_name.to_string(), id);
                id
            }
        };
        let mut metadata = BTreeMap::new();
        metadata.insert(
            "offered_qos_profiles".to_string(),
            qos::to_yaml(offered_qos),
        );
        metadata.insert("topic_type_hash".to_string(), type_hash.to_string());
        let channel = self
            .mcap()?
            .add_channel(schema, topic, "cdr", &metadata)
            .map_err(|e| BagError::mcap(&path, e))?;
        self.topic_of.insert(topic.to_string(), self.topics.len());
        self.topics.push(Topic {
            metadata: TopicMetadata {
                name: topic.to_string(),
                type_name: type_name.to_string(),
                serialization_format: "cdr".to_string(),
                offered_qos_profiles: offered_qos.to_vec(),
                type_description_hash: type_hash.to_string(),
            },
            channel,
            count: 0,
        });
        Ok(())
    }

    /// Writes one serialized message (CDR with its encapsulation header) on a declared topic.
    /// `log_time` is when it was received, `publish_time` when it was sent (ns since epoch).
    pub fn write_raw(
        &mut self,
        topic: &str,
        log_time: u64,
        publish_time: u64,
        cdr: &[u8],
    ) -> Result<(), BagError> {
        let &i = self
            .topic_of
            .get(topic)
            .ok_or_else(|| BagError::UnknownTopic(topic.to_string()))?;
        let channel = self.topics[i].channel;
        let sequence = (self.topics[i].count + 1) as u32;
        let path = self.path();
        self.mcap()?
            .write_to_known_channel(
                &MessageHeader {
                    channel_id: channel,
                    sequence,
                    log_time,
                    publish_time,
                },
                cdr,
            )
            .map_err(|e| BagError::mcap(&path, e))?;
        self.topics[i].count += 1;
        self.messages += 1;
        self.times = Some(match self.times {
            None => (log_time, log_time),
            Some((a, b)) => (a.min(log_time), b.max(log_time)),
        });
        // A message record adds 31 bytes: opcode, length, channel, sequence and two times.
        self.chunk_bytes += cdr.len() as u64 + 31;
        self.chunk_opened.get_or_insert_with(Instant::now);
        self.flush_if_due()?;
        Ok(())
    }

    /// Serializes and writes a message, declaring its topic on first use.
    pub fn write<M: RosMessage>(
        &mut self,
        topic: &str,
        offered_qos: &Qos,
        log_time: u64,
        message: &M,
    ) -> Result<(), BagError> {
        if let Some(&i) = self.topic_of.get(topic) {
            let known = &self.topics[i].metadata.type_name;
            if known != M::TYPE_NAME {
                return Err(BagError::TopicType {
                    topic: topic.to_string(),
                    recorded: known.clone(),
                    given: M::TYPE_NAME.to_string(),
                });
            }
        } else {
            self.add_topic(
                topic,
                M::TYPE_NAME,
                &M::definition(),
                M::TYPE_HASH,
                std::slice::from_ref(offered_qos),
            )?;
        }
        let cdr = to_cdr(message)?;
        self.write_raw(topic, log_time, log_time, &cdr)
    }

    /// Closes the open chunk if it is too big or too old.
    pub fn flush_if_due(&mut self) -> Result<bool, BagError> {
        let due = self.chunk_bytes >= self.options.chunk_bytes
            || self
                .chunk_opened
                .is_some_and(|t| t.elapsed() >= self.options.chunk_age);
        if due {
            self.flush()?;
        }
        Ok(due)
    }

    /// Closes the open chunk, pushes it to the operating system and refreshes
    /// `metadata.yaml`: whatever happens to the process afterwards, the bag is readable up
    /// to here.
    pub fn flush(&mut self) -> Result<(), BagError> {
        let path = self.path();
        self.chunk_opened = None;
        self.mcap()?.flush().map_err(|e| BagError::mcap(&path, e))?;
        self.chunk_bytes = 0;
        self.write_metadata_yaml()
    }

    /// Closes the open chunk and makes the file durable (`fsync`): for what must survive
    /// even a power cut, such as the input a run is about to plan.
    pub fn sync(&mut self) -> Result<(), BagError> {
        self.flush()?;
        self.file.sync_data().map_err(|source| BagError::Io {
            path: self.path(),
            source,
        })
    }

    fn metadata(&self) -> BagMetadata {
        let topics = self
            .topics
            .iter()
            .map(|t| TopicInformation {
                topic_metadata: t.metadata.clone(),
                message_count: t.count,
            })
            .collect();
        BagMetadata::of_one_file(&self.file_name, topics, self.times)
    }

    fn write_metadata_record(&mut self) -> Result<(), BagError> {
        let mut map = BTreeMap::new();
        map.insert(
            "serialized_metadata".to_string(),
            self.metadata().to_record_yaml(),
        );
        map.insert("ROS_DISTRO".to_string(), ROS_DISTRO.to_string());
        let path = self.path();
        self.mcap()?
            .write_metadata(&Metadata {
                name: "rosbag2".to_string(),
                metadata: map,
            })
            .map_err(|e| BagError::mcap(&path, e))
    }

    fn write_metadata_yaml(&self) -> Result<(), BagError> {
        write_metadata_yaml(&self.dir, &self.metadata())
    }

    /// Writes the final metadata record, the summary (statistics, schemas, channels, chunk
    /// and metadata indexes) and the footer, and the final `metadata.yaml`.
    pub fn finish(mut self) -> Result<BagSummary, BagError> {
        self.finish_in_place()
    }

    fn finish_in_place(&mut self) -> Result<BagSummary, BagError> {
        let path = self.path();
        self.chunk_opened = None;
        self.write_metadata_record()?;
        let mut mcap = self.mcap.take().ok_or(BagError::Finished)?;
        let summary = mcap.finish().map_err(|e| BagError::mcap(&path, e))?;
        let mut file = mcap.into_inner();
        file.flush().map_err(|source| BagError::Io {
            path: path.clone(),
            source,
        })?;
        self.write_metadata_yaml()?;
        Ok(BagSummary {
            dir: self.dir.clone(),
            mcap_file: path,
            messages: self.messages,
            topics: self.topics.len(),
            chunks: summary.chunk_indexes.len(),
        })
    }
}

/// Writes `DIR/metadata.yaml` through a temporary file, so a reader never sees half of it.
pub(crate) fn write_metadata_yaml(dir: &Path, metadata: &BagMetadata) -> Result<(), BagError> {
    let path = dir.join("metadata.yaml");
    let tmp = dir.join("metadata.yaml.tmp");
    let io = |source| BagError::Io {
        path: path.clone(),
        source,
    };
    let mut file = File::create(&tmp).map_err(io)?;
    file.write_all(metadata.to_file_yaml().as_bytes())
        .map_err(io)?;
    std::fs::rename(&tmp, &path).map_err(io)
}

impl Drop for BagWriter {
    fn drop(&mut self) {
        if self.mcap.is_some() {
            if let Err(e) = self.finish_in_place() {
                tracing::error!("closing bag {}: {e}", self.dir.display());
            }
        }
    }
}
