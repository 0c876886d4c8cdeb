//! `waam node`: run the ROS 2 node `waam_planner`.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::Context;
use clap::Args;
use waam_ros::node::args::RosArgs;
use waam_ros::node::declared::value_from_yaml;
use waam_ros::node::names::NodeNames;
use waam_ros::node::params::NodeParams;
use waam_ros::node::pipeline::sat_planner;
use waam_ros::node::{Mode, RunOptions};

/// Run the ROS 2 node `waam_planner` beside a welding cell.
///
/// Takes parts on `~/part` (std_msgs/String, a part document: blocks, or a graph part of
/// beads) and `~/part_mesh` (shape_msgs/Mesh in metres: voxelized at `mesh.block_mm`, or,
/// with the parameter `mesh.bead_mm: [W, H]` (mm), sliced into beads along its contours as
/// `waam slice --bead "W H"` does, the torch then following each bead's centre line),
/// plans each off the executor (a newer part cancels the one in progress) and publishes the joint trajectory, poses, path, markers and weld plan on
/// `~/plan/*` (Reliable, TransientLocal) and its state on `~/status`. For the closed loop it
/// takes the cell's sensors on `~/scan` (sensor_msgs/PointCloud2, a layer height scan in
/// metres, frame `part`, the robot's base link or any frame /tf and /tf_static connect to
/// them), `~/temperature` (sensor_msgs/Temperature, a pyrometer), `~/thermal_image`
/// (sensor_msgs/PointCloud2 with a `temperature` field, a thermal camera's image on the part)
/// and `~/arc_fault` (std_msgs/Header from the welder, stamped when the arc went out: the
/// weld goal is cancelled and the rest re-planned), and sends each weld path's wire feed per
/// deposit on `~/wire_feed_schedule` (trajectory_msgs/JointTrajectory, joint `wire_feed`,
/// relative to nominal) and the feed it strikes at on `~/wire_feed` (std_msgs/Float64;
/// `closed_loop.wire_feed_per_deposit:=false`: one feed per weld path): bad or late data
/// (`closed_loop.max_age_s`), or a sensor silent beyond its cadence
/// (`closed_loop.*_period_s`) while executing, is a WARN on /diagnostics naming the topic
/// and the reason, never a stop. Every setting of the
/// parameters file is a ROS parameter (`ros2 param list/get/set/describe/dump`); a change
/// applies from the next plan. Honours ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE (or
/// ROS_LOCALHOST_ONLY) and `--ros-args` as `ros2 run` and `ros2 launch` pass them. Stops on
/// Ctrl-C / SIGTERM.
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
    /// ROS 2 arguments, as rcl reads them (everything after --ros-args, up to `--`):
    /// `-r __ns:=/cell1` namespace, `-r __node:=NAME` node name, `-r FROM:=TO` topic remap,
    /// `-p NAME:=VALUE` parameter (e.g. `-p planner.timeout_s:=30.0`), `--params-file FILE`
    /// (applied after --params, before -p).
    #[arg(long = "ros-args", num_args = 0.., allow_hyphen_values = true, value_name = "ARG")]
    pub ros_args: Option<Vec<String>>,
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

/// The node's names and parameters: defaults, `--params`, each `--params-file`, each `-p`.
pub fn ros_setup(
    params_file: Option<&Path>,
    ros_args: &[String],
) -> anyhow::Result<(NodeNames, NodeParams)> {
    let ros = RosArgs::parse(ros_args)?;
    for ignored in &ros.ignored {
        tracing::warn!("--ros-args {ignored}: accepted but not acted on by this node");
    }
    let names = ros.names();
    let files: Vec<PathBuf> = params_file
        .map(Path::to_path_buf)
        .into_iter()
        .chain(ros.params_files.iter().cloned())
        .collect();
    let mut overrides = Vec::new();
    for (node, name, text) in &ros.params {
        if node.as_deref().is_some_and(|n| n != names.name) {
            continue; // for another node of the launch
        }
        let value = value_from_yaml(text).map_err(|e| anyhow::anyhow!("-p {name}: {e}"))?;
        overrides.push((name.clone(), value));
    }
    let params = NodeParams::load(&files, &names.fully_qualified(), &overrides)?;
    Ok((names, params))
}

pub fn run(args: NodeArgs) -> anyhow::Result<ExitCode> {
    let (names, params) = ros_setup(
        args.params.as_deref(),
        args.ros_args.as_deref().unwrap_or_default(),
    )?;
    let options = RunOptions {
        params,
        names,
        dry_run: args.dry_run,
        record: args.record,
        planner: sat_planner(),
    };
    waam_ros::node::run(options, Mode::Serve, stop_on_signal()?)?;
    Ok(ExitCode::SUCCESS)
}
