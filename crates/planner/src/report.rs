//! What the planner answers ([`Report`], [`Found`], [`NoPlan`], [`Counts`], [`Stats`]),
//! what stops it ([`PlanError`]) and what it says while it runs ([`Event`]).

use serde::Serialize;
use thiserror::Error;

use waam_part::plan::Plan;
use waam_part::{Block, Part};
use waam_thermal as thermal;

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
    /// Clauses other racers learned, handed to this search's solver (`race.rs`).
    pub clauses_imported: u64,
    /// The racer whose feasible plan the race saw first (`race.rs`: "default",
    /// "no-warm-start", "varisat", "seed N"); None without a race.
    pub first_plan_racer: Option<String>,
    /// Racers the race started (0 without a race): the others wait for the default's warm
    /// start, and a feasible one ends the race before they start (`race.rs`).
    pub racers_started: usize,
    pub clause_len_min: Option<usize>,
    pub clause_len_max: Option<usize>,
    pub clause_len_mean: Option<f64>,
    #[serde(skip)]
    pub(crate) clause_len_sum: u64,
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
    /// it ([`Options::executed`](crate::Options::executed)): a transit too slow, or a window broken on the executed
    /// time line.
    ExecutedRejected {
        /// Blocks in the prefix ruled out.
        prefix_len: usize,
        /// Literals in the clause learned from it.
        clause_len: usize,
    },
}

impl Stats {
    pub(crate) fn record_clause(&mut self, len: usize) {
        self.learned_clauses += 1;
        self.clause_len_sum += len as u64;
        self.clause_len_min = Some(self.clause_len_min.map_or(len, |m| m.min(len)));
        self.clause_len_max = Some(self.clause_len_max.map_or(len, |m| m.max(len)));
        self.clause_len_mean = Some(self.clause_len_sum as f64 / self.learned_clauses as f64);
    }

    /// Adds another search's statistics (a worker of [`cubes`](crate::cubes)): counts and times summed
    /// (times are then CPU seconds over the workers), the instance size and the run's
    /// length the largest (every worker encodes the same part), the first feasible plan
    /// the earliest, the margin the best.
    pub(crate) fn absorb(&mut self, other: &Stats) {
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
            racers_started,
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
        self.racers_started = self.racers_started.max(*racers_started);
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

/// The answer of [`plan`](crate::plan) or [`first`](crate::first).
#[derive(Debug, Clone)]
pub struct Report {
    /// The best feasible plan found.
    pub best: Option<Found>,
    /// True when the answer is proven: the plan is optimal (or the first, for
    /// [`first`](crate::first)), or no plan exists. False after a timeout.
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
