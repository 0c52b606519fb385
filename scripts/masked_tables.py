#!/usr/bin/env python3
"""The per-world tables of RESULTS.md ("Defaults: masked actions, floored advantages"):
reads the experiments' summaries committed as docs/results/masked-<world>-summary.json
(`fulcrum experiment`'s summary.json, copied there by scripts/results.sh) and prints, per
arm, seeds solved, the IQM of steps to 0.9 with its bootstrap interval, the median, the
log-rank p against the baseline with its direction, and Holm's adjustment over the four
empowerment forms of the world. The log-rank tests and Holm's adjustment are computed
again here from the per-seed steps and checked against the experiment's. Worlds whose
summary is not committed yet are left out. On exp2 and exp3 the table's
horizon-potential arm has beta 0.05 (its default when the table was made): a rerun names
it `horizon-potential-beta-0.05` (`--beta-sweep 0.05`), beside today's default arm, which
belongs to RESULTS.md's "The default on the paper's worlds". Standard library only."""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from noisy_tables import log_rank, pt, st  # noqa: E402

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
WORLDS = [("exp1-tree", "500k"), ("exp1-wall", "500k"), ("exp2", "3M"), ("exp3", "3M")]
FORMS = {"additive", "additive-fixed", "horizon-potential", "first-visit"}


def times(arm):
    return [s["steps_to_threshold"] for s in arm["per_seed"]]


def main():
    for w, budget in WORLDS:
        path = os.path.join(ROOT, "docs", "results", f"masked-{w}-summary.json")
        if not os.path.exists(path):
            continue
        s = json.load(open(path))
        old = {a["name"]: a for a in s["arms"]}.get("horizon-potential-beta-0.05")
        if old is not None:
            s["arms"] = [
                dict(old, name="horizon-potential") if a["name"] == "horizon-potential" else a
                for a in s["arms"]
                if a["name"] != "horizon-potential-beta-0.05"
            ]
            s["comparisons"] = [
                dict(c, arm="horizon-potential") if c["arm"] == "horizon-potential-beta-0.05" else c
                for c in s["comparisons"]
                if c["arm"] != "horizon-potential"
            ]
        arms = {a["name"]: a for a in s["arms"]}
        comps = {c["arm"]: c for c in s["comparisons"]}
        base = times(arms["baseline"])
        tests = {}
        for name, a in arms.items():
            if name == "baseline":
                continue
            chi2, p, o, e = log_rank(times(a), base)
            c = comps[name]["log_rank"]
            assert abs(p - c["p"]) < 1e-9 and abs(o - c["observed_a"]) < 1e-9, (w, name)
            tests[name] = (p, o > e)
        # Holm over the four forms.
        ps = sorted((tests[a][0], a) for a in tests if a in FORMS)
        holm, run = {}, 0.0
        for i, (p, a) in enumerate(ps):
            run = max(run, min(1.0, (len(ps) - i) * p))
            holm[a] = run
        print(f"\n{w} (budget {budget})")
        print("| arm | solved | IQM steps to 0.9 (95% CI) | median | log-rank p vs baseline | Holm (4 forms) |")
        print("|---|---|---|---|---|---|")
        for a in s["arms"]:
            ci = a["iqm_ci"]
            iq = f"{st(a['iqm_steps'])} ({st(ci[0])} - {st(ci[1])})" if ci else "-"
            if a["name"] in tests:
                p, faster = tests[a["name"]]
                lr = f"{pt(p)} ({'faster' if faster else 'slower'})"
            else:
                lr = "-"
            h = pt(holm[a["name"]]) if a["name"] in holm else "-"
            print(f"| {a['name']} | {a['reached']}/{a['finished']} | {iq} | {st(a['median_steps'])} | {lr} | {h} |")


if __name__ == "__main__":
    main()
