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
    #[error(transparent)]
    Ipc(#[from] fulcrum_shared::IpcError),
}
