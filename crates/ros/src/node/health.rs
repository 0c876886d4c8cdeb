//! The node's health on `/diagnostics` (diagnostic_msgs/DiagnosticArray) once a second, as
//! diagnostic_updater nodes report it: a monitor tells a stale node by the silence, and reads
//! the state and the last result without having seen the events on `~/status`.

use std::time::{Duration, Instant};

use waam_messages::status::Status;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};

pub const DIAGNOSTICS: &str = "/diagnostics";
/// How often the health goes out.
pub const PERIOD: Duration = Duration::from_secs(1);

/// How a job ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// A plan, summarised.
    Planned(String),
    /// No plan, and why.
    NoPlan(String),
}

/// What the event loop knows about the node's work.
pub struct Health {
    /// `/namespace/name`: the status's hardware id; `name: planner` its name.
    node: String,
    started: Instant,
    /// The job being planned, if any.
    pub planning: Option<u64>,
    /// The last finished job and its outcome.
    pub last: Option<(u64, Outcome)>,
    pub planned: u64,
    pub failed: u64,
}

impl Health {
    pub fn new(node: String) -> Health {
        Health {
            node,
            started: Instant::now(),
            planning: None,
            last: None,
            planned: 0,
            failed: 0,
        }
    }

    /// The health now: OK, or WARN when the last part got no plan.
    pub fn to_msg(&self, stamp: Time) -> DiagnosticArray {
        let state = match self.planning {
            Some(job) => format!("planning part {job}"),
            None => "idle".to_string(),
        };
        let (level, last) = match &self.last {
            None => (DiagnosticStatus::OK, "no part yet".to_string()),
            Some((job, Outcome::Planned(summary))) => {
                (DiagnosticStatus::OK, format!("part {job}: {summary}"))
            }
            Some((job, Outcome::NoPlan(reason))) => (
                DiagnosticStatus::WARN,
                format!("part {job}: no plan: {reason}"),
            ),
        };
        let mut values = vec![
            KeyValue::new("state", &state),
            KeyValue::new("last_result", &last),
            KeyValue::new("parts_planned", self.planned),
            KeyValue::new("parts_failed", self.failed),
            KeyValue::new(
                "uptime_s",
                format!("{:.0}", self.started.elapsed().as_secs_f64()),
            ),
        ];
        if let Some(job) = self.planning {
            values.push(KeyValue::new("job", job));
        }
        let name = format!("{}: planner", self.node.trim_start_matches('/'));
        Status::new(level, format!("{state}; last: {last}"), values)
            .reported_by(stamp, &name, &self.node)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn state_and_last_result() {
        let mut h = Health::new("/cell1/waam_planner".into());
        let msg = h.to_msg(Time::default());
        assert_eq!(msg.status[0].name, "cell1/waam_planner: planner");
        assert_eq!(msg.status[0].level, DiagnosticStatus::OK);
        h.planning = Some(2);
        h.last = Some((1, Outcome::NoPlan("cancelled".into())));
        let s = &h.to_msg(Time::default()).status[0];
        assert_eq!(s.level, DiagnosticStatus::WARN);
        assert_eq!(
            s.message,
            "planning part 2; last: part 1: no plan: cancelled"
        );
    }
}
