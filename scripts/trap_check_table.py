#!/usr/bin/env python3
"""The beacon-trap detector against the additive runs of RESULTS.md's tables
(RESULTS.md, "The trap detector, checked"). With --from-experiments it reads
experiments/trap-check/*/summary.json (made by scripts/results.sh; the summaries replay
the detector over each run's rows) and writes docs/results/trap-check.csv (one row per
run: experiment, arm, seed, env steps to 0.9 or empty, updates marked); in every case it
prints the table from docs/results/trap-check.csv. Standard library only."""
import csv
import glob
import json
import os
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
CSV = os.path.join(ROOT, "docs", "results", "trap-check.csv")


def write_csv():
    rows = []
    for path in sorted(glob.glob(os.path.join(ROOT, "experiments", "trap-check", "*", "summary.json"))):
        name = os.path.basename(os.path.dirname(path))
        s = json.load(open(path))
        for arm in s["arms"]:
            for p in arm["per_seed"]:
                rows.append((name, arm["name"], p["seed"], p["steps_to_threshold"], p["trap_updates"]))
    if not rows:
        sys.exit("no experiments/trap-check/*/summary.json: run scripts/results.sh first")
    with open(CSV, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["experiment", "arm", "seed", "steps_to_0.9", "trap_updates"])
        for e, a, seed, steps, trap in rows:
            w.writerow([e, a, seed, "" if steps is None else int(steps), trap])


def main():
    if "--from-experiments" in sys.argv[1:]:
        write_csv()
    groups = {}
    with open(CSV) as f:
        for r in csv.DictReader(f):
            solved, marked = r["steps_to_0.9"] != "", int(r["trap_updates"]) > 0
            groups.setdefault((r["experiment"], r["arm"]), []).append((solved, marked))
    print("| experiment | arm | runs | solved | marked | marked and solved | marked, never solved |")
    print("|---|---|---|---|---|---|---|")
    tot = [0, 0, 0, 0, 0]
    for (e, a), v in groups.items():
        n = len(v)
        solved = sum(s for s, _ in v)
        marked = sum(m for _, m in v)
        both = sum(s and m for s, m in v)
        never = sum(m and not s for s, m in v)
        tot = [x + y for x, y in zip(tot, [n, solved, marked, both, never])]
        print(f"| {e} | {a} | {n} | {solved} | {marked} | {both} | {never} |")
    print(f"| all | | {tot[0]} | {tot[1]} | {tot[2]} | {tot[3]} | {tot[4]} |")


if __name__ == "__main__":
    main()
