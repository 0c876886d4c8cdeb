//! The closed loop's decisions, recorded and re-run (#31): what the node writes into each
//! `replanned` status so that a boundary's decision can be made again offline
//! ([`BoundaryRecord`]), and the re-run of every recorded closed-loop execution from the
//! recorded sensor messages ([`recorded_executions`], [`replay_execution`]).
//!
//! The loop is deterministic given its inputs: the part, the plan executed, each deposit's
//! times on the controller's clock, the readings fed at each boundary in the order fed, and
//! the boundary's time. Which readings had arrived by a boundary depends on wall-clock
//! timing, so the node records it (by stamp and value); the readings themselves are taken
//! from the recorded sensor messages. The node's robot-motion check of a new plan
//! (`Cell::motion_until` and where the robot stands) needs the cell's robot and is not
//! re-run: the replay follows what the node recorded it did (taken or kept).

use std::fmt;

use nalgebra::Isometry3;
use serde_json::{json, Value};
use waam_cell::closed_loop::{sequence, split};
use waam_cell::{ClosedLoop, Decision, LoopOptions, Measured};
use waam_part::{Block, Part};
use waam_rosbag::{Bag, BagError};
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::{DiagnosticArray, KeyValue};
use waam_rosmsg::sensor_msgs::{PointCloud2, Temperature};
use waam_rosmsg::std_msgs::Float64;
use waam_rosmsg::tf2_msgs::TFMessage;
use waam_rosmsg::trajectory_msgs::JointTrajectory;
use waam_rosmsg::{from_cdr, RosMessage};

use super::{diff_fragments, Difference};
use crate::planning::PART_FRAME;
use crate::sensor::{self, BadReading, ScanTarget};
use crate::tf_buffer::TfBuffer;

/// The decision of the record made when the plan is done: nothing was decided; the feeds
/// revised while the last weld path's arc was on are recorded.
pub const FINISHED: &str = "finished";

/// The prefix of the status values a boundary's record is kept in.
pub const PREFIX: &str = "loop.";

/// One deposit as the node told the loop: block, whether it began a weld path, its start
/// and duration on the controller's clock, s.
#[derive(Debug, Clone, PartialEq)]
pub struct ToldDeposit {
    pub block: Block,
    pub arc_start: bool,
    pub start_s: f64,
    pub duration_s: f64,
}

/// A reading the loop was fed, named by what identifies its recorded message.
#[derive(Debug, Clone, PartialEq)]
pub enum ReadingRef {
    /// A `sensor_msgs/Temperature`: its stamp (s, as the loop took it) and value (NaN when
    /// the record does not keep it).
    Temperature { stamp_s: f64, celsius: f64 },
    /// A `sensor_msgs/PointCloud2` scan: its stamp and the points on the part the loop got.
    Scan { stamp_s: f64, points: usize },
    /// A thermal camera's `sensor_msgs/PointCloud2` (a `temperature` field): its stamp and
    /// the points with a temperature on the part the loop got.
    ThermalImage { stamp_s: f64, points: usize },
}

impl ReadingRef {
    pub fn of(m: &Measured) -> ReadingRef {
        match m {
            &Measured::Temperature { stamp_s, celsius } => {
                ReadingRef::Temperature { stamp_s, celsius }
            }
            Measured::Scan { stamp_s, points } => ReadingRef::Scan {
                stamp_s: *stamp_s,
                points: points.len(),
            },
            Measured::ThermalImage { stamp_s, points } => ReadingRef::ThermalImage {
                stamp_s: *stamp_s,
                points: points.len(),
            },
        }
    }
}

impl fmt::Display for ReadingRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReadingRef::Temperature { stamp_s, celsius } if celsius.is_nan() => {
                write!(f, "temperature stamped {stamp_s:.6} s")
            }
            ReadingRef::Temperature { stamp_s, celsius } => {
                write!(f, "temperature {celsius} °C stamped {stamp_s} s")
            }
            ReadingRef::Scan { stamp_s, points } => {
                write!(f, "scan stamped {stamp_s} s ({points} points on the part)")
            }
            ReadingRef::ThermalImage { stamp_s, points } => {
                write!(
                    f,
                    "thermal image stamped {stamp_s} s ({points} points read on the part)"
                )
            }
        }
    }
}

/// A weld path's wire feeds set again while its arc was on, after a scan came
/// ([`ClosedLoop::revise_feeds`]): once `told` of the boundary's deposits were told and `fed`
/// of its readings fed, deposits `from..` (from 0) of weld path `weld_path` (from 1) got
/// `feeds`.
#[derive(Debug, Clone, PartialEq)]
pub struct FeedRevision {
    pub told: usize,
    pub fed: usize,
    pub weld_path: usize,
    pub from: usize,
    pub feeds: Vec<f64>,
}

/// What a boundary's decision needs to be made again, and what it decided.
#[derive(Debug, Clone, PartialEq)]
pub struct BoundaryRecord {
    /// 1 at an execution's first boundary, then counting.
    pub boundary: usize,
    /// The boundary's time on the controller's clock (`at_boundary`'s `now_s`), s.
    pub now_s: f64,
    /// The deposits told since the previous boundary.
    pub deposits: Vec<ToldDeposit>,
    /// Every reading fed since the previous boundary (while the arc was on, then at this
    /// boundary), in the order fed (those the loop could not place included).
    pub readings: Vec<ReadingRef>,
    /// The wire feeds revised while the arc was on, in order (none in older records).
    pub feed_revisions: Vec<FeedRevision>,
    /// At the first boundary: the plan being executed (fragments of blocks).
    pub plan: Option<Vec<Vec<Block>>>,
    /// The scan margin the node checked scans with (`closed_loop.scan_margin_mm`).
    pub scan_margin_mm: f64,
    /// The wire feed limits of the height rule (`closed_loop.wire_feed_min`, `_max`); not
    /// in a recording of an older node (its wire feeds are then not re-derived).
    pub wire_feed_limits: Option<(f64, f64)>,
    /// The welder took a feed per deposit (`closed_loop.wire_feed_per_deposit`); not in a
    /// recording of an older node (whose rule set one feed per layer: not re-derived).
    pub wire_feed_per_deposit: Option<bool>,
    /// How many times as fast as its trajectory the robot moved (a dry run's time scale):
    /// the rate of the clock the deposits were told on (1 in older records).
    pub time_scale: f64,
    /// The re-plan's time limit, s, if any: a re-plan it cut short is not reproducible.
    pub timeout_s: Option<f64>,
    /// The loop's decision: `replan`, `fault` or `kept` (no completion found); [`FINISHED`]
    /// after the last weld path (nothing decided: its estimate NaN, `fragments` the plan).
    pub decision: String,
    /// Whether its remainder differs from the current one.
    pub changed: bool,
    /// Loss and conduction factors, rms errors before and after (°C).
    pub estimate: [f64; 4],
    /// The decision's whole plan (the executed prefix first).
    pub fragments: Vec<Vec<Block>>,
    /// Whether the re-plan's answer was proven.
    pub proven: bool,
    /// Whether an arc fault cut the last weld path short (the deposits told end where the
    /// arc went out; the loop marked the fault before deciding). Absent in older records:
    /// false.
    pub cut_short: bool,
}

/// A status value that is not a boundary record's.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("status value {key} = {value:?}: {why}")]
pub struct RecordError {
    pub key: String,
    pub value: String,
    pub why: String,
}

fn blocks_json(fragments: &[Vec<Block>]) -> String {
    json!(fragments).to_string()
}

/// Readings as the record keeps them, a few bytes each (a pyrometer at 100 Hz feeds
/// thousands a weld path): one token per reading, in the order fed, its kind (`t`
/// temperature, `s` scan, `i` thermal image), its stamp in µs after the previous reading's
/// (the first's since the epoch), and a cloud's points on the part (`:N`). A temperature's
/// value is not kept: the replay takes each recorded message in order, by kind and stamp.
fn pack_readings(readings: &[ReadingRef]) -> String {
    let mut last_us = 0i64;
    let tokens: Vec<String> = readings
        .iter()
        .map(|r| {
            let (kind, stamp_s, points) = match *r {
                ReadingRef::Temperature { stamp_s, .. } => ('t', stamp_s, None),
                ReadingRef::Scan { stamp_s, points } => ('s', stamp_s, Some(points)),
                ReadingRef::ThermalImage { stamp_s, points } => ('i', stamp_s, Some(points)),
            };
            let us = (stamp_s * 1e6).round() as i64;
            let delta = us - std::mem::replace(&mut last_us, us);
            match points {
                Some(n) => format!("{kind}{delta}:{n}"),
                None => format!("{kind}{delta}"),
            }
        })
        .collect();
    tokens.join(" ")
}

/// The readings of [`pack_readings`]' form (a temperature's value unknown: NaN).
fn unpack_readings(packed: &str) -> Result<Vec<ReadingRef>, &'static str> {
    let mut us = 0i64;
    packed
        .split_whitespace()
        .map(|token| {
            let mut chars = token.chars();
            let kind = chars.next().ok_or("an empty reading")?;
            let (delta, points) = match chars.as_str().split_once(':') {
                Some((d, n)) => (
                    d,
                    Some(n.parse::<usize>().map_err(|_| "a bad point count")?),
                ),
                None => (chars.as_str(), None),
            };
            us += delta.parse::<i64>().map_err(|_| "a bad stamp")?;
            let stamp_s = us as f64 * 1e-6;
            match (kind, points) {
                ('t', None) => Ok(ReadingRef::Temperature {
                    stamp_s,
                    celsius: f64::NAN,
                }),
                ('s', Some(points)) => Ok(ReadingRef::Scan { stamp_s, points }),
                ('i', Some(points)) => Ok(ReadingRef::ThermalImage { stamp_s, points }),
                _ => Err("a reading is neither t, sN:points nor iN:points"),
            }
        })
        .collect()
}

/// Whether a recorded message stamped `recorded_s` is the reading stamped `s` (the record
/// keeps stamps to the µs).
fn same_stamp(recorded_s: f64, s: f64) -> bool {
    (recorded_s * 1e6).round() == (s * 1e6).round()
}

impl BoundaryRecord {
    /// The record as status values (floats written so that they read back exactly).
    pub fn values(&self) -> Vec<KeyValue> {
        let kv = |k: &str, v: String| KeyValue::new(format!("{PREFIX}{k}"), v);
        let deposits: Vec<Value> = self
            .deposits
            .iter()
            .map(|d| json!([d.block, d.arc_start, d.start_s, d.duration_s]))
            .collect();
        let mut out = vec![
            kv("boundary", self.boundary.to_string()),
            kv("now_s", self.now_s.to_string()),
            kv("deposits", Value::from(deposits).to_string()),
            kv("readings", pack_readings(&self.readings)),
            kv("scan_margin_mm", self.scan_margin_mm.to_string()),
            kv("time_scale", self.time_scale.to_string()),
            kv(
                "timeout_s",
                self.timeout_s.map_or("none".into(), |t| t.to_string()),
            ),
            kv("decision", self.decision.clone()),
            kv("changed", self.changed.to_string()),
            kv("estimate", self.estimate.map(|v| v.to_string()).join(" ")),
            kv("fragments", blocks_json(&self.fragments)),
            kv("proven", self.proven.to_string()),
            kv("cut_short", self.cut_short.to_string()),
        ];
        if let Some(plan) = &self.plan {
            out.push(kv("plan", blocks_json(plan)));
        }
        if !self.feed_revisions.is_empty() {
            let revisions: Vec<Value> = self
                .feed_revisions
                .iter()
                .map(|r| json!([r.told, r.fed, r.weld_path, r.from, r.feeds]))
                .collect();
            out.push(kv("feed_revisions", Value::from(revisions).to_string()));
        }
        if let Some((lo, hi)) = self.wire_feed_limits {
            out.push(kv("wire_feed_limits", format!("{lo} {hi}")));
        }
        if let Some(per_deposit) = self.wire_feed_per_deposit {
            out.push(kv("wire_feed_per_deposit", per_deposit.to_string()));
        }
        out
    }

    /// The record in `values` (a status's), or `None` when it holds none.
    pub fn from_values(values: &[(String, String)]) -> Result<Option<BoundaryRecord>, RecordError> {
        let get = |k: &str| {
            values
                .iter()
                .find(|(key, _)| key.strip_prefix(PREFIX) == Some(k))
                .map(|(_, v)| v.as_str())
        };
        if get("boundary").is_none() {
            return Ok(None);
        }
        let bad = |k: &str, why: &str| RecordError {
            key: format!("{PREFIX}{k}"),
            value: get(k).unwrap_or("").chars().take(80).collect(),
            why: why.into(),
        };
        let need = |k: &str| get(k).ok_or_else(|| bad(k, "missing"));
        let num = |k: &str| -> Result<f64, RecordError> {
            need(k)?.parse().map_err(|_| bad(k, "not a number"))
        };
        let flag = |k: &str| -> Result<bool, RecordError> {
            need(k)?.parse().map_err(|_| bad(k, "not true/false"))
        };
        let json_of = |k: &str| -> Result<Value, RecordError> {
            serde_json::from_str(need(k)?).map_err(|e| bad(k, &e.to_string()))
        };
        let fragments_of = |k: &str| -> Result<Vec<Vec<Block>>, RecordError> {
            serde_json::from_value(json_of(k)?).map_err(|e| bad(k, &e.to_string()))
        };
        let deposits = serde_json::from_value::<Vec<(Block, bool, f64, f64)>>(json_of("deposits")?)
            .map_err(|e| bad("deposits", &e.to_string()))?
            .into_iter()
            .map(|(block, arc_start, start_s, duration_s)| ToldDeposit {
                block,
                arc_start,
                start_s,
                duration_s,
            })
            .collect();
        let readings = match need("readings")? {
            // Recorded by an older node: JSON, each reading's stamp and value in full.
            v if v.starts_with('[') => {
                serde_json::from_value::<Vec<(String, f64, f64)>>(json_of("readings")?)
                    .map_err(|e| bad("readings", &e.to_string()))?
                    .into_iter()
                    .map(|(kind, stamp_s, v)| match kind.as_str() {
                        "temperature" => Ok(ReadingRef::Temperature {
                            stamp_s,
                            celsius: v,
                        }),
                        "scan" => Ok(ReadingRef::Scan {
                            stamp_s,
                            points: v as usize,
                        }),
                        "image" => Ok(ReadingRef::ThermalImage {
                            stamp_s,
                            points: v as usize,
                        }),
                        _ => Err(bad(
                            "readings",
                            "a reading is neither temperature, scan nor image",
                        )),
                    })
                    .collect::<Result<_, _>>()?
            }
            v => unpack_readings(v).map_err(|why| bad("readings", why))?,
        };
        let estimate: Vec<f64> = need("estimate")?
            .split(' ')
            .map(|v| v.parse().map_err(|_| bad("estimate", "not four numbers")))
            .collect::<Result<_, _>>()?;
        let estimate: [f64; 4] = estimate
            .try_into()
            .map_err(|_| bad("estimate", "not four numbers"))?;
        Ok(Some(BoundaryRecord {
            boundary: need("boundary")?
                .parse()
                .map_err(|_| bad("boundary", "not a count"))?,
            now_s: num("now_s")?,
            deposits,
            readings,
            plan: get("plan").map(|_| fragments_of("plan")).transpose()?,
            feed_revisions: match get("feed_revisions") {
                None => Vec::new(),
                Some(_) => serde_json::from_value::<Vec<(usize, usize, usize, usize, Vec<f64>)>>(
                    json_of("feed_revisions")?,
                )
                .map_err(|e| bad("feed_revisions", &e.to_string()))?
                .into_iter()
                .map(|(told, fed, weld_path, from, feeds)| FeedRevision {
                    told,
                    fed,
                    weld_path,
                    from,
                    feeds,
                })
                .collect(),
            },
            scan_margin_mm: num("scan_margin_mm")?,
            time_scale: match get("time_scale") {
                Some(_) => num("time_scale")?,
                None => 1.0,
            },
            wire_feed_limits: get("wire_feed_limits")
                .map(|v| {
                    let limits: Vec<f64> = v
                        .split(' ')
                        .map(|x| {
                            x.parse()
                                .map_err(|_| bad("wire_feed_limits", "not two numbers"))
                        })
                        .collect::<Result<_, _>>()?;
                    match limits[..] {
                        [lo, hi] => Ok((lo, hi)),
                        _ => Err(bad("wire_feed_limits", "not two numbers")),
                    }
                })
                .transpose()?,
            wire_feed_per_deposit: get("wire_feed_per_deposit")
                .map(|_| flag("wire_feed_per_deposit"))
                .transpose()?,
            timeout_s: match need("timeout_s")? {
                "none" => None,
                _ => Some(num("timeout_s")?),
            },
            decision: need("decision")?.to_string(),
            changed: flag("changed")?,
            estimate,
            fragments: fragments_of("fragments")?,
            proven: flag("proven")?,
            cut_short: get("cut_short")
                .map(|_| flag("cut_short"))
                .transpose()?
                .unwrap_or(false),
        }))
    }
}

/// One boundary of a recorded execution: its record and what the node did (the status's
/// `reason`: replan, fault, unchanged or kept) and why (the status's message).
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedBoundary {
    pub log_time: u64,
    pub reason: String,
    pub message: String,
    pub weld_paths_welded: Option<usize>,
    pub record: BoundaryRecord,
}

/// One execution that ran closed loop: its job and boundaries in order, and the `replanned`
/// statuses of its job whose boundary record is missing (an older node) or does not read.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedExecution {
    pub job: u64,
    pub boundaries: Vec<RecordedBoundary>,
    pub unreadable: Vec<String>,
    /// The wire feed the node sent before each weld path (`~/wire_feed`), as recorded: the
    /// first weld path's is the last before boundary 1, weld path k + 1's the first after
    /// boundary k (`None`: none recorded there).
    pub wire_feeds: Vec<Option<f64>>,
    /// Each weld path's feed per deposit (`~/wire_feed_schedule`), placed as `wire_feeds`.
    pub wire_feed_schedules: Vec<Option<Vec<f64>>>,
}

/// A sensor message as recorded.
#[derive(Debug, Clone)]
enum Raw {
    Temperature(Temperature),
    Scan(PointCloud2),
    /// A cloud with a temperature field: a thermal camera's.
    Image(PointCloud2),
}

/// The recorded sensor messages and frames, from which the readings are taken again.
pub struct Sensors {
    raw: Vec<Raw>,
    used: Vec<bool>,
    /// Every message before this one is taken: the node fed them in the order it recorded
    /// them, so a search starts here (hours of 200 Hz readings stay linear).
    first_unused: usize,
    frames: TfBuffer,
    /// The robot's base link: the parent of the part frame on `/tf_static`, if recorded.
    base_link: Option<String>,
}

/// Every execution in `bag` whose `replanned` statuses carry boundary records, in order
/// (an execution begins at its boundary 1), and the recorded sensor messages.
pub fn recorded_executions(bag: &Bag) -> Result<(Vec<RecordedExecution>, Sensors), BagError> {
    let mut order: Vec<usize> = (0..bag.messages.len()).collect();
    order.sort_by_key(|&i| bag.messages[i].log_time);
    let mut executions: Vec<RecordedExecution> = Vec::new();
    // (log time, relative wire feed) of every `~/wire_feed` message, and the same of every
    // `~/wire_feed_schedule`.
    let mut feeds: Vec<(u64, f64)> = Vec::new();
    let mut schedules: Vec<(u64, Vec<f64>)> = Vec::new();
    let mut sensors = Sensors {
        raw: Vec::new(),
        used: Vec::new(),
        first_unused: 0,
        frames: TfBuffer::default(),
        base_link: None,
    };
    for i in order {
        let m = &bag.messages[i];
        let topic = bag.topic_of(m);
        let decode_error = |source| BagError::Decode {
            topic: topic.name.clone(),
            log_time: m.log_time,
            source,
        };
        match topic.type_name.as_str() {
            t if t == Temperature::TYPE_NAME => sensors
                .raw
                .push(Raw::Temperature(from_cdr(&m.data).map_err(decode_error)?)),
            // The planner's heat clouds are its simulation, not a sensor's.
            t if t == PointCloud2::TYPE_NAME && topic.name != crate::topics::HEAT => {
                let cloud: PointCloud2 = from_cdr(&m.data).map_err(decode_error)?;
                sensors.raw.push(
                    if cloud
                        .fields
                        .iter()
                        .any(|f| f.name == crate::scan::TEMPERATURE)
                    {
                        Raw::Image(cloud)
                    } else {
                        Raw::Scan(cloud)
                    },
                )
            }
            t if t == Float64::TYPE_NAME && topic.name.ends_with("/wire_feed") => {
                let feed: Float64 = from_cdr(&m.data).map_err(decode_error)?;
                feeds.push((m.log_time, feed.data));
            }
            t if t == JointTrajectory::TYPE_NAME && topic.name.ends_with("/wire_feed_schedule") => {
                let msg: JointTrajectory = from_cdr(&m.data).map_err(decode_error)?;
                // A revision while the arc was on (its first point after the strike) is
                // in the boundary record that follows it.
                let revision = msg
                    .points
                    .first()
                    .is_some_and(|p| p.time_from_start.as_secs_f64() > 0.0);
                match crate::wire_feed::schedule_feeds(&msg) {
                    Some(s) if !revision => schedules.push((m.log_time, s)),
                    _ => {}
                }
            }
            t if t == TFMessage::TYPE_NAME => {
                let msg: TFMessage = from_cdr(&m.data).map_err(decode_error)?;
                let fixed = topic.name.ends_with("tf_static");
                if fixed {
                    if let Some(t) = msg
                        .transforms
                        .iter()
                        .find(|t| t.child_frame_id.trim_start_matches('/') == PART_FRAME)
                    {
                        sensors.base_link = Some(t.header.frame_id.clone());
                    }
                }
                // Faults were the node's to report; a frame that does not read is simply
                // not there offline either.
                let _ = sensors.frames.add(&msg, fixed);
            }
            t if t == DiagnosticArray::TYPE_NAME => {
                let status: DiagnosticArray = from_cdr(&m.data).map_err(decode_error)?;
                for s in &status.status {
                    let values: Vec<(String, String)> = s
                        .values
                        .iter()
                        .map(|kv| (kv.key.clone(), kv.value.clone()))
                        .collect();
                    let value = |k: &str| {
                        values
                            .iter()
                            .find(|(key, _)| key == k)
                            .map(|(_, v)| v.clone())
                    };
                    if value("state").as_deref() != Some("replanned") {
                        continue;
                    }
                    let Some(job) = value("job").and_then(|j| j.parse().ok()) else {
                        continue;
                    };
                    let record = match BoundaryRecord::from_values(&values) {
                        Ok(Some(r)) => Ok(r),
                        Ok(None) => Err(format!(
                            "the replanned status at {} ns holds no boundary record (loop.*): \
                             recorded by a node that did not record its decisions",
                            m.log_time
                        )),
                        Err(e) => Err(format!(
                            "the replanned status at {} ns: its boundary record does not read: {e}",
                            m.log_time
                        )),
                    };
                    let record = match record {
                        Ok(r) => r,
                        Err(why) => {
                            let first = value("loop.boundary").as_deref() == Some("1");
                            match executions.iter_mut().rev().find(|e| e.job == job) {
                                Some(e) if !first => e.unreadable.push(why),
                                _ => executions.push(RecordedExecution {
                                    job,
                                    boundaries: Vec::new(),
                                    unreadable: vec![why],
                                    wire_feeds: Vec::new(),
                                    wire_feed_schedules: Vec::new(),
                                }),
                            }
                            continue;
                        }
                    };
                    let boundary = RecordedBoundary {
                        log_time: m.log_time,
                        reason: value("reason").unwrap_or_default(),
                        message: s.message.clone(),
                        weld_paths_welded: value("weld_paths_welded").and_then(|v| v.parse().ok()),
                        record,
                    };
                    match executions.iter_mut().rev().find(|e| e.job == job) {
                        Some(e) if boundary.record.boundary > 1 || e.boundaries.is_empty() => {
                            e.boundaries.push(boundary)
                        }
                        _ => executions.push(RecordedExecution {
                            job,
                            boundaries: vec![boundary],
                            unreadable: Vec::new(),
                            wire_feeds: Vec::new(),
                            wire_feed_schedules: Vec::new(),
                        }),
                    }
                }
            }
            _ => {}
        }
    }
    sensors.used = vec![false; sensors.raw.len()];
    // Each execution's wire feeds, by where they fall among its boundaries (in log time).
    let starts: Vec<u64> = executions
        .iter()
        .map(|e| e.boundaries.first().map_or(u64::MAX, |b| b.log_time))
        .collect();
    for (i, e) in executions.iter_mut().enumerate() {
        let Some(first) = e.boundaries.first() else {
            continue;
        };
        let end = starts.get(i + 1).copied().unwrap_or(u64::MAX);
        let before = feeds.iter().rev().find(|f| f.0 < first.log_time);
        e.wire_feeds.push(before.map(|f| f.1));
        let before = schedules.iter().rev().find(|f| f.0 < first.log_time);
        e.wire_feed_schedules.push(before.map(|f| f.1.clone()));
        for (k, b) in e.boundaries.iter().enumerate() {
            let next = e.boundaries.get(k + 1).map_or(end, |n| n.log_time);
            let after = feeds.iter().find(|f| b.log_time <= f.0 && f.0 < next);
            e.wire_feeds.push(after.map(|f| f.1));
            let after = schedules.iter().find(|f| b.log_time <= f.0 && f.0 < next);
            e.wire_feed_schedules.push(after.map(|f| f.1.clone()));
        }
    }
    Ok((executions, sensors))
}

fn stamp_s(t: Time) -> f64 {
    // As `sensor::check_stamp` turns a stamp into seconds.
    t.to_nanos() as f64 * 1e-9
}

impl Sensors {
    /// The recorded message `r` names (the first not taken yet), as the loop took it.
    fn take(
        &mut self,
        r: &ReadingRef,
        part: &Part,
        margin_mm: f64,
    ) -> Result<Measured, Unreplayable> {
        let found = (self.first_unused..self.raw.len()).find(|&i| {
            !self.used[i]
                && match (&self.raw[i], r) {
                    (
                        Raw::Temperature(t),
                        &ReadingRef::Temperature {
                            stamp_s: s,
                            celsius,
                        },
                    ) => {
                        same_stamp(stamp_s(t.header.stamp), s)
                            && (celsius.is_nan() || t.temperature == celsius)
                    }
                    (Raw::Scan(c), &ReadingRef::Scan { stamp_s: s, .. })
                    | (Raw::Image(c), &ReadingRef::ThermalImage { stamp_s: s, .. }) => {
                        same_stamp(stamp_s(c.header.stamp), s)
                    }
                    _ => false,
                }
        });
        let i = found.ok_or_else(|| Unreplayable::Missing(r.clone()))?;
        self.used[i] = true;
        while self.used.get(self.first_unused) == Some(&true) {
            self.first_unused += 1;
        }
        match &self.raw[i] {
            Raw::Temperature(t) => Ok(Measured::Temperature {
                stamp_s: stamp_s(t.header.stamp),
                celsius: t.temperature,
            }),
            Raw::Scan(cloud) => {
                let target = self.target(part, cloud);
                // The node judged its age when it came; offline it is as old as its stamp.
                let stamp = cloud.header.stamp;
                let good = sensor::scan(cloud, Some(&target), &self.frames, margin_mm, stamp, 1.0)
                    .map_err(|why| Unreplayable::Unplaced {
                        reading: r.clone(),
                        why,
                    })?;
                same_points(r, good.points.len())?;
                Ok(good.measured())
            }
            Raw::Image(cloud) => {
                let target = self.target(part, cloud);
                let stamp = cloud.header.stamp;
                let good = sensor::thermal_image(
                    cloud,
                    Some(&target),
                    &self.frames,
                    margin_mm,
                    stamp,
                    1.0,
                )
                .map_err(|why| Unreplayable::Unplaced {
                    reading: r.clone(),
                    why,
                })?;
                same_points(r, good.points.len())?;
                Ok(good.measured())
            }
        }
    }

    /// The part a cloud is placed on: on its plate as `/tf_static` had it at the cloud's
    /// stamp (the identity when the recording holds no plate).
    fn target(&self, part: &Part, cloud: &PointCloud2) -> ScanTarget {
        let base = self.base_link.clone().unwrap_or_default();
        let plate = self
            .base_link
            .as_ref()
            .and_then(|b| self.frames.lookup(b, PART_FRAME, cloud.header.stamp).ok())
            .unwrap_or_else(Isometry3::identity);
        ScanTarget::of_part(part, &base, plate)
    }
}

/// The cloud placed again gives the loop as many points as it got.
fn same_points(r: &ReadingRef, got: usize) -> Result<(), Unreplayable> {
    match *r {
        ReadingRef::Scan { points, .. } | ReadingRef::ThermalImage { points, .. }
            if points != got =>
        {
            Err(Unreplayable::Points {
                reading: r.clone(),
                points: got,
            })
        }
        _ => Ok(()),
    }
}

/// One way a re-run decision differs from the recorded one.
#[derive(Debug, Clone, PartialEq)]
pub enum DecisionDifference {
    /// The loop's decision (replan, fault, kept).
    Decision {
        recorded: String,
        new: String,
    },
    Changed {
        recorded: bool,
        new: bool,
    },
    /// A factor or rms error of the estimate.
    Estimate {
        name: &'static str,
        recorded: f64,
        new: f64,
    },
    /// The decision's whole plan.
    Plan(Difference),
    /// The wire feed of a weld path (1-based), relative to nominal: the height rule's
    /// decision.
    WireFeed {
        weld_path: usize,
        /// Its deposit (1-based).
        deposit: usize,
        recorded: f64,
        new: f64,
    },
    /// The recording does not fit the plan being executed (deposits off it, a boundary
    /// after the last deposit).
    Inputs(String),
}

impl fmt::Display for DecisionDifference {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecisionDifference::Decision { recorded, new } => {
                write!(f, "decision: recorded {recorded}, new {new}")
            }
            DecisionDifference::Changed { recorded, new } => {
                write!(f, "remainder changed: recorded {recorded}, new {new}")
            }
            DecisionDifference::Estimate {
                name,
                recorded,
                new,
            } => write!(f, "estimate: {name} recorded {recorded}, new {new}"),
            DecisionDifference::Plan(d) => write!(f, "plan: {d}"),
            DecisionDifference::WireFeed {
                weld_path,
                deposit,
                recorded,
                new,
            } => write!(
                f,
                "wire feed of weld path {weld_path}, deposit {deposit}: recorded {recorded}, new {new}"
            ),
            DecisionDifference::Inputs(why) => write!(f, "inputs: {why}"),
        }
    }
}

/// The verdict on one recorded decision.
#[derive(Debug, Clone, PartialEq)]
pub enum DecisionVerdict {
    Identical,
    Different(Vec<DecisionDifference>),
    /// Not re-run, or its difference not held against it, and why.
    NotReproducible(String),
}

/// The re-run of one boundary.
#[derive(Debug, Clone, PartialEq)]
pub struct DecisionReport {
    pub boundary: RecordedBoundary,
    pub verdict: DecisionVerdict,
    /// The re-run's estimate (loss, conduction) and plan's weld path count, when it ran.
    pub new: Option<(f64, f64, usize)>,
}

/// Why a recorded decision's inputs cannot be given to the loop again offline.
#[derive(Debug, thiserror::Error)]
enum Unreplayable {
    #[error("the {0} is not in the recording")]
    Missing(ReadingRef),
    #[error("the {reading} cannot be placed offline: {why}")]
    Unplaced {
        reading: ReadingRef,
        why: BadReading,
    },
    #[error("the {reading} gives {points} points on the part offline")]
    Points { reading: ReadingRef, points: usize },
    #[error("block {0:?} is not in the part")]
    NotInPart(Block),
}

fn indices(part: &Part, fragments: &[Vec<Block>]) -> Result<Vec<Vec<usize>>, Unreplayable> {
    fragments
        .iter()
        .map(|f| {
            f.iter()
                .map(|&b| part.index_of(b).ok_or(Unreplayable::NotInPart(b)))
                .collect()
        })
        .collect()
}

fn blocks(part: &Part, fragments: &[Vec<usize>]) -> Vec<Vec<Block>> {
    fragments
        .iter()
        .map(|f| f.iter().map(|&i| part.block(i)).collect())
        .collect()
}

/// Compares a re-run decision with the recorded one: exactly (the estimate and the re-plan
/// are deterministic).
pub fn compare(part: &Part, recorded: &BoundaryRecord, new: &Decision) -> Vec<DecisionDifference> {
    let mut out = Vec::new();
    if recorded.decision != new.reason {
        out.push(DecisionDifference::Decision {
            recorded: recorded.decision.clone(),
            new: new.reason.into(),
        });
    }
    if recorded.changed != new.changed {
        out.push(DecisionDifference::Changed {
            recorded: recorded.changed,
            new: new.changed,
        });
    }
    let e = &new.estimate;
    let names = [
        "loss factor",
        "conduction factor",
        "rms before (°C)",
        "rms after (°C)",
    ];
    let values = [e.loss, e.conduction, e.rmse_before_c, e.rmse_after_c];
    for ((name, a), b) in names.into_iter().zip(recorded.estimate).zip(values) {
        // Bit for bit (NaN as NaN): the same inputs give the same fit.
        if a.to_bits() != b.to_bits() && !(a.is_nan() && b.is_nan()) {
            out.push(DecisionDifference::Estimate {
                name,
                recorded: a,
                new: b,
            });
        }
    }
    out.extend(
        diff_fragments(&recorded.fragments, &blocks(part, &new.fragments()))
            .into_iter()
            .map(DecisionDifference::Plan),
    );
    out
}

/// Re-runs every decision of `execution` on `part` (the part the node received for its
/// job) from the recorded readings in `sensors`, with the node's re-plan options but no
/// time limit (`planner`; its timeout is ignored). After each decision the loop follows
/// what the node did (the recorded plan taken, or the current one kept), so each boundary
/// is judged on the node's own path.
pub fn replay_execution(
    execution: &RecordedExecution,
    part: &Part,
    planner: &waam_planner::Options,
    sensors: &mut Sensors,
) -> Vec<DecisionReport> {
    let mut reports = Vec::new();
    // The height rule's limits, when recorded: its wire feeds are re-derived too.
    let limits = execution
        .boundaries
        .first()
        .and_then(|b| b.record.wire_feed_limits);
    let per_deposit = execution
        .boundaries
        .first()
        .and_then(|b| b.record.wire_feed_per_deposit);
    let limits = limits.filter(|_| per_deposit.is_some());
    let opts = LoopOptions {
        planner: waam_planner::Options {
            timeout: None,
            ..planner.clone()
        },
        wire_feed: limits.unwrap_or((1.0, 1.0)),
        wire_feed_per_deposit: per_deposit.unwrap_or(false),
        clock_rate: execution
            .boundaries
            .first()
            .map_or(1.0, |b| b.record.time_scale),
    };
    let not_run = |b: &RecordedBoundary, why: String| DecisionReport {
        boundary: b.clone(),
        verdict: DecisionVerdict::NotReproducible(why),
        new: None,
    };
    let Some(first) = execution.boundaries.first() else {
        return reports;
    };
    let start = first
        .record
        .plan
        .as_ref()
        .ok_or_else(|| "its first boundary does not record the plan executed".to_string())
        .and_then(|plan| indices(part, plan).map_err(|e| e.to_string()))
        .and_then(|plan| ClosedLoop::new(part, &plan, opts, 0.0).map_err(|e| e.to_string()));
    let mut closed = match start {
        Ok(c) => c,
        Err(why) => {
            let why = format!("the execution cannot be re-run: {why}");
            return execution
                .boundaries
                .iter()
                .map(|b| not_run(b, why.clone()))
                .collect();
        }
    };
    let mut stop: Option<String> = None;
    // The first weld path's wire feed, asked before anything was welded (as the node did).
    let mut feed_diffs = limits
        .and_then(|_| feed_difference(&mut closed, execution, 0))
        .into_iter()
        .collect::<Vec<_>>();
    let mut welded = 0;
    for b in &execution.boundaries {
        if let Some(why) = &stop {
            reports.push(not_run(b, why.clone()));
            continue;
        }
        let r = &b.record;
        let different = |why: String| DecisionReport {
            boundary: b.clone(),
            verdict: DecisionVerdict::Different(vec![DecisionDifference::Inputs(why)]),
            new: None,
        };
        // As the node fed the loop: up to each wire-feed revision made while the arc was
        // on (the revision re-derived there), then the rest.
        let mut done = (0, 0);
        let mut failed = None;
        for revision in r.feed_revisions.iter().map(Some).chain([None]) {
            let (told, fed) = revision.map_or((r.deposits.len(), r.readings.len()), |v| {
                (v.told.min(r.deposits.len()), v.fed.min(r.readings.len()))
            });
            if let Err(why) = tell(&mut closed, part, &r.deposits[done.0.min(told)..told]) {
                failed = Some(different(why));
                break;
            }
            // As the node did: the arc went out where the plan meant the path to go on.
            if revision.is_none() && r.cut_short && !closed.path_ended() {
                failed = Some(different(
                    "an arc fault is recorded where the plan's weld path ended anyway".into(),
                ));
                break;
            }
            for reading in &r.readings[done.1.min(fed)..fed] {
                match sensors.take(reading, part, r.scan_margin_mm) {
                    // Readings the loop cannot place are ignored, as the node ignored them.
                    Ok(m) => {
                        let _ = closed.measured(&m);
                    }
                    Err(why) => {
                        failed = Some(not_run(b, why.to_string()));
                        break;
                    }
                }
            }
            if failed.is_some() {
                break;
            }
            done = (told, fed);
            if let Some(v) = revision {
                feed_diffs.extend(revision_difference(&mut closed, v));
            }
        }
        if let Some(report) = failed {
            reports.push(report);
            stop = Some("an earlier boundary could not be re-run".into());
            continue;
        }
        if r.decision == FINISHED {
            // The plan's end: no decision, only the feeds revised on its last weld path.
            let verdict = match std::mem::take(&mut feed_diffs) {
                _ if closed.next().is_some() => {
                    DecisionVerdict::Different(vec![DecisionDifference::Inputs(
                        "the plan's end is recorded where deposits remain".into(),
                    )])
                }
                d if d.is_empty() => DecisionVerdict::Identical,
                d => DecisionVerdict::Different(d),
            };
            reports.push(DecisionReport {
                boundary: b.clone(),
                verdict,
                new: None,
            });
            continue;
        }
        if closed.next().is_none() {
            reports.push(different(
                "a decision was recorded after the plan's last deposit".into(),
            ));
            stop = Some("an earlier boundary could not be re-run".into());
            continue;
        }
        let new = match closed.at_boundary(true, r.now_s) {
            Ok(d) => d,
            Err(e) => {
                reports.push(different(format!("the re-run fails: {e}")));
                stop = Some("an earlier boundary could not be re-run".into());
                continue;
            }
        };
        welded += r.deposits.iter().filter(|d| d.arc_start).count();
        let diffs = compare(part, r, &new);
        let verdict = if diffs.is_empty() {
            DecisionVerdict::Identical
        } else if let (false, Some(t)) = (r.proven, r.timeout_s) {
            DecisionVerdict::NotReproducible(format!(
                "the recorded re-plan was not proven within its time limit of {t} s (wall \
                 clock), so what it found depended on the machine's speed; re-run without a \
                 limit: {}",
                diffs
                    .iter()
                    .map(|d| d.to_string())
                    .collect::<Vec<_>>()
                    .join("; ")
            ))
        } else {
            DecisionVerdict::Different(diffs)
        };
        reports.push(DecisionReport {
            boundary: b.clone(),
            verdict,
            new: Some((
                new.estimate.loss,
                new.estimate.conduction,
                new.fragments().len(),
            )),
        });
        // Follow the node: its plan from here is the recorded one.
        let followed = indices(part, &r.fragments).map(|f| Decision {
            whole: sequence(&f),
            ..new.clone()
        });
        match followed {
            Ok(d) if split(&d.whole).len() == r.fragments.len() => {
                if b.reason == "kept" {
                    closed.reject(&d, r.now_s);
                } else {
                    closed.adopt(&d, r.now_s);
                }
            }
            _ => stop = Some("the recorded plan is not the part's".into()),
        }
        // The next weld path's wire feed (the node asks before its arc strikes; no reading
        // is fed in between), held against this boundary's decision.
        if limits.is_some() && stop.is_none() {
            feed_diffs.extend(feed_difference(&mut closed, execution, welded));
        }
        if let Some(report) = reports.last_mut() {
            let feeds = std::mem::take(&mut feed_diffs);
            if !feeds.is_empty() {
                report.verdict =
                    match std::mem::replace(&mut report.verdict, DecisionVerdict::Identical) {
                        DecisionVerdict::Identical => DecisionVerdict::Different(feeds),
                        DecisionVerdict::Different(mut d) => {
                            d.extend(feeds);
                            DecisionVerdict::Different(d)
                        }
                        other => other,
                    };
            }
        }
    }
    reports
}

/// The deposits told since the last step, told again.
fn tell(closed: &mut ClosedLoop, part: &Part, deposits: &[ToldDeposit]) -> Result<(), String> {
    deposits.iter().try_for_each(|d| {
        let i = part
            .index_of(d.block)
            .ok_or(format!("deposit {:?} is not in the part", d.block))?;
        closed
            .deposited(i, d.arc_start, d.start_s, d.duration_s)
            .map(drop)
            .map_err(|e| e.to_string())
    })
}

/// A revision of a weld path's wire feeds made again, against the recorded one.
fn revision_difference(
    closed: &mut ClosedLoop,
    revision: &FeedRevision,
) -> Option<DecisionDifference> {
    let recorded = &revision.feeds;
    let path = closed
        .fragments()
        .get(revision.weld_path.wrapping_sub(1))
        .cloned()
        .unwrap_or_default();
    let from = revision.from.min(path.len());
    let new = closed.revise_feeds(&path[..from], &path[from..]);
    first_feed_difference(recorded, &new).map(|k| DecisionDifference::WireFeed {
        weld_path: revision.weld_path,
        deposit: revision.from + k + 1,
        recorded: recorded.get(k).copied().unwrap_or(f64::NAN),
        new: new.get(k).copied().unwrap_or(f64::NAN),
    })
}

/// Where two lists of feeds first differ, bit for bit (a feed only one has differs).
fn first_feed_difference(recorded: &[f64], new: &[f64]) -> Option<usize> {
    let at = |v: &[f64], k: usize| v.get(k).copied().unwrap_or(f64::NAN);
    (0..recorded.len().max(new.len())).find(|&k| at(recorded, k).to_bits() != at(new, k).to_bits())
}

/// Weld path `f + 1`'s wire feeds as the loop derives them now, against those recorded:
/// its schedule deposit by deposit, or without one the feed it struck at (nothing when they
/// agree bit for bit, or when none was recorded or the plan has no such weld path).
fn feed_difference(
    closed: &mut ClosedLoop,
    execution: &RecordedExecution,
    f: usize,
) -> Option<DecisionDifference> {
    let schedule = execution.wire_feed_schedules.get(f).cloned().flatten();
    let blocks = closed.fragments().get(f)?.clone();
    let mut new = closed.path_feeds(&blocks);
    let recorded = match schedule {
        Some(schedule) => schedule,
        None => {
            new.truncate(1);
            vec![(*execution.wire_feeds.get(f)?)?]
        }
    };
    let at = |v: &[f64], k: usize| v.get(k).copied().unwrap_or(f64::NAN);
    first_feed_difference(&recorded, &new).map(|k| DecisionDifference::WireFeed {
        weld_path: f + 1,
        deposit: k + 1,
        recorded: at(&recorded, k),
        new: at(&new, k),
    })
}

/// The job a recorded "received" status names, from its values.
pub fn received_job(values: &[(String, String)]) -> Vec<u64> {
    let mut jobs = Vec::new();
    let mut received = false;
    for (k, v) in values {
        if k == "state" {
            received = v == "received";
        } else if k == "job" && received {
            jobs.extend(v.parse::<u64>().ok());
            received = false;
        }
    }
    jobs
}

#[cfg(test)]
mod tests {
    use super::*;
    use waam_rosmsg::std_msgs::Header;

    /// A scan is taken again from its recorded cloud as the node took it (part frame,
    /// points off the part dropped); one the recording lacks, or that gives other points,
    /// is said to be so.
    #[test]
    fn a_recorded_scan_is_placed_again_as_the_node_placed_it() {
        let part =
            Part::parse("name: w\nblock_mm: [6, 6, 2.5]\nmax_fragments: 1\nlayers:\n  - \"###\"\n")
                .unwrap();
        let stamp = Time::from_nanos(1_800_000_000_123_456_789);
        let mut cloud = crate::scan::cloud(
            &[
                [0.003, 0.003, 0.00225],
                [0.009, 0.003, 0.0023],
                [0.5, 0.5, 0.0],
            ],
            PART_FRAME,
        );
        cloud.header = Header::new(stamp, PART_FRAME);
        let target = ScanTarget::of_part(&part, "base_link", Isometry3::identity());
        let node = sensor::scan(
            &cloud,
            Some(&target),
            &TfBuffer::default(),
            10.0,
            stamp,
            1.0,
        )
        .unwrap()
        .measured();
        let mut sensors = Sensors {
            raw: vec![Raw::Scan(cloud)],
            used: vec![false],
            first_unused: 0,
            frames: TfBuffer::default(),
            base_link: None,
        };
        let r = ReadingRef::of(&node);
        assert_eq!(
            r,
            ReadingRef::Scan {
                stamp_s: stamp_s(stamp),
                points: 2
            }
        );
        assert_eq!(sensors.take(&r, &part, 10.0).unwrap(), node);
        // Each recorded message is taken once.
        let e = sensors.take(&r, &part, 10.0).unwrap_err();
        assert!(matches!(e, Unreplayable::Missing(_)), "{e}");
        assert!(e.to_string().contains("not in the recording"), "{e}");
        (sensors.used[0], sensors.first_unused) = (false, 0);
        let other = ReadingRef::Scan {
            stamp_s: stamp_s(stamp),
            points: 3,
        };
        let e = sensors.take(&other, &part, 10.0).unwrap_err();
        assert!(matches!(e, Unreplayable::Points { points: 2, .. }), "{e}");
    }

    #[test]
    fn a_boundary_record_reads_back_exactly() {
        let r = BoundaryRecord {
            boundary: 2,
            now_s: 1_765_000_000.123_456_7,
            deposits: vec![ToldDeposit {
                block: [1, 0, 2],
                arc_start: true,
                start_s: 0.1 + 0.2,
                duration_s: 1.0 / 3.0,
            }],
            readings: vec![
                ReadingRef::Temperature {
                    stamp_s: 1_765_000_000.5,
                    celsius: 612.25,
                },
                ReadingRef::Scan {
                    stamp_s: 1_765_000_001.0,
                    points: 6,
                },
            ],
            plan: Some(vec![vec![[0, 0, 0], [1, 0, 0]]]),
            feed_revisions: vec![FeedRevision {
                told: 1,
                fed: 2,
                weld_path: 2,
                from: 3,
                feeds: vec![1.0 / 0.9, 1.3],
            }],
            scan_margin_mm: 5.0,
            wire_feed_limits: Some((0.7, 1.3)),
            wire_feed_per_deposit: Some(true),
            time_scale: 20.0,
            timeout_s: None,
            decision: "replan".into(),
            changed: true,
            estimate: [0.75, 1.0, 124.5, f64::NAN],
            fragments: vec![vec![[0, 0, 0]], vec![[1, 0, 0]]],
            proven: true,
            cut_short: true,
        };
        let values: Vec<(String, String)> = r
            .values()
            .into_iter()
            .map(|kv| (kv.key, kv.value))
            .collect();
        let back = BoundaryRecord::from_values(&values).unwrap().unwrap();
        assert!(back.estimate[3].is_nan());
        // The readings to the µs, a temperature's value left out (the recorded message
        // has it): "t1765000000500000 s500000:6".
        let packed = values.iter().find(|(k, _)| k == "loop.readings").unwrap();
        assert_eq!(packed.1, "t1765000000500000 s500000:6");
        let [ReadingRef::Temperature { stamp_s, celsius }, ReadingRef::Scan { points: 6, .. }] =
            back.readings[..]
        else {
            panic!("{:?}", back.readings);
        };
        assert!(same_stamp(stamp_s, 1_765_000_000.5) && celsius.is_nan());
        let same = |mut x: BoundaryRecord| {
            x.estimate[3] = 0.0;
            x.readings.clear();
            x
        };
        assert_eq!(same(back), same(r.clone()));
        // A record of an older node: its readings in JSON, values and all.
        let mut older = values.clone();
        for (k, v) in older.iter_mut() {
            if k == "loop.readings" {
                *v = r#"[["temperature",1765000000.5,612.25],["scan",1765000001.0,6]]"#.into();
            }
        }
        let back = BoundaryRecord::from_values(&older).unwrap().unwrap();
        assert_eq!(back.readings, r.readings);
        // A packed reading that does not read: named.
        let mut garbled = values.clone();
        for (k, v) in garbled.iter_mut() {
            if k == "loop.readings" {
                *v = "t17 x3".into();
            }
        }
        let e = BoundaryRecord::from_values(&garbled).unwrap_err();
        assert_eq!(e.key, "loop.readings");
        assert_eq!(BoundaryRecord::from_values(&[]).unwrap(), None);
        let mut bad = values.clone();
        bad.retain(|(k, _)| k != "loop.now_s");
        let e = BoundaryRecord::from_values(&bad).unwrap_err();
        assert_eq!(e.key, "loop.now_s");
        // A record from before arc faults were recorded: no fault.
        let mut older = values.clone();
        older.retain(|(k, _)| k != "loop.cut_short");
        let back = BoundaryRecord::from_values(&older).unwrap().unwrap();
        assert!(!back.cut_short);
    }
}
