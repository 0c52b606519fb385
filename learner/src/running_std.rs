//! The running scale of the intrinsic reward (two value heads): the intrinsic reward
//! is divided by the standard deviation of every value seen so far.

/// A running mean and variance over every value seen so far (Chan et al.'s merge of
/// batch moments into the running ones), for the intrinsic reward's scale.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RunningStd {
    /// Values seen.
    pub count: f64,
    /// Their mean.
    pub mean: f64,
    /// Sum of squared deviations from the mean.
    pub m2: f64,
}

impl RunningStd {
    /// Merge a batch of values.
    pub fn update(&mut self, xs: &[f32]) {
        if xs.is_empty() {
            return;
        }
        let n = xs.len() as f64;
        let mean = xs.iter().map(|&x| x as f64).sum::<f64>() / n;
        let m2: f64 = xs.iter().map(|&x| (x as f64 - mean).powi(2)).sum();
        let total = self.count + n;
        let delta = mean - self.mean;
        self.mean += delta * n / total;
        self.m2 += m2 + delta * delta * self.count * n / total;
        self.count = total;
    }

    /// The population standard deviation (0 before any value).
    pub fn std(&self) -> f64 {
        if self.count > 0.0 {
            (self.m2 / self.count).sqrt()
        } else {
            0.0
        }
    }
}
