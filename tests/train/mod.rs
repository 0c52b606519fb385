//! `fulcrum train` across real processes: the supervisor, the empowerment service, the
//! learner and actors, with real iceoryx2 shared memory, real signals and real PPO.
//! Every run has its own namespace (the supervisor makes one per launch).

use std::io::Read;
use std::path::Path;
use std::process::{Child, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use fulcrum_learner::metrics::{read_metrics, MetricsRow};
use iceoryx2::prelude::*;

use crate::util::{
    deterministic, fulcrum, pids_with, same_bits, signal, wait_until, weights, TempDir,
};

mod chaos;
mod estimates;
mod eval;
mod family;
mod forms;
mod hang;
mod isolation;
mod noisy;
mod poison;
mod resume;
mod storage;
mod supervision;
mod trap;

/// Small, fast settings: batch = actors * 4 worlds * 32 steps.
const SMALL: &[&str] = &["--envs-per-actor", "4", "--steps-per-chunk", "32"];

fn train(args: &[&str]) -> Child {
    fulcrum()
        .arg("train")
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("fulcrum train starts")
}

/// Wait for a child with a deadline; its stderr as text.
fn finish(mut c: Child, limit: Duration) -> (ExitStatus, String, String) {
    let t0 = Instant::now();
    let mut err_pipe = c.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = err_pipe.read_to_string(&mut s);
        s
    });
    let mut out_pipe = c.stdout.take().unwrap();
    let out_reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = out_pipe.read_to_string(&mut s);
        s
    });
    loop {
        if let Some(s) = c.try_wait().unwrap() {
            return (s, reader.join().unwrap(), out_reader.join().unwrap());
        }
        if t0.elapsed() > limit {
            let _ = c.kill();
            let _ = c.wait();
            panic!(
                "fulcrum train did not finish in {limit:?}; stderr: {}",
                reader.join().unwrap()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn namespace_of(stderr: &str) -> String {
    let i = stderr
        .find("namespace ")
        .expect("the supervisor names its namespace");
    stderr[i + 10..]
        .split(|c: char| c == ')' || c.is_whitespace())
        .next()
        .unwrap()
        .to_string()
}

/// iceoryx2 services whose name contains the namespace.
fn services_of(ns: &str) -> Vec<String> {
    fulcrum_empowerment::service::quiet_ipc_logs();
    let mut names = Vec::new();
    let _ = ipc::Service::list(Config::global_config(), |s| {
        let n = s.static_details.name().to_string();
        if n.contains(ns) {
            names.push(n);
        }
        CallbackProgression::Continue
    });
    names
}

/// Nothing of the run is left: no process, no service (after cleaning dead nodes,
/// which any next start does).
fn assert_nothing_left(ns: &str) {
    let t0 = Instant::now();
    loop {
        let procs = pids_with(&[ns]);
        fulcrum_empowerment::service::clean_dead_nodes();
        let svcs = services_of(ns);
        if procs.is_empty() && svcs.is_empty() {
            return;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(5),
            "left behind: processes {procs:?}, services {svcs:?}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The `beta = ` line of a run's `config.toml`.
fn beta_of(cfg: &str) -> f64 {
    cfg.lines()
        .find_map(|l| l.strip_prefix("beta = "))
        .expect("config.toml has beta")
        .parse()
        .expect("beta is a number")
}

fn wait_rows(dir: &Path, n: usize, limit: Duration) {
    wait_until(limit, &format!("{n} metrics rows"), || {
        read_metrics(&dir.join("metrics.csv"))
            .map(|r| r.len())
            .unwrap_or(0)
            >= n
    });
}

/// Rows are updates 1..=n with env steps growing by the batch each.
fn assert_contiguous(rows: &[MetricsRow], n: u64, batch: u64) {
    assert_eq!(rows.len() as u64, n, "one row per update");
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r.update, i as u64 + 1);
        assert_eq!(r.env_steps, (i as u64 + 1) * batch);
    }
}

#[test]
fn two_actors_finish_and_leave_nothing_behind() {
    let dir = TempDir::fresh("two");
    let d = dir.to_str().unwrap();
    // 2 actors x 4 worlds x 32 steps = 256 steps an update; 2048 steps = 8 updates.
    let c = train(
        &[
            &["room", "--actors", "2", "--steps", "2048", "--out", d][..],
            SMALL,
        ]
        .concat(),
    );
    let (status, err, out) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 8, 256);
    assert!(rows
        .iter()
        .all(|r| r.dropped_chunks == 0 && r.policy_lag == 0.0));
    // The room's E is positive next to the tree with the axe: the service answered.
    assert!(rows.iter().any(|r| r.intrinsic_mean > 0.0));
    assert!(dir.join("checkpoints/latest.safetensors").exists());
    assert!(dir.join("plots/learning-curve.png").exists());
    let cfg = std::fs::read_to_string(dir.join("config.toml")).unwrap();
    assert!(cfg.contains("actors = 2") && cfg.contains("fulcrum_version"));
    assert!(out.contains("done: 2048 env steps"), "{out}");
    assert_nothing_left(&namespace_of(&err));
}

/// Train `world` for 6 updates without a stop, and again stopped after 3 and resumed:
/// the same metrics rows (but the timings), weights and evaluations, bit for bit.
fn resumed_equals_uninterrupted_on(world: &str, tag: &str, extra: &[&str]) {
    let a = TempDir::fresh(&format!("{tag}-a"));
    let b = TempDir::fresh(&format!("{tag}-b"));
    // Synchronous, one actor, with empowerment: 6 updates of 128 steps.
    let common = [
        &[world, "--actors", "1", "--steps", "768", "--seed", "7"][..],
        SMALL,
        extra,
    ]
    .concat();
    let (s, err, _) = finish(
        train(&[&common[..], &["--out", a.to_str().unwrap()]].concat()),
        Duration::from_secs(120),
    );
    assert!(s.success(), "{err}");
    let (s, err, out) = finish(
        train(
            &[
                &common[..],
                &["--out", b.to_str().unwrap(), "--stop-after-updates", "3"],
            ]
            .concat(),
        ),
        Duration::from_secs(120),
    );
    assert!(s.success(), "{err}");
    assert!(out.contains("stopped as asked"), "{out}");
    assert_eq!(read_metrics(&b.join("metrics.csv")).unwrap().len(), 3);
    let (s, err, _) = finish(
        train(&["--resume", b.to_str().unwrap()]),
        Duration::from_secs(120),
    );
    assert!(s.success(), "{err}");
    let ra = read_metrics(&a.join("metrics.csv")).unwrap();
    let rb = read_metrics(&b.join("metrics.csv")).unwrap();
    assert_eq!(ra.len(), 6);
    let ra: Vec<String> = ra.iter().map(deterministic).collect();
    let rb: Vec<String> = rb.iter().map(deterministic).collect();
    assert_eq!(ra, rb);
    // And the final weights are the same bits.
    assert!(same_bits(&weights(&a, world), &weights(&b, world)));
    // Periodic evaluations (updates 2, 4, 6): the same rows, none twice.
    let evals = |dir: &Path| std::fs::read_to_string(dir.join("eval.csv")).ok();
    assert_eq!(evals(&a), evals(&b));
    if extra.contains(&"--eval-every") {
        let text = evals(&a).expect("a run with --eval-every wrote no eval.csv");
        let updates: Vec<&str> = text.lines().skip(1).map(|l| &l[..2]).collect();
        assert_eq!(updates, ["2,", "4,", "6,"], "{text}");
    }
    let _ = std::fs::remove_dir_all(&a);
    let _ = std::fs::remove_dir_all(&b);
}

#[test]
fn bad_training_settings_are_refused_before_anything_starts() {
    let dir = TempDir::fresh("bad");
    let d = dir.to_str().unwrap();
    for (args, needle) in [
        (vec!["room", "--beta", "-1", "--out", d], "beta -1 must be"),
        (
            vec!["room", "--actors", "0", "--out", d],
            "number of actors",
        ),
        (
            vec!["room", "--horizon-equipped", "0", "--out", d],
            "the horizon with the tool 0",
        ),
        (vec!["room", "--tool", "hammer", "--out", d], "unknown tool"),
        (vec!["no-such-world", "--out", d], "no-such-world"),
        (
            vec![
                "exp1-tree-slip",
                "--no-empowerment",
                "--empowerment-model",
                "deterministic",
                "--out",
                d,
            ],
            "--empowerment-model and --no-empowerment (or --intrinsic none) contradict",
        ),
        (vec!["--resume", "/nonexistent/run"], "no config.toml"),
        // 1 actor x 8 worlds x 128 steps = 1024 a batch: 1500 is not whole updates.
        (
            vec!["room", "--actors", "1", "--steps", "1500", "--out", d],
            "use 1024 or 2048",
        ),
        (
            vec!["room", "--horizon-unequipped", "65", "--out", d],
            "the horizon without the tool 65",
        ),
        (
            vec![
                "room",
                "--intrinsic",
                "count",
                "--no-empowerment",
                "--out",
                d,
            ],
            "contradict",
        ),
        (
            vec![
                "room",
                "--intrinsic-value-head",
                "--no-empowerment",
                "--out",
                d,
            ],
            "the intrinsic value head needs an intrinsic reward",
        ),
        (
            vec![
                "room",
                "--intrinsic-value-head",
                "--gamma-int",
                "1.5",
                "--out",
                d,
            ],
            "gamma_int 1.5",
        ),
        (
            vec!["room", "--view", "crop:0", "--out", d],
            "'--view <full|crop:R>': unknown view 'crop:0' (views: full, or crop:R",
        ),
        (
            vec!["room", "--view", "window", "--out", d],
            "'--view <full|crop:R>': unknown view 'window'",
        ),
        (
            vec![
                "room",
                "--eval-every",
                "2",
                "--eval-episodes",
                "0",
                "--out",
                d,
            ],
            "0 episodes per evaluation",
        ),
    ] {
        let (s, err, _) = finish(train(&args), Duration::from_secs(30));
        assert_eq!(s.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
        assert!(
            !dir.join("config.toml").exists(),
            "nothing written for {args:?}"
        );
    }
}

/// Live children of a process whose command line contains `needle`.
fn children_with(parent: u32, needle: &str) -> Vec<u32> {
    pids_with(&[needle])
        .into_iter()
        .filter(|p| {
            let stat = std::fs::read_to_string(format!("/proc/{p}/stat")).unwrap_or_default();
            // Field 4 (after the command in parentheses) is the parent pid.
            let after = stat.rsplit(')').next().unwrap_or("");
            after.split_whitespace().nth(1) == Some(&parent.to_string())
        })
        .collect()
}

/// PPO through the whole system (actors, service, learner, shared memory) solves the
/// room within 200k env steps, with and without empowerment (bounded by steps, not
/// time; fixed seed and settings).
#[test]
fn the_whole_system_learns_the_room() {
    for arm in [&[][..], &["--no-empowerment"][..]] {
        let dir = TempDir::fresh("learn");
        let d = dir.to_str().unwrap();
        let args = [
            &[
                "room", "--actors", "1", "--steps", "200704", "--seed", "1", "--out", d,
            ][..],
            arm,
        ]
        .concat();
        let (s, err, _) = finish(train(&args), Duration::from_secs(300));
        assert!(s.success(), "{err}");
        let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
        // The last 10 updates (about 170 episodes): success rate >= 0.9.
        let tail = &rows[rows.len() - 10..];
        let (eps, succ) = tail.iter().fold((0.0, 0.0), |(e, s), r| {
            (
                e + r.episodes as f64,
                s + r.success_rate * r.episodes as f64,
            )
        });
        assert!(succ / eps >= 0.9, "{arm:?}: success {}", succ / eps);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
