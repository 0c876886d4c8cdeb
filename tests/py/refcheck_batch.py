#!/usr/bin/env python3
"""Checks many (part, plan) pairs with the independent checker in one process.

    python refcheck_batch.py REFCHECK_DIR < cases.json > results.json

cases.json: a list of {"id", "part": path, "plan": path}. For each case the output list
holds {"id", "valid", "invalid" (message or null), "feasible", "violation" (null or
{block, kind, time_s, step, prefix_len, prefix_fragments, phase, t85_s}), "crossings"
({"block": [x, y, z], "t85_s": [values in time order]} per windowed block), "error"}.
It only calls refcheck (reading, validation, simulation); it implements none of it.
"""
import json
import os
import sys
import tempfile


def main():
    refcheck_dir = sys.argv[1]
    # refcheck's numba cache would go beside its (read-only) sources.
    os.environ.setdefault("NUMBA_CACHE_DIR", os.path.join(tempfile.gettempdir(), "waam-numba-cache"))
    sys.path.insert(0, refcheck_dir)
    from refcheck.part import PartError, read_part
    from refcheck.plan import PlanError, read_plan, validate
    from refcheck.thermal import NotCooled, simulate

    parts = {}
    out = []
    for case in json.load(sys.stdin):
        res = {"id": case["id"], "valid": False, "invalid": None, "feasible": False,
               "violation": None, "crossings": [], "error": None}
        out.append(res)
        try:
            if case["part"] not in parts:
                parts[case["part"]] = read_part(case["part"])
            part = parts[case["part"]]
            _, frags = read_plan(case["plan"])
            err, ifr = validate(part, frags)
            if err:
                res["invalid"] = err
                continue
            res["valid"] = True
            viols, sim = simulate(part, ifr, record=True)
        except (PartError, PlanError, NotCooled) as exc:
            res["error"] = f"{type(exc).__name__}: {exc}"
            continue
        res["feasible"] = not viols
        if viols:
            v = viols[0]
            res["violation"] = {
                "block": list(part.blocks[v.block]), "kind": v.kind, "time_s": v.time_s,
                "step": v.step, "prefix_len": v.prefix_len, "prefix_fragments": v.prefix_frags,
                "phase": v.phase, "t85_s": v.value_s,
            }
        res["crossings"] = [{"block": list(part.blocks[b]), "t85_s": vals}
                            for b, vals in sorted(sim.crossings.items())]
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
