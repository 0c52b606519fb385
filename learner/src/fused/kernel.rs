//! The hand-written forward and backward pass of one minibatch (the math of
//! [`crate::fused`]'s module docs), and the dense loops it is made of.

use fulcrum_contracts::ppo_config::PpoConfig;

use super::{Data, Learner};
use crate::diagnostics::Stats;

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f")]
pub(super) fn gradient_avx512(l: &mut Learner, d: &Data, idx: &[usize], cfg: &PpoConfig) -> Stats {
    gradient_generic(l, d, idx, cfg)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(super) fn gradient_avx2(l: &mut Learner, d: &Data, idx: &[usize], cfg: &PpoConfig) -> Stats {
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
pub(super) fn gradient_generic(l: &mut Learner, d: &Data, idx: &[usize], cfg: &PpoConfig) -> Stats {
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

/// Sum of squares (f32 partial sums in 16 lanes, added in f64).
#[inline(always)]
pub(super) fn sum_sq(x: &[f32]) -> f64 {
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
