//! A fault-injection hook for tests: `FULCRUM_FAULT_BAD_CHUNK=ACTOR:SEQ` makes actor
//! ACTOR (first incarnation only) send its chunk number SEQ with an out-of-range
//! action byte, a chunk the learner must refuse. Read once per process; unset, it does
//! nothing. It exists so that a test can show that a refused chunk does not leave the
//! actor and the learner waiting on each other.

use std::sync::OnceLock;

use fulcrum_contracts::traj::{ChunkLayout, Section};

/// The environment variable of the hook.
pub const FAULT_BAD_CHUNK_ENV: &str = "FULCRUM_FAULT_BAD_CHUNK";

fn target() -> Option<(u32, u64)> {
    static T: OnceLock<Option<(u32, u64)>> = OnceLock::new();
    *T.get_or_init(|| {
        let v = std::env::var(FAULT_BAD_CHUNK_ENV).ok()?;
        let (a, s) = v.trim().split_once(':')?;
        Some((a.parse().ok()?, s.parse().ok()?))
    })
}

/// Corrupt the chunk `seq` of actor `index` in `buf` if the hook asks for it (in the
/// actor's first incarnation only: a restarted actor sends good chunks).
pub(crate) fn corrupt(
    index: u32,
    incarnation: u32,
    seq: u64,
    layout: &ChunkLayout,
    buf: &mut [u8],
) {
    if incarnation == 0 && target() == Some((index, seq)) {
        buf[layout.range(Section::Actions).start] = u8::MAX;
        tracing::warn!(actor = index, seq, "fault injected: a bad action byte");
    }
}
