//! Exact object empowerment in a stochastic world: the capacity of the channel from
//! open-loop action sequences to the objects' projection (`docs/world.md`,
//! "Stochastic worlds"):
//!
//! ```text
//! E^h_{j,D}(s) = max over p(a^h) on A_j^h of I(A^h ; proj_D(S_h) | S_0 = s)   bits
//! ```
//!
//! The channel's row for a sequence a^h is the distribution of proj_D(S_h), which
//! depends on a^h only through the distribution of S_h. So, from s, the method
//! propagates distributions over states: level 0 is {delta_s}, level k + 1 is
//! {mu T_a : mu in level k, a in A_j}, with equal distributions merged (as set
//! propagation merges states; probabilities compare at 2^-40). The rows of level h,
//! projected and merged, go to [`crate::capacity::capacity`].
//!
//! Two exact reductions keep the levels small:
//!
//! - **support prefilter**: `dist(t)`, the fewest steps (with A_j, through outcomes of
//!   positive probability) after which proj_D may differ from proj_D(t), by
//!   Bellman-Ford over the transition graph. If dist(s) > h, every state reachable in h
//!   steps has s's projection, and E is exactly 0;
//! - **sinks**: mass on a state t with dist(t) > r, r steps to go, ends in proj_D(t)
//!   whatever the actions; it moves to a sink for that projection value and is no
//!   longer followed. Two sequences that differ only in what they do to such mass give
//!   one row.
//!
//! With slip = 0 and every p = 1 the channel is deterministic and E = log2 of the
//! number of reachable projections, but deterministic worlds use set propagation
//! ([`crate::propagate`]) instead; the engine picks the method.
//!
//! Cost: per state, the sum over levels of (distinct distributions x |A_j| x support x
//! outcomes), parallel over start states, then the capacity of (distinct rows x
//! outputs). Memory: one level's distributions and its channel, within the engine's
//! limit shared by the threads (refused with [`EngineError::ChannelTooLarge`] beyond).

use fulcrum_world::hash::{FastMap, FastSet};
use rayon::prelude::*;

use crate::capacity::{capacity, Capacity};
use crate::error::EngineError;
use crate::propagate::Projection;
use crate::space::StateSpace;

/// Bytes a level's distribution entry costs: the entry, its key in the merge set, and
/// their share of the vectors' headers.
const ENTRY_BYTES: usize = 40;

/// "Never within the horizon" for [`Chance::dist`].
const FAR: u8 = u8::MAX;

/// One (tool, object set)'s channel over a stochastic state space.
#[derive(Debug)]
pub struct Chance<'a> {
    space: &'a StateSpace,
    proj: &'a Projection,
    actions: &'a [u8],
    /// Fewest steps after which the projection may change, `FAR` beyond `hmax`.
    dist: Vec<u8>,
    /// Bytes one value's levels may take (the values are computed in parallel).
    max_bytes: usize,
}

/// A distribution over nodes: states `< n`, and sinks `n + y` for projection value y;
/// sorted by node.
type Dist = Vec<(u32, f64)>;

/// Probabilities compare at this resolution when distributions are merged.
const QUANT: f64 = (1u64 << 40) as f64;

fn key(d: &Dist) -> Vec<(u32, u64)> {
    d.iter()
        .map(|&(t, p)| (t, (p * QUANT).round() as u64))
        .collect()
}

impl<'a> Chance<'a> {
    /// Prepare the channel of `actions` onto `proj` for horizons up to `hmax`; the
    /// values computed at once may take `max_bytes` together.
    pub fn new(
        space: &'a StateSpace,
        proj: &'a Projection,
        actions: &'a [u8],
        hmax: u32,
        max_bytes: usize,
    ) -> Self {
        let n = space.len();
        let mut dist = vec![FAR; n];
        // dist(t) = 1 + min over (a, t') of (0 if proj(t') != proj(t) else dist(t')).
        for r in 1..=hmax.min(254) as u8 {
            let next: Vec<u8> = (0..n as u32)
                .into_par_iter()
                .with_min_len(1024)
                .map(|t| {
                    if dist[t as usize] != FAR {
                        return dist[t as usize];
                    }
                    let pt = proj.ids[t as usize];
                    let hit = actions.iter().any(|&a| {
                        space
                            .outcomes(t, a)
                            .0
                            .iter()
                            .any(|&u| proj.ids[u as usize] != pt || dist[u as usize] < r)
                    });
                    if hit {
                        r
                    } else {
                        FAR
                    }
                })
                .collect();
            let done = next == dist;
            dist = next;
            if done {
                break;
            }
        }
        Chance {
            space,
            proj,
            actions,
            dist,
            max_bytes: max_bytes / rayon::current_num_threads().max(1),
        }
    }

    /// Whether E^h(s_i) is 0 by the support prefilter.
    pub fn surely_zero(&self, i: u32, h: u32) -> bool {
        (self.dist[i as usize] as u32) > h || self.dist[i as usize] == FAR
    }

    /// E^h at each state of `ids`, in parallel.
    pub fn values(&self, ids: &[u32], h: u32) -> Result<Vec<Capacity>, EngineError> {
        ids.par_iter().map(|&i| self.value(i, h)).collect()
    }

    /// E^h at state `i`.
    pub fn value(&self, i: u32, h: u32) -> Result<Capacity, EngineError> {
        if self.surely_zero(i, h) {
            return Ok(Capacity::default());
        }
        let n = self.space.len() as u32;
        let m = self.proj.size;
        let mut level: Vec<Dist> = vec![vec![(i, 1.0)]];
        let mut acc: FastMap<u32, f64> = FastMap::default();
        for k in 0..h {
            let r = h - k - 1;
            let mut seen: FastSet<Vec<(u32, u64)>> = FastSet::default();
            let mut next: Vec<Dist> = Vec::new();
            let mut entries = 0usize;
            for mu in &level {
                let frozen = mu.iter().all(|&(t, _)| t >= n);
                for &a in self.actions {
                    acc.clear();
                    for &(t, p) in mu {
                        if t >= n {
                            *acc.entry(t).or_insert(0.0) += p;
                            continue;
                        }
                        let (ids, ps) = self.space.outcomes(t, a);
                        for (&u, &pu) in ids.iter().zip(ps) {
                            let d = self.dist[u as usize];
                            let node = if d == FAR || d as u32 > r {
                                n + self.proj.ids[u as usize]
                            } else {
                                u
                            };
                            *acc.entry(node).or_insert(0.0) += p * pu;
                        }
                    }
                    let mut nu: Dist = acc.iter().map(|(&t, &p)| (t, p)).collect();
                    nu.sort_unstable_by_key(|e| e.0);
                    if seen.insert(key(&nu)) {
                        entries += nu.len();
                        next.push(nu);
                        let bytes = (entries + next.len() * m.min(64)) * ENTRY_BYTES;
                        if bytes > self.max_bytes {
                            return Err(EngineError::ChannelTooLarge {
                                h,
                                level: k + 1,
                                distributions: next.len(),
                                bytes,
                                limit: self.max_bytes,
                            });
                        }
                    }
                    if frozen {
                        break;
                    }
                }
            }
            level = next;
        }
        // Every node is a sink now (r = 0 at the last level). Rows over the m values.
        let mut rows = vec![0.0; level.len() * m];
        for (x, mu) in level.iter().enumerate() {
            for &(t, p) in mu {
                let y = if t >= n {
                    (t - n) as usize
                } else {
                    self.proj.ids[t as usize] as usize
                };
                rows[x * m + y] += p;
            }
        }
        Ok(capacity(&rows, m))
    }
}
