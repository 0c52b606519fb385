//! `fulcrum bench`: the throughput suite. Every figure is printed next to the machine it
//! ran on and a correctness count, and written as JSON with `--json FILE`.
//!
//! Figures are medians of repeated runs in one process. Nothing here asserts a speed:
//! the command fails only when a benchmark breaks (an error, a wrong count, a zero).

use std::time::Instant;

use anyhow::{ensure, Context, Result};
use fulcrum_empowerment::{enumerate, propagate, Engine, Limits, Method, StateSpace, ToolSel};
use fulcrum_shared::generate::{generate, GenParams};
use fulcrum_shared::{load_world, parse_world, ObjectSet, World};
use serde_json::json;

use crate::cli::BenchArgs;

#[cfg(feature = "multihost")]
pub mod remote;
mod scaling;
use fulcrum_shared::fsio::write_atomic;

/// One measured figure.
struct Figure {
    /// Zero is a valid reading (e.g. CPU while idle), not a broken benchmark.
    zero_ok: bool,
    name: String,
    value: f64,
    unit: &'static str,
    note: String,
}

/// Median wall time in milliseconds of `reps` runs of `f` (after one warm-up run).
fn median_ms<T>(reps: usize, mut f: impl FnMut() -> Result<T>) -> Result<(f64, T)> {
    let mut out = f()?;
    let mut times = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t0 = Instant::now();
        out = f()?;
        times.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(|a, b| a.total_cmp(b));
    Ok((times[times.len() / 2], out))
}

/// Peak resident memory of this process so far (VmHWM), in MiB.
fn peak_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<f64>().ok())
        })
        .map_or(0.0, |kb| kb / 1024.0)
}

/// CPU model, cores, memory, OS and compiler.
pub fn machine() -> serde_json::Value {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let cpu = cpuinfo
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split(':').nth(1))
        .map_or("unknown".to_string(), |s| s.trim().to_string());
    let mem_gib = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("MemTotal:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<f64>().ok())
        })
        .map_or(0.0, |kb| kb / 1024.0 / 1024.0);
    let os = std::fs::read_to_string("/etc/os-release")
        .ok()
        .and_then(|t| {
            t.lines().find(|l| l.starts_with("PRETTY_NAME=")).map(|l| {
                l.trim_start_matches("PRETTY_NAME=")
                    .trim_matches('"')
                    .to_string()
            })
        })
        .unwrap_or_else(|| std::env::consts::OS.to_string());
    json!({
        "cpu": cpu,
        "cores": std::thread::available_parallelism().map_or(1, |n| n.get()),
        "memory_gib": (mem_gib * 10.0).round() / 10.0,
        "os": os,
        "rustc": env!("FULCRUM_RUSTC"),
        "fulcrum": env!("CARGO_PKG_VERSION"),
    })
}

/// Parameters of the generated world of at least 10^6 states (quick: ~10^5).
pub fn big_world_params(quick: bool) -> GenParams {
    if quick {
        GenParams {
            width: 12,
            height: 12,
            tools: 4,
            objects: 4,
            rock: 0.0,
            seed: 7,
        }
    } else {
        GenParams {
            width: 14,
            height: 14,
            tools: 4,
            objects: 4,
            rock: 0.0,
            seed: 3,
        }
    }
}

/// Run the suite.
pub fn run(a: BenchArgs) -> Result<()> {
    let reps = if a.quick { 5 } else { 21 };
    let mut figs: Vec<Figure> = Vec::new();
    let m = machine();
    eprintln!(
        "fulcrum bench{}: {}",
        if a.quick { " --quick" } else { "" },
        m
    );

    if let Some(addr) = &a.remote {
        #[cfg(feature = "multihost")]
        remote::run(
            (!addr.is_empty()).then_some(addr.as_str()),
            a.quick,
            &mut figs,
        )?;
        #[cfg(not(feature = "multihost"))]
        {
            let _ = addr;
            return fulcrum_run::bad(super::NO_MULTIHOST.replace("{}", "bench --remote"));
        }
    } else if a.scaling {
        scaling::run(&a.plots, a.max_states, &mut figs)?;
    } else {
        empowerment_exp2(reps, a.quick, &mut figs)?;
        empowerment_big(a.quick, &mut figs)?;
        service_figures(a.quick, &mut figs)?;
        training_figures(a.quick, &mut figs)?;
        chunk_transport(a.quick, &mut figs)?;
        end_to_end(a.quick, &mut figs)?;
        time_to_solve(&mut figs)?;
    }

    println!(
        "fulcrum bench{} on {} ({} cores, {} GiB, {}, {})",
        if a.remote.is_some() {
            " --remote"
        } else if a.quick {
            " --quick"
        } else if a.scaling {
            " --scaling"
        } else {
            ""
        },
        m["cpu"].as_str().unwrap_or("?"),
        m["cores"],
        m["memory_gib"],
        m["os"].as_str().unwrap_or("?"),
        m["rustc"].as_str().unwrap_or("?")
    );
    let w = figs.iter().map(|f| f.name.len()).max().unwrap_or(10);
    for f in &figs {
        println!(
            "{:<w$}  {:>14} {:<10} {}",
            f.name,
            fmt_value(f.value),
            f.unit,
            f.note
        );
    }
    for f in &figs {
        ensure!(
            f.value.is_finite() && (f.value > 0.0 || (f.zero_ok && f.value == 0.0)),
            "benchmark '{}' gave {} {}: broken",
            f.name,
            f.value,
            f.unit
        );
    }
    if let Some(path) = &a.json {
        let v = json!({
            "machine": m,
            "quick": a.quick,
            "scaling": a.scaling,
            "figures": figs.iter().map(|f| json!({"name": f.name, "value": f.value, "unit": f.unit, "note": f.note})).collect::<Vec<_>>(),
        });
        write_atomic(path, serde_json::to_string_pretty(&v)?.as_bytes())
            .with_context(|| format!("cannot write {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

fn fmt_value(v: f64) -> String {
    if v >= 100.0 {
        format!("{v:.0}")
    } else if v >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.4}")
    }
}

fn objects(w: &World, names: &[&str]) -> ObjectSet {
    let mut v: Vec<usize> = names.iter().filter_map(|n| w.object_index(n)).collect();
    v.sort_unstable();
    ObjectSet::Objects(v)
}

/// exp2: enumeration, the full matrix, per-state cost, and the ratio to the paper's
/// method at h = 6.
fn empowerment_exp2(reps: usize, quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    let w = load_world("exp2")?;
    let limits = Limits::default();
    let (enum_ms, space) = median_ms(reps, || Ok(StateSpace::enumerate(&w, &limits)?))?;
    let n = space.len();
    figs.push(Figure {
        zero_ok: false,
        name: "exp2 state enumeration".into(),
        value: enum_ms,
        unit: "ms",
        note: format!("({n} states)"),
    });
    let columns = [
        objects(&w, &["boulder"]),
        objects(&w, &["door"]),
        objects(&w, &["boulder", "door"]),
    ];
    let (matrix_ms, mat) = median_ms(reps, || {
        let e = Engine::new(&w, limits)?;
        Ok(e.matrix(&columns, 5, 6, Method::Dp)?)
    })?;
    ensure!(
        (mat.values[0][2] - 0.4859727539794917).abs() < 1e-9,
        "exp2 matrix is wrong: {:?}",
        mat.values
    );
    let entries = mat.tools.len() * columns.len();
    figs.push(Figure {
        zero_ok: false,
        name: "exp2 full matrix incl. enumeration".into(),
        value: matrix_ms,
        unit: "ms",
        note: format!(
            "({} tools x {} columns, h = 5/6; goal <= 20 ms)",
            mat.tools.len(),
            columns.len()
        ),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "exp2 matrix cost per state per entry".into(),
        value: (matrix_ms - enum_ms).max(1e-6) * 1e6 / (n * entries) as f64,
        unit: "ns",
        note: format!("({entries} entries x {n} states, h up to 6)"),
    });

    // The ratio at h = 6: set propagation over every state against enumerating the
    // 6^6 sequences per state on a sample (same tool, objects, horizon).
    let e = Engine::new(&w, limits)?;
    let wand = ToolSel::Tool(w.tool_index("wand").context("exp2 has a wand")?);
    let set = objects(&w, &["boulder", "door"]);
    let (dp_ms, counts) = median_ms(reps, || Ok(e.counts(wand, &set, &[6], Method::Dp)?))?;
    let sample = if quick { 40 } else { 400 };
    let step = (n / sample).max(1);
    let ids: Vec<u32> = (0..n as u32).step_by(step).take(sample).collect();
    let actions = wand.actions(&w);
    let t0 = Instant::now();
    let mut agree = 0;
    for &i in &ids {
        let c = enumerate::reachable_count(&w, e.space.state(i), &actions, &set, 6);
        agree += (c as u32 == counts[0][i as usize]) as usize;
    }
    let enum_per_state_ms = t0.elapsed().as_secs_f64() * 1e3 / ids.len() as f64;
    ensure!(
        agree == ids.len(),
        "set propagation and enumeration disagree on {} of {} states",
        ids.len() - agree,
        ids.len()
    );
    figs.push(Figure {
        zero_ok: false,
        name: "exp2 E^6 all states, set propagation".into(),
        value: dp_ms,
        unit: "ms",
        note: format!("(wand -> boulder+door, {n} states)"),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "exp2 E^6 per state, enumeration".into(),
        value: enum_per_state_ms,
        unit: "ms",
        note: format!(
            "(6^6 sequences, 1 thread, {} sampled states, {agree} agree with set propagation)",
            ids.len()
        ),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "exp2 speed-up of set propagation at h = 6".into(),
        value: enum_per_state_ms * n as f64 / dp_ms,
        unit: "x",
        note: "(enumeration extrapolated to all states / set propagation; goal >= 1000x)".into(),
    });
    Ok(())
}

/// A generated world of >= 10^6 states: enumeration, one matrix column at h = 8, peak
/// memory.
fn empowerment_big(quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    let p = big_world_params(quick);
    let text = generate(&p)?;
    let w = parse_world(&text, "generated")?;
    let limits = Limits::default();
    let t0 = Instant::now();
    let e = Engine::new(&w, limits)?;
    let enum_ms = t0.elapsed().as_secs_f64() * 1e3;
    let n = e.space.len();
    let label = format!("gen {}x{} t{} o{}", p.width, p.height, p.tools, p.objects);
    figs.push(Figure { zero_ok: false, name: format!("{label} state enumeration"), value: enum_ms, unit: "ms", note: format!("({n} states, `fulcrum world generate --width {} --height {} --tools {} --objects {} --seed {}`)", p.width, p.height, p.tools, p.objects, p.seed) });
    let column = ObjectSet::Objects(vec![0]);
    let proj = propagate::Projection::new(&e.space, &column);
    let t0 = Instant::now();
    let m = e.matrix(std::slice::from_ref(&column), 8, 8, Method::Dp)?;
    let col_ms = t0.elapsed().as_secs_f64() * 1e3;
    ensure!(
        m.values.iter().all(|r| r[0].is_finite()),
        "matrix column is not finite"
    );
    figs.push(Figure {
        zero_ok: false,
        name: format!("{label} matrix column at h = 8"),
        value: col_ms,
        unit: "ms",
        note: format!(
            "({} tools -> {}, {} projected states; goal <= 2 s at 10^6 states)",
            m.tools.len(),
            m.columns[0],
            proj.size
        ),
    });
    figs.push(Figure {
        zero_ok: false,
        name: format!("{label} column cost per state per tool per step"),
        value: col_ms * 1e6 / (n * m.tools.len() * 8) as f64,
        unit: "ns",
        note: "(6 actions, one 64-bit word per set)".into(),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "peak memory (VmHWM) after the big world".into(),
        value: peak_mib(),
        unit: "MiB",
        note: format!(
            "({} MiB estimated for the state space)",
            e.space.bytes() >> 20
        ),
    });
    Ok(())
}

/// A child `fulcrum serve`, stopped with SIGINT when dropped.
struct ServeChild(std::process::Child);

impl ServeChild {
    fn start(world: &str, ns: &str) -> Result<ServeChild> {
        use std::io::{BufRead, BufReader};
        let mut child = std::process::Command::new(std::env::current_exe()?)
            .args(["serve", world, "--namespace", ns])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .context("cannot start fulcrum serve")?;
        let out = child.stdout.take().context("no stdout")?;
        for line in BufReader::new(out).lines() {
            if line?.contains("ready") {
                return Ok(ServeChild(child));
            }
        }
        let _ = child.kill();
        anyhow::bail!("fulcrum serve {world} exited before it was ready")
    }
}

impl Drop for ServeChild {
    fn drop(&mut self) {
        let _ = std::process::Command::new("kill")
            .args(["-INT", &self.0.id().to_string()])
            .status();
        let t0 = Instant::now();
        while t0.elapsed() < std::time::Duration::from_secs(5) {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// Sample states of a space, seeded.
fn sample_states(e: &Engine, n: usize) -> Vec<fulcrum_shared::State> {
    let step = (e.space.len() / n).max(1);
    (0..n)
        .map(|i| *e.space.state(((i * step) % e.space.len()) as u32))
        .collect()
}

/// The service: round-trip latency, lookup throughput with 1 and 2 client processes,
/// and the two floors (in-process lookups, a Unix datagram ping-pong).
fn service_figures(quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    use fulcrum_empowerment::service::{Ask, Client, ServeConfig, Tables};
    let world = "exp2";
    let w = load_world(world)?;
    let ns = format!("bench-{}", std::process::id());
    let serve = ServeChild::start(world, &ns)?;
    let mut c = Client::connect(&ns, &w, std::time::Duration::from_secs(30))?;
    let e = Engine::new(&w, Limits::default())?;
    let batch256 = sample_states(&e, 256);
    let rounds = if quick { 2000 } else { 20000 };
    for (label, states) in [("1 state", &batch256[..1]), ("256 states", &batch256[..])] {
        let mut t = Vec::with_capacity(rounds);
        for _ in 0..rounds {
            let t0 = Instant::now();
            c.submit(Ask::Lookup, states)?;
            let b = c.recv()?;
            t.push(t0.elapsed().as_secs_f64() * 1e6);
            ensure!(b.status.iter().all(|&s| s == 0), "lookup failed");
        }
        t.sort_by(|a, b| a.total_cmp(b));
        figs.push(Figure {
            zero_ok: false,
            name: format!("service round trip p50, {label}"),
            value: percentile(&t, 0.5),
            unit: "us",
            note: format!("({rounds} requests, exp2)"),
        });
        figs.push(Figure {
            zero_ok: false,
            name: format!("service round trip p99, {label}"),
            value: percentile(&t, 0.99),
            unit: "us",
            note: String::new(),
        });
    }
    // After an idle gap the service has stopped spinning and sleeps on its listener:
    // this round trip pays the event wake-up, the figure to set against the floor.
    let gapped = rounds / 10;
    let mut t = Vec::with_capacity(gapped);
    for _ in 0..gapped {
        std::thread::sleep(std::time::Duration::from_millis(1));
        let t0 = Instant::now();
        c.submit(Ask::Lookup, &batch256[..1])?;
        c.recv()?;
        t.push(t0.elapsed().as_secs_f64() * 1e6);
    }
    t.sort_by(|a, b| a.total_cmp(b));
    figs.push(Figure {
        zero_ok: false,
        name: "service round trip p50, 1 state, after 1 ms idle".into(),
        value: percentile(&t, 0.5),
        unit: "us",
        note: format!(
            "({gapped} requests; the service sleeps on its event, as in the ping-pong floor)"
        ),
    });
    // Throughput, one client in this process, pipelined batches of 256.
    let secs = if quick { 1.0 } else { 3.0 };
    let n1 = lookup_for(&mut c, &batch256, secs)?;
    figs.push(Figure {
        zero_ok: false,
        name: "service lookups/s, 1 client, batches of 256".into(),
        value: n1 / secs,
        unit: "states/s",
        note: "(pipelined, 4 requests in flight; goal >= 5M)".into(),
    });
    drop(c);
    // Two client processes at once.
    let exe = std::env::current_exe()?;
    let kids: Vec<std::process::Child> = (0..2)
        .map(|_| {
            std::process::Command::new(&exe)
                .args([
                    "__bench-client",
                    "--namespace",
                    &ns,
                    "--world",
                    world,
                    "--seconds",
                    &secs.to_string(),
                    "--batch",
                    "256",
                ])
                .stdout(std::process::Stdio::piped())
                .spawn()
        })
        .collect::<std::io::Result<_>>()?;
    let mut total = 0.0;
    for k in kids {
        let out = k.wait_with_output()?;
        ensure!(out.status.success(), "a bench client failed");
        total += String::from_utf8_lossy(&out.stdout)
            .trim()
            .parse::<f64>()
            .context("bench client output")?;
    }
    figs.push(Figure {
        zero_ok: false,
        name: "service lookups/s, 2 client processes".into(),
        value: total / secs,
        unit: "states/s",
        note: "(each pipelined, batches of 256)".into(),
    });
    // Idle: the service blocks on its listener once its short spin is over.
    let idle = if quick { 0.5 } else { 2.0 };
    std::thread::sleep(std::time::Duration::from_millis(100));
    let before = cpu_seconds(serve.0.id());
    std::thread::sleep(std::time::Duration::from_secs_f64(idle));
    let used = cpu_seconds(serve.0.id()) - before;
    figs.push(Figure {
        zero_ok: true,
        name: "service CPU while idle".into(),
        value: used / idle * 100.0,
        unit: "% of a core",
        note: format!("({used:.2} s of CPU in {idle} s idle, 10 ms clock ticks)"),
    });
    // Floor 1: the same lookups in-process, no IPC.
    let cfg = ServeConfig {
        horizon_sum: false,
        namespace: "unused".into(),
        tool: ToolSel::Tool(0),
        objects: w
            .empowerment
            .objects
            .clone()
            .context("exp2 names objects")?,
        horizon_unequipped: 5,
        horizon_equipped: 6,
        cache_bytes: 1 << 20,
        spin: std::time::Duration::ZERO,
    };
    let mut tables = Tables::new(Engine::new(&w, Limits::default())?, cfg)?;
    let mut req = Box::new(fulcrum_shared::msg::EmpRequest {
        world_hash: w.content_hash(),
        kind: fulcrum_shared::msg::kind::LOOKUP,
        count: 256,
        tool: 0,
        horizon: 0,
        objects: 0,
        seq: 0,
        states: [[0; fulcrum_shared::msg::STATE_BYTES]; fulcrum_shared::msg::MAX_BATCH],
    });
    for (i, s) in batch256.iter().enumerate() {
        req.states[i] = s.to_bytes();
    }
    let mut resp = Box::new(zeroed_response());
    let t0 = Instant::now();
    let mut n = 0usize;
    while t0.elapsed().as_secs_f64() < secs / 2.0 {
        for _ in 0..100 {
            tables.answer(&req, &mut resp);
            n += 256;
        }
    }
    figs.push(Figure {
        zero_ok: false,
        name: "floor: in-process lookups/s".into(),
        value: n as f64 / t0.elapsed().as_secs_f64(),
        unit: "states/s",
        note: "(the service's own answer loop, no IPC)".into(),
    });
    // Floor 2: a Unix datagram ping-pong between two processes.
    let p50_gap = pingpong_p50(rounds / 10, true)?;
    figs.push(Figure {
        zero_ok: false,
        name: "floor: Unix datagram ping-pong p50, after 1 ms idle".into(),
        value: p50_gap,
        unit: "us",
        note: "(the same with a 1 ms pause before each ping)".into(),
    });
    let p50 = pingpong_p50(rounds, false)?;
    figs.push(Figure {
        zero_ok: false,
        name: "floor: Unix datagram ping-pong p50".into(),
        value: p50,
        unit: "us",
        note: "(two processes, 8-byte messages: the cross-CPU wake-up)".into(),
    });
    Ok(())
}

/// An all-zero response (valid: plain data).
fn zeroed_response() -> fulcrum_shared::msg::EmpResponse {
    // SAFETY: EmpResponse is plain integers, floats and bytes; all-zero is a valid value.
    unsafe { std::mem::zeroed() }
}

/// Look up `states` repeatedly for `secs`, pipelined; returns states answered.
fn lookup_for(
    c: &mut fulcrum_empowerment::service::Client,
    states: &[fulcrum_shared::State],
    secs: f64,
) -> Result<f64> {
    use fulcrum_empowerment::service::Ask;
    let big: Vec<fulcrum_shared::State> = states
        .iter()
        .cycle()
        .take(states.len() * 64)
        .copied()
        .collect();
    let t0 = Instant::now();
    let mut n = 0usize;
    while t0.elapsed().as_secs_f64() < secs {
        let b = c.values(Ask::Lookup, &big, 256)?;
        n += b.values.len();
    }
    Ok(n as f64 * secs / t0.elapsed().as_secs_f64())
}

/// `fulcrum __bench-client`: look states up for a while, print how many.
pub fn client_process(ns: &str, world: &str, secs: f64, batch: usize) -> Result<()> {
    let w = load_world(world)?;
    let e = Engine::new(&w, Limits::default())?;
    let mut c =
        fulcrum_empowerment::service::Client::connect(ns, &w, std::time::Duration::from_secs(30))?;
    let states = sample_states(&e, batch.max(1));
    let n = lookup_for(&mut c, &states, secs)?;
    println!("{n}");
    Ok(())
}

/// `fulcrum __pingpong PATH`: echo datagrams back to their sender until an empty one.
pub fn pingpong_echo(path: &std::path::Path) -> Result<()> {
    let sock = std::os::unix::net::UnixDatagram::bind(path)?;
    let mut buf = [0u8; 64];
    loop {
        let (n, from) = sock.recv_from(&mut buf)?;
        if n == 0 {
            return Ok(());
        }
        if let Some(p) = from.as_pathname() {
            sock.send_to(&buf[..n], p)?;
        }
    }
}

/// Median round trip of 8-byte datagrams to a child echo process, in microseconds.
fn pingpong_p50(rounds: usize, gap: bool) -> Result<f64> {
    let dir = std::env::temp_dir().join(format!("fulcrum-pingpong-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let (theirs, ours) = (dir.join("echo"), dir.join("me"));
    let _ = std::fs::remove_file(&theirs);
    let _ = std::fs::remove_file(&ours);
    let mut child = std::process::Command::new(std::env::current_exe()?)
        .arg("__pingpong")
        .arg(&theirs)
        .spawn()?;
    let sock = std::os::unix::net::UnixDatagram::bind(&ours)?;
    let t0 = Instant::now();
    while !theirs.exists() {
        ensure!(
            t0.elapsed().as_secs() < 10,
            "the ping-pong echo did not start"
        );
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let mut buf = [0u8; 64];
    let mut t = Vec::with_capacity(rounds);
    for i in 0..rounds + 100 {
        if gap {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        let t0 = Instant::now();
        sock.send_to(&(i as u64).to_le_bytes(), &theirs)?;
        sock.recv(&mut buf)?;
        if i >= 100 {
            t.push(t0.elapsed().as_secs_f64() * 1e6);
        }
    }
    sock.send_to(&[], &theirs)?;
    let _ = child.wait();
    let _ = std::fs::remove_dir_all(&dir);
    t.sort_by(|a, b| a.total_cmp(b));
    Ok(percentile(&t, 0.5))
}

/// User + system CPU seconds of a process so far (/proc/PID/stat).
fn cpu_seconds(pid: u32) -> f64 {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
        return 0.0;
    };
    // Fields after the command name (which is in parentheses and may hold spaces).
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|x| x.parse::<f64>().ok()).unwrap_or(0.0);
    // utime and stime are fields 14 and 15 of stat, i.e. 11 and 12 after ')'; 100 Hz.
    (ticks(11) + ticks(12)) / 100.0
}

/// Training pieces: world steps per second on one core (with observation encoding) and
/// learner samples x epochs per second (one PPO update, CleanRL's defaults).
fn training_figures(quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    use rand::{Rng, SeedableRng};
    let w = load_world("exp1-tree")?;
    let spec = w.obs_spec();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let actions: Vec<u8> = (0..4096)
        .map(|_| rng.random_range(0..w.num_actions() as u8))
        .collect();
    let (mut g, mut f) = (vec![0u8; spec.cells()], vec![0u8; spec.flags]);
    let steps = if quick { 2_000_000 } else { 20_000_000 };
    let mut ep = w.reset();
    w.observe(&ep.state, &mut g, &mut f);
    let mut done = 0u64;
    let t0 = Instant::now();
    for i in 0..steps {
        let prev = ep.state;
        let out = w.env_step(&mut ep, actions[i % actions.len()]);
        w.observe_update(&prev, &ep.state, &mut g, &mut f);
        if out.terminated || out.truncated {
            done += 1;
            let last = ep.state;
            ep = w.reset();
            w.observe_update(&last, &ep.state, &mut g, &mut f);
        }
    }
    let secs = t0.elapsed().as_secs_f64();
    ensure!(
        done > 0 && g.iter().any(|&x| x != 0),
        "the world did not run"
    );
    figs.push(Figure {
        zero_ok: false,
        name: "world steps/s, one core, with observation".into(),
        value: steps as f64 / secs,
        unit: "steps/s",
        note: format!(
            "(exp1-tree, random actions, {done} episodes, incremental observation; goal >= 20M)"
        ),
    });
    // One PPO update on a batch of 1024 samples (8 envs x 128 steps).
    let shape = fulcrum_learner::local::shape_for(&w, 64);
    let net = fulcrum_learner::net::Net::new(shape, 1, &candle_core::Device::Cpu)?;
    let mut adam = fulcrum_learner::ppo::Adam::new(&net)?;
    let n = 1024;
    let mut glyphs = vec![0u8; n * spec.cells()];
    let mut flags = vec![0u8; n * spec.flags];
    let mut ep = w.reset();
    for i in 0..n {
        w.env_step(&mut ep, actions[i]);
        w.observe(
            &ep.state,
            &mut glyphs[i * spec.cells()..(i + 1) * spec.cells()],
            &mut flags[i * spec.flags..(i + 1) * spec.flags],
        );
    }
    let acts: Vec<u32> = actions[..n].iter().map(|&a| a as u32).collect();
    let lp = vec![-(w.num_actions() as f32).ln(); n];
    let vals = vec![0.0f32; n];
    let adv: Vec<f32> = (0..n)
        .map(|i| ((i * 37) % 11) as f32 / 10.0 - 0.5)
        .collect();
    let ret: Vec<f32> = adv.clone();
    let cfg = fulcrum_learner::ppo::PpoConfig::default();
    let data = fulcrum_learner::local::UpdateData {
        glyphs: &glyphs,
        flags: &flags,
        actions: &acts,
        logprobs: &lp,
        values: &vals,
        advantages: &adv,
        returns: &ret,
        action_mask: false,
        int: None,
    };
    let reps = if quick { 3 } else { 11 };
    let (ms, stats) = median_ms(reps, || {
        Ok(fulcrum_learner::local::update(
            &net, &mut adam, &cfg, 2.5e-4, &mut rng, &data,
        )?)
    })?;
    ensure!(stats.value_loss.is_finite(), "the update diverged");
    figs.push(Figure {
        zero_ok: false,
        name: "learner samples x epochs/s".into(),
        value: (n * cfg.epochs) as f64 / (ms / 1e3),
        unit: "samples/s",
        note: format!("(PPO update: {n} samples, {} epochs x {} minibatches, hidden 64, exp1-tree obs; goal >= 200k)", cfg.epochs, cfg.minibatches),
    });
    Ok(())
}

/// Trajectory chunks through iceoryx2 shared memory, with the run's own service
/// builders: loan a chunk, write every byte of it (as an actor does), send it, receive
/// it on a second node and copy it out (as the learner does). One thread alternates
/// the two sides, so the figure is the cost of the path itself, not of waiting on a
/// full queue (a full queue makes a publisher back off, by design).
fn chunk_transport(quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    use fulcrum_shared::traj::{self, ChunkHeader, ChunkLayout, TrainNames};
    use iceoryx2::prelude::*;
    let w = load_world("exp1-tree")?;
    let spec = w.obs_spec();
    let node = || {
        NodeBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
    };
    let (pn, sn) = (node()?, node()?);
    let mut notes = Vec::new();
    let mut best = 0.0f64;
    // The default chunk of `fulcrum train exp1-tree` (8 worlds x 128 steps), and a big one.
    for (envs, steps) in [(8usize, 128usize), (64, 128)] {
        let layout = ChunkLayout {
            envs,
            steps,
            cells: spec.cells(),
            flags: spec.flags,
        };
        let bytes = layout.bytes();
        let names = TrainNames::new(&format!("bench-chunks-{}-{envs}", std::process::id()));
        let psvc = traj::trajectory_service(&pn, &names).map_err(anyhow::Error::msg)?;
        let ssvc = traj::trajectory_service(&sn, &names).map_err(anyhow::Error::msg)?;
        let publisher = psvc
            .publisher_builder()
            .initial_max_slice_len(bytes)
            .max_loaned_samples(2)
            .create()?;
        let sub = ssvc.subscriber_builder().create()?;
        let mut buf: Vec<u8> = Vec::with_capacity(bytes);
        let mut one = |k: u64| -> Result<u8> {
            let mut s = publisher.loan_slice(bytes)?;
            let b: &mut [u8] = s.payload_mut();
            b.fill(k as u8);
            *s.user_header_mut() = ChunkHeader {
                seq: k,
                len: bytes as u64,
                ..ChunkHeader::default()
            };
            s.send()?;
            let r = sub.receive()?.context("a sent chunk did not arrive")?;
            buf.clear();
            buf.extend_from_slice(r.payload());
            Ok(buf[bytes / 2])
        };
        for k in 0..10 {
            one(k)?;
        }
        let target = if quick { 0.3 } else { 1.0 };
        let t0 = Instant::now();
        let mut k = 0u64;
        while t0.elapsed().as_secs_f64() < target {
            ensure!(one(k)? == k as u8, "a chunk arrived with other bytes");
            k += 1;
        }
        let gbs = k as f64 * bytes as f64 / t0.elapsed().as_secs_f64() / 1e9;
        if envs == 8 {
            best = gbs;
        }
        notes.push(format!("{} KiB: {gbs:.2} GB/s", bytes / 1024));
    }
    figs.push(Figure {
        zero_ok: false,
        name: "chunk transport".into(),
        value: best,
        unit: "GB/s",
        note: format!(
            "(exp1-tree chunks, loan + write every byte + send + receive + copy out; {})",
            notes.join(", ")
        ),
    });
    Ok(())
}

/// `fulcrum train ARGS --out DIR`, no input, output to nowhere.
fn train_command(args: &[&str], dir: &std::path::Path) -> Result<std::process::Command> {
    let mut c = std::process::Command::new(std::env::current_exe()?);
    c.arg("train")
        .args(args)
        .arg("--out")
        .arg(dir)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null());
    Ok(c)
}

/// Runs `fulcrum train ARGS --out DIR` (then removes DIR) and returns the env steps per
/// second of each update after the first (which pays for start-up), and the run's
/// resolved configuration.
fn train_sps(
    args: &[&str],
    dir: &std::path::Path,
) -> Result<(Vec<f64>, fulcrum_learner::config::RunConfig)> {
    let _ = std::fs::remove_dir_all(dir);
    let out = train_command(args, dir)?
        .stderr(std::process::Stdio::piped())
        .output()?;
    ensure!(
        out.status.success(),
        "fulcrum train {} failed: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    let rows = fulcrum_learner::run::read_metrics(&dir.join("metrics.csv"))?;
    let cfg = fulcrum_learner::config::RunConfig::load(&dir.join("config.toml"))
        .map_err(anyhow::Error::msg)?;
    let _ = std::fs::remove_dir_all(dir);
    let sps: Vec<f64> = rows.iter().skip(1).map(|r| r.sps).collect();
    ensure!(!sps.is_empty(), "the run made too few updates");
    Ok((sps, cfg))
}

/// End-to-end `fulcrum train exp1-tree` with empowerment: env steps per second of the
/// learner's updates (median over updates after the first), defaults for this machine.
fn end_to_end(quick: bool, figs: &mut Vec<Figure>) -> Result<()> {
    let dir = std::env::temp_dir().join(format!("fulcrum-bench-train-{}", std::process::id()));
    // Whole updates of this machine's default batch (actors = cores - 1, 8 worlds, 128 steps).
    let batch = (fulcrum_run::process::cores().saturating_sub(1).max(1) * 8 * 128) as u64;
    let steps = if quick { 16 } else { 100 } * batch;
    let (mut sps, cfg) = train_sps(&["exp1-tree", "--steps", &steps.to_string()], &dir)?;
    sps.sort_by(f64::total_cmp);
    figs.push(Figure {
        zero_ok: false,
        name: "end-to-end training env steps/s".into(),
        value: sps[sps.len() / 2],
        unit: "steps/s",
        note: format!(
            "(train exp1-tree, beta {}, {} actor(s) x {} worlds, {} learner thread(s), median of {} updates; goal >= 50k)",
            cfg.beta,
            cfg.actors,
            cfg.envs_per_actor,
            cfg.learner_threads,
            sps.len()
        ),
    });
    Ok(())
}

/// Seconds from `fulcrum train exp1-tree` being started to the first update at which the
/// success rate, pooled over 10 updates as `fulcrum experiment` pools it, reaches 0.9;
/// and the env steps by then. The run is then stopped (SIGINT, as a user would). `None`
/// when the budget ends first.
fn solve_once(args: &[&str], dir: &std::path::Path) -> Result<Option<(f64, f64)>> {
    use fulcrum_run::stats::{smooth, steps_to, Point};
    let _ = std::fs::remove_dir_all(dir);
    let t0 = Instant::now();
    let mut child = train_command(args, dir)?
        .stderr(std::process::Stdio::null())
        .spawn()?;
    let metrics = dir.join("metrics.csv");
    let solved = loop {
        let done = child.try_wait()?;
        let rows = fulcrum_learner::run::read_metrics(&metrics).unwrap_or_default();
        let pts: Vec<Point> = rows.iter().map(Point::from).collect();
        if let Some(steps) = steps_to(&smooth(&pts, 10), 0.9) {
            break Some((t0.elapsed().as_secs_f64(), steps));
        }
        if let Some(status) = done {
            ensure!(status.success(), "fulcrum train {} failed", args.join(" "));
            break None;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    };
    // SAFETY: kill(2) on our own child's pid.
    unsafe {
        libc::kill(child.id() as libc::pid_t, libc::SIGINT);
    }
    child.wait()?;
    let _ = std::fs::remove_dir_all(dir);
    Ok(solved)
}

/// Time to solve exp1-tree with train's defaults (the additive bonus of the world file,
/// masking on), five seeds: median wall seconds and env steps to a success rate of 0.9.
/// A seed that does not get there within the budget counts at the budget.
fn time_to_solve(figs: &mut Vec<Figure>) -> Result<()> {
    let dir = std::env::temp_dir().join(format!("fulcrum-bench-solve-{}", std::process::id()));
    let budget = 499_712u64;
    let batch = (fulcrum_run::process::cores().saturating_sub(1).max(1) * 8 * 128) as u64;
    let steps = budget.div_ceil(batch) * batch;
    let (mut secs, mut env) = (Vec::new(), Vec::new());
    let mut solved = 0;
    for seed in 1..=5 {
        let seed = seed.to_string();
        let steps = steps.to_string();
        let t0 = Instant::now();
        match solve_once(&["exp1-tree", "--seed", &seed, "--steps", &steps], &dir)? {
            Some((s, e)) => {
                solved += 1;
                secs.push(s);
                env.push(e);
            }
            None => {
                secs.push(t0.elapsed().as_secs_f64());
                env.push(budget as f64);
            }
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let list =
        |v: &[f64], f: fn(f64) -> String| v.iter().map(|&x| f(x)).collect::<Vec<_>>().join(" ");
    let note = format!(
        "(train exp1-tree defaults, seeds 1-5, {solved}/5 solved; sorted: {} s, {} steps; goal <= 10 s)",
        list(&{ let mut v = secs.clone(); v.sort_by(f64::total_cmp); v }, |x| format!("{x:.1}")),
        list(&{ let mut v = env.clone(); v.sort_by(f64::total_cmp); v }, |x| format!("{:.0}k", x / 1e3)),
    );
    figs.push(Figure {
        zero_ok: false,
        name: "exp1-tree time to 0.9 success, wall clock".into(),
        value: median(&mut secs),
        unit: "s",
        note: note.clone(),
    });
    figs.push(Figure {
        zero_ok: false,
        name: "exp1-tree env steps to 0.9 success".into(),
        value: median(&mut env),
        unit: "steps",
        note: "(the same runs: steps of the first update whose success, pooled over 10 updates, reached 0.9)".into(),
    });
    Ok(())
}
