//! `waam sim-cell PART --truth TRUTH.yaml [--open-loop] --out DIR`: a simulated cell.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::Context;
use waam_cell::{CellOptions, Truth};
use waam_planner::Options;

use super::{EXIT_INTERRUPTED, EXIT_NO, EXIT_OK};

/// Execute a part on a simulated cell whose true model differs from the planner's.
///
/// The part is planned, then welded deposit by deposit against TRUTH.yaml: other `thermal:`
/// constants, a deposit `height_factor`, weld paths `cut_short` (wire faults), sensor
/// noise. In closed loop (the default) the cell measures the true temperatures after every
/// weld path and layer, fits the planner model's loss and conduction coefficients to them,
/// re-plans the rest from the estimated state (exactly, like `waam plan`) and sets each
/// layer's wire feed so the height returns to nominal. `--open-loop` executes the first
/// plan as it is. Writes DIR/executed.yaml (every deposit as it happened, the plans used,
/// the estimates, the layer heights: docs/closed-loop.md) and prints the true model's
/// verdict on the executed time line.
///
/// Exit code 0: every block deposited and every t8/5 window kept on the true model; 1: a
/// window broke (or no plan); 2: bad input; 130: stopped by Ctrl-C.
#[derive(Debug, clap::Args)]
pub struct SimCellArgs {
    /// The part file (block part, shared part format).
    pub part: PathBuf,
    /// How the true cell differs: `thermal:` keys, `height_factor`, `cut_short: {path,
    /// after}` (or a list), `sensors: {noise_c, seed}` (docs/closed-loop.md).
    #[arg(long, value_name = "TRUTH.yaml")]
    pub truth: PathBuf,
    /// Execute the first plan as it is: no estimate, no re-plan, nominal wire feed (a path
    /// cut short resumes where it stopped, with a new arc start).
    #[arg(long)]
    pub open_loop: bool,
    /// The folder to write executed.yaml into (new or empty).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Time limit of each plan and re-plan, seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 60.0)]
    pub timeout: f64,
}

pub fn run(args: SimCellArgs, global: &super::GlobalArgs) -> anyhow::Result<ExitCode> {
    let part = super::read_part(&args.part)?;
    let text = std::fs::read_to_string(&args.truth)
        .with_context(|| format!("reading {}", args.truth.display()))?;
    let truth =
        Truth::parse(&text, &part).map_err(|e| anyhow::anyhow!("{}: {e}", args.truth.display()))?;
    let dir = super::first_run::output_dir(Some(&args.out))?;
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
    let executed = waam_cell::run(&part, &truth, &opts, &mut |line| {
        if !quiet {
            eprintln!("{line}");
        }
    })?;
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
