//! The bridge's errors, typed: zenoh's error is kept as the source and the operation is
//! named (iceoryx2's are [`fulcrum_contracts::IpcError`]); a request the bridge cannot
//! take (a bad address, a missing secret, a host the learner refused) is [`Refused`],
//! which the binary turns into exit code 2. [`Error`] is what the bridge's functions
//! return: a refusal, a failure naming what was being done with its source kept, another
//! crate's typed error, or a sentence of the bridge's own.

/// The bridge cannot do what it was asked (bad input, not a failure): one sentence.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Refused(pub String);

/// Shorthand for a [`Refused`] error.
pub fn refuse<T>(msg: impl Into<String>) -> Result<T> {
    Err(Error::Refused(Refused(msg.into())))
}

pub use fulcrum_contracts::context::{Context, Contextual, Source};

/// An error of the bridge.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The bridge cannot do what it was asked (exit 2).
    #[error(transparent)]
    Refused(#[from] Refused),
    /// A failure while doing what it says, its cause kept as the source.
    #[error(transparent)]
    Context(#[from] Contextual),
    /// Another crate's typed error.
    #[error("{0}")]
    Source(#[source] Source),
    /// A failure the bridge describes itself.
    #[error("{0}")]
    Failed(String),
}

impl Error {
    /// Another crate's error, kept as it is.
    pub fn source(e: impl Into<Source>) -> Error {
        Error::Source(e.into())
    }

    /// Whether the bridge refused the request (bad input) rather than failed.
    pub fn is_refusal(&self) -> bool {
        match self {
            Error::Refused(_) => true,
            Error::Context(Contextual {
                source: Some(source),
                ..
            })
            | Error::Source(source) => {
                source.is::<Refused>()
                    || source
                        .downcast_ref::<Error>()
                        .is_some_and(Error::is_refusal)
            }
            Error::Context(_) | Error::Failed(_) => false,
        }
    }
}

/// The bridge's results.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Return early with a failure the bridge describes.
macro_rules! fail {
    ($($arg:tt)*) => {
        return Err($crate::error::Error::Failed(format!($($arg)*)))
    };
}
pub(crate) use fail;

fulcrum_contracts::sources!(
    Error:
    std::io::Error,
    ZenohError,
    fulcrum_contracts::IpcError,
    fulcrum_contracts::config::ConfigError,
    fulcrum_world::WorldError,
    serde_json::Error,
    toml::de::Error,
);

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
