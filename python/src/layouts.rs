//! The layouts a `VecCore` on a world family plays: each episode of each environment
//! one layout, drawn when the episode starts from that environment's own generator (the
//! one `VecCore::seed` seeds), uniformly from a range of layout seeds.
//!
//! `layouts` is `N` (the seeds `0..N`, as `fulcrum train --layouts N`), `"all"` (any
//! seed below 2^40: a fresh layout every episode), `"test:K"` or `"test:A..B"` (held-out
//! seeds, from 2^40 on, which no training run meets) or `"train:K"` (the seeds `0..K`).
//! Seed `start + floor(r * len / 2^64)` for the generator's next 64-bit number r.

use std::ops::Range;
use std::sync::Arc;

use fulcrum_world::family::Family;
use fulcrum_world::{EvalLayouts, LayoutPool, Layouts, World};

/// Layouts kept made (every environment's current one lives on in its `Arc` besides).
const KEEP: usize = 4096;

/// A family's layouts and the seeds an episode draws from.
#[derive(Debug)]
pub(crate) struct FamilyEnvs {
    pool: LayoutPool,
    seeds: Range<u64>,
    label: String,
}

impl FamilyEnvs {
    /// The layouts `spec` of `family` (see the module docs).
    pub(crate) fn new(family: Family, spec: &str) -> Result<FamilyEnvs, String> {
        let seeds = if spec.starts_with("test:") || spec.starts_with("train:") {
            match EvalLayouts::parse(spec).map_err(|e| e.replace("--layouts", "layouts"))? {
                EvalLayouts::Test(r) => r,
                EvalLayouts::Train(k) => 0..k,
            }
        } else {
            spec.parse::<Layouts>()
                .map_err(|e| format!("layouts={spec:?}: {e}"))?
                .range()
        };
        Ok(FamilyEnvs {
            pool: LayoutPool::new(family, KEEP),
            seeds,
            label: spec.to_string(),
        })
    }

    /// The family.
    pub(crate) fn family(&self) -> &fulcrum_world::family::Family {
        self.pool.family()
    }

    /// The seeds episodes draw from.
    pub(crate) fn seeds(&self) -> Range<u64> {
        self.seeds.clone()
    }

    /// The layouts, as given.
    pub(crate) fn label(&self) -> &str {
        &self.label
    }

    /// The layout the random number `r` draws, made (or kept from before).
    pub(crate) fn draw(&mut self, r: u64) -> Result<(u64, Arc<World>), String> {
        let len = self.seeds.end - self.seeds.start;
        let seed = self.seeds.start + ((r as u128 * len as u128) >> 64) as u64;
        let w = self
            .pool
            .get(seed)
            .map_err(|e| format!("layout {seed} of '{}': {e}", self.pool.family().name))?;
        Ok((seed, w))
    }
}
