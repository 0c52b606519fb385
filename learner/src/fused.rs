//! The PPO update on flat f32 buffers, without candle's autograd.
//!
//! The candle path (the `ppo` module's loss and gradient clipping, then [`Adam::apply`])
//! took ~300 ms for the bench's update (1024 samples x 4 epochs, hidden 64,
//! exp1-tree: 12k samples x epochs/s, one thread). Measured: forward + loss ~50%,
//! backward ~43%, Adam ~6%; most of it in the embedding-sum layer (candle's strided
//! `sum` over the gathered (B, C, H) rows divides integers per element; the backward
//! scatters into a fresh (C*G, H) tensor) and in fresh, zero-filled buffers per op
//! (memset and page clearing ~18%). Here the same math is written out by hand, one
//! sample at a time (forward, loss gradient, backward, all in L1), accumulating the
//! parameters' gradient in one flat buffer; global-norm clipping and Adam are one pass
//! over flat buffers. The parameters and Adam's moments are copied out of the candle
//! tensors once per update and back at its end.
//!
//! Two exact savings on the embedding-sum layer (C*G rows of H floats, most of the
//! parameters):
//!
//! - **Sparse observations.** A grid differs from a reference grid (each cell's most
//!   frequent glyph, its "mode", in up to 64 grids of the rollout) in a few cells (the
//!   agent, objects that moved: 1.2 per sample on exp1-tree). With
//!   `base = b1 + sum_c E[mode_c]` computed once per minibatch, a sample's first layer is
//!   `base + sum over its differing cells of (E[row] - E[mode row])`, and its backward adds
//!   `dz1` to those rows and subtracts it from their mode rows, the mode rows receiving
//!   the minibatch's sum of `dz1` once. The same sums, in another order. A sample that
//!   differs in more than half its cells is summed directly.
//! - **Rows never seen.** An embedding row that no observation has used has zero
//!   gradient and zero moments, so Adam leaves it exactly as it is: zeroing, the norm and
//!   Adam skip such rows (a row joins for good the first time it is seen, or when loaded
//!   with nonzero moments).
//!
//! Gradients follow candle's autograd rules where they are not smooth, so the two paths
//! agree to rounding (tested in `tests/fused.rs`): `maximum`/`minimum` split the gradient
//! in half on a tie (the clipped surrogate inside the clip range is such a tie), `clamp`
//! is `maximum(lo).minimum(hi)`, and ReLU passes the gradient at 0. Adam's arithmetic is
//! candle's `affine` ops in the same order (bit for bit), except that subnormal moments
//! are flushed to 0 (which leaves the weights as they are; see [`crate::adam`]).
//!
//! The inner loops (`kernel`) are plain Rust over fixed-width chunks (accumulators in
//! registers), compiled three times ([`Simd`]): for the baseline target and for AVX2 and
//! AVX-512, chosen at run time. Without FMA contraction and with fixed summation orders,
//! all three give the same bits.
//!
//! [`Adam::apply`]: crate::adam::Adam::apply
//! [`Simd`]: crate::simd::Simd

use std::ops::Range;

use candle_core::{bail, Result, Tensor};
use fulcrum_contracts::ppo_config::PpoConfig;

use crate::adam::{adam_ranges, Adam, AdamStep};
use crate::diagnostics::Stats;
use crate::net::Net;
use crate::simd::{simd, Simd};
use fulcrum_contracts::layout::{NetShape, Offsets};

/// A rollout prepared for the update.
mod data;
/// The forward and backward pass of one minibatch.
mod kernel;

pub use data::Data;

/// Tensors concatenated into one flat f32 buffer.
fn flat(ts: &[Tensor]) -> Result<Vec<f32>> {
    let mut out = Vec::with_capacity(ts.iter().map(|t| t.elem_count()).sum());
    for t in ts {
        crate::net::append_f32(&mut out, t)?;
    }
    Ok(out)
}

/// Replace each tensor by its slice of `flat` (same shapes, same order).
fn unflat(ts: &mut [Tensor], flat: &[f32]) -> Result<()> {
    let total: usize = ts.iter().map(|t| t.elem_count()).sum();
    if total != flat.len() {
        bail!("flat buffer of {} floats for {total}", flat.len());
    }
    let mut off = 0;
    for t in ts.iter_mut() {
        let n = t.elem_count();
        *t = Tensor::from_slice(&flat[off..off + n], t.dims(), t.device())?;
        off += n;
    }
    Ok(())
}

/// The whole PPO state of an update on flat buffers: parameters, Adam's moments and
/// step, the gradient and scratch.
#[derive(Debug)]
pub struct Learner {
    /// Sizes.
    pub shape: NetShape,
    /// Parameter offsets.
    pub off: Offsets,
    /// Parameters, flat (the order of `Net::flat`).
    pub w: Vec<f32>,
    /// Adam's first moments, flat.
    pub m: Vec<f32>,
    /// Adam's second moments, flat.
    pub v: Vec<f32>,
    /// Adam's step.
    pub step: u64,
    /// Gradient of the last minibatch (unclipped), flat.
    pub g: Vec<f32>,
    /// Embedding rows seen (or with nonzero moments).
    live: Vec<bool>,
    /// Ranges of `w` that Adam updates: the live rows and all other parameters.
    ranges: Vec<Range<usize>>,
    /// The compiled variant of the inner loops that runs.
    simd: Simd,
    // W2 transposed (H, H); the heads transposed with the value as the last row
    // ((|A|+1), H) and their biases; the heads' gradient in that layout.
    w2t: Vec<f32>,
    ht: Vec<f32>,
    hb: Vec<f32>,
    dht: Vec<f32>,
    dhb: Vec<f32>,
}

impl Learner {
    /// From flat parameters and moments.
    pub fn new(
        shape: NetShape,
        w: Vec<f32>,
        m: Vec<f32>,
        v: Vec<f32>,
        step: u64,
    ) -> Result<Learner> {
        let off = Offsets::new(shape);
        if w.len() != off.len || m.len() != off.len || v.len() != off.len {
            bail!(
                "flat state: {} weights, {} and {} moments; the network has {}",
                w.len(),
                m.len(),
                v.len(),
                off.len
            );
        }
        let (h, a) = (shape.hidden, shape.actions);
        let rows = shape.cells * shape.glyphs;
        let live = (0..rows)
            .map(|r| {
                let span = off.embed + r * h..off.embed + (r + 1) * h;
                // Branch-free (vectorised): some element is not +-0.
                let bits = |x: &[f32]| x.iter().fold(0, |a, v| a | (v.to_bits() << 1));
                bits(&m[span.clone()]) | bits(&v[span]) != 0
            })
            .collect();
        let mut l = Learner {
            shape,
            off,
            w,
            m,
            v,
            step,
            g: vec![0.0; off.len],
            live,
            ranges: Vec::new(),
            simd: simd(),
            w2t: vec![0.0; h * h],
            ht: vec![0.0; (a + shape.heads()) * h],
            hb: vec![0.0; a + shape.heads()],
            dht: vec![0.0; (a + shape.heads()) * h],
            dhb: vec![0.0; a + shape.heads()],
        };
        l.rebuild_ranges();
        l.refresh();
        Ok(l)
    }

    /// Copy a network's parameters and its optimiser's state.
    pub fn load(net: &Net, adam: &Adam) -> Result<Learner> {
        Learner::new(
            net.shape,
            net.flat()?,
            flat(&adam.m)?,
            flat(&adam.v)?,
            adam.step,
        )
    }

    /// Write the parameters and the optimiser's state back.
    pub fn store(&self, net: &Net, adam: &mut Adam) -> Result<()> {
        net.set_flat(&self.w)?;
        unflat(&mut adam.m, &self.m)?;
        unflat(&mut adam.v, &self.v)?;
        adam.step = self.step;
        Ok(())
    }

    /// Run another compiled variant of the inner loops (all give the same bits); false,
    /// and no change, when this CPU lacks its instructions.
    pub fn set_simd(&mut self, v: Simd) -> bool {
        let ok = match v {
            Simd::Avx512 => simd() == Simd::Avx512,
            Simd::Avx2 => simd() != Simd::None,
            Simd::None => true,
        };
        if ok {
            self.simd = v;
        }
        ok
    }

    fn rebuild_ranges(&mut self) {
        let h = self.shape.hidden;
        self.ranges.clear();
        for (r, _) in self.live.iter().enumerate().filter(|x| *x.1) {
            let span = self.off.embed + r * h..self.off.embed + (r + 1) * h;
            match self.ranges.last_mut() {
                Some(last) if last.end == span.start => last.end = span.end,
                _ => self.ranges.push(span),
            }
        }
        let rest = self.off.wf..self.off.len;
        match self.ranges.last_mut() {
            Some(last) if last.end == rest.start => last.end = rest.end,
            _ => self.ranges.push(rest),
        }
    }

    /// Rebuild the transposed copies after the weights changed.
    fn refresh(&mut self) {
        let (h, a, o) = (self.shape.hidden, self.shape.actions, self.off);
        for i in 0..h {
            for j in 0..h {
                self.w2t[j * h + i] = self.w[o.w2 + i * h + j];
            }
        }
        for j in 0..h {
            for k in 0..a {
                self.ht[k * h + j] = self.w[o.wp + j * a + k];
            }
            self.ht[a * h + j] = self.w[o.wv + j];
            if self.shape.int_value {
                self.ht[(a + 1) * h + j] = self.w[o.wvi + j];
            }
        }
        self.hb[..a].copy_from_slice(&self.w[o.bp..o.bp + a]);
        self.hb[a] = self.w[o.bv];
        if self.shape.int_value {
            self.hb[a + 1] = self.w[o.bvi];
        }
    }

    /// Loss diagnostics and the gradient (into `self.g`) of the minibatch `idx` of `d`.
    pub fn gradient(&mut self, d: &Data, idx: &[usize], cfg: &PpoConfig) -> Stats {
        let mut grew = false;
        for &r in &d.used_rows {
            let live = &mut self.live[r as usize];
            grew |= !*live;
            *live = true;
        }
        if grew {
            self.rebuild_ranges();
        }
        for r in &self.ranges {
            self.g[r.clone()].fill(0.0);
        }
        match self.simd {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the CPU has these features (`simd`, `set_simd` checked).
            Simd::Avx512 => unsafe { kernel::gradient_avx512(self, d, idx, cfg) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as above.
            Simd::Avx2 => unsafe { kernel::gradient_avx2(self, d, idx, cfg) },
            _ => kernel::gradient_generic(self, d, idx, cfg),
        }
    }

    /// Clip the gradient to a global norm of `max_norm` and take an Adam step at `lr`;
    /// returns the norm before clipping. Same arithmetic as `clipped_grads` +
    /// `Adam::apply`.
    pub fn clip_and_step(&mut self, max_norm: f32, lr: f64) -> f32 {
        let sq: f64 = self
            .ranges
            .iter()
            .map(|r| kernel::sum_sq(&self.g[r.clone()]))
            .sum();
        let norm = sq.sqrt() as f32;
        let scale = (norm > max_norm).then(|| (max_norm / (norm + 1e-6)) as f64 as f32);
        self.step += 1;
        let k = AdamStep::new(self.step, lr);
        adam_ranges(
            self.simd,
            &mut self.w,
            &self.g,
            &mut self.m,
            &mut self.v,
            &self.ranges,
            k,
            scale,
        );
        self.refresh();
        norm
    }
}
