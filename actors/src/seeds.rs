//! The seeds of an actor's random draws: one per chunk, from (run seed, actor, policy
//! version, chunk), so that a run resumed from a checkpoint draws what one never stopped
//! would; the same mix with reserved arguments seeds the draws that are not a chunk's
//! (a layout's, a resumed world's).

/// A seed for one chunk's sampling.
pub fn chunk_seed(seed: u64, actor: u32, version: u64, k: u64) -> u64 {
    let mut x = seed ^ 0xa076_1d64_78bd_642f;
    for v in [actor as u64, version, k] {
        x = (x ^ v).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        x ^= x >> 29;
    }
    x
}
