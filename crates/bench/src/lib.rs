//! Benchmark families for the planner: parts shaped like what a cell welds (tubes, open
//! boxes, double tubes, L and T walls, cups), generated at a given size from a seed, with
//! t8/5 windows taken from a random valid plan, so a feasible plan is known to exist
//! ([`generate`]); and the per-family summary of timed runs ([`summary`]).

pub mod generate;
mod rng;
pub mod summary;

pub use generate::{generate, Family, GenerateError, Generated, Spec};
pub use summary::{summarize, Sample, Summary};
