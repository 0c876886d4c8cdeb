//! The first feasible plan by a race: threads each run one configuration of the planner
//! on the same part, the first feasible plan wins and the others are cancelled.
//!
//! Why a race and not a rule: which configuration finds a plan first depends on the part
//! in ways no threshold captures — on a double tube the warm start's phases led CaDiCaL
//! astray for 40 s where the search without them took 10 s; on a tall tube the warm start
//! breaks a window early and only another start keeps it. Every configuration is sound
//! (each plan is judged by the simulator, each learned clause is a fact about the part), so
//! racing them costs only cores.
//!
//! The racers ([`racers`]), one per thread, all started at once: the default (CaDiCaL with
//! the layer-by-layer warm start and, when that breaks a window, the varied starts of
//! [`crate::portfolio`]: exactly the run of `--threads 1`), CaDiCaL without the warm start,
//! varisat, then CaDiCaL with other seeds. Each racer is one thread (its varied starts
//! too), so none waits for another and none shares its core: the race is as fast as the
//! fastest of the configurations it runs, up to what the racers cost each other in memory
//! bandwidth. An earlier race ran the varied starts as a racer of their own and queued the
//! other configurations behind them: on 2 threads a generated box waited 5.7 s for a plan
//! that `--no-warm-start` finds in 0.5 s. Three racers on two cores were tried too: each
//! CaDiCaL racer then ran about half as fast (cache and time slicing), more than the
//! 1.5 the shares suggest. Racers that would not fit `max_memory_mb` together (each
//! encodes the part) are left out; the default always runs.
//!
//! The racers publish their learned thermal clauses ([`crate::sharing`]); the CaDiCaL
//! racers other than the default take them in, inside their solves.
//!
//! Proofs stay deterministic: "no plan" is answered only by the default configuration,
//! which takes no clauses in (so its reasons are those of a run without a race), and the
//! optimizing, counting and enumerating searches do not race.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::sync::Arc;
use std::time::{Duration, Instant};

use waam_part::Part;

use crate::sat::Backend;
use crate::sharing::{ClausePool, Sharing};
use crate::{
    estimated_memory_mb, max_fragments, search_plans, stopped_early, CandidateVerdict, Event,
    Options, PlanError, Progress, Report, Stats,
};

/// One configuration of the planner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Racer {
    /// CaDiCaL with the warm start (and the varied starts when it breaks a window): what
    /// `--threads 1` runs.
    Default,
    NoWarmStart,
    Varisat,
    /// CaDiCaL with the warm start and its own seed.
    Seeded(u32),
}

/// What a search run inside the race does differently.
pub(crate) struct Tuning {
    /// Try the varied starts when the warm start breaks a window (only the default racer
    /// does in a race: the others would repeat its work).
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

/// The threads a race of `opts` is for: 1 (no race) unless the run is the default
/// configuration (a chosen solver or `--no-warm-start` is run as asked).
pub(crate) fn threads(opts: &Options) -> usize {
    let default = opts.warm_start && opts.solver == Backend::Cadical;
    match opts.threads {
        _ if !default => 1,
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    }
}

/// The configurations raced on `threads` threads, one each, in this order: the default,
/// the other two a user can choose alone, then seeded CaDiCaL runs.
pub(crate) fn racers(threads: usize) -> Vec<Racer> {
    [Racer::Default, Racer::NoWarmStart, Racer::Varisat]
        .into_iter()
        .chain((1..).map(Racer::Seeded))
        .take(threads.max(1))
        .collect()
}

/// How many racers fit `opts.max_memory_mb` side by side (each encodes the part), at
/// least one: the default's own size is checked by its search, as on its own.
fn fitting(part: &Part, opts: &Options) -> usize {
    let each = estimated_memory_mb(part.len(), max_fragments(part, opts)).max(1);
    (opts.max_memory_mb / each).max(1) as usize
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
    let mut racers = racers(threads);
    racers.truncate(fitting(part, opts));
    let stop = Arc::new(AtomicBool::new(false));
    let pool = Arc::new(ClausePool::default());
    let shared = Arc::new((part.clone(), opts.clone()));
    let (tx, rx) = mpsc::channel::<Message>();
    // Detached, not scoped: the answer does not wait for a loser that stops only between
    // its solves (varisat); it ends on its own soon after the race's cancel.
    for (i, racer) in racers.into_iter().enumerate() {
        let tx = tx.clone();
        let (stop, pool, shared) = (Arc::clone(&stop), Arc::clone(&pool), Arc::clone(&shared));
        std::thread::spawn(move || {
            let (part, opts) = &*shared;
            let offset = started.elapsed();
            // One thread per racer: its varied starts and simulations take no other core.
            let o = Options {
                timeout: opts.timeout.map(|t| t.saturating_sub(offset)),
                cancel: Some(Arc::clone(&stop)),
                threads: 1,
                ..opts.clone()
            };
            let sharing = Sharing::new(pool, i);
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
    let tuning = Tuning {
        varied_starts: racer == Racer::Default,
        sharing: Some(sharing),
        seed: match racer {
            Racer::Seeded(s) => Some(s),
            _ => None,
        },
    };
    let o = match racer {
        Racer::Default | Racer::Seeded(_) => opts.clone(),
        Racer::NoWarmStart => Options {
            warm_start: false,
            ..opts.clone()
        },
        Racer::Varisat => Options {
            solver: Backend::Varisat,
            ..opts.clone()
        },
    };
    search_plans(part, &o, progress, false, &tuning)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_racer_per_thread_the_default_first() {
        assert_eq!(racers(2), [Racer::Default, Racer::NoWarmStart]);
        assert_eq!(
            racers(5),
            [
                Racer::Default,
                Racer::NoWarmStart,
                Racer::Varisat,
                Racer::Seeded(1),
                Racer::Seeded(2)
            ]
        );
        for threads in 1..=16 {
            assert_eq!(racers(threads).len(), threads);
        }
    }

    #[test]
    fn racers_that_do_not_fit_the_memory_limit_together_are_left_out() {
        let part = Part::from_blocks(
            "plate".into(),
            [6.0, 6.0, 2.5],
            [0.0; 3],
            2,
            (0..100)
                .flat_map(|x| (0..100).map(move |y| [x, y, 0]))
                .collect(),
        )
        .unwrap();
        let each = estimated_memory_mb(part.len(), 2);
        let o = |max_memory_mb| Options {
            max_memory_mb,
            ..Options::default()
        };
        assert_eq!(fitting(&part, &o(3 * each)), 3);
        assert_eq!(fitting(&part, &o(3 * each - 1)), 2);
        assert_eq!(fitting(&part, &o(each / 2)), 1, "the default always runs");
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
