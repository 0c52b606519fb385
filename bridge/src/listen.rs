//! The learner's side: the bridge that listens for actor hosts (each must present the
//! run's secret, [`crate::secret`]), answers their hello, hands their chunks to the
//! learner, sends the weights out and answers lookups with the run's service, after
//! the checks of [`crate::guard`].

use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::error::Result;
use fulcrum_contracts::config::RunConfig;
use fulcrum_contracts::lines::ChildLine;
use fulcrum_contracts::msg::{status, wire, EmpRequest, EmpResponse, MAX_IN_FLIGHT};
use fulcrum_contracts::stop::STOP;
use fulcrum_contracts::traj::{self, ChunkHeader, TrainNames, WeightsHeader};
use fulcrum_contracts::IpcError;
use fulcrum_empowerment::service::Client;
use fulcrum_learner::paths::RunPaths;
use fulcrum_world::World;
use iceoryx2::port::BackpressureAction;
use iceoryx2::prelude::*;
use zenoh::handlers::FifoChannel;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::Wait;

use crate::error::ZenohError;
use crate::guard::{Guard, Hosts};
use crate::hello::{read_hosts, valid_host_name, write_hosts, Hello};
use crate::secret::Secret;
use crate::session::{locator, node, open_session, Auth, ZenohOptions};
use crate::stats::BridgeStats;

/// The bridge on the learner's host, until SIGINT/SIGTERM (or the supervisor goes).
pub fn listen(addr: &str, dir: &Path, ns: &str, z: &ZenohOptions) -> Result<()> {
    let paths = RunPaths {
        dir: dir.to_path_buf(),
    };
    let cfg = RunConfig::load(&paths.config())?;
    let (world, family) = fulcrum_world::family::load_world_or_family(&cfg.world)?;
    let endpoint = locator(addr)?;
    let (secret, secret_file) = Secret::for_run(dir)?;
    let auth = Auth {
        secret,
        dictionary: Some(secret_file),
        run: Some(ns.to_string()),
    };
    let session = open_session(z, &endpoint, true, Some(&auth))?;
    let stats = Arc::new(BridgeStats::default());
    let hosts: Hosts = Arc::new(Mutex::new(read_hosts(&paths.host_names())));
    let guard = Guard::new(ns, &cfg, &world, family, hosts.clone());
    let hello_q = answer_hellos(&session, &paths, &cfg, &world, ns, hosts)?;

    let stop = Arc::new(AtomicBool::new(false));
    let mut threads = vec![
        chunks_in(&session, ns, &guard, &stop, &stats)?,
        weights_out(&session, ns, &stop, &stats)?,
    ];
    if cfg.empowerment {
        let q = session
            .declare_queryable(format!("fulcrum/{ns}/empowerment"))
            .with(FifoChannel::new(256))
            .wait()
            .map_err(|e| ZenohError::new("queryable", e))?;
        let (ns, stop, stats) = (ns.to_string(), stop.clone(), stats.clone());
        threads.push(std::thread::spawn(move || -> Result<()> {
            serve_lookups(&q, &ns, &world, &stop, &stats, &|k| guard.lookup(k));
            Ok(())
        }));
    }
    println!(
        "{}",
        ChildLine::BridgeListening {
            endpoint: endpoint.to_string(),
            run: ns.to_string(),
        }
    );
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

/// The run's config as a host receives it: the world named, not its path here.
fn config_for_hosts(cfg: &RunConfig, world: &World) -> String {
    let mut c = cfg.clone();
    c.world = world.name.clone();
    c.to_toml()
}

/// Answers `fulcrum/hello`: a name gets the same host index on every join (and after a
/// resume), kept in the run's hosts file.
fn answer_hellos(
    session: &zenoh::Session,
    paths: &RunPaths,
    cfg: &RunConfig,
    world: &World,
    ns: &str,
    hosts: Hosts,
) -> Result<zenoh::query::Queryable<()>> {
    let hello = Hello {
        run: ns.to_string(),
        run_tag: traj::run_tag(ns),
        run_id: cfg.run_id.clone(),
        world_source: world.source.clone(),
        world_hash: format!("{:016x}", world.content_hash()),
        world_name: world.name.clone(),
        config: config_for_hosts(cfg, world),
        host: 0,
    };
    let names_file = paths.host_names();
    session
        .declare_queryable("fulcrum/hello")
        .callback(move |q| {
            let name = q.parameters().get("name").unwrap_or("").to_string();
            if !valid_host_name(&name) {
                let _ = q
                    .reply_err(format!(
                        "'{name}' is not a usable host name: use letters, digits, '-', '_' or '.'"
                    ))
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
        .map_err(|e| ZenohError::new("queryable", e).into())
}

/// Chunks from other hosts: zenoh -> the learner's trajectory service, on a thread.
fn chunks_in(
    session: &zenoh::Session,
    ns: &str,
    guard: &Guard,
    stop: &Arc<AtomicBool>,
    stats: &Arc<BridgeStats>,
) -> Result<std::thread::JoinHandle<Result<()>>> {
    let sub = session
        .declare_subscriber(format!("fulcrum/{ns}/chunks/*"))
        .with(FifoChannel::new(4))
        .wait()
        .map_err(|e| ZenohError::new("subscriber", e))?;
    let (ns, stop, stats) = (ns.to_string(), stop.clone(), stats.clone());
    let guard = guard.clone();
    Ok(std::thread::spawn(move || -> Result<()> {
        let node = node()?;
        let names = TrainNames::new(&ns);
        let tsvc = traj::trajectory_service(&node, &names)?;
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
            .map_err(|e| IpcError::new("chunk publisher", e))?;
        let wake = traj::wake_service(&node, &names.trajectories_wake)?;
        let notifier = wake
            .notifier_builder()
            .create()
            .map_err(|e| IpcError::new("notifier", e))?;
        while !stop.load(Ordering::Relaxed) {
            let Ok(Some(sample)) = sub.recv_timeout(Duration::from_millis(100)) else {
                continue;
            };
            let name = sample.key_expr().as_str().rsplit('/').next().unwrap_or("");
            let bytes = sample.payload().to_bytes();
            // Checked whole before any shared memory is loaned for it.
            let h = match guard.chunk(name, &bytes) {
                Ok(h) => h,
                Err(why) => {
                    let what = format!("a chunk of {} bytes from '{name}'", bytes.len());
                    stats.refuse(&stats.refused_chunks, &what, &why);
                    continue;
                }
            };
            let body = &bytes[ChunkHeader::WIRE_BYTES..];
            let mut s = publisher
                .loan_slice_uninit(body.len())
                .map_err(|e| IpcError::new("loan", e))?;
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
    }))
}

/// The learner's weights: its policy service -> zenoh, the newest only, on a thread.
fn weights_out(
    session: &zenoh::Session,
    ns: &str,
    stop: &Arc<AtomicBool>,
    stats: &Arc<BridgeStats>,
) -> Result<std::thread::JoinHandle<Result<()>>> {
    let publisher = session
        .declare_publisher(format!("fulcrum/{ns}/policy"))
        .congestion_control(CongestionControl::Block)
        .priority(Priority::DataHigh)
        .wait()
        .map_err(|e| ZenohError::new("publisher", e))?;
    let (ns, stop, stats) = (ns.to_string(), stop.clone(), stats.clone());
    Ok(std::thread::spawn(move || -> Result<()> {
        let node = node()?;
        let names = TrainNames::new(&ns);
        // Across hosts, every host's weights service is made for the most actors.
        let psvc = traj::policy_service(&node, &names, traj::WEIGHTS_SUBSCRIBERS)?;
        let sub = psvc
            .subscriber_builder()
            .create()
            .map_err(|e| IpcError::new("weights subscriber", e))?;
        let wake = traj::wake_service(&node, &names.policy_wake)?;
        let listener = wake
            .listener_builder()
            .create()
            .map_err(|e| IpcError::new("listener", e))?;
        while !stop.load(Ordering::Relaxed) {
            let _ = listener.timed_wait(|_| {}, Duration::from_millis(100));
            let mut newest: Option<Vec<u8>> = None;
            while let Ok(Some(s)) = sub.receive() {
                let h: WeightsHeader = *s.user_header();
                let mut out = Vec::with_capacity(WeightsHeader::WIRE_BYTES + s.payload().len() * 4);
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
                    .map_err(|e| ZenohError::new("put", e))?;
                stats.weights.fetch_add(1, Ordering::Relaxed);
            }
        }
        Ok(())
    }))
}

/// Answer zenoh lookups with the run's local service: up to `MAX_IN_FLIGHT` at a time;
/// a request that does not parse, or whose kind `allowed` refuses, is answered with an
/// error and counted.
pub fn serve_lookups(
    q: &zenoh::query::Queryable<zenoh::handlers::FifoChannelHandler<zenoh::query::Query>>,
    ns: &str,
    world: &World,
    stop: &AtomicBool,
    stats: &BridgeStats,
    allowed: &dyn Fn(u32) -> Result<(), &'static str>,
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
                let why = "a lookup without a request";
                stats.refuse(&stats.refused_lookups, "a lookup", why);
                let _ = query.reply_err(why).wait();
                continue;
            };
            if let Err(why) = wire::read_request(&bytes, &mut req) {
                stats.refuse(&stats.refused_lookups, "a lookup", &why);
                let _ = query.reply_err(why).wait();
                continue;
            }
            if let Err(why) = allowed(req.kind) {
                stats.refuse(&stats.refused_lookups, "a lookup", why);
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

pub fn reply_unavailable(query: &zenoh::query::Query, req: &EmpRequest, stats: &BridgeStats) {
    let mut r = EmpResponse::boxed();
    r.status = status::UNAVAILABLE;
    r.seq = req.seq;
    stats.lookups_failed.fetch_add(1, Ordering::Relaxed);
    let _ = query
        .reply(query.key_expr().clone(), wire::response(&r))
        .wait();
}
