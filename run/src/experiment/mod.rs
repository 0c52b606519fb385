//! Experiments: every (arm, seed) pair trained with `fulcrum train`, then the
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
//! With `--launcher slurm` the pairs run as a Slurm job array instead ([`launch`],
//! [`run_task`]: see the `slurm` module); a set of worlds as one array of its (world,
//! arm, seed) triples ([`launch_set`], in the `set` module, which builds on `slurm`'s
//! script and tasks). [`collect`] gathers either kind of directory once its tasks have
//! ended (in the `set` module too: a set's directory is pooled, one world's collected
//! by `slurm`).
//!
//! The statistics are [`crate::stats`]: episode-pooled success over a trailing
//! window of `--smooth` updates, a grid of 200 intervals over the budget, the sample
//! standard deviation over seeds, steps to `--threshold`, the area under the success
//! curve, and Welch's t-test of each arm against the first (steps to threshold, with a
//! seed that never gets there counted at the whole budget, and area under the curve).

mod report;
mod schedule;
mod set;
mod slurm;
mod summary;

pub use set::{collect, launch_set, prepare_set, run_set, SetDir, SetRequest, SetWorld};
pub use slurm::{check_options, launch, run_task, Collected, Launch, SlurmOptions, TaskOutcome};

use std::path::{Path, PathBuf};

use crate::error::{Context, Result};
use fulcrum_learner::metrics::read_metrics;
use fulcrum_learner::paths::RunPaths;
use serde::{Deserialize, Serialize};

use crate::error::{bad, BadRequest};
use crate::process::{allowed_cpus, utc_stamp};

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

/// The version of `experiment.toml` this code writes: 2 since every arm with an
/// intrinsic reward names its form (version 1, without the field, relied on `train`'s
/// default, which was the additive bonus).
const SPEC_VERSION: u32 = 2;

/// `experiment.toml`: what the runs under the directory are.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Spec {
    #[serde(default = "legacy_version")]
    version: u32,
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

fn legacy_version() -> u32 {
    1
}

impl Spec {
    /// A spec read from disk, in this version's terms: the arms of a version-1 file
    /// that named no form ran the additive bonus, then `train`'s default.
    fn upgraded(mut self) -> Spec {
        let names_form = |args: &[String]| {
            args.iter()
                .any(|a| crate::argv::FORM_FLAGS.contains(&a.as_str()))
        };
        if self.version < 2 && !names_form(&self.extra) {
            for arm in &mut self.arms {
                if !names_form(&arm.args) {
                    arm.args.splice(0..0, crate::argv::additive_form());
                }
            }
        }
        self.version = SPEC_VERSION;
        self
    }
}

/// An experiment to run (or resume, or extend): its arms already checked.
#[derive(Debug, Clone)]
pub struct ExperimentRequest {
    /// The world as given (a built-in name or a path).
    pub world: String,
    /// The world's name.
    pub world_name: String,
    /// [`fulcrum_world::World::content_hash`], hex.
    pub world_hash: String,
    /// Env steps per run (whole updates).
    pub steps: u64,
    /// Seeds 1..=seeds.
    pub seeds: u64,
    /// Actors per run.
    pub actors: usize,
    /// Worlds per actor.
    pub envs_per_actor: usize,
    /// `train` flags given to every run.
    pub extra: Vec<String>,
    /// The arms.
    pub arms: Vec<Arm>,
    /// Runs at a time (default: one per `actors` cores).
    pub parallel: Option<usize>,
    /// The experiment directory (default `experiments/<world>-<time>`).
    pub out: Option<PathBuf>,
    /// The success rate that counts as solved.
    pub threshold: f64,
    /// Updates of the trailing window success is pooled over.
    pub smooth: usize,
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

/// The `train` command line of a pair (after the executable).
fn train_args(spec: &Spec, arm: &Arm, job: &Job, resume: bool) -> Vec<String> {
    crate::argv::train(&if resume {
        crate::argv::TrainJob::Resume(job.dir.clone())
    } else {
        crate::argv::TrainJob::New(crate::argv::NewRun {
            world: spec.world.clone(),
            seed: Some(job.seed),
            steps: Some(spec.steps),
            actors: Some(spec.actors),
            envs_per_actor: Some(spec.envs_per_actor),
            checkpoint_every: None,
            out: Some(job.dir.clone()),
            flags: [&arm.args[..], &spec.extra[..]].concat(),
        })
    })
}

/// Runs (or resumes) the experiment, then aggregates every finished run into
/// `summary.{md,json}` and the plots; returns the Markdown summary.
pub fn run(a: &ExperimentRequest) -> Result<String> {
    let done = run_one(a)?;
    let (markdown, failed, dir) = (done.markdown, done.failed, done.dir);
    if !failed.is_empty() {
        crate::fail!(
            "{} runs failed ({}); their logs are in {}; run the same command again to retry them",
            failed.len(),
            failed.join(", "),
            dir.join("logs").display()
        );
    }
    Ok(markdown)
}

/// What [`run_one`] did: the summary (as Markdown and itself), the runs that failed (the
/// summary pools the finished ones all the same) and the directory.
struct Done {
    markdown: String,
    summary: summary::Summary,
    failed: Vec<String>,
    dir: PathBuf,
}

/// An experiment directory made ready under its lock: the spec merged with the
/// directory's own and written, and the pairs of this command.
struct Prepared {
    dir: PathBuf,
    spec: Spec,
    jobs: Vec<Job>,
    lock: crate::lock::DirLock,
}

/// The pair `(arm, seed)` of the experiment in `dir`: its run directory and log.
fn job(dir: &Path, spec: &Spec, arm: usize, seed: u64) -> Job {
    let name = &spec.arms[arm].name;
    Job {
        arm,
        seed,
        dir: dir.join("runs").join(name).join(format!("seed-{seed}")),
        log: dir.join("logs").join(format!("{name}-seed-{seed}.log")),
    }
}

/// `experiment.toml` of `dir`, in this version's terms (None where there is none).
fn read_spec(dir: &Path) -> Result<Option<Spec>> {
    let spec_path = dir.join("experiment.toml");
    if !spec_path.exists() {
        return Ok(None);
    }
    let old: Spec = read_toml(&spec_path, "an experiment file")?;
    Ok(Some(old.upgraded()))
}

/// A TOML file this version wrote, or one sentence saying it is not `what` it can read.
fn read_toml<T: serde::de::DeserializeOwned>(path: &Path, what: &str) -> Result<T> {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|t| toml::from_str(&t).ok())
        .ok_or_else(|| {
            BadRequest(format!(
                "{} is not {what} this version can read",
                path.display()
            ))
            .into()
        })
}

/// Creates (or checks and extends) the experiment directory of `a`.
fn prepare(a: &ExperimentRequest) -> Result<Prepared> {
    let arms = a.arms.clone();
    let world_name = &a.world_name;
    let dir = a.out.clone().unwrap_or_else(|| {
        PathBuf::from("experiments").join(format!("{world_name}-{}", utc_stamp()))
    });
    let mut spec = Spec {
        version: SPEC_VERSION,
        world: a.world.clone(),
        world_hash: a.world_hash.clone(),
        steps: a.steps,
        seeds: a.seeds,
        actors: a.actors,
        envs_per_actor: a.envs_per_actor,
        extra: a.extra.clone(),
        arms: arms.clone(),
    };
    let spec_path = dir.join("experiment.toml");
    // The directory belongs to this invocation (and the runs it starts) from here on.
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let lock = crate::lock::lock_for_run(&dir)?;
    if let Some(old) = read_spec(&dir)? {
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
    fulcrum_contracts::fsio::write_atomic(&spec_path, text.as_bytes())
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
            jobs.push(job(&dir, &spec, ai, seed));
        }
    }
    Ok(Prepared {
        dir,
        spec,
        jobs,
        lock,
    })
}

/// [`run`], with the summary itself and the runs that failed.
fn run_one(a: &ExperimentRequest) -> Result<Done> {
    let arms = a.arms.clone();
    let world_name = &a.world_name;
    let Prepared {
        dir,
        spec,
        jobs,
        lock: _lock,
    } = prepare(a)?;
    let cpus = allowed_cpus();
    let parallel = a.parallel.unwrap_or((cpus.len() / a.actors).max(1)).max(1);
    let share = (cpus.len() / parallel).max(1);
    let todo: Vec<&Job> = jobs
        .iter()
        .filter(|j| state(&j.dir, spec.steps) != State::Done)
        .collect();
    // A run another invocation is training (`train --resume` on it by hand) is neither
    // started again nor cleared.
    for j in &todo {
        if let Some(pid) = crate::lock::DirLock::holder(&j.dir) {
            return bad(crate::lock::LockError::Held {
                dir: j.dir.clone(),
                pid,
            }
            .to_string());
        }
    }
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
    let failed = schedule::schedule(&spec, &jobs, &todo, &cpus, parallel, share)?;

    let summary = summary::aggregate(&spec, &arms, &jobs, a.threshold, a.smooth)?;
    let markdown = report::write(&summary, &dir)?;
    eprintln!(
        "summary: {}\nplots: {} {}",
        dir.join("summary.md").display(),
        dir.join("plots/success.png").display(),
        dir.join("plots/return.png").display()
    );
    Ok(Done {
        markdown,
        summary,
        failed,
        dir,
    })
}

/// An existing spec and the new command: the same world, budget, run settings and
/// arm definitions; seeds and arms may grow.
fn merge(old: Spec, new: Spec, path: &Path) -> Result<Spec> {
    let differs = |what: &str, o: String, n: String| -> Result<()> {
        if o != n {
            return bad(format!(
                "{} was made with {what} {o}, not {n}: a different experiment needs a directory of its own",
                path.display()
            ));
        }
        Ok(())
    };
    differs("world hash", old.world_hash.clone(), new.world_hash.clone())?;
    differs("steps", old.steps.to_string(), new.steps.to_string())?;
    differs("actors", old.actors.to_string(), new.actors.to_string())?;
    differs(
        "worlds per actor",
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
                    "{}: arm '{}' was run with '{}', not '{}': a different experiment needs a directory of its own",
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
