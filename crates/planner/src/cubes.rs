//! Cube and conquer: the plans of a part split into disjoint cubes by how they begin, and
//! the cubes enumerated by several workers at once, each worker with its own search (its
//! own solver and prefix cache) taking cubes from a shared queue and enumerating each under
//! the cube's assumption literals.
//!
//! A cube holds the plans that begin with given fragments (the last one possibly still
//! open). Every plan lies in exactly one of the first cubes, one per block with nothing
//! below it: a model has exactly one start of fragment 0 (`used(0)` holds, and at most one
//! block takes index 0 as a start), and that block has nothing directly below it, since
//! gravity puts the block below in the same or an earlier fragment, so in fragment 0 after
//! its first block, and a weld path never moves down. A cube is split one step deeper, and
//! its parts partition it again:
//! - an open last fragment at block u: exactly one of the moves `e(u,w)` or `end(u)`
//!   holds (at most one move out of a block, and `end(u)` exactly when there is none);
//! - after a closed fragment i: either no fragment i+1 (`!used(i+1)`), or exactly one
//!   block v starts it (`sz(v,i+1)`; at most one start per index), and by the same
//!   gravity argument the block below v, if any, is in an earlier fragment.
//!
//! Which cubes hold the work is not known beforehand (on the samples a few first blocks
//! hold nearly all feasible plans), so cubes are split while the search runs: when a worker
//! finds the queue empty, a busy worker splits its cube one step deeper, keeps one part
//! and queues the others, each with the plans of it already found (the worker that takes
//! it blocks them in its own solver first). Since cubes differ in how their plans begin,
//! two workers never simulate or learn the same prefix.
//!
//! Output order: each cube's plans are sorted, and cubes are handed over in their order
//! (a path before its extensions, extensions by the next block). So the plans come out in
//! the lexicographic order of their fragments (block indices), whatever the split, the
//! number of threads or the solver's own order.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::sync::{mpsc, Condvar, Mutex};
use std::time::{Duration, Instant};

use waam_part::graph::WeldGraph;
use waam_part::Part;
use waam_thermal as thermal;

use super::encoding::Encoding;
use super::sat::Lit;
use super::search::Search;
use super::{new_search, timed_out, CandidateVerdict, Counts, Event, Options, PlanError};
use super::{Progress, Stats};

/// A plan as fragments of block indices.
type Fragments = Vec<Vec<usize>>;

/// The plans that begin with `fragments` (block indices): the last fragment may go on
/// unless `closed`, and more fragments may follow unless `complete`. The derived order
/// (fragments first, a prefix before its extensions) is the lexicographic order of the
/// plans the cubes hold.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct Cube {
    pub fragments: Vec<Vec<usize>>,
    pub closed: bool,
    pub complete: bool,
}

impl Cube {
    /// Whether the plan `plan` (fragments of block indices) lies in this cube.
    pub fn holds(&self, plan: &[Vec<usize>]) -> bool {
        let Some((last, done)) = self.fragments.split_last() else {
            return true;
        };
        let m = done.len();
        plan.len() > m
            && plan[..m] == *done
            && plan[m].starts_with(last)
            && (!self.closed || plan[m].len() == last.len())
            && (!self.complete || plan.len() == m + 1)
    }

    /// The cube split one step deeper, in order (at most `k` fragments). An open last
    /// fragment ends, or goes on to a successor of its last block; after a closed one the
    /// plan ends, or the next fragment starts at a block whose block below (if any) is
    /// welded already (gravity, as for the first block). Empty when nothing is left to
    /// split.
    pub fn parts(&self, graph: &WeldGraph, k: usize) -> Vec<Cube> {
        let (Some(last), false) = (self.fragments.last(), self.complete) else {
            return Vec::new();
        };
        let mut welded = vec![false; graph.len()];
        self.fragments
            .iter()
            .flatten()
            .for_each(|&b| welded[b] = true);
        if !self.closed {
            let end = *last.last().expect("fragments are not empty");
            let ends = Cube {
                closed: true,
                ..self.clone()
            };
            let mut next: Vec<usize> = graph.successors(end).iter().map(|&w| w as usize).collect();
            next.sort_unstable();
            let goes_on = next.into_iter().filter(|&w| !welded[w]).map(|w| {
                let mut fragments = self.fragments.clone();
                fragments.last_mut().expect("not empty").push(w);
                Cube {
                    fragments,
                    closed: false,
                    complete: false,
                }
            });
            return std::iter::once(ends).chain(goes_on).collect();
        }
        if self.fragments.len() >= k {
            return Vec::new(); // the plan ends here: nothing to split
        }
        let ends = Cube {
            complete: true,
            ..self.clone()
        };
        let starts = (0..graph.len())
            .filter(|&v| !welded[v] && graph.supports(v).iter().all(|&b| welded[b as usize]))
            .map(|v| {
                let mut fragments = self.fragments.clone();
                fragments.push(vec![v]);
                Cube {
                    fragments,
                    closed: false,
                    complete: false,
                }
            });
        std::iter::once(ends).chain(starts).collect()
    }

    /// The literals that hold exactly in the models of this cube's plans.
    fn assumptions(&self, enc: &Encoding) -> Vec<Lit> {
        let mut lits = enc.prefix_literals(&self.fragments, self.closed);
        if self.complete {
            lits.extend(enc.at_most_fragments(self.fragments.len()));
        }
        lits
    }
}

/// The first cubes of a part's plans, in order: one per block that can begin a plan
/// (nothing below it).
pub fn first_cubes(part: &Part, graph: &WeldGraph) -> Vec<Cube> {
    (0..part.len())
        .filter(|&v| graph.on_plate(v))
        .map(|v| Cube {
            fragments: vec![vec![v]],
            closed: false,
            complete: false,
        })
        .collect()
}

/// The worker threads a run uses: `opts.threads`, else the thermal model's default (the
/// available cores unless set); no more than `opts.max_memory_mb` allows, since each
/// worker holds a search of its own.
fn worker_count(part: &Part, k: usize, opts: &Options) -> usize {
    let wanted = match opts.threads {
        0 => thermal::default_threads(),
        n => n,
    };
    let per_worker = super::estimated_memory_mb(part.len(), k).max(1);
    let fit = usize::try_from(opts.max_memory_mb / per_worker).unwrap_or(usize::MAX);
    wanted.min(fit).max(1)
}

/// What is enumerated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Mode {
    /// Every valid plan, counted only (no thermal check).
    Valid,
    /// Every feasible plan, each handed to the sink.
    Feasible,
}

/// What a worker tells the calling thread.
enum Message {
    /// A candidate judged (`Mode::Feasible`), with the worker's statistics after it.
    Candidate {
        worker: usize,
        fragments: Fragments,
        verdict: CandidateVerdict,
        stats: Stats,
    },
    /// `new` more valid plans counted (`Mode::Valid`).
    Counted {
        worker: usize,
        new: u64,
        stats: Stats,
    },
    /// A cube was split into `parts` (sent before any part is queued).
    Split {
        cube: Cube,
        parts: Vec<Cube>,
    },
    /// A cube's plans (sorted; `Mode::Feasible` only) and how many; `finished` false when
    /// the run stopped inside it.
    Done {
        cube: Cube,
        plans: Vec<Fragments>,
        count: u64,
        finished: bool,
    },
    Failed(thermal::NotCooled),
    /// A worker's final statistics; `stopped`: a deadline or cancel cut its search.
    Exit {
        worker: usize,
        stats: Stats,
        stopped: bool,
    },
}

/// How often the calling thread looks at the run's deadline and cancel flag between
/// messages (the workers stop within this and one solver check of theirs).
const POLL: Duration = Duration::from_millis(50);

/// A plan count past which a valid-plan count keeps no more plans of a cube (and so no
/// longer splits it): the plans found are handed on with a split, and memory is finite.
const KEEP_AT_MOST: usize = 1 << 16;

/// A split goes on (up to [`SPLIT_DEPTH`] steps deep) until it has this many parts.
const SPLIT_INTO: usize = 4;
const SPLIT_DEPTH: usize = 4;
/// A busy worker splits its cube when nothing is queued and it has searched this long
/// since it took or last split it.
const PRESPLIT: Duration = Duration::from_millis(50);

/// Enumerates every plan of `mode` over the cubes of the part, on `opts.threads` workers.
/// Progress events and the sink run on the calling thread; plans reach the sink in cube
/// order. `Counts::plans` holds the count for `Mode::Valid`, `Counts::feasible` for
/// `Mode::Feasible`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn conquer(
    part: &Part,
    graph: &WeldGraph,
    k: usize,
    opts: &Options,
    started: Instant,
    mode: Mode,
    progress: Progress,
    sink: &mut dyn FnMut(&[Vec<usize>]) -> std::io::Result<()>,
) -> Result<Counts, PlanError> {
    let cubes = first_cubes(part, graph);
    let workers = worker_count(part, k, opts);
    // The workers' searches stop on this flag, raised here on the run's own cancel or
    // deadline, or when something failed.
    let stop = Arc::new(AtomicBool::new(false));
    let worker_opts = Options {
        cancel: Some(Arc::clone(&stop)),
        ..opts.clone()
    };
    let queue = Queue {
        state: Mutex::new(QueueState {
            tasks: cubes.iter().map(|c| (c.clone(), Task::default())).collect(),
            busy: 0,
        }),
        changed: Condvar::new(),
        hungry: AtomicUsize::new(0),
    };
    let mut collector = Collector {
        workers: vec![Stats::default(); workers],
        counted: 0,
        open: cubes.into_iter().collect(),
        waiting: BTreeMap::new(),
        total: 0,
        unfinished: false,
        stopped: false,
        failed: None,
    };
    let (tx, rx) = mpsc::channel();
    std::thread::scope(|scope| {
        for worker in 0..workers {
            let tx = tx.clone();
            let job = Job {
                part,
                graph,
                k,
                opts: &worker_opts,
                started,
                mode,
                queue: &queue,
                stop: &stop,
                tx,
                worker,
            };
            scope.spawn(move || job.run());
        }
        drop(tx);
        loop {
            match rx.recv_timeout(POLL) {
                Ok(message) => collector.take(message, progress, sink, &stop),
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
            if timed_out(opts, started) {
                stop.store(true, Ordering::Relaxed);
            }
        }
    });
    // What a stopped run found in cubes it did not finish, in cube order.
    let rest = std::mem::take(&mut collector.waiting);
    for plans in rest.into_values() {
        collector.hand_over(&plans, sink, &stop);
    }
    collector.finish(mode, started)
}

/// The cubes waiting for a worker, each with the plans of it already found.
struct Queue {
    state: Mutex<QueueState>,
    /// Signalled when a cube is queued or a worker goes idle.
    changed: Condvar,
    /// Workers waiting for a cube (read without the lock by busy workers).
    hungry: AtomicUsize,
}

/// What comes with a cube split off another worker's.
#[derive(Default)]
struct Task {
    /// Its plans found already.
    found: Vec<Fragments>,
    /// The thermal clauses the other worker learned in the cube it split: they hold for
    /// every plan, and many are about this part (the split cube's plans begin alike).
    clauses: Arc<Vec<Vec<Lit>>>,
}

struct QueueState {
    tasks: BTreeMap<Cube, Task>,
    /// Workers searching a cube (none, and no cube queued: the run is done).
    busy: usize,
}

impl Queue {
    /// The next cube to search (the first in order), or `None` when every cube is done or
    /// the run stops.
    fn take(&self, stop: &AtomicBool) -> Option<(Cube, Task)> {
        let mut state = self.state.lock().expect("queue lock");
        loop {
            if stop.load(Ordering::Relaxed) {
                return None;
            }
            if let Some(task) = state.tasks.pop_first() {
                state.busy += 1;
                return Some(task);
            }
            if state.busy == 0 {
                return None;
            }
            self.hungry.fetch_add(1, Ordering::Relaxed);
            // Timed, so that a stop is seen without a signal.
            state = self
                .changed
                .wait_timeout(state, POLL)
                .expect("queue lock")
                .0;
            self.hungry.fetch_sub(1, Ordering::Relaxed);
        }
    }

    /// Whether a busy worker should split its cube: none is queued, and a worker waits for
    /// one, or the busy one has not split since `since` (so that the next worker to finish
    /// finds a cube at once: a worker can split only between two of its candidates).
    fn starving(&self, since: Instant) -> bool {
        (self.hungry.load(Ordering::Relaxed) > 0 || since.elapsed() >= PRESPLIT)
            && self.state.lock().expect("queue lock").tasks.is_empty()
    }

    fn push(&self, tasks: impl IntoIterator<Item = (Cube, Task)>) {
        self.state.lock().expect("queue lock").tasks.extend(tasks);
        self.changed.notify_all();
    }
}

/// A worker searching a cube taken off the queue: dropped when it is done with it, even
/// by a panic (the other workers would wait for it forever otherwise).
struct Busy<'a>(&'a Queue);

impl Drop for Busy<'_> {
    fn drop(&mut self) {
        let mut state = self.0.state.lock().unwrap_or_else(|e| e.into_inner());
        state.busy -= 1;
        drop(state);
        self.0.changed.notify_all();
    }
}

/// One worker's share of a run.
struct Job<'a, 'p> {
    part: &'p Part,
    graph: &'p WeldGraph,
    k: usize,
    opts: &'a Options,
    started: Instant,
    mode: Mode,
    queue: &'a Queue,
    stop: &'a AtomicBool,
    tx: mpsc::Sender<Message>,
    worker: usize,
}

/// The cube a worker searches and what it found of it.
struct Current {
    cube: Cube,
    assume: Vec<Lit>,
    /// Plans of the cube found so far (every plan of a feasible enumeration; of a count,
    /// the first [`KEEP_AT_MOST`]).
    found: Vec<Fragments>,
    /// Plans counted but not kept (the cube can no longer be split).
    not_kept: u64,
    /// Plans counted since the last progress message (`Mode::Valid`).
    unreported: u64,
    /// The thermal clauses learned in the cube before its last split, handed on with its
    /// parts (the ones learned since are [`Search::take_learned`]'s).
    learned: Arc<Vec<Vec<Lit>>>,
    /// When the cube was taken or last split.
    split_at: Instant,
}

impl Job<'_, '_> {
    /// Searches cubes off the queue until none is left or the run stops. The search is
    /// built here: it is not `Send` (its prefix cache is shared by `Rc`).
    fn run(&self) {
        let budget = match self.mode {
            Mode::Valid => 0,
            Mode::Feasible => self.opts.lookahead_budget,
        };
        let Some(mut search) = new_search(
            self.part,
            self.graph,
            self.k,
            self.opts,
            budget,
            self.started,
        ) else {
            self.stop_all();
            self.exit(Stats::default(), true);
            return;
        };
        if self.mode == Mode::Feasible {
            search.judge_inside_keeping(true);
        }
        let mut stopped = false;
        let (mut cubes, mut idle) = (0usize, Duration::ZERO);
        loop {
            let asked = Instant::now();
            let Some((cube, Task { found, clauses })) = self.queue.take(self.stop) else {
                idle += asked.elapsed();
                break;
            };
            let _busy = Busy(self.queue);
            idle += asked.elapsed();
            cubes += 1;
            // Plans of the cube another worker found before it split the cube off, and
            // what it learned there.
            for plan in &found {
                search.block_plan(plan);
            }
            search.add_learned(&clauses);
            // Clauses are handed on from the cube they were learned in.
            search.take_learned();
            let assume = cube.assumptions(&search.enc);
            let mut current = Current {
                cube,
                assume,
                found,
                not_kept: 0,
                unreported: 0,
                learned: clauses,
                split_at: Instant::now(),
            };
            let cube_started = Instant::now();
            stopped = !self.search_cube(&mut search, &mut current);
            tracing::trace!(
                "worker {}: cube {:?} done in {:.3} s",
                self.worker,
                current.cube,
                cube_started.elapsed().as_secs_f64()
            );
            let count = current.found.len() as u64 + current.not_kept;
            let mut plans = match self.mode {
                Mode::Feasible => current.found,
                Mode::Valid => Vec::new(),
            };
            plans.sort_unstable();
            let _ = self.tx.send(Message::Done {
                cube: current.cube,
                plans,
                count,
                finished: !stopped,
            });
            if stopped {
                break;
            }
        }
        search.stats.total_s = self.started.elapsed().as_secs_f64();
        tracing::debug!(
            "worker {}: {cubes} cube(s), waited {:.3} s of {:.3} s",
            self.worker,
            idle.as_secs_f64(),
            search.stats.total_s
        );
        let stopped = stopped || search.interrupted;
        self.exit(search.stats, stopped);
    }

    /// Enumerates the plans of `current` (splitting it when another worker starves);
    /// false when the run stopped first.
    fn search_cube(&self, search: &mut Search<'_>, current: &mut Current) -> bool {
        loop {
            if timed_out(self.opts, self.started) {
                return false;
            }
            if self.queue.starving(current.split_at) {
                self.split(search, current);
                current.split_at = Instant::now();
            }
            let Some(candidate) = search.next_candidate(&current.assume) else {
                return !search.interrupted;
            };
            if self.mode == Mode::Valid {
                search.block_plan(&candidate);
                if current.found.len() < KEEP_AT_MOST && current.not_kept == 0 {
                    current.found.push(candidate);
                } else {
                    current.not_kept += 1;
                }
                current.unreported += 1;
                if current.unreported == 256 {
                    let _ = self.tx.send(Message::Counted {
                        worker: self.worker,
                        new: std::mem::take(&mut current.unreported),
                        stats: search.stats.clone(),
                    });
                }
                continue;
            }
            let verdict = match search.judge(&candidate) {
                Ok(Some(verdict)) => verdict,
                // The deadline or a cancel, inside the simulation.
                Ok(None) => return false,
                Err(e) => {
                    let _ = self.tx.send(Message::Failed(e));
                    self.stop_all();
                    return false;
                }
            };
            if let CandidateVerdict::Feasible = verdict {
                search
                    .stats
                    .first_feasible_s
                    .get_or_insert(self.started.elapsed().as_secs_f64());
                search.block_plan(&candidate);
                current.found.push(candidate.clone());
            }
            let _ = self.tx.send(Message::Candidate {
                worker: self.worker,
                fragments: candidate,
                verdict,
                stats: search.stats.clone(),
            });
        }
    }

    /// Splits the current cube: keeps the part that holds the latest plan found (where the
    /// solver is searching; without one, the last part), queues the others with their plans
    /// found. The kept part is split again while that leaves fewer than
    /// [`SPLIT_INTO`] parts: where plans go on through a narrow passage, one step gives
    /// away only parts that end at once. The worker's own solver keeps every plan found
    /// blocked, so it goes on where it was.
    fn split(&self, search: &mut Search<'_>, current: &mut Current) {
        if current.not_kept > 0 {
            return;
        }
        let latest = current.found.last().cloned();
        let kept_of = |parts: &[Cube]| {
            latest.as_ref().map_or(parts.len().saturating_sub(1), |p| {
                parts.iter().position(|c| c.holds(p)).unwrap_or(0)
            })
        };
        let mut parts = current.cube.parts(self.graph, self.k);
        for _ in 1..SPLIT_DEPTH {
            if parts.len() >= SPLIT_INTO || parts.is_empty() {
                break;
            }
            let keep = kept_of(&parts);
            let deeper = parts[keep].parts(self.graph, self.k);
            if deeper.is_empty() {
                break;
            }
            // The parts of a part lie where it lay in the order.
            parts.splice(keep..=keep, deeper);
        }
        if parts.is_empty() {
            return;
        }
        let mut found: Vec<Vec<Fragments>> = vec![Vec::new(); parts.len()];
        for plan in current.found.drain(..) {
            let at = parts
                .iter()
                .position(|c| c.holds(&plan))
                .expect("the parts of a cube partition its plans");
            found[at].push(plan);
        }
        let keep = kept_of(&parts);
        tracing::trace!("worker {}: split {:?}", self.worker, current.cube);
        let _ = self.tx.send(Message::Split {
            cube: current.cube.clone(),
            parts: parts.clone(),
        });
        let mut tasks: Vec<(Cube, Vec<Fragments>)> = parts.into_iter().zip(found).collect();
        let (cube, found) = tasks.remove(keep);
        let mut learned: Vec<Vec<Lit>> = current.learned.as_ref().clone();
        learned.extend(search.take_learned());
        current.learned = Arc::new(learned);
        let clauses = &current.learned;
        self.queue.push(tasks.into_iter().map(|(c, found)| {
            let clauses = Arc::clone(clauses);
            (c, Task { found, clauses })
        }));
        current.assume = cube.assumptions(&search.enc);
        current.cube = cube;
        current.found = found;
    }

    fn stop_all(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }

    fn exit(&self, stats: Stats, stopped: bool) {
        let _ = self.tx.send(Message::Exit {
            worker: self.worker,
            stats,
            stopped,
        });
    }
}

/// The calling thread's side: merged statistics and counts, and the cubes' plans held back
/// until every cube before them is done.
struct Collector {
    /// Each worker's latest statistics.
    workers: Vec<Stats>,
    /// Valid plans counted so far (`Mode::Valid` progress).
    counted: u64,
    /// Cubes queued or being searched.
    open: BTreeSet<Cube>,
    /// Cubes done whose plans wait for an open cube before them.
    waiting: BTreeMap<Cube, Vec<Fragments>>,
    /// Plans counted in the cubes done.
    total: u64,
    /// A cube reported done was cut short.
    unfinished: bool,
    stopped: bool,
    failed: Option<PlanError>,
}

impl Collector {
    fn merged(&self) -> Stats {
        let mut all = Stats::default();
        for s in &self.workers {
            all.absorb(s);
        }
        all
    }

    fn take(
        &mut self,
        message: Message,
        progress: Progress,
        sink: &mut dyn FnMut(&[Vec<usize>]) -> std::io::Result<()>,
        stop: &AtomicBool,
    ) {
        match message {
            Message::Candidate {
                worker,
                fragments,
                verdict,
                stats,
            } => {
                self.workers[worker] = stats;
                let stats = self.merged();
                progress(Event::Candidate {
                    fragments: &fragments,
                    verdict,
                    stats: &stats,
                });
            }
            Message::Counted { worker, new, stats } => {
                self.workers[worker] = stats;
                self.counted += new;
                let stats = self.merged();
                progress(Event::Counting {
                    plans: self.counted,
                    stats: &stats,
                });
            }
            Message::Split { cube, parts } => {
                self.open.remove(&cube);
                self.open.extend(parts);
            }
            Message::Done {
                cube,
                plans,
                count,
                finished,
            } => {
                self.total += count;
                self.unfinished |= !finished;
                self.open.remove(&cube);
                self.waiting.insert(cube, plans);
                // Hand over every cube done before the first open one.
                while let Some(entry) = self.waiting.first_entry() {
                    if self.open.first().is_some_and(|open| open < entry.key()) {
                        break;
                    }
                    let plans = entry.remove();
                    self.hand_over(&plans, sink, stop);
                }
            }
            Message::Failed(e) => {
                stop.store(true, Ordering::Relaxed);
                self.failed.get_or_insert(e.into());
            }
            Message::Exit {
                worker,
                stats,
                stopped,
            } => {
                self.workers[worker] = stats;
                self.stopped |= stopped;
            }
        }
    }

    /// Hands plans to the sink; a sink that fails stops the run (its error is returned).
    fn hand_over(
        &mut self,
        plans: &[Fragments],
        sink: &mut dyn FnMut(&[Vec<usize>]) -> std::io::Result<()>,
        stop: &AtomicBool,
    ) {
        for plan in plans {
            if self.failed.is_some() {
                return;
            }
            if let Err(e) = sink(plan) {
                stop.store(true, Ordering::Relaxed);
                self.failed = Some(e.into());
            }
        }
    }

    fn finish(self, mode: Mode, started: Instant) -> Result<Counts, PlanError> {
        let mut stats = self.merged();
        if let Some(e) = self.failed {
            return Err(e);
        }
        stats.total_s = started.elapsed().as_secs_f64();
        Ok(Counts {
            plans: (mode == Mode::Valid).then_some(self.total),
            feasible: if mode == Mode::Feasible {
                self.total
            } else {
                0
            },
            complete: !self.stopped && !self.unfinished && self.open.is_empty(),
            stats,
        })
    }
}
