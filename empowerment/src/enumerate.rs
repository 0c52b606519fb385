//! The reference method (the paper's): enumerate all |A_j|^h action sequences from a
//! state with the world's own step function and count the distinct projections.
//!
//! Needs no state space and shares nothing with set propagation but `World::step` and
//! the projection key, which is what makes it a cross-check. Cost `|A_j|^h` steps per
//! state (depth-first, so memory is only the set of outcomes).

//!
//! In a stochastic world the reference is [`stochastic_value`]: for every sequence, the
//! exact distribution of proj_D(S_h) by following every outcome of every step with
//! [`World::outcomes`], then Blahut-Arimoto on the rows (no closed form, no pruning).

use fulcrum_world::hash::{FastMap, FastSet};
use fulcrum_world::{ObjectSet, State, World};

use crate::capacity::{blahut_arimoto, Capacity, GAP_BITS};
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

/// E^h in a stochastic world by brute force: every sequence of `actions` of length h,
/// every outcome of each step, one row per sequence, Blahut-Arimoto to
/// [`GAP_BITS`].
pub fn stochastic_value(
    world: &World,
    s: &State,
    actions: &[u8],
    set: &ObjectSet,
    h: u32,
) -> Capacity {
    let mut outputs: FastMap<[u16; 16], usize> = FastMap::default();
    let mut rows: Vec<Vec<(usize, f64)>> = Vec::new();
    let mut seq = vec![0usize; h as usize];
    let mut buf = Vec::new();
    loop {
        // The distribution after this sequence, outcome by outcome.
        let mut cur: Vec<(State, f64)> = vec![(*s, 1.0)];
        for &k in &seq {
            let mut next: Vec<(State, f64)> = Vec::new();
            for &(t, p) in &cur {
                world.outcomes(&t, actions[k], &mut buf);
                for &(u, q) in &buf {
                    match next.iter_mut().find(|e| e.0 == u) {
                        Some(e) => e.1 += p * q,
                        None => next.push((u, p * q)),
                    }
                }
            }
            cur = next;
        }
        let mut row: Vec<(usize, f64)> = Vec::new();
        for (t, p) in cur {
            let n = outputs.len();
            let y = *outputs.entry(project_key(set, &t)).or_insert(n);
            match row.iter_mut().find(|e| e.0 == y) {
                Some(e) => e.1 += p,
                None => row.push((y, p)),
            }
        }
        rows.push(row);
        // The next sequence, in lexicographic order.
        let mut i = seq.len();
        loop {
            if i == 0 {
                let m = outputs.len();
                let mut dense = vec![0.0; rows.len() * m];
                for (x, r) in rows.iter().enumerate() {
                    for &(y, p) in r {
                        dense[x * m + y] += p;
                    }
                }
                return blahut_arimoto(&dense, m, GAP_BITS);
            }
            i -= 1;
            seq[i] += 1;
            if seq[i] < actions.len() {
                break;
            }
            seq[i] = 0;
        }
    }
}
