//! The serving loop: open the ports, then answer requests until SIGINT or SIGTERM.
//!
//! The loop blocks on a wait-set that holds the server's wake-up listener and two
//! intervals (one checks the stop flag every 100 ms, one cleans up after dead
//! processes and logs the counters every 2 s). Woken by a client, it drains the
//! requests, then polls a short while for pipelined follow-ups before blocking again.
//! Where the answers prepare ([`Answer::prepares`]: a family's service) each look takes
//! every request waiting, lets [`Answer::prepare`] see them all, then answers them in
//! order.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use fulcrum_contracts::msg::{self, status, Describe, EmpRequest, EmpResponse, Names};
use iceoryx2::active_request::ActiveRequest;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::{ListenerKey, Notifier};
use iceoryx2::port::server::Server as IoxServer;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2::waitset::WaitSetRunResult;

use super::answer::Answer;
use super::error::ServiceError;
use super::ports::{clean_dead_nodes, event_service, rr_service, server_node, Rr};
use super::signal::{chain_termination_signals, stop_signal};
use super::tables::Tables;

/// How a service run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ServeExit {
    /// SIGINT.
    Interrupt,
    /// SIGTERM.
    Terminate,
}

/// Counters a service keeps (logged at debug level).
#[derive(Debug, Default, Clone, Copy)]
pub struct ServeStats {
    /// Requests answered.
    pub requests: u64,
    /// States answered.
    pub states: u64,
    /// Requests refused with an error status.
    pub refused: u64,
    /// Time spent answering (microseconds), for the mean latency in the logs.
    pub busy_us: u64,
}

/// Run the service until SIGINT or SIGTERM. `ready` is called once the ports are up.
pub fn serve(
    tables: &mut Tables,
    ready: impl FnOnce(&Describe),
) -> Result<(ServeExit, ServeStats), ServiceError> {
    let ns = tables.cfg.namespace.clone();
    let (spin, clients) = (tables.cfg.spin, tables.cfg.max_clients);
    serve_with(tables, &ns, spin, clients, ready)
}

/// Serve `namespace`'s requests with `answers` until SIGINT or SIGTERM (polling `spin`
/// for pipelined follow-ups before blocking). `ready` is called once the ports are up.
pub fn serve_with(
    answers: &mut dyn Answer,
    namespace: &str,
    spin: Duration,
    max_clients: usize,
    ready: impl FnOnce(&Describe),
) -> Result<(ServeExit, ServeStats), ServiceError> {
    let ports = Ports::open(namespace, max_clients)?;
    let waitset = WaitSetBuilder::new()
        .signal_handling_mode(SignalHandlingMode::HandleTerminationRequests)
        .create::<ipc::Service>()
        .map_err(|e| ServiceError::ipc("waitset", e))?;
    let _guard = waitset
        .attach_notification(&ports.listener)
        .map_err(|e| ServiceError::ipc("attach", e))?;
    let tick = waitset
        .attach_interval(Duration::from_secs(2))
        .map_err(|e| ServiceError::ipc("interval", e))?;
    let stop_check = waitset
        .attach_interval(Duration::from_millis(100))
        .map_err(|e| ServiceError::ipc("interval", e))?;
    chain_termination_signals();
    ready(answers.describe());

    let mut run = Run {
        answers,
        ports: &ports,
        spin,
        stats: ServeStats::default(),
        keys: HashMap::new(),
        failure: None,
    };
    let result = loop {
        let result = waitset.wait_and_process(|id| {
            if stop_signal() != 0 {
                return CallbackProgression::Stop;
            }
            if id.has_event_from(&stop_check) {
                return CallbackProgression::Continue;
            }
            if id.has_event_from(&tick) {
                clean_dead_nodes();
                run.log();
                return CallbackProgression::Continue;
            }
            run.drain()
        });
        // iceoryx2 reports any interrupted wait as an interrupt, also one that no
        // termination signal caused (stopped and continued with Ctrl-Z and `fg`, a
        // debugger attaching): only our flag says whether to stop.
        match result {
            Ok(WaitSetRunResult::Interrupt) if stop_signal() == 0 && run.failure.is_none() => {
                continue
            }
            r => break r,
        }
    };
    if let Some(e) = run.failure {
        return Err(e);
    }
    match (result, stop_signal()) {
        (Ok(_), libc::SIGINT) | (Ok(WaitSetRunResult::Interrupt), _) => {
            Ok((ServeExit::Interrupt, run.stats))
        }
        (Ok(_), _) => Ok((ServeExit::Terminate, run.stats)),
        (Err(e), _) => Err(ServiceError::ipc("wait", e)),
    }
}

/// The server's ports and the services they belong to, kept alive while it serves.
/// Fields drop in order: the ports before their services, the node last.
struct Ports {
    /// Wakes a client once its answer is sent.
    notifier: Notifier<ipc::Service>,
    _client_wake: EventFactory<ipc::Service>,
    /// Clients wake the server here.
    listener: Listener<ipc::Service>,
    _server_wake: EventFactory<ipc::Service>,
    server: IoxServer<ipc::Service, EmpRequest, u128, EmpResponse, ()>,
    _svc: Rr,
    _node: Node<ipc::Service>,
}

impl Ports {
    /// Check the namespace, clean up after dead processes, and open the server's ports
    /// (the service made for `max_clients` clients), refusing if another service already
    /// serves `namespace`.
    fn open(namespace: &str, max_clients: usize) -> Result<Self, ServiceError> {
        let ns = namespace.to_string();
        if !msg::valid_namespace(&ns) {
            return Err(ServiceError::BadNamespace(ns));
        }
        let names = Names::new(&ns);
        let cleaned = clean_dead_nodes();
        if cleaned > 0 {
            tracing::info!(cleaned, "removed resources of dead processes");
        }
        let node = server_node()?;
        let svc = rr_service(&node, &names, Some(max_clients))
            .map_err(|e| ServiceError::ipc("request-response service", e))?;
        if svc.dynamic_config().number_of_servers() > 0 {
            return Err(ServiceError::AlreadyRunning(ns));
        }
        let server = svc
            .server_builder()
            .create()
            .map_err(|_| ServiceError::AlreadyRunning(ns.clone()))?;
        // Two servers could race past the check above; the later one steps back.
        if svc.dynamic_config().number_of_servers() > 1 {
            return Err(ServiceError::AlreadyRunning(ns));
        }
        let server_wake = event_service(&node, &names.server_wake)
            .map_err(|e| ServiceError::ipc("server wake-up event", e))?;
        let listener = server_wake
            .listener_builder()
            .create()
            .map_err(|e| ServiceError::ipc("listener", e))?;
        let client_wake = event_service(&node, &names.client_wake)
            .map_err(|e| ServiceError::ipc("client wake-up event", e))?;
        let notifier = client_wake
            .notifier_builder()
            .create()
            .map_err(|e| ServiceError::ipc("notifier", e))?;
        Ok(Ports {
            notifier,
            _client_wake: client_wake,
            listener,
            _server_wake: server_wake,
            server,
            _svc: svc,
            _node: node,
        })
    }
}

/// A request received and not yet answered.
type Request = ActiveRequest<ipc::Service, EmpRequest, u128, EmpResponse, ()>;

/// One serving run's state between wake-ups.
struct Run<'a> {
    answers: &'a mut dyn Answer,
    ports: &'a Ports,
    spin: Duration,
    stats: ServeStats,
    /// Each client's listener (by its id in the request's user header), once found.
    keys: HashMap<u128, ListenerKey>,
    /// Why the loop stopped, if it failed.
    failure: Option<ServiceError>,
}

impl Run<'_> {
    /// The counters, at debug level.
    fn log(&self) {
        let s = &self.stats;
        tracing::debug!(
            requests = s.requests,
            states = s.states,
            refused = s.refused,
            mean_answer_us = s.busy_us as f64 / s.requests.max(1) as f64,
            "service"
        );
    }

    /// Answer every waiting request, then poll `spin` for pipelined follow-ups.
    ///
    /// The wake-ups are consumed only when the requests have run dry, so that the first
    /// request after an idle pause is answered before anything else; a request whose
    /// wake-up is consumed then is still seen by the one last look that follows (a
    /// client sends before it notifies). The poll yields the core between looks: on a
    /// machine with few cores the client that woke us may be waiting for this very core.
    fn drain(&mut self) -> CallbackProgression {
        let mut idle_since = Instant::now();
        let mut last_look = false;
        loop {
            match self.ports.server.receive() {
                Ok(Some(req)) if self.answers.prepares() => {
                    let Some(waiting) = self.gather(req) else {
                        return CallbackProgression::Stop;
                    };
                    let reqs: Vec<&EmpRequest> = waiting.iter().map(|r| r.payload()).collect();
                    self.answers.prepare(&reqs);
                    for req in &waiting {
                        self.handle(req);
                    }
                    idle_since = Instant::now();
                    last_look = false;
                }
                Ok(Some(req)) => {
                    self.handle(&req);
                    idle_since = Instant::now();
                    last_look = false;
                }
                Ok(None) if last_look => return CallbackProgression::Continue,
                Ok(None) => {
                    if idle_since.elapsed() >= self.spin {
                        self.ports.listener.try_wait(|_| {}).ok();
                        last_look = true;
                    } else {
                        std::thread::yield_now();
                    }
                }
                Err(e) => {
                    self.failure = Some(ServiceError::ipc("receive", e));
                    return CallbackProgression::Stop;
                }
            }
        }
    }

    /// `first` and every other request waiting now, in their order (`None`: receiving
    /// failed, and `failure` says why).
    fn gather(&mut self, first: Request) -> Option<Vec<Request>> {
        let mut waiting = vec![first];
        loop {
            match self.ports.server.receive() {
                Ok(Some(req)) => waiting.push(req),
                Ok(None) => return Some(waiting),
                Err(e) => {
                    self.failure = Some(ServiceError::ipc("receive", e));
                    return None;
                }
            }
        }
    }

    /// Answer one active request and wake its client.
    fn handle(&mut self, req: &Request) {
        let t0 = Instant::now();
        let mut resp = match req.loan_uninit() {
            Ok(r) => r,
            // The client is gone or its buffer is full: nothing to answer.
            Err(e) => {
                tracing::debug!(?e, "cannot answer a request");
                return;
            }
        };
        // SAFETY: EmpResponse is plain data for which all-zero bytes are a valid value;
        // zeroing the whole payload initialises it before any field is written.
        let out = unsafe {
            let p = resp.payload_mut().as_mut_ptr();
            std::ptr::write_bytes(p, 0, 1);
            &mut *p
        };
        let payload: &EmpRequest = req.payload();
        self.answers.answer(payload, out);
        let stats = &mut self.stats;
        stats.requests += 1;
        stats.states += out.count as u64;
        stats.busy_us += t0.elapsed().as_micros() as u64;
        if out.status != status::OK {
            stats.refused += 1;
        }
        // SAFETY: initialised above.
        let resp = unsafe { resp.assume_init() };
        if let Err(e) = resp.send() {
            tracing::debug!(?e, "response not delivered");
        }
        self.wake_client(*req.user_header());
        tracing::trace!(
            us = t0.elapsed().as_micros() as u64,
            n = payload.count,
            "request"
        );
    }

    /// Notify the listener whose id is `id`: straight to its key when known, else by
    /// looking through the listeners (and keeping its key).
    fn wake_client(&mut self, id: u128) {
        let notifier = &self.ports.notifier;
        if let Some(k) = self.keys.get(&id) {
            if notifier.notify_single_listener(k).is_ok() {
                return;
            }
            self.keys.remove(&id);
        }
        let keys = &mut self.keys;
        notifier.for_each_listener(|mono, details| {
            if details.listener_id.value() == id {
                let _ = mono.notify();
                keys.insert(id, mono.listener_key());
                CallbackProgression::Stop
            } else {
                CallbackProgression::Continue
            }
        });
    }
}
