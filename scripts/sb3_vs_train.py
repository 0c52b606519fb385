"""sb3-contrib's MaskablePPO beside `fulcrum train` on one world: env steps and seconds
to a success rate of 0.9, counted the same way for both (the episodes that did the task
over those that ended in the last 10 updates, pooled), seeds 1-5 of each, run one after
the other in the same minutes. BENCHMARKS.md ("Python") quotes its table.

    target/py-venv/bin/python scripts/sb3_vs_train.py [--world exp1-tree] [--seeds 5]

Both use 8 environments x 128 steps per update (`fulcrum train --actors 1`, whose
actor steps 8 worlds). `fulcrum train` runs twice per seed: with its defaults
(horizon-potential shaping from exact E) and with `--no-empowerment` (the task's reward
alone, as MaskablePPO gets it). Its seconds are the learner's `wall_s` of the solving
update (from the run's start, the empowerment table included); MaskablePPO's are from
the environments' creation to the end of the solving update.
"""

import argparse
import csv
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FULCRUM = ROOT / "target" / "release" / "fulcrum"
BUDGET = 499712


def pooled_first(metrics: Path, window: int = 10, goal: float = 0.9):
    """(env steps, wall seconds) of the first update whose pooled success reached goal."""
    rows = list(csv.DictReader(metrics.open()))
    for i, row in enumerate(rows):
        n = s = 0.0
        for r in rows[max(0, i + 1 - window) : i + 1]:
            e, rate = float(r["episodes"]), float(r["success_rate"])
            if e > 0 and rate == rate:
                n += e
                s += rate * e
        if n > 0 and s / n >= goal:
            return int(row["env_steps"]), float(row["wall_s"])
    return None


def train(world: str, seed: int, extra: list[str]):
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "run"
        cmd = [str(FULCRUM), "train", world, "--seed", str(seed), "--actors", "1"]
        cmd += ["--steps", str(BUDGET), "--out", str(out), *extra]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return pooled_first(out / "metrics.csv")


def sb3(world: str, seed: int):
    cmd = [sys.executable, str(ROOT / "examples" / "python" / "sb3_maskable.py")]
    cmd += ["--world", world, "--seed", str(seed), "--steps", str(BUDGET), "--until-solved"]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    m = re.search(r"success 0.9 first at (\d+) env steps, ([\d.]+) s", out)
    return (int(m.group(1)), float(m.group(2))) if m else None


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--world", default="exp1-tree")
    p.add_argument("--seeds", type=int, default=5)
    args = p.parse_args()
    arms = {
        "sb3-contrib MaskablePPO (R)": lambda s: sb3(args.world, s),
        "fulcrum train, defaults": lambda s: train(args.world, s, []),
        "fulcrum train --no-empowerment (R)": lambda s: train(args.world, s, ["--no-empowerment"]),
    }
    results = {name: [] for name in arms}
    for seed in range(1, args.seeds + 1):
        for name, run in arms.items():
            r = run(seed)
            results[name].append(r)
            print(f"seed {seed}  {name}: {r}", file=sys.stderr, flush=True)
    print(f"| {args.world}, seeds 1-{args.seeds} | solved | env steps to 0.9, median (each; "
          "never = the budget) | seconds to 0.9, median of the solved (each) |")
    print("|---|---|---|---|")
    for name, rs in results.items():
        solved = [r for r in rs if r]
        steps = [r[0] if r else BUDGET for r in rs]
        secs = [r[1] for r in solved]
        each_steps = " ".join(f"{s / 1e3:.0f}k" if r else "never" for s, r in zip(steps, rs))
        each_secs = " ".join(f"{r[1]:.1f}" if r else "never" for r in rs)
        med_secs = f"{statistics.median(secs):.1f}" if secs else "-"
        print(f"| {name} | {len(solved)}/{len(rs)} | {statistics.median(steps) / 1e3:.0f}k "
              f"({each_steps}) | {med_secs} ({each_secs}) |")


if __name__ == "__main__":
    main()
