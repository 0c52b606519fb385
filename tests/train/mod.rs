//! `fulcrum train` across real processes: the supervisor, the empowerment service, the
//! learner and actors, with real iceoryx2 shared memory, real signals and real PPO.
//! Every run has its own namespace (the supervisor makes one per launch).

use std::io::Read;
use std::path::Path;
use std::process::{Child, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use fulcrum_learner::metrics::{read_metrics, MetricsRow};
use iceoryx2::prelude::*;

use crate::util::{fulcrum, pids_with, signal, wait_until, TempDir};

mod chaos;
mod eval;
mod hang;
mod noisy;
mod poison;
mod storage;
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

#[test]
fn a_killed_actor_is_replaced_and_the_run_finishes() {
    let dir = TempDir::fresh("kill");
    let d = dir.to_str().unwrap();
    // 4000 updates of 256 steps (ten seconds or more here): long enough for three kills
    // of actor 0, each after its replacement has taken part in updates.
    let mut c = train(
        &[
            &[
                "room",
                "--actors",
                "2",
                "--steps",
                "1024000",
                "--no-empowerment",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    let rows_now = || {
        read_metrics(&dir.join("metrics.csv"))
            .map(|r| r.len())
            .unwrap_or(0)
    };
    let mut at = 3;
    for kill in 1..=3 {
        wait_rows(&dir, at, Duration::from_secs(60));
        let victims = pids_with(&["__actor", d, "--index 0"]);
        assert!(
            c.try_wait().unwrap().is_none(),
            "the run ended before kill {kill}"
        );
        assert_eq!(victims.len(), 1, "one actor 0 before kill {kill}");
        signal(victims[0], "-KILL");
        wait_until(Duration::from_secs(20), "actor 0 replaced", || {
            let now = pids_with(&["__actor", d, "--index 0"]);
            !now.is_empty() && now != victims
        });
        // The next kill after the new actor 0 took part in some updates.
        at = rows_now() + 20;
    }
    let (status, err, _) = finish(c, Duration::from_secs(180));
    assert!(status.success(), "{err}");
    assert_eq!(
        err.matches("actor 0 stopped (signal 9); restarted").count(),
        3,
        "{err}"
    );
    // Every update is whole (one full chunk per actor: the step count grows by the
    // batch each row) and the run reaches its steps.
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 4000, 256);
    assert_eq!(rows.last().unwrap().actor_restarts, 3);
    assert_nothing_left(&namespace_of(&err));
}

#[test]
fn sigint_stops_everything_and_resume_continues_the_rows() {
    let dir = TempDir::fresh("sigint");
    let d = dir.to_str().unwrap();
    // 1 actor: 128 steps an update; 2000 updates (seconds: long enough to interrupt).
    let c = train(
        &[
            &[
                "room",
                "--actors",
                "1",
                "--steps",
                "256000",
                "--checkpoint-every",
                "100000",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 4, Duration::from_secs(60));
    let pid = c.id();
    signal(pid, "-INT");
    let t0 = Instant::now();
    let (status, err, _) = finish(c, Duration::from_secs(30));
    assert!(
        t0.elapsed() < Duration::from_secs(5),
        "stopped in {:?}",
        t0.elapsed()
    );
    assert_eq!(status.code(), Some(130), "{err}");
    assert!(err.contains("--resume"), "{err}");
    assert_nothing_left(&namespace_of(&err));
    // The final checkpoint holds the last finished update (no periodic one was due).
    let before = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert!(!before.is_empty() && (before.len() as u64) < 2000);
    assert!(dir.join("checkpoints/latest.safetensors").exists());

    let c = train(&["--resume", d]);
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    assert!(err.contains("resuming"), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 2000, 128);
    // Rows written before the stop are kept as they were.
    for (a, b) in before.iter().zip(&rows) {
        assert_eq!(a.csv(), b.csv());
    }
    // Wall time continues across the resume.
    assert!(rows.last().unwrap().wall_s > before.last().unwrap().wall_s);
}

/// The columns that must match bit for bit (all but the timings).
fn deterministic(r: &MetricsRow) -> String {
    let mut r = *r;
    r.sps = 0.0;
    r.wall_s = 0.0;
    r.csv()
}

#[test]
fn a_resumed_run_equals_an_uninterrupted_one_bit_for_bit() {
    resumed_equals_uninterrupted("exact", &[]);
}

/// The new forms carry state across chunks (first-visit's paid flags, the potential of
/// each world's state), the unmasked policy samples other actions, and a cropped view
/// changes the network's input: each resumes to the same bits as a run that never
/// stopped.
#[test]
fn resumes_are_bit_for_bit_with_every_new_option() {
    for (tag, extra) in [
        ("exact-fv", &["--intrinsic", "first-visit"][..]),
        ("exact-hp", &["--intrinsic", "horizon-potential"][..]),
        ("exact-nomask", &["--no-action-mask"][..]),
        // The KL coefficient adapts after each update and is checkpointed.
        ("exact-rllib", &["--ppo-preset", "rllib"][..]),
        // Two value heads: the intrinsic rewards' running scale is checkpointed.
        ("exact-2h", &["--intrinsic-value-head", "--beta", "0.1"][..]),
        // A partial view: the network takes the 5 x 5 window around the agent; and
        // periodic evaluations, which the resumed run makes again after its checkpoint.
        ("exact-crop", &["--view", "crop:2", "--eval-every", "2"][..]),
    ] {
        resumed_equals_uninterrupted(tag, extra);
    }
}

fn resumed_equals_uninterrupted(tag: &str, extra: &[&str]) {
    resumed_equals_uninterrupted_on("room", tag, extra);
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
    let dev = candle_core::Device::Cpu;
    let w = fulcrum_world::load_world(world).unwrap();
    let shape = fulcrum_contracts::config::RunConfig::load(&a.join("config.toml"))
        .unwrap()
        .shape(&w);
    let flat = |dir: &Path| {
        let net = fulcrum_learner::net::Net::new(shape, 99, &dev).unwrap();
        let mut adam = fulcrum_learner::adam::Adam::new(&net).unwrap();
        fulcrum_learner::checkpoint::load(
            &dir.join("checkpoints/latest.safetensors"),
            &net,
            &mut adam,
        )
        .unwrap();
        net.flat().unwrap()
    };
    let (fa, fb) = (flat(&a), flat(&b));
    assert!(fa.iter().zip(&fb).all(|(x, y)| x.to_bits() == y.to_bits()));
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

#[test]
fn a_killed_service_is_restarted_and_actors_resume() {
    let dir = TempDir::fresh("service");
    let twin = TempDir::fresh("service-twin");
    let d = dir.to_str().unwrap();
    let common = [
        &["room", "--actors", "1", "--steps", "256000", "--seed", "7"][..],
        &["--intrinsic", "additive"][..],
        SMALL,
    ]
    .concat();
    let c = train(&[&common[..], &["--out", d]].concat());
    wait_rows(&dir, 3, Duration::from_secs(60));
    let svc = children_with(c.id(), "serve");
    assert_eq!(svc.len(), 1, "one service: {svc:?}");
    signal(svc[0], "-KILL");
    let (status, err, _) = finish(c, Duration::from_secs(180));
    assert!(status.success(), "{err}");
    assert!(
        err.contains("the empowerment service stopped (signal 9); restarting it"),
        "{err}"
    );
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 2000, 128);
    // No chunk was lost or refused across the restart (actors held theirs and asked
    // the new service).
    assert!(rows.iter().all(|r| r.dropped_chunks == 0));
    assert_nothing_left(&namespace_of(&err));
    // The intrinsic rewards of every chunk are the table's, never zeros or a stand-in:
    // the same run with a service nobody killed trains to the same bits, row by row
    // (one synchronous actor; the additive form depends on the table alone).
    let (status, err, _) = finish(
        train(&[&common[..], &["--out", twin.to_str().unwrap()]].concat()),
        Duration::from_secs(180),
    );
    assert!(status.success(), "{err}");
    let undisturbed = read_metrics(&twin.join("metrics.csv")).unwrap();
    let a: Vec<String> = rows.iter().map(deterministic).collect();
    let b: Vec<String> = undisturbed.iter().map(deterministic).collect();
    assert!(a == b, "a service restart changed what the run trained on");
}

#[test]
fn a_killed_learner_ends_the_run_with_a_resumable_checkpoint() {
    let dir = TempDir::fresh("learner");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &[
                "room",
                "--actors",
                "1",
                "--steps",
                "256000",
                "--no-empowerment",
                "--checkpoint-every",
                "5",
                "--seed",
                "7",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 12, Duration::from_secs(60));
    let l = children_with(c.id(), "__learner");
    assert_eq!(l.len(), 1);
    signal(l[0], "-KILL");
    let (status, err, _) = finish(c, Duration::from_secs(30));
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(err.contains("the learner failed (signal 9)"), "{err}");
    assert!(err.contains(&format!("--resume {d}")), "{err}");
    assert_nothing_left(&namespace_of(&err));
    let killed_at = read_metrics(&dir.join("metrics.csv")).unwrap().len() as u64;
    assert!(killed_at >= 12);
    // Continue to the end (2000 updates): the rows after the last checkpoint (a
    // multiple of 5) are redone, not duplicated.
    let c = train(&["--resume", d]);
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 2000, 128);
    // And redone to the same bits: the same run, never killed (the same step count,
    // which sets the learning-rate schedule).
    let twin = TempDir::fresh("learner-twin");
    let (status, err, _) = finish(
        train(
            &[
                &["room", "--actors", "1", "--steps", "256000"][..],
                &["--no-empowerment", "--checkpoint-every", "5", "--seed", "7"],
                &["--out", twin.to_str().unwrap()],
                SMALL,
            ]
            .concat(),
        ),
        Duration::from_secs(120),
    );
    assert!(status.success(), "{err}");
    let twin_rows = read_metrics(&twin.join("metrics.csv")).unwrap();
    let a: Vec<String> = rows.iter().map(deterministic).collect();
    let b: Vec<String> = twin_rows.iter().map(deterministic).collect();
    assert!(
        a == b,
        "the resume after a SIGKILL left the uninterrupted path"
    );
}

#[test]
fn asynchronous_actors_record_their_policy_lag() {
    let dir = TempDir::fresh("async");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &[
                "room",
                "--actors",
                "2",
                "--steps",
                "25600",
                "--max-policy-lag",
                "3",
                "--no-empowerment",
                "--out",
                d,
            ][..],
            SMALL,
        ]
        .concat(),
    );
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 100, 256);
    assert!(rows.iter().all(|r| (0.0..=3.0).contains(&r.policy_lag)));
    // Actors ran ahead of the learner: some chunks came from an older policy.
    assert!(rows.iter().any(|r| r.policy_lag > 0.0), "no lag recorded");
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

#[test]
fn every_intrinsic_form_trains_with_two_actors_and_logs_its_diagnostics() {
    for form in [
        "potential",
        "count",
        "none",
        "horizon-potential",
        "first-visit",
    ] {
        let dir = TempDir::fresh(form);
        let d = dir.to_str().unwrap();
        let c = train(
            &[
                &["room", "--actors", "2", "--steps", "4096", "--out", d][..],
                &["--intrinsic", form],
                SMALL,
            ]
            .concat(),
        );
        let (status, err, _) = finish(c, Duration::from_secs(120));
        assert!(status.success(), "{form}: {err}");
        let cfg = std::fs::read_to_string(dir.join("config.toml")).unwrap();
        assert!(cfg.contains(&format!("intrinsic = \"{form}\"")), "{cfg}");
        let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
        assert_contiguous(&rows, 16, 256);
        for r in &rows {
            match form {
                // gamma E' - E lies in [-max E, max E]; the room's E is at most a few bits.
                "potential" => {
                    assert!(r.intrinsic_mean.abs() < 4.0, "{r:?}");
                    assert!((0.0..=1.0).contains(&r.e_positive_frac), "{r:?}");
                }
                // gamma Phi' - Phi, Phi the sum of E^h over h <= 8 (a few bits each).
                "horizon-potential" => {
                    assert!(r.intrinsic_mean.abs() < 32.0, "{r:?}");
                }
                // E paid at most once per inventory per episode: far under E per step.
                "first-visit" => {
                    assert!(r.intrinsic_mean >= 0.0 && r.intrinsic_mean < 0.5, "{r:?}");
                    // NaN when no episode ended in the update.
                    assert!(
                        r.intrinsic_return.is_nan() || r.intrinsic_return >= 0.0,
                        "{r:?}"
                    );
                }
                // 1 / sqrt(N) with N >= 1, and N grows: the mean is in (0, 1].
                "count" => {
                    assert!(r.intrinsic_mean > 0.0 && r.intrinsic_mean <= 1.0, "{r:?}");
                    assert!(r.e_positive_frac.is_nan(), "{r:?}");
                }
                _ => assert_eq!(r.intrinsic_mean, 0.0),
            }
        }
        if form == "count" {
            // States are revisited by both actors: the mean bonus falls.
            assert!(rows.last().unwrap().intrinsic_mean < rows[0].intrinsic_mean);
        }
        // The room's axe is next to the agent: picked up in the first updates.
        let first = rows.iter().find_map(|r| r.first_pickup_step).unwrap();
        assert!(first <= 4096 && first % 256 == 0, "{first}");
        assert!(rows
            .iter()
            .all(|r| r.first_pickup_step.is_none_or(|s| s == first)));
        assert_nothing_left(&namespace_of(&err));
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[test]
fn one_horizon_everywhere_with_horizon_mode_fixed_and_recorded_episodes() {
    let dir = TempDir::fresh("fixed");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &["room", "--steps", "1024", "--out", d][..],
            &["--horizon-mode", "fixed", "--horizon-unequipped", "5"],
            &["--record", "2"],
            SMALL,
        ]
        .concat(),
    );
    let (status, err, out) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    // --record 2: two strips of the final policy's episodes.
    assert!(out.contains("2 episodes of the final policy"), "{out}");
    for k in 1..=2 {
        let png = std::fs::read(dir.join(format!("episodes/episode-{k}.png"))).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    }
    assert!(!dir.join("episodes/episode-3.png").exists());

    // `record --gif`: the same episodes as animations, one frame per state (the start
    // and one after each step), every frame the size of the first.
    let gifs = dir.join("gifs");
    let out = crate::util::fulcrum()
        .args(["record", d, "--episodes", "2", "--gif", "--seed", "5"])
        .arg("--out")
        .arg(&gifs)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 4, "{text}");
    for k in 1..=2 {
        let line = lines
            .iter()
            .find(|l| l.contains(&format!("episode-{k}.gif")))
            .unwrap_or_else(|| panic!("no episode-{k}.gif in {text}"));
        let steps: usize = line
            .split('(')
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("no step count in {line}"));
        assert!((1..=50).contains(&steps), "{line}");
        let file = std::fs::File::open(gifs.join(format!("episode-{k}.gif"))).unwrap();
        let mut opts = gif::DecodeOptions::new();
        opts.set_color_output(gif::ColorOutput::RGBA);
        let mut dec = opts.read_info(file).unwrap();
        // room is 7 x 5 cells of 14 pixels; the frame adds 8 pixels each side (at least
        // 160 wide), and 22 + 16 + 8 pixels of heading, caption and margin.
        assert_eq!((dec.width(), dec.height()), (160, 22 + 5 * 14 + 16 + 8));
        let mut frames = 0;
        while let Some(f) = dec.read_next_frame().unwrap() {
            assert_eq!((f.width, f.height), (160, 116));
            assert_eq!(f.delay, 25);
            frames += 1;
        }
        assert_eq!(frames, steps + 1, "{line}");
    }
    let cfg = std::fs::read_to_string(dir.join("config.toml")).unwrap();
    assert!(cfg.contains("horizon_unequipped = 5\n"), "{cfg}");
    assert!(cfg.contains("horizon_equipped = 5\n"), "{cfg}");
    assert!(cfg.contains("horizon_mode = \"fixed\""), "{cfg}");
}

/// CPU seconds (user + system) a process has used so far.
fn cpu_s(pid: u32) -> f64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
    // Fields after the command (which may hold spaces) start after the last ')'.
    let rest = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    // utime and stime are fields 14 and 15 of stat, 12 and 13 after the ')'.
    (ticks(11) + ticks(12)) / 100.0
}

#[test]
fn a_stopped_learner_blocks_actors_without_burning_a_core_or_losing_chunks() {
    let dir = TempDir::fresh("sigstop");
    let d = dir.to_str().unwrap();
    // Asynchronous actors: they keep producing until the learner's queue is full, then
    // wait under backpressure.
    let c = train(
        &[
            &["room", "--actors", "2", "--steps", "128000", "--out", d][..],
            &["--no-empowerment", "--max-policy-lag", "1000"],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 5, Duration::from_secs(60));
    let l = children_with(c.id(), "__learner");
    assert_eq!(l.len(), 1);
    let actors = children_with(c.id(), "__actor");
    assert_eq!(actors.len(), 2);
    signal(l[0], "-STOP");
    // Let the queue fill, then measure the actors' CPU over 2 s.
    std::thread::sleep(Duration::from_millis(1000));
    let rows_stopped = read_metrics(&dir.join("metrics.csv")).unwrap().len();
    let before: f64 = actors.iter().map(|&p| cpu_s(p)).sum();
    std::thread::sleep(Duration::from_secs(2));
    let used: f64 = actors.iter().map(|&p| cpu_s(p)).sum::<f64>() - before;
    assert!(
        used < 0.5,
        "two blocked actors used {used:.2} s of CPU in 2 s"
    );
    // Nothing was learned while stopped.
    assert_eq!(
        read_metrics(&dir.join("metrics.csv")).unwrap().len(),
        rows_stopped
    );
    signal(l[0], "-CONT");
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 500, 256);
    assert!(rows.iter().all(|r| r.dropped_chunks == 0), "no chunk lost");
    assert_nothing_left(&namespace_of(&err));
}

#[test]
fn a_killed_supervisor_takes_its_children_and_the_run_resumes() {
    let dir = TempDir::fresh("supervisor");
    let d = dir.to_str().unwrap();
    let mut c = train(
        &[
            &["room", "--actors", "1", "--steps", "256000", "--out", d][..],
            &["--checkpoint-every", "5"],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 12, Duration::from_secs(60));
    // The supervisor's stderr names the namespace; read it after the kill.
    signal(c.id(), "-KILL");
    let _ = c.wait();
    let mut err = String::new();
    let _ = c.stderr.take().unwrap().read_to_string(&mut err);
    let ns = namespace_of(&err);
    // Children notice (PR_SET_PDEATHSIG) and go.
    wait_until(Duration::from_secs(10), "the children gone", || {
        pids_with(&[&ns]).is_empty()
    });
    let done = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert!(done.len() >= 12);
    // The same run continues from its last checkpoint, up to 40 updates.
    let c2 = train(&["--resume", d, "--steps", "5120"]);
    let (status, err2, _) = finish(c2, Duration::from_secs(60));
    assert!(status.success(), "{err2}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 40, 128);
    // Whatever the dead left in shared memory, the next start cleaned: the test lists
    // the old namespace's services without cleaning anything itself.
    assert_eq!(
        services_of(&ns),
        Vec::<String>::new(),
        "left by the dead run"
    );
}

/// Every iceoryx2 file under `dir` (recursively) with group or other permission bits.
fn shared_files_not_owner_only(dir: &Path) -> (usize, Vec<String>) {
    use std::os::unix::fs::PermissionsExt;
    let (mut seen, mut wide) = (0, Vec::new());
    let Ok(rd) = std::fs::read_dir(dir) else {
        return (0, wide);
    };
    for e in rd.flatten() {
        let p = e.path();
        let Ok(m) = std::fs::symlink_metadata(&p) else {
            continue;
        };
        if m.is_dir() {
            let (s, w) = shared_files_not_owner_only(&p);
            seen += s;
            wide.extend(w);
        } else if p
            .file_name()
            .is_some_and(|n| n.to_string_lossy().starts_with("iox2_"))
        {
            // iceoryx2 0.10 keeps one machine-wide node counter (4 bytes) readable and
            // writable by all on purpose (`enable_global_access` in its
            // global_management_segment.rs); it holds nothing of a run. FAULTS.md says so.
            if p.to_string_lossy().ends_with(".global_mgmt") {
                continue;
            }
            seen += 1;
            if m.permissions().mode() & 0o077 != 0 {
                wide.push(format!("{} {:o}", p.display(), m.permissions().mode()));
            }
        }
    }
    (seen, wide)
}

#[test]
fn shared_memory_of_a_run_is_owner_only() {
    let dir = TempDir::fresh("modes");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &["room", "--actors", "1", "--steps", "64000", "--out", d][..],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 3, Duration::from_secs(60));
    // While the run is live: its shared memory (/dev/shm), and iceoryx2's service,
    // node and event files (/tmp/iceoryx2).
    let (shm, wide_shm) = shared_files_not_owner_only(Path::new("/dev/shm"));
    let (tmp, wide_tmp) = shared_files_not_owner_only(Path::new("/tmp/iceoryx2"));
    assert!(
        shm >= 3 && tmp >= 3,
        "the run's files: {shm} in /dev/shm, {tmp} in /tmp/iceoryx2"
    );
    assert!(
        wide_shm.is_empty() && wide_tmp.is_empty(),
        "{wide_shm:?} {wide_tmp:?}"
    );
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
}

#[test]
fn a_damaged_checkpoint_is_refused_on_resume_before_anything_starts() {
    let dir = TempDir::fresh("damaged");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &["room", "--actors", "1", "--steps", "512", "--out", d][..],
            SMALL,
        ]
        .concat(),
    );
    let (status, err, _) = finish(c, Duration::from_secs(60));
    assert!(status.success(), "{err}");
    let ckpt = dir.join("checkpoints/latest.safetensors");
    let good = std::fs::read(&ckpt).unwrap();
    let config = std::fs::read(dir.join("config.toml")).unwrap();
    let rows = std::fs::read(dir.join("metrics.csv")).unwrap();
    // Truncated, then one flipped byte in the tensor data (the checksum catches it).
    let mut flipped = good.clone();
    let last = flipped.len() - 1;
    flipped[last] ^= 0x40;
    for (bytes, says) in [
        (good[..good.len() / 2].to_vec(), "truncated or corrupt"),
        (flipped, "checksum"),
    ] {
        std::fs::write(&ckpt, &bytes).unwrap();
        let (status, err, _) = finish(
            train(&["--resume", d, "--steps", "1024"]),
            Duration::from_secs(30),
        );
        assert_eq!(status.code(), Some(2), "{err}");
        assert!(
            err.contains(&ckpt.display().to_string()),
            "names the file: {err}"
        );
        assert!(err.contains(says), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
        assert!(!err.contains("namespace"), "no process started: {err}");
        // Nothing of the run was touched.
        assert_eq!(std::fs::read(dir.join("config.toml")).unwrap(), config);
        assert_eq!(std::fs::read(dir.join("metrics.csv")).unwrap(), rows);
    }
}

/// The action mask is recorded in the checkpoint: a config.toml edited to the other
/// setting is refused on --resume before anything starts (exit 2, one sentence); so
/// are flags that would change the policy's settings (the view, the seed).
#[test]
fn a_checkpoint_is_never_continued_with_the_other_action_mask() {
    let dir = TempDir::fresh("mask-flip");
    let d = dir.to_str().unwrap();
    let (s, err, _) = finish(
        train(
            &[
                &["room", "--actors", "1", "--steps", "256", "--out", d][..],
                SMALL,
            ]
            .concat(),
        ),
        Duration::from_secs(120),
    );
    assert!(s.success(), "{err}");
    // Flags that would change what the policy learns are refused on --resume, named.
    let (s, err, _) = finish(
        train(&["--resume", d, "--view", "crop:2", "--seed", "3"]),
        Duration::from_secs(60),
    );
    assert_eq!(s.code(), Some(2), "{err}");
    assert!(
        err.contains("--view, --seed cannot be changed (start a new run instead)"),
        "{err}"
    );
    let (s, err, _) = finish(train(&["--resume", d, "--paper"]), Duration::from_secs(60));
    assert_eq!(s.code(), Some(2), "{err}");
    assert!(
        err.contains("--paper cannot be changed (start a new run instead)"),
        "{err}"
    );
    let cfg = dir.join("config.toml");
    let text = std::fs::read_to_string(&cfg).unwrap();
    assert!(text.contains("action_mask = true"), "{text}");
    assert!(text.contains("view = \"full\""), "{text}");
    std::fs::write(
        &cfg,
        text.replace("action_mask = true", "action_mask = false"),
    )
    .unwrap();
    let (s, err, _) = finish(
        train(&["--resume", d, "--steps", "512"]),
        Duration::from_secs(60),
    );
    assert_eq!(s.code(), Some(2), "{err}");
    assert!(err.contains("trained with action_mask = true"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
}

#[test]
fn a_torn_metrics_row_is_dropped_on_resume() {
    let dir = TempDir::fresh("torn");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &["room", "--actors", "1", "--steps", "1024", "--out", d][..],
            SMALL,
        ]
        .concat(),
    );
    let (status, err, _) = finish(c, Duration::from_secs(60));
    assert!(status.success(), "{err}");
    // A crash in the middle of writing row 9.
    let path = dir.join("metrics.csv");
    let mut text = std::fs::read_to_string(&path).unwrap();
    text.push_str("9,1152,4,0.");
    std::fs::write(&path, text).unwrap();
    let (status, err, _) = finish(
        train(&["--resume", d, "--steps", "2048"]),
        Duration::from_secs(60),
    );
    assert!(status.success(), "{err}");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.lines().skip(1).all(|l| MetricsRow::parse(l).is_some()),
        "{text}"
    );
    assert_contiguous(&read_metrics(&path).unwrap(), 16, 128);
}

/// Socket inodes of a process's open files.
fn socket_inodes(pid: u32) -> Vec<String> {
    let mut v = Vec::new();
    if let Ok(rd) = std::fs::read_dir(format!("/proc/{pid}/fd")) {
        for e in rd.flatten() {
            if let Ok(t) = std::fs::read_link(e.path()) {
                let t = t.to_string_lossy().to_string();
                if let Some(i) = t.strip_prefix("socket:[") {
                    v.push(i.trim_end_matches(']').to_string());
                }
            }
        }
    }
    v
}

#[test]
fn nothing_of_a_run_uses_a_network_socket() {
    let dir = TempDir::fresh("net");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &["room", "--actors", "2", "--steps", "128000", "--out", d][..],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 3, Duration::from_secs(60));
    let mut pids = children_with(c.id(), "fulcrum");
    pids.push(c.id());
    assert!(
        pids.len() >= 4,
        "supervisor, service, learner, actors: {pids:?}"
    );
    let ours: Vec<String> = pids.iter().flat_map(|&p| socket_inodes(p)).collect();
    // Every TCP and UDP socket of the machine, v4 and v6: none is the run's.
    for table in ["tcp", "tcp6", "udp", "udp6"] {
        let text = std::fs::read_to_string(format!("/proc/net/{table}")).unwrap_or_default();
        for line in text.lines().skip(1) {
            let inode = line.split_whitespace().nth(9).unwrap_or("");
            assert!(
                !ours.iter().any(|i| i == inode),
                "a {table} socket of the run: {line}"
            );
        }
    }
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
}

#[test]
fn chunks_of_another_run_or_world_are_refused_and_counted() {
    use fulcrum_contracts::traj::{self, ChunkHeader, ChunkLayout, TrainNames};
    fulcrum_empowerment::service::quiet_ipc_logs();
    let dir = TempDir::fresh("foreign");
    let d = dir.to_str().unwrap();
    let c = train(
        &[
            &["room", "--actors", "1", "--steps", "64000", "--out", d][..],
            &["--no-empowerment"],
            SMALL,
        ]
        .concat(),
    );
    wait_rows(&dir, 3, Duration::from_secs(60));
    // The run's services are named after its namespace (the learner's --namespace).
    // Publish well-formed chunks into the run's own trajectory service that claim
    // another run, and another world.
    let ns = {
        let t0 = Instant::now();
        loop {
            let found = pids_with(&["__learner", d]);
            if let Some(&p) = found.first() {
                let cmd = std::fs::read(format!("/proc/{p}/cmdline")).unwrap();
                let args: Vec<String> = String::from_utf8_lossy(&cmd)
                    .split('\0')
                    .map(str::to_string)
                    .collect();
                let i = args.iter().position(|a| a == "--namespace").unwrap();
                break args[i + 1].clone();
            }
            assert!(t0.elapsed() < Duration::from_secs(10), "no learner");
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    let w = fulcrum_world::load_world("room").unwrap();
    let spec = w.obs_spec();
    let layout = ChunkLayout {
        envs: 4,
        steps: 32,
        cells: spec.cells(),
        flags: spec.flags,
    };
    let node = NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .unwrap();
    let names = TrainNames::new(&ns);
    let svc = traj::trajectory_service(&node, &names).unwrap();
    let publisher = svc
        .publisher_builder()
        .initial_max_slice_len(layout.bytes())
        .create()
        .unwrap();
    let good = ChunkHeader {
        run: traj::run_tag(&ns),
        world_hash: w.content_hash(),
        envs: 4,
        steps: 32,
        cells: spec.cells() as u32,
        flags: spec.flags as u32,
        actions: w.num_actions() as u32,
        len: layout.bytes() as u64,
        ..ChunkHeader::default()
    };
    for h in [
        ChunkHeader {
            run: good.run ^ 1,
            ..good
        },
        ChunkHeader {
            world_hash: good.world_hash ^ 1,
            ..good
        },
    ] {
        let mut s = publisher.loan_slice(layout.bytes()).unwrap();
        s.payload_mut().fill(0);
        *s.user_header_mut() = h;
        s.send().unwrap();
    }
    let (status, err, _) = finish(c, Duration::from_secs(120));
    assert!(status.success(), "{err}");
    let rows = read_metrics(&dir.join("metrics.csv")).unwrap();
    assert_contiguous(&rows, 500, 128);
    assert_eq!(
        rows.last().unwrap().dropped_chunks,
        2,
        "both foreign chunks refused"
    );
}
