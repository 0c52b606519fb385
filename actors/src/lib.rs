//! fulcrum-actors: the actor process of `fulcrum train`. An actor steps M worlds in
//! lock-step with its own copy of the policy and writes chunks of T steps into shared
//! memory for the learner, with the intrinsic values of the states reached from the
//! empowerment service ([`actor`] describes a chunk's phases).

/// The actor process: one chunk after another (collect, look up, rewards, send, weights).
pub mod actor;
/// Why an actor failed.
pub mod error;
/// The test hook that sends one bad chunk.
pub mod fault;
/// The policy evaluated on plain buffers (no candle).
pub mod policy;
/// The shared-memory ports an actor opens: chunks out, weights in.
mod ports;
/// The worlds an actor resumes from the run's checkpoint.
mod resume;
/// The seeds of an actor's draws, one per chunk.
mod seeds;
/// Connecting to the empowerment service and the pipelined lookups.
mod service;
/// New weights from the learner into the policy.
mod weights;
/// The worlds an actor's envs play: one world, or a family's layouts.
mod worlds;

pub use actor::{run_actor, ActorId};
pub use error::ActorError;
pub use policy::Policy;
pub use seeds::chunk_seed;
pub use service::{SERVICE_START_LIMIT, SERVICE_WAIT};
