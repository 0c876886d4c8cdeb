//! Round trips through the writer and the reader, truncated files.

use std::time::Duration;

use super::metadata::BagMetadata;
use super::*;
use waam_rosmsg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use waam_rosmsg::std_msgs::{Bool, String as RosString};
use waam_rosmsg::waam_interfaces::{Block, WeldFragment, WeldPlan};
use waam_rosmsg::RosMessage;

/// Topic names as the node uses them (the bag knows nothing of them).
mod topics {
    pub const ARC_ON: &str = "/waam_planner/arc_on";
    pub const PART: &str = "/waam_planner/part";
    pub const STATUS: &str = "/waam_planner/status";
    pub const WELD_PLAN: &str = "/waam_planner/plan/weld_plan";
}

const T0: u64 = 1_700_000_000_000_000_000;

fn plan(x: i32) -> WeldPlan {
    WeldPlan {
        part_name: "wall".into(),
        fragments: vec![WeldFragment {
            blocks: vec![Block { x, y: 0, z: 0 }],
        }],
        ..Default::default()
    }
}

#[test]
fn a_finished_bag_reads_back_with_rosbag2_layout() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("session");
    let mut w = BagWriter::create(&dir, BagOptions::default()).unwrap();
    w.write(
        topics::PART,
        &Qos::reliable(10),
        T0,
        &RosString::from("name: a"),
    )
    .unwrap();
    for i in 0..3 {
        w.write(
            topics::WELD_PLAN,
            &Qos::latched(),
            T0 + 10 + i,
            &plan(i as i32),
        )
        .unwrap();
    }
    w.write(
        topics::ARC_ON,
        &Qos::reliable(10),
        T0 + 20,
        &Bool { data: true },
    )
    .unwrap();
    let summary = w.finish().unwrap();
    assert_eq!(summary.messages, 5);
    assert_eq!(summary.topics, 3);
    assert_eq!(summary.mcap_file, dir.join("session_0.mcap"));

    let bag = Bag::open(&dir).unwrap();
    assert_eq!(bag.truncated, None);
    assert_eq!(bag.profile, "ros2");
    assert_eq!(bag.messages.len(), 5);
    let names: Vec<_> = bag.topics.iter().map(|t| t.name.as_str()).collect();
    assert_eq!(names, [topics::PART, topics::WELD_PLAN, topics::ARC_ON]);
    let plan_topic = &bag.topics[1];
    assert_eq!(plan_topic.type_name, "waam_interfaces/msg/WeldPlan");
    assert_eq!(plan_topic.schema_encoding, "ros2msg");
    assert_eq!(plan_topic.message_encoding, "cdr");
    assert_eq!(plan_topic.definition, WeldPlan::definition());
    assert_eq!(plan_topic.type_hash, WeldPlan::TYPE_HASH);
    assert_eq!(plan_topic.offered_qos, vec![Qos::latched()]);
    assert_eq!(plan_topic.count, 3);
    let plans = bag.decode_all::<WeldPlan>().unwrap();
    assert_eq!(plans.len(), 3);
    assert_eq!(plans[2].2, plan(2));
    assert_eq!(plans[2].0, T0 + 12);
    assert_eq!(bag.time_range(), Some((T0, T0 + 20)));
    assert_eq!(bag.rosbag2_metadata.get("ROS_DISTRO").unwrap(), "jazzy");

    // The final rosbag2 record and metadata.yaml agree on counts, QoS and files.
    let record: BagMetadata =
        serde_yaml::from_str(&bag.rosbag2_metadata["serialized_metadata"]).unwrap();
    assert_eq!(record.version, 9);
    assert_eq!(record.message_count, 5);
    assert_eq!(record.duration.nanoseconds, 20);
    let yaml = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    let file: serde_yaml::Value = serde_yaml::from_str(&yaml).unwrap();
    let info: BagMetadata =
        serde_yaml::from_value(file["rosbag2_bagfile_information"].clone()).unwrap();
    assert_eq!(info, record);
    assert_eq!(info.relative_file_paths, ["session_0.mcap"]);
    assert_eq!(info.topics_with_message_count[1].message_count, 3);
    assert_eq!(
        info.topics_with_message_count[1]
            .topic_metadata
            .offered_qos_profiles,
        vec![Qos::latched()]
    );
}

#[test]
fn a_topic_keeps_its_type_and_directories_are_not_reused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("b");
    let mut w = BagWriter::create(&dir, BagOptions::default()).unwrap();
    w.write("/x", &Qos::reliable(1), T0, &Bool { data: true })
        .unwrap();
    let err = w
        .write("/x", &Qos::reliable(1), T0, &RosString::from("no"))
        .unwrap_err();
    assert!(err.to_string().contains("std_msgs/msg/Bool"), "{err}");
    let err = w.write_raw("/nope", T0, T0, &[0, 1, 0, 0]).unwrap_err();
    assert!(err.to_string().contains("/nope"), "{err}");
    w.finish().unwrap();
    let err = BagWriter::create(&dir, BagOptions::default())
        .err()
        .unwrap();
    assert!(err.to_string().contains("already exists"), "{err}");
}

/// Writes `n` status messages with flushes every few messages; returns the file bytes as they
/// were on disk after the last flush (the writer is still open: a killed process) and the
/// number of messages flushed by then.
fn killed_recording(dir: &std::path::Path, n: u64) -> (Vec<u8>, usize) {
    let options = BagOptions {
        chunk_bytes: 2_000,
        chunk_age: Duration::from_secs(3600),
        zstd_level: 1,
    };
    let mut w = BagWriter::create(dir, options).unwrap();
    let file = dir.join(format!(
        "{}_0.mcap",
        dir.file_name().unwrap().to_str().unwrap()
    ));
    let mut on_disk = (Vec::new(), 0);
    for i in 0..n {
        let status = DiagnosticArray {
            status: vec![DiagnosticStatus {
                message: format!("status {i} {}", "x".repeat(100)),
                ..Default::default()
            }],
            ..Default::default()
        };
        w.write(topics::STATUS, &Qos::latched(), T0 + i, &status)
            .unwrap();
        if !w.chunk_is_open() {
            on_disk = (std::fs::read(&file).unwrap(), i as usize + 1);
        }
    }
    std::mem::forget(w); // a killed process finishes nothing
    on_disk
}

#[test]
fn a_killed_recording_reads_up_to_its_last_closed_chunk() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("killed");
    let (bytes, flushed) = killed_recording(&dir, 100);
    assert!(flushed >= 80, "flushed {flushed}");
    let bag = Bag::from_bytes(&dir.join("killed_0.mcap"), &bytes).unwrap();
    let truncated = bag.truncated.as_ref().expect("reported as truncated");
    assert_eq!(truncated.file_len, bytes.len() as u64);
    assert_eq!(bag.messages.len(), flushed);
    assert!(bag.chunks >= 5, "{} chunks", bag.chunks);
    let statuses = bag.decode_all::<DiagnosticArray>().unwrap();
    assert!(statuses[flushed - 1].2.status[0]
        .message
        .starts_with(&format!("status {} ", flushed - 1)));
    // metadata.yaml was refreshed at the last flush and names the file.
    let yaml = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    assert!(yaml.contains("killed_0.mcap"));
}

#[test]
fn every_cut_of_a_bag_reads_as_a_prefix_without_panicking() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("full");
    let mut w = BagWriter::create(
        &dir,
        BagOptions {
            chunk_bytes: 300,
            ..Default::default()
        },
    )
    .unwrap();
    for i in 0..40u64 {
        w.write(
            topics::PART,
            &Qos::reliable(10),
            T0 + i,
            &RosString::from(&*format!("part {i}")),
        )
        .unwrap();
    }
    w.finish().unwrap();
    let bytes = std::fs::read(dir.join("full_0.mcap")).unwrap();
    let full = Bag::from_bytes(&dir, &bytes).unwrap();
    assert_eq!(full.messages.len(), 40);
    assert!(full.truncated.is_none());
    let mut seen_counts = std::collections::BTreeSet::new();
    for cut in (0..bytes.len()).step_by(7) {
        match Bag::from_bytes(&dir, &bytes[..cut]) {
            Ok(bag) => {
                assert!(bag.truncated.is_some(), "cut at {cut} not reported");
                assert_eq!(bag.messages, full.messages[..bag.messages.len()]);
                seen_counts.insert(bag.messages.len());
            }
            Err(e) => assert!(cut < 8, "cut at {cut}: {e}"),
        }
    }
    assert!(seen_counts.len() > 5, "{seen_counts:?}");
}

#[test]
fn the_recorder_closes_old_chunks_on_its_own() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("rec");
    let recorder = Recorder::with_options(
        &dir,
        BagOptions {
            chunk_age: Duration::from_millis(40),
            ..Default::default()
        },
    )
    .unwrap();
    recorder
        .record(topics::ARC_ON, &Qos::reliable(10), &Bool { data: true })
        .unwrap();
    // Poll (bounded) until the background thread has closed the chunk.
    let file = dir.join("rec_0.mcap");
    let mut read = 0;
    for _ in 0..200 {
        std::thread::sleep(Duration::from_millis(10));
        read = Bag::open(&file).unwrap().messages.len();
        if read == 1 {
            break;
        }
    }
    assert_eq!(read, 1, "the open chunk was never flushed");
    let clone = recorder.clone();
    clone
        .record(topics::ARC_ON, &Qos::reliable(10), &Bool { data: false })
        .unwrap();
    let summary = recorder.finish().unwrap();
    assert_eq!(summary.messages, 2);
    assert!(matches!(
        clone.record(topics::ARC_ON, &Qos::reliable(10), &Bool { data: false }),
        Err(BagError::Finished)
    ));
}

#[test]
fn a_chunk_compression_we_cannot_read_is_an_error_not_a_truncation() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("c");
    let mut w = BagWriter::create(&dir, BagOptions::default()).unwrap();
    w.write(topics::ARC_ON, &Qos::reliable(10), T0, &Bool { data: true })
        .unwrap();
    w.finish().unwrap();
    let mut bytes = std::fs::read(dir.join("c_0.mcap")).unwrap();
    let at = bytes.windows(4).position(|w| w == b"zstd").unwrap();
    bytes[at..at + 4].copy_from_slice(b"lz4x");
    let err = Bag::from_bytes(&dir, &bytes).unwrap_err();
    assert!(err.to_string().contains("lz4x"), "{err}");
}

/// A small finished recording with a few zstd chunks, as bytes.
fn small_recording() -> Vec<u8> {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("flips");
    let mut w = BagWriter::create(&dir, BagOptions::default()).unwrap();
    w.write(
        topics::PART,
        &Qos::reliable(10),
        T0,
        &RosString::from("name: a\nblock_mm: [6, 6, 2.5]\nmax_fragments: 1\nblocks: [[0,0,0]]\n"),
    )
    .unwrap();
    for i in 0..6 {
        w.write(
            topics::WELD_PLAN,
            &Qos::latched(),
            T0 + 10 + i,
            &plan(i as i32),
        )
        .unwrap();
        if i % 2 == 1 {
            w.flush().unwrap();
        }
    }
    let summary = w.finish().unwrap();
    std::fs::read(summary.mcap_file).unwrap()
}

/// Issue #18, C3: one bit flipped in a zstd chunk made the reader abort ("memory
/// allocation of ~7e18 bytes failed") or panic ("capacity overflow"). A seeded sample of
/// 2,000 single-bit flips over the whole file (chunks, summary, footer): `Bag::from_bytes`
/// returns (a bag, maybe marked truncated, or an error), never panics or aborts.
#[test]
fn no_single_bit_flip_makes_the_reader_panic_or_abort() {
    let clean = small_recording();
    assert!(Bag::from_bytes(std::path::Path::new("x.mcap"), &clean).is_ok());
    let bits = clean.len() * 8;
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut panics = Vec::new();
    for _ in 0..2000 {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let bit = (seed % bits as u64) as usize;
        let mut bytes = clean.clone();
        bytes[bit / 8] ^= 1 << (bit % 8);
        let read = std::panic::catch_unwind(|| {
            let _ = Bag::from_bytes(std::path::Path::new("x.mcap"), &bytes);
        });
        if read.is_err() {
            panics.push(bit);
        }
    }
    assert!(panics.is_empty(), "bits {panics:?} of {bits} panic");
}

/// Issue #18, C3: a chunk of 1.5 GiB of zeros, compressed to a few kB, aborted the reader;
/// now the record length limit refuses it before anything is allocated.
#[test]
fn a_chunk_that_decompresses_to_gigabytes_is_refused_without_allocating_them() {
    let big: u64 = 3 << 29; // 1.5 GiB
                            // The chunk's records: a Message record claiming the whole chunk, then zeros.
    let mut head = vec![0x05];
    head.extend_from_slice(&(big - 9).to_le_bytes());
    let zeros = std::io::Read::take(std::io::repeat(0), big - 9);
    let mut compressed = Vec::new();
    zstd::stream::copy_encode(std::io::Read::chain(&head[..], zeros), &mut compressed, 1).unwrap();
    assert!(compressed.len() < 200_000, "{}", compressed.len());
    let mut chunk = Vec::new();
    chunk.extend_from_slice(&T0.to_le_bytes());
    chunk.extend_from_slice(&T0.to_le_bytes());
    chunk.extend_from_slice(&big.to_le_bytes());
    chunk.extend_from_slice(&0u32.to_le_bytes());
    chunk.extend_from_slice(&4u32.to_le_bytes());
    chunk.extend_from_slice(b"zstd");
    chunk.extend_from_slice(&(compressed.len() as u64).to_le_bytes());
    chunk.extend_from_slice(&compressed);
    let mut file = mcap::MAGIC.to_vec();
    let header = [4u32.to_le_bytes().as_slice(), b"ros2", &0u32.to_le_bytes()].concat();
    file.push(0x01);
    file.extend_from_slice(&(header.len() as u64).to_le_bytes());
    file.extend_from_slice(&header);
    file.push(0x06);
    file.extend_from_slice(&(chunk.len() as u64).to_le_bytes());
    file.extend_from_slice(&chunk);
    let bag = Bag::from_bytes(std::path::Path::new("zeros.mcap"), &file).unwrap();
    assert!(bag.messages.is_empty());
    let reason = bag.truncated.expect("the chunk is not read").reason;
    assert!(reason.contains("exceeds limit"), "{reason}");
}

/// Issue #18: paths in `metadata.yaml` that climb out of the bag folder were opened, and
/// a FIFO blocked `bag info` for ever: both are refused.
#[test]
fn metadata_paths_stay_in_the_bag_folder_and_special_files_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("bag");
    let mut w = BagWriter::create(&dir, BagOptions::default()).unwrap();
    w.write(topics::ARC_ON, &Qos::reliable(1), T0, &Bool { data: true })
        .unwrap();
    w.finish().unwrap();
    let yaml = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    assert!(Bag::open(&dir).is_ok());
    std::fs::copy(dir.join("bag_0.mcap"), tmp.path().join("outside.mcap")).unwrap();
    for bad in ["../outside.mcap", "/etc/passwd", "sub/../../outside.mcap"] {
        let edited = yaml.replace("- bag_0.mcap", &format!("- {bad}"));
        assert_ne!(edited, yaml);
        std::fs::write(dir.join("metadata.yaml"), &edited).unwrap();
        let err = Bag::open(&dir).unwrap_err().to_string();
        assert!(err.contains("relative_file_paths"), "{bad}: {err}");
    }
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(tmp.path().join("outside.mcap"), dir.join("link.mcap")).unwrap();
        let edited = yaml.replace("- bag_0.mcap", "- link.mcap");
        std::fs::write(dir.join("metadata.yaml"), edited).unwrap();
        let err = Bag::open(&dir).unwrap_err().to_string();
        assert!(err.contains("leads out of the bag folder"), "{err}");
        // A FIFO named by the metadata, and /dev/zero given directly.
        let fifo = dir.join("fifo.mcap");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: mkfifo with a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let edited = yaml.replace("- bag_0.mcap", "- fifo.mcap");
        std::fs::write(dir.join("metadata.yaml"), edited).unwrap();
        let t = std::time::Instant::now();
        let err = Bag::open(&dir).unwrap_err().to_string();
        assert!(err.contains("not a regular file"), "{err}");
        let err = Bag::open(std::path::Path::new("/dev/zero"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("not a regular file"), "{err}");
        assert!(t.elapsed().as_secs() < 2);
    }
}

/// Issue #18: a full disk was reported as "I/O error from writing, or reading a
/// compression stream", without "No space left on device".
#[test]
fn an_mcap_io_error_keeps_its_cause() {
    let io = std::io::Error::from_raw_os_error(28); // ENOSPC
    let err = BagError::mcap(std::path::Path::new("b.mcap"), mcap::McapError::Io(io));
    let text = err.to_string();
    assert!(
        text.contains("I/O error") && text.contains("No space left on device"),
        "{text}"
    );
}
