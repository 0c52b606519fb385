//! Naming what was being done when an error came, typed: `.context(...)` on a result or
//! an option gives a [`Contextual`](crate::context::Contextual) error that keeps the cause as its source, and the
//! libraries' own error types (`fulcrum_run::Error`, the bridge's) take it with `?`.

use std::fmt::Display;

/// Another crate's error, as it came.
pub type Source = Box<dyn std::error::Error + Send + Sync + 'static>;

/// What was being done, and why it failed (none for a missing value).
#[derive(Debug, thiserror::Error)]
#[error("{what}")]
pub struct Contextual {
    /// What was being done.
    pub what: String,
    /// Why it failed.
    #[source]
    pub source: Option<Source>,
}

/// `.context(what)` and `.with_context(|| what)`, as `anyhow::Context`, typed.
pub trait Context<T> {
    /// The error, with what was being done.
    fn context(self, what: impl Display) -> Result<T, Contextual>;
    /// The same, with the description made only on error.
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T, Contextual>;
}

impl<T, E: Into<Source>> Context<T> for Result<T, E> {
    fn context(self, what: impl Display) -> Result<T, Contextual> {
        self.map_err(|e| Contextual {
            what: what.to_string(),
            source: Some(e.into()),
        })
    }
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T, Contextual> {
        self.map_err(|e| Contextual {
            what: what().to_string(),
            source: Some(e.into()),
        })
    }
}

impl<T> Context<T> for Option<T> {
    fn context(self, what: impl Display) -> Result<T, Contextual> {
        self.ok_or_else(|| Contextual {
            what: what.to_string(),
            source: None,
        })
    }
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T, Contextual> {
        self.ok_or_else(|| Contextual {
            what: what().to_string(),
            source: None,
        })
    }
}

/// `From` conversions that keep other crates' typed errors as a library error's
/// `Source(Box<dyn Error>)` variant: `sources!(Error: std::io::Error, ...)`, so that `?`
/// takes them.
#[macro_export]
macro_rules! sources {
    ($error:ident: $($t:ty),* $(,)?) => {
        $(impl From<$t> for $error {
            fn from(e: $t) -> $error {
                $error::Source(Box::new(e))
            }
        })*
    };
}
