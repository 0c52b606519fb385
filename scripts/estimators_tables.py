#!/usr/bin/env python3
"""RESULTS.md's "How far learned estimators are from the truth", recomputed from the
committed per-state file docs/results/estimators-states.csv.gz (made by
scripts/estimators_study.py). Standard library only; Spearman's rank correlation
(ties share their mean rank) is computed here, apart from fulcrum's scorer.

    python3 scripts/estimators_tables.py            the tables (docs/results/estimators-tables.md)
    python3 scripts/estimators_tables.py --plot F   also the picture, estimate against truth (matplotlib)
"""

import csv
import gzip
import math
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STATES = ROOT / "docs" / "results" / "estimators-states.csv.gz"
K = 32
ESTIMATORS = ["variational", "infonce"]


def read():
    with gzip.open(STATES, "rt", newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for k in ("true", "ceiling", "estimate"):
            r[k] = float(r[k])
        r["horizon"] = int(r["horizon"])
    return rows


def ranks(v):
    order = sorted(range(len(v)), key=lambda i: v[i])
    r = [0.0] * len(v)
    i = 0
    while i < len(order):
        j = i
        while j + 1 < len(order) and v[order[j + 1]] == v[order[i]]:
            j += 1
        for k in order[i : j + 1]:
            r[k] = (i + j) / 2 + 1
        i = j + 1
    return r


def spearman(x, y):
    rx, ry = ranks(x), ranks(y)
    mx, my = sum(rx) / len(rx), sum(ry) / len(ry)
    sxy = sum((a - mx) * (b - my) for a, b in zip(rx, ry))
    sxx = sum((a - mx) ** 2 for a in rx)
    syy = sum((b - my) ** 2 for b in ry)
    return None if sxx == 0 or syy == 0 else sxy / math.sqrt(sxx * syy)


def mean(v):
    return sum(v) / len(v)


def fmt(x, d=3):
    return "-" if x is None else f"{x:.{d}f}"


def objects_kind(objects):
    return "agent" if objects == "agent" else f"{len(objects.split('+'))} object" + ("s" if "+" in objects else "")


def main():
    rows = read()
    by = defaultdict(list)
    for r in rows:
        by[(r["world"], r["tool"], r["objects"], r["horizon"], r["estimator"])].append(r)
    channels = []
    for r in rows:
        c = (r["world"], r["tool"], r["objects"], r["horizon"])
        if c not in channels:
            channels.append(c)
    out = []
    p = out.append
    p("## Error of each estimator, by channel and horizon\n")
    p(f"500 states each (seed 0), {K} uniform action sequences a state; the ceiling is the mean of")
    p("log2 of the distinct outcomes among a state's sequences (what any bound over them can reach).\n")
    p("| world | tool -> objects | h | mean E | ceiling | variational: mean | MAE | bias | Spearman | InfoNCE: mean | MAE | bias | Spearman |")
    p("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for w, t, o, h in channels:
        base = by[(w, t, o, h, ESTIMATORS[0])]
        cells = [w, f"{t} -> {o}", str(h), fmt(mean([r["true"] for r in base])), fmt(mean([r["ceiling"] for r in base]))]
        for e in ESTIMATORS:
            rs = by[(w, t, o, h, e)]
            x, y = [r["estimate"] for r in rs], [r["true"] for r in rs]
            d = [a - b for a, b in zip(x, y)]
            cells += [fmt(mean(x)), fmt(mean([abs(v) for v in d])), fmt(mean(d)), fmt(spearman(x, y), 2)]
        p("| " + " | ".join(cells) + " |")

    # The pooled tables take the deterministic worlds (a noisy world's E is a capacity).
    det = [r for r in rows if not r["world"].endswith("-slip")]
    p("\n## The gap by true value (the deterministic worlds' channels and horizons pooled)\n")
    p("| true E (bits) | states | variational: mean estimate | bias | InfoNCE: mean estimate | bias |")
    p("|---|---|---|---|---|---|")
    bins = defaultdict(lambda: defaultdict(list))
    for r in det:
        bins[math.floor(r["true"])][r["estimator"]].append(r)
    for lo in sorted(bins):
        n = len(bins[lo][ESTIMATORS[0]])
        cells = [f"[{lo}, {lo + 1})", str(n)]
        for e in ESTIMATORS:
            rs = bins[lo][e]
            cells += [fmt(mean([r["estimate"] for r in rs])), fmt(mean([r["estimate"] - r["true"] for r in rs]))]
        p("| " + " | ".join(cells) + " |")

    p("\n## By horizon and by what is projected (MAE in bits, deterministic worlds pooled)\n")
    p("| group | states | variational MAE | InfoNCE MAE | mean E |")
    p("|---|---|---|---|---|")
    groups = [(f"h = {h}", lambda r, h=h: r["horizon"] == h) for h in sorted({r["horizon"] for r in det})]
    groups += [(kind, lambda r, kind=kind: objects_kind(r["objects"]) == kind) for kind in ["1 object", "2 objects", "agent"]]
    for name, keep in groups:
        sel = {e: [r for r in det if r["estimator"] == e and keep(r)] for e in ESTIMATORS}
        if not sel[ESTIMATORS[0]]:
            continue
        cells = [name, str(len(sel[ESTIMATORS[0]]))]
        cells += [fmt(mean([abs(r["estimate"] - r["true"]) for r in sel[e]])) for e in ESTIMATORS]
        cells.append(fmt(mean([r["true"] for r in sel[ESTIMATORS[0]]])))
        p("| " + " | ".join(cells) + " |")

    cap = math.log2(K)
    p(f"\n## Saturation of InfoNCE at log2 K = {cap:.0f} bits\n")
    p("| true E | states | InfoNCE mean | share within 0.25 bit of log2 K | variational mean |")
    p("|---|---|---|---|---|")
    for name, keep in [("below log2 K", lambda v: v < cap), ("log2 K or more", lambda v: v >= cap)]:
        info = [r for r in det if r["estimator"] == "infonce" and keep(r["true"])]
        var = [r for r in det if r["estimator"] == "variational" and keep(r["true"])]
        if not info:
            continue
        near = sum(r["estimate"] >= cap - 0.25 for r in info) / len(info)
        p(f"| {name} | {len(info)} | {fmt(mean([r['estimate'] for r in info]))} | {near:.3f} | {fmt(mean([r['estimate'] for r in var]))} |")
    print("\n".join(out))

    if len(sys.argv) > 2 and sys.argv[1] == "--plot":
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(10, 4.6), sharey=True)
        top = max(r["true"] for r in det) + 0.5
        for ax, e in zip(axes, ESTIMATORS):
            rs = [r for r in det if r["estimator"] == e]
            ax.scatter([r["true"] for r in rs], [r["estimate"] for r in rs], s=3, alpha=0.15)
            ax.plot([0, top], [0, top], "k--", lw=1, label="estimate = truth")
            ax.axhline(cap, color="r", lw=1, ls=":", label=f"log2 K = {cap:.0f}")
            ax.set_title(f"{e}: deterministic worlds, every channel and horizon")
            ax.set_xlabel("exact E (bits)")
            ax.legend(loc="upper left")
        axes[0].set_ylabel("estimate (bits)")
        fig.tight_layout()
        fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
