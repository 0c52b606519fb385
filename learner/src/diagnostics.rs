//! What a PPO step reports: the candle loss (`ppo::loss`) and the fused gradient
//! (`fused::Learner::gradient`) compute the same diagnostics.

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
