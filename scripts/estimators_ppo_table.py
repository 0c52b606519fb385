#!/usr/bin/env python3
"""RESULTS.md "How far learned estimators are from the truth", the PPO table: the
horizon-potential form on exact E against the same form on each reference estimator's E
(`train --empowerment-from`), 10 seeds each, from the experiments' summaries committed as
docs/results/estimators-ppo-<world>-{exact,variational,infonce}.json (made by
scripts/estimators_ppo.sh). Per arm: seeds that reached a success rate of 0.9, the IQM of
the steps to get there with its bootstrap interval and the median (the experiment's), and
the two-sided log-rank test against exact E recomputed here from the per-seed steps, with
Holm's adjustment over the two estimators. Standard library only."""

import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from noisy_tables import log_rank, pt, st  # noqa: E402

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
WORLDS = ["exp1-tree", "exp2"]
ESTIMATORS = ["variational", "infonce"]


def arm(world, source, name):
    path = os.path.join(ROOT, "docs", "results", f"estimators-ppo-{world}-{source}.json")
    if not os.path.exists(path):
        return None
    s = json.load(open(path))
    return {a["name"]: a for a in s["arms"]}[name]


def times(a):
    return [s["steps_to_threshold"] for s in a["per_seed"]]


def main():
    for world in WORLDS:
        exact = arm(world, "exact", "horizon-potential")
        if exact is None:
            continue
        rows = [("baseline (no E)", arm(world, "exact", "baseline")), ("exact E", exact)]
        rows += [(f"{e} estimate", arm(world, e, "horizon-potential")) for e in ESTIMATORS]
        tests = {}
        for name, a in rows[2:]:
            if a is not None:
                _, p, o, e = log_rank(times(a), times(exact))
                tests[name] = (p, "slower" if o < e else "faster")
        order = sorted(tests, key=lambda n: tests[n][0])
        holm, run = {}, 0.0
        for i, name in enumerate(order):
            run = max(run, min(1.0, (len(order) - i) * tests[name][0]))
            holm[name] = run
        print(f"\n{world}, horizon-potential, 10 seeds\n")
        print("| E from | seeds solved | IQM steps to 0.9 (95% CI) | median | log-rank p vs exact | Holm |")
        print("|---|---|---|---|---|---|")
        for name, a in rows:
            if a is None:
                continue
            lo, hi = a["iqm_ci"]
            test = f"{pt(tests[name][0])} ({tests[name][1]})" if name in tests else "-"
            h = pt(holm[name]) if name in holm else "-"
            print(f"| {name} | {a['reached']}/{a['seeds']} | {st(a['iqm_steps'])} ({st(lo)} - {st(hi)}) | {st(a['median_steps'])} | {test} | {h} |")


if __name__ == "__main__":
    main()
