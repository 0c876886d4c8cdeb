//! The ROS 2 node `waam_planner`: parts in, weld plans and trajectories out.

pub mod convert;
pub mod execute;
pub mod params;
pub mod ros;
pub mod worker;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use futures::StreamExt;
use ros2_client::{MessageTypeName, NodeName, NodeOptions, QosProfile};

use ros::{resolve_topic, RosEnv};

/// Node name on the ROS graph.
pub const NODE_NAME: &str = "waam_planner";

/// Prototype: echoes each part's size on `~/status` (std_msgs/String).
pub fn run_echo(stop: Arc<AtomicBool>) -> anyhow::Result<()> {
    let env = RosEnv::from_env()?;
    tracing::info!(domain = env.domain_id, range = ?env.range, "starting {NODE_NAME}");
    let context = env.context()?;
    let mut node = context.new_node(
        NodeName::new("/", NODE_NAME).unwrap(),
        NodeOptions::new().enable_rosout(true),
    )?;
    let spinner = node.spinner()?;
    std::thread::spawn(move || futures::executor::block_on(spinner.spin()));
    let reliable =
        QosProfile::publisher_default().history(ros2_client::qos::History::KeepLast { depth: 10 });
    let part_topic = node.create_topic(
        &resolve_topic("~/part", "/", NODE_NAME)?,
        MessageTypeName::new("std_msgs", "String"),
        &reliable,
    )?;
    let status_topic = node.create_topic(
        &resolve_topic("~/status", "/", NODE_NAME)?,
        MessageTypeName::new("std_msgs", "String"),
        &reliable,
    )?;
    let sub = node.create_subscription::<String>(&part_topic, None)?;
    let publisher = node.create_publisher::<String>(&status_topic, None)?;
    futures::executor::block_on(async {
        let stream = sub.async_stream();
        futures::pin_mut!(stream);
        while !stop.load(Ordering::Relaxed) {
            match stream.next().await {
                Some(Ok((text, _))) => {
                    tracing::info!("part of {} bytes", text.len());
                    if let Err(e) = publisher.publish(text.clone()) {
                        tracing::warn!("publish: {e:?}");
                    }
                }
                Some(Err(e)) => tracing::warn!("read: {e:?}"),
                None => break,
            }
        }
    });
    Ok(())
}
