#!/usr/bin/env python3
"""The table of RESULTS.md's "Layouts never seen": reads
docs/results/layouts-<N>-summary.json (`fulcrum experiment toolbox ... -- --layouts N`,
N = 16, 256 and all) and docs/results/layouts-evals.csv (every run's `fulcrum eval
--layouts test:500` and `--layouts train:K` rows), both written by
scripts/layouts_experiment.sh, and prints one row per (layouts trained on, arm):

- seeds whose training success (pooled over 10 updates, as the experiment pools it)
  reached 0.9, the IQM of their steps to 0.9 with its bootstrap interval, and the
  log-rank test against the baseline trained on as many layouts (two-sided; the
  summary's own statistic is recomputed first, `view_tables.check`);
- greedy success on the training layouts and on 500 held-out layouts, the gap between
  the two, and tool choice on the held-out layouts (the share of episodes whose first
  tool fits the layout's task object): IQM over the seeds with a 95% percentile
  bootstrap interval (10,000 resamples of the seeds, Python's generator seeded 0; the
  IQM drops n // 4 seeds at each end, as `fulcrum_run::stats::iqm`);
- the form against the baseline on held-out success and on held-out tool choice: an
  exact two-sided permutation test of the difference of the seeds' means (every split
  of the 20 seeds into two groups of 10).

The first table plays greedy (the most probable allowed action), the second samples the
actions from the policy as training does (`fulcrum eval --sample`, seeded with the
run's seed); the second adds, on the held-out layouts, the share of the episodes that
use a tool whose first tool fits (tool choice over tool use, per seed).

Holm's adjustment within each family of tests (log-rank; held-out success; tool
choice; each of the two plays apart), over the two forms and the three layout settings. Standard library only."""
import csv
import itertools
import json
import os
import random
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from view_tables import check, fmt_p, fmt_steps, holm, log_rank, side, times  # noqa: E402

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
COUNTS = ["16", "256", "all"]
FORMS = ["horizon-potential", "additive"]


def iqm(xs):
    v = sorted(xs)
    cut = len(v) // 4
    mid = v[cut : len(v) - cut]
    return sum(mid) / len(mid)


def bootstrap(xs, reps=10000, seed=0):
    rng = random.Random(seed)
    stats = sorted(iqm([rng.choice(xs) for _ in xs]) for _ in range(reps))

    def q(p):
        x = p * (len(stats) - 1)
        lo = int(x)
        hi = min(lo + 1, len(stats) - 1)
        return stats[lo] + (stats[hi] - stats[lo]) * (x - lo)

    return q(0.025), q(0.975)


def permutation_p(a, b):
    """Exact two-sided permutation test of mean(a) - mean(b)."""
    pooled = a + b
    n = len(a)
    want = abs(sum(a) / n - sum(b) / len(b))
    total = sum(pooled)
    hits = count = 0
    for idx in itertools.combinations(range(len(pooled)), n):
        sa = sum(pooled[i] for i in idx)
        d = abs(sa / n - (total - sa) / len(b))
        hits += d >= want - 1e-12
        count += 1
    return hits / count


def evals():
    """(layouts, arm, which, mode) -> {seed: row} from layouts-evals.csv."""
    out = {}
    with open(os.path.join(ROOT, "docs", "results", "layouts-evals.csv")) as f:
        for r in csv.DictReader(f):
            which = "test" if r["layouts"].startswith("test:") else "train"
            key = (r["layouts_trained"], r["arm"], which, r["mode"])
            out.setdefault(key, {})[int(r["train_seed"])] = r
    return out


def fmt(x, ci):
    return f"{x:.2f} ({ci[0]:.2f} - {ci[1]:.2f})"


def cell(xs):
    return fmt(iqm(xs), bootstrap(xs))


def table(ev, summaries, mode):
    """One table of RESULTS.md: the policies played `mode` (greedy or sample)."""
    rows, lr, succ, choice = [], {}, {}, {}
    for n in COUNTS:
        s = summaries[n]
        budget = s["steps"]
        arms = {a["name"]: a for a in s["arms"]}

        def per_seed(arm, which, col):
            got = ev[(n, arm, which, mode)]
            return [float(got[k][col]) for k in sorted(got)]

        base_test = per_seed("baseline", "test", "success")
        base_choice = per_seed("baseline", "test", "tool_choice")
        for name in ["baseline"] + FORMS:
            a = arms[name]
            train = per_seed(name, "train", "success")
            test = per_seed(name, "test", "success")
            tc = per_seed(name, "test", "tool_choice")
            used = per_seed(name, "test", "tool_use")
            fits = [c / u if u > 0 else 0.0 for c, u in zip(tc, used)]
            gap = [x - y for x, y in zip(train, test)]
            if name != "baseline":
                _, p, o_e = log_rank(times(a, budget), times(arms["baseline"], budget))
                lr[(n, name)] = (p, o_e)
                succ[(n, name)] = permutation_p(test, base_test)
                choice[(n, name)] = permutation_p(tc, base_choice)
            rows.append((n, name, a, train, test, gap, tc, fits))
    h_lr = holm({k: v[0] for k, v in lr.items()})
    h_s, h_c = holm(succ), holm(choice)
    sampled = mode == "sample"
    extra = " | first tool fits, of episodes using one" if sampled else ""
    print(
        "| layouts | arm | seeds at 0.9 on them | IQM steps to 0.9 (95% CI) | log-rank vs baseline: p, Holm "
        "| success, training layouts | success, 500 held-out | gap | tool choice, held-out "
        f"| held-out success vs baseline: p, Holm | tool choice vs baseline: p, Holm{extra} |"
    )
    print("|---" * (12 if sampled else 11) + "|")
    for n, name, a, train, test, gap, tc, fits in rows:
        if a["iqm_steps"] is None:
            steps = "-"
        else:
            lo, hi = a["iqm_ci"]
            steps = f"{fmt_steps(a['iqm_steps'])} ({fmt_steps(lo)} - {fmt_steps(hi)})"
        k = (n, name)
        if name == "baseline":
            vs_lr = vs_s = vs_c = "-"
        else:
            p, o_e = lr[k]
            vs_lr = f"{fmt_p(p)} ({side(o_e)}), Holm {fmt_p(h_lr[k])}"
            vs_s = f"{fmt_p(succ[k])}, Holm {fmt_p(h_s[k])}"
            vs_c = f"{fmt_p(choice[k])}, Holm {fmt_p(h_c[k])}"
        tail = f" | {cell(fits)}" if sampled else ""
        print(
            f"| {n} | {name} | {a['reached']}/{a['seeds']} | {steps} | {vs_lr} "
            f"| {cell(train)} | {cell(test)} | {cell(gap)} | {cell(tc)} | {vs_s} | {vs_c}{tail} |"
        )
    print()
    print(f"Per seed ({mode}), held-out success and tool choice (seeds 1 to 10):")
    for n, name, _, _, test, _, tc, _ in rows:
        print(f"- {n} layouts, {name}: success {' '.join(f'{x:.3f}' for x in test)}; "
              f"tool choice {' '.join(f'{x:.3f}' for x in tc)}")


def main():
    ev = evals()
    summaries = {}
    for n in COUNTS:
        s = json.load(open(os.path.join(ROOT, "docs", "results", f"layouts-{n}-summary.json")))
        check(s, {a["name"]: a for a in s["arms"]}, s["steps"])
        summaries[n] = s
    print("Greedy:")
    print()
    table(ev, summaries, "greedy")
    print()
    print("Sampled:")
    print()
    table(ev, summaries, "sample")


if __name__ == "__main__":
    main()
