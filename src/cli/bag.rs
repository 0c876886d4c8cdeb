//! `waam bag`: look into recordings (rosbag2 directories with MCAP storage).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use serde_json::json;
use waam_messages::sample::SampleSession;
use waam_rosbag::{Bag, BagOptions, Recorder};

use super::EXIT_OK;

/// Recordings: `waam bag info BAG` summarises one like `ros2 bag info`; `waam bag reindex
/// BAG` completes one whose recording process was killed.
#[derive(Debug, clap::Args)]
pub struct BagArgs {
    #[command(subcommand)]
    pub command: BagCommand,
}

#[derive(Debug, clap::Subcommand)]
pub enum BagCommand {
    Info(InfoArgs),
    Reindex(ReindexArgs),
    Sample(SampleArgs),
    Echo(EchoArgs),
}

/// (For tests.) Print the messages arriving on one ROS 2 topic as JSON lines, like
/// `ros2 topic echo`, until COUNT arrived or the timeout passed. Exit code 1 when fewer came.
#[derive(Debug, clap::Args)]
#[command(hide = true)]
pub struct EchoArgs {
    /// The topic, e.g. /waam_planner/plan/weld_plan.
    pub topic: String,
    /// Its type, e.g. waam_interfaces/msg/WeldPlan.
    #[arg(long = "type")]
    pub type_name: String,
    #[arg(long, default_value_t = 1)]
    pub count: u64,
    /// Seconds to wait at most.
    #[arg(long, default_value_t = 10.0)]
    pub timeout: f64,
    /// Subscribe best effort (for best-effort publishers such as joint states).
    #[arg(long)]
    pub best_effort: bool,
    /// Subscribe transient local (to get the last message a latched publisher sent).
    #[arg(long)]
    pub transient_local: bool,
}

/// Topics, types, message counts and duration of a recording, like `ros2 bag info` (with
/// --json also each topic's offered QoS and type hash).
///
/// BAG is a bag directory (with metadata.yaml) or an .mcap file. A recording whose process
/// was killed is read up to its last complete chunk and reported as truncated (it is not
/// changed: `waam bag reindex` completes it).
#[derive(Debug, clap::Args)]
pub struct InfoArgs {
    /// The bag directory or .mcap file.
    pub bag: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Complete a recording whose process died (kill -9, crash, power cut, full disk), like
/// `ros2 bag reindex` / `mcap recover`.
///
/// Such a file ends without the MCAP summary, indexes and closing magic: `waam bag info`,
/// `waam replay` and MCAP stream readers read it up to its last complete chunk, but rosbags,
/// `ros2 bag` and indexed MCAP readers read nothing. This reads it as far as it is readable
/// and rewrites it with summary, chunk and message indexes, statistics and closing magic,
/// and writes a matching metadata.yaml (message counts, topics, duration, file list).
///
/// The new file is written beside the old one, read back and synced, and only then renamed
/// over it: on any error the old file is left as it was. When the old file has bytes after
/// its last readable record (a half-written chunk, damage), it is also kept as
/// `<file>.orig`. A complete file is left as it is (only metadata.yaml is written again).
/// Run it only after the recording process has exited: a live recording has no summary
/// either.
#[derive(Debug, clap::Args)]
pub struct ReindexArgs {
    /// The bag directory (with metadata.yaml, or with one .mcap file).
    pub bag: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// (For tests and demos.) Record a synthetic session with one message of every recorded type
/// per round, on the node's topics, built from the bundled s1-wall part.
#[derive(Debug, clap::Args)]
#[command(hide = true)]
pub struct SampleArgs {
    /// The bag directory to create (must not exist).
    pub out: PathBuf,
    /// Rounds to record; 0 records until the process is stopped.
    #[arg(long, default_value_t = 1)]
    pub rounds: u64,
    /// Pause between rounds, milliseconds.
    #[arg(long, default_value_t = 0)]
    pub period_ms: u64,
    /// Longest time a chunk stays open, milliseconds.
    #[arg(long, default_value_t = 1000)]
    pub chunk_age_ms: u64,
}

pub fn run(args: BagArgs) -> anyhow::Result<ExitCode> {
    match args.command {
        BagCommand::Info(a) => info(a),
        BagCommand::Reindex(a) => reindex(a),
        BagCommand::Sample(a) => sample(a),
        BagCommand::Echo(a) => echo(a),
    }
}

fn info(args: InfoArgs) -> anyhow::Result<ExitCode> {
    let bag = Bag::open(&args.bag)?;
    let size = std::fs::metadata(&bag.mcap_file)
        .map(|m| m.len())
        .unwrap_or(0);
    let (start, end) = bag.time_range().unwrap_or((0, 0));
    let distro = bag
        .rosbag2_metadata
        .get("ROS_DISTRO")
        .cloned()
        .unwrap_or_default();
    let file = bag
        .mcap_file
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    if args.json {
        let topics: Vec<_> = bag
            .topics
            .iter()
            .map(|t| {
                json!({
                    "name": t.name,
                    "type": t.type_name,
                    "count": t.count,
                    "serialization_format": t.message_encoding,
                    "type_hash": t.type_hash,
                    "offered_qos_profiles": t.offered_qos,
                })
            })
            .collect();
        let out = json!({
            "files": [file],
            "bag_size": size,
            "storage_identifier": "mcap",
            "ros_distro": distro,
            "profile": bag.profile,
            "duration_ns": end - start,
            "start_ns": start,
            "end_ns": end,
            "message_count": bag.messages.len(),
            "chunks": bag.chunks,
            "topics": topics,
            "truncated": bag.truncated.as_ref().map(|t| json!({"file_len": t.file_len, "reason": t.reason})),
        });
        println!("{out}");
        return Ok(ExitCode::from(EXIT_OK));
    }
    println!("Files:             {file}");
    println!("Bag size:          {}", human_size(size));
    println!("Storage id:        mcap");
    println!(
        "ROS Distro:        {}",
        if distro.is_empty() {
            "unknown"
        } else {
            &distro
        }
    );
    println!("Duration:          {}s", seconds(end - start));
    println!("Start:             {}", date(start));
    println!("End:               {}", date(end));
    println!("Messages:          {}", bag.messages.len());
    for (i, t) in bag.topics.iter().enumerate() {
        let label = if i == 0 {
            "Topic information: "
        } else {
            "                   "
        };
        println!(
            "{label}Topic: {} | Type: {} | Count: {} | Serialization Format: {}",
            t.name, t.type_name, t.count, t.message_encoding
        );
    }
    if bag.topics.is_empty() {
        println!("Topic information: ");
    }
    if let Some(t) = &bag.truncated {
        println!(
            "Truncated:         yes: {} after {} bytes; read {} complete chunks ({} messages)",
            t.reason,
            t.file_len,
            bag.chunks,
            bag.messages.len()
        );
        println!(
            "                   `waam bag reindex {}` makes it complete for every reader",
            args.bag.display()
        );
    }
    Ok(ExitCode::from(EXIT_OK))
}

fn reindex(args: ReindexArgs) -> anyhow::Result<ExitCode> {
    let done = waam_rosbag::reindex(&args.bag)?;
    if args.json {
        println!(
            "{}",
            json!({
                "mcap_file": done.mcap_file,
                "was_complete": done.was_complete,
                "messages": done.messages,
                "topics": done.topics,
                "cut": done.cut,
                "unread_bytes": done.unread_bytes,
                "skipped_bytes": done.skipped_bytes(),
                "skipped": done.skipped.iter().map(|k| json!({
                    "from": k.from, "to": k.to, "reason": k.reason,
                })).collect::<Vec<_>>(),
                "skipped_records": done.skipped_records,
                "original_kept": done.original_kept,
            })
        );
        return Ok(ExitCode::from(EXIT_OK));
    }
    let file = done.mcap_file.display();
    if done.was_complete {
        println!(
            "{file}: already complete ({} messages on {} topics); metadata.yaml written again",
            done.messages, done.topics
        );
        return Ok(ExitCode::from(EXIT_OK));
    }
    println!(
        "{file}: rewritten complete with {} messages on {} topics (read up to: {})",
        done.messages,
        done.topics,
        done.cut.as_deref().unwrap_or("the end")
    );
    for k in &done.skipped {
        println!(
            "damaged: bytes {}..{} ({} bytes) stepped over to the next readable chunk: {}",
            k.from,
            k.to,
            k.to - k.from,
            k.reason
        );
    }
    if done.skipped_records > 0 {
        println!(
            "{} record(s) left out: their channel or schema was in a damaged stretch",
            done.skipped_records
        );
    }
    if let Some(kept) = &done.original_kept {
        println!(
            "{} bytes after the last readable record and {} damaged bytes were dropped; the \
             old file is kept as {}",
            done.unread_bytes,
            done.skipped_bytes(),
            kept.display()
        );
    }
    Ok(ExitCode::from(EXIT_OK))
}

fn echo(args: EchoArgs) -> anyhow::Result<ExitCode> {
    use waam_rosbag::qos::{Durability, Qos};
    let timeout = Duration::try_from_secs_f64(args.timeout)
        .map_err(|_| anyhow::anyhow!("--timeout: expected seconds >= 0, got {}", args.timeout))?;
    let mut qos = if args.best_effort {
        Qos::best_effort(100)
    } else {
        Qos::reliable(100)
    };
    if args.transient_local {
        qos.durability = Durability::TransientLocal;
    }
    let context = waam_ros::playback::context_from_env()?;
    let got = waam_ros::playback::echo(
        &context,
        &args.topic,
        &args.type_name,
        &qos,
        args.count,
        timeout,
        &mut |message| println!("{message}"),
    )?;
    Ok(ExitCode::from(if got >= args.count {
        EXIT_OK
    } else {
        super::EXIT_NO
    }))
}

fn sample(args: SampleArgs) -> anyhow::Result<ExitCode> {
    let options = BagOptions {
        chunk_age: Duration::from_millis(args.chunk_age_ms),
        ..Default::default()
    };
    let recorder = Recorder::with_options(&args.out, options)?;
    let mut session = SampleSession::new();
    let mut round = 0;
    while args.rounds == 0 || round < args.rounds {
        session.round(&recorder, round)?;
        round += 1;
        if args.period_ms > 0 {
            std::thread::sleep(Duration::from_millis(args.period_ms));
        }
    }
    recorder.finish()?;
    let counts: serde_json::Map<String, serde_json::Value> = session
        .counts
        .iter()
        .map(|(topic, (ty, n))| (topic.clone(), json!({"type": ty, "count": n})))
        .collect();
    println!("{}", serde_json::Value::Object(counts));
    Ok(ExitCode::from(EXIT_OK))
}

fn human_size(bytes: u64) -> String {
    const UNITS: [&str; 4] = ["B", "KiB", "MiB", "GiB"];
    let mut v = bytes as f64;
    let mut unit = 0;
    while v >= 1024.0 && unit + 1 < UNITS.len() {
        v /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.1} {}", UNITS[unit])
    }
}

fn seconds(ns: u64) -> String {
    format!("{}.{:09}", ns / 1_000_000_000, ns % 1_000_000_000)
}

/// `Nov 22 2025 05:09:12.123456789 (1763788152.123456789)`, UTC.
fn date(ns: u64) -> String {
    const MONTHS: [&str; 12] = [
        "Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec",
    ];
    let secs = ns / 1_000_000_000;
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{} {:2} {} {:02}:{:02}:{:02}.{:09} ({})",
        MONTHS[(month - 1) as usize],
        day,
        year,
        rem / 3600,
        rem / 60 % 60,
        rem % 60,
        ns % 1_000_000_000,
        seconds(ns)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_are_utc_calendar_dates() {
        assert_eq!(date(0), "Jan  1 1970 00:00:00.000000000 (0.000000000)");
        assert_eq!(
            date(1_763_788_152_123_456_789),
            "Nov 22 2025 05:09:12.123456789 (1763788152.123456789)"
        );
        assert_eq!(date(951_782_400_000_000_000).get(..11), Some("Feb 29 2000"));
    }

    #[test]
    fn sizes_read_like_ros2_bag_info() {
        assert_eq!(human_size(512), "512 B");
        assert_eq!(human_size(2048), "2.0 KiB");
        assert_eq!(human_size(3 * 1024 * 1024), "3.0 MiB");
    }
}
