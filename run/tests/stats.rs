//! The aggregation behind `fulcrum experiment`, on synthetic curves whose mean, standard
//! deviation, steps to threshold and area are counted by hand below, and Welch's test
//! against closed forms of Student's t distribution.

use fulcrum_run::stats::{
    area, band, final_rates, grid, incomplete_beta, interpolate, ln_gamma, mean_std, smooth,
    steps_to, welch, Point,
};

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + b.abs())
}

/// 10 updates of 100 steps, 10 episodes each, success `f(i)` at update i = 1..=10.
fn run(f: impl Fn(f64) -> f64) -> Vec<Point> {
    (1..=10)
        .map(|i| {
            let i = f64::from(i);
            Point {
                steps: 100.0 * i,
                episodes: 10.0,
                success: f(i),
                ret: 2.0 * f(i),
            }
        })
        .collect()
}

/// Seed A: i/10; seed B: min(1, 2i/10); seed C: 0.
fn seeds() -> [Vec<Point>; 3] {
    [
        run(|i| i / 10.0),
        run(|i| (2.0 * i / 10.0).min(1.0)),
        run(|_| 0.0),
    ]
}

fn curve(points: &[Point], g: &[f64]) -> Vec<f64> {
    let xy: Vec<(f64, f64)> = smooth(points, 1).iter().map(|&(x, s, _)| (x, s)).collect();
    interpolate(&xy, g)
}

#[test]
fn steps_to_threshold_is_the_first_update_at_or_above_it() {
    let [a, b, c] = seeds();
    let t = |p: &[Point]| steps_to(&smooth(p, 1), 0.9);
    // A reaches 0.9 at update 9, B reaches 1.0 at update 5 (0.8 at update 4), C never.
    assert_eq!(t(&a), Some(900.0));
    assert_eq!(t(&b), Some(500.0));
    assert_eq!(t(&c), None);
}

#[test]
fn smoothing_pools_episodes_not_updates() {
    let p = [
        Point {
            steps: 100.0,
            episodes: 1.0,
            success: 1.0,
            ret: 1.0,
        },
        Point {
            steps: 200.0,
            episodes: 3.0,
            success: 0.0,
            ret: 0.0,
        },
        Point {
            steps: 300.0,
            episodes: 0.0,
            success: f64::NAN,
            ret: f64::NAN,
        },
    ];
    let s = smooth(&p, 2);
    // (1*1 + 0*3) / 4 = 0.25, not the mean of rates 0.5.
    assert!(close(s[1].1, 0.25, 1e-12));
    // Window (update 2, update 3): update 3 finished nothing, so it is update 2 alone.
    assert!(close(s[2].1, 0.0, 1e-12));
    let raw = smooth(&p, 1);
    assert!(raw[2].1.is_nan(), "an update without episodes has no rate");
    // Pooled over all three updates: 1 success in 4 episodes.
    assert!(close(smooth(&p, 3)[2].1, 0.25, 1e-12));
}

#[test]
fn the_band_is_the_mean_and_sample_std_over_seeds_on_a_common_grid() {
    let [a, b, c] = seeds();
    let g = grid(1000.0, 10);
    assert_eq!(g.len(), 11);
    let curves = vec![curve(&a, &g), curve(&b, &g), curve(&c, &g)];
    // At g = 0 each seed holds its first value: A 0.1, B 0.2, C 0.
    assert!(close(curves[0][0], 0.1, 1e-12));
    assert!(close(curves[1][0], 0.2, 1e-12));
    let m = band(&curves);
    // At 300: values 0.3, 0.6, 0 -> mean 0.3; deviations 0, 0.3, -0.3 -> ss 0.18 / 2 -> std 0.3.
    assert!(close(m[3].0, 0.3, 1e-12));
    assert!(close(m[3].1, 0.3, 1e-12));
    // At 1000: 1, 1, 0 -> mean 2/3; ss = 2 (1/3)^2 + (2/3)^2 = 2/3, / 2 -> std sqrt(1/3).
    assert!(close(m[10].0, 2.0 / 3.0, 1e-12));
    assert!(close(m[10].1, (1.0f64 / 3.0).sqrt(), 1e-12));
    // Between updates the curve is linear: at 150, A = 0.15 and B = 0.3.
    let fine = grid(1000.0, 20);
    assert!(close(curve(&a, &fine)[3], 0.15, 1e-12));
    assert!(close(curve(&b, &fine)[3], 0.3, 1e-12));
    // One seed: std 0; nothing finite: NaN.
    assert_eq!(mean_std(&[0.4]), (0.4, 0.0));
    assert!(mean_std(&[f64::NAN]).0.is_nan());
}

#[test]
fn interpolation_skips_missing_rates_and_holds_the_ends() {
    let xy = [
        (100.0, f64::NAN),
        (200.0, 0.2),
        (300.0, f64::NAN),
        (400.0, 0.6),
    ];
    let v = interpolate(&xy, &[0.0, 250.0, 300.0, 500.0]);
    assert_eq!(v[0], 0.2);
    assert!(close(v[1], 0.3, 1e-12));
    assert!(close(v[2], 0.4, 1e-12));
    assert_eq!(v[3], 0.6);
    assert!(interpolate(&[(1.0, f64::NAN)], &[0.0])[0].is_nan());
}

#[test]
fn area_and_final_rates() {
    let [a, _, c] = seeds();
    let g = grid(1000.0, 10);
    // Segment 0..100 at 0.1: 10; segments k..k+1 (k = 1..9): (2k + 1) * 5, sum 495.
    assert!(close(area(&g, &curve(&a, &g)), 505.0 / 1000.0, 1e-12));
    assert_eq!(area(&g, &curve(&c, &g)), 0.0);
    // The last 20 % of A's updates: 0.9 and 1.0 with 10 episodes each.
    let (s, r) = final_rates(&a, 0.2);
    assert!(close(s, 0.95, 1e-12));
    assert!(close(r, 1.9, 1e-12));
}

#[test]
fn gamma_and_incomplete_beta_match_closed_forms() {
    assert!(close(ln_gamma(5.0), 24f64.ln(), 1e-13));
    assert!(close(
        ln_gamma(0.5),
        std::f64::consts::PI.sqrt().ln(),
        1e-13
    ));
    // Gamma(10.5) = 19!! / 2^10 * sqrt(pi) = 654729075 / 1024 * sqrt(pi).
    let g = 654_729_075.0 / 1024.0 * std::f64::consts::PI.sqrt();
    assert!(close(ln_gamma(10.5), f64::ln(g), 1e-13));
    for x in [0.01, 0.3, 0.5, 0.77, 0.99] {
        assert!(close(incomplete_beta(1.0, 1.0, x), x, 1e-12));
        assert!(close(incomplete_beta(3.0, 1.0, x), x * x * x, 1e-12));
        assert!(close(
            incomplete_beta(1.0, 2.0, x),
            1.0 - (1.0 - x) * (1.0 - x),
            1e-12
        ));
    }
    assert!(close(incomplete_beta(7.5, 7.5, 0.5), 0.5, 1e-12));
    // Student's t with 10 df: the two-sided 5 % point is 2.2281388519649 (tables).
    let (df, t) = (10.0, 2.228_138_851_964_9);
    assert!(close(
        incomplete_beta(df / 2.0, 0.5, df / (df + t * t)),
        0.05,
        1e-9
    ));
}

#[test]
fn welch_matches_students_t_in_closed_form() {
    // Equal sizes 2 and equal variances 2: df = 2, t = (1 - 4) / sqrt(2/2 + 2/2).
    // With 2 df, P(|T| >= |t|) = 1 - |t| / sqrt(2 + t^2).
    let w = welch(&[0.0, 2.0], &[3.0, 5.0]).unwrap();
    let t = -3.0 / 2f64.sqrt();
    assert!(close(w.t, t, 1e-12));
    assert!(close(w.df, 2.0, 1e-12));
    assert!(close(w.p, 1.0 - t.abs() / (2.0 + t * t).sqrt(), 1e-10));
    // One sample without variance: df = 1 (Cauchy), t = (0 - 2) / sqrt(0 + 2/2) = -2,
    // P(|T| >= 2) = 1 - (2 / pi) atan 2.
    let w = welch(&[0.0, 0.0], &[1.0, 3.0]).unwrap();
    assert!(close(w.t, -2.0, 1e-12));
    assert!(close(w.df, 1.0, 1e-12));
    let p = 1.0 - 2.0 / std::f64::consts::PI * 2f64.atan();
    assert!(close(w.p, p, 1e-10));
    // Degenerate and too small samples.
    assert_eq!(welch(&[1.0, 1.0], &[1.0, 1.0]).unwrap().p, 1.0);
    assert_eq!(welch(&[1.0, 1.0], &[2.0, 2.0]).unwrap().p, 0.0);
    assert!(welch(&[1.0], &[2.0, 3.0]).is_none());
}
