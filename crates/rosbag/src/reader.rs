//! Reads our bags back: every schema, channel and message in file order, tolerating a file
//! cut short (a killed recording) and saying where it ends.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mcap::read::Options;
use mcap::records::Record;
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

use super::metadata::relative_file_paths;
use super::qos::{self, Qos};
use super::BagError;
use waam_rosmsg::{from_cdr, RosMessage};

/// The largest record (or decompressed chunk record) read, bytes. A flipped bit in a
/// length field or a chunk of zeros that compresses 30,000:1 must not make the reader
/// allocate exabytes (it aborted) or gigabytes; no message we record comes near this.
pub const MAX_RECORD_BYTES: usize = 256 << 20;
/// The most message bytes a bag may decompress to in all (the messages are kept in memory).
pub const MAX_MESSAGE_BYTES: u64 = 1 << 30;
/// The largest `metadata.yaml` read (ours are a few kB).
pub const MAX_METADATA_BYTES: u64 = 16 << 20;
/// The largest bag file read (it is read into memory whole).
pub const MAX_FILE_BYTES: u64 = 1 << 30;

/// The length of `path` when it is a regular file (after symlinks). A FIFO blocked the
/// reader for ever and a device such as /dev/zero was read up to gigabytes: refused.
pub(crate) fn regular_file(path: &Path) -> Result<u64, BagError> {
    let meta = std::fs::metadata(path).map_err(|source| BagError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if !meta.is_file() {
        return Err(BagError::Corrupt {
            path: path.to_path_buf(),
            reason: "not a regular file (a FIFO, device or directory is not read)".into(),
        });
    }
    Ok(meta.len())
}

/// `dir.join(relative)` when it stays inside `dir` (after resolving `..` and symlinks):
/// a `metadata.yaml` must not make the reader open files elsewhere.
fn inside(dir: &Path, relative: &str, metadata: &Path) -> Result<PathBuf, BagError> {
    let refuse = |why: &str| BagError::Corrupt {
        path: metadata.to_path_buf(),
        reason: format!("relative_file_paths: {relative:?} {why}"),
    };
    let rel = Path::new(relative);
    if rel.is_absolute()
        || rel.components().any(|c| {
            !matches!(
                c,
                std::path::Component::Normal(_) | std::path::Component::CurDir
            )
        })
    {
        return Err(refuse("must name a file inside the bag folder"));
    }
    let joined = dir.join(rel);
    // Symlinks inside the folder may not lead out of it either.
    if let (Ok(real), Ok(root)) = (joined.canonicalize(), dir.canonicalize()) {
        if !real.starts_with(&root) {
            return Err(refuse("leads out of the bag folder"));
        }
    }
    Ok(joined)
}

/// Every record of an MCAP file in file order, chunks unpacked, as `mcap`'s
/// `ChunkFlattener` yields them, but with [`MAX_RECORD_BYTES`] as the record length limit
/// (ChunkFlattener sets none, and mcap then sizes buffers by untrusted lengths).
pub(crate) struct Records<'a> {
    bytes: &'a [u8],
    rest: &'a [u8],
    reader: LinearReader,
    /// [`Records::resyncing`]: go on past damage.
    resync: bool,
    /// Where the last record returned ended (or the reader was restarted).
    last_end: usize,
    /// Whether a record was returned since the reader was (re)started at `last_end`.
    read_since_start: bool,
    skipped: Vec<Skipped>,
}

/// A damaged stretch of a file that [`Records::resyncing`] stepped over.
#[derive(Debug, Clone, PartialEq)]
pub struct Skipped {
    /// Byte offsets: the end of the last readable record, the next readable record.
    pub from: u64,
    pub to: u64,
    /// Why the record at `from` could not be read.
    pub reason: String,
}

/// Top-level records a reader may start again at after damage: those a chunked writer puts
/// in the data section outside chunks (schemas, channels and messages live in chunks).
const RESYNC_OPCODES: [u8; 3] = [
    mcap::records::op::CHUNK,
    mcap::records::op::METADATA,
    mcap::records::op::ATTACHMENT,
];

impl<'a> Records<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Records<'a> {
        Records {
            bytes,
            rest: bytes,
            reader: Self::reader(false, false),
            resync: false,
            last_end: 0,
            read_since_start: false,
            skipped: Vec::new(),
        }
    }

    /// [`Records::new`] that, at a record it cannot read, starts again at the next chunk,
    /// metadata or attachment record that reads (one with a sane length whose chunk CRC
    /// holds), instead of ending: `waam bag reindex` keeps every intact chunk after damage.
    /// What it stepped over is in [`Records::skipped`].
    pub(crate) fn resyncing(bytes: &'a [u8]) -> Records<'a> {
        Records {
            reader: Self::reader(false, true),
            resync: true,
            ..Records::new(bytes)
        }
    }

    fn reader(mid_file: bool, check_crcs: bool) -> LinearReader {
        let options = LinearReaderOptions::default()
            .with_skip_start_magic(mid_file)
            .with_skip_end_magic(true)
            .with_prevalidate_chunk_crcs(check_crcs)
            .with_record_length_limit(MAX_RECORD_BYTES);
        LinearReader::new_with_options(options)
    }

    /// Bytes of the file read so far. Right after a record is returned this is the end of
    /// the record (for a record inside a chunk: the end of its chunk).
    pub(crate) fn consumed(&self) -> usize {
        self.bytes.len() - self.rest.len()
    }

    /// The damaged stretches stepped over so far (only [`Records::resyncing`] steps over).
    pub(crate) fn skipped(&self) -> &[Skipped] {
        &self.skipped
    }

    /// The next record as the reader gives it.
    fn read(&mut self) -> Option<mcap::McapResult<Record<'static>>> {
        while let Some(event) = self.reader.next_event() {
            match event {
                Ok(LinearReadEvent::ReadRequest(need)) => {
                    // Never more than the file holds: a length field cannot size a buffer.
                    let len = need.min(self.rest.len());
                    self.reader.insert(len).copy_from_slice(&self.rest[..len]);
                    self.reader.notify_read(len);
                    self.rest = &self.rest[len..];
                }
                Ok(LinearReadEvent::Record { data, opcode }) => {
                    return Some(mcap::parse_record(opcode, data).map(Record::into_owned))
                }
                Err(e) => return Some(Err(e)),
            }
        }
        None
    }

    /// The first offset from `from` on where a resync record plausibly begins: its length
    /// fits the file, and a chunk's own lengths and compression add up (so that random
    /// bytes inside damage are rarely tried, each try reading up to its length).
    fn next_candidate(&self, from: usize) -> Option<usize> {
        (from..self.bytes.len()).find(|&at| plausible_record(&self.bytes[at..]))
    }

    /// Restarts the reader at `at`.
    fn restart(&mut self, at: usize) {
        self.reader = Self::reader(true, true);
        self.rest = &self.bytes[at..];
        self.last_end = at;
        self.read_since_start = false;
    }
}

/// Whether `bytes` plausibly begin with a resync record (see [`Records::resyncing`]).
fn plausible_record(bytes: &[u8]) -> bool {
    let u64_at = |at: usize| -> Option<u64> {
        Some(u64::from_le_bytes(bytes.get(at..at + 8)?.try_into().ok()?))
    };
    let u32_at = |at: usize| -> Option<u64> {
        Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?) as u64)
    };
    let (Some(&opcode), Some(len)) = (bytes.first(), u64_at(1)) else {
        return false;
    };
    if !RESYNC_OPCODES.contains(&opcode)
        || len > MAX_RECORD_BYTES as u64
        || len > (bytes.len() - 9) as u64
    {
        return false;
    }
    if opcode != mcap::records::op::CHUNK {
        return true;
    }
    // A chunk: start and end time, uncompressed size and CRC, compression, records.
    let body = 9;
    let (Some(size), Some(clen)) = (u64_at(body + 16), u32_at(body + 28)) else {
        return false;
    };
    let Some(compression) = bytes.get(body + 32..body + 32 + clen.min(16) as usize) else {
        return false;
    };
    let records_at = body + 32 + clen as usize;
    size <= MAX_RECORD_BYTES as u64
        && matches!(compression, b"" | b"zstd" | b"lz4")
        && clen == compression.len() as u64
        && u64_at(records_at).is_some_and(|n| n + (records_at + 8 - body) as u64 == len)
}

impl Iterator for Records<'_> {
    type Item = mcap::McapResult<Record<'static>>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            match self.read() {
                Some(Err(e)) if self.resync => {
                    // Inside a chunk already read whole (a record in it is bad) the next
                    // record starts where the chunk ends; else past the bad record's start.
                    let from = self.last_end;
                    let search = if self.read_since_start && self.consumed() == from {
                        from
                    } else {
                        from + 1
                    };
                    let Some(at) = self.next_candidate(search) else {
                        return Some(Err(e));
                    };
                    match self.skipped.last_mut() {
                        // A false start inside the same damage: one stretch.
                        Some(last) if last.to == from as u64 && !self.read_since_start => {
                            last.to = at as u64
                        }
                        _ => self.skipped.push(Skipped {
                            from: from as u64,
                            to: at as u64,
                            reason: e.to_string(),
                        }),
                    }
                    self.restart(at);
                }
                Some(Ok(record)) => {
                    self.last_end = self.consumed();
                    self.read_since_start = true;
                    return Some(Ok(record));
                }
                other => return other,
            }
        }
    }
}

/// One topic (MCAP channel) of a bag.
#[derive(Debug, Clone, PartialEq)]
pub struct TopicInfo {
    pub name: String,
    /// `pkg/msg/Name` (the schema name).
    pub type_name: String,
    /// Schema encoding (`ros2msg`) and its text.
    pub schema_encoding: String,
    pub definition: String,
    pub message_encoding: String,
    pub offered_qos: Vec<Qos>,
    pub type_hash: String,
    /// Messages read on this topic.
    pub count: u64,
}

/// One recorded message.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedMessage {
    /// Index into [`Bag::topics`].
    pub topic: usize,
    pub sequence: u32,
    /// Receive and send time, ns since the epoch.
    pub log_time: u64,
    pub publish_time: u64,
    /// CDR with its encapsulation header.
    pub data: Vec<u8>,
}

/// Where and why a file ends before its footer.
#[derive(Debug, Clone, PartialEq)]
pub struct Truncation {
    /// Bytes in the file.
    pub file_len: u64,
    /// What the reader found at the end.
    pub reason: String,
}

/// The contents of one bag file.
#[derive(Debug, Clone, PartialEq)]
pub struct Bag {
    pub mcap_file: PathBuf,
    pub profile: String,
    pub library: String,
    pub topics: Vec<TopicInfo>,
    /// In file order (for our bags, also time order per topic).
    pub messages: Vec<RecordedMessage>,
    /// Chunks read whole.
    pub chunks: usize,
    /// The last `rosbag2` metadata record's keys (`ROS_DISTRO`, `serialized_metadata`).
    pub rosbag2_metadata: HashMap<String, String>,
    /// `Some` when the file ends without its summary and footer.
    pub truncated: Option<Truncation>,
}

impl Bag {
    /// Reads a bag directory (through its `metadata.yaml`, or its only `.mcap` file when the
    /// metadata is missing) or a single `.mcap` file.
    pub fn open(path: &Path) -> Result<Bag, BagError> {
        let file = mcap_file_of(path)?;
        let bytes = read_mcap_file(&file)?;
        Bag::from_bytes(&file, &bytes)
    }

    /// Parses the bytes of an MCAP file; `file` names it in errors.
    pub fn from_bytes(file: &Path, bytes: &[u8]) -> Result<Bag, BagError> {
        if !bytes.starts_with(mcap::MAGIC) {
            return Err(BagError::NotMcap(file.to_path_buf()));
        }
        let mut bag = Bag {
            mcap_file: file.to_path_buf(),
            profile: String::new(),
            library: String::new(),
            topics: Vec::new(),
            messages: Vec::new(),
            chunks: 0,
            rosbag2_metadata: HashMap::new(),
            truncated: None,
        };
        let mut schemas: HashMap<u16, (String, String, Arc<str>)> = HashMap::new();
        let mut topic_of_channel: HashMap<u16, usize> = HashMap::new();
        let mut footer = false;
        let mut message_bytes = 0u64;
        for record in Records::new(bytes) {
            let record = match record {
                Ok(r) => r,
                // Not a cut: a chunk this build cannot decompress (rosbag2 may write lz4).
                Err(e @ mcap::McapError::UnsupportedCompression(_)) => {
                    return Err(BagError::Corrupt {
                        path: file.to_path_buf(),
                        reason: format!("{e} (this build reads zstd and uncompressed chunks)"),
                    })
                }
                Err(e) => {
                    bag.truncated = Some(Truncation {
                        file_len: bytes.len() as u64,
                        reason: e.to_string(),
                    });
                    break;
                }
            };
            match record {
                Record::Header(h) => {
                    bag.profile = h.profile;
                    bag.library = h.library;
                }
                Record::Schema { header, data } => {
                    let text = String::from_utf8_lossy(&data).into_owned();
                    schemas.insert(header.id, (header.name, header.encoding, text.into()));
                }
                Record::Channel(c) => {
                    if topic_of_channel.contains_key(&c.id) {
                        continue;
                    }
                    let (type_name, encoding, definition) = schemas
                        .get(&c.schema_id)
                        .cloned()
                        .ok_or_else(|| BagError::Corrupt {
                            path: file.to_path_buf(),
                            reason: format!(
                                "channel {} ({}) refers to unknown schema {}",
                                c.id, c.topic, c.schema_id
                            ),
                        })?;
                    let offered_qos = qos::from_yaml(
                        c.metadata
                            .get("offered_qos_profiles")
                            .map(String::as_str)
                            .unwrap_or(""),
                    )
                    .map_err(|reason| BagError::Corrupt {
                        path: file.to_path_buf(),
                        reason: format!("topic {}: {reason}", c.topic),
                    })?;
                    topic_of_channel.insert(c.id, bag.topics.len());
                    bag.topics.push(TopicInfo {
                        name: c.topic,
                        type_name,
                        schema_encoding: encoding,
                        definition: definition.to_string(),
                        message_encoding: c.message_encoding,
                        offered_qos,
                        type_hash: c
                            .metadata
                            .get("topic_type_hash")
                            .cloned()
                            .unwrap_or_default(),
                        count: 0,
                    });
                }
                Record::Message { header, data } => {
                    let &topic = topic_of_channel.get(&header.channel_id).ok_or_else(|| {
                        BagError::Corrupt {
                            path: file.to_path_buf(),
                            reason: format!(
                                "message {} on unknown channel {}",
                                header.sequence, header.channel_id
                            ),
                        }
                    })?;
                    message_bytes += data.len() as u64;
                    if message_bytes > MAX_MESSAGE_BYTES {
                        return Err(BagError::Corrupt {
                            path: file.to_path_buf(),
                            reason: format!(
                                "the messages decompress to more than {MAX_MESSAGE_BYTES} bytes"
                            ),
                        });
                    }
                    bag.topics[topic].count += 1;
                    bag.messages.push(RecordedMessage {
                        topic,
                        sequence: header.sequence,
                        log_time: header.log_time,
                        publish_time: header.publish_time,
                        data: data.into_owned(),
                    });
                }
                Record::ChunkIndex(_) => {}
                Record::MessageIndex(_) => {}
                Record::Metadata(m) if m.name == "rosbag2" => {
                    bag.rosbag2_metadata = m.metadata.into_iter().collect()
                }
                Record::DataEnd(_) => {}
                Record::Footer(_) => footer = true,
                _ => {}
            }
        }
        bag.chunks = count_chunks(bytes);
        if bag.truncated.is_none() {
            let reason = if !footer {
                Some("the file ends without a footer")
            } else if bytes.len() < 2 * mcap::MAGIC.len() || !bytes.ends_with(mcap::MAGIC) {
                Some("the file ends without its closing magic")
            } else {
                None
            };
            bag.truncated = reason.map(|reason| Truncation {
                file_len: bytes.len() as u64,
                reason: reason.into(),
            });
        }
        Ok(bag)
    }

    /// The topic a message was recorded on.
    pub fn topic_of(&self, message: &RecordedMessage) -> &TopicInfo {
        &self.topics[message.topic]
    }

    /// Messages read on `topic` (0 for a topic not in the bag).
    pub fn count(&self, topic: &str) -> u64 {
        self.topics
            .iter()
            .find(|t| t.name == topic)
            .map_or(0, |t| t.count)
    }

    /// Messages on topics of type `M`, decoded, with their receive times.
    pub fn decode_all<M: RosMessage>(&self) -> Result<Vec<(u64, &str, M)>, BagError> {
        self.messages
            .iter()
            .filter(|m| self.topics[m.topic].type_name == M::TYPE_NAME)
            .map(|m| {
                let topic = self.topics[m.topic].name.as_str();
                from_cdr::<M>(&m.data)
                    .map(|msg| (m.log_time, topic, msg))
                    .map_err(|e| BagError::Decode {
                        topic: topic.to_string(),
                        log_time: m.log_time,
                        source: e,
                    })
            })
            .collect()
    }

    /// Messages on topics of type `M`, decoded, in file order.
    pub fn decode<M: RosMessage>(&self) -> Result<Vec<M>, BagError> {
        Ok(self.decode_all()?.into_iter().map(|(_, _, m)| m).collect())
    }

    /// First and last receive time of the messages read, ns since the epoch.
    pub fn time_range(&self) -> Option<(u64, u64)> {
        let mut times = self.messages.iter().map(|m| m.log_time);
        let first = times.next()?;
        Some(times.fold((first, first), |(a, b), t| (a.min(t), b.max(t))))
    }
}

/// The bytes of an MCAP file: a regular file of at most [`MAX_FILE_BYTES`].
pub(crate) fn read_mcap_file(file: &Path) -> Result<Vec<u8>, BagError> {
    let len = regular_file(file)?;
    if len > MAX_FILE_BYTES {
        return Err(BagError::Corrupt {
            path: file.to_path_buf(),
            reason: format!("{len} bytes: bags are read in memory, up to {MAX_FILE_BYTES} bytes"),
        });
    }
    std::fs::read(file).map_err(|source| BagError::Io {
        path: file.to_path_buf(),
        source,
    })
}

/// The MCAP file of a bag path: the path itself, or the file a bag directory's
/// `metadata.yaml` names (falling back to its only `.mcap` file).
pub fn mcap_file_of(path: &Path) -> Result<PathBuf, BagError> {
    if !path.is_dir() {
        if !path.exists() {
            return Err(BagError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "no such file or directory",
                ),
            });
        }
        return Ok(path.to_path_buf());
    }
    let metadata = path.join("metadata.yaml");
    if metadata.exists() && regular_file(&metadata)? > MAX_METADATA_BYTES {
        return Err(BagError::Corrupt {
            path: metadata,
            reason: format!("larger than {MAX_METADATA_BYTES} bytes"),
        });
    }
    if let Ok(text) = std::fs::read_to_string(&metadata) {
        let files = relative_file_paths(&text).map_err(|e| BagError::Corrupt {
            path: metadata.clone(),
            reason: e.to_string(),
        })?;
        return match files.as_slice() {
            [one] => inside(path, one, &metadata),
            [] => Err(BagError::Corrupt {
                path: metadata,
                reason: "relative_file_paths is empty".into(),
            }),
            _ => Err(BagError::Corrupt {
                path: metadata,
                reason: format!("split bags are not supported ({} files)", files.len()),
            }),
        };
    }
    let mut mcaps: Vec<PathBuf> = std::fs::read_dir(path)
        .map_err(|source| BagError::Io {
            path: path.to_path_buf(),
            source,
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    mcaps.sort();
    match mcaps.len() {
        1 => Ok(mcaps.remove(0)),
        n => Err(BagError::Corrupt {
            path: path.to_path_buf(),
            reason: format!("no metadata.yaml and {n} .mcap files (expected one)"),
        }),
    }
}

/// Chunks that were read whole (a partial last chunk is not counted).
fn count_chunks(bytes: &[u8]) -> usize {
    let Ok(reader) =
        mcap::read::LinearReader::new_with_options(bytes, Options::IgnoreEndMagic.into())
    else {
        return 0;
    };
    reader
        .take_while(Result::is_ok)
        .filter(|r| matches!(r, Ok(Record::Chunk { .. })))
        .count()
}
