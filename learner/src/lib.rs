//! fulcrum-learner: the candle PPO learner.
//!
//! PPO as CleanRL's `ppo.py` with an advantage floor, or RLlib's defaults ([`ppo`]:
//! presets), over the actions each mode allows (`fulcrum_shared::mask`), on an
//! actor-critic network whose first layer sums one embedding row per (cell, glyph), with
//! an optional second value head for the intrinsic return ([`net`]), with GAE that tells
//! truncation from termination ([`gae`]). [`local`] trains in one process (the reference
//! loop that the multi-process training of `fulcrum train` distributes).

/// Checkpoints: weights, optimiser state, counters, written atomically.
pub mod checkpoint;
/// The run configuration (`config.toml`).
pub mod config;
/// The PPO update on flat buffers (hand-written forward and backward, fused Adam).
pub mod fused;
/// Generalised advantage estimation with termination and truncation.
pub mod gae;
/// Single-process training loop.
pub mod local;
/// The actor-critic network.
pub mod net;
/// The PPO loss, Adam and gradient clipping.
pub mod ppo;
/// The learner process of `fulcrum train`.
pub mod run;
/// The running scale of the intrinsic reward.
pub mod running_std;

pub use gae::{gae, Rollout};
