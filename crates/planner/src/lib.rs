//! The SAT planner: at most k weld paths that together deposit every block once, moving
//! sideways or up, never welding under what stands, whose cooling keeps every t8/5 window
//! — or a proof that there is none.
//!
//! The objective of [`plan`]: fewest fragments (arc starts) first, then the largest
//! worst-case margin of any t8/5 value to its window's bounds. Fragment counts are tried
//! from 1 up under an assumption, so everything the solver learns carries over; within the
//! smallest count that has a feasible plan, every feasible plan found narrows the windows
//! by its margin, so the next one found is strictly better, until none is left.

pub mod cadical;
pub mod constructive;
mod contour;
pub mod cubes;
pub mod encoding;
mod lit;
mod portfolio;
mod prefix_cache;
mod race;
pub mod rest;
pub mod sat;
mod search;
mod sharing;
mod shortening;
pub mod thermal_prefix;

#[cfg(test)]
mod graph_tests;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::Serialize;
use thiserror::Error;

use waam_access::{TorchAccess, TorchSetup};
use waam_part::graph::WeldGraph;
use waam_part::plan::Plan;
use waam_part::{Block, Part};
use waam_thermal::{self as thermal, ThermalModel};

pub use encoding::Acyclicity;
pub use rest::{first_rest, plan_rest, Built, RestError};
pub use sat::Backend;
use search::Search;

/// A fresh SAT solver of the `backend`'s kind, for an encoding of `path_blocks` path-block
/// pairs (blocks × k: CaDiCaL runs a big formula without its long uninterruptible phases).
pub fn new_solver(backend: sat::Backend, path_blocks: usize) -> Box<dyn sat::SatSolver> {
    match backend {
        sat::Backend::Cadical => Box::new(cadical::Cadical::for_size(path_blocks)),
        sat::Backend::Varisat => Box::new(sat::Varisat::default()),
    }
}

/// How the planner searches.
#[derive(Debug, Clone)]
pub struct Options {
    pub acyclicity: Acyclicity,
    /// Block-steps the thermal model may simulate per violation to prove a shorter
    /// clause (0: learn the plain violating prefix, as the paper does), in the thermal loop
    /// and inside the search alike.
    pub lookahead_budget: usize,
    /// Stop and return the best found so far (not proven) after this long.
    pub timeout: Option<Duration>,
    /// Override the part's max_fragments.
    pub max_fragments: Option<usize>,
    /// Set from another thread to stop the run (as a timeout does): the node cancels a plan
    /// when a newer part arrives. CaDiCaL stops inside a solve; varisat after it.
    pub cancel: Option<Arc<AtomicBool>>,
    /// The SAT solver.
    pub solver: Backend,
    /// Check torch access at every deposit (None: the torch is not modelled, as the
    /// shared specs and their counts assume).
    pub torch: Option<TorchSetup>,
    /// Start from a plan built layer by layer ([`constructive`]): judged first, and the
    /// solver's phases point at it. Plans and proofs are the same with or without it.
    pub warm_start: bool,
    /// Judge every candidate that keeps its windows (and the torch) once more, on the time
    /// line a robot would weld it on (None: no robot, as the shared specs and their counts
    /// assume). A rejection is learned like a violation.
    pub executed: Option<ExecutedCheck>,
    /// Refuse a part whose search would need more memory than this, MB, by the estimate
    /// of [`estimated_memory_mb`] (checked before anything is built).
    pub max_memory_mb: u64,
    /// Worker threads of [`count`] and [`enumerate`], each searching its own cubes of the
    /// plans ([`cubes`]; 0: the thermal model's default, the available cores unless set),
    /// of [`first`]'s race (one racer each) and of the varied starts (0: all cores).
    /// Counts and the order of the plans are the same on any number.
    pub threads: usize,
}

/// Why a candidate fails when a robot welds it (its transit cannot be made in the
/// modelled time, or a window breaks on the executed time line), as the plans to rule
/// out with it.
#[derive(Debug, Clone, PartialEq)]
pub struct Rejection {
    /// Every plan that begins with these fragments (block indices) fails the same way:
    /// the last fragment ends there when `closed`, else it may go on.
    pub prefix: Vec<Vec<usize>>,
    pub closed: bool,
    /// One line on what failed.
    pub reason: String,
}

/// A candidate's fragments in, its [`Rejection`] out (`None`: the candidate passes, or fails
/// for a reason the caller reports itself).
pub type JudgeExecuted = dyn Fn(&[Vec<usize>]) -> Option<Rejection> + Send + Sync;

/// The check behind [`Options::executed`].
#[derive(Clone)]
pub struct ExecutedCheck(pub Arc<JudgeExecuted>);

impl std::fmt::Debug for ExecutedCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ExecutedCheck(..)")
    }
}

/// The default of [`Options::max_memory_mb`]: a part the planner would need more for (at
/// k = 2, more than about 100,000 blocks) is refused unless the limit is raised.
pub const DEFAULT_MAX_MEMORY_MB: u64 = 2048;

/// What searching a part of `blocks` blocks with at most `k` fragments takes, MB: the
/// encoding, CaDiCaL's clause database and the layer-by-layer warm start grow with the
/// blocks and with k. Measured peaks lie at or below 12 KiB + 4 KiB x k per block: plates
/// of 10^4 to 1.6 x 10^5 blocks and cubes of 2.7 x 10^4 and 6.4 x 10^4 at k = 1 and 8 (at
/// most 10 + 3k), and the 62,614-block flanged tube at k = 6 (31.5 KiB per block in 300 s).
pub fn estimated_memory_mb(blocks: usize, k: usize) -> u64 {
    let per_block_kib = 12 + 4 * k as u64;
    (blocks as u64).saturating_mul(per_block_kib) / 1024
}

impl Default for Options {
    fn default() -> Self {
        Options {
            acyclicity: Acyclicity::Lazy,
            lookahead_budget: 2_000_000,
            timeout: None,
            max_fragments: None,
            cancel: None,
            solver: Backend::default(),
            torch: None,
            warm_start: true,
            executed: None,
            max_memory_mb: DEFAULT_MAX_MEMORY_MB,
            threads: 0,
        }
    }
}

/// What a run did, like the paper's Table 1 and more.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Stats {
    pub variables: usize,
    pub clauses: usize,
    pub encode_s: f64,
    /// Candidate plans judged by the thermal model.
    pub candidates: u64,
    /// Feasible plans found.
    pub feasible: u64,
    /// Candidates with a deposit the torch cannot reach (0 without a torch).
    pub torch_blocked: u64,
    /// Candidates rejected on the robot's executed time line (0 without a robot).
    pub executed_rejected: u64,
    pub sat_solves: u64,
    pub cycle_cuts: u64,
    pub first_feasible_s: Option<f64>,
    pub total_s: f64,
    pub sat_s: f64,
    pub acyclicity_s: f64,
    pub simulator_s: f64,
    /// Time spent proving shorter clauses (part of the learning, not of the simulator).
    pub lookahead_s: f64,
    pub lookahead_block_steps: u64,
    /// Decisions dropped from learned clauses by proof.
    pub shortened: u64,
    /// Deposits simulated for candidates, and deposits resumed from a saved prefix.
    pub deposits_simulated: u64,
    pub deposits_reused: u64,
    /// Euler steps of cooldowns after complete candidates.
    pub cooldown_steps: u64,
    /// Complete candidates whose cooldown the check inside the search had already run
    /// (feasible without simulating them again).
    pub cooled_inside: u64,
    /// Worst-case t8/5 margin of the best plan so far, s (None: no plan yet, or no windows).
    pub best_margin_s: Option<f64>,
    pub learned_clauses: u64,
    /// Of the learned clauses, those learned inside the search from a partial assignment
    /// whose plan prefix broke a window (before any complete model); deposits simulated
    /// for them, and prefix steps confirmed again without simulating.
    pub inside_clauses: u64,
    pub inside_deposits: u64,
    pub inside_reused: u64,
    /// Clauses other racers learned, handed to this search's solver ([`race`]).
    pub clauses_imported: u64,
    /// The racer whose feasible plan the race saw first ([`race`]: "default",
    /// "no-warm-start", "varisat", "seed N"); None without a race.
    pub first_plan_racer: Option<String>,
    pub clause_len_min: Option<usize>,
    pub clause_len_max: Option<usize>,
    pub clause_len_mean: Option<f64>,
    #[serde(skip)]
    clause_len_sum: u64,
}

/// What the thermal check said about one candidate plan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CandidateVerdict {
    Feasible,
    Violated {
        /// The block whose window broke, and how.
        block: Block,
        kind: thermal::ViolationKind,
        /// Simulated time of the violation, s.
        time_s: f64,
        /// Blocks deposited up to the violation.
        prefix_len: usize,
        /// Literals in the clause learned from it.
        clause_len: usize,
    },
    /// The torch cannot reach a block: what stands before it (or the plate) is in the way.
    TorchBlocked {
        /// The block that cannot be welded.
        block: Block,
        /// The deposited block in the torch's way (None: the plate).
        obstacle: Option<Block>,
        /// Blocks deposited up to and including the blocked one.
        prefix_len: usize,
        /// Literals in the clause learned from it.
        clause_len: usize,
    },
    /// It keeps its windows on the thermal model's time line, but not when the robot welds
    /// it ([`Options::executed`]): a transit too slow, or a window broken on the executed
    /// time line.
    ExecutedRejected {
        /// Blocks in the prefix ruled out.
        prefix_len: usize,
        /// Literals in the clause learned from it.
        clause_len: usize,
    },
}

impl Stats {
    fn record_clause(&mut self, len: usize) {
        self.learned_clauses += 1;
        self.clause_len_sum += len as u64;
        self.clause_len_min = Some(self.clause_len_min.map_or(len, |m| m.min(len)));
        self.clause_len_max = Some(self.clause_len_max.map_or(len, |m| m.max(len)));
        self.clause_len_mean = Some(self.clause_len_sum as f64 / self.learned_clauses as f64);
    }

    /// Adds another search's statistics (a worker of [`cubes`]): counts and times summed
    /// (times are then CPU seconds over the workers), the instance size and the run's
    /// length the largest (every worker encodes the same part), the first feasible plan
    /// the earliest, the margin the best.
    fn absorb(&mut self, other: &Stats) {
        // Destructured, so that a new field cannot be forgotten here.
        let Stats {
            variables,
            clauses,
            encode_s,
            candidates,
            feasible,
            torch_blocked,
            executed_rejected,
            sat_solves,
            cycle_cuts,
            first_feasible_s,
            total_s,
            sat_s,
            acyclicity_s,
            simulator_s,
            lookahead_s,
            lookahead_block_steps,
            shortened,
            deposits_simulated,
            deposits_reused,
            cooldown_steps,
            cooled_inside,
            best_margin_s,
            learned_clauses,
            inside_clauses,
            inside_deposits,
            inside_reused,
            clauses_imported,
            first_plan_racer,
            clause_len_min,
            clause_len_max,
            clause_len_mean: _,
            clause_len_sum,
        } = other;
        let earliest = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(x), Some(y)) => Some(x.min(y)),
            (x, y) => x.or(y),
        };
        let largest = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(x), Some(y)) => Some(x.max(y)),
            (x, y) => x.or(y),
        };
        self.variables = self.variables.max(*variables);
        self.clauses = self.clauses.max(*clauses);
        self.encode_s += encode_s;
        self.candidates += candidates;
        self.feasible += feasible;
        self.torch_blocked += torch_blocked;
        self.executed_rejected += executed_rejected;
        self.sat_solves += sat_solves;
        self.cycle_cuts += cycle_cuts;
        self.first_feasible_s = earliest(self.first_feasible_s, *first_feasible_s);
        self.total_s = self.total_s.max(*total_s);
        self.sat_s += sat_s;
        self.acyclicity_s += acyclicity_s;
        self.simulator_s += simulator_s;
        self.lookahead_s += lookahead_s;
        self.lookahead_block_steps += lookahead_block_steps;
        self.shortened += shortened;
        self.deposits_simulated += deposits_simulated;
        self.deposits_reused += deposits_reused;
        self.cooldown_steps += cooldown_steps;
        self.cooled_inside += cooled_inside;
        self.best_margin_s = largest(self.best_margin_s, *best_margin_s);
        self.learned_clauses += learned_clauses;
        self.inside_clauses += inside_clauses;
        self.inside_deposits += inside_deposits;
        self.inside_reused += inside_reused;
        self.clauses_imported += clauses_imported;
        if self.first_plan_racer.is_none() {
            self.first_plan_racer.clone_from(first_plan_racer);
        }
        self.clause_len_min = clause_len_min.map_or(self.clause_len_min, |m| {
            Some(self.clause_len_min.map_or(m, |s| s.min(m)))
        });
        self.clause_len_max = clause_len_max.map_or(self.clause_len_max, |m| {
            Some(self.clause_len_max.map_or(m, |s| s.max(m)))
        });
        self.clause_len_sum += clause_len_sum;
        self.clause_len_mean = (self.learned_clauses > 0)
            .then(|| self.clause_len_sum as f64 / self.learned_clauses as f64);
    }
}

/// A feasible plan with its worst-case t8/5 margin.
#[derive(Debug, Clone)]
pub struct Found {
    /// Fragments of block indices, in weld order.
    pub fragments: Vec<Vec<usize>>,
    /// Smallest distance of any t8/5 value to its window bounds, s (+inf: no windows;
    /// NaN: the deadline or a cancel came before it was measured).
    pub margin: f64,
}

impl Found {
    /// The plan in the shared plan format.
    pub fn plan(&self, part: &Part) -> Plan {
        Plan::from_indices(part, &self.fragments)
    }

    /// The margin for people: "1.23 s", "unbounded (no windows)" or "not measured …".
    pub fn margin_text(&self) -> String {
        if self.margin.is_finite() {
            format!("{:.2} s", self.margin)
        } else if self.margin.is_nan() {
            "not measured before the timeout".to_string()
        } else {
            "unbounded (no windows)".to_string()
        }
    }
}

/// Why a part has no feasible plan.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum NoPlan {
    /// No valid plan at all with at most k fragments.
    NoValidPlan {
        max_fragments: usize,
        /// The fewest fragments a valid plan needs, if found.
        needs_at_least: Option<usize>,
        /// A layer that alone needs more weld paths than allowed: (z, paths, dead ends).
        layer: Option<(i64, usize, usize)>,
    },
    /// Valid plans exist, but every one breaks a t8/5 window.
    AllBreakWindows {
        /// The window broken most often among the candidates, and how often.
        block: Block,
        times: usize,
    },
    /// Valid plans exist, but in every one the torch cannot reach a block past what stands
    /// (no candidate broke a window first).
    TorchCannotReach {
        /// The block the torch could not reach most often among the candidates, and how often.
        block: Block,
        times: usize,
    },
    /// Valid plans exist that keep their windows on the thermal model's time line, but
    /// every one fails when the robot welds it (no candidate broke a window or was
    /// torch-blocked).
    RobotTimeline {
        /// Candidates rejected on the robot's executed time line.
        times: u64,
        /// Why the last one was.
        last: String,
    },
    /// Valid plans exist, but every one breaks a t8/5 window or has a block the torch
    /// cannot reach.
    WindowsOrTorch {
        /// The window broken most often, and how often.
        window: Block,
        window_times: usize,
        /// The block the torch could not reach most often, and how often.
        torch: Block,
        torch_times: usize,
    },
}

impl std::fmt::Display for NoPlan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NoPlan::NoValidPlan {
                max_fragments,
                needs_at_least,
                layer,
            } => {
                write!(f, "no valid plan with at most {max_fragments} fragment(s)")?;
                if let Some(n) = needs_at_least {
                    write!(f, ": needs at least {n} fragments")?;
                }
                if let Some((z, paths, ends)) = layer {
                    write!(
                        f,
                        " (layer z = {z} alone needs {paths} weld paths: a weld path crosses \
                         a layer in one piece, which ends at two dead ends at most (the layer \
                         has {ends}) and alternates between the colours of a checkerboard)"
                    )?;
                }
                Ok(())
            }
            NoPlan::AllBreakWindows { block, times } => write!(
                f,
                "valid plans exist, but every one breaks a t8/5 window; the window of block \
                 [{},{},{}] broke most often ({times} of the candidates)",
                block[0], block[1], block[2]
            ),
            NoPlan::TorchCannotReach { block, times } => write!(
                f,
                "torch cannot reach: every valid plan welds a block after something that stands \
                 in the torch's way; most often block [{},{},{}] ({times} of the candidates)",
                block[0], block[1], block[2]
            ),
            NoPlan::RobotTimeline { times, last } => write!(
                f,
                "valid plans exist, but the robot cannot weld any on the thermal model's time \
                 line ({times} candidate(s) rejected); the last: {last}"
            ),
            NoPlan::WindowsOrTorch {
                window,
                window_times,
                torch,
                torch_times,
            } => write!(
                f,
                "valid plans exist, but every one breaks a t8/5 window or welds a block the \
                 torch cannot reach; the window of block [{},{},{}] broke most often \
                 ({window_times} of the candidates), the torch could not reach block \
                 [{},{},{}] most often ({torch_times})",
                window[0], window[1], window[2], torch[0], torch[1], torch[2]
            ),
        }
    }
}

/// The answer of [`plan`] or [`first`].
#[derive(Debug, Clone)]
pub struct Report {
    /// The best feasible plan found.
    pub best: Option<Found>,
    /// True when the answer is proven: the plan is optimal (or the first, for
    /// [`first`]), or no plan exists. False after a timeout.
    pub proven: bool,
    /// Why there is no plan (when proven and none found).
    pub no_plan: Option<NoPlan>,
    pub stats: Stats,
}

/// Exact numbers of plans.
#[derive(Debug, Clone, Serialize)]
pub struct Counts {
    /// Valid plans (None when not counted).
    pub plans: Option<u64>,
    /// Feasible plans.
    pub feasible: u64,
    /// False when a timeout cut the count short.
    pub complete: bool,
    pub stats: Stats,
}

/// Errors that stop planning.
#[derive(Debug, Error)]
pub enum PlanError {
    #[error(transparent)]
    NotCooled(#[from] thermal::NotCooled),
    #[error(
        "part of {blocks} blocks with max_fragments {k}: planning it needs about {estimate_mb} MB, \
         more than max_memory_mb = {limit_mb} (raise it with --max-memory-mb, or the node \
         parameter planner.max_memory_mb)"
    )]
    TooLarge {
        blocks: usize,
        k: usize,
        estimate_mb: u64,
        limit_mb: u64,
    },
    #[error("writing plans: {0}")]
    Output(#[from] std::io::Error),
    /// A graph part whose numbers the graph thermal model cannot take.
    #[error("thermal model of the graph part: {0}")]
    Graph(#[from] thermal::graph::GraphError),
}

/// What the planner tells its caller while it runs.
#[derive(Debug, Clone, Copy)]
pub enum Event<'a> {
    /// The thermal model judged a candidate plan: every candidate comes as one event, with
    /// the planner's statistics after it.
    Candidate {
        /// Fragments of block indices, in weld order.
        fragments: &'a [Vec<usize>],
        verdict: CandidateVerdict,
        stats: &'a Stats,
    },
    /// Valid plans counted so far (`count`), without a thermal check.
    Counting { plans: u64, stats: &'a Stats },
}

impl<'a> Event<'a> {
    /// The planner's statistics at this event.
    pub fn stats(&self) -> &'a Stats {
        match self {
            Event::Candidate { stats, .. } | Event::Counting { stats, .. } => stats,
        }
    }
}

/// The caller's handler of [`Event`]s (progress display, recording).
pub type Progress<'a> = &'a mut dyn FnMut(Event<'_>);

fn max_fragments(part: &Part, opts: &Options) -> usize {
    opts.max_fragments
        .unwrap_or(part.max_fragments)
        .clamp(1, part.len())
}

/// Refuses a part too large for `opts.max_memory_mb`, before its graph is built.
fn check_size(part: &Part, opts: &Options) -> Result<(), PlanError> {
    let k = max_fragments(part, opts);
    let estimate_mb = estimated_memory_mb(part.len(), k);
    if estimate_mb > opts.max_memory_mb {
        return Err(PlanError::TooLarge {
            blocks: part.len(),
            k,
            estimate_mb,
            limit_mb: opts.max_memory_mb,
        });
    }
    // A graph part's thermal model can be refused (`ThermalModel::new` would panic inside
    // the search): say so before planning.
    if part.bead_part().is_some() {
        ThermalModel::try_new(part, &WeldGraph::new(part))?;
    }
    Ok(())
}

/// Whether the run must stop now: its time is up or it was cancelled.
fn timed_out(opts: &Options, started: Instant) -> bool {
    opts.timeout.is_some_and(|t| started.elapsed() >= t)
        || opts
            .cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
}

/// A search with the run's solver, its encoding and solves stopped at the run's deadline
/// or on cancel (`None`: stopped while encoding).
fn new_search<'p>(
    part: &'p Part,
    graph: &'p WeldGraph,
    k: usize,
    opts: &Options,
    lookahead_budget: usize,
    started: Instant,
) -> Option<Search<'p>> {
    let interrupt = thermal::Interrupt {
        deadline: opts.timeout.and_then(|t| started.checked_add(t)),
        cancel: opts.cancel.clone(),
    };
    let mut search = Search::new(
        part,
        graph,
        k,
        opts.acyclicity,
        lookahead_budget,
        opts.solver,
        interrupt,
    )?;
    search.set_torch(opts.torch.map(|t| TorchAccess::new(part, &t)));
    search.set_executed(opts.executed.clone());
    Some(search)
}

/// The report of a run stopped before its search was built.
fn stopped_early(started: Instant) -> Report {
    Report {
        best: None,
        proven: false,
        no_plan: None,
        stats: Stats {
            total_s: started.elapsed().as_secs_f64(),
            ..Stats::default()
        },
    }
}

/// The best feasible plan: fewest fragments, then the largest worst-case t8/5 margin. With
/// the default configuration on `opts.threads` threads (0: all cores) the first feasible
/// plan comes from a race of configurations and the optimisation goes on from it
/// ([`race::race_best`]); the answer of a completed search is the same either way.
pub fn plan(part: &Part, opts: &Options, progress: Progress) -> Result<Report, PlanError> {
    match race::threads(opts) {
        1 => search_plans(part, opts, progress, true, &race::Tuning::alone()),
        threads => race::race_best(part, opts, progress, threads),
    }
}

/// The first feasible plan found, without optimizing: with the default configuration on
/// `opts.threads` threads (0: all cores), a race of configurations ([`race`]); "no plan"
/// is the default configuration's answer either way.
pub fn first(part: &Part, opts: &Options, progress: Progress) -> Result<Report, PlanError> {
    match race::threads(opts) {
        1 => search_plans(part, opts, progress, false, &race::Tuning::alone()),
        threads => race::race(part, opts, progress, threads),
    }
}

fn search_plans(
    part: &Part,
    opts: &Options,
    progress: Progress,
    optimize: bool,
    tuning: &race::Tuning,
) -> Result<Report, PlanError> {
    let started = Instant::now();
    check_size(part, opts)?;
    let graph = WeldGraph::new(part);
    let k = max_fragments(part, opts);
    // A layer that alone needs more weld paths than allowed: no plan, proven at once. How
    // many a plan needs is searched for on small parts only (on large ones it is a long
    // search of its own).
    if let Some(layer) = layer_path_bound(part, &graph)
        .into_iter()
        .filter(|&(_, paths, _)| paths > k)
        .max_by_key(|&(z, paths, _)| (paths, std::cmp::Reverse(z)))
    {
        const SEARCH_NEEDED_UP_TO: usize = 2_000;
        let no_plan = if part.len() <= SEARCH_NEEDED_UP_TO {
            no_valid_plan(part, &graph, k, opts, started)
        } else {
            NoPlan::NoValidPlan {
                max_fragments: k,
                needs_at_least: None,
                layer: Some(layer),
            }
        };
        return Ok(Report {
            best: None,
            proven: true,
            no_plan: Some(no_plan),
            stats: Stats {
                total_s: started.elapsed().as_secs_f64(),
                ..Stats::default()
            },
        });
    }
    let Some(mut search) = new_search(part, &graph, k, opts, opts.lookahead_budget, started) else {
        return Ok(stopped_early(started));
    };
    if let Some(sharing) = &tuning.sharing {
        search.share(sharing.clone());
    }
    if let Some(seed) = tuning.seed {
        search.set_seed(seed);
    }
    search.judge_inside();
    let base = ThermalModel::new(part, &graph);
    let mut best: Option<Found> = None;
    let mut proven = true;
    let mut any_valid = false;
    // The windows are narrowed to the best plan's margin once the search is among plans
    // of its fragment count (a plan with fewer fragments is better whatever its margin).
    let mut narrowed_to_best = false;
    if let Some(incumbent) = &tuning.incumbent {
        // Another racer's feasible plan (judged by the part's own windows) takes the warm
        // start's place: judged again here, it is the plan to beat and the solver's phases.
        // No event: the race reported it when its racer found it.
        any_valid = true;
        search.set_phases(incumbent);
        if let Some(verdict) = search.judge(incumbent)? {
            let margin = feasible_margin(&mut search, verdict, &base, incumbent, opts, started)?;
            if let Some(margin) = margin {
                search.block_plan(incumbent);
                search.stats.best_margin_s = Some(margin).filter(|m| m.is_finite());
                best = Some(Found {
                    margin,
                    fragments: incumbent.clone(),
                });
            }
        }
    } else if opts.warm_start {
        let limits = constructive::Limits {
            deadline: opts.timeout.and_then(|t| started.checked_add(t)),
            cancel: opts.cancel.clone(),
        };
        // Cube layers are covered by small SAT solves; a graph part's beads are walked.
        let graph_part = part.bead_part().is_some();
        let warm = if graph_part {
            contour::layered_plan(part, &graph, k, &limits)
        } else {
            constructive::layered_plan(part, &graph, k, opts.solver, &limits)
        };
        if let Some(mut warm) = warm {
            any_valid = true;
            // Stopped before a verdict: the loop below sees the timeout.
            let mut verdict = search.judge(&warm)?;
            // The simulator says the warm start breaks a window: the portfolio varies the
            // cube construction's starts (in a race, a racer of its own does).
            if let Some(CandidateVerdict::Violated {
                block,
                kind,
                prefix_len,
                ..
            }) = verdict
                .filter(|_| tuning.varied_starts)
                .filter(|_| !graph_part)
            {
                tracing::debug!(
                    "warm start: the layer-by-layer plan breaks the window of {block:?} ({kind:?}) after {prefix_len} blocks; trying other starts"
                );
                // At most half the time left: the search keeps the rest.
                let half_left = constructive::Limits {
                    deadline: limits.deadline.map(|d| {
                        let now = Instant::now();
                        now + d.saturating_duration_since(now) / 2
                    }),
                    cancel: limits.cancel.clone(),
                };
                let portfolio = portfolio::Portfolio {
                    part,
                    graph: &graph,
                    k,
                    backend: opts.solver,
                    limits: &half_left,
                    model: &base,
                    // The run's threads: a racer's one, or all cores.
                    workers: match opts.threads {
                        0 => portfolio::cores(),
                        n => n,
                    },
                };
                let varied = portfolio.varied_start(&warm);
                if let Some((varied, _)) = varied {
                    // Every judged candidate is reported (recordings count them), the
                    // warm start's broken one too.
                    if let Some(judged) = verdict {
                        progress(Event::Candidate {
                            fragments: &warm,
                            verdict: judged,
                            stats: &search.stats,
                        });
                    }
                    // The simulator is the authority: judged like any candidate.
                    verdict = search.judge(&varied)?;
                    warm = varied;
                }
            }
            search.set_phases(&warm);
            if let Some(verdict) = verdict {
                tracing::debug!(
                "warm start: a plan of {} weld path(s) built layer by layer in {:.2} s: {verdict:?}",
                warm.len(),
                started.elapsed().as_secs_f64()
            );
                // The margin before the event: a listener that stops the run at the first
                // feasible plan (the node's first_feasible) raises the cancel flag.
                let margin = feasible_margin(&mut search, verdict, &base, &warm, opts, started)?;
                progress(Event::Candidate {
                    fragments: &warm,
                    verdict,
                    stats: &search.stats,
                });
                if let Some(margin) = margin {
                    search.block_plan(&warm);
                    search.stats.best_margin_s = Some(margin).filter(|m| m.is_finite());
                    best = Some(Found {
                        margin,
                        fragments: warm,
                    });
                }
            }
        }
    }
    // Fewest fragments first: f = 1, 2, ... under an assumption (all of k when not optimizing).
    let levels: Vec<usize> = if optimize { (1..=k).collect() } else { vec![k] };
    'levels: for f in levels {
        if best.as_ref().is_some_and(|b| b.margin.is_nan()) {
            // Stopped while measuring the best plan's margin: no optimum is proven.
            proven &= !optimize;
            break 'levels;
        }
        if let Some(b) = best.as_ref().filter(|b| b.fragments.len() <= f) {
            // Every plan with fewer fragments is ruled out (or the first will do).
            if !optimize || b.margin.is_infinite() {
                break 'levels;
            }
            if !narrowed_to_best {
                search.set_thermal(base.narrowed(b.margin + 1e-6));
                narrowed_to_best = true;
            }
        }
        let assume: Vec<_> = search.enc.at_most_fragments(f).into_iter().collect();
        loop {
            if timed_out(opts, started) {
                proven = false;
                break 'levels;
            }
            let Some(candidate) = search.next_candidate(&assume) else {
                if search.interrupted {
                    proven = false;
                    break 'levels;
                }
                break;
            };
            any_valid = true;
            let Some(verdict) = search.judge(&candidate)? else {
                proven = false;
                break 'levels;
            };
            // Judge by the part's own windows (the search may run on narrowed ones), before
            // the event: a listener may stop the run at the first feasible plan.
            let margin = feasible_margin(&mut search, verdict, &base, &candidate, opts, started)?;
            progress(Event::Candidate {
                fragments: &candidate,
                verdict,
                stats: &search.stats,
            });
            if let Some(margin) = margin {
                let better = best.as_ref().is_none_or(|b| {
                    candidate.len() < b.fragments.len()
                        || (candidate.len() == b.fragments.len() && margin > b.margin)
                });
                if better {
                    search.stats.best_margin_s = Some(margin).filter(|m| m.is_finite());
                    best = Some(Found {
                        fragments: candidate.clone(),
                        margin,
                    });
                }
                if margin.is_nan() {
                    proven &= !optimize;
                    break 'levels;
                }
                if !optimize || margin.is_infinite() {
                    break 'levels;
                }
                search.block_plan(&candidate);
                // Only strictly better plans from now on (margins compared to 1 µs).
                let margin = best.as_ref().map_or(margin, |b| b.margin);
                search.set_thermal(base.narrowed(margin + 1e-6));
                narrowed_to_best = true;
            }
        }
        if best.as_ref().is_some_and(|b| b.fragments.len() <= f) {
            break;
        }
    }
    // Prefixes cut inside the search may have ruled out every plan before a complete one
    // came out: whether valid plans exist at all is then one solve for structure only.
    if best.is_none() && proven && !any_valid && search.stats.inside_clauses > 0 {
        match new_search(part, &graph, k, opts, 0, started) {
            Some(mut structure) => {
                any_valid = structure.next_candidate(&[]).is_some();
                proven &= !structure.interrupted;
            }
            None => proven = false,
        }
    }
    let no_plan = match (&best, proven) {
        (None, true) if !any_valid => Some(no_valid_plan(part, &graph, k, opts, started)),
        (None, true) => {
            let most = |counts: &[usize]| {
                counts
                    .iter()
                    .enumerate()
                    .max_by_key(|&(i, &t)| (t, std::cmp::Reverse(i)))
                    .map(|(i, &t)| (part.block(i), t))
                    .expect("a part has blocks")
            };
            let (block, times) = most(&search.violations);
            let (torch, torch_times) = most(&search.torch_blocked);
            Some(match (times, torch_times) {
                (0, 0) if search.stats.executed_rejected > 0 => NoPlan::RobotTimeline {
                    times: search.stats.executed_rejected,
                    last: search.executed_last.clone().unwrap_or_default(),
                },
                (_, 0) => NoPlan::AllBreakWindows { block, times },
                (0, _) => NoPlan::TorchCannotReach {
                    block: torch,
                    times: torch_times,
                },
                _ => NoPlan::WindowsOrTorch {
                    window: block,
                    window_times: times,
                    torch,
                    torch_times,
                },
            })
        }
        _ => None,
    };
    search.stats.total_s = started.elapsed().as_secs_f64();
    Ok(Report {
        best,
        proven,
        no_plan,
        stats: search.stats,
    })
}

/// A feasible candidate's margin under the part's own windows (`model`), noting when the
/// first feasible plan came; `None` for any other verdict.
fn feasible_margin(
    search: &mut Search<'_>,
    verdict: CandidateVerdict,
    model: &ThermalModel,
    fragments: &[Vec<usize>],
    opts: &Options,
    started: Instant,
) -> Result<Option<f64>, PlanError> {
    if !matches!(verdict, CandidateVerdict::Feasible) {
        return Ok(None);
    }
    search
        .stats
        .first_feasible_s
        .get_or_insert(started.elapsed().as_secs_f64());
    margin_under(model, fragments, opts, started).map(Some)
}

/// The worst t8/5 margin of a feasible plan under the part's own windows; NaN when the
/// run's deadline or cancel stopped the simulation first (a transit of 10^8 steps takes
/// seconds, and the search has already simulated this plan once).
fn margin_under(
    model: &ThermalModel,
    fragments: &[Vec<usize>],
    opts: &Options,
    started: Instant,
) -> Result<f64, PlanError> {
    if !model.has_windows() {
        return Ok(f64::INFINITY);
    }
    let deadline = opts.timeout.and_then(|t| started.checked_add(t));
    let outcome = thermal::simulate_until(model, fragments, deadline, opts.cancel.clone())?;
    Ok(outcome.map_or(f64::NAN, |o| model.margin(&o.crossings)))
}

/// Counts the valid plans (`with_plans`) and the feasible plans, exactly, on `opts.threads`
/// workers (see [`cubes`]).
pub fn count(
    part: &Part,
    opts: &Options,
    with_plans: bool,
    progress: Progress,
) -> Result<Counts, PlanError> {
    let started = Instant::now();
    check_size(part, opts)?;
    let graph = WeldGraph::new(part);
    let k = max_fragments(part, opts);
    let mut complete = true;
    let plans = if with_plans {
        let valid = cubes::conquer(
            part,
            &graph,
            k,
            opts,
            started,
            cubes::Mode::Valid,
            progress,
            &mut |_| Ok(()),
        )?;
        complete = valid.complete;
        valid.plans
    } else {
        None
    };
    // The feasible plans share the deadline of the whole count.
    let mut counts = enumerate_from(part, &graph, k, opts, started, progress, &mut |_| Ok(()))?;
    counts.plans = plans;
    counts.complete &= complete;
    Ok(counts)
}

/// Enumerates every feasible plan on `opts.threads` workers, handing each to `sink` on the
/// calling thread, cube by cube as the cubes are done: in the lexicographic order of their
/// fragments (block indices), the same on any number of threads.
pub fn enumerate(
    part: &Part,
    opts: &Options,
    progress: Progress,
    sink: &mut dyn FnMut(&[Vec<usize>]) -> std::io::Result<()>,
) -> Result<Counts, PlanError> {
    check_size(part, opts)?;
    let graph = WeldGraph::new(part);
    let k = max_fragments(part, opts);
    enumerate_from(part, &graph, k, opts, Instant::now(), progress, sink)
}

/// The thermal loop to exhaustion over the cubes of the plans ([`cubes`]), blocking each
/// feasible plan after handing it to `sink`; timeouts count from `started`.
fn enumerate_from(
    part: &Part,
    graph: &WeldGraph,
    k: usize,
    opts: &Options,
    started: Instant,
    progress: Progress,
    sink: &mut dyn FnMut(&[Vec<usize>]) -> std::io::Result<()>,
) -> Result<Counts, PlanError> {
    cubes::conquer(
        part,
        graph,
        k,
        opts,
        started,
        cubes::Mode::Feasible,
        progress,
        sink,
    )
}

/// Explains a part with no valid plan: the fewest fragments it needs, and a layer that
/// alone needs more weld paths than allowed.
fn no_valid_plan(
    part: &Part,
    graph: &WeldGraph,
    k: usize,
    opts: &Options,
    started: Instant,
) -> NoPlan {
    let layer = layer_path_bound(part, graph)
        .into_iter()
        .filter(|&(_, paths, _)| paths > k)
        .max_by_key(|&(z, paths, _)| (paths, std::cmp::Reverse(z)));
    // The fewest fragments, by asking the solver for structure only, from the layers'
    // lower bound up. The verdict is proven already, so this extra figure gets a few
    // seconds at most (within the run's deadline): a mesh whose layers fall apart into
    // many pieces had kept the answer back for the whole timeout.
    const NEEDS_SEARCH: Duration = Duration::from_secs(5);
    let left = opts
        .timeout
        .map_or(NEEDS_SEARCH, |t| t.saturating_sub(started.elapsed()));
    let capped = Options {
        timeout: Some(left.min(NEEDS_SEARCH)),
        ..opts.clone()
    };
    let capped_from = Instant::now();
    let from = (k + 1).max(layer.map_or(0, |(_, paths, _)| paths));
    let mut interrupted = false;
    let needs_at_least = (from..=part.len().min(from + 15)).find(|&f| {
        if interrupted {
            return false;
        }
        let Some(mut search) = new_search(part, graph, f, &capped, 0, capped_from) else {
            interrupted = true;
            return false;
        };
        let found = search.next_candidate(&[]).is_some();
        interrupted = search.interrupted;
        found
    });
    NoPlan::NoValidPlan {
        max_fragments: k,
        needs_at_least,
        layer,
    }
}

/// Per layer: (z, a lower bound on the weld paths through it, its dead ends). A weld path
/// crosses a layer in one piece, so each piece of a layer (a component of its sideways
/// moves) needs a path, every dead end (a block with one sideways neighbour) ends one, and
/// since a path alternates between the two colours of a checkerboard (x + y even or odd),
/// it covers at most one block more of one colour than of the other (cube parts only: the
/// moves of a graph part do not alternate colours).
pub fn layer_path_bound(part: &Part, graph: &WeldGraph) -> Vec<(i64, usize, usize)> {
    let checkerboard = part.bead_part().is_none();
    let n = part.len();
    let z = |i: usize| part.block(i)[2];
    let sideways = |i: usize| {
        graph
            .successors(i)
            .iter()
            .map(|&j| j as usize)
            .filter(move |&j| z(j) == z(i))
    };
    let mut comp = vec![usize::MAX; n];
    let mut out: Vec<(i64, usize, usize)> = Vec::new();
    for s in 0..n {
        if comp[s] != usize::MAX {
            continue;
        }
        comp[s] = s;
        let (mut stack, mut ends, mut colours) = (vec![s], 0usize, [0usize; 2]);
        while let Some(i) = stack.pop() {
            if sideways(i).count() == 1 {
                ends += 1;
            }
            let [x, y, _] = part.block(i);
            colours[((x + y) & 1) as usize] += 1;
            for j in sideways(i) {
                if comp[j] == usize::MAX {
                    comp[j] = s;
                    stack.push(j);
                }
            }
        }
        let parity = if checkerboard {
            colours[0].abs_diff(colours[1])
        } else {
            0
        };
        let paths = ends.div_ceil(2).max(parity).max(1);
        match out.last_mut() {
            Some(last) if last.0 == z(s) => {
                last.1 += paths;
                last.2 += ends;
            }
            _ => out.push((z(s), paths, ends)),
        }
    }
    out
}
