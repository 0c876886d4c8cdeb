//! Recording a planning run (`waam plan --record`, `waam replay --record`) on the node's
//! topics: the part received, the planner's verdict on every candidate, the plan (or an ERROR
//! status saying why there is none), and the simulated heat of the chosen plan.

use crate::convert::{
    block_fragments, block_msg, fully_qualified, statistics, ConvertError, PlanMessages,
    WeldPlanOf, NODE_NAME,
};
use crate::heat::{record_heat, HeatOptions};
use crate::status::Status;
use crate::topics;
use waam_part::graph::WeldGraph;
use waam_part::{Part, Window};
use waam_pipeline::MeshSettings;
use waam_planner::{CandidateVerdict, Event, Options, Report};
use waam_rosbag::{BagError, Qos, Recorder};
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::{DiagnosticArray, KeyValue};
use waam_rosmsg::std_msgs::{Header, String as RosString};
use waam_rosmsg::waam_interfaces::PlanCandidate;
use waam_thermal::{ThermalModel, ViolationKind};

/// The frame of part coordinates (block centres in metres from the part origin).
pub const PART_FRAME: &str = "part";
/// A planning run could not be recorded.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    #[error(transparent)]
    Bag(#[from] BagError),
    #[error(transparent)]
    Convert(#[from] ConvertError),
}

/// The prefix of the planner's settings among status values.
pub const SETTING: &str = "planner.";

/// The planner's settings as status values: `planner.acyclicity`, `planner.lookahead_budget`,
/// `planner.solver`, `planner.max_fragments` (absent: the part's own),
/// `planner.timeout_s` (absent: none) and `planner.torch` (the torch setup as JSON; absent:
/// no torch check).
pub fn settings(opts: &Options) -> Vec<KeyValue> {
    let mut values = vec![
        KeyValue::new(format!("{SETTING}acyclicity"), opts.acyclicity.name()),
        KeyValue::new(format!("{SETTING}lookahead_budget"), opts.lookahead_budget),
        KeyValue::new(format!("{SETTING}solver"), opts.solver.name()),
        KeyValue::new(format!("{SETTING}warm_start"), opts.warm_start),
    ];
    if let Some(k) = opts.max_fragments {
        values.push(KeyValue::new(format!("{SETTING}max_fragments"), k));
    }
    if let Some(t) = opts.timeout {
        values.push(KeyValue::new(
            format!("{SETTING}timeout_s"),
            t.as_secs_f64(),
        ));
    }
    values.extend(torch_values(opts.torch));
    values
}

/// The torch setup as the status value `planner.torch` (JSON), none without a torch.
pub fn torch_values(torch: Option<waam_access::TorchSetup>) -> Vec<KeyValue> {
    torch
        .map(|t| {
            let json = serde_json::to_string(&t).expect("a torch setup serializes");
            KeyValue::new(format!("{SETTING}torch"), json)
        })
        .into_iter()
        .collect()
}

/// Planner settings from recorded status values; settings not recorded keep `base`'s.
pub fn options_from(
    values: &[(String, String)],
    base: &Options,
) -> Result<Options, RecordedSettingError> {
    let mut opts = base.clone();
    // Recorded before the warm start existed: the run had none.
    if !values
        .iter()
        .any(|(k, _)| *k == format!("{SETTING}warm_start"))
    {
        opts.warm_start = false;
    }
    for (key, value) in values {
        let Some(name) = key.strip_prefix(SETTING) else {
            continue;
        };
        let bad = |what: &str| RecordedSettingError {
            key: key.clone(),
            value: value.clone(),
            expected: what.into(),
        };
        match name {
            "acyclicity" => {
                opts.acyclicity = value.parse().map_err(|_| bad("not an acyclicity method"))?
            }
            "solver" => opts.solver = value.parse().map_err(|_| bad("not a SAT solver"))?,
            "warm_start" => opts.warm_start = value.parse().map_err(|_| bad("not true/false"))?,
            "lookahead_budget" => {
                opts.lookahead_budget = value.parse().map_err(|_| bad("not a count"))?
            }
            "max_fragments" => {
                opts.max_fragments = Some(value.parse().map_err(|_| bad("not a count"))?)
            }
            "torch" => {
                let setup: waam_access::TorchSetup =
                    serde_json::from_str(value).map_err(|_| bad("not a torch setup (JSON)"))?;
                setup
                    .validate()
                    .map_err(|e| bad(&format!("not a usable torch setup: {e}")))?;
                opts.torch = Some(setup);
            }
            // Replay plans to the end: a timeout makes no reproducible plan.
            "timeout_s" => {}
            _ => {}
        }
    }
    Ok(opts)
}

/// Status keys of the mesh settings ([`MeshSettings`]) and of the mesh part's name: recorded
/// with every mesh received, so that a replay voxelizes (or slices) it the same way.
pub mod mesh_keys {
    pub const NAME: &str = "mesh.name";
    pub const BLOCK_MM: &str = "mesh.block_mm";
    /// Present when the mesh was sliced into beads.
    pub const BEAD_MM: &str = "mesh.bead_mm";
    pub const T85_WINDOW_S: &str = "mesh.t85_window_s";
    pub const MAX_FRAGMENTS: &str = "mesh.max_fragments";
}

/// A recorded setting that cannot be read back.
#[derive(Debug, Clone, thiserror::Error)]
#[error("recorded {key}={value:?}: {expected}")]
pub struct RecordedSettingError {
    pub key: String,
    pub value: String,
    pub expected: String,
}

/// The mesh settings and the part's name as status values.
pub fn mesh_values(settings: &MeshSettings, name: &str) -> Vec<KeyValue> {
    let [a, b, c] = settings.block_mm;
    let mut values = vec![
        KeyValue::new(mesh_keys::NAME, name),
        KeyValue::new(mesh_keys::BLOCK_MM, format!("{a} {b} {c}")),
        KeyValue::new(mesh_keys::MAX_FRAGMENTS, settings.max_fragments),
    ];
    if let Some([w, h]) = settings.bead_mm {
        values.push(KeyValue::new(mesh_keys::BEAD_MM, format!("{w} {h}")));
    }
    if let Some(w) = settings.window {
        values.push(KeyValue::new(
            mesh_keys::T85_WINDOW_S,
            format!("{} {}", w.min_s, w.max_s),
        ));
    }
    values
}

/// Mesh settings and name from recorded status values (the last value of a key wins);
/// `None` when no `mesh.block_mm` was recorded.
pub fn mesh_settings_from_values(
    values: &[(String, String)],
) -> Result<Option<(MeshSettings, String)>, RecordedSettingError> {
    let get = |key: &str| values.iter().rev().find(|(k, _)| k == key).map(|(_, v)| v);
    let bad = |key: &str, value: &str, expected: &str| RecordedSettingError {
        key: key.into(),
        value: value.into(),
        expected: expected.into(),
    };
    let numbers = |key: &str, n: usize| -> Result<Option<Vec<f64>>, RecordedSettingError> {
        let Some(v) = get(key) else { return Ok(None) };
        let xs: Vec<f64> = v
            .split_whitespace()
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|_| bad(key, v, "not numbers"))?;
        if xs.len() != n || xs.iter().any(|x| !x.is_finite()) {
            return Err(bad(key, v, &format!("expected {n} finite numbers")));
        }
        Ok(Some(xs))
    };
    let Some(block) = numbers(mesh_keys::BLOCK_MM, 3)? else {
        return Ok(None);
    };
    let bead = numbers(mesh_keys::BEAD_MM, 2)?;
    let window = numbers(mesh_keys::T85_WINDOW_S, 2)?.map(|w| Window {
        min_s: w[0],
        max_s: w[1],
    });
    let max_fragments = match get(mesh_keys::MAX_FRAGMENTS) {
        Some(v) => v
            .parse()
            .map_err(|_| bad(mesh_keys::MAX_FRAGMENTS, v, "not a count"))?,
        None => {
            return Err(bad(
                mesh_keys::MAX_FRAGMENTS,
                "",
                &format!("missing beside {}", mesh_keys::BLOCK_MM),
            ))
        }
    };
    let name = get(mesh_keys::NAME)
        .cloned()
        .unwrap_or_else(|| "mesh".into());
    Ok(Some((
        MeshSettings {
            block_mm: [block[0], block[1], block[2]],
            bead_mm: bead.map(|b| [b[0], b[1]]),
            window,
            max_fragments,
        },
        name,
    )))
}

/// A status as a recording carries it on `~/status`: stamped now, reported by the node
/// [`NODE_NAME`] without a namespace (the recordings' topics are its).
pub fn recorded(status: Status) -> DiagnosticArray {
    status.to_msg(Time::now(), &fully_qualified("/", NODE_NAME))
}

/// Records the planner's verdict on every candidate as `PlanCandidate` messages. Feed it
/// the planner's progress; a recording error stops it and is returned by
/// [`CandidateRecorder::finish`].
pub struct CandidateRecorder {
    recorder: Recorder,
    index: u64,
    error: Option<RecordError>,
}

impl CandidateRecorder {
    pub fn new(recorder: &Recorder) -> Self {
        CandidateRecorder {
            recorder: recorder.clone(),
            index: 0,
            error: None,
        }
    }

    /// Call with every event of the planner: records one `PlanCandidate` per candidate
    /// with the planner's verdict on it (the broken window's block, kind, time and prefix,
    /// or the block the torch cannot reach and its prefix; and the learned clause's length).
    pub fn on_event(&mut self, event: &Event) {
        let Event::Candidate { verdict, .. } = event else {
            return;
        };
        if self.error.is_some() {
            return;
        }
        self.index += 1;
        let mut candidate = PlanCandidate {
            // Its block is a place in the part: the part frame, as the heat cloud.
            header: Header::new(Time::now(), PART_FRAME),
            index: self.index,
            verdict: PlanCandidate::FEASIBLE,
            ..Default::default()
        };
        let (verdict, block, time_s, prefix_len, clause_len) = match *verdict {
            CandidateVerdict::Feasible => (PlanCandidate::FEASIBLE, None, 0.0, 0, 0),
            CandidateVerdict::Violated {
                block,
                kind,
                time_s,
                prefix_len,
                clause_len,
            } => {
                let verdict = match kind {
                    ViolationKind::Min => PlanCandidate::TOO_SHORT,
                    ViolationKind::Max => PlanCandidate::TOO_LONG,
                };
                (verdict, Some(block), time_s, prefix_len, clause_len)
            }
            // The blocked block; no simulated time (the torch check is not a simulation).
            CandidateVerdict::TorchBlocked {
                block,
                prefix_len,
                clause_len,
                ..
            } => (
                PlanCandidate::TORCH_BLOCKED,
                Some(block),
                0.0,
                prefix_len,
                clause_len,
            ),
            // Rejected on the robot's executed time line: no one block to name.
            CandidateVerdict::ExecutedRejected {
                prefix_len,
                clause_len,
            } => (PlanCandidate::VIOLATED, None, 0.0, prefix_len, clause_len),
        };
        candidate.verdict = verdict;
        if let Some(block) = block {
            candidate.block = match block_msg(block) {
                Ok(b) => b,
                Err(e) => {
                    self.error = Some(e.into());
                    return;
                }
            };
            candidate.time_s = time_s;
        }
        candidate.prefix_len = u32::try_from(prefix_len).unwrap_or(u32::MAX);
        candidate.learned_clause_len = u32::try_from(clause_len).unwrap_or(u32::MAX);
        match self
            .recorder
            .record(topics::CANDIDATES, &Qos::reliable(100), &candidate)
        {
            Ok(()) => tracing::debug!("recorded candidate {}", self.index),
            Err(e) => self.error = Some(e.into()),
        }
    }

    /// The first error met while recording, if any.
    pub fn finish(self) -> Result<(), RecordError> {
        self.error.map_or(Ok(()), Err)
    }
}

/// Records one planning run: the part, every candidate, and the outcome. Errors while
/// recording candidates are kept and returned by [`PlanningRecorder::finish`].
pub struct PlanningRecorder {
    recorder: Recorder,
    candidates: CandidateRecorder,
}

impl PlanningRecorder {
    /// Records the part as received (its document text) and a "received" status with the
    /// planner's settings, and syncs them to disk (see [`Recorder::sync`]).
    pub fn start(
        recorder: &Recorder,
        part_text: &str,
        part_name: &str,
        opts: &Options,
    ) -> Result<Self, BagError> {
        recorder.record(
            topics::PART,
            &Qos::reliable(10),
            &RosString::from(part_text),
        )?;
        let mut values = vec![KeyValue::new("part", part_name)];
        values.extend(settings(opts));
        recorder.record(
            topics::STATUS,
            &Qos::latched(),
            &recorded(Status::ok("received", values)),
        )?;
        // The input is on disk before the planner runs: a crash or kill while planning
        // never loses what was to be planned.
        recorder.sync()?;
        Ok(PlanningRecorder {
            recorder: recorder.clone(),
            candidates: CandidateRecorder::new(recorder),
        })
    }

    /// Call with every event of the planner (see [`CandidateRecorder`]).
    pub fn on_event(&mut self, event: &Event) {
        self.candidates.on_event(event);
    }

    /// Records the outcome: the plan (with its motion's trajectory, poses, path and markers
    /// when there is one), a "planned" status and the heat frames of the plan, or an ERROR
    /// status with the reason there is none.
    pub fn finish(
        self,
        part: &Part,
        report: &Report,
        motion: Option<&PlanMessages>,
    ) -> Result<(), RecordError> {
        self.candidates.finish()?;
        let stats = statistics(&report.stats, report.proven);
        let Some(best) = &report.best else {
            let reason = match &report.no_plan {
                Some(r) => r.to_string(),
                None => "no feasible plan found before the timeout (not proven)".into(),
            };
            self.recorder.record(
                topics::STATUS,
                &Qos::latched(),
                &recorded(Status::error(reason, vec![])),
            )?;
            return Ok(());
        };
        let now = match motion {
            Some(messages) => {
                messages.record(&self.recorder)?;
                messages.weld_plan.header.stamp
            }
            None => {
                let now = Time::now();
                let plan = WeldPlanOf {
                    part_name: &part.name,
                    block_pitch: part.block_mm[0] / 1000.0,
                    fragments: block_fragments(part, &best.fragments),
                    toolpath: None,
                    weld_speed: part.block_mm[0] / 1000.0 / part.thermal.block_time_s,
                    transit_speed: 0.0,
                    worst_margin_s: best.margin,
                    statistics: stats,
                }
                .to_msg(&Header::new(now, PART_FRAME))?;
                self.recorder
                    .record_at(topics::WELD_PLAN, &Qos::latched(), now, &plan)?;
                now
            }
        };
        let values = vec![
            KeyValue::new("fragments", best.fragments.len()),
            KeyValue::new("worst_margin_s", best.margin),
            KeyValue::new("proven", report.proven),
            KeyValue::new("candidates", report.stats.candidates),
            KeyValue::new("feasible", report.stats.feasible),
            KeyValue::new("total_s", report.stats.total_s),
        ];
        self.recorder.record_at(
            topics::STATUS,
            &Qos::latched(),
            now,
            &recorded(Status::ok("planned", values)),
        )?;
        let graph = WeldGraph::new(part);
        let model = ThermalModel::new(part, &graph);
        record_heat(
            &self.recorder,
            part,
            &model,
            &best.fragments,
            PART_FRAME,
            now,
            HeatOptions::default(),
        )?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use waam_planner::{Acyclicity, Backend};

    #[test]
    fn settings_round_trip_through_status_values() {
        let opts = Options {
            acyclicity: Acyclicity::Eager,
            lookahead_budget: 7,
            timeout: Some(std::time::Duration::from_secs(3)),
            max_fragments: Some(4),
            cancel: None,
            solver: Backend::Varisat,
            torch: Some(waam_access::TorchSetup::new(
                waam_access::Torch::default(),
                10.0,
                5.0,
            )),
            warm_start: false,
            executed: None,
            max_memory_mb: waam_planner::DEFAULT_MAX_MEMORY_MB,
            threads: 0,
        };
        let values: Vec<(String, String)> = settings(&opts)
            .into_iter()
            .map(|kv| (kv.key, kv.value))
            .collect();
        assert!(values.contains(&("planner.acyclicity".into(), "eager".into())));
        let back = options_from(&values, &Options::default()).unwrap();
        assert_eq!(back.acyclicity, Acyclicity::Eager);
        assert_eq!(back.lookahead_budget, 7);
        assert_eq!(back.max_fragments, Some(4));
        assert!(!back.warm_start);
        // A recording from before the warm start replays without one.
        let old: Vec<_> = values
            .iter()
            .filter(|(k, _)| k != "planner.warm_start")
            .cloned()
            .collect();
        assert!(!options_from(&old, &Options::default()).unwrap().warm_start);
        assert_eq!(back.solver, Backend::Varisat);
        assert_eq!(back.timeout, None, "replay never plans under a timeout");
        assert_eq!(back.torch, opts.torch);
        let none = options_from(&[], &Options::default()).unwrap();
        assert_eq!(none.torch, None);
        let bad = [("planner.torch".to_string(), "{\"tilt_deg\": 3}".to_string())];
        let err = options_from(&bad, &Options::default()).unwrap_err();
        assert!(err.to_string().contains("planner.torch"), "{err}");
        let bad = [("planner.acyclicity".to_string(), "sideways".to_string())];
        let err = options_from(&bad, &Options::default())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("planner.acyclicity") && err.contains("sideways"),
            "{err}"
        );
    }

    #[test]
    fn mesh_settings_round_trip_through_status_values_and_bad_ones_are_named() {
        let mut settings = MeshSettings {
            block_mm: [6.0, 5.5, 2.5],
            bead_mm: None,
            window: Some(Window {
                min_s: 3.0,
                max_s: 9.5,
            }),
            max_fragments: 3,
        };
        let values = |settings: &MeshSettings| -> Vec<(String, String)> {
            mesh_values(settings, "mesh-2")
                .into_iter()
                .map(|kv| (kv.key, kv.value))
                .collect()
        };
        assert_eq!(
            mesh_settings_from_values(&values(&settings)).unwrap(),
            Some((settings.clone(), "mesh-2".to_string()))
        );
        // Sliced into beads: the bead size is recorded too, so a replay slices it again.
        settings.bead_mm = Some([6.0, 2.5]);
        assert_eq!(
            mesh_settings_from_values(&values(&settings)).unwrap(),
            Some((settings, "mesh-2".to_string()))
        );
        assert_eq!(mesh_settings_from_values(&[]).unwrap(), None);
        let bad = [(mesh_keys::BLOCK_MM.to_string(), "6 x 2.5".to_string())];
        let err = mesh_settings_from_values(&bad).unwrap_err();
        let err = err.to_string();
        assert!(
            err.contains("mesh.block_mm") && err.contains("6 x 2.5"),
            "{err}"
        );
        let short = [(mesh_keys::BLOCK_MM.to_string(), "6 6".to_string())];
        assert!(mesh_settings_from_values(&short).is_err());
        let bead = [
            (mesh_keys::BLOCK_MM.to_string(), "6 6 2".to_string()),
            (mesh_keys::MAX_FRAGMENTS.to_string(), "2".to_string()),
            (mesh_keys::BEAD_MM.to_string(), "6".to_string()),
        ];
        let err = mesh_settings_from_values(&bead).unwrap_err().to_string();
        assert!(err.contains("mesh.bead_mm"), "{err}");
    }
}
