//! The bridge's errors, typed: zenoh's error is kept as the source and the operation is
//! named (iceoryx2's are [`fulcrum_contracts::IpcError`]); a request the bridge cannot
//! take (a bad address, a missing secret, a host the learner refused) is [`Refused`],
//! which the binary turns into exit code 2.

/// The bridge cannot do what it was asked (bad input, not a failure): one sentence.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Refused(pub String);

/// Shorthand for a [`Refused`] error.
pub fn refuse<T>(msg: impl Into<String>) -> anyhow::Result<T> {
    Err(Refused(msg.into()).into())
}

/// A zenoh operation failed.
#[derive(Debug, thiserror::Error)]
#[error("zenoh ({what}): {source}")]
pub struct ZenohError {
    /// The operation, e.g. "subscriber" or "put".
    pub what: String,
    /// zenoh's error.
    #[source]
    pub source: zenoh::Error,
}

impl ZenohError {
    /// `what` failed with zenoh's error `e`.
    pub fn new(what: impl Into<String>, e: zenoh::Error) -> Self {
        ZenohError {
            what: what.into(),
            source: e,
        }
    }
}
