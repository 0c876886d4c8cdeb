#!/usr/bin/env bash
# Sets up the independent checker (shared/tools/refcheck) in a venv of its own and prints
# the venv's python: export WAAM_REFCHECK_PY="$(scripts/refcheck.sh)".
# Idempotent: a venv that already has the requirements is reused as it is.
#
#   REFCHECK_DIR   the checker's folder [default: ../shared/tools/refcheck from the repo root]
#   REFCHECK_VENV  where the venv lives   [default: .venv-refcheck in the repo root]
#
# refcheck compiles its simulator with numba and caches the result beside its sources,
# which are read-only: the test driver (tests/py/refcheck_batch.py) points NUMBA_CACHE_DIR
# at a writable folder inside the venv.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
dir="${REFCHECK_DIR:-$root/../shared/tools/refcheck}"
venv="${REFCHECK_VENV:-$root/.venv-refcheck}"

if [[ ! -f "$dir/requirements.txt" || ! -d "$dir/refcheck" ]]; then
    echo "refcheck.sh: no checker at $dir (set REFCHECK_DIR)" >&2
    exit 1
fi
if ! python3 -m venv --help >/dev/null 2>&1 || ! python3 -c 'import ensurepip' 2>/dev/null; then
    echo "refcheck.sh: installing python3-venv" >&2
    apt-get update -qq >&2 && apt-get install -y -qq python3-venv >&2
fi
stamp="$venv/.requirements"
if [[ ! -x "$venv/bin/python" ]] || ! cmp -s "$dir/requirements.txt" "$stamp"; then
    echo "refcheck.sh: creating $venv" >&2
    python3 -m venv "$venv" >&2
    "$venv/bin/python" -m pip install -q --disable-pip-version-check -r "$dir/requirements.txt" >&2
    cp "$dir/requirements.txt" "$stamp"
fi
mkdir -p "$venv/numba-cache"
echo "$venv/bin/python"
