//! The capacity of a discrete memoryless channel, in bits.
//!
//! A channel is a set of rows W(. | x), each a distribution over the same m outputs:
//!
//! ```text
//! C = max over p(x) of I(X; Y),   I = sum_x p(x) D(W(.|x) || q),   q = sum_x p(x) W(.|x)
//! ```
//!
//! with D the Kullback-Leibler divergence in bits. Only distinct rows matter (an input
//! twice is one input), and so [`capacity`] merges equal rows first. Two cases:
//!
//! - **two outputs**: a row is one number w = W(1 | x), and a row between two others is
//!   a mixture of them, which never raises I; the capacity is that of the binary channel
//!   of the smallest and largest w, a and b, in closed form ([`binary_capacity`]):
//!   with K = (h(b) - h(a)) / (b - a), h the binary entropy in bits,
//!   C = log2(1 + 2^-K) + a K - h(a). (a = 0, b = p is the Z-channel,
//!   log2(1 + p (1 - p)^((1 - p) / p)); a = e, b = 1 - e the symmetric one, 1 - h(e).)
//! - **more outputs**: Blahut-Arimoto ([`blahut_arimoto`]) from the uniform input,
//!   p(x) <- p(x) 2^{D(W(.|x) || q)} / Z, all in base 2. Each iterate gives the bounds
//!   `log2 Z <= C <= max_x D(W(.|x) || q)`, Z = sum_x p(x) 2^{D(W(.|x) || q)}; it stops
//!   when they are within [`GAP_BITS`] and reports the lower bound with the gap. Since
//!   the bounds hold for any p, the steps grow longer (exponent mu D, mu up to 8) while
//!   the lower bound rises, and return to the plain step when it falls.
//!
//! Shapes: `rows` is n rows of m probabilities, row-major in one slice.

/// Blahut-Arimoto stops once its upper and lower bounds are this close (bits).
pub const GAP_BITS: f64 = 1e-9;

/// How much [`blahut_arimoto`] lengthens its step after each step that raised the lower
/// bound (a step of 1 is the plain algorithm).
const ACCELERATION: f64 = 1.25;

/// The longest step [`blahut_arimoto`] takes.
const MAX_STEP: f64 = 8.0;

/// Iterations Blahut-Arimoto may take before it reports the gap it has reached.
pub const MAX_ITERATIONS: usize = 1_000_000;

/// A channel capacity: the value (a lower bound) and how far above it the capacity may
/// lie (0 where the value is exact).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Capacity {
    /// Bits.
    pub bits: f64,
    /// The capacity lies in `[bits, bits + gap]`.
    pub gap: f64,
}

/// The binary entropy in bits.
pub fn binary_entropy(p: f64) -> f64 {
    let t = |x: f64| if x <= 0.0 { 0.0 } else { -x * x.log2() };
    t(p) + t(1.0 - p)
}

/// The capacity of the binary channel with W(1 | 0) = a and W(1 | 1) = b, exact
/// (closed form; the module doc).
pub fn binary_capacity(a: f64, b: f64) -> f64 {
    let (a, b) = (a.min(b), a.max(b));
    if b - a <= 1e-15 {
        return 0.0;
    }
    // Mirror so that a is the side further from 1/2's far end: the form is symmetric
    // under w -> 1 - w, and the smaller a keeps 2^-K in range.
    let (a, b) = if a > 1.0 - b {
        (1.0 - b, 1.0 - a)
    } else {
        (a, b)
    };
    let k = (binary_entropy(b) - binary_entropy(a)) / (b - a);
    let c = (-k).exp2().ln_1p() / std::f64::consts::LN_2 + a * k - binary_entropy(a);
    c.max(0.0)
}

/// Blahut-Arimoto on `n` rows of `m` outputs (`rows.len() == n * m`): the lower bound
/// and the gap to the upper bound when they are within `tol` bits (or after
/// [`MAX_ITERATIONS`]).
pub fn blahut_arimoto(rows: &[f64], m: usize, tol: f64) -> Capacity {
    let n = rows.len() / m.max(1);
    if n <= 1 || m <= 1 {
        return Capacity::default();
    }
    // Sparse rows, and each row's sum of w log2 w, so that an iteration takes m
    // logarithms: D(W_x || q) = sum_y w log2 w - sum_y w log2 q(y).
    let mut start = Vec::with_capacity(n + 1);
    let mut ys: Vec<u32> = Vec::new();
    let mut ws: Vec<f64> = Vec::new();
    let mut neg_h = Vec::with_capacity(n);
    start.push(0);
    for row in rows.chunks_exact(m) {
        let mut t = 0.0;
        for (y, &w) in row.iter().enumerate() {
            if w > 0.0 {
                ys.push(y as u32);
                ws.push(w);
                t += w * w.log2();
            }
        }
        neg_h.push(t);
        start.push(ys.len());
    }
    let mut p = vec![1.0 / n as f64; n];
    let mut q = vec![0.0; m];
    let mut d = vec![0.0; n];
    let mut best = Capacity {
        bits: 0.0,
        gap: f64::INFINITY,
    };
    let mut mu = 1.0;
    let mut last_lower = f64::NEG_INFINITY;
    for _ in 0..MAX_ITERATIONS {
        q.fill(0.0);
        for x in 0..n {
            for k in start[x]..start[x + 1] {
                q[ys[k] as usize] += p[x] * ws[k];
            }
        }
        // Every q(y) a row reaches is positive: p stays above 0 (floored below).
        q.iter_mut()
            .for_each(|v| *v = v.max(f64::MIN_POSITIVE).log2());
        let mut upper = f64::NEG_INFINITY;
        let mut z = 0.0;
        for x in 0..n {
            let mut dx = neg_h[x];
            for k in start[x]..start[x + 1] {
                dx -= ws[k] * q[ys[k] as usize];
            }
            let dx = dx.max(0.0);
            d[x] = dx;
            upper = upper.max(dx);
            z += p[x] * dx.exp2();
        }
        let lower = z.log2().max(0.0);
        let gap = (upper - lower).max(0.0);
        if gap < best.gap {
            best = Capacity { bits: lower, gap };
        }
        if gap < tol {
            break;
        }
        // The bounds hold for any input distribution, so the step may be longer than
        // Blahut-Arimoto's: p <- p 2^{mu D} / Z, mu growing while the lower bound rises
        // and back to 1 (the plain, monotone iteration) when it falls.
        mu = if lower >= last_lower {
            (mu * ACCELERATION).min(MAX_STEP)
        } else {
            1.0
        };
        last_lower = lower;
        let mut zmu = 0.0;
        for (px, &dx) in p.iter_mut().zip(&d) {
            *px *= (mu * (dx - upper)).exp2();
            zmu += *px;
        }
        p.iter_mut().for_each(|px| *px = (*px / zmu).max(1e-280));
    }
    best
}

/// The capacity of the channel whose rows are `rows` (`n x m`, row-major): equal rows
/// merged, outputs no row reaches dropped, the closed form for two outputs, else
/// Blahut-Arimoto to [`GAP_BITS`].
pub fn capacity(rows: &[f64], m: usize) -> Capacity {
    if m == 0 || rows.is_empty() {
        return Capacity::default();
    }
    let used: Vec<usize> = (0..m)
        .filter(|&y| rows.chunks_exact(m).any(|r| r[y] > 0.0))
        .collect();
    match used.len() {
        0 | 1 => return Capacity::default(),
        2 => {
            let (lo, hi) = rows
                .chunks_exact(m)
                .map(|r| {
                    let (a, b) = (r[used[0]], r[used[1]]);
                    b / (a + b)
                })
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), w| {
                    (lo.min(w), hi.max(w))
                });
            return Capacity {
                bits: binary_capacity(lo, hi),
                gap: 0.0,
            };
        }
        _ => {}
    }
    let mut seen = std::collections::HashSet::new();
    let mut kept = Vec::new();
    for r in rows.chunks_exact(m) {
        let key: Vec<u64> = used.iter().map(|&y| r[y].to_bits()).collect();
        if seen.insert(key) {
            kept.extend(used.iter().map(|&y| r[y]));
        }
    }
    blahut_arimoto(&kept, used.len(), GAP_BITS)
}

#[cfg(test)]
mod tests {
    use super::*;

    // The symmetric channel with flip e has C = 1 - h(e); h(0.1) = 0.468996 (by hand:
    // -0.1 log2 0.1 - 0.9 log2 0.9 = 0.332193 + 0.136803), so C = 0.531004.
    #[test]
    fn symmetric_channel_by_both_routes() {
        let rows = [0.9, 0.1, 0.1, 0.9];
        let ba = blahut_arimoto(&rows, 2, GAP_BITS);
        assert!((ba.bits - 0.531004).abs() < 1e-6, "{ba:?}");
        assert!(ba.gap < GAP_BITS);
        assert!((binary_capacity(0.1, 0.9) - 0.531004).abs() < 1e-6);
        assert!((capacity(&rows, 2).bits - 0.531004).abs() < 1e-6);
    }
}
