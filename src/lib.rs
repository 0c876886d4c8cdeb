//! waam-planner: weld-path planning for Wire Arc Additive Manufacturing.
//!
//! Data flows one way: a [`part::Part`] (blocks on a grid, from a part file or a mesh)
//! becomes a [`graph::WeldGraph`]; the planner finds a [`plan::Plan`] of at most k weld
//! paths; the [`thermal`] model checks its t8/5 cooling windows; later stages turn the
//! plan into torch poses, robot trajectories, ROS 2 messages and recordings.

pub mod bag;
pub mod graph;
pub mod layer;
pub mod mesh;
pub mod motion;
pub mod msgs;
pub mod node;
pub mod part;
pub mod part_writer;
pub mod plan;
pub mod planner;
pub mod plot;
pub mod replay;
pub mod robot;
pub mod thermal;
pub mod toolpath;
pub mod trajectory;
