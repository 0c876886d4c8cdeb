//! The CaDiCaL backend (through pindakaas), with the paper's own acyclicity mechanism:
//! cycles are kept out *inside* the search by a user propagator (IPASIR-UP), not by cuts
//! between solves; and solves stop at a deadline or on cancel (CaDiCaL's terminate
//! callback), so a timeout holds even inside one long solve.
//!
//! The propagator follows the chosen sideways moves as chains (paths of blocks, each
//! moving to the next). When an assigned edge `u -> v` joins the chain ending at `u` to the
//! chain starting at `v`:
//! - if both are one chain, the edge closes a cycle with no arc start on it: the cut
//!   "not all of these edges" is handed to the solver as a conflict clause;
//! - otherwise the new chain runs from `h` to `t`, and the edge `t -> h` (if the weld
//!   graph has it) would close a cycle: it is propagated false, its reason being the
//!   chain's edges.
//!
//! Every clause handed over is a cycle cut, which holds in every plan, so no plan is lost;
//! and a complete assignment is checked for cycles before the solver may report it
//! (`check_solution`), so no model with a cycle gets out, whatever the chains missed.

use std::cell::RefCell;
use std::num::NonZeroI32;
use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use pindakaas::solver::cadical::Cadical as Inner;
use pindakaas::solver::propagation::{
    ClauseBuilder, ClausePersistence, ExternalPropagation, Propagator, PropagatorConfig, Solution,
    SolvingActions,
};
use pindakaas::solver::{Assumptions, SolveResult, TermSignal, TerminateCallback};
use pindakaas::{ClauseDatabase, Valuation};

use super::sat::{Lit, SatSolver};
use super::thermal_prefix::{PrefixReport, ThermalPrefix};
use waam_thermal::ThermalModel;

/// CaDiCaL 3 as a [`SatSolver`].
pub struct Cadical {
    inner: Inner,
    model: Vec<bool>,
    vars: usize,
    clauses: usize,
    buf: Vec<pindakaas::Lit>,
    /// The user propagator, once one is connected.
    inside: Option<Rc<RefCell<Inside>>>,
    deadline: Option<Instant>,
    cancel: Option<Arc<AtomicBool>>,
}

/// Set by a process that exits once its run is stopped (the `waam` CLI): a big solver
/// dropped after its deadline or cancel is then left to the exit, not freed.
static LEAVE_TO_EXIT: AtomicBool = AtomicBool::new(false);

/// Lets big solvers dropped after their run was stopped be freed by the process exit:
/// freeing 10^7 clauses takes up to a second on a loaded machine (on a thread of its own,
/// but its frees fill the allocator's bins that the answering thread then sorts), which
/// the answer at a `--timeout` would wait for. Only for processes that end after a run:
/// a long-lived one (the node) would keep the memory.
pub fn leave_stopped_solvers_to_exit() {
    LEAVE_TO_EXIT.store(true, Ordering::Relaxed);
}

/// From about this many path-block pairs (blocks × k; the encoding has some 22 clauses per
/// pair) the formula is big: see [`Cadical::for_size`].
pub const BIG_FORMULA_PATH_BLOCKS: usize = 50_000;

impl Default for Cadical {
    fn default() -> Self {
        Cadical::for_size(0)
    }
}

impl Cadical {
    /// A solver for an encoding of `path_blocks` path-block pairs (blocks × k).
    ///
    /// CaDiCaL polls the terminate callback between its phases, and (with the patch in
    /// `vendor/pindakaas-cadical`) after every conflict, but not inside a phase. On a big
    /// formula (8·10^6 clauses for a 62,614-block part at k = 6) its clause-database
    /// reduction, the arena moves of its garbage collection, inprocessing (variable
    /// elimination with subsumption) and random walks each ran 2–13 s past a deadline:
    /// there they are switched off, and the callback is asked at every poll (CaDiCaL
    /// asks every 11th by default), so that `--timeout` and cancel hold within a second.
    pub fn for_size(path_blocks: usize) -> Cadical {
        let mut inner = Inner::default();
        // Chronological backtracking can climb down thousands of decision levels one
        // conflict at a time (seen on 10^4-block parts with long prefix clauses): backjump.
        inner.set_option("chrono", 0);
        if path_blocks >= BIG_FORMULA_PATH_BLOCKS {
            for option in ["reduce", "arena", "inprocessing", "walk", "compact"] {
                inner.set_option(option, 0);
            }
            // A conflict there can take 0.1 s to analyse: ask at every poll, not every 11th.
            inner.set_option("terminateint", 0);
        }
        Cadical {
            inner,
            model: Vec::new(),
            vars: 0,
            clauses: 0,
            buf: Vec::new(),
            inside: None,
            deadline: None,
            cancel: None,
        }
    }
}

impl Drop for Cadical {
    /// Freeing a CaDiCaL instance of millions of clauses takes seconds: a big one is freed
    /// on a thread of its own, so that a run stopped by its deadline answers on time.
    fn drop(&mut self) {
        if self.clauses < 200_000 {
            return;
        }
        /// The solver with its propagator: the only two owners of that `Rc` move together.
        struct Parcel {
            _solver: Inner,
            _propagator: Option<Rc<RefCell<Inside>>>,
        }
        // The prefix check shares its snapshot cache (an `Rc`) with the thermal loop, which
        // stays on this thread: it is dropped here.
        if let Some(inside) = &self.inside {
            inside.borrow_mut().prefix = None;
        }
        // SAFETY: CaDiCaL keeps no thread-local state, and every clone of the propagator's
        // `Rc` (ours and the one the solver's store holds) is inside the parcel; what the
        // propagator still holds (the cycle chains) is owned by it alone.
        unsafe impl Send for Parcel {}
        let parcel = Parcel {
            _solver: std::mem::take(&mut self.inner),
            _propagator: self.inside.take(),
        };
        let (deadline, cancel) = (&self.deadline, &self.cancel);
        let stopped = deadline.is_some_and(|d| Instant::now() >= d)
            || cancel.as_ref().is_some_and(|c| c.load(Ordering::Relaxed));
        if stopped && LEAVE_TO_EXIT.load(Ordering::Relaxed) {
            std::mem::forget(parcel);
            return;
        }
        // If no thread can be started, the parcel is freed here.
        let _ = std::thread::Builder::new()
            .name("cadical-free".into())
            .spawn(move || drop(parcel));
    }
}

fn to_pk(l: Lit) -> pindakaas::Lit {
    pindakaas::Lit::from_raw(NonZeroI32::new(l.to_dimacs()).expect("literals are non-zero"))
}

impl SatSolver for Cadical {
    fn new_lit(&mut self) -> Lit {
        let v = self
            .inner
            .new_var_range(1)
            .next()
            .expect("one new variable");
        self.vars += 1;
        Lit::positive(i32::from(v) as u32)
    }

    fn add_clause(&mut self, lits: &[Lit]) {
        self.buf.clear();
        self.buf.extend(lits.iter().map(|&l| to_pk(l)));
        // An empty clause makes the formula unsatisfiable; the solver remembers that.
        let _ = self.inner.add_clause_from_slice(&self.buf);
        self.clauses += 1;
    }

    fn solve(&mut self, assumptions: &[Lit]) -> Option<bool> {
        let vars = self.vars;
        let model = &mut self.model;
        match self
            .inner
            .solve_assuming(assumptions.iter().map(|&l| to_pk(l)))
        {
            SolveResult::Satisfied(sol) => {
                model.clear();
                model.push(false);
                model.extend((1..=vars).map(|v| sol.value(to_pk(Lit::positive(v as u32)))));
                Some(true)
            }
            SolveResult::Unsatisfiable(_) => Some(false),
            SolveResult::Unknown => None,
        }
    }

    fn value(&self, lit: Lit) -> bool {
        let v = self.model.get(lit.var() as usize).copied().unwrap_or(false);
        v != lit.is_negative()
    }

    fn size(&self) -> (usize, usize) {
        (self.vars, self.clauses)
    }

    fn set_phase(&mut self, lit: Lit) {
        self.inner.phase(to_pk(lit));
    }

    fn set_seed(&mut self, seed: u32) {
        // CaDiCaL's "seed" drives its random choices (walks, shuffles); "phase" the value
        // it tries first where no phase was set: varied together, the racers differ.
        self.inner.set_option("seed", (seed & 0x7fff_ffff) as i32);
        self.inner.set_option("phase", (seed & 1) as i32);
    }

    fn set_interrupt(&mut self, deadline: Option<Instant>, cancel: Option<Arc<AtomicBool>>) {
        self.deadline = deadline;
        self.cancel = cancel.clone();
        if let Some(prefix) = self.propagator().borrow_mut().prefix.as_mut() {
            prefix.set_interrupt(deadline, cancel.clone());
        }
        if deadline.is_none() && cancel.is_none() {
            self.inner
                .set_terminate_callback(None::<fn() -> TermSignal>);
            return;
        }
        self.inner.set_terminate_callback(Some(move || {
            let late = deadline.is_some_and(|d| Instant::now() >= d);
            let cancelled = cancel.as_ref().is_some_and(|c| c.load(Ordering::Relaxed));
            if late || cancelled {
                TermSignal::Terminate
            } else {
                TermSignal::Continue
            }
        }));
    }

    fn exclude_cycles(&mut self, blocks: usize, edges: &[(usize, usize, Lit)]) -> bool {
        self.propagator().borrow_mut().cycles = Some(NoCycles::new(blocks, edges));
        for &(_, _, e) in edges {
            self.inner.add_observed_var(to_pk(e).var());
        }
        true
    }

    fn cycle_cuts(&self) -> u64 {
        self.inside
            .as_ref()
            .and_then(|p| p.borrow().cycles.as_ref().map(|c| c.cuts))
            .unwrap_or(0)
    }

    fn judge_prefixes(&mut self, mut prefix: ThermalPrefix) -> bool {
        prefix.set_interrupt(self.deadline, self.cancel.clone());
        let observed: Vec<Lit> = prefix.observed().collect();
        self.propagator().borrow_mut().prefix = Some(prefix);
        for l in observed {
            self.inner.add_observed_var(to_pk(l).var());
        }
        true
    }

    fn set_prefix_model(&mut self, model: Arc<ThermalModel>) {
        if let Some(prefix) = self.propagator().borrow_mut().prefix.as_mut() {
            prefix.set_model(model);
        }
    }

    fn take_prefix_report(&mut self) -> PrefixReport {
        self.inside
            .as_ref()
            .and_then(|p| p.borrow_mut().prefix.as_mut().map(|t| t.take_report()))
            .unwrap_or_default()
    }
}

impl Cadical {
    /// The user propagator, connected on first use (CaDiCaL takes one only).
    fn propagator(&mut self) -> &Rc<RefCell<Inside>> {
        self.inside.get_or_insert_with(|| {
            let inside = Rc::new(RefCell::new(Inside::default()));
            self.inner.connect_propagator(Rc::clone(&inside));
            inside
        })
    }
}

/// What the user propagator checks inside the search: no cycles, and (when asked) no plan
/// prefix that breaks a window.
#[derive(Default)]
struct Inside {
    cycles: Option<NoCycles>,
    prefix: Option<ThermalPrefix>,
}

impl Propagator for Inside {
    fn notify_assignment(&mut self, lits: &[pindakaas::Lit]) {
        if let Some(c) = self.cycles.as_mut() {
            c.notify_assignment(lits);
        }
        if let Some(p) = self.prefix.as_mut() {
            for &l in lits {
                p.notify(Lit::from_dimacs(i32::from(l)));
            }
        }
    }

    fn notify_new_decision_level(&mut self) {
        if let Some(c) = self.cycles.as_mut() {
            c.notify_new_decision_level();
        }
        if let Some(p) = self.prefix.as_mut() {
            p.new_level();
        }
    }

    fn notify_backtrack(&mut self, new_level: usize, _restart: bool) {
        if let Some(c) = self.cycles.as_mut() {
            c.notify_backtrack(new_level);
        }
        if let Some(p) = self.prefix.as_mut() {
            p.backtrack(new_level);
        }
    }

    fn propagate(&mut self, _slv: &mut dyn SolvingActions) -> Option<pindakaas::Lit> {
        if let Some(lit) = self.cycles.as_mut().and_then(NoCycles::propagate) {
            return Some(lit);
        }
        // A broken window queues its clause, which the solver asks for next; so do the
        // clauses the other racers learned.
        if let Some(p) = self.prefix.as_mut() {
            p.import_shared();
            p.check();
        }
        None
    }

    fn explain_propagation(&mut self, propagated: pindakaas::Lit, clause: ClauseBuilder<'_>) {
        if let Some(c) = self.cycles.as_mut() {
            c.explain_propagation(propagated, clause);
        }
    }

    fn check_solution(&mut self, _slv: &mut dyn SolvingActions, solution: Solution<'_>) -> bool {
        let cycles = self
            .cycles
            .as_mut()
            .is_some_and(|c| c.model_cycles(&solution));
        let broken = !cycles && self.prefix.as_mut().is_some_and(ThermalPrefix::check);
        !(cycles || broken)
    }

    fn provide_clause(
        &mut self,
        _slv: &mut dyn SolvingActions,
        mut clause: ClauseBuilder<'_>,
    ) -> Option<ClausePersistence> {
        if let Some((lits, persistence)) = self.cycles.as_mut().and_then(|c| c.clauses.pop()) {
            clause.extend(lits.into_iter().map(to_pk));
            return Some(persistence);
        }
        let lits = self.prefix.as_mut()?.pop_clause()?;
        clause.extend(lits.into_iter().map(to_pk));
        Some(ClausePersistence::Irredundant)
    }
}

impl PropagatorConfig for Inside {}

const NONE: u32 = u32::MAX;

/// The chains of chosen edges under the solver's current (partial) assignment.
///
/// Invariants: `succ`/`pred` hold the merged edges; for a block with no successor (a
/// chain's tail) `head_of` is its chain's head, for a block with no predecessor (a head)
/// `tail_of` is its chain's tail. Merges are undone in reverse order on backtracking.
struct NoCycles {
    /// Per variable number: the edge (u, v) it stands for (NONE: not an edge).
    edge_of: Vec<(u32, u32)>,
    /// Per block: its sideways successors and their edge literals.
    out: Vec<Vec<(u32, Lit)>>,
    succ: Vec<u32>,
    succ_lit: Vec<Lit>,
    pred: Vec<u32>,
    head_of: Vec<u32>,
    tail_of: Vec<u32>,
    /// Merged edges (u, v, head, tail), in assignment order.
    trail: Vec<(u32, u32, u32, u32)>,
    /// Trail length at the start of each decision level above 0.
    levels: Vec<usize>,
    /// Edges (t, h) that would close a chain into a cycle: to propagate false.
    pending: Vec<(u32, u32)>,
    /// Clauses to hand to the solver.
    clauses: Vec<(Vec<Lit>, ClausePersistence)>,
    /// Cycle cuts handed over (conflicts and model checks).
    cuts: u64,
}

impl NoCycles {
    fn new(blocks: usize, edges: &[(usize, usize, Lit)]) -> NoCycles {
        let max_var = edges.iter().map(|e| e.2.var() as usize).max().unwrap_or(0);
        let mut edge_of = vec![(NONE, NONE); max_var + 1];
        let mut out = vec![Vec::new(); blocks];
        for &(u, v, e) in edges {
            debug_assert!(!e.is_negative());
            edge_of[e.var() as usize] = (u as u32, v as u32);
            out[u].push((v as u32, e));
        }
        NoCycles {
            edge_of,
            out,
            succ: vec![NONE; blocks],
            succ_lit: vec![Lit::positive(1); blocks],
            pred: vec![NONE; blocks],
            head_of: (0..blocks as u32).collect(),
            tail_of: (0..blocks as u32).collect(),
            trail: Vec::new(),
            levels: Vec::new(),
            pending: Vec::new(),
            clauses: Vec::new(),
            cuts: 0,
        }
    }

    fn edge_lit(&self, u: u32, v: u32) -> Option<Lit> {
        self.out
            .get(u as usize)?
            .iter()
            .find(|(w, _)| *w == v)
            .map(|&(_, e)| e)
    }

    /// The edges of the chain from `from` to `to`, negated, into `clause` (at most one
    /// walk over the blocks: a broken chain stops it).
    fn chain_negated(&self, from: u32, to: u32, clause: &mut Vec<Lit>) {
        let mut at = from;
        let mut steps = 0;
        while at != to && steps < self.succ.len() {
            let next = self.succ[at as usize];
            if next == NONE {
                break;
            }
            clause.push(!self.succ_lit[at as usize]);
            at = next;
            steps += 1;
        }
    }

    /// Edge `u -> v` (literal `e`) was assigned true.
    fn assign(&mut self, u: u32, v: u32, e: Lit) {
        let (ui, vi) = (u as usize, v as usize);
        if self.succ[ui] != NONE || self.pred[vi] != NONE {
            // A second edge out of u or into v: the solver's own clauses conflict (or the
            // edge is known already). Nothing to merge.
            return;
        }
        let h = self.head_of[ui];
        let t = self.tail_of[vi];
        if h == v {
            // v ... u -> v: a cycle. Its cut is falsified now: a conflict.
            let mut clause = vec![!e];
            self.chain_negated(v, u, &mut clause);
            self.clauses.push((clause, ClausePersistence::Forgettable));
            self.cuts += 1;
            return;
        }
        self.succ[ui] = v;
        self.succ_lit[ui] = e;
        self.pred[vi] = u;
        self.head_of[t as usize] = h;
        self.tail_of[h as usize] = t;
        self.trail.push((u, v, h, t));
        if self.edge_lit(t, h).is_some() {
            self.pending.push((t, h));
        }
    }

    fn undo_to(&mut self, len: usize) {
        while self.trail.len() > len {
            let (u, v, h, t) = self.trail.pop().expect("longer than len");
            self.succ[u as usize] = NONE;
            self.pred[v as usize] = NONE;
            self.head_of[t as usize] = v;
            self.tail_of[h as usize] = u;
        }
    }

    /// Whether `t ... ` is still the chain from `h` to `t` (so `t -> h` closes a cycle).
    fn closes(&self, t: u32, h: u32) -> bool {
        self.succ[t as usize] == NONE
            && self.pred[h as usize] == NONE
            && self.head_of[t as usize] == h
            && self.tail_of[h as usize] == t
    }

    /// The cycles of a complete assignment, each as its cut.
    fn model_cycles(&mut self, solution: &Solution<'_>) -> bool {
        let n = self.succ.len();
        let mut next = vec![NONE; n];
        let mut next_lit = vec![Lit::positive(1); n];
        for (u, outs) in self.out.iter().enumerate() {
            for &(v, e) in outs {
                if solution.value(to_pk(e)) {
                    next[u] = v;
                    next_lit[u] = e;
                }
            }
        }
        // 0: unseen, 1: on the current walk, 2: done.
        let mut state = vec![0u8; n];
        let mut found = false;
        for s in 0..n {
            let mut walk = Vec::new();
            let mut at = s as u32;
            while at != NONE && state[at as usize] == 0 {
                state[at as usize] = 1;
                walk.push(at);
                at = next[at as usize];
            }
            if at != NONE && state[at as usize] == 1 {
                // A cycle from `at` around to it.
                let mut clause = Vec::new();
                let mut c = at;
                loop {
                    clause.push(!next_lit[c as usize]);
                    c = next[c as usize];
                    if c == at {
                        break;
                    }
                }
                self.clauses.push((clause, ClausePersistence::Irredundant));
                self.cuts += 1;
                found = true;
            }
            for w in walk {
                state[w as usize] = 2;
            }
        }
        found
    }
}

impl NoCycles {
    fn notify_assignment(&mut self, lits: &[pindakaas::Lit]) {
        for &l in lits {
            if l.is_negated() {
                continue;
            }
            let var = i32::from(l.var()) as usize;
            if let Some(&(u, v)) = self.edge_of.get(var) {
                if u != NONE {
                    self.assign(u, v, Lit::positive(var as u32));
                }
            }
        }
    }

    fn notify_new_decision_level(&mut self) {
        self.levels.push(self.trail.len());
    }

    fn notify_backtrack(&mut self, new_level: usize) {
        if let Some(&len) = self.levels.get(new_level) {
            self.undo_to(len);
            self.levels.truncate(new_level);
        }
        self.pending.clear();
    }

    fn propagate(&mut self) -> Option<pindakaas::Lit> {
        while let Some((t, h)) = self.pending.pop() {
            if self.closes(t, h) {
                let e = self.edge_lit(t, h)?;
                return Some(to_pk(!e));
            }
        }
        None
    }

    fn explain_propagation(&mut self, propagated: pindakaas::Lit, mut clause: ClauseBuilder<'_>) {
        let var = i32::from(propagated.var()) as usize;
        let Some(&(t, h)) = self.edge_of.get(var) else {
            return;
        };
        let mut reason = vec![!Lit::positive(var as u32)];
        self.chain_negated(h, t, &mut reason);
        clause.extend(reason.into_iter().map(to_pk));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ring of 4 blocks, both directions: every model is a set of paths, never a cycle.
    #[test]
    fn no_model_has_a_cycle() {
        let mut s = Cadical::default();
        let n = 4;
        let mut edges = Vec::new();
        for u in 0..n {
            for v in [(u + 1) % n, (u + n - 1) % n] {
                edges.push((u, v, s.new_lit()));
            }
        }
        // Every block has exactly one successor: only cycles satisfy this, so with the
        // propagator the formula is unsatisfiable.
        for u in 0..n {
            let outs: Vec<Lit> = edges.iter().filter(|e| e.0 == u).map(|e| e.2).collect();
            s.add_clause(&outs);
            s.add_clause(&[!outs[0], !outs[1]]);
            let ins: Vec<Lit> = edges.iter().filter(|e| e.1 == u).map(|e| e.2).collect();
            s.add_clause(&[!ins[0], !ins[1]]);
        }
        assert_eq!(s.solve(&[]), Some(true), "cycles are models without it");
        assert!(s.exclude_cycles(n, &edges));
        assert_eq!(s.solve(&[]), Some(false));
        assert!(s.cycle_cuts() > 0);
    }

    #[test]
    fn a_deadline_stops_a_hard_solve() {
        for path_blocks in [0, BIG_FORMULA_PATH_BLOCKS] {
            stop_a_hard_solve(Cadical::for_size(path_blocks));
        }
    }

    #[test]
    fn a_big_formula_runs_without_its_long_phases() {
        let (small, big) = (Cadical::for_size(0), Cadical::for_size(1_000_000));
        for option in ["reduce", "arena", "inprocessing", "walk", "compact"] {
            assert_eq!(
                small.inner.get_option(option),
                1,
                "{option}: CaDiCaL's default"
            );
            assert_eq!(big.inner.get_option(option), 0, "{option}");
        }
        assert_eq!(small.inner.get_option("terminateint"), 10);
        assert_eq!(big.inner.get_option("terminateint"), 0);
        assert_eq!(big.inner.get_option("chrono"), 0);
    }

    fn stop_a_hard_solve(mut s: Cadical) {
        crate::sat::tests::pigeonhole(&mut s, 11, 10);
        let t = Instant::now();
        s.set_interrupt(Some(t + std::time::Duration::from_millis(200)), None);
        assert_eq!(s.solve(&[]), None);
        assert!(t.elapsed().as_secs_f64() < 1.2, "{:?}", t.elapsed());
        let cancel = Arc::new(AtomicBool::new(true));
        s.set_interrupt(None, Some(cancel));
        assert_eq!(s.solve(&[]), None);
    }
}
