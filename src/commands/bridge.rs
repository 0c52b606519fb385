//! `fulcrum bridge` (feature `multihost`): one run across hosts. On each host the run's
//! processes talk through iceoryx2 shared memory as on one machine; the bridge forwards
//! between that host's services and zenoh, under key expressions that carry the run's
//! namespace:
//!
//! ```text
//! learner's host (train --listen ADDR)          actor host (actor-host --connect ADDR)
//!  learner <-shm- bridge --listen  <== zenoh ==>  bridge --connect -shm-> actors
//!
//! fulcrum/hello                     queryable   join: run, world, config, host index
//! fulcrum/<run>/chunks/<host>       put         chunks (header + payload), host -> learner
//! fulcrum/<run>/policy              put         weights (header + f32s), learner -> hosts
//! fulcrum/<run>/empowerment         queryable   lookups (msg::wire), host -> service
//! fulcrum/<run>/done                put         the run is over: actor hosts stop
//! ```
//!
//! Backpressure end to end: chunks travel with zenoh's blocking congestion control,
//! and the learner's side hands each chunk to the learner through an iceoryx2
//! publisher that waits while the learner's queue is full. A learner that stops
//! reading therefore stops the bridge, the link, the remote bridge, and the remote
//! actors in turn; nothing is dropped to make room. A chunk sent while no learner
//! listens (the link is down) is lost, and the learner counts it from the gap in the
//! actor's sequence numbers. A put that waits longer than the session timeout for room
//! in the link closes the session (zenoh's `wait_before_close`); the host reconnects.
//!
//! An actor host's bridge is also its actors' empowerment service: it answers DESCRIBE
//! itself and forwards every other request to the learner's host, where the bridge
//! asks the run's service (pipelined, up to `MAX_IN_FLIGHT` at once). When the link is
//! down the answer is `UNAVAILABLE`, and actors hold their chunk and ask again.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use fulcrum_empowerment::service::{self, Answer, Client};
use fulcrum_learner::config::RunConfig;
use fulcrum_learner::run::RunPaths;
use fulcrum_shared::msg::{self, status, wire, Describe, EmpRequest, EmpResponse, MAX_IN_FLIGHT};
use fulcrum_shared::traj::{self, ChunkHeader, TrainNames, WeightsHeader, HOST_STRIDE};
use fulcrum_shared::World;
use iceoryx2::port::BackpressureAction;
use iceoryx2::prelude::*;
use serde::{Deserialize, Serialize};
use zenoh::handlers::{FifoChannel, RingChannel};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::Wait;

use crate::cli::{BridgeArgs, ZenohArgs};
use crate::commands::bad;
use crate::commands::train::{die_with_parent, install_signal_handlers, STOP};

/// What a joining host learns (the reply to `fulcrum/hello`), as TOML.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Hello {
    /// The run's namespace on the learner's host (the key expressions' `<run>`).
    pub run: String,
    /// The run's tag ([`traj::run_tag`] of `run`): chunks carry it.
    pub run_tag: u64,
    /// The run's id (its directory name by default).
    pub run_id: String,
    /// The world's text; its hash is the run's world hash.
    pub world_source: String,
    /// [`World::content_hash`], hex.
    pub world_hash: String,
    /// The world's name.
    pub world_name: String,
    /// The run's `config.toml`.
    pub config: String,
    /// This host's index: its actors are `index * HOST_STRIDE + j`.
    pub host: u32,
}

/// An address as a zenoh locator: `host:port` becomes `tcp/host:port`.
pub fn locator(addr: &str) -> Result<String> {
    if addr.contains('/') {
        return Ok(addr.to_string());
    }
    let port_ok = addr
        .rsplit_once(':')
        .is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok());
    if !port_ok {
        return bad(format!(
            "'{addr}' is not an address: give host:port (e.g. 0.0.0.0:7447) or a zenoh locator (tcp/host:port)"
        ));
    }
    Ok(format!("tcp/{addr}"))
}

/// Open a zenoh session: a peer that listens on or connects to `endpoint`, no
/// multicast scouting, the link lease from `--session-timeout`.
pub fn open_session(z: &ZenohArgs, endpoint: &str, listen: bool) -> Result<zenoh::Session> {
    if !(z.session_timeout.is_finite() && z.session_timeout >= 0.5) {
        return bad(format!(
            "--session-timeout {} must be at least 0.5 seconds",
            z.session_timeout
        ));
    }
    let mut c = match &z.zenoh_config {
        Some(p) => match zenoh::Config::from_file(p) {
            Ok(c) => c,
            Err(e) => return bad(format!("{} is not a zenoh configuration: {e}", p.display())),
        },
        None => zenoh::Config::default(),
    };
    let lease_ms = (z.session_timeout * 1000.0).round() as u64;
    let loc = serde_json::to_string(&[endpoint]).expect("a string list serialises");
    let mut set = |k: &str, v: String| -> Result<()> {
        c.insert_json5(k, &v)
            .map_err(|e| anyhow::anyhow!("zenoh configuration {k} = {v}: {e}"))
    };
    set("mode", "\"peer\"".into())?;
    set("scouting/multicast/enabled", "false".into())?;
    if listen {
        set("listen/endpoints", loc)?;
    } else {
        set("connect/endpoints", loc)?;
        // Keep trying while the learner's host is away (zenoh's default for peers,
        // stated here because the link-cut recovery depends on it).
        set("connect/timeout_ms", "-1".into())?;
        set("connect/exit_on_failure", "false".into())?;
        set(
            "connect/retry",
            "{period_init_ms: 500, period_max_ms: 2000, period_increase_factor: 2.0}".into(),
        )?;
    }
    set("transport/link/tx/lease", lease_ms.to_string())?;
    set(
        "transport/link/tx/queue/congestion_control/block/wait_before_close",
        (lease_ms * 1000).to_string(),
    )?;
    match zenoh::open(c).wait() {
        Ok(s) => Ok(s),
        Err(e) if listen => bad(format!("cannot listen on {endpoint}: {e}")),
        Err(e) => Err(anyhow::anyhow!(
            "cannot start zenoh towards {endpoint}: {e}"
        )),
    }
}

fn node() -> Result<Node<ipc::Service>> {
    NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| anyhow::anyhow!("iceoryx2 node: {e:?}"))
}

/// Counters a bridge keeps (logged when it stops).
#[derive(Debug, Default)]
pub struct BridgeStats {
    /// Chunks forwarded.
    pub chunks: AtomicU64,
    /// Their bytes.
    pub chunk_bytes: AtomicU64,
    /// Chunks that could not go on: malformed, or (actor host) no learner listening.
    pub chunks_lost: AtomicU64,
    /// Weights forwarded.
    pub weights: AtomicU64,
    /// Lookups forwarded.
    pub lookups: AtomicU64,
    /// Lookups answered UNAVAILABLE.
    pub lookups_failed: AtomicU64,
}

impl BridgeStats {
    fn line(&self) -> String {
        let g = |a: &AtomicU64| a.load(Ordering::Relaxed);
        format!(
            "{} chunks ({:.1} MiB), {} lost; {} weights; {} lookups, {} unanswered",
            g(&self.chunks),
            g(&self.chunk_bytes) as f64 / (1 << 20) as f64,
            g(&self.chunks_lost),
            g(&self.weights),
            g(&self.lookups),
            g(&self.lookups_failed)
        )
    }
}

/// `fulcrum bridge`.
pub fn run(a: &BridgeArgs) -> Result<()> {
    install_signal_handlers();
    if let Some(p) = a.parent {
        die_with_parent(p);
    }
    match (&a.listen, &a.connect) {
        (Some(addr), _) => {
            let Some(ns) = &a.namespace else {
                return bad("bridge --listen needs --namespace (the run's)");
            };
            listen(addr, &a.run, ns, &a.zenoh)
        }
        (None, Some(addr)) => {
            let host = a.name.clone().unwrap_or_else(hostname);
            let want = Want {
                world: a.world.as_deref(),
                run_id: a.run_id.as_deref(),
            };
            connect(addr, &a.run, &host, want, a.give_up, &a.zenoh)
        }
        (None, None) => bad("bridge needs --listen ADDR or --connect ADDR"),
    }
}

/// This machine's hostname (or `host`).
pub fn hostname() -> String {
    super::bridge_hostname()
}

/// Whether a host name can be used in a key expression and a CSV field.
fn valid_host_name(n: &str) -> bool {
    !n.is_empty()
        && n.len() <= 64
        && n.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_' || b == b'.')
}

// ---------------------------------------------------------------- learner's side

/// The bridge on the learner's host, until SIGINT/SIGTERM (or the supervisor goes).
fn listen(addr: &str, dir: &Path, ns: &str, z: &ZenohArgs) -> Result<()> {
    let paths = RunPaths {
        dir: dir.to_path_buf(),
    };
    let cfg = RunConfig::load(&paths.config()).map_err(crate::commands::BadInput)?;
    let world = crate::commands::world(&cfg.world)?;
    let endpoint = locator(addr)?;
    let session = open_session(z, &endpoint, true)?;
    let stats = Arc::new(BridgeStats::default());

    // Join: a name gets the same index on every join (and after a resume).
    let hosts = Arc::new(Mutex::new(read_hosts(&paths.host_names())));
    let hello = Hello {
        run: ns.to_string(),
        run_tag: traj::run_tag(ns),
        run_id: cfg.run_id.clone(),
        world_source: world.source.clone(),
        world_hash: format!("{:016x}", world.content_hash()),
        world_name: world.name.clone(),
        config: std::fs::read_to_string(paths.config())
            .with_context(|| format!("cannot read {}", paths.config().display()))?,
        host: 0,
    };
    let names_file = paths.host_names();
    let hello_q = {
        let hosts = hosts.clone();
        session
            .declare_queryable("fulcrum/hello")
            .callback(move |q| {
                let name = q.parameters().get("name").unwrap_or("").to_string();
                if !valid_host_name(&name) {
                    let _ = q
                        .reply_err(format!("'{name}' is not a usable host name: use letters, digits, '-', '_' or '.'"))
                        .wait();
                    return;
                }
                let addr = q.parameters().get("from").unwrap_or("?").to_string();
                let index = {
                    let mut h = hosts.lock().unwrap_or_else(|p| p.into_inner());
                    let next = h.values().map(|(i, _)| *i).max().unwrap_or(0) + 1;
                    let index = h.entry(name.clone()).or_insert((next, addr)).0;
                    if let Err(e) = write_hosts(&names_file, &h) {
                        tracing::warn!("{e}");
                    }
                    index
                };
                let reply = Hello {
                    host: index,
                    ..hello.clone()
                };
                let text = toml::to_string(&reply).unwrap_or_default();
                eprintln!("fulcrum bridge: host '{name}' joined as host {index}");
                let _ = q.reply(q.key_expr().clone(), text).wait();
            })
            .wait()
            .map_err(|e| anyhow::anyhow!("zenoh queryable: {e}"))?
    };

    let stop = Arc::new(AtomicBool::new(false));
    let mut threads = Vec::new();
    // Chunks: zenoh -> the learner's trajectory service.
    {
        let sub = session
            .declare_subscriber(format!("fulcrum/{ns}/chunks/*"))
            .with(FifoChannel::new(4))
            .wait()
            .map_err(|e| anyhow::anyhow!("zenoh subscriber: {e}"))?;
        let (ns, stop, stats) = (ns.to_string(), stop.clone(), stats.clone());
        threads.push(std::thread::spawn(move || -> Result<()> {
            let node = node()?;
            let names = TrainNames::new(&ns);
            let tsvc = traj::trajectory_service(&node, &names).map_err(anyhow::Error::msg)?;
            let s2 = stop.clone();
            let publisher = tsvc
                .publisher_builder()
                .initial_max_slice_len(1 << 16)
                .allocation_strategy(AllocationStrategy::PowerOfTwo)
                .max_loaned_samples(2)
                .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
                .set_backpressure_handler(move |_: &iceoryx2::port::BackpressureInfo| {
                    // The learner's queue is full: the link waits with us.
                    if s2.load(Ordering::Relaxed) || STOP.load(Ordering::Relaxed) {
                        return BackpressureAction::DiscardDataAndFail;
                    }
                    std::thread::sleep(Duration::from_micros(500));
                    BackpressureAction::Retry
                })
                .create()
                .map_err(|e| anyhow::anyhow!("chunk publisher: {e:?}"))?;
            let wake =
                traj::wake_service(&node, &names.trajectories_wake).map_err(anyhow::Error::msg)?;
            let notifier = wake
                .notifier_builder()
                .create()
                .map_err(|e| anyhow::anyhow!("notifier: {e:?}"))?;
            while !stop.load(Ordering::Relaxed) {
                let Ok(Some(sample)) = sub.recv_timeout(Duration::from_millis(100)) else {
                    continue;
                };
                let bytes = sample.payload().to_bytes();
                let Some(h) = ChunkHeader::from_wire(&bytes) else {
                    stats.chunks_lost.fetch_add(1, Ordering::Relaxed);
                    continue;
                };
                let body = &bytes[ChunkHeader::WIRE_BYTES..];
                if body.len() as u64 != h.len {
                    tracing::warn!(
                        actor = h.actor,
                        "a chunk of the wrong length from another host"
                    );
                    stats.chunks_lost.fetch_add(1, Ordering::Relaxed);
                    continue;
                }
                let mut s = publisher
                    .loan_slice_uninit(body.len())
                    .map_err(|e| anyhow::anyhow!("loan: {e:?}"))?;
                *s.user_header_mut() = h;
                let s = s.write_from_slice(body);
                if s.send().is_err() {
                    break; // stopping
                }
                let _ = notifier.notify();
                stats.chunks.fetch_add(1, Ordering::Relaxed);
                stats
                    .chunk_bytes
                    .fetch_add(bytes.len() as u64, Ordering::Relaxed);
            }
            Ok(())
        }));
    }
    // Weights: the learner's policy service -> zenoh.
    {
        let publisher = session
            .declare_publisher(format!("fulcrum/{ns}/policy"))
            .congestion_control(CongestionControl::Block)
            .priority(Priority::DataHigh)
            .wait()
            .map_err(|e| anyhow::anyhow!("zenoh publisher: {e}"))?;
        let (ns, stop, stats) = (ns.to_string(), stop.clone(), stats.clone());
        threads.push(std::thread::spawn(move || -> Result<()> {
            let node = node()?;
            let names = TrainNames::new(&ns);
            let psvc = traj::policy_service(&node, &names).map_err(anyhow::Error::msg)?;
            let sub = psvc
                .subscriber_builder()
                .create()
                .map_err(|e| anyhow::anyhow!("weights subscriber: {e:?}"))?;
            let wake = traj::wake_service(&node, &names.policy_wake).map_err(anyhow::Error::msg)?;
            let listener = wake
                .listener_builder()
                .create()
                .map_err(|e| anyhow::anyhow!("listener: {e:?}"))?;
            while !stop.load(Ordering::Relaxed) {
                let _ = listener.timed_wait(|_| {}, Duration::from_millis(100));
                let mut newest: Option<Vec<u8>> = None;
                while let Ok(Some(s)) = sub.receive() {
                    let h: WeightsHeader = *s.user_header();
                    let mut out =
                        Vec::with_capacity(WeightsHeader::WIRE_BYTES + s.payload().len() * 4);
                    out.extend_from_slice(&h.to_wire());
                    for v in s.payload() {
                        out.extend_from_slice(&v.to_le_bytes());
                    }
                    newest = Some(out);
                }
                if let Some(w) = newest {
                    publisher
                        .put(w)
                        .wait()
                        .map_err(|e| anyhow::anyhow!("zenoh put: {e}"))?;
                    stats.weights.fetch_add(1, Ordering::Relaxed);
                }
            }
            Ok(())
        }));
    }
    // Lookups: zenoh queries -> the run's service.
    let _emp_q = if cfg.empowerment {
        let q = session
            .declare_queryable(format!("fulcrum/{ns}/empowerment"))
            .with(FifoChannel::new(256))
            .wait()
            .map_err(|e| anyhow::anyhow!("zenoh queryable: {e}"))?;
        let (ns, stop, stats) = (ns.to_string(), stop.clone(), stats.clone());
        threads.push(std::thread::spawn(move || -> Result<()> {
            serve_lookups(&q, &ns, &world, &stop, &stats);
            Ok(())
        }));
        true
    } else {
        false
    };
    println!("fulcrum bridge: ready, listening on {endpoint} for run {ns}");
    let _ = std::io::stdout().flush();
    while !STOP.load(Ordering::Relaxed) && threads.iter().all(|t| !t.is_finished()) {
        std::thread::sleep(Duration::from_millis(50));
    }
    // The run is over (or this bridge was stopped): tell the actor hosts.
    let _ = session.put(format!("fulcrum/{ns}/done"), "done").wait();
    stop.store(true, Ordering::Relaxed);
    let mut failure = None;
    for t in threads {
        if let Ok(Err(e)) = t.join() {
            failure.get_or_insert(e);
        }
    }
    drop(hello_q);
    let _ = session.close().wait();
    eprintln!("fulcrum bridge: stopped: {}", stats.line());
    match failure {
        Some(e) if !STOP.load(Ordering::Relaxed) => Err(e),
        _ => Ok(()),
    }
}

/// Answer zenoh lookups with the run's local service: up to `MAX_IN_FLIGHT` at a time.
pub(crate) fn serve_lookups(
    q: &zenoh::query::Queryable<zenoh::handlers::FifoChannelHandler<zenoh::query::Query>>,
    ns: &str,
    world: &World,
    stop: &AtomicBool,
    stats: &BridgeStats,
) {
    let mut client: Option<Client> = None;
    let mut req = EmpRequest::boxed();
    let mut batch: Vec<(zenoh::query::Query, u32)> = Vec::with_capacity(MAX_IN_FLIGHT);
    while !stop.load(Ordering::Relaxed) {
        let Ok(Some(first)) = q.recv_timeout(Duration::from_millis(100)) else {
            continue;
        };
        batch.clear();
        let mut next = Some(first);
        while let Some(query) = next.take() {
            let Some(bytes) = query.payload().map(|p| p.to_bytes()) else {
                let _ = query.reply_err("a lookup without a request").wait();
                continue;
            };
            if let Err(why) = wire::read_request(&bytes, &mut req) {
                let _ = query.reply_err(why).wait();
                continue;
            }
            if client.is_none() {
                client = Client::connect(ns, world, Duration::from_secs(2)).ok();
            }
            let sent = client.as_mut().map(|c| c.forward(&req));
            match sent {
                Some(Ok(())) => batch.push((query, req.seq)),
                _ => {
                    client = None;
                    reply_unavailable(&query, &req, stats);
                }
            }
            if batch.len() < MAX_IN_FLIGHT {
                next = q.try_recv().ok().flatten();
            }
        }
        for (query, seq) in batch.drain(..) {
            let answer = client.as_mut().map(|c| c.recv_response());
            match answer {
                Some(Ok(mut resp)) => {
                    resp.seq = seq;
                    stats.lookups.fetch_add(1, Ordering::Relaxed);
                    let _ = query
                        .reply(query.key_expr().clone(), wire::response(&resp))
                        .wait();
                }
                _ => {
                    client = None;
                    req.seq = seq;
                    reply_unavailable(&query, &req, stats);
                }
            }
        }
    }
}

fn reply_unavailable(query: &zenoh::query::Query, req: &EmpRequest, stats: &BridgeStats) {
    let mut r = EmpResponse::boxed();
    r.status = status::UNAVAILABLE;
    r.seq = req.seq;
    stats.lookups_failed.fetch_add(1, Ordering::Relaxed);
    let _ = query
        .reply(query.key_expr().clone(), wire::response(&r))
        .wait();
}

/// `name -> (index, address)` from `hosts.txt` (`index name address` lines).
fn read_hosts(path: &Path) -> BTreeMap<String, (u32, String)> {
    let mut out = BTreeMap::new();
    if let Ok(text) = std::fs::read_to_string(path) {
        for line in text.lines() {
            let w: Vec<&str> = line.split_whitespace().collect();
            if let [i, name, rest @ ..] = w.as_slice() {
                if let Ok(i) = i.parse::<u32>() {
                    out.insert(name.to_string(), (i, rest.join(" ")));
                }
            }
        }
    }
    out
}

fn write_hosts(path: &Path, hosts: &BTreeMap<String, (u32, String)>) -> Result<()> {
    let mut rows: Vec<(u32, &String, &String)> =
        hosts.iter().map(|(n, (i, a))| (*i, n, a)).collect();
    rows.sort();
    let text: String = rows
        .iter()
        .map(|(i, n, a)| format!("{i} {n} {a}\n"))
        .collect();
    write_atomic(path, text.as_bytes())
}

/// Write a file through a temporary file and a rename.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    fulcrum_shared::fsio::write_atomic(path, bytes)
        .with_context(|| format!("cannot write {}", path.display()))
}

// ---------------------------------------------------------------- actor host's side

/// What an actor host needs to start its actors (printed by the bridge when ready).
#[derive(Debug, Clone)]
pub struct Joined {
    /// The namespace of this host's shared-memory services.
    pub local_ns: String,
    /// The run's tag, for the actors' chunks.
    pub run_tag: u64,
    /// This host's index.
    pub host: u32,
}

impl Joined {
    /// The `ready` line the bridge prints.
    pub fn line(&self) -> String {
        format!(
            "fulcrum bridge: ready {} {:016x} {}",
            self.local_ns, self.run_tag, self.host
        )
    }

    /// Parse a `ready` line.
    pub fn parse(line: &str) -> Option<Joined> {
        let rest = line.strip_prefix("fulcrum bridge: ready ")?;
        let mut w = rest.split_whitespace();
        Some(Joined {
            local_ns: w.next()?.to_string(),
            run_tag: u64::from_str_radix(w.next()?, 16).ok()?,
            host: w.next()?.parse().ok()?,
        })
    }
}

/// Ask the learner's host to join, until it answers or `give_up` passes.
fn join(session: &zenoh::Session, endpoint: &str, name: &str, give_up: f64) -> Result<Hello> {
    let t0 = Instant::now();
    let mut said = false;
    loop {
        if STOP.load(Ordering::Relaxed) {
            anyhow::bail!("stopped before the learner answered");
        }
        let replies = session
            .get(format!("fulcrum/hello?name={name};from={}", hostname()))
            .timeout(Duration::from_secs(2))
            .wait()
            .map_err(|e| anyhow::anyhow!("zenoh get: {e}"))?;
        if let Ok(reply) = replies.recv() {
            match reply.result() {
                Ok(sample) => {
                    let text = sample
                        .payload()
                        .try_to_string()
                        .unwrap_or_default()
                        .to_string();
                    return toml::from_str(&text).map_err(|e| {
                        anyhow::anyhow!(
                            "the learner's host sent a join reply that does not parse: {e}"
                        )
                    });
                }
                Err(e) => {
                    let why = e.payload().try_to_string().unwrap_or_default().to_string();
                    return bad(format!("the learner's host refused this host: {why}"));
                }
            }
        }
        if t0.elapsed().as_secs_f64() > give_up {
            anyhow::bail!("no learner answered at {endpoint} within {give_up} s");
        }
        if !said {
            eprintln!("fulcrum bridge: waiting for the learner at {endpoint}");
            said = true;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// What an actor host insists on before it joins.
#[derive(Debug, Clone, Copy)]
struct Want<'a> {
    world: Option<&'a str>,
    run_id: Option<&'a str>,
}

/// The bridge of an actor host: join, write the run's config and world into `dir`,
/// then forward until the run is over or SIGINT/SIGTERM.
fn connect(
    addr: &str,
    dir: &Path,
    name: &str,
    want: Want,
    give_up: f64,
    z: &ZenohArgs,
) -> Result<()> {
    if !valid_host_name(name) {
        return bad(format!(
            "--name '{name}' is not usable: use letters, digits, '-', '_' or '.' (at most 64)"
        ));
    }
    let endpoint = locator(addr)?;
    let session = open_session(z, &endpoint, false)?;
    let hello = join(&session, &endpoint, name, give_up)?;
    let world = fulcrum_shared::parse_world(&hello.world_source, &hello.world_name)
        .map_err(|e| anyhow::anyhow!("the run's world does not parse here: {e}"))?;
    let hash = format!("{:016x}", world.content_hash());
    if hash != hello.world_hash {
        anyhow::bail!(
            "the run's world arrived damaged (hash {hash}, the learner's {})",
            hello.world_hash
        );
    }
    if let Some(id) = want.run_id.filter(|id| *id != hello.run_id) {
        return bad(format!(
            "the run at {endpoint} is '{}', not '{id}'",
            hello.run_id
        ));
    }
    if let Some(w) = want.world {
        let mine = crate::commands::world(w)?;
        if mine.content_hash() != world.content_hash() {
            return bad(format!(
                "the run at {endpoint} trains world '{}' (hash {}), not '{w}' (hash {:016x})",
                hello.world_name,
                hello.world_hash,
                mine.content_hash()
            ));
        }
    }
    if traj::run_tag(&hello.run) != hello.run_tag {
        anyhow::bail!("the learner's host sent a run tag that does not match its run");
    }
    // The run's settings, with the world as received.
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let world_path = dir.join("world.toml");
    write_atomic(&world_path, hello.world_source.as_bytes())?;
    let mut cfg: RunConfig = toml::from_str(&hello.config)
        .map_err(|e| anyhow::anyhow!("the run's config.toml does not parse here: {e}"))?;
    cfg.world = world_path.display().to_string();
    cfg.remote = false;
    write_atomic(&dir.join("config.toml"), cfg.to_toml().as_bytes())?;
    let local_ns = format!("{}.h{}", hello.run, hello.host);
    if !msg::valid_namespace(&local_ns) {
        anyhow::bail!("the run's namespace '{}' is not usable here", hello.run);
    }
    let joined = Joined {
        local_ns: local_ns.clone(),
        run_tag: hello.run_tag,
        host: hello.host,
    };
    let run = hello.run.clone();
    let stats = Arc::new(BridgeStats::default());
    let stop = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicBool::new(false));
    let _done_sub = {
        let done = done.clone();
        session
            .declare_subscriber(format!("fulcrum/{run}/done"))
            .callback(move |_| {
                done.store(true, Ordering::Relaxed);
                service::request_stop();
            })
            .wait()
            .map_err(|e| anyhow::anyhow!("zenoh subscriber: {e}"))?
    };
    let mut threads = Vec::new();
    // Chunks: this host's actors -> zenoh.
    {
        let publisher = session
            .declare_publisher(format!("fulcrum/{run}/chunks/{name}"))
            .congestion_control(CongestionControl::Block)
            .priority(Priority::Data)
            .wait()
            .map_err(|e| anyhow::anyhow!("zenoh publisher: {e}"))?;
        let (ns, stop, stats) = (local_ns.clone(), stop.clone(), stats.clone());
        threads.push(std::thread::spawn(move || -> Result<()> {
            let node = node()?;
            let names = TrainNames::new(&ns);
            let tsvc = traj::trajectory_service(&node, &names).map_err(anyhow::Error::msg)?;
            let sub = tsvc
                .subscriber_builder()
                .create()
                .map_err(|e| anyhow::anyhow!("chunk subscriber: {e:?}"))?;
            let wake =
                traj::wake_service(&node, &names.trajectories_wake).map_err(anyhow::Error::msg)?;
            let listener = wake
                .listener_builder()
                .create()
                .map_err(|e| anyhow::anyhow!("listener: {e:?}"))?;
            let mut buf: Vec<u8> = Vec::new();
            while !stop.load(Ordering::Relaxed) {
                let mut got = false;
                while let Ok(Some(s)) = sub.receive() {
                    got = true;
                    let h: ChunkHeader = *s.user_header();
                    buf.clear();
                    buf.extend_from_slice(&h.to_wire());
                    buf.extend_from_slice(s.payload());
                    drop(s);
                    let listening = publisher
                        .matching_status()
                        .wait()
                        .map(|m| m.matching())
                        .unwrap_or(false);
                    if !listening {
                        // No learner reachable: the chunk is lost (the learner sees
                        // the gap in this actor's sequence numbers).
                        stats.chunks_lost.fetch_add(1, Ordering::Relaxed);
                        continue;
                    }
                    publisher
                        .put(buf.clone())
                        .wait()
                        .map_err(|e| anyhow::anyhow!("zenoh put: {e}"))?;
                    stats.chunks.fetch_add(1, Ordering::Relaxed);
                    stats
                        .chunk_bytes
                        .fetch_add(buf.len() as u64, Ordering::Relaxed);
                }
                if !got {
                    let _ = listener.timed_wait(|_| {}, Duration::from_millis(100));
                }
            }
            Ok(())
        }));
    }
    // Weights: zenoh -> this host's policy service (only the newest matters).
    {
        let sub = session
            .declare_subscriber(format!("fulcrum/{run}/policy"))
            .with(RingChannel::new(1))
            .wait()
            .map_err(|e| anyhow::anyhow!("zenoh subscriber: {e}"))?;
        let (ns, stop, stats, tag) = (local_ns.clone(), stop.clone(), stats.clone(), hello.run_tag);
        threads.push(std::thread::spawn(move || -> Result<()> {
            let node = node()?;
            let names = TrainNames::new(&ns);
            let psvc = traj::policy_service(&node, &names).map_err(anyhow::Error::msg)?;
            let publisher = psvc
                .publisher_builder()
                .initial_max_slice_len(1 << 12)
                .allocation_strategy(AllocationStrategy::PowerOfTwo)
                .max_loaned_samples(2)
                .create()
                .map_err(|e| anyhow::anyhow!("weights publisher: {e:?}"))?;
            let wake = traj::wake_service(&node, &names.policy_wake).map_err(anyhow::Error::msg)?;
            let notifier = wake
                .notifier_builder()
                .create()
                .map_err(|e| anyhow::anyhow!("notifier: {e:?}"))?;
            let mut floats: Vec<f32> = Vec::new();
            while !stop.load(Ordering::Relaxed) {
                let Ok(Some(sample)) = sub.recv_timeout(Duration::from_millis(100)) else {
                    continue;
                };
                let bytes = sample.payload().to_bytes();
                let Some(h) = WeightsHeader::from_wire(&bytes) else {
                    continue;
                };
                let body = &bytes[WeightsHeader::WIRE_BYTES..];
                if h.run != tag || body.len() as u64 != h.len * 4 {
                    tracing::warn!("ignored weights of another run or length");
                    continue;
                }
                floats.clear();
                floats.extend(
                    body.chunks_exact(4)
                        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                );
                let mut s = publisher
                    .loan_slice_uninit(floats.len())
                    .map_err(|e| anyhow::anyhow!("loan: {e:?}"))?;
                *s.user_header_mut() = h;
                let s = s.write_from_slice(&floats);
                s.send()
                    .map_err(|e| anyhow::anyhow!("send weights: {e:?}"))?;
                let _ = notifier.notify();
                stats.weights.fetch_add(1, Ordering::Relaxed);
            }
            Ok(())
        }));
    }
    // This host's empowerment service: a stand-in that asks the learner's host.
    let result = if cfg.empowerment {
        let mut fwd = Forwarder::new(&session, &run, &world, stats.clone(), give_up)?;
        let line = joined.line();
        let r = service::serve_with(&mut fwd, &local_ns, Duration::from_micros(50), |_| {
            println!("{line}");
            let _ = std::io::stdout().flush();
        });
        r.map(|_| ()).map_err(anyhow::Error::from)
    } else {
        println!("{}", joined.line());
        let _ = std::io::stdout().flush();
        while !STOP.load(Ordering::Relaxed)
            && !done.load(Ordering::Relaxed)
            && threads.iter().all(|t| !t.is_finished())
        {
            std::thread::sleep(Duration::from_millis(50));
        }
        Ok(())
    };
    stop.store(true, Ordering::Relaxed);
    let mut failure = result.err();
    for t in threads {
        if let Ok(Err(e)) = t.join() {
            failure.get_or_insert(e);
        }
    }
    let _ = session.close().wait();
    eprintln!("fulcrum bridge: stopped: {}", stats.line());
    if done.load(Ordering::Relaxed) {
        println!("fulcrum bridge: the run is over");
        return Ok(());
    }
    match failure {
        Some(e) if !STOP.load(Ordering::Relaxed) => Err(e),
        _ => Ok(()),
    }
}

/// The empowerment service of an actor host: DESCRIBE from the learner's service (asked
/// once), everything else asked of it per request.
pub(crate) struct Forwarder {
    session: zenoh::Session,
    key: String,
    describe: Describe,
    stats: Arc<BridgeStats>,
    timeout: Duration,
}

impl Forwarder {
    pub(crate) fn new(
        session: &zenoh::Session,
        run: &str,
        world: &World,
        stats: Arc<BridgeStats>,
        give_up: f64,
    ) -> Result<Forwarder> {
        let mut f = Forwarder {
            session: session.clone(),
            key: format!("fulcrum/{run}/empowerment"),
            describe: Describe::empty(),
            stats,
            timeout: Duration::from_secs(2),
        };
        let mut req = EmpRequest::boxed();
        req.kind = msg::kind::DESCRIBE;
        req.world_hash = world.content_hash();
        let mut out = EmpResponse::boxed();
        let t0 = Instant::now();
        loop {
            if f.ask(&req, &mut out) && out.status == status::OK {
                break;
            }
            if STOP.load(Ordering::Relaxed) || t0.elapsed().as_secs_f64() > give_up {
                anyhow::bail!("the learner's empowerment service did not answer");
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        if out.describe.world_hash != world.content_hash() {
            anyhow::bail!("the learner's empowerment service serves another world");
        }
        f.describe = out.describe;
        Ok(f)
    }

    /// One round trip; false when no answer came.
    pub(crate) fn ask(&self, req: &EmpRequest, out: &mut EmpResponse) -> bool {
        let Ok(replies) = self
            .session
            .get(&self.key)
            .payload(wire::request(req))
            .priority(Priority::InteractiveHigh)
            .congestion_control(CongestionControl::Block)
            .timeout(self.timeout)
            .wait()
        else {
            return false;
        };
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                if wire::read_response(&sample.payload().to_bytes(), out).is_ok() {
                    return true;
                }
            }
        }
        false
    }
}

impl Answer for Forwarder {
    fn describe(&self) -> &Describe {
        &self.describe
    }

    fn answer(&mut self, req: &EmpRequest, out: &mut EmpResponse) {
        out.describe = self.describe;
        out.seq = req.seq;
        if req.kind == msg::kind::DESCRIBE {
            return;
        }
        if self.ask(req, out) {
            self.stats.lookups.fetch_add(1, Ordering::Relaxed);
            out.seq = req.seq;
        } else {
            self.stats.lookups_failed.fetch_add(1, Ordering::Relaxed);
            out.status = status::UNAVAILABLE;
            out.count = 0;
        }
    }
}

/// The actor id of actor `j` of host `host`.
pub fn actor_id(host: u32, j: usize) -> u32 {
    host * HOST_STRIDE + j as u32
}

/// Where an actor host works by default.
pub fn default_dir(name: &str) -> PathBuf {
    PathBuf::from("runs").join(format!("remote-{name}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_become_tcp_locators() {
        assert_eq!(locator("10.0.0.1:7447").unwrap(), "tcp/10.0.0.1:7447");
        assert_eq!(locator("hostb:80").unwrap(), "tcp/hostb:80");
        assert_eq!(locator("tcp/[::1]:7447").unwrap(), "tcp/[::1]:7447");
        for bad in ["10.0.0.1", ":7447", "h:port", "h:70000"] {
            let e = locator(bad).unwrap_err().to_string();
            assert!(e.contains(&format!("'{bad}' is not an address")), "{e}");
        }
    }

    #[test]
    fn the_ready_line_carries_namespace_tag_and_host() {
        let j = Joined {
            local_ns: "t1f.h3".into(),
            run_tag: 0x00ab_cdef_0123_4567,
            host: 3,
        };
        assert_eq!(j.line(), "fulcrum bridge: ready t1f.h3 00abcdef01234567 3");
        let back = Joined::parse(&j.line()).unwrap();
        assert_eq!(
            (back.local_ns.as_str(), back.run_tag, back.host),
            ("t1f.h3", j.run_tag, 3)
        );
        assert!(Joined::parse("fulcrum bridge: ready, listening on tcp/x:1 for run t").is_none());
        assert_eq!(actor_id(3, 2), 3 * 1024 + 2);
    }

    #[test]
    fn host_names_are_kept_across_joins_and_files() {
        let dir = std::env::temp_dir().join(format!("fulcrum-hosts-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("hosts.txt");
        let mut h = BTreeMap::new();
        h.insert("b".to_string(), (2, "vm2".to_string()));
        h.insert("a".to_string(), (1, "vm1".to_string()));
        write_hosts(&path, &h).unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "1 a vm1\n2 b vm2\n"
        );
        assert_eq!(read_hosts(&path), h);
        assert!(
            valid_host_name("node-7.lab_2") && !valid_host_name("a b") && !valid_host_name("x/y")
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
