//! Why an actor process failed.

/// Actor failures.
#[derive(Debug, thiserror::Error)]
pub enum ActorError {
    /// iceoryx2 failed.
    #[error(transparent)]
    Ipc(#[from] fulcrum_contracts::IpcError),
    /// The empowerment service failed in a way retrying cannot fix.
    #[error("empowerment service: {0}")]
    Service(String),
    /// A world family's layout could not be made.
    #[error("world family: {0}")]
    World(String),
}
