//! Aggregating the learning curves of several runs: what `fulcrum experiment` reports.
//!
//! Each run's `metrics.csv` gives one row per PPO update i: env steps x_i, episodes
//! finished in that update n_i, their success rate s_i and mean extrinsic return r_i
//! (NaN when n_i = 0).
//!
//! * **Smoothing** ([`smooth`]): the rate at update i is pooled over the episodes of the
//!   last `w` updates, s~_i = (sum_j s_j n_j) / (sum_j n_j) for j in (i - w, i], NaN
//!   when those updates finished no episode. Pooling weights each episode once, so an
//!   update with one lucky episode does not count as much as one with fifty.
//! * **Common grid** ([`interpolate`]): seeds are compared at the same env steps
//!   g_k = k * S / K, k = 0..=K. Between two finite points the curve is linear; before
//!   the first finite point it holds the first value and after the last it holds the
//!   last (a run is never extrapolated by a slope).
//! * **Mean and band** ([`mean_std`]): at each g_k, the mean over seeds and the sample
//!   standard deviation (divisor n - 1; 0 for one seed).
//! * **Steps to threshold** ([`steps_to`]): the env steps x_i of the first update whose
//!   smoothed rate reaches the threshold, or `None` when no update does.
//! * **Area under the curve** ([`area`]): the trapezoid integral of the grid curve over
//!   [g_0, g_K], divided by the span: the mean success rate over training, in [0, 1].
//! * **Welch's t-test** ([`welch`]): for two samples a, b of sizes n_a, n_b >= 2 with
//!   sample variances v_a, v_b, t = (mean_a - mean_b) / sqrt(v_a/n_a + v_b/n_b) with
//!   Welch-Satterthwaite degrees of freedom
//!   df = (v_a/n_a + v_b/n_b)^2 / ((v_a/n_a)^2/(n_a-1) + (v_b/n_b)^2/(n_b-1)),
//!   and the two-sided p-value P(|T_df| >= |t|) = I_{df/(df+t^2)}(df/2, 1/2), the
//!   regularised incomplete beta function ([`incomplete_beta`]).
//!
//! Comparing arms by *when* their seeds succeed: each seed i gives (t_i, e_i), the env
//! steps at which it reached the success threshold (e_i = true) or at which it was
//! censored by the budget without reaching it (e_i = false).
//!
//! * **Fisher's exact test** ([`fisher_exact`]): the 2x2 table of successes and
//!   failures of arms a and b, with margins n_a, n_b and k = total successes. Under
//!   independence the successes of a are hypergeometric,
//!   P(x) = C(n_a, x) C(n_b, k - x) / C(n_a + n_b, k), evaluated with log-factorials
//!   ln x! = ln Gamma(x + 1). The two-sided p-value sums P(x) over every x with
//!   P(x) <= P(x_obs) (1 + 1e-7), the relative tolerance of R's `fisher.test` (so
//!   that mirror tables of equal probability count despite rounding).
//! * **Log-rank test** ([`log_rank`]): at each distinct event time t_j, with n_j seeds
//!   at risk (t_i >= t_j; n_aj of them in a) and d_j events (d_aj in a), the expected
//!   events of a are E_aj = d_j n_aj / n_j with hypergeometric variance
//!   V_j = d_j (n_aj / n_j)(1 - n_aj / n_j)(n_j - d_j) / (n_j - 1). Censorings at t_j
//!   are still at risk there (events come first). With O_a the events of a,
//!   chi2 = (O_a - sum E_aj)^2 / sum V_j and p = P(chi2_1 >= chi2) = erfc(sqrt(chi2 / 2))
//!   ([`erfc`]).
//! * **Interquartile mean** ([`iqm`]): as in rliable (Agarwal et al. 2021), which calls
//!   `scipy.stats.trim_mean(x, 0.25)`: sort, drop floor(n / 4) values from each end
//!   (whole values, no fractional weights) and average the rest.
//! * **Percentile bootstrap** ([`bootstrap_ci`]): B resamples of the n values with
//!   replacement (ChaCha8 seeded with `seed`), the statistic of each, and their
//!   (1 - level)/2 and (1 + level)/2 quantiles, linearly interpolated between order
//!   statistics at position q (B - 1) (numpy's default `linear` method).
//! * **Solved fraction** ([`solved_by`]): the Kaplan-Meier estimate
//!   S(t) = prod_{t_j <= t} (1 - d_j / n_j) of the fraction of seeds that have not yet
//!   reached the threshold by t (censorings at t_j leave the risk set after the events
//!   at t_j), reported as 1 - S(t).

/// One update of one run, as read from `metrics.csv`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    /// Env steps after the update.
    pub steps: f64,
    /// Episodes finished in the update.
    pub episodes: f64,
    /// Their success rate (NaN when none finished).
    pub success: f64,
    /// Their mean extrinsic return (NaN when none finished).
    pub ret: f64,
}

impl From<&fulcrum_learner::metrics::MetricsRow> for Point {
    fn from(r: &fulcrum_learner::metrics::MetricsRow) -> Point {
        Point {
            steps: r.env_steps as f64,
            episodes: r.episodes as f64,
            success: r.success_rate,
            ret: r.extrinsic_return,
        }
    }
}

/// Episode-pooled success rate and mean return over a trailing window of `w` updates
/// (w >= 1; `w = 1` is the raw series). Returns `(steps, success, return)` per update.
pub fn smooth(points: &[Point], w: usize) -> Vec<(f64, f64, f64)> {
    let w = w.max(1);
    (0..points.len())
        .map(|i| {
            let lo = (i + 1).saturating_sub(w);
            let (mut n, mut s, mut r) = (0.0, 0.0, 0.0);
            for p in &points[lo..=i] {
                if p.episodes > 0.0 && p.success.is_finite() && p.ret.is_finite() {
                    n += p.episodes;
                    s += p.success * p.episodes;
                    r += p.ret * p.episodes;
                }
            }
            if n > 0.0 {
                (points[i].steps, s / n, r / n)
            } else {
                (points[i].steps, f64::NAN, f64::NAN)
            }
        })
        .collect()
}

/// The grid 0, S/K, ..., S (K + 1 points; K >= 1).
pub fn grid(span: f64, k: usize) -> Vec<f64> {
    let k = k.max(1);
    (0..=k).map(|i| span * i as f64 / k as f64).collect()
}

/// Linear interpolation of the finite points of `(x, y)` (x ascending) at each grid
/// point; the first and last finite values are held outside their range. All NaN when
/// there is no finite point.
pub fn interpolate(xy: &[(f64, f64)], grid: &[f64]) -> Vec<f64> {
    let pts: Vec<(f64, f64)> = xy
        .iter()
        .copied()
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    if pts.is_empty() {
        return vec![f64::NAN; grid.len()];
    }
    let mut j = 0;
    grid.iter()
        .map(|&g| {
            if g <= pts[0].0 {
                return pts[0].1;
            }
            if g >= pts[pts.len() - 1].0 {
                return pts[pts.len() - 1].1;
            }
            while pts[j + 1].0 < g {
                j += 1;
            }
            let ((x0, y0), (x1, y1)) = (pts[j], pts[j + 1]);
            if x1 > x0 {
                y0 + (y1 - y0) * (g - x0) / (x1 - x0)
            } else {
                y1
            }
        })
        .collect()
}

/// Mean and sample standard deviation (divisor n - 1; 0 when n = 1) of finite values;
/// `(NaN, NaN)` when there are none.
pub fn mean_std(xs: &[f64]) -> (f64, f64) {
    let v: Vec<f64> = xs.iter().copied().filter(|x| x.is_finite()).collect();
    let n = v.len() as f64;
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let m = v.iter().sum::<f64>() / n;
    if v.len() == 1 {
        return (m, 0.0);
    }
    let ss: f64 = v.iter().map(|x| (x - m) * (x - m)).sum();
    (m, (ss / (n - 1.0)).sqrt())
}

/// Per grid point, the mean and sample standard deviation over curves (all the same
/// length).
pub fn band(curves: &[Vec<f64>]) -> Vec<(f64, f64)> {
    let len = curves.iter().map(Vec::len).min().unwrap_or(0);
    (0..len)
        .map(|k| mean_std(&curves.iter().map(|c| c[k]).collect::<Vec<_>>()))
        .collect()
}

/// Env steps of the first point whose rate reaches `threshold`, if any.
pub fn steps_to(smoothed: &[(f64, f64, f64)], threshold: f64) -> Option<f64> {
    smoothed
        .iter()
        .find(|(_, s, _)| s.is_finite() && *s >= threshold)
        .map(|(x, _, _)| *x)
}

/// Trapezoid integral of `ys` over `xs` divided by the span (the curve's mean height).
/// NaN values count as 0. NaN when the span is not positive.
pub fn area(xs: &[f64], ys: &[f64]) -> f64 {
    let n = xs.len().min(ys.len());
    if n < 2 || xs[n - 1] <= xs[0] {
        return f64::NAN;
    }
    let y = |i: usize| if ys[i].is_finite() { ys[i] } else { 0.0 };
    let s: f64 = (1..n)
        .map(|i| (xs[i] - xs[i - 1]) * (y(i) + y(i - 1)) / 2.0)
        .sum();
    s / (xs[n - 1] - xs[0])
}

/// Episode-pooled success rate and mean return over the last `frac` of the updates
/// (at least one update).
pub fn final_rates(points: &[Point], frac: f64) -> (f64, f64) {
    let k = ((points.len() as f64 * frac).ceil() as usize).clamp(1, points.len().max(1));
    let tail = &points[points.len().saturating_sub(k)..];
    smooth(tail, tail.len())
        .last()
        .map(|&(_, s, r)| (s, r))
        .unwrap_or((f64::NAN, f64::NAN))
}

/// The result of Welch's unequal-variance t-test.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Welch {
    /// t statistic (mean of a minus mean of b over the standard error).
    pub t: f64,
    /// Welch-Satterthwaite degrees of freedom.
    pub df: f64,
    /// Two-sided p-value.
    pub p: f64,
}

/// Welch's t-test of two samples; `None` when a sample has fewer than two values.
/// Two samples without variance give p = 1 when their means are equal, else p = 0.
pub fn welch(a: &[f64], b: &[f64]) -> Option<Welch> {
    if a.len() < 2 || b.len() < 2 {
        return None;
    }
    let (ma, sa) = mean_std(a);
    let (mb, sb) = mean_std(b);
    let (na, nb) = (a.len() as f64, b.len() as f64);
    let (qa, qb) = (sa * sa / na, sb * sb / nb);
    let se2 = qa + qb;
    if se2 == 0.0 {
        return Some(if ma == mb {
            Welch {
                t: 0.0,
                df: na + nb - 2.0,
                p: 1.0,
            }
        } else {
            Welch {
                t: (ma - mb).signum() * f64::INFINITY,
                df: na + nb - 2.0,
                p: 0.0,
            }
        });
    }
    let t = (ma - mb) / se2.sqrt();
    let df = se2 * se2 / (qa * qa / (na - 1.0) + qb * qb / (nb - 1.0));
    let p = incomplete_beta(df / 2.0, 0.5, df / (df + t * t)).clamp(0.0, 1.0);
    Some(Welch { t, df, p })
}

/// ln Gamma(x) for x > 0 (Lanczos approximation, g = 7, 9 terms; relative error
/// below 1e-13 for the arguments used here).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Gamma(x) Gamma(1 - x) = pi / sin(pi x).
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The regularised incomplete beta function I_x(a, b) for a, b > 0 and x in [0, 1],
/// by its continued fraction (evaluated with the modified Lentz method), using the
/// symmetry I_x(a, b) = 1 - I_{1-x}(b, a) where the fraction converges slowly.
pub fn incomplete_beta(a: f64, b: f64, x: f64) -> f64 {
    if x.is_nan() || x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln();
    if x < (a + 1.0) / (a + b + 2.0) {
        ln_front.exp() * beta_fraction(a, b, x) / a
    } else {
        1.0 - ln_front.exp() * beta_fraction(b, a, 1.0 - x) / b
    }
}

/// The continued fraction 1 / (1 + d1 / (1 + d2 / (1 + ...))) of I_x(a, b), with
/// d_{2m+1} = -(a + m)(a + b + m) x / ((a + 2m)(a + 2m + 1)) and
/// d_{2m} = m (b - m) x / ((a + 2m - 1)(a + 2m)).
fn beta_fraction(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let clamp = |v: f64| if v.abs() < TINY { TINY } else { v };
    let mut c = 1.0;
    let mut d = 1.0 / clamp(1.0 - (a + b) * x / (a + 1.0));
    let mut f = d;
    for m in 1..10_000 {
        let m = f64::from(m);
        let even = m * (b - m) * x / ((a + 2.0 * m - 1.0) * (a + 2.0 * m));
        d = 1.0 / clamp(1.0 + even * d);
        c = clamp(1.0 + even / c);
        f *= d * c;
        let odd = -(a + m) * (a + b + m) * x / ((a + 2.0 * m) * (a + 2.0 * m + 1.0));
        d = 1.0 / clamp(1.0 + odd * d);
        c = clamp(1.0 + odd / c);
        let step = d * c;
        f *= step;
        if (step - 1.0).abs() < 1e-15 {
            break;
        }
    }
    f
}

/// Two-sided Fisher's exact test of arm a (`a_success` of `a_n` seeds succeeded) against
/// arm b (`b_success` of `b_n`): the total hypergeometric probability of the tables with
/// the same margins that are no more probable than the observed one (relative tolerance
/// 1e-7). Success counts above their totals are clamped to them; a table with an empty
/// row or column (only one table possible) gives p = 1.
pub fn fisher_exact(a_success: usize, a_n: usize, b_success: usize, b_n: usize) -> f64 {
    let (xa, xb) = (a_success.min(a_n), b_success.min(b_n));
    let k = xa + xb;
    let ln_fact = |m: usize| ln_gamma(m as f64 + 1.0);
    let ln_choose = |n: usize, r: usize| ln_fact(n) - ln_fact(r) - ln_fact(n - r);
    let ln_total = ln_choose(a_n + b_n, k);
    let ln_p = |x: usize| ln_choose(a_n, x) + ln_choose(b_n, k - x) - ln_total;
    let observed = ln_p(xa).exp() * (1.0 + 1e-7);
    let (lo, hi) = (k.saturating_sub(b_n), k.min(a_n));
    (lo..=hi)
        .map(|x| ln_p(x).exp())
        .filter(|&p| p <= observed)
        .sum::<f64>()
        .clamp(0.0, 1.0)
}

/// The result of a two-sample log-rank (Mantel-Cox) test.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LogRank {
    /// Chi-squared statistic (1 degree of freedom).
    pub chi2: f64,
    /// p-value P(chi2_1 >= chi2).
    pub p: f64,
    /// Events observed in sample a.
    pub observed_a: f64,
    /// Events expected in sample a under equal hazards.
    pub expected_a: f64,
}

/// The log-rank test of two samples of `(time, event)` pairs (`event` true when the
/// threshold was reached at `time`, false when censored there). Pairs with a NaN time
/// are ignored. `None` when there is no event at all or the variance is zero (e.g. one
/// sample is empty or has left the risk set before the first event).
pub fn log_rank(a: &[(f64, bool)], b: &[(f64, bool)]) -> Option<LogRank> {
    // (time, event, in a), sorted by time.
    let mut all: Vec<(f64, bool, bool)> = a
        .iter()
        .map(|&(t, e)| (t, e, true))
        .chain(b.iter().map(|&(t, e)| (t, e, false)))
        .filter(|(t, _, _)| !t.is_nan())
        .collect();
    all.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut n = all.len() as f64;
    let mut n_a = all.iter().filter(|x| x.2).count() as f64;
    let (mut observed, mut expected, mut var, mut events) = (0.0, 0.0, 0.0, 0.0);
    let mut i = 0;
    while i < all.len() {
        let t = all[i].0;
        let j = i + all[i..].partition_point(|x| x.0 == t);
        let (mut d, mut d_a, mut out_a) = (0.0, 0.0, 0.0);
        for &(_, e, in_a) in &all[i..j] {
            if e {
                d += 1.0;
            }
            if e && in_a {
                d_a += 1.0;
            }
            if in_a {
                out_a += 1.0;
            }
        }
        if d > 0.0 {
            let frac = n_a / n;
            events += d;
            observed += d_a;
            expected += d * frac;
            if n > 1.0 {
                var += d * frac * (1.0 - frac) * (n - d) / (n - 1.0);
            }
        }
        n -= (j - i) as f64;
        n_a -= out_a;
        i = j;
    }
    if events == 0.0 || var <= 0.0 {
        return None;
    }
    let chi2 = (observed - expected) * (observed - expected) / var;
    Some(LogRank {
        chi2,
        p: erfc((chi2 / 2.0).sqrt()).clamp(0.0, 1.0),
        observed_a: observed,
        expected_a: expected,
    })
}

/// The complementary error function erfc(x) = (2 / sqrt(pi)) int_x^inf e^{-u^2} du,
/// as the regularised upper incomplete gamma function Q(1/2, x^2) for x >= 0 (its
/// series below x^2 = 1.5, its continued fraction above; relative error below 1e-14),
/// and erfc(-x) = 2 - erfc(x). NaN for NaN.
pub fn erfc(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x < 0.0 {
        return 2.0 - erfc(-x);
    }
    if x > 27.0 {
        // erfc(27) < 1e-318: below the smallest normal f64.
        return 0.0;
    }
    let z = x * x;
    // e^{-z} z^{1/2} / Gamma(1/2) = e^{-x^2} x / sqrt(pi).
    let front = (-z).exp() * x / std::f64::consts::PI.sqrt();
    if z < 1.5 {
        // P(1/2, z) = front / (1/2) * sum_n z^n / ((3/2)(5/2)...(1/2 + n)).
        let (mut term, mut sum, mut a) = (2.0, 2.0, 0.5);
        for _ in 0..200 {
            a += 1.0;
            term *= z / a;
            sum += term;
            if term.abs() < sum.abs() * 1e-17 {
                break;
            }
        }
        1.0 - front * sum
    } else {
        // Q(1/2, z) = front / (z + 1/2 - 1 * 1/2 / (z + 5/2 - 2 * 3/2 / (z + 9/2 - ...))),
        // by the modified Lentz method.
        const TINY: f64 = 1e-300;
        let a = 0.5;
        let mut b = z + 1.0 - a;
        let mut c = 1.0 / TINY;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let i = f64::from(i);
            let an = -i * (i - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < TINY {
                d = TINY;
            }
            c = b + an / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            let step = d * c;
            h *= step;
            if (step - 1.0).abs() < 1e-15 {
                break;
            }
        }
        front * h
    }
}

/// Interquartile mean, `scipy.stats.trim_mean(xs, 0.25)` (rliable's IQM): the mean of
/// the sorted values after dropping floor(n / 4) from each end. NaN for empty input.
pub fn iqm(xs: &[f64]) -> f64 {
    if xs.is_empty() {
        return f64::NAN;
    }
    let mut v = xs.to_vec();
    v.sort_by(f64::total_cmp);
    let cut = v.len() / 4;
    let mid = &v[cut..v.len() - cut];
    mid.iter().sum::<f64>() / mid.len() as f64
}

/// Percentile bootstrap confidence interval of `stat` at confidence `level` (in
/// [0, 1], e.g. 0.95): `reps` resamples of `xs` with replacement drawn by a ChaCha8
/// generator seeded with `seed` (so the interval is a function of its arguments), and
/// the (1 - level)/2 and (1 + level)/2 quantiles of the resampled statistics, linearly
/// interpolated (numpy's default). Resamples whose statistic is NaN are dropped. `None`
/// for empty `xs`, `reps` = 0 or no non-NaN statistic.
pub fn bootstrap_ci(
    xs: &[f64],
    stat: fn(&[f64]) -> f64,
    reps: usize,
    seed: u64,
    level: f64,
) -> Option<(f64, f64)> {
    use rand::{Rng, SeedableRng};
    if xs.is_empty() || reps == 0 {
        return None;
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut sample = vec![0.0; xs.len()];
    let mut stats: Vec<f64> = (0..reps)
        .map(|_| {
            for s in sample.iter_mut() {
                *s = xs[rng.random_range(0..xs.len())];
            }
            stat(&sample)
        })
        .filter(|s| !s.is_nan())
        .collect();
    if stats.is_empty() {
        return None;
    }
    stats.sort_by(f64::total_cmp);
    let level = if level.is_nan() {
        0.0
    } else {
        level.clamp(0.0, 1.0)
    };
    Some((
        quantile(&stats, (1.0 - level) / 2.0),
        quantile(&stats, (1.0 + level) / 2.0),
    ))
}

/// The q-quantile of sorted, non-empty `v` by linear interpolation at position
/// q (n - 1); equal neighbours give exactly their value.
fn quantile(v: &[f64], q: f64) -> f64 {
    let h = q * (v.len() - 1) as f64;
    let lo = (h.floor() as usize).min(v.len() - 1);
    let hi = (lo + 1).min(v.len() - 1);
    let f = h - lo as f64;
    if v[lo] == v[hi] {
        v[lo]
    } else {
        v[lo] + (v[hi] - v[lo]) * f
    }
}

/// The Kaplan-Meier estimate of the fraction of seeds that reached the threshold by
/// each grid step g, 1 - S(g), from `(time, event)` pairs as in [`log_rank`] (NaN times
/// ignored); NaN at a NaN grid step, and everywhere when there is no seed.
pub fn solved_by(times: &[(f64, bool)], grid: &[f64]) -> Vec<f64> {
    let mut v: Vec<(f64, bool)> = times.iter().copied().filter(|(t, _)| !t.is_nan()).collect();
    if v.is_empty() {
        return vec![f64::NAN; grid.len()];
    }
    v.sort_by(|x, y| x.0.total_cmp(&y.0));
    // (event time, S just after it), ascending.
    let mut steps: Vec<(f64, f64)> = Vec::new();
    let (mut n, mut s, mut i) = (v.len() as f64, 1.0, 0);
    while i < v.len() {
        let t = v[i].0;
        let j = i + v[i..].partition_point(|x| x.0 == t);
        let d = v[i..j].iter().filter(|x| x.1).count() as f64;
        if d > 0.0 {
            s *= 1.0 - d / n;
            steps.push((t, s));
        }
        n -= (j - i) as f64;
        i = j;
    }
    grid.iter()
        .map(|&g| {
            let k = steps.partition_point(|&(t, _)| t <= g);
            if g.is_nan() {
                f64::NAN
            } else if k == 0 {
                0.0
            } else {
                1.0 - steps[k - 1].1
            }
        })
        .collect()
}

/// Holm's step-down adjustment of the p-values `ps` of one family (Holm 1979), in the
/// order given: sorted ascending, the i-th (from 0) becomes `min(1, (m - i) p)`, made
/// non-decreasing along the sorted order. NaN p-values are left NaN and not counted.
pub fn holm(ps: &[f64]) -> Vec<f64> {
    let mut order: Vec<usize> = (0..ps.len()).filter(|&i| !ps[i].is_nan()).collect();
    order.sort_by(|&a, &b| ps[a].total_cmp(&ps[b]));
    let m = order.len();
    let mut out = vec![f64::NAN; ps.len()];
    let mut running: f64 = 0.0;
    for (i, &k) in order.iter().enumerate() {
        running = running.max(((m - i) as f64 * ps[k]).min(1.0));
        out[k] = running;
    }
    out
}

/// McNemar's exact test of paired binary outcomes (two-sided): `b` pairs where only
/// the first of the two succeeded, `c` where only the second did; under the null each
/// discordant pair goes either way with probability 1/2, so
/// `p = min(1, 2 * P(X <= min(b, c)))`, X ~ Binomial(b + c, 1/2); 1 without a
/// discordant pair.
pub fn mcnemar_exact(b: usize, c: usize) -> f64 {
    let n = b + c;
    if n == 0 {
        return 1.0;
    }
    let k = b.min(c);
    // log C(n, i) - n log 2, summed in probability space.
    let ln2n = n as f64 * std::f64::consts::LN_2;
    let tail: f64 = (0..=k)
        .map(|i| {
            (ln_gamma(n as f64 + 1.0)
                - ln_gamma(i as f64 + 1.0)
                - ln_gamma((n - i) as f64 + 1.0)
                - ln2n)
                .exp()
        })
        .sum();
    (2.0 * tail).min(1.0)
}
