"""Reference values for run/src/eval.rs's tests: Wilson's 95% score interval and
Student's t 0.975 quantiles, from SciPy.

    python scripts/reference/eval_ci.py
"""

from scipy import stats

for k, n in [(7, 10), (0, 20), (20, 20)]:
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    print(f"wilson({k}, {n}) = ({ci.low:.7f}, {ci.high:.7f})")
for df in [1, 4, 29, 99]:
    print(f"t975({df}) = {stats.t.ppf(0.975, df):.9f}")
