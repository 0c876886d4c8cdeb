#!/usr/bin/env bash
# Creates (or reuses) the Python venv the recording tests read bags with: .venv-py in the repo
# root, holding the MCAP and rosbag2 readers at pinned versions. Idempotent: a venv that already
# has these versions is left as it is. Prints the venv's python path on its last line.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv-py"
PACKAGES=(mcap==1.6.0 mcap-ros2-support==0.6.0 rosbags==0.11.9)
STAMP="$VENV/.waam-packages"

if [[ -x "$VENV/bin/python" && -f "$STAMP" && "$(cat "$STAMP")" == "${PACKAGES[*]}" ]]; then
    echo "$VENV/bin/python"
    exit 0
fi

PYTHON="${PYTHON:-python3}"
# Debian ships venv/ensurepip apart from the interpreter: install what is missing (as root).
if ! command -v "$PYTHON" >/dev/null || ! "$PYTHON" -c 'import venv, ensurepip' 2>/dev/null; then
    if command -v apt-get >/dev/null && [[ $(id -u) == 0 ]]; then
        apt-get update -qq >&2
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3 python3-venv >&2
        PYTHON=python3
    else
        echo "py-venv.sh: need Python 3.10+ with the venv module (apt-get install python3-venv)" >&2
        exit 1
    fi
fi

"$PYTHON" -m venv "$VENV" >&2
"$VENV/bin/python" -m pip install --quiet --disable-pip-version-check "${PACKAGES[@]}" >&2
echo "${PACKAGES[*]}" > "$STAMP"
echo "$VENV/bin/python"
