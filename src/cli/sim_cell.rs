//! `waam sim-cell PART --truth TRUTH.yaml [--open-loop] [--robot URDF] --out DIR`: a
//! simulated cell; with `--node`, the same cell's sensors as a ROS 2 node beside `waam node`.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

use anyhow::Context;
use waam_cell::{CellOptions, Truth};
use waam_planner::Options;

use super::{EXIT_INTERRUPTED, EXIT_NO, EXIT_OK};

/// Execute a part on a simulated cell whose true model differs from the planner's.
///
/// The part is planned, then welded deposit by deposit against TRUTH.yaml: other `thermal:`
/// constants, a deposit `height_factor` (or `height_zones` of the part that build low or
/// high), weld paths `cut_short` (wire faults), sensor noise. In closed loop (the default)
/// the cell measures the true temperatures after every weld path and layer, fits the
/// planner model's loss and conduction coefficients to them, re-plans the rest from the
/// estimated state (exactly, like `waam plan`) and sets each deposit's wire feed so the
/// height over it returns to nominal. `--open-loop` executes the first
/// plan as it is. Writes DIR/executed.yaml (every deposit as it happened, the plans used,
/// the estimates, the layer heights: docs/closed-loop.md) and prints the true model's
/// verdict on the executed time line. With `--robot` each deposit is made when the robot's
/// trajectory makes it (its dwells and moves included), each new plan is taken only once
/// its motion is checked as the node checks it, and decisions come at weld-path ends.
///
/// With `--node` it is the true cell's sensors as a ROS 2 node (`waam_sim_cell`) for a
/// `waam node` executing PART (e.g. `waam node --dry-run -p closed_loop.enabled:=true`): it
/// follows the planner's `~/plan/weld_plan`, `~/arc_on`, `~/wire_feed` and
/// `~/wire_feed_schedule` and publishes on the planner's `~/temperature` the true
/// temperature of each deposit and on `~/scan` the true top of each deposit of each
/// finished layer (with --thermal-camera also images on `~/thermal_image`),
/// until Ctrl-C (docs/closed-loop.md).
///
/// Exit code 0: every block deposited and every t8/5 window kept on the true model; 1: a
/// window broke (or no plan); 2: bad input; 130: stopped by Ctrl-C (`--node`: 0).
#[derive(Debug, clap::Args)]
pub struct SimCellArgs {
    /// The part file: a block part (shared part format) or a graph part (`waam slice`).
    pub part: PathBuf,
    /// How the true cell differs: `thermal:` keys, `height_factor`, `cut_short: {path,
    /// after}` (or a list), `sensors: {noise_c, seed}` (docs/closed-loop.md).
    #[arg(long, value_name = "TRUTH.yaml")]
    pub truth: PathBuf,
    /// Execute the first plan as it is: no estimate, no re-plan, nominal wire feed (a path
    /// cut short resumes where it stopped, with a new arc start).
    #[arg(long)]
    pub open_loop: bool,
    #[command(flatten)]
    pub robot: super::motion::OptionalRobotArgs,
    /// The folder to write executed.yaml into (new or empty); not with --node.
    #[arg(
        long,
        value_name = "DIR",
        required_unless_present = "node",
        conflicts_with = "node"
    )]
    pub out: Option<PathBuf>,
    /// Time limit of each plan and re-plan, seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 60.0)]
    pub timeout: f64,
    /// Run as a ROS 2 node: the true cell's pyrometer and layer scanner for a `waam node`
    /// that executes PART.
    #[arg(long, conflicts_with = "open_loop")]
    pub node: bool,
    /// --node: the planner node whose topics are followed, as a name in this node's
    /// namespace [default: waam_planner].
    #[arg(long, value_name = "NAME")]
    pub planner: Option<String>,
    /// --node: how many times as fast as planned the planner executes (its
    /// `dry_run.time_scale`; 1 on a real controller) [default: 1].
    #[arg(long, value_name = "X")]
    pub time_scale: Option<f64>,
    /// --node: also publish a thermal camera's images on the planner's `~/thermal_image`:
    /// with each pyrometer reading, every welded block's true temperature at its centre
    /// (sensor_msgs/PointCloud2 with a `temperature` field, part frame).
    #[arg(long)]
    pub thermal_camera: bool,
    /// --node: ROS 2 arguments as rcl reads them (`-r __ns:=/cell1`, `-r __node:=NAME`).
    #[arg(long = "ros-args", num_args = 0.., allow_hyphen_values = true, value_name = "ARG")]
    pub ros_args: Option<Vec<String>>,
}

impl SimCellArgs {
    /// The first option given that only the node takes, when `--node` is not given (clap's
    /// `requires` counts `--node`'s default, false, as given).
    fn node_option_without_node(&self) -> Option<&'static str> {
        if self.node {
            return None;
        }
        [
            (self.planner.is_some(), "--planner"),
            (self.time_scale.is_some(), "--time-scale"),
            (self.thermal_camera, "--thermal-camera"),
            (self.ros_args.is_some(), "--ros-args"),
        ]
        .into_iter()
        .find_map(|(given, flag)| given.then_some(flag))
    }
}

pub fn run(args: SimCellArgs, global: &super::GlobalArgs) -> anyhow::Result<ExitCode> {
    if let Some(flag) = args.node_option_without_node() {
        anyhow::bail!("{flag} is for the simulated cell's ROS 2 node: give --node with it");
    }
    let part = super::read_part(&args.part)?;
    let text = std::fs::read_to_string(&args.truth)
        .with_context(|| format!("reading {}", args.truth.display()))?;
    let truth =
        Truth::parse(&text, &part).map_err(|e| anyhow::anyhow!("{}: {e}", args.truth.display()))?;
    if args.node {
        if args.robot.robot.is_some() {
            anyhow::bail!(
                "--robot is for the simulated cell without --node: as a node it follows the \
                 planner's trajectory, made for the planner's robot"
            );
        }
        return run_node(&part, &truth, &args);
    }
    // The robot before planning: a bad URDF fails at once.
    let robot = args.robot.robot_args().map(|a| a.load()).transpose()?;
    let dir = super::first_run::output_dir(args.out.as_deref())?;
    let stop = super::node::stop_on_signal()?;
    let opts = CellOptions {
        closed_loop: !args.open_loop,
        planner: Options {
            timeout: super::timeout_arg(Some(args.timeout))?,
            cancel: Some(Arc::clone(&stop)),
            ..Options::default()
        },
        ..CellOptions::default()
    };
    let quiet = global.quiet;
    let mut progress = |line: &str| {
        if !quiet {
            eprintln!("{line}");
        }
    };
    let started = Instant::now();
    let planning = waam_pipeline::Options {
        planner: opts.planner.clone(),
        ..Default::default()
    };
    let first = waam_pipeline::plan(&part, robot.as_ref(), &planning, &mut |_| {})?.report;
    let Some(found) = first.best else {
        let why = first.no_plan.map_or_else(
            || "the planner stopped before a plan".to_string(),
            |n| n.to_string(),
        );
        if stop.load(std::sync::atomic::Ordering::Relaxed) {
            println!("STOPPED before a plan");
            return Ok(ExitCode::from(EXIT_INTERRUPTED));
        }
        println!("NO PLAN to execute: {why}");
        return Ok(ExitCode::from(EXIT_NO));
    };
    let planned_in_s = started.elapsed().as_secs_f64();
    progress(&format!(
        "planned: {} weld path(s), margin {} ({planned_in_s:.2} s)",
        found.fragments.len(),
        found.margin_text(),
    ));
    let timeout = opts.planner.timeout;
    // On a robot: each plan the loop takes timed by its motion (a new one checked first, as
    // the node checks one, within the re-plan's limit).
    let mut timing = robot.as_ref().map(|cell| {
        let (part, stop) = (&part, Arc::clone(&stop));
        move |check: Option<&waam_part::Part>, fragments: &[Vec<usize>]| {
            let times = match check {
                Some(checked) => {
                    let chosen = waam_pipeline::ChosenPlan {
                        fragments: fragments.to_vec(),
                        stats: Default::default(),
                        proven: false,
                        worst_margin_s: f64::NAN,
                    };
                    let interrupt = waam_pipeline::Interrupt::after(timeout)
                        .with_cancel(Some(Arc::clone(&stop)));
                    cell.motion_until(checked.clone(), chosen, &interrupt)
                        .map(|planned| planned.toolpath.executed_times())
                }
                None => cell
                    .plan_motion(part, fragments)
                    .map(|(toolpath, _)| toolpath.executed_times()),
            }
            .map_err(|e| e.to_string())?;
            Ok(waam_cell::PlanTimes {
                deposits_s: times.deposits_s,
                arc_off_s: times.arc_off_s,
            })
        }
    });
    if timing.is_some() {
        progress("robot: each deposit made when its trajectory makes it");
    }
    let executed = waam_cell::run(
        &part,
        &found.fragments,
        planned_in_s,
        &truth,
        &opts,
        &mut progress,
        timing.as_mut().map(|t| t as &mut waam_cell::Timing),
    )?;
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = dir.join("executed.yaml");
    std::fs::write(&path, executed.to_yaml()?)
        .with_context(|| format!("writing {}", path.display()))?;
    if !executed.complete {
        println!(
            "STOPPED after {} deposits; {} written",
            executed.deposits.len(),
            path.display()
        );
        return Ok(ExitCode::from(EXIT_INTERRUPTED));
    }
    let on_truth = executed.check(&part, truth.thermal)?;
    let replans = executed
        .plans
        .iter()
        .filter(|p| p.reason != "initial")
        .count();
    let worst_latency = executed
        .plans
        .iter()
        .skip(1)
        .map(|p| p.latency_s)
        .fold(0.0, f64::max);
    println!(
        "{} loop: {} deposits in {} weld path(s), {:.1} s welding; {} re-plan(s) (slowest {:.3} s)",
        executed.loop_mode,
        executed.deposits.len(),
        executed.deposits.iter().filter(|d| d.arc_start).count(),
        on_truth.time_s,
        replans,
        worst_latency
    );
    if let Some(e) = executed.estimates.last() {
        println!(
            "model: loss x{:.3}, conduction x{:.3}; rms error {:.1} °C before, {:.1} °C after estimation",
            e.loss_factor, e.conduction_factor, e.rmse_before_c, e.rmse_after_c
        );
    }
    println!(
        "height: top {:.2} mm of nominal {:.2} mm ({:+.2} mm){}",
        executed.top_mm,
        executed.nominal_top_mm,
        executed.top_mm - executed.nominal_top_mm,
        if executed.complete {
            String::new()
        } else {
            format!(
                " over the {} layer(s) finished before the stop",
                executed.layers.len()
            )
        }
    );
    if let Some(last) = executed.layers.last() {
        println!(
            "height: the top layer's deposits from {:.2} to {:.2} mm",
            last.tops_mm[0], last.tops_mm[1]
        );
        println!(
            "height error per layer, mm: {}",
            layer_errors(&executed.layers)
        );
    }
    let code = match &on_truth.violation {
        None => {
            println!("TRUE MODEL: every t8/5 window kept");
            EXIT_OK
        }
        Some(v) => {
            println!(
                "TRUE MODEL: window of block {} broken ({:?}, t8/5 {:.2} s, window {}..{} s) at {:.1} s",
                waam_part::BlockDisplay(part.block(v.block)),
                v.kind,
                v.t85_s,
                v.window.min_s,
                v.window.max_s,
                v.time_s
            );
            EXIT_NO
        }
    };
    println!("{} written", path.display());
    Ok(ExitCode::from(code))
}

/// `--node`: the true cell's sensors over ROS 2 until Ctrl-C.
fn run_node(part: &waam_part::Part, truth: &Truth, args: &SimCellArgs) -> anyhow::Result<ExitCode> {
    let time_scale = args.time_scale.unwrap_or(1.0);
    if !(time_scale.is_finite() && time_scale > 0.0) {
        anyhow::bail!("--time-scale: expected a positive number, got {time_scale}");
    }
    let ros = waam_ros::node::args::RosArgs::parse(args.ros_args.as_deref().unwrap_or_default())?;
    let mut names = ros.names();
    if ros.node_name.is_none() {
        names.name = "waam_sim_cell".into();
    }
    let options = waam_ros::sim_cell::SimCellOptions {
        names,
        planner: args
            .planner
            .clone()
            .unwrap_or_else(|| "waam_planner".into()),
        time_scale,
        thermal_camera: args.thermal_camera,
    };
    waam_ros::sim_cell::run(part, truth, &options, super::node::stop_on_signal()?)?;
    Ok(ExitCode::from(EXIT_OK))
}

/// Each layer's height error: its deposits' top furthest from the nominal top (scanned, mm),
/// bottom first; the first and last eight of a taller part.
fn layer_errors(layers: &[waam_cell::executed::LayerRecord]) -> String {
    let error = |l: &waam_cell::executed::LayerRecord| {
        let nominal = l.nominal_mm * (l.z + 1) as f64;
        let [lo, hi] = l.tops_mm.map(|t| t - nominal);
        let e = if lo.abs() > hi.abs() { lo } else { hi };
        format!("{e:+.2}")
    };
    if layers.len() <= 16 {
        return layers.iter().map(error).collect::<Vec<_>>().join(" ");
    }
    let head: Vec<String> = layers[..8].iter().map(error).collect();
    let tail: Vec<String> = layers[layers.len() - 8..].iter().map(error).collect();
    format!("{} … {}", head.join(" "), tail.join(" "))
}
