//! The run library's errors, typed: what went wrong keeps its source, and the kind says
//! what the binary makes of it (its exit code is decided in `main.rs` alone, from
//! [`Error::kind`]).
//!
//! Two ways a run ends are not failures of the system: the request was wrong
//! ([`BadRequest`]: exit 2) or someone stopped it ([`Interrupted`]: exit 130). A child
//! process ends with a code its supervisor reads ([`Error::ChildExit`]: that code,
//! nothing printed). Everything else is a failure (exit 1) with its cause kept:
//! [`Error::Context`] names what was being done, [`Error::Source`] is another crate's
//! typed error as it came, [`Error::Failed`] a sentence of this crate's own.

/// A mistake in what was asked for (a request that cannot be planned, a run directory
/// that is not one): one sentence naming what is wrong and where. The binary exits 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadRequest(pub String);

/// The run or experiment was interrupted (SIGINT/SIGTERM) and kept what it had: the
/// message says how to continue. The binary exits 130.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Interrupted(pub String);

pub use fulcrum_contracts::context::{Context, Contextual, Source};

/// An error of the run library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The request was wrong (exit 2).
    #[error(transparent)]
    BadRequest(#[from] BadRequest),
    /// Stopped by a signal, with what it had kept (exit 130).
    #[error(transparent)]
    Interrupted(#[from] Interrupted),
    /// A child process ends with this exit code for its supervisor; nothing is printed.
    #[error("the process ends with exit code {0}")]
    ChildExit(u8),
    /// A failure while doing what it says, its cause kept as the source.
    #[error(transparent)]
    Context(#[from] Contextual),
    /// Another crate's typed error (kept as the source, so that whoever reads the
    /// chain of causes finds it).
    #[error("{0}")]
    Source(#[source] Source),
    /// A failure this crate describes itself (exit 1).
    #[error("{0}")]
    Failed(String),
}

/// What the binary makes of an error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Bad input: exit 2.
    BadRequest,
    /// Interrupted: exit 130.
    Interrupted,
    /// A child's own exit code, nothing printed.
    ChildExit(u8),
    /// Anything else: exit 1, unless a source says it was bad input.
    Failure,
}

impl Error {
    /// The kind of this error (a [`Error::Context`] or [`Error::Source`] keeps its
    /// source's kind when the source is one of this crate's errors).
    pub fn kind(&self) -> Kind {
        match self {
            Error::BadRequest(_) => Kind::BadRequest,
            Error::Interrupted(_) => Kind::Interrupted,
            Error::ChildExit(c) => Kind::ChildExit(*c),
            Error::Context(Contextual {
                source: Some(source),
                ..
            })
            | Error::Source(source) => match source.downcast_ref::<Error>() {
                Some(e) => e.kind(),
                None if source.is::<BadRequest>() => Kind::BadRequest,
                None if source.is::<Interrupted>() => Kind::Interrupted,
                None => Kind::Failure,
            },
            Error::Context(_) | Error::Failed(_) => Kind::Failure,
        }
    }
}

/// The run library's results.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Shorthand for a [`BadRequest`] error.
pub fn bad<T>(msg: impl Into<String>) -> Result<T> {
    Err(Error::BadRequest(BadRequest(msg.into())))
}

/// Return early with a failure this crate describes (as `anyhow::bail!`).
#[macro_export]
macro_rules! fail {
    ($($arg:tt)*) => {
        return Err($crate::error::Error::Failed(format!($($arg)*)))
    };
}

/// A failure this crate describes, formatted (as `anyhow::anyhow!`).
#[macro_export]
macro_rules! failure {
    ($($arg:tt)*) => {
        $crate::error::Error::Failed(format!($($arg)*))
    };
}

/// Return early with a failure unless the condition holds (as `anyhow::ensure!`).
#[macro_export]
macro_rules! ensure {
    ($cond:expr, $($arg:tt)*) => {
        if !$cond {
            $crate::fail!($($arg)*);
        }
    };
}

fulcrum_contracts::sources!(
    Error:
    std::io::Error,
    std::fmt::Error,
    fulcrum_world::WorldError,
    fulcrum_world::DescribeError,
    fulcrum_world::generate::GenError,
    fulcrum_contracts::config::ConfigError,
    fulcrum_contracts::IpcError,
    fulcrum_contracts::checkpoint::CheckpointError,
    fulcrum_learner::error::LearnerError,
    fulcrum_actors::ActorError,
    fulcrum_empowerment::EngineError,
    serde_json::Error,
    toml::de::Error,
    toml::ser::Error,
);
