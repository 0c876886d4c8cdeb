//! `waam layer …`: thick-wall layers welded as one trail under a finite-element heat model.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::{Args, Subcommand};
use waam_layer::part::{PartManifest, PartOptions};
use waam_layer::slice::{stl_text, LayerParams};
use waam_layer::{search, Layer, Model, SearchOptions, SearchResult};
use waam_messages::layer::{no_motion_status, planned_status};
use waam_plot::layer::{plot_temperature, plot_trail, TEMPERATURE_SIZE, TRAIL_SIZE};
use waam_ros::node::once::publish_once;
use waam_ros::node::params::TopicParams;
use waam_wall::layer::{plan_layer, read_layer, read_layer_dir, LayerInput, LayerRun};
use waam_wall::{plan_part_to_dir, slice_to_dir, LayerDone, PartRun};

use super::motion::{print_motion, MotionSummary};
use super::{EXIT_NO, EXIT_OK};

/// Plan, draw and benchmark weld trails for layers of walls (see docs/layer-format.md).
#[derive(Debug, Args)]
pub struct LayerArgs {
    #[command(subcommand)]
    pub command: LayerCommand,
}

#[derive(Debug, Subcommand)]
pub enum LayerCommand {
    Plan(PlanArgs),
    Slice(SliceArgs),
    PlanPart(PlanPartArgs),
    Extrude(ExtrudeArgs),
    Plot(PlotArgs),
    Bench(BenchArgs),
}

/// Cut a part (an STL mesh of thick walls) into horizontal layers and write each layer's
/// walls as a layer graph: nodes at wall crossings and dead ends, segments along the wall
/// centre lines, the wall width measured from the section.
///
/// Layer k is cut at z_min + (k + 1/2) x --layer-height and written as DIR/layer-KKK.yaml,
/// with DIR/part.yaml listing the layers and their heights (the input of `waam layer
/// plan-part DIR`). A section that is not a wall structure (an open outline, a region wider
/// than 1.5 wall widths, walls of different widths, walls the layer format refuses) stops
/// the run with an error naming its height and place (exit 2). See docs/layer-format.md.
#[derive(Debug, Args)]
pub struct SliceArgs {
    /// The part: an STL file (binary or ASCII), millimetres.
    pub mesh: PathBuf,
    /// Layer height (mm).
    #[arg(long, value_name = "MM")]
    pub layer_height: f64,
    /// The wall width the part was designed with (mm); default: measured (the
    /// length-weighted median distance between facing sides of the outline).
    #[arg(long, value_name = "MM")]
    pub wall_width: Option<f64>,
    /// Take process, material, temperature and torch parameters from this layer file
    /// (default: those of config/layers/paper-16mm.yaml).
    #[arg(long, value_name = "LAYER")]
    pub params: Option<PathBuf>,
    /// The directory to write the layer files and part.yaml into (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

/// Plan every layer of a part, bottom up, each starting from the heat the layer below
/// left: the field at the end of a layer cools for --interlayer seconds and becomes the
/// initial field of the layer above. Consecutive layers do not start at the same place and
/// do not deadhead between the same two places.
///
/// PART is a directory written by `waam layer slice` (with part.yaml) or an STL mesh (then
/// sliced first, with --layer-height and --wall-width). Writes OUT/part-plan.yaml (every
/// layer's objective, gap, start, deadheading and carried heat) and OUT/layer-KKK/ with
/// layer.yaml and trail.yaml (for `waam layer plot`), and with --robot toolpath.yaml and
/// trajectory.yaml: every layer through the same motion pipeline as `waam layer plan`,
/// welded at the layer's height, the arc off on every deadheading move.
///
/// Exit code 0: every layer has a trail (and, with --robot, a validated motion); 1: NO
/// MOTION for some layer; 2: bad input.
#[derive(Debug, Args)]
pub struct PlanPartArgs {
    /// A sliced part directory (part.yaml) or an STL mesh.
    pub part: PathBuf,
    /// The directory for the results (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// With an STL PART: the layer height (mm).
    #[arg(long, value_name = "MM")]
    pub layer_height: Option<f64>,
    /// With an STL PART: the wall width (mm); default measured.
    #[arg(long, value_name = "MM")]
    pub wall_width: Option<f64>,
    /// Seconds with the arc off between the end of a layer's horizon and the next layer
    /// (in the heat model's time; its Robin loss stands for conduction into the part).
    #[arg(long, value_name = "S", default_value_t = 2.0)]
    pub interlayer: f64,
    /// Search time limit per layer (s): the best trail found and its proven gap.
    #[arg(long, value_name = "S", default_value_t = 10.0)]
    pub time_limit: f64,
    /// Refuse a layer whose search would need more memory than this (MB, as `layer plan`).
    #[arg(long, value_name = "MB", default_value_t = waam_layer::search::DEFAULT_MAX_MEMORY_MB)]
    pub max_memory_mb: u64,
    /// Allow a layer to start, and deadhead, where the layer below did.
    #[arg(long)]
    pub no_vary: bool,
    #[command(flatten, next_help_heading = "Robot motion")]
    pub robot: super::motion::OptionalRobotArgs,
    /// Record the run as one rosbag2 bag (MCAP) in the new directory DIR: per layer, as
    /// `waam layer plan --record` does (document, statuses, motion, temperature field).
    #[arg(long, value_name = "DIR", help_heading = "Recording and ROS 2")]
    pub record: Option<PathBuf>,
}

/// Write a layer's walls extruded to a given height as an ASCII STL: a test part whose
/// sections are the layer (used to make config/rib-web-3x3.stl and config/honeycomb-12.stl).
#[derive(Debug, Args)]
pub struct ExtrudeArgs {
    /// The layer file.
    pub layer: PathBuf,
    /// Height of the part (mm).
    #[arg(long, value_name = "MM")]
    pub height: f64,
    /// The STL file to write.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
}

/// Find the weld trail (segment order, directions, the fewest deadheading moves) that keeps
/// the layer's temperature field closest to its target, and prove it optimal.
///
/// With --robot, the trail then becomes torch poses and a validated joint trajectory, as a
/// block plan does: one weld pass per run, the arc off on every deadheading move, welded at
/// the layer's own process.weld_speed_mm_s (the speed its heat model assumed; the process
/// settings' weld_speed_mm_s is not used). The layer (mm, z = 0) lies on the plate where the
/// process settings put it. --record writes a rosbag2 bag of the run, --publish sends the
/// motion once on ROS 2 as node waam_planner.
///
/// Exit code 0: proven optimal (and, with --robot, a motion planned); 1: time limit reached
/// (best trail and its gap reported) or NO MOTION (the robot cannot weld the trail: the
/// message names the pose and the wall); 2: bad input.
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// The layer file (YAML, docs/layer-format.md).
    pub layer: PathBuf,
    /// Write DIR/trail.yaml (moves, deadheading, torch position per step) and a copy of
    /// the layer as DIR/layer.yaml, for `waam layer plot DIR` or `waam plot DIR`; with
    /// --robot also DIR/toolpath.yaml and DIR/trajectory.yaml.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Stop after this many seconds and return the best trail with its proven gap (no
    /// trail, exit 1, when the limit comes before a first one). Counted from the start:
    /// reading the layer and building its heat model count against it.
    #[arg(long, value_name = "S")]
    pub time_limit: Option<f64>,
    /// Refuse a layer whose search would need more memory than this (MB, estimated from
    /// its mesh nodes, time steps and segments before the search starts).
    #[arg(long, value_name = "MB", default_value_t = waam_layer::search::DEFAULT_MAX_MEMORY_MB)]
    pub max_memory_mb: u64,
    /// Do not prune symmetric trails (slower; for checking).
    #[arg(long)]
    pub no_symmetry: bool,
    #[command(flatten, next_help_heading = "Robot motion")]
    pub robot: super::motion::OptionalRobotArgs,
    /// With --robot and --out: also write the motion as a robot program in this format
    /// into DIR (default cell settings; `waam export` takes others).
    #[arg(long, value_name = "FORMAT", requires_all = ["robot", "out"], conflicts_with = "json", value_parser = super::export::format_parser())]
    pub export: Option<waam_export::Format>,
    /// Record the run as a rosbag2 bag (MCAP) in the new directory DIR: the layer document,
    /// the statuses (objective, proof, gap), the motion's trajectory, poses, path, markers
    /// and weld plan (with --robot) and the temperature field over time.
    #[arg(long, value_name = "DIR", help_heading = "Recording and ROS 2")]
    pub record: Option<PathBuf>,
    /// With --robot: publish the motion once on ROS 2 as node waam_planner, on the node's
    /// topics (Reliable, TransientLocal), like `waam publish`; only a validated motion is
    /// sent (else an ERROR status). Honours ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE.
    #[arg(long, requires = "robot", help_heading = "Recording and ROS 2")]
    pub publish: bool,
    /// With --publish: seconds to keep serving the messages to late subscribers.
    #[arg(
        long,
        value_name = "S",
        default_value_t = 2.0,
        help_heading = "Recording and ROS 2"
    )]
    pub linger: f64,
}

/// Draw DIR/trail.png (the trail over the meshed walls) and DIR/temperature.png (one node's
/// temperature over time) of a directory written by `waam layer plan --out DIR` or of one
/// layer directory of `waam layer plan-part --out OUT` (OUT/layer-KKK).
#[derive(Debug, Args)]
pub struct PlotArgs {
    /// A directory written by `waam layer plan --out DIR`.
    pub dir: PathBuf,
    /// The node whose temperature is drawn: a mesh node index, or a layer node id (its
    /// nearest mesh node). Default: the layer's first node.
    #[arg(long, value_name = "N")]
    pub node: Option<String>,
}

/// Benchmark the search on layer files: time to proven optimum, or the gap at the limit.
///
/// One line per layer: the best objective found, the proven lower bound (at the limit: the
/// least bound of the search nodes still open), the bound at the root (before any
/// branching: what the bound alone proves), whether the optimum is proven, the relative
/// gap, the search nodes evaluated and the seconds taken. Layers run one after another.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Layer files (default: the bundled config/layers/*.yaml).
    pub layers: Vec<PathBuf>,
    /// Time limit per layer in seconds.
    #[arg(long, value_name = "S", default_value_t = 600.0)]
    pub time_limit: f64,
}

pub fn run(args: LayerArgs) -> anyhow::Result<ExitCode> {
    match args.command {
        LayerCommand::Plan(a) => plan(a),
        LayerCommand::Slice(a) => slice(a),
        LayerCommand::PlanPart(a) => plan_part(a),
        LayerCommand::Extrude(a) => extrude(a),
        LayerCommand::Plot(a) => plot(a),
        LayerCommand::Bench(a) => bench(a),
    }
}

fn time_limit(seconds: Option<f64>) -> anyhow::Result<Option<Duration>> {
    seconds
        .map(|s| {
            Duration::try_from_secs_f64(s)
                .map_err(|_| anyhow::anyhow!("--time-limit: {s} is not a number of seconds >= 0"))
        })
        .transpose()
}

fn plan(args: PlanArgs) -> anyhow::Result<ExitCode> {
    let started = Instant::now();
    let limit = time_limit(args.time_limit)?;
    let input = LayerInput::read(&args.layer)?;
    let (model, layer) = (&input.model, &input.model.layer);
    let options = SearchOptions {
        symmetry: !args.no_symmetry,
        max_memory_mb: args.max_memory_mb,
        ..SearchOptions::default()
    };
    waam_layer::search::check_size(model, &options)?;
    anyhow::ensure!(
        args.linger.is_finite() && args.linger >= 0.0,
        "--linger: expected seconds >= 0, got {}",
        args.linger
    );
    // The robot and the recording before the search: bad input fails at once, not after
    // minutes of searching.
    let robot = args.robot.robot_args().map(|a| a.load()).transpose()?;
    let recorder = super::record::layer_recorder(
        args.record.as_deref(),
        args.robot.robot.as_deref(),
        robot.as_ref(),
    )?;
    let run = LayerRun {
        out: args.out.as_deref(),
        options,
        deadline: limit.map(|l| started + l),
        cell: robot.as_ref().map(|cell| (&cell.settings, &cell.robot)),
        recorder: recorder.as_ref(),
    };
    let plan = plan_layer(&input, &run)?;
    let r = &plan.result;
    if !r.found() {
        eprintln!(
            "layer {}: no trail found within --time-limit {} s",
            layer.name,
            args.time_limit.unwrap_or_default()
        );
        return Ok(ExitCode::from(super::EXIT_NO));
    }
    if args.json {
        println!("{}", plan.json(model));
    } else {
        print_result(model, r);
        match &plan.motion {
            None => {}
            Some(Ok((tp, _))) => {
                print_motion(tp, args.out.as_deref());
                if let (Some(format), Some(dir), Some(robot)) = (args.export, &args.out, &robot) {
                    println!("{}", super::export::export_default(dir, format, robot)?);
                }
            }
            Some(Err(e)) => println!("NO MOTION: {e}"),
        }
    }
    if let (Some(frames), Some(recorder)) = (plan.heat_frames, recorder) {
        let summary = recorder.finish()?;
        tracing::info!(
            "recorded {} messages on {} topics ({frames} heat frames) to {}",
            summary.messages,
            summary.topics,
            summary.dir.display()
        );
    }
    if args.publish {
        // Only now: Ctrl-C during the search still ends the process at once.
        let stop = super::node::stop_on_signal()?;
        let status = match &plan.motion {
            Some(Err(e)) => no_motion_status(&e.to_string()),
            _ => planned_status(model, r),
        };
        publish_once(
            &layer.name,
            plan.messages.as_ref(),
            &status,
            &TopicParams::default(),
            Duration::from_secs_f64(args.linger),
            &stop,
        )?;
    }
    Ok(ExitCode::from(
        if r.proven_optimal && !plan.motion_failed() {
            EXIT_OK
        } else {
            EXIT_NO
        },
    ))
}

/// The search's result and the trail as text.
fn print_result(model: &Model, r: &SearchResult) {
    let layer = &model.layer;
    println!(
        "{}: objective {:.6e} K·steps, {} (lower bound {:.6e}, gap {:.3}%)",
        layer.name,
        r.objective,
        if r.proven_optimal {
            "PROVEN OPTIMAL"
        } else {
            "NOT PROVEN (time limit)"
        },
        r.lower_bound,
        100.0 * r.relative_gap
    );
    println!(
        "{} search nodes, {} complete trails, {:.3} s, {} symmetries",
        r.nodes_explored, r.leaves, r.seconds, r.symmetries
    );
    for (k, m) in r.trail.moves.iter().enumerate() {
        let (a, b) = model.ends(m);
        println!(
            "{:>3}. {}{} -> {}",
            k + 1,
            if m.deadhead_before { "(deadhead) " } else { "" },
            layer.nodes[a].id,
            layer.nodes[b].id
        );
    }
}

fn plot(args: PlotArgs) -> anyhow::Result<ExitCode> {
    let [trail_png, temp_png] = plot_dir(&args.dir, args.node.as_deref())?;
    println!("wrote {} and {}", trail_png.display(), temp_png.display());
    Ok(ExitCode::from(EXIT_OK))
}

/// Draws DIR/trail.png and DIR/temperature.png of a directory written by `waam layer plan
/// --out DIR` (for `waam layer plot` and `waam plot`); `node` as `--node` takes it.
pub fn plot_dir(dir: &Path, node: Option<&str>) -> anyhow::Result<[PathBuf; 2]> {
    let (model, trail) = read_layer_dir(dir)?;
    let layer = &model.layer;
    let node = match node {
        None => model.mesh.nearest(layer.point(0)),
        Some(s) => match s.parse::<usize>() {
            Ok(i) => i,
            Err(_) => {
                let v = layer
                    .nodes
                    .iter()
                    .position(|n| n.id == s)
                    .with_context(|| {
                        format!("--node {s}: neither a mesh node index nor a node id of the layer")
                    })?;
                model.mesh.nearest(layer.point(v))
            }
        },
    };
    let trail_png = dir.join("trail.png");
    let temp_png = dir.join("temperature.png");
    plot_trail(&model, &trail, &trail_png, TRAIL_SIZE)?;
    plot_temperature(&model, &trail, node, &temp_png, TEMPERATURE_SIZE)?;
    Ok([trail_png, temp_png])
}

fn bench(args: BenchArgs) -> anyhow::Result<ExitCode> {
    let layers = if args.layers.is_empty() {
        let mut v: Vec<PathBuf> = std::fs::read_dir("config/layers")
            .context(
                "cannot list config/layers (run from the repository root or name layer files)",
            )?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "yaml"))
            .collect();
        v.sort();
        v
    } else {
        args.layers
    };
    let limit = time_limit(Some(args.time_limit))?;
    println!("layer | segments | mesh nodes | steps | deadheads | objective | lower bound | root bound | proven | gap % | nodes | seconds");
    for path in layers {
        let model = LayerInput::read(&path)?.model;
        let layer = &model.layer;
        let r = search(
            &model,
            &SearchOptions {
                time_limit: limit,
                ..SearchOptions::default()
            },
        );
        println!(
            "{} | {} | {} | {} | {} | {:.6e} | {:.6e} | {:.6e} | {} | {:.3} | {} | {:.2}",
            layer.name,
            layer.segments.len(),
            model.mesh.points.len(),
            model.horizon,
            model.deadheads,
            r.objective,
            r.lower_bound,
            r.root_bound,
            r.proven_optimal,
            100.0 * r.relative_gap,
            r.nodes_explored,
            r.seconds
        );
    }
    Ok(ExitCode::from(EXIT_OK))
}

fn slice(args: SliceArgs) -> anyhow::Result<ExitCode> {
    let params = match &args.params {
        Some(p) => LayerParams::of(&read_layer(p)?.1),
        None => LayerParams::default(),
    };
    let (_, layers) = slice_to_dir(
        &args.mesh,
        args.layer_height,
        args.wall_width,
        params,
        &args.out,
    )?;
    for (k, l) in layers.iter().enumerate() {
        println!(
            "layer {k:>3}  z {:>8.3} mm  {:>3} nodes  {:>3} segments  wall {:.3} mm",
            l.z_mm,
            l.layer.nodes.len(),
            l.layer.segments.len(),
            l.layer.wall_width_mm
        );
    }
    println!(
        "wrote {} layers and part.yaml to {}",
        layers.len(),
        args.out.display()
    );
    Ok(ExitCode::from(EXIT_OK))
}

fn extrude(args: ExtrudeArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        args.height.is_finite() && args.height > 0.0,
        "--height: expected a number of mm > 0, got {}",
        args.height
    );
    let (_, layer) = read_layer(&args.layer)?;
    let mesh = waam_layer::slice::extrude(&layer, args.height);
    std::fs::write(&args.out, stl_text(&mesh, &layer.name))
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    println!(
        "wrote {} ({} triangles)",
        args.out.display(),
        mesh.triangles.len()
    );
    Ok(ExitCode::from(EXIT_OK))
}

fn plan_part(args: PlanPartArgs) -> anyhow::Result<ExitCode> {
    let limit = time_limit(Some(args.time_limit))?;
    anyhow::ensure!(
        args.interlayer.is_finite() && args.interlayer >= 0.0,
        "--interlayer: expected seconds >= 0, got {}",
        args.interlayer
    );
    anyhow::ensure!(
        args.part.exists(),
        "cannot read part {}: no such file or directory",
        args.part.display()
    );
    let layers: Vec<(f64, Layer)> = if args.part.is_dir() {
        anyhow::ensure!(
            args.layer_height.is_none() && args.wall_width.is_none(),
            "--layer-height and --wall-width are for an STL part; {} is a sliced part directory",
            args.part.display()
        );
        PartManifest::read_dir(&args.part)?.1
    } else {
        let h = args.layer_height.with_context(|| {
            format!(
                "{} is a mesh: give --layer-height to slice it (or slice it first with `waam layer slice`)",
                args.part.display()
            )
        })?;
        let (_, sliced) = slice_to_dir(
            &args.part,
            h,
            args.wall_width,
            LayerParams::default(),
            &args.out.join("sliced"),
        )?;
        sliced.into_iter().map(|l| (l.z_mm, l.layer)).collect()
    };
    let robot = args.robot.robot_args().map(|a| a.load()).transpose()?;
    // Before the recorder: its bag may go inside OUT.
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let recorder = super::record::layer_recorder(
        args.record.as_deref(),
        args.robot.robot.as_deref(),
        robot.as_ref(),
    )?;
    let options = PartOptions {
        interlayer_s: args.interlayer,
        search: SearchOptions {
            time_limit: limit,
            max_memory_mb: args.max_memory_mb,
            ..SearchOptions::default()
        },
        vary: !args.no_vary,
    };
    let run = PartRun {
        out: &args.out,
        options: &options,
        cell: robot.as_ref().map(|cell| (&cell.settings, &cell.robot)),
        recorder: recorder.as_ref(),
    };
    let plan = plan_part_to_dir(&layers, &run, print_layer_done)?;
    if let Some(recorder) = recorder {
        let s = recorder.finish()?;
        tracing::info!(
            "recorded {} messages on {} topics to {}",
            s.messages,
            s.topics,
            s.dir.display()
        );
    }
    let proven = plan
        .layers
        .iter()
        .filter(|p| p.result.proven_optimal)
        .count();
    println!(
        "planned {} layers ({proven} proven optimal), wrote {}",
        plan.layers.len(),
        plan.path.display()
    );
    Ok(ExitCode::from(if plan.motion_failed {
        EXIT_NO
    } else {
        EXIT_OK
    }))
}

/// One line per planned layer of `waam layer plan-part`.
fn print_layer_done(d: &LayerDone) {
    let (r, line) = (&d.planned.result, d.line);
    println!(
        "layer {:>3}/{}  z {:>7.3} mm  objective {:.6e}  {}  start {}  {} deadheads  initial max {:.0} °C mean {:.0} °C{}",
        d.index + 1,
        d.total,
        line.z_mm,
        r.objective,
        if r.proven_optimal {
            "proven optimal".to_string()
        } else {
            format!("gap {:.2}%", 100.0 * r.relative_gap)
        },
        line.start,
        line.deadheading.len(),
        line.initial_max_c,
        line.initial_mean_c,
        match d.motion {
            None => String::new(),
            Some(Ok((tp, _))) => format!("  motion {:.1} s", MotionSummary::of(tp).duration_s),
            Some(Err(e)) => format!("  NO MOTION: {e}"),
        }
    );
}
