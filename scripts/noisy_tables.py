#!/usr/bin/env python3
"""The tables of RESULTS.md ("Noisy worlds"): reads docs/results/noisy-<world>-summary.json
(copied there from experiments/noisy/<world> by scripts/results.sh) and prints, per world
and arm, seeds solved, the IQM of steps to 0.9 with its bootstrap interval, the median,
the log-rank p against the baseline with its direction, Holm's adjustment over the three
empowerment arms, and the log-rank test of horizon-potential against the same computed as
if the world were deterministic (computed here from the per-seed steps; the same test as
`fulcrum experiment`'s, which agrees on the comparisons against the baseline, checked
below). Standard library only."""
import json
import math
import os

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
WORLDS = [("exp1-tree-slip", "500k"), ("exp2-slip", "3M")]
FORMS = ["additive", "horizon-potential", "horizon-potential-deterministic"]


def st(x):
    if x is None:
        return "-"
    return f"{x/1e6:.2f}M" if x >= 1e6 else f"{x/1e3:.0f}k"


def pt(p):
    return "< 0.001" if p < 0.001 else f"{p:.3f}"


def log_rank(a, b):
    """Two-sided log-rank test of two groups of times to the threshold (None: censored
    at the budget): chi2 with 1 degree of freedom, p, observed and expected events of a."""
    times = sorted({t for t in a + b if t is not None})
    o_a = e_a = v = 0.0
    for t in times:
        n_a = sum(1 for x in a if x is None or x >= t)
        n_b = sum(1 for x in b if x is None or x >= t)
        d_a = sum(1 for x in a if x == t)
        d_b = sum(1 for x in b if x == t)
        n, d = n_a + n_b, d_a + d_b
        o_a += d_a
        e_a += d * n_a / n
        if n > 1:
            v += d * (n_a / n) * (n_b / n) * (n - d) / (n - 1)
    chi2 = (o_a - e_a) ** 2 / v if v > 0 else 0.0
    return chi2, math.erfc(math.sqrt(chi2 / 2)), o_a, e_a


def times(arm):
    return [s["steps_to_threshold"] for s in arm["per_seed"]]


def main():
    for w, budget in WORLDS:
        s = json.load(open(os.path.join(ROOT, "docs", "results", f"noisy-{w}-summary.json")))
        arms = {a["name"]: a for a in s["arms"]}
        comps = {c["arm"]: c for c in s["comparisons"]}
        for name, c in comps.items():
            mine = log_rank(times(arms[name]), times(arms["baseline"]))
            assert abs(mine[1] - c["log_rank"]["p"]) < 1e-9, (w, name, mine, c["log_rank"])
        ps = sorted((comps[f]["log_rank"]["p"], f) for f in FORMS)
        holm, run = {}, 0.0
        for i, (p, f) in enumerate(ps):
            run = max(run, min(1.0, (len(ps) - i) * p))
            holm[f] = run
        print(f"\n{w} (budget {budget}, 10 seeds)\n")
        print("| arm | solved | IQM steps to 0.9 (95% CI) | median | log-rank p vs baseline | Holm (3 arms) |")
        print("|---|---|---|---|---|---|")
        for a in s["arms"]:
            c = comps.get(a["name"])
            ci = a["iqm_ci"]
            iq = f"{st(a['iqm_steps'])} ({st(ci[0])} - {st(ci[1])})" if ci else "-"
            lr = "-"
            if c:
                lr = pt(c["log_rank"]["p"])
                lr += " (faster)" if c["log_rank"]["observed_a"] > c["log_rank"]["expected_a"] else " (slower)"
            h = pt(holm[a["name"]]) if a["name"] in holm else "-"
            print(f"| {a['name']} | {a['reached']}/{a['finished']} | {iq} | {st(a['median_steps'])} | {lr} | {h} |")
        chi2, p, o, e = log_rank(times(arms["horizon-potential"]), times(arms["horizon-potential-deterministic"]))
        faster = "exact faster" if o > e else "deterministic faster"
        print(f"\nhorizon-potential (exact) against horizon-potential-deterministic: log-rank chi2 {chi2:.2f}, p {pt(p)} ({faster})")


if __name__ == "__main__":
    main()
