//! The thermal loop: the SAT solver proposes a plan, the thermal model judges it, and a
//! violation teaches the solver a clause that rules out the violating prefix.
//!
//! What makes it fast:
//! - with CaDiCaL, prefixes are judged inside the search ([`crate::thermal_prefix`]), so the
//!   complete models that come out are (nearly) only the feasible plans;
//! - candidates share prefixes, so the simulation of a new candidate resumes from the
//!   snapshot of the longest prefix it shares with *any* earlier candidate or with a prefix
//!   judged inside the search ([`crate::prefix_cache`]);
//! - before a prefix clause is learned, it is shortened where that is *proven*
//!   ([`crate::shortening`]).

use std::cell::RefCell;
use std::rc::Rc;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

use waam_access::{Obstacle, TorchAccess};
use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_thermal::{self as thermal, Phase, Simulation, Snapshot, ThermalModel, Violation};

use super::encoding::{Acyclicity, Decoded, Encoding};
use super::prefix_cache::{
    deposits, prefix_keys, resume, snapshot_spacing, Key, PrefixCache, SharedCache,
};
use super::sat::{Backend, Lit, SatSolver};
use super::sharing::Sharing;
use super::shortening::shorten;
use super::thermal_prefix::{PrefixLiterals, ThermalPrefix};
use super::{CandidateVerdict, ExecutedCheck, Stats};

/// One SAT instance with its thermal loop.
pub struct Search<'p> {
    pub part: &'p Part,
    pub graph: &'p WeldGraph,
    pub enc: Encoding,
    solver: Box<dyn SatSolver>,
    thermal: Arc<ThermalModel>,
    acyclicity: Acyclicity,
    /// Simulated steps allowed for proving shorter clauses, per violation.
    lookahead_budget: usize,
    pub stats: Stats,
    /// Violations per window block (to name the one broken most often).
    pub violations: Vec<usize>,
    cache: SharedCache,
    /// Layers given the eager rank order (hybrid acyclicity).
    ranked_layers: Vec<i64>,
    spacing: usize,
    /// True once a solve was stopped by the deadline or a cancel (no answer, no proof).
    pub interrupted: bool,
    /// Cycle cuts the solver made inside its searches (counted into the statistics).
    inside_cuts: u64,
    /// Torch access, checked at every deposit (None: not modelled).
    torch: Option<TorchAccess>,
    /// Torch-blocked deposits per block (to name the one blocked most often).
    pub torch_blocked: Vec<usize>,
    /// The check on the robot's executed time line (None: no robot).
    executed: Option<ExecutedCheck>,
    /// Why the last candidate was rejected on it.
    pub executed_last: Option<String>,
    /// Clauses learned inside the search since [`Search::take_learned`], when kept.
    learned: Vec<Vec<Lit>>,
    /// The last complete plan (its prefix cache key) whose cooldown the check inside the
    /// search simulated under the current model and found keeping every window.
    cooled_inside: Option<Key>,
    /// When simulations stop too (a stopped simulation gives no verdict).
    deadline: Option<Instant>,
    cancel: Option<Arc<AtomicBool>>,
    /// Threads a candidate's simulation steps on (0: the thermal model's default).
    threads: usize,
    /// The race's clause pool (None: not racing).
    sharing: Option<Sharing>,
}

impl<'p> Search<'p> {
    /// `None` when `interrupt` (deadline or cancel, kept for the solves) comes before the
    /// encoding is complete.
    pub fn new(
        part: &'p Part,
        graph: &'p WeldGraph,
        k: usize,
        acyclicity: Acyclicity,
        lookahead_budget: usize,
        backend: Backend,
        interrupt: thermal::Interrupt,
    ) -> Option<Search<'p>> {
        let started = Instant::now();
        let mut solver = crate::new_solver(backend, part.len().saturating_mul(k));
        let enc = Encoding::new(part, graph, k, acyclicity, &mut solver, &|| {
            interrupt.reached()
        })?;
        // Lazy acyclicity inside the search where the backend can (the paper's way); cuts
        // between solves otherwise. Hybrid needs no ranks when no cycle reaches a model.
        if acyclicity != Acyclicity::Eager {
            solver.exclude_cycles(part.len(), &enc.cycle_edges(part));
        }
        let mut stats = Stats::default();
        let (vars, clauses) = solver.size();
        stats.variables = vars;
        stats.clauses = clauses;
        stats.encode_s = started.elapsed().as_secs_f64();
        let n = part.len();
        let mut search = Search {
            part,
            graph,
            enc,
            solver,
            thermal: Arc::new(ThermalModel::new(part, graph)),
            acyclicity,
            lookahead_budget,
            stats,
            violations: vec![0; n],
            cache: Rc::new(RefCell::new(PrefixCache::for_blocks(n))),
            ranked_layers: Vec::new(),
            spacing: snapshot_spacing(n),
            interrupted: false,
            inside_cuts: 0,
            torch: None,
            torch_blocked: vec![0; n],
            executed: None,
            executed_last: None,
            cooled_inside: None,
            learned: Vec::new(),
            deadline: None,
            cancel: None,
            threads: 0,
            sharing: None,
        };
        search.set_interrupt(interrupt.deadline, interrupt.cancel);
        Some(search)
    }

    /// Publishes the violations this search learns to a race's pool and, inside the
    /// search (CaDiCaL), takes the other racers'. Call before [`Search::judge_inside`].
    pub fn share(&mut self, sharing: Sharing) {
        self.sharing = Some(sharing);
    }

    /// Steps the simulations of later candidates on up to `threads` threads (0: the
    /// thermal model's default, the available cores).
    pub fn set_threads(&mut self, threads: usize) {
        self.threads = threads;
    }

    /// A simulation of the search's, on its threads.
    fn on_threads<'m>(&self, sim: Simulation<'m>) -> Simulation<'m> {
        sim.with_threads(self.threads)
    }

    /// Varies the solver's random choices (a racer's seed).
    pub fn set_seed(&mut self, seed: u32) {
        self.solver.set_seed(seed);
    }

    /// Checks torch access at every deposit of later candidates (None: no torch).
    pub fn set_torch(&mut self, torch: Option<TorchAccess>) {
        self.torch = torch;
    }

    /// Judges later candidates that keep their windows and the torch once more, on the
    /// robot's executed time line (None: no robot).
    pub fn set_executed(&mut self, executed: Option<ExecutedCheck>) {
        self.executed = executed;
    }

    /// Stops solves at `deadline` or on `cancel` (inside a solve where the backend can):
    /// [`Search::next_candidate`] then returns `None` and sets `interrupted`.
    pub fn set_interrupt(&mut self, deadline: Option<Instant>, cancel: Option<Arc<AtomicBool>>) {
        self.solver.set_interrupt(deadline, cancel.clone());
        self.deadline = deadline;
        self.cancel = cancel;
    }

    /// Points the solver's decisions at `fragments` (a warm start): every move of the
    /// plan true first, every other move false first. A hint only, never a constraint.
    pub fn set_phases(&mut self, fragments: &[Vec<usize>]) {
        let mut on = rustc_hash::FxHashSet::default();
        for lit in self.enc.plan_literals(fragments) {
            self.solver.set_phase(lit);
            on.insert(lit);
        }
        for (_, _, e) in self.enc.edges() {
            if !on.contains(&e) {
                self.solver.set_phase(!e);
            }
        }
    }

    /// Judges later candidates by `model` (e.g. narrowed windows while optimizing). What
    /// it learns from then on is not shared: a race's clauses must hold for the part's own
    /// windows.
    pub fn set_thermal(&mut self, model: ThermalModel) {
        if let Some(sharing) = &self.sharing {
            sharing.stop_publishing();
        }
        self.thermal = Arc::new(model);
        self.cooled_inside = None;
        self.cache.borrow_mut().clear();
        self.solver.set_prefix_model(Arc::clone(&self.thermal));
    }

    /// Judges plan prefixes inside the search too, where the backend can (CaDiCaL): a
    /// prefix that breaks a window is ruled out by its clause before any complete model
    /// holds it (see [`crate::thermal_prefix`]). Complete models are still judged here.
    /// Call before the first solve, and only for searches that judge plans (a count of
    /// valid plans must not).
    pub fn judge_inside(&mut self) {
        self.judge_inside_keeping(false);
    }

    /// [`Search::judge_inside`]; `keep`: the clauses it learns are kept for
    /// [`Search::take_learned`] too.
    pub fn judge_inside_keeping(&mut self, keep: bool) {
        if !self.thermal.has_windows() {
            return; // nothing can break
        }
        let n = self.part.len();
        let k = self.enc.max_fragments();
        let lits = PrefixLiterals {
            blocks: n,
            max_fragments: k,
            edges: self.enc.edges().collect(),
            starts: (0..n)
                .map(|v| (0..k).map(|i| self.enc.starts_fragment(v, i)).collect())
                .collect(),
            ends: (0..n).map(|v| self.enc.ends_at(v)).collect(),
        };
        let mut prefix = ThermalPrefix::new(
            &lits,
            Arc::clone(&self.thermal),
            Rc::clone(&self.cache),
            Arc::new(self.graph.clone()),
            self.lookahead_budget,
        );
        if keep {
            prefix.keep_clauses();
        }
        if let Some(sharing) = &self.sharing {
            prefix.share(sharing.clone());
        }
        self.solver.judge_prefixes(prefix);
    }

    /// Counts what the prefix check did inside the last solve.
    fn take_prefix_report(&mut self) {
        let report = self.solver.take_prefix_report();
        if report.cooled.is_some() {
            self.cooled_inside = report.cooled;
        }
        self.learned.extend(report.clauses);
        for (&len, &block) in report.clause_lens.iter().zip(&report.violated) {
            self.stats.record_clause(len);
            self.violations[block] += 1;
        }
        self.stats.inside_clauses += report.clause_lens.len() as u64;
        self.stats.inside_deposits += report.deposits;
        self.stats.inside_reused += report.reused + report.resumed;
        self.stats.clauses_imported += report.imported;
        self.stats.shortened += report.shortened;
        self.stats.lookahead_block_steps += report.lookahead_block_steps;
    }

    /// The next plan the solver allows, cutting cycles until the model is one;
    /// `None` when no plan is left (under `assumptions`).
    pub fn next_candidate(&mut self, assumptions: &[Lit]) -> Option<Vec<Vec<usize>>> {
        loop {
            let t = Instant::now();
            let sat = self.solver.solve(assumptions);
            self.stats.sat_solves += 1;
            let dt = t.elapsed().as_secs_f64();
            let inside = self.solver.cycle_cuts();
            self.stats.cycle_cuts += inside - self.inside_cuts;
            self.inside_cuts = inside;
            self.take_prefix_report();
            if sat != Some(true) {
                self.interrupted |= sat.is_none();
                self.stats.sat_s += dt;
                return None;
            }
            let t2 = Instant::now();
            match self.enc.decode(&self.solver) {
                Decoded::Plan(fragments) => {
                    self.stats.sat_s += dt;
                    self.stats.acyclicity_s += t2.elapsed().as_secs_f64();
                    return Some(fragments);
                }
                Decoded::Cycles(cycles) => {
                    debug_assert_ne!(
                        self.acyclicity,
                        Acyclicity::Eager,
                        "eager encoding left a cycle"
                    );
                    for cycle in &cycles {
                        let cut = self.enc.cycle_cut(cycle);
                        self.solver.add_clause(&cut);
                        self.stats.cycle_cuts += 1;
                    }
                    if self.acyclicity == Acyclicity::Hybrid {
                        // Layers that cycle once tend to cycle again: order them eagerly.
                        let z = |b: usize| self.part.block(b)[2];
                        let fresh: Vec<i64> = cycles
                            .iter()
                            .map(|c| z(c[0]))
                            .filter(|l| !self.ranked_layers.contains(l))
                            .collect();
                        if !fresh.is_empty() {
                            self.ranked_layers.extend(&fresh);
                            self.enc
                                .encode_ranks(self.part, &mut self.solver, |l| fresh.contains(&l));
                        }
                    }
                    // A solve that ended in a cycle is work done for acyclicity.
                    self.stats.acyclicity_s += dt + t2.elapsed().as_secs_f64();
                }
            }
        }
    }

    /// The clauses learned inside the search since the last call (when kept): they hold for
    /// every search of the same part and windows, so another worker can add them.
    pub fn take_learned(&mut self) -> Vec<Vec<Lit>> {
        std::mem::take(&mut self.learned)
    }

    /// Adds clauses another search of the same part and windows learned.
    pub fn add_learned(&mut self, clauses: &[Vec<Lit>]) {
        self.add_clauses(clauses);
    }

    /// Narrows the search to the plans that keep `clauses` (e.g. a raster's moves).
    pub fn add_clauses(&mut self, clauses: &[Vec<Lit>]) {
        for c in clauses {
            self.solver.add_clause(c);
        }
    }

    /// Rules out one complete plan (after counting or accepting it).
    pub fn block_plan(&mut self, fragments: &[Vec<usize>]) {
        let clause: Vec<Lit> = self
            .enc
            .plan_literals(fragments)
            .into_iter()
            .map(|l| !l)
            .collect();
        self.solver.add_clause(&clause);
    }

    /// Simulates a candidate, resuming from the longest shared prefix, and on a violation
    /// learns the (shortened) prefix clause. `None`: the deadline or a cancel stopped the
    /// simulation before a verdict (`interrupted` is then set). With a torch, a deposit the
    /// torch cannot reach is a violation too: the candidate is simulated up to it, and
    /// unless a window broke before, [`Search::learn_torch`] rules out the plans with it.
    pub fn judge(
        &mut self,
        fragments: &[Vec<usize>],
    ) -> Result<Option<CandidateVerdict>, thermal::NotCooled> {
        let t = Instant::now();
        self.stats.candidates += 1;
        let seq = deposits(fragments);
        let blocked = self
            .torch
            .as_ref()
            .and_then(|a| a.first_blocked(seq.iter().map(|&(b, _)| b)));
        let result = if self.thermal.has_windows() {
            self.simulate(&seq, blocked.map_or(seq.len(), |x| x.position))
        } else {
            // Nothing to break: the simulation could only say "feasible".
            Ok(Judged::Feasible)
        };
        self.stats.simulator_s += t.elapsed().as_secs_f64();
        match (result?, blocked) {
            (Judged::Interrupted, _) => {
                self.interrupted = true;
                Ok(None)
            }
            (Judged::Feasible, None) => {
                // The robot's word last: it is the slowest judge (a whole motion plan).
                let rejection = self.executed.as_ref().and_then(|c| (c.0)(fragments));
                // A check the deadline or cancel cut short is no verdict either.
                let stopped = thermal::Interrupt {
                    deadline: self.deadline,
                    cancel: self.cancel.clone(),
                };
                if rejection.is_none() && self.executed.is_some() && stopped.reached() {
                    self.interrupted = true;
                    return Ok(None);
                }
                if let Some(r) = rejection {
                    self.stats.executed_rejected += 1;
                    tracing::info!("candidate rejected on the robot's time line: {}", r.reason);
                    let prefix_len = r.prefix.iter().map(Vec::len).sum();
                    let clause_len = self.learn_clause(&r.prefix, r.closed);
                    self.executed_last = Some(r.reason);
                    return Ok(Some(CandidateVerdict::ExecutedRejected {
                        prefix_len,
                        clause_len,
                    }));
                }
                self.stats.feasible += 1;
                Ok(Some(CandidateVerdict::Feasible))
            }
            (Judged::Violated(v), _) => {
                self.violations[v.block] += 1;
                let t = Instant::now();
                let clause_len = self.learn(&seq, &v);
                self.stats.lookahead_s += t.elapsed().as_secs_f64();
                Ok(Some(CandidateVerdict::Violated {
                    block: self.part.block(v.block),
                    kind: v.kind,
                    time_s: v.time_s,
                    prefix_len: v.prefix_len,
                    clause_len,
                }))
            }
            (Judged::Feasible, Some(x)) => {
                self.torch_blocked[x.block] += 1;
                self.stats.torch_blocked += 1;
                let clause_len = self.learn_torch(&seq[..=x.position], x.block, x.obstacle);
                Ok(Some(CandidateVerdict::TorchBlocked {
                    block: self.part.block(x.block),
                    obstacle: match x.obstacle {
                        Obstacle::Plate => None,
                        Obstacle::Block(o) => Some(self.part.block(o)),
                    },
                    prefix_len: x.position + 1,
                    clause_len,
                }))
            }
        }
    }

    /// The simulation of the first `len` deposits of `seq` to its first violation; the
    /// cooldown only when that is all of `seq` (else the candidate stops at a deposit the
    /// torch cannot reach, and no violation before it is `Feasible` here).
    fn simulate(
        &mut self,
        seq: &[(usize, bool)],
        len: usize,
    ) -> Result<Judged, thermal::NotCooled> {
        let whole = len == seq.len();
        let seq = &seq[..len];
        let keys = prefix_keys(seq);
        // The check inside the search simulated this very plan to the end of its cooldown
        // already (the simulation depends on the deposit sequence alone): once is enough.
        if whole && keys.last().is_some() && keys.last() == self.cooled_inside.as_ref() {
            self.stats.deposits_reused += len as u64;
            self.stats.cooled_inside += 1;
            return Ok(Judged::Feasible);
        }
        let (sim, at) = resume(
            &self.thermal,
            &self.cache.borrow(),
            self.spacing,
            seq,
            &keys,
        );
        let mut sim = self.on_threads(sim).with_deadline(self.deadline);
        if let Some(cancel) = &self.cancel {
            sim = sim.with_cancel(Arc::clone(cancel));
        }
        self.stats.deposits_reused += at as u64;
        for (j, &(b, new)) in seq.iter().enumerate().skip(at) {
            self.stats.deposits_simulated += 1;
            let deposited = sim.deposit(b, new);
            // A stopped simulation's state is incomplete: no verdict, nothing cached.
            if sim.cancelled() {
                return Ok(Judged::Interrupted);
            }
            if let Err(v) = deposited {
                return Ok(Judged::Violated(v));
            }
            if (j + 1) % self.spacing == 0 {
                self.cache.borrow_mut().insert(keys[j], &sim);
            }
        }
        if !whole {
            return Ok(Judged::Feasible);
        }
        let before = sim.steps();
        let end = sim.finish();
        self.stats.cooldown_steps += sim.steps() - before;
        if sim.cancelled() {
            return Ok(Judged::Interrupted);
        }
        Ok(match end? {
            Ok(()) => Judged::Feasible,
            Err(v) => Judged::Violated(v),
        })
    }

    /// Learns the clause of the violating prefix, shortened where every alternative
    /// next step is proven to violate too. Returns the clause's length.
    fn learn(&mut self, seq: &[(usize, bool)], v: &Violation) -> usize {
        let interrupt = self.interrupt();
        let r = shorten(
            self.graph,
            self.enc.max_fragments(),
            seq,
            v.prefix_len,
            v.phase != Phase::Deposit,
            self.lookahead_budget,
            &interrupt,
            |len| self.state_after(&seq[..len]),
        );
        self.stats.lookahead_block_steps += r.cost;
        self.stats.shortened += r.dropped;
        let prefix = fragments_of(&seq[..r.len]);
        if let Some(sharing) = &self.sharing {
            let clause: Vec<Lit> = (self.enc.prefix_literals(&prefix, r.closed).into_iter())
                .map(|l| !l)
                .collect();
            sharing.publish(&clause);
        }
        self.learn_clause(&prefix, r.closed)
    }

    /// Learns what rules out the plans in which the torch meets `obstacle` at the last
    /// deposit of `prefix`, block `b` (the check depends only on the blocks deposited
    /// before `b`, and more deposited blocks never clear the way); the clause length.
    /// - The plate: every plan welds `b`, so no plan is left (the empty clause).
    /// - A block `a` higher than `b`: every plan that welds `a` before `b` (that is, in an
    ///   earlier fragment) — binary clauses `idx(b) <= idx(a)`, far shorter than the prefix.
    /// - Otherwise (a steep torch meeting a block no higher than `b`): the plans that
    ///   begin with `prefix`.
    fn learn_torch(&mut self, prefix: &[(usize, bool)], b: usize, obstacle: Obstacle) -> usize {
        match obstacle {
            Obstacle::Plate => self.learn_clause(&[], false),
            Obstacle::Block(a) if self.part.block(a)[2] > self.part.block(b)[2] => {
                let clauses = self.enc.not_before(a, b);
                for c in &clauses {
                    self.stats.record_clause(c.len());
                    self.solver.add_clause(c);
                }
                2
            }
            Obstacle::Block(_) => self.learn_clause(&fragments_of(prefix), false),
        }
    }

    /// Learns the clause that rules out every plan beginning with `prefix`; its length.
    fn learn_clause(&mut self, prefix: &[Vec<usize>], closed: bool) -> usize {
        let clause: Vec<Lit> = self
            .enc
            .prefix_literals(prefix, closed)
            .into_iter()
            .map(|l| !l)
            .collect();
        self.stats.record_clause(clause.len());
        self.solver.add_clause(&clause);
        clause.len()
    }

    /// A simulation on `model` (the same part's) at the longest prefix of `prefix` whose
    /// snapshot this search's cache holds, and that prefix's length (0: none): where a
    /// repair of a plan the search judged starts without simulating it again.
    pub(crate) fn resume_on<'m>(
        &self,
        model: &'m ThermalModel,
        prefix: &[(usize, bool)],
    ) -> (Simulation<'m>, usize) {
        let (sim, at) = resume(
            model,
            &self.cache.borrow(),
            self.spacing,
            prefix,
            &prefix_keys(prefix),
        );
        (self.on_threads(sim), at)
    }

    /// Keeps `snap`, another simulation's state after depositing all of `fragments` on
    /// this search's model: judging the plan then simulates its cooldown only.
    pub(crate) fn remember(&self, fragments: &[Vec<usize>], snap: Snapshot) {
        let seq = deposits(fragments);
        if let Some(&key) = prefix_keys(&seq)
            .last()
            .filter(|_| snap.welded() == seq.len())
        {
            self.cache.borrow_mut().insert_snapshot(key, snap);
        }
    }

    /// The simulation state after `prefix` (from the nearest cached snapshot).
    fn state_after(&self, prefix: &[(usize, bool)]) -> Option<Simulation<'_>> {
        let keys = prefix_keys(prefix);
        let (sim, at) = resume(
            &self.thermal,
            &self.cache.borrow(),
            self.spacing,
            prefix,
            &keys,
        );
        // Replaying may cross long transits: stopped with the search.
        let mut sim = self.on_threads(sim).interrupted_by(&self.interrupt());
        for &(b, new) in &prefix[at..] {
            sim.deposit(b, new).ok()?;
        }
        (!sim.cancelled()).then_some(sim)
    }

    /// The deadline and cancel flag the search stops at, for its simulations.
    fn interrupt(&self) -> thermal::Interrupt {
        thermal::Interrupt {
            deadline: self.deadline,
            cancel: self.cancel.clone(),
        }
    }
}

/// What a simulation of a candidate found.
enum Judged {
    Feasible,
    Violated(Violation),
    /// Stopped by the deadline or a cancel before a verdict.
    Interrupted,
}

/// Fragments of block indices from a deposit sequence.
pub fn fragments_of(seq: &[(usize, bool)]) -> Vec<Vec<usize>> {
    let mut out: Vec<Vec<usize>> = Vec::new();
    for &(b, new) in seq {
        if new || out.is_empty() {
            out.push(Vec::new());
        }
        out.last_mut().expect("just pushed").push(b);
    }
    out
}
