//! The counters a bridge keeps and logs when it stops.

use std::sync::atomic::{AtomicU64, Ordering};

/// How many refusals of each kind are said on stderr one by one (then only counted).
const SAY_AT_MOST: u64 = 20;

#[derive(Debug, Default)]
pub struct BridgeStats {
    /// Chunks forwarded.
    pub chunks: AtomicU64,
    /// Their bytes.
    pub chunk_bytes: AtomicU64,
    /// Chunks that could not go on: (actor host) no learner listening.
    pub chunks_lost: AtomicU64,
    /// Weights forwarded.
    pub weights: AtomicU64,
    /// Lookups forwarded.
    pub lookups: AtomicU64,
    /// Lookups answered UNAVAILABLE.
    pub lookups_failed: AtomicU64,
    /// Chunks refused by the learner's bridge ([`crate::guard`]).
    pub refused_chunks: AtomicU64,
    /// Lookups refused by the learner's bridge.
    pub refused_lookups: AtomicU64,
}

impl BridgeStats {
    pub fn line(&self) -> String {
        let g = |a: &AtomicU64| a.load(Ordering::Relaxed);
        format!(
            "{} chunks ({:.1} MiB), {} lost; {} weights; {} lookups, {} unanswered; refused: {} chunks, {} lookups",
            g(&self.chunks),
            g(&self.chunk_bytes) as f64 / (1 << 20) as f64,
            g(&self.chunks_lost),
            g(&self.weights),
            g(&self.lookups),
            g(&self.lookups_failed),
            g(&self.refused_chunks),
            g(&self.refused_lookups)
        )
    }

    /// Count a refusal in `counter` and say it (the first few of each kind).
    pub fn refuse(&self, counter: &AtomicU64, what: &str, why: &str) {
        let n = counter.fetch_add(1, Ordering::Relaxed) + 1;
        if n <= SAY_AT_MOST {
            eprintln!("fulcrum bridge: refused {what}: {why} ({n} so far)");
        }
    }
}
