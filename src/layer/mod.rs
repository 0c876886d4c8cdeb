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
//! (`crate::motion::plan_layer_motion`) and [`messages`] to recordings and ROS 2.

pub mod fem;
pub mod format;
pub mod improve;
pub mod mesh;
pub mod messages;
#[cfg(feature = "milp")]
pub mod milp;
pub mod model;
pub mod output;
pub mod plot;

pub mod search;
pub mod symmetry;

pub use format::{Layer, LayerError};
pub use model::{Model, Move, Trail};
pub use search::{search, SearchOptions, SearchResult};
