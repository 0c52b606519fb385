#!/usr/bin/env python3
"""Reference values for run/tests/stats_censored.rs (pip install scipy numpy;
lifelines, if installed, cross-checks the log-rank test and Kaplan-Meier)."""

import numpy as np
from scipy import special, stats

print("# Fisher's exact test, two-sided: scipy.stats.fisher_exact")
for a, na, b, nb in [(10, 10, 0, 10), (7, 10, 3, 10), (10, 10, 10, 10), (3, 5, 1, 9), (0, 4, 6, 8)]:
    p = stats.fisher_exact([[a, na - a], [b, nb - b]], alternative="two-sided").pvalue
    print(f"fisher({a}/{na} vs {b}/{nb}) = {p!r}")

print("# erfc: scipy.special.erfc")
for x in [0.0, 0.01, 0.3, 1.0, 1.22, 1.2247, 1.23, 2.0, 3.0, 4.0, 5.0, 10.0, 26.0, -1.0]:
    print(f"erfc({x}) = {special.erfc(x)!r}")

# Log-rank (Mantel-Cox), textbook formula; at tied times events come before censorings.
LR_A = [(3, True), (5, True), (5, False), (7, True), (9, False), (10, True)]
LR_B = [(5, True), (7, False), (8, True), (10, False), (10, False), (12, False)]


def log_rank(a, b):
    ta = np.array([t for t, _ in a], float)
    ea = np.array([e for _, e in a], bool)
    tb = np.array([t for t, _ in b], float)
    eb = np.array([e for _, e in b], bool)
    times = np.unique(np.concatenate([ta[ea], tb[eb]]))
    o = e = v = 0.0
    for t in times:
        na, nb = (ta >= t).sum(), (tb >= t).sum()
        da, db = (ea & (ta == t)).sum(), (eb & (tb == t)).sum()
        n, d = na + nb, da + db
        o += da
        e += d * na / n
        if n > 1:
            v += d * (na / n) * (1 - na / n) * (n - d) / (n - 1)
    chi2 = (o - e) ** 2 / v
    return chi2, stats.chi2.sf(chi2, 1), o, e


print("# log-rank: numpy textbook formula")
chi2, p, o, e = log_rank(LR_A, LR_B)
print(f"log_rank: chi2 = {chi2!r}, p = {p!r}, observed_a = {o!r}, expected_a = {e!r}")
try:
    from lifelines.statistics import logrank_test

    r = logrank_test(
        [t for t, _ in LR_A], [t for t, _ in LR_B], [e for _, e in LR_A], [e for _, e in LR_B]
    )
    print(f"  lifelines: chi2 = {r.test_statistic!r}, p = {r.p_value!r}")
except ImportError:
    pass

print("# IQM: scipy.stats.trim_mean(x, 0.25)")
IQM10 = [0.9, 0.1, 0.5, 0.7, 0.3, 1.0, 0.0, 0.6, 0.2, 0.8]
IQM8 = [4.0, 1.0, 7.0, 2.0, 10.0, 3.0, 5.0, 100.0]
print(f"iqm(n=10) = {stats.trim_mean(IQM10, 0.25)!r}")
print(f"iqm(n=8) = {stats.trim_mean(IQM8, 0.25)!r}")

# Kaplan-Meier, counted by hand:
#   t=2: 7 at risk, 1 event -> S = 6/7; the censoring at 3 leaves 5 at risk.
#   t=4: 5 at risk (the censoring at 4 still counts), 2 events -> S = 6/7 * 3/5 = 18/35.
#   t=6: 2 at risk, 1 event -> S = 18/35 * 1/2 = 9/35; t=8 is censored.
#   solved_by at [0, 2, 3, 4, 5, 6, 10] = [0, 1/7, 1/7, 17/35, 17/35, 26/35, 26/35].
KM = [(2, True), (3, False), (4, True), (4, True), (4, False), (6, True), (8, False)]
KM_GRID = [0, 2, 3, 4, 5, 6, 10]
print("# Kaplan-Meier 1 - S(t), by hand")
print([0, 1 / 7, 1 / 7, 17 / 35, 17 / 35, 26 / 35, 26 / 35])
try:
    from lifelines import KaplanMeierFitter

    km = KaplanMeierFitter().fit([t for t, _ in KM], [e for _, e in KM])
    print("  lifelines:", list(1 - km.survival_function_at_times(KM_GRID).values))
except ImportError:
    pass
