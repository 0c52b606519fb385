//! The worlds an actor resumes: its episode records from the run's checkpoint.
//!
//! A record is used only when it is one of the world's
//! ([`fulcrum_contracts::valid::check_record`]: the agent on the map and not in a wall,
//! boulder slots on the map or destroyed, a mode and inventory of the world, ...) and,
//! where the run has an empowerment service, its state is in the world's state space
//! (the service knows it; a state outside it would make every lookup fail). Any other
//! record starts a new episode in its world, with a warning naming the world and the
//! reason: a poisoned checkpoint costs those episodes, never the actor.

use std::path::Path;
use std::sync::Arc;

use fulcrum_contracts::checkpoint;
use fulcrum_contracts::layout::NetShape;
use fulcrum_contracts::msg::{item, MAX_BATCH};
use fulcrum_contracts::traj::{EnvRecord, ENV_BYTES, OLD_ENV_BYTES};
use fulcrum_contracts::valid::check_record;
use fulcrum_empowerment::service::{Ask, Client};
use fulcrum_world::{State, World};

use crate::error::ActorError;
use crate::worlds::EnvWorlds;

/// An env's world and its episode.
type Env = (Arc<World>, EnvRecord);

/// The worlds of actor `index` from the checkpoint, if it was taken at `version`; a
/// record that is not one of its world's (on a family: of its layout, one of the run's
/// training layouts) is replaced by a fresh episode (warned).
pub(crate) fn resume_records(
    path: &Path,
    shape: NetShape,
    index: u32,
    version: u64,
    m: usize,
    worlds: &mut EnvWorlds,
) -> Result<Option<Vec<Env>>, ActorError> {
    if !path.exists() {
        return Ok(None);
    }
    // The whole file is checked against the network's layout, as the learner checks it.
    let Ok(contents) = checkpoint::read(path, &shape.params()) else {
        return Ok(None);
    };
    let extra = contents.extra;
    if extra.counters.get("update") != Some(&version) {
        return Ok(None);
    }
    let Some(b) = extra.blobs.get(&format!("env/{index}")) else {
        return Ok(None);
    };
    // Records written before families are shorter (no layout seed).
    let Some(size) = [ENV_BYTES, OLD_ENV_BYTES]
        .into_iter()
        .find(|&size| b.len() == m * size)
    else {
        return Ok(None);
    };
    let mut recs = Vec::with_capacity(m);
    for (e, bytes) in b.chunks_exact(size).enumerate() {
        let layout = EnvRecord::from_bytes(bytes).map_or(0, |r| r.layout);
        if !worlds.trains_on(layout) {
            warn_reset(
                index,
                e,
                &format!("its layout {layout} is not one the run trains on"),
            );
            recs.push(fresh(worlds, index, e)?);
            continue;
        }
        let world = worlds.world(layout)?;
        match check_record(&world, bytes) {
            Ok(r) => recs.push((world, r)),
            Err(why) => {
                warn_reset(index, e, &why.to_string());
                recs.push(fresh(worlds, index, e)?);
            }
        }
    }
    Ok(Some(recs))
}

/// A fresh episode for env `e` in place of a record that cannot be resumed: on a family,
/// on a layout drawn from (actor, env), so that a resume stays reproducible.
fn fresh(worlds: &mut EnvWorlds, actor: u32, e: usize) -> Result<Env, ActorError> {
    let r = crate::seeds::chunk_seed(actor as u64, actor, e as u64, u64::MAX - 1);
    worlds.fresh(|| r)
}

fn warn_reset(actor: u32, e: usize, why: &str) {
    tracing::warn!(
        actor,
        world = e,
        why,
        "a world's record in the checkpoint is not a valid state: that world starts a new episode"
    );
}

/// Replace the records whose state the empowerment service does not know (outside the
/// world's state space) by fresh episodes, warned. A failed request leaves the records
/// as they are (the chunk's own lookups reconnect and ask again).
pub(crate) fn reset_unknown_states(
    cl: &mut Client,
    actor: u32,
    worlds: &mut EnvWorlds,
    recs: &mut [Env],
) -> Result<(), ActorError> {
    let states: Vec<State> = recs.iter().map(|r| r.1.episode.state).collect();
    let layouts: Vec<u64> = recs.iter().map(|r| r.1.layout).collect();
    let family = worlds.is_family();
    let mut known = Vec::with_capacity(states.len());
    for (part, lays) in states.chunks(MAX_BATCH).zip(layouts.chunks(MAX_BATCH)) {
        match cl
            .submit_on(Ask::Lookup, part, family.then_some(lays))
            .and_then(|_| cl.recv())
        {
            Ok(b) => known.extend(b.status.iter().map(|&s| s != item::NOT_IN_SPACE)),
            Err(e) => {
                tracing::warn!(actor, "empowerment service: {e}");
                return Ok(());
            }
        }
    }
    for (e, (r, ok)) in recs.iter_mut().zip(known).enumerate() {
        if !ok {
            warn_reset(actor, e, "its state is not in the world's state space");
            *r = fresh(worlds, actor, e)?;
        }
    }
    Ok(())
}
