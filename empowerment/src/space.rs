//! The state space: every state reachable from the initial one, with dense ids and a
//! successor table.
//!
//! Breadth-first search over all |A| actions, level by level: the successors of a level
//! are computed in parallel (rayon), then deduplicated in one hash map in id order, so
//! ids are deterministic (BFS order) whatever the thread count.
//!
//! Memory: `states` (38 B each), the successor table (`4 |A|` B each) and the index
//! (about 60 B each): roughly `100 + 4 |A|` bytes per state.

use std::collections::hash_map::Entry;

use fulcrum_shared::hash::FastMap;
use fulcrum_shared::{Mode, State, World};
use rayon::prelude::*;

use crate::error::EngineError;
use crate::limits::Limits;

/// An enumerated state space with its successor table.
#[derive(Debug)]
pub struct StateSpace {
    states: Vec<State>,
    index: FastMap<State, u32>,
    succ: Vec<u32>,
    actions: usize,
}

/// Bytes one state costs in a [`StateSpace`] with `actions` actions.
pub fn bytes_per_state(actions: usize) -> usize {
    38 + 4 * actions + 64
}

impl StateSpace {
    /// Enumerate the states reachable from `world.initial`. Refuses, with the estimate,
    /// when the space would outgrow `limits.max_bytes`.
    pub fn enumerate(world: &World, limits: &Limits) -> Result<StateSpace, EngineError> {
        let na = world.num_actions();
        let max_states = (limits.max_bytes / bytes_per_state(na)).min(u32::MAX as usize - 1);
        let mut states = vec![world.initial];
        let mut index = FastMap::default();
        index.insert(world.initial, 0u32);
        let mut succ: Vec<u32> = Vec::new();
        let mut start = 0;
        while start < states.len() {
            let end = states.len();
            let level = &states[start..end];
            // Small levels are cheaper on one thread than split across the pool.
            let next: Vec<State> = if level.len() >= 2048 {
                level
                    .par_iter()
                    .flat_map_iter(|s| (0..na as u8).map(move |a| world.step(s, a)))
                    .collect()
            } else {
                level
                    .iter()
                    .flat_map(|s| (0..na as u8).map(move |a| world.step(s, a)))
                    .collect()
            };
            succ.reserve(next.len());
            for ns in next {
                let id = match index.entry(ns) {
                    Entry::Occupied(e) => *e.get(),
                    Entry::Vacant(e) => {
                        let id = states.len() as u32;
                        e.insert(id);
                        states.push(ns);
                        id
                    }
                };
                succ.push(id);
            }
            if states.len() > max_states {
                return Err(EngineError::StateSpaceTooLarge {
                    world: world.name.clone(),
                    states: states.len(),
                    bytes: states.len() * bytes_per_state(na),
                    limit: limits.max_bytes,
                });
            }
            start = end;
        }
        Ok(StateSpace {
            states,
            index,
            succ,
            actions: na,
        })
    }

    /// Number of states.
    pub fn len(&self) -> usize {
        self.states.len()
    }

    /// Never true: the initial state is always there.
    pub fn is_empty(&self) -> bool {
        self.states.is_empty()
    }

    /// |A|.
    pub fn num_actions(&self) -> usize {
        self.actions
    }

    /// All states by id.
    pub fn states(&self) -> &[State] {
        &self.states
    }

    /// The state with id `i`.
    pub fn state(&self, i: u32) -> &State {
        &self.states[i as usize]
    }

    /// The id of a state, if it is in the space.
    pub fn id(&self, s: &State) -> Option<u32> {
        self.index.get(s).copied()
    }

    /// The id of T(s_i, a).
    #[inline]
    pub fn succ(&self, i: u32, a: u8) -> u32 {
        self.succ[i as usize * self.actions + a as usize]
    }

    /// The successor table, `len() x num_actions()` row-major.
    pub fn succ_table(&self) -> &[u32] {
        &self.succ
    }

    /// Ids of the normal-mode states.
    pub fn normal_ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.states
            .iter()
            .enumerate()
            .filter(|(_, s)| s.mode() == Mode::Normal)
            .map(|(i, _)| i as u32)
    }

    /// Approximate bytes held.
    pub fn bytes(&self) -> usize {
        self.len() * bytes_per_state(self.actions)
    }
}
