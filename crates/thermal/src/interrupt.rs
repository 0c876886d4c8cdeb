//! [`Interrupt`]: what stops a long run early (a deadline, a cancel flag).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// What stops a long run early: a deadline, a cancel flag, or both (the default, neither:
/// it runs to its end). The planner's `timeout` and `cancel`, for the stages that
/// simulate after it (check, plot, motion).
#[derive(Debug, Clone, Default)]
pub struct Interrupt {
    pub deadline: Option<Instant>,
    pub cancel: Option<Arc<AtomicBool>>,
}

impl Interrupt {
    /// Stops `timeout` from now (none: never; one too long for a clock: never either).
    pub fn after(timeout: Option<Duration>) -> Interrupt {
        Interrupt {
            deadline: timeout.and_then(|t| Instant::now().checked_add(t)),
            cancel: None,
        }
    }

    /// Also stops once `flag` is raised.
    pub fn with_cancel(mut self, flag: Option<Arc<AtomicBool>>) -> Interrupt {
        self.cancel = flag;
        self
    }

    /// Whether the deadline has passed or the flag is raised.
    pub fn reached(&self) -> bool {
        self.cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
            || self.deadline.is_some_and(|d| Instant::now() >= d)
    }
}
