//! The one pipeline the `waam` CLI and the ROS 2 node both run:
//! input → part → plan → check → toolpath → joint trajectory.
//!
//! Each stage is a function of the stage before: [`read_input`] turns a part document or a
//! mesh into a [`Part`], the planner (`waam-planner`) finds fragments, [`check_plan`] checks
//! them against the plan rules and every t8/5 window before anything goes further, and
//! [`Cell::motion`] turns a checked plan into a [`Planned`] (toolpath and validated joint
//! trajectory). Nothing here knows ROS: `waam-ros` turns a [`Planned`] into messages.
//!
//! [`plan`] runs these stages from a part on, for every caller (the CLI's `plan`, its first
//! run, `replay`, `bench scale` and the node): the planner with the cell's torch and robot
//! checks, then, with a cell, the check and the motion. [`CellSource::load`] sets a cell up
//! (process settings, URDF, TCP, joint limits, torch).
//!
//! One time line: the robot is timed to the thermal model (each weld path's arc strikes
//! at the model's time, the robot waiting at the approach point; a transit too slow for
//! `transit_time_s` is an error), and the plan is checked again on the time line the
//! motion executes — dwells included — with the same model and t8/5 rules
//! ([`check_executed`]). A plan that fails there is never returned.

use nalgebra::Isometry3;
use thiserror::Error;

use std::sync::Arc;

use waam_access::{Obstacle, TorchAccess};
use waam_mesh::{voxelize_indexed, Units, VoxelizeOptions, WindowRule};
use waam_motion::robot::Robot;
use waam_motion::toolpath::{ExecutedTimes, ProcessSettings, Toolpath};
use waam_motion::trajectory::{JointTrajectory, TrajectoryError};
use waam_motion::{plan_motion_timed, weld_speed, MotionError};
use waam_part::graph::WeldGraph;
use waam_part::plan::{Invalid, Plan};
use waam_part::{Part, PartError, Window};
use waam_planner::{ExecutedCheck, Rejection, Stats};
use waam_thermal::{self as thermal, ThermalModel, Timeline};

pub use waam_thermal::Interrupt;

mod cell;
mod run;

pub use cell::{CellError, CellSource};
pub use run::{plan, planner_options, Objective, Options, Outcome, Progress};

/// The robot the project ships (`urdf/waam_robot.urdf`), used when none is named.
pub const BUNDLED_URDF: &str = include_str!("../../../urdf/waam_robot.urdf");

/// Why a stage of the pipeline stopped.
#[derive(Debug, Error)]
pub enum PipelineError {
    #[error("bad part document: {0}")]
    Document(#[from] PartError),
    #[error("bad graph part document: {0}")]
    BeadDocument(#[from] waam_part::BeadPartError),
    #[error("bad part mesh: {0}")]
    Mesh(#[from] waam_mesh::MeshError),
    #[error("cannot slice the part mesh into beads: {0}")]
    Slice(#[from] waam_slice::SliceError),
    /// The planner could not run (the part too large for its memory limit, ...).
    #[error(transparent)]
    Planner(#[from] waam_planner::PlanError),
    #[error("the planner's plan is invalid: {0}")]
    Invalid(#[from] Invalid),
    #[error("the planner's plan cannot be simulated: {0}")]
    NotCooled(#[from] thermal::NotCooled),
    /// A deposit's window broken: "block [x,y,z]" or "node 12" ([`Part::deposit_name`]).
    #[error("the planner's plan breaks the t8/5 window of {0}")]
    Infeasible(String),
    #[error("the plan breaks the t8/5 window of {block} on the robot's executed time line ({kind} t8/5 {t85_s:.2} s, window [{min_s}, {max_s}] s, at {time_s:.2} s): the arc-on and arc-off dwells shift the deposits the thermal model assumed")]
    InfeasibleExecuted {
        block: String,
        kind: &'static str,
        t85_s: f64,
        min_s: f64,
        max_s: f64,
        time_s: f64,
    },
    #[error("the executed time line cannot be simulated: {0}")]
    Timeline(#[from] thermal::SimulateError),
    #[error("no robot motion for the plan: {0}")]
    Motion(#[from] MotionError),
    /// The deadline passed or the job was cancelled (see [`Interrupt`]).
    #[error("stopped by the time limit or a cancel while {0}")]
    Interrupted(&'static str),
    #[error("the torch cannot weld this plan: it cannot reach {block} (deposit {deposit} of {total}): {obstacle} stands in its way ({torch}); `--no-torch` or `torch: null` in the process settings turns the torch off")]
    TorchBlocked {
        block: String,
        /// Its position in the weld order, from 1.
        deposit: usize,
        total: usize,
        /// "block [x,y,z], deposited before it," ("node 12, ...") or "the plate".
        obstacle: String,
        torch: String,
    },
}

/// A part as it arrives: a part document, or a triangle mesh in metres.
#[derive(Debug, Clone)]
pub enum PartInput {
    Document(String),
    Mesh {
        name: String,
        vertices: Vec<[f64; 3]>,
        triangles: Vec<[u32; 3]>,
    },
}

impl PartInput {
    /// A few words on what arrived, for status and logs.
    pub fn describe(&self) -> String {
        match self {
            PartInput::Document(text) => format!("part document, {} bytes", text.len()),
            PartInput::Mesh {
                vertices,
                triangles,
                ..
            } => format!(
                "mesh, {} vertices, {} triangles",
                vertices.len(),
                triangles.len()
            ),
        }
    }
}

/// How a mesh becomes a part: voxelized at the block pitch, or, with `bead_mm`, sliced
/// into beads along its contours (a graph part); the t8/5 window every deposit gets, and
/// the part's max_fragments.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshSettings {
    pub block_mm: [f64; 3],
    /// Bead width W and layer height H, mm: slice instead of voxelizing.
    pub bead_mm: Option<[f64; 2]>,
    pub window: Option<Window>,
    pub max_fragments: usize,
}

impl MeshSettings {
    /// The part `name` of a mesh in metres: sliced into beads with `bead_mm`, else
    /// voxelized.
    pub fn part_of_mesh(
        &self,
        name: String,
        vertices: &[[f64; 3]],
        triangles: &[[u32; 3]],
    ) -> Result<Part, PipelineError> {
        let Some(bead) = self.bead_mm else {
            return self.voxelize(name, vertices, triangles);
        };
        let mesh = waam_mesh::TriangleMesh::from_indexed(vertices, triangles, Units::M)?;
        let options = waam_slice::SliceOptions {
            max_fragments: self.max_fragments,
            ..waam_slice::SliceOptions::new(name, bead)
        };
        let mut beads = waam_slice::slice(&mesh, &options)?.part;
        if let Some(window) = self.window {
            for i in 0..beads.nodes.len() {
                beads.set_window(i, window);
            }
        }
        for w in &beads.warnings {
            tracing::warn!("part mesh: {w}");
        }
        Ok(Part::of_beads(beads)?)
    }

    /// Voxelizes a mesh in metres into the part `name`.
    fn voxelize(
        &self,
        name: String,
        vertices: &[[f64; 3]],
        triangles: &[[u32; 3]],
    ) -> Result<Part, PipelineError> {
        let mut options = VoxelizeOptions::new(name, self.block_mm);
        options.max_fragments = self.max_fragments;
        options.windows = self
            .window
            .map(WindowRule::everywhere)
            .into_iter()
            .collect();
        let voxelized = voxelize_indexed(vertices, triangles, Units::M, &options)?;
        for w in &voxelized.warnings {
            tracing::warn!("part mesh: {w}");
        }
        Ok(voxelized.part)
    }
}

/// The part an input describes: reading the document (a block part, or a graph part of
/// beads), or voxelizing or slicing the mesh ([`MeshSettings::part_of_mesh`]).
pub fn read_input(input: PartInput, mesh: &MeshSettings) -> Result<Part, PipelineError> {
    match input {
        PartInput::Document(text) if waam_part::is_bead_part(&text) => {
            let beads = waam_part::BeadPart::parse(&text)?;
            for w in &beads.warnings {
                tracing::warn!("part {}: {w}", beads.name);
            }
            Ok(Part::of_beads(beads)?)
        }
        PartInput::Document(text) => {
            let part = Part::parse(&text)?;
            for w in &part.warnings {
                tracing::warn!("part {}: {w}", part.name);
            }
            Ok(part)
        }
        PartInput::Mesh {
            name,
            vertices,
            triangles,
        } => mesh.part_of_mesh(name, &vertices, &triangles),
    }
}

/// Checks a plan before anything is published or moved: the plan rules, then every t8/5
/// window, with the part's own model (not the planner's word for it).
pub fn check_plan(part: &Part, fragments: &[Vec<usize>]) -> Result<(), PipelineError> {
    check_plan_until(part, fragments, &Interrupt::default())
}

/// [`check_plan`], stopped by `interrupt` ([`PipelineError::Interrupted`]).
pub fn check_plan_until(
    part: &Part,
    fragments: &[Vec<usize>],
    interrupt: &Interrupt,
) -> Result<(), PipelineError> {
    let graph = WeldGraph::new(part);
    Plan::from_indices(part, fragments).validate(part, &graph)?;
    let model = ThermalModel::new(part, &graph);
    let outcome = thermal::simulate_until(
        &model,
        fragments,
        interrupt.deadline,
        interrupt.cancel.clone(),
    )?
    .ok_or(PipelineError::Interrupted(
        "checking the plan's t8/5 windows",
    ))?;
    match outcome.violation {
        Some(v) => Err(PipelineError::Infeasible(part.deposit_name(v.block))),
        None => Ok(()),
    }
}

/// Checks that the torch of `settings` (none: nothing to check) reaches every block of the
/// plan past the blocks deposited before it and the plate: the planner's own check, for
/// plans that enter from outside (`waam motion`, `waam publish --plan`) as much as for its
/// own.
pub fn check_torch(
    part: &Part,
    fragments: &[Vec<usize>],
    settings: &ProcessSettings,
) -> Result<(), PipelineError> {
    let Some(setup) = settings.torch_setup() else {
        return Ok(());
    };
    let access = TorchAccess::new(part, &setup);
    match access.first_blocked(fragments.iter().flatten().copied()) {
        None => Ok(()),
        Some(b) => Err(PipelineError::TorchBlocked {
            block: part.deposit_name(b.block),
            deposit: b.position + 1,
            total: part.len(),
            obstacle: match b.obstacle {
                Obstacle::Plate => "the plate".into(),
                Obstacle::Block(o) => format!("{}, deposited before it,", part.deposit_name(o)),
            },
            torch: setup.describe(),
        }),
    }
}

/// The thermal model's time line of a plan as arc-on times, s after the first weld path's:
/// the schedule the robot is timed to.
pub fn modelled_arc_on_s(part: &Part, fragments: &[Vec<usize>]) -> Vec<f64> {
    let graph = WeldGraph::new(part);
    let model = ThermalModel::new(part, &graph);
    Timeline::modelled(&model, fragments)
        .deposits
        .iter()
        .map(|d| d[0] as f64 * model.dt)
        .collect()
}

/// Checks a plan on the time line its toolpath executes (deposits and arc-offs read from
/// the poses, each rounded to the nearest Euler step), with the part's model and t8/5
/// rules. Returns that time line.
pub fn check_executed(
    part: &Part,
    fragments: &[Vec<usize>],
    toolpath: &Toolpath,
    interrupt: &Interrupt,
) -> Result<Timeline, PipelineError> {
    check_executed_times(part, fragments, &toolpath.executed_times(), interrupt)
}

/// [`check_executed`] on given deposit and arc-off times (s): a time line the robot did not
/// follow exactly as its toolpath says (a weld path cut short by an arc fault, the rest
/// moved on from when the arc went out).
pub fn check_executed_times(
    part: &Part,
    fragments: &[Vec<usize>],
    times: &ExecutedTimes,
    interrupt: &Interrupt,
) -> Result<Timeline, PipelineError> {
    let (timeline, violation) = simulate_executed(part, fragments, times, interrupt)?;
    match violation {
        Some(v) => Err(PipelineError::InfeasibleExecuted {
            block: part.deposit_name(v.block),
            kind: match v.kind {
                thermal::ViolationKind::Min => "below min_s:",
                thermal::ViolationKind::Max => "over max_s:",
            },
            t85_s: v.t85_s,
            min_s: v.window.min_s,
            max_s: v.window.max_s,
            time_s: v.time_s,
        }),
        None => Ok(timeline),
    }
}

/// The executed time line of a plan's toolpath and the first violation on it.
fn simulate_executed(
    part: &Part,
    fragments: &[Vec<usize>],
    times: &ExecutedTimes,
    interrupt: &Interrupt,
) -> Result<(Timeline, Option<thermal::Violation>), PipelineError> {
    let graph = WeldGraph::new(part);
    let model = ThermalModel::new(part, &graph);
    let timeline = Timeline::from_seconds(&times.deposits_s, &times.arc_off_s, model.dt)
        .map_err(thermal::SimulateError::from)?;
    let outcome = thermal::simulate_on_until(&model, fragments, &timeline, interrupt)?.ok_or(
        PipelineError::Interrupted("checking the plan on the robot's executed time line"),
    )?;
    Ok((timeline, outcome.violation))
}

/// The first `n` deposits of a plan, as fragments.
fn first_deposits(fragments: &[Vec<usize>], n: usize) -> Vec<Vec<usize>> {
    let mut left = n;
    let mut out = Vec::new();
    for f in fragments {
        if left == 0 {
            break;
        }
        let take = left.min(f.len());
        out.push(f[..take].to_vec());
        left -= take;
    }
    out
}

/// The plan chosen to be welded, before its check: the planner's ([`ChosenPlan::from_report`])
/// or one given (`waam publish --plan`).
#[derive(Debug, Clone)]
pub struct ChosenPlan {
    /// Fragments of block indices, in weld order.
    pub fragments: Vec<Vec<usize>>,
    /// What the planner did to find it.
    pub stats: Stats,
    /// Whether it is proven best.
    pub proven: bool,
    /// Smallest distance of a t8/5 value to its window bounds, s (+inf without windows).
    pub worst_margin_s: f64,
}

/// A planned part, checked, with its motion: ready to publish, record, export and execute.
#[derive(Debug, Clone)]
pub struct Planned {
    pub part: Part,
    pub found: ChosenPlan,
    pub toolpath: Toolpath,
    pub trajectory: JointTrajectory,
    /// The part frame in the robot's base link (m).
    pub plate: Isometry3<f64>,
    /// TCP speeds, m/s.
    pub weld_speed: f64,
    pub transit_speed: f64,
    /// The executed time line the plan was checked on (Euler steps from the first
    /// deposit; the part's `block_time_s / substeps` each).
    pub timeline: Timeline,
}

/// The cell a plan is welded in: process settings and robot.
#[derive(Debug, Clone)]
pub struct Cell {
    pub settings: ProcessSettings,
    pub robot: Robot,
}

impl Cell {
    /// Checks `found` ([`check_plan`], [`check_torch`]), plans its motion timed to the
    /// thermal model and checks the plan again on the motion's executed time line
    /// ([`check_executed`]).
    pub fn motion(&self, part: Part, found: ChosenPlan) -> Result<Planned, PipelineError> {
        self.motion_until(part, found, &Interrupt::default())
    }

    /// [`Cell::motion`], stopped by `interrupt` ([`PipelineError::Interrupted`]): checked in
    /// every simulation and between the stages.
    pub fn motion_until(
        &self,
        part: Part,
        found: ChosenPlan,
        interrupt: &Interrupt,
    ) -> Result<Planned, PipelineError> {
        check_plan_until(&part, &found.fragments, interrupt)?;
        if interrupt.reached() {
            return Err(PipelineError::Interrupted("planning the robot motion"));
        }
        let (toolpath, trajectory) = self.plan_motion_until(&part, &found.fragments, interrupt)?;
        let timeline = check_executed(&part, &found.fragments, &toolpath, interrupt)?;
        Ok(Planned {
            timeline,
            plate: self.settings.plate.isometry(),
            weld_speed: weld_speed(&part, &self.settings),
            transit_speed: self.settings.transit_speed_mm_s / 1000.0,
            part,
            found,
            toolpath,
            trajectory,
        })
    }

    /// The planner's check of a candidate on this cell's robot ([`Cell::rejection`]), for
    /// [`waam_planner::Options::executed`].
    /// Its simulations stop at `interrupt` (the planner's own), as a candidate not rejected.
    pub fn executed_check(&self, part: &Part, interrupt: Interrupt) -> ExecutedCheck {
        let (cell, part) = (self.clone(), part.clone());
        ExecutedCheck(Arc::new(move |fragments: &[Vec<usize>]| {
            cell.rejection(&part, fragments, &interrupt)
        }))
    }

    /// Why the robot cannot weld a candidate on the thermal model's time line, as the plans
    /// that fail the same way; `None` when it can (or fails otherwise: [`Cell::motion`]
    /// reports that). Two failures are learned:
    /// - *A transit the robot cannot make in `transit_time_s`* from weld path f to f + 1:
    ///   this plan only. The transit's poses depend on the weld paths up to f and the first
    ///   two blocks of f + 1 alone, but its joint path on the arm configuration the motion
    ///   stage picks for the whole toolpath, which later weld paths can change; a shorter
    ///   clause could rule out a plan the robot can weld.
    /// - *A window broken on the executed time line* (the dwells shift the deposits): the
    ///   plans that begin with the same weld paths, closed, up to the one that deposited the
    ///   last block before the violation. The robot is timed to the model, so the executed
    ///   time line up to the next weld path's arc-on depends on those weld paths only, not
    ///   on the arm.
    ///
    /// And, when the cell's torch is not the planner's (or reaches where the planner's check
    /// does not look), the torch's failures, which depend on the toolpath's poses only:
    /// - *a block the torch cannot reach*: the plans that deposit the same blocks in the
    ///   same order up to it (the access check depends on what stands before it);
    /// - *a move with the arc off the torch cannot make*: into weld path f, the plans with
    ///   the same weld paths before f and the same first two blocks of f (as for a
    ///   transit); a retract from f (or the last move), the same weld paths up to f, closed.
    pub fn rejection(
        &self,
        part: &Part,
        fragments: &[Vec<usize>],
        interrupt: &Interrupt,
    ) -> Option<Rejection> {
        let toolpath = match self.plan_motion(part, fragments) {
            Ok((toolpath, _)) => toolpath,
            Err(
                e @ PipelineError::Motion(MotionError::Trajectory(
                    TrajectoryError::TransitTooLong { fragment, .. },
                )),
            ) => {
                // `fragment` counts from 1: the transit leaves fragments[fragment - 1].
                fragments.get(fragment)?;
                // The joint path depends on the arm configuration the motion stage picks
                // for the whole toolpath, so only this very plan is known to fail.
                return Some(Rejection {
                    prefix: fragments.to_vec(),
                    closed: true,
                    reason: e.to_string(),
                });
            }
            Err(e @ PipelineError::TorchBlocked { deposit, .. }) => {
                return Some(Rejection {
                    prefix: first_deposits(fragments, deposit),
                    closed: false,
                    reason: e.to_string(),
                });
            }
            Err(e @ PipelineError::Motion(MotionError::Collision(_))) => {
                let PipelineError::Motion(MotionError::Collision(c)) = &e else {
                    unreachable!("matched above")
                };
                let f = c.fragment.min(fragments.len() - 1);
                let (prefix, closed) = if c.what == "retract" || f + 1 == fragments.len() {
                    (fragments[..=f].to_vec(), true)
                } else {
                    let mut prefix = fragments[..f].to_vec();
                    prefix.push(fragments[f][..fragments[f].len().min(2)].to_vec());
                    (prefix, fragments[f].len() == 1)
                };
                return Some(Rejection {
                    prefix,
                    closed,
                    reason: e.to_string(),
                });
            }
            Err(_) => return None,
        };
        let (_, violation) =
            simulate_executed(part, fragments, &toolpath.executed_times(), interrupt).ok()?;
        let v = violation?;
        // The weld path of the last block deposited before the violation.
        let mut left = v.prefix_len.max(1);
        let upto = fragments
            .iter()
            .position(|f| {
                if left <= f.len() {
                    return true;
                }
                left -= f.len();
                false
            })
            .unwrap_or(fragments.len() - 1);
        Some(Rejection {
            prefix: fragments[..=upto].to_vec(),
            closed: true,
            reason: format!(
                "the plan breaks the t8/5 window of {} on the robot's executed time line \
                 (at {:.2} s)",
                part.deposit_name(v.block),
                v.time_s
            ),
        })
    }

    /// [`Cell::plan_motion`], given up at `interrupt` ([`PipelineError::Interrupted`]). The
    /// motion stages (toolpath, inverse kinematics, clearance) have no stopping points of
    /// their own and take seconds on a part of 10^4 blocks (`plan --robot --timeout 5`
    /// answered after 9.5 s): with a deadline or a cancel they run on a thread of their own
    /// that is left behind when the interrupt comes; it ends on its own.
    fn plan_motion_until(
        &self,
        part: &Part,
        fragments: &[Vec<usize>],
        interrupt: &Interrupt,
    ) -> Result<(Toolpath, JointTrajectory), PipelineError> {
        let stopped = || PipelineError::Interrupted("planning the robot motion");
        if interrupt.deadline.is_none() && interrupt.cancel.is_none() {
            return self.plan_motion(part, fragments);
        }
        if interrupt.reached() {
            return Err(stopped());
        }
        let (cell, part, fragments) = (self.clone(), part.clone(), fragments.to_vec());
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let _ = tx.send(cell.plan_motion(&part, &fragments));
        });
        loop {
            match rx.recv_timeout(std::time::Duration::from_millis(50)) {
                Ok(motion) => return motion,
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) if !interrupt.reached() => {}
                Err(_) => return Err(stopped()),
            }
        }
    }

    /// The toolpath and validated joint trajectory of fragments whose plan rules the caller
    /// has checked (`waam motion` of a given plan), timed to the thermal model's time line;
    /// refused when the settings' torch cannot reach a block ([`check_torch`]).
    pub fn plan_motion(
        &self,
        part: &Part,
        fragments: &[Vec<usize>],
    ) -> Result<(Toolpath, JointTrajectory), PipelineError> {
        check_torch(part, fragments, &self.settings)?;
        let schedule = modelled_arc_on_s(part, fragments);
        Ok(plan_motion_timed(
            part,
            fragments,
            &self.settings,
            &self.robot,
            Some(&schedule),
        )?)
    }
}
