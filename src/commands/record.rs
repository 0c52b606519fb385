//! `fulcrum record RUN`, and `fulcrum train --record N`: episodes of a run's policy as
//! strips of frames (and, with `--gif`, animations), so a person can see what the agent
//! does.
//!
//! The run's checkpoint gives the policy (the weights of its last update); episodes are
//! played from the world's initial state with actions sampled from the policy, as the
//! actors sample them (a ChaCha generator seeded by `--seed`, default the run's seed).
//! Each frame colours every cell by E (the run's tool, objects and horizons, the held /
//! not-held horizon by the inventory) for the agent standing there, with the inventory
//! and objects of that moment: where the bonus is, and where the agent goes.

use crate::commands::bad;
use anyhow::Result;
use fulcrum_contracts::config::RunConfig;
use fulcrum_run::record::record;
use fulcrum_world::load_world;

use crate::cli::RecordArgs;

/// `fulcrum record`.
pub fn run(a: &RecordArgs) -> Result<()> {
    let paths = fulcrum_run::plan::run_dir(&a.run)?;
    let cfg = RunConfig::load(&paths.config())?;
    let w = load_world(&cfg.world)?;
    if a.episodes == 0 || a.episodes > 100 {
        return bad(format!("--episodes {} must be 1 to 100", a.episodes));
    }
    let out = a.out.clone().unwrap_or_else(|| paths.dir.join("episodes"));
    for (p, steps) in record(
        &paths,
        &cfg,
        &w,
        a.episodes,
        a.seed.unwrap_or(cfg.seed),
        &out,
        a.gif,
    )? {
        println!("{}  ({steps} steps)", p.display());
    }
    Ok(())
}
