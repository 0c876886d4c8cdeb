//! Execution as an action: `~/execute` of type `waam_interfaces/action/ExecutePlan`
//! (`ros/waam_interfaces/action/ExecutePlan.action`). The goal names a plan the node made (its
//! number, or 0 for the latest); the node runs that plan's validated trajectory on the
//! FollowJointTrajectory controller (or the dry run's simulated one), with feedback per goal
//! chunk; cancelling stops it as `~/stop` does (goal cancelled, arc off).

use std::sync::atomic::AtomicBool;
use std::sync::mpsc::Receiver;
use std::sync::Arc;

use ros2_client::action::GoalId;
use ros2_client::Node;
use serde::{Deserialize, Serialize};

use super::action;
use super::names::NodeNames;
use super::ros::ServeError;

/// `ExecutePlan` goal.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct ExecutePlanGoal {
    pub job: u64,
}
impl ros2_client::Message for ExecutePlanGoal {}

/// `ExecutePlan` result.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct ExecutePlanResult {
    pub outcome: u8,
    pub job: u64,
    pub message: String,
}
impl ros2_client::Message for ExecutePlanResult {}

impl ExecutePlanResult {
    pub const EXECUTED: u8 = 0;
    pub const FAILED: u8 = 1;
    pub const CANCELLED: u8 = 2;
    pub const NO_PLAN: u8 = 3;
    pub const UNAVAILABLE: u8 = 4;

    pub fn new(outcome: u8, job: u64, message: impl Into<String>) -> ExecutePlanResult {
        ExecutePlanResult {
            outcome,
            job,
            message: message.into(),
        }
    }
}

impl action::Failed for ExecutePlanResult {
    fn failed(reason: &str) -> Self {
        ExecutePlanResult::new(ExecutePlanResult::NO_PLAN, 0, reason)
    }
}

/// `ExecutePlan` feedback: sent as each goal chunk starts.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ExecutePlanFeedback {
    pub job: u64,
    /// 1-based number of the goal chunk being run, and how many there are.
    pub chunk: u32,
    pub chunks: u32,
    /// Whether the arc burns during this chunk.
    pub arc_on: bool,
    /// The weld path being welded (1-based), 0 for arc-off moves.
    pub weld_path: u32,
    /// The chunk's trajectory points (indices into the plan's joint trajectory).
    pub first_point: u32,
    pub last_point: u32,
    /// Share of the trajectory's duration done when this chunk starts (0..1).
    pub progress: f64,
}
impl ros2_client::Message for ExecutePlanFeedback {}

/// What the action thread asks of the event loop.
pub type Request = action::Request<u64>;

/// What the event loop tells the action thread.
pub type Reply = action::Reply<ExecutePlanResult, ExecutePlanFeedback>;

struct Goals<F>(F);

impl<F: Fn(Request) -> bool + Send + 'static> action::Handler<ExecutePlanGoal, ExecutePlanResult>
    for Goals<F>
{
    fn goal(&mut self, id: GoalId, goal: ExecutePlanGoal) -> Result<(), ExecutePlanResult> {
        if (self.0)(Request::Goal {
            goal: id,
            job: goal.job,
        }) {
            Ok(())
        } else {
            Err(ExecutePlanResult::new(
                ExecutePlanResult::UNAVAILABLE,
                goal.job,
                "the node is shutting down",
            ))
        }
    }

    fn cancel(&mut self, id: GoalId) -> bool {
        (self.0)(Request::Cancel(id))
    }
}

/// Starts `~/execute` (remapped as the node's names say); runs until `stop` is raised.
pub fn serve(
    node: &mut Node,
    names: &NodeNames,
    requests: impl Fn(Request) -> bool + Send + 'static,
    replies: Receiver<Reply>,
    stop: Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<()>, ServeError> {
    action::serve(
        node,
        names,
        "~/execute",
        ("waam_interfaces", "ExecutePlan"),
        Goals(requests),
        replies,
        stop,
    )
}
