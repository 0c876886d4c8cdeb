//! Miscellaneous solver state.
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use crate::solver::SolverError;

/// Satisfiability state.
#[derive(Copy, Clone, Eq, PartialEq, Debug)]
pub enum SatState {
    Unknown,
    Sat,
    Unsat,
    UnsatUnderAssumptions,
}

impl Default for SatState {
    fn default() -> SatState {
        SatState::Unknown
    }
}

/// Miscellaneous solver state.
///
/// Anything larger or any larger group of related state variables should be moved into a separate
/// part of [`Context`](crate::context::Context).
pub struct SolverState {
    pub sat_state: SatState,
    pub formula_is_empty: bool,
    /// Whether solve was called at least once.
    pub solver_invoked: bool,
    pub state_is_invalid: bool,
    pub solver_error: Option<SolverError>,
    /// waam-planner patch: when a solve stops early (`Solver::set_interrupt`).
    pub interrupt: Interrupt,
}

/// waam-planner patch: a deadline and a flag another thread may raise; a solve polls them
/// between conflicts and returns `SolverError::Interrupted` once either is due.
#[derive(Default)]
pub struct Interrupt {
    pub deadline: Option<Instant>,
    pub flag: Option<Arc<AtomicBool>>,
}

impl Interrupt {
    /// Whether the solve under way should stop now.
    pub fn due(&self) -> bool {
        self.flag.as_ref().map_or(false, |f| f.load(Ordering::Relaxed))
            || self.deadline.map_or(false, |d| Instant::now() >= d)
    }
}

impl Default for SolverState {
    fn default() -> SolverState {
        SolverState {
            sat_state: SatState::Unknown,
            formula_is_empty: true,
            solver_invoked: false,
            state_is_invalid: false,
            solver_error: None,
            interrupt: Interrupt::default(),
        }
    }
}
