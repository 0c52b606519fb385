//! The empowerment service and its client, over iceoryx2 request-response.
//!
//! One service process owns one world's engine. It precomputes the table of its
//! configuration (tool j, objects D, horizons h_u / h_e) and answers:
//!
//! - LOOKUP: a batch of packed states -> `E^{h(s)}_{j,D}(s)` as `f32`, with `h(s) = h_e`
//!   where j is held and `h_u` elsewhere;
//! - QUERY: any tool, object set and horizon, computed on demand and cached within a
//!   memory bound;
//! - DESCRIBE: the world and the configuration;
//! - VISIT: count one visit of each state and answer its visit count so far, shared by
//!   all clients (the count-based novelty bonus of `train --intrinsic count`).
//!
//! Wake-ups: pub/sub and request-response ports have no file descriptor, so requests
//! and responses are paired with event services (iceoryx2's request-response and pub/sub ports cannot be waited on by themselves). Each side first spins a
//! short bounded while (polling, no syscall) for the answer, then blocks on its
//! listener: a fast answer costs no wake-up, an idle process burns no core.
//!
//! A bad request never stops the service: it gets an error status (see
//! [`fulcrum_shared::msg::status`]), and states that are not in the state space get
//! [`fulcrum_shared::msg::item::NOT_IN_SPACE`].

use std::collections::{HashMap, VecDeque};
use std::time::{Duration, Instant};

use fulcrum_shared::msg::{
    self, item, kind, status, Describe, EmpRequest, EmpResponse, Names, AGENT_BIT, MAX_BATCH,
    MAX_CLIENTS, MAX_IN_FLIGHT, TOOL_ALL,
};
use fulcrum_shared::{ObjectSet, State, World, MAX_HORIZON};
use iceoryx2::node::NodeState;
use iceoryx2::port::client::Client as IoxClient;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::server::Server as IoxServer;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2::service::port_factory::request_response::PortFactory as RrFactory;
use iceoryx2::waitset::WaitSetRunResult;

use crate::engine::{Engine, Method, ToolSel};

type Rr = RrFactory<ipc::Service, EmpRequest, u128, EmpResponse, ()>;
type Pending =
    iceoryx2::pending_response::PendingResponse<ipc::Service, EmpRequest, u128, EmpResponse, ()>;

/// Why the service could not start or stopped.
#[derive(Debug, thiserror::Error)]
pub enum ServiceError {
    /// Another service already serves this namespace.
    #[error("an empowerment service for namespace '{0}' is already running; stop it or pick another --namespace")]
    AlreadyRunning(String),
    /// The namespace cannot be part of a service name.
    #[error("namespace '{0}' must be 1 to 64 characters of A-Z, a-z, 0-9, '_', '-', '.'")]
    BadNamespace(String),
    /// iceoryx2 failed.
    #[error("shared memory ({what}): {detail}")]
    Ipc {
        /// The operation.
        what: &'static str,
        /// iceoryx2's error.
        detail: String,
    },
    /// The engine refused the configuration.
    #[error(transparent)]
    Engine(#[from] crate::EngineError),
}

fn ipc(what: &'static str) -> impl FnOnce(&dyn std::fmt::Debug) -> ServiceError {
    move |e| ServiceError::Ipc {
        what,
        detail: format!("{e:?}"),
    }
}

macro_rules! ipc_err {
    ($what:expr) => {
        |e| ipc($what)(&e)
    };
}

/// The request-response service, built the same way by every process.
fn rr_service(node: &Node<ipc::Service>, names: &Names, create: bool) -> Result<Rr, String> {
    let b = node
        .service_builder(&ServiceName::new(&names.empowerment).map_err(|e| format!("{e:?}"))?)
        .request_response::<EmpRequest, EmpResponse>()
        .request_user_header::<u128>()
        .max_clients(MAX_CLIENTS)
        .max_servers(2)
        .max_nodes(MAX_CLIENTS + 4)
        .max_active_requests_per_client(MAX_IN_FLIGHT)
        .max_loaned_requests(MAX_IN_FLIGHT)
        .max_response_buffer_size(MAX_IN_FLIGHT)
        .enable_safe_overflow_for_requests(false)
        .enable_safe_overflow_for_responses(false);
    if create {
        b.open_or_create().map_err(|e| format!("{e:?}"))
    } else {
        b.open().map_err(|e| format!("{e:?}"))
    }
}

/// The two wake-up event services.
fn event_service(
    node: &Node<ipc::Service>,
    name: &str,
) -> Result<EventFactory<ipc::Service>, String> {
    node.service_builder(&ServiceName::new(name).map_err(|e| format!("{e:?}"))?)
        .event()
        .max_listeners(MAX_CLIENTS + 2)
        .max_notifiers(MAX_CLIENTS + 2)
        .max_nodes(MAX_CLIENTS + 4)
        .open_or_create()
        .map_err(|e| format!("{e:?}"))
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

fn node() -> Result<Node<ipc::Service>, ServiceError> {
    NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::HandleTerminationRequests)
        .create::<ipc::Service>()
        .map_err(ipc_err!("node"))
}

/// What a service computes for LOOKUP.
#[derive(Debug, Clone)]
pub struct ServeConfig {
    /// Namespace: `fulcrum/<namespace>/empowerment`.
    pub namespace: String,
    /// Tool whose actions drive the channel.
    pub tool: ToolSel,
    /// Objects of interest.
    pub objects: ObjectSet,
    /// Horizon where the tool is not held.
    pub horizon_unequipped: u32,
    /// Horizon where it is held.
    pub horizon_equipped: u32,
    /// LOOKUP answers Phi(s) = sum over h = 1..H of E^h(s), H the larger horizon, in every
    /// state (the potential of `train --intrinsic horizon-potential`) instead of E.
    pub horizon_sum: bool,
    /// Bytes the QUERY cache may hold.
    pub cache_bytes: usize,
    /// How long to poll for the next request before blocking.
    pub spin: Duration,
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

/// Object mask of a set (bit per object; [`AGENT_BIT`] for the agent).
pub fn object_mask(set: &ObjectSet) -> u32 {
    match set {
        ObjectSet::Agent => AGENT_BIT,
        ObjectSet::Objects(v) => v.iter().fold(0, |m, &i| m | 1 << i),
    }
}

/// The object set of a mask, if the world has those objects.
pub fn mask_set(world: &World, mask: u32) -> Option<ObjectSet> {
    if mask == AGENT_BIT {
        return Some(ObjectSet::Agent);
    }
    if mask == 0 || mask & AGENT_BIT != 0 || mask >> world.objects.len() != 0 {
        return None;
    }
    Some(ObjectSet::Objects(
        (0..world.objects.len())
            .filter(|&i| mask >> i & 1 == 1)
            .collect(),
    ))
}

fn tool_code(t: ToolSel) -> i32 {
    match t {
        ToolSel::All => TOOL_ALL,
        ToolSel::Tool(j) => j as i32,
    }
}

/// The DESCRIBE answer for an engine and configuration.
pub fn describe(engine: &Engine, cfg: &ServeConfig) -> Describe {
    let w = engine.world;
    let mut d = Describe {
        world_hash: w.content_hash(),
        states: engine.space.len() as u64,
        normal_states: engine.normal_states() as u64,
        n_tools: w.tools.len() as u32,
        n_objects: w.objects.len() as u32,
        tool: tool_code(cfg.tool),
        object_mask: object_mask(&cfg.objects),
        horizon_unequipped: cfg.horizon_unequipped,
        horizon_equipped: cfg.horizon_equipped,
        ..Describe::empty()
    };
    msg::put_name(&mut d.world, &w.name);
    for (k, t) in w.tools.iter().enumerate() {
        msg::put_name(&mut d.tools[k], &t.name);
    }
    for (i, o) in w.objects.iter().enumerate() {
        msg::put_name(&mut d.objects[i], &o.name);
    }
    d
}

/// The service's tables and cache: everything but the ports.
#[derive(Debug)]
pub struct Tables<'w> {
    engine: Engine<'w>,
    cfg: ServeConfig,
    unequipped: Vec<f32>,
    equipped: Vec<f32>,
    cache: VecDeque<((i32, u32, u32), Vec<f32>)>,
    describe: Describe,
    /// VISIT counts per state id (allocated at the first VISIT).
    visits: Vec<u32>,
}

impl<'w> Tables<'w> {
    /// Precompute the configuration's tables.
    pub fn new(engine: Engine<'w>, cfg: ServeConfig) -> Result<Self, ServiceError> {
        let f = |v: &Vec<u32>| {
            v.iter()
                .map(|&c| (c as f64).log2() as f32)
                .collect::<Vec<f32>>()
        };
        let (unequipped, equipped) = if cfg.horizon_sum {
            // Every horizon 1..=H in one propagation; Phi is their sum (f64, then f32).
            let h = cfg.horizon_unequipped.max(cfg.horizon_equipped);
            let hs: Vec<u32> = (1..=h).collect();
            let counts = engine.counts(cfg.tool, &cfg.objects, &hs, Method::Dp)?;
            let phi: Vec<f32> = (0..engine.space.len())
                .map(|i| counts.iter().map(|c| (c[i] as f64).log2()).sum::<f64>() as f32)
                .collect();
            (phi.clone(), phi)
        } else {
            let counts = engine.counts(
                cfg.tool,
                &cfg.objects,
                &[cfg.horizon_unequipped, cfg.horizon_equipped],
                Method::Dp,
            )?;
            (f(&counts[0]), f(&counts[1]))
        };
        let describe = describe(&engine, &cfg);
        Ok(Tables {
            unequipped,
            equipped,
            engine,
            cfg,
            cache: VecDeque::new(),
            describe,
            visits: Vec::new(),
        })
    }

    /// The DESCRIBE answer.
    pub fn describe(&self) -> &Describe {
        &self.describe
    }

    /// LOOKUP's answer for one state: E (or Phi with `horizon_sum`) in bits; `None` for a
    /// state outside the state space.
    pub fn lookup(&self, s: &State) -> Option<f32> {
        let id = self.engine.space.id(s)?;
        Some(self.value_at(s, id as usize))
    }

    fn value_at(&self, s: &State, id: usize) -> f32 {
        if self.cfg.tool.held(s) {
            self.equipped[id]
        } else {
            self.unequipped[id]
        }
    }

    /// Answer one request into `out` (all-zero on entry).
    pub fn answer(&mut self, req: &EmpRequest, out: &mut EmpResponse) {
        out.seq = req.seq;
        out.describe = self.describe;
        let n = req.count as usize;
        if req.kind != kind::DESCRIBE && req.world_hash != self.describe.world_hash {
            out.status = status::WRONG_WORLD;
            return;
        }
        if n > MAX_BATCH {
            out.status = status::BAD_COUNT;
            return;
        }
        match req.kind {
            kind::DESCRIBE => {}
            kind::LOOKUP => {
                let space = &self.engine.space;
                for i in 0..n {
                    let s = State::from_bytes(&req.states[i]);
                    match space.id(&s) {
                        Some(id) => out.values[i] = self.value_at(&s, id as usize),
                        None => out.item_status[i] = item::NOT_IN_SPACE,
                    }
                }
                out.count = n as u32;
            }
            kind::VISIT => {
                let space = &self.engine.space;
                if self.visits.is_empty() {
                    self.visits = vec![0; space.len()];
                }
                for i in 0..n {
                    let s = State::from_bytes(&req.states[i]);
                    match space.id(&s) {
                        Some(id) => {
                            let c = &mut self.visits[id as usize];
                            *c = c.saturating_add(1);
                            out.values[i] = *c as f32;
                        }
                        None => out.item_status[i] = item::NOT_IN_SPACE,
                    }
                }
                out.count = n as u32;
            }
            kind::QUERY => {
                let w = self.engine.world;
                let tool = match req.tool {
                    TOOL_ALL => ToolSel::All,
                    t if t >= 0 && (t as usize) < w.tools.len() => ToolSel::Tool(t as usize),
                    _ => {
                        out.status = status::BAD_TOOL;
                        return;
                    }
                };
                let Some(set) = mask_set(w, req.objects) else {
                    out.status = status::BAD_OBJECTS;
                    return;
                };
                if req.horizon > MAX_HORIZON {
                    out.status = status::BAD_HORIZON;
                    return;
                }
                let key = (req.tool, req.objects, req.horizon);
                if !self.cache.iter().any(|(k, _)| *k == key) {
                    let table_bytes = self.engine.space.len() * 4;
                    if table_bytes > self.cfg.cache_bytes {
                        out.status = status::TOO_LARGE;
                        return;
                    }
                    let v = match self.engine.values(tool, &set, req.horizon, Method::Dp) {
                        Ok(v) => v.iter().map(|&x| x as f32).collect(),
                        Err(_) => {
                            out.status = status::TOO_LARGE;
                            return;
                        }
                    };
                    while (self.cache.len() + 1) * table_bytes > self.cfg.cache_bytes {
                        self.cache.pop_front();
                    }
                    self.cache.push_back((key, v));
                }
                let table = &self
                    .cache
                    .iter()
                    .find(|(k, _)| *k == key)
                    .expect("cached above")
                    .1;
                let space = &self.engine.space;
                for i in 0..n {
                    match space.id(&State::from_bytes(&req.states[i])) {
                        Some(id) => out.values[i] = table[id as usize],
                        None => out.item_status[i] = item::NOT_IN_SPACE,
                    }
                }
                out.count = n as u32;
            }
            _ => out.status = status::BAD_KIND,
        }
    }
}

/// How a service run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ServeExit {
    /// SIGINT.
    Interrupt,
    /// SIGTERM.
    Terminate,
}

/// The termination signal the service saw (0 = none), set by [`chain_signal`].
static STOP_SIGNAL: std::sync::atomic::AtomicI32 = std::sync::atomic::AtomicI32::new(0);
/// The handlers iceoryx2 installed for SIGINT and SIGTERM, called after ours.
static PREVIOUS: std::sync::OnceLock<[libc::sigaction; 2]> = std::sync::OnceLock::new();

/// Make a running [`serve`] / [`serve_with`] return as if it got SIGTERM (within
/// 100 ms), from any thread.
pub fn request_stop() {
    STOP_SIGNAL.store(libc::SIGTERM, std::sync::atomic::Ordering::SeqCst);
}

/// Whether SIGINT or SIGTERM reached a process that serves (or [`request_stop`] was
/// called).
pub fn stop_requested() -> bool {
    STOP_SIGNAL.load(std::sync::atomic::Ordering::SeqCst) != 0
}

extern "C" fn chain_signal(sig: libc::c_int) {
    STOP_SIGNAL.store(sig, std::sync::atomic::Ordering::SeqCst);
    if let Some(prev) = PREVIOUS.get() {
        let p = &prev[usize::from(sig != libc::SIGINT)];
        if p.sa_sigaction != libc::SIG_DFL && p.sa_sigaction != libc::SIG_IGN {
            // SAFETY: the previous handler is iceoryx2's plain `fn(c_int)` handler, installed
            // without SA_SIGINFO; calling it from a handler is what the kernel would do.
            let f: extern "C" fn(libc::c_int) = unsafe { std::mem::transmute(p.sa_sigaction) };
            f(sig);
        }
    }
}

/// Records SIGINT and SIGTERM in our own flag as well as in iceoryx2's. iceoryx2 keeps
/// only the last signal in one global that some of its calls reset (its
/// `call_and_fetch` around shared-memory writes), and a signal delivered to another
/// thread does not interrupt the wait-set's epoll: either way a Ctrl-C could be lost
/// and the service would never stop. The wait-set checks this flag every 100 ms.
fn chain_termination_signals() {
    // iceoryx2 installs its handlers the first time its SignalHandler is used: make that
    // happen now, so that ours goes on top (and keep a signal that came before).
    use iceoryx2_bb_posix::signal::{NonFatalFetchableSignal, SignalHandler};
    match SignalHandler::last_signal() {
        Some(NonFatalFetchableSignal::Interrupt) => {
            STOP_SIGNAL.store(libc::SIGINT, std::sync::atomic::Ordering::SeqCst)
        }
        Some(NonFatalFetchableSignal::Terminate) => {
            STOP_SIGNAL.store(libc::SIGTERM, std::sync::atomic::Ordering::SeqCst)
        }
        _ => {}
    }
    PREVIOUS.get_or_init(|| {
        // SAFETY: sigaction with a zeroed struct, our handler and an empty mask; the old
        // actions are read into zeroed structs we own.
        unsafe {
            let mut old: [libc::sigaction; 2] = std::mem::zeroed();
            for (i, sig) in [libc::SIGINT, libc::SIGTERM].into_iter().enumerate() {
                let mut act: libc::sigaction = std::mem::zeroed();
                act.sa_sigaction = chain_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
                act.sa_flags = libc::SA_RESTART;
                libc::sigemptyset(&mut act.sa_mask);
                libc::sigaction(sig, &act, &mut old[i]);
            }
            old
        }
    });
}

/// What answers a service's requests: its own [`Tables`], or a bridge that asks the
/// service of another host (feature `multihost`).
pub trait Answer {
    /// The DESCRIBE answer.
    fn describe(&self) -> &Describe;
    /// Answer one request into `out` (all-zero on entry). Never panics on input.
    fn answer(&mut self, req: &EmpRequest, out: &mut EmpResponse);
}

impl Answer for Tables<'_> {
    fn describe(&self) -> &Describe {
        Tables::describe(self)
    }
    fn answer(&mut self, req: &EmpRequest, out: &mut EmpResponse) {
        Tables::answer(self, req, out)
    }
}

/// Run the service until SIGINT or SIGTERM. `ready` is called once the ports are up.
pub fn serve(
    tables: &mut Tables,
    ready: impl FnOnce(&Describe),
) -> Result<(ServeExit, ServeStats), ServiceError> {
    let ns = tables.cfg.namespace.clone();
    let spin = tables.cfg.spin;
    serve_with(tables, &ns, spin, ready)
}

/// Serve `namespace`'s requests with `answers` until SIGINT or SIGTERM (polling `spin`
/// for pipelined follow-ups before blocking). `ready` is called once the ports are up.
pub fn serve_with(
    answers: &mut dyn Answer,
    namespace: &str,
    spin: Duration,
    ready: impl FnOnce(&Describe),
) -> Result<(ServeExit, ServeStats), ServiceError> {
    let ns = namespace.to_string();
    if !msg::valid_namespace(&ns) {
        return Err(ServiceError::BadNamespace(ns));
    }
    let names = Names::new(&ns);
    let cleaned = clean_dead_nodes();
    if cleaned > 0 {
        tracing::info!(cleaned, "removed resources of dead processes");
    }
    let node = node()?;
    let svc = rr_service(&node, &names, true).map_err(|d| ServiceError::Ipc {
        what: "request-response service",
        detail: d,
    })?;
    if svc.dynamic_config().number_of_servers() > 0 {
        return Err(ServiceError::AlreadyRunning(ns));
    }
    let server: IoxServer<ipc::Service, EmpRequest, u128, EmpResponse, ()> = svc
        .server_builder()
        .create()
        .map_err(|_| ServiceError::AlreadyRunning(ns.clone()))?;
    // Two servers could race past the check above; the later one steps back.
    if svc.dynamic_config().number_of_servers() > 1 {
        return Err(ServiceError::AlreadyRunning(ns));
    }
    let wake = event_service(&node, &names.server_wake).map_err(|d| ServiceError::Ipc {
        what: "server wake-up event",
        detail: d,
    })?;
    let listener = wake
        .listener_builder()
        .create()
        .map_err(ipc_err!("listener"))?;
    let answer = event_service(&node, &names.client_wake).map_err(|d| ServiceError::Ipc {
        what: "client wake-up event",
        detail: d,
    })?;
    let notifier = answer
        .notifier_builder()
        .create()
        .map_err(ipc_err!("notifier"))?;
    let waitset = WaitSetBuilder::new()
        .signal_handling_mode(SignalHandlingMode::HandleTerminationRequests)
        .create::<ipc::Service>()
        .map_err(ipc_err!("waitset"))?;
    let _guard = waitset
        .attach_notification(&listener)
        .map_err(ipc_err!("attach"))?;
    let tick = waitset
        .attach_interval(Duration::from_secs(2))
        .map_err(ipc_err!("interval"))?;
    let stop_check = waitset
        .attach_interval(Duration::from_millis(100))
        .map_err(ipc_err!("interval"))?;
    chain_termination_signals();
    ready(answers.describe());

    let mut stats = ServeStats::default();
    let mut keys: HashMap<u128, iceoryx2::port::notifier::ListenerKey> = HashMap::new();
    let mut failure: Option<ServiceError> = None;
    let result = waitset.wait_and_process(|id| {
        if STOP_SIGNAL.load(std::sync::atomic::Ordering::SeqCst) != 0 {
            return CallbackProgression::Stop;
        }
        if id.has_event_from(&stop_check) {
            return CallbackProgression::Continue;
        }
        if id.has_event_from(&tick) {
            clean_dead_nodes();
            tracing::debug!(
                requests = stats.requests,
                states = stats.states,
                refused = stats.refused,
                mean_answer_us = stats.busy_us as f64 / stats.requests.max(1) as f64,
                "service"
            );
            return CallbackProgression::Continue;
        }
        listener.try_wait(|_| {}).ok();
        // Drain, then poll a short while for pipelined follow-ups before blocking.
        let mut idle_since = Instant::now();
        loop {
            match server.receive() {
                Ok(Some(req)) => {
                    if let Err(e) = handle(answers, &req, &notifier, &mut keys, &mut stats) {
                        failure = Some(e);
                        return CallbackProgression::Stop;
                    }
                    idle_since = Instant::now();
                }
                Ok(None) => {
                    if idle_since.elapsed() >= spin {
                        break;
                    }
                    std::hint::spin_loop();
                }
                Err(e) => {
                    failure = Some(ipc("receive")(&e));
                    return CallbackProgression::Stop;
                }
            }
        }
        CallbackProgression::Continue
    });
    if let Some(e) = failure {
        return Err(e);
    }
    match (
        result,
        STOP_SIGNAL.load(std::sync::atomic::Ordering::SeqCst),
    ) {
        (Ok(_), libc::SIGINT) | (Ok(WaitSetRunResult::Interrupt), _) => {
            Ok((ServeExit::Interrupt, stats))
        }
        (Ok(_), _) => Ok((ServeExit::Terminate, stats)),
        (Err(e), _) => Err(ipc("wait")(&e)),
    }
}

/// Answer one active request and wake its client.
fn handle(
    answers: &mut dyn Answer,
    req: &iceoryx2::active_request::ActiveRequest<ipc::Service, EmpRequest, u128, EmpResponse, ()>,
    notifier: &Notifier<ipc::Service>,
    keys: &mut HashMap<u128, iceoryx2::port::notifier::ListenerKey>,
    stats: &mut ServeStats,
) -> Result<(), ServiceError> {
    let t0 = Instant::now();
    let mut resp = match req.loan_uninit() {
        Ok(r) => r,
        // The client is gone or its buffer is full: nothing to answer.
        Err(e) => {
            tracing::debug!(?e, "cannot answer a request");
            return Ok(());
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
    answers.answer(payload, out);
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
    let listener_id = *req.user_header();
    wake_client(notifier, keys, listener_id);
    tracing::trace!(
        us = t0.elapsed().as_micros() as u64,
        n = payload.count,
        "request"
    );
    Ok(())
}

fn wake_client(
    notifier: &Notifier<ipc::Service>,
    keys: &mut HashMap<u128, iceoryx2::port::notifier::ListenerKey>,
    id: u128,
) {
    if let Some(k) = keys.get(&id) {
        if notifier.notify_single_listener(k).is_ok() {
            return;
        }
        keys.remove(&id);
    }
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

/// A client's typed errors.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ClientError {
    /// No service answered before the deadline.
    #[error("no empowerment service for namespace '{namespace}' after waiting {waited:?}; start one with `fulcrum serve WORLD --namespace {namespace}`")]
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
    /// A request got no answer in time.
    #[error("the empowerment service did not answer within {0:?}")]
    Timeout(Duration),
    /// The service went away with requests in flight.
    #[error("the empowerment service went away during a request")]
    ServiceGone,
    /// The service refused the request.
    #[error("the empowerment service refused the request: {}", status::describe(*.0))]
    Refused(u32),
    /// iceoryx2 failed.
    #[error("shared memory: {0}")]
    Ipc(String),
}

/// A connection to a service: batched, pipelined requests with deadlines.
#[derive(Debug)]
pub struct Client {
    _node: Node<ipc::Service>,
    svc: Rr,
    client: IoxClient<ipc::Service, EmpRequest, u128, EmpResponse, ()>,
    wake: Notifier<ipc::Service>,
    listener: Listener<ipc::Service>,
    listener_id: u128,
    world_hash: u64,
    describe: Describe,
    in_flight: VecDeque<(Pending, u32)>,
    seq: u32,
    /// How long one request may take before [`ClientError::Timeout`].
    pub timeout: Duration,
    /// How long to poll for an answer before blocking on the listener.
    pub spin: Duration,
    namespace: String,
}

/// The result of one batch: values and per-state statuses.
#[derive(Debug, Clone, PartialEq)]
pub struct Batch {
    /// E in bits per state.
    pub values: Vec<f32>,
    /// Per-state statuses ([`item`]).
    pub status: Vec<u8>,
}

/// What a request asks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ask {
    /// The service's configured table.
    Lookup,
    /// Count a visit of each state; the answer is its visit count so far (as `f32`).
    Visit,
    /// Any tool (index or [`TOOL_ALL`]), object mask and horizon.
    Query {
        /// Tool index or [`TOOL_ALL`].
        tool: i32,
        /// Object mask.
        objects: u32,
        /// Horizon.
        horizon: u32,
    },
}

impl Client {
    /// Connect to the service of `namespace`, waiting for it up to `deadline`, and check
    /// that it serves `world`.
    pub fn connect(
        namespace: &str,
        world: &World,
        deadline: Duration,
    ) -> Result<Client, ClientError> {
        let t0 = Instant::now();
        let names = Names::new(namespace);
        let node = NodeBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| ClientError::Ipc(format!("node: {e:?}")))?;
        let svc = loop {
            let ok = rr_service(&node, &names, false)
                .ok()
                .filter(|s| s.dynamic_config().number_of_servers() > 0);
            if let Some(s) = ok {
                break s;
            }
            if t0.elapsed() >= deadline {
                return Err(ClientError::NoService {
                    namespace: namespace.to_string(),
                    waited: deadline,
                });
            }
            if t0.elapsed() > Duration::from_millis(500) {
                clean_dead_nodes();
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let client = svc
            .client_builder()
            .create()
            .map_err(|e| ClientError::Ipc(format!("client: {e:?}")))?;
        let wake_svc = event_service(&node, &names.server_wake).map_err(ClientError::Ipc)?;
        let wake = wake_svc
            .notifier_builder()
            .create()
            .map_err(|e| ClientError::Ipc(format!("notifier: {e:?}")))?;
        let ans_svc = event_service(&node, &names.client_wake).map_err(ClientError::Ipc)?;
        let listener = ans_svc
            .listener_builder()
            .create()
            .map_err(|e| ClientError::Ipc(format!("listener: {e:?}")))?;
        let listener_id = listener.id().value();
        let mut c = Client {
            _node: node,
            svc,
            client,
            wake,
            listener,
            listener_id,
            world_hash: world.content_hash(),
            describe: Describe::empty(),
            in_flight: VecDeque::new(),
            seq: 0,
            timeout: deadline.max(Duration::from_secs(5)),
            spin: Duration::from_micros(50),
            namespace: namespace.to_string(),
        };
        c.describe = c.fetch_describe()?;
        if c.describe.world_hash != c.world_hash {
            return Err(ClientError::WrongWorld {
                namespace: namespace.to_string(),
                served: msg::get_name(&c.describe.world),
                served_hash: c.describe.world_hash,
                wanted: world.name.clone(),
                wanted_hash: c.world_hash,
            });
        }
        Ok(c)
    }

    /// The service's DESCRIBE answer.
    pub fn describe(&self) -> &Describe {
        &self.describe
    }

    fn fetch_describe(&mut self) -> Result<Describe, ClientError> {
        self.send(kind::DESCRIBE, &[], 0, 0, 0)?;
        let (resp, _) = self.receive_one()?;
        Ok(resp.describe)
    }

    /// Send one request (at most [`MAX_BATCH`] states) without waiting for its answer.
    /// At most [`MAX_IN_FLIGHT`] may be outstanding; [`Client::recv`] collects them in
    /// order.
    pub fn submit(&mut self, ask: Ask, states: &[State]) -> Result<(), ClientError> {
        assert!(
            states.len() <= MAX_BATCH,
            "a request carries at most {MAX_BATCH} states"
        );
        if self.in_flight.len() >= MAX_IN_FLIGHT {
            return Err(ClientError::Ipc(format!(
                "more than {MAX_IN_FLIGHT} requests in flight: collect answers with recv first"
            )));
        }
        match ask {
            Ask::Lookup => self.send(kind::LOOKUP, states, 0, 0, 0),
            Ask::Visit => self.send(kind::VISIT, states, 0, 0, 0),
            Ask::Query {
                tool,
                objects,
                horizon,
            } => self.send(kind::QUERY, states, tool, objects, horizon),
        }
    }

    fn send(
        &mut self,
        k: u32,
        states: &[State],
        tool: i32,
        objects: u32,
        horizon: u32,
    ) -> Result<(), ClientError> {
        // Packed straight into the loaned sample: no copy on the way.
        let hash = self.world_hash;
        self.send_slots(hash, k, states.len(), tool, objects, horizon, |i| {
            states[i].to_bytes()
        })
    }

    /// Send a request made of raw parts, unchecked (for tests and fuzzing: the service
    /// must answer anything with a status). Collect the answer with [`Client::recv`].
    pub fn send_raw(
        &mut self,
        k: u32,
        states: &[[u8; msg::STATE_BYTES]],
        tool: i32,
        objects: u32,
        horizon: u32,
    ) -> Result<(), ClientError> {
        let hash = self.world_hash;
        self.send_slots(hash, k, states.len(), tool, objects, horizon, |i| states[i])
    }

    /// Send another client's request as it is (its world hash, kind, states), without
    /// waiting: a bridge forwarding requests from another host. Collect the whole
    /// answer with [`Client::recv_response`].
    pub fn forward(&mut self, req: &EmpRequest) -> Result<(), ClientError> {
        let n = (req.count as usize).min(MAX_BATCH);
        if req.count as usize > MAX_BATCH {
            return Err(ClientError::Refused(status::BAD_COUNT));
        }
        self.send_slots(
            req.world_hash,
            req.kind,
            n,
            req.tool,
            req.objects,
            req.horizon,
            |i| req.states[i],
        )
    }

    /// Wait for the oldest request's whole answer, whatever its status.
    pub fn recv_response(&mut self) -> Result<Box<EmpResponse>, ClientError> {
        Ok(self.receive_one()?.0)
    }

    /// Loan a request, write its header and `n` state slots from `slot`, send it.
    #[allow(clippy::too_many_arguments)]
    fn send_slots(
        &mut self,
        world_hash: u64,
        k: u32,
        n: usize,
        tool: i32,
        objects: u32,
        horizon: u32,
        slot: impl Fn(usize) -> [u8; msg::STATE_BYTES],
    ) -> Result<(), ClientError> {
        if n > MAX_BATCH || self.in_flight.len() >= MAX_IN_FLIGHT {
            return Err(ClientError::Ipc(format!(
                "at most {MAX_BATCH} states a request and {MAX_IN_FLIGHT} requests in flight"
            )));
        }
        let mut req = self
            .client
            .loan_uninit()
            .map_err(|e| ClientError::Ipc(format!("loan: {e:?}")))?;
        self.seq = self.seq.wrapping_add(1);
        *req.user_header_mut() = self.listener_id;
        // SAFETY: the payload lives in shared memory, which is always backed by
        // initialised bytes, and every field of EmpRequest is plain integers or bytes, so
        // any content is a valid value; we write the header and the `count` states the
        // service reads, and leave the unused tail of `states` as it is (no 38 KiB memset
        // per request).
        let req = unsafe {
            let p = req.payload_mut().as_mut_ptr();
            std::ptr::addr_of_mut!((*p).world_hash).write(world_hash);
            std::ptr::addr_of_mut!((*p).kind).write(k);
            std::ptr::addr_of_mut!((*p).count).write(n as u32);
            std::ptr::addr_of_mut!((*p).tool).write(tool);
            std::ptr::addr_of_mut!((*p).horizon).write(horizon);
            std::ptr::addr_of_mut!((*p).objects).write(objects);
            std::ptr::addr_of_mut!((*p).seq).write(self.seq);
            let slots = std::ptr::addr_of_mut!((*p).states) as *mut [u8; msg::STATE_BYTES];
            for i in 0..n {
                slots.add(i).write(slot(i));
            }
            req.assume_init()
        };
        let pending = req.send().map_err(|e| match format!("{e:?}") {
            d if d.contains("Disconnected") || d.contains("NoConnection") => {
                ClientError::ServiceGone
            }
            d => ClientError::Ipc(format!("send: {d}")),
        })?;
        self.wake
            .notify()
            .map_err(|e| ClientError::Ipc(format!("notify: {e:?}")))?;
        self.in_flight.push_back((pending, self.seq));
        Ok(())
    }

    /// Requests sent and not yet collected.
    pub fn in_flight(&self) -> usize {
        self.in_flight.len()
    }

    /// Wait for the oldest request's answer.
    pub fn recv(&mut self) -> Result<Batch, ClientError> {
        let (resp, n) = self.receive_one()?;
        if resp.status != status::OK {
            return Err(ClientError::Refused(resp.status));
        }
        Ok(Batch {
            values: resp.values[..n].to_vec(),
            status: resp.item_status[..n].to_vec(),
        })
    }

    /// Wait for the oldest request's answer and copy it into `values` / `status`.
    pub fn recv_into(
        &mut self,
        values: &mut [f32],
        item_status: &mut [u8],
    ) -> Result<usize, ClientError> {
        let (resp, n) = self.receive_one()?;
        if resp.status != status::OK {
            return Err(ClientError::Refused(resp.status));
        }
        values[..n].copy_from_slice(&resp.values[..n]);
        item_status[..n].copy_from_slice(&resp.item_status[..n]);
        Ok(n)
    }

    fn receive_one(&mut self) -> Result<(Box<EmpResponse>, usize), ClientError> {
        let Some((pending, seq)) = self.in_flight.pop_front() else {
            return Err(ClientError::Ipc("no request in flight".into()));
        };
        let t0 = Instant::now();
        let mut last_check = t0;
        loop {
            match pending.receive() {
                Ok(Some(r)) => {
                    let p: &EmpResponse = r.payload();
                    if p.seq == seq {
                        let n = (p.count as usize).min(MAX_BATCH);
                        return Ok((Box::new(*p), n));
                    }
                }
                Ok(None) => {}
                Err(e) => return Err(ClientError::Ipc(format!("receive: {e:?}"))),
            }
            let waited = t0.elapsed();
            if waited >= self.timeout {
                self.in_flight.clear();
                return Err(ClientError::Timeout(self.timeout));
            }
            if waited < self.spin {
                std::hint::spin_loop();
                continue;
            }
            // Block on our listener; wake now and then to notice a dead service.
            let _ = self.listener.timed_wait(|_| {}, Duration::from_millis(20));
            if last_check.elapsed() >= Duration::from_millis(100) {
                last_check = Instant::now();
                clean_dead_nodes();
                if !pending.is_connected()
                    || pending.number_of_server_connections() == 0
                    || self.svc.dynamic_config().number_of_servers() == 0
                {
                    if let Ok(Some(r)) = pending.receive() {
                        let p: &EmpResponse = r.payload();
                        return Ok((Box::new(*p), (p.count as usize).min(MAX_BATCH)));
                    }
                    self.in_flight.clear();
                    return Err(ClientError::ServiceGone);
                }
            }
        }
    }

    /// E for any number of states, in pipelined batches of `batch` (<= [`MAX_BATCH`]).
    pub fn values(
        &mut self,
        ask: Ask,
        states: &[State],
        batch: usize,
    ) -> Result<Batch, ClientError> {
        let batch = batch.clamp(1, MAX_BATCH);
        let mut out = Batch {
            values: vec![0.0; states.len()],
            status: vec![0; states.len()],
        };
        let chunks: Vec<&[State]> = states.chunks(batch).collect();
        let depth = MAX_IN_FLIGHT.min(4);
        let mut sent = 0;
        let mut done = 0;
        while done < chunks.len() {
            while sent < chunks.len() && self.in_flight.len() < depth {
                self.submit(ask, chunks[sent])?;
                sent += 1;
            }
            let off = done * batch;
            let n = chunks[done].len();
            self.recv_into(&mut out.values[off..off + n], &mut out.status[off..off + n])?;
            done += 1;
        }
        Ok(out)
    }

    /// The namespace.
    pub fn namespace(&self) -> &str {
        &self.namespace
    }
}
