//! The bridge's errors, typed: zenoh's error is kept as the source and the operation is
//! named (iceoryx2's are [`fulcrum_contracts::IpcError`]); a request the bridge cannot
//! take (a bad address, a missing secret, a host the learner refused) is [`Refused`],
//! which the binary turns into exit code 2. [`Error`] is what the bridge's functions
//! return: a refusal, a failure naming what was being done with its source kept, another
//! crate's typed error, or a sentence of the bridge's own.

use std::fmt::Display;

/// The bridge cannot do what it was asked (bad input, not a failure): one sentence.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Refused(pub String);

/// Shorthand for a [`Refused`] error.
pub fn refuse<T>(msg: impl Into<String>) -> Result<T> {
    Err(Error::Refused(Refused(msg.into())))
}

/// Another crate's error, as it came.
pub type Source = Box<dyn std::error::Error + Send + Sync + 'static>;

/// An error of the bridge.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The bridge cannot do what it was asked (exit 2).
    #[error(transparent)]
    Refused(#[from] Refused),
    /// A failure while doing what `what` says.
    #[error("{what}")]
    Context {
        /// What was being done.
        what: String,
        /// Why it failed.
        #[source]
        source: Source,
    },
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
            Error::Context { source, .. } | Error::Source(source) => {
                source.is::<Refused>()
                    || source
                        .downcast_ref::<Error>()
                        .is_some_and(Error::is_refusal)
            }
            Error::Failed(_) => false,
        }
    }
}

/// The bridge's results.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Naming what was being done when an error came.
pub trait Context<T> {
    /// The error, with `what` was being done.
    fn context(self, what: impl Display) -> Result<T>;
    /// The same, with the description made only on error.
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T>;
}

impl<T, E: Into<Source>> Context<T> for std::result::Result<T, E> {
    fn context(self, what: impl Display) -> Result<T> {
        self.map_err(|e| Error::Context {
            what: what.to_string(),
            source: e.into(),
        })
    }
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T> {
        self.map_err(|e| Error::Context {
            what: what().to_string(),
            source: e.into(),
        })
    }
}

impl<T> Context<T> for Option<T> {
    fn context(self, what: impl Display) -> Result<T> {
        self.ok_or_else(|| Error::Failed(what.to_string()))
    }
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T> {
        self.ok_or_else(|| Error::Failed(what().to_string()))
    }
}

/// Return early with a failure the bridge describes.
macro_rules! fail {
    ($($arg:tt)*) => {
        return Err($crate::error::Error::Failed(format!($($arg)*)))
    };
}
pub(crate) use fail;

macro_rules! sources {
    ($($t:ty),* $(,)?) => {
        $(impl From<$t> for Error {
            fn from(e: $t) -> Error {
                Error::Source(Box::new(e))
            }
        })*
    };
}

sources!(
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
