//! `waam motion PART PLAN --robot URDF --out DIR`: toolpath and joint trajectory for an
//! existing plan. [`RobotArgs`] (the cell, through the pipeline's cell loader) and
//! [`report_motion`] serve `waam plan --robot` too.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use waam_motion::robot::parse_xyz_rpy;
pub use waam_motion::toolpath::MotionSummary;
use waam_motion::toolpath::Toolpath;
use waam_motion::trajectory::JointTrajectory;
use waam_motion::write_outputs;
use waam_pipeline::{Cell, CellError, CellSource, PipelineError};

use super::{read_part, EXIT_NO, EXIT_OK};

/// The robot and process options shared by every command that makes robot motion.
#[derive(Debug, Clone, clap::Args)]
pub struct RobotArgs {
    /// The robot's URDF (meshes need not exist). Its root link is the base frame.
    #[arg(long, value_name = "URDF")]
    pub robot: PathBuf,
    /// The TCP in the tip link as "x y z roll pitch yaw" (m, rad), for a URDF without a
    /// torch. Default: none when the tip link is named `tcp`, else the process file's `tcp`.
    #[arg(
        long,
        value_name = "\"x y z roll pitch yaw\"",
        allow_hyphen_values = true
    )]
    pub tcp: Option<String>,
    /// The link the TCP is attached to. Default: a link named `tcp`, else the end of the
    /// URDF's longest chain.
    #[arg(long, value_name = "LINK")]
    pub tip: Option<String>,
    /// Process settings (YAML, see config/process.yaml). Default: the values in
    /// config/process.yaml, built in.
    #[arg(long, value_name = "FILE")]
    pub process: Option<PathBuf>,
    /// Joint limits (MoveIt-style joint_limits.yaml): a joint's max_velocity replaces the
    /// URDF's, its max_acceleration limits the trajectory's accelerations. Default: the
    /// URDF's velocity limits, no acceleration limits. Welds keep their speed exactly: a
    /// weld the limits would slow down is an error naming the block.
    #[arg(long, value_name = "FILE")]
    pub limits: Option<PathBuf>,
}

/// [`RobotArgs`] where the robot is optional (`waam layer plan`): each option but --robot
/// requires --robot.
#[derive(Debug, Clone, clap::Args)]
pub struct OptionalRobotArgs {
    /// Also plan the robot motion: torch poses and a validated joint trajectory for this
    /// robot (URDF; meshes need not exist). `plan` and `layer`: written to
    /// DIR/toolpath.yaml and DIR/trajectory.yaml with --out, recorded (trajectory, poses,
    /// path, markers, weld plan) with --record; `sim-cell`: the true cell welds each deposit
    /// when the trajectory makes it.
    #[arg(long, value_name = "URDF")]
    pub robot: Option<PathBuf>,
    /// With --robot: the TCP in the tip link as "x y z roll pitch yaw" (m, rad).
    #[arg(
        long,
        value_name = "\"x y z roll pitch yaw\"",
        allow_hyphen_values = true,
        requires = "robot"
    )]
    pub tcp: Option<String>,
    /// With --robot: the link the TCP is attached to.
    #[arg(long, value_name = "LINK", requires = "robot")]
    pub tip: Option<String>,
    /// With --robot: process settings (YAML, see config/process.yaml): plate pose, torch
    /// angles, speeds, dwells.
    #[arg(long, value_name = "FILE", requires = "robot")]
    pub process: Option<PathBuf>,
    /// With --robot: joint limits (MoveIt-style joint_limits.yaml: velocity and
    /// acceleration); default: the URDF's velocity limits only.
    #[arg(long, value_name = "FILE", requires = "robot")]
    pub limits: Option<PathBuf>,
}

impl OptionalRobotArgs {
    /// The options as [`RobotArgs`], when a robot is given.
    pub fn robot_args(&self) -> Option<RobotArgs> {
        self.robot.as_ref().map(|robot| RobotArgs {
            robot: robot.clone(),
            tcp: self.tcp.clone(),
            tip: self.tip.clone(),
            process: self.process.clone(),
            limits: self.limits.clone(),
        })
    }
}

impl RobotArgs {
    /// Reads the process settings and the robot: the cell a plan is welded in.
    pub fn load(&self) -> anyhow::Result<Cell> {
        self.load_cell(false)
    }

    /// [`RobotArgs::load`]; with `no_torch`, without the process settings' torch
    /// (`--no-torch`).
    pub fn load_cell(&self, no_torch: bool) -> anyhow::Result<Cell> {
        let tcp = match &self.tcp {
            Some(text) => Some(parse_xyz_rpy(text).map_err(|e| anyhow::anyhow!("--tcp: {e}"))?),
            None => None,
        };
        let cell = CellSource {
            process: self.process.clone(),
            urdf: Some(self.robot.clone()),
            tip: self.tip.clone(),
            tcp,
            joint_limits: self.limits.clone(),
            no_torch,
        }
        .load()
        .map_err(cell_error)?;
        let robot = &cell.robot;
        match (&robot.opw_reason, robot.opw().is_some()) {
            (_, true) => tracing::info!(
                "robot {}: {} -> {}, analytic OPW inverse kinematics",
                robot.name,
                robot.base_link,
                robot.tip_link
            ),
            (Some(reason), false) => tracing::info!(
                "robot {}: {} -> {}, numeric inverse kinematics ({reason})",
                robot.name,
                robot.base_link,
                robot.tip_link
            ),
            (None, false) => {}
        }
        Ok(cell)
    }
}

/// The cell loader's error, worded by the command line's options.
pub fn cell_error(e: CellError) -> anyhow::Error {
    let file = |what: &str, path: &Path| format!("{what} {}", path.display());
    match e {
        CellError::ReadProcess { path, source } => {
            anyhow::Error::new(source).context(file("cannot read process settings", &path))
        }
        CellError::Process { path, source } => {
            anyhow::Error::new(source).context(file("in process settings", &path))
        }
        CellError::BundledRobot(source) => anyhow::Error::new(source).context("the bundled robot"),
        CellError::Robot { path, source } => {
            anyhow::Error::new(source).context(file("in robot", &path))
        }
        CellError::ReadLimits { path, source } => {
            anyhow::Error::new(source).context(file("cannot read joint limits", &path))
        }
        CellError::Limits { path, source } => {
            anyhow::Error::new(source).context(file("in joint limits", &path))
        }
    }
}

/// Writes `toolpath.yaml` and `trajectory.yaml` into `out`.
pub fn write_motion(tp: &Toolpath, traj: &JointTrajectory, out: &Path) -> anyhow::Result<()> {
    write_outputs(out, tp, traj)
        .with_context(|| format!("cannot write motion files in {}", out.display()))
}

/// Writes `toolpath.yaml` and `trajectory.yaml` into `out` first, then prints what
/// [`print_motion`] prints.
pub fn report_motion(
    tp: &Toolpath,
    traj: &JointTrajectory,
    out: Option<&Path>,
) -> anyhow::Result<()> {
    if let Some(out) = out {
        write_motion(tp, traj, out)?;
    }
    print_motion(tp, out);
    Ok(())
}

/// Prints a summary of the motion and, when its files were written into `written_to`,
/// their names.
pub fn print_motion(tp: &Toolpath, written_to: Option<&Path>) {
    let s = MotionSummary::of(tp);
    println!(
        "MOTION: {} poses ({} weld poses at points), {} weld pass(es), {:.1} s total, {:.1} s arc on",
        s.poses, s.weld_points, s.passes, s.duration_s, s.arc_on_s
    );
    if let Some(out) = written_to {
        println!(
            "wrote {} and {}",
            out.join("toolpath.yaml").display(),
            out.join("trajectory.yaml").display()
        );
    }
}

/// Turn an existing plan into torch poses and a joint trajectory for a robot.
///
/// Writes DIR/toolpath.yaml (TCP poses in the robot's base link with arc state and
/// fragment) and DIR/trajectory.yaml (joint positions and velocities over time). The
/// process settings' torch (the bundled typical GMAW torch unless --process says otherwise)
/// must reach every block past what stands before it, as the planner requires, and its
/// nozzle, body and wrist must clear the part as built on every move with the arc off.
/// Exit code 0: written; 1: the plan is invalid, the torch cannot weld it (TORCH BLOCKED,
/// naming the block and what is in its way) or the robot cannot (unreachable pose,
/// configuration change mid-weld — the message names the block and the pose); 2: bad
/// input.
#[derive(Debug, clap::Args)]
pub struct MotionArgs {
    /// The part file (YAML: the shared part format, or a graph part of beads, welded along
    /// their centre lines).
    pub part: PathBuf,
    /// The plan file (YAML, or JSON when it ends in .json or starts with `{`): blocks, or
    /// node ids for a graph part.
    pub plan: PathBuf,
    #[command(flatten)]
    pub robot: RobotArgs,
    /// Output directory for toolpath.yaml and trajectory.yaml (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// No torch: neither the access check at every deposit nor the torch along the moves
    /// (only the TCP's path is kept clear of the part), as if the process settings said
    /// `torch: null`.
    #[arg(long)]
    pub no_torch: bool,
    /// Give up after this many seconds (reading the part counts against it): the torch's
    /// access and clearance checks and the inverse kinematics of a part of many blocks take
    /// long. Prints TIMEOUT, exit 1. Ctrl-C stops it at once.
    #[arg(long, value_name = "SECONDS")]
    pub timeout: Option<f64>,
}

pub fn run(args: MotionArgs) -> anyhow::Result<ExitCode> {
    let timeout = super::timeout_arg(args.timeout)?;
    let started = std::time::Instant::now();
    let path = args.part.clone();
    let what = format!("reading {}", path.display());
    let part = super::within(timeout, &what, move || read_part(&path))?;
    let checked = super::read_plan(&part, &args.plan)?;
    let fragments = match checked {
        Ok(f) => f,
        Err(invalid) => {
            println!("INVALID: {invalid}");
            return Ok(ExitCode::from(EXIT_NO));
        }
    };
    // The plan's rules are checked above; its t8/5 windows are `waam check`'s business.
    // The motion is timed to the thermal model all the same (waits at the approach points).
    let cell = args.robot.load_cell(args.no_torch)?;
    // The motion stages have no stopping points of their own: they run on a thread that
    // is left behind at the time limit, and the process ends.
    let left = timeout.map(|t| t.saturating_sub(started.elapsed()));
    let motion = super::within(left, "planning the motion", move || {
        Ok(cell.plan_motion(&part, &fragments))
    });
    let motion = match motion {
        Ok(motion) => motion,
        Err(_) => {
            println!(
                "TIMEOUT: the motion was not planned within --timeout {} s",
                timeout.unwrap_or_default().as_secs_f64()
            );
            return Ok(ExitCode::from(EXIT_NO));
        }
    };
    let (toolpath, trajectory) = match motion {
        Ok(motion) => motion,
        Err(e @ PipelineError::TorchBlocked { .. }) => {
            println!("TORCH BLOCKED: {e}");
            return Ok(ExitCode::from(EXIT_NO));
        }
        Err(PipelineError::Motion(e)) => {
            println!("NO MOTION: {e}");
            return Ok(ExitCode::from(EXIT_NO));
        }
        Err(e) => {
            println!("NO MOTION: {e}");
            return Ok(ExitCode::from(EXIT_NO));
        }
    };
    report_motion(&toolpath, &trajectory, Some(&args.out))?;
    Ok(ExitCode::from(EXIT_OK))
}
