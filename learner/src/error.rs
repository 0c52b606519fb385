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
    /// The weights after an update hold NaN or infinite values (training diverged);
    /// they were not published.
    #[error("training diverged: the weights after update {update} are not finite ({bad} NaN or infinite values); they were not published to the actors and the last checkpoint keeps earlier weights")]
    Diverged {
        /// The update that made them.
        update: u64,
        /// How many values are not finite.
        bad: usize,
    },
    /// iceoryx2 failed.
    #[error(transparent)]
    Ipc(#[from] fulcrum_contracts::IpcError),
}
