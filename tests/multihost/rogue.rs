//! A rogue zenoh peer against a real run: `train --listen` on loopback, one honest
//! actor host, and a zenoh session inside this test that tries each attack. Without
//! the run's secret it gets no session at all; with it, every message the bridge must
//! not let through is refused and counted, and the run goes on to its end.

use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::time::Duration;

use fulcrum_bridge::zenoh::qos::CongestionControl;
use fulcrum_bridge::zenoh::{self, Wait};
use fulcrum_bridge::Hello;
use fulcrum_contracts::config::RunConfig;
use fulcrum_contracts::msg::{kind, wire, EmpRequest};
use fulcrum_contracts::traj::{self, ChunkHeader, ChunkLayout, WeightsHeader};

use super::{host_rows, loopback, Loopback, Proc};
use crate::util::free_port;
use crate::util::{fulcrum, pids_with, wait_until, TempDir};

/// A zenoh peer towards `addr`, presenting `secret` when given; it listens on nothing.
fn rogue(addr: &str, secret: Option<&str>, mode: &str) -> zenoh::Session {
    let mut c = zenoh::Config::default();
    let set = |c: &mut zenoh::Config, k: &str, v: &str| c.insert_json5(k, v).unwrap();
    set(&mut c, "mode", &format!("\"{mode}\""));
    set(&mut c, "connect/endpoints", &format!("[\"tcp/{addr}\"]"));
    set(&mut c, "listen/endpoints", "[]");
    set(&mut c, "scouting/multicast/enabled", "false");
    // Open at once and keep trying in the background, as an actor host's bridge does.
    set(&mut c, "connect/timeout_ms", "-1");
    set(&mut c, "connect/exit_on_failure", "false");
    if let Some(s) = secret {
        set(&mut c, "transport/auth/usrpwd/user", "\"fulcrum\"");
        set(
            &mut c,
            "transport/auth/usrpwd/password",
            &format!("\"{s}\""),
        );
    }
    zenoh::open(c).wait().unwrap()
}

/// The text of the first reply to a `get`, or the error reply's, or `None`.
fn ask(s: &zenoh::Session, key: &str, payload: Option<Vec<u8>>) -> Option<Result<Vec<u8>, String>> {
    let mut g = s.get(key).timeout(Duration::from_secs(3));
    if let Some(p) = payload {
        g = g.payload(p);
    }
    let replies = g.wait().unwrap();
    let reply = replies.recv().ok()?;
    Some(match reply.result() {
        Ok(sample) => Ok(sample.payload().to_bytes().to_vec()),
        Err(e) => Err(e.payload().try_to_string().unwrap_or_default().to_string()),
    })
}

/// TCP sockets in state LISTEN held by process `pid` (its fds against /proc/net/tcp*).
fn listening_sockets(pid: u32) -> usize {
    let inodes: Vec<String> = std::fs::read_dir(format!("/proc/{pid}/fd"))
        .map(|d| {
            d.flatten()
                .filter_map(|e| std::fs::read_link(e.path()).ok())
                .filter_map(|l| {
                    let l = l.display().to_string();
                    l.strip_prefix("socket:[")
                        .and_then(|r| r.strip_suffix(']'))
                        .map(str::to_string)
                })
                .collect()
        })
        .unwrap_or_default();
    let mut n = 0;
    for table in ["tcp", "tcp6"] {
        let text = std::fs::read_to_string(format!("/proc/{pid}/net/{table}")).unwrap();
        for l in text.lines().skip(1) {
            let f: Vec<&str> = l.split_whitespace().collect();
            if f.len() > 9 && f[3] == "0A" && inodes.iter().any(|i| i == f[9]) {
                n += 1;
            }
        }
    }
    n
}

/// A chunk for `actor` with the run's shape, every action set to `action`, and `extra`
/// bytes of body beyond the layout.
fn chunk(cfg: &RunConfig, hello: &Hello, actor: u32, action: u8, extra: usize) -> Vec<u8> {
    let world = fulcrum_world::parse_world(&hello.world_source, &hello.world_name).unwrap();
    let shape = cfg.shape(&world);
    let layout = ChunkLayout {
        envs: cfg.envs_per_actor,
        steps: cfg.steps_per_chunk,
        cells: shape.cells,
        flags: shape.flags,
    };
    let run = &hello.run;
    let body_len = layout.bytes() + extra;
    let h = ChunkHeader {
        run: traj::run_tag(run),
        world_hash: world.content_hash(),
        actor,
        envs: layout.envs as u32,
        steps: layout.steps as u32,
        cells: layout.cells as u32,
        flags: layout.flags as u32,
        actions: world.num_actions() as u32,
        len: body_len as u64,
        ..ChunkHeader::default()
    };
    let mut out = h.to_wire().to_vec();
    out.resize(ChunkHeader::WIRE_BYTES + body_len, 0);
    let body = &mut out[ChunkHeader::WIRE_BYTES..];
    for i in layout.range(traj::Section::Actions) {
        body[i] = action;
    }
    out
}

/// The counts in the bridge's last `refused:` line: (chunks, lookups).
fn refused(text: &str) -> Option<(u64, u64)> {
    let line = text
        .lines()
        .rev()
        .find(|l| l.contains("fulcrum bridge: stopped:"))?;
    let rest = line.split("refused: ").nth(1)?;
    let n: Vec<u64> = rest
        .split(|c: char| !c.is_ascii_digit())
        .filter_map(|w| w.parse().ok())
        .collect();
    Some((n[0], n[1]))
}

#[test]
fn a_rogue_peer_is_refused_at_each_step_and_the_run_goes_on() {
    let Loopback {
        dir,
        far,
        addr,
        mut learner,
    } = loopback("rogue", "exp2 --actors 1 --steps 600064");

    // The run's secret: owner-only, in the run directory, said once with the join line.
    let file = dir.join("secret");
    let mode = std::fs::metadata(&file).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600, "the secret file's mode is {mode:o}");
    let secret = std::fs::read_to_string(&file).unwrap();
    let secret = secret.trim().strip_prefix("fulcrum:").unwrap().to_string();
    assert_eq!(secret.len(), 64);
    assert_eq!(
        learner.text().matches(&secret).count(),
        1,
        "{}",
        learner.text()
    );
    assert!(learner
        .text()
        .contains(&format!("FULCRUM_SECRET={secret} fulcrum actor-host")));

    // An actor host without the secret stops before it starts anything (exit 2).
    let none = fulcrum()
        .args(["actor-host", "--connect", &addr, "--name", "nosecret"])
        .arg("--dir")
        .arg(far.join("nosecret"))
        .env_remove("FULCRUM_SECRET")
        .output()
        .unwrap();
    let says = String::from_utf8_lossy(&none.stderr);
    assert_eq!(none.status.code(), Some(2), "{says}");
    assert!(says.contains("needs its secret"), "{says}");

    // The honest host, with the secret in its environment.
    let mut host = fulcrum();
    host.args([
        "actor-host",
        "--connect",
        &addr,
        "--name",
        "near",
        "--actors",
        "1",
    ])
    .env("FULCRUM_SECRET", &secret)
    .arg("--dir")
    .arg(&far);
    let mut host = Proc::start(host);
    let near_chunks = |dir: &Path| {
        host_rows(dir)
            .iter()
            .filter(|r| r.host == 1)
            .map(|r| r.chunks)
            .sum::<u64>()
    };
    wait_until(Duration::from_secs(60), "the honest host joining", || {
        near_chunks(&dir) > 2
    });
    // An actor host accepts no connection: none of its processes listens.
    let far_s = far.display().to_string();
    let host_pids: Vec<u32> = [host.child.id()]
        .into_iter()
        .chain(pids_with(&["bridge", "--connect", &far_s]))
        .chain(pids_with(&["__actor", &far_s]))
        .collect();
    assert_eq!(host_pids.len(), 3, "actor-host, its bridge, its actor");
    for pid in &host_pids {
        assert_eq!(listening_sockets(*pid), 0, "process {pid} listens");
    }
    // The learner's bridge does listen (the check above can see a listening socket).
    let bridge = pids_with(&["bridge", "--listen", &addr])[0];
    assert_eq!(listening_sockets(bridge), 1);

    // Without the secret, or with a wrong one, there is no session: no hello answer.
    for s in [None, Some("00".repeat(32))] {
        let r = rogue(&addr, s.as_deref(), "peer");
        std::thread::sleep(Duration::from_millis(500));
        assert_eq!(r.info().peers_zid().wait().count(), 0);
        assert!(ask(&r, "fulcrum/hello?name=rogue;from=x", None).is_none());
        let _ = r.close().wait();
    }

    // With the secret: a session, and a hello without any path of the learner's host.
    let r = rogue(&addr, Some(&secret), "peer");
    let reply = ask(&r, "fulcrum/hello?name=rogue;from=x", None)
        .expect("a hello reply")
        .expect("joined");
    let text = String::from_utf8(reply).unwrap();
    assert!(!text.contains(&dir.display().to_string()), "{text}");
    let hello: Hello = toml::from_str(&text).unwrap();
    let cfg: RunConfig = toml::from_str(&hello.config).unwrap();
    assert_eq!(cfg.world, "exp2");
    assert!(!hello.config.contains('/'), "{text}");
    assert_eq!(hello.host, 2);
    let run = hello.run.clone();
    // Blocking congestion control, as real hosts send: zenoh's default for a put drops
    // it when the queue is full, which the 8 MiB chunk below can make happen on a slow
    // machine, and a dropped attack would never reach the bridge to be refused.
    let put = |key: &str, bytes: Vec<u8>| {
        r.put(key, bytes)
            .congestion_control(CongestionControl::Block)
            .wait()
            .unwrap()
    };

    // Chunks: for the honest host's actor, oversized, bad contents, from a host that
    // never joined: 4 refused.
    let mine = format!("fulcrum/{run}/chunks/rogue");
    put(&mine, chunk(&cfg, &hello, 1024, 0, 0));
    put(&mine, chunk(&cfg, &hello, 2048, 0, 8 << 20));
    put(&mine, chunk(&cfg, &hello, 2048, 200, 0));
    put(
        &format!("fulcrum/{run}/chunks/ghost"),
        chunk(&cfg, &hello, 2048, 0, 0),
    );
    // Lookups: QUERY, and VISIT in a run without the count bonus: 2 refused.
    for k in [kind::QUERY, kind::VISIT] {
        let mut req = EmpRequest::boxed();
        req.kind = k;
        req.world_hash = 1;
        let answer = ask(
            &r,
            &format!("fulcrum/{run}/empowerment"),
            Some(wire::request(&req)),
        );
        assert!(matches!(answer, Some(Err(_))), "kind {k}: {answer:?}");
    }
    // `done` and weights from a host: refused by zenoh's access control on arrival
    // (not counted by the bridge); the honest host does not stop.
    put(&format!("fulcrum/{run}/done"), b"done".to_vec());
    let w = WeightsHeader {
        run: traj::run_tag(&run),
        len: 4,
        ..WeightsHeader::default()
    };
    let mut weights = w.to_wire().to_vec();
    weights.extend_from_slice(&[0u8; 16]);
    put(&format!("fulcrum/{run}/policy"), weights);
    // And from a session in zenoh's client mode, which a peer routes for: `done`, and
    // puts on wildcards that match it.
    let client = rogue(&addr, Some(&secret), "client");
    wait_until(Duration::from_secs(10), "the client's session", || {
        client.info().routers_zid().wait().count() + client.info().peers_zid().wait().count() > 0
    });
    for key in [
        format!("fulcrum/{run}/done"),
        format!("fulcrum/{run}/*"),
        "fulcrum/**".into(),
    ] {
        client
            .put(key, "done")
            .congestion_control(CongestionControl::Block)
            .wait()
            .unwrap();
    }
    // Nor can it listen in on what other hosts send.
    let spy = client.declare_subscriber("fulcrum/**").wait().unwrap();

    // Two seconds on, the honest host still delivers (a `done` that reached it would
    // have stopped its actors within a few hundred milliseconds).
    std::thread::sleep(Duration::from_secs(2));
    let before = near_chunks(&dir);
    wait_until(Duration::from_secs(30), "the honest host going on", || {
        near_chunks(&dir) > before + 5
    });
    assert!(host.child.try_wait().unwrap().is_none(), "{}", host.text());
    assert!(spy.try_recv().unwrap().is_none(), "the spy heard the run");
    let _ = r.close().wait();
    let _ = client.close().wait();

    let status = learner.finish(Duration::from_secs(300));
    assert!(status.success(), "{}", learner.text());
    let hs = host.finish(Duration::from_secs(30));
    assert!(
        hs.success() && host.text().contains("the run is over"),
        "{}",
        host.text()
    );
    let out = learner.text();
    assert_eq!(refused(&out), Some((4, 2)), "{out}");
    for why in [
        "for an actor id not given to this host",
        "larger than a chunk of this run",
        "action out of range",
        "from a host that has not joined",
        "QUERY is not a request actors send",
        "a lookup kind this run's actors do not send",
    ] {
        assert!(out.contains(why), "no '{why}' in:\n{out}");
    }
    // One bridge from start to end: nothing was restarted.
    assert!(!out.contains("restart"), "{out}");
    assert_eq!(out.matches("fulcrum bridge: stopped:").count(), 1, "{out}");
    let rows = fulcrum_learner::metrics::read_metrics(&dir.join("metrics.csv")).unwrap();
    assert!(rows.last().unwrap().env_steps >= 600_064);
    let _ = std::fs::remove_dir_all(&far);
}

#[test]
fn an_actor_host_without_a_usable_secret_stops_before_it_starts_anything() {
    let far = TempDir::fresh("nosecret");
    let missing = far.join("no-such-secret");
    let cases: [(Option<&str>, Option<&Path>, &str); 3] = [
        (
            None,
            None,
            "joining a run needs its secret: set FULCRUM_SECRET or give --secret-file",
        ),
        (
            Some("not-hex"),
            None,
            "FULCRUM_SECRET does not hold a run secret",
        ),
        (None, Some(&missing), "cannot read the secret file"),
    ];
    for (env, file, says) in cases {
        let mut c = fulcrum();
        c.env_remove("FULCRUM_SECRET")
            .args(["actor-host", "--connect", "127.0.0.1:9", "--name", "x"])
            .arg("--dir")
            .arg(far.join("host"));
        if let Some(v) = env {
            c.env("FULCRUM_SECRET", v);
        }
        if let Some(f) = file {
            c.arg("--secret-file").arg(f);
        }
        let out = c.output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains(says) && !err.contains("panicked"), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(!far.join("host").exists());
    }
}

#[test]
fn a_resumed_run_keeps_its_secret() {
    let dir = TempDir::fresh("resume-secret");
    let listen = |extra: &[&str]| {
        let addr = format!("127.0.0.1:{}", free_port());
        let out = fulcrum()
            .args(["train", "--listen", &addr, "--stop-after-updates", "2"])
            .args(extra)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(out.status.success(), "{err}");
        err
    };
    let d = dir.display().to_string();
    let first = listen(&["exp2", "--actors", "1", "--steps", "99999744", "--out", &d]);
    let secret = std::fs::read_to_string(dir.join("secret")).unwrap();
    let hex = secret.trim().strip_prefix("fulcrum:").unwrap().to_string();
    assert!(first.contains(&format!("FULCRUM_SECRET={hex} ")), "{first}");
    let again = listen(&["--resume", &d]);
    assert!(again.contains("resuming"), "{again}");
    // The same secret, in the same owner-only file, said again in the join line.
    assert_eq!(std::fs::read_to_string(dir.join("secret")).unwrap(), secret);
    let mode = std::fs::metadata(dir.join("secret"))
        .unwrap()
        .permissions()
        .mode();
    assert_eq!(mode & 0o777, 0o600);
    assert!(again.contains(&format!("FULCRUM_SECRET={hex} ")), "{again}");
}
