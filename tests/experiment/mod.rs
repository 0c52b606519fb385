//! `fulcrum experiment`: the aggregation of finished runs against hand-counted values,
//! resuming an interrupted experiment (real `train` runs, a real SIGINT), and refusals.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use fulcrum_learner::metrics::{read_metrics, MetricsRow, METRICS_COLUMNS};

use crate::util::{fulcrum, TempDir};

mod locking;
pub mod tasks;

/// A finished run made by hand: 10 updates of 1024 steps, 10 episodes each, success
/// `f(i)` at update i, and a checkpoint file (its presence marks the run finished).
fn fake_run(dir: &Path, f: impl Fn(u64) -> f64) {
    std::fs::create_dir_all(dir.join("checkpoints")).unwrap();
    std::fs::write(dir.join("checkpoints/latest.safetensors"), b"x").unwrap();
    let mut text = METRICS_COLUMNS.join(",") + "\n";
    for i in 1..=10u64 {
        let row = MetricsRow {
            update: i,
            env_steps: 1024 * i,
            episodes: 10,
            extrinsic_return: f(i),
            success_rate: f(i),
            // Diagnostics: 10 bits per episode per update index, a pick-up from
            // update 3 on, E > 0 on a quarter of the steps.
            intrinsic_return: 10.0 * i as f64,
            pickup_rate: if i >= 3 { 1.0 } else { 0.0 },
            e_positive_frac: 0.25,
            ..MetricsRow::default()
        };
        text += &(row.csv() + "\n");
    }
    std::fs::write(dir.join("metrics.csv"), text).unwrap();
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * (1.0 + b.abs())
}

#[test]
fn finished_runs_are_aggregated_into_hand_counted_figures() {
    let dir = TempDir::fresh("aggregate");
    // baseline: seed 1 = i/10 (0.9 at update 9), seed 2 = min(1, 2i/10) (at update 5),
    // seed 3 = 0 (never). empowerment: 1 from update 2 on, every seed.
    fake_run(&dir.join("runs/baseline/seed-1"), |i| i as f64 / 10.0);
    fake_run(&dir.join("runs/baseline/seed-2"), |i| {
        (2.0 * i as f64 / 10.0).min(1.0)
    });
    fake_run(&dir.join("runs/baseline/seed-3"), |_| 0.0);
    for s in 1..=3 {
        fake_run(&dir.join(format!("runs/empowerment/seed-{s}")), |i| {
            if i >= 2 {
                1.0
            } else {
                0.0
            }
        });
    }
    let out = fulcrum()
        .args([
            "experiment",
            "room",
            "--seeds",
            "3",
            "--steps",
            "10240",
            "--smooth",
            "1",
        ])
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("0 to run"), "nothing is rerun: {stderr}");
    let s: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("summary.json")).unwrap()).unwrap();
    let arm = |i: usize, k: &str| s["arms"][i][k].clone();
    let f = |v: &serde_json::Value| v.as_f64().unwrap();

    // Steps to 0.9: baseline 9216 and 5120 (2 of 3): mean 7168, std |9216-5120|/sqrt 2.
    assert_eq!(arm(0, "reached"), 2);
    assert!(close(f(&arm(0, "steps_to_threshold")["mean"]), 7168.0));
    assert!(close(
        f(&arm(0, "steps_to_threshold")["std"]),
        4096.0 / 2f64.sqrt()
    ));
    assert_eq!(arm(1, "reached"), 3);
    assert!(close(f(&arm(1, "steps_to_threshold")["mean"]), 2048.0));
    assert!(close(f(&arm(1, "steps_to_threshold")["std"]), 0.0));

    // Area under the success curve (the first value held back to 0, linear between
    // updates, divided by 10240): seed 1: (0.1 * 1024 + 1024 * 99 / 20) / 10240 = 0.505;
    // seed 2: (0.2 * 1024 + 1024 * 2.4 + 5 * 1024) / 10240 = 0.76; seed 3: 0.
    let auc: Vec<f64> = (0..3).map(|k| f(&arm(0, "per_seed")[k]["auc"])).collect();
    assert!(
        close(auc[0], 0.505) && close(auc[1], 0.76) && close(auc[2], 0.0),
        "{auc:?}"
    );
    // Empowerment: 0 until 1024, up to 1 at 2048, then 1: (512 + 8 * 1024) / 10240.
    assert!(close(
        f(&arm(1, "per_seed")[0]["auc"]),
        (512.0 + 8.0 * 1024.0) / 10240.0
    ));

    // The band at 5120 (update 5): baseline 0.5, 1, 0 -> mean 0.5, std 0.5.
    let k = 100; // 5120 / (10240 / 200)
    assert!(close(f(&s["grid"][k]), 5120.0));
    assert!(close(f(&arm(0, "success_mean")[k]), 0.5));
    assert!(close(f(&arm(0, "success_std")[k]), 0.5));

    // Final success (last 10 % = update 10): 1, 1, 0.
    assert!(close(f(&arm(0, "final_success")["mean"]), 2.0 / 3.0));
    // Diagnostics of update 10; the first pick-up ends update 3 (3072 steps).
    assert!(close(f(&arm(0, "final_intrinsic_return")["mean"]), 100.0));
    assert!(close(f(&arm(0, "final_pickup_rate")["mean"]), 1.0));
    assert!(close(f(&arm(0, "final_e_positive")["mean"]), 0.25));
    assert!(close(f(&arm(0, "first_pickup_step")["mean"]), 3072.0));
    assert_eq!(arm(0, "picked"), 3);

    // Welch on steps to 0.9 with the never-reached seed at the budget: baseline
    // {9216, 5120, 10240} (mean 8192, variance 7340032), empowerment {2048 x 3}
    // (variance 0): df = n - 1 = 2, t = (2048 - 8192) / sqrt(7340032 / 3), and with
    // 2 df, p = 1 - |t| / sqrt(2 + t^2).
    let w = &s["comparisons"][0]["steps_to_threshold"];
    let t = -6144.0 / (7_340_032.0f64 / 3.0).sqrt();
    assert!(close(f(&w["t"]), t));
    assert!(close(f(&w["df"]), 2.0));
    assert!(close(f(&w["p"]), 1.0 - t.abs() / (2.0 + t * t).sqrt()));

    // The table and the pictures.
    let md = std::fs::read_to_string(dir.join("summary.md")).unwrap();
    assert!(md.contains("| baseline | 3/3 | 2/3 |"), "{md}");
    for f in ["success.png", "success.svg", "return.png", "return.svg"] {
        assert!(
            dir.join("plots").join(f).metadata().unwrap().len() > 1000,
            "{f}"
        );
    }
    let svg = std::fs::read_to_string(dir.join("plots/success.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains(">baseline</text>") && svg.contains(">empowerment</text>"));
    // One band and one legend swatch per arm, as filled polygons.
    assert_eq!(svg.matches("<polygon").count(), 4);
}

fn first_line_and_status(args: &[&str], dir: &Path) -> (i32, String) {
    let out = fulcrum().args(args).arg("--out").arg(dir).output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

#[test]
fn bad_experiments_are_refused_before_any_run() {
    let dir = TempDir::fresh("bad");
    for (args, says) in [
        (
            vec!["experiment", "room", "--arms", "baseline,nope"],
            "unknown arm 'nope'",
        ),
        (vec!["experiment", "room", "--seeds", "0"], "--seeds"),
        (
            vec!["experiment", "room", "--beta", "-1"],
            "beta -1 must be",
        ),
        (
            vec!["experiment", "room", "--threshold", "1.5"],
            "--threshold",
        ),
        (
            vec!["experiment", "room", "--", "--seed", "4"],
            "may not set",
        ),
        (vec!["experiment", "no-such-world"], "no-such-world"),
        (
            vec!["experiment", "room", "--steps", "1500"],
            "not a whole number of updates",
        ),
    ] {
        let (code, err) = first_line_and_status(&args, &dir);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
        assert!(!dir.exists(), "{args:?} created {}", dir.display());
    }
}

/// Small runs of the room: 1 actor x 4 worlds x 32 steps = batch 128.
const RUN: &[&str] = &[
    "experiment",
    "room",
    "--seeds",
    "2",
    "--arms",
    "baseline",
    "--parallel",
    "1",
    "--envs-per-actor",
    "4",
    "--steps",
    "196608",
];
const TRAIN: &[&str] = &["--", "--steps-per-chunk", "32", "--checkpoint-every", "8"];

#[test]
fn an_interrupted_experiment_resumes_without_rerunning_finished_runs() {
    let dir = TempDir::fresh("resume");
    let (s1, s2) = (
        dir.join("runs/baseline/seed-1"),
        dir.join("runs/baseline/seed-2"),
    );
    let mut child = fulcrum()
        .args(RUN)
        .arg("--out")
        .arg(&dir)
        .args(TRAIN)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait for seed 1 to finish and seed 2 to have a checkpoint and some rows.
    let t0 = Instant::now();
    loop {
        let done1 = read_metrics(&s1.join("metrics.csv"))
            .map(|r| r.last().map(|r| r.env_steps) == Some(196_608))
            .unwrap_or(false);
        let rows2 = read_metrics(&s2.join("metrics.csv"))
            .map(|r| r.len())
            .unwrap_or(0);
        if done1 && rows2 >= 20 && s2.join("checkpoints/latest.safetensors").exists() {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "the experiment did not get to seed 2"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    let seed1 = std::fs::read(s1.join("metrics.csv")).unwrap();
    let seed1_time = s1
        .join("metrics.csv")
        .metadata()
        .unwrap()
        .modified()
        .unwrap();
    assert!(Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap()
        .success());
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "no stop after SIGINT"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(status.code(), Some(130));
    let rows2 = read_metrics(&s2.join("metrics.csv")).unwrap().len();
    assert!(rows2 < 1536, "seed 2 was interrupted ({rows2} rows)");

    // The same command again: seed 1 is kept as it is, seed 2 resumes.
    let out = fulcrum()
        .args(RUN)
        .arg("--out")
        .arg(&dir)
        .args(TRAIN)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("1 to run"), "{stderr}");
    assert!(stderr.contains("resuming baseline/seed-2"), "{stderr}");
    assert!(
        !stderr.contains("seed-1 ("),
        "seed 1 is not run again: {stderr}"
    );
    assert_eq!(std::fs::read(s1.join("metrics.csv")).unwrap(), seed1);
    assert_eq!(
        s1.join("metrics.csv")
            .metadata()
            .unwrap()
            .modified()
            .unwrap(),
        seed1_time
    );
    // Seed 2 has one row per update, 1..=1536, none twice.
    let rows = read_metrics(&s2.join("metrics.csv")).unwrap();
    assert_eq!(rows.len(), 1536);
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r.update, i as u64 + 1);
        assert_eq!(r.env_steps, 128 * (i as u64 + 1));
    }
    let s: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["arms"][0]["finished"], 2);
}

#[test]
fn a_beta_sweep_runs_one_empowerment_arm_per_beta() {
    let dir = TempDir::fresh("sweep");
    let out = fulcrum()
        .args(["experiment", "room", "--seeds", "1", "--arms", "baseline"])
        .args(["--beta-sweep", "0.001,0.05", "--envs-per-actor", "4"])
        .args(["--steps", "1280", "--out"])
        .arg(&dir)
        .args(["--", "--steps-per-chunk", "32"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let s: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("summary.json")).unwrap()).unwrap();
    let names: Vec<&str> = s["arms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["name"].as_str().unwrap())
        .collect();
    // The sweep's form is train's default, horizon-potential.
    assert_eq!(
        names,
        [
            "baseline",
            "horizon-potential-beta-0.001",
            "horizon-potential-beta-0.05"
        ]
    );
    // Each arm's run was trained with its own beta (the run's resolved config.toml).
    for (arm, beta, emp) in [
        ("baseline", "0.0", "false"),
        ("horizon-potential-beta-0.001", "0.001", "true"),
        ("horizon-potential-beta-0.05", "0.05", "true"),
    ] {
        let cfg =
            std::fs::read_to_string(dir.join(format!("runs/{arm}/seed-1/config.toml"))).unwrap();
        assert!(cfg.contains(&format!("beta = {beta}\n")), "{arm}: {cfg}");
        assert!(
            cfg.contains(&format!("empowerment = {emp}\n")),
            "{arm}: {cfg}"
        );
        let rows = read_metrics(&dir.join(format!("runs/{arm}/seed-1/metrics.csv"))).unwrap();
        assert_eq!(rows.last().unwrap().env_steps, 1280);
    }
}

/// A tiny experiment over two generated worlds: 1 actor x 4 worlds x 32 steps, 10
/// updates a run.
const SET: &[&str] = &[
    "experiment",
    "--worlds",
    "gen:2",
    "--seeds",
    "2",
    "--arms",
    "baseline,additive",
    "--envs-per-actor",
    "4",
    "--steps",
    "1280",
];

#[test]
fn a_set_of_generated_worlds_is_run_per_world_and_pooled() {
    let dir = TempDir::fresh("set");
    let run = || {
        fulcrum()
            .args(SET)
            .arg("--out")
            .arg(&dir)
            .args(["--", "--steps-per-chunk", "32"])
            .output()
            .unwrap()
    };
    let out = run();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    // gen:2 is seeds 1 and 2 of `world generate` (both solvable).
    let names = ["gen-12x8-t3-o2-s1", "gen-12x8-t3-o2-s2"];
    let pooled: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("summary.json")).unwrap()).unwrap();
    let mut solved = [0u64; 2];
    for name in names {
        assert!(dir.join("worlds").join(format!("{name}.toml")).exists());
        let s: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join(name).join("summary.json")).unwrap())
                .unwrap();
        for (k, slot) in solved.iter_mut().enumerate() {
            *slot += s["arms"][k]["reached"].as_u64().unwrap();
            assert_eq!(s["arms"][k]["finished"], 2);
        }
        // Each run trained that world, from its file in the set's directory.
        let cfg = std::fs::read_to_string(dir.join(name).join("runs/additive/seed-1/config.toml"))
            .unwrap();
        assert!(cfg.contains(&format!("world_name = \"{name}\"")), "{cfg}");
        assert!(cfg.contains("intrinsic = \"additive\""), "{cfg}");
    }
    for (k, arm) in ["baseline", "additive"].iter().enumerate() {
        let a = &pooled["arms"][k];
        assert_eq!(a["name"], *arm);
        assert_eq!(a["pairs"], 4);
        assert_eq!(a["solved"].as_u64().unwrap(), solved[k]);
        let pairs: Vec<(String, u64)> = a["per_pair"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| {
                (
                    p["world"].as_str().unwrap().to_string(),
                    p["seed"].as_u64().unwrap(),
                )
            })
            .collect();
        assert_eq!(
            pairs,
            [(names[0], 1), (names[0], 2), (names[1], 1), (names[1], 2)]
                .map(|(w, s)| (w.to_string(), s))
        );
    }
    assert_eq!(pooled["comparisons"][0]["arm"], "additive");
    let md = std::fs::read_to_string(dir.join("summary.md")).unwrap();
    assert!(md.contains("| gen-12x8-t3-o2-s1 ("), "{md}");

    // The same command resumes: nothing runs again.
    let out = run();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stderr.matches("0 to run").count(), 2, "{stderr}");

    // Another set under the same directory is refused, naming the one there.
    let out = fulcrum()
        .args([
            "experiment",
            "--worlds",
            "gen:2:seed=5",
            "--arms",
            "baseline",
        ])
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("a different set needs a directory of its own"),
        "{stderr}"
    );
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
}

#[test]
fn bad_sets_are_refused_in_one_sentence() {
    let dir = TempDir::fresh("bad-set");
    for (args, says) in [
        (
            vec!["experiment", "--worlds", "gen:0"],
            "--worlds 'gen:0': the count",
        ),
        (
            vec!["experiment", "--worlds", "exp1-tree"],
            "does not start with gen:",
        ),
        (
            vec!["experiment", "--worlds", "gen:3:hue=2"],
            "unknown key 'hue'",
        ),
        (
            vec![
                "experiment",
                "--worlds",
                "gen:2:width=4,height=4,tools=0,objects=1",
            ],
            "fewer than the 2 asked for",
        ),
    ] {
        let (code, err) = first_line_and_status(&args, &dir);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
        assert!(!dir.exists(), "{args:?} created {}", dir.display());
    }
    let (code, err) = first_line_and_status(&["experiment", "room", "--worlds", "gen:2"], &dir);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("cannot be used with"), "{err}");
}

#[test]
fn an_experiment_made_when_additive_was_the_default_resumes_as_additive() {
    let dir = TempDir::fresh("legacy");
    let cmd = || {
        let mut c = fulcrum();
        c.args(["experiment", "room", "--seeds", "1", "--arms", "additive"])
            .args(["--envs-per-actor", "4", "--steps", "1280", "--out"])
            .arg(&dir)
            .args(["--", "--steps-per-chunk", "32"]);
        c
    };
    let out = cmd().output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The file as the version before wrote it: no version, and the additive arm naming
    // no form (train's default then).
    let spec = dir.join("experiment.toml");
    let text = std::fs::read_to_string(&spec).unwrap();
    assert!(text.contains("version = 2\n"), "{text}");
    let legacy = text
        .replace("version = 2\n", "")
        .replace("\"--intrinsic\",\n    \"additive\",\n", "")
        .replace("args = [\"--intrinsic\", \"additive\"]", "args = []");
    assert!(!legacy.contains("--intrinsic"), "{legacy}");
    std::fs::write(&spec, legacy).unwrap();
    let out = cmd().output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("0 to run"), "{stderr}");
    let now = std::fs::read_to_string(&spec).unwrap();
    assert!(
        now.contains("version = 2\n") && now.contains("additive"),
        "{now}"
    );
    // The default arm, `empowerment`, is train's default form now, not the additive one.
    let fresh = TempDir::fresh("legacy-default");
    let out = fulcrum()
        .args([
            "experiment",
            "room",
            "--seeds",
            "1",
            "--arms",
            "empowerment",
        ])
        .args(["--envs-per-actor", "4", "--steps", "1280", "--out"])
        .arg(&*fresh)
        .args(["--", "--steps-per-chunk", "32"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let cfg = std::fs::read_to_string(fresh.join("runs/empowerment/seed-1/config.toml")).unwrap();
    assert!(cfg.contains("intrinsic = \"horizon-potential\""), "{cfg}");
}
