//! `fulcrum bench --remote [ADDR]` (feature `multihost`): what the link between hosts
//! carries, measured with the bridges' own code and settings.
//!
//! A peer (`fulcrum __remote-peer --listen ADDR`, started here on 127.0.0.1, or by
//! `scripts/two-hosts.sh bench` in a second network namespace) subscribes to chunks
//! and answers lookups with the learner-side bridge's lookup loop in front of a real
//! `fulcrum serve exp2`. This side
//!
//! - puts chunks (a chunk header and a payload of 64 KiB or 1 MiB) with blocking
//!   congestion control for a few seconds, then asks the peer how many arrived: MiB/s
//!   from the first put to the last arrival, and whether any was lost;
//! - asks lookups of 1 and of 128 states (an actor's sub-batch) through the actor-side
//!   stand-in service's round trip: p50 and p99.

use std::io::{BufRead, BufReader, Write};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{ensure, Context, Result};
use fulcrum_bridge::zenoh::handlers::FifoChannel;
use fulcrum_bridge::zenoh::qos::{CongestionControl, Priority};
use fulcrum_bridge::zenoh::Wait;
use fulcrum_contracts::lines::ChildLine;
use fulcrum_contracts::msg::{kind, EmpRequest, EmpResponse};
use fulcrum_contracts::traj::ChunkHeader;
use fulcrum_empowerment::{Engine, Limits};
use fulcrum_world::load_world;

use super::service::{sample_states, ServeChild};
use super::{percentile, Figure};
use fulcrum_bridge::{
    locator, open_session, serve_lookups, Auth, BridgeStats, Forwarder, Secret, ZenohOptions,
};
use fulcrum_run::process::{install_signal_handlers, STOP};

const RUN: &str = "bench";

fn zargs() -> ZenohOptions {
    ZenohOptions {
        session_timeout: 10.0,
        zenoh_config: None,
    }
}

/// `fulcrum __remote-peer`: the far end of `bench --remote`, until SIGINT/SIGTERM.
pub fn peer(listen: &str) -> Result<()> {
    install_signal_handlers();
    let endpoint = locator(listen)?;
    let ns = format!("rpeer-{}", std::process::id());
    let _serve = ServeChild::start("exp2", &ns)?;
    let world = load_world("exp2")?;
    // Beyond loopback the peer demands a secret (FULCRUM_SECRET, the same at both ends).
    let dict_dir = std::env::temp_dir().join(format!("fulcrum-peer-{}", std::process::id()));
    let auth = match Secret::from_file_or_env(None)? {
        Some(secret) => {
            std::fs::create_dir_all(&dict_dir)?;
            let dictionary = Some(secret.write_dictionary(&dict_dir)?);
            Some(Auth {
                secret,
                dictionary,
                run: None,
            })
        }
        None => None,
    };
    let session = open_session(&zargs(), &endpoint, true, auth.as_ref());
    let _ = std::fs::remove_dir_all(&dict_dir); // zenoh has read it
    let session = session?;
    let (count, bytes) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicU64::new(0)));
    let sub = session
        .declare_subscriber(format!("fulcrum/{RUN}/chunks/*"))
        .with(FifoChannel::new(4))
        .wait()
        .map_err(|e| anyhow::anyhow!("zenoh subscriber: {e}"))?;
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let sink = {
        let (count, bytes, stop) = (count.clone(), bytes.clone(), stop.clone());
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                if let Ok(Some(s)) = sub.recv_timeout(Duration::from_millis(100)) {
                    let b = s.payload().to_bytes();
                    // As the learner-side bridge does before it copies the chunk on.
                    if ChunkHeader::from_wire(&b).is_some() {
                        count.fetch_add(1, Ordering::Relaxed);
                        bytes.fetch_add(b.len() as u64, Ordering::Relaxed);
                    }
                }
            }
        })
    };
    let _stats = {
        let (count, bytes) = (count.clone(), bytes.clone());
        session
            .declare_queryable(format!("fulcrum/{RUN}/stats"))
            .callback(move |q| {
                let text = format!(
                    "{} {}",
                    count.load(Ordering::Relaxed),
                    bytes.load(Ordering::Relaxed)
                );
                let _ = q.reply(q.key_expr().clone(), text).wait();
            })
            .wait()
            .map_err(|e| anyhow::anyhow!("zenoh queryable: {e}"))?
    };
    let lookups = session
        .declare_queryable(format!("fulcrum/{RUN}/empowerment"))
        .with(FifoChannel::new(256))
        .wait()
        .map_err(|e| anyhow::anyhow!("zenoh queryable: {e}"))?;
    let served = {
        let (stop, ns) = (stop.clone(), ns.clone());
        std::thread::spawn(move || {
            let stats = BridgeStats::default();
            serve_lookups(&lookups, &ns, &world, &stop, &stats, &|_| Ok(()));
        })
    };
    println!(
        "{}",
        ChildLine::PeerReady {
            endpoint: endpoint.to_string(),
        }
    );
    let _ = std::io::stdout().flush();
    while !STOP.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(50));
    }
    stop.store(true, Ordering::Relaxed);
    let _ = sink.join();
    let _ = served.join();
    let _ = session.close().wait();
    Ok(())
}

/// The peer's counters: chunks and bytes received so far.
fn peer_stats(session: &fulcrum_bridge::zenoh::Session) -> Option<(u64, u64)> {
    let replies = session
        .get(format!("fulcrum/{RUN}/stats"))
        .timeout(Duration::from_secs(2))
        .wait()
        .ok()?;
    let reply = replies.recv().ok()?;
    let text = reply
        .result()
        .ok()?
        .payload()
        .try_to_string()
        .ok()?
        .to_string();
    let mut w = text.split_whitespace();
    Some((w.next()?.parse().ok()?, w.next()?.parse().ok()?))
}

/// A peer this bench started on 127.0.0.1 (stopped on drop).
struct LocalPeer(std::process::Child);

impl Drop for LocalPeer {
    fn drop(&mut self) {
        // SAFETY: kill(2) on our own child's pid.
        unsafe {
            libc::kill(self.0.id() as libc::pid_t, libc::SIGTERM);
        }
        let _ = self.0.wait();
    }
}

/// The remote figures, against the peer at `addr` (or one started on 127.0.0.1).
pub(super) fn run(addr: Option<&str>, quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    let (_local, addr, where_) = match addr {
        Some(a) => (None, a.to_string(), format!("peer at {a}")),
        None => {
            let port = std::net::TcpListener::bind("127.0.0.1:0")?
                .local_addr()?
                .port();
            let a = format!("127.0.0.1:{port}");
            let mut child = std::process::Command::new(std::env::current_exe()?)
                .args(fulcrum_run::argv::remote_peer(&a))
                .stdout(std::process::Stdio::piped())
                .stdin(std::process::Stdio::null())
                .spawn()
                .context("cannot start the remote peer")?;
            let out = child.stdout.take().context("peer stdout")?;
            let peer = LocalPeer(child);
            let ready = BufReader::new(out)
                .lines()
                .map_while(|l| l.ok())
                .any(|l| ChildLine::says_ready(&l));
            ensure!(ready, "the remote peer stopped before it was ready");
            (Some(peer), a, "peer on 127.0.0.1 (one machine)".to_string())
        }
    };
    let endpoint = locator(&addr)?;
    let auth = Secret::from_file_or_env(None)?.map(|secret| Auth {
        secret,
        dictionary: None,
        run: None,
    });
    let session = open_session(&zargs(), &endpoint, false, auth.as_ref())?;
    let t0 = Instant::now();
    while peer_stats(&session).is_none() {
        ensure!(
            t0.elapsed() < Duration::from_secs(30),
            "no remote peer answered at {endpoint}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }

    // Chunks.
    let publisher = session
        .declare_publisher(format!("fulcrum/{RUN}/chunks/bench"))
        .congestion_control(CongestionControl::Block)
        .priority(Priority::Data)
        .wait()
        .map_err(|e| anyhow::anyhow!("zenoh publisher: {e}"))?;
    let secs = if quick { 1.0 } else { 4.0 };
    for (label, size) in [("64 KiB", 64usize << 10), ("1 MiB", 1 << 20)] {
        let h = ChunkHeader {
            len: size as u64,
            ..ChunkHeader::default()
        };
        let mut msg = h.to_wire().to_vec();
        msg.extend((0..size).map(|i| (i * 31 % 251) as u8));
        let (c0, b0) = peer_stats(&session).context("the peer stopped answering")?;
        let t0 = Instant::now();
        let mut sent = 0u64;
        while t0.elapsed().as_secs_f64() < secs {
            publisher
                .put(msg.clone())
                .wait()
                .map_err(|e| anyhow::anyhow!("zenoh put: {e}"))?;
            sent += 1;
        }
        let (mut c, mut b) = (c0, b0);
        let wait0 = Instant::now();
        while c - c0 < sent && wait0.elapsed() < Duration::from_secs(30) {
            if let Some((cc, bb)) = peer_stats(&session) {
                (c, b) = (cc, bb);
            }
        }
        let elapsed = t0.elapsed().as_secs_f64();
        let got = c - c0;
        ensure!(got == sent, "{label} chunks: {sent} sent, {got} arrived");
        figs.push(Figure {
            zero_ok: false,
            name: format!("remote chunks, {label}"),
            value: (b - b0) as f64 / elapsed / (1 << 20) as f64,
            unit: "MiB/s",
            note: format!("({sent} chunks, none lost, blocking congestion control; {where_})"),
        });
    }

    // Lookups through the actor-side stand-in's round trip.
    let w = load_world("exp2")?;
    let fwd = Forwarder::new(&session, RUN, &w, Arc::new(BridgeStats::default()), 30.0)?;
    let e = Engine::new(&w, Limits::default())?;
    let states = sample_states(&e, 128);
    let rounds = if quick { 300 } else { 3000 };
    let mut req = EmpRequest::boxed();
    req.kind = kind::LOOKUP;
    req.world_hash = w.content_hash();
    let mut out = EmpResponse::boxed();
    for n in [1usize, 128] {
        req.count = n as u32;
        for (slot, s) in req.states.iter_mut().zip(&states[..n]) {
            *slot = s.to_bytes();
        }
        let mut t = Vec::with_capacity(rounds);
        for _ in 0..rounds {
            let t0 = Instant::now();
            ensure!(fwd.ask(&req, &mut out), "a remote lookup got no answer");
            t.push(t0.elapsed().as_secs_f64() * 1e6);
            ensure!(
                out.status == 0 && out.item_status[..n].iter().all(|&s| s == 0),
                "a remote lookup failed"
            );
        }
        t.sort_by(f64::total_cmp);
        for (q, label) in [(0.5, "p50"), (0.99, "p99")] {
            figs.push(Figure {
                zero_ok: false,
                name: format!("remote lookup round trip {label}, {n} state(s)"),
                value: percentile(&t, q),
                unit: "us",
                note: if q == 0.5 {
                    format!("({rounds} lookups, exp2, via the learner-side bridge and service; {where_})")
                } else {
                    String::new()
                },
            });
        }
    }
    drop(publisher);
    let _ = session.close().wait();
    Ok(())
}
