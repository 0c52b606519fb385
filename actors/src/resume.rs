//! The worlds an actor resumes: its episode records from the run's checkpoint.

use std::path::Path;

use fulcrum_shared::checkpoint;
use fulcrum_shared::layout::NetShape;
use fulcrum_shared::traj::{EnvRecord, ENV_BYTES};
use fulcrum_shared::World;

/// The worlds of actor `index` from the checkpoint, if it was taken at `version`.
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
    let recs: Vec<EnvRecord> = b
        .chunks_exact(ENV_BYTES)
        .map(EnvRecord::from_bytes)
        .collect::<Option<_>>()?;
    // Never start from a record whose agent is off the map (another world's file).
    recs.iter()
        .all(|x| {
            (x.episode.state.x as usize) < world.width
                && (x.episode.state.y as usize) < world.height
        })
        .then_some(recs)
}
