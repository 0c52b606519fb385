//! Exact object empowerment by set propagation.
//!
//! For tool j (action subset A_j), objects D and horizon h:
//!
//! ```text
//! R_0(s) = { proj_D(s) }
//! R_k(s) = U_{a in A_j} R_{k-1}(T(s, a))
//! E^h_{j,D}(s) = log2 |R_h(s)|
//! ```
//!
//! since the projections reachable with h actions from s are those reachable with h-1
//! actions from each successor. Sets are bitsets over the dense ids of D's projected
//! states (`W = ceil(P / 64)` words, P = distinct projections in the space). One pass
//! gives every horizon 1..h.
//!
//! Cost: `h * |S| * |A_j| * W` word ORs, parallel over states (rayon), against
//! `|S| * |A_j|^h` steps for enumerating action sequences. Memory: two tables of
//! `|S| * W` words.

use fulcrum_world::hash::FastMap;
use fulcrum_world::{ObjectSet, State, BOULDER_DESTROYED};
use rayon::prelude::*;

use crate::error::EngineError;
use crate::limits::Limits;
use crate::space::StateSpace;

/// proj_D for every state of a space, as dense ids.
#[derive(Debug, Clone)]
pub struct Projection {
    /// Projection id of each state (by state id).
    pub ids: Vec<u32>,
    /// Number of distinct projections P.
    pub size: usize,
}

/// The key proj_D(s): the agent's cell, or the slots of D's objects (others zeroed);
/// for a set of conditions a boulder's slot is 0 (intact, at any cell) or 1 (destroyed).
#[inline]
pub fn project_key(set: &ObjectSet, s: &State) -> [u16; 16] {
    let mut k = [0u16; 16];
    match set {
        ObjectSet::Agent => {
            k[0] = s.x as u16;
            k[1] = s.y as u16;
        }
        ObjectSet::Objects(list) => {
            for &i in list {
                k[i] = s.objects[i];
            }
        }
        ObjectSet::Conditions { objects, boulders } => {
            for &i in objects {
                let v = s.objects[i];
                k[i] = if boulders >> i & 1 == 1 {
                    (v == BOULDER_DESTROYED) as u16
                } else {
                    v
                };
            }
        }
    }
    k
}

impl Projection {
    /// Project every state of `space` onto `set`.
    pub fn new(space: &StateSpace, set: &ObjectSet) -> Projection {
        let mut map: FastMap<[u16; 16], u32> = FastMap::default();
        // States next to each other in breadth-first order mostly share their
        // projection (the objects change far less often than the agent moves): the last
        // one's id is checked before the map.
        let mut last: Option<([u16; 16], u32)> = None;
        let ids = space
            .states()
            .iter()
            .map(|s| {
                let k = project_key(set, s);
                match last {
                    Some((lk, id)) if lk == k => id,
                    _ => {
                        let n = map.len() as u32;
                        let id = *map.entry(k).or_insert(n);
                        last = Some((k, id));
                        id
                    }
                }
            })
            .collect();
        Projection {
            ids,
            size: map.len(),
        }
    }

    /// 64-bit words per set.
    pub fn words(&self) -> usize {
        self.size.div_ceil(64).max(1)
    }
}

/// Check that a table of this projection fits, and the horizon is allowed.
pub fn check_table(
    space: &StateSpace,
    proj: &Projection,
    hmax: u32,
    what: &str,
    limits: &Limits,
) -> Result<(), EngineError> {
    if hmax > fulcrum_world::MAX_HORIZON {
        return Err(EngineError::HorizonTooLarge {
            h: hmax,
            max: fulcrum_world::MAX_HORIZON,
        });
    }
    let bytes = space.len() * proj.words() * 8 * 2 + space.len() * 4;
    if space.bytes() + bytes > limits.max_bytes {
        return Err(EngineError::TableTooLarge {
            what: what.to_string(),
            states: space.len(),
            words: proj.words(),
            bytes,
            limit: limits.max_bytes,
        });
    }
    Ok(())
}

/// |R_h(s)| for every state and each requested horizon: `counts[k][s]` for
/// `horizons[k]`. The caller checks memory with [`check_table`].
pub fn reachable_counts(
    space: &StateSpace,
    proj: &Projection,
    actions: &[u8],
    horizons: &[u32],
) -> Vec<Vec<u32>> {
    let n = space.len();
    let hmax = horizons.iter().copied().max().unwrap_or(0);
    let mut out: Vec<Vec<u32>> = vec![Vec::new(); horizons.len()];
    let w = proj.words();
    let na = space.num_actions();
    let succ = space.succ_table();
    let record = |k: u32, counts: &dyn Fn() -> Vec<u32>, out: &mut Vec<Vec<u32>>| {
        let mut cached: Option<Vec<u32>> = None;
        for (slot, &h) in horizons.iter().enumerate() {
            if h == k {
                out[slot] = cached.get_or_insert_with(counts).clone();
            }
        }
    };
    if w == 1 {
        // One word per set: the common case (a few objects), kept branch-free.
        let mut cur: Vec<u64> = proj.ids.iter().map(|&p| 1u64 << p).collect();
        let mut next = vec![0u64; n];
        record(0, &|| vec![1; n], &mut out);
        for k in 1..=hmax {
            next.par_iter_mut()
                .with_min_len(1024)
                .enumerate()
                .for_each(|(s, dst)| {
                    let row = &succ[s * na..s * na + na];
                    let mut acc = 0u64;
                    for &a in actions {
                        acc |= cur[row[a as usize] as usize];
                    }
                    *dst = acc;
                });
            std::mem::swap(&mut cur, &mut next);
            record(
                k,
                &|| cur.par_iter().map(|x| x.count_ones()).collect(),
                &mut out,
            );
        }
    } else {
        let mut cur = vec![0u64; n * w];
        for (s, &p) in proj.ids.iter().enumerate() {
            cur[s * w + p as usize / 64] |= 1 << (p % 64);
        }
        let mut next = vec![0u64; n * w];
        record(0, &|| vec![1; n], &mut out);
        for k in 1..=hmax {
            next.par_chunks_mut(w)
                .with_min_len(256)
                .enumerate()
                .for_each(|(s, dst)| {
                    let row = &succ[s * na..s * na + na];
                    dst.fill(0);
                    for &a in actions {
                        let t = row[a as usize] as usize;
                        for (d, x) in dst.iter_mut().zip(&cur[t * w..t * w + w]) {
                            *d |= *x;
                        }
                    }
                });
            std::mem::swap(&mut cur, &mut next);
            record(
                k,
                &|| {
                    cur.par_chunks(w)
                        .map(|c| c.iter().map(|x| x.count_ones()).sum())
                        .collect()
                },
                &mut out,
            );
        }
    }
    out
}
