//! Planning off the node's executor: one job at a time, the latest part wins.
//!
//! Each submitted input runs in its own thread with its own cancel flag. A newer submission
//! raises the flag of the job in progress and starts at once; the old job stops at its next
//! cancellation point, and whatever it still reports is tagged with its (stale) job id so the
//! node can drop it. Events come back on one channel, in the order they happen.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

/// A cancellation flag shared between the node and one planning job, and the planner's stop
/// flag: cancelling raises both; a job that has what it wants (the first feasible plan) raises
/// only the stop flag and still delivers its result.
#[derive(Debug, Clone, Default)]
pub struct Cancel {
    cancelled: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    /// A child's parent's cancel flag ([`Cancel::child`]).
    parent: Option<Arc<AtomicBool>>,
}

impl Cancel {
    pub fn new() -> Cancel {
        Cancel::default()
    }
    pub fn cancel(&self) {
        self.cancelled.store(true, Ordering::Relaxed);
        self.stop.store(true, Ordering::Relaxed);
    }
    pub fn is_cancelled(&self) -> bool {
        self.cancelled.load(Ordering::Relaxed)
            || self
                .parent
                .as_ref()
                .is_some_and(|p| p.load(Ordering::Relaxed))
    }
    /// A cancel of its own that this one's cancel raises too (one goal's: an arc fault
    /// cancels the goal, not the execution).
    pub fn child(&self) -> Cancel {
        Cancel {
            parent: Some(Arc::clone(&self.cancelled)),
            ..Cancel::default()
        }
    }
    /// Stops the planner (as its timeout does) without cancelling the job.
    pub fn stop_early(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }
    /// The stop flag, for planners that poll an `AtomicBool`.
    pub fn flag(&self) -> Arc<AtomicBool> {
        Arc::clone(&self.stop)
    }
    /// The cancel flag alone (not raised by [`Cancel::stop_early`]), for the stages after
    /// planning, which must finish a plan the planner stopped early on.
    pub fn cancelled_flag(&self) -> Arc<AtomicBool> {
        Arc::clone(&self.cancelled)
    }
}

/// The planner's counters at a progress report.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Counts {
    pub candidates: u64,
    pub feasible: u64,
    pub cuts: u64,
    /// Worst-case t8/5 margin of the best plan so far, s (`None`: none yet, or no windows).
    pub best_margin_s: Option<f64>,
}

/// How far a job has come: a stage name, a fraction of it when known, and a remark.
#[derive(Debug, Clone, PartialEq)]
pub struct Progress {
    pub stage: &'static str,
    pub fraction: Option<f64>,
    pub detail: String,
    /// While planning: the planner's counters.
    pub counts: Option<Counts>,
}

/// What a job hands to the pipeline: its cancel flag and a way to report progress.
pub struct JobContext {
    pub job: u64,
    pub cancel: Cancel,
    report: Box<dyn Fn(Progress) + Send + Sync>,
}

impl JobContext {
    /// A job's context: its id, its cancel flag and where its progress goes.
    pub fn new(
        job: u64,
        cancel: Cancel,
        report: impl Fn(Progress) + Send + Sync + 'static,
    ) -> Self {
        JobContext {
            job,
            cancel,
            report: Box::new(report),
        }
    }

    pub fn progress(&self, stage: &'static str, fraction: Option<f64>, detail: impl Into<String>) {
        self.report(Progress {
            stage,
            fraction,
            detail: detail.into(),
            counts: None,
        });
    }

    pub fn report(&self, progress: Progress) {
        (self.report)(progress);
    }
}

/// The planning work itself: input in, output or a reason out. Runs on a worker thread.
pub trait Pipeline: Send + Sync + 'static {
    type Input: Send + 'static;
    type Output: Send + 'static;
    type Error: std::error::Error + Send + 'static;
    fn run(&self, input: Self::Input, ctx: &JobContext) -> Result<Self::Output, Self::Error>;
}

/// Why a job ended without output.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum JobFailure<E> {
    #[error("cancelled: a newer part arrived")]
    Superseded,
    #[error("internal error: {0}")]
    Panicked(String),
    #[error(transparent)]
    Failed(E),
}

/// What the worker tells the node.
#[derive(Debug)]
pub enum WorkerEvent<T, E> {
    Progress {
        job: u64,
        progress: Progress,
    },
    /// A cancelled job finishes with `Err` too, and its id is no longer current.
    Finished {
        job: u64,
        result: Result<T, JobFailure<E>>,
    },
}

/// The events of a pipeline's worker.
pub type EventOf<P> = WorkerEvent<<P as Pipeline>::Output, <P as Pipeline>::Error>;

/// Runs one job at a time on its own thread; a newer job cancels the one in progress.
pub struct Worker<P: Pipeline> {
    pipeline: Arc<P>,
    events: Arc<dyn Fn(EventOf<P>) + Send + Sync>,
    next_id: u64,
    current: Option<(u64, Cancel)>,
    threads: Vec<JoinHandle<()>>,
}

impl<P: Pipeline> Worker<P> {
    /// A worker that hands every event to `events` (called from the job threads).
    pub fn new(pipeline: P, events: impl Fn(EventOf<P>) + Send + Sync + 'static) -> Worker<P> {
        Worker {
            pipeline: Arc::new(pipeline),
            events: Arc::new(events),
            next_id: 1,
            current: None,
            threads: Vec::new(),
        }
    }

    /// Starts a job for `input`; returns its id and the id of the job it cancelled, if any.
    pub fn submit(&mut self, input: P::Input) -> (u64, Option<u64>) {
        let superseded = self.current.take().map(|(id, cancel)| {
            cancel.cancel();
            id
        });
        let job = self.next_id;
        self.next_id += 1;
        let cancel = Cancel::new();
        self.current = Some((job, cancel.clone()));
        let pipeline = Arc::clone(&self.pipeline);
        let events = Arc::clone(&self.events);
        let progress_events = Arc::clone(&self.events);
        let ctx = JobContext {
            job,
            cancel,
            report: Box::new(move |progress| {
                progress_events(WorkerEvent::Progress { job, progress });
            }),
        };
        self.threads.retain(|t| !t.is_finished());
        let thread = std::thread::Builder::new()
            .name(format!("plan-{job}"))
            .spawn(move || {
                let result = match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    pipeline.run(input, &ctx)
                })) {
                    _ if ctx.cancel.is_cancelled() => Err(JobFailure::Superseded),
                    Ok(result) => result.map_err(JobFailure::Failed),
                    Err(panic) => Err(JobFailure::Panicked(panic_text(&panic))),
                };
                events(WorkerEvent::Finished { job, result });
            })
            .expect("cannot start a planning thread");
        self.threads.push(thread);
        (job, superseded)
    }

    /// Jobs from now on run `pipeline`; the job in progress keeps the one it started with.
    pub fn set_pipeline(&mut self, pipeline: P) {
        self.pipeline = Arc::new(pipeline);
    }

    /// The job in progress.
    pub fn current(&self) -> Option<u64> {
        self.current.as_ref().map(|(id, _)| *id)
    }

    /// Cancels the job in progress, if it is `job`; its result will be dropped.
    pub fn cancel(&mut self, job: u64) -> bool {
        if self.is_current(job) {
            if let Some((_, cancel)) = self.current.take() {
                cancel.cancel();
            }
            return true;
        }
        false
    }

    /// Whether `job` is the latest one (its results are wanted).
    pub fn is_current(&self, job: u64) -> bool {
        self.current.as_ref().is_some_and(|(id, _)| *id == job)
    }

    /// Marks `job` done once its result has been handled.
    pub fn finish(&mut self, job: u64) {
        if self.is_current(job) {
            self.current = None;
        }
    }

    /// Whether a job is running.
    pub fn busy(&self) -> bool {
        self.current.is_some()
    }

    /// Cancels the job in progress. Threads still running are left to end on their own (a
    /// planner deep in a solver call may take until its time limit), never waited for.
    pub fn shutdown(&mut self) {
        if let Some((_, cancel)) = self.current.take() {
            cancel.cancel();
        }
        self.threads.retain(|t| !t.is_finished());
    }
}

impl<P: Pipeline> Drop for Worker<P> {
    fn drop(&mut self) {
        self.shutdown();
    }
}

fn panic_text(panic: &Box<dyn std::any::Any + Send>) -> String {
    if let Some(s) = panic.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = panic.downcast_ref::<String>() {
        s.clone()
    } else {
        "a planning thread panicked".to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc::channel;
    use std::time::Duration;

    #[derive(Debug, PartialEq, thiserror::Error)]
    #[error("{0}")]
    struct Stop(&'static str);

    /// Counts to `n`, stopping when cancelled; "boom" panics, "bad" fails.
    struct Counter;
    impl Pipeline for Counter {
        type Input = (u32, &'static str);
        type Output = u32;
        type Error = Stop;
        fn run(&self, (n, mode): (u32, &'static str), ctx: &JobContext) -> Result<u32, Stop> {
            match mode {
                "boom" => panic!("boom"),
                "bad" => return Err(Stop("bad input")),
                _ => {}
            }
            for i in 0..n {
                if ctx.cancel.is_cancelled() {
                    return Err(Stop("stopped"));
                }
                ctx.progress("counting", Some(i as f64 / n as f64), "");
                std::thread::sleep(Duration::from_millis(1));
            }
            Ok(n)
        }
    }

    fn finished(
        rx: &std::sync::mpsc::Receiver<EventOf<Counter>>,
    ) -> Vec<(u64, Result<u32, JobFailure<Stop>>)> {
        let mut out = Vec::new();
        while let Ok(ev) = rx.recv_timeout(Duration::from_secs(20)) {
            if let WorkerEvent::Finished { job, result } = ev {
                out.push((job, result));
                if out.len() == 2 {
                    break;
                }
            }
        }
        out
    }

    #[test]
    fn latest_part_wins() {
        let (tx, rx) = channel();
        let mut worker = Worker::new(Counter, move |e| {
            let _ = tx.send(e);
        });
        let (first, none) = worker.submit((100_000, "count"));
        assert_eq!(none, None);
        // Wait until the first job is under way, then supersede it.
        loop {
            if let Ok(WorkerEvent::Progress { job, .. }) = rx.recv_timeout(Duration::from_secs(20))
            {
                assert_eq!(job, first);
                break;
            }
        }
        let (second, cancelled) = worker.submit((3, "count"));
        assert_eq!(cancelled, Some(first));
        assert!(worker.is_current(second) && !worker.is_current(first));
        let mut results = finished(&rx);
        results.sort_by_key(|r| r.0);
        assert_eq!(results[0].0, first);
        assert!(results[0]
            .1
            .as_ref()
            .unwrap_err()
            .to_string()
            .contains("cancelled"));
        assert_eq!(results[1], (second, Ok(3)));
        worker.finish(second);
        assert!(!worker.busy());
    }

    #[test]
    fn failures_and_panics_become_reasons() {
        let (tx, rx) = channel();
        let mut worker = Worker::new(Counter, move |e| {
            let _ = tx.send(e);
        });
        worker.submit((1, "boom"));
        let mut results = finished_one(&rx);
        assert!(results.pop().unwrap().contains("internal error: boom"));
        worker.submit((1, "bad"));
        assert_eq!(finished_one(&rx), vec!["bad input".to_string()]);
    }

    fn finished_one(rx: &std::sync::mpsc::Receiver<EventOf<Counter>>) -> Vec<String> {
        loop {
            match rx.recv_timeout(Duration::from_secs(20)).unwrap() {
                WorkerEvent::Finished { result, .. } => {
                    return vec![result.unwrap_err().to_string()]
                }
                WorkerEvent::Progress { .. } => {}
            }
        }
    }
}
