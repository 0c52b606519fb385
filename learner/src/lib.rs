//! fulcrum-learner: the PPO learner (candle, in the training issue). So far: the
//! advantage estimation it will use.

/// Generalised advantage estimation with termination and truncation.
pub mod gae;

pub use gae::{gae, Rollout};
