//! The worlds an actor's envs play: the run's one world, or a family's layouts.
//!
//! On a family each env plays one layout per episode. Its first layouts are drawn from
//! a generator seeded by (run seed, actor, env); the layout of every later episode is
//! drawn, when the episode before it ends, from the chunk's generator (the one the
//! actions come from), so a run resumed from a checkpoint (whose records carry each
//! env's layout) draws the same layouts as one never stopped.

use std::sync::Arc;

use fulcrum_contracts::config::RunConfig;
use fulcrum_contracts::traj::EnvRecord;
use fulcrum_world::family::load_family;
use fulcrum_world::{LayoutPool, Layouts, World};
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::error::ActorError;

/// Layouts an actor keeps made on `--layouts all` (every env's current one lives on in
/// its `Arc` besides).
const KEEP_FRESH: usize = 64;

/// The run's one world, or a family's layouts and which of them a run trains on.
pub(crate) enum EnvWorlds {
    One(Arc<World>),
    Family {
        pool: Box<LayoutPool>,
        layouts: Layouts,
    },
}

impl EnvWorlds {
    /// The worlds of the run `cfg` on `world` (a family's [`fulcrum_world::family::Family::run_world`]).
    pub(crate) fn new(world: &World, cfg: &RunConfig) -> Result<EnvWorlds, ActorError> {
        let Some(layouts) = cfg.layouts else {
            return Ok(EnvWorlds::One(Arc::new(world.clone())));
        };
        let family = load_family(&cfg.world).map_err(|e| ActorError::World(e.to_string()))?;
        Ok(EnvWorlds::Family {
            pool: Box::new(LayoutPool::new(family, layouts.pool_size(KEEP_FRESH))),
            layouts,
        })
    }

    /// Whether the envs play a family's layouts.
    pub(crate) fn is_family(&self) -> bool {
        matches!(self, EnvWorlds::Family { .. })
    }

    /// The world of layout `seed` (the one world, whatever the seed).
    pub(crate) fn world(&mut self, seed: u64) -> Result<Arc<World>, ActorError> {
        match self {
            EnvWorlds::One(w) => Ok(w.clone()),
            EnvWorlds::Family { pool, .. } => pool
                .get(seed)
                .map_err(|e| ActorError::World(format!("layout {seed}: {e}"))),
        }
    }

    /// Whether `seed` is one of the run's training layouts (any seed for one world).
    pub(crate) fn trains_on(&self, seed: u64) -> bool {
        match self {
            EnvWorlds::One(_) => true,
            EnvWorlds::Family { layouts, .. } => layouts.range().contains(&seed),
        }
    }

    /// A fresh episode: on a family, on the layout the random number `r()` draws (called
    /// only there, so one world's generator stream is unchanged).
    pub(crate) fn fresh(
        &mut self,
        r: impl FnOnce() -> u64,
    ) -> Result<(Arc<World>, EnvRecord), ActorError> {
        let seed = match self {
            EnvWorlds::One(_) => 0,
            EnvWorlds::Family { layouts, .. } => layouts.draw(r()),
        };
        let w = self.world(seed)?;
        let rec = EnvRecord::on_layout(w.reset(), seed);
        Ok((w, rec))
    }

    /// The first episodes of actor `actor`'s `m` envs.
    pub(crate) fn first(
        &mut self,
        seed: u64,
        actor: u32,
        m: usize,
    ) -> Result<Vec<(Arc<World>, EnvRecord)>, ActorError> {
        let mut rng =
            ChaCha8Rng::seed_from_u64(crate::seeds::chunk_seed(seed, actor, u64::MAX, u64::MAX));
        (0..m).map(|_| self.fresh(|| rng.next_u64())).collect()
    }
}
