//! The one pipeline the `waam` CLI and the ROS 2 node both run:
//! input → part → plan → check → toolpath → joint trajectory.
//!
//! Each stage is a function of the stage before: [`read_input`] turns a part document or a
//! mesh into a [`Part`], the planner (`waam-planner`) finds fragments, [`check_plan`] checks
//! them against the plan rules and every t8/5 window before anything goes further, and
//! [`Cell::motion`] turns a checked plan into a [`Planned`] (toolpath and validated joint
//! trajectory). Nothing here knows ROS: `waam-ros` turns a [`Planned`] into messages.

use nalgebra::Isometry3;
use thiserror::Error;

use waam_mesh::{voxelize_indexed, Units, VoxelizeOptions, WindowRule};
use waam_motion::robot::Robot;
use waam_motion::toolpath::{ProcessSettings, Toolpath};
use waam_motion::trajectory::JointTrajectory;
use waam_motion::{plan_motion, weld_speed, MotionError};
use waam_part::graph::WeldGraph;
use waam_part::plan::{Invalid, Plan};
use waam_part::{BlockDisplay, Part, PartError, Window};
use waam_planner::Stats;
use waam_thermal::{self as thermal, ThermalModel};

/// The robot the project ships (`urdf/waam_robot.urdf`), used when none is named.
pub const BUNDLED_URDF: &str = include_str!("../../../urdf/waam_robot.urdf");

/// Why a stage of the pipeline stopped.
#[derive(Debug, Error)]
pub enum PipelineError {
    #[error("bad part document: {0}")]
    Document(#[from] PartError),
    #[error("bad part mesh: {0}")]
    Mesh(#[from] waam_mesh::MeshError),
    #[error("the planner's plan is invalid: {0}")]
    Invalid(#[from] Invalid),
    #[error("the planner's plan cannot be simulated: {0}")]
    NotCooled(#[from] thermal::NotCooled),
    #[error("the planner's plan breaks the t8/5 window of block {0}")]
    Infeasible(BlockDisplay),
    #[error("no robot motion for the plan: {0}")]
    Motion(#[from] MotionError),
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

/// How a mesh becomes a part: the block pitch, the t8/5 window every block gets, and the
/// part's max_fragments.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshSettings {
    pub block_mm: [f64; 3],
    pub window: Option<Window>,
    pub max_fragments: usize,
}

impl MeshSettings {
    /// Voxelizes a mesh in metres into the part `name`.
    pub fn voxelize(
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

/// The part an input describes (reading the document or voxelizing the mesh).
pub fn read_input(input: PartInput, mesh: &MeshSettings) -> Result<Part, PipelineError> {
    match input {
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
        } => mesh.voxelize(name, &vertices, &triangles),
    }
}

/// Checks a plan before anything is published or moved: the plan rules, then every t8/5
/// window, with the part's own model (not the planner's word for it).
pub fn check_plan(part: &Part, fragments: &[Vec<usize>]) -> Result<(), PipelineError> {
    let graph = WeldGraph::new(part);
    Plan::from_indices(part, fragments).validate(part, &graph)?;
    let model = ThermalModel::new(part, &graph);
    let outcome = thermal::simulate(&model, fragments)?;
    match outcome.violation {
        Some(v) => Err(PipelineError::Infeasible(BlockDisplay(part.block(v.block)))),
        None => Ok(()),
    }
}

/// A plan the planner found, before its check.
#[derive(Debug, Clone)]
pub struct Found {
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
    pub found: Found,
    pub toolpath: Toolpath,
    pub trajectory: JointTrajectory,
    /// The part frame in the robot's base link (m).
    pub plate: Isometry3<f64>,
    /// TCP speeds, m/s.
    pub weld_speed: f64,
    pub transit_speed: f64,
}

/// The cell a plan is welded in: process settings and robot.
#[derive(Debug, Clone)]
pub struct Cell {
    pub settings: ProcessSettings,
    pub robot: Robot,
}

impl Cell {
    /// Checks `found` ([`check_plan`]) and plans its motion.
    pub fn motion(&self, part: Part, found: Found) -> Result<Planned, PipelineError> {
        check_plan(&part, &found.fragments)?;
        let (toolpath, trajectory) = self.plan_motion(&part, &found.fragments)?;
        Ok(Planned {
            plate: self.settings.plate.isometry(),
            weld_speed: weld_speed(&part, &self.settings),
            transit_speed: self.settings.transit_speed_mm_s / 1000.0,
            part,
            found,
            toolpath,
            trajectory,
        })
    }

    /// The toolpath and validated joint trajectory of fragments whose plan rules the caller
    /// has checked (`waam motion` of a given plan).
    pub fn plan_motion(
        &self,
        part: &Part,
        fragments: &[Vec<usize>],
    ) -> Result<(Toolpath, JointTrajectory), MotionError> {
        plan_motion(part, fragments, &self.settings, &self.robot)
    }
}
