#!/usr/bin/env bash
# The whole test suite, from a fresh clone on a Debian machine that has Rust.
# It installs what the tests need itself (Python environments for the cross-tool tests),
# then checks formatting and lints, then runs every test. `.ci/run` calls this script.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n== %s\n' "$*"; }

step "formatting (cargo fmt --check)"
cargo fmt --all -- --check

step "lints (cargo clippy -D warnings)"
cargo clippy --workspace --all-targets --all-features -- -D warnings

# The independent checker lives beside the repo (shared/); the project's own tests do not
# need it, but where it is present the cross-check against it runs too.
if [[ -d ../shared/tools/refcheck ]]; then
    step "reference checker venv (shared/tools/refcheck)"
    WAAM_REFCHECK_PY="$(scripts/refcheck.sh)"
    export WAAM_REFCHECK_PY
fi

step "recording tests venv (scripts/py-venv.sh: mcap, mcap-ros2-support, rosbags)"
WAAM_BAG_PYTHON="$(scripts/py-venv.sh | tail -1)"
export WAAM_BAG_PYTHON

step "export tests venv (scripts/export-venv.sh: rapidchecker, pygcode)"
WAAM_EXPORT_PYTHON="$(scripts/export-venv.sh | tail -1)"
export WAAM_EXPORT_PYTHON

step "bead coverage venv (scripts/coverage-venv.sh: trimesh, shapely)"
WAAM_COVERAGE_PYTHON="$(scripts/coverage-venv.sh | tail -1)"
export WAAM_COVERAGE_PYTHON

step "ROS 2 Jazzy venv (scripts/ros-venv.sh: rclpy, message packages, Fast DDS wheels)"
WAAM_ROS_VENV="$(scripts/ros-venv.sh | tail -1)"
export WAAM_ROS_VENV

# The ~/plan and ~/execute action types and the test controller's control_msgs, for rclpy.
step "ROS 2 interfaces (scripts/build-interfaces.sh: waam_interfaces, the tests' control_msgs)"
scripts/build-interfaces.sh
export WAAM_ROS_BUILD_VENV="$PWD/.venv-ros-build" WAAM_ROS_INTERFACES="$PWD/ros/install"

# `milp` adds the MILP cross-check of the thick-wall layer search (pure Rust, light).
step "tests (cargo test)"
cargo test --workspace --all-targets --all-features

# The fuzz harness (crates/ros/tests/fuzz.rs: one mutation fuzzer per reader over the corpus in
# tests/data/fuzz/) ran above with its default 160 cases per reader; once more with 10,000
# each (a few seconds per reader), bounded in time so that a hang fails the run. The same
# package selection and features as above, so that the build above is reused (without them
# cargo resolves other features and rebuilds the binary and its crates: ~2 minutes).
step "fuzz (crates/ros/tests/fuzz.rs, 10,000 cases per reader)"
WAAM_FUZZ_CASES=10000 timeout 600 cargo test --workspace --all-features --test fuzz
