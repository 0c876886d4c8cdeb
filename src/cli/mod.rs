//! Command-line interface: one module per subcommand.

use std::path::Path;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, Parser, Subcommand};
use waam_part::Part;
use waam_planner::{Acyclicity, Backend};

pub mod bag;
pub mod bench;
pub mod check;
pub mod export;
pub mod first_run;
pub mod layer;
pub mod motion;
pub mod node;
pub mod plan;
pub mod plot;
pub mod publish;
pub mod record;
pub mod replay;
pub mod sim_cell;
pub mod slice;
pub mod voxelize;

/// Exit code of a run whose answer is "yes" (valid and feasible, plan found, ...).
pub const EXIT_OK: u8 = 0;
/// Exit code of a run whose answer is "no" (invalid, infeasible, no plan, a difference).
pub const EXIT_NO: u8 = 1;
/// Exit code of a run that could not give an answer: bad input, unreadable file.
pub const EXIT_BAD_INPUT: u8 = 2;
/// Stopped by Ctrl-C or SIGTERM (128 + SIGINT, as shells report it).
pub const EXIT_INTERRUPTED: u8 = 130;

#[derive(Debug, Parser)]
#[command(
    name = "waam",
    version,
    about = "Plan weld paths for Wire Arc Additive Manufacturing and hand them to a robot cell",
    long_about = "waam plans the weld order of a part built from blocks (or voxelized from an STL \
                  mesh) as at most k weld paths, checks every candidate against the t8/5 cooling \
                  windows of a thermal model, and turns the plan into torch poses and robot \
                  trajectories.\n\nExit codes: 0 = yes (valid, feasible, found), 1 = no (invalid, \
                  infeasible, none found, differs), 2 = bad input."
)]
pub struct Cli {
    #[command(flatten)]
    pub global: GlobalArgs,
    #[command(subcommand)]
    pub command: Command,
}

/// Options every subcommand understands.
#[derive(Debug, Args)]
pub struct GlobalArgs {
    /// Print only the result: no progress bars, no log lines below warnings.
    #[arg(short, long, global = true)]
    pub quiet: bool,
    /// More log output (-v: debug, with the search's own narration; -vv: trace). RUST_LOG
    /// overrides this. Colour only on a terminal, never with NO_COLOR set.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    pub verbose: u8,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    Bag(bag::BagArgs),
    Check(check::CheckArgs),
    Export(export::ExportArgs),
    /// Thick-wall layers: plan, plot and benchmark one weld trail per layer.
    Layer(layer::LayerArgs),
    Plan(plan::PlanArgs),
    Bench(bench::BenchArgs),
    Replay(replay::ReplayArgs),
    Voxelize(voxelize::VoxelizeArgs),
    Slice(slice::SliceArgs),
    Motion(motion::MotionArgs),
    Plot(plot::PlotArgs),
    Node(node::NodeArgs),
    Publish(publish::PublishArgs),
    SimCell(sim_cell::SimCellArgs),
}

/// Runs the chosen subcommand; its `ExitCode` carries the answer.
pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Bag(args) => bag::run(args),
        Command::Check(args) => check::run(args),
        Command::Export(args) => export::run(args),
        Command::Layer(args) => layer::run(args),
        // No PART and nothing that asks for the plain planner: the first run's whole chain.
        Command::Plan(args) if args.is_first_run() => first_run::run(args, &cli.global),
        Command::Plan(args) => plan::run(args, &cli.global),
        Command::Bench(args) => bench::run(args),
        Command::Replay(args) => replay::run(args),
        Command::Voxelize(args) => voxelize::run(args),
        Command::Slice(args) => slice::run(args),
        Command::Motion(args) => motion::run(args),
        Command::Plot(args) => plot::run(args),
        Command::Node(args) => node::run(args),
        Command::Publish(args) => publish::run(args),
        Command::SimCell(args) => sim_cell::run(args, &cli.global),
    }
}

/// clap's parser of the planner's SAT solvers, each listed with its help line.
pub fn solver_parser() -> impl clap::builder::TypedValueParser<Value = Backend> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser as _};
    PossibleValuesParser::new(
        Backend::ALL.map(|(_, name, help)| PossibleValue::new(name).help(help)),
    )
    .map(|name| name.parse().expect("clap accepts only listed names"))
}

/// Reads a part file, logging the reader's warnings.
/// The bundled sample part (`config/parts/ex2-bracket.yaml`), planned when no part is named:
/// a stepped L-bracket wall that the typical torch can weld (the H-column cannot be).
pub const DEFAULT_PART: &str = include_str!("../../config/parts/ex2-bracket.yaml");

/// clap's parser of a count that must be at least 1 (`--max-fragments 0` is bad input,
/// exit 2, not a search that finds no plan).
pub fn at_least_one(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(0) => Err("must be at least 1".into()),
        Ok(n) => Ok(n),
        Err(e) => Err(e.to_string()),
    }
}

/// clap's parser of a thread count: 1 to the planner's [`waam_planner::MAX_THREADS`].
pub fn thread_count(text: &str) -> Result<usize, String> {
    match at_least_one(text)? {
        n if n > waam_planner::MAX_THREADS => Err(format!(
            "must be at most {} (one thread per core is what helps)",
            waam_planner::MAX_THREADS
        )),
        n => Ok(n),
    }
}

/// clap's parser of the planner's acyclicity methods, each listed with its help line.
pub fn acyclicity_parser() -> impl clap::builder::TypedValueParser<Value = Acyclicity> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser as _};
    PossibleValuesParser::new(
        Acyclicity::ALL.map(|(_, name, help)| PossibleValue::new(name).help(help)),
    )
    .map(|name| name.parse().expect("clap accepts only listed names"))
}

/// `--timeout S` as a time limit: seconds >= 0 that fit a `Duration`, else bad input.
pub fn timeout_arg(seconds: Option<f64>) -> anyhow::Result<Option<std::time::Duration>> {
    seconds
        .map(|s| {
            std::time::Duration::try_from_secs_f64(s)
                .map_err(|_| anyhow::anyhow!("--timeout: expected seconds >= 0, got {s}"))
        })
        .transpose()
}

/// Runs `work` on a thread of its own and waits at most `limit` for it: reading a part of
/// a million blocks takes seconds that `--timeout` covers too. Past the limit the thread
/// is left behind; the command ends with the error.
pub fn within<T: Send + 'static>(
    limit: Option<std::time::Duration>,
    what: &str,
    work: impl FnOnce() -> anyhow::Result<T> + Send + 'static,
) -> anyhow::Result<T> {
    use std::sync::mpsc::RecvTimeoutError;
    let Some(limit) = limit else {
        return work();
    };
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(work());
    });
    match rx.recv_timeout(limit) {
        Ok(result) => result,
        Err(RecvTimeoutError::Timeout) => anyhow::bail!(
            "{what}: not done within --timeout {} s",
            limit.as_secs_f64()
        ),
        Err(RecvTimeoutError::Disconnected) => anyhow::bail!("{what}: the reader failed"),
    }
}

/// A part file: a block part, or a graph part (`kind: beads`) in its planning view.
pub fn read_part(path: &Path) -> anyhow::Result<Part> {
    let bytes =
        std::fs::read(path).with_context(|| format!("cannot read part {}", path.display()))?;
    let graph = std::str::from_utf8(&bytes).is_ok_and(waam_part::is_bead_part);
    // No `?` inside: every error gets the file's name.
    let part = if graph {
        waam_part::BeadPart::from_bytes(&bytes)
            .map_err(anyhow::Error::from)
            .and_then(|beads| Part::of_beads(beads).map_err(anyhow::Error::from))
    } else {
        Part::from_bytes(&bytes).map_err(anyhow::Error::from)
    }
    .with_context(|| format!("in part {}", path.display()))?;
    for warning in &part.warnings {
        tracing::warn!("{}: {warning}", path.display());
    }
    Ok(part)
}

/// A plan file of `part` (YAML, or JSON by its `.json` extension or a leading `{`):
/// node ids for a graph part, blocks else. `Ok(Err(rule))`: it reads but breaks a plan
/// rule (INVALID); `Err`: it cannot be read.
pub fn read_plan(part: &Part, path: &Path) -> anyhow::Result<Result<Vec<Vec<usize>>, String>> {
    let bytes =
        std::fs::read(path).with_context(|| format!("cannot read plan {}", path.display()))?;
    let is_json = path.extension().is_some_and(|e| e == "json");
    let in_plan = || format!("in plan {}", path.display());
    Ok(match part.bead_part() {
        Some(beads) => {
            let plan = waam_part::GraphPlan::from_bytes(&bytes, is_json).with_context(in_plan)?;
            plan.validate(beads, &beads.moves())
                .map(|()| plan.fragments)
                .map_err(|e| e.to_string())
        }
        None => {
            let plan = waam_part::plan::Plan::from_bytes(&bytes, is_json).with_context(in_plan)?;
            plan.validate(part, &waam_part::graph::WeldGraph::new(part))
                .map_err(|e| e.to_string())
        }
    })
}

/// Logs go to stderr through `tracing`; `RUST_LOG` wins over `-q` / `-v`.
pub fn init_logging(global: &GlobalArgs) {
    let default = match (global.quiet, global.verbose) {
        (true, _) => "warn",
        (false, 0) => "info",
        (false, 1) => "debug",
        (false, _) => "trace",
    };
    // varisat reports its search progress at info level; RustDDS logs every discovery event
    // at info and every large datagram at warn; ros2-client echoes each /rosout record the
    // node already logged itself.
    let default =
        format!("{default},varisat=warn,rustdds=error,ros2_client=warn,ros2_client::rosout=off");
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(colour_on_stderr())
        .with_target(false)
        .init();
}

/// Colour only on a terminal, and never when `NO_COLOR` is set to anything but the empty
/// string (no-color.org): logs redirected to a file carry no escape codes.
fn colour_on_stderr() -> bool {
    use std::io::IsTerminal;
    let no_color = std::env::var_os("NO_COLOR").is_some_and(|v| !v.is_empty());
    !no_color && std::io::stderr().is_terminal()
}
