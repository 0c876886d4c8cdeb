//! The ROS 2 node `waam_planner`: parts in, weld plans and robot trajectories out.
//!
//! Threads: the `ros2-client` spinner; an input thread that takes `~/part` and `~/part_mesh`
//! messages; one planning thread per job ([`worker`], latest part wins); the execution thread
//! when a controller is attached ([`controller`]); and the event loop here, which alone
//! decides what is published. Bad input of any kind ends as an ERROR status, never as a
//! stopped node, and only a plan that passed validation and the thermal check is published.

pub mod action;
pub mod arc_fault;
pub mod args;
pub mod closed_loop;
pub mod controller;
pub mod declared;
mod event_loop;
pub mod execute;
pub mod execute_action;
pub mod fjt;
pub mod frames;
pub mod health;
pub mod io;
pub mod names;
pub mod once;
pub mod param_server;
pub mod params;
pub mod pipeline;
pub mod plan_action;
pub mod ros;
pub mod sensors;
pub mod stop_service;
pub mod worker;

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

use futures::StreamExt;
use ros2_client::NodeOptions;

use controller::{spawn_executor, Controller, ExecCommand, SimController};
use event_loop::EventLoop;
use io::{Inputs, Level, Outputs};
use names::NodeNames;
use params::NodeParams;
use pipeline::{PartInput, PlanFn, Planned, PlanningPipeline};
use ros::RosEnv;
use waam_messages::convert::PlanMessages;
use waam_messages::status::JobStatus;
use waam_rosbag::Recorder;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::KeyValue;
use waam_rosmsg::std_msgs::Header;
use worker::{Cancel, JobFailure, Worker, WorkerEvent};

pub use waam_messages::convert::NODE_NAME;

/// How a run of the node is set up.
pub struct RunOptions {
    pub params: NodeParams,
    /// Name, namespace and remaps (`--ros-args -r`).
    pub names: NodeNames,
    /// Follow each plan with the built-in simulated controller (publishes `/joint_states`).
    pub dry_run: bool,
    /// Record everything received and sent into this rosbag2 directory.
    pub record: Option<PathBuf>,
    /// The planner jobs call.
    pub planner: Arc<PlanFn>,
}

/// What the node does: serve parts from topics until stopped, or plan one part and exit.
pub enum Mode {
    Serve,
    Once {
        input: PartInput,
        /// First wait up to this long for a subscriber on the joint trajectory topic.
        wait_for_subscriber: Duration,
        /// Keep serving the latched outputs this long before exiting.
        linger: Duration,
    },
}

enum Event {
    Input(PartInput),
    /// Parameters changed: plans from now on use this pipeline.
    Pipeline(Box<PlanningPipeline>),
    /// A `~/plan` goal or cancel request.
    Action(plan_action::Request),
    /// A `~/execute` goal or cancel request.
    Execute(execute_action::Request),
    /// An execution ended (`serial` tells which).
    Executed {
        serial: u64,
        job: u64,
        goal: Option<ros2_client::action::GoalId>,
        cancelled: bool,
        result: Result<(), controller::ExecError>,
    },
    /// `~/stop`: stop planning and execution; say what was stopped.
    Stop(Sender<String>),
    /// What a sensor's latest message told (for `/diagnostics`).
    Sensor(sensors::SensorNews),
    Worker(WorkerEvent<Box<Planned>, pipeline::JobError>),
}

/// Why the node could not start or go on.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    #[error(transparent)]
    Env(#[from] ros::RosEnvError),
    #[error(transparent)]
    Io(#[from] io::IoError),
    #[error("cannot record into {}: {source}", dir.display())]
    Record {
        dir: PathBuf,
        source: waam_rosbag::BagError,
    },
    #[error(transparent)]
    Setup(#[from] pipeline::SetupError),
    #[error("cannot create the ROS 2 node: {0}")]
    CreateNode(String),
    #[error("cannot start the ROS 2 spinner: {0}")]
    Spinner(String),
    #[error(transparent)]
    Serve(#[from] ros::ServeError),
    #[error(transparent)]
    Urdf(#[from] frames::UrdfError),
    #[error("cannot start a thread: {0}")]
    Thread(#[from] std::io::Error),
}

/// Runs the node until `stop` is raised (or, for [`Mode::Once`], the part is done). Returns
/// whether the last part was planned (and executed, when a controller is attached).
pub fn run(options: RunOptions, mode: Mode, stop: Arc<AtomicBool>) -> Result<bool, NodeError> {
    let env = RosEnv::from_env()?;
    let names = &options.names;
    let params = &options.params;
    let mut node = start_node(&env, names)?;
    let recorder = open_recorder(options.record.as_ref())?;
    let outputs = Arc::new(Outputs::new(
        &mut node,
        names,
        &params.topics,
        options.dry_run,
        recorder.clone(),
    )?);
    outputs.log(Level::Info, &started_line(&node, &env, &options));
    let mut pipeline = PlanningPipeline::from_params(params, Arc::clone(&options.planner))?;
    pipeline.recorder = recorder.clone();
    let cell = Cell::publish(&mut node, names, params, &pipeline, recorder.clone())?;
    let diagnostics = health_output(&mut node, names)?;
    // The torch the planner checks, in every "received" status: a replay plans with it.
    let torch_values = waam_messages::planning::torch_values(pipeline.cell.settings.torch_setup());
    let mesh_settings = pipeline.mesh.clone();
    let (pipeline_cell, pipeline_timeout_s) = (pipeline.cell.clone(), pipeline.timeout_s);

    let scan_targets = sensors::ScanTargets::new(&pipeline.cell.robot.base_link);
    let (events, event_rx) = channel::<Event>();
    // The sensors' good readings; the event loop drains `measured_rx` into the closed loop.
    let (measured_tx, measured_rx) = channel::<waam_cell::Measured>();
    // Arc faults go from the sensor thread to the execution at once (they stop a weld goal).
    let arc_faults = arc_fault::ArcFaults::new();
    let wiring = sensors::Wiring {
        measured: measured_tx,
        targets: scan_targets.clone(),
        faults: arc_faults.clone(),
    };
    let worker_events = events.clone();
    let worker = Worker::new(pipeline, move |e| {
        let _ = worker_events.send(Event::Worker(e));
    });
    let params_stop = Arc::new(AtomicBool::new(false));
    let (services, once) = start(
        mode,
        &mut node,
        &options,
        (&events, wiring),
        &outputs,
        &params_stop,
        &stop,
    )?;
    // The node is shared from here on: the FollowJointTrajectory client waits on it.
    let node = Arc::new(std::sync::Mutex::new(node));
    let (executor, executor_thread, readings) =
        start_executor(&options, &outputs, &node, arc_faults)?;
    let mut state = LoopState::new(
        &outputs,
        executor,
        params.execution.auto_execute,
        // Serving, an execution's end comes back as an event; once, on a channel.
        once.is_none().then(|| events.clone()),
        services.execute_replies.clone(),
    );
    state.readings = readings;
    state.closed_loop = replan_setup(params, &pipeline_cell, pipeline_timeout_s);
    drop(events);
    let mut event_loop = EventLoop {
        state,
        worker,
        health: health::Health::new(
            names.fully_qualified(),
            [
                params.closed_loop.scan_period_s,
                params.closed_loop.temperature_period_s,
                params.closed_loop.thermal_camera_period_s,
            ],
        ),
        goals: Default::default(),
        cell,
        mesh_settings,
        torch_values,
        action_replies: services.action_replies.clone(),
        measured_rx,
        scan_targets,
        health_due: false,
        once: once.is_some(),
        stop: Arc::clone(&stop),
    };
    event_loop.run(&event_rx, &diagnostics);
    event_loop.shut_down(executor_thread);
    params_stop.store(true, Ordering::Relaxed);
    services.join();
    if let Some(linger) = once {
        linger_unless_stopped(linger, &stop);
    }
    finish_recording(recorder.as_ref());
    drop(node); // stops the spinner
    Ok(event_loop.state.success)
}

/// Serving: starts the [`Services`]. Once: hands the part to the event loop (see
/// [`plan_once`]) and returns how long to linger after it.
fn start(
    mode: Mode,
    node: &mut ros2_client::Node,
    options: &RunOptions,
    (events, sensors): (&Sender<Event>, sensors::Wiring),
    outputs: &Arc<Outputs>,
    services_stop: &Arc<AtomicBool>,
    stop: &AtomicBool,
) -> Result<(Services, Option<Duration>), NodeError> {
    match mode {
        Mode::Serve => {
            let services =
                Services::serve(node, options, (events, sensors), outputs, services_stop)?;
            Ok((services, None))
        }
        Mode::Once {
            input,
            wait_for_subscriber,
            linger,
        } => {
            plan_once(
                node,
                options,
                outputs,
                events,
                input,
                wait_for_subscriber,
                stop,
            )?;
            Ok((Services::default(), Some(linger)))
        }
    }
}

/// Where the health goes out (`/diagnostics`).
fn health_output(
    node: &mut ros2_client::Node,
    names: &NodeNames,
) -> Result<io::Output<waam_rosmsg::diagnostic_msgs::DiagnosticArray>, NodeError> {
    Ok(io::Output::new(
        node,
        names,
        health::DIAGNOSTICS,
        io::stream_qos(),
        waam_rosbag::Qos::reliable(10),
    )?)
}

/// The recorder of `--record DIR`, if asked for.
fn open_recorder(record: Option<&PathBuf>) -> Result<Option<Recorder>, NodeError> {
    record
        .map(|dir| {
            Recorder::create(dir).map_err(|source| NodeError::Record {
                dir: dir.clone(),
                source,
            })
        })
        .transpose()
}

/// Planning once: lets subscribers fetch the latched outputs before the writers go away.
fn linger_unless_stopped(linger: Duration, stop: &AtomicBool) {
    let until = Instant::now() + linger;
    while Instant::now() < until && !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Closes the recording, if any, so that it opens without a reindex.
fn finish_recording(recorder: Option<&Recorder>) {
    if let Some(r) = recorder {
        match r.finish() {
            Ok(summary) => tracing::info!("recording finished: {summary:?}"),
            Err(e) => tracing::warn!("finishing the recording: {e}"),
        }
    }
}

/// The log line that says the node is up, where, and what it will do with plans.
fn started_line(node: &ros2_client::Node, env: &RosEnv, options: &RunOptions) -> String {
    let params = &options.params;
    format!(
        "{} up: domain {}, discovery {:?}{}{}",
        node.fully_qualified_name(),
        env.domain_id,
        env.range,
        if options.dry_run { ", dry run" } else { "" },
        if params.execution.enabled && !options.dry_run {
            format!(", executing on {}", params.execution.controller_action)
        } else {
            String::new()
        }
    )
}

/// The robot and the part frame for viewers, latched; the part frame moves with the
/// process settings, so a parameter change publishes them again.
struct Cell {
    urdf: String,
    frames: frames::CellFrames,
    recorder: Option<Recorder>,
}

impl Cell {
    fn publish(
        node: &mut ros2_client::Node,
        names: &NodeNames,
        params: &NodeParams,
        pipeline: &PlanningPipeline,
        recorder: Option<Recorder>,
    ) -> Result<Cell, NodeError> {
        let cell = Cell {
            urdf: frames::urdf_text(params)?,
            frames: frames::CellFrames::new(node, names)?,
            recorder,
        };
        cell.publish_again(pipeline);
        Ok(cell)
    }

    fn publish_again(&self, pipeline: &PlanningPipeline) {
        self.frames
            .publish(&self.urdf, pipeline, self.recorder.as_ref());
    }
}

/// What serving adds to the node: parameter services, `~/plan`, `~/execute`, `~/stop`, the
/// input topics and the sensors, each on a thread of its own; none when planning once.
#[derive(Default)]
struct Services {
    threads: Vec<std::thread::JoinHandle<()>>,
    action_replies: Option<Sender<plan_action::Reply>>,
    execute_replies: Option<Sender<execute_action::Reply>>,
}

impl Services {
    /// Starts them all; requests come to the event loop on `events`; they run until `stop`.
    fn serve(
        node: &mut ros2_client::Node,
        options: &RunOptions,
        (events, sensors): (&Sender<Event>, sensors::Wiring),
        outputs: &Arc<Outputs>,
        stop: &Arc<AtomicBool>,
    ) -> Result<Services, NodeError> {
        let (names, params) = (&options.names, &options.params);
        let store = param_server::ParamStore::new(
            params.clone(),
            pipeline_on_change(options, outputs.recorder.clone(), events.clone()),
        );
        let mut threads = vec![param_server::serve(
            node,
            &names.fully_qualified(),
            Arc::clone(&store),
            Arc::clone(stop),
        )?];
        let (action_replies, replies) = channel();
        threads.push(plan_action::serve(
            node,
            names,
            store,
            to_loop(events, Event::Action),
            replies,
            Arc::clone(stop),
        )?);
        let (execute_replies, replies) = channel();
        threads.push(execute_action::serve(
            node,
            names,
            to_loop(events, Event::Execute),
            replies,
            Arc::clone(stop),
        )?);
        threads.push(stop_service::serve(
            node,
            names,
            to_loop(events, Event::Stop),
            Arc::clone(stop),
        )?);
        let inputs = Inputs::new(node, names, &params.topics)?;
        outputs.log(
            Level::Info,
            &format!(
                "waiting for parts on {} and {}",
                inputs.part_topic, inputs.mesh_topic
            ),
        );
        spawn_inputs(inputs, events.clone(), Arc::clone(outputs));
        let cell_sensors = sensors::Sensors::new(node, names, &params.closed_loop)?;
        outputs.log(
            Level::Info,
            &format!(
                "closed loop: layer scans on {}, temperatures on {}, thermal images on {}, arc \
                 faults on {}",
                cell_sensors.scan_topic,
                cell_sensors.temperature_topic,
                cell_sensors.camera_topic,
                cell_sensors.arc_fault_topic
            ),
        );
        cell_sensors.spawn(
            sensors,
            to_loop(events, Event::Sensor),
            outputs.recorder.clone(),
        )?;
        Ok(Services {
            threads,
            action_replies: Some(action_replies),
            execute_replies: Some(execute_replies),
        })
    }

    fn join(self) {
        for thread in self.threads {
            let _ = thread.join();
        }
    }
}

/// Hands requests to the event loop as `wrap` makes them events; `false`: the loop is gone
/// (the node is stopping).
fn to_loop<R>(events: &Sender<Event>, wrap: fn(R) -> Event) -> impl Fn(R) -> bool + Send {
    let events = std::sync::Mutex::new(events.clone());
    move |request| {
        let events = events.lock().unwrap_or_else(|e| e.into_inner());
        events.send(wrap(request)).is_ok()
    }
}

/// Parameter changes build the next pipeline here (a bad one is refused) and hand it to the
/// event loop.
fn pipeline_on_change(
    options: &RunOptions,
    recorder: Option<Recorder>,
    events: Sender<Event>,
) -> Box<param_server::OnChange> {
    let planner = Arc::clone(&options.planner);
    let to_loop = std::sync::Mutex::new(events);
    Box::new(move |next: &NodeParams| {
        let mut pipeline = PlanningPipeline::from_params(next, Arc::clone(&planner))?;
        pipeline.recorder = recorder.clone();
        let sent = to_loop
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .send(Event::Pipeline(Box::new(pipeline)));
        sent.map_err(|_| param_server::ChangeError::ShuttingDown)
    })
}

/// [`Mode::Once`]: waits (up to `wait_for_subscriber`) for a subscriber on the joint
/// trajectory topic, records the part as if it had come on `~/part`, and hands it to the
/// event loop.
fn plan_once(
    node: &ros2_client::Node,
    options: &RunOptions,
    outputs: &Outputs,
    events: &Sender<Event>,
    input: PartInput,
    wait_for_subscriber: Duration,
    stop: &AtomicBool,
) -> Result<(), NodeError> {
    let until = Instant::now() + wait_for_subscriber;
    while outputs.joint_trajectory.subscribers(node) == 0
        && Instant::now() < until
        && !stop.load(Ordering::Relaxed)
    {
        std::thread::sleep(Duration::from_millis(20));
    }
    // Record the part as if it had arrived on ~/part, so a replay finds it.
    if let (Some(r), PartInput::Document(text)) = (&outputs.recorder, &input) {
        let topic = options.names.resolve(&options.params.topics.part)?;
        let msg = waam_rosmsg::std_msgs::String { data: text.clone() };
        if let Err(e) = r.record(&topic.to_string(), &waam_rosbag::Qos::reliable(10), &msg) {
            tracing::warn!("recording {topic}: {e}");
        }
    }
    let _ = events.send(Event::Input(input));
    Ok(())
}

/// How the closed loop re-plans (`closed_loop.enabled`; none when off): in the pipeline's
/// cell, within the planner's time limit.
fn replan_setup(
    params: &NodeParams,
    cell: &waam_pipeline::Cell,
    timeout_s: f64,
) -> Option<closed_loop::ReplanSetup> {
    params
        .closed_loop
        .enabled
        .then(|| closed_loop::ReplanSetup {
            cell: cell.clone(),
            planner: waam_planner::Options {
                timeout: Duration::try_from_secs_f64(timeout_s)
                    .ok()
                    .filter(|t| !t.is_zero()),
                max_memory_mb: params.planner.memory_limit_mb(),
                threads: params.planner.thread_count(),
                ..waam_planner::Options::default()
            },
            wire_feed: (
                params.closed_loop.wire_feed_min,
                params.closed_loop.wire_feed_max,
            ),
            wire_feed_per_deposit: params.closed_loop.wire_feed_per_deposit,
            wire_feed_lead_s: params.closed_loop.wire_feed_lead_s,
            // The controller's, when an execution starts.
            time_scale: 1.0,
            scan_margin_mm: params.closed_loop.scan_margin_mm,
        })
}

/// Execution: the simulated controller on a dry run, FollowJointTrajectory when enabled, on
/// a thread of its own; none otherwise. With it, where the sensors' readings go to the
/// execution's closed loop.
#[allow(clippy::type_complexity)]
fn start_executor(
    options: &RunOptions,
    outputs: &Arc<Outputs>,
    node: &Arc<std::sync::Mutex<ros2_client::Node>>,
    faults: arc_fault::ArcFaults,
) -> Result<
    (
        Option<Sender<ExecCommand>>,
        Option<std::thread::JoinHandle<()>>,
        Option<Sender<waam_cell::Measured>>,
    ),
    NodeError,
> {
    let params = &options.params;
    let controller: Box<dyn Controller> = if options.dry_run {
        Box::new(SimController::new(
            Arc::clone(outputs),
            params.dry_run.time_scale,
            params.dry_run.rate_hz,
        ))
    } else if params.execution.enabled {
        Box::new(fjt::FjtController::new(
            Arc::clone(node),
            &options.names,
            &params.execution,
        )?)
    } else {
        return Ok((None, None, None));
    };
    let (tx, rx) = channel();
    let (readings_tx, readings) = channel();
    let thread = spawn_executor(
        controller,
        Arc::clone(outputs),
        params.execution.max_points_per_goal as usize,
        params.execution.lead_in_s,
        rx,
        readings,
        faults,
    );
    Ok((Some(tx), Some(thread), Some(readings_tx)))
}

/// The node `names` gives (with `/rosout`) on the environment's domain and discovery range,
/// its spinner running on a thread of its own until the node is dropped. `ros2-client`'s
/// parameter services are off: [`param_server`] serves the node's own.
pub fn start_node(env: &RosEnv, names: &NodeNames) -> Result<ros2_client::Node, NodeError> {
    let mut node = env
        .context()?
        .new_node(
            names.node_name()?,
            NodeOptions::new()
                .enable_rosout(true)
                .start_parameter_services(false),
        )
        .map_err(|e| NodeError::CreateNode(format!("{e:?}")))?;
    let spinner = node
        .spinner()
        .map_err(|e| NodeError::Spinner(format!("{e:?}")))?;
    std::thread::Builder::new()
        .name("ros-spin".into())
        .spawn(move || futures::executor::block_on(spinner.spin()))?;
    Ok(node)
}

/// Plans kept for `~/execute` (the latest ones).
const KEEP_PLANS: usize = 8;

/// An execution in progress.
struct Execution {
    /// Tells this execution's end from an older one's.
    serial: u64,
    /// When it began: the sensors' cadences count from here.
    started: std::time::Instant,
    job: u64,
    cancel: Cancel,
    /// The `~/execute` goal that asked for it (none: run on planning).
    goal: Option<ros2_client::action::GoalId>,
}

/// The event loop's memory between events.
struct LoopState {
    outputs: Arc<Outputs>,
    executor: Option<Sender<ExecCommand>>,
    /// Run each plan as soon as it is made (`execution.auto_execute`).
    auto_execute: bool,
    execution: Option<Execution>,
    serial: u64,
    /// The latest plans by job, oldest first: what `~/execute` can run.
    plans: std::collections::VecDeque<(u64, Arc<Planned>)>,
    /// Where an execution's end goes while serving.
    events: Option<Sender<Event>>,
    execute_replies: Option<Sender<execute_action::Reply>>,
    /// When and which stage the last progress status was published.
    last_progress: Option<(Instant, &'static str)>,
    success: bool,
    /// Closed loop: how executions re-plan (none: off), and where sensor readings go to the
    /// execution in progress.
    closed_loop: Option<closed_loop::ReplanSetup>,
    readings: Option<Sender<waam_cell::Measured>>,
}

impl LoopState {
    fn new(
        outputs: &Arc<Outputs>,
        executor: Option<Sender<ExecCommand>>,
        auto_execute: bool,
        events: Option<Sender<Event>>,
        execute_replies: Option<Sender<execute_action::Reply>>,
    ) -> LoopState {
        LoopState {
            outputs: Arc::clone(outputs),
            executor,
            auto_execute,
            execution: None,
            serial: 0,
            plans: std::collections::VecDeque::new(),
            events,
            execute_replies,
            last_progress: None,
            success: false,
            closed_loop: None,
            readings: None,
        }
    }

    /// A sensor's good reading, for the closed loop of the execution in progress.
    fn measured(&self, reading: waam_cell::Measured) {
        if let (Some(_), Some(tx)) = (&self.closed_loop, &self.readings) {
            let _ = tx.send(reading);
        }
    }

    /// Parameters changed: re-plans use the new cell and time limit.
    fn replan_in(&mut self, pipeline: &PlanningPipeline) {
        if let Some(setup) = &mut self.closed_loop {
            setup.cell = pipeline.cell.clone();
            setup.planner.timeout = Duration::try_from_secs_f64(pipeline.timeout_s)
                .ok()
                .filter(|t| !t.is_zero());
        }
    }

    fn status(&self, status: JobStatus) {
        self.outputs.publish_status(&status);
    }

    /// A planning status, at most 4 per second unless the stage changes.
    fn progress(&mut self, job: u64, progress: worker::Progress) {
        let now = Instant::now();
        if let Some((at, stage)) = self.last_progress {
            if stage == progress.stage && now.duration_since(at) < Duration::from_millis(250) {
                return;
            }
        }
        self.last_progress = Some((now, progress.stage));
        self.status(JobStatus::Planning {
            job,
            stage: progress.stage.to_string(),
            fraction: progress.fraction,
            detail: progress.detail,
        });
    }

    /// Publishes a finished job's plan (or its error) and starts its execution. Returns the
    /// channel that reports the end of the execution, when one was started.
    fn finished(
        &mut self,
        job: u64,
        result: Result<Box<Planned>, JobFailure<pipeline::JobError>>,
    ) -> Option<std::sync::mpsc::Receiver<Result<(), controller::ExecError>>> {
        self.last_progress = None;
        let planned = match result {
            Ok(planned) => planned,
            Err(e) => {
                let reason = e.to_string();
                self.success = false;
                self.outputs
                    .log(Level::Error, &format!("part {job}: {reason}"));
                self.status(JobStatus::Error {
                    job: Some(job),
                    reason,
                });
                return None;
            }
        };
        publish_plan(&self.outputs, &planned);
        if let Some(r) = &self.outputs.recorder {
            record_heat(r, &planned);
        }
        self.status(JobStatus::Planned {
            job,
            values: plan_values(&planned),
        });
        self.outputs.log(
            Level::Info,
            &format!(
                "part {job} planned: {} blocks in {} fragment(s), {} trajectory points, {:.1} s",
                planned.part.len(),
                planned.found.fragments.len(),
                planned.trajectory.points.len(),
                planned
                    .trajectory
                    .points
                    .last()
                    .map_or(0.0, |p| p.time_from_start)
            ),
        );
        self.success = true;
        let planned: Arc<Planned> = Arc::from(planned);
        self.plans.push_back((job, Arc::clone(&planned)));
        while self.plans.len() > KEEP_PLANS {
            self.plans.pop_front();
        }
        if !self.auto_execute {
            return None;
        }
        if let Some(old) = self.execution.take() {
            old.cancel.cancel();
            self.outputs.log(
                Level::Warn,
                "a newer plan arrived: stopping the execution in progress",
            );
        }
        self.execute(job, planned, None)
    }

    /// Starts `~/execute` goal `goal` on plan `job` (0: the latest), or says why not.
    fn execute_goal(
        &mut self,
        goal: ros2_client::action::GoalId,
        job: u64,
    ) -> Result<(), execute_action::ExecutePlanResult> {
        use execute_action::ExecutePlanResult as R;
        if self.executor.is_none() {
            return Err(R::new(
                R::UNAVAILABLE,
                job,
                "no controller: set parameter execution.enabled (at start) or run with --dry-run",
            ));
        }
        let found = if job == 0 {
            self.plans.back()
        } else {
            self.plans.iter().find(|(j, _)| *j == job)
        };
        let Some((job, planned)) = found.cloned() else {
            let kept: Vec<String> = self.plans.iter().map(|(j, _)| j.to_string()).collect();
            return Err(R::new(
                R::NO_PLAN,
                job,
                if job == 0 {
                    "no plan yet: plan a part first (~/plan, ~/part)".to_string()
                } else {
                    format!(
                        "no plan of part {job}: the node keeps its last {KEEP_PLANS} plans \
                         (now: [{}])",
                        kept.join(", ")
                    )
                },
            ));
        };
        if let Some(running) = &self.execution {
            return Err(R::new(
                R::UNAVAILABLE,
                job,
                format!(
                    "part {} is being executed: cancel its goal or call ~/stop first",
                    running.job
                ),
            ));
        }
        self.execute(job, planned, Some(goal));
        Ok(())
    }

    /// Hands plan `job` to the execution thread. Returns the channel that reports its end
    /// when not serving (serving, it comes back as [`Event::Executed`]).
    fn execute(
        &mut self,
        job: u64,
        planned: Arc<Planned>,
        goal: Option<ros2_client::action::GoalId>,
    ) -> Option<std::sync::mpsc::Receiver<Result<(), controller::ExecError>>> {
        let executor = self.executor.as_ref()?;
        let cancel = Cancel::new();
        self.serial += 1;
        let serial = self.serial;
        self.execution = Some(Execution {
            serial,
            started: std::time::Instant::now(),
            job,
            cancel: cancel.clone(),
            goal,
        });
        let (done_tx, done_rx) = channel();
        let events = self.events.clone();
        let flag = cancel.clone();
        let done = Box::new(
            move |result: Result<(), controller::ExecError>| match events {
                Some(events) => {
                    let _ = events.send(Event::Executed {
                        serial,
                        job,
                        goal,
                        cancelled: flag.is_cancelled(),
                        result,
                    });
                }
                None => {
                    let _ = done_tx.send(result);
                }
            },
        );
        let on_chunk: Option<controller::OnChunk> = match (goal, &self.execute_replies) {
            (Some(goal), Some(replies)) => {
                let replies = replies.clone();
                Some(Box::new(move |feedback| {
                    let _ = replies.send(execute_action::Reply::Feedback(goal, feedback));
                }))
            }
            _ => None,
        };
        let _ = executor.send(ExecCommand::Run {
            job,
            planned,
            cancel,
            on_chunk,
            done,
            closed_loop: self.closed_loop.clone(),
        });
        self.events.is_none().then_some(done_rx)
    }
}

type JobResult = Result<Box<Planned>, JobFailure<pipeline::JobError>>;

fn result_ok(result: &JobResult) -> Result<&Planned, ()> {
    result.as_deref().map_err(|_| ())
}

/// The last feedback of a goal that got a plan: the counters and margin of the run.
fn final_feedback(p: &Planned, since: Instant) -> plan_action::PlanPartFeedback {
    let s = &p.found.stats;
    plan_action::PlanPartFeedback {
        stage: "planned".into(),
        candidates: s.candidates,
        feasible: s.feasible,
        cuts: s.cycle_cuts,
        best_margin_s: p.found.worst_margin_s,
        elapsed_s: since.elapsed().as_secs_f64(),
    }
}

/// A `~/plan` goal's end from its job's.
fn goal_result(
    job: u64,
    result: &JobResult,
) -> (
    ros2_client::action::GoalStatusEnum,
    plan_action::PlanPartResult,
) {
    use plan_action::PlanPartResult as R;
    use ros2_client::action::GoalStatusEnum as S;
    match result {
        Ok(planned) => {
            let header = Header::new(Time::now(), planned.toolpath.frame.clone());
            match PlanMessages::of_planned(planned, &header) {
                Ok(m) => (
                    S::Succeeded,
                    R {
                        outcome: R::PLANNED,
                        reason: String::new(),
                        plan: m.weld_plan,
                        job,
                    },
                ),
                Err(e) => (S::Aborted, R::failed(R::NO_PLAN, e.to_string())),
            }
        }
        Err(JobFailure::Failed(pipeline::JobError::Pipeline(e))) => {
            (S::Aborted, R::failed(R::BAD_INPUT, e.to_string()))
        }
        Err(JobFailure::Superseded) => (S::Aborted, R::failed(R::CANCELLED, "superseded")),
        Err(e) => (S::Aborted, R::failed(R::NO_PLAN, e.to_string())),
    }
}

/// Publishes every output of a plan, all with the same header (recording them too).
pub fn publish_plan(outputs: &Outputs, planned: &Planned) {
    let header = Header::new(Time::now(), planned.toolpath.frame.clone());
    match PlanMessages::of_planned(planned, &header) {
        Ok(m) => publish_messages(outputs, &m),
        Err(e) => outputs.log(Level::Error, &format!("cannot publish the plan: {e}")),
    }
}

/// Publishes a plan's messages on the outputs (recording them when the outputs record).
pub fn publish_messages(outputs: &Outputs, m: &PlanMessages) {
    let rec = outputs.recorder.as_ref();
    outputs.joint_trajectory.publish(&m.joint_trajectory, rec);
    outputs.poses.publish(&m.poses, rec);
    outputs.path.publish(&m.path, rec);
    outputs.markers.publish(&m.markers, rec);
    outputs.weld_plan.publish(&m.weld_plan, rec);
}

/// Records the chosen plan's simulated block temperatures (PointCloud2 frames in the part
/// frame, metres, as the CLI records them; /tf_static ties it to the robot) so Foxglove can
/// play the build's heat back.
fn record_heat(recorder: &Recorder, planned: &Planned) {
    let graph = waam_part::graph::WeldGraph::new(&planned.part);
    let model = waam_thermal::ThermalModel::new(&planned.part, &graph);
    if let Err(e) = waam_messages::heat::record_heat(
        recorder,
        &planned.part,
        &model,
        &planned.found.fragments,
        waam_messages::planning::PART_FRAME,
        Time::now(),
        waam_messages::heat::HeatOptions::default(),
    ) {
        tracing::warn!("recording the heat frames: {e}");
    }
}

/// The statistics a "planned" status carries.
fn plan_values(p: &Planned) -> Vec<KeyValue> {
    let (f, s) = (&p.found, &p.found.stats);
    let duration = p
        .trajectory
        .points
        .last()
        .map_or(0.0, |q| q.time_from_start);
    vec![
        KeyValue::new("part", &p.part.name),
        KeyValue::new("blocks", p.part.len()),
        KeyValue::new("fragments", f.fragments.len()),
        KeyValue::new("candidates", s.candidates),
        KeyValue::new("feasible_found", s.feasible),
        KeyValue::new("optimal", f.proven),
        KeyValue::new("planning_time_s", format!("{:.3}", s.total_s)),
        KeyValue::new("worst_margin_s", format!("{:.3}", f.worst_margin_s)),
        KeyValue::new("toolpath_poses", p.toolpath.poses.len()),
        KeyValue::new("trajectory_points", p.trajectory.points.len()),
        KeyValue::new("duration_s", format!("{duration:.3}")),
    ]
}

/// The input thread: turns `~/part` and `~/part_mesh` messages into jobs (and records them).
fn spawn_inputs(inputs: Inputs, events: Sender<Event>, outputs: Arc<Outputs>) {
    std::thread::Builder::new()
        .name("ros-inputs".into())
        .spawn(move || {
            let Inputs {
                part_topic,
                part,
                mesh_topic,
                mesh,
            } = inputs;
            let mut mesh_count = 0u64;
            let recorder = outputs.recorder.clone();
            let record =
                |topic: &str, msg: &dyn Fn(&Recorder) -> Result<(), waam_rosbag::BagError>| {
                    if let Some(r) = &recorder {
                        if let Err(e) = msg(r) {
                            tracing::warn!("recording {topic}: {e}");
                        }
                    }
                };
            let parts = part.async_stream().map(|r| r.map(Incoming::Part));
            let meshes = mesh.async_stream().map(|r| r.map(Incoming::Mesh));
            let mut merged = futures::stream::select(Box::pin(parts), Box::pin(meshes));
            futures::executor::block_on(async {
                while let Some(item) = merged.next().await {
                    let input = match item {
                        Ok(Incoming::Part((msg, _))) => {
                            record(&part_topic, &|r| {
                                r.record(&part_topic, &waam_rosbag::qos::Qos::reliable(10), &msg)
                            });
                            PartInput::Document(msg.data)
                        }
                        Ok(Incoming::Mesh((msg, _))) => {
                            record(&mesh_topic, &|r| {
                                r.record(&mesh_topic, &waam_rosbag::qos::Qos::reliable(10), &msg)
                            });
                            mesh_count += 1;
                            pipeline::mesh_input(format!("mesh-{mesh_count}"), &msg)
                        }
                        Err(e) => {
                            // An undecodable message (wrong type on the topic, bad CDR).
                            outputs
                                .log(Level::Error, &format!("cannot read an input message: {e}"));
                            outputs.publish_status(&JobStatus::Error {
                                job: None,
                                reason: format!("cannot read an input message: {e}"),
                            });
                            continue;
                        }
                    };
                    if events.send(Event::Input(input)).is_err() {
                        return;
                    }
                }
            });
        })
        .expect("cannot start the input thread");
}

enum Incoming {
    Part((waam_rosmsg::std_msgs::String, ros2_client::MessageInfo)),
    Mesh((waam_rosmsg::shape_msgs::Mesh, ros2_client::MessageInfo)),
}
