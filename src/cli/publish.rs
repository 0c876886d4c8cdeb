//! `waam publish PART`: plan one part file, publish everything once on ROS 2 and exit.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use clap::Args;
use waam_part::graph::WeldGraph;
use waam_part::plan::Plan;
use waam_part::Part;
use waam_pipeline::ChosenPlan;
use waam_ros::node::pipeline::{sat_planner, PartInput, PlanFn, PlanRequest};
use waam_ros::node::{Mode, RunOptions};

use super::node::{load_params, stop_on_signal};
use super::{EXIT_NO, EXIT_OK};

/// Plan a part file and publish the result once, as `waam node` would, then exit.
///
/// Publishes the joint trajectory, poses, path, markers, weld plan and status on the node's
/// topics (as node `waam_planner`), keeps them available to late subscribers for --linger
/// seconds, and exits 0 when the part was planned (and executed), 1 when not.
#[derive(Debug, Args)]
pub struct PublishArgs {
    /// The part file (YAML, shared part format).
    pub part: PathBuf,
    /// Publish this plan (YAML or JSON plan format) instead of planning; it is validated and
    /// thermally checked first.
    #[arg(long, value_name = "PLAN")]
    pub plan: Option<PathBuf>,
    /// ROS 2 parameters file; default: the bundled config/waam_planner.params.yaml.
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Follow the trajectory with the built-in simulated controller (publishes
    /// /joint_states and ~/arc_on), then exit.
    #[arg(long)]
    pub dry_run: bool,
    /// Execute on the FollowJointTrajectory controller of the parameters file
    /// (execution.controller_action), even if execution.enabled is false.
    #[arg(long, conflicts_with = "dry_run")]
    pub execute: bool,
    /// Before planning, wait up to this many seconds for a subscriber on the joint trajectory
    /// topic (so that a viewer started at the same time sees the whole run).
    #[arg(long, value_name = "SECONDS", default_value_t = 0.0)]
    pub wait_for_subscriber: f64,
    /// Seconds to keep serving the latched outputs before exiting.
    #[arg(long, value_name = "SECONDS", default_value_t = 2.0)]
    pub linger: f64,
    /// Record everything sent into this rosbag2 directory (MCAP).
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
}

pub fn run(args: PublishArgs) -> anyhow::Result<ExitCode> {
    let mut params = load_params(args.params.as_deref())?;
    if args.execute {
        params.execution.enabled = true;
    }
    let text = std::fs::read_to_string(&args.part)
        .with_context(|| format!("cannot read part {}", args.part.display()))?;
    let planner = match &args.plan {
        Some(path) => given_plan(&text, path)?,
        None => sat_planner(),
    };
    for (name, v) in [
        ("--linger", args.linger),
        ("--wait-for-subscriber", args.wait_for_subscriber),
    ] {
        anyhow::ensure!(
            v.is_finite() && v >= 0.0,
            "{name}: expected seconds >= 0, got {v}"
        );
    }
    let options = RunOptions {
        params,
        names: Default::default(),
        dry_run: args.dry_run,
        record: args.record,
        planner,
    };
    let mode = Mode::Once {
        input: PartInput::Document(text),
        wait_for_subscriber: Duration::from_secs_f64(args.wait_for_subscriber),
        linger: Duration::from_secs_f64(args.linger),
    };
    let ok = waam_ros::node::run(options, mode, stop_on_signal()?)?;
    Ok(ExitCode::from(if ok { EXIT_OK } else { EXIT_NO }))
}

/// A "planner" that answers with the plan read from `path` (for the part in `part_text`).
fn given_plan(part_text: &str, path: &std::path::Path) -> anyhow::Result<Arc<PlanFn>> {
    let part = Part::parse(part_text).context("in the part file")?;
    let bytes =
        std::fs::read(path).with_context(|| format!("cannot read plan {}", path.display()))?;
    let json = path.extension().is_some_and(|e| e == "json");
    let plan =
        Plan::from_bytes(&bytes, json).with_context(|| format!("in plan {}", path.display()))?;
    let fragments = plan
        .validate(&part, &WeldGraph::new(&part))
        .map_err(|e| anyhow::anyhow!("plan {} is invalid: {e}", path.display()))?;
    Ok(Arc::new(move |request: &PlanRequest| {
        request.motion(ChosenPlan {
            fragments: fragments.clone(),
            stats: Default::default(),
            proven: false,
            worst_margin_s: f64::INFINITY,
        })
    }))
}
