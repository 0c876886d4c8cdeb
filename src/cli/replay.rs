//! `waam replay BAG`: re-plan every part a recording received and compare with the recorded
//! plans — a regression check for the planner, and offline debugging of a cell's builds.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde_json::json;
use waam_messages::convert::statistics;
use waam_messages::planning::{
    mesh_settings_from_values, options_from, PlanningRecorder, RecordError,
};
use waam_messages::replay::decisions::{self, DecisionReport, DecisionVerdict};
use waam_messages::replay::{self, CaseInput, Replanned, Verdict};
use waam_part::writer;
use waam_part::Part;
use waam_pipeline::Progress;
use waam_planner::{Acyclicity, Options};
use waam_ros::node::pipeline::mesh_arrays;
use waam_rosbag::{Bag, Recorder};

use super::{EXIT_BAD_INPUT, EXIT_INTERRUPTED, EXIT_NO, EXIT_OK};

/// Re-plan every part found in a recording and compare each new plan with the recorded one.
///
/// The planner runs with the settings recorded with the part (`waam plan --record` records
/// them), else the defaults; options given here override them. Never with the recorded
/// timeout (a timeout makes no reproducible plan); `--timeout` bounds the whole replay.
///
/// Parts are the part documents received on `.../part` topics and the meshes received on
/// `.../part_mesh` (voxelized again with the settings the node recorded with them); each is
/// paired with the first plan (waam_interfaces/WeldPlan) or ERROR status recorded after it. Prints IDENTICAL, or
/// DIFFERENT with the fragments, the first differing block and the statistics that changed
/// (candidates, feasible plans, learned clauses; never times). A truncated recording (a killed
/// process) is read up to its last complete chunk and said to be truncated.
///
/// Closed loop: every execution the node ran with `closed_loop.enabled` is re-run decision
/// by decision, on the part its job received and the plan it executed, from what each
/// `replanned` status records (`loop.*`: the deposits' times, the boundary's time, which
/// readings had come, by stamp and value) and the recorded Temperature and PointCloud2
/// messages themselves. Each decision is IDENTICAL or DIFFERENT (the loop's decision, the
/// estimate's factors and rms errors bit for bit, the new plan's fragments), or NOT
/// REPRODUCIBLE with the reason (a reading missing from the recording, a re-plan that the
/// node's time limit cut short, a status without a readable record). The node's robot-motion
/// check of a new plan is not re-run: the loop follows what the node did. `--decisions-only`
/// skips re-planning the parts.
///
/// Exit code 0: every compared plan and decision is identical; 1: a difference, or
/// `--timeout` came first; 2: bad input (unreadable bag, nothing to compare in it); 130:
/// stopped by Ctrl-C.
#[derive(Debug, clap::Args)]
pub struct ReplayArgs {
    /// The recording: a bag directory (with metadata.yaml) or an .mcap file.
    pub bag: PathBuf,
    /// Also write the re-planned session as a new bag in the new directory OUT.
    #[arg(long, value_name = "OUT")]
    pub record: Option<PathBuf>,
    /// Compare only the plans, not the planner's statistics.
    #[arg(long)]
    pub plans_only: bool,
    /// Re-run only the closed loop's decisions, not the parts' plans (e.g. a recording of
    /// `waam publish --plan`, whose plan is not the planner's).
    #[arg(long, conflicts_with_all = ["record", "plans_only"])]
    pub decisions_only: bool,
    /// Re-plan with this max_fragments (k) instead of the recorded setting (or the part's own).
    #[arg(long, value_name = "K", value_parser = super::at_least_one)]
    pub max_fragments: Option<usize>,
    /// How cycles are excluded (as `waam plan --acyclicity`), instead of the recorded setting.
    #[arg(long, value_parser = super::acyclicity_parser())]
    pub acyclicity: Option<Acyclicity>,
    /// Learn plain violating prefixes (as `waam plan --no-shortening`), whatever was recorded.
    #[arg(long)]
    pub no_shortening: bool,
    /// Instead of re-planning, play the recorded messages back to ROS 2 topics with their
    /// original timing and QoS (a dry run of a past session). Honours ROS_DOMAIN_ID and
    /// ROS_AUTOMATIC_DISCOVERY_RANGE / ROS_LOCALHOST_ONLY.
    #[arg(long, conflicts_with_all = ["record", "plans_only", "max_fragments", "decisions_only"])]
    pub publish: bool,
    /// With --publish: play this many times faster than recorded.
    #[arg(long, default_value_t = 1.0, requires = "publish")]
    pub rate: f64,
    /// With --publish: seconds to wait before the first message, for subscribers to be
    /// discovered (as `ros2 bag play --delay`).
    #[arg(long, default_value_t = 1.0, requires = "publish")]
    pub delay: f64,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Stop re-planning after this many seconds in all: the part being planned then is
    /// cut off and, like the parts after it, not compared (exit 1). Ctrl-C stops the same
    /// way (exit 130).
    #[arg(long, value_name = "SECONDS", conflicts_with = "publish")]
    pub timeout: Option<f64>,
}

pub fn run(args: ReplayArgs) -> anyhow::Result<ExitCode> {
    let started = Instant::now();
    let deadline = args
        .timeout
        .map(|s| {
            Duration::try_from_secs_f64(s)
                .ok()
                .and_then(|t| started.checked_add(t))
                .ok_or_else(|| anyhow::anyhow!("--timeout: expected seconds >= 0, got {s}"))
        })
        .transpose()?;
    let bag = Bag::open(&args.bag)?;
    if let Some(t) = &bag.truncated {
        eprintln!(
            "warning: {} is truncated ({} after {} bytes): replaying what was recorded up to \
             its last complete chunk",
            bag.mcap_file.display(),
            t.reason,
            t.file_len
        );
    }
    if args.publish {
        return publish(&args, &bag);
    }
    let cases = replay::recorded_cases(&bag)?;
    let (executions, mut sensors) = decisions::recorded_executions(&bag)?;
    if cases.is_empty() {
        let layer_note = if bag.count(waam_messages::topics::LAYER) > 0 {
            "; it is a layer recording (`waam layer plan --record`), which replay does not \
             re-plan: `waam bag info` and `waam replay --publish` read it"
        } else {
            ""
        };
        eprintln!(
            "error: {} holds no part (std_msgs/String on a .../part topic, shape_msgs/Mesh) \
             to re-plan{layer_note}",
            args.bag.display()
        );
        return Ok(ExitCode::from(EXIT_BAD_INPUT));
    }
    let overrides = |mut opts: Options| {
        if let Some(a) = args.acyclicity {
            opts.acyclicity = a;
        }
        if args.no_shortening {
            opts.lookahead_budget = 0;
        }
        if args.max_fragments.is_some() {
            opts.max_fragments = args.max_fragments;
        }
        opts.timeout = None;
        opts
    };
    let recorder = args.record.as_deref().map(Recorder::create).transpose()?;
    if let Some(r) = &recorder {
        // Replays plan without a robot: the part frame is tied to the node's default cell.
        super::record::record_frames(r, None)?;
    }
    // Ctrl-C raises the flag; the planner stops on it within a second.
    let interrupted = Arc::new(AtomicBool::new(false));
    {
        let flag = Arc::clone(&interrupted);
        ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed))?;
    }
    let stopped =
        || interrupted.load(Ordering::Relaxed) || deadline.is_some_and(|d| Instant::now() >= d);
    let mut record_error = None;
    let reports = replay::replay(cases, !args.plans_only, |case| {
        if args.decisions_only {
            return Replanned::Unsupported("not re-planned (--decisions-only)".into());
        }
        if stopped() {
            return Replanned::Unsupported(STOPPED.into());
        }
        let opts = match options_from(&case.status_values, &Options::default()) {
            Ok(opts) => Options {
                // Within what is left of --timeout; a run cut short is not compared.
                timeout: deadline.map(|d| d.saturating_duration_since(Instant::now())),
                cancel: Some(Arc::clone(&interrupted)),
                ..overrides(opts)
            },
            Err(e) => return Replanned::Unsupported(e.to_string()),
        };
        let (part, text) = match case_part(case) {
            Ok(found) => found,
            Err(why) => return why,
        };
        let mut planning = recorder.as_ref().and_then(|r| {
            PlanningRecorder::start(r, &text, &part.name, &opts)
                .map_err(|e| record_error.get_or_insert(RecordError::from(e)))
                .ok()
        });
        let mut progress = |progress: Progress| {
            if let (Some(p), Progress::Planner(event)) = (planning.as_mut(), progress) {
                p.on_event(&event);
            }
        };
        // Without a robot: the recorded settings' torch, if any, is checked as recorded.
        let options = waam_pipeline::Options {
            planner: opts.clone(),
            ..waam_pipeline::Options::default()
        };
        let report = match waam_pipeline::plan(&part, None, &options, &mut progress) {
            Ok(outcome) => outcome.report,
            Err(e) => return Replanned::NoPlan(e.to_string()),
        };
        if stopped() {
            return Replanned::Unsupported(STOPPED.into());
        }
        if let Some(p) = planning {
            if let Err(e) = p.finish(&part, &report, None) {
                record_error.get_or_insert(e);
            }
        }
        match &report.best {
            Some(best) => Replanned::Plan {
                fragments: best.plan(&part).fragments,
                statistics: statistics(&report.stats, report.proven),
            },
            None => Replanned::NoPlan(
                report
                    .no_plan
                    .as_ref()
                    .map_or("no feasible plan".into(), |r| r.to_string()),
            ),
        }
    });
    if let Some(e) = record_error {
        return Err(e.into());
    }
    if let Some(recorder) = recorder {
        let summary = recorder.finish()?;
        eprintln!(
            "recorded the re-planned session ({} messages) to {}",
            summary.messages,
            summary.dir.display()
        );
    }
    // The closed loop's decisions: each execution re-run on the part its job received.
    let mut decided: Vec<Decided> = Vec::new();
    for (n, execution) in executions.iter().enumerate() {
        let case = reports
            .iter()
            .map(|r| &r.case)
            .position(|c| decisions::received_job(&c.status_values).contains(&execution.job));
        let part = case
            .ok_or_else(|| {
                format!(
                    "the recording holds no part received as job {}",
                    execution.job
                )
            })
            .and_then(|c| {
                case_part(&reports[c].case)
                    .map(|(p, _)| p)
                    .map_err(|e| match e {
                        Replanned::NoPlan(why) | Replanned::Unsupported(why) => why,
                        Replanned::Plan { .. } => unreachable!("case_part gives no plan"),
                    })
            });
        let reports = match (&part, stopped()) {
            (_, true) => not_reproducible(execution, STOPPED),
            (Ok(part), false) => {
                // As the node re-plans (`closed_loop.enabled`): the planner's defaults;
                // its time limit is not applied offline.
                let planner = Options {
                    cancel: Some(Arc::clone(&interrupted)),
                    ..Options::default()
                };
                decisions::replay_execution(execution, part, &planner, &mut sensors)
            }
            (Err(why), false) => not_reproducible(execution, why),
        };
        decided.push(Decided {
            execution: n + 1,
            part: case.map_or(0, |c| c + 1),
            job: execution.job,
            reports,
            unreadable: execution.unreadable.clone(),
        });
    }
    let decision_count = |f: fn(&DecisionVerdict) -> bool| {
        decided
            .iter()
            .flat_map(|d| &d.reports)
            .filter(|r| f(&r.verdict))
            .count()
    };
    let d_identical = decision_count(|v| *v == DecisionVerdict::Identical);
    let d_different = decision_count(|v| matches!(v, DecisionVerdict::Different(_)));
    let d_skipped = decision_count(|v| matches!(v, DecisionVerdict::NotReproducible(_)))
        + decided.iter().map(|d| d.unreadable.len()).sum::<usize>();
    let different = reports
        .iter()
        .filter(|r| matches!(r.verdict, Verdict::Different(_)))
        .count();
    let identical = reports
        .iter()
        .filter(|r| r.verdict == Verdict::Identical)
        .count();
    let skipped = reports.len() - different - identical;
    if args.json {
        let cases: Vec<_> = reports
            .iter()
            .map(|r| {
                let (verdict, details) = match &r.verdict {
                    Verdict::Identical => ("identical", vec![]),
                    Verdict::Different(d) => {
                        ("different", d.iter().map(|d| d.to_string()).collect())
                    }
                    Verdict::Skipped(why) => ("skipped", vec![why.clone()]),
                };
                json!({
                    "topic": r.case.topic,
                    "log_time_ns": r.case.log_time,
                    "part": part_name(&r.case.input),
                    "verdict": verdict,
                    "details": details,
                })
            })
            .collect();
        println!(
            "{}",
            json!({
                "bag": args.bag,
                "truncated": bag.truncated.as_ref().map(|t| &t.reason),
                "identical": identical,
                "different": different,
                "skipped": skipped,
                "cases": cases,
                "decisions_identical": d_identical,
                "decisions_different": d_different,
                "decisions_not_reproducible": d_skipped,
                "decisions": decisions_json(&decided),
            })
        );
    } else {
        for (i, r) in reports.iter().enumerate() {
            let what = format!("part {} ({})", i + 1, part_name(&r.case.input));
            match &r.verdict {
                Verdict::Identical => match &r.replanned {
                    Replanned::Plan {
                        fragments,
                        statistics,
                    } => println!(
                        "{what}: IDENTICAL ({} fragment(s), {} candidates)",
                        fragments.len(),
                        statistics.candidates
                    ),
                    _ => println!("{what}: IDENTICAL (no plan, as recorded)"),
                },
                Verdict::Different(d) => {
                    println!("{what}: DIFFERENT");
                    for d in d {
                        println!("  {d}");
                    }
                }
                Verdict::Skipped(why) => println!("{what}: SKIPPED: {why}"),
            }
        }
        print_decisions(&decided);
        println!(
            "{} part(s): {identical} identical, {different} different, {skipped} skipped{}",
            reports.len(),
            if bag.truncated.is_some() {
                " (recording truncated)"
            } else {
                ""
            }
        );
        if !decided.is_empty() {
            println!(
                "{} closed-loop decision(s): {d_identical} identical, {d_different} different, \
                 {d_skipped} not reproducible",
                d_identical + d_different + d_skipped
            );
        }
    }
    let cut = reports
        .iter()
        .filter(|r| matches!(&r.verdict, Verdict::Skipped(why) if why == STOPPED))
        .count();
    if cut > 0 {
        let (why, code) = if interrupted.load(Ordering::Relaxed) {
            ("Ctrl-C", EXIT_INTERRUPTED)
        } else {
            ("--timeout", EXIT_NO)
        };
        eprintln!(
            "error: replay stopped by {why}: {cut} of {} part(s) not compared",
            reports.len()
        );
        return Ok(ExitCode::from(code));
    }
    if identical + different + d_identical + d_different == 0 {
        // A truncated recording can leave parts without outcomes: nothing was checked, so
        // this is not a pass.
        let decisions_note = if d_skipped > 0 {
            format!(", all {d_skipped} closed-loop decision(s) not reproducible")
        } else {
            String::new()
        };
        eprintln!(
            "error: {}: nothing to compare: all {} part(s) skipped{decisions_note}",
            args.bag.display(),
            reports.len()
        );
        return Ok(ExitCode::from(EXIT_BAD_INPUT));
    }
    Ok(ExitCode::from(if different + d_different > 0 {
        EXIT_NO
    } else {
        EXIT_OK
    }))
}

/// Why a part was not compared when the replay was stopped.
const STOPPED: &str = "not re-planned: the replay was stopped (--timeout or Ctrl-C)";

/// `--publish`: plays the recording back to ROS 2.
fn publish(args: &ReplayArgs, bag: &Bag) -> anyhow::Result<ExitCode> {
    if !(args.rate.is_finite() && args.rate > 0.0) {
        anyhow::bail!("--rate: expected a positive number, got {}", args.rate);
    }
    let delay = Duration::try_from_secs_f64(args.delay)
        .map_err(|_| anyhow::anyhow!("--delay: expected seconds >= 0, got {}", args.delay))?;
    let context = waam_ros::playback::context_from_env()?;
    let player = waam_ros::playback::Player::new(context, "waam_replay", bag)?;
    for topic in &player.skipped {
        eprintln!("warning: not played: {topic}");
    }
    let sent = player.play(bag, args.rate, delay)?;
    if args.json {
        println!("{}", json!({"bag": args.bag, "published": sent}));
    } else {
        for (topic, n) in &sent {
            println!("published {n} message(s) on {topic}");
        }
        println!(
            "published {} message(s) on {} topic(s)",
            sent.values().sum::<u64>(),
            sent.len()
        );
    }
    Ok(ExitCode::from(EXIT_OK))
}

/// The part a recorded case received, and its document; or why not (as replay's outcome).
/// A mesh is voxelized (or sliced into beads) with the settings the node recorded when it
/// received it.
fn case_part(case: &replay::RecordedCase) -> Result<(Part, String), Replanned> {
    match &case.input {
        CaseInput::PartText(text) => match read_document(text) {
            Ok(part) => Ok((part, text.clone())),
            Err(e) => Err(Replanned::NoPlan(format!("bad part: {e}"))),
        },
        CaseInput::Mesh(mesh) => {
            let (settings, name) = match mesh_settings_from_values(&case.status_values) {
                Ok(Some(found)) => found,
                Ok(None) => {
                    return Err(Replanned::Unsupported(
                        "a mesh recorded without the node's voxelizing settings \
                         (mesh.block_mm ...)"
                            .into(),
                    ))
                }
                Err(e) => return Err(Replanned::Unsupported(e.to_string())),
            };
            let (vertices, triangles) = mesh_arrays(mesh);
            match settings.part_of_mesh(name, &vertices, &triangles) {
                Ok(part) => {
                    let text = match part.bead_part() {
                        Some(beads) => beads.to_yaml(),
                        None => writer::to_yaml(&part),
                    };
                    Ok((part, text))
                }
                Err(e) => Err(Replanned::NoPlan(e.to_string())),
            }
        }
    }
}

/// A recorded part document: a block part or a graph part of beads.
fn read_document(text: &str) -> Result<Part, waam_pipeline::PipelineError> {
    // Mesh settings do not matter for a document.
    let unused = waam_pipeline::MeshSettings {
        block_mm: [1.0; 3],
        bead_mm: None,
        window: None,
        max_fragments: 1,
    };
    waam_pipeline::read_input(waam_pipeline::PartInput::Document(text.into()), &unused)
}

/// The part's name from its document (for messages), or what it is.
fn part_name(input: &CaseInput) -> String {
    match input {
        CaseInput::PartText(text) => read_document(text)
            .map(|p| p.name)
            .unwrap_or_else(|_| "unreadable part".into()),
        CaseInput::Mesh(m) => format!("mesh of {} triangles", m.triangles.len()),
    }
}

/// The re-run decisions of one recorded execution: its number in the recording, the part
/// (1-based, as printed; 0: not found) and job it executed.
struct Decided {
    execution: usize,
    part: usize,
    job: u64,
    reports: Vec<DecisionReport>,
    /// Recorded decisions whose record is missing or does not read, and why.
    unreadable: Vec<String>,
}

/// Every boundary of `execution`, not re-run, and why.
fn not_reproducible(execution: &decisions::RecordedExecution, why: &str) -> Vec<DecisionReport> {
    execution
        .boundaries
        .iter()
        .map(|b| DecisionReport {
            boundary: b.clone(),
            verdict: DecisionVerdict::NotReproducible(why.to_string()),
            new: None,
        })
        .collect()
}

/// What the node did at a boundary, as recorded.
fn recorded_outcome(b: &decisions::RecordedBoundary) -> String {
    let r = &b.record;
    let what = match b.reason.as_str() {
        "unchanged" => "the remainder unchanged".to_string(),
        "kept" => "the current plan kept".to_string(),
        _ => format!(
            "{}: a new plan of {} weld path(s) in all taken",
            b.reason,
            r.fragments.len()
        ),
    };
    format!(
        "{what}; loss x{:.4}, conduction x{:.4}, {} reading(s)",
        r.estimate[0],
        r.estimate[1],
        r.readings.len()
    )
}

/// One line per decision, in the style of the plans' lines.
fn print_decisions(decided: &[Decided]) {
    for Decided {
        execution,
        part: case,
        reports,
        unreadable,
        ..
    } in decided
    {
        for why in unreadable {
            println!("execution {execution} (part {case}), a decision: NOT REPRODUCIBLE: {why}");
        }
        for r in reports {
            let b = &r.boundary;
            let what = format!(
                "execution {execution} (part {case}), decision {} (after {} weld path(s), at {} s)",
                b.record.boundary,
                b.weld_paths_welded.map_or("?".into(), |w| w.to_string()),
                b.record.now_s
            );
            match &r.verdict {
                DecisionVerdict::Identical => {
                    println!("{what}: IDENTICAL ({})", recorded_outcome(b));
                    if b.record.changed {
                        let how = if b.reason == "kept" {
                            "refused"
                        } else {
                            "passed"
                        };
                        println!(
                            "  (the new plan {how} the node's robot-motion check, which is not \
                             re-run offline)"
                        );
                    }
                }
                DecisionVerdict::Different(d) => {
                    println!("{what}: DIFFERENT (recorded: {})", recorded_outcome(b));
                    for d in d {
                        println!("  {d}");
                    }
                }
                DecisionVerdict::NotReproducible(why) => {
                    println!("{what}: NOT REPRODUCIBLE: {why}")
                }
            }
        }
    }
}

fn decisions_json(decided: &[Decided]) -> Vec<serde_json::Value> {
    decided
        .iter()
        .flat_map(|d| {
            let unreadable = d.unreadable.iter().map(move |why| {
                json!({
                    "execution": d.execution,
                    "part": d.part,
                    "job": d.job,
                    "verdict": "not_reproducible",
                    "details": [why],
                })
            });
            unreadable.chain(d.reports.iter().map(move |r| {
                let b = &r.boundary;
                let (verdict, details) = match &r.verdict {
                    DecisionVerdict::Identical => ("identical", vec![]),
                    DecisionVerdict::Different(d) => {
                        ("different", d.iter().map(|d| d.to_string()).collect())
                    }
                    DecisionVerdict::NotReproducible(why) => {
                        ("not_reproducible", vec![why.clone()])
                    }
                };
                json!({
                    "execution": d.execution,
                    "part": d.part,
                    "job": d.job,
                    "boundary": b.record.boundary,
                    "log_time_ns": b.log_time,
                    "now_s": b.record.now_s,
                    "weld_paths_welded": b.weld_paths_welded,
                    "recorded_reason": b.reason,
                    "recorded_decision": b.record.decision,
                    "loss_factor": b.record.estimate[0],
                    "conduction_factor": b.record.estimate[1],
                    "readings": b.record.readings.len(),
                    "feed_revisions": b.record.feed_revisions.len(),
                    "scans": b
                        .record
                        .readings
                        .iter()
                        .filter(|r| matches!(r, decisions::ReadingRef::Scan { .. }))
                        .count(),
                    // The re-run's own estimate and plan size, when it ran.
                    "rerun": r.new.map(|(loss, conduction, weld_paths)| json!({
                        "loss_factor": loss,
                        "conduction_factor": conduction,
                        "weld_paths": weld_paths,
                    })),
                    "verdict": verdict,
                    "details": details,
                })
            }))
        })
        .collect()
}
