#!/usr/bin/env bash
# Creates (or reuses) a Python venv for the tests: scripts/venv.sh NAME PACKAGE==VERSION...
# makes .venv-NAME in the repo root holding exactly those pinned packages. Idempotent: a venv
# that already has these versions is left as it is. Prints the venv's python path on its last
# line.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv-$1"
shift
PACKAGES=("$@")
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
        echo "venv.sh: need Python 3.10+ with the venv module (apt-get install python3-venv)" >&2
        exit 1
    fi
fi

"$PYTHON" -m venv "$VENV" >&2
"$VENV/bin/python" -m pip install --quiet --disable-pip-version-check "${PACKAGES[@]}" >&2
echo "${PACKAGES[*]}" > "$STAMP"
echo "$VENV/bin/python"
