//! fulcrum-contracts: the contracts between the processes of a training run, built on
//! the tool world of `fulcrum-world`: the run's configuration (`config.toml`) and its
//! intrinsic reward forms and PPO settings, checkpoint files, the shared-memory layouts
//! of trajectory chunks, weights and service messages and their names, the network's
//! weight layout, what the learner checks in a chunk before it uses it, the typed lines
//! children print for their parents, the one stop flag of a process, and atomic file
//! writes.
//!
//! ```
//! use fulcrum_contracts::intrinsic::{bonus, Intrinsic};
//! // Potential-based shaping pays gamma * Phi(s') - Phi(s); a terminal s' has potential 0.
//! assert_eq!(bonus(Intrinsic::HorizonPotential, 0.5, 2.0, 4.0, false), 0.0);
//! assert_eq!(bonus(Intrinsic::HorizonPotential, 0.5, 2.0, 4.0, true), -2.0);
//! ```

/// Checkpoint files: format, checks, atomic writes (weights, optimiser state, counters).
pub mod checkpoint;
/// Everything the learner checks in a trajectory chunk before it uses any of it.
pub mod chunk_check;
/// A training run's configuration: what `config.toml` holds.
pub mod config;
/// Naming what was being done when an error came, typed.
pub mod context;
/// Atomic file writes that leave device nodes and FIFOs alone.
pub mod fsio;
/// This machine's name.
pub mod host;
/// Intrinsic reward forms (additive, potential-based shaping, count novelty).
pub mod intrinsic;
/// An iceoryx2 failure, typed.
pub mod ipc_error;
/// The network's weight layout, which the learner and the actors share.
pub mod layout;
/// The lines child processes print for their parents, typed both ways.
pub mod lines;
/// Shared-memory message layouts and service names.
pub mod msg;
/// PPO's hyperparameters: the `[ppo]` table of a run's `config.toml`.
pub mod ppo_config;
/// The one stop flag of a process: SIGINT, SIGTERM or a request from within.
pub mod stop;
/// Trajectory chunks and policy weights in shared memory.
pub mod traj;
/// Which packed states and episode records belong to a world.
pub mod valid;

pub use ipc_error::IpcError;
