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

use candle_core::{Result, Tensor};

use crate::fused::{adam_slices, AdamStep};
use crate::net::{logprob_entropy, Net, ObsBatch};

/// PPO hyperparameters (CleanRL's defaults).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PpoConfig {
    /// Discount.
    pub gamma: f32,
    /// GAE lambda.
    pub gae_lambda: f32,
    /// Clip range for the ratio and the value.
    pub clip: f32,
    /// Entropy coefficient.
    pub ent_coef: f32,
    /// Value-loss coefficient.
    pub vf_coef: f32,
    /// Epochs per update.
    pub epochs: usize,
    /// Minibatches per epoch.
    pub minibatches: usize,
    /// Global gradient-norm limit.
    pub max_grad_norm: f32,
    /// Adam learning rate at the start (annealed to 0).
    pub lr: f64,
    /// The smallest standard deviation advantages are divided by in a minibatch's
    /// normalisation: A_norm = (A - mean) / (max(std, floor) + 1e-8). CleanRL's has no
    /// floor (0), so that a minibatch without any reward, whose advantages are the
    /// value function's noise, still makes a full-size policy update; that drift,
    /// unchecked by the entropy bonus, collapsed the policy's entropy before it ever
    /// saw the task's reward on exp3. A floor on the scale of the rewards (0.1 of a task
    /// reward of 1) leaves updates from real returns as they were and makes updates from
    /// noise small. Missing in configurations written before it existed: 0.
    #[serde(default)]
    pub adv_std_floor: f32,
    /// Whether the learning rate falls linearly to 0 over the run (CleanRL) or stays
    /// at `lr` (RLlib).
    #[serde(default = "yes")]
    pub lr_anneal: bool,
    /// Normalise advantages once over the whole batch (RLlib's `standardize_fields`)
    /// instead of per minibatch (CleanRL).
    #[serde(default)]
    pub adv_norm_batch: bool,
    /// RLlib's value loss when > 0: `min((v - R)^2, vf_loss_clip)` without the 0.5 and
    /// without CleanRL's clipping of v around V_old; 0 = CleanRL's clipped value loss.
    #[serde(default)]
    pub vf_loss_clip: f32,
    /// The KL penalty's coefficient at the start (RLlib's `kl_coeff`; 0 = no penalty).
    /// The penalty is `kl_coef * mean((ratio - 1) - log ratio)`, the sample estimate of
    /// KL(pi_old || pi) under the old policy's actions (RLlib computes the exact KL
    /// from the old logits, which fulcrum's chunks do not carry).
    #[serde(default)]
    pub kl_coef: f32,
    /// The KL the coefficient adapts to after each update (RLlib: x1.5 when the mean KL
    /// of the update is above twice the target, x0.5 when below half of it).
    #[serde(default = "kl_target")]
    pub kl_target: f32,
}

fn yes() -> bool {
    true
}

fn kl_target() -> f32 {
    0.01
}

/// Named sets of PPO settings (`train --ppo-preset`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preset {
    /// CleanRL's `ppo.py` with fulcrum's advantage floor (the default).
    Fulcrum,
    /// CleanRL's `ppo.py` exactly (no advantage floor).
    CleanRl,
    /// RLlib's PPO defaults, the paper's learner: lr 5e-5 constant, batch 4096
    /// (RLlib: 4000), 30 epochs of minibatches of 128, lambda 1.0, clip 0.3, no entropy
    /// bonus, the KL penalty (0.2, target 0.01), value loss coefficient 1 clipped at 10,
    /// advantages standardised over the batch, no gradient clipping. RLlib's separate
    /// value network is not reproduced: fulcrum's value head shares the torso.
    Rllib,
}

impl std::str::FromStr for Preset {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "fulcrum" => Ok(Preset::Fulcrum),
            "cleanrl" => Ok(Preset::CleanRl),
            "rllib" => Ok(Preset::Rllib),
            _ => Err(format!(
                "unknown PPO preset '{s}' (presets: fulcrum, cleanrl, rllib)"
            )),
        }
    }
}

impl Preset {
    /// The preset's PPO settings.
    pub fn ppo(self) -> PpoConfig {
        let d = PpoConfig::default();
        match self {
            Preset::Fulcrum => d,
            Preset::CleanRl => PpoConfig {
                adv_std_floor: 0.0,
                ..d
            },
            Preset::Rllib => PpoConfig {
                gamma: 0.99,
                gae_lambda: 1.0,
                clip: 0.3,
                ent_coef: 0.0,
                vf_coef: 1.0,
                epochs: 30,
                minibatches: 32,
                max_grad_norm: f32::INFINITY,
                lr: 5e-5,
                adv_std_floor: 1e-4,
                lr_anneal: false,
                adv_norm_batch: true,
                vf_loss_clip: 10.0,
                kl_coef: 0.2,
                kl_target: 0.01,
            },
        }
    }

    /// Steps per chunk of the preset with 8 worlds per actor and one actor (RLlib's
    /// batch of about 4000: 8 x 512), or `None` to keep train's default.
    pub fn steps_per_chunk(self) -> Option<usize> {
        (self == Preset::Rllib).then_some(512)
    }
}

impl PpoConfig {
    /// The learning rate of update `u` of `updates` (0-based).
    pub fn lr_at(&self, u: u64, updates: u64) -> f64 {
        if self.lr_anneal {
            self.lr * (1.0 - u as f64 / updates.max(1) as f64)
        } else {
            self.lr
        }
    }

    /// The KL coefficient after an update whose mean KL was `kl` (RLlib's rule).
    pub fn adapt_kl(&self, coef: f32, kl: f32) -> f32 {
        if coef == 0.0 || !kl.is_finite() {
            coef
        } else if kl > 2.0 * self.kl_target {
            coef * 1.5
        } else if kl < 0.5 * self.kl_target {
            coef * 0.5
        } else {
            coef
        }
    }
}

impl Default for PpoConfig {
    fn default() -> Self {
        PpoConfig {
            gamma: 0.99,
            gae_lambda: 0.95,
            clip: 0.2,
            ent_coef: 0.01,
            vf_coef: 0.5,
            epochs: 4,
            minibatches: 4,
            max_grad_norm: 0.5,
            lr: 2.5e-4,
            adv_std_floor: 0.1,
            lr_anneal: true,
            adv_norm_batch: false,
            vf_loss_clip: 0.0,
            kl_coef: 0.0,
            kl_target: 0.01,
        }
    }
}

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
    /// ([`crate::fused::adam_slices`]: subnormal moments become 0, the weights unchanged).
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

/// Diagnostics of one minibatch step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Stats {
    /// L_pi.
    pub policy_loss: f32,
    /// L_v (with the 0.5).
    pub value_loss: f32,
    /// Mean entropy.
    pub entropy: f32,
    /// mean((ratio - 1) - log ratio).
    pub approx_kl: f32,
    /// Fraction of samples with |ratio - 1| > clip.
    pub clip_frac: f32,
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
