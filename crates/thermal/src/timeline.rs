//! Whole plans: [`simulate`] runs one on the spec's time line, [`simulate_on`] on a given
//! [`Timeline`] (the robot's executed one), both to an [`Outcome`].

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

use thiserror::Error;

use waam_part::MAX_STEPS;

use crate::interrupt::Interrupt;
use crate::model::{round_steps, ThermalModel};
use crate::simulation::{Simulation, Snapshot};
use crate::violation::{Crossing, NotCooled, Phase, Violation};

/// The outcome of simulating a whole plan.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// `None`: every window kept (the plan is feasible).
    pub violation: Option<Violation>,
    /// Every crossing seen, in time order (up to the violation).
    pub crossings: Vec<Crossing>,
    pub steps: u64,
    pub time_s: f64,
}

/// Simulates a whole plan given as fragments of block indices, recording crossings.
pub fn simulate(model: &ThermalModel, fragments: &[Vec<usize>]) -> Result<Outcome, NotCooled> {
    let outcome = simulate_until(model, fragments, None, None)?;
    Ok(outcome.expect("a simulation without deadline or cancel runs to its end"))
}

/// [`simulate`], stopped at `deadline` or soon after `cancel` is raised: `Ok(None)` then.
/// A long transit or cooldown (up to a billion steps) takes minutes; callers with a
/// time limit use this one.
pub fn simulate_until(
    model: &ThermalModel,
    fragments: &[Vec<usize>],
    deadline: Option<Instant>,
    cancel: Option<Arc<AtomicBool>>,
) -> Result<Option<Outcome>, NotCooled> {
    let mut sim = Simulation::new(model).with_deadline(deadline);
    if let Some(flag) = cancel {
        sim = sim.with_cancel(flag);
    }
    simulate_in(sim, fragments)
}

/// [`simulate_until`] on a simulation set up by the caller (threads, deadline, cancel),
/// recording crossings; `Ok(None)` when its deadline or cancel stopped it.
pub fn simulate_in(
    sim: Simulation<'_>,
    fragments: &[Vec<usize>],
) -> Result<Option<Outcome>, NotCooled> {
    Ok(run(sim, fragments, false)?.map(|(outcome, _)| outcome))
}

/// [`simulate_in`], with the state after the last deposit (before the cooldown) when the
/// plan keeps every window: whoever judges the plan again resumes from there instead of
/// simulating every deposit again (minutes at 10^5 blocks).
pub fn simulate_keeping_end(
    sim: Simulation<'_>,
    fragments: &[Vec<usize>],
) -> Result<Option<(Outcome, Option<Snapshot>)>, NotCooled> {
    run(sim, fragments, true)
}

fn run(
    sim: Simulation<'_>,
    fragments: &[Vec<usize>],
    keep_end: bool,
) -> Result<Option<(Outcome, Option<Snapshot>)>, NotCooled> {
    let mut sim = sim.recording();
    let mut violation = None;
    'plan: for fragment in fragments {
        for (p, &b) in fragment.iter().enumerate() {
            if let Err(v) = sim.deposit(b, p == 0) {
                violation = Some(v);
                break 'plan;
            }
        }
    }
    let mut end = None;
    if violation.is_none() {
        end = keep_end.then(|| sim.snapshot());
        violation = sim.finish()?.err();
    }
    if sim.cancelled() {
        return Ok(None);
    }
    let end = end.filter(|_| violation.is_none());
    let outcome = Outcome {
        violation,
        steps: sim.steps(),
        time_s: sim.time_s(),
        crossings: sim.crossings.take().unwrap_or_default(),
    };
    Ok(Some((outcome, end)))
}

/// When a plan's blocks are deposited and each weld path's arc goes off, in Euler steps
/// from the first deposit. [`Timeline::modelled`] is the spec's time line (`block_time_s`
/// per block, `transit_time_s` between fragments); the motion stage reports the robot's
/// executed one ([`Timeline::from_seconds`]), on which [`simulate_on`] runs the same model
/// and the same t8/5 rules.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Timeline {
    /// Per fragment, the step at which each of its blocks is deposited.
    pub deposits: Vec<Vec<u64>>,
    /// Per fragment, the step at which its arc goes off (steps before it are deposit
    /// steps, steps after it until the next deposit are transit steps).
    pub arc_off: Vec<u64>,
}

/// A time line that does not fit its plan.
#[derive(Debug, Clone, Error, PartialEq)]
#[error("bad time line: {0}")]
pub struct TimelineError(pub String);

/// Why [`simulate_on`] gave no outcome.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum SimulateError {
    #[error(transparent)]
    NotCooled(#[from] NotCooled),
    #[error(transparent)]
    Timeline(#[from] TimelineError),
}

impl Timeline {
    /// The spec's time line of a plan: every block `substeps` steps (a graph part's node
    /// its [`ThermalModel::deposit_steps`]), `transit_steps` between fragments, the arc off
    /// right after a fragment's last block.
    pub fn modelled(model: &ThermalModel, fragments: &[Vec<usize>]) -> Timeline {
        let mut now = 0u64;
        let mut deposits = Vec::with_capacity(fragments.len());
        let mut arc_off = Vec::with_capacity(fragments.len());
        for (f, fragment) in fragments.iter().enumerate() {
            if f > 0 {
                now += model.transit_steps;
            }
            deposits.push(
                fragment
                    .iter()
                    .map(|&b| {
                        let at = now;
                        now += model.deposit_steps(b);
                        at
                    })
                    .collect(),
            );
            arc_off.push(now);
        }
        Timeline { deposits, arc_off }
    }

    /// A time line from times in seconds (any origin): each time becomes the nearest
    /// Euler step counted from the first deposit, so that it is off by at most half a step.
    pub fn from_seconds(
        deposits_s: &[Vec<f64>],
        arc_off_s: &[f64],
        dt: f64,
    ) -> Result<Timeline, TimelineError> {
        let Some(&t0) = deposits_s.first().and_then(|f| f.first()) else {
            return Err(TimelineError("no deposits".into()));
        };
        let step = |t: f64| -> Result<u64, TimelineError> {
            let x = (t - t0) / dt;
            if x.is_finite() && x > -0.5 && x < MAX_STEPS as f64 {
                Ok(round_steps(x.max(0.0)))
            } else {
                Err(TimelineError(format!(
                    "time {t} s is before the first deposit or not finite"
                )))
            }
        };
        Ok(Timeline {
            deposits: deposits_s
                .iter()
                .map(|f| f.iter().map(|&t| step(t)).collect())
                .collect::<Result<_, _>>()?,
            arc_off: arc_off_s
                .iter()
                .map(|&t| step(t))
                .collect::<Result<_, _>>()?,
        })
    }

    /// Checks that the time line has one step per block of `fragments`, starts at 0 and
    /// never goes back in time.
    pub fn fits(&self, fragments: &[Vec<usize>]) -> Result<(), TimelineError> {
        let bad = |m: String| Err(TimelineError(m));
        if self.deposits.len() != fragments.len() || self.arc_off.len() != fragments.len() {
            return bad(format!(
                "{} deposit lists and {} arc-off steps for {} fragments",
                self.deposits.len(),
                self.arc_off.len(),
                fragments.len()
            ));
        }
        let mut now = 0u64;
        for (f, (steps, fragment)) in self.deposits.iter().zip(fragments).enumerate() {
            if steps.len() != fragment.len() || steps.is_empty() {
                return bad(format!(
                    "fragment {}: {} deposit steps for {} blocks",
                    f + 1,
                    steps.len(),
                    fragment.len()
                ));
            }
            for &s in steps.iter().chain([&self.arc_off[f]]) {
                if s < now {
                    return bad(format!("fragment {}: step {s} goes back in time", f + 1));
                }
                now = s;
            }
        }
        if self.deposits[0][0] != 0 {
            return bad("the first deposit is not at step 0".into());
        }
        Ok(())
    }
}

/// [`simulate`] on a given time line: each block is deposited at its step, the steps
/// up to a fragment's arc-off are deposit steps, the steps after it transit steps, and
/// the cooldown follows the last arc-off. On [`Timeline::modelled`] this is [`simulate`],
/// bit for bit.
pub fn simulate_on(
    model: &ThermalModel,
    fragments: &[Vec<usize>],
    timeline: &Timeline,
) -> Result<Outcome, SimulateError> {
    let outcome = simulate_on_until(model, fragments, timeline, &Interrupt::default())?;
    Ok(outcome.expect("a simulation without deadline or cancel runs to its end"))
}

/// [`simulate_on`], stopped by `interrupt`: `Ok(None)` then.
pub fn simulate_on_until(
    model: &ThermalModel,
    fragments: &[Vec<usize>],
    timeline: &Timeline,
    interrupt: &Interrupt,
) -> Result<Option<Outcome>, SimulateError> {
    timeline.fits(fragments)?;
    let mut sim = Simulation::new(model).recording().interrupted_by(interrupt);
    let mut violation = None;
    'plan: for (f, fragment) in fragments.iter().enumerate() {
        for (p, &b) in fragment.iter().enumerate() {
            let at = timeline.deposits[f][p];
            let run = if p == 0 && f > 0 {
                let off = timeline.arc_off[f - 1];
                sim.run(off - sim.steps, Phase::Deposit, false)
                    .and_then(|()| sim.run(at - off, Phase::Transit, false))
            } else {
                sim.run(at - sim.steps, Phase::Deposit, false)
            };
            if let Err(v) = run {
                violation = Some(v);
                break 'plan;
            }
            if sim.cancelled() {
                return Ok(None);
            }
            sim.place(b, p == 0);
        }
    }
    if violation.is_none() {
        let off = *timeline.arc_off.last().expect("fits: a fragment");
        violation = sim.run(off - sim.steps, Phase::Deposit, false).err();
    }
    if violation.is_none() {
        violation = sim.finish()?.err();
    }
    if sim.cancelled() {
        return Ok(None);
    }
    Ok(Some(Outcome {
        violation,
        steps: sim.steps(),
        time_s: sim.time_s(),
        crossings: sim.crossings.take().unwrap_or_default(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{model, WALL};
    use crate::violation::ViolationKind;

    #[test]
    fn a_lone_block_cools_to_ambient_and_crosses_once() {
        let (_, m) = model(
            "name: b\nblock_mm: [1,1,1]\nmax_fragments: 1\nblocks: [[0,0,0]]\nt85: [{block: [0,0,0], min_s: 0, max_s: 100}]\n",
        );
        let out = simulate(&m, &[vec![0]]).unwrap();
        assert!(out.violation.is_none());
        assert_eq!(out.crossings.len(), 1);
        assert!(out.crossings[0].t85_s > 0.0);
    }

    /// Fragments of a (block, new fragment) order.
    fn split(order: &[(usize, bool)]) -> Vec<Vec<usize>> {
        let mut out: Vec<Vec<usize>> = Vec::new();
        for &(b, new) in order {
            match out.last_mut() {
                Some(f) if !new => f.push(b),
                _ => out.push(vec![b]),
            }
        }
        out
    }

    #[test]
    fn the_modelled_timeline_is_the_spec_time_line_bit_for_bit() {
        // Tight and loose windows: some plans break one (in every phase), some keep all.
        for (lo, hi) in [(0.0, 1000.0), (3.0, 1000.0), (0.0, 4.0), (2.0, 9.0)] {
            let (part, m) = model(&format!(
                "{WALL}t85: [{{box: {{min: [0,0,0], max: [3,0,1]}}, min_s: {lo}, max_s: {hi}}}]\n"
            ));
            let n = part.len();
            for cut in [1usize, 2, 3, 5] {
                for rev in [false, true] {
                    let mut order: Vec<usize> = (0..n).collect();
                    if rev {
                        order[..4].reverse();
                    }
                    let seq: Vec<(usize, bool)> = order
                        .iter()
                        .enumerate()
                        .map(|(p, &b)| (b, p == 0 || p == cut))
                        .collect();
                    let fragments = split(&seq);
                    let want = simulate(&m, &fragments).unwrap();
                    let timeline = Timeline::modelled(&m, &fragments);
                    let got = simulate_on(&m, &fragments, &timeline).unwrap();
                    assert_eq!(got.violation, want.violation);
                    assert_eq!(got.crossings, want.crossings);
                    assert_eq!(got.steps, want.steps);
                    assert_eq!(got.time_s.to_bits(), want.time_s.to_bits());
                }
            }
        }
    }

    /// A caller that deposits one block at a time on a robot's time line (the simulated
    /// cell) gets the temperatures `simulate_on` has there, bit for bit.
    #[test]
    fn depositing_on_a_timeline_one_block_at_a_time_is_simulate_on() {
        let (part, m) = model(&format!(
            "{WALL}t85: [{{box: {{min: [0,0,0], max: [3,0,1]}}, min_s: 0, max_s: 1000}}]\n"
        ));
        let order: Vec<(usize, bool)> = (0..part.len()).map(|b| (b, b == 0 || b == 3)).collect();
        let fragments = split(&order);
        // The model's time line stretched: longer deposits, a longer transit.
        let mut timeline = Timeline::modelled(&m, &fragments);
        for (f, steps) in timeline.deposits.iter_mut().enumerate() {
            for (p, at) in steps.iter_mut().enumerate() {
                *at = *at * 3 / 2 + 7 * f as u64 + p as u64;
            }
        }
        for (f, off) in timeline.arc_off.iter_mut().enumerate() {
            *off = timeline.deposits[f].last().unwrap() + 40;
        }
        let want = simulate_on(&m, &fragments, &timeline).unwrap();
        let mut sim = Simulation::new(&m).recording();
        for (f, fragment) in fragments.iter().enumerate() {
            for (p, &b) in fragment.iter().enumerate() {
                let off = f.checked_sub(1).map(|g| timeline.arc_off[g]);
                sim.deposit_at(b, p == 0, off, timeline.deposits[f][p])
                    .unwrap();
            }
        }
        sim.run_to(*timeline.arc_off.last().unwrap(), false)
            .unwrap();
        assert!(sim.finish().unwrap().is_ok());
        assert_eq!(sim.steps(), want.steps);
        assert!(!want.crossings.is_empty());
        assert_eq!(sim.crossings(), &want.crossings[..]);
    }

    #[test]
    fn a_timeline_in_seconds_rounds_to_the_nearest_step_from_the_first_deposit() {
        let t =
            Timeline::from_seconds(&[vec![10.0, 11.3], vec![17.02]], &[11.81, 18.0], 0.05).unwrap();
        assert_eq!(t.deposits, vec![vec![0, 26], vec![140]]);
        assert_eq!(t.arc_off, vec![36, 160]);
        assert!(t.fits(&[vec![4, 5], vec![6]]).is_ok());
        // Shapes and order are checked.
        let e = t.fits(&[vec![4], vec![6]]).unwrap_err();
        assert!(
            e.to_string()
                .contains("fragment 1: 2 deposit steps for 1 blocks"),
            "{e}"
        );
        let back = Timeline {
            deposits: vec![vec![0, 30], vec![20]],
            arc_off: vec![40, 50],
        };
        assert!(back.fits(&[vec![4, 5], vec![6]]).is_err());
        assert!(Timeline::from_seconds(&[vec![1.0]], &[f64::NAN], 0.05).is_err());
    }

    #[test]
    fn the_executed_timeline_can_change_the_verdict() {
        // Two single-block fragments side by side. With the modelled 5 s transit block 0
        // cools below 500 °C alone after 0.95 s between 800 and 500 °C (too short for
        // min_s = 1), is reheated by block 1 and crosses again; after a 0.5 s transit block
        // 1 comes while block 0 is still hot and it crosses once, after 1.05 s.
        let (_, m) = model(&format!(
            "{WALL}t85: [{{box: {{min: [0,0,0], max: [0,0,0]}}, min_s: 1, max_s: 100}}]\n"
        ));
        let fragments = vec![vec![0], vec![1]];
        let modelled = Timeline::modelled(&m, &fragments);
        assert_eq!(modelled.deposits, vec![vec![0], vec![120]]);
        assert_eq!(modelled.arc_off, vec![20, 140]);
        let v = simulate_on(&m, &fragments, &modelled)
            .unwrap()
            .violation
            .unwrap();
        assert_eq!(
            (v.block, v.kind, v.phase),
            (0, ViolationKind::Min, Phase::Transit)
        );
        let quick = Timeline {
            deposits: vec![vec![0], vec![30]],
            arc_off: vec![20, 50],
        };
        let out = simulate_on(&m, &fragments, &quick).unwrap();
        assert!(out.violation.is_none());
        assert_eq!(out.crossings.len(), 1);
        assert!((out.crossings[0].t85_s - 1.05).abs() < 1e-9);
    }
}
