#!/usr/bin/env python3
"""Experiments behind the warm-start portfolio (README, "Scale parts"): how the seam of a tall
one-block tube moves its windowed blocks' t8/5.

  scripts/tube_seam.py seams PART.yaml W D H   hand-built plans of a W x D ring tower, H layers:
        reversed-path plans from starts every 10 blocks (both ways), spirals, halves, a
        second weld path started at several layers; each judged by `waam check` against the
        part with its windows opened to [0, 1e5] s, so every crossing is printed.
  scripts/tube_seam.py hidden SEED W D H OUT.yaml   a W x D x H tube whose three windows
        (random blocks) are [0.95 x shortest, 1.01 x longest] t8/5 of a hidden reversed-path
        plan from a random start: a feasible plan exists; `waam plan OUT.yaml --first` shows
        whether the planner finds one.

WAAM (env) is the waam binary (default target/release/waam). The ring runs from (0,0) along
y = 0, up x = W-1, back along y = D-1 and down x = 0.
"""
import json, os, random, re, subprocess, sys, tempfile

WAAM = os.environ.get("WAAM", "target/release/waam")


def ring_of(w, d):
    return ([(x, 0) for x in range(w)] + [(w - 1, y) for y in range(1, d)]
            + [(x, d - 1) for x in range(w - 2, -1, -1)] + [(0, y) for y in range(d - 2, 0, -1)])


def reversed_path(ring, h, s0, d):
    """One weld path, each layer walked back over the one below, the first from s0 going d."""
    n, seq, s = len(ring), [], s0
    for z in range(h):
        seq += [(*ring[(s + d * i) % n], z) for i in range(n)]
        s, d = (s + d * (n - 1)) % n, -d
    return seq


def spiral(ring, h, s0, d):
    """One weld path, every layer the same way round, starting above where the last ended."""
    n, seq, s = len(ring), [], s0
    for z in range(h):
        seq += [(*ring[(s + d * i) % n], z) for i in range(n)]
        s = (s + d * (n - 1)) % n
    return seq


def half(ring, h, lo, count):
    """A U-shaped half of the ring, walked back and forth up to the top."""
    idx = [(lo + i) % len(ring) for i in range(count)]
    seq = []
    for z in range(h):
        seq += [(*ring[i], z) for i in (idx if z % 2 == 0 else idx[::-1])]
    return seq


def part_yaml(name, w, d, h, windows, k=2):
    full, mid = "#" * w, "#" + "." * (w - 2) + "#"
    layer = [full] + [mid] * (d - 2) + [full]
    out = [f"name: {name}", "block_mm: [6.0, 6.0, 2.5]", f"max_fragments: {k}", "layers:"]
    for _ in range(h):
        out += ["  - |"] + ["    " + r for r in layer]
    out.append("t85:")
    out += [f"  - {{block: [{b[0]}, {b[1]}, {b[2]}], min_s: {lo:.2f}, max_s: {hi:.2f}}}"
            for b, lo, hi in windows]
    return "\n".join(out) + "\n"


def crossings(part_path, name, fragments):
    """Every t8/5 crossing per windowed block, from `waam check`."""
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump({"part": name, "fragments": [[list(b) for b in fr] for fr in fragments]}, f)
    out = subprocess.run([WAAM, "-q", "check", part_path, f.name], capture_output=True, text=True).stdout
    os.unlink(f.name)
    result = {}
    for line in out.splitlines():
        m = re.match(r"\s+\[(-?\d+),(-?\d+),(-?\d+)\] \[.*\]:(.*)", line)
        if m:
            result[tuple(int(v) for v in m.groups()[:3])] = [float(v) for v in m.group(4).split()]
    return result


def windows_of(part_path):
    text = open(part_path).read()
    return [((int(a), int(b), int(c)), float(lo), float(hi)) for a, b, c, lo, hi in re.findall(
        r"block: \[(-?\d+), (-?\d+), (-?\d+)\], min_s: ([0-9.e+]+), max_s: ([0-9.e+]+)", text)]


def seams(part_path, w, d, h):
    windows = windows_of(part_path)
    name = re.search(r"^name: (\S+)", open(part_path).read(), re.M).group(1)
    wide = tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False)
    wide.write(re.sub(r"min_s: [0-9.e+]+, max_s: [0-9.e+]+", "min_s: 0.0, max_s: 100000.0",
                      open(part_path).read()))
    wide.close()
    ring = ring_of(w, d)
    n = len(ring)

    def report(tag, fragments):
        cross = crossings(wide.name, name, fragments)
        ok, cols = True, []
        for b, lo, hi in windows:
            v = cross.get(b, [])
            bad = bool(v) and (min(v) < lo or max(v) > hi)
            ok &= not bad
            cols.append(f"{list(b)}: {'!' if bad else ''}{min(v, default=0):.1f}..{max(v, default=0):.1f}")
        print(f"{tag:32s} {'OK ' if ok else 'bad'}  " + "  ".join(cols), flush=True)

    for d_ in (1, -1):
        for s0 in range(0, n, 10):
            report(f"reversed path s0={s0} d={d_}", [reversed_path(ring, h, s0, d_)])
    for d_ in (1, -1):
        for s0 in range(0, n, 10):
            report(f"spiral s0={s0} d={d_}", [spiral(ring, h, s0, d_)])
    for lo in range(0, n, n // 4):
        report(f"halves from {lo}", [half(ring, h, lo, n // 2), half(ring, h, lo + n // 2, n - n // 2)])
    whole = reversed_path(ring, h, 12 % n, 1)
    for m in (h // 4, h // 2, 3 * h // 4):
        report(f"s0=12 split at z={m}", [whole[: m * n], whole[m * n:]])
    os.unlink(wide.name)


def hidden(seed, w, d, h, out):
    rng = random.Random(seed)
    ring = ring_of(w, d)
    n = len(ring)
    plan = reversed_path(ring, h, rng.randrange(n), rng.choice((1, -1)))
    blocks = [(*ring[rng.randrange(n)], z) for z in
              (rng.randrange(1, h // 4), rng.randrange(h // 4, h // 2), rng.randrange(h // 2, h - 10))]
    name = f"hidden-{seed}"
    with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False) as f:
        f.write(part_yaml(name, w, d, h, [(b, 0.0, 1e5) for b in blocks]))
    cross = crossings(f.name, name, [plan])
    os.unlink(f.name)
    windows = [(b, min(v) * 0.95, max(v) * 1.01) for b, v in cross.items()]
    open(out, "w").write(part_yaml(name, w, d, h, windows))
    print(out, windows)


if __name__ == "__main__":
    if sys.argv[1] == "seams":
        seams(sys.argv[2], *map(int, sys.argv[3:6]))
    elif sys.argv[1] == "hidden":
        hidden(int(sys.argv[2]), *map(int, sys.argv[3:6]), sys.argv[6])
    else:
        sys.exit(__doc__)
