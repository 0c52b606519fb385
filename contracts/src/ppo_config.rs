//! The `[ppo]` table of a run's `config.toml`: PPO's hyperparameters, which the learner
//! trains with and the actors read (the discount of potential-based shaping).

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
