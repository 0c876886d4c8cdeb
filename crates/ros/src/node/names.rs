//! The node's name, namespace and remap rules, and how they turn a topic, service or action
//! name into the one on the wire — as rcl does for `--ros-args -r`.

use ros2_client::{Name, NodeName};

use super::ros::{resolve_topic, RosEnvError};
use waam_messages::convert::NODE_NAME;

/// One `-r [NODE:]FROM:=TO` rule.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Remap {
    /// Applies only to the node of this name (`NODE:` prefix), else to every node.
    pub node: Option<String>,
    pub from: String,
    pub to: String,
}

/// Where the node sits in the ROS graph.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeNames {
    /// Absolute namespace, `/` for none.
    pub namespace: String,
    pub name: String,
    pub remaps: Vec<Remap>,
}

impl Default for NodeNames {
    fn default() -> Self {
        NodeNames {
            namespace: "/".into(),
            name: NODE_NAME.into(),
            remaps: Vec::new(),
        }
    }
}

impl NodeNames {
    /// `/namespace/name`.
    pub fn fully_qualified(&self) -> String {
        waam_messages::convert::fully_qualified(&self.namespace, &self.name)
    }

    pub fn node_name(&self) -> Result<NodeName, RosEnvError> {
        NodeName::new(&self.namespace, &self.name).map_err(|e| RosEnvError::TopicName {
            name: self.fully_qualified(),
            reason: format!("not a valid node name: {e:?}"),
        })
    }

    /// `name` resolved against the node (`~/x`, `x`, `/x`), then remapped by the first rule
    /// whose resolved FROM equals it.
    pub fn resolve(&self, name: &str) -> Result<Name, RosEnvError> {
        let resolved = resolve_topic(name, &self.namespace, &self.name)?;
        for rule in &self.remaps {
            if rule.node.as_deref().is_some_and(|n| n != self.name) {
                continue;
            }
            let from = resolve_topic(&rule.from, &self.namespace, &self.name)?;
            if from.to_string() == resolved.to_string() {
                return resolve_topic(&rule.to, &self.namespace, &self.name);
            }
        }
        Ok(resolved)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn remaps_apply_after_resolution() {
        let names = NodeNames {
            namespace: "/cell1".into(),
            name: "planner".into(),
            remaps: vec![
                Remap {
                    node: None,
                    from: "~/status".into(),
                    to: "/cell1/state".into(),
                },
                Remap {
                    node: Some("other".into()),
                    from: "/joint_states".into(),
                    to: "js".into(),
                },
                Remap {
                    node: Some("planner".into()),
                    from: "arc_on".into(),
                    to: "~/arc".into(),
                },
            ],
        };
        assert_eq!(names.fully_qualified(), "/cell1/planner");
        let r = |n: &str| names.resolve(n).unwrap().to_string();
        assert_eq!(r("~/status"), "/cell1/state");
        assert_eq!(r("/cell1/planner/status"), "/cell1/state");
        assert_eq!(r("/joint_states"), "/joint_states", "rule for another node");
        assert_eq!(r("arc_on"), "/cell1/planner/arc");
        assert_eq!(r("~/part"), "/cell1/planner/part");
    }

    #[test]
    fn a_node_without_a_namespace_reports_as_its_recordings_do() {
        // The node's statuses and the CLI's recorded ones carry one hardware_id.
        let recorded =
            waam_messages::planning::recorded(waam_messages::status::Status::ok("planned", vec![]));
        assert_eq!(
            NodeNames::default().fully_qualified(),
            recorded.status[0].hardware_id
        );
    }
}
