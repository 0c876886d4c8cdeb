//! A running simulation of one plan prefix ([`Simulation`]): deposits, the stepping loop,
//! the t8/5 counters, and [`Snapshot`]s to resume from. A step is computed by a
//! [`Kernel`] over the stepped slots, on one thread or on the [`pool`].

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Instant;

use waam_part::graph::NONE;
use waam_part::{BlockDisplay, Window};

use crate::graph::{graph_blocks, graph_slots, GraphTable};
use crate::interrupt::Interrupt;
use crate::kernel::Kernel;
use crate::model::{steps_beyond, ThermalModel, HOT_C, TOLERANCE_S, WARM_C};
use crate::pool;
use crate::violation::{Crossing, NotCooled, Phase, Violation, ViolationKind};

/// `w_crossed` of a windowed block that has not cooled through 500 °C yet.
const NOT_CROSSED: (u64, u64) = (u64::MAX, 0);

/// A saved simulation state: resume from it with [`Simulation::restore`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Snapshot {
    welded: usize,
    windowed: usize,
    fragments: usize,
    steps: u64,
    /// Temperatures of the welded blocks in weld order.
    temps: Vec<f64>,
    counts: Vec<u64>,
    crossed: Vec<(u64, u64)>,
    lows: Vec<f64>,
}

impl Snapshot {
    /// Blocks deposited at the time of the snapshot.
    pub fn welded(&self) -> usize {
        self.welded
    }

    /// Heap bytes held by the snapshot (what a cache of snapshots should count).
    pub fn bytes(&self) -> usize {
        std::mem::size_of::<Snapshot>()
            + self.temps.capacity() * std::mem::size_of::<f64>()
            + self.counts.capacity() * std::mem::size_of::<u64>()
            + self.crossed.capacity() * std::mem::size_of::<(u64, u64)>()
            + self.lows.capacity() * std::mem::size_of::<f64>()
    }
}

/// The thermal state of a partly built part, as an estimator knows it: what is welded, in
/// which order, how hot each block is, and how long each windowed block has been cooling.
/// [`Simulation::from_state`] resumes from it; [`Simulation::state`] reads it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BuildState {
    /// Welded blocks in weld order, each with whether it began a weld path (arc start).
    pub order: Vec<(usize, bool)>,
    /// Temperatures of the welded blocks, °C, in weld order.
    pub temperatures: Vec<f64>,
    /// Of the welded blocks with a t8/5 window, in weld order: Euler steps spent between
    /// 500 and 800 °C since the block was last above 800 °C (the spec's counter n).
    pub t85_steps: Vec<u64>,
    /// Euler steps since the first deposit (the time is `steps · dt`).
    pub steps: u64,
}

/// A [`BuildState`] that does not fit its model.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("bad build state: {0}")]
pub struct StateError(pub String);

/// Temperature buffers keep one padding slot at each end, so that the contiguous -x / +x
/// reads of the first and last slot stay in bounds: slot `s` lives at `temp[s + PAD]`.
const PAD: usize = 1;

/// Default thread count of new simulations (0: not set, use the available cores).
static DEFAULT_THREADS: AtomicUsize = AtomicUsize::new(0);

/// Sets the thread count new simulations use (1: single-threaded; 0: the available cores).
pub fn set_default_threads(threads: usize) {
    DEFAULT_THREADS.store(threads, Ordering::Relaxed);
}

/// The thread count new simulations use.
pub fn default_threads() -> usize {
    match DEFAULT_THREADS.load(Ordering::Relaxed) {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    }
}

/// Below this many slots in the stepped range a step runs on one thread: splitting it
/// costs more (one barrier per step, ~1 µs) than it saves.
pub const PARALLEL_MIN_SLOTS: usize = 4096;

/// A running simulation of one plan prefix.
///
/// Layout: a block's *slot* is its index in the part, i.e. blocks sorted by (z, y, x), so
/// the -x / +x neighbour of slot `s`, when the part has it, is slot `s - 1` / `s + 1` (a
/// contiguous read) and the z = 0 blocks are the slots `0..n0`. A step computes every slot
/// of the range `lo..hi` spanning the welded slots; unwelded slots inside it are computed too
/// and ignored (plans weld bottom-up, so the range is the welded layers). The ±y / ±z
/// neighbours are kept as slot indices (a gather), pointing at the slot itself while the
/// neighbour is not welded: then `T_self - T_self` is the very operand the spec's sum has
/// for an absent neighbour. The ±x neighbours are selected by two flag bits instead.
#[derive(Debug, Clone)]
pub struct Simulation<'m> {
    model: &'m ThermalModel,
    /// Number of welded blocks.
    welded: usize,
    fragments: usize,
    pub(crate) steps: u64,
    /// Temperatures before / after a step, slot `s` at `s + PAD`.
    temp: Vec<f64>,
    next: Vec<f64>,
    /// -y, +y, -z, +z neighbour slots (the slot itself while that neighbour is unwelded).
    ny0: Vec<u32>,
    ny1: Vec<u32>,
    nz0: Vec<u32>,
    nz1: Vec<u32>,
    /// [`MINUS_X`](crate::kernel::MINUS_X), [`PLUS_X`](crate::kernel::PLUS_X),
    /// [`MINUS_Y`](crate::kernel::MINUS_Y) << d: that neighbour is welded.
    welded_faces: Vec<u8>,
    /// r · exposed faces, per slot.
    radiation: Vec<f64>,
    exposed: Vec<u8>,
    is_welded: Vec<bool>,
    /// A graph part's step tables (its model's neighbour columns, s_i and ρ_i), stepped over
    /// `temp` / `next` instead of the block faces above, which are then empty.
    graph: Option<GraphTable>,
    /// Welded slots in weld order, and whether each began a weld path.
    order: Vec<u32>,
    starts: Vec<bool>,
    /// The stepped slot range `lo..hi` after each deposit (`ranges[k]`: after k + 1).
    ranges: Vec<(u32, u32)>,
    // Windowed blocks in deposit order: slot, bounds, block, t8/5 counter (whole steps).
    w_slot: Vec<u32>,
    w_lo: Vec<f64>,
    w_hi: Vec<f64>,
    /// The least t8/5 count (whole steps) above `w_hi`: see [`steps_beyond`].
    w_over: Vec<u64>,
    w_block: Vec<u32>,
    w_count: Vec<u64>,
    /// The least and the most t8/5 count at a downward crossing of 500 °C so far
    /// ([`NOT_CROSSED`] before the first): the plan's margin without recording crossings.
    w_crossed: Vec<(u64, u64)>,
    /// The lowest temperature between 500 and 800 °C since the block was last above
    /// 800 °C (+inf: none yet): how near a block that stays too long in the band came to
    /// leaving it (no verdict depends on it).
    w_low: Vec<f64>,
    pub(crate) crossings: Option<Vec<Crossing>>,
    threads: usize,
    parallel_min: usize,
    cancel: Option<Arc<AtomicBool>>,
    deadline: Option<Instant>,
    cancelled: bool,
}

impl<'m> Simulation<'m> {
    pub fn new(model: &'m ThermalModel) -> Simulation<'m> {
        let n = model.len();
        let graph = model.graph.as_ref().map(GraphTable::new);
        // A graph part: no block faces; slots in whole blocks of 4 for its kernel.
        let (faces, buffer) = match graph {
            Some(_) => (0, graph_slots(n)),
            None => (n, n),
        };
        let slots: Vec<u32> = (0..faces as u32).collect();
        Simulation {
            model,
            welded: 0,
            fragments: 0,
            steps: 0,
            temp: vec![model.params.ambient_c; buffer + 2 * PAD],
            next: vec![model.params.ambient_c; buffer + 2 * PAD],
            ny0: slots.clone(),
            ny1: slots.clone(),
            nz0: slots.clone(),
            nz1: slots,
            welded_faces: vec![0; faces],
            radiation: vec![0.0; faces],
            exposed: vec![0; faces],
            graph,
            is_welded: vec![false; n],
            order: Vec::new(),
            starts: Vec::new(),
            ranges: Vec::new(),
            w_slot: Vec::new(),
            w_lo: Vec::new(),
            w_hi: Vec::new(),
            w_over: Vec::new(),
            w_block: Vec::new(),
            w_count: Vec::new(),
            w_crossed: Vec::new(),
            w_low: Vec::new(),
            crossings: None,
            threads: default_threads(),
            parallel_min: PARALLEL_MIN_SLOTS,
            cancel: None,
            deadline: None,
            cancelled: false,
        }
    }

    /// A simulation that resumes from `state` (the estimator's temperatures at its time):
    /// its deposits are placed without stepping, then its temperatures, t8/5 counters and
    /// time are set. From the [`Simulation::state`] of a simulation it continues that
    /// simulation bit for bit.
    pub fn from_state(
        model: &'m ThermalModel,
        state: &BuildState,
    ) -> Result<Simulation<'m>, StateError> {
        let bad = |m: String| Err(StateError(m));
        let n = model.len();
        let mut seen = vec![false; n];
        for (p, &(b, new)) in state.order.iter().enumerate() {
            if b >= n {
                return bad(format!(
                    "deposit {}: block index {b} is not in the part ({n} blocks)",
                    p + 1
                ));
            }
            if std::mem::replace(&mut seen[b], true) {
                return bad(format!(
                    "deposit {}: block index {b} is welded twice",
                    p + 1
                ));
            }
            if p == 0 && !new {
                return bad("the first deposit must begin a weld path".into());
            }
        }
        if state.temperatures.len() != state.order.len() {
            return bad(format!(
                "{} temperatures for {} welded blocks",
                state.temperatures.len(),
                state.order.len()
            ));
        }
        if let Some(p) = state
            .temperatures
            .iter()
            .position(|t| !t.is_finite() || *t < -273.15)
        {
            return bad(format!(
                "deposit {}: temperature {} °C is not a temperature",
                p + 1,
                state.temperatures[p]
            ));
        }
        let windowed = state
            .order
            .iter()
            .filter(|&&(b, _)| model.windows[b].is_some())
            .count();
        if state.t85_steps.len() != windowed {
            return bad(format!(
                "{} t8/5 counters for {windowed} welded blocks with a window",
                state.t85_steps.len()
            ));
        }
        if state.steps > crate::MAX_STEPS {
            return bad(format!(
                "time of {} steps is beyond the model's limit",
                state.steps
            ));
        }
        let mut sim = Simulation::new(model);
        for &(b, new) in &state.order {
            sim.place(b, new);
        }
        for (&s, &t) in sim.order.iter().zip(&state.temperatures) {
            sim.temp[s as usize + PAD] = t;
        }
        sim.w_count.copy_from_slice(&state.t85_steps);
        sim.steps = state.steps;
        Ok(sim)
    }

    /// The state to resume from with [`Simulation::from_state`].
    pub fn state(&self) -> BuildState {
        BuildState {
            order: (self.order.iter().zip(&self.starts))
                .map(|(&s, &new)| (s as usize, new))
                .collect(),
            temperatures: self.temperatures().map(|(_, t)| t).collect(),
            t85_steps: self.w_count.clone(),
            steps: self.steps,
        }
    }

    /// Also record every t8/5 crossing (for reports; the planner leaves this off).
    pub fn recording(mut self) -> Self {
        self.crossings = Some(Vec::new());
        self
    }

    /// Steps on up to `threads` threads once the stepped range has at least
    /// [`PARALLEL_MIN_SLOTS`] slots (1: always single-threaded; 0: [`default_threads`]).
    /// Results are the same.
    pub fn with_threads(mut self, threads: usize) -> Self {
        self.set_threads(threads);
        self
    }

    /// [`Simulation::with_threads`] on a running simulation: from the next step on.
    pub fn set_threads(&mut self, threads: usize) {
        self.threads = match threads {
            0 => default_threads(),
            n => n,
        };
    }

    /// Threads as in [`Simulation::with_threads`], from `min_slots` slots on.
    pub fn with_parallel_min(mut self, min_slots: usize) -> Self {
        self.parallel_min = min_slots;
        self
    }

    /// Stops stepping (checked before every step) once `flag` is raised: deposits and
    /// [`Simulation::finish`] then return `Ok` early and [`Simulation::cancelled`] is true.
    pub fn with_cancel(mut self, flag: Arc<AtomicBool>) -> Self {
        self.cancel = Some(flag);
        self
    }

    /// Stops stepping, as a cancel does, once `deadline` has passed (checked every few
    /// hundred steps).
    pub fn with_deadline(mut self, deadline: Option<Instant>) -> Self {
        self.deadline = deadline;
        self
    }

    /// Stops stepping at the deadline or the cancel of `interrupt`.
    pub fn interrupted_by(mut self, interrupt: &Interrupt) -> Self {
        self.deadline = interrupt.deadline;
        self.cancel = interrupt.cancel.clone();
        self
    }

    /// Whether the cancel flag stopped a run (the state is then incomplete).
    pub fn cancelled(&self) -> bool {
        self.cancelled
    }

    /// The worst t8/5 margin of the crossings so far (+inf before the first): the same
    /// number as [`ThermalModel::margin`] of the crossings a recording simulation of the
    /// same deposits would hold (a block's worst crossing is its shortest or its longest
    /// t8/5), without recording them, and carried by snapshots.
    pub fn margin_s(&self) -> f64 {
        let dt = self.model.dt;
        (self.w_crossed.iter().enumerate())
            .filter(|&(_, &c)| c != NOT_CROSSED)
            .map(|(a, &(least, most))| {
                (least as f64 * dt - self.w_lo[a]).min(self.w_hi[a] - most as f64 * dt)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// The crossings recorded so far (empty unless [`Simulation::recording`]).
    pub fn crossings(&self) -> &[Crossing] {
        self.crossings.as_deref().unwrap_or(&[])
    }

    /// Blocks deposited so far.
    pub fn welded(&self) -> usize {
        self.welded
    }

    /// Fragments begun so far.
    pub fn fragments(&self) -> usize {
        self.fragments
    }

    /// Euler steps done so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The Euler step, s.
    pub fn dt(&self) -> f64 {
        self.model.dt
    }

    /// Simulated time so far, s.
    pub fn time_s(&self) -> f64 {
        self.steps as f64 * self.model.dt
    }

    /// The welded blocks in weld order with their temperatures, °C.
    pub fn temperatures(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.order
            .iter()
            .map(|&s| (s as usize, self.temp[s as usize + PAD]))
    }

    /// Deposits `block` (beginning a new fragment if `new_fragment`) and runs its steps.
    /// A new fragment after the first is preceded by the transit steps.
    pub fn deposit(&mut self, block: usize, new_fragment: bool) -> Result<(), Violation> {
        debug_assert!(!self.is_welded[block], "block deposited twice");
        if new_fragment && self.fragments > 0 {
            self.run(self.model.transit_steps, Phase::Transit, false)?;
        }
        self.place(block, new_fragment);
        self.run(self.model.deposit_steps(block), Phase::Deposit, false)
    }

    /// The transit steps before a new fragment (the first half of `deposit(b, true)`).
    pub fn transit(&mut self) -> Result<(), Violation> {
        if self.fragments > 0 {
            self.run(self.model.transit_steps, Phase::Transit, false)?;
        }
        Ok(())
    }

    /// Deposits `block` as the first block of a new fragment after [`Simulation::transit`]
    /// (the second half of `deposit(b, true)`).
    pub fn deposit_after_transit(&mut self, block: usize) -> Result<(), Violation> {
        self.place(block, true);
        self.run(self.model.deposit_steps(block), Phase::Deposit, false)
    }

    /// Runs on to step `at` of a robot's time line ([`crate::Timeline`]), as a transit (the
    /// arc off between weld paths) when `transit`; steps already run are not run again.
    pub fn run_to(&mut self, at: u64, transit: bool) -> Result<(), Violation> {
        let phase = if transit {
            Phase::Transit
        } else {
            Phase::Deposit
        };
        self.run(at.saturating_sub(self.steps), phase, false)
    }

    /// Deposits `block` at step `at` of a robot's time line, as [`crate::simulate_on`]
    /// does: the steps up to it run first — when it begins a weld path after another, up to
    /// `arc_off` (the step that path's arc went out) with the arc on, then as a transit.
    pub fn deposit_at(
        &mut self,
        block: usize,
        new_fragment: bool,
        arc_off: Option<u64>,
        at: u64,
    ) -> Result<(), Violation> {
        debug_assert!(!self.is_welded[block], "block deposited twice");
        if let (true, Some(off)) = (new_fragment && self.fragments > 0, arc_off) {
            self.run_to(off, false)?;
            self.run_to(at, true)?;
        } else {
            self.run_to(at, false)?;
        }
        self.place(block, new_fragment);
        Ok(())
    }

    /// Whether `block` is welded.
    pub fn is_welded(&self, block: usize) -> bool {
        self.is_welded[block]
    }

    /// The lowest temperature of windowed `block` between 500 and 800 °C since it was last
    /// above 800 °C, °C: how near a block that stays too long in the band came to leaving
    /// it. `None` before it is welded, if it has no window, or if it has not been in the
    /// band since (or the simulation was resumed from a [`BuildState`], which has no record
    /// of it).
    pub fn lowest_in_band_c(&self, block: usize) -> Option<f64> {
        let a = self.w_block.iter().position(|&b| b as usize == block)?;
        Some(self.w_low[a]).filter(|t| t.is_finite())
    }

    /// Runs the cooldown after the last block: steps until every windowed block is below
    /// 500 °C. `Ok(Ok(()))` is a feasible end, `Ok(Err(v))` a violation while cooling.
    pub fn finish(&mut self) -> Result<Result<(), Violation>, NotCooled> {
        if let Err(v) = self.run(self.model.cooldown_steps, Phase::Cooldown, true) {
            return Ok(Err(v));
        }
        if self.cancelled {
            return Ok(Ok(()));
        }
        match self.first_warm() {
            None => Ok(Ok(())),
            Some(a) => Err(NotCooled {
                block: match self.graph {
                    Some(_) => format!("node {}", self.w_block[a]),
                    None => BlockDisplay(self.model.blocks[self.w_block[a] as usize]).to_string(),
                },
                max_cooldown_s: self.model.params.max_cooldown_s,
            }),
        }
    }

    /// Saves the state (temperatures, counters, time) for a later [`Simulation::restore`].
    pub fn snapshot(&self) -> Snapshot {
        let mut s = Snapshot::default();
        self.snapshot_into(&mut s);
        s
    }

    /// [`Simulation::snapshot`] into an existing buffer (no allocation once it is big enough).
    pub fn snapshot_into(&self, s: &mut Snapshot) {
        s.welded = self.welded;
        s.windowed = self.w_slot.len();
        s.fragments = self.fragments;
        s.steps = self.steps;
        s.temps.clear();
        s.temps
            .extend(self.order.iter().map(|&b| self.temp[b as usize + PAD]));
        s.counts.clear();
        s.counts.extend_from_slice(&self.w_count);
        s.crossed.clear();
        s.crossed.extend_from_slice(&self.w_crossed);
        s.lows.clear();
        s.lows.extend_from_slice(&self.w_low);
    }

    /// Returns to a snapshot taken on this simulation while its first `snap.welded()`
    /// blocks were the ones welded now: later deposits are undone.
    pub fn restore(&mut self, snap: &Snapshot) {
        self.truncate(snap.welded);
        debug_assert_eq!(self.w_slot.len(), snap.windowed);
        for (&s, &t) in self.order.iter().zip(&snap.temps) {
            self.temp[s as usize + PAD] = t;
        }
        self.w_count.copy_from_slice(&snap.counts);
        self.w_crossed.copy_from_slice(&snap.crossed);
        self.w_low.copy_from_slice(&snap.lows);
        self.fragments = snap.fragments;
        self.steps = snap.steps;
    }

    /// Rebuilds the state of a snapshot that was taken after depositing
    /// `order[..snap.welded()]` (as (block, new fragment) pairs), on any simulation of
    /// the same model: the way to resume a saved prefix in a new simulation.
    /// Deposits this simulation shares with `order` are kept (only the rest is placed).
    pub fn restore_from_trail(&mut self, snap: &Snapshot, order: &[(usize, bool)]) {
        let common = self
            .order
            .iter()
            .zip(&order[..snap.welded])
            .take_while(|&(&s, &(b, _))| s as usize == b)
            .count();
        self.truncate(common);
        for &(b, new_fragment) in &order[common..snap.welded] {
            self.place(b, new_fragment);
        }
        self.restore(snap);
    }

    /// A graph part's step tables, for the tests that compare states.
    #[cfg(test)]
    pub(crate) fn graph_table(&self) -> Option<&GraphTable> {
        self.graph.as_ref()
    }

    /// Points face `k` of slot `s` at slot `to` (`s` itself: not welded).
    fn link(&mut self, s: usize, k: usize, to: usize) {
        let bit = 1u8 << k;
        if to == s {
            self.welded_faces[s] &= !bit;
        } else {
            self.welded_faces[s] |= bit;
        }
        match k {
            0 | 1 => {}
            2 => self.ny0[s] = to as u32,
            3 => self.ny1[s] = to as u32,
            4 => self.nz0[s] = to as u32,
            _ => self.nz1[s] = to as u32,
        }
    }

    /// Undoes deposits until `welded` blocks remain (temperatures are left as they are:
    /// use [`Simulation::restore`] to go back in time).
    fn truncate(&mut self, welded: usize) {
        let model = self.model;
        let r = model.params.radiation_per_s_k3;
        while self.welded > welded {
            self.welded -= 1;
            let s = self.order.pop().expect("a welded slot") as usize;
            self.starts.pop();
            self.is_welded[s] = false;
            if let (Some(g), Some(gm)) = (&mut self.graph, &model.graph) {
                g.undeposit(gm, s);
            } else {
                for (k, &j) in model.faces[s].iter().enumerate() {
                    let p = j as usize;
                    if j != NONE && self.is_welded[p] {
                        self.link(p, k ^ 1, p);
                        self.exposed[p] += 1;
                        self.radiation[p] = r * self.exposed[p] as f64;
                    }
                    self.link(s, k, s);
                }
            }
            // Unwelded slots inside the stepped range are computed too: keep them tame.
            self.temp[s + PAD] = model.params.ambient_c;
            self.ranges.pop();
            if self.w_slot.last() == Some(&(s as u32)) {
                self.w_slot.pop();
                self.w_lo.pop();
                self.w_hi.pop();
                self.w_over.pop();
                self.w_block.pop();
                self.w_count.pop();
                self.w_crossed.pop();
                self.w_low.pop();
            }
        }
    }

    pub(crate) fn place(&mut self, block: usize, new_fragment: bool) {
        let model = self.model;
        let s = block;
        self.welded += 1;
        self.fragments += new_fragment as usize;
        self.is_welded[s] = true;
        self.order.push(s as u32);
        self.starts.push(new_fragment);
        self.temp[s + PAD] = model.params.deposit_c;
        if let (Some(g), Some(gm)) = (&mut self.graph, &model.graph) {
            g.deposit(gm, block);
        } else {
            self.place_faces(block);
        }
        let (lo, hi) = match self.ranges.last() {
            Some(&(lo, hi)) => (lo.min(s as u32), hi.max(s as u32 + 1)),
            None => (s as u32, s as u32 + 1),
        };
        self.ranges.push((lo, hi));
        if let Some(w) = model.windows[block] {
            self.w_slot.push(s as u32);
            self.w_lo.push(w.min_s);
            self.w_hi.push(w.max_s);
            self.w_over.push(steps_beyond(w.max_s, model.dt));
            self.w_block.push(block as u32);
            self.w_count.push(0);
            self.w_crossed.push(NOT_CROSSED);
            self.w_low.push(f64::INFINITY);
        }
    }

    /// Links a deposited block's faces to its welded neighbours (the block model).
    fn place_faces(&mut self, block: usize) {
        let model = self.model;
        let r = model.params.radiation_per_s_k3;
        let s = block;
        let mut welded_faces = 0u8;
        for (k, &j) in model.faces[block].iter().enumerate() {
            let p = j as usize;
            if j != NONE && self.is_welded[p] {
                self.link(s, k, p);
                self.link(p, k ^ 1, s);
                self.exposed[p] -= 1;
                self.radiation[p] = r * self.exposed[p] as f64;
                welded_faces += 1;
            } else {
                self.link(s, k, s);
            }
        }
        let z0 = model.on_substrate[block];
        self.exposed[s] = 6 - welded_faces - z0 as u8;
        self.radiation[s] = r * self.exposed[s] as f64;
    }

    /// The first windowed block (in deposit order) at or above 500 °C.
    fn first_warm(&self) -> Option<usize> {
        self.w_slot
            .iter()
            .position(|&s| self.temp[s as usize + PAD] >= WARM_C)
    }

    /// Runs up to `n` steps; stops at the first violation. With `cooling`, stops before a
    /// step once every windowed block is below 500 °C.
    pub(crate) fn run(&mut self, n: u64, phase: Phase, cooling: bool) -> Result<(), Violation> {
        let mut warm = cooling && self.first_warm().is_some();
        for _ in 0..n {
            if cooling && !warm {
                return Ok(());
            }
            if let Some(c) = &self.cancel {
                if c.load(Ordering::Relaxed) {
                    self.cancelled = true;
                }
            }
            if self.steps % 256 == 0 && self.deadline.is_some_and(|d| Instant::now() >= d) {
                self.cancelled = true;
            }
            if self.cancelled {
                return Ok(());
            }
            self.step();
            self.steps += 1;
            let (broken, warm_after) = self.judge_windows();
            warm = warm_after;
            if let Some((a, kind)) = broken {
                std::mem::swap(&mut self.temp, &mut self.next);
                return Err(self.violation(a, kind, phase));
            }
            std::mem::swap(&mut self.temp, &mut self.next);
        }
        Ok(())
    }

    /// The step kernel's view of this simulation (raw pointers, for the worker threads).
    fn kernel(&mut self) -> Kernel {
        let p = &self.model.params;
        Kernel {
            t: self.temp[PAD..].as_ptr(),
            out: self.next[PAD..].as_mut_ptr(),
            ny0: self.ny0.as_ptr(),
            ny1: self.ny1.as_ptr(),
            nz0: self.nz0.as_ptr(),
            nz1: self.nz1.as_ptr(),
            welded_faces: self.welded_faces.as_ptr(),
            near: self.model.near.as_ptr(),
            runs: self.model.runs.as_ptr(),
            radiation: self.radiation.as_ptr(),
            h: p.conduction_per_s,
            hs: p.substrate_per_s,
            amb: p.ambient_c,
            q: self.model.ambient_k4,
            dt: self.model.dt,
            n0: self.model.substrate_slots,
            simd: self.model.simd,
        }
    }

    /// One Euler step of every welded block, from `temp` into `next`.
    fn step(&mut self) {
        let Some(&(lo, hi)) = self.ranges.last() else {
            return;
        };
        let (lo, hi) = (lo as usize, hi as usize);
        if let (Some(g), Some(gm)) = (&self.graph, &self.model.graph) {
            // The graph kernel steps whole blocks of 4 slots: the buffers hold
            // `graph_slots` slots after PAD, and slots in the blocks but outside `lo..hi`
            // are unwelded or padding (coefficients +0.0: they keep ambient).
            let (a, b) = graph_blocks(lo, hi);
            let kernel = g.step_over(
                gm,
                self.temp[PAD..].as_ptr(),
                self.next[PAD..].as_mut_ptr(),
                self.model.simd,
            );
            // SAFETY: the tables and both buffers belong to this simulation and outlive
            // the call; `temp` and `next` are distinct vectors of graph_slots + 2·PAD
            // slots, and blocks a..b lie within graph_slots.
            unsafe { kernel.run(a, b) };
            return;
        }
        let kernel = self.kernel();
        if self.threads > 1 && hi - lo >= self.parallel_min.max(1) {
            if let Some(pool) = pool::Pool::acquire(self.threads) {
                pool.run(&kernel, lo, hi);
                return;
            }
        }
        // SAFETY: `kernel` points into this simulation's buffers, which outlive the call;
        // every index it reads is a slot < n (see `Kernel::run`).
        unsafe { kernel.run(lo, hi) };
    }

    /// Updates the t8/5 counters after a step (`temp` before, `next` after) and returns
    /// the broken window of the lowest block index, if any, and whether some windowed block
    /// is still at or above 500 °C.
    fn judge_windows(&mut self) -> (Option<(usize, ViolationKind)>, bool) {
        let dt = self.model.dt;
        let mut warm = false;
        let mut worst: Option<(usize, ViolationKind)> = None;
        // Every window's columns cut to one length: the loop below runs without bounds
        // checks on them (it runs for every windowed block on every step).
        let n = self.w_slot.len();
        let (slots, blocks) = (&self.w_slot[..n], &self.w_block[..n]);
        let (over, lo) = (&self.w_over[..n], &self.w_lo[..n]);
        let (counts, lows) = (&mut self.w_count[..n], &mut self.w_low[..n]);
        let crossed = &mut self.w_crossed[..n];
        let mut keep = |a: usize, kind| match worst {
            Some((b, _)) if blocks[b] <= blocks[a] => {}
            _ => worst = Some((a, kind)),
        };
        for a in 0..n {
            let s = slots[a] as usize + PAD;
            let (u, v) = (self.temp[s], self.next[s]);
            warm |= v >= WARM_C;
            if v > HOT_C {
                counts[a] = 0;
                lows[a] = f64::INFINITY;
            } else if v >= WARM_C {
                counts[a] += 1;
                lows[a] = lows[a].min(v);
                // The same as `count · dt > max_s + TOLERANCE_S`, without the conversion.
                if counts[a] >= over[a] {
                    keep(a, ViolationKind::Max);
                }
            } else if u >= WARM_C {
                let t85_s = counts[a] as f64 * dt;
                let (least, most) = &mut crossed[a];
                *least = (*least).min(counts[a]);
                *most = (*most).max(counts[a]);
                if let Some(c) = &mut self.crossings {
                    c.push(Crossing {
                        block: blocks[a] as usize,
                        t85_s,
                        time_s: self.steps as f64 * dt,
                    });
                }
                if t85_s < lo[a] - TOLERANCE_S {
                    keep(a, ViolationKind::Min);
                }
            }
        }
        (worst, warm)
    }

    fn violation(&self, a: usize, kind: ViolationKind, phase: Phase) -> Violation {
        let dt = self.model.dt;
        Violation {
            block: self.w_block[a] as usize,
            kind,
            window: Window {
                min_s: self.w_lo[a],
                max_s: self.w_hi[a],
            },
            t85_s: self.w_count[a] as f64 * dt,
            step: self.steps,
            time_s: self.steps as f64 * dt,
            prefix_len: self.welded,
            prefix_fragments: self.fragments,
            phase,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{model, WALL};

    #[test]
    fn restore_replays_bit_for_bit() {
        let (part, m) = model(&format!(
            "{WALL}t85: [{{box: {{min: [0,0,0], max: [3,0,1]}}, min_s: 0, max_s: 1000}}]\n"
        ));
        let order: Vec<usize> = (0..part.len()).collect();
        let mut a = Simulation::new(&m);
        for (p, &b) in order.iter().enumerate().take(3) {
            a.deposit(b, p == 0).unwrap();
        }
        let snap = a.snapshot();
        // Go down another branch, then come back and finish the original order.
        a.deposit(order[5], true).unwrap();
        a.deposit(order[4], false).unwrap();
        a.restore(&snap);
        for &b in &order[3..] {
            a.deposit(b, false).unwrap();
        }
        let mut fresh = Simulation::new(&m);
        for (p, &b) in order.iter().enumerate() {
            fresh.deposit(b, p == 0).unwrap();
        }
        let ta: Vec<_> = a.temperatures().collect();
        let tf: Vec<_> = fresh.temperatures().collect();
        assert_eq!(ta, tf);
        assert_eq!(a.steps(), fresh.steps());
        assert_eq!(a.exposed, fresh.exposed);
        // Down to the lowest temperature each windowed block had between 500 and 800 °C.
        let lows = |s: &Simulation| {
            order
                .iter()
                .map(|&b| s.lowest_in_band_c(b))
                .collect::<Vec<_>>()
        };
        assert_eq!(lows(&a), lows(&fresh));
        assert!(lows(&a)
            .iter()
            .flatten()
            .all(|t| (500.0..=800.0).contains(t)));
        assert!(
            lows(&a).iter().any(Option::is_some),
            "a block has been in the band"
        );
    }

    /// More heat is not always hotter in this model, so no clause may be shortened on the
    /// strength of "a later deposit only warms what stands" (issue #12's hint): a block
    /// welded onto the plate beside a finished tower draws the tower's heat into the
    /// substrate, and some seconds later the tower is colder than with no deposit at all.
    #[test]
    fn a_later_deposit_can_leave_a_standing_block_colder() {
        let (part, m) = model(
            "name: fin\nblock_mm: [6,6,2.5]\nmax_fragments: 2\n\
             blocks: [[0,0,0],[0,0,1],[0,0,2],[1,0,0]]\nthermal: {transit_time_s: 1.0}\n",
        );
        let at = |b| part.index_of(b).unwrap();
        let top = at([0, 0, 2]);
        let tower = |sim: &mut Simulation| {
            for (p, b) in [[0, 0, 0], [0, 0, 1], [0, 0, 2]].into_iter().enumerate() {
                sim.deposit(at(b), p == 0).unwrap();
            }
            sim.transit().unwrap();
        };
        let temp = |sim: &Simulation| sim.temperatures().find(|t| t.0 == top).unwrap().1;
        let (mut free, mut fin) = (Simulation::new(&m), Simulation::new(&m));
        tower(&mut free);
        tower(&mut fin);
        fin.deposit_after_transit(at([1, 0, 0])).unwrap();
        free.transit().unwrap(); // the same 20 steps with nothing deposited
        let mut colder = Vec::new();
        for _ in 0..40 {
            assert_eq!(free.steps(), fin.steps());
            if temp(&fin) < temp(&free) - 10.0 {
                colder.push((fin.time_s(), temp(&free), temp(&fin)));
            }
            free.transit().unwrap();
            fin.transit().unwrap();
        }
        assert!(
            !colder.is_empty(),
            "the deposit beside the tower never left its top colder"
        );
    }

    /// The margin a simulation carries is the one of the crossings a recording
    /// simulation holds, also when resumed from a snapshot in another simulation: with
    /// windows whose worst margin is a reheated block's shortest t8/5 (0.8 s of 0.8 and
    /// 4.8 s), and its longest.
    #[test]
    fn the_margin_carried_is_the_margin_of_the_crossings() {
        for (min_s, max_s) in [(0.7, 30.0), (0.5, 5.0)] {
            let (part, m) = model(&format!(
                "{WALL}t85: [{{box: {{min: [0,0,0], max: [3,0,1]}}, min_s: {min_s}, max_s: {max_s}}}]\n"
            ));
            let at = |b| part.index_of(b).unwrap();
            // Two weld paths: the bottom row, then the top row the other way round.
            let plan = vec![
                (0..4).map(|x| at([x, 0, 0])).collect::<Vec<_>>(),
                (0..4).rev().map(|x| at([x, 0, 1])).collect(),
            ];
            let seq: Vec<(usize, bool)> = plan
                .iter()
                .flat_map(|f| f.iter().enumerate().map(|(p, &b)| (b, p == 0)))
                .collect();
            let recorded = crate::simulate(&m, &plan).unwrap();
            assert!(recorded.violation.is_none());
            // Reheated blocks cross 500 °C twice.
            assert!(recorded.crossings.len() > part.len());
            let expected = m.margin(&recorded.crossings);
            let mut whole = Simulation::new(&m);
            let mut snap = None;
            for (d, &(b, new)) in seq.iter().enumerate() {
                whole.deposit(b, new).unwrap();
                if d == 4 {
                    snap = Some(whole.snapshot());
                }
            }
            whole.finish().unwrap().unwrap();
            assert_eq!(whole.margin_s().to_bits(), expected.to_bits());
            let mut resumed = Simulation::new(&m);
            resumed.restore_from_trail(&snap.unwrap(), &seq);
            for &(b, new) in &seq[5..] {
                resumed.deposit(b, new).unwrap();
            }
            resumed.finish().unwrap().unwrap();
            assert_eq!(resumed.margin_s().to_bits(), expected.to_bits());
        }
        let (_, m) = model(WALL);
        assert_eq!(Simulation::new(&m).margin_s(), f64::INFINITY);
    }

    #[test]
    fn resuming_from_a_state_continues_the_simulation_bit_for_bit() {
        let (part, m) = model(&format!(
            "{WALL}t85: [{{box: {{min: [0,0,0], max: [3,0,1]}}, min_s: 0, max_s: 1000}}]\n"
        ));
        let order: Vec<(usize, bool)> = (0..part.len()).map(|b| (b, b == 0 || b == 5)).collect();
        for cut in [1, 3, 5, 7] {
            let mut whole = Simulation::new(&m).recording();
            for &(b, new) in &order[..cut] {
                whole.deposit(b, new).unwrap();
            }
            let state = whole.state();
            assert_eq!(state.order, order[..cut]);
            let mut resumed = Simulation::from_state(&m, &state).unwrap().recording();
            for &(b, new) in &order[cut..] {
                whole.deposit(b, new).unwrap();
                resumed.deposit(b, new).unwrap();
            }
            whole.finish().unwrap().unwrap();
            resumed.finish().unwrap().unwrap();
            let bits = |s: &Simulation| -> Vec<(usize, u64)> {
                s.temperatures().map(|(b, t)| (b, t.to_bits())).collect()
            };
            assert_eq!(bits(&resumed), bits(&whole), "cut after {cut}");
            assert_eq!(resumed.steps(), whole.steps());
            assert_eq!(resumed.fragments(), whole.fragments());
            // The crossings after the cut are the same ones, at the same steps.
            let after: Vec<_> = whole
                .crossings()
                .iter()
                .filter(|c| c.time_s > state.steps as f64 * m.dt)
                .cloned()
                .collect();
            assert_eq!(resumed.crossings(), &after[..]);
        }
    }

    #[test]
    fn a_state_that_does_not_fit_is_refused_with_a_reason() {
        let (_, m) = model(&format!(
            "{WALL}t85: [{{box: {{min: [0,0,0], max: [0,0,0]}}, min_s: 0, max_s: 1000}}]\n"
        ));
        let ok = BuildState {
            order: vec![(0, true), (1, false)],
            temperatures: vec![900.0, 1500.0],
            t85_steps: vec![0],
            steps: 40,
        };
        assert!(Simulation::from_state(&m, &ok).is_ok());
        let err = |s: BuildState| Simulation::from_state(&m, &s).unwrap_err().to_string();
        let e = err(BuildState {
            order: vec![(0, true), (0, false)],
            ..ok.clone()
        });
        assert!(e.contains("welded twice"), "{e}");
        let e = err(BuildState {
            order: vec![(0, true), (99, false)],
            ..ok.clone()
        });
        assert!(e.contains("99 is not in the part"), "{e}");
        let e = err(BuildState {
            temperatures: vec![1.0],
            ..ok.clone()
        });
        assert!(e.contains("1 temperatures for 2"), "{e}");
        let e = err(BuildState {
            temperatures: vec![1.0, f64::NAN],
            ..ok.clone()
        });
        assert!(e.contains("deposit 2"), "{e}");
        let e = err(BuildState {
            t85_steps: vec![],
            ..ok.clone()
        });
        assert!(e.contains("0 t8/5 counters for 1"), "{e}");
    }

    #[test]
    fn transit_steps_come_between_fragments() {
        let (_, m) = model(WALL);
        let mut s = Simulation::new(&m);
        s.deposit(0, true).unwrap();
        s.deposit(1, true).unwrap();
        assert_eq!(s.steps(), 20 + 100 + 20);
    }
}
