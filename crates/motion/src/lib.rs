//! From weld passes to robot motion: [`toolpath`] (torch poses, arc-on/off markers,
//! transits), [`robot`] (a URDF arm and its inverse kinematics) and [`trajectory`] (a timed,
//! validated joint trajectory).
//!
//! [`plan_motion`] turns a plan's fragments (and `waam_layer::plan_layer_motion` a layer's
//! trail) into weld passes, the passes into a toolpath (torch poses, arc-on/off markers, transits) and
//! the toolpath into a validated joint trajectory for the robot; [`write_outputs`] writes
//! `toolpath.yaml` and `trajectory.yaml`.

use std::path::Path;

pub mod clearance;
pub mod robot;
pub mod toolpath;
pub mod trajectory;

use thiserror::Error;

use crate::robot::Robot;
use crate::toolpath::{ProcessSettings, Toolpath, ToolpathError, WeldPass, WeldTiming};
use crate::trajectory::{JointTrajectory, TrajectoryError};
use waam_part::Part;

/// Why no motion could be planned.
#[derive(Debug, Error)]
pub enum MotionError {
    #[error(transparent)]
    Toolpath(#[from] ToolpathError),
    #[error(transparent)]
    Trajectory(#[from] TrajectoryError),
    #[error(transparent)]
    Collision(#[from] clearance::Collision),
}

/// Toolpath and joint trajectory for a plan (fragments of block indices, or of node ids
/// of a graph part: welded along its beads). Errors name the block (node) and the pose.
pub fn plan_motion(
    part: &Part,
    fragments: &[Vec<usize>],
    settings: &ProcessSettings,
    robot: &Robot,
) -> Result<(Toolpath, JointTrajectory), MotionError> {
    plan_motion_timed(part, fragments, settings, robot, None)
}

/// [`plan_motion`] with the robot timed to a schedule: each weld path's arc strikes at
/// `arc_on_at_s[f]` s after the first's (the thermal model's time line), the robot
/// waiting at the approach point for it; a transit slower than that is an error.
pub fn plan_motion_timed(
    part: &Part,
    fragments: &[Vec<usize>],
    settings: &ProcessSettings,
    robot: &Robot,
    arc_on_at_s: Option<&[f64]>,
) -> Result<(Toolpath, JointTrajectory), MotionError> {
    let robot = robot.clone().with_solver(settings.ik_solver);
    // A graph part is welded along its beads' centre lines, a cube part through the
    // blocks' top centres.
    let mut tp = match part.bead_part() {
        Some(beads) => {
            let routes =
                toolpath::beads::routes_of_graph_plan(beads, fragments, settings.weld_speed_mm_s)?;
            toolpath::build_routes(
                &routes,
                settings,
                settings.plate.isometry(),
                &robot.base_link,
            )?
        }
        None => {
            let passes = toolpath::passes_from_plan(part, fragments);
            let timing = WeldTiming::of_plan(part, settings);
            toolpath::build(&passes, settings, timing, &robot.base_link)?
        }
    };
    let traj =
        trajectory::plan_trajectory(&robot, &mut tp, settings, arc_on_at_s).map_err(|mut t| {
            if let Some(at) = t.at_mut() {
                // A pose's point is its deposit's position in the weld path.
                at.block = fragments
                    .get(at.fragment)
                    .and_then(|f| f.get(at.point))
                    .map(|&b| part.deposit_name(b));
            }
            MotionError::Trajectory(t)
        })?;
    clearance::check_moves(
        part,
        fragments,
        &tp,
        &settings.plate.isometry(),
        settings.torch.as_ref(),
    )?;
    Ok((tp, traj))
}

/// The torch speed while welding a plan, m/s: the process settings' weld speed, else one
/// block length per block time (a graph part: one bead width, as its toolpath welds).
pub fn weld_speed(part: &Part, settings: &ProcessSettings) -> f64 {
    match settings.weld_speed_mm_s {
        Some(v) => v / 1000.0,
        None => part.block_mm[0] / 1000.0 / part.thermal.block_time_s,
    }
}

/// Toolpath and joint trajectory for any weld passes (block plans, layer trails), timed
/// to `arc_on_at_s` as in [`plan_motion_timed`] when given.
pub fn plan_passes(
    passes: &[WeldPass],
    timing: WeldTiming,
    settings: &ProcessSettings,
    robot: &Robot,
    arc_on_at_s: Option<&[f64]>,
) -> Result<(Toolpath, JointTrajectory), MotionError> {
    let robot = robot.clone().with_solver(settings.ik_solver);
    let mut tp = toolpath::build(passes, settings, timing, &robot.base_link)?;
    let traj = trajectory::plan_trajectory(&robot, &mut tp, settings, arc_on_at_s)?;
    Ok((tp, traj))
}

/// Writes `DIR/toolpath.yaml` and `DIR/trajectory.yaml` (creating DIR).
pub fn write_outputs(dir: &Path, tp: &Toolpath, traj: &JointTrajectory) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(dir.join("toolpath.yaml"), tp.to_yaml())?;
    std::fs::write(dir.join("trajectory.yaml"), traj.to_yaml())?;
    Ok(())
}
