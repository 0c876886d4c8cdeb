//! Running a planned trajectory: the execution thread, and the simulated controller of a
//! dry run that follows goals in (scaled) real time and publishes `/joint_states`.

use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::execute::{oversized_welds, plan_steps, Step};
use super::execute_action::ExecutePlanFeedback;
use super::io::{Level, Outputs};
use super::pipeline::Planned;
use super::worker::Cancel;
use waam_messages::convert::goal_msg;
use waam_messages::status::JobStatus;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::DiagnosticStatus;
use waam_rosmsg::sensor_msgs::JointState;
use waam_rosmsg::std_msgs::{Bool, Header};
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
    fn execute(&mut self, goal: TrajectoryMsg, cancel: &Cancel) -> Result<(), ExecError>;
    /// Called once before a plan's first goal (a controller's trajectory mode).
    fn prepare(&mut self, _cancel: &Cancel) -> Result<(), ExecError> {
        Ok(())
    }
    /// Called while no goal runs, about every `idle_period()`.
    fn idle(&mut self) {}
    fn idle_period(&self) -> Duration {
        Duration::from_millis(200)
    }
}

/// Called as each goal chunk starts (the `~/execute` feedback).
pub type OnChunk = Box<dyn Fn(ExecutePlanFeedback) + Send>;

/// Runs a planned trajectory on `controller`: goals with the arc switched on `~/arc_on`
/// between them, cut only where the arc is off ([`plan_steps`]). Stops at the first failed
/// goal or when cancelled, always leaving the arc off.
#[allow(clippy::too_many_arguments)] // one execution's whole setting, passed once
pub fn run_plan(
    job: u64,
    planned: &Planned,
    controller: &mut dyn Controller,
    outputs: &Outputs,
    max_points: usize,
    lead_in_s: f64,
    cancel: &Cancel,
    on_chunk: Option<&OnChunk>,
) -> Result<(), ExecError> {
    let points = &planned.trajectory.points;
    let arc: Vec<bool> = points.iter().map(|p| p.arc_on).collect();
    let steps = plan_steps(&arc, max_points);
    let goals = steps
        .iter()
        .filter(|s| matches!(s, Step::Goal { .. }))
        .count();
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
    let (t0, duration) = match (points.first(), points.last()) {
        (Some(a), Some(b)) => (a.time_from_start, b.time_from_start - a.time_from_start),
        _ => (0.0, 0.0),
    };
    let report = |message: String, level: u8| {
        outputs.status.publish(
            &JobStatus::Executing {
                job,
                message,
                level,
            }
            .to_msg(Time::now(), ""),
            outputs.recorder.as_ref(),
        );
    };
    let set_arc = |on: bool| {
        outputs
            .arc_on
            .publish(&Bool { data: on }, outputs.recorder.as_ref());
    };
    outputs.log(
        Level::Info,
        &format!(
            "executing part {job}: {} fragment(s) in {goals} goal(s): each weld whole, arc-off moves in goals of at most {max_points} points",
            planned.found.fragments.len()
        ),
    );
    let mut arc_is_on = false;
    let mut sent = 0;
    let result = (|| {
        controller
            .prepare(cancel)
            .map_err(|e| format!("before the first goal: {e}"))?;
        for step in &steps {
            if cancel.is_cancelled() {
                return Err(ExecError("cancelled".to_string()));
            }
            match step {
                Step::Arc(on) => {
                    set_arc(*on);
                    arc_is_on = *on;
                }
                Step::Goal { span, welding } => {
                    sent += 1;
                    if let Some(on_chunk) = on_chunk {
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
                    let goal = goal_msg(&planned.trajectory, span.clone(), lead_in_s);
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
                    controller
                        .execute(goal, cancel)
                        .map_err(|e| format!("goal {sent}/{goals} ({what}) failed: {e}"))?;
                }
            }
        }
        Ok(())
    })();
    if arc_is_on {
        set_arc(false);
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
    },
}

/// Starts the execution thread: runs plans one at a time, idles the controller in between.
pub fn spawn_executor(
    mut controller: Box<dyn Controller>,
    outputs: Arc<Outputs>,
    max_points: usize,
    lead_in_s: f64,
    commands: Receiver<ExecCommand>,
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
                }) => {
                    let result = run_plan(
                        job,
                        &planned,
                        controller.as_mut(),
                        &outputs,
                        max_points,
                        lead_in_s,
                        &cancel,
                        on_chunk.as_ref(),
                    );
                    done(result);
                }
                Err(RecvTimeoutError::Timeout) => controller.idle(),
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
    fn execute(&mut self, goal: TrajectoryMsg, cancel: &Cancel) -> Result<(), ExecError> {
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
}
