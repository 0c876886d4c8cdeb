//! A simulated WAAM cell (issue #31): it executes a plan deposit by deposit against a
//! *true* model that differs from the planner's ([`Truth`]: other thermal constants, a
//! deposit height factor, weld paths cut short), measures after every weld path and every
//! layer, and — in closed loop — estimates the thermal model from the measurements,
//! re-plans the rest ([`waam_planner::plan_rest`]) and sets each layer's wire feed so the
//! height returns to nominal. Everything that happened is an [`Executed`] record.
//!
//! Modules: `truth.rs` (TRUTH.yaml, sensor noise), `estimate.rs` (the model fit),
//! `executed.rs` (executed.yaml and its re-simulation), `measured.rs` (sensor readings as
//! the node passes them on); the loop and the height rule here.

pub mod estimate;
pub mod executed;
pub mod measured;
pub mod truth;

use std::sync::atomic::Ordering;
use std::time::Instant;

use thiserror::Error;

use waam_part::graph::WeldGraph;
use waam_part::{Block, Part};
use waam_planner::{self as planner, Built, Options, PlanError, RestError};
use waam_thermal::{Simulation, ThermalModel};

pub use estimate::{Estimate, Measurement};
pub use executed::{CheckError, Deposit, EstimateRecord, Executed, LayerRecord, PlanUsed};
pub use measured::Measured;
pub use truth::{CutShort, Noise, Truth, TruthError};

/// How the cell runs.
#[derive(Debug, Clone)]
pub struct CellOptions {
    /// Measure, estimate, re-plan and control the height (false: execute the first plan
    /// as it is, resuming a path cut short where it stopped).
    pub closed_loop: bool,
    /// The planner's options (the first plan and every re-plan; its timeout applies to
    /// each, its cancel flag stops the whole run).
    pub planner: Options,
    /// The wire feed the height controller may set, relative to nominal (process limits).
    pub wire_feed: (f64, f64),
}

impl Default for CellOptions {
    fn default() -> Self {
        CellOptions {
            closed_loop: true,
            planner: Options::default(),
            wire_feed: (0.7, 1.3),
        }
    }
}

/// Why the cell could not run.
#[derive(Debug, Error)]
pub enum CellError {
    #[error("the simulated cell takes block parts (a graph part has no block layers to scan)")]
    GraphPart,
    #[error("planning the part: {0}")]
    Plan(#[from] PlanError),
    #[error("re-planning the rest: {0}")]
    Rest(#[from] RestError),
    #[error("no plan to execute: {0}")]
    NoPlan(String),
}

/// What the cell tells its caller as it runs (one line each).
pub type Progress<'a> = &'a mut dyn FnMut(&str);

/// The deposit sequence of a plan, as (block, begins a weld path).
fn sequence(plan: &[Vec<usize>]) -> Vec<(usize, bool)> {
    plan.iter()
        .flat_map(|f| f.iter().enumerate().map(|(p, &b)| (b, p == 0)))
        .collect()
}

/// Fragments of a deposit sequence (the first one may continue a weld path in progress).
fn split(seq: &[(usize, bool)]) -> Vec<Vec<usize>> {
    let mut out: Vec<Vec<usize>> = Vec::new();
    for &(b, new) in seq {
        match out.last_mut() {
            Some(f) if !new => f.push(b),
            _ => out.push(vec![b]),
        }
    }
    out
}

/// The height rule: deposit height is proportional to wire feed at a fixed travel speed
/// (the bead's cross-section is the wire volume fed per length of path). After each layer
/// the cell knows the height still missing, `missing` (nominal top so far minus measured
/// top, mm), and the last layer's gain `gain` (measured height per nominal height at the
/// wire feed it got); the next layer gets the wire feed that makes it `nominal + missing`
/// high at that gain, within the process limits.
pub fn next_wire_feed(nominal_mm: f64, missing_mm: f64, gain: f64, limits: (f64, f64)) -> f64 {
    if !(gain.is_finite() && gain > 0.0) {
        return 1.0;
    }
    ((nominal_mm + missing_mm) / (nominal_mm * gain)).clamp(limits.0, limits.1)
}

/// Executes `part` on the true cell `truth`.
pub fn run(
    part: &Part,
    truth: &Truth,
    opts: &CellOptions,
    progress: Progress,
) -> Result<Executed, CellError> {
    if part.bead_part().is_some() {
        return Err(CellError::GraphPart);
    }
    let started = Instant::now();
    let first = planner::plan(part, &opts.planner, &mut |_| {})?;
    let Some(found) = first.best else {
        let why = first
            .no_plan
            .map_or("the planner stopped before a plan".to_string(), |n| {
                n.to_string()
            });
        return Err(CellError::NoPlan(why));
    };
    progress(&format!(
        "planned: {} weld path(s), margin {} ({:.2} s)",
        found.fragments.len(),
        found.margin_text(),
        started.elapsed().as_secs_f64()
    ));
    let graph = WeldGraph::new(part);
    let nominal_h = part.block_mm[2];
    let blocks = |b: &[usize]| -> Vec<Block> { b.iter().map(|&i| part.block(i)).collect() };
    let mut out = Executed {
        part: part.name.clone(),
        loop_mode: if opts.closed_loop { "closed" } else { "open" }.into(),
        deposits: Vec::new(),
        plans: vec![PlanUsed {
            at_deposit: 0,
            at_s: 0.0,
            reason: "initial".into(),
            latency_s: started.elapsed().as_secs_f64(),
            continues: false,
            remainder: found.fragments.iter().map(|f| blocks(f)).collect(),
        }],
        estimates: Vec::new(),
        layers: Vec::new(),
        top_mm: 0.0,
        nominal_top_mm: part.layers() as f64 * nominal_h,
        complete: false,
    };
    // The true cell's heat, run through every window (its verdicts come from
    // `Executed::check` on the executed time line).
    let truth_part = estimate::counting_part(part, truth.thermal);
    let truth_model = ThermalModel::new(&truth_part, &graph);
    let mut sim = Simulation::new(&truth_model).with_threads(1);
    let mut noise = Noise::new(truth.seed, truth.noise_c);
    let mut seq = sequence(&found.fragments);
    let mut executed: Vec<(usize, bool)> = Vec::new();
    let mut measurements: Vec<Measurement> = Vec::new();
    let layers = part.layers().max(0) as usize;
    let mut left_in_layer = vec![0usize; layers];
    for i in 0..part.len() {
        left_in_layer[part.block(i)[2] as usize] += 1;
    }
    // Per layer: heights deposited so far and the wire feed it was given.
    let mut layer_heights: Vec<Vec<f64>> = vec![Vec::new(); layers];
    let mut layer_feed: Vec<Option<f64>> = vec![None; layers];
    let (mut missing_mm, mut gain) = (0.0f64, 1.0f64);
    let (mut path, mut in_path, mut faults) = (0usize, 0usize, 0usize);
    let mut i = 0;
    while i < seq.len() {
        if opts
            .planner
            .cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
        {
            progress("stopped");
            return Ok(out);
        }
        let (b, new) = seq[i];
        if new {
            path += 1;
            in_path = 0;
        }
        let z = part.block(b)[2] as usize;
        let feed = *layer_feed[z].get_or_insert_with(|| {
            if opts.closed_loop {
                next_wire_feed(nominal_h, missing_mm, gain, opts.wire_feed)
            } else {
                1.0
            }
        });
        if new {
            sim.transit().expect("windows widened: no violation");
        }
        let start_s = sim.time_s();
        if new {
            sim.deposit_after_transit(b)
        } else {
            sim.deposit(b, false)
        }
        .expect("windows widened: no violation");
        let height_mm = nominal_h * truth.height_factor * feed;
        out.deposits.push(Deposit {
            block: part.block(b),
            start_s,
            duration_s: sim.time_s() - start_s,
            height_mm,
            arc_start: new,
            wire_feed: feed,
        });
        executed.push((b, new));
        layer_heights[z].push(height_mm);
        left_in_layer[z] -= 1;
        in_path += 1;
        i += 1;
        let layer_done = left_in_layer[z] == 0;
        if layer_done {
            // The scan: the layer's mean height.
            let h = layer_heights[z].iter().sum::<f64>() / layer_heights[z].len() as f64;
            missing_mm += nominal_h - h;
            gain = h / (nominal_h * feed);
            out.layers.push(LayerRecord {
                z: z as i64,
                nominal_mm: nominal_h,
                height_mm: h,
                wire_feed: feed,
            });
        }
        if i == seq.len() {
            break;
        }
        // A wire fault ends the path here: it goes on (if at all) with a new arc start.
        let fault = truth.cut_after(path) == Some(in_path) && !seq[i].1;
        if fault {
            faults += 1;
            seq[i].1 = true;
            progress(&format!(
                "weld path {path} cut short after {in_path} deposits (t = {:.1} s)",
                sim.time_s()
            ));
        }
        let path_end = seq[i].1;
        if !(opts.closed_loop && (path_end || layer_done)) {
            continue;
        }
        // Measure the true temperatures of the welded blocks, then estimate and re-plan.
        measurements.push(Measurement {
            deposits: executed.len(),
            temperatures: sim
                .temperatures()
                .map(|(b, t)| (b, t + noise.sample()))
                .collect(),
        });
        let t = Instant::now();
        let est = estimate::fit(part, part.thermal, &executed, &measurements);
        out.estimates.push(EstimateRecord {
            at_deposit: executed.len(),
            at_s: sim.time_s(),
            loss_factor: est.loss,
            conduction_factor: est.conduction,
            rmse_before_c: est.rmse_before_c,
            rmse_after_c: est.rmse_after_c,
            latency_s: t.elapsed().as_secs_f64(),
        });
        let built = Built {
            state: estimate::state(part, est.params, &executed),
            open: !path_end,
        };
        let mut model_part = part.clone();
        model_part.thermal = est.params;
        let rest_opts = Options {
            max_fragments: Some(opts.planner.max_fragments.unwrap_or(part.max_fragments) + faults),
            ..opts.planner.clone()
        };
        let t = Instant::now();
        let report = planner::plan_rest(&model_part, &built, &rest_opts, &mut |_| {})?;
        let latency_s = t.elapsed().as_secs_f64();
        let (reason, whole) = match report.best {
            Some(f) => (
                if fault { "fault" } else { "replan" },
                sequence(&f.fragments),
            ),
            None => ("kept", seq.clone()),
        };
        debug_assert_eq!(whole[..executed.len()], executed[..]);
        let changed = whole[executed.len()..] != seq[executed.len()..];
        // The new remainder takes over here, at a weld-path or layer boundary.
        seq = whole;
        let remainder: Vec<Vec<Block>> = split(&seq[executed.len()..])
            .iter()
            .map(|f| blocks(f))
            .collect();
        if reason != "replan" || changed {
            progress(&format!(
                "{reason} after {} deposits: loss x{:.3}, conduction x{:.3} (rms {:.1} -> {:.1} °C), plan {:.3} s",
                executed.len(),
                est.loss,
                est.conduction,
                est.rmse_before_c,
                est.rmse_after_c,
                latency_s
            ));
        }
        out.plans.push(PlanUsed {
            at_deposit: executed.len(),
            at_s: sim.time_s(),
            reason: reason.into(),
            latency_s,
            continues: !seq[executed.len()].1,
            remainder,
        });
    }
    out.top_mm = out.layers.iter().map(|l| l.height_mm).sum();
    out.complete = true;
    Ok(out)
}
