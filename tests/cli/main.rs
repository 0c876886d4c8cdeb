//! The `waam` command line's tests, in one binary (as ripgrep's `tests/integration/`): one
//! module per topic, all sharing [`common`] (the one `fn waam`, the sample parts, the
//! recordings' helpers). The library crates' own tests live beside them, in
//! `crates/<crate>/tests/`.
//!
//! Some modules drive Python or ROS 2 peers and skip unless their environment is set up
//! (`WAAM_BAG_PYTHON`, `WAAM_EXPORT_PYTHON`, `WAAM_COVERAGE_PYTHON`, `WAAM_ROS_VENV`, `WAAM_REFCHECK_PY`, ...:
//! `scripts/test.sh` sets them).

mod common;

mod access;
mod bag;
mod bag_python;
mod bench_generate;
mod cli_motion;
mod coverage;
mod export;
mod first_run;
mod harden;
mod layer;
mod layer_motion;
mod layer_part;
mod limits;
mod mesh;
mod planner;
mod readme_architecture;
mod refcheck_crosscheck;
mod replay;
mod replay_publish;
mod robustness;
mod ros_node;
mod sim_cell;
mod torch;
