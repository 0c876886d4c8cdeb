//! [`reindex`]: a recording whose process died (SIGKILL, power cut, full disk) ends without
//! the MCAP summary, indexes and closing magic that indexed readers (rosbags, `ros2 bag`,
//! the Python `mcap` seeking reader) need. Like `ros2 bag reindex` / `mcap recover`, it
//! reads the file as far as it is readable and rewrites it complete, with a matching
//! `metadata.yaml`.
//!
//! Nothing is lost on the way: the new file is written beside the old one, read back and
//! synced before it replaces the old one by a rename; when the old file has bytes after the
//! last readable record (a half-written chunk, damage), the old file is kept as
//! `<file>.orig`.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use mcap::records::{Metadata, Record};
use mcap::{Attachment, Compression, McapError, WriteOptions};

use super::metadata::{BagMetadata, TopicInformation, TopicMetadata, ROS_DISTRO};
use super::qos;
use super::reader::{mcap_file_of, read_mcap_file, Records, Skipped};
use super::writer::{write_metadata_yaml, BagOptions};
use super::BagError;

/// What [`reindex`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct Reindexed {
    /// The bag's MCAP file (rewritten in place unless it was complete).
    pub mcap_file: PathBuf,
    /// The file already ended with its summary and footer: it was left as it was and only
    /// `metadata.yaml` was written again.
    pub was_complete: bool,
    /// Messages in the bag now (every message that could be read).
    pub messages: u64,
    /// Topics (channels) in the bag now.
    pub topics: usize,
    /// Why reading the old file stopped before its end (`None` when it was complete).
    pub cut: Option<String>,
    /// Bytes at the end of the old file after its last readable record.
    pub unread_bytes: u64,
    /// Damaged stretches of the old file stepped over: reading went on at the next chunk
    /// (or metadata, attachment) record that reads.
    pub skipped: Vec<Skipped>,
    /// Records read but not kept: a message whose channel, or a channel whose schema, was
    /// in a damaged stretch.
    pub skipped_records: u64,
    /// Where the old file was kept: only when it had unread or skipped bytes.
    pub original_kept: Option<PathBuf>,
}

impl Reindexed {
    /// Bytes of the old file stepped over as damage.
    pub fn skipped_bytes(&self) -> u64 {
        self.skipped.iter().map(|s| s.to - s.from).sum()
    }
}

/// Rewrites the bag directory `dir` complete: its MCAP file with summary, chunk and message
/// indexes, statistics and closing magic, holding every record that could be read, and
/// `metadata.yaml` with the message counts, topics, duration and file list of what it now
/// holds. Run it only once the recording process is gone: a live recording also has no
/// summary yet.
pub fn reindex(dir: &Path) -> Result<Reindexed, BagError> {
    if !dir.is_dir() {
        return Err(BagError::Corrupt {
            path: dir.to_path_buf(),
            reason: "not a directory: reindex rewrites a bag directory (its .mcap file and \
                     metadata.yaml)"
                .into(),
        });
    }
    let file = mcap_file_of(dir)?;
    let bytes = read_mcap_file(&file)?;
    if !bytes.starts_with(mcap::MAGIC) {
        return Err(BagError::NotMcap(file));
    }
    let relative = file
        .strip_prefix(dir)
        .unwrap_or(&file)
        .to_string_lossy()
        .into_owned();

    let scan = read_through(&file, &bytes)?;
    if scan.complete {
        write_metadata_yaml(dir, &scan.metadata(&relative))?;
        return Ok(scan.report(file, true, None));
    }

    let file_name = file
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .ok_or_else(|| BagError::BadPath(file.clone()))?;
    let tmp = file.with_file_name(format!(".{file_name}.reindex"));
    let result = write_complete(&file, &bytes, &tmp, &relative);
    let scan = match result {
        Ok(scan) => scan,
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            return Err(e);
        }
    };
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| BagError::Io { path, source }
    };
    // Keep what could not be read: it may be more than a half-written chunk.
    let original_kept = if scan.unread_bytes > 0 || scan.damaged() {
        let kept = free_name(&file.with_file_name(format!("{file_name}.orig")));
        if let Err(e) = std::fs::hard_link(&file, &kept) {
            let _ = std::fs::remove_file(&tmp);
            return Err(io(&kept)(e));
        }
        Some(kept)
    } else {
        None
    };
    std::fs::rename(&tmp, &file).map_err(io(&file))?;
    write_metadata_yaml(dir, &scan.metadata(&relative))?;
    // The renames are durable once the directory is synced.
    if let Some(parent) = file.parent() {
        File::open(parent)
            .and_then(|d| d.sync_all())
            .map_err(io(parent))?;
    }
    Ok(scan.report(file, false, original_kept))
}

/// `path`, or `path.1`, `path.2`, … : the first that does not exist.
fn free_name(path: &Path) -> PathBuf {
    let mut candidate = path.to_path_buf();
    let mut n = 0;
    while candidate.exists() {
        n += 1;
        candidate = PathBuf::from(format!("{}.{n}", path.display()));
    }
    candidate
}

/// Writes the complete file to `tmp`, syncs it and reads it back: it must be complete and
/// hold every message read from the old file.
fn write_complete(file: &Path, bytes: &[u8], tmp: &Path, relative: &str) -> Result<Scan, BagError> {
    let out = File::create(tmp).map_err(|source| BagError::Io {
        path: tmp.to_path_buf(),
        source,
    })?;
    let options = BagOptions::default();
    let header = match Records::new(bytes).next() {
        Some(Ok(Record::Header(h))) => h,
        _ => {
            return Err(BagError::Corrupt {
                path: file.to_path_buf(),
                reason: "no MCAP header record after the magic: nothing to recover".into(),
            })
        }
    };
    let mcap_error = |e| BagError::mcap(tmp, e);
    let mut writer = WriteOptions::new()
        .profile(&header.profile)
        .library(&header.library)
        .compression(Some(Compression::Zstd))
        .compression_level(options.zstd_level)
        .chunk_size(Some(options.chunk_bytes))
        .create(BufWriter::with_capacity(1 << 20, out))
        .map_err(mcap_error)?;
    let scan = copy_records(file, bytes, Some(&mut writer))?;
    // The rosbag2 record of a complete bag: the metadata of what the bag now holds (readers
    // take the last one).
    let mut record = BTreeMap::new();
    record.insert(
        "serialized_metadata".to_string(),
        scan.metadata(relative).to_record_yaml(),
    );
    record.insert("ROS_DISTRO".to_string(), ROS_DISTRO.to_string());
    writer
        .write_metadata(&Metadata {
            name: "rosbag2".to_string(),
            metadata: record,
        })
        .map_err(mcap_error)?;
    writer.finish().map_err(mcap_error)?;
    let out = writer.into_inner().into_inner().map_err(|e| BagError::Io {
        path: tmp.to_path_buf(),
        source: e.into_error(),
    })?;
    out.sync_all().map_err(|source| BagError::Io {
        path: tmp.to_path_buf(),
        source,
    })?;
    // Read back with the same pass (counting, not keeping, the messages).
    let written = read_mcap_file(tmp)?;
    let check = read_through(tmp, &written)?;
    if !check.complete || check.messages() != scan.messages() {
        return Err(BagError::Corrupt {
            path: file.to_path_buf(),
            reason: format!(
                "the rewritten file did not read back complete ({} of {} messages; {:?}); \
                 the original is left as it was",
                check.messages(),
                scan.messages(),
                check.cut
            ),
        });
    }
    Ok(scan)
}

/// One channel as read, with its message count.
struct Channel {
    topic: String,
    schema: u16,
    message_encoding: String,
    metadata: BTreeMap<String, String>,
    count: u64,
}

/// What one pass over the old file found.
struct Scan {
    /// Schema names by id.
    schemas: HashMap<u16, String>,
    /// By id: the order rosbag2 and our writer declare topics in.
    channels: BTreeMap<u16, Channel>,
    /// First and last receive time.
    times: Option<(u64, u64)>,
    /// A footer was read, nothing failed and the closing magic is there.
    complete: bool,
    cut: Option<String>,
    unread_bytes: u64,
    skipped: Vec<Skipped>,
    skipped_records: u64,
}

impl Scan {
    fn messages(&self) -> u64 {
        self.channels.values().map(|c| c.count).sum()
    }

    /// Whether anything in the middle of the file was stepped over.
    fn damaged(&self) -> bool {
        !self.skipped.is_empty() || self.skipped_records > 0
    }

    fn metadata(&self, relative: &str) -> BagMetadata {
        let topics = self
            .channels
            .values()
            .map(|c| TopicInformation {
                topic_metadata: TopicMetadata {
                    name: c.topic.clone(),
                    type_name: self.schemas.get(&c.schema).cloned().unwrap_or_default(),
                    serialization_format: c.message_encoding.clone(),
                    offered_qos_profiles: c
                        .metadata
                        .get("offered_qos_profiles")
                        .and_then(|yaml| qos::from_yaml(yaml).ok())
                        .unwrap_or_default(),
                    type_description_hash: c
                        .metadata
                        .get("topic_type_hash")
                        .cloned()
                        .unwrap_or_default(),
                },
                message_count: c.count,
            })
            .collect();
        BagMetadata::of_one_file(relative, topics, self.times)
    }

    fn report(self, mcap_file: PathBuf, was_complete: bool, kept: Option<PathBuf>) -> Reindexed {
        Reindexed {
            mcap_file,
            was_complete,
            messages: self.messages(),
            topics: self.channels.len(),
            cut: self.cut,
            unread_bytes: self.unread_bytes,
            skipped: self.skipped,
            skipped_records: self.skipped_records,
            original_kept: kept,
        }
    }
}

/// Adds `schema` to the scan and, once, to the writer.
fn copy_schema<W: Write + std::io::Seek>(
    scan: &mut Scan,
    writer: Option<&mut mcap::Writer<W>>,
    copied: &mut HashSet<u16>,
    schema: &mcap::Schema<'_>,
) -> Result<(), McapError> {
    scan.schemas
        .entry(schema.id)
        .or_insert_with(|| schema.name.clone());
    match writer {
        Some(w) if copied.insert(schema.id) => w
            .add_schema_with_id(schema.id, &schema.name, &schema.encoding, &schema.data)
            .map(drop),
        _ => Ok(()),
    }
}

/// Adds channel `id` to the writer and, when the writer takes it (its schema is known),
/// to the scan.
fn copy_channel<W: Write + std::io::Seek>(
    scan: &mut Scan,
    writer: Option<&mut mcap::Writer<W>>,
    id: u16,
    schema_id: u16,
    channel: Channel,
) -> Result<(), McapError> {
    let added = match writer {
        Some(w) => w
            .add_channel_with_id(
                id,
                schema_id,
                &channel.topic,
                &channel.message_encoding,
                &channel.metadata,
            )
            .map(drop),
        None => Ok(()),
    };
    if added.is_ok() {
        scan.channels.insert(id, channel);
    }
    added
}

/// [`copy_records`] without copying: what the file holds and whether it is complete.
fn read_through(file: &Path, bytes: &[u8]) -> Result<Scan, BagError> {
    copy_records(
        file,
        bytes,
        None::<&mut mcap::Writer<std::io::Cursor<Vec<u8>>>>,
    )
}

/// Reads every record of `bytes` in file order, stepping over damage to the next chunk that
/// reads ([`Records::resyncing`]), counts the messages per channel and, with a `writer`,
/// copies schemas, channels, messages, metadata and attachments into it (with their ids,
/// sequence numbers and times). A record the writer refuses (a channel of an unknown
/// schema, a message of an unknown channel: their records were in damage) is left out.
/// Indexes, statistics and the summary are left out: the writer makes new ones.
fn copy_records<W: Write + std::io::Seek>(
    file: &Path,
    bytes: &[u8],
    mut writer: Option<&mut mcap::Writer<W>>,
) -> Result<Scan, BagError> {
    let mut scan = Scan {
        schemas: HashMap::new(),
        channels: BTreeMap::new(),
        times: None,
        complete: false,
        cut: None,
        unread_bytes: 0,
        skipped: Vec::new(),
        skipped_records: 0,
    };
    let mut records = Records::resyncing(bytes);
    // The old summary, when the file has one whose offsets hold: it names the channels
    // and schemas even when the chunk that declared them is damaged.
    let summary = mcap::Summary::read(bytes).ok().flatten();
    let mut readable_end = 0;
    let mut copied_schemas = HashSet::new();
    let mut footer = false;
    while let Some(record) = records.next() {
        let record = match record {
            Ok(r) => r,
            Err(e) => {
                scan.cut = Some(e.to_string());
                break;
            }
        };
        let copied: Result<(), McapError> = match record {
            Record::Schema { header, data } => copy_schema(
                &mut scan,
                writer.as_deref_mut(),
                &mut copied_schemas,
                &mcap::Schema {
                    id: header.id,
                    name: header.name,
                    encoding: header.encoding,
                    data,
                },
            ),
            Record::Channel(c) if !scan.channels.contains_key(&c.id) => copy_channel(
                &mut scan,
                writer.as_deref_mut(),
                c.id,
                c.schema_id,
                Channel {
                    topic: c.topic,
                    schema: c.schema_id,
                    message_encoding: c.message_encoding,
                    metadata: c.metadata,
                    count: 0,
                },
            ),
            Record::Message { header, data } => {
                // A channel whose record was in a damaged chunk: from the old summary,
                // when the file has one.
                if let Some(c) = summary
                    .as_ref()
                    .filter(|_| !scan.channels.contains_key(&header.channel_id))
                    .and_then(|s| s.channels.get(&header.channel_id))
                {
                    if let Some(schema) = &c.schema {
                        let _ = copy_schema(
                            &mut scan,
                            writer.as_deref_mut(),
                            &mut copied_schemas,
                            schema,
                        );
                    }
                    let schema_id = c.schema.as_ref().map_or(0, |s| s.id);
                    let _ = copy_channel(
                        &mut scan,
                        writer.as_deref_mut(),
                        c.id,
                        schema_id,
                        Channel {
                            topic: c.topic.clone(),
                            schema: schema_id,
                            message_encoding: c.message_encoding.clone(),
                            metadata: c.metadata.clone(),
                            count: 0,
                        },
                    );
                }
                match scan.channels.get_mut(&header.channel_id) {
                    Some(channel) => {
                        let written = match writer.as_deref_mut() {
                            Some(w) => w.write_to_known_channel(&header, &data),
                            None => Ok(()),
                        };
                        if written.is_ok() {
                            channel.count += 1;
                            let t = header.log_time;
                            scan.times =
                                Some(scan.times.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
                        }
                        written
                    }
                    None => Err(McapError::UnknownChannel(
                        header.sequence,
                        header.channel_id,
                    )),
                }
            }
            Record::Metadata(m) => match writer.as_deref_mut() {
                Some(w) => w.write_metadata(&m),
                None => Ok(()),
            },
            Record::Attachment { header, data, .. } => match writer.as_deref_mut() {
                Some(w) => w.attach(&Attachment {
                    log_time: header.log_time,
                    create_time: header.create_time,
                    name: header.name,
                    media_type: header.media_type,
                    data,
                }),
                None => Ok(()),
            },
            Record::Footer(_) => {
                footer = true;
                Ok(())
            }
            // Header (the writer wrote its own), indexes, statistics, summary offsets, the
            // data end, repeated channels: the writer makes its own.
            _ => Ok(()),
        };
        match copied {
            Ok(()) => readable_end = records.consumed(),
            Err(McapError::Io(e)) => {
                return Err(BagError::Io {
                    path: file.to_path_buf(),
                    source: e,
                })
            }
            Err(e) => {
                tracing::debug!("{}: record left out: {e}", file.display());
                scan.skipped_records += 1;
                readable_end = records.consumed();
            }
        }
    }
    scan.skipped = records.skipped().to_vec();
    let closed = footer && bytes.ends_with(mcap::MAGIC);
    scan.complete = scan.cut.is_none() && !scan.damaged() && closed;
    if !scan.complete {
        // Read to its closing magic, past damage: nothing at the end is unread.
        let to_the_end = scan.cut.is_none() && closed;
        scan.unread_bytes = if to_the_end {
            0
        } else {
            (bytes.len() - readable_end) as u64
        };
        scan.cut.get_or_insert_with(|| {
            if to_the_end {
                "its end, past the damage".into()
            } else if footer {
                "the file ends without its closing magic".into()
            } else {
                "the file ends without a footer".into()
            }
        });
    }
    Ok(scan)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Bag, BagWriter, Qos};
    use waam_rosmsg::std_msgs::{Bool, String as RosString};

    const T0: u64 = 1_700_000_000_000_000_000;

    /// A finished bag `dir` of 60 messages on two topics in small chunks; its file's bytes.
    fn finished_bag(dir: &Path) -> Vec<u8> {
        let options = BagOptions {
            chunk_bytes: 120,
            ..BagOptions::default()
        };
        let mut w = BagWriter::create(dir, options).unwrap();
        for i in 0..60u64 {
            if i % 3 == 0 {
                let on = Bool { data: i % 2 == 0 };
                w.write("/waam_planner/arc_on", &Qos::reliable(10), T0 + i, &on)
                    .unwrap();
            } else {
                let text = RosString::from(&*format!("part {i}"));
                w.write("/waam_planner/part", &Qos::reliable(10), T0 + i, &text)
                    .unwrap();
            }
        }
        let summary = w.finish().unwrap();
        std::fs::read(summary.mcap_file).unwrap()
    }

    /// Every message as (topic, log time, sequence, bytes).
    fn messages_of(bag: &Bag) -> Vec<(String, u64, u32, Vec<u8>)> {
        bag.messages
            .iter()
            .map(|m| {
                let t = bag.topic_of(m).name.clone();
                (t, m.log_time, m.sequence, m.data.clone())
            })
            .collect()
    }

    /// Every message as an indexed reader reads it: through the summary's chunk indexes
    /// (there is no summary in a killed file, so this reads nothing there).
    fn read_indexed(bytes: &[u8]) -> Vec<(String, u64, u32, Vec<u8>)> {
        let summary = mcap::Summary::read(bytes)
            .unwrap()
            .expect("the file has a summary");
        let mut out = Vec::new();
        for index in &summary.chunk_indexes {
            for m in summary.stream_chunk(bytes, index).unwrap() {
                let m = m.unwrap();
                out.push((
                    m.channel.topic.clone(),
                    m.log_time,
                    m.sequence,
                    m.data.into_owned(),
                ));
            }
        }
        out
    }

    fn yaml_count(dir: &Path) -> (u64, Vec<(String, u64)>) {
        let text = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
        let v: serde_yaml::Value = serde_yaml::from_str(&text).unwrap();
        let info = &v["rosbag2_bagfile_information"];
        let topics = info["topics_with_message_count"]
            .as_sequence()
            .unwrap()
            .iter()
            .map(|t| {
                (
                    t["topic_metadata"]["name"].as_str().unwrap().to_string(),
                    t["message_count"].as_u64().unwrap(),
                )
            })
            .collect();
        (info["message_count"].as_u64().unwrap(), topics)
    }

    /// A file cut anywhere (a killed recording, a copy that stopped) becomes a complete file
    /// holding exactly the messages that could be read from the cut one, readable through
    /// its index, with a metadata.yaml that counts them; a cut in the middle of a record
    /// keeps the old file as `.orig`; a cut too early to hold a header is an error that
    /// leaves the file as it was.
    #[test]
    fn every_cut_of_a_bag_reindexes_to_a_complete_file_of_what_was_readable() {
        let tmp = tempfile::tempdir().unwrap();
        let full_dir = tmp.path().join("full");
        let bytes = finished_bag(&full_dir);
        let metadata = std::fs::read(full_dir.join("metadata.yaml")).unwrap();
        // The magic, then the header record: opcode, u64 length, body.
        let header_len = u64::from_le_bytes(bytes[9..17].try_into().unwrap()) as usize;
        let header_end = 8 + 9 + header_len;
        let mut recovered = std::collections::BTreeSet::new();
        let mut kept = 0;
        for (n, cut) in (0..bytes.len()).step_by(89).enumerate() {
            let dir = tmp.path().join(format!("cut{n}"));
            std::fs::create_dir(&dir).unwrap();
            std::fs::write(dir.join("metadata.yaml"), &metadata).unwrap();
            let file = dir.join("full_0.mcap");
            std::fs::write(&file, &bytes[..cut]).unwrap();
            let done = match reindex(&dir) {
                Ok(done) => done,
                Err(e) => {
                    assert!(cut < header_end, "cut at {cut}: {e}");
                    assert_eq!(std::fs::read(&file).unwrap(), &bytes[..cut]);
                    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2, "left files");
                    continue;
                }
            };
            let before = Bag::from_bytes(&file, &bytes[..cut]).unwrap();
            assert!(!done.was_complete);
            assert_eq!(done.messages, before.messages.len() as u64);
            let after = Bag::open(&dir).unwrap();
            assert!(
                after.truncated.is_none(),
                "cut at {cut}: {:?}",
                after.truncated
            );
            assert_eq!(messages_of(&after), messages_of(&before), "cut at {cut}");
            let new_bytes = std::fs::read(&file).unwrap();
            assert_eq!(
                read_indexed(&new_bytes),
                messages_of(&before),
                "cut at {cut}"
            );
            let (total, topics) = yaml_count(&dir);
            assert_eq!(total, done.messages);
            for (topic, count) in topics {
                assert_eq!(count, before.count(&topic), "cut at {cut}: {topic}");
            }
            match &done.original_kept {
                Some(orig) => {
                    assert!(done.unread_bytes > 0);
                    assert_eq!(std::fs::read(orig).unwrap(), &bytes[..cut]);
                    kept += 1;
                }
                None => assert_eq!(done.unread_bytes, 0),
            }
            recovered.insert(done.messages);
        }
        assert!(recovered.len() > 8, "{recovered:?}");
        assert!(kept > 0);
    }

    /// A complete bag is left byte for byte, and the metadata.yaml written again is the one
    /// the recorder wrote.
    #[test]
    fn a_complete_bag_is_left_as_it_is() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("full");
        let bytes = finished_bag(&dir);
        let metadata = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
        std::fs::remove_file(dir.join("metadata.yaml")).unwrap();
        let done = reindex(&dir).unwrap();
        assert!(done.was_complete);
        assert_eq!(done.messages, 60);
        assert_eq!(std::fs::read(dir.join("full_0.mcap")).unwrap(), bytes);
        let again = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
        assert_eq!(again, metadata);
    }

    /// What is not an MCAP file is an error naming the file, and nothing is written.
    #[test]
    fn a_file_that_is_not_mcap_is_refused_untouched() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("junk");
        std::fs::create_dir(&dir).unwrap();
        std::fs::write(dir.join("junk_0.mcap"), b"not an mcap file at all").unwrap();
        let err = reindex(&dir).unwrap_err().to_string();
        assert!(err.contains("junk_0.mcap") && err.contains("MCAP"), "{err}");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        let err = reindex(&dir.join("junk_0.mcap")).unwrap_err().to_string();
        assert!(err.contains("not a directory"), "{err}");
    }

    /// A damaged chunk in the middle of a bag (a flipped byte in its compressed records, or
    /// a length field that runs past the file) costs that chunk alone: reindex goes on at
    /// the next chunk and keeps every message of the chunks before *and after* it, saying
    /// what it stepped over. Also when the file was killed as well (no summary).
    #[test]
    fn a_damaged_middle_chunk_costs_only_its_own_messages() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("good");
        let bytes = finished_bag(&dir);
        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        let chunks = &summary.chunk_indexes;
        assert!(chunks.len() >= 5, "{} chunks", chunks.len());
        let all = read_indexed(&bytes);
        let k = chunks.len() / 2;
        let lost: Vec<_> = summary
            .stream_chunk(&bytes, &chunks[k])
            .unwrap()
            .map(|m| m.unwrap().log_time)
            .collect();
        assert!(!lost.is_empty());
        let (start, len) = (
            chunks[k].chunk_start_offset as usize,
            chunks[k].chunk_length as usize,
        );
        let data_end = chunks.last().map(|c| c.chunk_start_offset + c.chunk_length);
        let flipped_records = {
            let mut b = bytes.clone();
            b[start + len - 10] ^= 0x5a;
            b
        };
        let long_length = {
            let mut b = bytes.clone();
            b[start + 1..start + 9].copy_from_slice(&(u64::MAX / 2).to_le_bytes());
            b.truncate(data_end.unwrap() as usize);
            b
        };
        for (name, damaged) in [("flipped", flipped_records), ("length", long_length)] {
            let dir = tmp.path().join(name);
            std::fs::create_dir(&dir).unwrap();
            std::fs::write(dir.join("bag_0.mcap"), &damaged).unwrap();
            let done = reindex(&dir).unwrap();
            assert!(!done.was_complete, "{name}");
            assert_eq!(done.skipped.len(), 1, "{name}: {:?}", done.skipped);
            let skip = &done.skipped[0];
            assert_eq!(skip.from as usize, start, "{name}: {skip:?}");
            // Up to the next chunk: the damaged chunk's message indexes follow it.
            let next = chunks[k + 1].chunk_start_offset;
            assert!(next >= (start + len) as u64);
            assert_eq!(skip.to, next, "{name}: {skip:?}");
            assert_eq!(done.skipped_bytes(), next - start as u64);
            assert!(done.original_kept.is_some(), "{name}");
            let rewritten = std::fs::read(dir.join("bag_0.mcap")).unwrap();
            let expected: Vec<_> = all
                .iter()
                .filter(|m| !lost.contains(&m.1))
                .cloned()
                .collect();
            assert_eq!(read_indexed(&rewritten), expected, "{name}");
            assert_eq!(done.messages, expected.len() as u64, "{name}");
            assert_eq!(yaml_count(&dir).0, done.messages, "{name}");
        }
    }

    /// Reindex steps over damage, so it reads on where the plain reader stops: one flipped
    /// bit anywhere in the chunks (a seeded sample of 300) never makes it panic or loop,
    /// and it keeps every message of every chunk but the one hit.
    #[test]
    fn no_single_bit_flip_costs_reindex_more_than_its_chunk() {
        let tmp = tempfile::tempdir().unwrap();
        let bytes = finished_bag(&tmp.path().join("good"));
        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        let chunks = &summary.chunk_indexes;
        let most = chunks
            .iter()
            .map(|c| summary.stream_chunk(&bytes, c).unwrap().count())
            .max()
            .unwrap() as u64;
        let (lo, hi) = (
            chunks[0].chunk_start_offset as usize,
            (chunks.last().unwrap().chunk_start_offset + chunks.last().unwrap().chunk_length)
                as usize,
        );
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for n in 0..300 {
            // xorshift: a fixed sample of (byte, bit) positions.
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let at = lo + (state % (hi - lo) as u64) as usize;
            let mut damaged = bytes.clone();
            damaged[at] ^= 1 << ((state >> 40) % 8);
            let dir = tmp.path().join(format!("flip{n}"));
            std::fs::create_dir(&dir).unwrap();
            std::fs::write(dir.join("bag_0.mcap"), &damaged).unwrap();
            if let Ok(done) = reindex(&dir) {
                assert!(
                    done.messages + most >= 60,
                    "flip at byte {at}: {} messages kept, {:?}, {} records left out, cut {:?}, chunks at {:?}",
                    done.messages,
                    done.skipped,
                    done.skipped_records,
                    done.cut,
                    chunks.iter().map(|c| (c.chunk_start_offset, c.chunk_length)).collect::<Vec<_>>()
                );
            }
        }
    }
}
