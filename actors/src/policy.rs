//! The actor's policy: the learner's network evaluated on plain f32 buffers.
//!
//! Same math as `fulcrum_learner::net::Net::forward` (see its docs), one sample at a
//! time, from the flat weights the learner publishes (the layout of
//! [`fulcrum_contracts::layout`]):
//!
//! ```text
//! z1     = b1 + sum_c E[c * G + glyph_c] + flags @ Wf      (H)
//! h2     = relu( relu(z1) @ W2 + b2 )                       (H)
//! logits = h2 @ Wp + bp                                     (|A|)
//! value  = h2 @ Wv + bv                                     (1)
//! ```
//!
//! A step of M worlds costs M * (C + F + H + |A| + 1) * H multiply-adds and no
//! allocation: on the paper's worlds a few microseconds per world, against tens of
//! microseconds per candle op of the batched tensor path (measured in `fulcrum bench`).

use fulcrum_contracts::layout::{NetShape, Offsets};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// A policy evaluated without candle.
#[derive(Debug, Clone)]
pub struct Policy {
    shape: NetShape,
    off: Offsets,
    w: Vec<f32>,
    z1: Vec<f32>,
    h2: Vec<f32>,
    logits: Vec<f32>,
    masked: bool,
    /// The intrinsic value of the last observation evaluated (intrinsic head only).
    value_int: f32,
}

impl Policy {
    /// A policy with zero weights (set them with [`Policy::set`]).
    pub fn new(shape: NetShape) -> Policy {
        let off = Offsets::new(shape);
        Policy {
            shape,
            off,
            w: vec![0.0; off.len],
            z1: vec![0.0; shape.hidden],
            h2: vec![0.0; shape.hidden],
            logits: vec![0.0; shape.actions],
            masked: false,
            value_int: 0.0,
        }
    }

    /// Sample only the actions that [`fulcrum_world::mask::action_mask`] allows in each
    /// observation (masked logits count as -inf: probability 0, never drawn).
    pub fn with_action_mask(mut self, on: bool) -> Policy {
        self.masked = on;
        self
    }

    /// Floats the weights take.
    pub fn len(&self) -> usize {
        self.off.len
    }

    /// Whether the network has no weights (never for a real shape).
    pub fn is_empty(&self) -> bool {
        self.off.len == 0
    }

    /// Take new flat weights (must be [`Policy::len`] floats).
    pub fn set(&mut self, flat: &[f32]) -> bool {
        if flat.len() != self.w.len() {
            return false;
        }
        self.w.copy_from_slice(flat);
        true
    }

    /// Evaluate one observation: fills the logits and returns the value.
    fn eval(&mut self, glyphs: &[u8], flags: &[u8]) -> f32 {
        let NetShape {
            glyphs: g,
            hidden: h,
            actions: a,
            ..
        } = self.shape;
        let o = self.off;
        let w = &self.w;
        let z1 = &mut self.z1;
        z1.copy_from_slice(&w[o.b1..o.b1 + h]);
        for (c, &gl) in glyphs.iter().enumerate() {
            let r = o.embed + (c * g + gl as usize) * h;
            for (z, e) in z1.iter_mut().zip(&w[r..r + h]) {
                *z += e;
            }
        }
        for (k, &fl) in flags.iter().enumerate() {
            if fl != 0 {
                let r = o.wf + k * h;
                let x = fl as f32;
                for (z, e) in z1.iter_mut().zip(&w[r..r + h]) {
                    *z += x * e;
                }
            }
        }
        let h2 = &mut self.h2;
        h2.copy_from_slice(&w[o.b2..o.b2 + h]);
        for (i, &zi) in z1.iter().enumerate() {
            let x = zi.max(0.0);
            if x != 0.0 {
                let r = o.w2 + i * h;
                for (y, e) in h2.iter_mut().zip(&w[r..r + h]) {
                    *y += x * e;
                }
            }
        }
        for y in h2.iter_mut() {
            *y = y.max(0.0);
        }
        let logits = &mut self.logits;
        logits.copy_from_slice(&w[o.bp..o.bp + a]);
        let mut value = w[o.bv];
        for (i, &x) in h2.iter().enumerate() {
            if x != 0.0 {
                let r = o.wp + i * a;
                for (l, e) in logits.iter_mut().zip(&w[r..r + a]) {
                    *l += x * e;
                }
                value += x * w[o.wv + i];
            }
        }
        if self.shape.int_value {
            let mut vi = w[o.bvi];
            for (i, &x) in h2.iter().enumerate() {
                if x != 0.0 {
                    vi += x * w[o.wvi + i];
                }
            }
            self.value_int = vi;
        }
        value
    }

    /// Value of each of `n` observations.
    pub fn values(&mut self, glyphs: &[u8], flags: &[u8], out: &mut [f32]) {
        self.values_all(glyphs, flags, out, &mut []);
    }

    /// Values of each of `out.len()` observations, and their intrinsic values into
    /// `out_int` when it is not empty (intrinsic value head).
    pub fn values_all(
        &mut self,
        glyphs: &[u8],
        flags: &[u8],
        out: &mut [f32],
        out_int: &mut [f32],
    ) {
        let (c, f) = (self.shape.cells, self.shape.flags);
        for i in 0..out.len() {
            out[i] = self.eval(&glyphs[i * c..(i + 1) * c], &flags[i * f..(i + 1) * f]);
            if let Some(v) = out_int.get_mut(i) {
                *v = self.value_int;
            }
        }
    }

    /// The most probable allowed action of one observation (ties to the lower index):
    /// the greedy policy of evaluation.
    pub fn greedy(&mut self, glyphs: &[u8], flags: &[u8]) -> u8 {
        self.eval(glyphs, flags);
        let mask = if self.masked {
            fulcrum_world::mask::action_mask(flags)
        } else {
            u32::MAX
        };
        let mut best: Option<(usize, f32)> = None;
        for (k, &l) in self.logits.iter().enumerate() {
            if mask >> k & 1 == 1 && best.is_none_or(|(_, b)| l > b) {
                best = Some((k, l));
            }
        }
        best.map_or(0, |(k, _)| k as u8)
    }

    /// Sample an action for each of the `actions.len()` observations: log pi(a) and V.
    pub fn act(
        &mut self,
        glyphs: &[u8],
        flags: &[u8],
        rng: &mut ChaCha8Rng,
        actions: &mut [u8],
        logprobs: &mut [f32],
        values: &mut [f32],
    ) {
        self.act_all(glyphs, flags, rng, actions, logprobs, values, &mut []);
    }

    /// [`Policy::act`], and the intrinsic values into `values_int` when it is not empty.
    #[allow(clippy::too_many_arguments)]
    pub fn act_all(
        &mut self,
        glyphs: &[u8],
        flags: &[u8],
        rng: &mut ChaCha8Rng,
        actions: &mut [u8],
        logprobs: &mut [f32],
        values: &mut [f32],
        values_int: &mut [f32],
    ) {
        let (c, f) = (self.shape.cells, self.shape.flags);
        for i in 0..actions.len() {
            let fl = &flags[i * f..(i + 1) * f];
            values[i] = self.eval(&glyphs[i * c..(i + 1) * c], fl);
            if let Some(v) = values_int.get_mut(i) {
                *v = self.value_int;
            }
            let mask = if self.masked {
                fulcrum_world::mask::action_mask(fl)
            } else {
                u32::MAX
            };
            let allowed = |k: usize| mask >> k & 1 == 1;
            // log-softmax over the allowed actions, then inverse-CDF sampling with one
            // uniform draw.
            let max = self
                .logits
                .iter()
                .enumerate()
                .filter(|(k, _)| allowed(*k))
                .fold(f32::NEG_INFINITY, |m, (_, &l)| m.max(l));
            let lse = max
                + self
                    .logits
                    .iter()
                    .enumerate()
                    .filter(|(k, _)| allowed(*k))
                    .map(|(_, l)| (l - max).exp())
                    .sum::<f32>()
                    .ln();
            let u: f32 = rng.random();
            let mut acc = 0.0;
            let mut pick = (0..self.logits.len())
                .rev()
                .find(|&k| allowed(k))
                .unwrap_or(0);
            for (k, l) in self.logits.iter().enumerate() {
                if !allowed(k) {
                    continue;
                }
                acc += (l - lse).exp();
                if u < acc {
                    pick = k;
                    break;
                }
            }
            actions[i] = pick as u8;
            logprobs[i] = self.logits[pick] - lse;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;
    use fulcrum_learner::net::{log_softmax, Net};

    /// The plain evaluation equals candle's forward pass of the same weights.
    /// A network of `shape` with every weight nudged (nonzero biases, so that every
    /// parameter matters), the same weights in a [`Policy`], and `n` observations.
    pub(super) fn fixture(shape: NetShape, seed: u64, n: usize) -> (Net, Policy, Vec<u8>, Vec<u8>) {
        let net = Net::new(shape, seed, &Device::Cpu).unwrap();
        let mut flat = net.flat().unwrap();
        for (i, x) in flat.iter_mut().enumerate() {
            *x += ((i * 7919) % 13) as f32 * 0.01 - 0.06;
        }
        net.set_flat(&flat).unwrap();
        let mut p = Policy::new(shape);
        assert!(p.set(&flat));
        let c = shape.cells;
        let glyphs: Vec<u8> = (0..n * c)
            .map(|i| ((i * 5 + i / c) % shape.glyphs) as u8)
            .collect();
        let flags: Vec<u8> = (0..n * shape.flags).map(|i| (i % 3 == 0) as u8).collect();
        (net, p, glyphs, flags)
    }

    #[test]
    fn equals_the_candle_network() {
        let shape = NetShape {
            cells: 12,
            glyphs: 11,
            flags: 5,
            hidden: 16,
            actions: 7,
            int_value: false,
        };
        let n = 9;
        let (net, mut p, glyphs, flags) = fixture(shape, 3, n);
        let (logits, value) = net.forward(&net.batch(&glyphs, &flags).unwrap()).unwrap();
        let lp = log_softmax(&logits).unwrap().to_vec2::<f32>().unwrap();
        let v: Vec<f32> = value.to_vec1().unwrap();
        let mut vals = vec![0.0; n];
        p.values(&glyphs, &flags, &mut vals);
        for i in 0..n {
            assert!((vals[i] - v[i]).abs() < 1e-4, "{} vs {}", vals[i], v[i]);
        }
        let mut rng = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(5);
        let (mut a, mut l, mut vv) = (vec![0u8; n], vec![0.0; n], vec![0.0; n]);
        p.act(&glyphs, &flags, &mut rng, &mut a, &mut l, &mut vv);
        for i in 0..n {
            assert!((l[i] - lp[i][a[i] as usize]).abs() < 1e-4);
        }
        // The same draws as the candle path's sampler.
        let mut rng2 = <ChaCha8Rng as rand::SeedableRng>::seed_from_u64(5);
        let (a2, _) = fulcrum_learner::net::sample(&logits, &mut rng2).unwrap();
        let a2: Vec<u8> = a2.iter().map(|&x| x as u8).collect();
        assert_eq!(a, a2);
    }
}

#[cfg(test)]
mod masked_tests {
    use super::*;
    use candle_core::Device;
    use fulcrum_learner::net::{log_softmax, Net};
    use fulcrum_world::mask::action_mask;
    use rand::SeedableRng;

    /// With the mask, sampled actions are always allowed, and their log-probabilities are
    /// those of the unmasked distribution renormalised over the allowed actions:
    /// log p(a) - log(sum over allowed b of p(b)), computed here from candle's unmasked
    /// log-softmax.
    #[test]
    fn masked_sampling_is_the_renormalised_distribution() {
        // Two tools: flags [held0, held1, normal, choosing-tool, dir0, dir1], 7 actions.
        let shape = NetShape {
            cells: 12,
            glyphs: 11,
            flags: 6,
            hidden: 16,
            actions: 7,
            int_value: false,
        };
        let net = Net::new(shape, 9, &Device::Cpu).unwrap();
        let mut p = Policy::new(shape).with_action_mask(true);
        assert!(p.set(&net.flat().unwrap()));
        let modes: [[u8; 6]; 5] = [
            [0, 0, 1, 0, 0, 0],
            [1, 0, 1, 0, 0, 0],
            [1, 1, 0, 1, 0, 0],
            [0, 1, 0, 1, 0, 0],
            [1, 0, 0, 0, 1, 0],
        ];
        let n = 400;
        let glyphs: Vec<u8> = (0..n * 12).map(|i| ((i * 7 + i / 5) % 11) as u8).collect();
        let flags: Vec<u8> = (0..n).flat_map(|i| modes[i % 5]).collect();
        let (logits, _) = net.forward(&net.batch(&glyphs, &flags).unwrap()).unwrap();
        let lp = log_softmax(&logits).unwrap().to_vec2::<f32>().unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (mut a, mut l, mut v) = (vec![0u8; n], vec![0.0; n], vec![0.0; n]);
        p.act(&glyphs, &flags, &mut rng, &mut a, &mut l, &mut v);
        let mut seen = [0u32; 7];
        for i in 0..n {
            let m = action_mask(&flags[i * 6..(i + 1) * 6]);
            assert_eq!(m >> a[i] & 1, 1, "sample {i}: action {} not allowed", a[i]);
            seen[a[i] as usize] += 1;
            let z: f32 = (0..7)
                .filter(|&k| m >> k & 1 == 1)
                .map(|k| lp[i][k].exp())
                .sum();
            let want = lp[i][a[i] as usize] - z.ln();
            assert!((l[i] - want).abs() < 1e-5, "sample {i}: {} vs {want}", l[i]);
        }
        // Every action is allowed somewhere and drawn.
        assert!(seen.iter().all(|&c| c > 0), "{seen:?}");
    }
}

#[cfg(test)]
mod int_head_tests {
    use super::tests::fixture;
    use super::*;
    use rand::SeedableRng;

    /// With the intrinsic value head the plain evaluation gives candle's second head too,
    /// and the extrinsic value and the sampled actions are those of the same weights.
    #[test]
    fn intrinsic_values_equal_the_candle_head() {
        let shape = NetShape {
            cells: 12,
            glyphs: 11,
            flags: 6,
            hidden: 16,
            actions: 7,
            int_value: true,
        };
        let n = 9;
        let (net, mut p, glyphs, flags) = fixture(shape, 4, n);
        let (_, value, vi) = net
            .forward_all(&net.batch(&glyphs, &flags).unwrap())
            .unwrap();
        let (value, vi): (Vec<f32>, Vec<f32>) =
            (value.to_vec1().unwrap(), vi.unwrap().to_vec1().unwrap());
        let (mut v, mut w) = (vec![0.0; n], vec![0.0; n]);
        p.values_all(&glyphs, &flags, &mut v, &mut w);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let (mut a, mut l) = (vec![0u8; n], vec![0.0; n]);
        let (mut v2, mut w2) = (vec![0.0; n], vec![0.0; n]);
        p.act_all(&glyphs, &flags, &mut rng, &mut a, &mut l, &mut v2, &mut w2);
        for i in 0..n {
            assert!((v[i] - value[i]).abs() < 1e-4 && (w[i] - vi[i]).abs() < 1e-4);
            assert_eq!((v[i], w[i]), (v2[i], w2[i]));
        }
        // The two heads differ (not one value written twice).
        assert!(v.iter().zip(&w).any(|(a, b)| (a - b).abs() > 1e-3));
    }
}
