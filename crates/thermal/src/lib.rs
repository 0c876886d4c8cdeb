//! The lumped thermal model and the t8/5 check of `shared/spec/thermal-model.md`.
//!
//! One temperature per welded block, explicit Euler, written out to the operation so that
//! two programs agree on every verdict: fluxes are summed in face order (-x, +x, -y, +y,
//! -z, +z), then the substrate term, then radiation, exactly as the spec writes them.
//!
//! The simulator is built for the planner, which runs it millions of times:
//! - block i lives in slot i, in the part's (z, y, x) order, so the ±x neighbours are the
//!   slots beside it and the z = 0 blocks come first; a step covers the slots from the
//!   lowest to the highest welded one (an unwelded slot in between is its own neighbour on
//!   every face and stays at ambient);
//! - every slot keeps its six neighbour slots, an absent neighbour pointing at the slot
//!   itself: `T_self - T_self` is exactly 0, so the inner loop needs no branch;
//! - the stepping loop allocates nothing;
//! - [`Simulation::snapshot`] / [`Simulation::restore`] resume from a saved prefix state.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use thiserror::Error;

use waam_part::graph::{WeldGraph, NONE};
use waam_part::{Block, BlockDisplay, Part, Window};
pub use waam_part::{ThermalParams, MAX_STEPS};

/// Above this a block is hot again and its t8/5 counter restarts, °C.
pub const HOT_C: f64 = 800.0;
/// Below this a block has finished its t8/5 cooling, °C.
pub const WARM_C: f64 = 500.0;
/// Tolerance of every t8/5 comparison, seconds.
pub const TOLERANCE_S: f64 = 1e-9;

/// The least t8/5 count c (whole steps) with `c as f64 * dt > max_s + TOLERANCE_S`, the
/// spec's test of a maximum: c ↦ c·dt rounds monotonically (c < 2^53 converts exactly), so
/// the test holds exactly for the counts from this one on. `u64::MAX` where no count
/// reaches it.
fn steps_beyond(max_s: f64, dt: f64) -> u64 {
    let limit = max_s + TOLERANCE_S;
    let over = |c: u64| c as f64 * dt > limit;
    let guess = limit / dt;
    // Also a NaN limit, which no count passes.
    if guess.is_nan() || guess >= 2f64.powi(52) {
        return u64::MAX;
    }
    let mut c = guess.floor().max(0.0) as u64;
    while c > 0 && over(c - 1) {
        c -= 1;
    }
    while !over(c) {
        c += 1;
    }
    c
}

/// Rounds a non-negative step count, halves away from zero.
fn round_steps(x: f64) -> u64 {
    (x + 0.5).floor() as u64
}

/// What stops a long run early: a deadline, a cancel flag, or both (the default, neither:
/// it runs to its end). The planner's `timeout` and `cancel`, for the stages that
/// simulate after it (check, plot, motion).
#[derive(Debug, Clone, Default)]
pub struct Interrupt {
    pub deadline: Option<Instant>,
    pub cancel: Option<Arc<AtomicBool>>,
}

impl Interrupt {
    /// Stops `timeout` from now (none: never; one too long for a clock: never either).
    pub fn after(timeout: Option<Duration>) -> Interrupt {
        Interrupt {
            deadline: timeout.and_then(|t| Instant::now().checked_add(t)),
            cancel: None,
        }
    }

    /// Also stops once `flag` is raised.
    pub fn with_cancel(mut self, flag: Option<Arc<AtomicBool>>) -> Interrupt {
        self.cancel = flag;
        self
    }

    /// Whether the deadline has passed or the flag is raised.
    pub fn reached(&self) -> bool {
        self.cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
            || self.deadline.is_some_and(|d| Instant::now() >= d)
    }
}

/// Which way a t8/5 window was broken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ViolationKind {
    /// Crossed 500 °C downwards after less than `min_s` between 800 and 500 °C.
    Min,
    /// Spent more than `max_s` between 800 and 500 °C.
    Max,
}

/// Where in the time line a step happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// The steps after depositing a block.
    Deposit,
    /// The steps between two fragments (the earlier fragment is closed).
    Transit,
    /// The steps after the last block (the plan is complete).
    Cooldown,
}

/// The first t8/5 window broken by a plan, and the prefix of the plan that forces it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Violation {
    /// Index of the block whose window is broken.
    pub block: usize,
    pub kind: ViolationKind,
    pub window: Window,
    /// The block's t8/5 time (n·dt) when judged, s.
    pub t85_s: f64,
    /// Steps done, including the violating one.
    pub step: u64,
    /// `step · dt`, s.
    pub time_s: f64,
    /// Blocks deposited when the window broke: the violating prefix.
    pub prefix_len: usize,
    /// Fragments begun when the window broke.
    pub prefix_fragments: usize,
    /// Deposit: the last fragment of the prefix is open; transit or cooldown: it is closed.
    pub phase: Phase,
}

/// One downward crossing of 500 °C by a windowed block.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Crossing {
    pub block: usize,
    /// Time spent between 800 and 500 °C since the block was last above 800 °C, s.
    pub t85_s: f64,
    /// Time of the crossing, s.
    pub time_s: f64,
}

/// A windowed block that was still at or above 500 °C after `max_cooldown_s`.
#[derive(Debug, Clone, Error, PartialEq)]
#[error("block {block} is still at or above 500 °C after max_cooldown_s = {max_cooldown_s} s (thermal constants cannot cool it)")]
pub struct NotCooled {
    pub block: String,
    pub max_cooldown_s: f64,
}

/// The per-part constants of the model, computed once and shared by every simulation.
#[derive(Debug, Clone)]
pub struct ThermalModel {
    pub params: ThermalParams,
    pub dt: f64,
    pub transit_steps: u64,
    pub cooldown_steps: u64,
    /// (ambient + 273.15)^4.
    ambient_k4: f64,
    faces: Vec<[u32; 6]>,
    on_substrate: Vec<bool>,
    /// Per block: its window, if any.
    windows: Vec<Option<Window>>,
    blocks: Vec<Block>,
    /// The z = 0 blocks are the first `substrate_slots` (blocks are sorted by z).
    substrate_slots: usize,
    /// Per slot its ±y / ±z neighbour slots, and where four in a row are consecutive: see
    /// [`neighbour_runs`].
    near: Vec<[u32; 4]>,
    runs: Vec<u8>,
    simd: Simd,
}

/// The ±y / ±z neighbour slots of every slot as the part lays them out, and per slot `s`
/// the bits d (-y, +y, -z, +z) where slots `s..s + 4` have the consecutive neighbours
/// `near[s][d] + 0..4`. In a part whose layers repeat and whose rows span alike, most runs
/// are consecutive: a vector kernel then reads the four neighbours with one load instead of
/// a gather (slow on some CPUs) and keeps the slot's own value where the neighbour is not
/// welded. A missing neighbour gets a stand-in slot that continues the run of the slot
/// before it (its value is never used, only its place).
fn neighbour_runs(faces: &[[u32; 6]]) -> (Vec<[u32; 4]>, Vec<u8>) {
    let n = faces.len();
    let mut near = vec![[0u32; 4]; n];
    for s in 0..n {
        for d in 0..4 {
            near[s][d] = match faces[s][d + 2] {
                NONE => match s.checked_sub(1).map(|p| near[p][d] as usize + 1) {
                    Some(next) if next < n => next as u32,
                    _ => s as u32,
                },
                j => j,
            };
        }
    }
    let runs = (0..n)
        .map(|s| {
            (0..4)
                .filter(|&d| s + 4 <= n && (1..4).all(|j| near[s + j][d] == near[s][d] + j as u32))
                .fold(0u8, |bits, d| bits | 1 << d)
        })
        .collect();
    (near, runs)
}

impl ThermalModel {
    pub fn new(part: &Part, graph: &WeldGraph) -> ThermalModel {
        let params = part.thermal;
        let dt = params.dt();
        // The step reads the ±x neighbours of slot i at i ∓ 1 and the substrate blocks as a
        // prefix: both need the part's (z, y, x) order.
        assert!(
            part.blocks()
                .windows(2)
                .all(|w| (w[0][2], w[0][1], w[0][0]) < (w[1][2], w[1][1], w[1][0])),
            "part blocks must be sorted by (z, y, x)"
        );
        let mut windows = vec![None; part.len()];
        for &(i, w) in part.windows() {
            windows[i] = Some(w);
        }
        let faces: Vec<[u32; 6]> = (0..part.len()).map(|i| graph.faces(i)).collect();
        let (near, runs) = neighbour_runs(&faces);
        ThermalModel {
            params,
            dt,
            transit_steps: round_steps(params.transit_time_s / dt),
            cooldown_steps: round_steps(params.max_cooldown_s / dt),
            // powf, not powi: the same libm pow the reference checker uses.
            ambient_k4: (params.ambient_c + 273.15).powf(4.0),
            faces,
            on_substrate: part.blocks().iter().map(|b| b[2] == 0).collect(),
            windows,
            blocks: part.blocks().to_vec(),
            substrate_slots: part.blocks().partition_point(|b| b[2] == 0),
            near,
            runs,
            simd: Simd::detect(),
        }
    }

    /// The same model stepped by `simd` (the scalar kernel if the CPU lacks it).
    pub fn with_simd(mut self, simd: Simd) -> ThermalModel {
        self.simd = if simd <= Simd::detect() {
            simd
        } else {
            Simd::Scalar
        };
        self
    }

    /// The step kernel in use.
    pub fn simd(&self) -> Simd {
        self.simd
    }

    /// Number of blocks of the part.
    pub fn len(&self) -> usize {
        self.faces.len()
    }

    /// True for a model of no blocks.
    pub fn is_empty(&self) -> bool {
        self.faces.is_empty()
    }

    /// The window of block `i`, if it has one.
    pub fn window(&self, i: usize) -> Option<Window> {
        self.windows[i]
    }

    /// True when some block has a t8/5 window. Without one no plan can break a window, so
    /// every valid plan is feasible with an infinite margin.
    pub fn has_windows(&self) -> bool {
        self.windows.iter().any(Option::is_some)
    }

    /// The same model with every window narrowed by `margin` seconds on both sides: a
    /// plan keeps these windows exactly when every t8/5 value keeps that margin.
    pub fn narrowed(&self, margin: f64) -> ThermalModel {
        let mut m = self.clone();
        for w in m.windows.iter_mut().flatten() {
            w.min_s += margin;
            w.max_s -= margin;
        }
        m
    }

    /// The smallest distance of any t8/5 value to its window's bounds (+inf without
    /// windows): the plan's worst-case margin.
    pub fn margin(&self, crossings: &[Crossing]) -> f64 {
        crossings
            .iter()
            .filter_map(|c| {
                self.windows[c.block].map(|w| (c.t85_s - w.min_s).min(w.max_s - c.t85_s))
            })
            .fold(f64::INFINITY, f64::min)
    }
}

/// A saved simulation state: resume from it with [`Simulation::restore`].
#[derive(Debug, Clone, Default)]
pub struct Snapshot {
    welded: usize,
    windowed: usize,
    fragments: usize,
    steps: u64,
    /// Temperatures of the welded blocks in weld order.
    temps: Vec<f64>,
    counts: Vec<u64>,
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
    }
}

/// Bits of [`Simulation::welded_faces`]: the face-neighbour on that side is welded.
const MINUS_X: u8 = 1;
const PLUS_X: u8 = 2;
/// The ±y / ±z bits: [`MINUS_Y`] << d for d = 0..4 (-y, +y, -z, +z).
const MINUS_Y: u8 = 4;
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
    steps: u64,
    /// Temperatures before / after a step, slot `s` at `s + PAD`.
    temp: Vec<f64>,
    next: Vec<f64>,
    /// -y, +y, -z, +z neighbour slots (the slot itself while that neighbour is unwelded).
    ny0: Vec<u32>,
    ny1: Vec<u32>,
    nz0: Vec<u32>,
    nz1: Vec<u32>,
    /// [`MINUS_X`], [`PLUS_X`], [`MINUS_Y`] << d: that neighbour is welded.
    welded_faces: Vec<u8>,
    /// r · exposed faces, per slot.
    radiation: Vec<f64>,
    exposed: Vec<u8>,
    is_welded: Vec<bool>,
    /// Welded slots in weld order.
    order: Vec<u32>,
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
    crossings: Option<Vec<Crossing>>,
    threads: usize,
    parallel_min: usize,
    cancel: Option<Arc<AtomicBool>>,
    deadline: Option<Instant>,
    cancelled: bool,
}

impl<'m> Simulation<'m> {
    pub fn new(model: &'m ThermalModel) -> Simulation<'m> {
        let n = model.len();
        let slots: Vec<u32> = (0..n as u32).collect();
        Simulation {
            model,
            welded: 0,
            fragments: 0,
            steps: 0,
            temp: vec![model.params.ambient_c; n + 2 * PAD],
            next: vec![model.params.ambient_c; n + 2 * PAD],
            ny0: slots.clone(),
            ny1: slots.clone(),
            nz0: slots.clone(),
            nz1: slots,
            welded_faces: vec![0; n],
            radiation: vec![0.0; n],
            exposed: vec![0; n],
            is_welded: vec![false; n],
            order: Vec::new(),
            ranges: Vec::new(),
            w_slot: Vec::new(),
            w_lo: Vec::new(),
            w_hi: Vec::new(),
            w_over: Vec::new(),
            w_block: Vec::new(),
            w_count: Vec::new(),
            crossings: None,
            threads: default_threads(),
            parallel_min: PARALLEL_MIN_SLOTS,
            cancel: None,
            deadline: None,
            cancelled: false,
        }
    }

    /// Also record every t8/5 crossing (for reports; the planner leaves this off).
    pub fn recording(mut self) -> Self {
        self.crossings = Some(Vec::new());
        self
    }

    /// Steps on up to `threads` threads once the stepped range has at least
    /// [`PARALLEL_MIN_SLOTS`] slots (1: always single-threaded). Results are the same.
    pub fn with_threads(mut self, threads: usize) -> Self {
        self.threads = threads.max(1);
        self
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
        self.run(self.model.params.substeps as u64, Phase::Deposit, false)
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
        self.run(self.model.params.substeps as u64, Phase::Deposit, false)
    }

    /// Whether `block` is welded.
    pub fn is_welded(&self, block: usize) -> bool {
        self.is_welded[block]
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
                block: BlockDisplay(self.model.blocks[self.w_block[a] as usize]).to_string(),
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
            self.is_welded[s] = false;
            for (k, &j) in model.faces[s].iter().enumerate() {
                let p = j as usize;
                if j != NONE && self.is_welded[p] {
                    self.link(p, k ^ 1, p);
                    self.exposed[p] += 1;
                    self.radiation[p] = r * self.exposed[p] as f64;
                }
                self.link(s, k, s);
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
            }
        }
    }

    fn place(&mut self, block: usize, new_fragment: bool) {
        let model = self.model;
        let r = model.params.radiation_per_s_k3;
        let s = block;
        self.welded += 1;
        self.fragments += new_fragment as usize;
        self.is_welded[s] = true;
        self.order.push(s as u32);
        self.temp[s + PAD] = model.params.deposit_c;
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
        }
    }

    /// The first windowed block (in deposit order) at or above 500 °C.
    fn first_warm(&self) -> Option<usize> {
        self.w_slot
            .iter()
            .position(|&s| self.temp[s as usize + PAD] >= WARM_C)
    }

    /// Runs up to `n` steps; stops at the first violation. With `cooling`, stops before a
    /// step once every windowed block is below 500 °C.
    fn run(&mut self, n: u64, phase: Phase, cooling: bool) -> Result<(), Violation> {
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
        let mut keep = |a: usize, kind, w_block: &[u32]| match worst {
            Some((b, _)) if w_block[b] <= w_block[a] => {}
            _ => worst = Some((a, kind)),
        };
        for a in 0..self.w_slot.len() {
            let s = self.w_slot[a] as usize + PAD;
            let (u, v) = (self.temp[s], self.next[s]);
            warm |= v >= WARM_C;
            if v > HOT_C {
                self.w_count[a] = 0;
            } else if v >= WARM_C {
                self.w_count[a] += 1;
                // The same as `count · dt > max_s + TOLERANCE_S`, without the conversion.
                if self.w_count[a] >= self.w_over[a] {
                    keep(a, ViolationKind::Max, &self.w_block);
                }
            } else if u >= WARM_C {
                let t85_s = self.w_count[a] as f64 * dt;
                if let Some(c) = &mut self.crossings {
                    c.push(Crossing {
                        block: self.w_block[a] as usize,
                        t85_s,
                        time_s: self.steps as f64 * dt,
                    });
                }
                if t85_s < self.w_lo[a] - TOLERANCE_S {
                    keep(a, ViolationKind::Min, &self.w_block);
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

/// Which step kernel the CPU runs (chosen once per model by runtime detection).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Simd {
    /// Plain scalar code (any CPU).
    Scalar,
    /// 4 blocks at a time with AVX2 (x86_64 only).
    Avx2,
    /// 8 blocks at a time with AVX-512F (x86_64, built with rustc >= 1.89).
    Avx512,
}

impl Simd {
    /// The best kernel this CPU supports.
    pub fn detect() -> Simd {
        #[cfg(target_arch = "x86_64")]
        {
            if Self::avx512() {
                return Simd::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                return Simd::Avx2;
            }
        }
        Simd::Scalar
    }

    /// Whether the AVX-512 kernel is built (rustc >= 1.89) and the CPU has AVX-512F.
    #[rustversion::since(1.89)]
    fn avx512() -> bool {
        #[cfg(target_arch = "x86_64")]
        return std::arch::is_x86_feature_detected!("avx512f");
        #[allow(unreachable_code)]
        false
    }

    #[rustversion::before(1.89)]
    fn avx512() -> bool {
        false
    }

    /// The kernels this CPU can run, best last.
    pub fn available() -> Vec<Simd> {
        let best = Simd::detect();
        [Simd::Scalar, Simd::Avx2, Simd::Avx512]
            .into_iter()
            .filter(|&s| s <= best)
            .collect()
    }
}

/// Everything one step reads and writes, as raw pointers so that threads can share it.
/// Slot `s`'s temperature is `*t.add(s)`; `t.sub(1)` and `t.add(n)` are padding.
#[derive(Clone, Copy)]
struct Kernel {
    t: *const f64,
    out: *mut f64,
    ny0: *const u32,
    ny1: *const u32,
    nz0: *const u32,
    nz1: *const u32,
    welded_faces: *const u8,
    /// Per slot its ±y / ±z neighbour slots as laid out in the part (a stand-in where the
    /// part has none), and the bits d where slots i..i + 4 have consecutive ones.
    near: *const [u32; 4],
    runs: *const u8,
    radiation: *const f64,
    h: f64,
    hs: f64,
    amb: f64,
    q: f64,
    dt: f64,
    /// Slots `0..n0` are the z = 0 blocks.
    n0: usize,
    simd: Simd,
}

// SAFETY: a `Kernel` is only used while the simulation that made it is borrowed mutably
// by `Simulation::step`, which waits for every thread before returning; the threads write
// disjoint slot ranges of `out` and only read the rest.
unsafe impl Send for Kernel {}
unsafe impl Sync for Kernel {}

impl Kernel {
    /// Steps slots `a..b` (b <= n, the part's block count).
    ///
    /// # Safety
    /// The pointers must be those of a live simulation with n slots, `a <= b <= n`, and no
    /// other thread may touch `out[a..b]`.
    unsafe fn run(&self, a: usize, b: usize) {
        #[cfg(target_arch = "x86_64")]
        match self.simd {
            Simd::Avx512 => return self.range_avx512(a, b),
            Simd::Avx2 => return self.range_avx2(a, b),
            Simd::Scalar => {}
        }
        self.range_scalar(a, b);
    }

    /// Slots `a..b` one at a time. The z = 0 slots have the substrate term h_s; the others
    /// h_s = 0.0 (exactly the value the spec's [z_i = 0] · h_s gives them, so the sum is the
    /// same).
    unsafe fn range_scalar(&self, a: usize, b: usize) {
        let mid = self.n0.clamp(a, b);
        self.segment_scalar(a, mid, self.hs);
        self.segment_scalar(mid, b, 0.0);
    }

    /// The spec's step for one slot, in the spec's order of operations.
    #[inline(always)]
    unsafe fn slot(&self, i: usize, hs: f64) {
        let t = self.t;
        let ti = *t.add(i);
        let xf = *self.welded_faces.add(i);
        let tmx = if xf & MINUS_X != 0 {
            *t.sub(1).add(i)
        } else {
            ti
        };
        let tpx = if xf & PLUS_X != 0 { *t.add(i + 1) } else { ti };
        let tmy = *t.add(*self.ny0.add(i) as usize);
        let tpy = *t.add(*self.ny1.add(i) as usize);
        let tmz = *t.add(*self.nz0.add(i) as usize);
        let tpz = *t.add(*self.nz1.add(i) as usize);
        let h = self.h;
        let mut f = h * (tmx - ti);
        f += h * (tpx - ti);
        f += h * (tmy - ti);
        f += h * (tpy - ti);
        f += h * (tmz - ti);
        f += h * (tpz - ti);
        f += hs * (self.amb - ti);
        let tk = ti + 273.15;
        let t2 = tk * tk;
        f -= *self.radiation.add(i) * (t2 * t2 - self.q);
        *self.out.add(i) = ti + self.dt * f;
    }

    unsafe fn segment_scalar(&self, a: usize, b: usize, hs: f64) {
        for i in a..b {
            self.slot(i, hs);
        }
    }

    /// Slots `a..b` four at a time with AVX2, in one pass: the substrate coefficient is
    /// chosen per lane (h_s below slot n0, 0.0 above, as [`Kernel::range_scalar`] has it)
    /// and a last partial vector is the vector ending at `b`, which computes some slots
    /// twice, to the same values (`out` is not read during a step).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn range_avx2(&self, a: usize, b: usize) {
        if b - a < 4 {
            return self.range_scalar(a, b);
        }
        let mut i = a;
        while i + 4 <= b {
            self.lanes_avx2(i);
            i += 4;
        }
        if i < b {
            self.lanes_avx2(b - 4);
        }
    }

    /// Slots `i..i + 4` (`i + 4 <= n`): the same operations in the same order on each lane
    /// as [`Kernel::slot`] (AVX2 adds, subtracts and multiplies are the IEEE operations of
    /// the scalar code; there is no fused multiply-add). The ±x neighbours are the
    /// contiguous reads beside the slots; a ±y / ±z neighbour is one load where the four
    /// slots' neighbours are consecutive (see [`neighbour_runs`]), else a gather; either
    /// way the slot's own value stands in for an unwelded neighbour.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn lanes_avx2(&self, i: usize) {
        use std::arch::x86_64::*;
        let t = self.t;
        let ti = _mm256_loadu_pd(t.add(i));
        let faces = _mm256_cvtepu8_epi64(_mm_cvtsi32_si128(
            (self.welded_faces.add(i) as *const i32).read_unaligned(),
        ));
        macro_rules! welded {
            ($bit:expr) => {{
                let bit = _mm256_set1_epi64x($bit as i64);
                _mm256_castsi256_pd(_mm256_cmpeq_epi64(_mm256_and_si256(faces, bit), bit))
            }};
        }
        let tmx = _mm256_blendv_pd(ti, _mm256_loadu_pd(t.sub(1).add(i)), welded!(MINUS_X));
        let tpx = _mm256_blendv_pd(ti, _mm256_loadu_pd(t.add(i + 1)), welded!(PLUS_X));
        let runs = *self.runs.add(i);
        let near = &*self.near.add(i);
        macro_rules! neighbour {
            ($d:expr, $slots:expr) => {
                if runs & (1 << $d) != 0 {
                    let v = _mm256_loadu_pd(t.add(near[$d] as usize));
                    _mm256_blendv_pd(ti, v, welded!(MINUS_Y << $d))
                } else {
                    let idx = _mm_loadu_si128($slots.add(i) as *const __m128i);
                    _mm256_i32gather_pd::<8>(t, idx)
                }
            };
        }
        let tmy = neighbour!(0, self.ny0);
        let tpy = neighbour!(1, self.ny1);
        let tmz = neighbour!(2, self.nz0);
        let tpz = neighbour!(3, self.nz1);
        // h_s on the lanes below slot n0, +0.0 on the others.
        let hs_v = if i >= self.n0 {
            _mm256_setzero_pd()
        } else {
            let lane = _mm256_setr_epi64x(i as i64, i as i64 + 1, i as i64 + 2, i as i64 + 3);
            let below = _mm256_cmpgt_epi64(_mm256_set1_epi64x(self.n0 as i64), lane);
            _mm256_and_pd(_mm256_castsi256_pd(below), _mm256_set1_pd(self.hs))
        };
        let h = _mm256_set1_pd(self.h);
        let mut f = _mm256_mul_pd(h, _mm256_sub_pd(tmx, ti));
        f = _mm256_add_pd(f, _mm256_mul_pd(h, _mm256_sub_pd(tpx, ti)));
        f = _mm256_add_pd(f, _mm256_mul_pd(h, _mm256_sub_pd(tmy, ti)));
        f = _mm256_add_pd(f, _mm256_mul_pd(h, _mm256_sub_pd(tpy, ti)));
        f = _mm256_add_pd(f, _mm256_mul_pd(h, _mm256_sub_pd(tmz, ti)));
        f = _mm256_add_pd(f, _mm256_mul_pd(h, _mm256_sub_pd(tpz, ti)));
        f = _mm256_add_pd(
            f,
            _mm256_mul_pd(hs_v, _mm256_sub_pd(_mm256_set1_pd(self.amb), ti)),
        );
        let tk = _mm256_add_pd(ti, _mm256_set1_pd(273.15));
        let t2 = _mm256_mul_pd(tk, tk);
        let re = _mm256_loadu_pd(self.radiation.add(i));
        f = _mm256_sub_pd(
            f,
            _mm256_mul_pd(
                re,
                _mm256_sub_pd(_mm256_mul_pd(t2, t2), _mm256_set1_pd(self.q)),
            ),
        );
        let out = _mm256_add_pd(ti, _mm256_mul_pd(_mm256_set1_pd(self.dt), f));
        _mm256_storeu_pd(self.out.add(i), out);
    }

    /// Slots `a..b` eight at a time in one pass, as [`Kernel::lanes_avx2`] but with the
    /// substrate coefficient per lane (h_s on the z = 0 slots, 0.0 on the others, as
    /// [`Kernel::run`] gives them) and the last, partial vector masked: a small part's step
    /// is a handful of vectors, and the two segments' AVX2 and scalar tails showed in its
    /// profile (ex3 `--all --threads 1`: about 3 % less CPU in all).
    #[cfg(target_arch = "x86_64")]
    #[rustversion::since(1.89)]
    #[target_feature(enable = "avx512f")]
    unsafe fn range_avx512(&self, a: usize, b: usize) {
        let mut i = a;
        while i + 8 <= b {
            let idx = [self.ny0, self.ny1, self.nz0, self.nz1].map(|p| p.add(i));
            self.lanes_avx512(i, 0xff, self.welded_faces.add(i), idx);
            i += 8;
        }
        if i < b {
            // The index arrays end at slot n: the last lanes read copies, padded with
            // slot i itself (a valid slot, read by gathers whose results are not stored).
            let m = b - i;
            let mut xflags = [0u8; 8];
            std::ptr::copy_nonoverlapping(self.welded_faces.add(i), xflags.as_mut_ptr(), m);
            let mut idx = [[i as u32; 8]; 4];
            for (buf, p) in idx.iter_mut().zip([self.ny0, self.ny1, self.nz0, self.nz1]) {
                std::ptr::copy_nonoverlapping(p.add(i), buf.as_mut_ptr(), m);
            }
            let mask = (1u8 << m) - 1;
            self.lanes_avx512(i, mask, xflags.as_ptr(), idx.each_ref().map(|b| b.as_ptr()));
        }
    }

    /// The lanes of `mask` of slots `i..i + 8`; `xflags` and `idx` (±y, ±z neighbours)
    /// point at those slots' entries.
    #[cfg(target_arch = "x86_64")]
    #[rustversion::since(1.89)]
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn lanes_avx512(&self, i: usize, mask: u8, xflags: *const u8, idx: [*const u32; 4]) {
        use std::arch::x86_64::*;
        let t = self.t;
        let h = _mm512_set1_pd(self.h);
        // h_s on the z = 0 lanes, +0.0 on the others.
        let substrate = match self.n0.saturating_sub(i) {
            0 => 0u8,
            n if n >= 8 => 0xff,
            n => (1u8 << n) - 1,
        };
        let hs_v = _mm512_maskz_mov_pd(substrate, _mm512_set1_pd(self.hs));
        let amb = _mm512_set1_pd(self.amb);
        let q = _mm512_set1_pd(self.q);
        let dt = _mm512_set1_pd(self.dt);
        let kelvin = _mm512_set1_pd(273.15);
        let bit_mx = _mm512_set1_epi64(MINUS_X as i64);
        let bit_px = _mm512_set1_epi64(PLUS_X as i64);
        let ti = _mm512_maskz_loadu_pd(mask, t.add(i));
        let xf = _mm512_cvtepu8_epi64(_mm_loadl_epi64(xflags as *const __m128i));
        let m_mx = _mm512_test_epi64_mask(xf, bit_mx) & mask;
        let m_px = _mm512_test_epi64_mask(xf, bit_px) & mask;
        let tmx = _mm512_mask_loadu_pd(ti, m_mx, t.sub(1).add(i));
        let tpx = _mm512_mask_loadu_pd(ti, m_px, t.add(i + 1));
        let gather =
            |p: *const u32| _mm512_i32gather_pd::<8>(_mm256_loadu_si256(p as *const __m256i), t);
        let tmy = gather(idx[0]);
        let tpy = gather(idx[1]);
        let tmz = gather(idx[2]);
        let tpz = gather(idx[3]);
        let mut f = _mm512_mul_pd(h, _mm512_sub_pd(tmx, ti));
        f = _mm512_add_pd(f, _mm512_mul_pd(h, _mm512_sub_pd(tpx, ti)));
        f = _mm512_add_pd(f, _mm512_mul_pd(h, _mm512_sub_pd(tmy, ti)));
        f = _mm512_add_pd(f, _mm512_mul_pd(h, _mm512_sub_pd(tpy, ti)));
        f = _mm512_add_pd(f, _mm512_mul_pd(h, _mm512_sub_pd(tmz, ti)));
        f = _mm512_add_pd(f, _mm512_mul_pd(h, _mm512_sub_pd(tpz, ti)));
        f = _mm512_add_pd(f, _mm512_mul_pd(hs_v, _mm512_sub_pd(amb, ti)));
        let tk = _mm512_add_pd(ti, kelvin);
        let t2 = _mm512_mul_pd(tk, tk);
        let re = _mm512_maskz_loadu_pd(mask, self.radiation.add(i));
        f = _mm512_sub_pd(
            f,
            _mm512_mul_pd(re, _mm512_sub_pd(_mm512_mul_pd(t2, t2), q)),
        );
        _mm512_mask_storeu_pd(
            self.out.add(i),
            mask,
            _mm512_add_pd(ti, _mm512_mul_pd(dt, f)),
        );
    }

    /// Before rustc 1.89 there is no AVX-512 kernel ([`Simd::detect`] never picks it).
    #[cfg(target_arch = "x86_64")]
    #[rustversion::before(1.89)]
    unsafe fn range_avx512(&self, a: usize, b: usize) {
        self.range_avx2(a, b)
    }
}

/// A fixed pool of worker threads for the step, created once per process (on the first
/// step big enough to split) and shared by every simulation; one simulation uses it at a
/// time (another one meanwhile steps on its own thread). Per step the caller publishes the
/// kernel and cuts the slot range into chunks; the caller and the workers claim chunks
/// until none is left, and the caller waits until every chunk is done: one barrier per
/// step. Chunks are claimed, not assigned, so a worker the OS has not scheduled (other
/// processes on the cores) delays nothing: the caller steps its chunks. A worker preempted
/// while it holds a chunk does delay the step; after such a stall (> 0.3 ms) steps run on
/// the caller's thread alone for 0.5 s, doubling (up to 16 s) while stalls keep coming
/// within 30 s of each other, so an oversubscribed machine costs little. Idle workers spin
/// ~50 µs, then sleep on a condition variable.
mod pool {
    use std::cell::UnsafeCell;
    use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
    use std::sync::{Condvar, Mutex, OnceLock};
    use std::time::{Duration, Instant};

    use super::Kernel;

    /// Chunks per thread of one step (more: better balance, more atomics).
    const CHUNKS_PER_THREAD: usize = 4;

    struct Job {
        kernel: Option<Kernel>,
        lo: usize,
        hi: usize,
        chunks: usize,
    }

    struct Shared {
        /// epoch << 32 | first unclaimed chunk << 16 | last unclaimed chunk + 1.
        claim: AtomicU64,
        finished: AtomicUsize,
        sleepers: AtomicUsize,
        lock: Mutex<()>,
        wake: Condvar,
        job: UnsafeCell<Job>,
    }

    // SAFETY: `job` is written only by the pool's owner while no chunk is claimed and
    // unfinished, and read only by a thread holding a claimed, unfinished chunk.
    unsafe impl Sync for Shared {}

    impl Shared {
        /// Claims and steps chunks of `epoch` until none is left: the caller from the
        /// front, the workers from the back, so that with two threads each one mostly
        /// steps the same half of the slots every step (it stays in its core's cache).
        fn work(&self, epoch: u64, front: bool) {
            let mut cur = self.claim.load(Ordering::Acquire);
            loop {
                let (e, lo, hi) = (cur >> 32, (cur >> 16) & 0xffff, cur & 0xffff);
                if e != epoch || lo >= hi {
                    return;
                }
                let (chunk, new) = if front {
                    (lo, cur + (1 << 16))
                } else {
                    (hi - 1, cur - 1)
                };
                match self.claim.compare_exchange_weak(
                    cur,
                    new,
                    Ordering::AcqRel,
                    Ordering::Acquire,
                ) {
                    Ok(_) => {
                        // SAFETY: this chunk of this epoch is ours and unfinished, so the
                        // job is this epoch's and stays as it is.
                        unsafe {
                            let job = &*self.job.get();
                            let (a, b) = cut(job.lo, job.hi, chunk as usize, job.chunks);
                            if let Some(k) = &job.kernel {
                                k.run(a, b);
                            }
                        }
                        self.finished.fetch_add(1, Ordering::Release);
                        cur = self.claim.load(Ordering::Acquire);
                    }
                    Err(now) => cur = now,
                }
            }
        }
    }

    /// Slots of chunk `c` of `chunks` over `lo..hi`, cut at multiples of 8 slots (the
    /// 64-byte lines of the output).
    fn cut(lo: usize, hi: usize, c: usize, chunks: usize) -> (usize, usize) {
        let at = |c: usize| {
            if c == 0 {
                lo
            } else if c == chunks {
                hi
            } else {
                ((lo + (hi - lo) * c / chunks) & !7).clamp(lo, hi)
            }
        };
        (at(c), at(c + 1))
    }

    pub struct Pool {
        shared: &'static Shared,
        workers: usize,
        busy: AtomicBool,
        epoch: AtomicU64,
        /// Steps run on the caller's thread alone until this time ([`clock_ns`]).
        backoff_until: AtomicU64,
        /// Length of the last back-off, ns.
        backoff: AtomicU64,
        /// Start of the current [`WINDOW`] and the time stalls cost in it, ns.
        window_start: AtomicU64,
        window_stalls: AtomicU64,
        /// Time of the last back-off ([`clock_ns`]).
        last_backoff: AtomicU64,
    }

    /// A wait this long for the workers' chunks means a worker was preempted mid-chunk.
    const STALL: Duration = Duration::from_micros(300);
    /// Stalls that cost more than a tenth of such a window mean the cores are
    /// oversubscribed (other processes want them too). A few short stalls are the jitter of
    /// a virtual machine's idle cores (seen twice a second on a 2-vCPU VM, 0.3 ms each):
    /// they cost less than stepping alone would.
    const WINDOW: Duration = Duration::from_millis(250);
    /// After stalls cost too much, steps run single-threaded this long; twice as long after
    /// each back-off that follows the last one within [`QUIET`], up to [`MAX_BACKOFF`].
    const BACKOFF: Duration = Duration::from_millis(500);
    const MAX_BACKOFF: Duration = Duration::from_secs(16);
    const QUIET: Duration = Duration::from_secs(30);

    /// Nanoseconds since the pool's first use.
    fn clock_ns() -> u64 {
        static START: OnceLock<Instant> = OnceLock::new();
        START.get_or_init(Instant::now).elapsed().as_nanos() as u64
    }

    static POOL: OnceLock<Pool> = OnceLock::new();

    /// The exclusive use of the pool until dropped.
    pub struct Guard(&'static Pool, usize);

    impl Drop for Guard {
        fn drop(&mut self) {
            self.0.busy.store(false, Ordering::Release);
        }
    }

    impl Pool {
        /// The pool for a step on `threads` threads (caller included), if it is free.
        pub fn acquire(threads: usize) -> Option<Guard> {
            let pool = POOL.get_or_init(|| {
                let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
                Pool::spawn(cores.saturating_sub(1).max(1))
            });
            if pool.backoff_until.load(Ordering::Relaxed) > clock_ns()
                || pool.busy.swap(true, Ordering::Acquire)
            {
                return None;
            }
            Some(Guard(pool, threads.min(pool.workers + 1)))
        }

        fn spawn(workers: usize) -> Pool {
            let shared: &'static Shared = Box::leak(Box::new(Shared {
                claim: AtomicU64::new(0),
                finished: AtomicUsize::new(0),
                sleepers: AtomicUsize::new(0),
                lock: Mutex::new(()),
                wake: Condvar::new(),
                job: UnsafeCell::new(Job {
                    kernel: None,
                    lo: 0,
                    hi: 0,
                    chunks: 0,
                }),
            }));
            for w in 0..workers {
                std::thread::Builder::new()
                    .name(format!("thermal-{w}"))
                    .spawn(move || worker(shared))
                    .expect("cannot start a simulator thread");
            }
            Pool {
                shared,
                workers,
                busy: AtomicBool::new(false),
                epoch: AtomicU64::new(0),
                backoff_until: AtomicU64::new(0),
                backoff: AtomicU64::new(0),
                window_start: AtomicU64::new(0),
                window_stalls: AtomicU64::new(0),
                last_backoff: AtomicU64::new(0),
            }
        }
    }

    impl Guard {
        /// Steps slots `lo..hi` on the pool's threads and this one.
        pub fn run(&self, kernel: &Kernel, lo: usize, hi: usize) {
            let (pool, threads) = (self.0, self.1);
            let shared = pool.shared;
            let chunks = (threads * CHUNKS_PER_THREAD).min(0xffff);
            // SAFETY: no chunk is claimed and unfinished (the last `run` waited for all).
            unsafe {
                *shared.job.get() = Job {
                    kernel: Some(*kernel),
                    lo,
                    hi,
                    chunks,
                };
            }
            let epoch = (pool.epoch.fetch_add(1, Ordering::Relaxed) + 1) & 0xffff_ffff;
            shared.finished.store(0, Ordering::Relaxed);
            shared
                .claim
                .store(epoch << 32 | chunks as u64, Ordering::SeqCst);
            if shared.sleepers.load(Ordering::SeqCst) > 0 {
                let _g = shared.lock.lock().unwrap_or_else(|e| e.into_inner());
                shared.wake.notify_all();
            }
            shared.work(epoch, true);
            // Spin, never yield: the chunks left are being stepped right now, and a yield
            // on a busy machine hands the core to another process for a whole time slice.
            let mut spins = 0u32;
            let mut waiting: Option<Instant> = None;
            while shared.finished.load(Ordering::Acquire) < chunks {
                std::hint::spin_loop();
                spins += 1;
                if spins % 1024 == 0 {
                    waiting.get_or_insert_with(Instant::now);
                }
            }
            // A long wait for the workers' chunks: a worker holding one lost its core.
            if let Some(waited) = waiting.map(|w| w.elapsed()).filter(|&w| w > STALL) {
                pool.stalled(waited);
            }
        }
    }

    impl Pool {
        /// Counts a stall; when stalls cost more than a tenth of the current window,
        /// stepping alone is faster for a while, the longer the more often it happens.
        fn stalled(&self, waited: Duration) {
            let now = clock_ns();
            let window = WINDOW.as_nanos() as u64;
            if now.saturating_sub(self.window_start.load(Ordering::Relaxed)) > window {
                self.window_start.store(now, Ordering::Relaxed);
                self.window_stalls.store(0, Ordering::Relaxed);
            }
            let cost = self
                .window_stalls
                .fetch_add(waited.as_nanos() as u64, Ordering::Relaxed)
                + waited.as_nanos() as u64;
            if cost <= window / 10 {
                return;
            }
            self.window_stalls.store(0, Ordering::Relaxed);
            let quiet = now.saturating_sub(self.last_backoff.swap(now, Ordering::Relaxed));
            let len = if quiet > QUIET.as_nanos() as u64 {
                BACKOFF.as_nanos() as u64
            } else {
                (self.backoff.load(Ordering::Relaxed) * 2)
                    .clamp(BACKOFF.as_nanos() as u64, MAX_BACKOFF.as_nanos() as u64)
            };
            self.backoff.store(len, Ordering::Relaxed);
            self.backoff_until.store(now + len, Ordering::Relaxed);
        }
    }

    fn worker(shared: &'static Shared) {
        let mut seen = 0u64;
        loop {
            let started = Instant::now();
            let mut spins = 0u32;
            loop {
                let e = shared.claim.load(Ordering::Acquire) >> 32;
                if e != seen {
                    seen = e;
                    break;
                }
                spins += 1;
                if spins % 256 == 0 && started.elapsed() > Duration::from_micros(50) {
                    let mut g = shared.lock.lock().unwrap_or_else(|e| e.into_inner());
                    shared.sleepers.fetch_add(1, Ordering::SeqCst);
                    while shared.claim.load(Ordering::SeqCst) >> 32 == seen {
                        g = shared.wake.wait(g).unwrap_or_else(|e| e.into_inner());
                    }
                    shared.sleepers.fetch_sub(1, Ordering::SeqCst);
                    drop(g);
                } else {
                    std::hint::spin_loop();
                }
            }
            shared.work(seen, false);
        }
    }
}

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
    /// The spec's time line of a plan: every block `substeps` steps, `transit_steps`
    /// between fragments, the arc off right after a fragment's last block.
    pub fn modelled(model: &ThermalModel, fragments: &[Vec<usize>]) -> Timeline {
        let substeps = model.params.substeps as u64;
        let mut now = 0u64;
        let mut deposits = Vec::with_capacity(fragments.len());
        let mut arc_off = Vec::with_capacity(fragments.len());
        for (f, fragment) in fragments.iter().enumerate() {
            if f > 0 {
                now += model.transit_steps;
            }
            deposits.push(
                (0..fragment.len() as u64)
                    .map(|k| now + k * substeps)
                    .collect(),
            );
            now += fragment.len() as u64 * substeps;
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

    fn model(text: &str) -> (Part, ThermalModel) {
        let part = Part::parse(text).unwrap();
        let graph = WeldGraph::new(&part);
        let model = ThermalModel::new(&part, &graph);
        (part, model)
    }

    const WALL: &str = "name: w\nblock_mm: [6,6,2.5]\nmax_fragments: 2\nlayers: ['####', '####']\n";

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

    #[test]
    fn transit_steps_come_between_fragments() {
        let (_, m) = model(WALL);
        let mut s = Simulation::new(&m);
        s.deposit(0, true).unwrap();
        s.deposit(1, true).unwrap();
        assert_eq!(s.steps(), 20 + 100 + 20);
    }
}

/// The bit-identity test: the fast step (slots, SIMD, threads) against a plain scalar
/// reference of the spec's step on random parts, plans and constants.
#[cfg(test)]
mod identity {
    use super::*;
    use proptest::prelude::*;

    /// The spec's step written plainly: one temperature per block, a neighbour that is
    /// absent or not welded read as T_i, the fluxes summed in face order (-x, +x, -y, +y,
    /// -z, +z), then the substrate term, then radiation (r · e_i) · ((T+273.15)²)² − q).
    struct Reference<'m> {
        m: &'m ThermalModel,
        temp: Vec<f64>,
        welded: Vec<bool>,
        fragments: usize,
        steps: u64,
    }

    impl<'m> Reference<'m> {
        fn new(m: &'m ThermalModel) -> Self {
            Reference {
                m,
                temp: vec![0.0; m.len()],
                welded: vec![false; m.len()],
                fragments: 0,
                steps: 0,
            }
        }

        fn step(&mut self) {
            let p = &self.m.params;
            let (h, amb, q, dt) = (
                p.conduction_per_s,
                p.ambient_c,
                self.m.ambient_k4,
                self.m.dt,
            );
            let old = self.temp.clone();
            for i in (0..old.len()).filter(|&i| self.welded[i]) {
                let ti = old[i];
                let faces = self.m.faces[i];
                let on = |k: usize| faces[k] != NONE && self.welded[faces[k] as usize];
                let t = |k: usize| if on(k) { old[faces[k] as usize] } else { ti };
                let mut f = h * (t(0) - ti);
                for k in 1..6 {
                    f += h * (t(k) - ti);
                }
                let z0 = self.m.on_substrate[i];
                let hs = if z0 { p.substrate_per_s } else { 0.0 };
                f += hs * (amb - ti);
                let e = 6 - (0..6).filter(|&k| on(k)).count() as u8 - z0 as u8;
                let tk = ti + 273.15;
                let t2 = tk * tk;
                f -= (p.radiation_per_s_k3 * e as f64) * (t2 * t2 - q);
                self.temp[i] = ti + dt * f;
            }
            self.steps += 1;
        }

        fn deposit(&mut self, b: usize, new_fragment: bool) {
            if new_fragment && self.fragments > 0 {
                for _ in 0..self.m.transit_steps {
                    self.step();
                }
            }
            self.fragments += new_fragment as usize;
            self.welded[b] = true;
            self.temp[b] = self.m.params.deposit_c;
            for _ in 0..self.m.params.substeps {
                self.step();
            }
        }

        /// (block, temperature bits) of the welded blocks, by block.
        fn state(&self) -> Vec<(usize, u64)> {
            (0..self.temp.len())
                .filter(|&i| self.welded[i])
                .map(|i| (i, self.temp[i].to_bits()))
                .collect()
        }
    }

    fn state(sim: &Simulation<'_>) -> Vec<(usize, u64)> {
        let mut v: Vec<_> = sim.temperatures().map(|(b, t)| (b, t.to_bits())).collect();
        v.sort_unstable();
        v
    }

    prop_compose! {
        fn case()(
            dims in (1i64..7, 1i64..6, 1i64..6),
            fill in proptest::collection::vec(any::<u8>(), 6 * 5 * 5),
            density in 96u8..=255,
            seed in any::<u64>(),
            news in proptest::collection::vec(any::<u8>(), 150),
            h in 0.0f64..3.0,
            hs in 0.0f64..3.0,
            r in 0.0f64..5e-12,
            ambient in -30.0f64..120.0,
            deposit in 300.0f64..3000.0,
            substeps in 1u32..25,
            block_time in 0.2f64..2.0,
            transit in 0.0f64..6.0,
        ) -> (Part, Vec<(usize, bool)>) {
            let (nx, ny, nz) = dims;
            let mut blocks = Vec::new();
            for z in 0..nz {
                for y in 0..ny {
                    for x in 0..nx {
                        if fill[(z * 30 + y * 6 + x) as usize] <= density {
                            blocks.push([x, y, z]);
                        }
                    }
                }
            }
            if blocks.is_empty() {
                blocks.push([0, 0, 0]);
            }
            let mut part = Part::from_blocks("p".into(), [6.0, 6.0, 2.5], [0.0; 3], 3, blocks)
                .expect("a generated part");
            part.thermal = ThermalParams {
                ambient_c: ambient,
                deposit_c: deposit,
                block_time_s: block_time,
                substeps,
                transit_time_s: transit,
                conduction_per_s: h,
                substrate_per_s: hs,
                radiation_per_s_k3: r,
                max_cooldown_s: 0.0,
            };
            // A random deposit order (any order: the simulator does not check plans).
            let mut order: Vec<usize> = (0..part.len()).collect();
            let mut x = seed | 1;
            for i in (1..order.len()).rev() {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                order.swap(i, (x % (i as u64 + 1)) as usize);
            }
            let seq = order
                .into_iter()
                .enumerate()
                .map(|(p, b)| (b, p == 0 || news[p] < 40))
                .collect();
            (part, seq)
        }
    }

    proptest! {
        /// The integer threshold of a maximum is the spec's float test, count for count.
        #[test]
        fn steps_beyond_is_the_float_test(
            max_s in prop_oneof![0.0f64..400.0, -5.0f64..0.0, Just(f64::INFINITY)],
            dt in 1e-4f64..2.0,
        ) {
            let c = steps_beyond(max_s, dt);
            let over = |c: u64| c as f64 * dt > max_s + TOLERANCE_S;
            if c == u64::MAX {
                prop_assert!(!over(1 << 52));
            } else {
                prop_assert!(over(c));
                prop_assert!(c == 0 || !over(c - 1));
                for k in c.saturating_sub(50)..c + 50 {
                    prop_assert_eq!(over(k), k >= c);
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]
        #[test]
        fn fast_step_is_bit_identical_to_the_reference((part, seq) in case()) {
            let graph = WeldGraph::new(&part);
            let model = ThermalModel::new(&part, &graph);
            let kernels: Vec<ThermalModel> =
                Simd::available().into_iter().map(|s| model.clone().with_simd(s)).collect();
            let mut reference = Reference::new(&model);
            let mut sims: Vec<Simulation<'_>> = kernels
                .iter()
                .map(|m| Simulation::new(m).with_threads(1))
                .collect();
            sims.push(Simulation::new(&model).with_threads(2).with_parallel_min(0));
            let mut snaps = Vec::new();
            for &(b, new) in &seq {
                reference.deposit(b, new);
                let want = reference.state();
                for sim in &mut sims {
                    sim.deposit(b, new).unwrap();
                    prop_assert_eq!(sim.steps(), reference.steps);
                    prop_assert_eq!(&state(sim), &want);
                }
                snaps.push((sims[0].snapshot(), want));
            }
            // Back to a random earlier prefix and forward again: the same bits.
            let back = seq.len() / 2;
            let (snap, want) = &snaps[back];
            for sim in &mut sims {
                sim.restore(snap);
                prop_assert_eq!(&state(sim), want);
            }
            let mut fresh = Simulation::new(&model);
            fresh.restore_from_trail(snap, &seq);
            prop_assert_eq!(&state(&fresh), want);
            for &(b, new) in &seq[back + 1..] {
                fresh.deposit(b, new).unwrap();
            }
            prop_assert_eq!(state(&fresh), reference.state());
        }
    }

    /// The radiation term is ((T + 273.15)²)², not powi(4) or powf(4): the same bits as
    /// the simulator has always computed (and powf only for the ambient constant).
    #[test]
    fn radiation_is_the_square_of_the_square() {
        for t in [20.0f64, 500.0, 800.0, 2500.0, 1234.5678] {
            let tk = t + 273.15;
            let t2 = tk * tk;
            assert_eq!((t2 * t2).to_bits(), (tk * tk * (tk * tk)).to_bits());
        }
    }
}
