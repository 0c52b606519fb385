//! An experiment directory belongs to one invocation, and an experiment never starts
//! or clears a run directory that another invocation holds.

use std::path::Path;
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use fulcrum_learner::metrics::read_metrics;

use crate::util::{fulcrum, signal, wait_until, TempDir};

/// One seed of the baseline, long enough to be running when the second command comes.
fn experiment(dir: &Path) -> Child {
    fulcrum()
        .args([
            "experiment",
            "room",
            "--seeds",
            "1",
            "--arms",
            "baseline",
            "--parallel",
            "1",
            "--envs-per-actor",
            "4",
            "--steps",
            "1966080",
        ])
        .arg("--out")
        .arg(dir)
        .args([
            "--",
            "--steps-per-chunk",
            "32",
            "--checkpoint-every",
            "100000",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn rows(run: &Path) -> usize {
    read_metrics(&run.join("metrics.csv"))
        .map(|r| r.len())
        .unwrap_or(0)
}

/// Waits for `c` to exit (at most `limit`); its exit code and stderr.
fn exit_of(c: Child, limit: Duration) -> (Option<i32>, String) {
    let t0 = Instant::now();
    let mut c = c;
    loop {
        if c.try_wait().unwrap().is_some() {
            let out = c.wait_with_output().unwrap();
            return (
                out.status.code(),
                String::from_utf8_lossy(&out.stderr).into_owned(),
            );
        }
        assert!(t0.elapsed() < limit, "no exit in {limit:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn refused_naming(err: &str, pid: u32, dir: &Path) {
    assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
    assert!(
        err.contains(&format!("pid {pid}")),
        "names the holder: {err}"
    );
    assert!(
        err.contains(&dir.display().to_string()) && err.contains("in use"),
        "{err}"
    );
}

#[test]
fn a_second_experiment_on_one_directory_is_refused_naming_the_first() {
    let dir = TempDir::fresh("exp-lock");
    let run = dir.join("runs/baseline/seed-1");
    let first = experiment(&dir);
    let holder = first.id();
    wait_until(Duration::from_secs(60), "the first run's rows", || {
        rows(&run) >= 3
    });
    let spec = std::fs::read(dir.join("experiment.toml")).unwrap();
    let t0 = Instant::now();
    let (code, err) = exit_of(experiment(&dir), Duration::from_secs(30));
    assert_eq!(code, Some(2), "{err}");
    refused_naming(&err, holder, &dir);
    assert!(t0.elapsed() < Duration::from_secs(10), "refused at once");
    // Nothing of the first was touched: its spec, its run going on.
    assert_eq!(std::fs::read(dir.join("experiment.toml")).unwrap(), spec);
    let n = rows(&run);
    wait_until(Duration::from_secs(30), "the first run goes on", || {
        rows(&run) > n
    });
    signal(holder, "-INT");
    let (code, err) = exit_of(first, Duration::from_secs(30));
    assert_eq!(code, Some(130), "{err}");
}

#[test]
fn an_experiment_never_clears_a_run_that_another_invocation_trains() {
    let dir = TempDir::fresh("exp-held-run");
    let run = dir.join("runs/baseline/seed-1");
    // The experiment's first run directory, trained by hand: no checkpoint yet, so the
    // experiment would take it for a run to start over and clear it.
    let by_hand = fulcrum()
        .args([
            "train",
            "room",
            "--actors",
            "1",
            "--envs-per-actor",
            "4",
            "--steps-per-chunk",
            "32",
            "--steps",
            "1280000",
            "--checkpoint-every",
            "100000",
        ])
        .arg("--out")
        .arg(&run)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let holder = by_hand.id();
    wait_until(Duration::from_secs(60), "the hand run's rows", || {
        rows(&run) >= 3
    });
    let (code, err) = exit_of(experiment(&dir), Duration::from_secs(30));
    assert_eq!(code, Some(2), "{err}");
    refused_naming(&err, holder, &run);
    // The run directory is whole and its run goes on.
    assert!(run.join("config.toml").exists());
    let n = rows(&run);
    wait_until(Duration::from_secs(30), "the hand run goes on", || {
        rows(&run) > n
    });
    signal(holder, "-INT");
    let (code, err) = exit_of(by_hand, Duration::from_secs(30));
    assert_eq!(code, Some(130), "{err}");
    let r = read_metrics(&run.join("metrics.csv")).unwrap();
    assert!(r.iter().enumerate().all(|(i, r)| r.update == i as u64 + 1));
}
