//! fulcrum-shared: the tool world of `docs/world.md`, which actors step and the empowerment
//! engine plans over, and the contracts between the processes of `fulcrum train`
//! (shared-memory messages, the network's weight layout, the run's configuration,
//! checkpoint files).
//!
//! ```
//! use fulcrum_shared::{load_world, EAST};
//! let world = load_world("exp1-tree").unwrap();
//! let s = world.step(&world.initial, EAST);
//! assert_eq!((s.x, s.y), (2, 4));
//! ```

/// The built-in worlds (the paper's four, and a small room; and two with chance).
pub mod builtin;
/// Stochastic dynamics: the exact transition distribution, and sampling from it.
pub mod chance;
/// Checkpoint files: format, checks, atomic writes (weights, optimiser state, counters).
pub mod checkpoint;
/// Everything the learner checks in a trajectory chunk before it uses any of it.
pub mod chunk_check;
/// A training run's configuration: what `config.toml` holds.
pub mod config;
/// The text form of states (`agent=X,Y holding=... mode=... obj=...`).
pub mod describe;
/// Episodes, task rewards and the learner's observation encoding.
pub mod env;
/// Atomic file writes that leave device nodes and FIFOs alone.
pub mod fsio;
/// Random valid world files.
pub mod generate;
/// A fast hasher for state-keyed maps.
pub mod hash;
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
/// Per-mode action masking from the observation's flags.
pub mod mask;
/// Shared-memory message layouts and service names.
pub mod msg;
/// World files: parsing and validation with file:line:col errors.
pub mod parse;
/// PPO's hyperparameters: the `[ppo]` table of a run's `config.toml`.
pub mod ppo_config;
/// The packed state.
pub mod state;
/// The one stop flag of a process: SIGINT, SIGTERM or a request from within.
pub mod stop;
/// Trajectory chunks and policy weights in shared memory.
pub mod traj;
/// Which packed states and episode records belong to a world.
pub mod valid;
/// What of the map the learner sees: all of it, or a window around the agent.
pub mod view;
/// The world, the rule table and the exact dynamics.
pub mod world;

pub use describe::DescribeError;
pub use env::{Episode, ObsSpec, Outcome};
pub use ipc_error::IpcError;
pub use parse::{load_world, parse_world, WorldError, MAX_HORIZON};
pub use state::{Mode, State, BOULDER_DESTROYED};
pub use view::View;
pub use world::{
    ObjectKind, ObjectSet, Range, Rule, Task, Terrain, ToolChoice, World, APPLY, EAST, NORTH,
    SELECT0, SOUTH, WEST,
};
