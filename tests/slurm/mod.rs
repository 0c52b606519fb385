//! `fulcrum experiment --launcher slurm` against a real Slurm (feature `slurm`): a
//! single-node cluster (slurmctld, slurmd and munge from Debian's packages) started by
//! the test, as root, in a directory of its own (`scripts/slurm-node.sh`). The array
//! runs; one task is killed with `scancel --signal=KILL` mid-run and requeued, and
//! finishes from its checkpoint; `--collect` equals a local experiment with the same
//! seeds, bit for bit; a set of generated worlds runs as one array and collects to
//! the local set. Where Slurm is not installed or the test is not root, it fails
//! and says so (CI installs the packages and runs it as root).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

use fulcrum_learner::metrics::read_metrics;

use crate::experiment::tasks::{
    array_script, collect, collected_equals_local, script_pairs, set_collected_equals_local,
    EXPERIMENT, SET,
};
use crate::util::{free_port, fulcrum, pids_with, wait_until, TempDir};

/// A running single-node cluster; stopped when dropped.
struct Node {
    dir: TempDir,
    conf: PathBuf,
}

fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/slurm-node.sh")
}

impl Node {
    fn start() -> Node {
        let dir = TempDir::fresh("slurm-node");
        let out = Command::new(script())
            .arg("start")
            .arg(&*dir)
            .args([free_port().to_string(), free_port().to_string()])
            .output()
            .expect("scripts/slurm-node.sh runs");
        assert!(
            out.status.success(),
            "cannot start a Slurm node for this test: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let conf = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
        Node { dir, conf }
    }

    /// A Slurm client command against this node.
    fn run(&self, cmd: &str, args: &[&str]) -> Output {
        let out = Command::new(cmd)
            .env("SLURM_CONF", &self.conf)
            .args(args)
            .output()
            .unwrap_or_else(|e| panic!("{cmd}: {e}"));
        assert!(
            out.status.success(),
            "{cmd} {args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        out
    }

    /// The experiment `args` launched on this node into `dir` as an array of `tasks`
    /// tasks; its job id.
    fn submit(&self, args: &[&str], dir: &Path, tasks: usize) -> String {
        let out = fulcrum()
            .env("SLURM_CONF", &self.conf)
            .args(args)
            .args(["--launcher", "slurm", "--slurm-time", "20:00", "--out"])
            .arg(dir)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert!(
            err.contains(&format!("submitted {tasks} array tasks")),
            "{err}"
        );
        let job = String::from_utf8_lossy(&out.stdout).trim().to_string();
        assert!(
            !job.is_empty() && job.chars().all(|c| c.is_ascii_digit()),
            "sbatch's job id: '{job}'; {err}"
        );
        job
    }

    /// The tasks of `job` that are still in the queue, as `<id> <state>` lines.
    fn queued(&self, job: &str) -> String {
        let out = self.run("squeue", &["-h", "-j", job, "-o", "%i %T"]);
        String::from_utf8_lossy(&out.stdout).trim().to_string()
    }
}

impl Drop for Node {
    fn drop(&mut self) {
        let _ = Command::new("scancel")
            .env("SLURM_CONF", &self.conf)
            .args(["-u", "root"])
            .status();
        let _ = Command::new(script()).arg("stop").arg(&*self.dir).status();
    }
}

#[test]
fn an_array_survives_a_killed_task_and_collects_to_the_local_result() {
    let t0 = std::time::Instant::now();
    let node = Node::start();
    let dir = TempDir::fresh("slurm-exp");
    let local = TempDir::fresh("slurm-local");

    let job = node.submit(EXPERIMENT, &dir, 4);
    let script_file = array_script(&dir);
    let pairs = script_pairs(&std::fs::read_to_string(&script_file).unwrap());
    assert_eq!(pairs.len(), 4);
    let i = pairs
        .iter()
        .position(|(a, s)| a == "baseline" && *s == 1)
        .unwrap();
    let task = format!("{job}_{i}");

    // Killed mid-run, past a checkpoint, with everything it started.
    let run = dir.join("runs/baseline/seed-1");
    wait_until(Duration::from_secs(300), "task 0 mid-run", || {
        run.join("checkpoints/latest.safetensors").exists()
            && read_metrics(&run.join("metrics.csv")).is_ok_and(|r| r.len() > 10)
    });
    eprintln!("{:.1?}: killing task {task}", t0.elapsed());
    node.run("scancel", &["--signal=KILL", "--full", &task]);
    wait_until(Duration::from_secs(60), "the killed task's end", || {
        !node.queued(&job).contains(&format!("{task} RUNNING"))
            && pids_with(&[run.to_str().unwrap()]).is_empty()
    });
    let rows = read_metrics(&run.join("metrics.csv")).unwrap();
    assert!(
        rows.len() < 200,
        "killed before its budget: {} rows",
        rows.len()
    );

    eprintln!("{:.1?}: requeueing task {task}", t0.elapsed());
    // Requeued, as after a preemption (the node's requeue delay is 10 s).
    node.run("scontrol", &["requeue", &task]);
    wait_until(Duration::from_secs(600), "every task's end", || {
        node.queued(&job).is_empty()
    });
    eprintln!("{:.1?}: every task ended", t0.elapsed());
    let log = std::fs::read_to_string(dir.join(format!("logs/slurm-{task}.out"))).unwrap();
    assert!(
        log.contains("starting baseline/seed-1") && log.contains("resuming baseline/seed-1"),
        "{log}"
    );
    assert!(log.contains("finished baseline/seed-1"), "{log}");

    collected_equals_local(&dir, &local);
}

#[test]
fn a_set_of_worlds_runs_as_one_array_and_collects_to_the_local_set() {
    let node = Node::start();
    let dir = TempDir::fresh("slurm-set");
    let local = TempDir::fresh("slurm-set-local");
    let job = node.submit(SET, &dir, 4);
    wait_until(Duration::from_secs(600), "every task's end", || {
        node.queued(&job).is_empty()
    });
    let c = collect(&dir);
    let err = String::from_utf8_lossy(&c.stderr);
    assert!(c.status.success(), "{err}");
    assert!(err.contains("4 of 4 runs finished"), "{err}");
    for i in 0..4 {
        let log = std::fs::read_to_string(dir.join(format!("logs/slurm-{job}_{i}.out")))
            .unwrap_or_else(|e| panic!("task {i}'s Slurm log: {e}"));
        assert!(log.contains("finished "), "task {i}: {log}");
    }
    set_collected_equals_local(&dir, &local, &c);
}
