//! The thermal check inside the search: the plan prefix that the solver's partial
//! assignment already fixes is simulated as it grows, and the moment it breaks a window the
//! solver gets the clause the thermal loop would learn for that prefix.
//!
//! The prefix is read off the encoding's literals: the start of fragment 0 (`sz(v,0)`),
//! then the chosen move out of the last block (`e(u,v)`), and where the last block ends a
//! weld path (`end(u)`) the start of the next fragment (`sz(v,i+1)`). Every plan that makes
//! those literals true begins with that very deposit sequence, and a simulation depends
//! only on the sequence so far, so a window broken by the prefix is broken by every such
//! plan: the clause "not all of these literals" (the same as
//! [`crate::encoding::Encoding::prefix_literals`] gives) cuts no feasible plan.
//!
//! When the solver backtracks, the prefix shrinks only as far as its literals were
//! unassigned, and when the solver fixes the same steps again (after a restart, say) they
//! are confirmed without simulating them again; a prefix met before on another branch
//! resumes from its snapshot in the prefix cache it shares with the thermal loop.

use std::rc::Rc;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

use waam_thermal::{Phase, Simulation, Snapshot, ThermalModel};

use super::lit::Lit;
use super::prefix_cache::{extend_key, snapshot_spacing, Key, SharedCache, EMPTY_KEY};
use super::sharing::Sharing;
use super::shortening::shorten;
use waam_part::graph::WeldGraph;

const NONE: u32 = u32::MAX;
/// `simulated` when the simulation's state is no prefix's (it must be restored).
const DIRTY: usize = usize::MAX;

/// What an observed variable stands for.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Meaning {
    Other,
    /// The move from block u to block v.
    Edge(u32, u32),
    /// Block v starts fragment i.
    Start(u32, u32),
    /// A weld path ends at block v.
    End(u32),
}

/// An assignment the prefix reads, to undo on backtracking.
#[derive(Debug, Clone, Copy)]
enum Change {
    Next(u32),
    Start(u32),
    End(u32),
}

/// One deposit of the prefix and the literal that fixes it (the fragment's start or the
/// move into the block).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Step {
    block: u32,
    new: bool,
    lit: Lit,
}

/// The literals of the encoding the prefix is read from.
pub struct PrefixLiterals {
    pub blocks: usize,
    pub max_fragments: usize,
    /// Every move as (u, v, e(u,v)).
    pub edges: Vec<(usize, usize, Lit)>,
    /// `starts[v][i]`: block v starts fragment i.
    pub starts: Vec<Vec<Lit>>,
    /// `ends[v]`: a weld path ends at block v.
    pub ends: Vec<Lit>,
}

/// What the prefix check did since it was last asked (drained by the search).
#[derive(Debug, Default, Clone)]
pub struct PrefixReport {
    /// Lengths of the clauses handed to the solver.
    pub clause_lens: Vec<usize>,
    /// The window block each of them broke.
    pub violated: Vec<usize>,
    /// Deposits simulated.
    pub deposits: u64,
    /// Steps dropped from the clauses by proof, and block-steps simulated for it.
    pub shortened: u64,
    pub lookahead_block_steps: u64,
    /// Prefix steps confirmed again after a backtrack, without simulating them again.
    pub reused: u64,
    /// Prefix steps resumed from a snapshot of the same prefix met on another branch.
    pub resumed: u64,
    /// The clauses handed to the solver (kept only when asked: [`ThermalPrefix::keep_clauses`]).
    pub clauses: Vec<Vec<Lit>>,
    /// The cache key of the last complete prefix whose cooldown kept every window: the
    /// thermal loop need not cool a candidate with it again.
    pub cooled: Option<Key>,
    /// Clauses the other racers learned, handed to the solver ([`crate::sharing`]).
    pub imported: u64,
}

/// A simulation together with the model it borrows.
struct OwnedSimulation {
    // Declared before `model`, so dropped before it.
    sim: Simulation<'static>,
    model: Arc<ThermalModel>,
}

impl OwnedSimulation {
    fn new(
        model: Arc<ThermalModel>,
        deadline: Option<Instant>,
        cancel: Option<Arc<AtomicBool>>,
    ) -> OwnedSimulation {
        // SAFETY: the model lives on the heap behind `model`, which never moves it and is
        // kept (and dropped last) by this struct; `sim` is private to it and never moved
        // out, so the borrow never outlives the model.
        let borrowed: &'static ThermalModel = unsafe { &*Arc::as_ptr(&model) };
        let mut sim = Simulation::new(borrowed)
            .with_threads(1)
            .with_deadline(deadline);
        if let Some(c) = cancel {
            sim = sim.with_cancel(c);
        }
        OwnedSimulation { sim, model }
    }
}

/// The prefix fixed by the solver's assignment, simulated as it grows.
pub struct ThermalPrefix {
    meaning: Vec<Meaning>,
    ends: Vec<Lit>,
    /// For proving shorter clauses: the weld graph, the most fragments, and the block-steps
    /// allowed per clause (0: learn the plain violating prefix).
    graph: Arc<WeldGraph>,
    max_fragments: usize,
    lookahead_budget: usize,
    n: usize,
    /// Per block: its chosen successor and the move's literal.
    next: Vec<(u32, Lit)>,
    ended: Vec<bool>,
    /// Per fragment: its start block and literal.
    start: Vec<(u32, Lit)>,
    trail: Vec<Change>,
    /// Trail length at the start of each decision level above 0.
    levels: Vec<usize>,
    /// The simulated prefix; its first `confirmed` steps hold under the assignment.
    prefix: Vec<Step>,
    confirmed: usize,
    /// The prefix as (block, new fragment), and the cache key of each of its prefixes.
    order: Vec<(usize, bool)>,
    keys: Vec<Key>,
    /// Per block: its position in `prefix` (NONE: not in it).
    position: Vec<u32>,
    owned: OwnedSimulation,
    /// Deposits of `prefix` the simulation's state is after (DIRTY: to be restored).
    simulated: usize,
    /// The state before any deposit.
    empty: Snapshot,
    cache: SharedCache,
    /// Prefix lengths that are snapshotted (multiples of it).
    spacing: usize,
    /// The complete prefix passed its cooldown (reset when the prefix changes).
    cooled: bool,
    /// A deadline or cancel stopped a simulation: no more verdicts.
    stopped: bool,
    deadline: Option<Instant>,
    cancel: Option<Arc<AtomicBool>>,
    clauses: Vec<Vec<Lit>>,
    report: PrefixReport,
    /// Copy the clauses into the report (for a search that hands them on).
    keep_clauses: bool,
    /// The race's clause pool: violations learned here are published, the other racers'
    /// are handed to the solver too (see [`crate::sharing`]).
    sharing: Option<Sharing>,
}

impl ThermalPrefix {
    /// The check of the prefixes of `lits` by `model`, keeping its snapshots in `cache`
    /// (the thermal loop's).
    pub fn new(
        lits: &PrefixLiterals,
        model: Arc<ThermalModel>,
        cache: SharedCache,
        graph: Arc<WeldGraph>,
        lookahead_budget: usize,
    ) -> ThermalPrefix {
        let max_var = lits
            .edges
            .iter()
            .map(|e| e.2)
            .chain(lits.starts.iter().flatten().copied())
            .chain(lits.ends.iter().copied())
            .map(|l| l.var() as usize)
            .max()
            .unwrap_or(0);
        let mut meaning = vec![Meaning::Other; max_var + 1];
        for &(u, v, e) in &lits.edges {
            meaning[e.var() as usize] = Meaning::Edge(u as u32, v as u32);
        }
        for (v, row) in lits.starts.iter().enumerate() {
            for (i, s) in row.iter().enumerate() {
                meaning[s.var() as usize] = Meaning::Start(v as u32, i as u32);
            }
        }
        for (v, e) in lits.ends.iter().enumerate() {
            meaning[e.var() as usize] = Meaning::End(v as u32);
        }
        let n = lits.blocks;
        let unset = (NONE, Lit::positive(1));
        let mut prefix = ThermalPrefix {
            meaning,
            ends: lits.ends.clone(),
            graph,
            max_fragments: lits.max_fragments,
            lookahead_budget,
            n,
            next: vec![unset; n],
            ended: vec![false; n],
            start: vec![unset; lits.max_fragments],
            trail: Vec::new(),
            levels: Vec::new(),
            prefix: Vec::new(),
            confirmed: 0,
            order: Vec::new(),
            keys: Vec::new(),
            position: vec![NONE; n],
            owned: OwnedSimulation::new(model, None, None),
            simulated: 0,
            empty: Snapshot::default(),
            cache,
            spacing: snapshot_spacing(n),
            cooled: false,
            stopped: false,
            deadline: None,
            cancel: None,
            clauses: Vec::new(),
            report: PrefixReport::default(),
            keep_clauses: false,
            sharing: None,
        };
        prefix.reset_simulation();
        prefix
    }

    /// The literals the check reads (to observe in the solver).
    pub fn observed(&self) -> impl Iterator<Item = Lit> + '_ {
        self.meaning
            .iter()
            .enumerate()
            .filter(|(_, m)| **m != Meaning::Other)
            .map(|(v, _)| Lit::positive(v as u32))
    }

    /// Judges later prefixes by `model` (e.g. narrowed windows): everything simulated so
    /// far is dropped.
    pub fn set_model(&mut self, model: Arc<ThermalModel>) {
        self.owned = OwnedSimulation::new(model, self.deadline, self.cancel.clone());
        self.reset_simulation();
    }

    /// Stops simulations at `deadline` or on `cancel` (no verdict is given after that).
    pub fn set_interrupt(&mut self, deadline: Option<Instant>, cancel: Option<Arc<AtomicBool>>) {
        self.deadline = deadline;
        self.cancel = cancel;
        let model = Arc::clone(&self.owned.model);
        self.set_model(model);
    }

    /// Starts the simulation over from the empty prefix.
    fn reset_simulation(&mut self) {
        self.empty = self.owned.sim.snapshot();
        self.cache.borrow_mut().clear();
        self.truncate(0);
        self.simulated = 0;
        self.stopped = false;
    }

    /// What the check did since the last call.
    /// Copies every clause handed to the solver into the report too.
    pub fn keep_clauses(&mut self) {
        self.keep_clauses = true;
    }

    /// Publishes the clauses learned here to the race's pool, and takes the others'.
    pub fn share(&mut self, sharing: Sharing) {
        self.sharing = Some(sharing);
    }

    /// Queues the clauses the other racers learned since the last call (called while the
    /// solver propagates; a clause the assignment falsifies makes the solver backtrack).
    pub fn import_shared(&mut self) {
        if let Some(sharing) = self.sharing.as_mut() {
            self.report.imported += sharing.take_new(&mut self.clauses) as u64;
        }
    }

    pub fn take_report(&mut self) -> PrefixReport {
        std::mem::take(&mut self.report)
    }

    /// A clause for the solver, if one is waiting.
    pub fn pop_clause(&mut self) -> Option<Vec<Lit>> {
        self.clauses.pop()
    }

    /// Literals assigned true or false (observed variables only matter).
    pub fn notify(&mut self, lit: Lit) {
        if lit.is_negative() {
            return;
        }
        match self.meaning.get(lit.var() as usize) {
            Some(&Meaning::Edge(u, v)) if self.next[u as usize].0 == NONE => {
                self.next[u as usize] = (v, lit);
                self.trail.push(Change::Next(u));
            }
            Some(&Meaning::Start(v, i)) if self.start[i as usize].0 == NONE => {
                self.start[i as usize] = (v, lit);
                self.trail.push(Change::Start(i));
            }
            Some(&Meaning::End(v)) if !self.ended[v as usize] => {
                self.ended[v as usize] = true;
                self.trail.push(Change::End(v));
            }
            _ => {}
        }
    }

    pub fn new_level(&mut self) {
        self.levels.push(self.trail.len());
    }

    pub fn backtrack(&mut self, level: usize) {
        let Some(&len) = self.levels.get(level) else {
            return;
        };
        self.levels.truncate(level);
        while self.trail.len() > len {
            // The prefix holds only up to the first step that relied on an undone literal.
            let keep = match self.trail.pop().expect("longer than len") {
                Change::Next(u) => {
                    self.next[u as usize].0 = NONE;
                    self.after(u)
                }
                Change::End(u) => {
                    self.ended[u as usize] = false;
                    self.after(u)
                }
                Change::Start(i) => {
                    let (v, _) =
                        std::mem::replace(&mut self.start[i as usize], (NONE, Lit::positive(1)));
                    match self.position[v as usize] {
                        NONE => usize::MAX,
                        p => p as usize,
                    }
                }
            };
            self.confirmed = self.confirmed.min(keep);
        }
    }

    /// Prefix steps up to and including block `u` (all of them if `u` is not in it).
    fn after(&self, u: u32) -> usize {
        match self.position[u as usize] {
            NONE => usize::MAX,
            p => p as usize + 1,
        }
    }

    /// The step the assignment fixes after the first `len` steps of the prefix, if any.
    fn fixed_step(&self, len: usize) -> Option<Step> {
        let Some(last) = len.checked_sub(1).map(|j| self.prefix[j]) else {
            let (v, lit) = self.start[0];
            return (v != NONE).then_some(Step {
                block: v,
                new: true,
                lit,
            });
        };
        let (v, lit) = self.next[last.block as usize];
        let step = if v != NONE {
            Step {
                block: v,
                new: false,
                lit,
            }
        } else if self.ended[last.block as usize] {
            let fragments = self.prefix[..len].iter().filter(|s| s.new).count();
            let (v, lit) = *self.start.get(fragments)?;
            if v == NONE {
                return None;
            }
            Step {
                block: v,
                new: true,
                lit,
            }
        } else {
            return None;
        };
        // A block twice: the assignment contradicts itself, the solver will see it.
        let fresh = match self.position[step.block as usize] {
            NONE => true,
            p => p as usize >= len,
        };
        fresh.then_some(step)
    }

    /// Follows the prefix as far as the assignment fixes it, simulating what is new; true
    /// when it breaks a window (a clause is then waiting in [`ThermalPrefix::pop_clause`]).
    pub fn check(&mut self) -> bool {
        if self.stopped {
            return false;
        }
        while let Some(step) = self.fixed_step(self.confirmed) {
            if self.prefix.get(self.confirmed) == Some(&step) {
                self.confirmed += 1;
                self.report.reused += 1;
                continue;
            }
            self.truncate(self.confirmed);
            if self.deposit(step) {
                return true;
            }
            if self.stopped {
                return false;
            }
            self.confirmed += 1;
        }
        if self.confirmed == self.n && !self.cooled {
            return self.cooldown();
        }
        false
    }

    /// Drops the prefix after its first `len` steps.
    fn truncate(&mut self, len: usize) {
        for s in self.prefix.drain(len.min(self.prefix.len())..) {
            self.position[s.block as usize] = NONE;
        }
        self.order.truncate(len);
        self.keys.truncate(len);
        self.confirmed = self.confirmed.min(len);
        if self.simulated > len {
            self.simulated = DIRTY;
        }
        self.cooled = false;
    }

    /// Brings the simulation to the state after the first `len` steps of the prefix,
    /// from the longest snapshot of it (false: stopped by the deadline or a cancel).
    fn restore(&mut self, len: usize) -> bool {
        if self.simulated == len {
            return true;
        }
        let current = if self.simulated < len {
            self.simulated
        } else {
            0
        };
        let cache = Rc::clone(&self.cache);
        let cache = cache.borrow();
        let cached = (current + 1..=len)
            .rev()
            .filter(|j| j % self.spacing == 0)
            .find_map(|j| Some((j, cache.get(self.keys[j - 1], j)?)));
        match cached {
            Some((j, snap)) => {
                self.owned.sim.restore_from_trail(snap, &self.order);
                self.simulated = j;
            }
            None if self.simulated < len => {}
            None => {
                self.owned.sim.restore(&self.empty);
                self.simulated = 0;
            }
        }
        drop(cache);
        for j in self.simulated..len {
            let (b, new) = self.order[j];
            // Deposited before without a violation: it deposits the same way again.
            let ok = self.owned.sim.deposit(b, new).is_ok();
            self.report.deposits += 1;
            if self.owned.sim.cancelled() || !ok {
                self.stopped = true;
                self.simulated = DIRTY;
                return false;
            }
            self.simulated = j + 1;
            self.remember();
        }
        true
    }

    /// Snapshots the simulation's state (after `simulated` steps) where the spacing asks.
    fn remember(&mut self) {
        if self.simulated % self.spacing == 0 {
            self.cache
                .borrow_mut()
                .insert(self.keys[self.simulated - 1], &self.owned.sim);
        }
    }

    /// Deposits `step` after the prefix (all of it confirmed); true on a violation (its
    /// clause is queued).
    fn deposit(&mut self, step: Step) -> bool {
        let len = self.prefix.len();
        let key = extend_key(
            self.keys.last().copied().unwrap_or(EMPTY_KEY),
            step.block as usize,
            step.new,
        );
        self.order.push((step.block as usize, step.new));
        self.keys.push(key);
        let cache = Rc::clone(&self.cache);
        let cached = cache.borrow().get(key, len + 1).map(|snap| {
            // This very prefix was simulated on another branch.
            self.owned.sim.restore_from_trail(snap, &self.order);
        });
        if cached.is_some() {
            self.report.resumed += 1;
        } else {
            if !self.restore(len) {
                self.order.pop();
                self.keys.pop();
                return false;
            }
            let result = self.owned.sim.deposit(step.block as usize, step.new);
            self.report.deposits += 1;
            if self.owned.sim.cancelled() {
                self.stopped = true;
            }
            if self.stopped || result.is_err() {
                self.simulated = DIRTY;
                if let (Err(v), false) = (result, self.stopped) {
                    self.prefix.push(step); // for the clause only
                    self.learn(v.prefix_len, v.phase != Phase::Deposit, v.block);
                    self.prefix.pop();
                }
                self.order.pop();
                self.keys.pop();
                return !self.stopped;
            }
        }
        self.position[step.block as usize] = len as u32;
        self.prefix.push(step);
        self.simulated = len + 1;
        self.remember();
        false
    }

    /// The cooldown after the complete prefix; true on a violation.
    fn cooldown(&mut self) -> bool {
        if !self.restore(self.n) {
            return false;
        }
        let end = self.owned.sim.finish();
        self.simulated = DIRTY;
        if self.owned.sim.cancelled() {
            self.stopped = true;
            return false;
        }
        self.cooled = true;
        if let Ok(Ok(())) = end {
            self.report.cooled = self.keys.get(self.n - 1).copied();
        }
        match end {
            // A complete plan is the same whether its last fragment is closed or not.
            Ok(Err(v)) => {
                self.learn(self.n, false, v.block);
                true
            }
            // Feasible, or a part that cannot cool: the thermal loop reports that.
            _ => false,
        }
    }

    /// Queues the clause ruling out the plans that begin with the first `len` steps (the
    /// last fragment ending there when `closed`).
    /// The prefix is shortened first where that is proven ([`shorten`]).
    fn learn(&mut self, len: usize, closed: bool, window: usize) {
        let seq: Vec<(usize, bool)> = self.prefix[..len]
            .iter()
            .map(|s| (s.block as usize, s.new))
            .collect();
        let graph = Arc::clone(&self.graph);
        let (k, budget) = (self.max_fragments, self.lookahead_budget);
        let interrupt = waam_thermal::Interrupt {
            deadline: self.deadline,
            cancel: self.cancel.clone(),
        };
        let r = shorten(&graph, k, &seq, len, closed, budget, &interrupt, |l| {
            // The steps before the violating one deposited without a violation.
            if self.restore(l) {
                Some(self.owned.sim.clone())
            } else {
                None
            }
        });
        self.report.shortened += r.dropped;
        self.report.lookahead_block_steps += r.cost;
        let (len, closed) = (r.len, r.closed);
        let steps = &self.prefix[..len];
        let mut clause: Vec<Lit> = steps.iter().map(|s| !s.lit).collect();
        for pair in steps.windows(2).filter(|p| p[1].new) {
            clause.push(!self.ends[pair[0].block as usize]);
        }
        if closed {
            if let Some(last) = steps.last() {
                clause.push(!self.ends[last.block as usize]);
            }
        }
        self.report.clause_lens.push(clause.len());
        self.report.violated.push(window);
        if self.keep_clauses {
            self.report.clauses.push(clause.clone());
        }
        if let Some(sharing) = &self.sharing {
            sharing.publish(&clause);
        }
        self.clauses.push(clause);
    }
}
