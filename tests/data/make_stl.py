#!/usr/bin/env python3
"""Writes the STL fixtures of crates/mesh/tests/mesh.rs (run from anywhere; no dependencies).

box_ascii.stl / box_binary.stl   36 x 24 x 10 mm box at (10, -5, 3): 6 x 4 x 4 blocks of 6 x 6 x 2.5
tube_ascii.stl / tube_binary.stl 24 x 24 x 5 mm square tube, 12 x 12 hole: the blocks of s3-ring
ring_binary.stl                  round ring, radii 30 and 18 mm, 10 mm high, 48 segments
round_tube.stl                   round tube, radii 20 and 14 mm, 10 mm high, 30 faces around
                                 (the bead coverage check, tests/cli/coverage.rs)
open_box.stl                     the box without its top face (ASCII)
flipped_box.stl                  the box with one triangle turned over (binary)
"""
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def quad(a, b, c, d):
    """Two triangles of the quad a-b-c-d (counter-clockwise seen from outside)."""
    return [(a, b, c), (a, c, d)]


def box(x0, y0, z0, x1, y1, z1):
    p = lambda i, j, k: ((x0, x1)[i], (y0, y1)[j], (z0, z1)[k])
    t = []
    t += quad(p(0, 0, 0), p(0, 1, 0), p(1, 1, 0), p(1, 0, 0))  # bottom, facing -z
    t += quad(p(0, 0, 1), p(1, 0, 1), p(1, 1, 1), p(0, 1, 1))  # top
    t += quad(p(0, 0, 0), p(1, 0, 0), p(1, 0, 1), p(0, 0, 1))  # y = y0, facing -y
    t += quad(p(0, 1, 0), p(0, 1, 1), p(1, 1, 1), p(1, 1, 0))  # y = y1
    t += quad(p(0, 0, 0), p(0, 0, 1), p(0, 1, 1), p(0, 1, 0))  # x = x0, facing -x
    t += quad(p(1, 0, 0), p(1, 1, 0), p(1, 1, 1), p(1, 0, 1))  # x = x1
    return t


def prism_ring(outer, inner, z0, z1):
    """A ring between two counter-clockwise polygons (lists of (x, y)), from z0 to z1."""
    t = []
    n = len(outer)
    for i in range(n):
        a, b = outer[i], outer[(i + 1) % n]
        c, d = inner[i], inner[(i + 1) % n]
        t += quad((*a, z0), (*b, z0), (*b, z1), (*a, z1))  # outer wall, facing out
        t += quad((*c, z0), (*c, z1), (*d, z1), (*d, z0))  # inner wall, facing the hole
        t += quad((*a, z1), (*b, z1), (*d, z1), (*c, z1))  # top
        t += quad((*a, z0), (*c, z0), (*d, z0), (*b, z0))  # bottom
    return t


def square(lo, hi, steps):
    """Counter-clockwise square boundary with `steps` points per side (matching rings)."""
    pts = []
    for s in range(steps):
        pts.append((lo + (hi - lo) * s / steps, lo))
    for s in range(steps):
        pts.append((hi, lo + (hi - lo) * s / steps))
    for s in range(steps):
        pts.append((hi - (hi - lo) * s / steps, hi))
    for s in range(steps):
        pts.append((lo, hi - (hi - lo) * s / steps))
    return pts


def circle(r, n):
    return [(r * math.cos(2 * math.pi * i / n), r * math.sin(2 * math.pi * i / n)) for i in range(n)]


def normal(t):
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = t
    u, v = (bx - ax, by - ay, bz - az), (cx - ax, cy - ay, cz - az)
    n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
    length = math.sqrt(sum(c * c for c in n)) or 1.0
    return tuple(c / length for c in n)


def ascii_stl(name, tris):
    out = [f"solid {name}"]
    for t in tris:
        out.append("  facet normal %.6e %.6e %.6e" % normal(t))
        out.append("    outer loop")
        for v in t:
            out.append("      vertex %r %r %r" % tuple(float(struct.unpack('<f', struct.pack('<f', c))[0]) for c in v))
        out.append("    endloop")
        out.append("  endfacet")
    out.append(f"endsolid {name}")
    return ("\n".join(out) + "\n").encode()


def binary_stl(header, tris):
    data = header.encode().ljust(80, b" ") + struct.pack("<I", len(tris))
    for t in tris:
        data += struct.pack("<3f", *normal(t))
        for v in t:
            data += struct.pack("<3f", *v)
        data += b"\0\0"
    return data


def write(name, data):
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(data)


b = box(10, -5, 3, 46, 19, 13)
write("box_ascii.stl", ascii_stl("box", b))
write("box_binary.stl", binary_stl("solid box, binary despite this header", b))
tube = prism_ring(square(0, 24, 1), square(6, 18, 1), 0, 5)
write("tube_ascii.stl", ascii_stl("tube", tube))
write("tube_binary.stl", binary_stl("tube", tube))
write("ring_binary.stl", binary_stl("ring", prism_ring(circle(30, 48), circle(18, 48), 0, 10)))
write("round_tube.stl", binary_stl("round tube", prism_ring(circle(20, 30), circle(14, 30), 0, 10)))
write("open_box.stl", ascii_stl("open", b[:2] + b[4:]))
flipped = list(b)
flipped[5] = (flipped[5][0], flipped[5][2], flipped[5][1])
write("flipped_box.stl", binary_stl("flipped", flipped))
