//! The bridge's transport errors, typed: zenoh's error is kept as the source and the
//! operation is named (iceoryx2's are [`fulcrum_shared::IpcError`]).

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
