//! The lumped thermal model and the t8/5 check of `shared/spec/thermal-model.md`.
//!
//! One temperature per welded block, explicit Euler, written out to the operation so that
//! two programs agree on every verdict: fluxes are summed in face order (-x, +x, -y, +y,
//! -z, +z), then the substrate term, then radiation, exactly as the spec writes them.
//!
//! The simulator is built for the planner, which runs it millions of times:
//! - block i lives in slot i, in the part's (z, y, x) order, so the ±x neighbours are the
//!   slots beside it and the z = 0 blocks come first; a step covers the slots from the
//!   lowest to the highest welded one (an unwelded slot in between is its own neighbour on
//!   every face and stays at ambient);
//! - every slot keeps its six neighbour slots, an absent neighbour pointing at the slot
//!   itself: `T_self - T_self` is exactly 0, so the inner loop needs no branch;
//! - the stepping loop allocates nothing;
//! - [`Simulation::snapshot`] / [`Simulation::restore`] resume from a saved prefix state.
//!
//! Where things are (one module per file, in reading order):
//! - `model.rs`: [`ThermalModel`], the per-part constants, and the t8/5 thresholds;
//! - `simulation.rs`: [`Simulation`] (deposits, the stepping loop, the t8/5 counters) and
//!   [`Snapshot`];
//! - `violation.rs`: what a run reports ([`Violation`], [`Crossing`], [`NotCooled`]);
//! - `interrupt.rs`: [`Interrupt`], a deadline and a cancel flag;
//! - `kernel/`: the step itself, one module per kernel ([`Simd`]: scalar, AVX2, AVX-512)
//!   and the bit-identity test of every kernel against a plain reference of the spec;
//! - `pool.rs`: the worker threads that share a big step;
//! - `timeline.rs`: whole plans, on the spec's time line ([`simulate`]) or on a given one
//!   ([`simulate_on`], [`Timeline`]).

pub mod graph;
mod interrupt;
mod kernel;
mod model;
mod pool;
mod simulation;
#[cfg(test)]
mod testing;
mod timeline;
mod violation;

pub use interrupt::Interrupt;
pub use kernel::Simd;
pub use model::{ThermalModel, HOT_C, TOLERANCE_S, WARM_C};
pub use simulation::{
    default_threads, set_default_threads, BuildState, Simulation, Snapshot, StateError,
    PARALLEL_MIN_SLOTS,
};
pub use timeline::{
    simulate, simulate_in, simulate_keeping_end, simulate_on, simulate_on_until, simulate_until,
    Outcome, SimulateError, Timeline, TimelineError,
};
pub use violation::{Crossing, NotCooled, Phase, Violation, ViolationKind};
pub use waam_part::{ThermalParams, MAX_STEPS};
