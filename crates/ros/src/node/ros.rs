//! The ROS 2 environment as rcl reads it: domain id, discovery range, and name resolution.
//!
//! `ros2-client` opens domain 0 on every interface unless told otherwise; a cell's ROS 2 stack
//! chooses the domain and discovery range through environment variables, so we read them here
//! the way rcl does and build the DDS participant to match.

use std::net::{IpAddr, Ipv4Addr};

use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::{Context, Name};

/// Errors from the ROS 2 environment and from creating ROS 2 entities.
#[derive(Debug, thiserror::Error)]
pub enum RosEnvError {
    #[error("ROS_DOMAIN_ID={0:?} is not a domain id (an integer 0..=232)")]
    DomainId(String),
    #[error(
        "ROS_AUTOMATIC_DISCOVERY_RANGE={0:?} is not one of SUBNET, LOCALHOST, OFF, SYSTEM_DEFAULT"
    )]
    DiscoveryRange(String),
    #[error("topic name {name:?}: {reason}")]
    TopicName { name: String, reason: String },
    #[error("cannot start DDS: {0}")]
    Dds(String),
}

/// A service or action server of the node, or its thread, could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    #[error(transparent)]
    Name(#[from] RosEnvError),
    /// A service name `ros2-client` refuses.
    #[error("{name}: {reason}")]
    BadName { name: String, reason: String },
    /// `what` is "service" or "action".
    #[error("cannot create {what} {name}: {reason}")]
    Create {
        what: &'static str,
        name: String,
        reason: String,
    },
    #[error("cannot start {thread}: {source}")]
    Thread {
        thread: String,
        source: std::io::Error,
    },
}

/// How far discovery reaches, as `ROS_AUTOMATIC_DISCOVERY_RANGE` says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiscoveryRange {
    /// Every interface (the ROS 2 default).
    Subnet,
    /// Loopback only: peers on this machine.
    Localhost,
}

/// The domain id and discovery range of this process.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RosEnv {
    pub domain_id: u16,
    pub range: DiscoveryRange,
}

impl RosEnv {
    /// Reads `ROS_DOMAIN_ID`, `ROS_AUTOMATIC_DISCOVERY_RANGE` and the older `ROS_LOCALHOST_ONLY`.
    pub fn from_env() -> Result<RosEnv, RosEnvError> {
        let var = |key: &str| std::env::var(key).ok().filter(|v| !v.trim().is_empty());
        RosEnv::from_vars(
            var("ROS_DOMAIN_ID").as_deref(),
            var("ROS_AUTOMATIC_DISCOVERY_RANGE").as_deref(),
            var("ROS_LOCALHOST_ONLY").as_deref(),
        )
    }

    /// The rules of [`RosEnv::from_env`] on given values (testable without touching the env).
    pub fn from_vars(
        domain_id: Option<&str>,
        range: Option<&str>,
        localhost_only: Option<&str>,
    ) -> Result<RosEnv, RosEnvError> {
        let domain_id = match domain_id {
            None => 0,
            Some(text) => match text.trim().parse::<u16>() {
                Ok(id) if id <= 232 => id,
                _ => return Err(RosEnvError::DomainId(text.to_string())),
            },
        };
        let range = match range.map(|r| r.trim().to_ascii_uppercase()).as_deref() {
            None | Some("SYSTEM_DEFAULT") | Some("SUBNET") => {
                if localhost_only.map(str::trim) == Some("1") {
                    DiscoveryRange::Localhost
                } else {
                    DiscoveryRange::Subnet
                }
            }
            // OFF means "no automatic discovery" in rcl; without static peers the closest we
            // can honour is loopback only, which never leaves the machine.
            Some("LOCALHOST") | Some("OFF") => DiscoveryRange::Localhost,
            Some(_) => return Err(RosEnvError::DiscoveryRange(range.unwrap().to_string())),
        };
        Ok(RosEnv { domain_id, range })
    }

    /// A ROS 2 context (one DDS participant) on this domain and discovery range.
    pub fn context(&self) -> Result<Context, RosEnvError> {
        let mut builder = DomainParticipantBuilder::new(self.domain_id);
        if self.range == DiscoveryRange::Localhost {
            builder = builder.with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)]);
        }
        let participant = builder
            .build()
            .map_err(|e| RosEnvError::Dds(e.to_string()))?;
        Context::from_domain_participant(participant).map_err(|e| RosEnvError::Dds(e.to_string()))
    }
}

/// Resolves a topic name as rcl does for a node `/namespace/node`: `~/x` is private to the
/// node (`/namespace/node/x`), `/x` is absolute, `x` is relative to the namespace.
pub fn resolve_topic(topic: &str, namespace: &str, node: &str) -> Result<Name, RosEnvError> {
    let bad = |reason: &str| RosEnvError::TopicName {
        name: topic.to_string(),
        reason: reason.to_string(),
    };
    let namespace = namespace.trim_end_matches('/');
    let full = if let Some(rest) = topic.strip_prefix("~/") {
        format!("{namespace}/{node}/{rest}")
    } else if topic.starts_with('/') {
        topic.to_string()
    } else if topic.starts_with('~') {
        return Err(bad("a private name starts with \"~/\""));
    } else {
        format!("{namespace}/{topic}")
    };
    Name::parse(&full).map_err(|e| bad(&format!("{e:?}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn domain_and_range_follow_rcl() {
        let env = RosEnv::from_vars(None, None, None).unwrap();
        assert_eq!(
            env,
            RosEnv {
                domain_id: 0,
                range: DiscoveryRange::Subnet
            }
        );
        let env = RosEnv::from_vars(Some("42"), Some("localhost"), None).unwrap();
        assert_eq!(
            env,
            RosEnv {
                domain_id: 42,
                range: DiscoveryRange::Localhost
            }
        );
        let env = RosEnv::from_vars(Some("7"), None, Some("1")).unwrap();
        assert_eq!(env.range, DiscoveryRange::Localhost);
        assert!(matches!(
            RosEnv::from_vars(Some("233"), None, None),
            Err(RosEnvError::DomainId(_))
        ));
        assert!(matches!(
            RosEnv::from_vars(Some("x"), None, None),
            Err(RosEnvError::DomainId(_))
        ));
        assert!(matches!(
            RosEnv::from_vars(None, Some("LAN"), None),
            Err(RosEnvError::DiscoveryRange(_))
        ));
    }

    #[test]
    fn names_resolve_like_rcl() {
        let n = resolve_topic("~/plan/poses", "/", "waam_planner").unwrap();
        assert_eq!(n.to_string(), "/waam_planner/plan/poses");
        let n = resolve_topic("~/part", "/cell1", "waam_planner").unwrap();
        assert_eq!(n.to_string(), "/cell1/waam_planner/part");
        let n = resolve_topic("/joint_states", "/cell1", "waam_planner").unwrap();
        assert_eq!(n.to_string(), "/joint_states");
        let n = resolve_topic("arc_on", "/cell1", "waam_planner").unwrap();
        assert_eq!(n.to_string(), "/cell1/arc_on");
        assert!(resolve_topic("~part", "/", "n").is_err());
        assert!(resolve_topic("~/bad name", "/", "n").is_err());
    }
}
