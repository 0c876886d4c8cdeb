//! The lumped thermal model and the t8/5 check of `shared/spec/thermal-model.md`.
//!
//! One temperature per welded block, explicit Euler, written out to the operation so that
//! two programs agree on every verdict: fluxes are summed in face order (-x, +x, -y, +y,
//! -z, +z), then the substrate term, then radiation, exactly as the spec writes them.
//!
//! The simulator is built for the planner, which runs it millions of times:
//! - blocks live in *slots* in weld order, so the welded set is always slots `0..m`;
//! - every slot keeps its six neighbour slots, an absent neighbour pointing at the slot
//!   itself: `T_self - T_self` is exactly 0, so the inner loop needs no branch;
//! - the stepping loop allocates nothing;
//! - [`Simulation::snapshot`] / [`Simulation::restore`] resume from a saved prefix state.

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

/// Rounds a non-negative step count, halves away from zero.
fn round_steps(x: f64) -> u64 {
    (x + 0.5).floor() as u64
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
}

impl ThermalModel {
    pub fn new(part: &Part, graph: &WeldGraph) -> ThermalModel {
        let params = part.thermal;
        let dt = params.dt();
        let mut windows = vec![None; part.len()];
        for &(i, w) in part.windows() {
            windows[i] = Some(w);
        }
        ThermalModel {
            params,
            dt,
            transit_steps: round_steps(params.transit_time_s / dt),
            cooldown_steps: round_steps(params.max_cooldown_s / dt),
            // powf, not powi: the same libm pow the reference checker uses.
            ambient_k4: (params.ambient_c + 273.15).powf(4.0),
            faces: (0..part.len()).map(|i| graph.faces(i)).collect(),
            on_substrate: part.blocks().iter().map(|b| b[2] == 0).collect(),
            windows,
            blocks: part.blocks().to_vec(),
        }
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
    temps: Vec<f64>,
    counts: Vec<u64>,
}

impl Snapshot {
    /// Blocks deposited at the time of the snapshot.
    pub fn welded(&self) -> usize {
        self.welded
    }
}

/// A running simulation of one plan prefix.
#[derive(Debug, Clone)]
pub struct Simulation<'m> {
    model: &'m ThermalModel,
    /// Welded slots: `0..welded`.
    welded: usize,
    fragments: usize,
    steps: u64,
    temp: Vec<f64>,
    next: Vec<f64>,
    neighbours: Vec<[u32; 6]>,
    substrate: Vec<f64>,
    radiation: Vec<f64>,
    exposed: Vec<u8>,
    block_of_slot: Vec<u32>,
    slot_of_block: Vec<u32>,
    // Windowed blocks in deposit order: slot, bounds, block, t8/5 counter (whole steps).
    w_slot: Vec<u32>,
    w_lo: Vec<f64>,
    w_hi: Vec<f64>,
    w_block: Vec<u32>,
    w_count: Vec<u64>,
    crossings: Option<Vec<Crossing>>,
}

impl<'m> Simulation<'m> {
    pub fn new(model: &'m ThermalModel) -> Simulation<'m> {
        let n = model.len();
        Simulation {
            model,
            welded: 0,
            fragments: 0,
            steps: 0,
            temp: vec![0.0; n],
            next: vec![0.0; n],
            neighbours: vec![[0; 6]; n],
            substrate: vec![0.0; n],
            radiation: vec![0.0; n],
            exposed: vec![0; n],
            block_of_slot: vec![NONE; n],
            slot_of_block: vec![NONE; n],
            w_slot: Vec::new(),
            w_lo: Vec::new(),
            w_hi: Vec::new(),
            w_block: Vec::new(),
            w_count: Vec::new(),
            crossings: None,
        }
    }

    /// Also record every t8/5 crossing (for reports; the planner leaves this off).
    pub fn recording(mut self) -> Self {
        self.crossings = Some(Vec::new());
        self
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
        (0..self.welded).map(|s| (self.block_of_slot[s] as usize, self.temp[s]))
    }

    /// Deposits `block` (beginning a new fragment if `new_fragment`) and runs its steps.
    /// A new fragment after the first is preceded by the transit steps.
    pub fn deposit(&mut self, block: usize, new_fragment: bool) -> Result<(), Violation> {
        debug_assert!(self.slot_of_block[block] == NONE, "block deposited twice");
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
        self.slot_of_block[block] != NONE
    }

    /// Runs the cooldown after the last block: steps until every windowed block is below
    /// 500 °C. `Ok(Ok(()))` is a feasible end, `Ok(Err(v))` a violation while cooling.
    pub fn finish(&mut self) -> Result<Result<(), Violation>, NotCooled> {
        if let Err(v) = self.run(self.model.cooldown_steps, Phase::Cooldown, true) {
            return Ok(Err(v));
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
        s.temps.extend_from_slice(&self.temp[..self.welded]);
        s.counts.clear();
        s.counts.extend_from_slice(&self.w_count);
    }

    /// Returns to a snapshot taken on this simulation while its first `snap.welded()`
    /// blocks were the ones welded now: later deposits are undone.
    pub fn restore(&mut self, snap: &Snapshot) {
        self.truncate(snap.welded);
        debug_assert_eq!(self.w_slot.len(), snap.windowed);
        self.temp[..snap.welded].copy_from_slice(&snap.temps);
        self.w_count.copy_from_slice(&snap.counts);
        self.fragments = snap.fragments;
        self.steps = snap.steps;
    }

    /// Rebuilds the state of a snapshot that was taken after depositing
    /// `order[..snap.welded()]` (as (block, new fragment) pairs), on any simulation of
    /// the same model: the way to resume a saved prefix in a new simulation.
    pub fn restore_from_trail(&mut self, snap: &Snapshot, order: &[(usize, bool)]) {
        self.truncate(0);
        for &(b, new_fragment) in &order[..snap.welded] {
            self.place(b, new_fragment);
        }
        self.restore(snap);
    }

    /// Undoes deposits until `welded` blocks remain (temperatures are left as they are:
    /// use [`Simulation::restore`] to go back in time).
    fn truncate(&mut self, welded: usize) {
        let r = self.model.params.radiation_per_s_k3;
        while self.welded > welded {
            self.welded -= 1;
            let s = self.welded;
            for k in 0..6 {
                let p = self.neighbours[s][k] as usize;
                if p != s {
                    self.neighbours[p][k ^ 1] = p as u32;
                    self.exposed[p] += 1;
                    self.radiation[p] = r * self.exposed[p] as f64;
                }
            }
            let b = self.block_of_slot[s] as usize;
            self.slot_of_block[b] = NONE;
            self.block_of_slot[s] = NONE;
            if self.w_slot.last() == Some(&(s as u32)) {
                self.w_slot.pop();
                self.w_lo.pop();
                self.w_hi.pop();
                self.w_block.pop();
                self.w_count.pop();
            }
        }
    }

    fn place(&mut self, block: usize, new_fragment: bool) {
        let model = self.model;
        let r = model.params.radiation_per_s_k3;
        let s = self.welded;
        self.welded += 1;
        self.fragments += new_fragment as usize;
        self.slot_of_block[block] = s as u32;
        self.block_of_slot[s] = block as u32;
        self.temp[s] = model.params.deposit_c;
        let mut welded_faces = 0u8;
        for (k, &j) in model.faces[block].iter().enumerate() {
            let p = if j == NONE {
                NONE
            } else {
                self.slot_of_block[j as usize]
            };
            if p == NONE {
                self.neighbours[s][k] = s as u32;
            } else {
                let p = p as usize;
                self.neighbours[s][k] = p as u32;
                self.neighbours[p][k ^ 1] = s as u32;
                self.exposed[p] -= 1;
                self.radiation[p] = r * self.exposed[p] as f64;
                welded_faces += 1;
            }
        }
        let z0 = model.on_substrate[block];
        self.substrate[s] = if z0 {
            model.params.substrate_per_s
        } else {
            0.0
        };
        self.exposed[s] = 6 - welded_faces - z0 as u8;
        self.radiation[s] = r * self.exposed[s] as f64;
        if let Some(w) = model.windows[block] {
            self.w_slot.push(s as u32);
            self.w_lo.push(w.min_s);
            self.w_hi.push(w.max_s);
            self.w_block.push(block as u32);
            self.w_count.push(0);
        }
    }

    /// The first windowed block (in deposit order) at or above 500 °C.
    fn first_warm(&self) -> Option<usize> {
        self.w_slot
            .iter()
            .position(|&s| self.temp[s as usize] >= WARM_C)
    }

    /// Runs up to `n` steps; stops at the first violation. With `cooling`, stops before a
    /// step once every windowed block is below 500 °C.
    fn run(&mut self, n: u64, phase: Phase, cooling: bool) -> Result<(), Violation> {
        for _ in 0..n {
            if cooling && self.first_warm().is_none() {
                return Ok(());
            }
            self.step();
            self.steps += 1;
            if let Some((a, kind)) = self.judge_windows() {
                std::mem::swap(&mut self.temp, &mut self.next);
                return Err(self.violation(a, kind, phase));
            }
            std::mem::swap(&mut self.temp, &mut self.next);
        }
        Ok(())
    }

    /// One Euler step of every welded block, from `temp` into `next`.
    fn step(&mut self) {
        let m = self.welded;
        let p = &self.model.params;
        let (h, amb, q, dt) = (
            p.conduction_per_s,
            p.ambient_c,
            self.model.ambient_k4,
            self.model.dt,
        );
        let temp = &self.temp[..m];
        let next = &mut self.next[..m];
        let nb = &self.neighbours[..m];
        let hs = &self.substrate[..m];
        let re = &self.radiation[..m];
        for i in 0..m {
            let ti = temp[i];
            let n = nb[i];
            // Every neighbour slot is < m (absent ones point at i itself): `place` and
            // `truncate` keep that invariant, so the unchecked reads stay in bounds.
            let t = |k: usize| unsafe { *temp.get_unchecked(n[k] as usize) };
            // Absent neighbours point at slot i itself: their term is exactly 0.
            let mut f = h * (t(0) - ti);
            f += h * (t(1) - ti);
            f += h * (t(2) - ti);
            f += h * (t(3) - ti);
            f += h * (t(4) - ti);
            f += h * (t(5) - ti);
            f += hs[i] * (amb - ti);
            let t = ti + 273.15;
            let t2 = t * t;
            f -= re[i] * (t2 * t2 - q);
            next[i] = ti + dt * f;
        }
    }

    /// Updates the t8/5 counters after a step (`temp` before, `next` after) and returns
    /// the broken window of the lowest block index, if any.
    fn judge_windows(&mut self) -> Option<(usize, ViolationKind)> {
        let dt = self.model.dt;
        let mut worst: Option<(usize, ViolationKind)> = None;
        let mut keep = |a: usize, kind, w_block: &[u32]| match worst {
            Some((b, _)) if w_block[b] <= w_block[a] => {}
            _ => worst = Some((a, kind)),
        };
        for a in 0..self.w_slot.len() {
            let s = self.w_slot[a] as usize;
            let (u, v) = (self.temp[s], self.next[s]);
            if v > HOT_C {
                self.w_count[a] = 0;
            } else if v >= WARM_C {
                self.w_count[a] += 1;
                if self.w_count[a] as f64 * dt > self.w_hi[a] + TOLERANCE_S {
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
        worst
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
    let mut sim = Simulation::new(model).recording();
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
    Ok(Outcome {
        violation,
        steps: sim.steps(),
        time_s: sim.time_s(),
        crossings: sim.crossings.take().unwrap_or_default(),
    })
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

    #[test]
    fn transit_steps_come_between_fragments() {
        let (_, m) = model(WALL);
        let mut s = Simulation::new(&m);
        s.deposit(0, true).unwrap();
        s.deposit(1, true).unwrap();
        assert_eq!(s.steps(), 20 + 100 + 20);
    }
}
