//! Which episode records belong to a world.
//!
//! An [`EnvRecord`](crate::traj::EnvRecord) that comes from outside the process (a chunk
//! in shared memory, a checkpoint file) is only bytes until it is checked.
//! [`check_record`](crate::valid::check_record) accepts exactly what the world can hold
//! and refuses the rest with one sentence. Its state must be a state of the world
//! ([`World::check_state`](fulcrum_world::World::check_state)).
//!
//! A valid record holds a valid state, a step count below the world's `max_steps` (an
//! episode that reaches it is reset before the record is written), rewarded bits only
//! for the task's objects, a task return between 0 and the most an episode can earn, a
//! finite intrinsic return, and flag bytes 0 or 1 with zero padding.

use crate::traj::{EnvRecord, ENV_BYTES, OLD_ENV_BYTES};
pub use fulcrum_world::valid::InvalidState;
use fulcrum_world::World;

/// Why an episode record is not one of the world's (one sentence).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InvalidRecord {
    /// Not [`ENV_BYTES`] long.
    #[error("an episode record has {0} bytes, not {ENV_BYTES}")]
    Length(usize),
    /// The state is not one of the world's.
    #[error("its state is not one of the world's: {0}")]
    State(#[from] InvalidState),
    /// Any other field out of range.
    #[error("{0}")]
    Field(String),
}

/// Decode and check one episode record of `world` (see the module docs).
pub fn check_record(world: &World, b: &[u8]) -> Result<EnvRecord, InvalidRecord> {
    let field = |m: String| Err(InvalidRecord::Field(m));
    let Some(r) = (b.len() == ENV_BYTES || b.len() == OLD_ENV_BYTES)
        .then(|| EnvRecord::from_bytes(b))
        .flatten()
    else {
        return Err(InvalidRecord::Length(b.len()));
    };
    world.check_state(&r.episode.state)?;
    if r.episode.t >= world.max_steps {
        return field(format!(
            "its step count {} is not below the world's max_steps {}",
            r.episode.t, world.max_steps
        ));
    }
    if r.episode.rewarded & !world.rewardable() != 0 {
        return field(format!(
            "its rewarded objects {:#06x} are not all objects of the task",
            r.episode.rewarded
        ));
    }
    let max = world.max_episode_reward();
    if !(0.0..=max).contains(&r.ext_return) {
        return field(format!(
            "its task return {} is outside 0..={max}",
            r.ext_return
        ));
    }
    if !r.int_return.is_finite() {
        return field(format!(
            "its intrinsic return {} is not finite",
            r.int_return
        ));
    }
    if b[52] > 1 || b[53] > 1 || b[54..56].iter().any(|&x| x != 0) {
        return field("its flag bytes are not 0 or 1, or its padding is not 0".to_string());
    }
    Ok(r)
}
