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
//! The racers ([`racers`]), one per thread: the default (CaDiCaL with the layer-by-layer
//! warm start and, when that breaks a window, the varied starts of [`crate::portfolio`]:
//! exactly the run of `--threads 1`), varisat (its own warm start, repaired and varied as
//! the default's is: exactly the run of `--solver varisat`), CaDiCaL without the warm
//! start, then CaDiCaL with other seeds. Varisat's racer runs only when its layer-by-layer
//! plan is not the default's; otherwise the next configuration in line runs on its thread
//! ([`stand_in`]). The default configuration alone, when its warm start cannot be
//! repaired, also tries varisat's layer-by-layer plan
//! ([`crate::portfolio::Portfolio::layered`]); in a race varisat's racer has it. The
//! default starts at once, the others as soon as its warm start is judged and is no plan
//! ([`Gate`]): a feasible warm start is the answer without a racer beside it slowing it
//! down. Each racer is one thread (its varied starts too), so none waits for another once
//! started and none shares its core: the race is as fast as the fastest of the
//! configurations it runs, up to the default's warm start and the simulation's pool (a
//! configuration alone on all cores steps its simulations on every core, a racer mostly
//! on its own: the pool serves one simulation at a time; every racer's simulations step
//! on at most the race's threads, its repair and varied starts on its share,
//! [`Tuning::workers`]). An earlier race ran the varied starts as a
//! racer of their own and queued the other configurations behind them: on 2 threads a
//! generated box waited 5.7 s for a plan that `--no-warm-start` finds in 0.5 s. Three
//! racers on two cores were tried too: each CaDiCaL racer then ran about half as fast
//! (cache and time slicing), more than the 1.5 the shares suggest. Racers that would not fit `max_memory_mb` together (each
//! encodes the part) are left out; the default always runs.
//!
//! The racers publish their learned thermal clauses ([`crate::sharing`]); the CaDiCaL
//! racers other than the default take them in, inside their solves.
//!
//! Proofs stay deterministic: "no plan" is answered only by the default configuration,
//! which takes no clauses in (so its reasons are those of a run without the race); the
//! counting and enumerating searches do not race.
//!
//! The best plan races too ([`race_best`]): the default racer runs the whole optimizing
//! search of `--threads 1`, the others look for a first plan; when one of them finds it
//! before the default has any, a second optimizing search starts from that plan.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use waam_part::graph::WeldGraph;
use waam_part::Part;

use crate::constructive::{layered_plan, Limits};
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
    /// Not a configuration of its own: the default's optimizing search started from the
    /// first plan another racer found ([`race_best`]).
    FromPlan,
}

impl Racer {
    /// Whether the racer repairs and varies its warm start when it breaks a window: the
    /// default, and varisat, whose warm start is a plan of its own (varisat covers the
    /// layers differently from CaDiCaL), so its repair is no repeat of the default's. A
    /// racer that did not was weaker than its configuration alone: on a double tube of 10^4
    /// blocks `--solver varisat` repaired its warm start in 2.4 s, its racer found nothing
    /// in 15 s. A seeded racer starts from the default's warm start: it would repeat it.
    pub fn varies_starts(self) -> bool {
        matches!(self, Racer::Default | Racer::Varisat)
    }

    /// The racer's name in statistics and logs.
    pub fn name(self) -> String {
        match self {
            Racer::Default => "default".into(),
            Racer::NoWarmStart => "no-warm-start".into(),
            Racer::Varisat => "varisat".into(),
            Racer::Seeded(s) => format!("seed {s}"),
            Racer::FromPlan => "from another racer's plan".into(),
        }
    }
}

/// What a search run inside the race does differently.
pub(crate) struct Tuning {
    /// Try the varied starts when the warm start breaks a window (in a race, the racers
    /// that [`Racer::varies_starts`]).
    pub varied_starts: bool,
    /// With the varied starts, a CaDiCaL run also tries varisat's layer-by-layer plan when
    /// its own cannot be repaired (not in a race that runs a varisat racer).
    pub varisat_warm_start: bool,
    pub sharing: Option<Sharing>,
    pub seed: Option<u32>,
    /// A feasible plan another racer found: the search judges it first, in the warm
    /// start's place, and looks only for better plans.
    pub incumbent: Option<Vec<Vec<usize>>>,
    /// A warm start built before the search (the varisat racer's, built to compare it with
    /// the default's): judged in place of building one.
    pub warm_start: Option<Vec<Vec<usize>>>,
    /// The default racer's: its warm start as the other racers see it (they start once it
    /// is judged and is no feasible plan).
    pub default_warm_start: Option<Arc<DefaultWarmStart>>,
    /// The threads of the racer's repair and varied starts, its share of the race's
    /// (None: the run's, `opts.threads`). Its simulations of candidates step on the run's.
    pub workers: Option<usize>,
}

/// The default racer's warm start as the other racers see it.
#[derive(Default)]
pub(crate) struct DefaultWarmStart {
    /// Raised once it is judged and is no feasible plan, or there is none.
    failed: AtomicBool,
    /// The layer-by-layer plan it judged (set before `failed` is raised), if it built one.
    plan: OnceLock<Vec<Vec<usize>>>,
}

impl Tuning {
    /// A racer's in a race of `lineup`; `default_warm_start` for the default's to tell.
    fn racing(
        racer: Racer,
        lineup: &[Racer],
        sharing: Sharing,
        default_warm_start: Option<Arc<DefaultWarmStart>>,
    ) -> Tuning {
        Tuning {
            varied_starts: racer.varies_starts(),
            // The default tries varisat's plan after its own unless varisat races.
            varisat_warm_start: racer == Racer::Default && !lineup.contains(&Racer::Varisat),
            sharing: Some(sharing),
            seed: match racer {
                Racer::Seeded(s) => Some(s),
                _ => None,
            },
            incumbent: None,
            warm_start: None,
            default_warm_start,
            workers: None,
        }
    }

    /// A run on its own (no race).
    pub fn alone() -> Tuning {
        Tuning {
            varied_starts: true,
            varisat_warm_start: true,
            sharing: None,
            seed: None,
            incumbent: None,
            warm_start: None,
            default_warm_start: None,
            workers: None,
        }
    }

    /// The warm start (`plan`, the layer-by-layer plan before any repair; `None`: there was
    /// none) gave no feasible plan: tells the other racers ([`Tuning::default_warm_start`]).
    pub fn note_warm_start_failed(&self, plan: Option<&[Vec<usize>]>) {
        if let Some(shared) = &self.default_warm_start {
            if let Some(plan) = plan {
                // Only the first: a later call says there is still no plan.
                let _ = shared.plan.set(plan.to_vec());
            }
            shared.failed.store(true, Ordering::Release);
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
/// the other two a user can choose alone (varisat first: see [`stand_in`]), then seeded
/// CaDiCaL runs.
pub(crate) fn racers(threads: usize) -> Vec<Racer> {
    lineup().take(threads.max(1)).collect()
}

fn lineup() -> impl Iterator<Item = Racer> {
    [Racer::Default, Racer::Varisat, Racer::NoWarmStart]
        .into_iter()
        .chain((1..).map(Racer::Seeded))
}

/// The racer that runs in the varisat racer's place when varisat's layer-by-layer plan is
/// the default's own: the first of the line not racing already.
///
/// Why: varisat's racer is worth its thread for its warm start, a plan of its own (on a
/// T or two rings varisat covers the layers otherwise than CaDiCaL), which its repair then
/// mends. Where both solvers build the same plan (a floor walked as a serpentine, a box's
/// rings, a bead part's contours) its repair repeats the default's, and the thread is
/// better spent on the search without the warm start. On 2 threads that makes the second
/// racer varisat on the parts where varisat's plan is a different one and `--no-warm-start`
/// on the others. On 72 generated parts of 10^4 blocks, the faster of the default and a
/// fixed second racer (each run alone) was more than 2x slower than the best single
/// configuration on four parts with `--no-warm-start`, three with varisat, none with
/// this rule; the race itself went from 66 to 71 of 72 within 2x (docs/benchmarks.md).
fn stand_in(racing: &[Racer]) -> Racer {
    lineup()
        .find(|r| *r != Racer::Varisat && !racing.contains(r))
        .expect("the line is endless")
}

/// Varisat's layer-by-layer plan of `part` when it is not `default` (the default racer's),
/// else `None`: its racer would repeat the default's repair.
fn own_varisat_plan(
    part: &Part,
    opts: &Options,
    default: Option<&Vec<Vec<usize>>>,
) -> Option<Vec<Vec<usize>>> {
    // A bead part's warm start is walked along its contours, by no solver.
    if part.bead_part().is_some() {
        return None;
    }
    let graph = WeldGraph::new(part);
    let limits = Limits {
        deadline: opts.timeout.and_then(|t| Instant::now().checked_add(t)),
        cancel: opts.cancel.clone(),
    };
    let plan = layered_plan(
        part,
        &graph,
        max_fragments(part, opts),
        Backend::Varisat,
        &limits,
    )?;
    (default != Some(&plan)).then_some(plan)
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
        racer: Racer,
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
    let n = racers.len();
    let default_warm_start = Arc::new(DefaultWarmStart::default());
    let gate = Gate {
        after: Some(Arc::clone(&default_warm_start)),
        ..Gate::default()
    };
    for (i, &racer) in racers.iter().enumerate() {
        let sharing = Sharing::new(Arc::clone(&pool), i);
        // The default takes no clauses in: its proofs stay those of a run alone.
        let (entrant, gate) = match racer {
            Racer::Default => {
                let failed = Some(Arc::clone(&default_warm_start));
                let tuning = Tuning::racing(racer, &racers, sharing.publish_only(), failed);
                (Entrant::new(racer, tuning), gate.open())
            }
            _ => (Entrant::racing(racer, &racers, sharing), gate.clone()),
        };
        spawn(
            (entrant, false, share(i, n, threads)),
            &shared,
            (started, &gate),
            &stop,
            &tx,
        );
    }
    drop(tx);
    let mut winner: Option<Report> = None;
    let mut default: Option<Result<Report, PlanError>> = None;
    // Until a plan is found or the default configuration ends (a proof, an error, the
    // deadline or a cancel: then the race is over for every racer).
    while winner.is_none() && default.is_none() {
        match rx.recv_timeout(POLL) {
            Ok(Message::Candidate {
                racer: _,
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
                    Ok(mut r) if r.best.is_some() => {
                        tracing::debug!("race: {racer:?} found the first feasible plan");
                        r.stats.first_plan_racer = Some(racer.name());
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
    report.stats.racers_started = gate.started.load(Ordering::Relaxed);
    Ok(report)
}

/// The best plan of `part` (fewest weld paths, then the largest t8/5 margin), its first
/// feasible plan raced on `threads` threads; events reach `progress` on the calling thread.
///
/// The default racer runs the optimizing search of `--threads 1` as it is (it takes no
/// clauses in); the others look for a first plan. Once the default has a feasible plan of
/// its own, the others stop. When another racer finds one first, it stops the others and
/// a second optimizing search (the default configuration, [`Racer::FromPlan`]) starts from
/// its plan as the plan to beat, taking in the clauses the racers shared, beside the
/// default, which goes on.
///
/// The answer is deterministic: a proven answer is only ever the default racer's, which is
/// the `--threads 1` search itself — the same plan, the same candidates (only the
/// default's events reach `progress`), the same "no plan" and reasons, so a recording
/// replays identically on any number of threads. The race helps when the deadline or a
/// cancel comes first: then the answer is the better plan of the two optimizing searches
/// (or the race's first plan), not proven. Waiting for the default's proof costs little:
/// the search from the race's plan proves the same k and margin (it is complete and sound;
/// its plan to beat and the shared clauses, each a fact about the part's own windows —
/// a racer stops publishing once it narrows, [`Sharing::stop_publishing`] — only remove
/// plans) but may return another plan equally good.
pub(crate) fn race_best(
    part: &Part,
    opts: &Options,
    progress: Progress,
    threads: usize,
) -> Result<Report, PlanError> {
    let started = Instant::now();
    let mut racers = racers(threads);
    // The second optimizing search takes the place of a racer that was stopped.
    racers.truncate(fitting(part, opts));
    if racers.len() == 1 {
        return search_plans(part, opts, progress, true, &Tuning::alone());
    }
    // The racers looking for a first plan stop once there is one; the optimizing searches
    // once one of them has the answer.
    let seekers = Arc::new(AtomicBool::new(false));
    let optimizers = Arc::new(AtomicBool::new(false));
    let pool = Arc::new(ClausePool::default());
    let shared = Arc::new((part.clone(), opts.clone()));
    let (tx, rx) = mpsc::channel::<Message>();
    let from_plan_id = racers.len();
    let n = racers.len();
    let default_warm_start = Arc::new(DefaultWarmStart::default());
    let gate = Gate {
        after: Some(Arc::clone(&default_warm_start)),
        ..Gate::default()
    };
    for (i, &racer) in racers.iter().enumerate() {
        let sharing = Sharing::new(Arc::clone(&pool), i);
        if racer == Racer::Default {
            // Takes no clauses in: its "no plan" is that of a run alone.
            let failed = Some(Arc::clone(&default_warm_start));
            let tuning = Tuning::racing(racer, &racers, sharing.publish_only(), failed);
            spawn(
                (Entrant::new(racer, tuning), true, share(i, n, threads)),
                &shared,
                (started, &gate.open()),
                &optimizers,
                &tx,
            );
        } else {
            spawn(
                (
                    Entrant::racing(racer, &racers, sharing),
                    false,
                    share(i, n, threads),
                ),
                &shared,
                (started, &gate),
                &seekers,
                &tx,
            );
        }
    }
    // The first feasible plan the race saw: which racer, when.
    let mut first: Option<(Racer, f64)> = None;
    let mut default_has_plan = false;
    let mut from_plan_started = false;
    // Optimizing searches still running, and the best unproven answer of those that ended
    // (or the winner's first plan, should its search end with nothing better).
    let mut optimizing = 1;
    let mut kept: Option<Report> = None;
    let mut proven: Option<Result<Report, PlanError>> = None;
    while proven.is_none() && optimizing > 0 {
        match rx.recv_timeout(POLL) {
            Ok(Message::Candidate {
                racer,
                fragments,
                verdict,
                stats,
            }) => {
                let feasible = verdict == CandidateVerdict::Feasible;
                if feasible && (racer == Racer::Default || !(default_has_plan || from_plan_started))
                {
                    first.get_or_insert((racer, started.elapsed().as_secs_f64()));
                }
                // Only the default's candidates: the events (and so a recording) are
                // those of `--threads 1`, whichever racer was faster.
                if racer != Racer::Default {
                    continue;
                }
                if feasible {
                    default_has_plan = true;
                    seekers.store(true, Ordering::Relaxed);
                }
                progress(Event::Candidate {
                    fragments: &fragments,
                    verdict,
                    stats: &stats,
                });
            }
            Ok(Message::Done { racer, result, .. }) => match (racer, *result) {
                // Only the default's proof is the answer: it is the `--threads 1` search as
                // it is, so a proven answer is the same plan on any number of threads (a
                // recording replays identically). The search from another racer's plan is
                // the fallback when the deadline or a cancel comes first.
                (Racer::Default, Ok(r)) if r.proven => proven = Some(Ok(r)),
                (Racer::Default | Racer::FromPlan, Ok(mut r)) => {
                    optimizing -= 1;
                    r.proven = false;
                    kept = Some(better(kept, r));
                }
                // The default's error is the answer a run alone gives.
                (Racer::Default, Err(e)) => proven = Some(Err(e)),
                (racer, Err(e)) => {
                    optimizing -= usize::from(racer == Racer::FromPlan);
                    tracing::warn!("race: {racer:?} stopped: {e}");
                }
                (racer, Ok(mut r)) => {
                    let Some(plan) = r.best.as_ref().map(|b| b.fragments.clone()) else {
                        continue;
                    };
                    if default_has_plan || from_plan_started {
                        continue;
                    }
                    tracing::debug!(
                        "race: {racer:?} found the first feasible plan; optimizing from it"
                    );
                    seekers.store(true, Ordering::Relaxed);
                    from_plan_started = true;
                    optimizing += 1;
                    let tuning = Tuning {
                        varied_starts: false,
                        varisat_warm_start: false,
                        sharing: Some(Sharing::new(Arc::clone(&pool), from_plan_id)),
                        seed: None,
                        incumbent: Some(plan),
                        warm_start: None,
                        default_warm_start: None,
                        workers: None,
                    };
                    // Not counted among the racers: it is the default configuration again.
                    spawn(
                        (Entrant::new(Racer::FromPlan, tuning), true, 1),
                        &shared,
                        (started, &Gate::default()),
                        &optimizers,
                        &tx,
                    );
                    // Not proven optimal: the answer unless the optimizing searches find better.
                    r.proven = false;
                    r.no_plan = None;
                    kept = Some(better(kept, r));
                }
            },
            Err(mpsc::RecvTimeoutError::Timeout) => {
                if opts
                    .cancel
                    .as_ref()
                    .is_some_and(|c| c.load(Ordering::Relaxed))
                {
                    optimizers.store(true, Ordering::Relaxed);
                    seekers.store(true, Ordering::Relaxed);
                }
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
        }
    }
    optimizers.store(true, Ordering::Relaxed);
    seekers.store(true, Ordering::Relaxed);
    let mut report = match (proven, kept) {
        (Some(answer), _) => answer?,
        (None, Some(kept)) => kept,
        (None, None) => stopped_early(started),
    };
    if report.best.is_some() {
        if let Some((racer, at_s)) = first {
            report.stats.first_plan_racer = Some(racer.name());
            report.stats.first_feasible_s = Some(at_s);
        }
    }
    report.stats.total_s = started.elapsed().as_secs_f64();
    report.stats.racers_started = gate.started.load(Ordering::Relaxed);
    Ok(report)
}

/// The better of two unproven answers: fewer weld paths, then the larger margin (a plan
/// over none; on a tie the one kept first).
fn better(kept: Option<Report>, new: Report) -> Report {
    let Some(kept) = kept else { return new };
    let key = |r: &Report| {
        r.best
            .as_ref()
            .map(|b| (std::cmp::Reverse(b.fragments.len()), b.margin))
    };
    match (key(&kept), key(&new)) {
        (None, Some(_)) => new,
        (Some((kn, km)), Some((nn, nm))) if nn > kn || (nn == kn && nm > km) => new,
        _ => kept,
    }
}

/// The threads of racer `i` of `racers` on `threads`: one each, and those no racer takes
/// (memory admitted fewer racers than threads) to the default (the first): only its
/// repair and varied starts judge candidates on more than one. At 10^5 blocks only the
/// default fits in memory, and on one thread it left the other cores idle.
fn share(i: usize, racers: usize, threads: usize) -> usize {
    if i == 0 {
        threads.saturating_sub(racers.saturating_sub(1)).max(1)
    } else {
        1
    }
}

/// Runs `search` on threads of its own (`racer.1`: the first its own, the others its
/// repair's and varied starts' workers) as `racer.0`, stopped by `stop` or the run's
/// deadline (counted from `started`), its events and its result sent on `tx`.
/// Detached, not scoped: the answer does not wait for a loser that stops only between
/// its solves (varisat); it ends on its own soon after its stop flag is raised.
fn spawn(
    (entrant, optimize, threads): (Entrant, bool, usize),
    shared: &Arc<(Part, Options)>,
    (started, gate): (Instant, &Gate),
    stop: &Arc<AtomicBool>,
    tx: &mpsc::Sender<Message>,
) {
    let (shared, stop, tx, gate) = (
        Arc::clone(shared),
        Arc::clone(stop),
        tx.clone(),
        gate.clone(),
    );
    std::thread::spawn(move || {
        if !gate.pass(&stop) {
            return;
        }
        let (part, opts) = &*shared;
        // What is left of the race's time.
        let left = |offset: Duration| Options {
            timeout: opts.timeout.map(|t| t.saturating_sub(offset)),
            cancel: Some(Arc::clone(&stop)),
            ..opts.clone()
        };
        let (racer, tuning) = entrant.who_runs(part, &left(started.elapsed()), gate.default_plan());
        // Its share of the threads: its varied starts take no other racer's core.
        let tuning = Tuning {
            workers: Some(threads),
            ..tuning
        };
        // The search's times count from here (after varisat's plan was built to choose
        // who runs), so they are shifted by the race's time until now.
        let offset = started.elapsed();
        let o = left(offset);
        let mut forward = |event: Event<'_>| {
            if let Event::Candidate {
                fragments,
                verdict,
                stats,
            } = event
            {
                let _ = tx.send(Message::Candidate {
                    racer,
                    fragments: fragments.to_vec(),
                    verdict,
                    stats: Box::new(stats.clone()),
                });
            }
        };
        let result = run(racer, part, &o, &mut forward, tuning, optimize);
        let _ = tx.send(Message::Done {
            racer,
            result: Box::new(result),
            offset,
        });
    });
}

/// A racer and its tuning, as its thread gets them.
struct Entrant {
    racer: Racer,
    tuning: Tuning,
    /// Varisat's racer: who runs in its place, with its tuning, when varisat's plan is the
    /// default's own ([`stand_in`]).
    stand_in: Option<(Racer, Tuning)>,
}

impl Entrant {
    fn new(racer: Racer, tuning: Tuning) -> Entrant {
        Entrant {
            racer,
            tuning,
            stand_in: None,
        }
    }

    /// A racer other than the default in a race of `lineup`, taking clauses in.
    fn racing(racer: Racer, lineup: &[Racer], sharing: Sharing) -> Entrant {
        let stand_in = (racer == Racer::Varisat).then(|| {
            let other = stand_in(lineup);
            (other, Tuning::racing(other, lineup, sharing.clone(), None))
        });
        Entrant {
            racer,
            tuning: Tuning::racing(racer, lineup, sharing, None),
            stand_in,
        }
    }

    /// The racer that runs, and its tuning: varisat's with its own plan as its warm start,
    /// or the one standing in for it when that plan is `default`'s.
    fn who_runs(
        self,
        part: &Part,
        opts: &Options,
        default: Option<&Vec<Vec<usize>>>,
    ) -> (Racer, Tuning) {
        let Some((other, tuning)) = self.stand_in else {
            return (self.racer, self.tuning);
        };
        match own_varisat_plan(part, opts, default) {
            Some(plan) => (
                self.racer,
                Tuning {
                    warm_start: Some(plan),
                    ..self.tuning
                },
            ),
            None => {
                tracing::debug!(
                    "race: varisat's warm start is the default's; {} runs in its place",
                    other.name()
                );
                (other, tuning)
            }
        }
    }
}

/// When a racer starts, and how many have.
///
/// The racers other than the default start once the default's warm start is judged and is
/// no feasible plan (or there is none): a feasible warm start is the answer, and racers
/// beside it only slow it down — on 2 cores a 10^4-block box's warm start was judged in
/// 1.0 s alone, 1.4–1.7 s beside `--no-warm-start`. The wait is the time to build the warm
/// start and simulate it up to the window it breaks; another racer's first plan needs a
/// whole simulation of its own.
#[derive(Clone, Default)]
struct Gate {
    /// None: start at once; else once the default's warm start failed.
    after: Option<Arc<DefaultWarmStart>>,
    /// Racers that started (a race's statistic).
    started: Arc<AtomicUsize>,
}

impl Gate {
    /// Waits until the racer may start (true) or the race is stopped first (false).
    fn pass(&self, stop: &AtomicBool) -> bool {
        if let Some(after) = &self.after {
            while !after.failed.load(Ordering::Acquire) {
                if stop.load(Ordering::Relaxed) {
                    return false;
                }
                std::thread::sleep(GATE_POLL);
            }
        }
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        self.started.fetch_add(1, Ordering::Relaxed);
        true
    }

    /// The layer-by-layer plan of the default's warm start that failed, once the gate
    /// opened after it.
    fn default_plan(&self) -> Option<&Vec<Vec<usize>>> {
        self.after.as_ref()?.plan.get()
    }

    /// The same count, starting at once.
    fn open(&self) -> Gate {
        Gate {
            after: None,
            started: Arc::clone(&self.started),
        }
    }
}

/// How often a racer waiting at its [`Gate`] looks again.
const GATE_POLL: Duration = Duration::from_millis(5);

/// One racer's run, stopped by `opts.cancel` (the race's) or its deadline; the default
/// tells `tuning.default_warm_start` when its warm start is no plan.
fn run(
    racer: Racer,
    part: &Part,
    opts: &Options,
    progress: Progress,
    tuning: Tuning,
    optimize: bool,
) -> Result<Report, PlanError> {
    let o = match racer {
        Racer::Default | Racer::Seeded(_) | Racer::FromPlan => opts.clone(),
        Racer::NoWarmStart => Options {
            warm_start: false,
            ..opts.clone()
        },
        Racer::Varisat => Options {
            solver: Backend::Varisat,
            ..opts.clone()
        },
    };
    search_plans(part, &o, progress, optimize, &tuning)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn test_part(file: &str) -> Part {
        let path = format!("{}/../../tests/data/{file}", env!("CARGO_MANIFEST_DIR"));
        Part::parse(&std::fs::read_to_string(path).unwrap()).unwrap()
    }

    /// The default's feasible warm start ends the race before another racer starts; one
    /// that breaks a window lets them start, and the faster one wins.
    #[test]
    fn the_other_racers_start_once_the_default_warm_start_breaks_a_window() {
        let opts = Options {
            timeout: Some(Duration::from_secs(60)),
            ..Options::default()
        };
        // CaDiCaL's warm start of this tube keeps every window (varisat's does not).
        let part = test_part("varisat-tube-400.yaml");
        let report = race(&part, &opts, &mut |_| {}, 3).unwrap();
        assert!(report.best.is_some());
        assert_eq!(report.stats.first_plan_racer.as_deref(), Some("default"));
        assert_eq!(report.stats.racers_started, 1, "{:?}", report.stats);
        // The default's warm start of this one breaks a window, and the search without it
        // (the third racer) finds a plan about ten times sooner than the default's repair.
        let part = test_part("race-tube-600.yaml");
        let report = race(&part, &opts, &mut |_| {}, 3).unwrap();
        assert_eq!(report.stats.racers_started, 3, "{:?}", report.stats);
        assert_eq!(
            report.stats.first_plan_racer.as_deref(),
            Some("no-warm-start")
        );
    }

    /// `search`'s report, and whether its first candidate (the warm start) broke a window.
    fn watching_the_warm_start(
        search: impl FnOnce(Progress) -> Result<Report, PlanError>,
    ) -> (bool, Report) {
        let mut broke = false;
        let report = search(&mut |event: Event<'_>| {
            if let Event::Candidate { verdict, stats, .. } = event {
                if stats.candidates == 1 {
                    broke = matches!(verdict, CandidateVerdict::Violated { .. });
                }
            }
        })
        .unwrap();
        (broke, report)
    }

    /// Varisat's racer repairs its own warm start, as `--solver varisat` alone does: a
    /// generated tube whose varisat warm start breaks a window gets its plan from the
    /// repair (no solve), where a racer that only searched needed solves.
    #[test]
    fn the_varisat_racer_repairs_its_own_warm_start() {
        let part = test_part("varisat-tube-400.yaml");
        let opts = Options {
            threads: 1,
            timeout: Some(Duration::from_secs(60)),
            ..Options::default()
        };
        let sharing = Sharing::new(Arc::new(ClausePool::default()), 2);
        let tuning = Tuning::racing(Racer::Varisat, &racers(3), sharing, None);
        let (warm_start_broke, report) = watching_the_warm_start(|progress| {
            run(Racer::Varisat, &part, &opts, progress, tuning, false)
        });
        assert!(
            warm_start_broke,
            "the test needs a warm start that breaks a window"
        );
        assert!(report.best.is_some());
        assert_eq!(report.stats.sat_solves, 0, "{:?}", report.stats);
        assert_eq!(report.stats.candidates, 2, "{:?}", report.stats);
    }

    /// Varisat's racer runs when varisat's layer-by-layer plan is not the default's (then
    /// with that plan as its warm start), and gives its thread to the next racer in line
    /// when it is.
    #[test]
    fn varisat_gives_its_thread_away_when_its_plan_is_the_defaults() {
        assert_eq!(racers(2), [Racer::Default, Racer::Varisat]);
        assert_eq!(stand_in(&racers(2)), Racer::NoWarmStart);
        assert_eq!(stand_in(&racers(3)), Racer::Seeded(1));
        let opts = Options {
            timeout: Some(Duration::from_secs(60)),
            ..Options::default()
        };
        let plan = |part: &Part, backend| {
            let graph = WeldGraph::new(part);
            let limits = Limits {
                deadline: None,
                cancel: None,
            };
            layered_plan(part, &graph, max_fragments(part, &opts), backend, &limits).unwrap()
        };
        let entrant = || {
            let sharing = Sharing::new(Arc::new(ClausePool::default()), 1);
            Entrant::racing(Racer::Varisat, &racers(2), sharing)
        };
        // Either solver walks this plate's layers as the same serpentine.
        let blocks = (0..3)
            .flat_map(|z| (0..4).flat_map(move |y| (0..6).map(move |x| [x, y, z])))
            .collect();
        let plate =
            Part::from_blocks("plate".into(), [6.0, 6.0, 2.5], [0.0; 3], 2, blocks).unwrap();
        let default = plan(&plate, Backend::Cadical);
        let (racer, tuning) = entrant().who_runs(&plate, &opts, Some(&default));
        assert_eq!(racer, Racer::NoWarmStart);
        assert!(tuning.warm_start.is_none() && !tuning.varied_starts);
        // Varisat covers this tube's layers otherwise (its plan breaks a window, CaDiCaL's
        // does not).
        let tube = test_part("varisat-tube-400.yaml");
        let default = plan(&tube, Backend::Cadical);
        let own = plan(&tube, Backend::Varisat);
        assert_ne!(own, default);
        let (racer, tuning) = entrant().who_runs(&tube, &opts, Some(&default));
        assert_eq!(racer, Racer::Varisat);
        assert_eq!(tuning.warm_start, Some(own));
        assert!(tuning.varied_starts);
    }

    /// A run on its own whose warm start breaks a window that its repair does not keep
    /// tries varisat's layer-by-layer plan: on this double tube varisat's plan,
    /// repaired or varied, gives the default a plan without a solve (without it: one solve,
    /// 13 s in a release build).
    #[test]
    fn a_run_alone_tries_varisats_plan_when_its_own_cannot_be_repaired() {
        let part = test_part("double-tube-800.yaml");
        let opts = Options {
            threads: 1,
            timeout: Some(Duration::from_secs(120)),
            ..Options::default()
        };
        let (warm_start_broke, report) = watching_the_warm_start(|progress| {
            search_plans(&part, &opts, progress, false, &Tuning::alone())
        });
        assert!(warm_start_broke, "the test needs a broken warm start");
        assert!(report.best.is_some(), "{:?}", report.stats);
        assert_eq!(report.stats.sat_solves, 0, "{:?}", report.stats);
    }

    #[test]
    fn threads_no_racer_takes_go_to_the_default() {
        assert_eq!((0..2).map(|i| share(i, 2, 2)).collect::<Vec<_>>(), [1, 1]);
        assert_eq!(share(0, 1, 2), 2);
        assert_eq!(share(0, 1, 16), 16);
        assert_eq!(
            (0..3).map(|i| share(i, 3, 8)).collect::<Vec<_>>(),
            [6, 1, 1]
        );
        assert_eq!(share(0, 3, 2), 1);
        assert_eq!(
            (0..4).map(|i| share(i, 4, 4)).collect::<Vec<_>>(),
            [1, 1, 1, 1]
        );
    }

    #[test]
    fn one_racer_per_thread_the_default_first() {
        assert_eq!(racers(2), [Racer::Default, Racer::Varisat]);
        assert_eq!(
            racers(5),
            [
                Racer::Default,
                Racer::Varisat,
                Racer::NoWarmStart,
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
    fn optimizing_from_another_racers_plan_proves_the_same_answer() {
        // A 3 x 2 plate, 2 layers, k = 2, a wide window on a top block: the worst feasible
        // plan (most weld paths, smallest margin) as the plan to beat.
        let blocks = (0..2)
            .flat_map(|z| (0..2).flat_map(move |y| (0..3).map(move |x| [x, y, z])))
            .collect();
        let mut part =
            Part::from_blocks("plate".into(), [6.0, 6.0, 2.5], [0.0; 3], 2, blocks).unwrap();
        let top = part.index_of([1, 1, 1]).unwrap();
        part.set_window(
            top,
            waam_part::Window {
                min_s: 0.0,
                max_s: 1e4,
            },
        );
        let opts = Options {
            threads: 1,
            ..Options::default()
        };
        let graph = waam_part::graph::WeldGraph::new(&part);
        let model = waam_thermal::ThermalModel::new(&part, &graph);
        let mut feasible = Vec::new();
        crate::enumerate(&part, &opts, &mut |_| {}, &mut |p| {
            feasible.push(p.to_vec());
            Ok(())
        })
        .unwrap();
        let margin =
            |p: &[Vec<usize>]| model.margin(&waam_thermal::simulate(&model, p).unwrap().crossings);
        let worst = feasible
            .iter()
            .max_by(|a, b| a.len().cmp(&b.len()).then(margin(b).total_cmp(&margin(a))))
            .unwrap()
            .clone();
        let alone = search_plans(&part, &opts, &mut |_| {}, true, &Tuning::alone()).unwrap();
        let tuning = Tuning {
            varied_starts: false,
            varisat_warm_start: false,
            sharing: None,
            seed: None,
            incumbent: Some(worst.clone()),
            warm_start: None,
            default_warm_start: None,
            workers: None,
        };
        let from_plan = search_plans(&part, &opts, &mut |_| {}, true, &tuning).unwrap();
        let (a, f) = (alone.best.unwrap(), from_plan.best.unwrap());
        assert!(alone.proven && from_plan.proven);
        assert_eq!(f.fragments.len(), a.fragments.len());
        assert!(
            (f.margin - a.margin).abs() <= 1e-6,
            "{} vs {}",
            f.margin,
            a.margin
        );
        assert!(
            worst.len() > a.fragments.len() || margin(&worst) < a.margin - 1e-6,
            "the plan to beat is not the best: the test needs a worse one"
        );
        assert_ne!(f.fragments, worst, "a better plan than the one to beat");
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
