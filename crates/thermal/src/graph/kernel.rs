//! The fast step of the graph model, bit for bit [`GraphReference`](super::GraphReference).
//!
//! Layout: node i lives in slot i; slots are padded to a multiple of 4 (a *block*, one
//! AVX2 vector). Every slot has D = max degree *columns*, column k its k-th contact in
//! contact-list order (the doc's order of summation), stored per block as 4 lanes
//! (`[block][column][lane]`, so a block's table is one contiguous run of memory):
//! - the neighbour slot and the coefficient g_ik, while both ends are welded;
//! - otherwise the slot itself and +0.0: the term is `0.0 * (T_i - T_i) = +0.0`, and
//!   adding +0.0 to a flux that starts at +0.0 (so is never -0.0) changes no bit: the loop
//!   needs no branch, and unwelded slots inside the stepped range keep their temperature.
//!
//! Per block a bit mask marks the columns whose four neighbour slots are consecutive
//! (along a contour, or to the layer below, when slots follow the contours): those are
//! one load instead of a gather.

use std::sync::atomic::{AtomicU64, Ordering};

use super::{GraphModel, NodeGeometry};
use crate::{Simd, ThermalParams};

/// Lanes of a block (one AVX2 vector of f64).
const LANES: usize = 4;

/// A `step(n)` runs on several threads once n × stepped slots reaches this: the threads
/// are started per call (~50 µs), which a few hundred thousand node-steps repay.
pub const GRAPH_PARALLEL_MIN_WORK: u64 = 1 << 18;

/// Chunks per thread of one threaded step (more: better balance, more atomics).
const CHUNKS_PER_THREAD: usize = 4;

/// The step's per-slot tables of a set of welded nodes: what a deposit changes, apart
/// from the deposited node's temperature. [`GraphSimulation`] keeps one next to its
/// temperatures; the planner's `Simulation` keeps one next to its own (it steps them over
/// its temperature buffers, so snapshots and its t8/5 counters read them as for blocks).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct GraphTable {
    /// Columns per slot: the model's largest degree.
    cols: usize,
    /// `[block][column][lane]`: neighbour slot (the slot itself while inactive) and g_ik
    /// (+0.0 while inactive).
    nbr: Vec<u32>,
    coef: Vec<f64>,
    /// Per block: columns in use (the largest degree of its four nodes).
    used: Vec<u32>,
    /// Per block: bit k set where column k's four neighbour slots are consecutive.
    runs: Vec<u64>,
    /// Per slot s_i and ρ_i, +0.0 while unwelded.
    substrate: Vec<f64>,
    radiation: Vec<f64>,
    welded: Vec<bool>,
}

/// Slots of a model of `n` nodes: padded to whole blocks of 4.
pub(crate) fn graph_slots(n: usize) -> usize {
    n.div_ceil(LANES) * LANES
}

/// Blocks of 4 slots covering slots `lo..hi`.
pub(crate) fn graph_blocks(lo: usize, hi: usize) -> (usize, usize) {
    (lo / LANES, hi.div_ceil(LANES))
}

impl GraphTable {
    /// Every node unwelded.
    pub(crate) fn new(model: &GraphModel) -> GraphTable {
        let n = model.len();
        let slots = graph_slots(n);
        let blocks = slots / LANES;
        let cols = model.max_degree();
        let mut nbr = vec![0u32; slots * cols];
        for b in 0..blocks {
            for k in 0..cols {
                for l in 0..LANES {
                    nbr[(b * cols + k) * LANES + l] = (b * LANES + l) as u32;
                }
            }
        }
        let used = (0..blocks)
            .map(|b| {
                (b * LANES..((b + 1) * LANES).min(n))
                    .map(|i| model.links(i).len() as u32)
                    .max()
                    .unwrap_or(0)
            })
            .collect();
        // Self-pointers are consecutive in every column; the bits `update_runs` computes
        // (none above the columns), so that an undeposit restores the table exactly.
        let all = if cols >= 64 {
            u64::MAX
        } else {
            (1u64 << cols) - 1
        };
        GraphTable {
            cols,
            nbr,
            coef: vec![0.0; slots * cols],
            used,
            runs: vec![all; blocks],
            substrate: vec![0.0; slots],
            radiation: vec![0.0; slots],
            welded: vec![false; n],
        }
    }

    /// Makes `node` welded and its contacts to welded nodes active, recomputing ρ of the
    /// node and of its welded neighbours (the temperature is the caller's).
    ///
    /// # Panics
    /// If `node` is already welded.
    pub(crate) fn deposit(&mut self, m: &GraphModel, node: usize) {
        assert!(!self.welded[node], "node {node} deposited twice");
        self.welded[node] = true;
        self.substrate[node] = m.substrate[node];
        self.relink(m, node, true);
    }

    /// The exact inverse of [`Self::deposit`] of `node`, the last node deposited or any
    /// other welded one: its contacts inactive again, ρ of its welded neighbours recomputed
    /// from the welded set as the deposit did, its own s_i and ρ_i +0.0.
    ///
    /// # Panics
    /// If `node` is not welded.
    pub(crate) fn undeposit(&mut self, m: &GraphModel, node: usize) {
        assert!(self.welded[node], "node {node} undeposited but not welded");
        self.welded[node] = false;
        self.substrate[node] = 0.0;
        self.relink(m, node, false);
        self.radiation[node] = 0.0;
    }

    /// Points the columns of `node`'s contacts with welded nodes (both ends) at each other
    /// (`on`) or back at themselves, and recomputes the radiation terms that change.
    fn relink(&mut self, m: &GraphModel, node: usize, on: bool) {
        let first = m.start[node] as usize;
        for (k, l) in m.links(node).iter().enumerate() {
            let j = l.other as usize;
            if !self.welded[j] {
                continue;
            }
            let back = m.mirror[first + k] as usize;
            let kj = back - m.start[j] as usize;
            if on {
                self.activate(node, k, j, l.coef);
                self.activate(j, kj, node, m.links[back].coef);
            } else {
                self.activate(node, k, node, 0.0);
                self.activate(j, kj, j, 0.0);
            }
            self.radiation[j] = m.radiation(j, |o| self.welded[o as usize]);
            self.update_runs(j / LANES);
        }
        if on {
            self.radiation[node] = m.radiation(node, |o| self.welded[o as usize]);
        }
        self.update_runs(node / LANES);
    }

    /// Points column `k` of slot `i` at slot `j` with coefficient `g`.
    fn activate(&mut self, i: usize, k: usize, j: usize, g: f64) {
        let at = ((i / LANES) * self.cols + k) * LANES + i % LANES;
        self.nbr[at] = j as u32;
        self.coef[at] = g;
    }

    fn update_runs(&mut self, b: usize) {
        let mut bits = 0u64;
        for k in 0..self.cols.min(64) {
            let at = (b * self.cols + k) * LANES;
            let s = &self.nbr[at..at + LANES];
            if (1..LANES).all(|l| s[l] == s[0] + l as u32) {
                bits |= 1 << k;
            }
        }
        self.runs[b] = bits;
    }

    /// Whether `node` is welded.
    pub(crate) fn is_welded(&self, node: usize) -> bool {
        self.welded[node]
    }

    /// The step from `t` into `out` (slot i at `t[i]`, [`graph_slots`] slots each).
    ///
    /// The pointers must stay valid and the buffers keep their sizes for as long as the
    /// returned [`GraphStep`] runs, and `out` must not alias `t`: see [`GraphStep::run`].
    pub(crate) fn step_over(
        &self,
        m: &GraphModel,
        t: *const f64,
        out: *mut f64,
        simd: Simd,
    ) -> GraphStep {
        GraphStep {
            t,
            out,
            nbr: self.nbr.as_ptr(),
            coef: self.coef.as_ptr(),
            used: self.used.as_ptr(),
            runs: self.runs.as_ptr(),
            substrate: self.substrate.as_ptr(),
            radiation: self.radiation.as_ptr(),
            cols: self.cols,
            amb: m.params.ambient_c,
            q: m.ambient_k4,
            dt: m.dt,
            simd: best_simd(simd),
        }
    }
}

/// The kernels built here: AVX2 covers an AVX-512 CPU too.
pub(crate) fn best_simd(simd: Simd) -> Simd {
    if simd >= Simd::Avx2 {
        Simd::Avx2
    } else {
        Simd::Scalar
    }
}

/// A running simulation of the graph model with the fast step.
#[derive(Debug, Clone)]
pub struct GraphSimulation<'m> {
    model: &'m GraphModel,
    simd: Simd,
    pub(super) table: GraphTable,
    /// Temperatures before / after a step, by slot (padding slots at ambient).
    temp: Vec<f64>,
    next: Vec<f64>,
    /// Blocks `lo..hi` span the welded slots (empty: none welded).
    pub(super) lo: usize,
    pub(super) hi: usize,
    steps: u64,
    threads: usize,
    parallel_min: u64,
}

impl<'m> GraphSimulation<'m> {
    /// Every node unwelded at ambient; the best kernel of this CPU.
    pub fn new(model: &'m GraphModel) -> Self {
        let slots = graph_slots(model.len());
        let amb = model.params.ambient_c;
        GraphSimulation {
            model,
            simd: best_simd(Simd::detect()),
            table: GraphTable::new(model),
            temp: vec![amb; slots],
            next: vec![amb; slots],
            lo: usize::MAX,
            hi: 0,
            steps: 0,
            threads: 1,
            parallel_min: GRAPH_PARALLEL_MIN_WORK,
        }
    }

    /// Steps on up to `threads` threads (scoped threads started per [`Self::step`] call,
    /// not the block simulator's pool, which is private to it) once a call's work reaches
    /// [`GRAPH_PARALLEL_MIN_WORK`]. The bits are the same.
    pub fn with_threads(mut self, threads: usize) -> Self {
        self.threads = threads.max(1);
        self
    }

    /// Threads as in [`Self::with_threads`] from `work` node-steps per call on.
    pub fn with_parallel_min(mut self, work: u64) -> Self {
        self.parallel_min = work;
        self
    }

    /// The same simulation stepped by `simd` (the scalar loop if the CPU lacks it).
    pub fn with_simd(mut self, simd: Simd) -> Self {
        self.simd = if simd <= Simd::detect() {
            best_simd(simd)
        } else {
            Simd::Scalar
        };
        self
    }

    /// The kernel in use.
    pub fn simd(&self) -> Simd {
        self.simd
    }

    /// Deposits `node`: T = deposit_c, welded from now on, its contacts to welded nodes
    /// active (no steps: see [`GraphModel::deposit_steps`]).
    ///
    /// # Panics
    /// If `node` is already welded.
    pub fn deposit(&mut self, node: usize) {
        self.table.deposit(self.model, node);
        self.temp[node] = self.model.params.deposit_c;
        self.lo = self.lo.min(node / LANES);
        self.hi = self.hi.max(node / LANES + 1);
    }

    /// Undoes the deposit of `node` (no steps are undone): unwelded, back at ambient, its
    /// contacts inactive. After depositing a, b, c and undepositing c the tables are those
    /// of depositing a and b only, bit for bit.
    ///
    /// # Panics
    /// If `node` is not welded.
    pub fn undeposit(&mut self, node: usize) {
        self.table.undeposit(self.model, node);
        self.temp[node] = self.model.params.ambient_c;
        let welded = |b: &usize| {
            (b * LANES..(b * LANES + LANES).min(self.model.len())).any(|i| self.table.welded[i])
        };
        match (self.lo..self.hi).find(welded) {
            Some(lo) => {
                self.lo = lo;
                self.hi = (lo..self.hi).rev().find(welded).map_or(lo, |b| b + 1);
            }
            None => (self.lo, self.hi) = (usize::MAX, 0),
        }
    }

    /// `n` Euler steps of every welded node.
    pub fn step(&mut self, n: u64) {
        let blocks = self.hi.saturating_sub(self.lo);
        let threads = self.threads.min(blocks);
        if threads > 1 && n.saturating_mul((blocks * LANES) as u64) >= self.parallel_min {
            return self.step_parallel(n, threads);
        }
        for _ in 0..n {
            if self.lo < self.hi {
                let kernel = self.kernel();
                // SAFETY: the kernel points into this simulation's buffers, which live and
                // keep their sizes through the call; blocks lo..hi exist (see `GraphStep::run`).
                unsafe { kernel.run(self.lo, self.hi) };
                std::mem::swap(&mut self.temp, &mut self.next);
            }
            self.steps += 1;
        }
    }

    /// `n` steps on `threads` threads. Each step's blocks are cut into chunks that the
    /// threads claim one at a time (chunk g of the whole run belongs to step g / chunks), so
    /// a thread the OS has not scheduled delays nothing unless it holds a chunk: the others
    /// step its share. A step begins once every chunk of the one before has finished, as
    /// every chunk reads all temperatures.
    fn step_parallel(&mut self, n: u64, threads: usize) {
        let forth = self.kernel();
        let back = GraphStep {
            t: forth.out,
            out: forth.t as *mut f64,
            ..forth
        };
        let (lo, hi) = (self.lo, self.hi);
        let chunks = (threads * CHUNKS_PER_THREAD).min(hi - lo) as u64;
        let claimed = AtomicU64::new(0);
        let finished = AtomicU64::new(0);
        let work = || {
            for step in 0..n {
                let end = (step + 1) * chunks;
                let mut g = claimed.load(Ordering::Relaxed);
                // Chunks left in this step: claim one (g >= step · chunks, since every
                // chunk of the earlier steps has finished, so was claimed).
                while g < end {
                    match claimed.compare_exchange_weak(
                        g,
                        g + 1,
                        Ordering::Relaxed,
                        Ordering::Relaxed,
                    ) {
                        Ok(_) => {
                            let c = (g - step * chunks) as usize;
                            let cut = |c: usize| lo + (hi - lo) * c / chunks as usize;
                            let kernel = if step % 2 == 0 { &forth } else { &back };
                            // SAFETY: both buffers live and keep their sizes until the scope
                            // ends; this chunk's blocks of `out` are written by this thread
                            // alone, and no one writes `t` during this step (all chunks of
                            // the step before have finished, none of the next has begun).
                            unsafe { kernel.run(cut(c), cut(c + 1)) };
                            finished.fetch_add(1, Ordering::Release);
                            g = claimed.load(Ordering::Relaxed);
                        }
                        Err(now) => g = now,
                    }
                }
                let mut spins = 0u32;
                while finished.load(Ordering::Acquire) < end {
                    spins += 1;
                    // On a busy machine the thread we wait for may have lost its core.
                    if spins > 4096 {
                        std::thread::yield_now();
                    } else {
                        std::hint::spin_loop();
                    }
                }
            }
        };
        std::thread::scope(|s| {
            for _ in 1..threads {
                s.spawn(work);
            }
            work();
        });
        if n % 2 == 1 {
            std::mem::swap(&mut self.temp, &mut self.next);
        }
        self.steps += n;
    }

    fn kernel(&mut self) -> GraphStep {
        self.table.step_over(
            self.model,
            self.temp.as_ptr(),
            self.next.as_mut_ptr(),
            self.simd,
        )
    }

    /// Temperatures by node, °C (unwelded nodes at ambient).
    pub fn temperatures(&self) -> &[f64] {
        &self.temp[..self.model.len()]
    }

    /// Whether `node` is welded.
    pub fn is_welded(&self, node: usize) -> bool {
        self.table.is_welded(node)
    }

    /// Steps done so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Slots stepped per step, whole blocks of 4 (a measure of the work done).
    pub fn stepped_slots(&self) -> usize {
        self.hi.saturating_sub(self.lo) * LANES
    }
}

/// What one step reads and writes, as raw pointers (so that the AVX2 code can run on
/// them without bounds checks).
#[derive(Clone, Copy)]
pub(crate) struct GraphStep {
    t: *const f64,
    out: *mut f64,
    nbr: *const u32,
    coef: *const f64,
    used: *const u32,
    runs: *const u64,
    substrate: *const f64,
    radiation: *const f64,
    cols: usize,
    amb: f64,
    q: f64,
    dt: f64,
    simd: Simd,
}

// SAFETY: a `GraphStep` is shared only inside `GraphSimulation::step_parallel`, which holds
// the simulation mutably borrowed until every thread has finished; threads write disjoint
// block ranges of `out` and read `t`, which no one writes during that step.
unsafe impl Send for GraphStep {}
unsafe impl Sync for GraphStep {}

impl GraphStep {
    /// Steps blocks `a..b`.
    ///
    /// # Safety
    /// The tables must be those of a live [`GraphTable`] with at least `b` blocks, `t` and
    /// `out` live buffers of at least its slot count (every neighbour slot is below it),
    /// and `out` must not alias `t`.
    pub(crate) unsafe fn run(&self, a: usize, b: usize) {
        #[cfg(target_arch = "x86_64")]
        if self.simd >= Simd::Avx2 {
            return self.blocks_avx2(a, b);
        }
        self.blocks_scalar(a, b);
    }

    /// The doc's step slot by slot, columns in order; inactive columns add +0.0.
    unsafe fn blocks_scalar(&self, a: usize, b: usize) {
        for blk in a..b {
            let used = *self.used.add(blk) as usize;
            for l in 0..LANES {
                let i = blk * LANES + l;
                let ti = *self.t.add(i);
                let mut f = 0.0;
                for k in 0..used {
                    let at = (blk * self.cols + k) * LANES + l;
                    let tj = *self.t.add(*self.nbr.add(at) as usize);
                    f += *self.coef.add(at) * (tj - ti);
                }
                f += *self.substrate.add(i) * (self.amb - ti);
                let tk = ti + 273.15;
                let t2 = tk * tk;
                f -= *self.radiation.add(i) * (t2 * t2 - self.q);
                *self.out.add(i) = ti + self.dt * f;
            }
        }
    }

    /// Blocks `a..b` with AVX2: each lane does the scalar loop's operations in the same
    /// order (AVX2 adds, subtracts and multiplies are the IEEE operations; no fused
    /// multiply-add).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn blocks_avx2(&self, a: usize, b: usize) {
        use std::arch::x86_64::*;
        let amb = _mm256_set1_pd(self.amb);
        let q = _mm256_set1_pd(self.q);
        let dt = _mm256_set1_pd(self.dt);
        let kelvin = _mm256_set1_pd(273.15);
        let t = self.t;
        for blk in a..b {
            let i = blk * LANES;
            let ti = _mm256_loadu_pd(t.add(i));
            let used = *self.used.add(blk) as usize;
            let runs = *self.runs.add(blk);
            let row = blk * self.cols * LANES;
            let mut f = _mm256_setzero_pd();
            // Every column consecutive (the common case along contours): a loop without
            // the per-column test, the step being bound by instructions, not latency.
            if used < 64 && runs | !((1u64 << used) - 1) == u64::MAX {
                for k in 0..used {
                    let at = row + k * LANES;
                    let c = _mm256_loadu_pd(self.coef.add(at));
                    let tj = _mm256_loadu_pd(t.add(*self.nbr.add(at) as usize));
                    f = _mm256_add_pd(f, _mm256_mul_pd(c, _mm256_sub_pd(tj, ti)));
                }
            } else {
                for k in 0..used {
                    let at = row + k * LANES;
                    let c = _mm256_loadu_pd(self.coef.add(at));
                    let tj = if k < 64 && runs >> k & 1 != 0 {
                        _mm256_loadu_pd(t.add(*self.nbr.add(at) as usize))
                    } else {
                        let idx = _mm_loadu_si128(self.nbr.add(at) as *const __m128i);
                        _mm256_i32gather_pd::<8>(t, idx)
                    };
                    f = _mm256_add_pd(f, _mm256_mul_pd(c, _mm256_sub_pd(tj, ti)));
                }
            }
            let s = _mm256_loadu_pd(self.substrate.add(i));
            f = _mm256_add_pd(f, _mm256_mul_pd(s, _mm256_sub_pd(amb, ti)));
            let tk = _mm256_add_pd(ti, kelvin);
            let t2 = _mm256_mul_pd(tk, tk);
            let r = _mm256_loadu_pd(self.radiation.add(i));
            f = _mm256_sub_pd(f, _mm256_mul_pd(r, _mm256_sub_pd(_mm256_mul_pd(t2, t2), q)));
            _mm256_storeu_pd(self.out.add(i), _mm256_add_pd(ti, _mm256_mul_pd(dt, f)));
        }
    }
}

/// A ring-like test part: `layers` layers of `rings` concentric rings of `ring` nodes.
#[derive(Debug, Clone, Copy)]
pub struct Ring {
    pub layers: usize,
    pub ring: usize,
    pub rings: usize,
    /// Number the nodes at random (no consecutive neighbours: every column a gather).
    pub shuffle: bool,
}

/// The graph of a [`Ring`]: W = 6 mm, H = 2.5 mm, node lengths varying ±10 %; contacts
/// Along the ring, Beside to the next ring, Stacked to the two nodes below (as if each
/// layer were shifted along the ring), listed sorted by (lower, higher) node.
pub fn ring_graph(spec: Ring) -> (Vec<NodeGeometry>, Vec<(u32, u32, f64)>) {
    let Ring {
        layers,
        ring,
        rings,
        shuffle,
    } = spec;
    let (w, h) = (6.0, 2.5);
    let per_layer = ring * rings;
    let n = layers * per_layer;
    let id = |z: usize, r: usize, p: usize| z * per_layer + r * ring + p % ring;
    let len = |p: usize| w * (1.0 + 0.1 * ((p as f64) * 0.7).sin());
    let mut nodes = Vec::with_capacity(n);
    for z in 0..layers {
        for _r in 0..rings {
            for p in 0..ring {
                let l = len(p);
                nodes.push(NodeGeometry {
                    volume: l * w * h,
                    surface: 2.0 * l * w + 2.0 * l * h + 2.0 * w * h,
                    substrate: if z == 0 { l * w } else { 0.0 },
                });
            }
        }
    }
    let mut contacts = Vec::new();
    for z in 0..layers {
        for r in 0..rings {
            for p in 0..ring {
                let i = id(z, r, p);
                if ring > 1 && (ring > 2 || p == 0) {
                    contacts.push((i, id(z, r, p + 1), w * h * (0.95 + 0.1 * (p % 3) as f64)));
                }
                if r + 1 < rings {
                    contacts.push((i, id(z, r + 1, p), len(p) * h * 0.9));
                }
                if z > 0 {
                    contacts.push((i, id(z - 1, r, p), 0.6 * len(p) * w));
                    if ring > 1 {
                        contacts.push((i, id(z - 1, r, p + 1), 0.4 * len(p) * w));
                    }
                }
            }
        }
    }
    let mut perm: Vec<usize> = (0..n).collect();
    if shuffle {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        for i in (1..n).rev() {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            perm.swap(i, (x % (i as u64 + 1)) as usize);
        }
        let mut shuffled = nodes.clone();
        for (i, &p) in perm.iter().enumerate() {
            shuffled[p] = nodes[i];
        }
        nodes = shuffled;
    }
    let mut contacts: Vec<(u32, u32, f64)> = contacts
        .into_iter()
        .map(|(a, b, area)| {
            let (a, b) = (perm[a] as u32, perm[b] as u32);
            (a.min(b), a.max(b), area)
        })
        .collect();
    contacts.sort_by_key(|&(a, b, _)| (a, b));
    (nodes, contacts)
}

/// Throughput of the fast step: [`ring_graph`] of `spec`, all welded, `steps` steps on `simd` and
/// `threads` threads, best of `reps` runs (a busy machine takes the core away now and
/// then). Returns nodes, node-steps per second of wall time, and node-steps per second of
/// the process's CPU time (Linux, else NaN; with threads it counts barrier waits too).
pub fn bench_graph(
    spec: Ring,
    simd: Simd,
    threads: usize,
    steps: u64,
    reps: usize,
) -> (usize, f64, f64) {
    let (nodes, contacts) = ring_graph(spec);
    let model = GraphModel::new(ThermalParams::default(), 6.0, 2.5, &nodes, &contacts)
        .expect("a valid ring graph");
    let mut sim = GraphSimulation::new(&model)
        .with_simd(simd)
        .with_threads(threads);
    for i in 0..model.len() {
        sim.deposit(i);
    }
    sim.step(steps.min(20));
    let work = model.len() as f64 * steps as f64;
    let (mut wall, mut cpu) = (0.0f64, 0.0f64);
    for _ in 0..reps.max(1) {
        let (start, cpu_start) = (std::time::Instant::now(), process_cpu_s());
        sim.step(steps);
        wall = wall.max(work / start.elapsed().as_secs_f64());
        cpu = cpu.max(work / (process_cpu_s() - cpu_start));
    }
    (model.len(), wall, cpu)
}

/// CPU time of this process (user + system), s, from /proc (NaN elsewhere).
fn process_cpu_s() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    // Fields after the command name (which may hold spaces): utime and stime are the
    // 12th and 13th, in clock ticks (100 per second on Linux).
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<f64> = rest
        .split_whitespace()
        .skip(11)
        .take(2)
        .filter_map(|x| x.parse().ok())
        .collect();
    match f[..] {
        [u, s] => (u + s) / 100.0,
        _ => f64::NAN,
    }
}
