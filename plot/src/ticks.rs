//! Numbers on axes and in cells: finite values, tick steps, decimals.

/// `v` if finite.
pub(crate) fn finite(v: Option<f64>) -> Option<f64> {
    v.filter(|x| x.is_finite())
}

/// Number of decimals that shows multiples of `step` exactly (0..=6).
pub(crate) fn decimals_for(step: f64) -> usize {
    if !step.is_finite() || step <= 0.0 {
        return 2;
    }
    (0..=6)
        .find(|&d| {
            let s = step * 10f64.powi(d as i32);
            (s - s.round()).abs() < 1e-6 * s.abs().max(1.0)
        })
        .unwrap_or(6)
}

/// `v` with `decimals` decimals, or in scientific notation when it is very large.
pub(crate) fn format_value(v: f64, decimals: usize) -> String {
    if v.abs() >= 1e6 {
        format!("{v:.2e}")
    } else {
        let s = format!("{v:.decimals$}");
        // Avoid "-0.00".
        if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
            s[1..].to_string()
        } else {
            s
        }
    }
}

/// Decimals printed inside a heatmap cell: 2, fewer for large values so they fit.
pub(crate) fn cell_decimals(v: f64) -> usize {
    match v.abs() {
        a if a < 100.0 => 2,
        a if a < 1000.0 => 1,
        _ => 0,
    }
}

/// "Nice" ticks (steps of 1, 2, 2.5 or 5 times a power of ten) in [lo, hi].
pub(crate) fn nice_ticks(lo: f64, hi: f64, max_ticks: usize) -> (Vec<f64>, f64) {
    let span = hi - lo;
    if !span.is_finite() || span <= 0.0 || max_ticks < 2 {
        return (if lo.is_finite() { vec![lo] } else { vec![] }, 1.0);
    }
    let raw = span / (max_ticks - 1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw * (1.0 - 1e-9))
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil();
    let ticks = (0..=max_ticks * 3)
        .map(|i| (first + i as f64) * step)
        .take_while(|v| *v <= hi + step * 1e-9)
        .collect();
    (ticks, step)
}
