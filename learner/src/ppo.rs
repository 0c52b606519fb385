//! PPO (clipped surrogate), as CleanRL's `ppo.py`.
//!
//! For a minibatch with advantages A (normalised to mean 0 and divided by the larger of
//! their std and [`PpoConfig::adv_std_floor`]), old log-probs
//! `lp_old`, old values `v_old` and returns R:
//!
//! ```text
//! ratio  = exp(lp - lp_old)
//! L_pi   = mean( max(-A * ratio, -A * clip(ratio, 1 - eps, 1 + eps)) )
//! L_v    = 0.5 * mean( max((v - R)^2, (v_old + clip(v - v_old, -eps, eps) - R)^2) )
//! L      = L_pi - c_ent * mean(entropy) + c_v * L_v
//! ```
//!
//! With the intrinsic value head, `L_v` is the sum of the two heads' value losses (each
//! against its own returns and old values).
//!
//! With the RLlib preset ([`Preset::Rllib`]) three terms change: advantages are
//! standardised once over the batch, `L_v = mean( min((v - R)^2, vf_loss_clip) )`, and a
//! KL penalty `c_kl * mean((ratio - 1) - log ratio)` is added, c_kl adapting after each
//! update ([`PpoConfig::adapt_kl`]).
//!
//! minimised by Adam (our own, so that its moments and step are checkpointed) after
//! clipping the global gradient norm; the learning rate is annealed linearly to 0 over
//! the run.
//!
//! [`PpoConfig::adv_std_floor`]: fulcrum_contracts::ppo_config::PpoConfig::adv_std_floor
//! [`Preset::Rllib`]: crate::preset::Preset::Rllib
//! [`PpoConfig::adapt_kl`]: fulcrum_contracts::ppo_config::PpoConfig::adapt_kl

use candle_core::{Result, Tensor};

use crate::diagnostics::Stats;
use crate::net::{logprob_entropy, Net, ObsBatch};
use fulcrum_contracts::ppo_config::PpoConfig;

/// One minibatch's data.
#[derive(Debug)]
pub struct Minibatch<'a> {
    /// Observations.
    pub obs: &'a ObsBatch,
    /// Actions taken (u32), shape (B,).
    pub actions: &'a Tensor,
    /// log pi_old(a|s), (B,).
    pub old_logprob: &'a Tensor,
    /// Advantages (raw; normalised here), (B,).
    pub advantages: &'a Tensor,
    /// Returns (value targets), (B,).
    pub returns: &'a Tensor,
    /// V_old(s), (B,).
    pub old_values: &'a Tensor,
    /// Added to the logits before the softmax, (B, |A|): 0 where an action is allowed,
    /// [`crate::net::MASKED_LOGIT`] where the action mask removes it; `None` unmasked.
    pub logit_bias: Option<&'a Tensor>,
    /// With the intrinsic value head: its returns and old values, (B,) each.
    pub int: Option<(&'a Tensor, &'a Tensor)>,
}

/// The loss of a minibatch and its diagnostics.
pub fn loss(net: &Net, mb: &Minibatch, cfg: &PpoConfig) -> Result<(Tensor, Stats)> {
    let (logits, value, value_int) = net.forward_all(mb.obs)?;
    let logits = match mb.logit_bias {
        Some(b) => (logits + b)?,
        None => logits,
    };
    let (lp, ent) = logprob_entropy(&logits, mb.actions)?;
    let logratio = (&lp - mb.old_logprob)?;
    let ratio = logratio.exp()?;
    let adv = mb.advantages;
    let n = adv.elem_count();
    let adv = if cfg.adv_norm_batch {
        // Normalised over the whole batch before the minibatches were cut.
        adv.clone()
    } else {
        let mean = adv.mean_all()?;
        let centred = adv.broadcast_sub(&mean)?;
        // Unbiased std, as torch's default.
        let std = (centred.sqr()?.sum_all()? / ((n.max(2) - 1) as f64))?
            .sqrt()?
            .maximum(cfg.adv_std_floor as f64)?;
        centred.broadcast_div(&(std + 1e-8)?)?
    };
    let pg1 = (adv.neg()? * &ratio)?;
    let pg2 = (adv.neg()? * ratio.clamp(1.0 - cfg.clip, 1.0 + cfg.clip)?)?;
    let pg = pg1.maximum(&pg2)?.mean_all()?;
    let value_loss = |value: &Tensor, returns: &Tensor, old_values: &Tensor| -> Result<Tensor> {
        let v_unclipped = (value - returns)?.sqr()?;
        if cfg.vf_loss_clip > 0.0 {
            v_unclipped.minimum(cfg.vf_loss_clip as f64)?.mean_all()
        } else {
            let v_clipped = (old_values + (value - old_values)?.clamp(-cfg.clip, cfg.clip)?)?;
            (v_clipped - returns)?
                .sqr()?
                .maximum(&v_unclipped)?
                .mean_all()?
                * 0.5
        }
    };
    let mut v_loss = value_loss(&value, mb.returns, mb.old_values)?;
    if let (Some(vi), Some((ri, oi))) = (&value_int, mb.int) {
        v_loss = (v_loss + value_loss(vi, ri, oi)?)?;
    }
    let ent_mean = ent.mean_all()?;
    let mut total =
        ((&pg - (&ent_mean * cfg.ent_coef as f64)?)? + (&v_loss * cfg.vf_coef as f64)?)?;
    if cfg.kl_coef != 0.0 {
        let k3 = ((&ratio - 1.0)? - &logratio)?.mean_all()?;
        total = (total + (k3 * cfg.kl_coef as f64)?)?;
    }
    let r: Vec<f32> = ratio.to_vec1()?;
    let lr: Vec<f32> = logratio.to_vec1()?;
    let kl = r.iter().zip(&lr).map(|(r, l)| (r - 1.0) - l).sum::<f32>() / n as f32;
    let cf = r.iter().filter(|r| (*r - 1.0).abs() > cfg.clip).count() as f32 / n as f32;
    Ok((
        total,
        Stats {
            policy_loss: pg.to_scalar()?,
            value_loss: v_loss.to_scalar()?,
            entropy: ent_mean.to_scalar()?,
            approx_kl: kl,
            clip_frac: cf,
        },
    ))
}

/// Gradients of `loss` in parameter order, clipped to a global norm of `max_norm`.
/// Returns them and the norm before clipping.
pub fn clipped_grads(net: &Net, loss: &Tensor, max_norm: f32) -> Result<(Vec<Tensor>, f32)> {
    let store = loss.backward()?;
    let mut grads = Vec::with_capacity(net.params.len());
    for (_, v) in &net.params {
        grads.push(match store.get(v.as_tensor()) {
            Some(g) => g.clone(),
            None => v.as_tensor().zeros_like()?,
        });
    }
    let mut sq = 0.0f32;
    for g in &grads {
        sq += g.sqr()?.sum_all()?.to_scalar::<f32>()?;
    }
    let norm = sq.sqrt();
    if norm > max_norm {
        let s = (max_norm / (norm + 1e-6)) as f64;
        for g in &mut grads {
            *g = (&*g * s)?;
        }
    }
    Ok((grads, norm))
}

// Their old paths: the optimiser, the presets and the hyperparameters lived here.
