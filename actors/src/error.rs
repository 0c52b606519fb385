//! Why an actor process failed.

/// Actor failures.
#[derive(Debug, thiserror::Error)]
pub enum ActorError {
    /// iceoryx2 failed.
    #[error("shared memory: {0}")]
    Ipc(String),
    /// The empowerment service failed in a way retrying cannot fix.
    #[error("empowerment service: {0}")]
    Service(String),
}

pub(crate) fn ipc(what: &str) -> impl Fn(&dyn std::fmt::Debug) -> ActorError + '_ {
    move |e| ActorError::Ipc(format!("{what}: {e:?}"))
}
