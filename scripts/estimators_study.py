#!/usr/bin/env python3
"""How far learned empowerment estimators are from the truth: RESULTS.md's study.

    target/py-venv/bin/python scripts/estimators_study.py   (resumable)

For each channel (world, tool, objects) and horizon h in {1, 3, 5, 8} (a noisy world's
at h in {1, 3}): a dataset of 500
states drawn with seed 0, 32 uniform action sequences a state (`fulcrum.empowerment.dataset`),
and the two reference estimators of examples/python/learned_empowerment.py trained on
it (1500 steps of 64 states, seed 0). Every state's truth and both estimates go to
docs/results/estimators-states.csv.gz (with the sample ceiling: log2 of the distinct
outcomes among the state's 32 sequences); scripts/estimators_tables.py makes the tables
from that file alone. Each finished (channel, h, estimator) is kept under
experiments/estimators/ so an interrupted study goes on where it stopped.
"""

import csv
import gzip
import importlib.util
import io
import sys
from pathlib import Path

import numpy as np

from fulcrum import empowerment

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "experiments" / "estimators"
STATES = REPO / "docs" / "results" / "estimators-states.csv.gz"

# (world, tool, objects): each world's training channel (one object on exp1-tree, two on
# exp2 and exp3) and the agent's cell.
CHANNELS = [
    ("exp1-tree", "axe", "tree"),
    ("exp1-tree", "axe", "agent"),
    ("exp2", "wand", "boulder+door"),
    ("exp2", "wand", "agent"),
    ("exp3", "axe", "door+boulder"),
    ("exp3", "axe", "agent"),
]
HORIZONS = [1, 3, 5, 8]
# A noisy world, where E is a channel capacity: computing it exactly at h = 5 over the
# agent's cell takes minutes a state here, so h = 1 and 3.
NOISY = [("exp1-tree-slip", "axe", "agent")]
NOISY_HORIZONS = [1, 3]
ESTIMATORS = ["variational", "infonce"]
N_STATES, K, STEPS, SEED = 500, 32, 1500, 0
FIELDS = ["world", "tool", "objects", "horizon", "estimator", "row", "normal", "true", "ceiling", "estimate"]


def example():
    path = REPO / "examples" / "python" / "learned_empowerment.py"
    spec = importlib.util.spec_from_file_location("learned_empowerment", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def one(mod, world, tool, objects, h, estimator):
    """Rows of one (channel, horizon, estimator), from its file or computed."""
    name = f"{world}-{tool}-{objects.replace('+', '_')}-h{h}"
    done = OUT / f"{name}-{estimator}.csv"
    if done.exists():
        with open(done) as f:
            return list(csv.DictReader(f))
    data_path = OUT / f"{name}.npz"
    if not data_path.exists():
        empowerment.dataset(
            world, tool=tool, objects=objects, horizon=h, states=f"sample:{N_STATES}",
            sequences=K, seed=SEED, out=data_path,
        )
    z = np.load(data_path)
    n = len(z["E"])
    ceiling = np.log2([len(set(r)) for r in z["seq_proj"].reshape(n, K)])
    data = mod.load(data_path)
    model, _ = mod.train(data, estimator, STEPS, seed=SEED)
    est = mod.estimate(model, data)
    rows = [
        {
            "world": world, "tool": tool, "objects": objects, "horizon": h, "estimator": estimator,
            "row": i, "normal": int(z["normal"][i]), "true": f"{z['E'][i]:.6f}",
            "ceiling": f"{ceiling[i]:.6f}", "estimate": f"{est[i]:.6f}",
        }
        for i in range(n)
    ]
    tmp = done.with_suffix(".tmp")
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, FIELDS)
        w.writeheader()
        w.writerows(rows)
    tmp.replace(done)
    s = empowerment.score(est, str(data_path))
    print(f"{name} {estimator}: mean true {z['E'].mean():.3f}, mean estimate {est.mean():.3f}, "
          f"MAE {s['mae']:.3f}, Spearman {s['spearman']}", flush=True)
    return rows


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    mod = example()
    mod.torch.set_num_threads(int(sys.argv[1]) if len(sys.argv) > 1 else 2)
    rows = []
    grid = [(c, h) for c in CHANNELS for h in HORIZONS] + [(c, h) for c in NOISY for h in NOISY_HORIZONS]
    for (world, tool, objects), h in grid:
        for estimator in ESTIMATORS:
            rows += one(mod, world, tool, objects, h, estimator)
    tmp = STATES.with_suffix(".tmp")
    # mtime 0: the same rows give the same bytes.
    with gzip.GzipFile(tmp, "wb", mtime=0) as raw, io.TextIOWrapper(raw, newline="") as f:
        w = csv.DictWriter(f, FIELDS)
        w.writeheader()
        w.writerows(rows)
    tmp.replace(STATES)
    print(f"wrote {STATES}: {len(rows)} rows")


if __name__ == "__main__":
    main()
