#!/usr/bin/env python3
"""The table of RESULTS.md ("The two misses, with 20 seeds"): reads the per-seed outcomes
in docs/results/misses.csv (from `fulcrum experiment WORLD --seeds 20 --arms
baseline,horizon-potential`, see RESULTS.md) and prints, per world and arm, the seeds
that reached a success rate of 0.9, the median steps to get there (a seed that never did
counted at the budget), the two-sided Fisher exact test of solved / not solved against
the baseline and the two-sided log-rank test of the "solved by step t" curves (the same
tests as `fulcrum experiment`, written again here from their definitions). Standard
library only."""
import csv
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from noisy_tables import log_rank, pt  # noqa: E402

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
BUDGET = 999_424


def fisher_two_sided(a, b, c, d):
    """Fisher's exact test of the 2 x 2 table [[a, b], [c, d]]: the probability, under
    the hypergeometric law with the margins fixed, of every table no more likely than
    this one."""
    n1, n2, k = a + b, c + d, a + c

    def p(x):
        return math.comb(n1, x) * math.comb(n2, k - x) / math.comb(n1 + n2, k)

    here = p(a)
    lo, hi = max(0, k - n2), min(k, n1)
    return min(1.0, sum(p(x) for x in range(lo, hi + 1) if p(x) <= here * (1 + 1e-7)))


# The outcomes: with the potential counting a boulder's cells (the first runs), and by
# its condition (`train --potential-objects task`, the default since).
CSVS = ["misses.csv", "misses-task.csv"]


def from_experiments(name, dirs):
    """docs/results/NAME from the experiments' summaries: a row per arm and seed."""
    rows = []
    for d in dirs:
        with open(os.path.join(d, "summary.json")) as f:
            summary = json.load(f)
        world = os.path.splitext(os.path.basename(summary["world"]))[0]
        for arm in summary["arms"]:
            for r in arm["per_seed"]:
                t = r["steps_to_threshold"]
                rows.append([world, arm["name"], r["seed"], "" if t is None else int(t), f"{r['final_success']:.4f}"])
    path = os.path.join(ROOT, "docs", "results", name)
    with open(path + ".tmp", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["world", "arm", "seed", "steps_to_0.9", "final_success"])
        w.writerows(rows)
    os.replace(path + ".tmp", path)
    print(f"wrote {path} ({len(rows)} rows)")


def main():
    # --from-experiments [--name misses-task.csv] DIR...
    if sys.argv[1:2] == ["--from-experiments"]:
        args = sys.argv[2:]
        name = "misses.csv"
        if args[:1] == ["--name"]:
            name, args = args[1], args[2:]
        return from_experiments(name, args)
    for k, name in enumerate(CSVS):
        if k:
            print()
        print(f"{name}\n")
        table(name)


def table(name):
    runs = {}
    with open(os.path.join(ROOT, "docs", "results", name)) as f:
        for r in csv.DictReader(f):
            t = int(r["steps_to_0.9"]) if r["steps_to_0.9"] else None
            runs.setdefault(r["world"], {}).setdefault(r["arm"], []).append(t)
    print("| world | arm | solved | median steps to 0.9 | Fisher p vs baseline | log-rank p vs baseline |")
    print("|---|---|---|---|---|---|")
    for world, arms in runs.items():
        base = arms["baseline"]
        for arm, ts in arms.items():
            solved = sum(t is not None for t in ts)
            at = sorted(BUDGET if t is None else t for t in ts)
            median = (at[len(at) // 2 - 1] + at[len(at) // 2]) / 2 if len(at) % 2 == 0 else at[len(at) // 2]
            if arm == "baseline":
                fisher = rank = "-"
            else:
                b_solved = sum(t is not None for t in base)
                fisher = pt(fisher_two_sided(solved, len(ts) - solved, b_solved, len(base) - b_solved))
                _, p, o, e = log_rank(ts, base)
                rank = f"{pt(p)} ({'faster' if o > e else 'slower'})"
            print(f"| {world} | {arm} | {solved}/{len(ts)} | {median / 1e3:.0f}k | {fisher} | {rank} |")


if __name__ == "__main__":
    main()
