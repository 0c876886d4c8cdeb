//! `waam node`: run the ROS 2 node `waam_planner`.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::Context;
use clap::Args;
use waam_ros::node::params::NodeParams;
use waam_ros::node::pipeline::sat_planner;
use waam_ros::node::{Mode, RunOptions};

/// Run the ROS 2 node `waam_planner` beside a welding cell.
///
/// Takes parts on `~/part` (std_msgs/String, a part document) and `~/part_mesh`
/// (shape_msgs/Mesh in metres), plans each off the executor (a newer part cancels the one in
/// progress) and publishes the joint trajectory, poses, path, markers and weld plan on
/// `~/plan/*` (Reliable, TransientLocal) and its state on `~/status`. Honours ROS_DOMAIN_ID
/// and ROS_AUTOMATIC_DISCOVERY_RANGE (or ROS_LOCALHOST_ONLY). Stops on Ctrl-C / SIGTERM.
#[derive(Debug, Args)]
pub struct NodeArgs {
    /// ROS 2 parameters file (`waam_planner: ros__parameters: ...`); default: the bundled
    /// config/waam_planner.params.yaml.
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Follow every plan with the built-in simulated controller, publishing /joint_states
    /// (and ~/arc_on) in real time scaled by dry_run.time_scale; no robot needed.
    #[arg(long)]
    pub dry_run: bool,
    /// Record everything the node receives and sends into this rosbag2 directory (MCAP).
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
}

/// Reads the parameters file, or the bundled defaults.
pub fn load_params(path: Option<&Path>) -> anyhow::Result<NodeParams> {
    match path {
        Some(path) => Ok(NodeParams::from_file(path)?),
        None => Ok(NodeParams::defaults()),
    }
}

/// A stop flag raised by Ctrl-C or SIGTERM.
pub fn stop_on_signal() -> anyhow::Result<Arc<AtomicBool>> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed))
        .context("cannot install the Ctrl-C handler")?;
    Ok(stop)
}

pub fn run(args: NodeArgs) -> anyhow::Result<ExitCode> {
    let params = load_params(args.params.as_deref())?;
    let options = RunOptions {
        params,
        dry_run: args.dry_run,
        record: args.record,
        planner: sat_planner(),
    };
    waam_ros::node::run(options, Mode::Serve, stop_on_signal()?)?;
    Ok(ExitCode::SUCCESS)
}
