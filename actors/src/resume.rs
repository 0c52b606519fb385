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

use fulcrum_contracts::checkpoint;
use fulcrum_contracts::layout::NetShape;
use fulcrum_contracts::msg::{item, MAX_BATCH};
use fulcrum_contracts::traj::{EnvRecord, ENV_BYTES};
use fulcrum_contracts::valid::check_record;
use fulcrum_empowerment::service::{Ask, Client};
use fulcrum_world::{State, World};

/// The worlds of actor `index` from the checkpoint, if it was taken at `version`; a
/// record that is not one of the world's is replaced by a fresh episode (warned).
pub(crate) fn resume_records(
    path: &Path,
    shape: NetShape,
    index: u32,
    version: u64,
    m: usize,
    world: &World,
) -> Option<Vec<EnvRecord>> {
    if !path.exists() {
        return None;
    }
    // The whole file is checked against the network's layout, as the learner checks it.
    let extra = checkpoint::read(path, &shape.params()).ok()?.extra;
    if extra.counters.get("update") != Some(&version) {
        return None;
    }
    let b = extra.blobs.get(&format!("env/{index}"))?;
    if b.len() != m * ENV_BYTES {
        return None;
    }
    let recs = b
        .chunks_exact(ENV_BYTES)
        .enumerate()
        .map(|(e, bytes)| match check_record(world, bytes) {
            Ok(r) => r,
            Err(why) => {
                warn_reset(index, e, &why.to_string());
                EnvRecord::new(world.reset())
            }
        })
        .collect();
    Some(recs)
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
    world: &World,
    recs: &mut [EnvRecord],
) {
    let states: Vec<State> = recs.iter().map(|r| r.episode.state).collect();
    let mut known = Vec::with_capacity(states.len());
    for part in states.chunks(MAX_BATCH) {
        match cl.submit(Ask::Lookup, part).and_then(|_| cl.recv()) {
            Ok(b) => known.extend(b.status.iter().map(|&s| s != item::NOT_IN_SPACE)),
            Err(e) => {
                tracing::warn!(actor, "empowerment service: {e}");
                return;
            }
        }
    }
    for (e, (r, ok)) in recs.iter_mut().zip(known).enumerate() {
        if !ok {
            warn_reset(actor, e, "its state is not in the world's state space");
            *r = EnvRecord::new(world.reset());
        }
    }
}
