//! ROS 2 QoS profiles as rosbag2 stores them (metadata version 9: policies by name).

use serde::{Deserialize, Serialize};

/// History policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum History {
    SystemDefault,
    KeepLast,
    KeepAll,
    Unknown,
}

/// Reliability policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Reliability {
    SystemDefault,
    Reliable,
    BestEffort,
    Unknown,
    BestAvailable,
}

/// Durability policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Durability {
    SystemDefault,
    TransientLocal,
    Volatile,
    Unknown,
    BestAvailable,
}

/// Liveliness policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Liveliness {
    SystemDefault,
    Automatic,
    ManualByNode,
    ManualByTopic,
    Unknown,
    BestAvailable,
}

/// A QoS duration as rmw writes it: seconds and nanoseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct QosTime {
    pub sec: u64,
    pub nsec: u64,
}

impl QosTime {
    /// `RMW_DURATION_INFINITE` (i64::MAX ns), what a publisher with default deadline,
    /// lifespan and lease offers, as rosbag2 records it.
    pub const INFINITE: QosTime = QosTime {
        sec: 9_223_372_036,
        nsec: 854_775_807,
    };

    pub fn from_secs(sec: u64) -> QosTime {
        QosTime { sec, nsec: 0 }
    }
}

/// One offered QoS profile, with the keys and order rosbag2 writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Qos {
    pub history: History,
    pub depth: u32,
    pub reliability: Reliability,
    pub durability: Durability,
    pub deadline: QosTime,
    pub lifespan: QosTime,
    pub liveliness: Liveliness,
    pub liveliness_lease_duration: QosTime,
    pub avoid_ros_namespace_conventions: bool,
}

impl Qos {
    /// Reliable, volatile, keep last `depth`: the node's inputs and ordinary topics.
    pub fn reliable(depth: u32) -> Qos {
        Qos {
            history: History::KeepLast,
            depth,
            reliability: Reliability::Reliable,
            durability: Durability::Volatile,
            deadline: QosTime::INFINITE,
            lifespan: QosTime::INFINITE,
            liveliness: Liveliness::Automatic,
            liveliness_lease_duration: QosTime::INFINITE,
            avoid_ros_namespace_conventions: false,
        }
    }

    /// Reliable, transient local, keep last 1: the node's plan outputs (a late subscriber
    /// still gets the last plan).
    pub fn latched() -> Qos {
        Qos {
            durability: Durability::TransientLocal,
            ..Qos::reliable(1)
        }
    }

    /// Best effort, volatile, keep last `depth`: sensor-like streams (joint states).
    pub fn best_effort(depth: u32) -> Qos {
        Qos {
            reliability: Reliability::BestEffort,
            ..Qos::reliable(depth)
        }
    }

    /// What rcl offers on `/rosout` (Jazzy): reliable, transient local, depth 1000, 10 s
    /// lifespan.
    pub fn rosout() -> Qos {
        Qos {
            durability: Durability::TransientLocal,
            lifespan: QosTime::from_secs(10),
            ..Qos::reliable(1000)
        }
    }
}

/// The `offered_qos_profiles` channel metadata value: the profiles as a YAML sequence.
pub fn to_yaml(profiles: &[Qos]) -> String {
    if profiles.is_empty() {
        return String::new();
    }
    let text = serde_yaml::to_string(profiles).expect("QoS profiles serialize to YAML");
    text.trim_end().to_string()
}

/// Parses an `offered_qos_profiles` value (the string form of metadata versions 4-9: names
/// or rmw enum numbers). An empty string is no profiles.
/// A recorded QoS profile list that cannot be read (the message says where).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct QosError(pub String);

impl From<String> for QosError {
    fn from(message: String) -> Self {
        QosError(message)
    }
}

impl From<&str> for QosError {
    fn from(message: &str) -> Self {
        QosError(message.to_string())
    }
}

pub fn from_yaml(text: &str) -> Result<Vec<Qos>, QosError> {
    if text.trim().is_empty() {
        return Ok(Vec::new());
    }
    waam_yaml::check(text).map_err(|e| format!("offered_qos_profiles: {e}"))?;
    let value: serde_yaml::Value =
        serde_yaml::from_str(text).map_err(|e| format!("offered_qos_profiles: {e}"))?;
    let serde_yaml::Value::Sequence(items) = value else {
        return Err(QosError(
            "offered_qos_profiles: expected a YAML sequence".into(),
        ));
    };
    items.into_iter().map(profile_from_value).collect()
}

/// One profile from YAML, accepting both policy names (v9) and rmw enum numbers (v4-v8).
fn profile_from_value(mut value: serde_yaml::Value) -> Result<Qos, QosError> {
    use serde_yaml::Value;
    const NAMES: [(&str, &[&str]); 4] = [
        (
            "history",
            &["system_default", "keep_last", "keep_all", "unknown"],
        ),
        (
            "reliability",
            &[
                "system_default",
                "reliable",
                "best_effort",
                "unknown",
                "best_available",
            ],
        ),
        (
            "durability",
            &[
                "system_default",
                "transient_local",
                "volatile",
                "unknown",
                "best_available",
            ],
        ),
        (
            "liveliness",
            &[
                "system_default",
                "automatic",
                "manual_by_node",
                "manual_by_topic",
                "unknown",
                "best_available",
            ],
        ),
    ];
    if let Value::Mapping(map) = &mut value {
        for (key, names) in NAMES {
            if let Some(slot) = map.get_mut(key) {
                if let Some(n) = slot.as_u64() {
                    let name = names.get(n as usize).copied().unwrap_or("unknown");
                    *slot = Value::String(name.to_string());
                }
            }
        }
    }
    serde_yaml::from_value(value).map_err(|e| QosError(format!("offered_qos_profiles: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaml_has_rosbag2_v9_keys_and_names() {
        let text = to_yaml(&[Qos::latched()]);
        let expected = "\
- history: keep_last
  depth: 1
  reliability: reliable
  durability: transient_local
  deadline:
    sec: 9223372036
    nsec: 854775807
  lifespan:
    sec: 9223372036
    nsec: 854775807
  liveliness: automatic
  liveliness_lease_duration:
    sec: 9223372036
    nsec: 854775807
  avoid_ros_namespace_conventions: false";
        assert_eq!(text, expected);
        assert_eq!(from_yaml(&text).unwrap(), vec![Qos::latched()]);
    }

    #[test]
    fn old_enum_numbers_are_understood() {
        let text = "- history: 1\n  depth: 5\n  reliability: 2\n  durability: 2\n  \
                    deadline: {sec: 0, nsec: 0}\n  lifespan: {sec: 0, nsec: 0}\n  \
                    liveliness: 1\n  liveliness_lease_duration: {sec: 0, nsec: 0}\n  \
                    avoid_ros_namespace_conventions: false\n";
        let qos = from_yaml(text).unwrap();
        assert_eq!(qos[0].history, History::KeepLast);
        assert_eq!(qos[0].reliability, Reliability::BestEffort);
        assert_eq!(qos[0].durability, Durability::Volatile);
        assert_eq!(qos[0].depth, 5);
        assert!(from_yaml("").unwrap().is_empty());
        assert!(from_yaml("- history: [").is_err());
    }
}
