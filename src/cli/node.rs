//! `waam node`: run the ROS 2 node.

use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use clap::Args;

/// Run the ROS 2 node `waam_planner`.
#[derive(Debug, Args)]
pub struct NodeArgs {}

pub fn run(_args: NodeArgs) -> anyhow::Result<ExitCode> {
    waam::node::run_echo(Arc::new(AtomicBool::new(false)))?;
    Ok(ExitCode::SUCCESS)
}
