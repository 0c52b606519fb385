#!/usr/bin/env python3
"""Reference values for run/tests/stats.rs's Holm and McNemar tests
(pip install scipy statsmodels): Holm's step-down adjustment from statsmodels'
multipletests, McNemar's exact test from statsmodels (the binomial test on the
discordant pairs, two-sided) and, the same number, scipy's binomtest."""

from scipy import stats
from statsmodels.stats.multitest import multipletests
from statsmodels.stats.contingency_tables import mcnemar

print("# Holm: multipletests(ps, method='holm')[1]")
for ps in [[0.01, 0.04, 0.03, 0.005], [0.069, 0.754, 0.394, 0.456], [0.5, 0.5], [0.001]]:
    print(f"holm({ps}) = {list(multipletests(ps, method='holm')[1])!r}")

print("# McNemar exact, two-sided: b only-first, c only-second")
for b, c in [(0, 0), (3, 0), (0, 7), (5, 2), (10, 4), (1, 1), (20, 9)]:
    p = mcnemar([[0, b], [c, 0]], exact=True).pvalue
    q = stats.binomtest(min(b, c), b + c, 0.5).pvalue if b + c else 1.0
    print(f"mcnemar({b}, {c}) = {p!r}  (binomtest {q!r})")
