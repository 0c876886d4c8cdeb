//! The node's event loop: the one place that decides what is published. Each kind of event
//! has its handler; the loop itself only publishes the health and waits for the next event.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use ros2_client::action::{GoalId, GoalStatusEnum};

use super::pipeline::{self, PartInput};
use super::plan_action::{PlanPartFeedback, PlanPartResult};
use super::worker::{Progress, Worker, WorkerEvent};
use super::{
    execute_action, final_feedback, goal_result, health, io, plan_action, result_ok, Cell, Event,
    JobResult, Level, LoopState, PlanningPipeline,
};
use waam_messages::status::JobStatus;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};

/// Everything the loop keeps between events.
pub(super) struct EventLoop {
    pub state: LoopState,
    pub worker: Worker<PlanningPipeline>,
    pub health: health::Health,
    /// `~/plan` goals by job: goal id and when it was accepted.
    pub goals: HashMap<u64, (GoalId, Instant)>,
    pub cell: Cell,
    /// How meshes are voxelized now (recorded with every mesh received).
    pub mesh_settings: waam_pipeline::MeshSettings,
    pub torch_values: Vec<KeyValue>,
    pub action_replies: Option<std::sync::mpsc::Sender<plan_action::Reply>>,
    /// The sensors' good readings, in the part frame: drained into the closed loop.
    pub measured_rx: Receiver<waam_cell::Measured>,
    /// The part the sensors' scans are checked against (the latest plan's).
    pub scan_targets: super::sensors::ScanTargets,
    /// Publish the health at once (a sensor went bad or good again).
    pub health_due: bool,
    /// Planning one part: the loop ends when it is done.
    pub once: bool,
    pub stop: Arc<AtomicBool>,
}

impl EventLoop {
    /// Handles events until `stop` is raised, the event senders are gone, or (once) the part
    /// is done; publishes the health every [`health::PERIOD`].
    pub fn run(&mut self, events: &Receiver<Event>, diagnostics: &io::Output<DiagnosticArray>) {
        let mut last_health: Option<Instant> = None;
        while !self.stop.load(Ordering::Relaxed) {
            if self.health_due || last_health.is_none_or(|t| t.elapsed() >= health::PERIOD) {
                last_health = Some(Instant::now());
                self.health_due = false;
                let executing = self.state.execution.as_ref().map(|e| e.started);
                for (level, line) in self.health.cadence(executing, Instant::now()) {
                    self.log_sensor(level, &line);
                }
                // Not recorded: a recording has the events on ~/status.
                diagnostics.publish(&self.health.to_msg(Time::now()), None);
            }
            // To the execution's closed loop (dropped when none runs: memory cannot grow).
            for reading in self.measured_rx.try_iter() {
                self.state.measured(reading);
            }
            let event = match events.recv_timeout(Duration::from_millis(100)) {
                Ok(event) => event,
                Err(RecvTimeoutError::Timeout) => continue,
                Err(RecvTimeoutError::Disconnected) => break,
            };
            if self.handle(event) {
                break;
            }
        }
    }

    /// Handles one event; `true` when the node is done (planning once).
    fn handle(&mut self, event: Event) -> bool {
        match event {
            Event::Pipeline(pipeline) => self.on_parameters(*pipeline),
            Event::Stop(answer) => {
                let _ = answer.send(self.on_stop());
            }
            Event::Sensor(news) => self.on_sensor(news),
            Event::Execute(execute_action::Request::Goal { goal, job }) => {
                self.on_execute_goal(goal, job)
            }
            Event::Execute(execute_action::Request::Cancel(goal)) => self.on_execute_cancel(goal),
            Event::Executed {
                serial,
                job,
                goal,
                cancelled,
                result,
            } => self.on_executed(serial, job, goal, cancelled, result),
            Event::Action(plan_action::Request::Cancel(goal)) => self.on_plan_cancel(goal),
            Event::Action(plan_action::Request::Goal { goal, job }) => {
                self.on_part(job, Some(goal))
            }
            Event::Input(input) => self.on_part(pipeline::Job::from(input), None),
            Event::Worker(WorkerEvent::Progress { job, progress }) => {
                self.on_progress(job, progress)
            }
            Event::Worker(WorkerEvent::Finished { job, result }) => {
                return self.on_finished(job, result)
            }
        }
        false
    }

    fn reply(&self, r: plan_action::Reply) {
        if let Some(tx) = &self.action_replies {
            plan_action::send(tx, r);
        }
    }

    /// Ends `~/plan` goal `goal` without a plan.
    fn end_goal(&self, goal: GoalId, status: GoalStatusEnum, reason: &str) {
        self.reply(plan_action::Reply::Done(
            goal,
            status,
            PlanPartResult::failed(PlanPartResult::CANCELLED, reason),
        ));
    }

    fn on_parameters(&mut self, pipeline: PlanningPipeline) {
        self.mesh_settings = pipeline.mesh.clone();
        self.cell.publish_again(&pipeline);
        self.state.replan_in(&pipeline);
        self.worker.set_pipeline(pipeline);
        self.state
            .outputs
            .log(Level::Info, "parameters changed: the next plan uses them");
    }

    /// A sensor's verdict: into the health; a sensor going bad (or good again) goes out on
    /// `/diagnostics` at once and into the log.
    fn on_sensor(&mut self, news: super::sensors::SensorNews) {
        if let Some((level, line)) = self.health.sensor(news) {
            self.health_due = true;
            self.log_sensor(level, &line);
        }
    }

    /// A sensor's change of health into the log: INFO when OK again, else WARN.
    fn log_sensor(&self, level: u8, line: &str) {
        let level = if level == DiagnosticStatus::OK {
            Level::Info
        } else {
            Level::Warn
        };
        self.state.outputs.log(level, line);
    }

    /// `~/stop`: stops planning and execution; returns what was stopped.
    fn on_stop(&mut self) -> String {
        let mut stopped = Vec::new();
        if let Some(job) = self.worker.current() {
            self.worker.cancel(job);
            self.health.planning = None;
            if let Some((goal, _)) = self.goals.remove(&job) {
                self.end_goal(goal, GoalStatusEnum::Canceled, "stopped by ~/stop");
            }
            self.state.status(JobStatus::Error {
                job: Some(job),
                reason: "stopped by ~/stop".into(),
            });
            stopped.push(format!("planning of part {job}"));
        }
        if let Some(execution) = self.state.execution.take() {
            // The executor cancels its goal and switches the arc off; an ~/execute goal
            // ends cancelled when it has.
            execution.cancel.cancel();
            stopped.push(format!(
                "the execution of part {} (goal cancelled, arc off)",
                execution.job
            ));
        }
        let message = if stopped.is_empty() {
            "nothing to stop".to_string()
        } else {
            format!("stopped {}", stopped.join(" and "))
        };
        self.state
            .outputs
            .log(Level::Warn, &format!("~/stop: {message}"));
        message
    }

    fn on_execute_goal(&mut self, goal: GoalId, job: u64) {
        if let Err(refused) = self.state.execute_goal(goal, job) {
            self.state
                .outputs
                .log(Level::Warn, &format!("~/execute: {}", refused.message));
            if let Some(tx) = &self.state.execute_replies {
                let _ = tx.send(execute_action::Reply::Done(
                    goal,
                    GoalStatusEnum::Aborted,
                    refused,
                ));
            }
        }
    }

    fn on_execute_cancel(&mut self, goal: GoalId) {
        if let Some(execution) = &self.state.execution {
            if execution.goal == Some(goal) {
                execution.cancel.cancel();
                self.state.outputs.log(
                    Level::Info,
                    &format!(
                        "part {}: execution cancelled by its ~/execute goal",
                        execution.job
                    ),
                );
            }
        }
    }

    fn on_executed(
        &mut self,
        serial: u64,
        job: u64,
        goal: Option<GoalId>,
        cancelled: bool,
        result: Result<(), super::controller::ExecError>,
    ) {
        if self
            .state
            .execution
            .as_ref()
            .is_some_and(|e| e.serial == serial)
        {
            self.state.execution = None;
        }
        let (Some(goal), Some(tx)) = (goal, &self.state.execute_replies) else {
            return;
        };
        use execute_action::ExecutePlanResult as R;
        use GoalStatusEnum as S;
        let (status, end) = match result {
            Ok(()) => (
                S::Succeeded,
                R::new(R::EXECUTED, job, format!("part {job}: executed")),
            ),
            Err(e) if cancelled => (
                S::Canceled,
                R::new(R::CANCELLED, job, format!("part {job}: {e}")),
            ),
            Err(e) => (
                S::Aborted,
                R::new(R::FAILED, job, format!("part {job}: {e}")),
            ),
        };
        let _ = tx.send(execute_action::Reply::Done(goal, status, end));
    }

    /// A `~/plan` client cancels its goal.
    fn on_plan_cancel(&mut self, goal: GoalId) {
        let Some(job) = self
            .goals
            .iter()
            .find(|(_, g)| g.0 == goal)
            .map(|(j, _)| *j)
        else {
            return;
        };
        self.goals.remove(&job);
        if self.worker.cancel(job) {
            self.health.planning = None;
            self.state.status(JobStatus::Error {
                job: Some(job),
                reason: "cancelled by the ~/plan client".into(),
            });
            self.state
                .outputs
                .log(Level::Info, &format!("part {job}: goal cancelled"));
        }
        self.end_goal(goal, GoalStatusEnum::Canceled, "cancelled by the client");
    }

    /// A part from a topic or a `~/plan` goal: planned from now on, superseding the one
    /// being planned.
    fn on_part(&mut self, job_input: pipeline::Job, goal: Option<GoalId>) {
        let source = job_input.input.describe();
        let settings = self.received_settings(&job_input);
        // The input (recorded as it arrived, by the input thread or `plan_once`) is on disk
        // before its planning starts: a crash while planning never loses it.
        if let Some(r) = &self.state.outputs.recorder {
            if let Err(e) = r.sync() {
                tracing::warn!("syncing the recording: {e}");
            }
        }
        let (job, cancelled) = self.worker.submit(job_input);
        if let Some((old, _)) = cancelled.and_then(|old| self.goals.remove(&old)) {
            self.end_goal(
                old,
                GoalStatusEnum::Aborted,
                &format!("superseded by part {job}"),
            );
        }
        if let Some(goal) = goal {
            self.goals.insert(job, (goal, Instant::now()));
        }
        self.health.planning = Some(job);
        self.state.status(JobStatus::Received {
            job,
            source: source.clone(),
            cancelled,
            settings,
        });
        let mut line = format!("part {job} received ({source})");
        if let Some(old) = cancelled {
            line.push_str(&format!(
                "; it supersedes part {old}, whose planning is cancelled"
            ));
        }
        self.state.outputs.log(Level::Info, &line);
    }

    /// How a part will be planned, for its "received" status: the mesh settings of a mesh,
    /// and the planner's settings, so that `waam replay` plans the same way (a recording
    /// without them is taken to predate the planner's warm start).
    fn received_settings(&self, job: &pipeline::Job) -> Vec<KeyValue> {
        let mut settings = match &job.input {
            PartInput::Mesh { name, .. } => waam_messages::planning::mesh_values(
                job.mesh.as_ref().unwrap_or(&self.mesh_settings),
                name,
            ),
            PartInput::Document(_) => Vec::new(),
        };
        settings.extend(waam_messages::planning::settings(&waam_planner::Options {
            max_fragments: job.max_fragments,
            ..waam_planner::Options::default()
        }));
        settings.extend(self.torch_values.iter().cloned());
        settings
    }

    fn on_progress(&mut self, job: u64, progress: Progress) {
        if !self.worker.is_current(job) {
            return;
        }
        if let Some((goal, since)) = self.goals.get(&job) {
            let counts = progress.counts.unwrap_or_default();
            self.reply(plan_action::Reply::Feedback(
                *goal,
                PlanPartFeedback {
                    stage: progress.stage.to_string(),
                    candidates: counts.candidates,
                    feasible: counts.feasible,
                    cuts: counts.cuts,
                    best_margin_s: counts.best_margin_s.unwrap_or(f64::NAN),
                    elapsed_s: since.elapsed().as_secs_f64(),
                },
            ));
        }
        self.state.progress(job, progress);
    }

    /// A job ended: its goal, the health and the outputs learn how. `true` when the node
    /// is done (planning once, and the execution, if any, ended).
    fn on_finished(&mut self, job: u64, result: JobResult) -> bool {
        if !self.worker.is_current(job) {
            tracing::debug!("part {job}: stale result dropped");
            return false;
        }
        self.worker.finish(job);
        self.health.planning = None;
        if let Some((goal, since)) = self.goals.remove(&job) {
            let (status, end) = goal_result(job, &result);
            if let Ok(p) = result_ok(&result) {
                self.reply(plan_action::Reply::Feedback(goal, final_feedback(p, since)));
            }
            self.reply(plan_action::Reply::Done(goal, status, end));
        }
        match &result {
            Ok(p) => {
                self.health.planned += 1;
                self.scan_targets.measure(p);
                let summary = format!(
                    "planned {} ({} blocks, {} fragment(s))",
                    p.part.name,
                    p.part.len(),
                    p.found.fragments.len()
                );
                self.health.last = Some((job, health::Outcome::Planned(summary)));
            }
            Err(e) => {
                self.health.failed += 1;
                self.health.last = Some((job, health::Outcome::NoPlan(e.to_string())));
            }
        }
        let done = self.state.finished(job, result);
        if !self.once {
            return false;
        }
        if let Some(done) = done {
            // Wait for the execution to end (or the user to stop us).
            loop {
                match done.recv_timeout(Duration::from_millis(100)) {
                    Ok(result) => {
                        self.state.success &= result.is_ok();
                        break;
                    }
                    Err(RecvTimeoutError::Timeout) if !self.stop.load(Ordering::Relaxed) => {}
                    _ => {
                        self.state.success = false;
                        break;
                    }
                }
            }
        }
        true
    }

    /// Stops an execution in progress (the arc goes off) and the planning before the
    /// recording closes.
    pub fn shut_down(&mut self, executor_thread: Option<std::thread::JoinHandle<()>>) {
        if let Some(execution) = self.state.execution.take() {
            execution.cancel.cancel();
        }
        drop(self.state.executor.take());
        if let Some(thread) = executor_thread {
            let _ = thread.join();
        }
        self.worker.shutdown();
    }
}
