//! The iceoryx2 services every process opens the same way, and the care of what dead
//! processes leave behind.
//!
//! One request-response service carries the requests and answers; two event services
//! carry the wake-ups (clients wake the server, the server wakes each client), since
//! request-response ports have no file descriptor to wait on.

use fulcrum_contracts::msg::{EmpRequest, EmpResponse, Names, MAX_CLIENTS, MAX_IN_FLIGHT};
use iceoryx2::node::NodeState;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2::service::port_factory::request_response::PortFactory as RrFactory;

use super::error::{IpcSource, ServiceError};

/// The request-response service's port factory (requests carry the client's listener
/// id in their user header).
pub(super) type Rr = RrFactory<ipc::Service, EmpRequest, u128, EmpResponse, ()>;

/// An answer on its way to a client.
pub(super) type Pending =
    iceoryx2::pending_response::PendingResponse<ipc::Service, EmpRequest, u128, EmpResponse, ()>;

/// The request-response service, built the same way by every process: created for
/// `Some(clients)` clients (the server), else only opened, whatever number of clients
/// the server made it for (a client asks for none: the server's memory grows with it,
/// and a training run makes it for its own actors).
pub(super) fn rr_service(
    node: &Node<ipc::Service>,
    names: &Names,
    create: Option<usize>,
) -> Result<Rr, IpcSource> {
    let mut b = node
        .service_builder(&ServiceName::new(&names.empowerment)?)
        .request_response::<EmpRequest, EmpResponse>()
        .request_user_header::<u128>()
        .max_servers(2)
        .max_active_requests_per_client(MAX_IN_FLIGHT)
        .max_loaned_requests(MAX_IN_FLIGHT)
        .max_response_buffer_size(MAX_IN_FLIGHT)
        .enable_safe_overflow_for_requests(false)
        .enable_safe_overflow_for_responses(false);
    match create {
        Some(clients) => {
            // Nodes cost little: as many as the most clients, so that one too many gets
            // "full" at its client, not a service it cannot open.
            b = b
                .max_clients(clients)
                .max_nodes(MAX_CLIENTS.max(clients) + 4);
            Ok(b.open_or_create()?)
        }
        None => Ok(b.open()?),
    }
}

/// One of the two wake-up event services.
pub(super) fn event_service(
    node: &Node<ipc::Service>,
    name: &str,
) -> Result<EventFactory<ipc::Service>, IpcSource> {
    Ok(node
        .service_builder(&ServiceName::new(name)?)
        .event()
        .max_listeners(MAX_CLIENTS + 2)
        .max_notifiers(MAX_CLIENTS + 2)
        .max_nodes(MAX_CLIENTS + 4)
        .open_or_create()?)
}

/// The service's node: iceoryx2 handles SIGINT and SIGTERM (see [`super::signal`]).
pub(super) fn server_node() -> Result<Node<ipc::Service>, ServiceError> {
    NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::HandleTerminationRequests)
        .create::<ipc::Service>()
        .map_err(|e| ServiceError::ipc("node", e))
}

/// Remove what dead processes left behind (their nodes, ports and services), so that a
/// `kill -9` never blocks the next start. Returns how many dead nodes were cleaned.
pub fn clean_dead_nodes() -> usize {
    let mut n = 0;
    let _ = Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::Dead(dead) = state {
            if dead.try_remove_stale_resources().is_ok() {
                n += 1;
            }
        }
        CallbackProgression::Continue
    });
    n
}

/// Quiet iceoryx2's own logging (it warns once per process that no config file was
/// loaded) unless `IOX2_LOG_LEVEL` asks for more.
pub fn quiet_ipc_logs() {
    set_log_level_from_env_or(LogLevel::Error);
}
