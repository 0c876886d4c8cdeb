//! Publishing messages planned outside the node (`waam layer plan --publish`) once, as node
//! `waam_planner` on its own topics and QoS, so a cell sees them as it sees the node's plans.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::io::{Level, Outputs};
use super::params::TopicParams;
use super::ros::RosEnv;
use waam_messages::convert::PlanMessages;
use waam_rosmsg::diagnostic_msgs::DiagnosticArray;

/// Publishes `messages` (a validated plan's, when there is one) and then `status` on
/// `topics`, keeps them for late subscribers (the outputs are TransientLocal) for `linger`
/// or until `stop` is raised, and returns.
pub fn publish_once(
    name: &str,
    messages: Option<&PlanMessages>,
    status: &DiagnosticArray,
    topics: &TopicParams,
    linger: Duration,
    stop: &AtomicBool,
) -> Result<(), super::NodeError> {
    let env = RosEnv::from_env()?;
    let names = super::names::NodeNames::default();
    let mut node = super::start_node(&env, &names)?;
    let outputs = Outputs::new(&mut node, &names, topics, false, None)?;
    if let Some(m) = messages {
        super::publish_messages(&outputs, m);
    }
    outputs.status.publish(status, None);
    let what = match messages {
        Some(_) => format!("the plan of {name} on {}", outputs.joint_trajectory.topic),
        None => format!("the status of {name} (no plan) on {}", outputs.status.topic),
    };
    outputs.log(
        Level::Info,
        &format!(
            "{} (domain {}, discovery {:?}): published {what}; keeping it {:.1} s",
            node.fully_qualified_name(),
            env.domain_id,
            env.range,
            linger.as_secs_f64()
        ),
    );
    let until = Instant::now() + linger;
    while Instant::now() < until && !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(50));
    }
    Ok(())
}
