//! Thick-wall layers: one continuous weld trail (with the fewest deadheading moves) over
//! a layer of walls, chosen to keep a finite-element temperature field near a target —
//! the problem of Schmidt, Buhl and Fügenschuh, "A Finite Element Approach for Trajectory
//! Optimization in Wire-Arc Additive Manufacturing" (2021), solved to proven optimality
//! by branch and bound instead of a MILP.
//!
//! Data flows: [`format::Layer`] (the layer file) → [`mesh::Mesh`] → [`fem`] matrices and
//! the implicit-Euler [`fem::Heat`] stepper → [`model::Model`] (torch positions, loads,
//! schedule, objective) → [`search::search`] → a [`model::Trail`], written by
//! [`output`] and drawn by [`plot`]; [`model::Model::passes`] hands it to the toolpath
//! (`waam_motion::plan_layer_motion`) and [`messages`] to recordings and ROS 2.
//!
//! Parts: [`slice`] cuts a mesh into layers (one layer graph per section) and [`part`]
//! plans them bottom up, each layer starting from the heat the layer below left.

pub mod assignment;
pub mod fem;
pub mod format;
pub mod improve;
pub mod mesh;
#[cfg(feature = "milp")]
pub mod milp;
pub mod model;
pub mod output;
pub mod part;
pub mod search;
pub mod slice;
pub mod symmetry;

pub use format::{Layer, LayerError};
pub use model::{Model, Move, Trail};
pub use search::{search, SearchOptions, SearchResult};

use waam_motion::robot::Robot;
use waam_motion::toolpath::{ProcessSettings, Toolpath, WeldTiming};
use waam_motion::trajectory::JointTrajectory;
use waam_motion::{plan_passes, MotionError};

/// Toolpath and joint trajectory for a layer trail: one pass per run between deadheading
/// moves (the arc is off on each of them), welded at the layer's own weld speed so the torch
/// moves as the finite-element model assumed. Errors name the wall.
pub fn plan_layer_motion(
    model: &Model,
    trail: &Trail,
    settings: &ProcessSettings,
    robot: &Robot,
) -> Result<(Toolpath, JointTrajectory), MotionError> {
    plan_layer_motion_at(model, trail, 0.0, settings, robot)
}

/// [`plan_layer_motion`] for a layer of a part: the torch welds at height `z_mm` above the
/// plate (the layer's cutting height).
pub fn plan_layer_motion_at(
    model: &Model,
    trail: &Trail,
    z_mm: f64,
    settings: &ProcessSettings,
    robot: &Robot,
) -> Result<(Toolpath, JointTrajectory), MotionError> {
    let (mut passes, segments) = model.passes_with_segments(trail);
    for pass in &mut passes {
        for p in &mut pass.points_mm {
            p.z = z_mm;
        }
    }
    let timing = WeldTiming::Speed(model.layer.process.weld_speed_mm_s);
    plan_passes(&passes, timing, settings, robot, None).map_err(|mut e| {
        if let MotionError::Trajectory(t) = &mut e {
            if let Some(at) = t.at_mut() {
                at.block = segments
                    .get(at.fragment)
                    .and_then(|f| f.get(at.point))
                    .map(|&s| model.layer.segment_name(s));
            }
        }
        e
    })
}

/// Why a layer's model, bound, trail or cross-check could not be made: a message naming the
/// wall, node or matrix at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct ModelError(pub String);

impl From<String> for ModelError {
    fn from(message: String) -> Self {
        ModelError(message)
    }
}

impl From<&str> for ModelError {
    fn from(message: &str) -> Self {
        ModelError(message.to_string())
    }
}
