//! `~/stop` (std_srvs/Trigger): stop everything now — the planning in progress (its `~/plan`
//! goal ends cancelled) and the execution in progress (goals cancelled, arc off). The answer
//! says what was stopped.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, Sender};
use std::sync::Arc;
use std::time::Duration;

use ros2_client::{Node, QosProfile, ServiceMapping, ServiceTypeName};

use super::fjt::{TriggerRequest, TriggerResponse};
use super::names::NodeNames;
use super::ros::ServeError;

/// Serves `~/stop` until `stop` is raised; each call hands `request` a channel for the
/// event loop's one-line answer.
pub fn serve(
    node: &mut Node,
    names: &NodeNames,
    request: impl Fn(Sender<String>) -> bool + Send + 'static,
    stop: Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<()>, ServeError> {
    let name = names.resolve("~/stop")?;
    let qos =
        QosProfile::publisher_default().history(ros2_client::qos::History::KeepLast { depth: 10 });
    let server = node
        .create_server::<TriggerRequest, TriggerResponse>(
            ServiceMapping::Enhanced,
            &name,
            &ServiceTypeName::new("std_srvs", "Trigger"),
            qos.clone(),
            qos,
        )
        .map_err(|e| ServeError::Create {
            what: "service",
            name: name.to_string(),
            reason: format!("{e:?}"),
        })?;
    std::thread::Builder::new()
        .name("ros-stop".into())
        .spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                let Ok(Some((id, _))) = server.receive_request() else {
                    std::thread::sleep(Duration::from_millis(10));
                    continue;
                };
                let (tx, rx) = channel();
                let response = if request(tx) {
                    match rx.recv_timeout(Duration::from_secs(1)) {
                        Ok(message) => TriggerResponse {
                            success: true,
                            message,
                        },
                        Err(_) => TriggerResponse {
                            success: false,
                            message: "the node did not answer within a second".into(),
                        },
                    }
                } else {
                    TriggerResponse {
                        success: false,
                        message: "the node is shutting down".into(),
                    }
                };
                if let Err(e) = server.send_response(id, response) {
                    tracing::warn!("~/stop response: {e:?}");
                }
            }
        })
        .map_err(|source| ServeError::Thread {
            thread: "the stop thread".into(),
            source,
        })
}
