//! The first feasible plan by a race: threads each run one configuration of the planner
//! on the same part, the first feasible plan wins and the others are cancelled.
//!
//! Why a race and not a rule: which configuration finds a plan first depends on the part
//! in ways no threshold captures — on a double tube the warm start's phases led CaDiCaL
//! astray for 40 s where the search without them took 10 s; on a tall tube the warm start
//! breaks a window early and only another start keeps it. Every configuration is sound
//! (each plan is judged by the simulator, each learned clause is a fact about the part), so
//! racing them costs only cores, and the answer is as good as the fastest configuration's
//! (on a shared machine, up to the factor of the racers sharing the cores).
//!
//! The configurations, in the order threads take them ([`racers`]): the default (CaDiCaL
//! with the layer-by-layer warm start), the varied starts (the warm start set off from
//! other places, [`crate::portfolio`], a finite job: its thread then takes the next
//! configuration), CaDiCaL without the warm start, varisat, and CaDiCaL with other seeds.
//! The racers publish their learned thermal clauses ([`crate::sharing`]); the CaDiCaL
//! racers other than the default take them in, inside their solves.
//!
//! Proofs stay deterministic: "no plan" is answered only by the default configuration,
//! which takes no clauses in (so its reasons are those of a run without a race), and the optimizing, counting and enumerating
//! searches do not race.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::sync::Arc;
use std::time::{Duration, Instant};

use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_thermal::ThermalModel;

use crate::portfolio::Portfolio;
use crate::sat::Backend;
use crate::sharing::{ClausePool, Sharing};
use crate::{
    constructive, margin_under, max_fragments, search_plans, stopped_early, CandidateVerdict,
    Event, Found, Options, PlanError, Progress, Report, Stats,
};

/// One configuration of the planner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Racer {
    /// CaDiCaL with the warm start: what `--threads 1` runs.
    Default,
    /// The warm start set off from other places, each variant simulated.
    VariedStarts,
    NoWarmStart,
    Varisat,
    /// CaDiCaL with the warm start and its own seed.
    Seeded(u32),
}

/// What a search run inside the race does differently.
pub(crate) struct Tuning {
    /// Try the varied starts inline when the warm start breaks a window (off in the race:
    /// they are a racer of their own there).
    pub varied_starts: bool,
    pub sharing: Option<Sharing>,
    pub seed: Option<u32>,
}

impl Tuning {
    /// A run on its own (no race).
    pub fn alone() -> Tuning {
        Tuning {
            varied_starts: true,
            sharing: None,
            seed: None,
        }
    }
}

/// The threads a race of `opts` runs on: 1 (no race) unless the run is the default
/// configuration (a chosen solver or `--no-warm-start` is run as asked).
pub(crate) fn threads(opts: &Options) -> usize {
    let default = opts.warm_start && opts.solver == Backend::Cadical;
    match opts.threads {
        _ if !default => 1,
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    }
}

/// The configurations in the order threads take them: enough searches that every thread
/// has one after the varied starts are done.
pub(crate) fn racers(threads: usize) -> Vec<Racer> {
    let mut racers = vec![
        Racer::Default,
        Racer::VariedStarts,
        Racer::NoWarmStart,
        Racer::Varisat,
    ];
    racers.extend((1..threads.saturating_sub(2)).map(|s| Racer::Seeded(s as u32)));
    racers
}

/// A candidate judged by a racer, sent to the calling thread.
enum Message {
    Candidate {
        fragments: Vec<Vec<usize>>,
        verdict: CandidateVerdict,
        stats: Box<Stats>,
    },
    Done {
        racer: Racer,
        result: Box<Result<Report, PlanError>>,
        /// When the racer started, after the race did.
        offset: Duration,
    },
}

/// How often the calling thread looks at the caller's cancel flag.
const POLL: Duration = Duration::from_millis(50);

/// The first feasible plan of `part`, raced on `threads` threads; events reach `progress`
/// on the calling thread.
pub(crate) fn race(
    part: &Part,
    opts: &Options,
    progress: Progress,
    threads: usize,
) -> Result<Report, PlanError> {
    let started = Instant::now();
    let racers = Arc::new(racers(threads));
    let stop = Arc::new(AtomicBool::new(false));
    let next = Arc::new(AtomicUsize::new(0));
    let pool = Arc::new(ClausePool::default());
    let shared = Arc::new((part.clone(), opts.clone()));
    let (tx, rx) = mpsc::channel::<Message>();
    // Detached, not scoped: the answer does not wait for a loser that stops only between
    // its solves (varisat); it ends on its own soon after the race's cancel.
    for _ in 0..threads.min(racers.len()) {
        let tx = tx.clone();
        let (racers, next, stop, pool, shared) = (
            Arc::clone(&racers),
            Arc::clone(&next),
            Arc::clone(&stop),
            Arc::clone(&pool),
            Arc::clone(&shared),
        );
        std::thread::spawn(move || {
            let (part, opts) = &*shared;
            loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(&racer) = racers.get(i) else { break };
                if stop.load(Ordering::Relaxed) {
                    break;
                }
                let offset = started.elapsed();
                let o = Options {
                    timeout: opts.timeout.map(|t| t.saturating_sub(offset)),
                    cancel: Some(Arc::clone(&stop)),
                    ..opts.clone()
                };
                let sharing = Sharing::new(Arc::clone(&pool), i);
                // The default takes no clauses in: its proofs stay those of a run alone.
                let sharing = match racer {
                    Racer::Default => sharing.publish_only(),
                    _ => sharing,
                };
                let mut forward = |event: Event<'_>| {
                    if let Event::Candidate {
                        fragments,
                        verdict,
                        stats,
                    } = event
                    {
                        let _ = tx.send(Message::Candidate {
                            fragments: fragments.to_vec(),
                            verdict,
                            stats: Box::new(stats.clone()),
                        });
                    }
                };
                let result = run(racer, part, &o, &mut forward, sharing);
                let _ = tx.send(Message::Done {
                    racer,
                    result: Box::new(result),
                    offset,
                });
            }
        });
    }
    drop(tx);
    let mut winner: Option<Report> = None;
    let mut default: Option<Result<Report, PlanError>> = None;
    // Until a plan is found or the default configuration ends (a proof, an error, the
    // deadline or a cancel: then the race is over for every racer).
    while winner.is_none() && default.is_none() {
        match rx.recv_timeout(POLL) {
            Ok(Message::Candidate {
                fragments,
                verdict,
                stats,
            }) => progress(Event::Candidate {
                fragments: &fragments,
                verdict,
                stats: &stats,
            }),
            Ok(Message::Done {
                racer,
                result,
                offset,
            }) => {
                let result = (*result).map(|mut r| {
                    let shift = offset.as_secs_f64();
                    r.stats.first_feasible_s = r.stats.first_feasible_s.map(|t| t + shift);
                    r
                });
                match result {
                    Ok(r) if r.best.is_some() => {
                        tracing::debug!("race: {racer:?} found the first feasible plan");
                        winner = Some(r);
                    }
                    // A proof (no plan) or an error: only the default's, so the answer is
                    // the one a run without the race gives.
                    result if racer == Racer::Default => default = Some(result),
                    Err(e) => tracing::warn!("race: {racer:?} stopped: {e}"),
                    Ok(_) => {}
                }
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {
                if opts
                    .cancel
                    .as_ref()
                    .is_some_and(|c| c.load(Ordering::Relaxed))
                {
                    stop.store(true, Ordering::Relaxed);
                }
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
        }
    }
    stop.store(true, Ordering::Relaxed);
    let mut report = match (winner, default) {
        (Some(w), _) => w,
        (None, Some(d)) => d?,
        (None, None) => stopped_early(started),
    };
    report.stats.total_s = started.elapsed().as_secs_f64();
    Ok(report)
}

/// One racer's run, stopped by `opts.cancel` (the race's) or its deadline.
fn run(
    racer: Racer,
    part: &Part,
    opts: &Options,
    progress: Progress,
    sharing: Sharing,
) -> Result<Report, PlanError> {
    let tuning = |seed| Tuning {
        varied_starts: false,
        sharing: Some(sharing.clone()),
        seed,
    };
    match racer {
        Racer::Default => search_plans(part, opts, progress, false, &tuning(None)),
        Racer::Seeded(s) => search_plans(part, opts, progress, false, &tuning(Some(s))),
        Racer::NoWarmStart => {
            let o = Options {
                warm_start: false,
                ..opts.clone()
            };
            search_plans(part, &o, progress, false, &tuning(None))
        }
        Racer::Varisat => {
            let o = Options {
                solver: Backend::Varisat,
                ..opts.clone()
            };
            search_plans(part, &o, progress, false, &tuning(None))
        }
        Racer::VariedStarts => varied_starts(part, opts, progress),
    }
}

/// The varied starts alone: a feasible variant of the layer-by-layer plan, or nothing
/// (not proven). Parts with a torch or a robot check are left to the searches, which judge
/// those too; graph parts have no variants.
fn varied_starts(part: &Part, opts: &Options, progress: Progress) -> Result<Report, PlanError> {
    let started = Instant::now();
    if part.bead_part().is_some() || opts.torch.is_some() || opts.executed.is_some() {
        return Ok(stopped_early(started));
    }
    let graph = WeldGraph::new(part);
    let k = max_fragments(part, opts);
    let limits = constructive::Limits {
        deadline: opts.timeout.and_then(|t| started.checked_add(t)),
        cancel: opts.cancel.clone(),
    };
    let Some(base) = constructive::layered_plan(part, &graph, k, opts.solver, &limits) else {
        return Ok(stopped_early(started));
    };
    let model = ThermalModel::new(part, &graph);
    // Only when the simulator says the plain warm start breaks a window: a feasible one is
    // the default racer's first candidate already.
    let plain =
        waam_thermal::simulate_until(&model, &base, limits.deadline, limits.cancel.clone())?;
    if plain.is_none_or(|o| o.violation.is_none()) {
        return Ok(stopped_early(started));
    }
    let portfolio = Portfolio {
        part,
        graph: &graph,
        k,
        backend: opts.solver,
        limits: &limits,
        model: &model,
        workers: 1,
    };
    let Some((fragments, _)) = portfolio.varied_start(&base) else {
        return Ok(stopped_early(started));
    };
    let mut stats = Stats {
        candidates: 1,
        feasible: 1,
        first_feasible_s: Some(started.elapsed().as_secs_f64()),
        ..Stats::default()
    };
    let margin = margin_under(&model, &fragments, opts, started)?;
    stats.best_margin_s = Some(margin).filter(|m| m.is_finite());
    stats.total_s = started.elapsed().as_secs_f64();
    progress(Event::Candidate {
        fragments: &fragments,
        verdict: CandidateVerdict::Feasible,
        stats: &stats,
    });
    Ok(Report {
        best: Some(Found { fragments, margin }),
        proven: true,
        no_plan: None,
        stats,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_thread_gets_a_search_after_the_varied_starts() {
        for threads in 1..=16 {
            let r = racers(threads);
            assert_eq!(r[0], Racer::Default);
            let searches = r.iter().filter(|&&x| x != Racer::VariedStarts).count();
            assert!(searches >= threads, "{threads} threads: {r:?}");
        }
    }

    #[test]
    fn a_chosen_configuration_runs_alone() {
        let o = |warm_start, solver, threads| Options {
            warm_start,
            solver,
            threads,
            ..Options::default()
        };
        assert_eq!(threads(&o(true, Backend::Cadical, 4)), 4);
        assert_eq!(threads(&o(false, Backend::Cadical, 4)), 1);
        assert_eq!(threads(&o(true, Backend::Varisat, 4)), 1);
        assert!(threads(&o(true, Backend::Cadical, 0)) >= 1);
    }
}
