//! The service's and the client's typed errors.
//!
//! iceoryx2 has one error type per operation; a failed operation keeps its own error
//! as the `source` (boxed, so one variant covers them all) and names the operation in
//! `what`. Each message also ends with iceoryx2's words, so that `to_string()` alone
//! still says what went wrong.

use std::sync::Arc;
use std::time::Duration;

use fulcrum_contracts::msg::status;

/// An iceoryx2 error of any of its types, as a service or a client keeps it.
pub(super) type IpcSource = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Why the service could not start or stopped.
#[derive(Debug, thiserror::Error)]
pub enum ServiceError {
    /// Another service already serves this namespace.
    #[error("an empowerment service for namespace '{0}' is already running; stop it or pick another namespace")]
    AlreadyRunning(String),
    /// The namespace cannot be part of a service name.
    #[error("namespace '{0}' must be 1 to 64 characters of A-Z, a-z, 0-9, '_', '-', '.'")]
    BadNamespace(String),
    /// iceoryx2 failed.
    #[error("shared memory ({what}): {source}")]
    Ipc {
        /// The operation.
        what: &'static str,
        /// iceoryx2's error.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
    /// The engine refused the configuration.
    #[error(transparent)]
    Engine(#[from] crate::EngineError),
}

impl ServiceError {
    /// `what` failed with iceoryx2's error `e`.
    pub(super) fn ipc(what: &'static str, e: impl Into<IpcSource>) -> Self {
        ServiceError::Ipc {
            what,
            source: e.into(),
        }
    }
}

/// A client's typed errors.
#[derive(Debug, Clone, thiserror::Error)]
pub enum ClientError {
    /// No service answered before the deadline.
    #[error("no empowerment service for namespace '{namespace}' after waiting {waited:?}; start one for that namespace first")]
    NoService {
        /// Namespace.
        namespace: String,
        /// How long the client waited.
        waited: Duration,
    },
    /// The service serves another world.
    #[error("the empowerment service for namespace '{namespace}' serves world '{served}' (hash {served_hash:016x}), not '{wanted}' (hash {wanted_hash:016x})")]
    WrongWorld {
        /// Namespace.
        namespace: String,
        /// The service's world.
        served: String,
        /// Its hash.
        served_hash: u64,
        /// The client's world.
        wanted: String,
        /// Its hash.
        wanted_hash: u64,
    },
    /// The service has as many clients as it was made for.
    #[error("the empowerment service for namespace '{namespace}' has as many clients as it takes ({max}); close one, or start the service with a larger --max-clients")]
    Full {
        /// Namespace.
        namespace: String,
        /// The clients it takes at once.
        max: usize,
    },
    /// A request got no answer in time.
    #[error("the empowerment service did not answer within {0:?}")]
    Timeout(Duration),
    /// The service went away with requests in flight.
    #[error("the empowerment service went away during a request")]
    ServiceGone,
    /// The service refused the request.
    #[error("the empowerment service refused the request: {}", status::describe(*.0))]
    Refused(u32),
    /// An exchange that cannot go on, in words: the client's own limits (too many
    /// requests in flight, none to collect) or a caller's finding about an answer.
    #[error("shared memory: {0}")]
    Ipc(String),
    /// iceoryx2 failed.
    #[error("shared memory: {what}: {source}")]
    Transport {
        /// The operation.
        what: &'static str,
        /// iceoryx2's error (shared, so that the error stays `Clone`).
        #[source]
        source: Arc<dyn std::error::Error + Send + Sync + 'static>,
    },
}

impl ClientError {
    /// `what` failed with iceoryx2's error `e`.
    pub(super) fn transport(what: &'static str, e: impl Into<IpcSource>) -> Self {
        ClientError::Transport {
            what,
            source: Arc::from(e.into()),
        }
    }
}
