//! Planning as an action: `~/plan` of type `waam_interfaces/action/PlanPart`
//! (`ros/waam_interfaces/action/PlanPart.action`). A client ties its request to its result,
//! gets progress as feedback and can cancel.
//!
//! The action thread ([`action`]) speaks the protocol; the node's event loop runs the jobs on
//! the same worker as `~/part` (the latest request wins: a newer goal or part cancels the goal
//! in progress) and answers with [`Reply`]s.

use std::sync::atomic::AtomicBool;
use std::sync::mpsc::{Receiver, Sender};
use std::sync::Arc;

use ros2_client::action::GoalId;
use ros2_client::Node;
use serde::{Deserialize, Serialize};

use super::action;
use super::names::NodeNames;
use super::param_server::ParamStore;
use super::params::MAX_WAIT_S;
use super::pipeline::{mesh_input, mesh_settings, Job, PartInput, SetupError};
use super::ros::ServeError;
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
    /// The plan's number (as in `~/status`): `~/execute` runs it; 0 without a plan.
    pub job: u64,
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
            job: 0,
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
pub type Request = action::Request<Job>;

/// What the event loop tells the action thread.
pub type Reply = action::Reply<PlanPartResult, PlanPartFeedback>;

impl action::Failed for PlanPartResult {
    fn failed(reason: &str) -> Self {
        PlanPartResult::failed(PlanPartResult::BAD_INPUT, reason)
    }
}

/// Turns goals into jobs for the event loop.
struct Goals<F> {
    store: Arc<ParamStore>,
    requests: F,
}

impl<F: Fn(Request) -> bool + Send + 'static> action::Handler<PlanPartGoal, PlanPartResult>
    for Goals<F>
{
    fn goal(&mut self, id: GoalId, goal: PlanPartGoal) -> Result<(), PlanPartResult> {
        let job = job_of(goal, &self.store)
            .map_err(|e| PlanPartResult::failed(PlanPartResult::BAD_INPUT, e.to_string()))?;
        if (self.requests)(Request::Goal { goal: id, job }) {
            Ok(())
        } else {
            Err(PlanPartResult::failed(
                PlanPartResult::CANCELLED,
                "the node is shutting down",
            ))
        }
    }

    fn cancel(&mut self, id: GoalId) -> bool {
        (self.requests)(Request::Cancel(id))
    }
}

/// Starts `~/plan` (remapped as the node's names say); runs until `stop` is raised.
pub fn serve(
    node: &mut Node,
    names: &NodeNames,
    store: Arc<ParamStore>,
    requests: impl Fn(Request) -> bool + Send + 'static,
    replies: Receiver<Reply>,
    stop: Arc<AtomicBool>,
) -> Result<std::thread::JoinHandle<()>, ServeError> {
    action::serve(
        node,
        names,
        "~/plan",
        ("waam_interfaces", "PlanPart"),
        Goals { store, requests },
        replies,
        stop,
    )
}

/// Why a `~/plan` goal cannot be planned (the goal's field and what it must be).
#[derive(Debug, thiserror::Error)]
pub enum GoalError {
    #[error("the goal has neither a part_document nor a mesh")]
    NoPart,
    /// The node's mesh parameters cannot voxelize a mesh.
    #[error(transparent)]
    MeshParams(#[from] SetupError),
    #[error("block_mm: expected [] or three lengths > 0 (mm), got {0:?}")]
    BlockMm(Vec<f64>),
    #[error("t85_window_s: expected [] or [min_s, max_s] with 0 <= min_s <= max_s, got {0:?}")]
    Window(Vec<f64>),
    #[error("max_fragments: expected 0 or k >= 1, got {0}")]
    MaxFragments(i32),
    #[error("timeout_s: expected 0 (the node's) or seconds in (0, {max}], got {0}", max = MAX_WAIT_S)]
    Timeout(f64),
}

/// The job a goal asks for, or why it cannot be planned.
fn job_of(goal: PlanPartGoal, store: &ParamStore) -> Result<Job, GoalError> {
    let input = if !goal.part_document.is_empty() {
        PartInput::Document(goal.part_document)
    } else if !goal.mesh.vertices.is_empty() {
        mesh_input("goal-mesh".into(), &goal.mesh)
    } else {
        return Err(GoalError::NoPart);
    };
    let mut mesh = mesh_settings(&store.current())?;
    match goal.block_mm[..] {
        [] => {}
        [a, b, c] if [a, b, c].iter().all(|v| v.is_finite() && *v > 0.0) => {
            // A goal's pitch asks for blocks, over the node's beads.
            (mesh.block_mm, mesh.bead_mm) = ([a, b, c], None)
        }
        _ => return Err(GoalError::BlockMm(goal.block_mm)),
    }
    match goal.t85_window_s[..] {
        [] => {}
        [min_s, max_s]
            if min_s.is_finite() && max_s.is_finite() && 0.0 <= min_s && min_s <= max_s =>
        {
            mesh.window = Some(Window { min_s, max_s })
        }
        _ => return Err(GoalError::Window(goal.t85_window_s)),
    }
    let max_fragments = match goal.max_fragments {
        0 => None,
        k if k > 0 => Some(k as usize),
        k => return Err(GoalError::MaxFragments(k)),
    };
    if let Some(k) = max_fragments {
        mesh.max_fragments = k;
    }
    let timeout_s = match goal.timeout_s {
        0.0 => None,
        t if t.is_finite() && t > 0.0 && t <= MAX_WAIT_S => Some(t),
        t => return Err(GoalError::Timeout(t)),
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
