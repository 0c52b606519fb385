//! The Slurm launcher's parts that need no Slurm: the array script `--dry-run` writes,
//! every array task run by hand exactly as the script runs it (one stopped by SIGTERM,
//! as Slurm stops a preempted task, then killed outright, each time run again), and
//! `--collect`, whose summary must equal a local experiment's with the same seeds, bit
//! for bit. `tests/slurm` runs the same through a real Slurm.

use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Child, Output, Stdio};
use std::time::Duration;

use fulcrum_learner::metrics::read_metrics;

use crate::util::{deterministic, fulcrum, same_bits, signal, wait_until, weights, TempDir};

/// The experiment both sides run: exp1-tree, two arms, two seeds, 200 updates each.
pub const EXPERIMENT: &[&str] = &[
    "experiment",
    "exp1-tree",
    "--seeds",
    "2",
    "--steps",
    "204800",
    "--arms",
    "baseline,empowerment",
];

/// The pairs of [`EXPERIMENT`].
pub const PAIRS: [(&str, u64); 4] = [
    ("baseline", 1),
    ("baseline", 2),
    ("empowerment", 1),
    ("empowerment", 2),
];

/// Every pair of two experiment directories trained the same, bit for bit: metrics
/// (but the timings), final weights, and the summary.
pub fn same_experiment(a: &Path, b: &Path) {
    for (arm, seed) in PAIRS {
        let run = format!("runs/{arm}/seed-{seed}");
        let rows = |d: &Path| -> Vec<String> {
            read_metrics(&d.join(&run).join("metrics.csv"))
                .unwrap()
                .iter()
                .map(deterministic)
                .collect()
        };
        let (ra, rb) = (rows(a), rows(b));
        assert_eq!(ra.len(), 200, "{run}");
        assert_eq!(ra, rb, "{run}: the metrics differ");
        assert!(
            same_bits(
                &weights(&a.join(&run), "exp1-tree"),
                &weights(&b.join(&run), "exp1-tree")
            ),
            "{run}: the weights differ"
        );
    }
    let summary = |d: &Path| std::fs::read_to_string(d.join("summary.json")).unwrap();
    assert_eq!(summary(a), summary(b), "the summaries differ");
}

/// The (arm, seed) pairs an array script's ARMS and SEEDS lines give, in task order.
pub fn script_pairs(script: &str) -> Vec<(String, u64)> {
    let list = |name: &str| -> Vec<String> {
        let line = script
            .lines()
            .find_map(|l| l.strip_prefix(&format!("{name}=(")))
            .unwrap_or_else(|| panic!("no {name}=( line in\n{script}"));
        line.trim_end_matches(')')
            .split_whitespace()
            .map(|w| w.trim_matches('\'').to_string())
            .collect()
    };
    list("ARMS")
        .into_iter()
        .zip(list("SEEDS").iter().map(|s| s.parse().unwrap()))
        .collect()
}

/// `fulcrum experiment --task DIR --arm A --seed K`, in a process group of its own.
fn task(dir: &Path, arm: &str, seed: u64) -> Child {
    fulcrum()
        .args(["experiment", "--task"])
        .arg(dir)
        .args(["--arm", arm, "--seed", &seed.to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0)
        .spawn()
        .unwrap()
}

fn finish(c: Child) -> Output {
    c.wait_with_output().unwrap()
}

/// `--collect` on `dir` (every run finished) prints the table a local experiment with
/// the same seeds prints (run into `local`), and every run is the same bit for bit.
pub fn collected_equals_local(dir: &Path, local: &Path) {
    let c = collect(dir);
    let err = String::from_utf8_lossy(&c.stderr);
    assert!(c.status.success(), "{err}");
    assert!(err.contains("4 of 4 runs finished"), "{err}");
    prints_as_local(EXPERIMENT, local, &c);
    same_experiment(dir, local);
}

/// The experiment `args` run locally in `local` prints what `--collect` printed (`c`).
fn prints_as_local(args: &[&str], local: &Path, c: &Output) {
    let o = fulcrum()
        .args(args)
        .arg("--out")
        .arg(local)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        String::from_utf8_lossy(&c.stdout),
        String::from_utf8_lossy(&o.stdout)
    );
}

/// The array script an experiment launched on Slurm wrote into `dir/slurm/`.
pub fn array_script(dir: &Path) -> std::path::PathBuf {
    std::fs::read_dir(dir.join("slurm"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|e| e == "sbatch"))
        .expect("the array script")
}

/// The experiment `args` launched on Slurm into `dir` with `--dry-run`.
fn dry_run(args: &[&str], dir: &Path) -> Output {
    fulcrum()
        .args(args)
        .args(["--launcher", "slurm", "--dry-run", "--out"])
        .arg(dir)
        .output()
        .unwrap()
}

pub fn collect(dir: &Path) -> Output {
    fulcrum()
        .args(["experiment", "--collect"])
        .arg(dir)
        .output()
        .unwrap()
}

/// Waits until the run has a checkpoint and has gone past it, short of its budget.
fn wait_mid_run(run: &Path) {
    wait_until(Duration::from_secs(120), "a checkpoint mid-run", || {
        run.join("checkpoints/latest.safetensors").exists()
            && read_metrics(&run.join("metrics.csv")).is_ok_and(|r| r.len() > 10)
    });
}

#[test]
fn array_tasks_run_by_hand_and_collected_equal_the_local_experiment() {
    let dir = TempDir::fresh("tasks");
    let local = TempDir::fresh("tasks-local");

    // The script, written and printed, nothing submitted and nothing trained.
    let out = fulcrum()
        .args(EXPERIMENT)
        .args([
            "--launcher",
            "slurm",
            "--dry-run",
            "--slurm-partition",
            "short",
            "--slurm-time",
            "30:00",
            "--slurm-mem",
            "2G",
            "--sbatch=--account=rl",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let script = String::from_utf8_lossy(&out.stdout).to_string();
    for line in [
        "#SBATCH --array=0-3",
        "#SBATCH --requeue",
        "#SBATCH --cpus-per-task=1",
        "#SBATCH --partition=short",
        "#SBATCH --time=30:00",
        "#SBATCH --mem=2G",
        "#SBATCH --account=rl",
    ] {
        assert!(
            script.lines().any(|l| l == line),
            "no '{line}' in\n{script}"
        );
    }
    let mut pairs = script_pairs(&script);
    pairs.sort();
    let want: Vec<(String, u64)> = PAIRS.iter().map(|(a, s)| (a.to_string(), *s)).collect();
    assert_eq!(pairs, want);
    let files: Vec<_> = std::fs::read_dir(dir.join("slurm"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    assert_eq!(std::fs::read_to_string(&files[0]).unwrap(), script);
    assert!(!dir.join("runs").exists(), "a dry run trained nothing");

    // Before any task: every pair is named missing, exit 1.
    let c = collect(&dir);
    let err = String::from_utf8_lossy(&c.stderr);
    assert_eq!(c.status.code(), Some(1), "{err}");
    assert_eq!(err.matches("missing: ").count(), 4, "{err}");

    // baseline/seed-1: stopped by SIGTERM mid-run (Slurm's preemption signal): the run
    // checkpoints and stops, the task records the failure and exits 1.
    let run = dir.join("runs/baseline/seed-1");
    let t = task(&dir, "baseline", 1);
    wait_mid_run(&run);
    signal(t.id(), "-TERM");
    let o = finish(t);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("was stopped"), "{err}");
    let c = collect(&dir);
    let err = String::from_utf8_lossy(&c.stderr);
    assert!(
        err.contains("failed: baseline/seed-1: ") && err.contains("was stopped"),
        "{err}"
    );
    assert!(err.contains("missing: empowerment/seed-2"), "{err}");

    // Run again, then killed outright with everything it started (as Slurm kills a
    // task's processes): nothing is recorded, the checkpoint stays.
    let t = task(&dir, "baseline", 1);
    let before = read_metrics(&run.join("metrics.csv")).unwrap().len();
    wait_until(Duration::from_secs(120), "progress after resuming", || {
        read_metrics(&run.join("metrics.csv")).is_ok_and(|r| r.len() > before + 10)
    });
    // SAFETY: kill(2) on the task's process group (its pid: process_group(0)).
    unsafe {
        libc::kill(-(t.id() as libc::pid_t), libc::SIGKILL);
    }
    let o = finish(t);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("resuming baseline/seed-1"), "{err}");
    let rows = read_metrics(&run.join("metrics.csv")).unwrap();
    assert!(
        rows.len() < 200,
        "killed before its budget: {} rows",
        rows.len()
    );

    // Every task as the array would run it; the killed one continues.
    for (arm, seed) in PAIRS {
        let o = finish(task(&dir, arm, seed));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{arm}/{seed}: {err}");
        if (arm, seed) == ("baseline", 1) {
            assert!(err.contains("resuming baseline/seed-1"), "{err}");
        }
    }
    // A finished pair's task does nothing.
    let o = finish(task(&dir, "empowerment", 2));
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("had finished"));
    assert!(!dir.join("slurm/status/baseline-seed-1").exists());

    collected_equals_local(&dir, &local);
}

#[test]
fn bad_task_and_collect_requests_are_refused_in_one_sentence() {
    let dir = TempDir::fresh("tasks-bad");
    let out = dry_run(EXPERIMENT, &dir);
    assert!(out.status.success());
    let missing = dir.join("nowhere");
    let d = dir.to_str().unwrap();
    let m = missing.to_str().unwrap();
    for (args, says) in [
        (
            vec!["experiment", "--task", d, "--arm", "nope", "--seed", "1"],
            "has no arm 'nope' (its arms: baseline, empowerment)",
        ),
        (
            vec![
                "experiment",
                "--task",
                d,
                "--arm",
                "baseline",
                "--seed",
                "3",
            ],
            "has seeds 1 to 2, not 3",
        ),
        (
            vec![
                "experiment",
                "--task",
                m,
                "--arm",
                "baseline",
                "--seed",
                "1",
            ],
            "is not an experiment directory",
        ),
        (
            vec!["experiment", "--collect", m],
            "is not an experiment directory",
        ),
        (
            vec!["experiment", "room", "--dry-run"],
            "--dry-run goes with --launcher slurm",
        ),
        (
            vec!["experiment", "room", "--slurm-partition", "x"],
            "go with --launcher slurm",
        ),
        (
            // Refused before the set's files are written (`missing` stays absent).
            vec![
                "experiment",
                "--worlds",
                "gen:2",
                "--launcher",
                "slurm",
                "--dry-run",
                "--slurm-cpus",
                "0",
                "--out",
                m,
            ],
            "--slurm-cpus must be at least 1",
        ),
        (
            vec![
                "experiment",
                "room",
                "--launcher",
                "slurm",
                "--dry-run",
                "--sbatch",
                "account=rl",
            ],
            "is not an sbatch option",
        ),
        (
            vec![
                "experiment",
                "room",
                "--launcher",
                "slurm",
                "--dry-run",
                "--slurm-time",
                "1 hour",
            ],
            "is not a Slurm value",
        ),
    ] {
        let out = fulcrum().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
    }
    assert!(!missing.exists());
    assert!(!dir.join("runs").exists());
}

/// A set of generated worlds launched on Slurm: one array over every (world, arm, seed)
/// triple, its script run task by task by `bash` as Slurm runs it (with
/// `SLURM_ARRAY_TASK_ID`), then `--collect` on the set's directory: the pooled table and
/// `summary.json` equal those of the same set run locally, and a task missing is named
/// with its world.
#[test]
fn a_set_of_worlds_on_slurm_collects_to_the_local_set() {
    let dir = TempDir::fresh("set-slurm");
    let local = TempDir::fresh("set-local");
    let out = dry_run(SET, &dir);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let script = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        script.lines().any(|l| l == "#SBATCH --array=0-3"),
        "{script}"
    );
    // Two worlds x two arms: each world's experiment directory twice.
    let dirs = script
        .lines()
        .find_map(|l| l.strip_prefix("DIRS=("))
        .unwrap_or_else(|| panic!("no DIRS=( line in\n{script}"));
    let worlds = ["gen-12x8-t3-o2-s1", "gen-12x8-t3-o2-s2"];
    for w in worlds {
        assert_eq!(dirs.matches(&format!("/{w}'")).count(), 2, "{dirs}");
    }
    let path = array_script(&dir);
    // Where the script sends Slurm's output (a task whose output cannot open fails).
    assert!(dir.join("logs").is_dir());
    let run_task = |i: usize| {
        let o = std::process::Command::new("bash")
            .arg(&path)
            .env("SLURM_ARRAY_TASK_ID", i.to_string())
            .env("PATH", std::env::var("PATH").unwrap_or_default())
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "task {i}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    };
    for i in 0..3 {
        run_task(i);
    }
    // One task still to run: named with its world, exit 1.
    let c = collect(&dir);
    let err = String::from_utf8_lossy(&c.stderr);
    assert_eq!(c.status.code(), Some(1), "{err}");
    assert!(
        err.contains("missing: gen-12x8-t3-o2-s2/horizon-potential/seed-1"),
        "{err}"
    );
    run_task(3);
    let c = collect(&dir);
    let err = String::from_utf8_lossy(&c.stderr);
    assert!(c.status.success(), "{err}");
    assert!(err.contains("4 of 4 runs finished"), "{err}");

    set_collected_equals_local(&dir, &local, &c);
}

/// A set of two generated worlds, two arms, one seed, 20 updates each.
pub const SET: &[&str] = &[
    "experiment",
    "--worlds",
    "gen:2",
    "--seeds",
    "1",
    "--arms",
    "baseline,horizon-potential",
    "--steps",
    "20480",
];

/// `--collect` of the set in `dir` (its output `c`) equals [`SET`] run locally in
/// `local`: the printed table and `summary.json`.
pub fn set_collected_equals_local(dir: &Path, local: &Path, c: &Output) {
    prints_as_local(SET, local, c);
    let json = |d: &Path| std::fs::read_to_string(d.join("summary.json")).unwrap();
    assert_eq!(json(dir), json(local));
    assert!(json(dir).contains("\"gen-12x8-t3-o2-s2\""), "{}", json(dir));
}
