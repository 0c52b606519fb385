//! Which packed states belong to a world.
//!
//! A [`State`] that comes from outside the process (a chunk in shared memory, a
//! checkpoint file) is only bytes until it is checked: the dynamics and the observation
//! index the map with the agent's cell, a boulder's slot and the mode, so a state that no
//! step could have produced would panic the process that uses it.
//! [`World::check_state`] accepts exactly what the world can hold, and refuses the rest
//! with one sentence.
//!
//! A valid state has the agent inside the map and on a cell it may stand on, a mode of
//! the world (choosing a direction only for a held tool, choosing a tool only while
//! holding one), inventory bits only for the world's tools, each object's slot one of
//! its kind's conditions (a boulder: a cell of the map or destroyed), unused slots and
//! the reserved byte 0, and nothing standing where it cannot stand (the plausibility
//! rules of a state description, [`World::parse_state`]). Reachability from the initial
//! state is a stronger property that needs the enumerated state space; the actor asks
//! the empowerment service for it where the run has one.

use crate::state::{State, BOULDER_DESTROYED, MAX_OBJECTS};
use crate::world::{ObjectKind, Task, World, DESTROYED, INTACT};

/// Why a packed state is not a state of the world (one sentence).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct InvalidState(pub String);

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

    /// Bits of [`Episode::rewarded`](crate::Episode::rewarded) a record may have set: the destroy task's
    /// objects.
    pub fn rewardable(&self) -> u16 {
        match &self.task {
            Task::Destroy(list) => list.iter().fold(0, |m, &i| m | 1 << i),
            _ => 0,
        }
    }
}
