//! Experiments on a Slurm cluster: the pairs still to run as one job array, each task a
//! pair trained exactly as a local experiment trains it, and the summary collected
//! once the tasks have ended.
//!
//! ```text
//! DIR/experiment.toml                 as for a local experiment (the same checks)
//! DIR/slurm/array-<time>.sbatch       the array script: task i = (ARMS[i], SEEDS[i])
//!                                     of the experiment in DIRS[i] (DIR, or for a set
//!                                     each world's directory under it)
//! DIR/slurm/status/<arm>-seed-<k>     a task's failure (exit status, time); removed
//!                                     when the pair finishes
//! DIR/logs/<arm>-seed-<k>.log         the run's output (appended across requeues)
//! DIR/logs/slurm-<job>_<task>.out     what Slurm saw of the task
//! ```
//!
//! Each array task runs `fulcrum experiment --task DIR --arm A --seed K`: a finished pair
//! is left alone, an interrupted one continues from its checkpoint (`train --resume`),
//! one that never wrote a checkpoint starts over, all with the local scheduler's own
//! `train` command line, so a pair's curve is the same bit for bit wherever it ran
//! (synchronous PPO is deterministic given its seed). A task writes only its run
//! directory, its log and its status file. The script asks Slurm to requeue a task that
//! is preempted or whose node fails (`--requeue`); SIGTERM before the kill makes the run
//! write a checkpoint first, and the requeued task continues from the newest one.
//!
//! `fulcrum experiment --collect DIR` aggregates what has finished into the summary and
//! plots, as the local experiment does, and names every pair that is missing, failed
//! or unfinished.

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use crate::error::{bad, BadRequest, Context, Result};
use crate::lock::DirLock;
use crate::process::{install_signal_handlers, stopping, utc_stamp};

use super::schedule::{clear_fresh, last_steps, train_command};
use super::{job, prepare, read_spec, state, ExperimentRequest, Job, Spec, State};

/// What the array script asks of Slurm.
#[derive(Debug, Clone)]
pub struct SlurmOptions {
    /// `--partition` (the cluster's default where None).
    pub partition: Option<String>,
    /// `--time` of each task (Slurm's formats: `MM`, `HH:MM:SS`, `D-HH:MM`, ...).
    pub time: String,
    /// `--cpus-per-task` (default: the run's actors, as a local experiment gives each run).
    pub cpus: Option<usize>,
    /// `--mem` of each task (the cluster's default where None).
    pub mem: Option<String>,
    /// More `#SBATCH` options, each as written after `#SBATCH ` (e.g. `--account=rl`).
    pub extra: Vec<String>,
    /// Submit the script with `sbatch` (false: write it and print it only).
    pub submit: bool,
    /// The `fulcrum` executable the tasks run.
    pub exe: PathBuf,
}

/// What [`launch`] did.
#[derive(Debug, Clone)]
pub struct Launch {
    /// The experiment directory (absolute).
    pub dir: PathBuf,
    /// The array script, None when every pair had finished.
    pub script: Option<PathBuf>,
    /// The script's text.
    pub text: String,
    /// Array tasks (pairs still to run).
    pub tasks: usize,
    /// The array's job id, when submitted.
    pub job: Option<String>,
}

/// One array task: a pair of the experiment in `dir`.
#[derive(Debug, Clone)]
pub(super) struct Task {
    /// The experiment directory (absolute).
    dir: PathBuf,
    arm: String,
    seed: u64,
}

/// The experiment directory made ready, then the array script of its unfinished pairs
/// written and (unless `o.submit` is false) submitted with `sbatch --parsable`.
pub fn launch(a: &ExperimentRequest, o: &SlurmOptions) -> Result<Launch> {
    check_options(o)?;
    let prepared = prepare(a)?;
    let dir = absolute(&prepared.dir)?;
    let tasks = unfinished(&prepared.spec, &prepared.jobs, &dir);
    let title = format!(
        "{} (arm, seed) pairs of {}, one array task each",
        tasks.len(),
        prepared.spec.world
    );
    let cpus = o.cpus.unwrap_or(prepared.spec.actors);
    write_and_submit(&dir, &title, &prepared.spec.world, &tasks, o, cpus)
}

pub(super) fn absolute(dir: &Path) -> Result<PathBuf> {
    Ok(std::path::absolute(dir).with_context(|| format!("cannot resolve {}", dir.display()))?)
}

/// The pairs of `jobs` that have not finished, as tasks on the experiment in `dir`.
pub(super) fn unfinished(spec: &Spec, jobs: &[Job], dir: &Path) -> Vec<Task> {
    jobs.iter()
        .filter(|j| state(&j.dir, spec.steps) != State::Done)
        .map(|j| Task {
            dir: dir.to_path_buf(),
            arm: spec.arms[j.arm].name.clone(),
            seed: j.seed,
        })
        .collect()
}

/// The options checked, as [`launch`] and [`super::launch_set`] check them before anything is
/// written (a set's caller checks them before it writes the set's files).
pub fn check_options(o: &SlurmOptions) -> Result<()> {
    if let Some(c) = o.cpus {
        if c == 0 {
            return bad("--slurm-cpus must be at least 1");
        }
    }
    for (flag, v) in [
        ("--slurm-time", Some(&o.time)),
        ("--slurm-mem", o.mem.as_ref()),
    ]
    .into_iter()
    .chain([("--slurm-partition", o.partition.as_ref())])
    {
        if let Some(v) = v {
            if v.is_empty() || v.chars().any(|c| c.is_whitespace() || c == '\'') {
                return bad(format!(
                    "{flag} '{v}' is not a Slurm value (no spaces or quotes)"
                ));
            }
        }
    }
    if let Some(e) = o
        .extra
        .iter()
        .find(|e| !e.starts_with('-') || e.contains('\n'))
    {
        return bad(format!(
            "--sbatch '{e}' is not an sbatch option (write it as after '#SBATCH ', e.g. --account=rl)"
        ));
    }
    Ok(())
}

/// The array script of `tasks` written under `dir/slurm/` and submitted (unless
/// `o.submit` is false); nothing written when no task is left.
pub(super) fn write_and_submit(
    dir: &Path,
    title: &str,
    name: &str,
    tasks: &[Task],
    o: &SlurmOptions,
    cpus: usize,
) -> Result<Launch> {
    if tasks.is_empty() {
        return Ok(Launch {
            dir: dir.to_path_buf(),
            script: None,
            text: String::new(),
            tasks: 0,
            job: None,
        });
    }
    let cwd = std::env::current_dir().context("cannot read the working directory")?;
    let slurm_dir = dir.join("slurm");
    // Slurm opens each task's output in `logs/` and fails the task where it is missing.
    for d in [&slurm_dir, &dir.join("logs")] {
        std::fs::create_dir_all(d).with_context(|| format!("cannot create {}", d.display()))?;
    }
    let path = slurm_dir.join(format!("array-{}.sbatch", utc_stamp()));
    let text = script(title, name, tasks, (dir, &path, &cwd), o, cpus);
    fulcrum_contracts::fsio::write_atomic(&path, text.as_bytes())
        .with_context(|| format!("cannot write {}", path.display()))?;
    let mut job = None;
    if o.submit {
        let out = Command::new("sbatch")
            .arg("--parsable")
            .arg(&path)
            .stdin(Stdio::null())
            .output()
            .map_err(|e| {
                BadRequest(format!(
                    "cannot run sbatch ({e}): is Slurm's client on PATH? --dry-run writes {} without submitting it",
                    path.display()
                ))
            })?;
        if !out.status.success() {
            crate::fail!(
                "sbatch refused {}: {}",
                path.display(),
                String::from_utf8_lossy(&out.stderr).trim()
            );
        }
        let id = String::from_utf8_lossy(&out.stdout).trim().to_string();
        // `--parsable` prints `id` or `id;cluster`.
        job = Some(id.split(';').next().unwrap_or("").to_string());
    }
    Ok(Launch {
        dir: dir.to_path_buf(),
        script: Some(path),
        text,
        tasks: tasks.len(),
        job,
    })
}

/// `s` quoted for bash (single quotes; a quote inside as `'\''`).
fn quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// The array script: task i runs the pair (ARMS[i], SEEDS[i]) of the experiment in
/// DIRS[i].
fn script(
    title: &str,
    name: &str,
    tasks: &[Task],
    (dir, path, cwd): (&Path, &Path, &Path),
    o: &SlurmOptions,
    cpus: usize,
) -> String {
    let d = dir.display().to_string();
    let mut t = String::from("#!/bin/bash\n");
    t += &format!(
        "# fulcrum experiment on Slurm: {title}.\n\
         # Edit the #SBATCH lines as your cluster needs, then submit with\n\
         #   sbatch {}\n\
         # A task that Slurm requeues (preemption, a node failure) continues its run from\n\
         # its checkpoint. Once every task has ended:\n\
         #   fulcrum experiment --collect {}\n",
        quote(&path.display().to_string()),
        quote(&d),
    );
    let name: String = name
        .rsplit('/')
        .next()
        .unwrap_or("world")
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let mut lines = vec![
        format!("--job-name=fulcrum-{name}"),
        format!("--array=0-{}", tasks.len() - 1),
        "--ntasks=1".to_string(),
        format!("--cpus-per-task={cpus}"),
        format!("--time={}", o.time),
        "--requeue".to_string(),
        "--open-mode=append".to_string(),
        format!("--output={d}/logs/slurm-%A_%a.out"),
        format!("--chdir={}", cwd.display()),
    ];
    if let Some(p) = &o.partition {
        lines.push(format!("--partition={p}"));
    }
    if let Some(m) = &o.mem {
        lines.push(format!("--mem={m}"));
    }
    lines.extend(o.extra.iter().cloned());
    for l in lines {
        t += &format!("#SBATCH {l}\n");
    }
    let list = |f: &dyn Fn(&Task) -> String| -> String {
        tasks.iter().map(f).collect::<Vec<_>>().join(" ")
    };
    t += "set -eu\n";
    t += &format!(
        "DIRS=({})\n",
        list(&|k| quote(&k.dir.display().to_string()))
    );
    t += &format!("ARMS=({})\n", list(&|k| quote(&k.arm)));
    t += &format!("SEEDS=({})\n", list(&|k| k.seed.to_string()));
    t += "i=${SLURM_ARRAY_TASK_ID:?submit this script with sbatch, which sets SLURM_ARRAY_TASK_ID}\n";
    t += &format!(
        "exec {} experiment --task \"${{DIRS[$i]}}\" --arm \"${{ARMS[$i]}}\" --seed \"${{SEEDS[$i]}}\"\n",
        quote(&o.exe.display().to_string()),
    );
    t
}

/// The status file of a pair.
fn status_file(dir: &Path, spec: &Spec, j: &Job) -> PathBuf {
    dir.join("slurm")
        .join("status")
        .join(format!("{}-seed-{}", spec.arms[j.arm].name, j.seed))
}

/// How [`run_task`] left its pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TaskOutcome {
    /// It had finished before.
    AlreadyDone,
    /// It finished now.
    Finished,
}

/// One pair of the experiment in `dir`, trained (or resumed) to the budget: what each
/// array task runs. SIGTERM and SIGINT are passed on to the run, which checkpoints and
/// stops; a failure is recorded in the pair's status file and returned.
pub fn run_task(dir: &Path, arm: &str, seed: u64) -> Result<TaskOutcome> {
    let Some(spec) = read_spec(dir)? else {
        return bad(format!(
            "{} is not an experiment directory (it has no experiment.toml)",
            dir.display()
        ));
    };
    let Some(ai) = spec.arms.iter().position(|a| a.name == arm) else {
        let names: Vec<&str> = spec.arms.iter().map(|a| a.name.as_str()).collect();
        return bad(format!(
            "{} has no arm '{arm}' (its arms: {})",
            dir.display(),
            names.join(", ")
        ));
    };
    if !(1..=spec.seeds).contains(&seed) {
        return bad(format!(
            "{} has seeds 1 to {}, not {seed}",
            dir.display(),
            spec.seeds
        ));
    }
    let j = job(dir, &spec, ai, seed);
    let status = status_file(dir, &spec, &j);
    wait_for_leftovers(&j.dir);
    let st = state(&j.dir, spec.steps);
    if st == State::Done {
        let _ = std::fs::remove_file(&status);
        eprintln!(
            "fulcrum experiment: {arm}/seed-{seed} had finished ({})",
            j.dir.display()
        );
        return Ok(TaskOutcome::AlreadyDone);
    }
    install_signal_handlers();
    let result = train_pair(&spec, &j, st);
    match &result {
        Ok(()) => {
            let _ = std::fs::remove_file(&status);
        }
        Err(e) => {
            if let Some(parent) = status.parent() {
                let _ = std::fs::create_dir_all(parent);
            }
            let text = format!("{}\t{e}\n", utc_stamp());
            let _ = fulcrum_contracts::fsio::write_atomic(&status, text.as_bytes());
        }
    }
    result.map(|()| TaskOutcome::Finished)
}

/// How long a task waits for the processes of a killed predecessor to let go of its run
/// directory.
const LEFTOVERS_WAIT: Duration = Duration::from_secs(60);

/// Wait (at most [`LEFTOVERS_WAIT`]) until no process holds the run directory `dir`.
/// A task that Slurm killed and requeued on the same node can start again while the
/// learner, actors and service of the killed one still hold the directory's lock: they
/// die with their supervisor (`PR_SET_PDEATHSIG`), the learner after writing its
/// checkpoint, which takes seconds. Past the wait, `train` says who holds it.
fn wait_for_leftovers(dir: &Path) {
    let t0 = std::time::Instant::now();
    let mut said = false;
    while let Some(pid) = DirLock::holder(dir) {
        if t0.elapsed() >= LEFTOVERS_WAIT || stopping() {
            return;
        }
        if !said {
            eprintln!(
                "fulcrum experiment: waiting for pid {pid} to let go of {}",
                dir.display()
            );
            said = true;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// `train` on the pair, its output appended to the pair's log, until it exits.
fn train_pair(spec: &Spec, j: &Job, st: State) -> Result<()> {
    if st == State::Fresh && j.dir.exists() {
        clear_fresh(j)?;
    }
    let exe = std::env::current_exe().context("cannot find the fulcrum executable")?;
    let resume = st == State::Partial;
    let name = format!("{}/seed-{}", spec.arms[j.arm].name, j.seed);
    let mut cmd = train_command(&exe, spec, j, resume)?;
    eprintln!(
        "fulcrum experiment: {} {name} (log {})",
        if resume { "resuming" } else { "starting" },
        j.log.display()
    );
    // SAFETY: only async-signal-safe calls (prctl) between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
            Ok(())
        });
    }
    let mut child = cmd
        .spawn()
        .with_context(|| format!("cannot start the run {name}"))?;
    let mut passed_on = false;
    let status = loop {
        if let Some(s) = child.try_wait().context("cannot wait for the run")? {
            break s;
        }
        if stopping() && !passed_on {
            // SAFETY: kill(2) on our own child's pid.
            unsafe {
                libc::kill(child.id() as libc::pid_t, libc::SIGTERM);
            }
            passed_on = true;
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    if status.success() && state(&j.dir, spec.steps) == State::Done {
        eprintln!("fulcrum experiment: finished {name}");
        return Ok(());
    }
    crate::fail!(
        "the run {name} {} ({status}) at {} of {} env steps; see {}",
        if passed_on { "was stopped" } else { "failed" },
        last_steps(&j.dir),
        spec.steps,
        j.log.display()
    )
}

/// Where each pair of a collected experiment stands.
#[derive(Debug, Clone, Default)]
pub struct Collected {
    /// The summary's Markdown.
    pub markdown: String,
    /// Pairs that finished.
    pub finished: usize,
    /// Pairs with no run directory (never started).
    pub missing: Vec<String>,
    /// Pairs whose last task failed: name and what its status file says.
    pub failed: Vec<(String, String)>,
    /// Pairs with a checkpoint short of the budget: name and env steps reached.
    pub unfinished: Vec<(String, u64)>,
}

/// [`super::collect`] of one world's experiment, with its summary.
pub(super) fn collect_one(
    dir: &Path,
    threshold: f64,
    smooth: usize,
) -> Result<(Collected, super::summary::Summary)> {
    let Some(spec) = read_spec(dir)? else {
        return bad(format!(
            "{} is not an experiment directory (it has no experiment.toml)",
            dir.display()
        ));
    };
    let _lock = crate::lock::lock_for_run(dir)?;
    let mut jobs = Vec::new();
    for ai in 0..spec.arms.len() {
        for seed in 1..=spec.seeds {
            jobs.push(job(dir, &spec, ai, seed));
        }
    }
    std::fs::create_dir_all(dir.join("plots"))
        .with_context(|| format!("cannot create {}", dir.join("plots").display()))?;
    let summary = super::summary::aggregate(&spec, &spec.arms, &jobs, threshold, smooth)?;
    let markdown = super::report::write(&summary, dir)?;
    let mut c = Collected {
        markdown,
        ..Collected::default()
    };
    for j in &jobs {
        let name = format!("{}/seed-{}", spec.arms[j.arm].name, j.seed);
        let status = std::fs::read_to_string(status_file(dir, &spec, j)).ok();
        match state(&j.dir, spec.steps) {
            State::Done => c.finished += 1,
            _ if status.is_some() => c
                .failed
                .push((name, status.unwrap_or_default().trim().replace('\t', ": "))),
            State::Partial => c.unfinished.push((name, last_steps(&j.dir))),
            State::Fresh => c.missing.push(name),
        }
    }
    Ok((c, summary))
}
