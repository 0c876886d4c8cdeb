#!/usr/bin/env bash
# The Python venv the recording tests read bags with: .venv-py, holding the MCAP and rosbag2
# readers at pinned versions (see scripts/venv.sh). Prints the venv's python path last.
exec "$(dirname "${BASH_SOURCE[0]}")/venv.sh" py mcap==1.6.0 mcap-ros2-support==0.6.0 rosbags==0.11.9
