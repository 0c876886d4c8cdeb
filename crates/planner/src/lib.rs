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
mod options;
mod portfolio;
mod prefix_cache;
mod race;
mod repair;
mod report;
pub mod rest;
pub mod sat;
mod search;
mod sharing;
mod shortening;
pub mod thermal_prefix;

#[cfg(test)]
mod graph_tests;

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use waam_access::TorchAccess;
use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_thermal::{self as thermal, ThermalModel};

use crate::prefix_cache::deposits;

pub use encoding::Acyclicity;
pub use options::{
    estimated_memory_mb, ExecutedCheck, JudgeExecuted, Options, Rejection, DEFAULT_MAX_MEMORY_MB,
    MAX_THREADS,
};
pub use report::{
    CandidateVerdict, Counts, Event, Found, NoPlan, PlanError, Progress, Report, Stats,
};
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
    search.set_threads(opts.threads);
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
        let warm = if let Some(built) = &tuning.warm_start {
            Some(built.clone())
        } else if graph_part {
            contour::layered_plan(part, &graph, k, &limits)
        } else {
            constructive::layered_plan(part, &graph, k, opts.solver, &limits)
        };
        if let Some(mut warm) = warm {
            any_valid = true;
            // Stopped before a verdict: the loop below sees the timeout.
            let mut verdict = search.judge(&warm)?;
            if !matches!(verdict, Some(CandidateVerdict::Feasible)) {
                tuning.note_warm_start_failed(Some(&warm));
            }
            // The simulator says the warm start breaks a window: the portfolio varies the
            // cube construction's starts (in a race, the default and varisat racers do).
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
                // The run's threads, or a racer's share of them (0: all cores).
                let workers = match tuning.workers.unwrap_or(opts.threads) {
                    0 => portfolio::cores(),
                    n => n,
                };
                // First the plan changed around the window the simulator names (it stops
                // by itself when no change gets further); on a first layer with area, then
                // its rasters (the one that gets furthest repaired in turn); then the
                // portfolio's other starts and covers; then varisat's plan, repaired, then
                // varied: all in what is left of that time.
                // The warm start as the search simulated it: its snapshots spare the
                // repair simulating it again from the first deposit (a minute at 10^5).
                let resume = |prefix: &[(usize, bool)]| search.resume_on(&base, prefix);
                // The repair's first step ends at the half; once a step gets further the
                // repair may go on to the deadline (see `repair`).
                let repair = repair::Repair {
                    part,
                    graph: &graph,
                    k,
                    model: &base,
                    limits: &limits,
                    yield_at: half_left.deadline,
                    workers,
                    resume: Some(&resume),
                    reached: Default::default(),
                };
                let portfolio = portfolio::Portfolio {
                    part,
                    graph: &graph,
                    k,
                    backend: opts.solver,
                    limits: &half_left,
                    model: &base,
                    workers,
                };
                // Varisat's layer-by-layer plan (varisat covers the layers otherwise than
                // CaDiCaL), judged, repaired and varied as this one, last, in a CaDiCaL run
                // (`--solver varisat` runs varisat only) unless a varisat racer has it. Last:
                // at 10^5 blocks building and simulating it takes minutes.
                let other = (tuning.varisat_warm_start && opts.solver == Backend::Cadical)
                    .then_some(portfolio::Portfolio {
                        backend: Backend::Varisat,
                        ..portfolio
                    });
                let varied = part
                    .index_of(block)
                    .and_then(|b| repair.repaired(&warm, prefix_len, b))
                    .or_else(|| match portfolio.rasters(&warm)? {
                        Ok(found) => Some(found),
                        Err((plan, blocks, b)) if blocks > prefix_len => {
                            repair.repaired(&plan, blocks, b)
                        }
                        Err(_) => None,
                    })
                    .or_else(|| portfolio.varied_start(&warm))
                    .or_else(|| match other.as_ref()?.layered(&warm)? {
                        Ok(found) => Some(found),
                        Err((plan, blocks, b)) => repair
                            .repaired(&plan, blocks, b)
                            .or_else(|| other.as_ref()?.varied_start(&plan)),
                    });
                if let Some(repair::Repaired { plan: varied, end }) = varied {
                    // The changed plan leaves its simulation's last state with the search:
                    // its verdict below then simulates the cooldown only (a minute and a
                    // half of deposits at 10^5 blocks).
                    if let Some(end) = end {
                        search.remember(&varied, end);
                    }
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
    if best.is_none() {
        tuning.note_warm_start_failed(None);
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
    margin_under(search, model, fragments, opts, started).map(Some)
}

/// The worst t8/5 margin of a feasible plan under the part's own windows; NaN when the
/// run's deadline or cancel stopped the simulation first (a transit of 10^8 steps takes
/// seconds). The search has just simulated this plan: its last snapshot of it (a
/// simulation carries its margin so far) spares simulating the plan again from the first
/// deposit, a minute and a half at 10^5 blocks.
fn margin_under(
    search: &Search<'_>,
    model: &ThermalModel,
    fragments: &[Vec<usize>],
    opts: &Options,
    started: Instant,
) -> Result<f64, PlanError> {
    if !model.has_windows() {
        return Ok(f64::INFINITY);
    }
    let seq = deposits(fragments);
    let (sim, at) = search.resume_on(model, &seq);
    let mut sim = sim.with_deadline(opts.timeout.and_then(|t| started.checked_add(t)));
    if let Some(cancel) = &opts.cancel {
        sim = sim.with_cancel(cancel.clone());
    }
    let mut kept = true;
    for &(b, new) in &seq[at..] {
        // Feasible under the windows the search judged by, which are these or narrower.
        if sim.deposit(b, new).is_err() {
            kept = false;
            break;
        }
    }
    if kept {
        // A window broken while cooling down ends the simulation as above.
        let _ = sim.finish()?;
    }
    Ok(if sim.cancelled() {
        f64::NAN
    } else {
        sim.margin_s()
    })
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
