//! Planning the rest of a part from a built state (issue #31: the closed loop re-plans what
//! remains from what the cell measured).
//!
//! The same encoding, rules and learned clauses as [`crate::plan`], on the whole part: the
//! weld paths already done are fixed by assumptions (their starts, moves and ends, as
//! [`Encoding::prefix_literals`] writes them), so every model is a whole plan that begins
//! with what was built, and at most k weld paths in all. Only the judge differs: each
//! candidate's remainder is simulated from the given [`BuildState`] (the estimator's
//! temperatures, t8/5 counters and time), not from an empty plate. A violation teaches the
//! clause of its violating prefix; shortening it may drop remainder steps only (a shorter
//! prefix inside the built part would be judged from another state), so the clauses are as
//! sound as the loop's. Every plan ruled out breaks a window from the given state, hence
//! "no completion" is a proof for that state.
//!
//! What counts against k: every weld path begun, the built ones included. A path cut short
//! (a wire fault) and then resumed is a new arc start: with [`Built::open`] false the next
//! deposit begins a new weld path. With `open` true (re-planned at a layer boundary while
//! the arc is still on) the rest may continue the last path along a move of the weld graph,
//! or end it there.

use std::time::Instant;

use thiserror::Error;

use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_thermal::{
    self as thermal, BuildState, Phase, Simulation, StateError, ThermalModel, Violation,
};

use crate::encoding::{Decoded, Encoding};
use crate::prefix_cache::deposits;
use crate::sat::{Lit, SatSolver};
use crate::search::fragments_of;
use crate::shortening::shorten;
use crate::{
    check_size, max_fragments, new_solver, stopped_early, timed_out, Acyclicity, CandidateVerdict,
    Event, Found, NoPlan, Options, PlanError, Progress, Report, Stats,
};

/// What has been built: the deposits welded so far, in order, and the thermal state now.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Built {
    /// Welded blocks (part indices) in weld order with whether each began a weld path, their
    /// temperatures, t8/5 counters and the time (from the estimator, not necessarily the
    /// planner's own model).
    pub state: BuildState,
    /// The last weld path may go on (its arc is still on); false: every weld path done is
    /// closed and the next deposit is an arc start.
    pub open: bool,
}

impl Built {
    /// The weld paths done so far, block indices in weld order.
    pub fn fragments(&self) -> Vec<Vec<usize>> {
        fragments_of(&self.state.order)
    }

    /// What a whole plan that begins with this prefix adds to it: whether its first
    /// fragment continues the last weld path done, and the fragments (or the rest of the
    /// continued one) after the prefix.
    pub fn remainder(&self, whole: &[Vec<usize>]) -> (bool, Vec<Vec<usize>>) {
        let done = self.fragments();
        let Some(last) = done.len().checked_sub(1) else {
            return (false, whole.to_vec());
        };
        let mut rest: Vec<Vec<usize>> = whole[done.len()..].to_vec();
        let extra = whole[last][done[last].len()..].to_vec();
        let continues = !extra.is_empty();
        if continues {
            rest.insert(0, extra);
        }
        (continues, rest)
    }
}

/// Why the rest of a part cannot be planned from a built state.
#[derive(Debug, Error)]
pub enum RestError {
    /// The built prefix breaks a rule of the part (named, with the deposit).
    #[error("the built prefix is not the start of a valid plan: {0}")]
    Prefix(String),
    #[error(transparent)]
    State(#[from] StateError),
    #[error(transparent)]
    Plan(#[from] PlanError),
}

/// The best completion of `built`: fewest weld paths in all, then the largest worst-case
/// t8/5 margin of what is still to cool; `best` holds the whole plan (the built prefix
/// first, see [`Built::remainder`]). `proven` and `no_plan` as in [`crate::plan`], for
/// this state.
pub fn plan_rest(
    part: &Part,
    built: &Built,
    opts: &Options,
    progress: Progress,
) -> Result<Report, RestError> {
    search_rest(part, built, opts, progress, true)
}

/// The first feasible completion of `built` found, without optimizing.
pub fn first_rest(
    part: &Part,
    built: &Built,
    opts: &Options,
    progress: Progress,
) -> Result<Report, RestError> {
    search_rest(part, built, opts, progress, false)
}

/// Checks that the built prefix moves along the weld graph and welds no block before what
/// it stands on, within `k` weld paths.
fn check_prefix(part: &Part, graph: &WeldGraph, built: &Built, k: usize) -> Result<(), RestError> {
    let bad = |m: String| Err(RestError::Prefix(m));
    let n = part.len();
    let mut welded = vec![false; n];
    let mut last: Option<usize> = None;
    let mut paths = 0;
    for (p, &(b, new)) in built.state.order.iter().enumerate() {
        let at = || format!("deposit {}", p + 1);
        if b >= n {
            return bad(format!("{}: block index {b} is not in the part", at()));
        }
        let block = part.block(b);
        if welded[b] {
            return bad(format!("{}: block {block:?} is welded twice", at()));
        }
        paths += usize::from(new);
        if !new {
            match last {
                Some(a) if graph.has_edge(a, b) => {}
                Some(a) => {
                    return bad(format!(
                        "{}: no weld move from {:?} to {block:?}",
                        at(),
                        part.block(a)
                    ))
                }
                None => return bad("the first deposit must begin a weld path".into()),
            }
        }
        if let Some(&s) = graph.supports(b).iter().find(|&&s| !welded[s as usize]) {
            return bad(format!(
                "{}: block {block:?} is welded before {:?}, which it stands on",
                at(),
                part.block(s as usize)
            ));
        }
        welded[b] = true;
        last = Some(b);
    }
    if paths > k {
        return bad(format!("{paths} weld paths, more than max_fragments = {k}"));
    }
    Ok(())
}

fn search_rest(
    part: &Part,
    built: &Built,
    opts: &Options,
    progress: Progress,
    optimize: bool,
) -> Result<Report, RestError> {
    let started = Instant::now();
    check_size(part, opts)?;
    let graph = WeldGraph::new(part);
    let k = max_fragments(part, opts);
    check_prefix(part, &graph, built, k)?;
    let base = ThermalModel::try_new(part, &graph).map_err(PlanError::from)?;
    // The state is checked once here; every candidate resumes from it.
    Simulation::from_state(&base, &built.state)?;
    let done = built.fragments();
    let built_len = built.state.order.len();
    let mut stats = Stats::default();
    let interrupt = thermal::Interrupt {
        deadline: opts.timeout.and_then(|t| started.checked_add(t)),
        cancel: opts.cancel.clone(),
    };
    let mut solver = new_solver(opts.solver, part.len().saturating_mul(k));
    solver.set_interrupt(interrupt.deadline, interrupt.cancel.clone());
    let Some(enc) = Encoding::new(part, &graph, k, opts.acyclicity, &mut solver, &|| {
        interrupt.reached()
    }) else {
        return Ok(stopped_early(started));
    };
    if opts.acyclicity != Acyclicity::Eager {
        solver.exclude_cycles(part.len(), &enc.cycle_edges(part));
    }
    (stats.variables, stats.clauses) = solver.size();
    stats.encode_s = started.elapsed().as_secs_f64();
    let prefix = if done.is_empty() {
        Vec::new()
    } else {
        enc.prefix_literals(&done, !built.open)
    };
    let mut judge = Judge {
        part,
        graph: &graph,
        k,
        built,
        built_len,
        budget: opts.lookahead_budget,
        interrupt: &interrupt,
        threads: opts.threads,
    };
    let mut model = base.clone();
    let mut violations = vec![0usize; part.len()];
    let mut best: Option<Found> = None;
    let (mut proven, mut any_valid, mut interrupted) = (true, false, false);
    // A closed prefix with blocks left needs another weld path: said here, as the solver
    // may take long to prove that fewer leave blocks uncovered (a Hamiltonian refutation).
    let fewest = done.len() + usize::from(!built.open && built_len < part.len());
    let levels: Vec<usize> = if optimize {
        (fewest.max(1)..=k).collect()
    } else {
        vec![k]
    };
    'levels: for f in levels {
        let mut assume = prefix.clone();
        assume.extend(enc.at_most_fragments(f));
        loop {
            if timed_out(opts, started) {
                proven = false;
                break 'levels;
            }
            let t = Instant::now();
            let candidate =
                next_candidate(&mut solver, &enc, &assume, &mut stats, &mut interrupted);
            stats.sat_s += t.elapsed().as_secs_f64();
            let Some(candidate) = candidate else {
                if interrupted {
                    proven = false;
                    break 'levels;
                }
                break;
            };
            any_valid = true;
            stats.candidates += 1;
            let t = Instant::now();
            let judged = judge.run(&model, &candidate, &mut stats)?;
            stats.simulator_s += t.elapsed().as_secs_f64();
            let verdict = match judged {
                Judged::Interrupted => {
                    proven = false;
                    break 'levels;
                }
                Judged::Violated(v, seq) => {
                    violations[v.block] += 1;
                    let t = Instant::now();
                    let (len, closed) = judge.shortened(&model, &seq, &v, &mut stats);
                    stats.lookahead_s += t.elapsed().as_secs_f64();
                    let clause: Vec<Lit> = enc
                        .prefix_literals(&fragments_of(&seq[..len]), closed)
                        .into_iter()
                        .map(|l| !l)
                        .collect();
                    stats.record_clause(clause.len());
                    solver.add_clause(&clause);
                    CandidateVerdict::Violated {
                        block: part.block(v.block),
                        kind: v.kind,
                        time_s: v.time_s,
                        prefix_len: v.prefix_len,
                        clause_len: clause.len(),
                    }
                }
                Judged::Feasible(margin_crossings) => {
                    stats.feasible += 1;
                    stats
                        .first_feasible_s
                        .get_or_insert(started.elapsed().as_secs_f64());
                    let margin = if base.has_windows() {
                        base.margin(&margin_crossings)
                    } else {
                        f64::INFINITY
                    };
                    if best.as_ref().is_none_or(|b| {
                        candidate.len() < b.fragments.len()
                            || (candidate.len() == b.fragments.len() && margin > b.margin)
                    }) {
                        stats.best_margin_s = Some(margin).filter(|m| m.is_finite());
                        best = Some(Found {
                            fragments: candidate.clone(),
                            margin,
                        });
                    }
                    CandidateVerdict::Feasible
                }
            };
            progress(Event::Candidate {
                fragments: &candidate,
                verdict,
                stats: &stats,
            });
            if let (CandidateVerdict::Feasible, Some(b)) = (verdict, &best) {
                if !optimize || b.margin.is_infinite() {
                    break 'levels;
                }
                // Only strictly better completions from now on (margins compared to 1 µs).
                let blocked: Vec<Lit> = enc
                    .plan_literals(&candidate)
                    .into_iter()
                    .map(|l| !l)
                    .collect();
                solver.add_clause(&blocked);
                model = base.narrowed(b.margin + 1e-6);
            }
        }
        if best.as_ref().is_some_and(|b| b.fragments.len() <= f) {
            break;
        }
    }
    let no_plan = match (&best, proven) {
        (None, true) if !any_valid => Some(NoPlan::NoValidPlan {
            max_fragments: k,
            needs_at_least: None,
            layer: None,
        }),
        (None, true) => {
            let (i, &times) = violations
                .iter()
                .enumerate()
                .max_by_key(|&(i, &t)| (t, std::cmp::Reverse(i)))
                .expect("a part has blocks");
            Some(NoPlan::AllBreakWindows {
                block: part.block(i),
                times,
            })
        }
        _ => None,
    };
    stats.total_s = started.elapsed().as_secs_f64();
    Ok(Report {
        best,
        proven,
        no_plan,
        stats,
    })
}

/// The next model of the solver under `assume` as a plan, cutting cycles between solves
/// when the backend does not keep them out itself; `None` when none is left or the solve
/// was stopped (`interrupted` is then set).
fn next_candidate(
    solver: &mut Box<dyn SatSolver>,
    enc: &Encoding,
    assume: &[Lit],
    stats: &mut Stats,
    interrupted: &mut bool,
) -> Option<Vec<Vec<usize>>> {
    loop {
        stats.sat_solves += 1;
        let sat = solver.solve(assume);
        if sat != Some(true) {
            *interrupted |= sat.is_none();
            return None;
        }
        match enc.decode(solver) {
            Decoded::Plan(fragments) => return Some(fragments),
            Decoded::Cycles(cycles) => {
                for cycle in &cycles {
                    solver.add_clause(&enc.cycle_cut(cycle));
                    stats.cycle_cuts += 1;
                }
            }
        }
    }
}

/// What the simulation from the built state said of a candidate.
enum Judged {
    /// Every window kept; the crossings from the state on.
    Feasible(Vec<thermal::Crossing>),
    /// The first violation, and the candidate's deposit sequence.
    Violated(Violation, Vec<(usize, bool)>),
    Interrupted,
}

/// Simulates candidates' remainders from the built state.
struct Judge<'a> {
    part: &'a Part,
    graph: &'a WeldGraph,
    k: usize,
    built: &'a Built,
    built_len: usize,
    budget: usize,
    interrupt: &'a thermal::Interrupt,
    /// Threads the simulations step on (0: the thermal model's default).
    threads: usize,
}

impl Judge<'_> {
    fn start<'m>(&self, model: &'m ThermalModel) -> Result<Simulation<'m>, StateError> {
        Ok(Simulation::from_state(model, &self.built.state)?
            .with_threads(self.threads)
            .interrupted_by(self.interrupt))
    }

    fn run(
        &mut self,
        model: &ThermalModel,
        candidate: &[Vec<usize>],
        stats: &mut Stats,
    ) -> Result<Judged, RestError> {
        let seq = deposits(candidate);
        debug_assert_eq!(seq[..self.built_len], self.built.state.order[..]);
        let mut sim = self.start(model)?.recording();
        stats.deposits_reused += self.built_len as u64;
        for &(b, new) in &seq[self.built_len..] {
            stats.deposits_simulated += 1;
            let deposited = sim.deposit(b, new);
            if sim.cancelled() {
                return Ok(Judged::Interrupted);
            }
            if let Err(v) = deposited {
                return Ok(Judged::Violated(v, seq));
            }
        }
        let before = sim.steps();
        let end = sim.finish().map_err(PlanError::from)?;
        stats.cooldown_steps += sim.steps() - before;
        if sim.cancelled() {
            return Ok(Judged::Interrupted);
        }
        Ok(match end {
            Ok(()) => Judged::Feasible(sim.crossings().to_vec()),
            Err(v) => Judged::Violated(v, seq),
        })
    }

    /// The violating prefix of `seq`, shortened by proof as the loop does, but never into
    /// the built prefix (its shorter prefixes have no state of their own here): its length
    /// and whether its last fragment is closed.
    fn shortened(
        &self,
        model: &ThermalModel,
        seq: &[(usize, bool)],
        v: &Violation,
        stats: &mut Stats,
    ) -> (usize, bool) {
        let state_after = |len: usize| -> Option<Simulation<'_>> {
            if len < self.built_len {
                return None;
            }
            let mut sim = self.start(model).ok()?;
            for &(b, new) in &seq[self.built_len..len] {
                sim.deposit(b, new).ok()?;
            }
            (!sim.cancelled()).then_some(sim)
        };
        let r = shorten(
            self.graph,
            self.k,
            seq,
            v.prefix_len,
            v.phase != Phase::Deposit,
            self.budget,
            self.interrupt,
            state_after,
        );
        stats.lookahead_block_steps += r.cost;
        stats.shortened += r.dropped;
        debug_assert!(r.len >= self.built_len || self.part.is_empty());
        (r.len, r.closed)
    }
}
