//! Execution on a real controller: a `control_msgs/action/FollowJointTrajectory` client.
//!
//! One goal at a time: wait for the action server (bounded), send the goal, wait for
//! acceptance, then for the result; a cancelled execution cancels the goal on the server.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use futures::FutureExt as _;
use ros2_client::action::ActionClientQosPolicies;
use ros2_client::action_msgs::GoalStatusEnum;
use ros2_client::{ActionClient, ActionTypeName, Node, QosProfile, ServiceMapping};

use super::controller::{Controller, ExecError};
use super::names::NodeNames;
use super::params::ExecutionParams;
use super::ros::ServeError;
use super::worker::Cancel;
use waam_rosmsg::control_msgs::{
    FollowJointTrajectoryFeedback as Feedback, FollowJointTrajectoryGoal as Goal,
    FollowJointTrajectoryResult as FjtResult, JointTolerance,
};
use waam_rosmsg::trajectory_msgs::JointTrajectory as TrajectoryMsg;

type Client = ActionClient<Goal, FjtResult, Feedback>;

/// The QoS rcl uses for action services and topics (services: reliable, volatile, depth 10;
/// status: transient local).
fn action_qos() -> ActionClientQosPolicies {
    let service =
        QosProfile::publisher_default().history(ros2_client::qos::History::KeepLast { depth: 10 });
    ActionClientQosPolicies {
        goal_service: service.clone(),
        result_service: service.clone(),
        cancel_service: service.clone(),
        feedback_subscription: service.clone(),
        status_subscription: service
            .durability(ros2_client::qos::Durability::TransientLocal)
            .history(ros2_client::qos::History::KeepLast { depth: 1 }),
    }
}

/// std_srvs/Trigger request: an empty message, which carries one placeholder byte in CDR.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct TriggerRequest {
    pub structure_needs_at_least_one_member: u8,
}
impl ros2_client::Message for TriggerRequest {}

/// std_srvs/Trigger response.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct TriggerResponse {
    pub success: bool,
    pub message: String,
}
impl ros2_client::Message for TriggerResponse {}

type Trigger = ros2_client::Client<TriggerRequest, TriggerResponse>;

/// Runs goals on a FollowJointTrajectory action server.
pub struct FjtController {
    client: Client,
    node: Arc<Mutex<Node>>,
    action: String,
    server_timeout: Duration,
    /// The controller's joint names in the URDF's joint order; empty: the URDF's.
    joint_names: Vec<String>,
    goal_tolerance: f64,
    path_tolerance: f64,
    goal_time_tolerance: f64,
    /// Called before each plan runs (MotoROS2's trajectory mode), with its name.
    start: Option<(Trigger, String)>,
}

impl FjtController {
    pub fn new(
        node: Arc<Mutex<Node>>,
        names: &NodeNames,
        params: &ExecutionParams,
    ) -> Result<Self, super::NodeError> {
        let mut guard = node.lock().unwrap_or_else(|e| e.into_inner());
        let name = names.resolve(&params.controller_action)?;
        let client = guard
            .create_action_client::<Goal, FjtResult, Feedback>(
                ServiceMapping::Enhanced,
                &name,
                &ActionTypeName::new("control_msgs", "FollowJointTrajectory"),
                action_qos(),
            )
            .map_err(|e| ServeError::Create {
                what: "action client",
                name: name.to_string(),
                reason: format!("{e:?}"),
            })?;
        let start = if params.start_service.is_empty() {
            None
        } else {
            let service = names.resolve(&params.start_service)?;
            let qos = QosProfile::publisher_default()
                .history(ros2_client::qos::History::KeepLast { depth: 10 });
            let client = guard
                .create_client::<TriggerRequest, TriggerResponse>(
                    ServiceMapping::Enhanced,
                    &service,
                    &ros2_client::ServiceTypeName::new("std_srvs", "Trigger"),
                    qos.clone(),
                    qos,
                )
                .map_err(|e| ServeError::Create {
                    what: "service client",
                    name: service.to_string(),
                    reason: format!("{e:?}"),
                })?;
            Some((client, service.to_string()))
        };
        drop(guard);
        Ok(FjtController {
            client,
            node,
            action: name.to_string(),
            server_timeout: Duration::from_secs_f64(params.server_timeout_s),
            joint_names: params.joint_names.clone(),
            goal_tolerance: params.goal_tolerance_rad,
            path_tolerance: params.path_tolerance_rad,
            goal_time_tolerance: params.goal_time_tolerance_s,
            start,
        })
    }

    /// The controller's names for the goal's joints `urdf` (in the URDF's joint order).
    fn map_names(&self, urdf: &[String]) -> Result<Vec<String>, ExecError> {
        if self.joint_names.is_empty() {
            return Ok(urdf.to_vec());
        }
        if self.joint_names.len() != urdf.len() {
            return Err(ExecError(format!(
                "execution.joint_names has {} names, the robot {} joints ({})",
                self.joint_names.len(),
                urdf.len(),
                urdf.join(", ")
            )));
        }
        Ok(self.joint_names.clone())
    }

    /// Per-joint tolerances (`value` 0 = the controller's default: no entry at all).
    fn tolerances(names: &[String], value: f64) -> Vec<JointTolerance> {
        if value == 0.0 {
            return Vec::new();
        }
        names
            .iter()
            .map(|name| JointTolerance {
                name: name.clone(),
                position: value,
                ..JointTolerance::default()
            })
            .collect()
    }

    /// Waits until the action's goal and result services have a server (bounded).
    fn wait_for_server(&self) -> Result<(), ExecError> {
        let node = self.node.lock().unwrap_or_else(|e| e.into_inner());
        let waits = async {
            futures::join!(
                self.client.goal_client().wait_for_service(&node),
                self.client.result_client().wait_for_service(&node)
            );
        };
        let found = futures::executor::block_on(async {
            futures::select! {
                _ = waits.fuse() => true,
                _ = sleep(self.server_timeout).fuse() => false,
            }
        });
        if found {
            Ok(())
        } else {
            Err(ExecError(format!(
                "no FollowJointTrajectory server on {} after {:.1} s",
                self.action,
                self.server_timeout.as_secs_f64()
            )))
        }
    }
}

/// A future that completes after `d` (a helper thread; we have no async timer otherwise).
fn sleep(d: Duration) -> futures::channel::oneshot::Receiver<()> {
    let (tx, rx) = futures::channel::oneshot::channel();
    std::thread::spawn(move || {
        std::thread::sleep(d);
        let _ = tx.send(());
    });
    rx
}

/// Polls `f` every 5 ms until it yields, `cancel` is raised or `deadline` passes.
fn poll_until<T>(
    deadline: Instant,
    cancel: &Cancel,
    mut f: impl FnMut() -> Result<Option<T>, ExecError>,
) -> Result<Option<T>, ExecError> {
    loop {
        if let Some(v) = f()? {
            return Ok(Some(v));
        }
        if cancel.is_cancelled() || Instant::now() >= deadline {
            return Ok(None);
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

impl Controller for FjtController {
    fn prepare(&mut self, cancel: &Cancel) -> Result<(), ExecError> {
        let Some((client, service)) = &self.start else {
            return Ok(());
        };
        let node = self.node.lock().unwrap_or_else(|e| e.into_inner());
        let found = futures::executor::block_on(async {
            futures::select! {
                _ = client.wait_for_service(&node).fuse() => true,
                _ = sleep(self.server_timeout).fuse() => false,
            }
        });
        drop(node);
        if !found {
            return Err(ExecError(format!(
                "no service {service} after {:.1} s",
                self.server_timeout.as_secs_f64()
            )));
        }
        let request = client
            .send_request(TriggerRequest::default())
            .map_err(|e| format!("cannot call {service}: {e:?}"))?;
        let deadline = Instant::now() + self.server_timeout;
        let response = poll_until(deadline, cancel, || {
            Ok(match client.receive_response() {
                Ok(Some((id, r))) if id == request => Some(r),
                _ => None,
            })
        })?;
        match response {
            Some(r) if r.success => Ok(()),
            Some(r) => Err(ExecError(format!("{service} refused: {}", r.message))),
            None => Err(ExecError(format!("{service} did not answer"))),
        }
    }

    fn execute(
        &mut self,
        trajectory: TrajectoryMsg,
        cancel: &Cancel,
        during: &mut dyn FnMut(f64),
    ) -> Result<(), ExecError> {
        self.wait_for_server()?;
        let duration = trajectory
            .points
            .last()
            .map_or(0.0, |p| p.time_from_start.as_secs_f64());
        let mut trajectory = trajectory;
        trajectory.joint_names = self.map_names(&trajectory.joint_names)?;
        let names = &trajectory.joint_names;
        let goal = Goal {
            path_tolerance: Self::tolerances(names, self.path_tolerance),
            goal_tolerance: Self::tolerances(names, self.goal_tolerance),
            goal_time_tolerance: waam_rosmsg::builtin_interfaces::Duration::from_secs_f64(
                self.goal_time_tolerance,
            ),
            trajectory,
            ..Goal::default()
        };
        let (request, goal_id) = self
            .client
            .send_goal(goal)
            .map_err(|e| format!("cannot send the goal: {e}"))?;
        let answer_by = Instant::now() + self.server_timeout;
        let response = poll_until(answer_by, cancel, || {
            self.client
                .receive_goal_response(request)
                .map_err(|e| ExecError(format!("reading the goal response: {e:?}")))
        })?;
        match response {
            Some(r) if r.accepted => {}
            Some(_) => return Err(ExecError(format!("{} rejected the goal", self.action))),
            None if cancel.is_cancelled() => return Err(ExecError("cancelled".into())),
            None => {
                return Err(ExecError(format!(
                    "{} did not answer the goal",
                    self.action
                )))
            }
        }
        let result_request = self
            .client
            .request_result(goal_id)
            .map_err(|e| format!("cannot request the result: {e}"))?;
        // The goal takes its duration; allow the server timeout on top for the answer.
        let done_by = Instant::now() + Duration::from_secs_f64(duration) + self.server_timeout;
        let result = poll_until(done_by, cancel, || {
            during(self.now_s());
            self.client
                .receive_result(result_request)
                .map_err(|e| ExecError(format!("reading the result: {e:?}")))
        })?;
        match result {
            Some((GoalStatusEnum::Succeeded, r)) if r.error_code == FjtResult::SUCCESSFUL => Ok(()),
            Some((status, r)) => Err(ExecError(format!(
                "goal ended {status:?}, error code {}: {}",
                r.error_code, r.error_string
            ))),
            None => {
                let _ = self.client.cancel_goal(goal_id);
                if cancel.is_cancelled() {
                    Err(ExecError("cancelled (goal cancel sent)".into()))
                } else {
                    Err(ExecError(format!(
                        "no result from {} {:.1} s after the goal's end (goal cancel sent)",
                        self.action,
                        self.server_timeout.as_secs_f64()
                    )))
                }
            }
        }
    }
}
