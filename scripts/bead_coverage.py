#!/usr/bin/env python3
"""How well a G-code program's welded moves cover a mesh's layers: an independent check of
`waam slice` / `waam plan --bead` / `waam export --format gcode` (issue #29).

It slices the STL itself (trimesh) at every layer's mid-height, z = zmin + (i + 0.5)·H
(an STL of several closed bodies, which may overlap, is the union of their sections),
takes every G1 move made with the arc on as a bead W wide (shapely: the move's line
buffered by W/2, flat ends, round corners where moves follow on), and reports per layer the fraction of the section the beads
cover and the fraction of the beads outside the section. Nothing of waam-planner is used:
only the mesh, the program and the bead size.

Arc-on moves are grouped into layers by their z: the distinct z levels of welded moves,
lowest first, are layers 0, 1, ... (the torch may weld at the bead's centre or top, or at
a stick-out above it: only the order of the levels counts). A move between two levels (a
step up inside a weld path) belongs to neither.

    bead_coverage.py MESH.stl PROGRAM.gcode --bead "W H" [--min-mean 0.92]
        [--min-layer 0.85] [--max-outside 0.20] [--arc-on M3] [--arc-off M5] [--json]

Exit 0 when every threshold holds, 1 when one fails, 2 on bad input.
"""

import argparse
import json
import re
import sys

import numpy as np
import shapely
import trimesh
from shapely.geometry import LineString, MultiPolygon, Polygon
from shapely.ops import unary_union


def parse_program(text, arc_on, arc_off):
    """The program's welded moves as ((x0, y0, z0), (x1, y1, z1)) pairs."""
    pos = None
    arc = False
    welded = []
    word = re.compile(r"([A-Z])\s*(-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)")
    for raw in text.splitlines():
        line = raw.split(";", 1)[0].strip().upper()
        if not line:
            continue
        if line.startswith(arc_on.upper()):
            arc = True
            continue
        if line.startswith(arc_off.upper()):
            arc = False
            continue
        words = dict((k, float(v)) for k, v in word.findall(line))
        if "G" not in words or int(words["G"]) not in (0, 1):
            continue
        new = list(pos) if pos else [0.0, 0.0, 0.0]
        for i, axis in enumerate("XYZ"):
            if axis in words:
                new[i] = words[axis]
        if pos is not None and arc and int(words["G"]) == 1 and new != pos:
            welded.append((tuple(pos), tuple(new)))
        pos = new
    return welded


def flat(move, h):
    """Whether a move stays at one height (a step up inside a weld path does not)."""
    a, b = move
    return abs(a[2] - b[2]) <= 1e-3 * h


def levels(moves, tolerance, h):
    """Distinct z levels of the moves that stay at one height, lowest first."""
    zs = sorted(a[2] for a, b in moves if flat((a, b), h))
    out = []
    for z in zs:
        if not out or z - out[-1][-1] > tolerance:
            out.append([z])
        else:
            out[-1].append(z)
    return [sum(g) / len(g) for g in out]


def body_section(body, z):
    """One connected body's section at height z: its closed contours taken even-odd (a
    contour inside another is a hole, inside that an island, at any depth)."""
    section = body.section(plane_origin=[0.0, 0.0, z], plane_normal=[0.0, 0.0, 1.0])
    if section is None:
        return Polygon()
    planar, to_3d = section.to_2D()
    # Back into the mesh's x, y (to_2D may rotate and shift the plane's frame).
    back = lambda pts: trimesh.transform_points(
        np.column_stack([pts, np.zeros(len(pts))]), to_3d
    )[:, :2]
    region = Polygon()
    for p in planar.polygons_closed:
        if p is None:
            continue
        contour = shapely.make_valid(Polygon(back(np.asarray(p.exterior.coords))))
        region = region.symmetric_difference(contour)
    return region


def polygons(mesh, z):
    """The mesh's section at height z as a shapely (Multi)Polygon (empty if none): the union
    of its bodies' sections. An STL may be several closed bodies that overlap (a rib
    standing in a tube); trimesh's `polygons_full` nests all contours of a section into one
    tree and lost the rib, whose corners touch the tube's inner wall (its whole area then
    counted as welded outside the section)."""
    bodies = mesh.split(only_watertight=False) if mesh.body_count > 1 else [mesh]
    return unary_union([body_section(b, z) for b in bodies])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mesh")
    ap.add_argument("program")
    ap.add_argument("--bead", required=True, help='"W H": bead width and layer height, mm')
    ap.add_argument("--min-mean", type=float, default=0.92)
    ap.add_argument("--min-layer", type=float, default=0.85)
    ap.add_argument("--max-outside", type=float, default=0.20)
    ap.add_argument("--arc-on", default="M3")
    ap.add_argument("--arc-off", default="M5")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    try:
        w, h = (float(v) for v in args.bead.replace(",", " ").split())
        mesh = trimesh.load_mesh(args.mesh)
        with open(args.program, encoding="utf-8") as f:
            moves = parse_program(f.read(), args.arc_on, args.arc_off)
    except (ValueError, OSError) as e:
        print(f"bead_coverage: {e}", file=sys.stderr)
        return 2
    zmin, zmax = mesh.bounds[0][2], mesh.bounds[1][2]
    count = int(np.floor((zmax - zmin) / h + 1e-9))
    if (count - 0.5) * h + zmin >= zmax:
        count -= 1
    zs = levels(moves, h / 4, h)
    if len(zs) != count:
        print(
            f"bead_coverage: the program welds on {len(zs)} levels, the mesh has {count} layers of {h} mm",
            file=sys.stderr,
        )
        return 1
    report = []
    for i, level in enumerate(zs):
        section = polygons(mesh, zmin + (i + 0.5) * h)
        # Consecutive moves form one bead: buffered as one line, its corners round as the
        # melt pool is (segment by segment, flat ends leave a wedge outside every corner
        # that a continuous bead does not have: 14 % of a 16 mm boss).
        chains = []
        for a, b in moves:
            if not (flat((a, b), h) and abs(a[2] - level) <= h / 4):
                continue
            if chains and np.allclose(chains[-1][-1], a[:2], atol=1e-6):
                chains[-1].append(b[:2])
            else:
                chains.append([a[:2], b[:2]])
        beads = unary_union(
            [LineString(c).buffer(w / 2, cap_style="flat", join_style="round") for c in chains]
        )
        area = section.area
        covered = beads.intersection(section).area / area if area > 0 else 0.0
        outside = beads.difference(section).area / beads.area if beads.area > 0 else 0.0
        report.append({"layer": i, "section_mm2": area, "covered": covered, "outside": outside})
    mean = sum(r["covered"] for r in report) / len(report)
    worst = min(report, key=lambda r: r["covered"])
    most_out = max(report, key=lambda r: r["outside"])
    ok = (
        mean >= args.min_mean
        and worst["covered"] >= args.min_layer
        and most_out["outside"] <= args.max_outside
    )
    if args.json:
        print(json.dumps({"layers": report, "mean": mean, "ok": ok}))
    else:
        for r in report:
            print(
                f"layer {r['layer']:3d}: section {r['section_mm2']:9.1f} mm2, covered {100 * r['covered']:5.1f} %, outside {100 * r['outside']:5.1f} %"
            )
        print(
            f"{len(report)} layers: covered mean {100 * mean:.1f} % (>= {100 * args.min_mean:.0f} %), "
            f"worst {100 * worst['covered']:.1f} % in layer {worst['layer']} (>= {100 * args.min_layer:.0f} %), "
            f"outside at most {100 * most_out['outside']:.1f} % in layer {most_out['layer']} (<= {100 * args.max_outside:.0f} %): "
            + ("OK" if ok else "FAILED")
        )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
