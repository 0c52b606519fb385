//! The counters a bridge keeps and logs when it stops.

use std::sync::atomic::{AtomicU64, Ordering};

#[derive(Debug, Default)]
pub struct BridgeStats {
    /// Chunks forwarded.
    pub chunks: AtomicU64,
    /// Their bytes.
    pub chunk_bytes: AtomicU64,
    /// Chunks that could not go on: malformed, or (actor host) no learner listening.
    pub chunks_lost: AtomicU64,
    /// Weights forwarded.
    pub weights: AtomicU64,
    /// Lookups forwarded.
    pub lookups: AtomicU64,
    /// Lookups answered UNAVAILABLE.
    pub lookups_failed: AtomicU64,
}

impl BridgeStats {
    pub fn line(&self) -> String {
        let g = |a: &AtomicU64| a.load(Ordering::Relaxed);
        format!(
            "{} chunks ({:.1} MiB), {} lost; {} weights; {} lookups, {} unanswered",
            g(&self.chunks),
            g(&self.chunk_bytes) as f64 / (1 << 20) as f64,
            g(&self.chunks_lost),
            g(&self.weights),
            g(&self.lookups),
            g(&self.lookups_failed)
        )
    }
}
