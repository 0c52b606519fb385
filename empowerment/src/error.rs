//! The engine's errors: each names what was asked and the numbers that refuse it.

use crate::limits::human_bytes;

/// Why an empowerment computation was refused or failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EngineError {
    /// Enumeration passed the memory limit.
    #[error("the state space of world '{world}' has more than {states} states (about {bytes_h} at that size), over the memory limit of {limit_h}", bytes_h = human_bytes(*bytes), limit_h = human_bytes(*limit))]
    StateSpaceTooLarge {
        /// World name.
        world: String,
        /// States found when it stopped.
        states: usize,
        /// Estimated bytes at that point.
        bytes: usize,
        /// The limit.
        limit: usize,
    },
    /// The set table would not fit.
    #[error("the empowerment table for {what} needs about {bytes_h} ({states} states x {words} words x 2), over the memory limit of {limit_h}", bytes_h = human_bytes(*bytes), limit_h = human_bytes(*limit))]
    TableTooLarge {
        /// What was asked.
        what: String,
        /// States.
        states: usize,
        /// 64-bit words per set.
        words: usize,
        /// Estimated bytes.
        bytes: usize,
        /// The limit.
        limit: usize,
    },
    /// A horizon beyond what the engine accepts.
    #[error("horizon {h} is too large: at most {max}")]
    HorizonTooLarge {
        /// Asked.
        h: u32,
        /// Allowed.
        max: u32,
    },
    /// The reference method would take too long.
    #[error("the enumerate method at horizon {h} needs {per_state:.3e} action sequences per state ({actions}^{h}) for {states} states; use the dp method or a smaller horizon")]
    EnumerationTooLong {
        /// Horizon.
        h: u32,
        /// |A_j|.
        actions: usize,
        /// States asked for.
        states: usize,
        /// Sequences per state.
        per_state: f64,
    },
    /// A stochastic channel whose distributions over states outgrow the memory limit.
    #[error("the stochastic channel at horizon {h} has {distributions} distinct distributions over states after {level} actions, about {bytes_h}, over the memory limit of {limit_h} per thread; use a smaller horizon", bytes_h = human_bytes(*bytes), limit_h = human_bytes(*limit))]
    ChannelTooLarge {
        /// Horizon.
        h: u32,
        /// Actions taken when it stopped.
        level: u32,
        /// Distributions at that level.
        distributions: usize,
        /// Estimated bytes.
        bytes: usize,
        /// The limit per thread.
        limit: usize,
    },
    /// A question asked of a stochastic world that only a deterministic one answers.
    #[error("{0}")]
    Deterministic(String),
    /// A state that is not in the world's state space.
    #[error("{0}")]
    NotInSpace(String),
    /// A request that names what the world does not have (an unknown tool, object or
    /// inventory) or is not written as one: the sentence says which and what would be.
    #[error("{0}")]
    Request(String),
}
