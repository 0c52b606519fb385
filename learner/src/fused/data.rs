//! One rollout prepared for the fused update: sizes checked, each sample's cells that
//! differ from the rollout's most frequent grid found (the sparse first layer of
//! [`crate::fused`]), the embedding rows used listed.

use candle_core::{bail, Result};

use fulcrum_contracts::layout::NetShape;

/// One rollout prepared for the update.
#[derive(Debug)]
pub struct Data<'a> {
    /// Glyph grids, (N * C).
    pub(super) glyphs: &'a [u8],
    /// Per cell, the row `c * G + glyph` of its most frequent glyph in the rollout, (C).
    pub(super) mode_rows: Vec<u32>,
    /// Differing cells of the sparse samples: (row, mode row).
    pub(super) diffs: Vec<(u32, u32)>,
    /// Sample i's differing cells are `diffs[diff_at[i]..diff_at[i + 1]]`, (N + 1).
    pub(super) diff_at: Vec<u32>,
    /// Samples summed directly (more than half their cells differ), (N).
    pub(super) dense: Vec<bool>,
    /// Distinct embedding rows used, ascending.
    pub(super) used_rows: Vec<u32>,
    /// Flags as f32, (N * F).
    pub(super) flags: Vec<f32>,
    pub(super) actions: &'a [u32],
    pub(super) logprobs: &'a [f32],
    pub(super) values: &'a [f32],
    pub(super) advantages: &'a [f32],
    pub(super) returns: &'a [f32],
    /// Per sample, the allowed actions ([`fulcrum_world::mask::action_mask`]); `None`
    /// without masking.
    pub(super) masks: Option<Vec<u32>>,
    /// V_int old and the intrinsic returns, with the intrinsic value head.
    pub(super) int: Option<(&'a [f32], &'a [f32])>,
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
            .map(fulcrum_world::mask::action_mask_f32)
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
