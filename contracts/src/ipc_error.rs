//! An iceoryx2 failure, typed: iceoryx2 has one error type per operation, so the
//! operation is named in `what` and iceoryx2's own error is kept, boxed, as the source.

/// An iceoryx2 operation failed.
#[derive(Debug, thiserror::Error)]
#[error("shared memory ({what}): {source}")]
pub struct IpcError {
    /// The operation, e.g. "trajectory service" or "send chunk".
    pub what: String,
    /// iceoryx2's error.
    #[source]
    pub source: Box<dyn std::error::Error + Send + Sync + 'static>,
}

impl IpcError {
    /// `what` failed with `e`.
    pub fn new(
        what: impl Into<String>,
        e: impl Into<Box<dyn std::error::Error + Send + Sync>>,
    ) -> Self {
        IpcError {
            what: what.into(),
            source: e.into(),
        }
    }
}
