//! The server side of a ROS 2 action, as the node's actions (`~/plan`, `~/execute`) speak
//! it: goals, cancel requests, result requests and goal statuses. The work itself runs on the
//! node's event loop, which answers with [`Reply`]s; this keeps the protocol in one place.

use std::collections::{BTreeMap, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Receiver;
use std::sync::Arc;
use std::time::Duration;

use ros2_client::action::{
    ActionServer, ActionServerQosPolicies, GetResultResponse, GoalId, GoalInfo, GoalStatusEnum,
    SendGoalResponse,
};
use ros2_client::action_msgs::{
    CancelGoalResponse, CancelGoalResponseEnum, GoalStatus, GoalStatusArray,
};
use ros2_client::{ActionTypeName, Message, Node, QosProfile, ServiceMapping};

use super::names::NodeNames;
use super::ros::ServeError;

/// A result that can say why there is none (an unknown goal, a node shutting down).
pub trait Failed: Message + Clone + Send + 'static {
    fn failed(reason: &str) -> Self;
}

/// What an action's thread asks of the event loop: start the job of a goal, or cancel one.
pub enum Request<J> {
    Goal { goal: GoalId, job: J },
    Cancel(GoalId),
}

/// What the event loop tells an action's thread.
pub enum Reply<R, F> {
    Feedback(GoalId, F),
    Done(GoalId, GoalStatusEnum, R),
}

/// What an action's thread does with a goal: start it (`Ok`), or end it at once with a
/// result saying why not. Every goal is accepted, so that a client always learns the reason
/// (a rejected goal could not say why).
pub trait Handler<G, R>: Send + 'static {
    fn goal(&mut self, id: GoalId, goal: G) -> Result<(), R>;
    /// Whether the event loop took the cancel request (else the node is shutting down).
    fn cancel(&mut self, id: GoalId) -> bool;
}

/// Finished goals kept for late result requests.
const KEEP_RESULTS: usize = 32;

/// Starts action `relative_name` (resolved with the node's names and remaps) of
/// `package/Type` on a thread of its own, until `stop` is raised.
pub fn serve<G, R, F>(
    node: &mut Node,
    names: &NodeNames,
    relative_name: &str,
    type_name: (&str, &str),
    mut handler: impl Handler<G, R>,
    replies: Receiver<Reply<R, F>>,
    stop: Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<()>, ServeError>
where
    G: Message + Clone + Send + 'static,
    R: Failed,
    F: Message + Clone + Send + 'static,
{
    let name = names.resolve(relative_name)?;
    let service =
        QosProfile::publisher_default().history(ros2_client::qos::History::KeepLast { depth: 10 });
    let server: ActionServer<G, R, F> = node
        .create_action_server(
            ServiceMapping::Enhanced,
            &name,
            &ActionTypeName::new(type_name.0, type_name.1),
            ActionServerQosPolicies {
                goal_service: service.clone(),
                result_service: service.clone(),
                cancel_service: service.clone(),
                feedback_publisher: service.clone(),
                status_publisher: service
                    .durability(ros2_client::qos::Durability::TransientLocal)
                    .history(ros2_client::qos::History::KeepLast { depth: 1 }),
            },
        )
        .map_err(|e| ServeError::Create {
            what: "action",
            name: name.to_string(),
            reason: format!("{e:?}"),
        })?;
    std::thread::Builder::new()
        .name(format!("ros-action-{}", type_name.1))
        .spawn(move || {
            let mut goals = Goals::default();
            while !stop.load(Ordering::Relaxed) {
                let busy = goals.step(&server, &mut handler, &replies);
                if !busy {
                    std::thread::sleep(Duration::from_millis(10));
                }
            }
        })
        .map_err(|source| ServeError::Thread {
            thread: format!("the thread of action {name}"),
            source,
        })
}

struct Goals<R> {
    /// Every known goal's status.
    status: BTreeMap<GoalId, GoalStatus>,
    results: BTreeMap<GoalId, R>,
    finished: VecDeque<GoalId>,
    waiting: Vec<(ros2_client::RmwRequestId, GoalId)>,
}

impl<R> Default for Goals<R> {
    fn default() -> Self {
        Goals {
            status: BTreeMap::new(),
            results: BTreeMap::new(),
            finished: VecDeque::new(),
            waiting: Vec::new(),
        }
    }
}

impl<R: Failed> Goals<R> {
    /// One round of the protocol; whether there was anything to do.
    fn step<G: Message + Clone + 'static, F: Message + Clone + 'static>(
        &mut self,
        server: &ActionServer<G, R, F>,
        handler: &mut impl Handler<G, R>,
        replies: &Receiver<Reply<R, F>>,
    ) -> bool {
        let mut busy = false;
        let mut changed = false;
        if let Ok(Some((req, goal))) = server.receive_goal() {
            busy = true;
            let id = goal.goal_id;
            let stamp = ros2_client::builtin_interfaces::Time::now();
            let _ = server.send_goal_response(
                req,
                SendGoalResponse {
                    accepted: true,
                    stamp,
                },
            );
            self.status.insert(
                id,
                GoalStatus {
                    goal_info: GoalInfo { goal_id: id, stamp },
                    status: GoalStatusEnum::Executing,
                },
            );
            if let Err(result) = handler.goal(id, goal.goal) {
                self.finish(id, GoalStatusEnum::Aborted, result);
            }
            changed = true;
        }
        if let Ok(Some((req, cancel))) = server.receive_cancel_request() {
            busy = true;
            // `CancelGoalRequest`'s fields are not public in ros2-client; its serde form is.
            let info = serde_json::to_value(&cancel)
                .ok()
                .and_then(|v| serde_json::from_value::<GoalInfo>(v["goal_info"].clone()).ok());
            let response = match info {
                Some(info) => self.cancel(info.goal_id, handler),
                None => CancelGoalResponse {
                    return_code: CancelGoalResponseEnum::Rejected,
                    goals_canceling: vec![],
                },
            };
            let _ = server.send_cancel_response(req, response);
            changed = true;
        }
        if let Ok(Some((req, get))) = server.receive_result_request() {
            busy = true;
            self.waiting.push((req, get.goal_id));
        }
        while let Ok(reply) = replies.try_recv() {
            busy = true;
            match reply {
                Reply::Feedback(id, feedback) => {
                    let _ = server.send_feedback(id, feedback);
                }
                Reply::Done(id, status, result) => {
                    self.finish(id, status, result);
                    changed = true;
                }
            }
        }
        // Answer result requests of finished (or unknown) goals.
        let mut still = Vec::new();
        for (req, id) in self.waiting.drain(..) {
            match (self.results.get(&id), self.status.get(&id)) {
                (Some(result), Some(status)) => {
                    let _ = server.send_result(
                        req,
                        GetResultResponse {
                            status: status.status,
                            result: result.clone(),
                        },
                    );
                }
                (None, Some(_)) => still.push((req, id)),
                _ => {
                    let _ = server.send_result(
                        req,
                        GetResultResponse {
                            status: GoalStatusEnum::Unknown,
                            result: R::failed("unknown goal"),
                        },
                    );
                }
            }
        }
        self.waiting = still;
        if changed {
            let _ = server.send_goal_statuses(GoalStatusArray {
                status_list: self.status.values().cloned().collect(),
            });
        }
        busy
    }

    fn cancel<G>(&mut self, id: GoalId, handler: &mut impl Handler<G, R>) -> CancelGoalResponse {
        match self.status.get_mut(&id) {
            Some(s) if s.status == GoalStatusEnum::Executing => {
                s.status = GoalStatusEnum::Canceling;
                let info = s.goal_info.clone();
                handler.cancel(id);
                CancelGoalResponse {
                    return_code: CancelGoalResponseEnum::None,
                    goals_canceling: vec![info],
                }
            }
            Some(_) => CancelGoalResponse {
                return_code: CancelGoalResponseEnum::GoalTerminated,
                goals_canceling: vec![],
            },
            None => CancelGoalResponse {
                return_code: CancelGoalResponseEnum::UnknownGoal,
                goals_canceling: vec![],
            },
        }
    }

    fn finish(&mut self, id: GoalId, status: GoalStatusEnum, result: R) {
        if self.results.contains_key(&id) {
            return; // already ended (cancelled, then its job's end reported too)
        }
        if let Some(s) = self.status.get_mut(&id) {
            s.status = status;
        }
        self.results.insert(id, result);
        self.finished.push_back(id);
        while self.finished.len() > KEEP_RESULTS {
            if let Some(old) = self.finished.pop_front() {
                self.results.remove(&old);
                self.status.remove(&old);
            }
        }
    }
}
