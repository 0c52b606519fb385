//! Which packed states and episode records belong to a world.
//!
//! A [`State`](crate::State) or an [`EnvRecord`](crate::traj::EnvRecord) that comes from outside the process (a chunk in shared
//! memory, a checkpoint file) is only bytes until it is checked: the dynamics and the
//! observation index the map with the agent's cell, a boulder's slot and the mode, so a
//! record that no step could have produced would panic the process that uses it.
//! [`World::check_state`](crate::World::check_state) and [`check_record`](crate::valid::check_record) accept exactly what the world can hold,
//! and refuse the rest with one sentence.
//!
//! A valid state has the agent inside the map and on a cell it may stand on, a mode of
//! the world (choosing a direction only for a held tool, choosing a tool only while
//! holding one), inventory bits only for the world's tools, each object's slot one of
//! its kind's conditions (a boulder: a cell of the map or destroyed), unused slots and
//! the reserved byte 0, and nothing standing where it cannot stand (the plausibility
//! rules of a state description, [`World::parse_state`](crate::World::parse_state)). Reachability from the initial
//! state is a stronger property that needs the enumerated state space; the actor asks
//! the empowerment service for it where the run has one.
//!
//! A valid record holds a valid state, a step count below the world's `max_steps` (an
//! episode that reaches it is reset before the record is written), rewarded bits only
//! for the task's objects, a task return between 0 and the most an episode can earn, a
//! finite intrinsic return, and flag bytes 0 or 1 with zero padding.

use crate::state::{State, BOULDER_DESTROYED, MAX_OBJECTS};
use crate::traj::{EnvRecord, ENV_BYTES};
use crate::world::{ObjectKind, Task, World, DESTROYED, INTACT};

/// Why a packed state is not a state of the world (one sentence).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct InvalidState(pub String);

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

impl World {
    /// Whether `s` is a state of this world (see the module docs); never panics,
    /// whatever the bytes.
    pub fn check_state(&self, s: &State) -> Result<(), InvalidState> {
        let bad = |m: String| Err(InvalidState(m));
        let (n_tools, n_obj) = (self.tools.len(), self.objects.len());
        if s.x as usize >= self.width || s.y as usize >= self.height {
            return bad(format!(
                "the agent at {},{} is outside the {}x{} map",
                s.x, s.y, self.width, self.height
            ));
        }
        if s.mode as usize >= 2 + n_tools {
            return bad(format!(
                "mode {} is not a mode of a world with {n_tools} tools",
                s.mode
            ));
        }
        if s.reserved != 0 {
            return bad(format!("the reserved byte is {}, not 0", s.reserved));
        }
        if (s.inventory as u32) >> n_tools != 0 {
            return bad(format!(
                "inventory {:#06x} holds tools beyond the world's {n_tools}",
                s.inventory
            ));
        }
        let cells = self.width * self.height;
        for (i, &v) in s.objects.iter().enumerate().take(MAX_OBJECTS) {
            let Some(o) = self.objects.get(i) else {
                if v != 0 {
                    return bad(format!(
                        "object slot {i} is {v}, but the world has {n_obj} objects"
                    ));
                }
                continue;
            };
            let ok = match o.kind {
                ObjectKind::Boulder => v == BOULDER_DESTROYED || (v as usize) < cells,
                ObjectKind::Door => v <= DESTROYED as u16,
                ObjectKind::Tree | ObjectKind::Wall => v == INTACT as u16 || v == DESTROYED as u16,
            };
            if !ok {
                return bad(format!(
                    "the {}'s slot holds {v}, which is no {} state",
                    o.name,
                    o.kind.name()
                ));
            }
        }
        self.check_plausible(s).map_err(|e| InvalidState(e.0))
    }

    /// The most task reward an episode can earn, and so one step can pay (a destroy
    /// task: each listed object pays once; a push task: 1).
    pub fn max_episode_reward(&self) -> f32 {
        match &self.task {
            Task::None => 0.0,
            Task::Destroy(list) => list.len() as f32,
            Task::Push(_) => 1.0,
        }
    }

    /// Bits of [`crate::Episode::rewarded`] a record may have set: the destroy task's
    /// objects.
    fn rewardable(&self) -> u16 {
        match &self.task {
            Task::Destroy(list) => list.iter().fold(0, |m, &i| m | 1 << i),
            _ => 0,
        }
    }
}

/// Decode and check one episode record of `world` (see the module docs).
pub fn check_record(world: &World, b: &[u8]) -> Result<EnvRecord, InvalidRecord> {
    let field = |m: String| Err(InvalidRecord::Field(m));
    let Some(r) = (b.len() == ENV_BYTES)
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
    if b[52] > 1 || b[53] > 1 || b[54..].iter().any(|&x| x != 0) {
        return field("its flag bytes are not 0 or 1, or its padding is not 0".to_string());
    }
    Ok(r)
}
