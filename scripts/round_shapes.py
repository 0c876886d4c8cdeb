#!/usr/bin/env python3
"""Round and curved test parts beyond the samples (issue #29): an elliptical cup, a tube with
a rib across it, two tubes 1 mm apart, a cone wall leaning in, a plate with three round
bosses. Closed STL meshes
built from prisms and frusta (no boolean engine needed), written to DIR (default: .).

    PY=$(scripts/coverage-venv.sh | tail -1)
    $PY scripts/round_shapes.py /tmp/shapes
    waam plan /tmp/shapes/elliptical_cup.stl --bead "6 2.5" -k 3 --first --out D
    waam export D --format gcode
    $PY scripts/bead_coverage.py --bead "6 2.5" /tmp/shapes/elliptical_cup.stl D/WAAM.gcode

Figures: docs/benchmarks.md, "Other round parts".
"""
import os
import sys

import numpy as np
import trimesh

OUT = sys.argv[1] if len(sys.argv) > 1 else "."
os.makedirs(OUT, exist_ok=True)
N = 128
ang = np.linspace(0, 2*np.pi, N+1)[:-1]
def ellipse(a, b, n=N):
    t = np.linspace(0, 2*np.pi, n+1)[:-1]
    return np.c_[a*np.cos(t), b*np.sin(t)]
def solid(c0, c1, z0, z1):
    """Closed prism/frustum between two CCW curves of equal length at z0 and z1."""
    n = len(c0); v = [[x, y, z0] for x, y in c0] + [[x, y, z1] for x, y in c1]
    v += [[*c0.mean(0), z0], [*c1.mean(0), z1]]
    b, t = 2*n, 2*n+1; f = []
    for i in range(n):
        j = (i+1) % n
        f += [[i, j, n+j], [i, n+j, n+i], [b, j, i], [t, n+i, n+j]]
    m = trimesh.Trimesh(v, f, process=True); m.fix_normals(); return m
def ring(o0, o1, i0, i1, z0, z1):
    """Closed annular solid: outer curves o0->o1, inner i0->i1 (all CCW, same length)."""
    n = len(o0)
    v = [[x, y, z0] for x, y in o0] + [[x, y, z1] for x, y in o1] + \
        [[x, y, z0] for x, y in i0] + [[x, y, z1] for x, y in i1]
    O0, O1, I0, I1 = 0, n, 2*n, 3*n; f = []
    for i in range(n):
        j = (i+1) % n
        f += [[O0+i, O0+j, O1+j], [O0+i, O1+j, O1+i]]          # outer wall
        f += [[I0+i, I1+j, I0+j], [I0+i, I1+i, I1+j]]          # inner wall
        f += [[O0+i, I0+j, O0+j], [O0+i, I0+i, I0+j]]          # bottom
        f += [[O1+i, O1+j, I1+j], [O1+i, I1+j, I1+i]]          # top
    m = trimesh.Trimesh(v, f, process=True); m.fix_normals(); return m
def rect(cx, cy, w, d):
    return np.array([[cx-w/2, cy-d/2], [cx+w/2, cy-d/2], [cx+w/2, cy+d/2], [cx-w/2, cy+d/2]])
def save(parts, name):
    m = trimesh.util.concatenate(parts)
    closed = all(p.is_watertight for p in parts)
    print(name, [round(float(x), 1) for x in m.bounds.ravel()], "closed" if closed else "NOT closed")
    m.export(os.path.join(OUT, name + ".stl"))
# elliptical cup: 80 x 50 outside, 6 mm wall, 5 mm bottom, 40 high
save([solid(ellipse(40, 25), ellipse(40, 25), 0, 5),
      ring(ellipse(40, 25), ellipse(40, 25), ellipse(34, 19), ellipse(34, 19), 5, 40)], "elliptical_cup")
# a tube (r 30 / 24, 40 high) with a rib across it touching its inner wall
ribx = np.sqrt(24**2 - 3**2)
save([ring(ellipse(30, 30), ellipse(30, 30), ellipse(24, 24), ellipse(24, 24), 0, 40),
      solid(rect(0, 0, 2*ribx, 6), rect(0, 0, 2*ribx, 6), 0, 40)], "ribbed_tube")
# two tubes 1 mm apart (r 30 / 24 and 37 / 31, 10 high): no weld may cross the gap
save([ring(ellipse(30, 30), ellipse(30, 30), ellipse(24, 24), ellipse(24, 24), 0, 10),
      ring(ellipse(37, 37), ellipse(37, 37), ellipse(31, 31), ellipse(31, 31), 0, 10)], "double_tube")
# a cone wall leaning in: r 40 -> 25 outside over 45 mm, 6 mm wall
save([ring(ellipse(40, 40), ellipse(25, 25), ellipse(34, 34), ellipse(19, 19), 0, 45)], "leaning_cone")
# a 100 x 60 x 6 plate with three round bosses r 8, 20 high
save([solid(rect(0, 0, 100, 60), rect(0, 0, 100, 60), 0, 6)] +
     [solid(ellipse(8, 8, 64) + [x, 0], ellipse(8, 8, 64) + [x, 0], 6, 26) for x in (-30, 0, 30)], "plate_bosses")
