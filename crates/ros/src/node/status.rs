//! The statuses the node reports on `~/status`.

use crate::convert::diagnostics;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};

/// The statuses the node reports on `~/status`, one DiagnosticStatus each.
#[derive(Debug, Clone, PartialEq)]
pub enum Status {
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
}

impl Status {
    /// The status as a DiagnosticArray (level, one-line message, key-value details).
    pub fn to_msg(&self, stamp: Time, hardware_id: &str) -> DiagnosticArray {
        fn kv(key: &str, value: impl ToString) -> KeyValue {
            KeyValue::new(key, value)
        }
        let (level, message, values) = match self {
            Status::Received {
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
            Status::Planning {
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
            Status::Planned { job, values } => {
                let mut all = vec![kv("state", "planned"), kv("job", job)];
                all.extend(values.iter().cloned());
                (DiagnosticStatus::OK, format!("planned part {job}"), all)
            }
            Status::Error { job, reason } => {
                let mut values = vec![kv("state", "error"), kv("reason", reason)];
                if let Some(job) = job {
                    values.push(kv("job", job));
                }
                (DiagnosticStatus::ERROR, reason.clone(), values)
            }
            Status::Executing {
                job,
                message,
                level,
            } => (
                *level,
                message.clone(),
                vec![kv("state", "executing"), kv("job", job)],
            ),
        };
        let mut msg = diagnostics(stamp, level, &message, values);
        msg.status[0].hardware_id = hardware_id.to_string();
        msg
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statuses_carry_state_level_and_reason() {
        let s = Status::Received {
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
        let e = Status::Error {
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
}
