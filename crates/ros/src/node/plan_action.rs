//! Planning as an action: `~/plan` of type `waam_interfaces/action/PlanPart`
//! (`ros/waam_interfaces/action/PlanPart.action`). A client ties its request to its result,
//! gets progress as feedback and can cancel.
//!
//! This thread speaks the action protocol (goals, cancel requests, result requests, goal
//! statuses); the node's event loop runs the jobs on the same worker as `~/part` (the latest
//! request wins: a newer goal or part cancels the goal in progress) and answers with
//! [`Reply`]s.

use std::collections::{BTreeMap, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender};
use std::sync::Arc;
use std::time::Duration;

use ros2_client::action::{
    ActionServer, ActionServerQosPolicies, GetResultResponse, GoalId, GoalInfo, GoalStatusEnum,
    SendGoalResponse,
};
use ros2_client::action_msgs::{
    CancelGoalResponse, CancelGoalResponseEnum, GoalStatus, GoalStatusArray,
};
use ros2_client::{ActionTypeName, Node, QosProfile, RmwRequestId, ServiceMapping};
use serde::{Deserialize, Serialize};

use super::names::NodeNames;
use super::param_server::ParamStore;
use super::params::MAX_WAIT_S;
use super::pipeline::{mesh_input, mesh_settings, Job, PartInput};
use waam_part::Window;
use waam_rosmsg::shape_msgs::Mesh;
use waam_rosmsg::waam_interfaces::WeldPlan;

/// `PlanPart` goal (field order of the `.action` file).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct PlanPartGoal {
    pub part_document: String,
    pub mesh: Mesh,
    pub block_mm: Vec<f64>,
    pub t85_window_s: Vec<f64>,
    pub max_fragments: i32,
    pub timeout_s: f64,
    pub first_feasible: bool,
}
impl ros2_client::Message for PlanPartGoal {}

/// `PlanPart` result.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct PlanPartResult {
    pub outcome: u8,
    pub reason: String,
    pub plan: WeldPlan,
}
impl ros2_client::Message for PlanPartResult {}

impl PlanPartResult {
    pub const PLANNED: u8 = 0;
    pub const NO_PLAN: u8 = 1;
    pub const CANCELLED: u8 = 2;
    pub const BAD_INPUT: u8 = 3;

    pub fn failed(outcome: u8, reason: impl Into<String>) -> PlanPartResult {
        PlanPartResult {
            outcome,
            reason: reason.into(),
            plan: WeldPlan::default(),
        }
    }
}

/// `PlanPart` feedback.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct PlanPartFeedback {
    pub stage: String,
    pub candidates: u64,
    pub feasible: u64,
    pub cuts: u64,
    pub best_margin_s: f64,
    pub elapsed_s: f64,
}
impl ros2_client::Message for PlanPartFeedback {}

/// What the action thread asks of the event loop.
pub enum Request {
    Goal { goal: GoalId, job: Job },
    Cancel(GoalId),
}

/// What the event loop tells the action thread.
pub enum Reply {
    Feedback(GoalId, PlanPartFeedback),
    Done(GoalId, GoalStatusEnum, PlanPartResult),
}

type Server = ActionServer<PlanPartGoal, PlanPartResult, PlanPartFeedback>;

/// Finished goals kept for late result requests.
const KEEP_RESULTS: usize = 32;

/// Starts `~/plan` (remapped as the node's names say); runs until `stop` is raised.
pub fn serve(
    node: &mut Node,
    names: &NodeNames,
    store: Arc<ParamStore>,
    requests: impl Fn(Request) -> bool + Send + 'static,
    replies: Receiver<Reply>,
    stop: Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<()>, String> {
    let name = names.resolve("~/plan").map_err(|e| e.to_string())?;
    let service =
        QosProfile::publisher_default().history(ros2_client::qos::History::KeepLast { depth: 10 });
    let server: Server = node
        .create_action_server(
            ServiceMapping::Enhanced,
            &name,
            &ActionTypeName::new("waam_interfaces", "PlanPart"),
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
        .map_err(|e| format!("cannot create action {name}: {e:?}"))?;
    std::thread::Builder::new()
        .name("ros-plan-action".into())
        .spawn(move || {
            let mut goals = Goals::default();
            while !stop.load(Ordering::Relaxed) {
                let busy = goals.step(&server, &store, &requests, &replies);
                if !busy {
                    std::thread::sleep(Duration::from_millis(10));
                }
            }
        })
        .map_err(|e| format!("cannot start the action thread: {e}"))
}

#[derive(Default)]
struct Goals {
    /// Every known goal's status.
    status: BTreeMap<GoalId, GoalStatus>,
    results: BTreeMap<GoalId, PlanPartResult>,
    finished: VecDeque<GoalId>,
    waiting: Vec<(RmwRequestId, GoalId)>,
}

impl Goals {
    /// One round of the protocol; whether there was anything to do.
    fn step(
        &mut self,
        server: &Server,
        store: &ParamStore,
        requests: &impl Fn(Request) -> bool,
        replies: &Receiver<Reply>,
    ) -> bool {
        let mut busy = false;
        let mut changed = false;
        if let Ok(Some((req, goal))) = server.receive_goal() {
            busy = true;
            let id = goal.goal_id;
            let stamp = ros2_client::builtin_interfaces::Time::now();
            // Every goal is accepted: one the node cannot plan ends at once with the reason
            // (a rejected goal could not say why).
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
            match job_of(goal.goal, store) {
                Ok(job) => {
                    if !requests(Request::Goal { goal: id, job }) {
                        self.finish(
                            id,
                            GoalStatusEnum::Aborted,
                            PlanPartResult::failed(
                                PlanPartResult::CANCELLED,
                                "the node is shutting down",
                            ),
                        );
                    }
                }
                Err(reason) => self.finish(
                    id,
                    GoalStatusEnum::Aborted,
                    PlanPartResult::failed(PlanPartResult::BAD_INPUT, reason),
                ),
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
                Some(info) => self.cancel(info.goal_id, requests),
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
                            result: PlanPartResult::failed(
                                PlanPartResult::BAD_INPUT,
                                "unknown goal",
                            ),
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

    fn cancel(&mut self, id: GoalId, requests: &impl Fn(Request) -> bool) -> CancelGoalResponse {
        match self.status.get_mut(&id) {
            Some(s) if s.status == GoalStatusEnum::Executing => {
                s.status = GoalStatusEnum::Canceling;
                let info = s.goal_info.clone();
                requests(Request::Cancel(id));
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

    fn finish(&mut self, id: GoalId, status: GoalStatusEnum, result: PlanPartResult) {
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

/// The job a goal asks for, or why it cannot be planned.
fn job_of(goal: PlanPartGoal, store: &ParamStore) -> Result<Job, String> {
    let input = if !goal.part_document.is_empty() {
        PartInput::Document(goal.part_document)
    } else if !goal.mesh.vertices.is_empty() {
        mesh_input("goal-mesh".into(), &goal.mesh)
    } else {
        return Err("the goal has neither a part_document nor a mesh".into());
    };
    let mut mesh = mesh_settings(&store.current()).map_err(|e| e.to_string())?;
    match goal.block_mm[..] {
        [] => {}
        [a, b, c] if [a, b, c].iter().all(|v| v.is_finite() && *v > 0.0) => {
            mesh.block_mm = [a, b, c]
        }
        _ => {
            return Err(format!(
                "block_mm: expected [] or three lengths > 0 (mm), got {:?}",
                goal.block_mm
            ))
        }
    }
    match goal.t85_window_s[..] {
        [] => {}
        [min_s, max_s]
            if min_s.is_finite() && max_s.is_finite() && 0.0 <= min_s && min_s <= max_s =>
        {
            mesh.window = Some(Window { min_s, max_s })
        }
        _ => {
            return Err(format!(
                "t85_window_s: expected [] or [min_s, max_s] with 0 <= min_s <= max_s, got {:?}",
                goal.t85_window_s
            ))
        }
    }
    let max_fragments = match goal.max_fragments {
        0 => None,
        k if k > 0 => Some(k as usize),
        k => return Err(format!("max_fragments: expected 0 or k >= 1, got {k}")),
    };
    if let Some(k) = max_fragments {
        mesh.max_fragments = k;
    }
    let timeout_s = match goal.timeout_s {
        0.0 => None,
        t if t.is_finite() && t > 0.0 && t <= MAX_WAIT_S => Some(t),
        t => {
            return Err(format!(
                "timeout_s: expected 0 (the node's) or seconds in (0, {MAX_WAIT_S}], got {t}"
            ))
        }
    };
    Ok(Job {
        input,
        mesh: Some(mesh),
        max_fragments,
        timeout_s,
        first_feasible: goal.first_feasible,
    })
}

/// Sends `reply` to the action thread (dropped when it is gone: the node is stopping).
pub fn send(replies: &Sender<Reply>, reply: Reply) {
    let _ = replies.send(reply);
}
