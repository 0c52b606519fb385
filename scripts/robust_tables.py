#!/usr/bin/env python3
"""The tables of RESULTS.md ("Worlds nobody wrote"): reads the summaries of the
robustness experiments committed as docs/results/<set>-summary.json (the sets in SETS)
(written by `fulcrum experiment --worlds`, every (world, seed) pair's steps to 0.9 in
`per_pair`) and prints, per arm, the pairs solved,
their share with its Wilson 95% interval, the IQM of steps to 0.9 with its bootstrap
interval (as the experiment computed it), the median, the log-rank p against the
baseline with Holm's adjustment over the arms, the pairs solved by only one of the two,
McNemar's exact p with Holm's adjustment, and the pairs the trap detector marked.

Everything but the bootstrap interval is computed here again from the pairs (the median,
the counts, Wilson's interval, the log-rank and McNemar tests, Holm) and checked against
the summary's own numbers. Standard library only."""
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from noisy_tables import log_rank, pt  # noqa: E402

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
# The three sets with the potential counting a boulder's cells, then the same three and a
# fourth with train's default since (a destroy task's boulder by its condition).
SETS = [
    "robust",
    "robust-fresh",
    "robust-third",
    "task-robust",
    "task-robust-fresh",
    "task-robust-third",
    "task-robust-fourth",
]


def st(x):
    return f"{x/1e6:.2f}M" if x >= 1e6 else f"{x/1e3:.0f}k"


def wilson(k, n, z=1.959963984540054):
    p = k / n
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return c - h, c + h


def mcnemar(b, c):
    """Exact two-sided McNemar test: the binomial test of b against b + c at 1/2."""
    n = b + c
    if n == 0:
        return 1.0
    k = min(b, c)
    return min(1.0, 2 * sum(math.comb(n, i) for i in range(k + 1)) / 2**n)


def holm(ps):
    order = sorted(range(len(ps)), key=lambda i: ps[i])
    out, run = [0.0] * len(ps), 0.0
    for rank, i in enumerate(order):
        run = max(run, min(1.0, (len(ps) - rank) * ps[i]))
        out[i] = run
    return out


def close(a, b):
    return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))


def table(name):
    d = json.load(open(os.path.join(ROOT, "docs", "results", f"{name}-summary.json")))
    budget = d["steps"]
    arms = d["arms"]
    pairs = {a["name"]: {(p["world"], p["seed"]): p["steps_to_threshold"] for p in a["per_pair"]} for a in arms}
    base = pairs["baseline"]
    others = [a["name"] for a in arms if a["name"] != "baseline"]
    lr, mc, only = {}, {}, {}
    for arm in others:
        keys = sorted(base)
        a_t = [pairs[arm][k] for k in keys]
        b_t = [base[k] for k in keys]
        _, p, o, e = log_rank(a_t, b_t)
        lr[arm] = (p, o > e)
        only_base = sum(1 for k in keys if base[k] is not None and pairs[arm][k] is None)
        only_arm = sum(1 for k in keys if base[k] is None and pairs[arm][k] is not None)
        only[arm] = (only_base, only_arm)
        mc[arm] = mcnemar(only_base, only_arm)
    lr_holm = dict(zip(others, holm([lr[a][0] for a in others])))
    mc_holm = dict(zip(others, holm([mc[a] for a in others])))
    comps = {c["arm"]: c for c in d["comparisons"]}
    lines = [
        "| arm | pairs solved | share (95% CI) | IQM steps to 0.9 (95% CI) | median | log-rank p vs baseline (Holm) | solved by baseline only / by the arm only | McNemar p (Holm) | pairs marked as trapped |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for a in arms:
        ts = list(pairs[a["name"]].values())
        n, k = len(ts), sum(t is not None for t in ts)
        lo, hi = wilson(k, n)
        at = sorted(budget if t is None else t for t in ts)
        median = (at[n // 2 - 1] + at[n // 2]) / 2 if n % 2 == 0 else at[n // 2]
        # What is computed here must be what the experiment wrote.
        assert (k, n) == (a["solved"], a["pairs"]), a["name"]
        assert close(lo, a["share_ci"][0]) and close(hi, a["share_ci"][1]), a["name"]
        assert close(median, a["median_steps"]), a["name"]
        ci = f"{st(a['iqm_steps'])} ({st(a['iqm_ci'][0])} - {st(a['iqm_ci'][1])})"
        marked = sum(1 for p in a["per_pair"] if p["trap_updates"] > 0)
        assert marked == a["trapped"], a["name"]
        if a["name"] == "baseline":
            rest = "- | - | -"
        else:
            c = comps[a["name"]]
            p, faster = lr[a["name"]]
            assert close(p, c["log_rank"]["p"]) and close(lr_holm[a["name"]], c["log_rank_holm"])
            assert only[a["name"]] == (c["only_against"], c["only_arm"])
            assert close(mc[a["name"]], c["mcnemar_p"]) and close(mc_holm[a["name"]], c["mcnemar_holm"])
            rest = (
                f"{pt(p)} ({'faster' if faster else 'slower'}) ({pt(lr_holm[a['name']])}) | "
                f"{only[a['name']][0]} / {only[a['name']][1]} | {pt(mc[a['name']])} ({pt(mc_holm[a['name']])})"
            )
        lines.append(
            f"| {a['name']} | {k}/{n} | {k / n:.2f} ({lo:.2f} - {hi:.2f}) | {ci} | {st(median)} | {rest} | {marked}/{n} |"
        )
    return "\n".join(lines)


def pairs_of(name, arm):
    d = json.load(open(os.path.join(ROOT, "docs", "results", f"{name}-summary.json")))
    (a,) = [a for a in d["arms"] if a["name"] == arm]
    return {(p["world"], p["seed"]): p["steps_to_threshold"] for p in a["per_pair"]}


def sign_test(k, n):
    """Exact two-sided sign test: the binomial test of k of n at 1/2."""
    if n == 0:
        return 1.0
    k = min(k, n - k)
    return min(1.0, 2 * sum(math.comb(n, i) for i in range(k + 1)) / 2**n)


def rule_change():
    """The default's runs by the boulder's cells against by its condition, pair for pair,
    on the worlds of the first three sets whose runs changed (the baseline's did not)."""
    worlds = pairs = only_new = only_old = faster = slower = 0
    for name in SETS[:3]:
        assert pairs_of(name, "baseline") == pairs_of(f"task-{name}", "baseline"), name
        old, new = pairs_of(name, "horizon-potential"), pairs_of(f"task-{name}", "horizon-potential")
        changed = {w for (w, _), t in new.items() if old[(w, _)] != t}
        worlds += len(changed)
        for k, t in new.items():
            if k[0] not in changed:
                continue
            pairs += 1
            o = old[k]
            only_new += o is None and t is not None
            only_old += o is not None and t is None
            if o is not None and t is not None:
                faster += t < o
                slower += t > o
    return (
        f"horizon-potential by the boulder's cells -> by its condition: {worlds} worlds changed, "
        f"{pairs} pairs; solved only by condition {only_new}, only by cells {only_old}; "
        f"where both solve, faster {faster}, slower {slower} (two-sided sign test p: {pt(sign_test(faster, faster + slower))})"
    )


def main():
    for name in SETS:
        print(f"{name}\n\n{table(name)}\n")
    print(rule_change())


if __name__ == "__main__":
    main()
