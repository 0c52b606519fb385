//! The two ways a run ends that are not failures of the system: the request was wrong,
//! or someone stopped it.

/// A mistake in what was asked for (a request that cannot be planned, a run directory
/// that is not one): one sentence naming what is wrong and where. The binary exits 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadRequest(pub String);

/// Shorthand for a [`BadRequest`] error.
pub fn bad<T>(msg: impl Into<String>) -> anyhow::Result<T> {
    Err(BadRequest(msg.into()).into())
}

/// The run or experiment was interrupted (SIGINT/SIGTERM) and kept what it had: the
/// message says how to continue. The binary exits 130.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Interrupted(pub String);
