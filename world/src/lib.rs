//! fulcrum-world: the tool world of `docs/world.md`, which actors step and the
//! empowerment engine plans over: world files and their parser, the rule table and the
//! exact dynamics (deterministic and stochastic), packed states and their text form,
//! episodes and observations (the whole map or a window around the agent), action
//! masks, and the world generator. No process, file format or shared memory here: those
//! are `fulcrum-contracts`, which builds on this crate.
//!
//! ```
//! use fulcrum_world::{load_world, EAST};
//! let world = load_world("exp1-tree").unwrap();
//! let s = world.step(&world.initial, EAST);
//! assert_eq!((s.x, s.y), (2, 4));
//! ```

/// The built-in worlds (the paper's four, and a small room; and two with chance).
pub mod builtin;
/// Stochastic dynamics: the exact transition distribution, and sampling from it.
pub mod chance;
/// The text form of states (`agent=X,Y holding=... mode=... obj=...`).
pub mod describe;
/// Episodes, task rewards and the learner's observation encoding.
pub mod env;
/// World families: layouts drawn by seed.
pub mod family;
/// Random valid world files.
pub mod generate;
/// A fast hasher for state-keyed maps.
pub mod hash;
/// Which layouts of a family a run trains and is evaluated on; the layouts an actor
/// keeps.
pub mod layouts;
/// Per-mode action masking from the observation's flags.
pub mod mask;
/// World files: parsing and validation with file:line:col errors.
pub mod parse;
/// The packed state.
pub mod state;
/// Which packed states belong to a world.
pub mod valid;
/// What of the map the learner sees: all of it, or a window around the agent.
pub mod view;
/// The world, the rule table and the exact dynamics.
pub mod world;

pub use describe::DescribeError;
pub use env::{Episode, ObsSpec, Outcome};
pub use layouts::{EvalLayouts, LayoutPool, Layouts, HELD_OUT_START};
pub use parse::{load_world, parse_world, WorldError, MAX_HORIZON};
pub use state::{Mode, State, BOULDER_DESTROYED};
pub use view::View;
pub use world::{
    ObjectKind, ObjectSet, Range, Rule, Task, Terrain, ToolChoice, World, APPLY, EAST, NORTH,
    SELECT0, SOUTH, WEST,
};
