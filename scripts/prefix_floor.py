"""How many deposits must a search simulate to enumerate a part's feasible plans?

Reads every valid plan of a part and every feasible one (both as `waam plan --all` writes
them), judges each valid plan with the independent checker (shared/tools/refcheck), and
prints the sizes of three prefix trees of deposit sequences (block, new fragment):
- all valid plans;
- the violating prefixes (each infeasible plan up to its first violation) and the feasible
  plans: the least a search that learns exact violating prefixes simulates;
- the feasible plans plus, for every subtree without a feasible plan, one path from where
  it branches off to its nearest violation: what an oracle for "doomed" prefixes would need.

    python3 scripts/prefix_floor.py PART.yaml ALL.yaml FEASIBLE.yaml
    (ALL.yaml: `waam plan` --all on the part with its t85 list removed)

Run it with the checker's venv: "$(scripts/refcheck.sh)" scripts/prefix_floor.py ...
"""

import os
import statistics
import sys
from collections import Counter, defaultdict

import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(
    0, os.environ.get("REFCHECK_DIR", os.path.join(HERE, "..", "..", "shared", "tools", "refcheck"))
)
from refcheck import thermal  # noqa: E402
from refcheck.part import read_part  # noqa: E402
from refcheck.plan import validate  # noqa: E402


def plans(path):
    """Each plan as its fragments and its deposit sequence."""
    for doc in yaml.safe_load_all(open(path)):
        if doc:
            frags = [[tuple(b) for b in f] for f in doc["fragments"]]
            seq = tuple((b, i == 0) for f in frags for i, b in enumerate(f))
            yield frags, seq


def prefixes(seq, n):
    return (seq[:i] for i in range(1, n + 1))


def main(part_path, all_path, feasible_path):
    part = read_part(part_path)
    thermal.warm_up()
    valid, verdicts = set(), []
    for frags, seq in plans(all_path):
        err, ifr = validate(part, frags)
        if err:
            sys.exit(f"{all_path}: invalid plan: {err}")
        violations, _ = thermal.simulate(part, ifr)
        verdicts.append((seq, violations[0] if violations else None))
        valid.update(prefixes(seq, len(seq)))
    good = set()
    for _, seq in plans(feasible_path):
        good.update(prefixes(seq, len(seq)))
    violating = set()
    for seq, v in verdicts:
        violating.update(prefixes(seq, v.prefix_len if v else len(seq)))
    # Where each doomed subtree branches off the feasible tree, and its violations.
    doomed = defaultdict(list)
    kinds = Counter()
    for seq, v in verdicts:
        if v is None:
            continue
        kinds[(v.kind, v.phase)] += 1
        root = next(p for p in prefixes(seq, len(seq)) if p not in good)
        doomed[root].append(v.prefix_len)
    oracle = len(good) + sum(min(v) - len(r) + 1 for r, v in doomed.items())
    late = [pl - len(r) for r, v in doomed.items() for pl in v]
    print(f"valid plans {len(verdicts)}, feasible {sum(v is None for _, v in verdicts)}")
    print(f"prefix tree of all valid plans: {len(valid)} deposits")
    print(f"violating prefixes + feasible plans: {len(violating)} deposits")
    print(f"feasible plans: {len(good)} deposits; doomed subtrees: {len(doomed)}, "
          f"branching off at mean depth {statistics.mean(len(r) for r in doomed):.1f}")
    print(f"first violation after the branch point: mean {statistics.mean(late):.1f}, "
          f"median {statistics.median(late)} deposits")
    print(f"oracle (feasible tree + one path per doomed subtree): {oracle} deposits")
    print("first violations by kind and phase:", dict(kinds))


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(*sys.argv[1:])
