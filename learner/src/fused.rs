//! The PPO update on flat f32 buffers, without candle's autograd.
//!
//! [`crate::ppo::loss`] + [`crate::ppo::clipped_grads`] + [`crate::ppo::Adam::apply`] as
//! candle ops took ~300 ms for the bench's update (1024 samples x 4 epochs, hidden 64,
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
//! agree to rounding (tested below): `maximum`/`minimum` split the gradient in half on a
//! tie (the clipped surrogate inside the clip range is such a tie), `clamp` is
//! `maximum(lo).minimum(hi)`, and ReLU passes the gradient at 0. Adam's arithmetic is
//! candle's `affine` ops in the same order (bit for bit), except that subnormal moments
//! are flushed to 0 (which leaves the weights as they are; see `flush`).
//!
//! The inner loops are plain Rust over fixed-width chunks (accumulators in registers),
//! compiled three times: for the baseline target and for AVX2 and AVX-512, chosen at
//! run time. Without FMA contraction and with fixed summation orders, all three give the
//! same bits.

use std::ops::Range;

use candle_core::{bail, Result, Tensor};

use crate::net::{Net, NetShape};
use crate::ppo::{Adam, PpoConfig, Stats};

/// Offsets of the parameters in the flat buffer (the order of `Net::params`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Offsets {
    /// `policy.embed` (C*G, H).
    pub embed: usize,
    /// `policy.flags.w` (F, H).
    pub wf: usize,
    /// `policy.l1.b` (H).
    pub b1: usize,
    /// `policy.l2.w` (H, H).
    pub w2: usize,
    /// `policy.l2.b` (H).
    pub b2: usize,
    /// `policy.pi.w` (H, |A|).
    pub wp: usize,
    /// `policy.pi.b` (|A|).
    pub bp: usize,
    /// `policy.v.w` (H, 1).
    pub wv: usize,
    /// `policy.v.b` (1).
    pub bv: usize,
    /// `policy.v_int.w` (H, 1), with the intrinsic value head (else `len`).
    pub wvi: usize,
    /// `policy.v_int.b` (1), with the intrinsic value head (else `len`).
    pub bvi: usize,
    /// Total.
    pub len: usize,
}

impl Offsets {
    /// Offsets for a shape.
    pub fn new(s: NetShape) -> Offsets {
        let h = s.hidden;
        let embed = 0;
        let wf = embed + s.cells * s.glyphs * h;
        let b1 = wf + s.flags * h;
        let w2 = b1 + h;
        let b2 = w2 + h * h;
        let wp = b2 + h;
        let bp = wp + h * s.actions;
        let wv = bp + s.actions;
        let bv = wv + h;
        let (wvi, bvi, len) = if s.int_value {
            (bv + 1, bv + 1 + h, bv + 2 + h)
        } else {
            (bv + 1, bv + 1, bv + 1)
        };
        Offsets {
            embed,
            wf,
            b1,
            w2,
            b2,
            wp,
            bp,
            wv,
            bv,
            wvi,
            bvi,
            len,
        }
    }
}

/// One rollout prepared for the update.
#[derive(Debug)]
pub struct Data<'a> {
    /// Glyph grids, (N * C).
    glyphs: &'a [u8],
    /// Per cell, the row `c * G + glyph` of its most frequent glyph in the rollout, (C).
    mode_rows: Vec<u32>,
    /// Differing cells of the sparse samples: (row, mode row).
    diffs: Vec<(u32, u32)>,
    /// Sample i's differing cells are `diffs[diff_at[i]..diff_at[i + 1]]`, (N + 1).
    diff_at: Vec<u32>,
    /// Samples summed directly (more than half their cells differ), (N).
    dense: Vec<bool>,
    /// Distinct embedding rows used, ascending.
    used_rows: Vec<u32>,
    /// Flags as f32, (N * F).
    flags: Vec<f32>,
    actions: &'a [u32],
    logprobs: &'a [f32],
    values: &'a [f32],
    advantages: &'a [f32],
    returns: &'a [f32],
    /// Per sample, the allowed actions ([`fulcrum_shared::mask::action_mask`]); `None`
    /// without masking.
    masks: Option<Vec<u32>>,
    /// V_int old and the intrinsic returns, with the intrinsic value head.
    int: Option<(&'a [f32], &'a [f32])>,
}

impl<'a> Data<'a> {
    /// Check the sizes and ranges, and find each sample's cells that differ from the
    /// rollout's most frequent glyph.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        shape: NetShape,
        glyphs: &'a [u8],
        flags: &[u8],
        actions: &'a [u32],
        logprobs: &'a [f32],
        values: &'a [f32],
        advantages: &'a [f32],
        returns: &'a [f32],
    ) -> Result<Data<'a>> {
        let n = actions.len();
        let (c, g, f) = (shape.cells, shape.glyphs, shape.flags);
        if glyphs.len() != n * c || flags.len() != n * f {
            bail!(
                "update data: {n} samples but {} glyph and {} flag bytes (cells {c}, flags {f})",
                glyphs.len(),
                flags.len()
            );
        }
        for (name, len) in [
            ("logprobs", logprobs.len()),
            ("values", values.len()),
            ("advantages", advantages.len()),
            ("returns", returns.len()),
        ] {
            if len != n {
                bail!("update data: {n} actions but {len} {name}");
            }
        }
        if let Some(&a) = actions.iter().find(|&&a| a as usize >= shape.actions) {
            bail!("update data: action {a} out of range ({})", shape.actions);
        }
        if let Some(&gl) = glyphs.iter().max().filter(|&&gl| gl as usize >= g) {
            bail!("update data: glyph {gl} out of range ({g})");
        }
        // The reference grid: each cell's most frequent glyph in up to 64 grids spread
        // over the rollout (any reference is exact; a common one makes samples sparse).
        let mut count = vec![0u32; c * g];
        for i in (0..n).step_by(n.div_ceil(64).max(1)) {
            let grid = &glyphs[i * c..(i + 1) * c];
            for (cnt, &gl) in count.chunks_exact_mut(g.max(1)).zip(grid) {
                cnt[gl as usize] += 1;
            }
        }
        let mode: Vec<u8> = count
            .chunks_exact(g.max(1))
            .map(|cnt| (0..g).max_by_key(|&k| (cnt[k], g - k)).unwrap_or(0) as u8)
            .collect();
        let mode_rows: Vec<u32> = mode
            .iter()
            .enumerate()
            .map(|(cell, &m)| (cell * g + m as usize) as u32)
            .collect();
        let mut used = vec![false; c * g];
        for &r in &mode_rows {
            used[r as usize] = true;
        }
        let mut diffs = Vec::new();
        let mut diff_at = Vec::with_capacity(n + 1);
        let mut dense = Vec::with_capacity(n);
        diff_at.push(0);
        for i in 0..n {
            let grid = &glyphs[i * c..(i + 1) * c];
            let start = diffs.len();
            // Eight cells at a time: most words equal the reference's.
            for (w, (a, b)) in grid.chunks(8).zip(mode.chunks(8)).enumerate() {
                if a == b {
                    continue;
                }
                for (k, (&gl, &m)) in a.iter().zip(b).enumerate() {
                    if gl != m {
                        let base = ((w * 8 + k) * g) as u32;
                        diffs.push((base + gl as u32, base + m as u32));
                    }
                }
            }
            let is_dense = 2 * (diffs.len() - start) > c;
            if is_dense {
                diffs.truncate(start);
                for (cell, &gl) in grid.iter().enumerate() {
                    used[cell * g + gl as usize] = true;
                }
            }
            dense.push(is_dense);
            diff_at.push(diffs.len() as u32);
        }
        for &(r, _) in &diffs {
            used[r as usize] = true;
        }
        let used_rows: Vec<u32> = (0..c * g).filter(|&r| used[r]).map(|r| r as u32).collect();
        Ok(Data {
            glyphs,
            mode_rows,
            diffs,
            diff_at,
            dense,
            used_rows,
            flags: flags.iter().map(|&x| x as f32).collect(),
            actions,
            logprobs,
            values,
            advantages,
            returns,
            masks: None,
            int: None,
        })
    }

    /// The intrinsic value head's old values and returns (one per sample), trained with
    /// the same clipped value loss as the extrinsic head.
    pub fn with_intrinsic(mut self, values: &'a [f32], returns: &'a [f32]) -> Result<Self> {
        let n = self.actions.len();
        if values.len() != n || returns.len() != n {
            bail!(
                "update data: {n} actions but {} intrinsic values and {} intrinsic returns",
                values.len(),
                returns.len()
            );
        }
        self.int = Some((values, returns));
        Ok(self)
    }

    /// Mask each sample's logits by the actions its flags allow (per-mode action
    /// masking): masked actions get probability 0 in the log-probabilities, the entropy
    /// and the gradient. Fails when a taken action is not allowed (a chunk sampled
    /// without the mask).
    pub fn with_action_mask(mut self, on: bool) -> Result<Self> {
        if !on {
            self.masks = None;
            return Ok(self);
        }
        let f = self.flags.len() / self.actions.len().max(1);
        let masks: Vec<u32> = self
            .flags
            .chunks_exact(f.max(1))
            .map(fulcrum_shared::mask::action_mask_f32)
            .collect();
        if let Some(i) = (0..self.actions.len()).find(|&i| masks[i] >> self.actions[i] & 1 == 0) {
            bail!(
                "update data: sample {i} took action {}, which its mode does not allow (a chunk sampled without the action mask)",
                self.actions[i]
            );
        }
        self.masks = Some(masks);
        Ok(self)
    }

    /// Samples.
    pub fn len(&self) -> usize {
        self.actions.len()
    }

    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.actions.is_empty()
    }

    /// Cells of the sparse samples that differ from the mode (a measure of sparsity).
    pub fn differing_cells(&self) -> usize {
        self.diffs.len()
    }

    /// Samples summed directly.
    pub fn dense_samples(&self) -> usize {
        self.dense.iter().filter(|&&d| d).count()
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

/// Which compiled variant of the inner loops this CPU runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Simd {
    /// AVX-512F (and AVX2).
    Avx512,
    /// AVX2.
    Avx2,
    /// The baseline target.
    None,
}

/// The variant for this CPU.
pub fn simd() -> Simd {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        if has!("avx2") {
            return if has!("avx512f") {
                Simd::Avx512
            } else {
                Simd::Avx2
            };
        }
    }
    Simd::None
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
fn adam_ranges(
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

/// Sum of squares (f32 partial sums in 16 lanes, added in f64).
#[inline(always)]
fn sum_sq(x: &[f32]) -> f64 {
    let mut acc = [0.0f32; 16];
    let mut it = x.chunks_exact(16);
    for c in &mut it {
        for l in 0..16 {
            acc[l] += c[l] * c[l];
        }
    }
    let mut s: f64 = acc.iter().map(|&a| a as f64).sum();
    for &r in it.remainder() {
        s += (r * r) as f64;
    }
    s
}

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
            Simd::Avx512 => unsafe { gradient_avx512(self, d, idx, cfg) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as above.
            Simd::Avx2 => unsafe { gradient_avx2(self, d, idx, cfg) },
            _ => gradient_generic(self, d, idx, cfg),
        }
    }

    /// Clip the gradient to a global norm of `max_norm` and take an Adam step at `lr`;
    /// returns the norm before clipping. Same arithmetic as `clipped_grads` +
    /// `Adam::apply`.
    pub fn clip_and_step(&mut self, max_norm: f32, lr: f64) -> f32 {
        let sq: f64 = self.ranges.iter().map(|r| sum_sq(&self.g[r.clone()])).sum();
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

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f")]
fn gradient_avx512(l: &mut Learner, d: &Data, idx: &[usize], cfg: &PpoConfig) -> Stats {
    gradient_generic(l, d, idx, cfg)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn gradient_avx2(l: &mut Learner, d: &Data, idx: &[usize], cfg: &PpoConfig) -> Stats {
    gradient_generic(l, d, idx, cfg)
}

/// Chunk width of the register-held accumulators.
const L: usize = 32;

/// `out[j] += sum_k c_k * mat[k * width + j]` over the listed (k, c_k); `out.len()` is
/// the width.
#[inline(always)]
fn combine_rows(out: &mut [f32], mat: &[f32], terms: &[(u32, f32)]) {
    let width = out.len();
    let mut j0 = 0;
    while j0 + L <= width {
        let mut acc: [f32; L] = out[j0..j0 + L].try_into().unwrap();
        for &(k, c) in terms {
            let base = k as usize * width + j0;
            let row: &[f32; L] = mat[base..base + L].try_into().unwrap();
            for l in 0..L {
                acc[l] += c * row[l];
            }
        }
        out[j0..j0 + L].copy_from_slice(&acc);
        j0 += L;
    }
    for (j, o) in out.iter_mut().enumerate().skip(j0) {
        let mut a = *o;
        for &(k, c) in terms {
            a += c * mat[k as usize * width + j];
        }
        *o = a;
    }
}

/// `out[j] += sum_r table[r * width + j]` over the rows.
#[inline(always)]
fn sum_rows(out: &mut [f32], table: &[f32], rows: &[u32]) {
    let width = out.len();
    let mut j0 = 0;
    while j0 + L <= width {
        let mut acc: [f32; L] = out[j0..j0 + L].try_into().unwrap();
        for &r in rows {
            let base = r as usize * width + j0;
            let row: &[f32; L] = table[base..base + L].try_into().unwrap();
            for l in 0..L {
                acc[l] += row[l];
            }
        }
        out[j0..j0 + L].copy_from_slice(&acc);
        j0 += L;
    }
    for (j, o) in out.iter_mut().enumerate().skip(j0) {
        let mut a = *o;
        for &r in rows {
            a += table[r as usize * width + j];
        }
        *o = a;
    }
}

/// `out[j] += sum (table[r * width + j] - table[m * width + j])` over the (r, m).
#[inline(always)]
fn sum_row_diffs(out: &mut [f32], table: &[f32], diffs: &[(u32, u32)]) {
    let width = out.len();
    let mut j0 = 0;
    while j0 + L <= width {
        let mut acc: [f32; L] = out[j0..j0 + L].try_into().unwrap();
        for &(r, m) in diffs {
            let (br, bm) = (r as usize * width + j0, m as usize * width + j0);
            let row: &[f32; L] = table[br..br + L].try_into().unwrap();
            let mrow: &[f32; L] = table[bm..bm + L].try_into().unwrap();
            for l in 0..L {
                acc[l] += row[l] - mrow[l];
            }
        }
        out[j0..j0 + L].copy_from_slice(&acc);
        j0 += L;
    }
    for (j, o) in out.iter_mut().enumerate().skip(j0) {
        let mut a = *o;
        for &(r, m) in diffs {
            a += table[r as usize * width + j] - table[m as usize * width + j];
        }
        *o = a;
    }
}

/// The nonzero entries of `x` as (index, value) at the start of `terms` (without
/// branches); returns their number.
#[inline(always)]
fn nonzero(x: &[f32], terms: &mut [(u32, f32)]) -> usize {
    let terms = &mut terms[..x.len()];
    let mut n = 0;
    for (k, &v) in x.iter().enumerate() {
        terms[n.min(k)] = (k as u32, v);
        n += (v != 0.0) as usize;
    }
    n
}

#[inline(always)]
fn axpy(y: &mut [f32], a: f32, x: &[f32]) {
    for (y, &x) in y.iter_mut().zip(x) {
        *y += a * x;
    }
}

#[inline(always)]
fn add(y: &mut [f32], x: &[f32]) {
    for (y, &x) in y.iter_mut().zip(x) {
        *y += x;
    }
}

#[inline(always)]
fn sub(y: &mut [f32], x: &[f32]) {
    for (y, &x) in y.iter_mut().zip(x) {
        *y -= x;
    }
}

#[inline(always)]
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 16];
    let (ca, cb) = (a.chunks_exact(16), b.chunks_exact(16));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..16 {
            acc[l] += x[l] * y[l];
        }
    }
    let mut s = 0.0;
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    // Pairwise, fixed order.
    let mut w = 16;
    while w > 1 {
        w /= 2;
        for l in 0..w {
            acc[l] += acc[l + w];
        }
    }
    acc[0] + s
}

/// d max(a, b) / da and / db as candle's autograd: 1 to the larger, half each on a tie.
#[inline(always)]
fn max_weights(a: f32, b: f32) -> (f32, f32) {
    let m = a.max(b);
    let (ea, eb) = ((m == a) as u8 as f32, (m == b) as u8 as f32);
    (ea / (eb + 1.0), eb / (ea + 1.0))
}

/// clamp(x, lo, hi) and its derivative as candle's `maximum(lo).minimum(hi)`.
#[inline(always)]
fn clamp_grad(x: f32, lo: f32, hi: f32) -> (f32, f32) {
    let y = if x > lo { x } else { lo };
    let dy = ((y == x) as u8 as f32) / ((y == lo) as u8 as f32 + 1.0);
    let z = if y < hi { y } else { hi };
    let dz = ((z == y) as u8 as f32) / ((z == hi) as u8 as f32 + 1.0);
    (z, dy * dz)
}

/// One sample's value loss term (already divided as in the loss's mean: the L_v part,
/// before `vf_coef`) and its gradient with respect to the value (with `vf_coef` and
/// `inv_n`): CleanRL's `0.5 * max((v - R)^2, (v_old + clip(v - v_old) - R)^2)`, or
/// RLlib's `min((v - R)^2, vf_loss_clip)`.
#[inline(always)]
fn value_loss(value: f32, old_v: f32, ret: f32, cfg: &PpoConfig, inv_n: f32) -> (f32, f32) {
    let vu = (value - ret) * (value - ret);
    if cfg.vf_loss_clip > 0.0 {
        // RLlib: min((v - R)^2, c); `minimum` splits the gradient on a tie.
        let (_, vu_max) = max_weights(cfg.vf_loss_clip, vu);
        let w = 1.0 - vu_max;
        (
            vu.min(cfg.vf_loss_clip),
            cfg.vf_coef * inv_n * w * 2.0 * (value - ret),
        )
    } else {
        let (dc, ddc) = clamp_grad(value - old_v, -cfg.clip, cfg.clip);
        let vc = old_v + dc;
        let va = (vc - ret) * (vc - ret);
        let (wa, wb) = max_weights(va, vu);
        let coef = cfg.vf_coef * 0.5 * inv_n;
        (
            0.5 * va.max(vu),
            coef * (wa * 2.0 * (vc - ret) * ddc + wb * 2.0 * (value - ret)),
        )
    }
}

#[inline(always)]
fn gradient_generic(l: &mut Learner, d: &Data, idx: &[usize], cfg: &PpoConfig) -> Stats {
    let s = l.shape;
    let o = l.off;
    let (c, f, h, na) = (s.cells, s.flags, s.hidden, s.actions);
    // Heads: the logits, the value and (optionally) the intrinsic value.
    let nh = na + s.heads();
    let n = idx.len();
    l.dht.fill(0.0);
    l.dhb.fill(0.0);
    if n == 0 {
        return Stats::default();
    }
    // Advantage normalisation over the minibatch (as `loss`: mean, unbiased std), or
    // none here when the batch was normalised as a whole.
    let (mean, std_eps) = if cfg.adv_norm_batch {
        (0.0, 1.0)
    } else {
        let mean = idx.iter().map(|&i| d.advantages[i]).sum::<f32>() / n as f32;
        let var = idx
            .iter()
            .map(|&i| (d.advantages[i] - mean) * (d.advantages[i] - mean))
            .sum::<f32>()
            / (n.max(2) - 1) as f32;
        (mean, var.sqrt().max(cfg.adv_std_floor) + 1e-8)
    };
    let inv_n = 1.0 / n as f32;
    let (lo, hi) = (1.0 - cfg.clip, 1.0 + cfg.clip);

    let w = &l.w[..];
    let (w2t, ht, hb) = (&l.w2t[..], &l.ht[..], &l.hb[..]);
    let (g_embed, g_rest) = l.g.split_at_mut(o.wf);
    let (g_wf, g_rest) = g_rest.split_at_mut(o.b1 - o.wf);
    let (g_b1, g_rest) = g_rest.split_at_mut(h);
    let (g_w2, g_rest) = g_rest.split_at_mut(h * h);
    let g_b2 = &mut g_rest[..h];
    let (dht, dhb) = (&mut l.dht[..], &mut l.dhb[..]);

    let embed = &w[o.embed..o.wf];
    let wf = &w[o.wf..o.b1];
    let b1 = &w[o.b1..o.w2];
    let w2 = &w[o.w2..o.b2];
    let b2 = &w[o.b2..o.wp];

    // First layer of the mode observation, and the sparse samples' sum of dz1.
    let mut base = b1.to_vec();
    sum_rows(&mut base, embed, &d.mode_rows);
    let mut dz1_sparse = vec![0.0f32; h];
    let mut rows = vec![0u32; c];

    let mut z1 = vec![0.0f32; h];
    let mut h1 = vec![0.0f32; h];
    let mut z2 = vec![0.0f32; h];
    let mut h2 = vec![0.0f32; h];
    let mut dz2 = vec![0.0f32; h];
    let mut dz1 = vec![0.0f32; h];
    let mut out = vec![0.0f32; nh];
    let mut dout = vec![0.0f32; nh];
    let mut logp = vec![0.0f32; na];
    let mut p = vec![0.0f32; na];
    let mut terms = vec![(0u32, 0.0f32); h.max(f).max(nh)];
    let mut h1_terms = vec![(0u32, 0.0f32); h];
    let (mut pg_sum, mut v_sum, mut ent_sum, mut kl_sum, mut clipped) =
        (0.0f32, 0.0f32, 0.0f32, 0.0f32, 0usize);

    for &i in idx {
        let fl = &d.flags[i * f..(i + 1) * f];
        let diffs = &d.diffs[d.diff_at[i] as usize..d.diff_at[i + 1] as usize];
        // Forward: z1 = b1 + sum of embedding rows + flags @ Wf.
        if d.dense[i] {
            for (cell, (r, &gl)) in rows
                .iter_mut()
                .zip(&d.glyphs[i * c..(i + 1) * c])
                .enumerate()
            {
                *r = (cell * s.glyphs) as u32 + gl as u32;
            }
            z1.copy_from_slice(b1);
            sum_rows(&mut z1, embed, &rows);
        } else {
            z1.copy_from_slice(&base);
            sum_row_diffs(&mut z1, embed, diffs);
        }
        let k = nonzero(fl, &mut terms);
        combine_rows(&mut z1, wf, &terms[..k]);
        for (y, &x) in h1.iter_mut().zip(&z1) {
            *y = x.max(0.0);
        }
        // z2 = h1 @ W2 + b2 (zero inputs skipped).
        z2.copy_from_slice(b2);
        let h1_nz = nonzero(&h1, &mut h1_terms);
        let h1_terms = &h1_terms[..h1_nz];
        combine_rows(&mut z2, w2, h1_terms);
        for (y, &x) in h2.iter_mut().zip(&z2) {
            *y = x.max(0.0);
        }
        // Heads: logits and value.
        for (k, y) in out.iter_mut().enumerate() {
            *y = hb[k] + dot(&h2, &ht[k * h..(k + 1) * h]);
        }

        // Loss of this sample and its gradient w.r.t. logits and value.
        let logits = &out[..na];
        let mask = d.masks.as_ref().map_or(u32::MAX, |m| m[i]);
        let allowed = |k: usize| mask >> k & 1 == 1;
        let mx = logits
            .iter()
            .enumerate()
            .filter(|(k, _)| allowed(*k))
            .fold(f32::NEG_INFINITY, |m, (_, &x)| m.max(x));
        let mut z = 0.0f32;
        for (k, (e, &x)) in p.iter_mut().zip(logits).enumerate() {
            *e = if allowed(k) { (x - mx).exp() } else { 0.0 };
            z += *e;
        }
        let (lse, inv_z) = (z.ln(), 1.0 / z);
        let mut ent = 0.0f32;
        for (k, ((lp, e), &x)) in logp.iter_mut().zip(p.iter_mut()).zip(logits).enumerate() {
            if !allowed(k) {
                // Probability 0: no term in the entropy, no gradient.
                *lp = f32::NEG_INFINITY;
                continue;
            }
            *lp = (x - mx) - lse;
            *e *= inv_z;
            ent += *e * *lp;
        }
        let ent = -ent;
        let act = d.actions[i] as usize;
        let logratio = logp[act] - d.logprobs[i];
        let ratio = logratio.exp();
        let adv = (d.advantages[i] - mean) / std_eps;
        let (cl, dcl) = clamp_grad(ratio, lo, hi);
        let (pg1, pg2) = (-adv * ratio, -adv * cl);
        let (w1, w2) = max_weights(pg1, pg2);
        let mut dlp = inv_n * ((-adv) * w1 + (-adv) * w2 * dcl) * ratio;
        if cfg.kl_coef != 0.0 {
            // d/dlogp of c_kl * ((ratio - 1) - logratio) / n.
            dlp += cfg.kl_coef * inv_n * (ratio - 1.0);
        }
        let dent = -cfg.ent_coef * inv_n;
        // g_j = dL/dlogp_j; dlogit_k = g_k - p_k * sum_j g_j (masked: 0).
        let mut gsum = 0.0f32;
        for (j, ((dy, &lp), &pj)) in dout[..na].iter_mut().zip(&logp).zip(&p).enumerate() {
            if !allowed(j) {
                *dy = 0.0;
                continue;
            }
            let mut g = -dent * pj * (lp + 1.0);
            if j == act {
                g += dlp;
            }
            *dy = g;
            gsum += g;
        }
        for (dy, &pj) in dout[..na].iter_mut().zip(&p) {
            *dy -= pj * gsum;
        }
        let (l, g) = value_loss(out[na], d.values[i], d.returns[i], cfg, inv_n);
        dout[na] = g;
        v_sum += l;
        if let Some((vals, rets)) = d.int {
            let (l, g) = value_loss(out[na + 1], vals[i], rets[i], cfg, inv_n);
            dout[na + 1] = g;
            v_sum += l;
        }

        pg_sum += pg1.max(pg2);
        ent_sum += ent;
        kl_sum += (ratio - 1.0) - logratio;
        clipped += ((ratio - 1.0).abs() > cfg.clip) as usize;

        // Backward through the heads: dh2 = sum_k dout_k * head_k.
        add(dhb, &dout);
        for (k, &dy) in dout.iter().enumerate() {
            axpy(&mut dht[k * h..(k + 1) * h], dy, &h2);
        }
        dz2.fill(0.0);
        for (k, (t, &x)) in terms.iter_mut().zip(&dout).enumerate() {
            *t = (k as u32, x);
        }
        combine_rows(&mut dz2, ht, &terms[..nh]);
        // Layer 2: dz2, dW2 += h1^T dz2, db2 += dz2, dh1 = dz2 @ W2^T.
        for (y, &z) in dz2.iter_mut().zip(&z2) {
            if z < 0.0 {
                *y = 0.0;
            }
        }
        add(g_b2, &dz2);
        for &(k, x) in h1_terms {
            axpy(&mut g_w2[k as usize * h..(k as usize + 1) * h], x, &dz2);
        }
        let k = nonzero(&dz2, &mut terms);
        dz1.fill(0.0);
        combine_rows(&mut dz1, w2t, &terms[..k]);
        for (y, &z) in dz1.iter_mut().zip(&z1) {
            if z < 0.0 {
                *y = 0.0;
            }
        }
        // Layer 1: bias, flags, embedding rows.
        add(g_b1, &dz1);
        for (k, &x) in fl.iter().enumerate() {
            if x != 0.0 {
                axpy(&mut g_wf[k * h..(k + 1) * h], x, &dz1);
            }
        }
        if d.dense[i] {
            for &r in &rows {
                let r = r as usize;
                add(&mut g_embed[r * h..(r + 1) * h], &dz1);
            }
        } else {
            for &(r, m) in diffs {
                let (r, m) = (r as usize, m as usize);
                add(&mut g_embed[r * h..(r + 1) * h], &dz1);
                sub(&mut g_embed[m * h..(m + 1) * h], &dz1);
            }
            add(&mut dz1_sparse, &dz1);
        }
    }
    for &m in &d.mode_rows {
        let m = m as usize;
        add(&mut g_embed[m * h..(m + 1) * h], &dz1_sparse);
    }

    // The heads' gradient back into the parameter layout.
    for j in 0..h {
        for k in 0..na {
            l.g[o.wp + j * na + k] = l.dht[k * h + j];
        }
        l.g[o.wv + j] = l.dht[na * h + j];
        if s.int_value {
            l.g[o.wvi + j] = l.dht[(na + 1) * h + j];
        }
    }
    l.g[o.bp..o.bp + na].copy_from_slice(&l.dhb[..na]);
    l.g[o.bv] = l.dhb[na];
    if s.int_value {
        l.g[o.bvi] = l.dhb[na + 1];
    }

    Stats {
        policy_loss: pg_sum * inv_n,
        value_loss: v_sum * inv_n,
        entropy: ent_sum * inv_n,
        approx_kl: kl_sum / n as f32,
        clip_frac: clipped as f32 / n as f32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::net::{logprob_entropy, Net};
    use crate::ppo::{clipped_grads, loss, Minibatch};
    use candle_core::Device;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    struct Rollout {
        glyphs: Vec<u8>,
        flags: Vec<u8>,
        actions: Vec<u32>,
        logprobs: Vec<f32>,
        values: Vec<f32>,
        advantages: Vec<f32>,
        returns: Vec<f32>,
    }

    /// Observations: grids that differ from one random grid in a few cells (as a world's
    /// observations do), every fourth one random throughout (summed directly); old
    /// log-probs and values near the network's own so that ratios fall inside and outside
    /// the clip range, and values on both sides of the value clip.
    fn rollout(net: &Net, n: usize, seed: u64) -> Rollout {
        let s = net.shape;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let grid: Vec<u8> = (0..s.cells)
            .map(|_| rng.random_range(0..s.glyphs as u8))
            .collect();
        let mut glyphs = Vec::with_capacity(n * s.cells);
        for i in 0..n {
            let mut g = grid.clone();
            if i % 4 == 3 {
                g.iter_mut()
                    .for_each(|x| *x = rng.random_range(0..s.glyphs as u8));
            } else {
                for _ in 0..3 {
                    g[rng.random_range(0..s.cells)] = rng.random_range(0..s.glyphs as u8);
                }
            }
            glyphs.extend(g);
        }
        let flags: Vec<u8> = (0..n * s.flags).map(|_| rng.random_range(0..2u8)).collect();
        let actions: Vec<u32> = (0..n)
            .map(|_| rng.random_range(0..s.actions as u32))
            .collect();
        let obs = net.batch(&glyphs, &flags).unwrap();
        let (logits, value) = net.forward(&obs).unwrap();
        let at = Tensor::from_slice(&actions, n, &Device::Cpu).unwrap();
        let (lp, _) = logprob_entropy(&logits, &at).unwrap();
        let lp: Vec<f32> = lp.to_vec1().unwrap();
        let value: Vec<f32> = value.to_vec1().unwrap();
        Rollout {
            logprobs: lp
                .iter()
                .map(|x| x + rng.random_range(-0.4f32..0.4))
                .collect(),
            values: value
                .iter()
                .map(|x| x + rng.random_range(-0.5f32..0.5))
                .collect(),
            advantages: (0..n).map(|_| rng.random_range(-2.0f32..2.0)).collect(),
            returns: (0..n).map(|_| rng.random_range(-1.0f32..1.0)).collect(),
            glyphs,
            flags,
            actions,
        }
    }

    fn shapes() -> Vec<NetShape> {
        vec![
            NetShape {
                cells: 6,
                glyphs: 4,
                flags: 3,
                hidden: 5,
                actions: 4,
                int_value: false,
            },
            NetShape {
                cells: 20,
                glyphs: 7,
                flags: 4,
                hidden: 40,
                actions: 6,
                int_value: false,
            },
            NetShape {
                cells: 30,
                glyphs: 9,
                flags: 6,
                hidden: 64,
                actions: 7,
                int_value: false,
            },
        ]
    }

    fn close(a: f32, b: f32, tol: f32) -> bool {
        (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
    }

    #[test]
    fn gradient_and_stats_match_candle_autograd() {
        check_gradient(false, PpoConfig::default());
        // CleanRL's exact setting: no advantage floor.
        check_gradient(false, crate::ppo::Preset::CleanRl.ppo());
    }

    /// The RLlib preset's loss: advantages as given (normalised over the batch before),
    /// RLlib's value loss `min((v - R)^2, 10)`, the KL penalty; with and without the mask.
    #[test]
    fn rllib_gradient_and_stats_match_candle_autograd() {
        let cfg = PpoConfig {
            // Small enough that some squared errors exceed it (both sides of the min).
            vf_loss_clip: 0.3,
            ..crate::ppo::Preset::Rllib.ppo()
        };
        check_gradient(false, cfg);
        check_gradient(true, cfg);
    }

    /// With the action mask: the candle path adds `MASKED_LOGIT` to the removed actions'
    /// logits (probability exactly 0), the fused path skips them; entropy, log-probs and
    /// every gradient agree, and the removed actions' logits get no gradient.
    #[test]
    fn masked_gradient_and_stats_match_candle_autograd() {
        check_gradient(true, PpoConfig::default());
    }

    /// Redraw a rollout's actions among those its flags allow (with the masked
    /// distribution's log-probs, perturbed as `rollout` does).
    fn mask_rollout(net: &Net, r: &mut Rollout, seed: u64) {
        let s = net.shape;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for (i, a) in r.actions.iter_mut().enumerate() {
            let m = fulcrum_shared::mask::action_mask(&r.flags[i * s.flags..(i + 1) * s.flags]);
            let ok: Vec<u32> = (0..s.actions as u32).filter(|&k| m >> k & 1 == 1).collect();
            *a = ok[rng.random_range(0..ok.len())];
        }
        let n = r.actions.len();
        let dev = Device::Cpu;
        let obs = net.batch(&r.glyphs, &r.flags).unwrap();
        let bias = crate::net::mask_bias(&r.flags, s.flags, s.actions, &dev).unwrap();
        let logits = (net.forward(&obs).unwrap().0 + bias).unwrap();
        let at = Tensor::from_slice(&r.actions, n, &dev).unwrap();
        let lp: Vec<f32> = logprob_entropy(&logits, &at).unwrap().0.to_vec1().unwrap();
        r.logprobs = lp
            .iter()
            .map(|x| x + rng.random_range(-0.4f32..0.4))
            .collect();
    }

    /// Two value heads: the intrinsic head's clipped value loss against its own returns
    /// adds to the extrinsic one's; every gradient (the new head's included) agrees.
    #[test]
    fn intrinsic_value_head_gradient_matches_candle_autograd() {
        check_gradient_heads(false, PpoConfig::default(), true);
        check_gradient_heads(true, crate::ppo::Preset::Rllib.ppo(), true);
    }

    fn check_gradient(masked: bool, cfg: PpoConfig) {
        check_gradient_heads(masked, cfg, false);
    }

    fn check_gradient_heads(masked: bool, cfg: PpoConfig, int_value: bool) {
        let dev = Device::Cpu;
        for (k, shape) in shapes().into_iter().enumerate() {
            let shape = NetShape { int_value, ..shape };
            // The first shape is no world's (flags != 2n + 2): its mask allows all.
            if masked && k == 0 {
                continue;
            }
            let net = Net::new(shape, 7 + k as u64, &dev).unwrap();
            let n = 37;
            let mut r = rollout(&net, n, 100 + k as u64);
            if masked {
                mask_rollout(&net, &mut r, 300 + k as u64);
            }
            let bias = crate::net::mask_bias(&r.flags, shape.flags, shape.actions, &dev).unwrap();
            // The intrinsic head's old values and returns, on both sides of the clip.
            let mut irng = ChaCha8Rng::seed_from_u64(500 + k as u64);
            let (vals_int, rets_int): (Vec<f32>, Vec<f32>) = if int_value {
                let obs = net.batch(&r.glyphs, &r.flags).unwrap();
                let vi: Vec<f32> = net.forward_all(&obs).unwrap().2.unwrap().to_vec1().unwrap();
                (
                    vi.iter()
                        .map(|x| x + irng.random_range(-0.5f32..0.5))
                        .collect(),
                    (0..n).map(|_| irng.random_range(-1.0f32..1.0)).collect(),
                )
            } else {
                (Vec::new(), Vec::new())
            };
            let (ovi, rti) = (
                Tensor::from_slice(&vals_int, vals_int.len(), &dev).unwrap(),
                Tensor::from_slice(&rets_int, rets_int.len(), &dev).unwrap(),
            );
            // Candle: loss and unclipped gradient.
            let t = |v: &[f32]| Tensor::from_slice(v, v.len(), &dev).unwrap();
            let obs = net.batch(&r.glyphs, &r.flags).unwrap();
            let at = Tensor::from_slice(&r.actions, n, &dev).unwrap();
            let (olp, adv, ret, ov) = (
                t(&r.logprobs),
                t(&r.advantages),
                t(&r.returns),
                t(&r.values),
            );
            let mb = Minibatch {
                obs: &obs,
                actions: &at,
                old_logprob: &olp,
                advantages: &adv,
                returns: &ret,
                old_values: &ov,
                logit_bias: masked.then_some(&bias),
                int: int_value.then_some((&rti, &ovi)),
            };
            let (l, want) = loss(&net, &mb, &cfg).unwrap();
            let (grads, want_norm) = clipped_grads(&net, &l, f32::MAX).unwrap();
            let want_g: Vec<f32> = grads
                .iter()
                .flat_map(|g| g.flatten_all().unwrap().to_vec1::<f32>().unwrap())
                .collect();
            assert!(want.clip_frac > 0.0 && want.clip_frac < 1.0, "{want:?}");
            // Fused.
            let data = Data::new(
                shape,
                &r.glyphs,
                &r.flags,
                &r.actions,
                &r.logprobs,
                &r.values,
                &r.advantages,
                &r.returns,
            )
            .unwrap()
            .with_action_mask(masked)
            .unwrap();
            let data = if int_value {
                data.with_intrinsic(&vals_int, &rets_int).unwrap()
            } else {
                data
            };
            assert!(data.differing_cells() > 0);
            assert!(data.dense_samples() > 0 && data.dense_samples() < n);
            let mut fl = Learner::load(&net, &crate::ppo::Adam::new(&net).unwrap()).unwrap();
            let idx: Vec<usize> = (0..n).collect();
            let got = fl.gradient(&data, &idx, &cfg);
            for (a, b) in [
                (got.policy_loss, want.policy_loss),
                (got.value_loss, want.value_loss),
                (got.entropy, want.entropy),
                (got.approx_kl, want.approx_kl),
                (got.clip_frac, want.clip_frac),
            ] {
                assert!(close(a, b, 1e-5), "{got:?} vs {want:?}");
            }
            assert_eq!(fl.g.len(), want_g.len());
            let scale = want_g.iter().fold(0.0f32, |m, x| m.max(x.abs()));
            for (i, (a, b)) in fl.g.iter().zip(&want_g).enumerate() {
                assert!(
                    (a - b).abs() <= 1e-5 * scale,
                    "shape {k}, grad {i}: {a} vs {b} (max |g| {scale})"
                );
            }
            if masked {
                // An action removed in every sample gets no gradient at its bias.
                let o = Offsets::new(shape);
                let removed = (0..n).fold(u32::MAX, |m, i| {
                    m & !fulcrum_shared::mask::action_mask(
                        &r.flags[i * shape.flags..(i + 1) * shape.flags],
                    )
                });
                for a in (0..shape.actions).filter(|&a| removed >> a & 1 == 1) {
                    assert_eq!(fl.g[o.bp + a], 0.0, "shape {k}, action {a}");
                }
            }
            let norm = fl.clip_and_step(f32::MAX, 0.0);
            assert!(close(norm, want_norm, 1e-5), "{norm} vs {want_norm}");
        }
    }

    #[test]
    fn update_matches_candle_loss_clipping_and_adam() {
        let dev = Device::Cpu;
        for (k, shape) in shapes().into_iter().enumerate() {
            let a = Net::new(shape, 21 + k as u64, &dev).unwrap();
            let b = Net::new(shape, 21 + k as u64, &dev).unwrap();
            let (mut adam_a, mut adam_b) = (
                crate::ppo::Adam::new(&a).unwrap(),
                crate::ppo::Adam::new(&b).unwrap(),
            );
            let n = 64;
            let cfg = PpoConfig::default();
            let mut rng_a = ChaCha8Rng::seed_from_u64(5);
            let mut rng_b = ChaCha8Rng::seed_from_u64(5);
            // Two rollouts: the second uses rows the first did not and leaves rows that
            // only have moments from the first.
            for u in 0..2 {
                let r = rollout(&a, n, 200 + 10 * u + k as u64);
                let d = crate::local::UpdateData {
                    glyphs: &r.glyphs,
                    flags: &r.flags,
                    actions: &r.actions,
                    logprobs: &r.logprobs,
                    values: &r.values,
                    advantages: &r.advantages,
                    returns: &r.returns,
                    action_mask: false,
                    int: None,
                };
                crate::local::update(&a, &mut adam_a, &cfg, 1e-3, &mut rng_a, &d).unwrap();
                reference_update(&b, &mut adam_b, &cfg, 1e-3, &mut rng_b, &d);
            }
            assert_eq!(adam_a.step, adam_b.step);
            let (fa, fb) = (a.flat().unwrap(), b.flat().unwrap());
            for (i, (x, y)) in fa.iter().zip(&fb).enumerate() {
                assert!((x - y).abs() < 2e-5, "shape {k}, weight {i}: {x} vs {y}");
            }
            for (ma, mb) in adam_a.m.iter().zip(&adam_b.m) {
                assert_eq!(ma.dims(), mb.dims());
            }
            // The generator advanced alike (same shuffles).
            assert_eq!(rng_a.random::<u64>(), rng_b.random::<u64>());
        }
    }

    /// The update as candle autograd: `loss`, `clipped_grads`, `Adam::apply`.
    fn reference_update(
        net: &Net,
        adam: &mut crate::ppo::Adam,
        cfg: &PpoConfig,
        lr: f64,
        rng: &mut ChaCha8Rng,
        d: &crate::local::UpdateData,
    ) {
        use rand::seq::SliceRandom;
        let n = d.actions.len();
        let (c, f) = (net.shape.cells, net.shape.flags);
        let mb = n / cfg.minibatches.max(1);
        let mut idx: Vec<usize> = (0..n).collect();
        let dev = Device::Cpu;
        for _ in 0..cfg.epochs {
            idx.shuffle(rng);
            for chunk in idx.chunks(mb.max(1)) {
                let g: Vec<u8> = chunk
                    .iter()
                    .flat_map(|&i| d.glyphs[i * c..(i + 1) * c].iter().copied())
                    .collect();
                let fl: Vec<u8> = chunk
                    .iter()
                    .flat_map(|&i| d.flags[i * f..(i + 1) * f].iter().copied())
                    .collect();
                let pick = |v: &[f32]| {
                    let x: Vec<f32> = chunk.iter().map(|&i| v[i]).collect();
                    Tensor::from_vec(x, chunk.len(), &dev).unwrap()
                };
                let acts: Vec<u32> = chunk.iter().map(|&i| d.actions[i]).collect();
                let obs = net.batch(&g, &fl).unwrap();
                let at = Tensor::from_vec(acts, chunk.len(), &dev).unwrap();
                let (olp, adv, ret, ov) = (
                    pick(d.logprobs),
                    pick(d.advantages),
                    pick(d.returns),
                    pick(d.values),
                );
                let batch = Minibatch {
                    obs: &obs,
                    actions: &at,
                    old_logprob: &olp,
                    advantages: &adv,
                    returns: &ret,
                    old_values: &ov,
                    logit_bias: None,
                    int: None,
                };
                let (l, _) = loss(net, &batch, cfg).unwrap();
                let (grads, _) = clipped_grads(net, &l, cfg.max_grad_norm).unwrap();
                adam.apply(net, &grads, lr).unwrap();
            }
        }
    }

    #[test]
    fn compiled_variants_give_the_same_bits() {
        let dev = Device::Cpu;
        let shape = shapes()[2];
        let net = Net::new(shape, 3, &dev).unwrap();
        let r = rollout(&net, 48, 9);
        let data = Data::new(
            shape,
            &r.glyphs,
            &r.flags,
            &r.actions,
            &r.logprobs,
            &r.values,
            &r.advantages,
            &r.returns,
        )
        .unwrap();
        let adam = crate::ppo::Adam::new(&net).unwrap();
        let idx: Vec<usize> = (0..48).collect();
        let cfg = PpoConfig::default();
        let mut runs = Vec::new();
        for v in [Simd::None, Simd::Avx2, Simd::Avx512] {
            let mut fl = Learner::load(&net, &adam).unwrap();
            if !fl.set_simd(v) {
                continue;
            }
            let mut stats = Vec::new();
            for _ in 0..3 {
                stats.push(fl.gradient(&data, &idx, &cfg));
                fl.clip_and_step(cfg.max_grad_norm, 1e-3);
            }
            runs.push((v, stats, fl.w.clone(), fl.m.clone(), fl.v.clone()));
        }
        for r in &runs[1..] {
            assert_eq!(r.1, runs[0].1, "{:?}", r.0);
            assert!(
                r.2 == runs[0].2 && r.3 == runs[0].3 && r.4 == runs[0].4,
                "{:?}",
                r.0
            );
        }
    }

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
