//! `~/status`: the one shape of every status report (the node's, and those recorded by
//! `waam plan --record` and `waam layer plan --record`), and the one builder of the
//! `DiagnosticArray` it goes out as (the node's health on `/diagnostics` too).

use crate::convert::NODE_NAME;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use waam_rosmsg::std_msgs::Header;

/// One status report: a level, a one-line message and key-value details.
#[derive(Debug, Clone, PartialEq)]
pub struct Status {
    /// `DiagnosticStatus::OK`, `WARN` or `ERROR`.
    pub level: u8,
    pub message: String,
    pub values: Vec<KeyValue>,
}

impl Status {
    pub fn new(level: u8, message: impl Into<String>, values: Vec<KeyValue>) -> Status {
        Status {
            level,
            message: message.into(),
            values,
        }
    }

    pub fn ok(message: impl Into<String>, values: Vec<KeyValue>) -> Status {
        Status::new(DiagnosticStatus::OK, message, values)
    }

    pub fn error(message: impl Into<String>, values: Vec<KeyValue>) -> Status {
        Status::new(DiagnosticStatus::ERROR, message, values)
    }

    /// As `~/status` carries it: reported by the node's one component ([`NODE_NAME`]), its
    /// `hardware_id` the node's fully qualified name `node`
    /// ([`fully_qualified`](crate::convert::fully_qualified); recordings
    /// of the CLI speak for the node without a namespace, `/waam_planner`).
    pub fn to_msg(&self, stamp: Time, node: &str) -> DiagnosticArray {
        self.reported_by(stamp, NODE_NAME, node)
    }

    /// The one builder of a `DiagnosticArray`: this status as component `name` of
    /// `hardware_id` reports it.
    pub fn reported_by(&self, stamp: Time, name: &str, hardware_id: &str) -> DiagnosticArray {
        DiagnosticArray {
            header: Header::new(stamp, ""),
            status: vec![self.diagnostic(name, hardware_id)],
        }
    }

    /// This status as one entry of a `DiagnosticArray` (a node reporting several components,
    /// as the node's health does for its sensors, puts one per component in the array).
    pub fn diagnostic(&self, name: &str, hardware_id: &str) -> DiagnosticStatus {
        DiagnosticStatus {
            level: self.level,
            name: name.to_string(),
            message: self.message.clone(),
            hardware_id: hardware_id.to_string(),
            values: self.values.clone(),
        }
    }
}

/// What the node reports about its jobs on `~/status`, one [`Status`] each.
#[derive(Debug, Clone, PartialEq)]
pub enum JobStatus {
    /// An input arrived; `cancelled` names the job it superseded; `settings` are how it
    /// will be turned into a part (for a mesh: the voxelizing settings), for replays.
    Received {
        job: u64,
        source: String,
        cancelled: Option<u64>,
        settings: Vec<KeyValue>,
    },
    Planning {
        job: u64,
        stage: String,
        fraction: Option<f64>,
        detail: String,
    },
    Planned {
        job: u64,
        values: Vec<KeyValue>,
    },
    Error {
        job: Option<u64>,
        reason: String,
    },
    /// Execution news (goals sent, arc switched, done).
    Executing {
        job: u64,
        message: String,
        level: u8,
    },
    /// The closed loop decided at a weld-path boundary of an execution (#31): `reason`
    /// (replan, fault, unchanged, kept), the boundary's wall-clock `latency_s` and what it
    /// found and estimated (`values`).
    Replanned {
        job: u64,
        reason: String,
        latency_s: f64,
        message: String,
        values: Vec<KeyValue>,
    },
}

impl JobStatus {
    /// The status as a DiagnosticArray (level, one-line message, key-value details), as
    /// [`Status::to_msg`] builds it for the node `node` (fully qualified).
    pub fn to_msg(&self, stamp: Time, node: &str) -> DiagnosticArray {
        self.status().to_msg(stamp, node)
    }

    /// Its level, message and details.
    pub fn status(&self) -> Status {
        fn kv(key: &str, value: impl ToString) -> KeyValue {
            KeyValue::new(key, value)
        }
        let (level, message, values) = match self {
            JobStatus::Received {
                job,
                source,
                cancelled,
                settings,
            } => {
                let mut message = format!("received part {job} ({source})");
                let mut values = vec![kv("state", "received"), kv("job", job)];
                if let Some(old) = cancelled {
                    message.push_str(&format!("; cancelled planning of part {old}"));
                    values.push(kv("cancelled_job", old));
                }
                values.extend(settings.iter().cloned());
                (DiagnosticStatus::OK, message, values)
            }
            JobStatus::Planning {
                job,
                stage,
                fraction,
                detail,
            } => {
                let mut message = format!("planning part {job}: {stage}");
                let mut values = vec![kv("state", "planning"), kv("job", job), kv("stage", stage)];
                if let Some(f) = fraction {
                    message.push_str(&format!(" {:.0}%", f * 100.0));
                    values.push(kv("progress", format!("{f:.3}")));
                }
                if !detail.is_empty() {
                    message.push_str(&format!(" ({detail})"));
                    values.push(kv("detail", detail));
                }
                (DiagnosticStatus::OK, message, values)
            }
            JobStatus::Planned { job, values } => {
                let mut all = vec![kv("state", "planned"), kv("job", job)];
                all.extend(values.iter().cloned());
                (DiagnosticStatus::OK, format!("planned part {job}"), all)
            }
            JobStatus::Error { job, reason } => {
                let mut values = vec![kv("state", "error"), kv("reason", reason)];
                if let Some(job) = job {
                    values.push(kv("job", job));
                }
                (DiagnosticStatus::ERROR, reason.clone(), values)
            }
            JobStatus::Executing {
                job,
                message,
                level,
            } => (
                *level,
                message.clone(),
                vec![kv("state", "executing"), kv("job", job)],
            ),
            JobStatus::Replanned {
                job,
                reason,
                latency_s,
                message,
                values,
            } => {
                let mut all = vec![
                    kv("state", "replanned"),
                    kv("job", job),
                    kv("reason", reason),
                    kv("latency_s", format!("{latency_s:.3}")),
                ];
                all.extend(values.iter().cloned());
                (DiagnosticStatus::OK, message.clone(), all)
            }
        };
        Status::new(level, message, values)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statuses_carry_state_level_and_reason() {
        let s = JobStatus::Received {
            job: 3,
            source: "mesh".into(),
            cancelled: Some(2),
            settings: vec![KeyValue::new("mesh.name", "mesh-1")],
        }
        .to_msg(Time::default(), "");
        let st = &s.status[0];
        assert_eq!(st.level, DiagnosticStatus::OK);
        assert!(st.message.contains("cancelled planning of part 2"));
        assert!(st.values.contains(&KeyValue::new("cancelled_job", 2)));
        assert!(st.values.contains(&KeyValue::new("mesh.name", "mesh-1")));
        let e = JobStatus::Error {
            job: Some(4),
            reason: "bad part document: x".into(),
        }
        .to_msg(Time::default(), "");
        assert_eq!(e.status[0].level, DiagnosticStatus::ERROR);
        assert_eq!(e.status[0].message, "bad part document: x");
        assert!(e.status[0]
            .values
            .contains(&KeyValue::new("state", "error")));
    }

    #[test]
    fn the_hardware_id_is_the_nodes_fully_qualified_name() {
        use crate::convert::fully_qualified;
        assert_eq!(fully_qualified("/", NODE_NAME), "/waam_planner");
        assert_eq!(fully_qualified("/cell1", "planner"), "/cell1/planner");
        assert_eq!(fully_qualified("/cell1/", "planner"), "/cell1/planner");
        // Recordings of the CLI speak for the node without a namespace.
        let recorded = crate::planning::recorded(Status::ok("planned", vec![]));
        assert_eq!(recorded.status[0].hardware_id, "/waam_planner");
        assert_eq!(recorded.status[0].name, NODE_NAME);
    }

    #[test]
    fn a_status_is_one_diagnostic_status_of_its_reporter() {
        let values = vec![KeyValue::new("part", "wall")];
        let recorded =
            Status::ok("received", values.clone()).to_msg(Time::from_nanos(7), "/waam_planner");
        assert_eq!(recorded.header, Header::new(Time::from_nanos(7), ""));
        assert_eq!(
            recorded.status,
            vec![DiagnosticStatus {
                level: DiagnosticStatus::OK,
                name: NODE_NAME.into(),
                message: "received".into(),
                hardware_id: "/waam_planner".into(),
                values,
            }]
        );
        let node = JobStatus::Planned {
            job: 2,
            values: vec![],
        }
        .to_msg(Time::default(), "/cell1/planner");
        assert_eq!(node.status[0].name, NODE_NAME);
        assert_eq!(node.status[0].hardware_id, "/cell1/planner");
        let health = Status::error("down", vec![]).reported_by(Time::default(), "n: planner", "/n");
        assert_eq!(health.status[0].level, DiagnosticStatus::ERROR);
        assert_eq!(
            (
                health.status[0].name.as_str(),
                health.status[0].hardware_id.as_str()
            ),
            ("n: planner", "/n")
        );
    }
}
