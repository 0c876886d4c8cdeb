//! Recording a planning run (`waam plan --record`, `waam replay --record`) on the node's
//! topics: the part received, the planner's verdict on every candidate, the plan (or an ERROR
//! status saying why there is none), and the simulated heat of the chosen plan.

use super::heat::{record_heat, HeatOptions};
use crate::node::convert::PlanMessages;
use crate::topics;
use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_planner::{CandidateVerdict, Options, Report, Stats};
use waam_rosbag::{BagError, Qos, Recorder};
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use waam_rosmsg::std_msgs::{Header, String as RosString};
use waam_rosmsg::waam_interfaces::{Block, PlanCandidate, PlanStatistics, WeldFragment, WeldPlan};
use waam_thermal::{ThermalModel, ViolationKind};

/// The frame of part coordinates (block centres in metres from the part origin).
pub const PART_FRAME: &str = "part";
/// `hardware_id` and status name of our diagnostics.
pub const NODE_NAME: &str = "waam_planner";

/// The planner's statistics as our message carries them.
pub fn statistics(stats: &Stats, proven: bool) -> PlanStatistics {
    PlanStatistics {
        candidates: stats.candidates,
        feasible: stats.feasible,
        optimal: proven,
        time_to_first_feasible_s: stats.first_feasible_s.unwrap_or(f64::NAN),
        total_time_s: stats.total_s,
        sat_time_s: stats.sat_s,
        acyclicity_time_s: stats.acyclicity_s,
        simulation_time_s: stats.simulator_s,
        learned_clauses: u32::try_from(stats.learned_clauses).unwrap_or(u32::MAX),
        learned_clause_min: stats.clause_len_min.map_or(0, |v| v as u32),
        learned_clause_max: stats.clause_len_max.map_or(0, |v| v as u32),
        learned_clause_mean: stats.clause_len_mean.unwrap_or(0.0),
    }
}

/// A plan as a `WeldPlan` without toolpath (the fragments, pitch, margin and statistics).
pub fn weld_plan(
    part: &Part,
    fragments: &[Vec<usize>],
    margin_s: f64,
    statistics: PlanStatistics,
    header: Header,
) -> Result<WeldPlan, BagError> {
    let fragments = fragments
        .iter()
        .map(|f| {
            f.iter()
                .map(|&i| {
                    let b = part.block(i);
                    Block::from_part(b).ok_or_else(|| BagError::Corrupt {
                        path: PART_FRAME.into(),
                        reason: format!("block [{},{},{}] does not fit in int32", b[0], b[1], b[2]),
                    })
                })
                .collect::<Result<Vec<_>, _>>()
                .map(|blocks| WeldFragment { blocks })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(WeldPlan {
        header,
        part_name: part.name.clone(),
        block_pitch: part.block_mm[0] / 1000.0,
        fragments,
        points: Vec::new(),
        weld_speed: part.block_mm[0] / 1000.0 / part.thermal.block_time_s,
        transit_speed: 0.0,
        worst_margin_s: margin_s,
        statistics,
    })
}

/// Prefix of the status keys that record the planner's settings (replay uses them).
pub const SETTING: &str = "planner.";

/// The planner's settings as status values: `planner.acyclicity`, `planner.lookahead_budget`,
/// `planner.solver`, `planner.max_fragments` (absent: the part's own) and
/// `planner.timeout_s` (absent: none).
pub fn settings(opts: &Options) -> Vec<KeyValue> {
    let mut values = vec![
        KeyValue::new(format!("{SETTING}acyclicity"), opts.acyclicity.name()),
        KeyValue::new(format!("{SETTING}lookahead_budget"), opts.lookahead_budget),
        KeyValue::new(format!("{SETTING}solver"), opts.solver.name()),
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
    values
}

/// Planner settings from recorded status values; settings not recorded keep `base`'s.
pub fn options_from(values: &[(String, String)], base: &Options) -> Result<Options, String> {
    let mut opts = base.clone();
    for (key, value) in values {
        let Some(name) = key.strip_prefix(SETTING) else {
            continue;
        };
        let bad = |what: &str| format!("recorded setting {key}={value:?}: {what}");
        match name {
            "acyclicity" => {
                opts.acyclicity = value.parse().map_err(|_| bad("not an acyclicity method"))?
            }
            "solver" => opts.solver = value.parse().map_err(|_| bad("not a SAT solver"))?,
            "lookahead_budget" => {
                opts.lookahead_budget = value.parse().map_err(|_| bad("not a count"))?
            }
            "max_fragments" => {
                opts.max_fragments = Some(value.parse().map_err(|_| bad("not a count"))?)
            }
            // Replay plans to the end: a timeout makes no reproducible plan.
            "timeout_s" => {}
            _ => {}
        }
    }
    Ok(opts)
}

/// A status report of the node's one component.
pub fn status(level: u8, message: &str, values: Vec<KeyValue>) -> DiagnosticArray {
    DiagnosticArray {
        header: Header::new(Time::now(), ""),
        status: vec![DiagnosticStatus {
            level,
            name: NODE_NAME.into(),
            message: message.into(),
            hardware_id: NODE_NAME.into(),
            values,
        }],
    }
}

/// Records the planner's verdict on every candidate as `PlanCandidate` messages. Feed it
/// the planner's progress; a recording error stops it and is returned by
/// [`CandidateRecorder::finish`].
pub struct CandidateRecorder {
    recorder: Recorder,
    seen: Stats,
    index: u64,
    error: Option<BagError>,
}

impl CandidateRecorder {
    pub fn new(recorder: &Recorder) -> Self {
        CandidateRecorder {
            recorder: recorder.clone(),
            seen: Stats::default(),
            index: 0,
            error: None,
        }
    }

    /// Call with the planner's statistics after every candidate: records one
    /// `PlanCandidate` per new candidate with the planner's verdict on it (the broken
    /// window's block, kind, time and prefix, and the learned clause's length). Candidates
    /// the planner reported only in bulk (plain counting) are recorded as counted.
    pub fn progress(&mut self, stats: &Stats) {
        if self.error.is_some() || stats.candidates <= self.seen.candidates {
            return;
        }
        let new = stats.candidates - self.seen.candidates;
        for k in 0..new {
            self.index += 1;
            let mut candidate = PlanCandidate {
                header: Header::new(Time::now(), ""),
                index: self.index,
                verdict: PlanCandidate::VIOLATED,
                ..Default::default()
            };
            // The details belong to the latest candidate only.
            match stats.last_candidate.filter(|_| k + 1 == new) {
                Some(CandidateVerdict::Feasible) => candidate.verdict = PlanCandidate::FEASIBLE,
                Some(CandidateVerdict::Violated {
                    block,
                    kind,
                    time_s,
                    prefix_len,
                    clause_len,
                }) => {
                    candidate.verdict = match kind {
                        ViolationKind::Min => PlanCandidate::TOO_SHORT,
                        ViolationKind::Max => PlanCandidate::TOO_LONG,
                    };
                    candidate.block = Block::from_part(block).unwrap_or_default();
                    candidate.time_s = time_s;
                    candidate.prefix_len = u32::try_from(prefix_len).unwrap_or(u32::MAX);
                    candidate.learned_clause_len = u32::try_from(clause_len).unwrap_or(u32::MAX);
                }
                None => {}
            }
            if let Err(e) =
                self.recorder
                    .record(topics::CANDIDATES, &Qos::reliable(100), &candidate)
            {
                self.error = Some(e);
                return;
            }
        }
        self.seen = stats.clone();
    }

    /// The first error met while recording, if any.
    pub fn finish(self) -> Result<(), BagError> {
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
    /// planner's settings.
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
            &status(DiagnosticStatus::OK, "received", values),
        )?;
        Ok(PlanningRecorder {
            recorder: recorder.clone(),
            candidates: CandidateRecorder::new(recorder),
        })
    }

    /// Call with the planner's statistics after every candidate (see [`CandidateRecorder`]).
    pub fn progress(&mut self, stats: &Stats) {
        self.candidates.progress(stats);
    }

    /// Records the outcome: the plan (with its motion's trajectory, poses, path and markers
    /// when there is one), a "planned" status and the heat frames of the plan, or an ERROR
    /// status with the reason there is none.
    pub fn finish(
        self,
        part: &Part,
        report: &Report,
        motion: Option<&PlanMessages>,
    ) -> Result<(), BagError> {
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
                &status(DiagnosticStatus::ERROR, &reason, vec![]),
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
                let plan = weld_plan(
                    part,
                    &best.fragments,
                    best.margin,
                    stats,
                    Header::new(now, PART_FRAME),
                )?;
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
            &status(DiagnosticStatus::OK, "planned", values),
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
        assert_eq!(back.solver, Backend::Varisat);
        assert_eq!(back.timeout, None, "replay never plans under a timeout");
        let bad = [("planner.acyclicity".to_string(), "sideways".to_string())];
        let err = options_from(&bad, &Options::default()).unwrap_err();
        assert!(
            err.contains("planner.acyclicity") && err.contains("sideways"),
            "{err}"
        );
    }
}
