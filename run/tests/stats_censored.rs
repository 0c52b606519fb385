//! Comparing arms by censored time-to-threshold: Fisher's exact test, the log-rank test,
//! erfc, the interquartile mean, the percentile bootstrap and the Kaplan-Meier solved
//! fraction. Expected numbers are printed by `scripts/reference/stats_censored.py`
//! (scipy 1.17 / numpy 2.4; lifelines 0.30 agrees on the log-rank and Kaplan-Meier
//! values) or counted by hand in that script's comments.

use fulcrum_run::stats::{bootstrap_ci, erfc, fisher_exact, iqm, log_rank, solved_by};

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs().max(f64::MIN_POSITIVE)
}

fn mean(xs: &[f64]) -> f64 {
    xs.iter().sum::<f64>() / xs.len() as f64
}

#[test]
fn fisher_exact_matches_scipy() {
    // scipy.stats.fisher_exact([[a, na - a], [b, nb - b]]).pvalue
    let cases = [
        ((10, 10, 0, 10), 1.082508822446903e-05),
        ((7, 10, 3, 10), 0.1788954079975752),
        ((10, 10, 10, 10), 1.0),
        ((3, 5, 1, 9), 0.09490509490509491),
        ((0, 4, 6, 8), 0.06060606060606061),
    ];
    for ((a, na, b, nb), want) in cases {
        let p = fisher_exact(a, na, b, nb);
        assert!(
            close(p, want, 1e-9),
            "fisher({a}/{na} vs {b}/{nb}) = {p}, want {want}"
        );
        // Swapping the arms does not change a two-sided test.
        assert!(close(fisher_exact(b, nb, a, na), want, 1e-9));
    }
}

#[test]
fn fisher_exact_degenerate_tables() {
    assert_eq!(fisher_exact(0, 0, 0, 0), 1.0);
    assert_eq!(fisher_exact(0, 10, 0, 10), 1.0);
    assert_eq!(fisher_exact(3, 3, 0, 0), 1.0);
}

#[test]
fn erfc_matches_known_values() {
    // scipy.special.erfc
    let cases = [
        (0.0, 1.0),
        (0.01, 0.9887165844441503),
        (0.3, 0.6713732405408726),
        (1.0, 0.15729920705028516),
        (1.22, 0.08446611897335318),
        (1.2247, 0.08327581479808639),
        (1.23, 0.08194989587323863),
        (2.0, 0.004677734981047266),
        (3.0, 2.2090496998585445e-05),
        (4.0, 1.541725790028002e-08),
        (5.0, 1.5374597944280347e-12),
        (10.0, 2.0884875837625446e-45),
        (26.0, 5.663192408856145e-296),
        (-1.0, 1.8427007929497148),
    ];
    for (x, want) in cases {
        let got = erfc(x);
        assert!(close(got, want, 1e-12), "erfc({x}) = {got}, want {want}");
    }
    assert_eq!(erfc(30.0), 0.0);
    assert_eq!(erfc(f64::INFINITY), 0.0);
    assert_eq!(erfc(f64::NEG_INFINITY), 2.0);
    assert!(erfc(f64::NAN).is_nan());
}

const LR_A: [(f64, bool); 6] = [
    (3.0, true),
    (5.0, true),
    (5.0, false),
    (7.0, true),
    (9.0, false),
    (10.0, true),
];
const LR_B: [(f64, bool); 6] = [
    (5.0, true),
    (7.0, false),
    (8.0, true),
    (10.0, false),
    (10.0, false),
    (12.0, false),
];

#[test]
fn log_rank_matches_textbook_formula_with_ties() {
    // stats_censored.py log_rank (numpy), equal to lifelines.statistics.logrank_test.
    let r = log_rank(&LR_A, &LR_B).unwrap();
    assert_eq!(r.observed_a, 4.0);
    assert!(close(r.expected_a, 2.3674242424242427, 1e-12), "{r:?}");
    assert!(close(r.chi2, 1.9884712959890383, 1e-12), "{r:?}");
    assert!(close(r.p, 0.15850081061071888, 1e-10), "{r:?}");
    // Swapping the samples keeps chi2 and p.
    let s = log_rank(&LR_B, &LR_A).unwrap();
    assert!(close(s.chi2, r.chi2, 1e-12) && close(s.p, r.p, 1e-12));
    assert_eq!(s.observed_a, 2.0);
}

#[test]
fn log_rank_none_without_events_or_variance() {
    let censored = [(10.0, false), (10.0, false)];
    assert_eq!(log_rank(&censored, &censored), None);
    assert_eq!(log_rank(&[], &[]), None);
    assert_eq!(log_rank(&[], &LR_B), None);
    // Sample a leaves the risk set before the first event: V = 0.
    assert_eq!(log_rank(&[(1.0, false)], &[(2.0, true), (3.0, true)]), None);
}

#[test]
fn iqm_matches_scipy_trim_mean() {
    // scipy.stats.trim_mean(x, 0.25)
    let x10 = [0.9, 0.1, 0.5, 0.7, 0.3, 1.0, 0.0, 0.6, 0.2, 0.8];
    let x8 = [4.0, 1.0, 7.0, 2.0, 10.0, 3.0, 5.0, 100.0];
    assert!(close(iqm(&x10), 0.5166666666666666, 1e-12));
    assert!(close(iqm(&x8), 4.75, 1e-12));
    assert!(iqm(&[]).is_nan());
    assert_eq!(iqm(&[3.0]), 3.0);
}

#[test]
fn bootstrap_ci_is_deterministic_and_brackets_the_estimate() {
    let xs = [0.9, 0.1, 0.5, 0.7, 0.3, 1.0, 0.0, 0.6, 0.2, 0.8];
    for stat in [mean as fn(&[f64]) -> f64, iqm] {
        let (lo, hi) = bootstrap_ci(&xs, stat, 2000, 7, 0.95).unwrap();
        assert!(lo <= stat(&xs) && stat(&xs) <= hi, "({lo}, {hi})");
        assert!(lo < hi);
        assert_eq!(bootstrap_ci(&xs, stat, 2000, 7, 0.95), Some((lo, hi)));
        // A narrower level gives a nested interval from the same resamples.
        let (lo50, hi50) = bootstrap_ci(&xs, stat, 2000, 7, 0.5).unwrap();
        assert!(lo <= lo50 && hi50 <= hi);
    }
    let c = [0.25; 10];
    assert_eq!(bootstrap_ci(&c, mean, 500, 1, 0.95), Some((0.25, 0.25)));
    assert_eq!(bootstrap_ci(&c, iqm, 500, 2, 0.95), Some((0.25, 0.25)));
    // Level 1 spans the extreme resamples: for {0, 1} and 1000 resamples, all-0 and
    // all-1 resamples (probability 1/4 each) both occur.
    assert_eq!(
        bootstrap_ci(&[0.0, 1.0], mean, 1000, 3, 1.0),
        Some((0.0, 1.0))
    );
    assert_eq!(bootstrap_ci(&[], mean, 100, 0, 0.95), None);
    assert_eq!(bootstrap_ci(&xs, mean, 0, 0, 0.95), None);
}

#[test]
fn solved_by_is_kaplan_meier() {
    // Hand count in stats_censored.py: 1 - S = 0, 1/7, 1/7, 17/35, 17/35, 26/35, 26/35.
    let km = [
        (2.0, true),
        (3.0, false),
        (4.0, true),
        (4.0, true),
        (4.0, false),
        (6.0, true),
        (8.0, false),
    ];
    let grid = [0.0, 2.0, 3.0, 4.0, 5.0, 6.0, 10.0];
    let want = [
        0.0,
        1.0 / 7.0,
        1.0 / 7.0,
        17.0 / 35.0,
        17.0 / 35.0,
        26.0 / 35.0,
        26.0 / 35.0,
    ];
    let got = solved_by(&km, &grid);
    for (g, w) in got.iter().zip(want) {
        assert!((g - w).abs() < 1e-12, "{got:?}");
    }
    // Without censoring it is the empirical fraction solved.
    let plain = [(1.0, true), (2.0, true), (3.0, false), (4.0, false)];
    let got = solved_by(&plain, &[0.5, 1.0, 2.5, 9.0]);
    for (g, w) in got.iter().zip([0.0, 0.25, 0.5, 0.5]) {
        assert!((g - w).abs() < 1e-12, "{got:?}");
    }
    assert!(solved_by(&[], &[1.0, 2.0]).iter().all(|x| x.is_nan()));
}

/// The running scale of the intrinsic rewards merges batches into the same moments as
/// one pass over all values. By hand: [1, 2, 3, 4, 10] has mean 4 and squared
/// deviations 9 + 4 + 1 + 0 + 36 = 50, so the population std is sqrt(50 / 5) = sqrt(10).
#[test]
fn running_std_merges_batches_exactly() {
    use fulcrum_learner::running_std::RunningStd;
    let mut r = RunningStd::default();
    assert_eq!(r.std(), 0.0);
    r.update(&[1.0, 2.0]);
    r.update(&[]);
    r.update(&[3.0, 4.0, 10.0]);
    assert_eq!(r.count, 5.0);
    assert!((r.mean - 4.0).abs() < 1e-12);
    assert!((r.std() - 10f64.sqrt()).abs() < 1e-12, "{}", r.std());
}

/// Holm's step-down adjustment: statsmodels' `multipletests(ps, method="holm")`
/// (scripts/reference/holm_mcnemar.py).
#[test]
fn holm_matches_statsmodels() {
    use fulcrum_run::stats::holm;
    for (ps, want) in [
        (vec![0.01, 0.04, 0.03, 0.005], vec![0.03, 0.06, 0.06, 0.02]),
        (vec![0.069, 0.754, 0.394, 0.456], vec![0.276, 1.0, 1.0, 1.0]),
        (vec![0.5, 0.5], vec![1.0, 1.0]),
        (vec![0.001], vec![0.001]),
    ] {
        let got = holm(&ps);
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            assert!(
                close(*g, *w, 1e-12),
                "holm({ps:?}) = {got:?}, want {want:?}"
            );
        }
    }
    // A NaN (a comparison without a test) is neither adjusted nor counted.
    let got = holm(&[0.01, f64::NAN, 0.04]);
    assert!(close(got[0], 0.02, 1e-12) && got[1].is_nan() && close(got[2], 0.04, 1e-12));
}

/// McNemar's exact test on the discordant pairs: statsmodels' `mcnemar(exact=True)`
/// and scipy's `binomtest` agree on every value (scripts/reference/holm_mcnemar.py).
#[test]
fn mcnemar_exact_matches_statsmodels() {
    use fulcrum_run::stats::mcnemar_exact;
    for (b, c, want) in [
        (0, 0, 1.0),
        (3, 0, 0.25),
        (0, 7, 0.015625),
        (5, 2, 0.453125),
        (10, 4, 0.1795654296875),
        (1, 1, 1.0),
        (20, 9, 0.06142834573984146),
    ] {
        let got = mcnemar_exact(b, c);
        assert!(
            close(got, want, 1e-9),
            "mcnemar({b}, {c}) = {got}, want {want}"
        );
        assert_eq!(got, mcnemar_exact(c, b), "symmetric");
    }
}
