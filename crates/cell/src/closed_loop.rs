//! The closed loop's decisions, step by step and without DDS: what the simulated cell
//! ([`crate::run`]) and the ROS node both drive.
//!
//! The caller tells the loop what was deposited and when ([`ClosedLoop::deposited`]), when
//! the arc went out ([`ClosedLoop::path_ended`]) and what the sensors read
//! ([`ClosedLoop::measured`], [`ClosedLoop::temperatures`], [`ClosedLoop::layer_tops`]);
//! it asks for each deposit's wire feed ([`ClosedLoop::wire_feed`]) and, at a weld-path or
//! layer boundary, for a [`Decision`] ([`ClosedLoop::at_boundary`]): the model fitted to the
//! measurements so far and the rest re-planned from the estimated state. The caller adopts
//! the decision ([`ClosedLoop::adopt`]) or, when its own checks refuse the new remainder (the
//! node's robot motion), keeps the current plan ([`ClosedLoop::reject`]).

use std::time::Instant;

use thiserror::Error;

use waam_part::graph::WeldGraph;
use waam_part::{Block, Part, Window};
use waam_planner::{self as planner, Built, Options, Stats};
use waam_thermal::{Simulation, ThermalModel};

use crate::estimate::{self, Estimate, Measurement};
use crate::executed::{EstimateRecord, LayerRecord, PlanUsed};
use crate::measured::Measured;
use crate::{next_wire_feed, CellError};

/// How the loop decides.
#[derive(Debug, Clone)]
pub struct LoopOptions {
    /// The planner's options for every re-plan (its timeout applies to each).
    pub planner: Options,
    /// The wire feed the height rule may set, relative to nominal (process limits; (1, 1)
    /// keeps the nominal feed).
    pub wire_feed: (f64, f64),
    /// The welder takes a wire feed per deposit along a weld path (false: one per weld path,
    /// changed only while the arc is off).
    pub wire_feed_per_deposit: bool,
    /// Seconds of the process per second of the caller's clock, on which deposits are told
    /// (a dry run's time scale; 1 on a real cell): the estimate re-simulates them at it.
    pub clock_rate: f64,
}

/// A sensor reading the loop cannot place.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MeasureError {
    #[error("reading at {stamp_s:.3} s: no deposit was under way then")]
    NoDeposit { stamp_s: f64 },
    #[error("temperature at {stamp_s:.3} s: {celsius} °C is not a temperature")]
    BadTemperature { stamp_s: f64, celsius: f64 },
    #[error("scan at {stamp_s:.3} s: no finished layer is waiting for its scan")]
    NoLayer { stamp_s: f64 },
    #[error("scan at {stamp_s:.3} s: none of its {points} points lies over layer {z}")]
    NoPoints { stamp_s: f64, points: usize, z: i64 },
    #[error("thermal image at {stamp_s:.3} s: none of its {points} points lies on a deposit")]
    OffDeposits { stamp_s: f64, points: usize },
}

/// What the loop decided at a boundary.
#[derive(Debug, Clone)]
pub struct Decision {
    /// "replan" (a new completion found), "fault" (the same, after a path was cut short)
    /// or "kept" (no feasible completion found: the current plan goes on).
    pub reason: &'static str,
    /// Wall-clock time the re-plan took, s.
    pub latency_s: f64,
    /// The model fitted to every measurement so far.
    pub estimate: Estimate,
    /// The whole plan from the first deposit, as (block, begins a weld path).
    pub whole: Vec<(usize, bool)>,
    /// Deposits done when the decision was made.
    pub at_deposit: usize,
    /// The remainder differs from the current one.
    pub changed: bool,
    /// What the re-plan's search did, whether its completion is proven best, and its worst
    /// t8/5 margin from the estimated state, s (NaN when kept).
    pub stats: Stats,
    pub proven: bool,
    pub margin_s: f64,
}

impl Decision {
    /// The whole plan as fragments of block indices (the executed prefix first).
    pub fn fragments(&self) -> Vec<Vec<usize>> {
        split(&self.whole)
    }

    /// The fragments still to come (the first may continue the path in progress).
    pub fn remainder(&self) -> Vec<Vec<usize>> {
        split(&self.whole[self.at_deposit..])
    }
}

/// The deposit sequence of a plan, as (block, begins a weld path).
pub fn sequence(plan: &[Vec<usize>]) -> Vec<(usize, bool)> {
    plan.iter()
        .flat_map(|f| f.iter().enumerate().map(|(p, &b)| (b, p == 0)))
        .collect()
}

/// Fragments of a deposit sequence (the first one may continue a weld path in progress).
pub fn split(seq: &[(usize, bool)]) -> Vec<Vec<usize>> {
    let mut out: Vec<Vec<usize>> = Vec::new();
    for &(b, new) in seq {
        match out.last_mut() {
            Some(f) if !new => f.push(b),
            _ => out.push(vec![b]),
        }
    }
    out
}

/// The loop's state: the plan, what was executed and measured, and its records.
#[derive(Debug, Clone)]
pub struct ClosedLoop {
    part: Part,
    opts: LoopOptions,
    /// The current whole plan, (block, begins a weld path).
    plan: Vec<(usize, bool)>,
    executed: Vec<(usize, bool)>,
    /// (start_s, duration_s) of each executed deposit, on the caller's clock.
    times: Vec<(f64, f64)>,
    /// Sorted by `deposits`, one per deposit count.
    measurements: Vec<Measurement>,
    left_in_layer: Vec<usize>,
    /// Each deposit's wire feed, fixed when first asked for.
    feed: Vec<Option<f64>>,
    /// Each deposit's top above the part's origin, mm, and its gain (the height it made per
    /// height its wire feed asked for): as measured by the scans, else as expected when
    /// its feed was set (from what it stands on, at the gain there).
    top_mm: Vec<Option<f64>>,
    gain_of: Vec<Option<f64>>,
    expected_top_mm: Vec<Option<f64>>,
    expected_gain: Vec<Option<f64>>,
    /// What each deposit stands on (the graph's supports).
    supports: Vec<Vec<u32>>,
    scanned: Vec<bool>,
    /// The last scanned layer's median gain (1 before the first scan).
    gain: f64,
    faults: usize,
    fault_pending: bool,
    plans: Vec<PlanUsed>,
    estimates: Vec<EstimateRecord>,
    layers: Vec<LayerRecord>,
    /// Which blocks lie near a point, made when the first scan or thermal image comes.
    near: std::sync::OnceLock<Near>,
}

impl ClosedLoop {
    /// The loop of `part` starting with `plan` (fragments of block indices), found in
    /// `latency_s`.
    pub fn new(
        part: &Part,
        plan: &[Vec<usize>],
        opts: LoopOptions,
        latency_s: f64,
    ) -> Result<ClosedLoop, CellError> {
        let layers = part.layers().max(0) as usize;
        let mut left_in_layer = vec![0usize; layers];
        for i in 0..part.len() {
            left_in_layer[part.block(i)[2] as usize] += 1;
        }
        let mut this = ClosedLoop {
            part: part.clone(),
            opts,
            plan: sequence(plan),
            executed: Vec::new(),
            times: Vec::new(),
            measurements: Vec::new(),
            left_in_layer,
            feed: vec![None; part.len()],
            top_mm: vec![None; part.len()],
            gain_of: vec![None; part.len()],
            expected_top_mm: vec![None; part.len()],
            expected_gain: vec![None; part.len()],
            supports: {
                let graph = WeldGraph::new(part);
                (0..part.len())
                    .map(|i| graph.supports(i).to_vec())
                    .collect()
            },
            scanned: vec![false; layers],
            gain: 1.0,
            faults: 0,
            fault_pending: false,
            plans: Vec::new(),
            estimates: Vec::new(),
            layers: Vec::new(),
            near: Default::default(),
        };
        this.plans.push(PlanUsed {
            at_deposit: 0,
            at_s: 0.0,
            reason: "initial".into(),
            latency_s,
            continues: false,
            remainder: this.blocks(plan),
        });
        Ok(this)
    }

    fn blocks(&self, fragments: &[Vec<usize>]) -> Vec<Vec<Block>> {
        fragments
            .iter()
            .map(|f| f.iter().map(|&i| self.part.block(i)).collect())
            .collect()
    }

    /// The next deposit of the current plan: (block index, begins a weld path).
    pub fn next(&self) -> Option<(usize, bool)> {
        self.plan.get(self.executed.len()).copied()
    }

    /// The current whole plan as fragments (the executed prefix first).
    pub fn fragments(&self) -> Vec<Vec<usize>> {
        split(&self.plan)
    }

    /// Deposits done so far.
    pub fn deposits(&self) -> usize {
        self.executed.len()
    }

    /// The wire feed of deposit `block`, relative to nominal: the height rule's for the
    /// height still missing under it (the nominal top of the layers below minus the top of
    /// what it stands on) at the gain there (the mean of its supports'). Tops and gains are
    /// the scans' where measured, else those expected when the supports' feeds were set: a
    /// layer welded before the one below it was scanned counts on that layer's correction
    /// rather than making up its shortfall again. Set when first asked for, then fixed.
    pub fn wire_feed(&mut self, block: usize) -> f64 {
        if let Some(feed) = self.feed[block] {
            return feed;
        }
        let h = self.part.block_mm[2];
        let z = self.part.block(block)[2] as f64;
        let gain = self.gain_under(block);
        let feed = next_wire_feed(h, z * h - self.base_mm(block), gain, self.opts.wire_feed);
        self.set_feed(block, feed, gain);
        feed
    }

    fn set_feed(&mut self, block: usize, feed: f64, gain: f64) {
        self.feed[block] = Some(feed);
        self.expected_gain[block] = Some(gain);
        self.expected_top_mm[block] =
            Some(self.base_mm(block) + self.part.block_mm[2] * gain * feed);
    }

    /// The wire feeds of a weld path about to start, one per deposit: the height rule's
    /// own (`wire_feed_per_deposit`), or, for a welder that holds one feed per weld path,
    /// their mean for each. Fixed from then on.
    pub fn path_feeds(&mut self, blocks: &[usize]) -> Vec<f64> {
        let own: Vec<f64> = blocks.iter().map(|&b| self.wire_feed(b)).collect();
        if self.opts.wire_feed_per_deposit || own.is_empty() {
            return own;
        }
        let mean = own.iter().sum::<f64>() / own.len() as f64;
        for &b in blocks {
            let gain = self.expected_gain[b].unwrap_or(self.gain);
            self.set_feed(b, mean, gain);
        }
        vec![mean; blocks.len()]
    }

    /// The wire feeds of `rest` — the deposits of the weld path under way still to begin —
    /// set again from what is measured now (a scan that came while the arc was on), in
    /// order, so each counts on the new feeds of those under it. The path's deposits before
    /// them (`begun`: their feeds stand) first get what is expected of them again, where not
    /// scanned yet: their feeds at the gain now known under them. For a welder that takes a
    /// feed per deposit; one that holds a feed per weld path keeps the feeds it struck at.
    pub fn revise_feeds(&mut self, begun: &[usize], rest: &[usize]) -> Vec<f64> {
        if self.opts.wire_feed_per_deposit {
            for &b in begun {
                if let (Some(feed), None) = (self.feed[b], self.top_mm[b]) {
                    let gain = self.gain_under(b);
                    self.set_feed(b, feed, gain);
                }
            }
            for &b in rest {
                self.feed[b] = None;
                self.expected_gain[b] = None;
                self.expected_top_mm[b] = None;
            }
        }
        rest.iter().map(|&b| self.wire_feed(b)).collect()
    }

    /// The top of what deposit `block` stands on, above the origin, mm: the plate (0) for
    /// the first layer, else the mean of its supports' tops (measured, else expected;
    /// nominal for an overhang standing on nothing).
    fn base_mm(&self, block: usize) -> f64 {
        let nominal = self.part.block(block)[2] as f64 * self.part.block_mm[2];
        self.mean_of_supports(block, |s| self.top_mm[s].or(self.expected_top_mm[s]))
            .unwrap_or(nominal)
    }

    /// The gain under deposit `block`: the mean of its supports' (measured, else
    /// expected), or the last scanned layer's.
    fn gain_under(&self, block: usize) -> f64 {
        self.mean_of_supports(block, |s| self.gain_of[s].or(self.expected_gain[s]))
            .unwrap_or(self.gain)
    }

    /// The mean of `value` over what `block` stands on, if it stands on something and
    /// every value is known.
    fn mean_of_supports(&self, block: usize, value: impl Fn(usize) -> Option<f64>) -> Option<f64> {
        let supports = &self.supports[block];
        let known: Option<Vec<f64>> = supports.iter().map(|&s| value(s as usize)).collect();
        known
            .filter(|v| !v.is_empty())
            .map(|v| v.iter().sum::<f64>() / v.len() as f64)
    }

    /// Block `block` was deposited from `start_s` for `duration_s` (the caller's clock);
    /// it must be the plan's next. Returns whether it finished its layer.
    pub fn deposited(
        &mut self,
        block: usize,
        arc_start: bool,
        start_s: f64,
        duration_s: f64,
    ) -> Result<bool, CellError> {
        match self.next() {
            Some((b, _)) if b == block => {}
            next => {
                return Err(CellError::OffPlan(format!(
                    "deposit {}: block {:?} welded, the plan has {}",
                    self.executed.len() + 1,
                    self.part
                        .block(block.min(self.part.len().saturating_sub(1))),
                    next.map_or("nothing left".into(), |(b, _)| format!(
                        "{:?}",
                        self.part.block(b)
                    ))
                )))
            }
        }
        self.executed.push((block, arc_start));
        self.times.push((start_s, duration_s));
        let z = self.part.block(block)[2] as usize;
        self.left_in_layer[z] -= 1;
        Ok(self.left_in_layer[z] == 0)
    }

    /// The arc went out after the last deposit. When the plan meant the weld path to go
    /// on, the path was cut short (a fault): what follows begins a new weld path, and the
    /// re-plan may use one more. Returns whether it was a fault.
    pub fn path_ended(&mut self) -> bool {
        let i = self.executed.len();
        match self.plan.get_mut(i) {
            Some((_, new)) if !*new => {
                *new = true;
                self.faults += 1;
                self.fault_pending = true;
                true
            }
            _ => false,
        }
    }

    /// A field of temperatures (block index, °C) read now, after the deposits so far.
    pub fn temperatures(&mut self, temperatures: impl IntoIterator<Item = (usize, f64)>) {
        let deposits = self.executed.len();
        self.add(deposits, temperatures.into_iter().collect());
    }

    fn add(&mut self, deposits: usize, mut temperatures: Vec<(usize, f64)>) {
        match self
            .measurements
            .binary_search_by_key(&deposits, |m| m.deposits)
        {
            Ok(k) => self.measurements[k].temperatures.append(&mut temperatures),
            Err(k) => self.measurements.insert(
                k,
                Measurement {
                    deposits,
                    temperatures,
                },
            ),
        }
    }

    /// Layer `z` was measured: each of its deposits' top above the origin, mm (a scan, or
    /// the simulated cell's truth): the height rule's input. A deposit not in `tops` takes
    /// the layer's median top. The layer's height is its median top over the layers below
    /// (as measured, nominal where not); the gain, the median over its deposits of height
    /// made per height asked for.
    pub fn layer_tops(&mut self, z: usize, tops: &[(usize, f64)]) {
        let nominal = self.part.block_mm[2];
        let Some(median_top) = median(tops.iter().map(|t| t.1).collect()) else {
            return;
        };
        let layer: Vec<usize> = (0..self.part.len())
            .filter(|&i| self.part.block(i)[2] as usize == z)
            .collect();
        for &b in &layer {
            self.top_mm[b] = Some(median_top);
        }
        for &(b, top) in tops {
            self.top_mm[b] = Some(top);
        }
        for &b in &layer {
            let made = self.top_mm[b].map(|t| t - self.base_mm(b));
            self.gain_of[b] = made
                .map(|m| m / (nominal * self.feed[b].unwrap_or(1.0)))
                .filter(|g| g.is_finite() && *g > 0.0);
        }
        let gains: Vec<f64> = layer.iter().filter_map(|&b| self.gain_of[b]).collect();
        let feed = layer
            .iter()
            .map(|&b| self.feed[b].unwrap_or(1.0))
            .sum::<f64>()
            / layer.len().max(1) as f64;
        let below: f64 = (0..z)
            .map(|l| {
                self.layers
                    .iter()
                    .find(|r| r.z == l as i64)
                    .map_or(nominal, |r| r.height_mm)
            })
            .sum();
        let height_mm = median_top - below;
        self.gain = median(gains).unwrap_or(height_mm / (nominal * feed));
        self.scanned[z] = true;
        let tops = layer.iter().filter_map(|&b| self.top_mm[b]);
        let tops_mm = [
            tops.clone().fold(f64::INFINITY, f64::min),
            tops.fold(f64::NEG_INFINITY, f64::max),
        ];
        self.layers.push(LayerRecord {
            z: z as i64,
            nominal_mm: nominal,
            height_mm,
            wire_feed: feed,
            tops_mm,
        });
    }

    /// A sensor reading: a temperature is the deposit's under the torch at its stamp
    /// (taken as its temperature at the end of that deposit); a scan measures the lowest
    /// finished layer not scanned yet — its top is the median z of the points over that
    /// layer's blocks.
    pub fn measured(&mut self, reading: &Measured) -> Result<(), MeasureError> {
        match reading {
            &Measured::Temperature { stamp_s, celsius } => {
                if !celsius.is_finite() {
                    return Err(MeasureError::BadTemperature { stamp_s, celsius });
                }
                let k = self.under_way(stamp_s)?;
                self.add(k + 1, vec![(self.executed[k].0, celsius)]);
                Ok(())
            }
            Measured::ThermalImage { stamp_s, points } => {
                let stamp_s = *stamp_s;
                let k = self.under_way(stamp_s)?;
                let seen = self.on_deposits(k + 1, points);
                if seen.is_empty() {
                    return Err(MeasureError::OffDeposits {
                        stamp_s,
                        points: points.len(),
                    });
                }
                self.add(k + 1, seen);
                Ok(())
            }
            Measured::Scan { stamp_s, points } => {
                let stamp_s = *stamp_s;
                let z = (0..self.scanned.len())
                    .find(|&z| self.left_in_layer[z] == 0 && !self.scanned[z])
                    .ok_or(MeasureError::NoLayer { stamp_s })?;
                let tops = self.tops_over(z, points);
                if tops.is_empty() {
                    return Err(MeasureError::NoPoints {
                        stamp_s,
                        points: points.len(),
                        z: z as i64,
                    });
                }
                self.layer_tops(z, &tops);
                Ok(())
            }
        }
    }

    /// The deposit under way at `stamp_s`: the last one begun by then, if it had not ended.
    /// The model knows the temperatures at the end of each deposit, and a reading taken
    /// during one is taken as its end's (between deposits the model has no state).
    fn under_way(&self, stamp_s: f64) -> Result<usize, MeasureError> {
        let k = self.times.partition_point(|&(start, _)| start <= stamp_s);
        k.checked_sub(1)
            .filter(|&k| stamp_s <= self.times[k].0 + self.times[k].1 + 1e-9)
            .ok_or(MeasureError::NoDeposit { stamp_s })
    }

    /// The temperature of each of the first `deposits` deposits a thermal image shows: the
    /// mean of its points on that deposit. A point is on the deposit whose volume it lies
    /// nearest, when within half a layer height of it (a surface point, measured with the
    /// camera's error); points on the plate, the fixture or what is not welded yet are not.
    /// A deposit's volume is where it stands: moved up or down from the nominal one by as
    /// much as its top (scanned, else expected from its feed) lies from the nominal top, so
    /// that a part built low is read on the deposits the camera sees.
    fn on_deposits(&self, deposits: usize, points: &[([f64; 3], f64)]) -> Vec<(usize, f64)> {
        let near = self.near.get_or_init(|| Near::new(&self.part));
        let tolerance = self.part.block_mm[2] / 2.0;
        let mut order = vec![usize::MAX; self.part.len()];
        for (k, &(b, _)) in self.executed[..deposits].iter().enumerate() {
            order[b] = k;
        }
        let shift = |b: usize| -> f64 {
            let nominal_top = self.part.centre_mm(self.part.block(b))[2] - self.part.origin_mm[2]
                + self.part.block_mm[2] / 2.0;
            self.top_mm[b]
                .or(self.expected_top_mm[b])
                .map_or(0.0, |top| top - nominal_top)
        };
        let reach = self.executed[..deposits]
            .iter()
            .map(|&(b, _)| shift(b).abs())
            .fold(0.0, f64::max);
        let mut sums: std::collections::BTreeMap<usize, (f64, usize)> = Default::default();
        for &(p, celsius) in points {
            if !celsius.is_finite() {
                continue;
            }
            let nearest = near
                .within(p, tolerance + reach)
                .filter(|&b| order[b] != usize::MAX)
                .map(|b| {
                    (
                        self.part.distance_to_mm(b, [p[0], p[1], p[2] - shift(b)]),
                        b,
                    )
                })
                .filter(|&(d, _)| d <= tolerance)
                .min_by(|a, b| a.0.total_cmp(&b.0));
            if let Some((_, b)) = nearest {
                let s = sums.entry(b).or_default();
                s.0 += celsius;
                s.1 += 1;
            }
        }
        sums.into_iter()
            .map(|(b, (sum, n))| (b, sum / n as f64))
            .collect()
    }

    /// The top of each deposit of layer `z` a scan shows, above the origin: the median z
    /// of the points over it (within its footprint: a block's cell, a graph part's piece
    /// of bead W wide).
    fn tops_over(&self, z: usize, points: &[[f64; 3]]) -> Vec<(usize, f64)> {
        let near = self.near.get_or_init(|| Near::new(&self.part));
        let Some(centre_z) = (0..self.part.len())
            .find(|&i| self.part.block(i)[2] as usize == z)
            .map(|i| self.part.centre_mm(self.part.block(i))[2])
        else {
            return Vec::new();
        };
        let mut over: std::collections::BTreeMap<usize, Vec<f64>> = Default::default();
        for p in points.iter().filter(|p| p.iter().all(|v| v.is_finite())) {
            // Its footprint's point at the layer's mid-height: inside the deposit.
            let at = [p[0], p[1], centre_z];
            let under = near
                .within(at, 0.0)
                .filter(|&b| self.part.block(b)[2] as usize == z)
                .map(|b| (self.part.distance_to_mm(b, at), b))
                .filter(|&(d, _)| d <= 1e-9)
                .min_by(|a, b| a.0.total_cmp(&b.0));
            if let Some((_, b)) = under {
                over.entry(b)
                    .or_default()
                    .push(p[2] - self.part.origin_mm[2]);
            }
        }
        over.into_iter()
            .filter_map(|(b, zs)| Some((b, median(zs)?)))
            .collect()
    }

    /// At a boundary (`path_ended`: the arc is out; else a layer ended with the arc on),
    /// at `now_s` on the caller's clock: the model fitted to every measurement so far and
    /// the rest re-planned from the estimated state. Nothing changes until the caller
    /// adopts or rejects the decision.
    pub fn at_boundary(&mut self, path_ended: bool, now_s: f64) -> Result<Decision, CellError> {
        let t = Instant::now();
        let executed = estimate::Executed {
            deposits: &self.executed,
            times: &self.times,
            clock_rate: self.opts.clock_rate,
        };
        let est = estimate::fit(&self.part, self.part.thermal, executed, &self.measurements);
        self.estimates.push(EstimateRecord {
            at_deposit: self.executed.len(),
            at_s: now_s,
            loss_factor: est.loss,
            conduction_factor: est.conduction,
            rmse_before_c: est.rmse_before_c,
            rmse_after_c: est.rmse_after_c,
            latency_s: t.elapsed().as_secs_f64(),
        });
        let built = Built {
            state: estimate::state(&self.part, est.params, executed),
            open: !path_ended,
        };
        let mut model_part = self.part.clone();
        model_part.thermal = est.params;
        let rest_opts = Options {
            max_fragments: Some(
                self.opts
                    .planner
                    .max_fragments
                    .unwrap_or(self.part.max_fragments)
                    + self.faults,
            ),
            ..self.opts.planner.clone()
        };
        let t = Instant::now();
        let report = planner::plan_rest(&model_part, &built, &rest_opts, &mut |_| {})?;
        let latency_s = t.elapsed().as_secs_f64();
        let fault = std::mem::take(&mut self.fault_pending);
        let (reason, whole, margin_s) = match &report.best {
            Some(f) => (
                if fault { "fault" } else { "replan" },
                sequence(&f.fragments),
                f.margin,
            ),
            None => ("kept", self.plan.clone(), f64::NAN),
        };
        let done = self.executed.len();
        debug_assert_eq!(whole[..done], self.executed[..]);
        Ok(Decision {
            reason,
            latency_s,
            estimate: est,
            changed: whole[done..] != self.plan[done..],
            whole,
            at_deposit: done,
            stats: report.stats,
            proven: report.proven,
            margin_s,
        })
    }

    /// The decision's plan takes over now, at `now_s`.
    pub fn adopt(&mut self, decision: &Decision, now_s: f64) {
        self.plan = decision.whole.clone();
        self.record(decision.reason, decision.latency_s, now_s);
    }

    /// The decision's plan was refused by the caller's own checks: the current one goes on
    /// (recorded as kept).
    pub fn reject(&mut self, decision: &Decision, now_s: f64) {
        self.record("kept", decision.latency_s, now_s);
    }

    fn record(&mut self, reason: &str, latency_s: f64, now_s: f64) {
        let done = self.executed.len();
        let remainder = self.blocks(&split(&self.plan[done..]));
        self.plans.push(PlanUsed {
            at_deposit: done,
            at_s: now_s,
            reason: reason.into(),
            latency_s,
            continues: self.plan.get(done).is_some_and(|&(_, new)| !new),
            remainder,
        });
    }

    /// The part a decision's whole plan is checked on: the estimated constants, one more
    /// weld path allowed per path cut short (as the re-plan had), and the windows that the
    /// deposits made so far already broke under them widened — the past cannot be changed;
    /// the check judges what is still to come. Also the blocks whose windows were widened,
    /// in the order they broke.
    pub fn part_to_check(&self, decision: &Decision) -> (Part, Vec<Block>) {
        let mut part = self.part.clone();
        part.thermal = decision.estimate.params;
        part.max_fragments += self.faults;
        let mut broken = Vec::new();
        // Each round widens one more window, which then never breaks: at most one round
        // per window.
        loop {
            let violation = {
                let graph = WeldGraph::new(&part);
                let model = ThermalModel::new(&part, &graph);
                let mut sim = Simulation::new(&model).with_threads(1);
                let executed = estimate::Executed {
                    deposits: &self.executed,
                    times: &self.times,
                    clock_rate: self.opts.clock_rate,
                };
                executed.make(&mut sim, 0..self.executed.len()).err()
            };
            let Some(v) = violation else {
                return (part, broken);
            };
            part.set_window(
                v.block,
                Window {
                    min_s: 0.0,
                    max_s: f64::INFINITY,
                },
            );
            broken.push(self.part.block(v.block));
        }
    }

    /// Every plan used (the initial one first), every estimate, every scanned layer.
    pub fn plans(&self) -> &[PlanUsed] {
        &self.plans
    }
    /// The temperatures placed so far, by the deposits done when each was read.
    pub fn measurements(&self) -> &[Measurement] {
        &self.measurements
    }
    pub fn estimates(&self) -> &[EstimateRecord] {
        &self.estimates
    }
    pub fn layers(&self) -> &[LayerRecord] {
        &self.layers
    }
}

/// The median of `values` (none when empty).
fn median(mut values: Vec<f64>) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    Some(if n % 2 == 1 {
        values[n / 2]
    } else {
        (values[n / 2 - 1] + values[n / 2]) / 2.0
    })
}

/// The blocks of a part by where they lie: an R-tree of their centres, and how far from its
/// centre any point of a block lies at most.
#[derive(Debug, Clone)]
struct Near {
    centres: rstar::RTree<rstar::primitives::GeomWithData<[f64; 3], usize>>,
    reach_mm: f64,
}

impl Near {
    fn new(part: &Part) -> Near {
        let centres: Vec<_> = (0..part.len())
            .map(|i| rstar::primitives::GeomWithData::new(part.centre_mm(part.block(i)), i))
            .collect();
        let reach_mm = match part.bead_part() {
            // A deposit's piece of centre line, W wide and H high, around its centre.
            Some(beads) => {
                let [w, h] = beads.bead_mm;
                beads
                    .nodes
                    .iter()
                    .map(|n| {
                        let along = beads.beads[n.bead]
                            .piece_mm(n.from_mm, n.to_mm)
                            .iter()
                            .map(|q| (q[0] - n.centre_mm[0]).hypot(q[1] - n.centre_mm[1]))
                            .fold(0.0, f64::max);
                        (along + w / 2.0).hypot(h / 2.0)
                    })
                    .fold(0.0, f64::max)
            }
            None => part.block_mm.iter().map(|v| v * v).sum::<f64>().sqrt() / 2.0,
        };
        Near {
            centres: rstar::RTree::bulk_load(centres),
            reach_mm,
        }
    }

    /// The blocks a point within `tolerance_mm` of a block's volume may belong to.
    fn within(&self, p: [f64; 3], tolerance_mm: f64) -> impl Iterator<Item = usize> + '_ {
        let r = self.reach_mm + tolerance_mm;
        self.centres
            .locate_within_distance(p, r * r)
            .map(|c| c.data)
    }
}
