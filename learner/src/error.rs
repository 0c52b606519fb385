//! Why the learner process stopped with an error.

use crate::checkpoint::CheckpointError;

/// Learner failures.
#[derive(Debug, thiserror::Error)]
pub enum LearnerError {
    /// The run directory or its files.
    #[error("{0}")]
    Run(String),
    /// A checkpoint could not be written or read.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    /// candle failed.
    #[error("candle: {0}")]
    Candle(#[from] candle_core::Error),
    /// iceoryx2 failed.
    #[error("shared memory: {0}")]
    Ipc(String),
}

/// An iceoryx2 error of the step `what`.
pub(crate) fn ipc(what: &str) -> impl Fn(&dyn std::fmt::Debug) -> LearnerError + '_ {
    move |e| LearnerError::Ipc(format!("{what}: {e:?}"))
}
