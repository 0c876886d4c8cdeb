#!/usr/bin/env bash
# The Python venv of the independent bead-coverage check (scripts/bead_coverage.py): trimesh
# slices the STL itself, shapely measures the sections and the welded beads; networkx, scipy and
# rtree are what trimesh's section polygons need. Pinned (see scripts/venv.sh). Prints the
# venv's python path last (scripts/test.sh exports it as WAAM_COVERAGE_PYTHON).
exec "$(dirname "${BASH_SOURCE[0]}")/venv.sh" coverage numpy==2.2.6 trimesh==4.8.3 shapely==2.1.2 networkx==3.4.2 rtree==1.4.1 scipy==1.15.3
