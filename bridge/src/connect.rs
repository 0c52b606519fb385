//! The actor host's side: join, write the run's config and world, then forward chunks
//! out, weights in and lookups across until the run is over.

use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crate::error::refuse;
use crate::error::{fail, Context, Result};
use fulcrum_contracts::config::RunConfig;
use fulcrum_contracts::msg;
use fulcrum_contracts::stop::STOP;
use fulcrum_contracts::traj::{self, ChunkHeader, TrainNames, WeightsHeader};
use fulcrum_contracts::IpcError;
use fulcrum_empowerment::service;
use fulcrum_world::World;
use iceoryx2::prelude::*;
use zenoh::handlers::RingChannel;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::Wait;

use crate::error::ZenohError;
use crate::forward::Forwarder;
use crate::hello::{join, joined_line, valid_host_name, write_atomic, Hello, Joined};
use crate::secret::Secret;
use crate::session::{locator, node, open_session, Auth, ZenohOptions};
use crate::stats::BridgeStats;
use fulcrum_contracts::lines::ChildLine;

/// What an actor host insists on before it joins.
#[derive(Debug, Clone, Copy)]
pub struct Want<'a> {
    /// The world the run must train (a name or a file).
    pub world: Option<&'a str>,
    /// The run's id.
    pub run_id: Option<&'a str>,
}

/// The bridge of an actor host: join with the run's `secret`, write the run's config
/// and world into `dir`, then forward until the run is over or SIGINT/SIGTERM. The
/// session listens on nothing: this host accepts no connection.
pub fn connect(
    addr: &str,
    dir: &Path,
    name: &str,
    want: Want,
    give_up: f64,
    z: &ZenohOptions,
    secret: &Secret,
) -> Result<()> {
    if !valid_host_name(name) {
        return refuse(format!(
            "the host name '{name}' is not usable: use letters, digits, '-', '_' or '.' (at most 64)"
        ));
    }
    let endpoint = locator(addr)?;
    let auth = Auth {
        secret: secret.clone(),
        dictionary: None,
        run: None,
    };
    let session = open_session(z, &endpoint, false, Some(&auth))?;
    let hello = join(&session, &endpoint, name, give_up)?;
    let world = check_hello(&hello, want, &endpoint)?;
    let cfg = write_run(dir, &hello)?;
    let local_ns = format!("{}.h{}", hello.run, hello.host);
    if !msg::valid_namespace(&local_ns) {
        fail!("the run's namespace '{}' is not usable here", hello.run);
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
            .map_err(|e| ZenohError::new("subscriber", e))?
    };
    let threads = vec![
        chunks_out(&session, &run, name, &local_ns, &stop, &stats)?,
        weights_in(&session, &run, &local_ns, hello.run_tag, &stop, &stats)?,
    ];
    // This host's empowerment service: a stand-in that asks the learner's host.
    let result = if cfg.empowerment {
        let mut fwd = Forwarder::new(&session, &run, &world, stats.clone(), give_up)?;
        let line = joined_line(&joined);
        // This host's actors, whatever their number: the most a service takes.
        let clients = fulcrum_contracts::msg::MAX_CLIENTS;
        let r = service::serve_with(
            &mut fwd,
            &local_ns,
            Duration::from_micros(50),
            clients,
            |_| {
                println!("{line}");
                let _ = std::io::stdout().flush();
            },
        );
        r.map(|_| ()).map_err(crate::error::Error::source)
    } else {
        println!("{}", joined_line(&joined));
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
        println!("{}", ChildLine::RunOver);
        return Ok(());
    }
    match failure {
        Some(e) if !STOP.load(Ordering::Relaxed) => Err(e),
        _ => Ok(()),
    }
}

/// The world and run the learner's host sent, checked against what this host wants.
fn check_hello(hello: &Hello, want: Want, endpoint: &str) -> Result<World> {
    // A family's run stands on its run world (layout 0 carrying the family's text), as
    // on the learner's host.
    let world = if fulcrum_world::family::is_family_text(&hello.world_source) {
        fulcrum_world::family::parse_family(&hello.world_source, &hello.world_name)
            .and_then(|f| f.run_world())
    } else {
        fulcrum_world::parse_world(&hello.world_source, &hello.world_name)
    }
    .context("the run's world does not parse here")?;
    let hash = format!("{:016x}", world.content_hash());
    if hash != hello.world_hash {
        fail!(
            "the run's world arrived damaged (hash {hash}, the learner's {})",
            hello.world_hash
        );
    }
    if let Some(id) = want.run_id.filter(|id| *id != hello.run_id) {
        return refuse(format!(
            "the run at {endpoint} is '{}', not '{id}'",
            hello.run_id
        ));
    }
    if let Some(w) = want.world {
        let (mine, _) = fulcrum_world::family::load_world_or_family(w)?;
        if mine.content_hash() != world.content_hash() {
            return refuse(format!(
                "the run at {endpoint} trains world '{}' (hash {}), not '{w}' (hash {:016x})",
                hello.world_name,
                hello.world_hash,
                mine.content_hash()
            ));
        }
    }
    if traj::run_tag(&hello.run) != hello.run_tag {
        fail!("the learner's host sent a run tag that does not match its run");
    }
    Ok(world)
}

/// The run's settings in `dir`, with the world as received; returns the config.
fn write_run(dir: &Path, hello: &Hello) -> Result<RunConfig> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let world_path = dir.join("world.toml");
    write_atomic(&world_path, hello.world_source.as_bytes())?;
    let mut cfg: RunConfig =
        toml::from_str(&hello.config).context("the run's config.toml does not parse here")?;
    cfg.world = world_path.display().to_string();
    cfg.remote = false;
    write_atomic(&dir.join("config.toml"), cfg.to_toml().as_bytes())?;
    Ok(cfg)
}

/// Chunks of this host's actors -> zenoh, on a thread.
fn chunks_out(
    session: &zenoh::Session,
    run: &str,
    name: &str,
    local_ns: &str,
    stop: &Arc<AtomicBool>,
    stats: &Arc<BridgeStats>,
) -> Result<std::thread::JoinHandle<Result<()>>> {
    let publisher = session
        .declare_publisher(format!("fulcrum/{run}/chunks/{name}"))
        .congestion_control(CongestionControl::Block)
        .priority(Priority::Data)
        .wait()
        .map_err(|e| ZenohError::new("publisher", e))?;
    let (ns, stop, stats) = (local_ns.to_string(), stop.clone(), stats.clone());
    Ok(std::thread::spawn(move || -> Result<()> {
        let node = node()?;
        let names = TrainNames::new(&ns);
        let tsvc = traj::trajectory_service(&node, &names)?;
        let sub = tsvc
            .subscriber_builder()
            .create()
            .map_err(|e| IpcError::new("chunk subscriber", e))?;
        let wake = traj::wake_service(&node, &names.trajectories_wake)?;
        let listener = wake
            .listener_builder()
            .create()
            .map_err(|e| IpcError::new("listener", e))?;
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
                    .map_err(|e| ZenohError::new("put", e))?;
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
    }))
}

/// Weights from zenoh -> this host's policy service (only the newest matters), on a
/// thread; weights of another run or of the wrong length are ignored.
fn weights_in(
    session: &zenoh::Session,
    run: &str,
    local_ns: &str,
    tag: u64,
    stop: &Arc<AtomicBool>,
    stats: &Arc<BridgeStats>,
) -> Result<std::thread::JoinHandle<Result<()>>> {
    let sub = session
        .declare_subscriber(format!("fulcrum/{run}/policy"))
        .with(RingChannel::new(1))
        .wait()
        .map_err(|e| ZenohError::new("subscriber", e))?;
    let (ns, stop, stats) = (local_ns.to_string(), stop.clone(), stats.clone());
    Ok(std::thread::spawn(move || -> Result<()> {
        let node = node()?;
        let names = TrainNames::new(&ns);
        // Across hosts, every host's weights service is made for the most actors.
        let psvc = traj::policy_service(&node, &names, traj::WEIGHTS_SUBSCRIBERS)?;
        let publisher = psvc
            .publisher_builder()
            .initial_max_slice_len(1 << 12)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .max_loaned_samples(2)
            .create()
            .map_err(|e| IpcError::new("weights publisher", e))?;
        let wake = traj::wake_service(&node, &names.policy_wake)?;
        let notifier = wake
            .notifier_builder()
            .create()
            .map_err(|e| IpcError::new("notifier", e))?;
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
                .map_err(|e| IpcError::new("loan", e))?;
            *s.user_header_mut() = h;
            let s = s.write_from_slice(&floats);
            s.send().map_err(|e| IpcError::new("send weights", e))?;
            let _ = notifier.notify();
            stats.weights.fetch_add(1, Ordering::Relaxed);
        }
        Ok(())
    }))
}
