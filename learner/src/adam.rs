//! Adam with its state in the open (first and second moments, step), so that a
//! checkpoint carries it: the optimiser of the candle path ([`Adam::apply`]) and of the
//! fused update (`fused::Learner::clip_and_step`), both running the one loop
//! [`adam_slices`] over flat f32 buffers.
//!
//! The arithmetic is candle's `affine` ops in the same order (bit for bit), except that
//! subnormal moments are flushed to 0 (which leaves the weights as they are; see
//! `flush`). The loop is compiled for each [`Simd`] variant, all giving the same bits.
//!
//! [`Adam::apply`]: crate::adam::Adam::apply
//! [`adam_slices`]: crate::adam::adam_slices
//! [`Simd`]: crate::simd::Simd

use std::ops::Range;

use candle_core::{Result, Tensor};

use crate::net::Net;
use crate::simd::{simd, Simd};

/// Adam with its state in the open (moments and step), eps 1e-5 as CleanRL.
#[derive(Debug)]
pub struct Adam {
    /// First moments, one per parameter.
    pub m: Vec<Tensor>,
    /// Second moments.
    pub v: Vec<Tensor>,
    /// Steps taken.
    pub step: u64,
}

impl Adam {
    /// Zero state for a network.
    pub fn new(net: &Net) -> Result<Adam> {
        let z = |t: &Tensor| t.zeros_like();
        Ok(Adam {
            m: net
                .params
                .iter()
                .map(|(_, v)| z(v.as_tensor()))
                .collect::<Result<_>>()?,
            v: net
                .params
                .iter()
                .map(|(_, v)| z(v.as_tensor()))
                .collect::<Result<_>>()?,
            step: 0,
        })
    }

    /// One step with gradients `grads` (same order as the parameters).
    ///
    /// The arithmetic of candle's ops `m * b1 + g * (1 - b1)`, `v * b2 + g^2 * (1 - b2)`,
    /// `w - (m / c1) / (sqrt(v / c2) + eps) * lr`, as one loop per parameter
    /// ([`adam_slices`]: subnormal moments become 0, the weights unchanged).
    pub fn apply(&mut self, net: &Net, grads: &[Tensor], lr: f64) -> Result<()> {
        if grads.len() != net.params.len() || self.m.len() != net.params.len() {
            candle_core::bail!(
                "Adam: {} parameters, {} gradients, {} moments",
                net.params.len(),
                grads.len(),
                self.m.len()
            );
        }
        self.step += 1;
        let k = AdamStep::new(self.step, lr);
        for (i, ((_, var), g)) in net.params.iter().zip(grads).enumerate() {
            let t = var.as_tensor();
            let (dims, dev) = (t.dims().to_vec(), t.device().clone());
            let vec = |t: &Tensor| t.flatten_all()?.to_vec1::<f32>();
            let (mut w, g) = (vec(t)?, vec(g)?);
            let (mut m, mut v) = (vec(&self.m[i])?, vec(&self.v[i])?);
            if g.len() != w.len() || m.len() != w.len() || v.len() != w.len() {
                candle_core::bail!(
                    "Adam: parameter {i} has {} floats, its gradient {}",
                    w.len(),
                    g.len()
                );
            }
            adam_slices(&mut w, &g, &mut m, &mut v, k, None);
            self.m[i] = Tensor::from_vec(m, dims.as_slice(), &dev)?;
            self.v[i] = Tensor::from_vec(v, dims.as_slice(), &dev)?;
            var.set(&Tensor::from_vec(w, dims.as_slice(), &dev)?)?;
        }
        Ok(())
    }
}

/// Adam's constants for one step (candle's `affine` scalars, as f32).
#[derive(Debug, Clone, Copy)]
pub struct AdamStep {
    b1: f32,
    one_minus_b1: f32,
    b2: f32,
    one_minus_b2: f32,
    inv_c1: f32,
    inv_c2: f32,
    eps: f32,
    lr: f32,
}

impl AdamStep {
    /// Constants of step number `step` (1-based) at learning rate `lr`; betas 0.9, 0.999,
    /// eps 1e-5.
    pub fn new(step: u64, lr: f64) -> AdamStep {
        const B1: f64 = 0.9;
        const B2: f64 = 0.999;
        const EPS: f64 = 1e-5;
        let t = step as i32;
        let (c1, c2) = (1.0 - B1.powi(t), 1.0 - B2.powi(t));
        AdamStep {
            b1: B1 as f32,
            one_minus_b1: (1.0 - B1) as f32,
            b2: B2 as f32,
            one_minus_b2: (1.0 - B2) as f32,
            inv_c1: (1.0 / c1) as f32,
            inv_c2: (1.0 / c2) as f32,
            eps: EPS as f32,
            lr: lr as f32,
        }
    }
}

/// One Adam step over flat slices; the gradient is multiplied by `gscale` first (the
/// clipping factor; `None` for none). The arithmetic of candle's ops `m * b1 + g * (1 -
/// b1)`, `v * b2 + g^2 * (1 - b2)`, `w - (m / c1) / (sqrt(v / c2) + eps) * lr` in the same
/// order, except that subnormal moments become 0 (see `flush`).
pub fn adam_slices(
    w: &mut [f32],
    g: &[f32],
    m: &mut [f32],
    v: &mut [f32],
    k: AdamStep,
    gscale: Option<f32>,
) {
    let all = 0..w.len();
    adam_ranges(simd(), w, g, m, v, std::slice::from_ref(&all), k, gscale);
}

#[allow(clippy::too_many_arguments)]
pub(crate) fn adam_ranges(
    variant: Simd,
    w: &mut [f32],
    g: &[f32],
    m: &mut [f32],
    v: &mut [f32],
    ranges: &[Range<usize>],
    k: AdamStep,
    gscale: Option<f32>,
) {
    let n = w.len();
    assert!(g.len() == n && m.len() == n && v.len() == n);
    match variant {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the CPU has these features (`simd`, `set_simd` checked).
        Simd::Avx512 => unsafe { adam_avx512(w, g, m, v, ranges, k, gscale) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above.
        Simd::Avx2 => unsafe { adam_avx2(w, g, m, v, ranges, k, gscale) },
        _ => adam_generic(w, g, m, v, ranges, k, gscale),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f")]
fn adam_avx512(
    w: &mut [f32],
    g: &[f32],
    m: &mut [f32],
    v: &mut [f32],
    ranges: &[Range<usize>],
    k: AdamStep,
    gscale: Option<f32>,
) {
    adam_generic(w, g, m, v, ranges, k, gscale);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn adam_avx2(
    w: &mut [f32],
    g: &[f32],
    m: &mut [f32],
    v: &mut [f32],
    ranges: &[Range<usize>],
    k: AdamStep,
    gscale: Option<f32>,
) {
    adam_generic(w, g, m, v, ranges, k, gscale);
}

#[inline(always)]
fn adam_generic(
    w: &mut [f32],
    g: &[f32],
    m: &mut [f32],
    v: &mut [f32],
    ranges: &[Range<usize>],
    k: AdamStep,
    gscale: Option<f32>,
) {
    let s = gscale.unwrap_or(1.0);
    for r in ranges {
        let (w, g, m, v) = (
            &mut w[r.clone()],
            &g[r.clone()],
            &mut m[r.clone()],
            &mut v[r.clone()],
        );
        for (((w, &g), m), v) in w.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
            // x * 1.0 is exact: no scale is the same as scale 1.
            let g = if gscale.is_some() { g * s } else { g };
            *m = flush(*m * k.b1 + g * k.one_minus_b1);
            *v = flush(*v * k.b2 + (g * g) * k.one_minus_b2);
            let mhat = *m * k.inv_c1;
            let denom = (*v * k.inv_c2).sqrt() + k.eps;
            *w -= (mhat / denom) * k.lr;
        }
    }
}

/// A subnormal moment as zero. The first moment of a parameter whose gradient stays 0
/// (a dead unit, a row seen once) decays by 0.9 a step and turns subnormal after ~800
/// steps; arithmetic on subnormals is ~100x slower (measured: 919 such moments after 45
/// updates made an update 1.5x slower). The weights do not change: the step such a
/// moment gives, below 1e-31, vanishes when subtracted from any weight above 1e-24.
#[inline(always)]
fn flush(x: f32) -> f32 {
    if x.abs() < f32::MIN_POSITIVE {
        0.0
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn adam_slices_is_candles_arithmetic() {
        // The candle-op Adam of one step, bit for bit.
        let dev = Device::Cpu;
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut r =
            |n: usize| -> Vec<f32> { (0..n).map(|_| rng.random_range(-1.0f32..1.0)).collect() };
        let (w, g, m, v0) = (r(50), r(50), r(50), r(50));
        let v: Vec<f32> = v0.iter().map(|x| x.abs()).collect();
        let (step, lr) = (3u64, 2.5e-4);
        let t = |x: &[f32]| Tensor::from_slice(x, x.len(), &dev).unwrap();
        let (b1, b2, eps) = (0.9f64, 0.999f64, 1e-5f64);
        let (c1, c2) = (1.0 - b1.powi(step as i32), 1.0 - b2.powi(step as i32));
        let (tw, tg) = (t(&w), t(&g));
        let tm = ((t(&m) * b1).unwrap() + (&tg * (1.0 - b1)).unwrap()).unwrap();
        let tv = ((t(&v) * b2).unwrap() + (tg.sqr().unwrap() * (1.0 - b2)).unwrap()).unwrap();
        let mhat = (&tm / c1).unwrap();
        let denom = ((&tv / c2).unwrap().sqrt().unwrap() + eps).unwrap();
        let upd = ((mhat / denom).unwrap() * lr).unwrap();
        let want_w: Vec<f32> = (tw - upd).unwrap().to_vec1().unwrap();
        let (mut w2, mut m2, mut v2) = (w.clone(), m.clone(), v.clone());
        adam_slices(&mut w2, &g, &mut m2, &mut v2, AdamStep::new(step, lr), None);
        assert_eq!(w2, want_w);
        assert_eq!(m2, tm.to_vec1::<f32>().unwrap());
        assert_eq!(v2, tv.to_vec1::<f32>().unwrap());
    }
}
