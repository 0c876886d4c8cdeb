#!/usr/bin/env bash
# Creates (or refreshes) .venv-ros in the repository root: Python 3.11 with ROS 2 Jazzy's rclpy,
# the message packages and Fast DDS from PyPI wheels. Idempotent: a stamp file records what was
# installed, so a second run with nothing changed returns at once.
#
# The wheels need no ROS install and no sourcing: `ros_wheels_bootstrapper` (pulled in by rclpy)
# re-executes the interpreter with LD_LIBRARY_PATH pointing at the wheels' bundled libraries, so
# `.venv-ros/bin/python script.py` is all a caller needs.
#
# Usage: scripts/ros-venv.sh        (prints the venv's path on its last line)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
venv="${WAAM_ROS_VENV:-$root/.venv-ros}"
packages=(
  ros-jazzy-rclpy ros-jazzy-std-msgs ros-jazzy-geometry-msgs ros-jazzy-trajectory-msgs
  ros-jazzy-visualization-msgs ros-jazzy-nav-msgs ros-jazzy-shape-msgs ros-jazzy-diagnostic-msgs
  ros-jazzy-sensor-msgs ros-jazzy-rmw-fastrtps-cpp
)
stamp="$venv/.waam-ros-packages"
wanted="${packages[*]}"

if [[ -x "$venv/bin/python" && -f "$stamp" && "$(cat "$stamp")" == "$wanted" ]]; then
  echo "$venv"
  exit 0
fi

# The wheels are built for CPython 3.11 only.
find_python() {
  for candidate in python3.11 python3; do
    if command -v "$candidate" >/dev/null 2>&1 &&
      "$candidate" -c 'import sys, venv, ensurepip; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
      command -v "$candidate"
      return 0
    fi
  done
  return 1
}
if ! python="$(find_python)"; then
  echo "ros-venv: no Python 3.11 with venv found; installing it with apt-get" >&2
  if [[ $(id -u) -ne 0 ]]; then sudo=sudo; else sudo=; fi
  $sudo apt-get update -qq
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3.11 python3.11-venv >&2
  python="$(find_python)" || { echo "ros-venv: Python 3.11 still not usable" >&2; exit 1; }
fi

echo "ros-venv: creating $venv with $python" >&2
"$python" -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check "${packages[@]}" >&2
# A smoke test: the interpreter re-executes itself with the wheels' libraries and loads rclpy.
"$venv/bin/python" -c 'import rclpy, std_msgs.msg, trajectory_msgs.msg, visualization_msgs.msg' >&2
echo "$wanted" >"$stamp"
echo "$venv"
