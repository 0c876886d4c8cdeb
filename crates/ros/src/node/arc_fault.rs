//! Arc faults from the welding power source (`closed_loop.arc_fault_topic`): the arc went
//! out on its own — a wire fault, an arc loss — during a weld path. The sensor thread
//! [`report`](ArcFaults::report)s each good one; while a weld goal runs the execution has
//! [`arm`](ArcFaults::arm)ed the latch with that goal's cancel, which a fault raises at once
//! (the robot stops; a FollowJointTrajectory goal is cancelled on the server). Faults while
//! no weld goal runs are recorded and reported on `/diagnostics`, but stop nothing: the
//! arc is off anyway.

use std::sync::{Arc, Mutex};

use super::worker::Cancel;

/// The latch between the sensor thread and the execution.
#[derive(Clone, Default)]
pub struct ArcFaults(Arc<Mutex<Latch>>);

#[derive(Default)]
struct Latch {
    /// Stamps of the faults since the weld goal was armed, s on the ROS clock.
    stamps: Vec<f64>,
    /// The running weld goal's cancel.
    goal: Option<Cancel>,
}

impl ArcFaults {
    pub fn new() -> ArcFaults {
        ArcFaults::default()
    }

    fn latch(&self) -> std::sync::MutexGuard<'_, Latch> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The arc went out at `stamp_s`. Returns whether a weld goal was running (and is now
    /// cancelled).
    pub fn report(&self, stamp_s: f64) -> bool {
        let mut latch = self.latch();
        match &latch.goal {
            Some(goal) => {
                goal.cancel();
                latch.stamps.push(stamp_s);
                true
            }
            None => false,
        }
    }

    /// A weld goal runs from now on: a fault cancels `goal`. Earlier faults are forgotten.
    pub fn arm(&self, goal: &Cancel) {
        let mut latch = self.latch();
        latch.stamps.clear();
        latch.goal = Some(goal.clone());
    }

    /// The weld goal ended: the first fault that came while it ran, if any.
    pub fn disarm(&self) -> Option<f64> {
        let mut latch = self.latch();
        latch.goal = None;
        let first = latch.stamps.first().copied();
        latch.stamps.clear();
        first
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fault_cancels_only_the_armed_weld_goal() {
        let faults = ArcFaults::new();
        assert!(!faults.report(1.0), "no weld goal runs");
        let execution = Cancel::new();
        let goal = execution.child();
        faults.arm(&goal);
        assert!(!goal.is_cancelled());
        assert!(faults.report(2.5));
        assert!(faults.report(2.7));
        assert!(goal.is_cancelled() && !execution.is_cancelled());
        assert_eq!(faults.disarm(), Some(2.5));
        assert_eq!(faults.disarm(), None);
        // The execution's cancel reaches its goals.
        let goal = execution.child();
        execution.cancel();
        assert!(goal.is_cancelled());
    }
}
