//! `fulcrum experiment`: every (arm, seed) pair trained with `fulcrum train`, then the
//! curves aggregated into the paper's figures (mean line, shaded std band, one colour
//! per arm) and a summary table.
//!
//! ```text
//! DIR/experiment.toml              what the experiment is (world, budget, arms, seeds)
//! DIR/runs/<arm>/seed-<k>/         one `fulcrum train` run directory per pair
//! DIR/logs/<arm>-seed-<k>.log      its output
//! DIR/summary.md, summary.json     the table (and the curves, in the JSON)
//! DIR/plots/success.{png,svg}      success rate, mean +/- std over seeds, per arm
//! DIR/plots/return.{png,svg}       extrinsic return per episode, the same way
//! ```
//!
//! Runs go `--parallel` at a time (default: one per `--actors` cores), each pinned to
//! its own share of the cores (`sched_setaffinity`, inherited by its children). Seeds
//! are 1..=N. Every run's settings are fixed by the experiment, not by the machine (one
//! actor of 8 worlds unless told otherwise), so the same command gives the same curves
//! anywhere: synchronous PPO is deterministic given its seed.
//!
//! Running the same command again resumes: finished runs are kept, interrupted runs
//! continue from their checkpoints (`train --resume`), runs that never wrote one start
//! over, and more seeds or arms may be added. Changing the world, the budget or an
//! arm's settings under the same directory is refused.
//!
//! The statistics are [`fulcrum_learner::stats`]: episode-pooled success over a trailing
//! window of `--smooth` updates, a grid of 200 intervals over the budget, the sample
//! standard deviation over seeds, steps to `--threshold`, the area under the success
//! curve, and Welch's t-test of each arm against the first (steps to threshold, with a
//! seed that never gets there counted at the whole budget, and area under the curve).

use std::collections::BTreeMap;
use std::io::{Read, Seek, SeekFrom};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::Parser;
use fulcrum_learner::run::{read_metrics, MetricsRow, RunPaths};
use fulcrum_learner::stats::{self, LogRank, Point, Welch};
use serde::{Deserialize, Serialize};

use crate::cli::{ExperimentArgs, TrainArgs};
use crate::commands::{bad, train};

/// Intervals of the common grid over the budget.
const GRID: usize = 200;
/// The final rates are pooled over this fraction of the last updates.
const FINAL_FRACTION: f64 = 0.1;

/// One arm: a name and the `train` flags that make it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Arm {
    /// Name in tables, plots and directories.
    pub name: String,
    /// Flags given to `fulcrum train` for this arm.
    pub args: Vec<String>,
}

/// `experiment.toml`: what the runs under the directory are.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Spec {
    world: String,
    world_hash: String,
    steps: u64,
    seeds: u64,
    actors: usize,
    envs_per_actor: usize,
    /// Flags given to every run (after `--`).
    extra: Vec<String>,
    arms: Vec<Arm>,
}

/// `train` flags parsed exactly as the child will parse them.
#[derive(Debug, Parser)]
#[command(name = "train")]
struct TrainOnly {
    #[command(flatten)]
    train: TrainArgs,
}

/// The arms asked for: `--arms` (baseline, empowerment) then one per `--beta-sweep` value.
fn arms(a: &ExperimentArgs) -> Result<Vec<Arm>> {
    let mut out: Vec<Arm> = Vec::new();
    // The additive form is train's default: its arms name only the beta, as before
    // there were other forms (so earlier experiment directories still resume).
    let with_beta = |form: &str, beta: Option<f64>| {
        let mut v = if form == "additive" {
            Vec::new()
        } else {
            vec!["--intrinsic".to_string(), form.to_string()]
        };
        if let Some(b) = beta {
            v.extend(["--beta".into(), b.to_string()]);
        }
        v
    };
    let form = a.intrinsic.as_str();
    for name in a.arms.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let args = match name {
            "baseline" => vec!["--no-empowerment".to_string()],
            "none" => vec!["--intrinsic".to_string(), "none".to_string()],
            "empowerment" => with_beta(form, a.beta),
            "additive" | "potential" | "count" | "horizon-potential" | "first-visit" => {
                with_beta(name, a.beta)
            }
            "baseline-unmasked" => vec![
                "--no-empowerment".to_string(),
                "--no-action-mask".to_string(),
            ],
            "cleanrl" | "rllib" => vec![
                "--no-empowerment".to_string(),
                "--ppo-preset".to_string(),
                name.to_string(),
            ],
            "additive-fixed" => {
                let mut v = vec!["--horizon-mode".to_string(), "fixed".to_string()];
                v.extend(with_beta("additive", a.beta));
                v
            }
            other => {
                return bad(format!(
                    "--arms: unknown arm '{other}' (arms: baseline, empowerment, none, additive, additive-fixed, potential, horizon-potential, first-visit, count, cleanrl, rllib, baseline-unmasked; for betas use --beta-sweep)"
                ))
            }
        };
        out.push(Arm {
            name: name.to_string(),
            args,
        });
    }
    if let Some(sweep) = &a.beta_sweep {
        for b in sweep.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let v: f64 = match b.parse() {
                Ok(v) => v,
                Err(_) => return bad(format!("--beta-sweep: '{b}' is not a number")),
            };
            out.push(Arm {
                name: if form == "additive" {
                    format!("beta-{v}")
                } else {
                    format!("{form}-beta-{v}")
                },
                args: with_beta(form, Some(v)),
            });
        }
    }
    let mut seen = std::collections::HashSet::new();
    if let Some(d) = out.iter().find(|a| !seen.insert(a.name.clone())) {
        return bad(format!("arm '{}' is named twice", d.name));
    }
    if out.is_empty() {
        return bad("no arms to run: give --arms or --beta-sweep");
    }
    Ok(out)
}

/// One (arm, seed) pair.
#[derive(Debug, Clone)]
struct Job {
    arm: usize,
    seed: u64,
    dir: PathBuf,
    log: PathBuf,
}

/// Where a pair stands on disk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    /// Its metrics reach the budget.
    Done,
    /// It has a checkpoint to continue from.
    Partial,
    /// Nothing to continue from.
    Fresh,
}

fn state(dir: &Path, steps: u64) -> State {
    let paths = RunPaths {
        dir: dir.to_path_buf(),
    };
    let done = read_metrics(&paths.metrics())
        .ok()
        .and_then(|rows| rows.last().map(|r| r.env_steps >= steps))
        .unwrap_or(false);
    if done && paths.checkpoint().exists() {
        State::Done
    } else if paths.checkpoint().exists() && paths.config().exists() {
        State::Partial
    } else {
        State::Fresh
    }
}

/// The `train` command line of a pair (after the executable and `train`).
fn train_args(spec: &Spec, arm: &Arm, job: &Job, resume: bool) -> Vec<String> {
    if resume {
        return vec!["--resume".into(), job.dir.display().to_string()];
    }
    let mut v = vec![
        spec.world.clone(),
        "--seed".into(),
        job.seed.to_string(),
        "--steps".into(),
        spec.steps.to_string(),
        "--actors".into(),
        spec.actors.to_string(),
        "--envs-per-actor".into(),
        spec.envs_per_actor.to_string(),
        "--out".into(),
        job.dir.display().to_string(),
    ];
    v.extend(arm.args.iter().cloned());
    v.extend(spec.extra.iter().cloned());
    v
}

/// The CPUs this process may run on.
fn allowed_cpus() -> Vec<usize> {
    // SAFETY: sched_getaffinity fills the zeroed set we own.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return (0..train::cores()).collect();
        }
        (0..libc::CPU_SETSIZE as usize)
            .filter(|&c| libc::CPU_ISSET(c, &set))
            .collect()
    }
}

/// `fulcrum experiment`.
pub fn run(a: &ExperimentArgs) -> Result<()> {
    if a.seeds == 0 {
        return bad("--seeds must be at least 1");
    }
    if a.actors == 0 {
        return bad("--actors must be at least 1");
    }
    if !(a.threshold > 0.0 && a.threshold <= 1.0) {
        return bad(format!(
            "--threshold {} must be a success rate in (0, 1]",
            a.threshold
        ));
    }
    if a.smooth == 0 {
        return bad("--smooth must be at least 1 update");
    }
    let arms = arms(a)?;

    // Check every arm's runs exactly as `train` will, before anything starts.
    let mut world_hash = String::new();
    let mut steps = 0;
    let mut world_name = String::new();
    for arm in &arms {
        let mut argv = vec!["train".to_string(), a.world.clone()];
        if let Some(s) = a.steps {
            argv.extend(["--steps".into(), s.to_string()]);
        }
        argv.extend([
            "--actors".into(),
            a.actors.to_string(),
            "--envs-per-actor".into(),
            a.envs_per_actor.to_string(),
        ]);
        argv.extend(arm.args.iter().cloned());
        argv.extend(a.train_args.iter().cloned());
        let parsed = TrainOnly::try_parse_from(&argv).or_else(|e| {
            let msg = e.to_string();
            let first = msg
                .lines()
                .next()
                .unwrap_or("")
                .trim_start_matches("error: ");
            bad(format!(
                "the flags after -- are not valid train flags: {first}"
            ))
        })?;
        if parsed.train.resume.is_some()
            || parsed.train.out.is_some()
            || parsed.train.seed.is_some()
        {
            return bad("the flags after -- may not set --resume, --out or --seed: the experiment chooses them");
        }
        let (cfg, w) = train::plan(&parsed.train).with_context(|| format!("arm '{}'", arm.name))?;
        world_hash = cfg.world_hash.clone();
        world_name = w.name.clone();
        steps = cfg.updates() * cfg.batch() as u64;
    }

    let dir = a.out.clone().unwrap_or_else(|| {
        PathBuf::from("experiments").join(format!("{world_name}-{}", train::chrono_like_now()))
    });
    let mut spec = Spec {
        world: a.world.clone(),
        world_hash,
        steps,
        seeds: a.seeds,
        actors: a.actors,
        envs_per_actor: a.envs_per_actor,
        extra: a.train_args.clone(),
        arms: arms.clone(),
    };
    let spec_path = dir.join("experiment.toml");
    if spec_path.exists() {
        let old: Spec = std::fs::read_to_string(&spec_path)
            .ok()
            .and_then(|t| toml::from_str(&t).ok())
            .ok_or_else(|| {
                crate::commands::BadInput(format!(
                    "{} is not an experiment file this version can read",
                    spec_path.display()
                ))
            })?;
        spec = merge(old, spec, &spec_path)?;
    }
    std::fs::create_dir_all(dir.join("logs"))
        .with_context(|| format!("cannot create {}", dir.display()))?;
    std::fs::create_dir_all(dir.join("plots"))
        .with_context(|| format!("cannot create {}", dir.display()))?;
    let text = format!(
        "# fulcrum experiment; run the same command again to resume or extend it.\n{}",
        toml::to_string(&spec).context("cannot encode experiment.toml")?
    );
    fulcrum_shared::fsio::write_atomic(&spec_path, text.as_bytes())
        .with_context(|| format!("cannot write {}", spec_path.display()))?;

    // The pairs of this command (the spec may hold more arms from earlier commands).
    let mut jobs = Vec::new();
    for arm in &arms {
        let ai = spec
            .arms
            .iter()
            .position(|x| x.name == arm.name)
            .unwrap_or(0);
        for seed in 1..=a.seeds {
            jobs.push(Job {
                arm: ai,
                seed,
                dir: dir
                    .join("runs")
                    .join(&arm.name)
                    .join(format!("seed-{seed}")),
                log: dir
                    .join("logs")
                    .join(format!("{}-seed-{seed}.log", arm.name)),
            });
        }
    }
    let cpus = allowed_cpus();
    let parallel = a.parallel.unwrap_or((cpus.len() / a.actors).max(1)).max(1);
    let share = (cpus.len() / parallel).max(1);
    let todo: Vec<&Job> = jobs
        .iter()
        .filter(|j| state(&j.dir, spec.steps) != State::Done)
        .collect();
    eprintln!(
        "fulcrum experiment: {} in {}: {} arms x {} seeds, {} env steps each; {} to run, {} at a time on {} core{} each",
        world_name,
        dir.display(),
        arms.len(),
        a.seeds,
        spec.steps,
        todo.len(),
        parallel.min(todo.len().max(1)),
        share,
        if share == 1 { "" } else { "s" }
    );
    let failed = schedule(&spec, &jobs, &todo, &cpus, parallel, share)?;

    let markdown = aggregate(&spec, &arms, &jobs, a.threshold, a.smooth, &dir)?;
    print!("{markdown}");
    eprintln!(
        "summary: {}\nplots: {} {}",
        dir.join("summary.md").display(),
        dir.join("plots/success.png").display(),
        dir.join("plots/return.png").display()
    );
    if !failed.is_empty() {
        anyhow::bail!(
            "{} runs failed ({}); their logs are in {}; run the same command again to retry them",
            failed.len(),
            failed.join(", "),
            dir.join("logs").display()
        );
    }
    Ok(())
}

/// An existing spec and the new command: the same world, budget, run settings and
/// arm definitions; seeds and arms may grow.
fn merge(old: Spec, new: Spec, path: &Path) -> Result<Spec> {
    let differs = |what: &str, o: String, n: String| -> Result<()> {
        if o != n {
            return bad(format!(
                "{} was made with {what} {o}, not {n}: use another --out for a different experiment",
                path.display()
            ));
        }
        Ok(())
    };
    differs("world hash", old.world_hash.clone(), new.world_hash.clone())?;
    differs("steps", old.steps.to_string(), new.steps.to_string())?;
    differs("--actors", old.actors.to_string(), new.actors.to_string())?;
    differs(
        "--envs-per-actor",
        old.envs_per_actor.to_string(),
        new.envs_per_actor.to_string(),
    )?;
    differs(
        "the train flags",
        format!("'{}'", old.extra.join(" ")),
        format!("'{}'", new.extra.join(" ")),
    )?;
    let mut arms = old.arms.clone();
    for arm in &new.arms {
        match arms.iter().find(|a| a.name == arm.name) {
            Some(o) if o.args != arm.args => {
                return bad(format!(
                    "{}: arm '{}' was run with '{}', not '{}': use another --out",
                    path.display(),
                    arm.name,
                    o.args.join(" "),
                    arm.args.join(" ")
                ))
            }
            Some(_) => {}
            None => arms.push(arm.clone()),
        }
    }
    Ok(Spec {
        seeds: old.seeds.max(new.seeds),
        arms,
        ..new
    })
}

extern "C" fn on_signal(_sig: libc::c_int) {
    INTERRUPTED.store(true, std::sync::atomic::Ordering::Relaxed);
}

static INTERRUPTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Runs the pairs in `todo`, `parallel` at a time; returns the names of failed pairs.
fn schedule(
    spec: &Spec,
    jobs: &[Job],
    todo: &[&Job],
    cpus: &[usize],
    parallel: usize,
    share: usize,
) -> Result<Vec<String>> {
    // SAFETY: the handler only stores to an atomic.
    unsafe {
        libc::signal(
            libc::SIGINT,
            on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t,
        );
        libc::signal(
            libc::SIGTERM,
            on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t,
        );
    }
    let exe = std::env::current_exe().context("cannot find the fulcrum executable")?;
    let total = jobs.len() as u64 * spec.steps;
    let mut progress = Progress::new(total);
    let mut queue: std::collections::VecDeque<&Job> = todo.iter().copied().collect();
    let mut running: Vec<(usize, &Job, Child)> = Vec::new(); // (slot, job, child)
    let mut failed = Vec::new();
    let mut finished_steps: u64 = (jobs.len() - todo.len()) as u64 * spec.steps;
    let name = |j: &Job| format!("{}/seed-{}", spec.arms[j.arm].name, j.seed);
    loop {
        let interrupted = INTERRUPTED.load(std::sync::atomic::Ordering::Relaxed);
        // Start runs in free slots.
        while !interrupted && running.len() < parallel {
            let Some(job) = queue.pop_front() else { break };
            let slot = (0..parallel)
                .find(|s| !running.iter().any(|(r, _, _)| r == s))
                .unwrap_or(0);
            let set: Vec<usize> = cpus
                .iter()
                .copied()
                .cycle()
                .skip(slot * share)
                .take(share)
                .collect();
            let st = state(&job.dir, spec.steps);
            if st == State::Fresh && job.dir.exists() {
                // A run that never wrote a checkpoint has nothing to continue from.
                std::fs::remove_dir_all(&job.dir)
                    .with_context(|| format!("cannot clear {}", job.dir.display()))?;
            }
            if let Some(parent) = job.dir.parent() {
                std::fs::create_dir_all(parent)
                    .with_context(|| format!("cannot create {}", parent.display()))?;
            }
            let log = std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(&job.log)
                .with_context(|| format!("cannot open {}", job.log.display()))?;
            let args = train_args(spec, &spec.arms[job.arm], job, st == State::Partial);
            let mut cmd = Command::new(&exe);
            cmd.arg("train")
                .args(&args)
                .stdin(Stdio::null())
                .stdout(log.try_clone().context("cannot share the log file")?)
                .stderr(log)
                .process_group(0);
            let parent = std::process::id();
            // SAFETY: only async-signal-safe calls (sched_setaffinity, prctl, getppid,
            // _exit-free checks) between fork and exec.
            unsafe {
                cmd.pre_exec(move || {
                    let mut mask: libc::cpu_set_t = std::mem::zeroed();
                    for &c in &set {
                        libc::CPU_SET(c, &mut mask);
                    }
                    libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mask);
                    libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
                    if libc::getppid() as u32 != parent {
                        libc::raise(libc::SIGTERM);
                    }
                    Ok(())
                });
            }
            let child = cmd
                .spawn()
                .with_context(|| format!("cannot start the run {}", name(job)))?;
            progress.note(&format!(
                "{} {} (log {})",
                if st == State::Partial {
                    "resuming"
                } else {
                    "starting"
                },
                name(job),
                job.log.display()
            ));
            running.push((slot, job, child));
        }
        if interrupted {
            for (_, _, c) in &running {
                // SAFETY: kill(2) on our own child's pid.
                unsafe {
                    libc::kill(c.id() as libc::pid_t, libc::SIGINT);
                }
            }
        }
        // Reap.
        let mut i = 0;
        while i < running.len() {
            match running[i].2.try_wait() {
                Ok(Some(status)) => {
                    let (_, job, _) = running.swap_remove(i);
                    if status.success() && state(&job.dir, spec.steps) == State::Done {
                        finished_steps += spec.steps;
                        progress.note(&format!("finished {}", name(job)));
                    } else if !interrupted {
                        progress.note(&format!(
                            "{} failed ({status}); see {}",
                            name(job),
                            job.log.display()
                        ));
                        failed.push(name(job));
                    }
                }
                Ok(None) => i += 1,
                Err(e) => return Err(e).context("cannot wait for a run"),
            }
        }
        let live: u64 = running
            .iter()
            .map(|(_, j, _)| last_steps(&j.dir).min(spec.steps))
            .sum();
        progress.set(
            finished_steps + live,
            jobs.len() - todo.len() + (todo.len() - queue.len() - running.len()),
            jobs.len(),
        );
        if running.is_empty() && (queue.is_empty() || interrupted) {
            break;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    progress.finish();
    if INTERRUPTED.load(std::sync::atomic::Ordering::Relaxed) {
        return Err(train::Interrupted(
            "experiment interrupted; every run kept its checkpoint: run the same command again to resume"
                .into(),
        )
        .into());
    }
    Ok(failed)
}

/// Env steps of a run's last metrics row (reads only the file's tail).
fn last_steps(dir: &Path) -> u64 {
    let path = RunPaths {
        dir: dir.to_path_buf(),
    }
    .metrics();
    let Ok(mut f) = std::fs::File::open(&path) else {
        return 0;
    };
    let len = f.metadata().map(|m| m.len()).unwrap_or(0);
    let _ = f.seek(SeekFrom::Start(len.saturating_sub(2048)));
    let mut tail = String::new();
    let _ = f.read_to_string(&mut tail);
    tail.lines()
        .rev()
        .filter_map(fulcrum_learner::run::MetricsRow::parse)
        .map(|r| r.env_steps)
        .next()
        .unwrap_or(0)
}

/// One bar over all runs' env steps on a terminal; a line every 10 s elsewhere.
struct Progress {
    bar: Option<indicatif::ProgressBar>,
    last_line: Instant,
    total: u64,
}

impl Progress {
    fn new(total: u64) -> Progress {
        let bar = super::terminal_bar(
            total,
            "{elapsed_precise} [{bar:30}] {percent:>3}% env steps  {msg}  eta {eta}",
        );
        Progress {
            bar,
            last_line: Instant::now(),
            total,
        }
    }

    fn set(&mut self, pos: u64, done: usize, runs: usize) {
        let msg = format!("{done}/{runs} runs done");
        match &self.bar {
            Some(b) => {
                b.set_position(pos);
                b.set_message(msg);
            }
            None => {
                if self.last_line.elapsed() >= Duration::from_secs(10) {
                    self.last_line = Instant::now();
                    eprintln!(
                        "{:.0}% of env steps, {msg}",
                        100.0 * pos as f64 / self.total.max(1) as f64
                    );
                }
            }
        }
    }

    fn note(&self, text: &str) {
        match &self.bar {
            Some(b) => b.println(format!("fulcrum experiment: {text}")),
            None => eprintln!("fulcrum experiment: {text}"),
        }
    }

    fn finish(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
    }
}

/// Mean and standard deviation, as written to JSON.
#[derive(Debug, Clone, Copy, Serialize)]
struct MeanStd {
    mean: Option<f64>,
    std: Option<f64>,
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

impl MeanStd {
    fn of(xs: &[f64]) -> MeanStd {
        let (m, s) = stats::mean_std(xs);
        MeanStd {
            mean: finite(m),
            std: finite(s),
        }
    }
}

#[derive(Debug, Serialize)]
struct SeedSummary {
    seed: u64,
    steps_to_threshold: Option<f64>,
    final_success: Option<f64>,
    final_return: Option<f64>,
    auc: Option<f64>,
    /// Diagnostics over the last 10 % of updates: intrinsic return per episode (the
    /// form's b_t summed, before beta), tool pick-up rate per episode, fraction of steps
    /// whose E(s') > 0.
    final_intrinsic_return: Option<f64>,
    final_pickup_rate: Option<f64>,
    final_e_positive: Option<f64>,
    /// Env steps of the first update in which an episode with a pick-up ended.
    first_pickup_step: Option<f64>,
}

/// Episode-weighted mean of `f` over the last `frac` of the rows (NaN without episodes).
fn tail_per_episode(rows: &[MetricsRow], frac: f64, f: fn(&MetricsRow) -> f64) -> f64 {
    let k = ((rows.len() as f64 * frac).ceil() as usize).clamp(1, rows.len().max(1));
    let (mut n, mut s) = (0.0, 0.0);
    for r in &rows[rows.len().saturating_sub(k)..] {
        if r.episodes > 0 && f(r).is_finite() {
            n += r.episodes as f64;
            s += f(r) * r.episodes as f64;
        }
    }
    if n > 0.0 {
        s / n
    } else {
        f64::NAN
    }
}

/// Mean of the finite `e_positive_frac` over the last `frac` of the rows.
fn tail_mean_e_positive(rows: &[MetricsRow], frac: f64) -> f64 {
    let k = ((rows.len() as f64 * frac).ceil() as usize).clamp(1, rows.len().max(1));
    let v: Vec<f64> = rows[rows.len().saturating_sub(k)..]
        .iter()
        .map(|r| r.e_positive_frac)
        .filter(|x| x.is_finite())
        .collect();
    stats::mean_std(&v).0
}

#[derive(Debug, Serialize)]
struct ArmSummary {
    name: String,
    args: Vec<String>,
    seeds: usize,
    finished: usize,
    reached: usize,
    steps_to_threshold: MeanStd,
    final_success: MeanStd,
    final_return: MeanStd,
    auc: MeanStd,
    final_intrinsic_return: MeanStd,
    final_pickup_rate: MeanStd,
    final_e_positive: MeanStd,
    /// Over the seeds that picked a tool up; `picked` says how many did.
    first_pickup_step: MeanStd,
    picked: usize,
    per_seed: Vec<SeedSummary>,
    success_mean: Vec<Option<f64>>,
    success_std: Vec<Option<f64>>,
    return_mean: Vec<Option<f64>>,
    return_std: Vec<Option<f64>>,
    /// Steps to threshold with a seed that never got there counted at the budget
    /// (censored): interquartile mean, its percentile-bootstrap 95% interval, median.
    iqm_steps: Option<f64>,
    iqm_ci: Option<(f64, f64)>,
    median_steps: Option<f64>,
    /// Kaplan-Meier fraction of seeds solved by each grid step.
    solved_by: Vec<Option<f64>>,
}

#[derive(Debug, Serialize)]
struct Comparison {
    arm: String,
    against: String,
    /// Steps to threshold, a seed that never reached it counted at the budget.
    steps_to_threshold: Option<Welch>,
    auc: Option<Welch>,
    /// Fisher's exact test (two-sided) on the seeds that reached the threshold.
    fisher_p: f64,
    /// The log-rank test of the two "solved by step t" curves (censored at the budget).
    log_rank: Option<LogRank>,
}

#[derive(Debug, Serialize)]
struct Summary {
    world: String,
    steps: u64,
    threshold: f64,
    smooth_updates: usize,
    grid: Vec<f64>,
    arms: Vec<ArmSummary>,
    comparisons: Vec<Comparison>,
}

/// Reads the finished runs of `jobs`, writes summary.{md,json} and the plots.
fn aggregate(
    spec: &Spec,
    arms: &[Arm],
    jobs: &[Job],
    threshold: f64,
    smooth: usize,
    dir: &Path,
) -> Result<String> {
    let g = stats::grid(spec.steps as f64, GRID);
    let mut out = Vec::new();
    let mut censored: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let mut aucs: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let mut events: BTreeMap<String, Vec<(f64, bool)>> = BTreeMap::new();
    let mut solved: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    for arm in arms {
        let mine: Vec<&Job> = jobs
            .iter()
            .filter(|j| spec.arms[j.arm].name == arm.name)
            .collect();
        let mut per_seed = Vec::new();
        let (mut succ_curves, mut ret_curves) = (Vec::new(), Vec::new());
        for j in &mine {
            if state(&j.dir, spec.steps) != State::Done {
                continue;
            }
            let rows = read_metrics(&RunPaths { dir: j.dir.clone() }.metrics())
                .with_context(|| format!("cannot read the metrics of {}", j.dir.display()))?;
            let pts: Vec<Point> = rows
                .iter()
                .filter(|r| r.env_steps <= spec.steps)
                .map(MetricsRow::point)
                .collect();
            let sm = stats::smooth(&pts, smooth);
            let sc = stats::interpolate(&sm.iter().map(|p| (p.0, p.1)).collect::<Vec<_>>(), &g);
            let rc = stats::interpolate(&sm.iter().map(|p| (p.0, p.2)).collect::<Vec<_>>(), &g);
            let (fs, fr) = stats::final_rates(&pts, FINAL_FRACTION);
            let auc = stats::area(&g, &sc);
            let reach = stats::steps_to(&sm, threshold);
            per_seed.push(SeedSummary {
                seed: j.seed,
                steps_to_threshold: reach,
                final_success: finite(fs),
                final_return: finite(fr),
                auc: finite(auc),
                final_intrinsic_return: finite(tail_per_episode(&rows, FINAL_FRACTION, |r| {
                    r.intrinsic_return
                })),
                final_pickup_rate: finite(tail_per_episode(&rows, FINAL_FRACTION, |r| {
                    r.pickup_rate
                })),
                final_e_positive: finite(tail_mean_e_positive(&rows, FINAL_FRACTION)),
                first_pickup_step: rows
                    .iter()
                    .find(|r| r.episodes > 0 && r.pickup_rate > 0.0)
                    .map(|r| r.env_steps as f64),
            });
            censored
                .entry(arm.name.clone())
                .or_default()
                .push(reach.unwrap_or(spec.steps as f64));
            events
                .entry(arm.name.clone())
                .or_default()
                .push((reach.unwrap_or(spec.steps as f64), reach.is_some()));
            aucs.entry(arm.name.clone()).or_default().push(auc);
            succ_curves.push(sc);
            ret_curves.push(rc);
        }
        let reached: Vec<f64> = per_seed
            .iter()
            .filter_map(|s| s.steps_to_threshold)
            .collect();
        let col = |f: fn(&SeedSummary) -> Option<f64>| -> Vec<f64> {
            per_seed.iter().filter_map(f).collect()
        };
        let (sb, rb) = (stats::band(&succ_curves), stats::band(&ret_curves));
        let cens = censored.get(&arm.name).cloned().unwrap_or_default();
        let ev = events.get(&arm.name).cloned().unwrap_or_default();
        solved.insert(arm.name.clone(), (reached.len(), per_seed.len()));
        let median = |x: &[f64]| {
            let mut v = x.to_vec();
            v.sort_by(f64::total_cmp);
            let n = v.len();
            if n == 0 {
                f64::NAN
            } else if n % 2 == 1 {
                v[n / 2]
            } else {
                0.5 * (v[n / 2 - 1] + v[n / 2])
            }
        };
        out.push(ArmSummary {
            iqm_steps: finite(stats::iqm(&cens)),
            iqm_ci: stats::bootstrap_ci(&cens, stats::iqm, 2000, 0x1a2b, 0.95),
            median_steps: finite(median(&cens)),
            solved_by: stats::solved_by(&ev, &g).into_iter().map(finite).collect(),
            name: arm.name.clone(),
            args: arm.args.clone(),
            seeds: mine.len(),
            finished: per_seed.len(),
            reached: reached.len(),
            steps_to_threshold: MeanStd::of(&reached),
            final_success: MeanStd::of(&col(|s| s.final_success)),
            final_return: MeanStd::of(&col(|s| s.final_return)),
            auc: MeanStd::of(&col(|s| s.auc)),
            final_intrinsic_return: MeanStd::of(&col(|s| s.final_intrinsic_return)),
            final_pickup_rate: MeanStd::of(&col(|s| s.final_pickup_rate)),
            final_e_positive: MeanStd::of(&col(|s| s.final_e_positive)),
            first_pickup_step: MeanStd::of(&col(|s| s.first_pickup_step)),
            picked: col(|s| s.first_pickup_step).len(),
            per_seed,
            success_mean: sb.iter().map(|b| finite(b.0)).collect(),
            success_std: sb.iter().map(|b| finite(b.1)).collect(),
            return_mean: rb.iter().map(|b| finite(b.0)).collect(),
            return_std: rb.iter().map(|b| finite(b.1)).collect(),
        });
    }
    let mut comparisons = Vec::new();
    if let Some(first) = arms.first() {
        for arm in arms.iter().skip(1) {
            let get =
                |m: &BTreeMap<String, Vec<f64>>, k: &str| m.get(k).cloned().unwrap_or_default();
            comparisons.push(Comparison {
                arm: arm.name.clone(),
                against: first.name.clone(),
                steps_to_threshold: stats::welch(
                    &get(&censored, &arm.name),
                    &get(&censored, &first.name),
                ),
                auc: stats::welch(&get(&aucs, &arm.name), &get(&aucs, &first.name)),
                fisher_p: {
                    let (a, an) = solved.get(&arm.name).copied().unwrap_or_default();
                    let (b, bn) = solved.get(&first.name).copied().unwrap_or_default();
                    stats::fisher_exact(a, an, b, bn)
                },
                log_rank: stats::log_rank(
                    &events.get(&arm.name).cloned().unwrap_or_default(),
                    &events.get(&first.name).cloned().unwrap_or_default(),
                ),
            });
        }
    }
    let summary = Summary {
        world: spec.world.clone(),
        steps: spec.steps,
        threshold,
        smooth_updates: smooth,
        grid: g,
        arms: out,
        comparisons,
    };
    let markdown = markdown(&summary);
    let json = serde_json::to_string_pretty(&summary).context("cannot encode summary.json")?;
    fulcrum_shared::fsio::write_atomic(&dir.join("summary.json"), json.as_bytes())
        .with_context(|| format!("cannot write {}", dir.join("summary.json").display()))?;
    fulcrum_shared::fsio::write_atomic(&dir.join("summary.md"), markdown.as_bytes())
        .with_context(|| format!("cannot write {}", dir.join("summary.md").display()))?;
    draw(&summary, dir)?;
    Ok(markdown)
}

fn steps_text(x: f64) -> String {
    if x >= 1e6 {
        format!("{:.2}M", x / 1e6)
    } else if x >= 1e3 {
        format!("{:.0}k", x / 1e3)
    } else {
        format!("{x:.0}")
    }
}

fn ms(v: &MeanStd, f: fn(f64) -> String) -> String {
    match (v.mean, v.std) {
        (Some(m), Some(s)) => format!("{} ± {}", f(m), f(s)),
        _ => "-".into(),
    }
}

fn markdown(s: &Summary) -> String {
    let two = |x: f64| format!("{x:.2}");
    let mut t = format!(
        "World `{}`, {} env steps per run; success pooled over {} updates; final = the last {:.0} % of updates.\n\n\
         | arm | runs | reached {} | steps to {} (mean ± std of those) | final success | final return | area under success |\n\
         |---|---|---|---|---|---|---|\n",
        s.world,
        s.steps,
        s.smooth_updates,
        FINAL_FRACTION * 100.0,
        s.threshold,
        s.threshold
    );
    for a in &s.arms {
        t += &format!(
            "| {} | {}/{} | {}/{} | {} | {} | {} | {} |\n",
            a.name,
            a.finished,
            a.seeds,
            a.reached,
            a.finished,
            ms(&a.steps_to_threshold, steps_text),
            ms(&a.final_success, two),
            ms(&a.final_return, two),
            ms(&a.auc, |x| format!("{x:.3}")),
        );
    }
    t += &format!(
        "\nDiagnostics (the last {:.0} % of updates; intrinsic return is the form's term summed over an episode, before beta):\n\n\
         | arm | intrinsic return per episode | steps with E > 0 | tool pick-up rate | first pick-up at (seeds) |\n|---|---|---|---|---|\n",
        FINAL_FRACTION * 100.0
    );
    for a in &s.arms {
        t += &format!(
            "| {} | {} | {} | {} | {} ({}/{}) |\n",
            a.name,
            ms(&a.final_intrinsic_return, two),
            ms(&a.final_e_positive, two),
            ms(&a.final_pickup_rate, two),
            ms(&a.first_pickup_step, steps_text),
            a.picked,
            a.finished,
        );
    }
    t += &format!(
        "\nTime to solve (a seed that never reached {th} counts as censored at the budget, {b}): \
         interquartile mean with a percentile-bootstrap 95% interval (2000 resamples of the seeds), \
         median; against the first arm, Fisher's exact test on the seeds solved and the log-rank \
         test of the \"solved by step t\" curves (both two-sided):\n\n\
         | arm | solved | IQM steps to {th} (95% CI) | median | Fisher p | log-rank chi2, p |\n|---|---|---|---|---|---|\n",
        th = s.threshold,
        b = steps_text(s.steps as f64),
    );
    for (i, a) in s.arms.iter().enumerate() {
        let c = i.checked_sub(1).and_then(|k| s.comparisons.get(k));
        let iqm = match (a.iqm_steps, a.iqm_ci) {
            (Some(m), Some((lo, hi))) => {
                format!(
                    "{} ({} - {})",
                    steps_text(m),
                    steps_text(lo),
                    steps_text(hi)
                )
            }
            _ => "-".into(),
        };
        t += &format!(
            "| {} | {}/{} | {} | {} | {} | {} |\n",
            a.name,
            a.reached,
            a.finished,
            iqm,
            a.median_steps.map_or("-".into(), steps_text),
            c.map_or("-".into(), |c| p_text(c.fisher_p)),
            c.map_or("-".into(), |c| match &c.log_rank {
                Some(l) => format!("{:.2}, {}", l.chi2, p_text(l.p)),
                None => "- (no seed solved)".into(),
            }),
        );
    }
    if !s.comparisons.is_empty() {
        t += "\nWelch's t-test against the first arm (two-sided; steps to threshold count a seed that never got there at the budget):\n\n\
              | arm | against | steps to threshold: t, df, p | area: t, df, p |\n|---|---|---|---|\n";
        let w = |x: &Option<Welch>| match x {
            Some(w) => format!("{:.2}, {:.1}, {}", w.t, w.df, p_text(w.p)),
            None => "- (fewer than 2 runs)".into(),
        };
        for c in &s.comparisons {
            t += &format!(
                "| {} | {} | {} | {} |\n",
                c.arm,
                c.against,
                w(&c.steps_to_threshold),
                w(&c.auc)
            );
        }
    }
    t
}

fn p_text(p: f64) -> String {
    if p < 0.001 {
        "< 0.001".into()
    } else {
        format!("{p:.3}")
    }
}

/// The two figures, each as PNG and SVG.
fn draw(s: &Summary, dir: &Path) -> Result<()> {
    let series = |mean: fn(&ArmSummary) -> &Vec<Option<f64>>,
                  std: fn(&ArmSummary) -> &Vec<Option<f64>>| {
        s.arms
            .iter()
            .map(|a| fulcrum_plot::Band {
                name: a.name.clone(),
                mean: mean(a).iter().map(|v| v.unwrap_or(f64::NAN)).collect(),
                std: std(a).iter().map(|v| v.unwrap_or(f64::NAN)).collect(),
            })
            .collect::<Vec<_>>()
    };
    let seeds = s.arms.iter().map(|a| a.finished).max().unwrap_or(0);
    for (file, y, bands, unit) in [
        (
            "success",
            "success rate",
            series(|a| &a.success_mean, |a| &a.success_std),
            Some((0.0, 1.0)),
        ),
        (
            "return",
            "extrinsic return per episode",
            series(|a| &a.return_mean, |a| &a.return_std),
            None,
        ),
        (
            "solved",
            "fraction of seeds solved",
            s.arms
                .iter()
                .map(|a| fulcrum_plot::Band {
                    name: a.name.clone(),
                    mean: a.solved_by.iter().map(|v| v.unwrap_or(f64::NAN)).collect(),
                    std: vec![0.0; a.solved_by.len()],
                })
                .collect(),
            Some((0.0, 1.0)),
        ),
    ] {
        let chart = fulcrum_plot::BandChart {
            y_range: unit,
            ..fulcrum_plot::BandChart::over_steps(
                if file == "solved" {
                    format!(
                        "{}: seeds at success {} by env step t ({seeds} seeds, Kaplan-Meier)",
                        s.world, s.threshold
                    )
                } else {
                    format!("{}: {y}, mean ± std over {seeds} seeds", s.world)
                },
                y.to_string(),
                s.grid.clone(),
                bands,
            )
        };
        for ext in ["png", "svg"] {
            let path = dir.join("plots").join(format!("{file}.{ext}"));
            let r = if ext == "png" {
                fulcrum_plot::band_chart_png(&path, &chart)
            } else {
                fulcrum_plot::band_chart_svg(&path, &chart)
            };
            r.with_context(|| format!("cannot draw {}", path.display()))?;
        }
    }
    Ok(())
}
