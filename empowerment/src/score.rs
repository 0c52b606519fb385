//! Scoring estimates of empowerment against the exact values of a dataset.
//!
//! For estimates `x_i` of true values `y_i` (bits), `i = 1..n`:
//!
//! ```text
//! mae      = (1/n) sum |x_i - y_i|
//! bias     = (1/n) sum (x_i - y_i)          (below 0: the estimates are low)
//! rmse     = sqrt((1/n) sum (x_i - y_i)^2)
//! spearman = Pearson correlation of the ranks of x and of y, tied values sharing
//!            the mean of their ranks (undefined where either side is constant)
//! ```
//!
//! and the same by bins of the true value one bit wide (`[b, b + 1)`, b = floor(y)) and by
//! horizon.

/// Error of a group of estimates.
#[derive(Clone, Debug, PartialEq)]
pub struct Errors {
    /// Estimates in the group.
    pub n: usize,
    /// Mean absolute error, bits.
    pub mae: f64,
    /// Mean signed error, bits.
    pub bias: f64,
    /// Root mean squared error, bits.
    pub rmse: f64,
    /// Spearman's rank correlation; None where x or y is constant.
    pub spearman: Option<f64>,
}

/// The errors of one true-value bin.
#[derive(Clone, Debug, PartialEq)]
pub struct Bin {
    /// The bin's lower edge (bits); it holds true values in `[lo, lo + 1)`.
    pub lo: f64,
    /// Its errors.
    pub errors: Errors,
}

/// A score: overall, by true-value bin, by horizon.
#[derive(Clone, Debug, PartialEq)]
pub struct Score {
    /// Over every estimate.
    pub all: Errors,
    /// By bins of the true value, ascending.
    pub by_bin: Vec<Bin>,
    /// By horizon, ascending.
    pub by_horizon: Vec<(u32, Errors)>,
}

/// Ranks 1..n, ties given the mean of the ranks they span.
pub fn ranks(v: &[f64]) -> Vec<f64> {
    let mut order: Vec<usize> = (0..v.len()).collect();
    order.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
    let mut r = vec![0.0; v.len()];
    let mut i = 0;
    while i < order.len() {
        let mut j = i;
        while j + 1 < order.len() && v[order[j + 1]] == v[order[i]] {
            j += 1;
        }
        let mean = (i + j) as f64 / 2.0 + 1.0;
        for &k in &order[i..=j] {
            r[k] = mean;
        }
        i = j + 1;
    }
    r
}

fn pearson(x: &[f64], y: &[f64]) -> Option<f64> {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
        syy += (b - my) * (b - my);
    }
    (sxx > 0.0 && syy > 0.0).then(|| sxy / (sxx * syy).sqrt())
}

/// The errors of estimates `x` of `y` (equal lengths, at least one).
pub fn errors(x: &[f64], y: &[f64]) -> Errors {
    let n = x.len();
    let d: Vec<f64> = x.iter().zip(y).map(|(a, b)| a - b).collect();
    let nf = n as f64;
    Errors {
        n,
        mae: d.iter().map(|e| e.abs()).sum::<f64>() / nf,
        bias: d.iter().sum::<f64>() / nf,
        rmse: (d.iter().map(|e| e * e).sum::<f64>() / nf).sqrt(),
        spearman: if n < 2 {
            None
        } else {
            pearson(&ranks(x), &ranks(y))
        },
    }
}

/// Score estimates against a dataset's true values and horizons (equal lengths).
pub fn score(estimates: &[f64], truth: &[f64], horizon: &[u32]) -> Result<Score, String> {
    if estimates.len() != truth.len() || truth.len() != horizon.len() {
        return Err(format!(
            "{} estimates for a dataset of {} states",
            estimates.len(),
            truth.len()
        ));
    }
    if truth.is_empty() {
        return Err("no estimates to score".into());
    }
    if let Some(i) = estimates.iter().position(|x| !x.is_finite()) {
        return Err(format!(
            "estimate {i} is {}: every estimate must be a finite number of bits",
            estimates[i]
        ));
    }
    let group = |keep: &dyn Fn(usize) -> bool| {
        let idx: Vec<usize> = (0..truth.len()).filter(|&i| keep(i)).collect();
        let x: Vec<f64> = idx.iter().map(|&i| estimates[i]).collect();
        let y: Vec<f64> = idx.iter().map(|&i| truth[i]).collect();
        errors(&x, &y)
    };
    let mut bins: Vec<f64> = truth.iter().map(|y| y.floor()).collect();
    bins.sort_by(f64::total_cmp);
    bins.dedup();
    let mut hs = horizon.to_vec();
    hs.sort_unstable();
    hs.dedup();
    Ok(Score {
        all: errors(estimates, truth),
        by_bin: bins
            .iter()
            .map(|&lo| Bin {
                lo,
                errors: group(&|i| truth[i].floor() == lo),
            })
            .collect(),
        by_horizon: hs
            .iter()
            .map(|&h| (h, group(&|i| horizon[i] == h)))
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Five states, counted by hand. Truth y = [0, 1, 1, 2, 3] (ranks 1, 2.5, 2.5, 4, 5),
    /// estimates x = [0.5, 1, 0.5, 2, 2] (sorted 0.5, 0.5, 1, 2, 2: ranks
    /// [1.5, 3, 1.5, 4.5, 4.5]).
    /// Errors x - y = [0.5, 0, -0.5, 0, -1]: mae 2/5 = 0.4, bias -1/5 = -0.2,
    /// rmse sqrt(1.5/5). Spearman: rank deviations from 3 are
    /// rx = [-1.5, 0, -1.5, 1.5, 1.5], ry = [-2, -0.5, -0.5, 1, 2];
    /// sum rx ry = 3 + 0 + 0.75 + 1.5 + 3 = 8.25, sum rx^2 = 9, sum ry^2 = 9.5,
    /// rho = 8.25 / sqrt(85.5) = 0.892218...
    #[test]
    fn five_states_by_hand() {
        let y = [0.0, 1.0, 1.0, 2.0, 3.0];
        let x = [0.5, 1.0, 0.5, 2.0, 2.0];
        assert_eq!(ranks(&x), vec![1.5, 3.0, 1.5, 4.5, 4.5]);
        assert_eq!(ranks(&y), vec![1.0, 2.5, 2.5, 4.0, 5.0]);
        let s = score(&x, &y, &[1, 1, 3, 3, 3]).unwrap();
        assert!((s.all.mae - 0.4).abs() < 1e-12);
        assert!((s.all.bias + 0.2).abs() < 1e-12);
        assert!((s.all.rmse - (0.3f64).sqrt()).abs() < 1e-12);
        assert!((s.all.spearman.unwrap() - 8.25 / 85.5f64.sqrt()).abs() < 1e-12);
        // Bins [0,1): state 0; [1,2): states 1, 2; [2,3): 3; [3,4): 4.
        let lo: Vec<f64> = s.by_bin.iter().map(|b| b.lo).collect();
        assert_eq!(lo, vec![0.0, 1.0, 2.0, 3.0]);
        assert_eq!(s.by_bin[1].errors.n, 2);
        assert!((s.by_bin[1].errors.mae - 0.25).abs() < 1e-12);
        assert!((s.by_bin[1].errors.bias + 0.25).abs() < 1e-12);
        assert_eq!(s.by_bin[1].errors.spearman, None); // the truth is constant there
                                                       // h = 1: states 0, 1 (errors 0.5, 0); h = 3: states 2, 3, 4 (-0.5, 0, -1).
        assert_eq!(s.by_horizon[0].0, 1);
        assert!((s.by_horizon[0].1.bias - 0.25).abs() < 1e-12);
        assert!((s.by_horizon[1].1.mae - 0.5).abs() < 1e-12);
    }

    #[test]
    fn refusals() {
        assert!(score(&[1.0], &[1.0, 2.0], &[1, 1]).is_err());
        assert!(score(&[f64::NAN], &[1.0], &[1])
            .unwrap_err()
            .contains("estimate 0 is NaN"));
    }
}
