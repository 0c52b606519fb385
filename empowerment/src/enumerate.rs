//! The reference method (the paper's): enumerate all |A_j|^h action sequences from a
//! state with the world's own step function and count the distinct projections.
//!
//! Needs no state space and shares nothing with set propagation but `World::step` and
//! the projection key, which is what makes it a cross-check. Cost `|A_j|^h` steps per
//! state (depth-first, so memory is only the set of outcomes).

use fulcrum_shared::hash::FastSet;
use fulcrum_shared::{ObjectSet, State, World};

use crate::propagate::project_key;

/// |{ proj_D(T^h(s, a)) : a in A_j^h }|.
pub fn reachable_count(world: &World, s: &State, actions: &[u8], set: &ObjectSet, h: u32) -> usize {
    let mut seen: FastSet<[u16; 16]> = FastSet::default();
    dfs(world, s, actions, set, h, &mut seen);
    seen.len()
}

fn dfs(
    world: &World,
    s: &State,
    actions: &[u8],
    set: &ObjectSet,
    h: u32,
    seen: &mut FastSet<[u16; 16]>,
) {
    if h == 0 {
        seen.insert(project_key(set, s));
        return;
    }
    for &a in actions {
        let n = world.step(s, a);
        dfs(world, &n, actions, set, h - 1, seen);
    }
}

/// E^h in bits by enumeration.
pub fn value(world: &World, s: &State, actions: &[u8], set: &ObjectSet, h: u32) -> f64 {
    (reachable_count(world, s, actions, set, h) as f64).log2()
}
