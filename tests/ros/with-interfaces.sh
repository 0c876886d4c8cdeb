#!/usr/bin/env bash
# Runs Python with the interfaces scripts/build-interfaces.sh built (waam_interfaces with its
# actions, the tests' control_msgs): `with-interfaces.sh VENV INSTALL script.py ARGS...`,
# VENV = .venv-ros-build, INSTALL = ros/install.
set -eo pipefail
venv="$1" install="$2"
shift 2
# (no `set -u`: colcon's setup scripts read unset variables)
# shellcheck disable=SC1091
source "$venv/bin/activate"
# shellcheck disable=SC1091
source "$install/setup.bash"
exec python "$@"
