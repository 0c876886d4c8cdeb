//! `waam plan [PART]`: the best feasible weld plan of a part, or why there is none.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;
use waam_part::plan::Plan;
use waam_part::Part;
use waam_planner::{self as planner, Acyclicity, Backend, Options, Stats};

use super::{record, GlobalArgs, EXIT_INTERRUPTED, EXIT_NO, EXIT_OK};
use waam_access::TorchSetup;
use waam_motion::toolpath::{toolpath_of_plan, ProcessSettings, ToolpathFrame};
use waam_pipeline::{Interrupt, Objective, Progress};

/// Plan the weld order of a part: at most k weld paths covering every block, moving
/// sideways or up, never under what stands, keeping every t8/5 window.
///
/// The best plan has the fewest fragments (arc starts), then the largest worst-case margin
/// of any t8/5 value to its window bounds. Without PART, plans a bundled sample part (a
/// stepped L-bracket wall of 113 blocks) and runs the whole chain with the bundled robot and
/// its torch: plan,
/// toolpath, joint trajectory, pictures (3-D views, temperatures during the build) and a
/// rosbag2/MCAP recording, all in a new folder (--out DIR, or waam-out/, else waam-out-2/,
/// …; an existing non-empty folder is never written into); with --json, --count, --all,
/// --record or --robot it plans the sample part like any other. Ctrl-C stops the search as
/// the timeout does (the best plan so far is still reported, written and recorded). Exit
/// code 0: a plan was found; 1: there is none (or none found before the timeout); 2: bad
/// input; 130: stopped by Ctrl-C.
#[derive(Debug, clap::Args)]
pub struct PlanArgs {
    /// The part file (YAML, shared part format), or an STL mesh with --pitch. Default: the
    /// bundled L-bracket sample (config/parts/ex2-bracket.yaml).
    pub part: Option<PathBuf>,
    #[command(flatten, next_help_heading = "Mesh input (PART is an .stl file)")]
    pub mesh: super::voxelize::MeshArgs,
    /// Write DIR/plan.yaml and DIR/toolpath.yaml (the torch poses: in the part frame, or
    /// with --robot in its base link with DIR/trajectory.yaml); with --all,
    /// DIR/feasible-plans.yaml.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Return the first feasible plan found, without optimizing.
    #[arg(long, conflicts_with_all = ["all", "count"])]
    pub first: bool,
    /// Enumerate every feasible plan, streamed to DIR/feasible-plans.yaml (or stdout).
    #[arg(long, conflicts_with = "count")]
    pub all: bool,
    /// Print the exact numbers of valid plans and of feasible plans.
    #[arg(long)]
    pub count: bool,
    /// Stop after this many seconds and report the best found so far (not proven).
    #[arg(long, value_name = "SECONDS")]
    pub timeout: Option<f64>,
    /// Override the part's max_fragments (k).
    #[arg(long, value_name = "K", value_parser = super::at_least_one)]
    pub max_fragments: Option<usize>,
    /// Refuse a part whose search would need more memory than this (MB, estimated from
    /// its blocks and k before anything is built; about 13 KB per block at k = 1).
    #[arg(long, value_name = "MB", default_value_t = waam_planner::DEFAULT_MAX_MEMORY_MB)]
    pub max_memory_mb: u64,
    /// Worker threads of --all and --count, each searching its own share of the plans
    /// (default: the available cores). Counts and the order of the plans are the same on
    /// any number. For the first plan (of --first, and of the best plan, which optimizes on
    /// from it), the configurations raced, one thread each (1: the default configuration
    /// alone, its varied starts on one thread too). "No plan" is always the default's
    /// answer, and a proven best plan is the same plan on any number (the race helps the
    /// best plan when --timeout or Ctrl-C comes before the proof). N bounds the thermal
    /// checks too: a simulation steps on at most N threads (default: all cores, held by
    /// one simulation at a time; a race's other racers step on one core each), so a run on
    /// one thread keeps to one core. 1 to 1024.
    #[arg(long, value_name = "N", value_parser = super::thread_count)]
    pub threads: Option<usize>,
    /// How cycles are excluded: lazily by cuts between solves, or eagerly by a rank order.
    #[arg(long, value_parser = super::acyclicity_parser(), default_value = "lazy")]
    pub acyclicity: Acyclicity,
    /// The SAT solver: CaDiCaL (cycles kept out inside its search; stops inside a solve at
    /// --timeout) or varisat (pure Rust; cycles cut between solves; stops inside a solve at
    /// --timeout too).
    #[arg(long, value_parser = super::solver_parser(), default_value = Backend::default().name())]
    pub solver: Backend,
    /// Learn the plain violating prefix (as the paper) instead of proven shorter clauses.
    #[arg(long)]
    pub no_shortening: bool,
    /// Do not start from a plan built layer by layer (one SAT solve per layer, joined by
    /// up moves): the solver searches from scratch. Answers are the same; only the time
    /// to find them differs.
    #[arg(long)]
    pub no_warm_start: bool,
    /// Record the run as a rosbag2 bag (MCAP) in the new directory DIR: the part, every
    /// candidate's verdict (broken window, prefix, learned clause), the plan, the simulated
    /// heat of the build and, with --robot, the motion as the node publishes it.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["all", "count"])]
    pub record: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also print the plan's block lists when they are written to a file (--out, or the
    /// first run without PART); -v does the same.
    #[arg(long)]
    pub print_plan: bool,
    /// --robot and the options of its motion (also recorded with --record).
    #[command(flatten)]
    pub robot: super::motion::OptionalRobotArgs,
    /// Check torch access at every deposit: plans that weld a block after something that
    /// stands in the torch's way are ruled out. The torch is the process settings' (the
    /// bundled typical GMAW torch: a nozzle 18 mm across, its end 12 mm above the bead,
    /// tilted by the travel angle; or --process's). On by default with --robot.
    #[arg(long, conflicts_with = "no_torch")]
    pub torch: bool,
    /// With --robot or the first run (no PART): plan without the torch access check, and keep
    /// only the TCP's path (not the torch's body) clear of the part on moves with the arc off.
    #[arg(long)]
    pub no_torch: bool,
    /// With --robot and --out: also write the motion as a robot program in this format
    /// into DIR (default cell settings; `waam export` takes others).
    #[arg(long, value_name = "FORMAT", requires_all = ["robot", "out"], value_parser = super::export::format_parser())]
    pub export: Option<waam_export::Format>,
}

impl PlanArgs {
    /// No PART and nothing that asks for the plain planner: the first run's whole chain.
    pub fn is_first_run(&self) -> bool {
        self.part.is_none()
            && !self.json
            && !self.count
            && !self.all
            && self.record.is_none()
            && self.robot.robot.is_none()
    }
}

/// The torch the planner checks: with --robot the process settings' (unless --no-torch),
/// with --torch the process settings' or the bundled ones', else none.
pub fn torch(args: &PlanArgs, settings: Option<&ProcessSettings>) -> Option<TorchSetup> {
    if args.no_torch || !(args.torch || args.robot.robot.is_some()) {
        return None;
    }
    match settings {
        Some(s) => s.torch_setup(),
        None => ProcessSettings::default().torch_setup(),
    }
}

/// The planner options of the command line (without the torch: see [`torch`]).
pub fn options(args: &PlanArgs) -> anyhow::Result<Options> {
    Ok(Options {
        acyclicity: args.acyclicity,
        lookahead_budget: if args.no_shortening {
            0
        } else {
            Options::default().lookahead_budget
        },
        timeout: super::timeout_arg(args.timeout)?,
        max_fragments: args.max_fragments,
        cancel: None,
        solver: args.solver,
        torch: None,
        warm_start: !args.no_warm_start,
        executed: None,
        max_memory_mb: args.max_memory_mb,
        threads: args.threads.unwrap_or(0),
    })
}

pub fn run(args: PlanArgs, global: &GlobalArgs) -> anyhow::Result<ExitCode> {
    let started = std::time::Instant::now();
    // One run, then the process ends: a solver stopped by --timeout is not freed first.
    planner::cadical::leave_stopped_solvers_to_exit();
    let mut opts = options(&args)?;
    let deadline = opts.timeout.and_then(|t| started.checked_add(t));
    // Ctrl-C (or SIGTERM) stops the search as the timeout does: the best plan found so far
    // is still reported, written and recorded, and the exit code says it was interrupted.
    let stop = super::node::stop_on_signal()?;
    opts.cancel = Some(Arc::clone(&stop));
    let part = match &args.part {
        // Reading counts against --timeout: a block list of a million blocks takes seconds.
        Some(path) => {
            let (mesh, path) = (args.mesh.clone(), path.clone());
            let what = format!("reading {}", path.display());
            super::within(opts.timeout, &what, move || mesh.read_part_or_mesh(&path))?
        }
        None => Part::parse(super::DEFAULT_PART).context("the bundled sample part")?,
    };
    opts.timeout = opts.timeout.map(|t| t.saturating_sub(started.elapsed()));
    // The robot before planning: a bad URDF fails at once, not after the search.
    // --no-torch: nor along the moves.
    let robot = args
        .robot
        .robot_args()
        .map(|a| a.load_cell(args.no_torch))
        .transpose()?;
    // The pipeline checks the cell's torch (the same) and, with a robot, every candidate
    // on the robot's time line (learned from like a violation).
    opts.torch = torch(&args, robot.as_ref().map(|c| &c.settings));
    if !args.json && !global.quiet {
        eprintln!(
            "part {:?}: {} blocks, {} layers, max_fragments {}, {} windowed blocks",
            part.name,
            part.len(),
            part.layers(),
            opts.max_fragments.unwrap_or(part.max_fragments),
            part.windows().len()
        );
    }
    if let (Some(t), false) = (&opts.torch, args.json || global.quiet) {
        eprintln!("torch access checked: {}", t.describe());
    }
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    // The URDF as recorded on /robot_description.
    let urdf_text = match &args.record {
        Some(_) => record::urdf_text(args.robot.robot.as_deref())?,
        None => None,
    };
    let mut session = match &args.record {
        Some(dir) => Some(record::start_planning(
            dir,
            args.part.as_deref(),
            &part,
            &opts,
            robot.as_ref().zip(urdf_text.as_deref()),
        )?),
        None => None,
    };
    let mut bar = LazyBar::new(global.quiet || args.json);
    let mut progress = |event: planner::Event| {
        bar.update(event.stats());
        if let Some((_, planning)) = session.as_mut() {
            planning.on_event(&event);
        }
    };
    // Counting and enumerating with a robot check its torch and its time line too.
    let searched = waam_pipeline::planner_options(&part, robot.as_ref(), &opts);
    if args.count {
        let counts = planner::count(&part, &searched, true, &mut progress)?;
        bar.finish();
        if args.json {
            println!(
                "{}",
                json!({"part": part.name, "plans": counts.plans, "feasible": counts.feasible,
                       "complete": counts.complete, "stats": counts.stats})
            );
        } else {
            let note = if counts.complete {
                ""
            } else {
                " (timeout: counts are lower bounds)"
            };
            println!("plans: {}{note}", counts.plans.unwrap_or(0));
            println!("feasible: {}{note}", counts.feasible);
            print_stats(&counts.stats);
        }
        return Ok(ExitCode::from(EXIT_OK));
    }
    if args.all {
        let mut writer: Box<dyn Write> = match &args.out {
            Some(dir) => {
                let path = dir.join("feasible-plans.yaml");
                Box::new(std::io::BufWriter::new(
                    std::fs::File::create(&path)
                        .with_context(|| format!("cannot create {}", path.display()))?,
                ))
            }
            None => Box::new(std::io::stdout().lock()),
        };
        let mut sink = |fragments: &[Vec<usize>]| {
            writeln!(writer, "---")?;
            write!(writer, "{}", Plan::from_indices(&part, fragments).to_yaml())
        };
        let counts = planner::enumerate(&part, &searched, &mut progress, &mut sink)?;
        writer.flush()?;
        bar.finish();
        if args.json {
            println!(
                "{}",
                json!({"part": part.name, "feasible": counts.feasible, "complete": counts.complete,
                       "stats": counts.stats})
            );
        } else {
            let note = if counts.complete {
                ""
            } else {
                " (timeout: not all were found)"
            };
            eprintln!("feasible plans: {}{note}", counts.feasible);
            if !global.quiet {
                print_stats(&counts.stats);
            }
        }
        return Ok(ExitCode::from(EXIT_OK));
    }
    let pipeline = waam_pipeline::Options {
        planner: opts,
        objective: if args.first {
            Objective::First
        } else {
            Objective::Best
        },
        // The motion counts against --timeout and stops on Ctrl-C like the search.
        motion: Interrupt {
            deadline,
            cancel: Some(Arc::clone(&stop)),
        },
    };
    let outcome = waam_pipeline::plan(&part, robot.as_ref(), &pipeline, &mut |p| {
        if let Progress::Planner(event) = p {
            progress(event);
        }
    })?;
    let report = outcome.report;
    bar.finish();
    if let (Some(dir), Some(best)) = (&args.out, &report.best) {
        let path = dir.join("plan.yaml");
        std::fs::write(&path, best.plan(&part).to_yaml())
            .with_context(|| format!("cannot write {}", path.display()))?;
        // A graph part's plan names its nodes: the part (sliced here from a mesh, perhaps)
        // goes beside it, so that `waam check DIR/part.yaml DIR/plan.yaml` reads both.
        if let Some(beads) = part.bead_part() {
            let path = dir.join("part.yaml");
            std::fs::write(&path, beads.to_yaml())
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
        // Without a robot the torch poses are still written, in the part frame (the
        // mesh's coordinates), for `waam export DIR --format gcode` and `waam plot`; with
        // one, the validated motion below writes them in its base link.
        if robot.is_none() {
            write_part_frame_toolpath(dir, &part, &best.fragments, global.quiet || args.json)?;
        }
    }
    // The motion is planned only for a feasible plan, and only a validated one is written
    // or recorded.
    let mut motion_ok = true;
    let mut planned = None;
    if let (Some(cell), Some(motion)) = (&robot, outcome.motion) {
        match motion {
            Ok(p) => {
                super::motion::report_motion(&p.toolpath, &p.trajectory, args.out.as_deref())?;
                if let (Some(format), Some(dir)) = (args.export, &args.out) {
                    println!("{}", super::export::export_default(dir, format, cell)?);
                }
                planned = Some(p);
            }
            Err(e) => {
                println!("NO MOTION: {e}");
                motion_ok = false;
            }
        }
    }
    if let Some((recorder, planning)) = session {
        let messages = planned.as_ref().map(record::plan_messages).transpose()?;
        let summary =
            record::finish_planning(recorder, planning, &part, &report, messages.as_ref())?;
        tracing::info!(
            "recorded {} messages on {} topics to {}",
            summary.messages,
            summary.topics,
            summary.dir.display()
        );
    }
    let interrupted = stop.load(Ordering::Relaxed);
    let proof = match (&report.best, report.proven, args.first, interrupted) {
        (Some(_), true, false, _) => "optimal (proven)",
        (Some(_), true, true, _) => "first found (not optimized)",
        (Some(_), false, _, true) => "best found before Ctrl-C (optimality NOT proven)",
        (Some(_), false, _, false) => "best found before the timeout (optimality NOT proven)",
        (None, true, _, _) => "no feasible plan (proven)",
        (None, false, _, true) => "none found before Ctrl-C (infeasibility NOT proven)",
        (None, false, _, false) => "none found before the timeout (infeasibility NOT proven)",
    };
    if args.json {
        let plan = report.best.as_ref().map(|b| {
            let p = b.plan(&part);
            // A graph plan names node ids, a cube plan blocks.
            let fragments = match &p.nodes {
                Some(nodes) => json!(nodes),
                None => json!(p.fragments),
            };
            json!({"fragments": fragments, "margin_s": finite_or_null(b.margin)})
        });
        println!(
            "{}",
            json!({"part": part.name, "found": report.best.is_some(), "proven": report.proven,
                   "result": proof, "plan": plan, "no_plan": report.no_plan,
                   "no_plan_reason": report.no_plan.as_ref().map(|r| r.to_string()),
                   "stats": report.stats})
        );
    } else {
        match &report.best {
            Some(best) => {
                let plan = best.plan(&part);
                println!(
                    "plan: {} fragment(s), worst-case t8/5 margin {} — {proof}",
                    plan.fragments.len(),
                    best.margin_text()
                );
                // Written to a file: the block lists only on request.
                if args.out.is_none() || args.print_plan || global.verbose > 0 {
                    print!("{}", plan.to_yaml());
                } else if let Some(dir) = &args.out {
                    println!("wrote {}", dir.join("plan.yaml").display());
                }
            }
            None => match &report.no_plan {
                Some(reason) => println!("NO PLAN: {reason}"),
                None => println!("NO PLAN: {proof}"),
            },
        }
        if !global.quiet {
            print_stats(&report.stats);
        }
    }
    let ok = report.best.is_some() && motion_ok;
    Ok(ExitCode::from(match (interrupted, ok) {
        (true, _) => EXIT_INTERRUPTED,
        (false, true) => EXIT_OK,
        (false, false) => EXIT_NO,
    }))
}

/// Writes `dir/toolpath.yaml`: the plan's torch poses in the part frame, with the bundled
/// process settings. A toolpath that cannot be built (over the pose budget) is reported
/// and left out: the plan stands.
fn write_part_frame_toolpath(
    dir: &std::path::Path,
    part: &Part,
    fragments: &[Vec<usize>],
    quiet: bool,
) -> anyhow::Result<()> {
    let settings = ProcessSettings::default();
    match toolpath_of_plan(part, fragments, &settings, ToolpathFrame::Part) {
        Ok(tp) => {
            let path = dir.join("toolpath.yaml");
            std::fs::write(&path, tp.to_yaml())
                .with_context(|| format!("cannot write {}", path.display()))?;
            if !quiet {
                eprintln!(
                    "toolpath: {} poses in the part frame, wrote {}",
                    tp.poses.len(),
                    path.display()
                );
            }
        }
        Err(e) => eprintln!("warning: no toolpath.yaml: {e}"),
    }
    Ok(())
}

fn finite_or_null(x: f64) -> serde_json::Value {
    if x.is_finite() {
        json!(x)
    } else {
        serde_json::Value::Null
    }
}

fn print_stats(s: &Stats) {
    let mut first = s
        .first_feasible_s
        .map_or("-".to_string(), |t| format!("{t:.4} s"));
    if let Some(racer) = &s.first_plan_racer {
        first.push_str(&format!(
            " (racer: {racer}, {} racer(s) started)",
            s.racers_started
        ));
    }
    if s.torch_blocked > 0 {
        eprintln!(
            "torch: {} of the candidates weld a block the torch cannot reach",
            s.torch_blocked
        );
    }
    if s.executed_rejected > 0 {
        eprintln!(
            "robot: {} of the candidates fail on the time line the robot welds them on \
             (a transit too slow for transit_time_s, or a window broken by the dwells)",
            s.executed_rejected
        );
    }
    eprintln!(
        "stats: {} candidates, {} feasible, first feasible {first}, total {:.4} s \
         (encode {:.4} s, SAT {:.4} s, acyclicity {:.4} s [{} cuts], simulator {:.4} s, \
         clause shortening {:.4} s)",
        s.candidates,
        s.feasible,
        s.total_s,
        s.encode_s,
        s.sat_s,
        s.acyclicity_s,
        s.cycle_cuts,
        s.simulator_s,
        s.lookahead_s
    );
    if let (Some(min), Some(max), Some(mean)) =
        (s.clause_len_min, s.clause_len_max, s.clause_len_mean)
    {
        eprintln!(
            "learned clauses: {} of length {min} / {max} / {mean:.1} (min / max / mean), \
             {} decisions dropped by proof; encoding {} variables, {} clauses",
            s.learned_clauses, s.shortened, s.variables, s.clauses
        );
    }
    if s.candidates > 0 {
        eprintln!(
            "simulation: {} deposits simulated, {} resumed from saved prefixes, {} cooldown steps; \
             inside the search: {} deposits simulated, {} confirmed again, {} cooldowns that \
             judged a complete plan",
            s.deposits_simulated,
            s.deposits_reused,
            s.cooldown_steps,
            s.inside_deposits,
            s.inside_reused,
            s.cooled_inside
        );
    }
}

/// A progress spinner that appears only once a run has taken more than a second.
pub struct LazyBar {
    quiet: bool,
    started: Instant,
    bar: Option<ProgressBar>,
}

impl LazyBar {
    pub fn new(quiet: bool) -> LazyBar {
        LazyBar {
            quiet,
            started: Instant::now(),
            bar: None,
        }
    }

    pub fn update(&mut self, s: &Stats) {
        if self.quiet || self.started.elapsed() < Duration::from_secs(1) {
            return;
        }
        let bar = self.bar.get_or_insert_with(|| {
            let bar = ProgressBar::new_spinner();
            bar.set_style(
                ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
                    .expect("a valid template"),
            );
            bar.enable_steady_tick(Duration::from_millis(120));
            bar
        });
        let best = match (s.feasible, s.best_margin_s) {
            (0, _) => "no feasible plan yet".to_string(),
            (_, Some(m)) => format!("best margin {m:.2} s"),
            (_, None) => "a feasible plan".to_string(),
        };
        let torch = if s.torch_blocked > 0 {
            format!(", {} torch-blocked", s.torch_blocked)
        } else {
            String::new()
        };
        bar.set_message(format!(
            "{} candidates, {} feasible{torch}, {} learned clauses, {} cycle cuts; {best}",
            s.candidates, s.feasible, s.learned_clauses, s.cycle_cuts
        ));
    }

    pub fn finish(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}
