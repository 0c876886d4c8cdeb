#!/usr/bin/env bash
# The Python venv the robot-program export tests use: .venv-export, holding rapidchecker (ABB
# RAPID grammar and format checker) and pygcode (a G-code parser) at pinned versions (see
# scripts/venv.sh). Prints the venv's python path last (scripts/test.sh exports it as
# WAAM_EXPORT_PYTHON).
exec "$(dirname "${BASH_SOURCE[0]}")/venv.sh" export rapidchecker==0.1.5 pygcode==0.2.1
