//! fulcrum-learner: the candle PPO learner.
//!
//! PPO as CleanRL's `ppo.py` with an advantage floor, or RLlib's defaults ([`ppo`]:
//! presets), over the actions each mode allows (`fulcrum_world::mask`), on an
//! actor-critic network whose first layer sums one embedding row per (cell, glyph), with
//! an optional second value head for the intrinsic return ([`net`]), with GAE that tells
//! truncation from termination ([`mod@gae`]). [`local`] trains in one process (the
//! reference loop that the multi-process training of `fulcrum train` distributes),
//! [`process`] is the learner process of that training. What the learner shares with the actors (the weight layout, the
//! run configuration, the checkpoint format) is in `fulcrum_contracts`.

/// Adam with its state in the open, and its loop over flat buffers.
pub mod adam;
/// An update's batch: chunks turned into rewards, advantages and returns.
mod batch;
/// Checkpoints of the candle network and its optimiser.
pub mod checkpoint;
/// The counters a checkpoint of the learner carries.
mod counters;
/// The learner's CSV files: appended under a header, trimmed on resume.
mod csv;
/// What a PPO step reports (losses, entropy, KL, clip fraction).
pub mod diagnostics;
/// Why the learner process failed.
pub mod error;
/// `eval.csv`: evaluations of the policy, by `fulcrum eval` and `train --eval-every`.
pub mod evalcsv;
/// The PPO update on flat buffers (hand-written forward and backward, fused Adam).
pub mod fused;
/// Generalised advantage estimation with termination and truncation.
pub mod gae;
/// `hosts.csv`: per update and host, the chunks used (runs with remote actors).
pub mod hosts;
/// A chunk's way in: copied out of shared memory, then checked whole.
mod intake;
/// Single-process training loop.
pub mod local;
/// `metrics.csv`: one row per update, written and read back.
pub mod metrics;
/// The actor-critic network.
pub mod net;
/// The files of a run directory.
pub mod paths;
/// The learner's shared-memory ports: chunks in, weights out.
mod ports;
/// The PPO loss and gradient clipping on candle tensors.
pub mod ppo;
/// Named sets of PPO settings (fulcrum, CleanRL, RLlib).
pub mod preset;
/// The learner process of `fulcrum train`: gather, update, publish, record, checkpoint.
pub mod process;
/// The running scale of the intrinsic reward.
pub mod running_std;
/// The compiled variants of the inner loops (baseline, AVX2, AVX-512).
pub mod simd;
/// TensorBoard event files beside `metrics.csv` (`RUN/tb/`).
pub mod tensorboard;
/// The beacon-trap detector: an additive run standing where E is high.
pub mod trap;
/// No silent hang and no divergence spread: the finite-weight check, the local
/// actors' deadline in synchronous mode, the notices to the supervisor.
pub mod watch;

pub use gae::{gae, Rollout};
