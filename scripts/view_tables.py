#!/usr/bin/env python3
"""The tables of RESULTS.md's "A partial view" section: reads
experiments/view/<world>/summary.json (written by `fulcrum experiment ... --views
full,crop:4`) and prints, per arm, the seeds solved, the IQM of steps to 0.9 with its
bootstrap interval, the median, and two log-rank tests (two-sided), computed here from
each seed's steps to 0.9 (censored at the budget): the form against the baseline with
the same view, and the cropped arm against the same form with the full view; each with
Holm's adjustment within its family over the four worlds (8 tests each). Standard
library only.

The log-rank test here is the textbook one (Mantel-Cox): at each distinct time t at
which some seed of either arm reached 0.9, with n_a, n_b seeds still unsolved and d_a,
d_b solved at t, observed - expected for arm a is sum(d_a - d n_a / n) and its variance
sum(n_a n_b d (n - d) / (n^2 (n - 1))); chi2 = (O - E)^2 / V with one degree of
freedom, p = erfc(sqrt(chi2 / 2)). `check()` reproduces the summary's own value for
each arm against the baseline before any new p-value is printed."""
import json
import math
import os

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
WORLDS = [("exp1-tree", "500k"), ("exp1-wall", "500k"), ("exp2", "3M"), ("exp3", "3M")]


def times(arm, budget):
    """(time, solved) per seed: steps to 0.9, or the budget, censored."""
    out = []
    for s in arm["per_seed"]:
        t = s["steps_to_threshold"]
        out.append((t, True) if t is not None else (budget, False))
    return out


def log_rank(a, b):
    """(chi2, p, O - E for a) of two lists of (time, solved)."""
    events = sorted({t for t, d in a + b if d})
    o_e, var = 0.0, 0.0
    for t in events:
        na = sum(1 for x, _ in a if x >= t)
        nb = sum(1 for x, _ in b if x >= t)
        da = sum(1 for x, d in a if d and x == t)
        db = sum(1 for x, d in b if d and x == t)
        n, d = na + nb, da + db
        if n < 2:
            continue
        o_e += da - d * na / n
        var += na * nb * d * (n - d) / (n * n * (n - 1))
    if var == 0:
        return 0.0, 1.0, o_e
    chi2 = o_e * o_e / var
    return chi2, math.erfc(math.sqrt(chi2 / 2)), o_e


def fmt_steps(x):
    if x is None:
        return "-"
    return f"{x / 1e6:.2f}M" if x >= 1e6 else f"{x / 1e3:.0f}k"


def fmt_p(p):
    return "< 0.001" if p < 0.001 else f"{p:.3f}"


def side(o_e):
    # More solved than expected (O > E) at early times means faster.
    return "faster" if o_e > 0 else "slower"


def check(s, arms, budget):
    """The summary's log-rank chi2 against its first arm, recomputed here."""
    first = arms[s["arms"][0]["name"]]
    for c in s["comparisons"]:
        chi2, _, _ = log_rank(times(arms[c["arm"]], budget), times(first, budget))
        want = c["log_rank"]["chi2"] if c["log_rank"] else 0.0
        assert abs(chi2 - want) < 1e-6, (c["arm"], chi2, want)


def holm(ps):
    """Holm's step-down adjustment of a dict name -> p."""
    order = sorted(ps, key=ps.get)
    out, run = {}, 0.0
    for i, k in enumerate(order):
        run = max(run, min(1.0, (len(order) - i) * ps[k]))
        out[k] = run
    return out


def main():
    rows = []  # (world, label, arm, form, crop, vs_base, vs_full), tests as (p, o_e)
    for world, label in WORLDS:
        path = os.path.join(ROOT, "experiments", "view", world, "summary.json")
        try:
            s = json.load(open(path))
        except OSError as e:
            print(world, e)
            continue
        budget = s["steps"]
        arms = {a["name"]: a for a in s["arms"]}
        check(s, arms, budget)
        for a in s["arms"]:
            name = a["name"]
            crop = name.endswith("-crop4")
            form = name[: -len("-crop4")] if crop else name
            base = arms["baseline-crop4" if crop else "baseline"]

            def test(other):
                _, p, o_e = log_rank(times(a, budget), times(other, budget))
                return p, o_e

            vs_base = test(base) if form != "baseline" else None
            vs_full = test(arms[form]) if crop else None
            rows.append((world, label, a, form, crop, vs_base, vs_full))
    # Holm's adjustment within each family, over every world: the form against the
    # baseline (one test per world and view), and crop against full (one per world and
    # form).
    fam_base = holm({(r[0], r[4]): r[5][0] for r in rows if r[5]})
    fam_full = holm({(r[0], r[3]): r[6][0] for r in rows if r[6]})

    def cell(t, adj):
        if t is None:
            return "-"
        return f"{fmt_p(t[0])} ({side(t[1])}), Holm {fmt_p(adj)}"

    world = None
    for w, label, a, form, crop, vs_base, vs_full in rows:
        if w != world:
            world = w
            print(f"\n{w} (budget {label})\n")
            print(
                "| arm | view | solved | IQM steps to 0.9 (95% CI) | median "
                "| vs baseline, same view: log-rank p | crop vs full, same form: log-rank p |"
            )
            print("|---|---|---|---|---|---|---|")
        lo, hi = a["iqm_ci"]
        print(
            f"| {form} | {'crop:4' if crop else 'full'} | {a['reached']}/{a['seeds']} "
            f"| {fmt_steps(a['iqm_steps'])} ({fmt_steps(lo)} - {fmt_steps(hi)}) "
            f"| {fmt_steps(a['median_steps'])} "
            f"| {cell(vs_base, fam_base.get((w, crop)))} "
            f"| {cell(vs_full, fam_full.get((w, form)))} |"
        )

if __name__ == "__main__":
    main()
