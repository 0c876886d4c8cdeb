//! Running a planned trajectory: the execution thread, and the simulated controller of a
//! dry run that follows goals in (scaled) real time and publishes `/joint_states`.

use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::arc_fault::ArcFaults;
use super::closed_loop::{FeedSchedule, Outcome, Replan, ReplanSetup, Replanner};
use super::execute::{oversized_welds, plan_steps, Step};
use super::execute_action::ExecutePlanFeedback;
use super::io::{Level, Outputs};
use super::pipeline::Planned;
use super::worker::Cancel;
use waam_cell::Measured;
use waam_messages::convert::goal_msg;
use waam_messages::status::JobStatus;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::DiagnosticStatus;
use waam_rosmsg::sensor_msgs::JointState;
use waam_rosmsg::std_msgs::{Bool, Float64, Header};
use waam_rosmsg::trajectory_msgs::JointTrajectory as TrajectoryMsg;

/// Why an execution stopped: the controller's answer, a timeout, or a cancel.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct ExecError(pub String);

impl From<String> for ExecError {
    fn from(message: String) -> Self {
        ExecError(message)
    }
}

impl From<&str> for ExecError {
    fn from(message: &str) -> Self {
        ExecError(message.to_string())
    }
}

/// Something that moves the robot through one goal at a time.
pub trait Controller: Send {
    /// Runs one goal to its end; `Err` with the reason when it fails or is cancelled.
    /// Calls `during` with the time on its clock ([`Controller::now_s`]) now and then while
    /// the goal runs (the closed loop's readings while the arc is on).
    fn execute(
        &mut self,
        goal: TrajectoryMsg,
        cancel: &Cancel,
        during: &mut dyn FnMut(f64),
    ) -> Result<(), ExecError>;
    /// Called once before a plan's first goal (a controller's trajectory mode).
    fn prepare(&mut self, _cancel: &Cancel) -> Result<(), ExecError> {
        Ok(())
    }
    /// Called while no goal runs, about every `idle_period()`.
    fn idle(&mut self) {}
    fn idle_period(&self) -> Duration {
        Duration::from_millis(200)
    }
    /// The clock the robot moves on, s: what sensor stamps are matched against (the ROS
    /// clock; a simulated cell may keep its own).
    fn now_s(&self) -> f64 {
        Time::now().to_nanos() as f64 * 1e-9
    }
    /// How many times as fast as the trajectory's time the robot moves (a dry run's
    /// `dry_run.time_scale`).
    fn time_scale(&self) -> f64 {
        1.0
    }
}

/// Called as each goal chunk starts (the `~/execute` feedback).
pub type OnChunk = Box<dyn Fn(ExecutePlanFeedback) + Send>;

/// Where an execution's news goes: the node's outputs (a test's record).
pub trait ExecOutputs {
    /// `~/arc_on`.
    fn arc(&self, on: bool);
    /// `~/wire_feed` (closed loop): the wire feed the next weld path strikes at, relative
    /// to nominal.
    fn wire_feed(&self, relative: f64);
    /// `~/wire_feed_schedule` (closed loop): the next weld path's feed per deposit.
    fn wire_feed_schedule(&self, schedule: &FeedSchedule);
    /// `~/status`.
    fn status(&self, status: JobStatus);
    fn log(&self, level: Level, message: &str);
    /// A re-plan's plan on the plan topics.
    fn plan(&self, planned: &Planned);
}

impl ExecOutputs for Outputs {
    fn arc(&self, on: bool) {
        self.arc_on
            .publish(&Bool { data: on }, self.recorder.as_ref());
    }
    fn wire_feed(&self, relative: f64) {
        self.wire_feed
            .publish(&Float64 { data: relative }, self.recorder.as_ref());
    }
    fn wire_feed_schedule(&self, schedule: &FeedSchedule) {
        let msg = waam_messages::wire_feed::schedule_msg(&schedule.starts_s, &schedule.feeds);
        self.wire_feed_schedule
            .publish(&msg, self.recorder.as_ref());
    }
    fn status(&self, status: JobStatus) {
        self.publish_status(&status);
    }
    fn log(&self, level: Level, message: &str) {
        Outputs::log(self, level, message);
    }
    fn plan(&self, planned: &Planned) {
        super::publish_plan(self, planned);
    }
}

/// The closed loop of one execution: how it re-plans, where the sensors' readings come
/// from (drained at each weld-path boundary) and the welder's arc faults (which stop a weld
/// goal at once).
pub struct ClosedLoopRun<'a> {
    pub setup: ReplanSetup,
    pub readings: &'a Receiver<Measured>,
    pub faults: ArcFaults,
}

/// Runs a planned trajectory on `controller`: goals with the arc switched on `~/arc_on`
/// between them, cut only where the arc is off ([`plan_steps`]). Stops at the first failed
/// goal or when cancelled, always leaving the arc off. With a closed loop, each weld-path
/// boundary may hand over to a re-planned remainder ([`closed_loop`](super::closed_loop)).
#[allow(clippy::too_many_arguments)] // one execution's whole setting, passed once
pub fn run_plan(
    job: u64,
    planned: &Planned,
    controller: &mut dyn Controller,
    outputs: &dyn ExecOutputs,
    max_points: usize,
    lead_in_s: f64,
    cancel: &Cancel,
    on_chunk: Option<&OnChunk>,
    closed_loop: Option<ClosedLoopRun>,
) -> Result<(), ExecError> {
    let mut current = std::borrow::Cow::Borrowed(planned);
    let arc: Vec<bool> = planned.trajectory.points.iter().map(|p| p.arc_on).collect();
    let mut steps = plan_steps(&arc, max_points);
    let count_goals = |steps: &[Step]| {
        steps
            .iter()
            .filter(|s| matches!(s, Step::Goal { .. }))
            .count()
    };
    let mut goals = count_goals(&steps);
    for (fragment, n) in oversized_welds(&steps, max_points) {
        outputs.log(
            Level::Warn,
            &format!(
                "part {job}: weld path {} has {n} points, more than execution.max_points_per_goal \
                 ({max_points}); it goes as one goal, since a goal boundary would stop the robot \
                 with the arc on",
                fragment + 1
            ),
        );
    }
    let report = |message: String, level: u8| {
        outputs.status(JobStatus::Executing {
            job,
            message,
            level,
        });
    };
    outputs.log(
        Level::Info,
        &format!(
            "executing part {job}: {} fragment(s) in {goals} goal(s): each weld whole, arc-off moves in goals of at most {max_points} points",
            planned.found.fragments.len()
        ),
    );
    // Drain what came before this execution: readings of another part.
    if let Some(run) = &closed_loop {
        run.readings.try_iter().for_each(drop);
    }
    let mut replanner = closed_loop.as_ref().and_then(|run| {
        let mut setup = run.setup.clone();
        // ~/stop and a cancelled goal stop a re-plan too.
        setup.planner.cancel = Some(cancel.cancelled_flag());
        setup.time_scale = controller.time_scale();
        Replanner::new(planned, setup)
            .map_err(|e| {
                outputs.log(
                    Level::Warn,
                    &format!("part {job}: closed loop off for this execution: {e}"),
                )
            })
            .ok()
    });
    let mut arc_is_on = false;
    let mut sent = 0;
    // The last weld goal: its fragment, last point and start on the controller's clock.
    let mut last_weld: Option<(usize, usize, f64)> = None;
    let result = (|| {
        controller
            .prepare(cancel)
            .map_err(|e| format!("before the first goal: {e}"))?;
        let mut i = 0;
        while i < steps.len() {
            if cancel.is_cancelled() {
                return Err(ExecError("cancelled".to_string()));
            }
            let step = steps[i].clone();
            i += 1;
            match step {
                Step::Arc(on) => {
                    // The wire feeds go out before the arc strikes: the schedule, and the
                    // feed to strike at.
                    let next_weld = steps[i..]
                        .iter()
                        .find_map(|s| match s {
                            Step::Goal { welding, .. } => Some(*welding),
                            Step::Arc(_) => None,
                        })
                        .flatten();
                    if let (true, Some(cl), Some(f)) = (on, replanner.as_mut(), next_weld) {
                        if let Some(schedule) = cl.wire_feeds(&current, f) {
                            outputs.wire_feed_schedule(&schedule);
                            outputs.wire_feed(schedule.feeds[0]);
                            let (lo, hi) = schedule
                                .feeds
                                .iter()
                                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                                    (lo.min(v), hi.max(v))
                                });
                            outputs.log(
                                Level::Info,
                                &format!(
                                    "part {job}: weld path {} (from layer {}) at wire feed {lo:.3}..{hi:.3} x nominal over {} deposits",
                                    f + 1,
                                    schedule.layer,
                                    schedule.feeds.len()
                                ),
                            );
                        }
                    }
                    outputs.arc(on);
                    arc_is_on = on;
                    let (Some(cl), Some(run), false, Some((f, standing, started))) =
                        (replanner.as_mut(), &closed_loop, on, last_weld)
                    else {
                        continue;
                    };
                    // A weld-path boundary: the arc is out, the robot at rest.
                    let replan = cl
                        .welded(&current, f, started, controller.time_scale())
                        .and_then(|()| {
                            cl.at_boundary(
                                &current,
                                run.readings.try_iter(),
                                standing,
                                max_points,
                                controller.now_s(),
                            )
                        });
                    let replan = match replan {
                        Ok(Some(replan)) => replan,
                        Ok(None) => {
                            if let Some(status) = cl.finished(job) {
                                outputs.status(status);
                            }
                            continue;
                        }
                        Err(e) => {
                            // The execution goes on with its plan.
                            outputs.log(
                                Level::Warn,
                                &format!("part {job}: closed loop off from here: {e}"),
                            );
                            replanner = None;
                            continue;
                        }
                    };
                    if let Outcome::New(new, rest) = publish_replan(job, outputs, replan) {
                        current = std::borrow::Cow::Owned(*new);
                        goals = sent + count_goals(&rest);
                        steps = rest;
                        i = 0;
                    }
                }
                Step::Goal { span, welding } => {
                    sent += 1;
                    let points = &current.trajectory.points;
                    if let Some(on_chunk) = on_chunk {
                        let (t0, duration) = match (points.first(), points.last()) {
                            (Some(a), Some(b)) => {
                                (a.time_from_start, b.time_from_start - a.time_from_start)
                            }
                            _ => (0.0, 0.0),
                        };
                        let start = span.start().saturating_sub(1);
                        on_chunk(ExecutePlanFeedback {
                            job,
                            chunk: sent as u32,
                            chunks: goals as u32,
                            arc_on: welding.is_some(),
                            weld_path: welding.map_or(0, |f| f as u32 + 1),
                            first_point: *span.start() as u32,
                            last_point: *span.end() as u32,
                            progress: if duration > 0.0 {
                                ((points[start].time_from_start - t0) / duration).clamp(0.0, 1.0)
                            } else {
                                0.0
                            },
                        });
                    }
                    let goal = goal_msg(&current.trajectory, span.clone(), lead_in_s);
                    let what = match welding {
                        Some(f) => format!("welding fragment {}", f + 1),
                        None => "moving (arc off)".to_string(),
                    };
                    report(
                        format!(
                            "part {job}: goal {sent}/{goals}, {what}, {} points",
                            goal.points.len()
                        ),
                        DiagnosticStatus::OK,
                    );
                    // With the closed loop, the welder's arc fault stops a weld goal (even
                    // when an error turned the loop off: then the execution stops).
                    let faults = match (welding, &closed_loop) {
                        (Some(_), Some(run)) => Some(&run.faults),
                        _ => None,
                    };
                    let goal_cancel = cancel.child();
                    if let Some(faults) = faults {
                        faults.arm(&goal_cancel);
                    }
                    let started = controller.now_s();
                    let time_scale = controller.time_scale();
                    // With the arc on, the readings go to the loop as they come: a scan of
                    // a layer the path has finished revises the feeds still to come.
                    let mut during = |now_s: f64| {
                        let (Some(f), Some(run), Some(cl)) =
                            (welding, &closed_loop, replanner.as_mut())
                        else {
                            return;
                        };
                        let readings = run.readings.try_iter();
                        match cl.during_weld(&current, f, started, time_scale, now_s, readings) {
                            Ok(Some(revised)) => {
                                outputs.wire_feed_schedule(&revised);
                                outputs.log(
                                    Level::Info,
                                    &format!(
                                        "part {job}: weld path {}, arc on: a scan revised the wire feeds of its last {} deposits (from layer {})",
                                        f + 1,
                                        revised.feeds.len(),
                                        revised.layer
                                    ),
                                );
                            }
                            Ok(None) => {}
                            Err(e) => {
                                outputs.log(
                                    Level::Warn,
                                    &format!("part {job}: closed loop off from here: {e}"),
                                );
                                replanner = None;
                            }
                        }
                    };
                    let done = controller.execute(goal, &goal_cancel, &mut during);
                    let fault = faults.and_then(ArcFaults::disarm);
                    if let (Some(_), Some(f), None, false) =
                        (fault, welding, &replanner, cancel.is_cancelled())
                    {
                        return Err(ExecError(format!(
                            "weld path {} cut short by an arc fault; the closed loop is off \
                             (an earlier error): execution stopped, the part is not finished",
                            f + 1
                        )));
                    }
                    let (Some(fault_s), Some(f), Some(cl), Some(run), false) = (
                        fault,
                        welding,
                        replanner.as_mut(),
                        &closed_loop,
                        cancel.is_cancelled(),
                    ) else {
                        done.map_err(|e| format!("goal {sent}/{goals} ({what}) failed: {e}"))?;
                        if let Some(f) = welding {
                            last_weld = Some((f, *span.end(), started));
                        }
                        continue;
                    };
                    // An arc fault: the arc is out, the robot stopped (the goal cancelled).
                    outputs.arc(false);
                    arc_is_on = false;
                    let cut = cl
                        .cut_short(&current, f, started, controller.time_scale(), fault_s)
                        .map_err(|e| {
                            format!("weld path {} cut short by an arc fault: {e}", f + 1)
                        })?;
                    let Some(cut) = cut else {
                        // Every deposit was welded: the path ended as planned (an ordinary
                        // boundary at the arc-off step that follows).
                        outputs.log(
                            Level::Warn,
                            &format!(
                                "part {job}: arc fault at the end of weld path {}: every deposit welded",
                                f + 1
                            ),
                        );
                        last_weld = Some((f, *span.end(), started));
                        continue;
                    };
                    let stopped = |why: String| {
                        ExecError(format!(
                            "weld path {} cut short by an arc fault after {} of {} deposits; {why}: \
                             execution stopped, the part is not finished",
                            f + 1,
                            cut.deposits,
                            cut.of
                        ))
                    };
                    if cut.deposits == 0 {
                        return Err(stopped("nothing of it welded".into()));
                    }
                    let replan = cl
                        .at_boundary(
                            &current,
                            run.readings.try_iter(),
                            *span.end(),
                            max_points,
                            controller.now_s(),
                        )
                        .map_err(|e| stopped(format!("the closed loop failed: {e}")))?
                        .ok_or_else(|| stopped("nothing was left to re-plan".into()))?;
                    match publish_replan(job, outputs, replan) {
                        Outcome::New(new, rest) => {
                            current = std::borrow::Cow::Owned(*new);
                            goals = sent + count_goals(&rest);
                            steps = rest;
                            i = 0;
                        }
                        Outcome::Kept(why) => {
                            return Err(stopped(format!("the rest was not re-planned: {why}")))
                        }
                        Outcome::Unchanged => {
                            return Err(stopped("the rest was not re-planned".into()))
                        }
                    }
                }
            }
        }
        Ok(())
    })();
    if arc_is_on {
        outputs.arc(false);
    }
    match &result {
        Ok(()) => {
            report(format!("part {job}: executed"), DiagnosticStatus::OK);
            outputs.log(Level::Info, &format!("part {job}: execution finished"));
        }
        Err(e) => {
            report(
                format!("part {job}: execution stopped: {e}"),
                DiagnosticStatus::ERROR,
            );
            outputs.log(Level::Error, &format!("part {job}: execution stopped: {e}"));
        }
    }
    result
}

/// A boundary's status, logged and published; a new plan published on the plan topics.
/// Returns what the execution does next.
fn publish_replan(job: u64, outputs: &dyn ExecOutputs, replan: Replan) -> Outcome {
    let status = replan.status(job);
    if let JobStatus::Replanned { message, .. } = &status {
        outputs.log(Level::Info, message);
    }
    outputs.status(status);
    if let Outcome::New(new, _) = &replan.outcome {
        outputs.plan(new);
    }
    replan.outcome
}

/// Work for the execution thread.
pub enum ExecCommand {
    Run {
        job: u64,
        planned: Arc<Planned>,
        cancel: Cancel,
        /// Told as each goal chunk starts (`~/execute` feedback).
        on_chunk: Option<OnChunk>,
        /// Told when the run ends (`waam publish`, `~/execute`).
        done: Box<dyn FnOnce(Result<(), ExecError>) + Send>,
        /// Closed loop (`closed_loop.enabled`): how to re-plan at weld-path boundaries.
        closed_loop: Option<ReplanSetup>,
    },
}

/// Starts the execution thread: runs plans one at a time, idles the controller in between.
pub fn spawn_executor(
    mut controller: Box<dyn Controller>,
    outputs: Arc<Outputs>,
    max_points: usize,
    lead_in_s: f64,
    commands: Receiver<ExecCommand>,
    readings: Receiver<Measured>,
    faults: ArcFaults,
) -> std::thread::JoinHandle<()> {
    std::thread::Builder::new()
        .name("execute".into())
        .spawn(move || loop {
            match commands.recv_timeout(controller.idle_period()) {
                Ok(ExecCommand::Run {
                    job,
                    planned,
                    cancel,
                    on_chunk,
                    done,
                    closed_loop,
                }) => {
                    let closed_loop = closed_loop.map(|setup| ClosedLoopRun {
                        setup,
                        readings: &readings,
                        faults: faults.clone(),
                    });
                    let result = run_plan(
                        job,
                        &planned,
                        controller.as_mut(),
                        outputs.as_ref(),
                        max_points,
                        lead_in_s,
                        &cancel,
                        on_chunk.as_ref(),
                        closed_loop,
                    );
                    done(result);
                }
                Err(RecvTimeoutError::Timeout) => {
                    // Readings between executions belong to none.
                    readings.try_iter().for_each(drop);
                    controller.idle()
                }
                Err(RecvTimeoutError::Disconnected) => return,
            }
        })
        .expect("cannot start the execution thread")
}

/// The dry run's controller: follows each goal in real time × `time_scale`, interpolating
/// joint positions linearly between points, and publishes `/joint_states` at `rate_hz`
/// (also while idle, so a viewer always shows the robot).
pub struct SimController {
    outputs: Arc<Outputs>,
    joint_names: Vec<String>,
    position: Vec<f64>,
    time_scale: f64,
    period: Duration,
}

impl SimController {
    pub fn new(outputs: Arc<Outputs>, time_scale: f64, rate_hz: f64) -> SimController {
        SimController {
            outputs,
            joint_names: Vec::new(),
            position: Vec::new(),
            time_scale,
            period: Duration::from_secs_f64(1.0 / rate_hz),
        }
    }

    fn publish(&self, velocity: Vec<f64>) {
        if let Some(out) = &self.outputs.joint_states {
            out.publish(
                &JointState {
                    header: Header::new(Time::now(), ""),
                    name: self.joint_names.clone(),
                    position: self.position.clone(),
                    velocity,
                    effort: Vec::new(),
                },
                self.outputs.recorder.as_ref(),
            );
        }
    }
}

impl Controller for SimController {
    fn execute(
        &mut self,
        goal: TrajectoryMsg,
        cancel: &Cancel,
        during: &mut dyn FnMut(f64),
    ) -> Result<(), ExecError> {
        let Some(first) = goal.points.first() else {
            return Ok(());
        };
        if self.joint_names != goal.joint_names || self.position.len() != first.positions.len() {
            // First goal (or another robot): start at the goal's first point.
            self.joint_names = goal.joint_names.clone();
            self.position = first.positions.clone();
        }
        let start_pos = self.position.clone();
        let times: Vec<f64> = goal
            .points
            .iter()
            .map(|p| p.time_from_start.as_secs_f64())
            .collect();
        let end = *times.last().unwrap_or(&0.0);
        let started = Instant::now();
        loop {
            if cancel.is_cancelled() {
                return Err(ExecError("cancelled".into()));
            }
            let t = (started.elapsed().as_secs_f64() * self.time_scale).min(end);
            // The segment holding t: from the previous point (or the start) to point k.
            let k = times
                .iter()
                .position(|&tk| tk >= t)
                .unwrap_or(times.len() - 1);
            let (t_a, a) = if k == 0 {
                (0.0, &start_pos)
            } else {
                (times[k - 1], &goal.points[k - 1].positions)
            };
            let b = &goal.points[k].positions;
            let span = times[k] - t_a;
            let s = if span > 0.0 { (t - t_a) / span } else { 1.0 };
            self.position = a.iter().zip(b).map(|(x, y)| x + (y - x) * s).collect();
            let velocity = if span > 0.0 && t < end {
                a.iter().zip(b).map(|(x, y)| (y - x) / span).collect()
            } else {
                vec![0.0; b.len()]
            };
            self.publish(velocity);
            if t >= end {
                return Ok(());
            }
            during(self.now_s());
            std::thread::sleep(self.period);
        }
    }

    fn idle(&mut self) {
        if !self.joint_names.is_empty() {
            self.publish(vec![0.0; self.position.len()]);
        }
    }

    fn idle_period(&self) -> Duration {
        self.period
    }

    fn time_scale(&self) -> f64 {
        self.time_scale
    }
}
