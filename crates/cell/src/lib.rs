//! A simulated WAAM cell (issue #31): it executes a plan deposit by deposit against a
//! *true* model that differs from the planner's ([`Truth`]: other thermal constants, a
//! deposit height factor, weld paths cut short), measures after every weld path and every
//! layer, and — in closed loop — estimates the thermal model from the measurements,
//! re-plans the rest ([`waam_planner::plan_rest`]) and sets each deposit's wire feed so the
//! height returns to nominal. Everything that happened is an [`Executed`] record.
//!
//! Modules: `closed_loop.rs` (the loop's decisions, step by step: what this cell and the
//! ROS node drive), `truth.rs` (TRUTH.yaml, sensor noise), `estimate.rs` (the model fit),
//! `executed.rs` (executed.yaml and its re-simulation), `measured.rs` (sensor readings as
//! the node passes them on), `robot.rs` (where a robot makes each deposit, for the cell on
//! a robot); the simulated cell's driver and the height rule here.

pub mod closed_loop;
pub mod estimate;
pub mod executed;
pub mod measured;
mod robot;
pub mod truth;

use std::sync::atomic::Ordering;

use thiserror::Error;

use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_planner::{Options, RestError};
use waam_thermal::{Simulation, ThermalModel};

pub use closed_loop::{ClosedLoop, Decision, LoopOptions, MeasureError};
pub use estimate::{Estimate, Measurement};
pub use executed::{CheckError, Deposit, EstimateRecord, Executed, LayerRecord, PlanUsed};
pub use measured::Measured;
use robot::{retimed, Timed};
pub use robot::{PlanTimes, Timing};
pub use truth::{CutShort, HeightZone, Noise, Truth, TruthError};

/// How the cell runs.
#[derive(Debug, Clone)]
pub struct CellOptions {
    /// Measure, estimate, re-plan and control the height (false: execute the first plan
    /// as it is, resuming a path cut short where it stopped).
    pub closed_loop: bool,
    /// The planner's options of every re-plan (its timeout applies to each, its cancel
    /// flag stops the whole run).
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
    #[error("re-planning the rest: {0}")]
    Rest(#[from] RestError),
    #[error("the execution left the plan: {0}")]
    OffPlan(String),
    #[error("timing the plan on the robot: {0}")]
    Robot(String),
}

/// What the cell tells its caller as it runs (one line each).
pub type Progress<'a> = &'a mut dyn FnMut(&str);

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

/// Executes `part` on the true cell `truth`, starting with `plan` (fragments of block
/// indices, found by the pipeline in `planned_in_s`): a driver of [`ClosedLoop`] that
/// deposits on the true model, reads its sensors and, in closed loop, asks for a decision
/// after every weld path and layer. On a robot (`robot` times its plans) each deposit is
/// made when the robot's trajectory makes it (`robot` times each plan the loop takes, and
/// checks a new one as the node does: one it refuses is not taken), and decisions come at
/// weld-path ends only — a layer that ends with the arc on is no place to change the path
/// the robot follows.
pub fn run(
    part: &Part,
    plan: &[Vec<usize>],
    planned_in_s: f64,
    truth: &Truth,
    opts: &CellOptions,
    progress: Progress,
    mut robot: Option<&mut Timing>,
) -> Result<Executed, CellError> {
    let loop_opts = LoopOptions {
        planner: opts.planner.clone(),
        // Open loop keeps the nominal feed.
        wire_feed: if opts.closed_loop {
            opts.wire_feed
        } else {
            (1.0, 1.0)
        },
        wire_feed_per_deposit: true,
        // Deposits are told on the true model's own clock.
        clock_rate: 1.0,
    };
    let mut cl = ClosedLoop::new(part, plan, loop_opts, planned_in_s)?;
    let nominal_h = part.block_mm[2];
    let mut deposits = Vec::new();
    let record = |cl: &ClosedLoop, deposits: Vec<Deposit>, complete: bool| Executed {
        part: part.name.clone(),
        loop_mode: if opts.closed_loop { "closed" } else { "open" }.into(),
        deposits,
        plans: cl.plans().to_vec(),
        estimates: cl.estimates().to_vec(),
        layers: cl.layers().to_vec(),
        // Stopped early: the layers finished so far, against their nominal.
        top_mm: cl.layers().iter().map(|l| l.height_mm).sum(),
        nominal_top_mm: if complete {
            part.layers() as f64 * nominal_h
        } else {
            cl.layers().iter().map(|l| l.nominal_mm).sum()
        },
        complete,
    };
    // The true cell's heat, run through every window (its verdicts come from
    // `Executed::check` on the executed time line).
    let truth_part = estimate::counting_part(part, truth.thermal);
    let graph = WeldGraph::new(part);
    let truth_model = ThermalModel::new(&truth_part, &graph);
    let mut sim = Simulation::new(&truth_model).with_threads(1);
    let mut noise = Noise::new(truth.seed, truth.noise_c);
    // Each deposit's true top above the origin, mm: it stands on the mean top of its
    // supports (the plate, or nominal, where it has none); the scan reads them.
    let mut true_top: Vec<f64> = vec![0.0; part.len()];
    let (mut path, mut in_path) = (0usize, 0usize);
    // On a robot: where it makes each deposit (its first at 0 s), and its time line's step.
    let step = |t: f64| (t / truth_model.dt).round().max(0.0) as u64;
    let mut timed = match robot.as_mut() {
        Some(t) => {
            let times = t(None, plan).map_err(CellError::Robot)?;
            let first = times.deposits_s.first().and_then(|f| f.first()).copied();
            Some(Timed::new(plan.to_vec(), &times, -first.unwrap_or(0.0))?)
        }
        None => None,
    };
    while let Some((b, new)) = cl.next() {
        if opts
            .planner
            .cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
        {
            progress("stopped");
            return Ok(record(&cl, deposits, false));
        }
        if new {
            path += 1;
            in_path = 0;
        }
        let z = part.block(b)[2] as usize;
        let feed = cl.wire_feed(b);
        let start_s = match &timed {
            // When the robot's trajectory makes it, to its end.
            Some(timed) => {
                let d = cl.deposits();
                let (at, end) = (step(timed.starts[d]), step(timed.ends[d]));
                sim.deposit_at(b, new, timed.arc_off_before[d].map(step), at)
                    .and_then(|()| sim.run_to(end, false))
                    .expect("windows widened: no violation");
                at as f64 * truth_model.dt
            }
            None => {
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
                start_s
            }
        };
        let height_mm = nominal_h * truth.height_factor_at(part.centre_mm(part.block(b))) * feed;
        let duration_s = sim.time_s() - start_s;
        deposits.push(Deposit {
            block: part.block(b),
            start_s,
            duration_s,
            height_mm,
            arc_start: new,
            wire_feed: feed,
        });
        let layer_done = cl.deposited(b, new, start_s, duration_s)?;
        let supports = graph.supports(b);
        let base = if supports.is_empty() {
            z as f64 * nominal_h
        } else {
            supports.iter().map(|&s| true_top[s as usize]).sum::<f64>() / supports.len() as f64
        };
        true_top[b] = base + height_mm;
        in_path += 1;
        if layer_done {
            // The scan: every deposit's top.
            let tops: Vec<(usize, f64)> = (0..part.len())
                .filter(|&i| part.block(i)[2] as usize == z)
                .map(|i| (i, true_top[i]))
                .collect();
            cl.layer_tops(z, &tops);
        }
        let Some((_, next_new)) = cl.next() else {
            break;
        };
        // A wire fault ends the path here: it goes on (if at all) with a new arc start.
        let fault = truth.cut_after(path) == Some(in_path) && !next_new;
        if fault {
            cl.path_ended();
            progress(&format!(
                "weld path {path} cut short after {in_path} deposits (t = {:.1} s)",
                sim.time_s()
            ));
        }
        let path_end = cl.next().is_some_and(|(_, new)| new);
        // On a robot a layer that ends with the arc on is not a boundary.
        let boundary = path_end || (layer_done && timed.is_none());
        if !(opts.closed_loop && boundary) {
            // The robot's path split where the fault came.
            if let (true, Some(t), Some(old)) = (fault, robot.as_mut(), &timed) {
                if let Some(new) = retimed(&mut **t, old, None, cl.fragments(), cl.deposits())? {
                    timed = Some(new);
                }
            }
            continue;
        }
        // Measure the true temperatures of the welded blocks, then estimate and re-plan.
        cl.temperatures(sim.temperatures().map(|(b, t)| (b, t + noise.sample())));
        let decision = cl.at_boundary(path_end, sim.time_s())?;
        if decision.reason != "replan" || decision.changed {
            let est = &decision.estimate;
            progress(&format!(
                "{} after {} deposits: loss x{:.3}, conduction x{:.3} (rms {:.1} -> {:.1} °C), plan {:.3} s",
                decision.reason,
                cl.deposits(),
                est.loss,
                est.conduction,
                est.rmse_before_c,
                est.rmse_after_c,
                decision.latency_s
            ));
        }
        // The new remainder takes over here, at a weld-path or layer boundary; on a robot
        // only once its motion is checked (else the plan goes on as it was).
        let refused = match (robot.as_mut(), &timed) {
            (Some(t), Some(old)) if decision.changed => {
                let (check, _) = cl.part_to_check(&decision);
                let whole = decision.fragments();
                match retimed(&mut **t, old, Some(&check), whole, cl.deposits()) {
                    Ok(new) => {
                        timed = new.or(timed.take());
                        None
                    }
                    Err(why) => Some(why),
                }
            }
            _ => None,
        };
        match refused {
            None => cl.adopt(&decision, sim.time_s()),
            Some(why) => {
                progress(&format!("the new plan is not taken: {why}"));
                cl.reject(&decision, sim.time_s());
            }
        }
        // A plan kept after a fault: the robot's path split where it came.
        if let (Some(t), Some(old)) = (robot.as_mut(), &timed) {
            if let Some(new) = retimed(&mut **t, old, None, cl.fragments(), cl.deposits())? {
                timed = Some(new);
            }
        }
    }
    Ok(record(&cl, deposits, true))
}
