//! The empowerment service across real processes and real iceoryx2 shared memory:
//! `fulcrum serve` as a child process, clients from this test process (the library)
//! and from the CLI. Each test has its own namespace.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use fulcrum_contracts::msg::{self, item, status, AGENT_BIT, TOOL_ALL};
use fulcrum_empowerment::service::{Ask, Client, ClientError};
use fulcrum_empowerment::{Engine, Limits, Method, ToolSel};
use fulcrum_world::family::{load_family, Family};
use fulcrum_world::{load_world, ObjectSet, State, World};
use rand::{Rng, SeedableRng};

use crate::util::{fulcrum, is_ready, namespace, run};

/// A running `fulcrum serve`, stopped (SIGINT, then SIGKILL) when dropped.
struct Serve {
    child: Child,
    ready: String,
}

impl Serve {
    fn start(world: &str, ns: &str, extra: &[&str]) -> Serve {
        Serve::start_with(&[world], ns, extra)
    }

    /// `fulcrum serve WHAT --namespace NS EXTRA` (`WHAT`: a world, or `--run DIR`).
    fn start_with(what: &[&str], ns: &str, extra: &[&str]) -> Serve {
        let world = what.join(" ");
        let mut child = fulcrum()
            .arg("serve")
            .args(what)
            .args(["--namespace", ns])
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("fulcrum serve starts");
        let stdout = child.stdout.take().unwrap();
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                let _ = tx.send(line);
            }
        });
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match rx.recv_timeout(left) {
                Ok(l) if is_ready(&l) => return Serve { child, ready: l },
                Ok(_) => {}
                Err(_) => {
                    let _ = child.kill();
                    panic!("fulcrum serve {world} did not become ready");
                }
            }
        }
    }

    fn signal(&self, sig: &str) {
        let ok = Command::new("kill")
            .args([sig, &self.child.id().to_string()])
            .status()
            .unwrap();
        assert!(ok.success());
    }

    /// Wait for exit with a deadline.
    fn wait(&mut self, limit: Duration) -> Option<std::process::ExitStatus> {
        let t0 = Instant::now();
        while t0.elapsed() < limit {
            if let Some(s) = self.child.try_wait().unwrap() {
                return Some(s);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        None
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            self.signal("-INT");
            if self.wait(Duration::from_secs(5)).is_none() {
                let _ = self.child.kill();
                let _ = self.child.wait();
            }
        }
    }
}

/// `n` random states of the world's state space (seeded).
fn random_states(engine: &Engine, n: usize, seed: u64) -> Vec<State> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            *engine
                .space
                .state(rng.random_range(0..engine.space.len() as u32))
        })
        .collect()
}

fn tool(w: &World) -> ToolSel {
    // The tools of the canonical worlds' [empowerment] sections after selection.
    match w.name.as_str() {
        "exp1-tree" => ToolSel::Tool(0),
        "exp1-wall" => ToolSel::Tool(1),
        "exp2" => ToolSel::Tool(0),
        _ => ToolSel::Tool(1), // exp3 names the axe
    }
}

#[test]
fn lookups_and_queries_equal_local_values_in_every_canonical_world() {
    for name in ["exp1-tree", "exp1-wall", "exp2", "exp3"] {
        let ns = namespace(name);
        let _serve = Serve::start(name, &ns, &[]);
        let w = load_world(name).unwrap();
        let e = Engine::new(&w, Limits::default()).unwrap();
        let mut c = Client::connect(&ns, &w, Duration::from_secs(10)).unwrap();
        let d = *c.describe();
        assert_eq!(d.states as usize, e.space.len());
        assert_eq!(msg::get_name(&d.world), name);
        let set = w.empowerment.objects.clone().unwrap();
        let t = tool(&w);
        let (hu, he) = (
            w.empowerment.horizon_unequipped,
            w.empowerment.horizon_equipped,
        );
        let vu = e.values(t, &set, hu, Method::Dp).unwrap();
        let ve = e.values(t, &set, he, Method::Dp).unwrap();
        let states = random_states(&e, 3000, 7);
        let got = c.values(Ask::Lookup, &states, 256).unwrap();
        for (k, s) in states.iter().enumerate() {
            let id = e.space.id(s).unwrap() as usize;
            let want = if t.held(s) { ve[id] } else { vu[id] };
            assert_eq!(got.status[k], item::OK);
            assert!(
                (got.values[k] as f64 - want).abs() < 1e-6,
                "{name} {}: {} vs {want}",
                w.describe(s),
                got.values[k]
            );
        }
        // An ad-hoc query: all actions, the agent as the object, h = 3.
        let local = e
            .values(ToolSel::All, &ObjectSet::Agent, 3, Method::Dp)
            .unwrap();
        let got = c
            .values(
                Ask::Query {
                    tool: TOOL_ALL,
                    objects: AGENT_BIT,
                    horizon: 3,
                },
                &states[..500],
                100,
            )
            .unwrap();
        for (k, s) in states[..500].iter().enumerate() {
            let want = local[e.space.id(s).unwrap() as usize];
            assert!((got.values[k] as f64 - want).abs() < 1e-6);
        }
    }
}

#[test]
fn a_client_started_first_waits_for_the_service() {
    let ns = namespace("early");
    let w = load_world("exp2").unwrap();
    let ns2 = ns.clone();
    let early = std::thread::spawn(move || {
        let w = load_world("exp2").unwrap();
        let mut c = Client::connect(&ns2, &w, Duration::from_secs(30))?;
        c.values(Ask::Lookup, &[w.initial], 1)
    });
    std::thread::sleep(Duration::from_millis(800));
    let _serve = Serve::start("exp2", &ns, &[]);
    let b = early
        .join()
        .unwrap()
        .expect("the early client connects once the service is up");
    // exp2's start: the wand is not held, h = 5; the agent at (1,6) is 3+ steps from
    // the wand's neighbours... the value is whatever the engine says locally.
    let e = Engine::new(&w, Limits::default()).unwrap();
    let local = e
        .values(
            ToolSel::Tool(0),
            w.empowerment.objects.as_ref().unwrap(),
            5,
            Method::Dp,
        )
        .unwrap();
    assert_eq!(b.values[0] as f64, local[0] as f32 as f64);
    // And one that waits in vain gets a typed error, not a hang.
    let err = Client::connect(&namespace("nobody"), &w, Duration::from_millis(300)).unwrap_err();
    assert!(matches!(err, ClientError::NoService { .. }), "{err:?}");
}

// `serve --tool auto` says which column the selection came from: the selection's one
// horizon, the world's horizon where the tool is not held (exp3's 10; the column
// `empowerment/tests/reference/exp3_bruteforce.py --horizon 10` prints, worlds/EXPECTED.md),
// even where the served table's horizons are others (here 2 / 1).
#[test]
fn serve_says_the_selection_column_at_the_worlds_horizons() {
    let ns = namespace("column");
    let mut child = fulcrum()
        .args(["serve", "exp3", "--namespace", &ns, "--tool", "auto"])
        .args(["--horizon-unequipped", "2", "--horizon-equipped", "1"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("fulcrum serve starts");
    let stderr = child.stderr.take().unwrap();
    let line = BufReader::new(stderr)
        .lines()
        .map_while(Result::ok)
        .find(|l| l.starts_with("tool selection for"));
    let _ = child.kill();
    let _ = child.wait();
    let want = format!(
        "tool selection for door+boulder: key (key {:.6}, axe {:.6})",
        2.4749743255786685, 2.155702806873758
    );
    assert_eq!(line.as_deref(), Some(want.as_str()));
}

#[test]
fn a_wrong_world_client_is_refused() {
    let ns = namespace("wrong");
    let _serve = Serve::start("exp1-tree", &ns, &[]);
    let other = load_world("exp2").unwrap();
    match Client::connect(&ns, &other, Duration::from_secs(10)) {
        Err(ClientError::WrongWorld { served, wanted, .. }) => {
            assert_eq!((served.as_str(), wanted.as_str()), ("exp1-tree", "exp2"));
        }
        other => panic!("expected WrongWorld, got {other:?}"),
    }
    // Through the CLI: one sentence, exit code 2.
    let out = fulcrum()
        .args([
            "empowerment",
            "query",
            "exp2",
            "--state",
            "agent=1,6",
            "--service",
            "--namespace",
            &ns,
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("serves world 'exp1-tree'"));
}

#[test]
fn bad_requests_get_error_statuses_and_the_service_goes_on() {
    let ns = namespace("bad");
    let _serve = Serve::start("exp3", &ns, &[]);
    let w = load_world("exp3").unwrap();
    let e = Engine::new(&w, Limits::default()).unwrap();
    let mut c = Client::connect(&ns, &w, Duration::from_secs(10)).unwrap();
    let start = [w.initial.to_bytes()];
    let refused = |c: &mut Client, k: u32, tool: i32, objects: u32, horizon: u32| {
        c.send_raw(k, &start, tool, objects, horizon).unwrap();
        match c.recv() {
            Err(ClientError::Refused(s)) => s,
            other => panic!("expected a refusal, got {other:?}"),
        }
    };
    // exp3 has 2 tools and 2 objects.
    assert_eq!(refused(&mut c, msg::kind::QUERY, 7, 1, 3), status::BAD_TOOL);
    assert_eq!(
        refused(&mut c, msg::kind::QUERY, -5, 1, 3),
        status::BAD_TOOL
    );
    assert_eq!(
        refused(&mut c, msg::kind::QUERY, 0, 1 << 5, 3),
        status::BAD_OBJECTS
    );
    assert_eq!(
        refused(&mut c, msg::kind::QUERY, 0, 0, 3),
        status::BAD_OBJECTS
    );
    assert_eq!(
        refused(&mut c, msg::kind::QUERY, 0, 1, 1000),
        status::BAD_HORIZON
    );
    assert_eq!(refused(&mut c, 99, 0, 1, 3), status::BAD_KIND);
    // Garbage state bytes: a status per item, never a crash.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    for round in 0..20 {
        let n = rng.random_range(1..=msg::MAX_BATCH);
        let raw: Vec<[u8; msg::STATE_BYTES]> = (0..n)
            .map(|_| {
                let mut b = [0u8; msg::STATE_BYTES];
                rng.fill(&mut b[..]);
                b
            })
            .collect();
        c.send_raw(msg::kind::LOOKUP, &raw, 0, 0, 0).unwrap();
        let b = c.recv().unwrap();
        assert_eq!(b.status.len(), n, "round {round}");
        assert!(
            b.status.iter().all(|&s| s == item::NOT_IN_SPACE),
            "random bytes are (almost surely) not states"
        );
    }
    // The next good request is answered: the key next to the closed door (h = 10
    // unequipped... the service's table is axe -> door+boulder).
    let s = w.parse_state("agent=5,3 holding=axe").unwrap();
    let got = c.values(Ask::Lookup, &[s], 1).unwrap();
    let set = w.empowerment.objects.clone().unwrap();
    let want =
        e.values(ToolSel::Tool(1), &set, 5, Method::Dp).unwrap()[e.space.id(&s).unwrap() as usize];
    assert_eq!(got.status[0], item::OK);
    assert!((got.values[0] as f64 - want).abs() < 1e-6);
}

#[test]
fn sigkill_gives_clients_a_typed_error_and_a_restart_serves_again() {
    let ns = namespace("kill");
    let w = load_world("exp1-tree").unwrap();
    let mut serve = Serve::start("exp1-tree", &ns, &[]);
    let mut c = Client::connect(&ns, &w, Duration::from_secs(10)).unwrap();
    c.timeout = Duration::from_secs(10);
    assert_eq!(
        c.values(Ask::Lookup, &[w.initial], 1).unwrap().status[0],
        item::OK
    );
    serve.signal("-KILL");
    serve.wait(Duration::from_secs(5)).expect("killed");
    let t0 = Instant::now();
    let err = c.values(Ask::Lookup, &[w.initial], 1).unwrap_err();
    assert!(
        matches!(err, ClientError::ServiceGone | ClientError::Timeout(_)),
        "{err:?}"
    );
    assert!(
        t0.elapsed() < Duration::from_secs(11),
        "a typed error, not a hang"
    );
    // A new service on the same namespace starts (the dead one's resources are
    // cleaned) and serves again, to a new client and to the old one.
    let _serve2 = Serve::start("exp1-tree", &ns, &[]);
    let mut c2 = Client::connect(&ns, &w, Duration::from_secs(10)).unwrap();
    assert_eq!(
        c2.values(Ask::Lookup, &[w.initial], 1).unwrap().status[0],
        item::OK
    );
}

#[test]
fn a_second_service_for_a_namespace_refuses_politely() {
    let ns = namespace("twice");
    let serve = Serve::start("exp2", &ns, &[]);
    assert!(
        serve.ready.contains("fulcrum/") && serve.ready.contains("/empowerment"),
        "{}",
        serve.ready
    );
    let out = fulcrum()
        .args(["serve", "exp2", "--namespace", &ns])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("already running"), "{err}");
}

#[test]
fn sigint_and_sigterm_stop_the_service_cleanly() {
    for sig in ["-INT", "-TERM"] {
        let ns = namespace("stop");
        let w = load_world("room").unwrap();
        let mut serve = Serve::start("room", &ns, &[]);
        let mut c = Client::connect(&ns, &w, Duration::from_secs(10)).unwrap();
        assert_eq!(
            c.values(Ask::Lookup, &[w.initial], 1).unwrap().status[0],
            item::OK
        );
        drop(c);
        serve.signal(sig);
        let st = serve
            .wait(Duration::from_secs(5))
            .expect("stops within 5 s");
        assert!(st.success(), "{sig}: {st:?}");
        // Nothing is left that blocks the next start on the same namespace.
        let _again = Serve::start("room", &ns, &[]);
    }
}

/// Attach to `pid` as a tracer, interrupt every thread it has, wait for each stop and
/// detach again: what `gdb -p`, `strace -p` and `perf trace -p` do to a process.
fn trace_and_detach(pid: i32) {
    let tids: Vec<i32> = std::fs::read_dir(format!("/proc/{pid}/task"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().parse().unwrap())
        .collect();
    for &tid in &tids {
        // SAFETY: ptrace on a thread of our own child; arguments as the man page says.
        unsafe {
            let seized = libc::ptrace(libc::PTRACE_SEIZE, tid, 0usize, 0usize);
            assert_eq!(
                seized,
                0,
                "PTRACE_SEIZE {tid}: {}",
                std::io::Error::last_os_error()
            );
            assert_eq!(libc::ptrace(libc::PTRACE_INTERRUPT, tid, 0usize, 0usize), 0);
            let mut st = 0;
            assert_eq!(libc::waitpid(tid, &mut st, libc::__WALL), tid);
        }
    }
    std::thread::sleep(Duration::from_millis(100));
    for &tid in &tids {
        // SAFETY: as above; the thread is in a ptrace stop.
        let r = unsafe { libc::ptrace(libc::PTRACE_DETACH, tid, 0usize, 0usize) };
        assert_eq!(
            r,
            0,
            "PTRACE_DETACH {tid}: {}",
            std::io::Error::last_os_error()
        );
    }
}

#[test]
fn a_debugger_attaching_and_leaving_does_not_stop_the_service() {
    // The attach interrupts the service's wait with EINTR, which iceoryx2's wait set
    // reports as an interrupt as if SIGINT had come: the service must serve on.
    let ns = namespace("ptrace");
    let w = load_world("room").unwrap();
    let mut serve = Serve::start("room", &ns, &[]);
    let mut c = Client::connect(&ns, &w, Duration::from_secs(10)).unwrap();
    c.timeout = Duration::from_secs(10);
    std::thread::sleep(Duration::from_millis(300)); // the service is asleep in its wait
    trace_and_detach(serve.child.id() as i32);
    std::thread::sleep(Duration::from_millis(300));
    assert!(
        serve.child.try_wait().unwrap().is_none(),
        "the service exited"
    );
    assert_eq!(
        c.values(Ask::Lookup, &[w.initial], 1).unwrap().status[0],
        item::OK
    );
    // And SIGINT still stops it cleanly.
    drop(c);
    serve.signal("-INT");
    let st = serve
        .wait(Duration::from_secs(5))
        .expect("stops within 5 s");
    assert!(st.success(), "{st:?}");
}

#[test]
fn query_service_from_the_cli_equals_the_local_query() {
    let ns = namespace("cli");
    let _serve = Serve::start("exp3", &ns, &[]);
    let run = |extra: &[&str]| {
        let mut args = vec![
            "empowerment",
            "query",
            "exp3",
            "--state",
            "agent=5,3 holding=key door=open",
            "--tool",
            "key",
            "--objects",
            "door",
            "--horizon",
            "3",
            "--json",
        ];
        args.extend_from_slice(extra);
        let out = fulcrum().args(&args).output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["value"].as_f64().unwrap()
    };
    let local = run(&[]);
    let remote = run(&["--service", "--namespace", &ns]);
    assert_eq!(local, 1.0);
    assert_eq!(remote, local);
}

#[test]
fn many_clients_at_once() {
    let ns = namespace("many");
    let _serve = Serve::start("exp2", &ns, &[]);
    let w = load_world("exp2").unwrap();
    let e = Engine::new(&w, Limits::default()).unwrap();
    let set = w.empowerment.objects.clone().unwrap();
    let vu = e.values(ToolSel::Tool(0), &set, 5, Method::Dp).unwrap();
    let ve = e.values(ToolSel::Tool(0), &set, 6, Method::Dp).unwrap();
    let states = random_states(&e, 2000, 3);
    let want: Vec<f32> = states
        .iter()
        .map(|s| {
            let id = e.space.id(s).unwrap() as usize;
            (if s.holds(0) { ve[id] } else { vu[id] }) as f32
        })
        .collect();
    // 12 clients (as many actors as a big machine runs, plus CLI users), each its own
    // node, all at once.
    std::thread::scope(|sc| {
        for k in 0..12 {
            let (ns, w, states, want) = (&ns, &w, &states, &want);
            sc.spawn(move || {
                let mut c = Client::connect(ns, w, Duration::from_secs(20)).unwrap();
                for round in 0..5 {
                    let b = c.values(Ask::Lookup, states, 64 + 64 * k).unwrap();
                    assert_eq!(&b.values, want, "client {k} round {round}");
                }
            });
        }
    });
}

#[test]
fn a_service_whose_output_reader_left_still_stops_cleanly() {
    // A supervisor may read the service's "ready" line and close the pipe: the final
    // line must not turn SIGINT into a panic or a death by SIGPIPE.
    let ns = namespace("pipe");
    let mut child = fulcrum()
        .args(["serve", "room", "--namespace", &ns])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let ready = lines.next().unwrap().unwrap();
    assert!(is_ready(&ready), "{ready}");
    drop(lines);
    let ok = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?}: {err}", out.status);
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn visit_counts_are_shared_by_two_client_processes() {
    let ns = namespace("visits");
    let _serve = Serve::start("room", &ns, &[]);
    let visit = || {
        fulcrum()
            .args(["__visit", "--namespace", &ns, "--world", "room"])
            .args(["--state", "agent=2,2", "--times", "300"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    // Two processes visit the same state 300 times each, at the same time.
    let (a, b) = (visit(), visit());
    let mut counts: Vec<u32> = Vec::new();
    for c in [a, b] {
        let out = c.wait_with_output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8(out.stdout).unwrap();
        let mine: Vec<u32> = text.lines().map(|l| l.parse().unwrap()).collect();
        assert_eq!(mine.len(), 300);
        // Each process sees its counts grow.
        assert!(mine.windows(2).all(|w| w[0] < w[1]), "{mine:?}");
        counts.extend(mine);
    }
    // One counter for both: every count 1..=600 was answered exactly once.
    counts.sort_unstable();
    assert_eq!(counts, (1..=600).collect::<Vec<u32>>());
}

#[test]
fn a_signal_delivered_to_any_thread_stops_the_service_at_once() {
    // A process-directed signal may land on any thread; one that lands on a thread
    // other than the one in epoll does not interrupt the wait, and iceoryx2 keeps the
    // last signal in a global that some of its calls reset. The service keeps its own
    // flag and checks it every 100 ms.
    for sig in [libc::SIGINT, libc::SIGTERM] {
        let ns = namespace("anythread");
        let mut s = Serve::start("room", &ns, &[]);
        let pid = s.child.id() as i32;
        let tids: Vec<i32> = std::fs::read_dir(format!("/proc/{pid}/task"))
            .unwrap()
            .flatten()
            .filter_map(|e| e.file_name().to_string_lossy().parse().ok())
            .filter(|&t| t != pid)
            .collect();
        assert!(!tids.is_empty(), "the service has worker threads");
        // SAFETY: tgkill to a thread of our own child.
        let r = unsafe { libc::syscall(libc::SYS_tgkill, pid, tids[0], sig) };
        assert_eq!(r, 0);
        let t0 = Instant::now();
        let status = s.wait(Duration::from_secs(5)).expect("the service stops");
        assert!(
            t0.elapsed() < Duration::from_millis(1000),
            "{:?}",
            t0.elapsed()
        );
        assert!(status.success(), "{status:?}");
    }
}

/// A service takes as many clients at once as `--max-clients` says: one more gets the
/// typed `Full` error naming the flag; a client that leaves makes room. 0 is refused.
#[test]
fn a_service_takes_as_many_clients_as_it_was_made_for() {
    let ns = namespace("full");
    let _serve = Serve::start("room", &ns, &["--max-clients", "2"]);
    let w = load_world("room").unwrap();
    let a = Client::connect(&ns, &w, Duration::from_secs(10)).unwrap();
    let mut b = Client::connect(&ns, &w, Duration::from_secs(10)).unwrap();
    let err = Client::connect(&ns, &w, Duration::from_secs(10)).unwrap_err();
    assert!(matches!(err, ClientError::Full { max: 2, .. }), "{err:?}");
    assert!(
        err.to_string()
            .contains("has as many clients as it takes (2); close one, or start the service with a larger --max-clients"),
        "{err}"
    );
    drop(a);
    let mut c = Client::connect(&ns, &w, Duration::from_secs(10)).unwrap();
    let s = [w.initial];
    assert_eq!(
        b.values(Ask::Lookup, &s, 1).unwrap().values,
        c.values(Ask::Lookup, &s, 1).unwrap().values
    );
    let out = fulcrum()
        .args(["serve", "room", "--max-clients", "0", "--namespace"])
        .arg(namespace("zero"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--max-clients 0 must be 1 to 1024"), "{err}");
}

/// `serve --run DIR` (what `fulcrum train` starts) serves what the run's config.toml
/// names: here a horizon-potential run of the room with the axe for the tree at
/// horizons 4 and 2, so the table is Phi = E^1 + ... + E^4 (without the axe) or up to
/// E^2 (with it), as the engine computes it; flags of their own are refused beside it.
#[test]
fn serve_run_reads_everything_from_the_runs_config() {
    let dir = crate::util::TempDir::fresh("serve-run");
    let d = dir.to_str().unwrap();
    let out = fulcrum()
        .args([
            "train",
            "room",
            "--actors",
            "1",
            "--steps",
            "1024",
            "--intrinsic",
            "horizon-potential",
            "--horizon-unequipped",
            "4",
            "--horizon-equipped",
            "2",
            "--out",
            d,
        ])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let ns = namespace("serve-run");
    let serve = Serve::start_with(&["--run", d], &ns, &[]);
    assert!(
        serve.ready.contains("h = 4 unequipped / 2 equipped"),
        "{}",
        serve.ready
    );
    let w = load_world("room").unwrap();
    let e = Engine::new(&w, Limits::default()).unwrap();
    let tree = ObjectSet::Objects(vec![0]);
    let want = e
        .lookup_values(ToolSel::Tool(0), &tree, 4, 2, true)
        .unwrap();
    let mut c = Client::connect(&ns, &w, Duration::from_secs(30)).unwrap();
    let got = c.values(Ask::Lookup, e.space.states(), 256).unwrap();
    assert_eq!(got.values, want);
    assert!(want.iter().any(|&v| v > 1.0), "a sum of several horizons");
    drop(serve);
    let refused = fulcrum()
        .args(["serve", "--run", d, "--tool", "axe"])
        .output()
        .unwrap();
    assert_eq!(refused.status.code(), Some(2));
}

/// The kernel's transparent-huge-page flag of a process (`THP_enabled` in its
/// /proc status: 0 once it has asked for ordinary pages).
fn thp_enabled(pid: u32) -> String {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    status
        .lines()
        .find_map(|l| l.strip_prefix("THP_enabled:"))
        .unwrap_or_else(|| {
            panic!("no THP_enabled line in /proc/{pid}/status: a kernel before 5.0?")
        })
        .trim()
        .to_string()
}

/// A family's service, which makes a table's working memory and drops it for every
/// layout it meets, runs on ordinary pages; one world's service, whose one table is made
/// at its start, keeps the transparent huge pages it was started with.
#[test]
fn a_family_service_asks_for_ordinary_pages_and_one_worlds_does_not() {
    let family = Serve::start("toolbox", &namespace("thp-family"), &[]);
    assert_eq!(thp_enabled(family.child.id()), "0");
    let one = Serve::start("exp1-tree", &namespace("thp-one"), &[]);
    assert_eq!(thp_enabled(one.child.id()), "1");
}

/// `fulcrum serve FAMILY`: lookups name each state's layout, a training layout and a
/// held-out one in one request, and the answers are the values of the layout made as one
/// world (the engine on the layout's own states: Phi with --horizon-sum); a state is read
/// in the layout its request names; QUERY is refused.
#[test]
fn a_family_service_answers_each_state_from_its_own_layout() {
    let (_serve, family, mut c) = family_service("family");
    let seeds = [3u64, fulcrum_world::HELD_OUT_START + 11];
    let (states, layouts, want) = layout_states(&family, &seeds, 100);
    for (chunk, (ls, ws)) in states.chunks(msg::MAX_BATCH).zip(
        layouts
            .chunks(msg::MAX_BATCH)
            .zip(want.chunks(msg::MAX_BATCH)),
    ) {
        c.submit_on(Ask::Lookup, chunk, Some(ls)).unwrap();
        let b = c.recv().unwrap();
        assert_eq!(b.values.len(), chunk.len());
        for ((v, st), w) in b.values.iter().zip(&b.status).zip(ws) {
            assert_eq!(*st, item::OK);
            assert!((*v as f64 - w).abs() < 1e-4, "{v} vs {w}");
        }
    }
    // A state is read in the layout its request names: layout 3's start named as the
    // held-out layout's is answered from that layout (its value there, or NOT_IN_SPACE
    // where that layout has no such state), and a state of no layout is refused.
    let start = family.layout(3).unwrap().initial;
    let other = family.layout(seeds[1]).unwrap();
    let e = Engine::new(&other, Limits::default()).unwrap();
    let mut off = start;
    off.x = 200;
    c.submit_on(Ask::Lookup, &[start, off], Some(&[seeds[1], 3]))
        .unwrap();
    let b = c.recv().unwrap();
    match e.space.id(&start) {
        Some(id) => {
            assert_eq!(b.status[0], item::OK);
            assert!((b.values[0] as f64 - layout_phi(&other, &e)[id as usize]).abs() < 1e-4);
        }
        None => assert_eq!(b.status[0], item::NOT_IN_SPACE),
    }
    assert_eq!(b.status[1], item::NOT_IN_SPACE);
    // QUERY names tools and objects of one world: refused.
    c.submit_on(
        Ask::Query {
            tool: TOOL_ALL,
            objects: AGENT_BIT,
            horizon: 2,
        },
        &[start],
        Some(&[3]),
    )
    .unwrap();
    match c.recv() {
        Err(ClientError::Refused(code)) => assert_eq!(code, status::BAD_KIND),
        other => panic!("QUERY on a family: {other:?}"),
    }
}

/// A `toolbox` service answering Phi (`--horizon-sum`) in namespace `tag`, the family,
/// and a client connected to it.
fn family_service(tag: &str) -> (Serve, Family, Client) {
    let ns = namespace(tag);
    let serve = Serve::start("toolbox", &ns, &["--horizon-sum"]);
    assert!(
        serve.ready.contains("world family toolbox"),
        "{}",
        serve.ready
    );
    let family = load_family("toolbox").unwrap();
    let c = Client::connect_to(
        &ns,
        "toolbox",
        family.content_hash(),
        Duration::from_secs(10),
    )
    .unwrap();
    (serve, family, c)
}

/// `per` random states of each layout of `seeds`, their layouts, and Phi at each from
/// the layout made as one world ([`layout_phi`]).
fn layout_states(family: &Family, seeds: &[u64], per: usize) -> (Vec<State>, Vec<u64>, Vec<f64>) {
    let (mut states, mut layouts, mut want) = (Vec::new(), Vec::new(), Vec::new());
    for &seed in seeds {
        let w = family.layout(seed).unwrap();
        let e = Engine::new(&w, Limits::default()).unwrap();
        let phi = layout_phi(&w, &e);
        for s in random_states(&e, per, seed) {
            states.push(s);
            layouts.push(seed);
            want.push(phi[e.space.id(&s).unwrap() as usize]);
        }
    }
    (states, layouts, want)
}

/// Phi = sum over h <= 8 of E^h at every state of a `toolbox` layout made as one world,
/// with the tool its matrix selects for its task object (h 8 unequipped, 3 equipped).
fn layout_phi(w: &World, e: &Engine) -> Vec<f64> {
    let set = w.empowerment.objects.clone().unwrap();
    let m = e
        .matrix(std::slice::from_ref(&set), 8, 3, Method::Dp)
        .unwrap();
    let t = ToolSel::Tool(m.selection[0].unwrap());
    let by_h: Vec<Vec<f64>> = (1..=8)
        .map(|h| e.values(t, &set, h, Method::Dp).unwrap())
        .collect();
    (0..e.space.len())
        .map(|i| by_h.iter().map(|v| v[i]).sum())
        .collect()
}

/// Requests sent back to back, each naming layouts never met, wait together at the
/// service, which makes their tables at once; collected without waiting (`try_recv`, as
/// an actor collects while it plays a chunk), each answer is its own request's, in order,
/// with every layout's own values.
#[test]
fn a_family_service_answers_pipelined_requests_for_new_layouts_in_order() {
    let (_serve, family, mut c) = family_service("family-pipe");
    assert!(c.try_recv().unwrap().is_none(), "nothing in flight");
    let mut want: Vec<Vec<f64>> = Vec::new();
    for r in 0..msg::MAX_IN_FLIGHT as u64 {
        // Two layouts a request, none met before: 20 + 2r and 21 + 2r, ten states each.
        let (states, layouts, w) = layout_states(&family, &[20 + 2 * r, 21 + 2 * r], 10);
        c.submit_on(Ask::Lookup, &states, Some(&layouts)).unwrap();
        want.push(w);
    }
    let t0 = std::time::Instant::now();
    let mut got = 0;
    while got < want.len() {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "answers did not come"
        );
        let Some(b) = c.try_recv().unwrap() else {
            std::thread::sleep(Duration::from_micros(200));
            continue;
        };
        assert_eq!(b.values.len(), want[got].len());
        for ((v, st), w) in b.values.iter().zip(&b.status).zip(&want[got]) {
            assert_eq!(*st, item::OK);
            assert!((*v as f64 - w).abs() < 1e-4, "request {got}: {v} vs {w}");
        }
        got += 1;
    }
    assert_eq!(c.in_flight(), 0);
}

/// `fulcrum bench --only service` runs the service's group alone: its figures, every
/// one of them (the names `src/commands/bench/service.rs` gives, listed by hand), and
/// nothing of the other groups; an unknown group, or the Python group without the
/// package, is refused with exit code 2.
#[test]
fn bench_only_service_gives_the_service_figures_alone() {
    let dir = crate::util::TempDir::new("bench-only");
    let json = dir.join("bench.json");
    let out = run(&[
        "bench",
        "--quick",
        "--only",
        "service",
        "--json",
        json.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["only"], serde_json::json!(["service"]));
    let names: Vec<&str> = v["figures"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["name"].as_str().unwrap())
        .collect();
    let want = [
        "service round trip p50, 1 state",
        "service round trip p99, 1 state",
        "service round trip p50, 256 states",
        "service round trip p99, 256 states",
        "service round trip p50, 1 state, after 1 ms idle",
        "floor: Unix datagram ping-pong p50, after 1 ms idle",
        "service round trip p50, 1 state, after 1 ms idle, caches evicted",
        "floor: Unix datagram ping-pong p50, after 1 ms idle, caches evicted",
        "service lookups/s, 1 client, batches of 256",
        "service lookups/s, 2 client processes",
        "service CPU while idle",
        "floor: Unix datagram ping-pong p50",
        "floor: in-process lookups/s",
        "service round trip after 1 ms idle over its floor",
        "service round trip after 1 ms idle over its floor, caches evicted",
    ];
    assert_eq!(names, want);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.starts_with("fulcrum bench --quick --only service on "),
        "{stdout}"
    );

    let bad = run(&["bench", "--only", "services"]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(bad.status.code(), Some(2), "{err}");
    assert!(
        err.contains("invalid value 'services' for '--only <GROUP>'"),
        "{err}"
    );

    // The Python figures asked for by name, with an interpreter that cannot import the
    // package: one sentence and exit code 2, not an empty table.
    let none = fulcrum()
        .args(["bench", "--quick", "--only", "python"])
        .env("FULCRUM_PYTHON", "/bin/false")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&none.stderr);
    assert_eq!(none.status.code(), Some(2), "{err}");
    assert!(
        err.contains("no Python figures: '/bin/false' cannot import fulcrum"),
        "{err}"
    );
}
