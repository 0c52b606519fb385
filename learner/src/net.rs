//! The actor-critic network.
//!
//! Input: a `W x H` glyph grid (ids `0..G`) and a flag vector of length F (held tools,
//! mode one-hot; see `fulcrum_world::env`). With C = W * H cells and hidden size H:
//!
//! ```text
//! h1     = relu( sum_c E[c * G + glyph_c] + flags @ Wf + b1 )      E: (C*G, H), Wf: (F, H)
//! h2     = relu( h1 @ W2 + b2 )                                      W2: (H, H)
//! logits = h2 @ Wp + bp                                              Wp: (H, |A|)
//! value  = h2 @ Wv + bv                                              Wv: (H, 1)
//! v_int  = h2 @ Wvi + bvi     (only with the intrinsic value head)   Wvi: (H, 1)
//! ```
//!
//! The first layer sums one embedding row per (cell, glyph): exactly a linear layer on
//! the one-hot grid (C*G inputs, C of them 1), at the cost of C row gathers instead of a
//! (C*G) x H product. Parameters are named by path (`policy.embed`, `policy.l2.w`, ...)
//! so checkpoints stay readable. Initial weights come from our own seeded generator
//! (candle's CPU generator cannot be seeded).

use candle_core::{DType, Device, Result, Storage, Tensor, Var, D};
use fulcrum_contracts::layout::NetShape;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The network's parameters, in a fixed order.
#[derive(Debug)]
pub struct Net {
    /// Sizes.
    pub shape: NetShape,
    /// (name, variable), in checkpoint order.
    pub params: Vec<(String, Var)>,
    device: Device,
}

/// A batch of observations as the network takes them.
#[derive(Debug)]
pub struct ObsBatch {
    /// Embedding row per (sample, cell): `c * G + glyph`, shape (B * C,).
    pub rows: Tensor,
    /// Flags as f32, shape (B, F).
    pub flags: Tensor,
    /// B.
    pub len: usize,
}

fn normal(rng: &mut ChaCha8Rng, n: usize, std: f32) -> Vec<f32> {
    (0..n)
        .map(|_| {
            // Box-Muller.
            let u1: f32 = rng.random::<f32>().max(1e-12);
            let u2: f32 = rng.random();
            std * (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
        })
        .collect()
}

impl Net {
    /// A fresh network, weights drawn from `seed`.
    pub fn new(shape: NetShape, seed: u64, device: &Device) -> Result<Net> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let NetShape {
            cells,
            glyphs,
            flags,
            hidden,
            actions,
            int_value,
        } = shape;
        let fan1 = (cells + flags) as f32;
        let mut params = Vec::new();
        let mut add = |name: &str, data: Vec<f32>, dims: &[usize]| -> Result<()> {
            let t = Tensor::from_vec(data, dims, device)?;
            params.push((name.to_string(), Var::from_tensor(&t)?));
            Ok(())
        };
        // He-style scales for the ReLU layers; a small policy head (near-uniform
        // initial policy) and a unit-scale value head, as CleanRL's orthogonal init.
        add(
            "policy.embed",
            normal(&mut rng, cells * glyphs * hidden, (2.0 / fan1).sqrt()),
            &[cells * glyphs, hidden],
        )?;
        add(
            "policy.flags.w",
            normal(&mut rng, flags * hidden, (2.0 / fan1).sqrt()),
            &[flags, hidden],
        )?;
        add("policy.l1.b", vec![0.0; hidden], &[hidden])?;
        add(
            "policy.l2.w",
            normal(&mut rng, hidden * hidden, (2.0 / hidden as f32).sqrt()),
            &[hidden, hidden],
        )?;
        add("policy.l2.b", vec![0.0; hidden], &[hidden])?;
        add(
            "policy.pi.w",
            normal(&mut rng, hidden * actions, 0.01 / (hidden as f32).sqrt()),
            &[hidden, actions],
        )?;
        add("policy.pi.b", vec![0.0; actions], &[actions])?;
        add(
            "policy.v.w",
            normal(&mut rng, hidden, 1.0 / (hidden as f32).sqrt()),
            &[hidden, 1],
        )?;
        add("policy.v.b", vec![0.0; 1], &[1])?;
        if int_value {
            add(
                "policy.v_int.w",
                normal(&mut rng, hidden, 1.0 / (hidden as f32).sqrt()),
                &[hidden, 1],
            )?;
            add("policy.v_int.b", vec![0.0; 1], &[1])?;
        }
        Ok(Net {
            shape,
            params,
            device: device.clone(),
        })
    }

    fn p(&self, i: usize) -> &Tensor {
        self.params[i].1.as_tensor()
    }

    /// Turn glyph grids (B * C bytes) and flags (B * F bytes) into a batch.
    pub fn batch(&self, glyphs: &[u8], flags: &[u8]) -> Result<ObsBatch> {
        let NetShape {
            cells,
            glyphs: g,
            flags: f,
            ..
        } = self.shape;
        let len = glyphs.len() / cells;
        let rows: Vec<u32> = glyphs
            .iter()
            .enumerate()
            .map(|(i, &gl)| ((i % cells) * g + gl as usize) as u32)
            .collect();
        let fl: Vec<f32> = flags.iter().map(|&x| x as f32).collect();
        Ok(ObsBatch {
            rows: Tensor::from_vec(rows, len * cells, &self.device)?,
            flags: Tensor::from_vec(fl, (len, f), &self.device)?,
            len,
        })
    }

    /// Logits (B, |A|) and values (B,).
    pub fn forward(&self, obs: &ObsBatch) -> Result<(Tensor, Tensor)> {
        let (logits, value, _) = self.forward_all(obs)?;
        Ok((logits, value))
    }

    /// Logits (B, |A|), values (B,) and, with the intrinsic head, intrinsic values (B,).
    pub fn forward_all(&self, obs: &ObsBatch) -> Result<(Tensor, Tensor, Option<Tensor>)> {
        let NetShape { cells, hidden, .. } = self.shape;
        let emb = self
            .p(0)
            .index_select(&obs.rows, 0)?
            .reshape((obs.len, cells, hidden))?
            .sum(1)?;
        let h1 = (emb + obs.flags.matmul(self.p(1))?)?
            .broadcast_add(self.p(2))?
            .relu()?;
        let h2 = h1.matmul(self.p(3))?.broadcast_add(self.p(4))?.relu()?;
        let logits = h2.matmul(self.p(5))?.broadcast_add(self.p(6))?;
        let value = h2.matmul(self.p(7))?.broadcast_add(self.p(8))?.squeeze(1)?;
        let value_int = if self.shape.int_value {
            Some(
                h2.matmul(self.p(9))?
                    .broadcast_add(self.p(10))?
                    .squeeze(1)?,
            )
        } else {
            None
        };
        Ok((logits, value, value_int))
    }

    /// All parameters as one flat f32 buffer (the weights actors receive).
    pub fn flat(&self) -> Result<Vec<f32>> {
        let mut out = Vec::with_capacity(self.len());
        for (_, v) in &self.params {
            append_f32(&mut out, v.as_tensor())?;
        }
        Ok(out)
    }

    /// Load a flat buffer made by [`Net::flat`].
    pub fn set_flat(&self, flat: &[f32]) -> Result<()> {
        let mut off = 0;
        for (name, v) in &self.params {
            let n = v.as_tensor().elem_count();
            if off + n > flat.len() {
                candle_core::bail!("weights buffer too short for {name}: {} floats", flat.len());
            }
            v.set(&Tensor::from_slice(
                &flat[off..off + n],
                v.as_tensor().dims(),
                &self.device,
            )?)?;
            off += n;
        }
        if off != flat.len() {
            candle_core::bail!(
                "weights buffer has {} floats, the network {off}",
                flat.len()
            );
        }
        Ok(())
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.params
            .iter()
            .map(|(_, v)| v.as_tensor().elem_count())
            .sum()
    }

    /// Never true.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The device.
    pub fn device(&self) -> &Device {
        &self.device
    }
}

/// Append an f32 tensor's elements (row-major) to `out`: straight from the storage when
/// it is a contiguous CPU tensor (no intermediate vector), else through `to_vec1`.
pub fn append_f32(out: &mut Vec<f32>, t: &Tensor) -> Result<()> {
    if t.dtype() == DType::F32 {
        let (storage, layout) = t.storage_and_layout();
        if let (Storage::Cpu(cpu), Some((a, b))) = (&*storage, layout.contiguous_offsets()) {
            out.extend_from_slice(&cpu.as_slice::<f32>()?[a..b]);
            return Ok(());
        }
    }
    out.extend(t.flatten_all()?.to_dtype(DType::F32)?.to_vec1::<f32>()?);
    Ok(())
}

/// The logit bias of an action the mask removes: finite, so that `p * log p` is
/// `0 * (-1e30) = 0` in the entropy (an infinite bias would give NaN there), and large
/// enough that `exp` of it is exactly 0 in f32.
pub const MASKED_LOGIT: f32 = -1e30;

/// Per sample, 0 for the actions [`fulcrum_world::mask::action_mask`] allows and
/// [`MASKED_LOGIT`] for the others: `(n, actions)` for `n` samples of `flags` bytes each.
pub fn mask_bias(flag_bytes: &[u8], flags: usize, actions: usize, dev: &Device) -> Result<Tensor> {
    let n = flag_bytes.len() / flags.max(1);
    let mut b = vec![0.0f32; n * actions];
    for (row, fl) in b
        .chunks_exact_mut(actions.max(1))
        .zip(flag_bytes.chunks_exact(flags.max(1)))
    {
        let m = fulcrum_world::mask::action_mask(fl);
        for (a, x) in row.iter_mut().enumerate() {
            if m >> a & 1 == 0 {
                *x = MASKED_LOGIT;
            }
        }
    }
    Tensor::from_vec(b, (n, actions), dev)
}

/// log softmax over the last dimension.
pub fn log_softmax(logits: &Tensor) -> Result<Tensor> {
    let max = logits.max_keepdim(D::Minus1)?;
    let shifted = logits.broadcast_sub(&max)?;
    let lse = shifted.exp()?.sum_keepdim(D::Minus1)?.log()?;
    shifted.broadcast_sub(&lse)
}

/// log pi(a | s) of the taken actions and the entropy, per sample.
pub fn logprob_entropy(logits: &Tensor, actions: &Tensor) -> Result<(Tensor, Tensor)> {
    let logp = log_softmax(logits)?;
    let taken = logp.gather(&actions.unsqueeze(1)?, 1)?.squeeze(1)?;
    let entropy = (logp.exp()? * &logp)?.sum(1)?.neg()?;
    Ok((taken, entropy))
}

/// Sample one action per row of `logits` with our generator; returns actions and their
/// log-probabilities.
pub fn sample(logits: &Tensor, rng: &mut ChaCha8Rng) -> Result<(Vec<u32>, Vec<f32>)> {
    let logp = log_softmax(&logits.to_dtype(DType::F32)?)?.to_vec2::<f32>()?;
    let mut acts = Vec::with_capacity(logp.len());
    let mut lps = Vec::with_capacity(logp.len());
    for row in logp {
        let u: f32 = rng.random();
        let mut acc = 0.0;
        // The last action with nonzero probability when rounding leaves `u` above the
        // running sum (masked actions have probability 0).
        let mut pick = row
            .iter()
            .rposition(|&lp| lp > MASKED_LOGIT / 2.0)
            .unwrap_or(row.len() - 1);
        for (a, lp) in row.iter().enumerate() {
            acc += lp.exp();
            if u < acc {
                pick = a;
                break;
            }
        }
        acts.push(pick as u32);
        lps.push(row[pick]);
    }
    Ok((acts, lps))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The network's parameters are the shared layout's, name for name and dimension
    /// for dimension (what actors and checkpoints rely on).
    #[test]
    fn parameters_follow_the_shared_layout() {
        for int_value in [false, true] {
            let shape = NetShape {
                cells: 12,
                glyphs: 11,
                flags: 6,
                hidden: 16,
                actions: 7,
                int_value,
            };
            let net = Net::new(shape, 1, &Device::Cpu).unwrap();
            let got: Vec<(&str, Vec<usize>)> = net
                .params
                .iter()
                .map(|(n, v)| (n.as_str(), v.as_tensor().dims().to_vec()))
                .collect();
            assert_eq!(got, shape.params());
        }
    }
}
