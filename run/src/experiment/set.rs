//! An experiment over a set of worlds: the same arms and seeds on every world of the
//! set (worlds nobody wrote: `fulcrum experiment --worlds gen:N`), and the (world,
//! seed) pairs pooled per arm.
//!
//! ```text
//! DIR/set.toml                  what the set is (its description, its worlds in order
//!                               and the fewest steps each world's task takes)
//! DIR/worlds/<world>.toml       the world files, as generated
//! DIR/<world>/                  each world's experiment (see the module above)
//! DIR/summary.md, summary.json  the pooled table and every pair's outcome
//! ```
//!
//! A pair is solved when its success rate, pooled over `--smooth` updates, reaches the
//! threshold within the budget. Per arm over its pairs: the share solved with Wilson's
//! 95% interval; the steps to the threshold with an unsolved pair counted at the
//! budget, as interquartile mean with a percentile-bootstrap 95% interval (2000
//! resamples of the pairs) and median; against the first arm, the log-rank test of the
//! "solved by step t" curves and McNemar's exact test on the pairs that only one of the
//! two solved (the pairs are matched: same world, same seed), each with Holm's
//! adjustment over the arms compared; and the pairs the beacon-trap detector marked.
//! Pairs are pooled over worlds: the log-rank test does not stratify by world.
//!
//! The same command with the same directory resumes, as a single world's experiment
//! does; another set under the same directory is refused. On Slurm the set is one job
//! array over every world's pairs ([`launch_set`]), and `--collect DIR` pools
//! the finished pairs as a local run of the set does ([`collect`], which also takes one
//! world's experiment directory):
//!
//! ```text
//! DIR/slurm/array-<time>.sbatch  task i = the pair (ARMS[i], SEEDS[i]) of DIRS[i]
//! DIR/logs/slurm-<job>_<task>.out
//! ```

use std::path::{Path, PathBuf};

use crate::error::{Context, Result};
use serde::{Deserialize, Serialize};

use super::report::{p_text, steps_text};
use super::slurm::{self, Collected, Launch, SlurmOptions};
use super::summary::Summary;
use super::{run_one, ExperimentRequest};
use crate::error::{bad, BadRequest};
use crate::lock::{lock_for_run, DirLock};
use crate::stats::{self, LogRank};

/// One world of a set: its name, the fewest steps its task takes, and its experiment.
#[derive(Debug, Clone)]
pub struct SetWorld {
    /// The world's name (its directory under the set's).
    pub name: String,
    /// The fewest steps in which its task can be done.
    pub fewest_steps: u32,
    /// Its experiment (`out` is the set's directory joined with the name).
    pub request: ExperimentRequest,
}

/// A set of worlds to run, its files already written by [`prepare_set`].
#[derive(Debug)]
pub struct SetRequest {
    /// The set as asked for (`gen:N:...`).
    pub description: String,
    /// The set's directory, locked by this invocation.
    pub dir: SetDir,
    /// Its worlds, in order.
    pub worlds: Vec<SetWorld>,
}

/// The set's directory and its lock.
#[derive(Debug)]
pub struct SetDir {
    /// The directory.
    pub path: PathBuf,
    _lock: DirLock,
}

/// `set.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct SetSpec {
    set: String,
    worlds: Vec<String>,
    /// The fewest steps each world's task takes, in the order of `worlds` (absent from
    /// the files of sets made before it was recorded).
    #[serde(default)]
    fewest_steps: Vec<u32>,
}

/// Lock the set's directory and write its `set.toml` and world files (`(name, text,
/// fewest steps)` in order); returns the directory and each world file's path. A
/// directory that holds another set, or other files under the same names, is refused.
pub fn prepare_set(
    dir: &Path,
    description: &str,
    files: &[(String, String, u32)],
) -> Result<(SetDir, Vec<PathBuf>)> {
    std::fs::create_dir_all(dir.join("worlds"))
        .with_context(|| format!("cannot create {}", dir.display()))?;
    let lock = lock_for_run(dir)?;
    let spec = SetSpec {
        set: description.to_string(),
        worlds: files.iter().map(|(n, _, _)| n.clone()).collect(),
        fewest_steps: files.iter().map(|f| f.2).collect(),
    };
    let spec_path = dir.join("set.toml");
    if spec_path.exists() {
        let old: SetSpec = super::read_toml(&spec_path, "a set file")?;
        if (&old.set, &old.worlds) != (&spec.set, &spec.worlds) {
            return bad(format!(
                "{} holds the set {}, not {description}: a different set needs a directory of its own",
                dir.display(),
                old.set
            ));
        }
    }
    let mut paths = Vec::with_capacity(files.len());
    for (name, text, _) in files {
        let path = dir.join("worlds").join(format!("{name}.toml"));
        match std::fs::read_to_string(&path) {
            Ok(old) if old != *text => {
                return bad(format!(
                    "{} differs from the world the set makes under that name: a different set needs a directory of its own",
                    path.display()
                ))
            }
            Ok(_) => {}
            Err(_) => fulcrum_contracts::fsio::write_atomic(&path, text.as_bytes())
                .with_context(|| format!("cannot write {}", path.display()))?,
        }
        paths.push(std::fs::canonicalize(&path).unwrap_or(path));
    }
    let text = format!(
        "# fulcrum experiment over a set of worlds; run the same command again to resume it.\n{}",
        toml::to_string(&spec).context("cannot encode set.toml")?
    );
    fulcrum_contracts::fsio::write_atomic(&spec_path, text.as_bytes())
        .with_context(|| format!("cannot write {}", spec_path.display()))?;
    Ok((
        SetDir {
            path: dir.to_path_buf(),
            _lock: lock,
        },
        paths,
    ))
}

/// One (world, seed) pair of an arm.
#[derive(Debug, Clone, Serialize)]
struct Pair {
    world: String,
    seed: u64,
    /// Env steps to the threshold; `None` when never reached within the budget.
    steps_to_threshold: Option<f64>,
    /// Updates the beacon-trap detector marked.
    trap_updates: u64,
}

#[derive(Debug, Serialize)]
struct SetArm {
    name: String,
    args: Vec<String>,
    pairs: usize,
    solved: usize,
    share: f64,
    share_ci: (f64, f64),
    iqm_steps: Option<f64>,
    iqm_ci: Option<(f64, f64)>,
    median_steps: Option<f64>,
    trapped: usize,
    per_pair: Vec<Pair>,
}

#[derive(Debug, Serialize)]
struct SetComparison {
    arm: String,
    against: String,
    log_rank: Option<LogRank>,
    log_rank_holm: Option<f64>,
    /// Pairs solved by the first arm only, and by this arm only.
    only_against: usize,
    only_arm: usize,
    mcnemar_p: f64,
    mcnemar_holm: f64,
}

#[derive(Debug, Serialize)]
struct SetSummary {
    set: String,
    worlds: Vec<(String, u32)>,
    seeds: u64,
    steps: u64,
    threshold: f64,
    arms: Vec<SetArm>,
    comparisons: Vec<SetComparison>,
}

/// Runs (or resumes) every world's experiment of the set, then pools the pairs into
/// `DIR/summary.{md,json}`; returns the Markdown.
pub fn run_set(req: &SetRequest) -> Result<String> {
    let n = req.worlds.len();
    let mut failed = Vec::new();
    let mut summaries = Vec::with_capacity(n);
    for (i, w) in req.worlds.iter().enumerate() {
        eprintln!("fulcrum experiment: world {} of {n}: {}", i + 1, w.name);
        let done = run_one(&w.request)?;
        if !done.failed.is_empty() {
            failed.push(format!("{}: {}", w.name, done.failed.join(", ")));
        }
        summaries.push(done.summary);
    }
    let worlds: Vec<(String, u32)> = req
        .worlds
        .iter()
        .map(|w| (w.name.clone(), w.fewest_steps))
        .collect();
    let markdown = pool(&req.description, &req.dir.path, &worlds, &summaries)?;
    let dir = &req.dir.path;
    if !failed.is_empty() {
        crate::fail!(
            "runs failed on {} of the {n} worlds ({}); their logs are under {}/<world>/logs; run the same command again to retry them",
            failed.len(),
            failed.join(", "),
            dir.display()
        );
    }
    Ok(markdown)
}

/// The worlds' summaries (in the set's order) pooled pair by pair into
/// `dir/summary.{md,json}`; returns the Markdown.
fn pool(
    description: &str,
    dir: &Path,
    worlds: &[(String, u32)],
    summaries: &[Summary],
) -> Result<String> {
    let first = summaries
        .first()
        .ok_or_else(|| BadRequest("the set has no world".into()))?;
    let budget = first.steps as f64;
    let mut arms = Vec::new();
    for (k, arm) in first.arms.iter().enumerate() {
        let mut pairs = Vec::new();
        for ((world, _), s) in worlds.iter().zip(summaries) {
            let Some(a) = s.arms.get(k) else { continue };
            for seed in &a.per_seed {
                pairs.push(Pair {
                    world: world.clone(),
                    seed: seed.seed,
                    steps_to_threshold: seed.steps_to_threshold,
                    trap_updates: seed.trap_updates,
                });
            }
        }
        arms.push(set_arm(&arm.name, &arm.args, pairs, budget));
    }
    let comparisons = compare_all(&arms, budget);
    let summary = SetSummary {
        set: description.to_string(),
        worlds: worlds.to_vec(),
        seeds: first.arms.first().map_or(0, |a| a.seeds as u64),
        steps: first.steps,
        threshold: first.threshold,
        arms,
        comparisons,
    };
    let markdown = markdown(&summary, first.smooth_updates);
    let json = serde_json::to_string_pretty(&summary).context("cannot encode summary.json")?;
    fulcrum_contracts::fsio::write_atomic(&dir.join("summary.json"), json.as_bytes())
        .with_context(|| format!("cannot write {}", dir.join("summary.json").display()))?;
    fulcrum_contracts::fsio::write_atomic(&dir.join("summary.md"), markdown.as_bytes())
        .with_context(|| format!("cannot write {}", dir.join("summary.md").display()))?;
    Ok(markdown)
}

/// The summary and plots of the experiment in `dir` from every finished pair, as a
/// local experiment writes them, and where the other pairs stand. On a set's directory
/// (`set.toml`), every world's experiment collected and the pairs pooled as
/// [`run_set`] pools them.
pub fn collect(dir: &Path, threshold: f64, smooth: usize) -> Result<Collected> {
    if dir.join("set.toml").exists() {
        return collect_set(dir, threshold, smooth);
    }
    slurm::collect_one(dir, threshold, smooth).map(|(c, _)| c)
}

/// `fulcrum experiment --collect DIR` on a set's directory: every world's experiment
/// collected ([`slurm::collect_one`]: its summary and plots written), then the
/// pairs pooled as [`run_set`] pools them; the pairs not finished are named with their
/// world.
fn collect_set(dir: &Path, threshold: f64, smooth: usize) -> Result<Collected> {
    let spec: SetSpec = super::read_toml(&dir.join("set.toml"), "a set file")?;
    if spec.fewest_steps.len() != spec.worlds.len() {
        return bad(format!(
            "{} was written before a set recorded its worlds' fewest steps: run the set's command again (without --launcher) to pool it",
            dir.join("set.toml").display()
        ));
    }
    let _lock = lock_for_run(dir)?;
    let mut all = Collected::default();
    let mut summaries = Vec::with_capacity(spec.worlds.len());
    for name in &spec.worlds {
        let (c, s) = slurm::collect_one(&dir.join(name), threshold, smooth)
            .with_context(|| format!("world {name}"))?;
        all.finished += c.finished;
        all.missing
            .extend(c.missing.into_iter().map(|m| format!("{name}/{m}")));
        all.failed.extend(
            c.failed
                .into_iter()
                .map(|(m, why)| (format!("{name}/{m}"), why)),
        );
        all.unfinished.extend(
            c.unfinished
                .into_iter()
                .map(|(m, k)| (format!("{name}/{m}"), k)),
        );
        summaries.push(s);
    }
    let worlds: Vec<(String, u32)> = spec
        .worlds
        .iter()
        .cloned()
        .zip(spec.fewest_steps.iter().copied())
        .collect();
    all.markdown = pool(&spec.set, dir, &worlds, &summaries)?;
    Ok(all)
}

/// An arm's pooled numbers.
fn set_arm(name: &str, args: &[String], per_pair: Vec<Pair>, budget: f64) -> SetArm {
    let censored: Vec<f64> = per_pair
        .iter()
        .map(|p| p.steps_to_threshold.unwrap_or(budget))
        .collect();
    let solved = per_pair
        .iter()
        .filter(|p| p.steps_to_threshold.is_some())
        .count();
    let w = crate::eval::wilson(solved, per_pair.len());
    let finite = |x: f64| x.is_finite().then_some(x);
    SetArm {
        name: name.to_string(),
        args: args.to_vec(),
        pairs: per_pair.len(),
        solved,
        share: w.value,
        share_ci: (w.lo, w.hi),
        iqm_steps: finite(stats::iqm(&censored)),
        iqm_ci: stats::bootstrap_ci(&censored, stats::iqm, 2000, 0x1a2b, 0.95),
        median_steps: finite(median(&censored)),
        trapped: per_pair.iter().filter(|p| p.trap_updates > 0).count(),
        per_pair,
    }
}

fn median(x: &[f64]) -> f64 {
    let mut v = x.to_vec();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// Every arm after the first against the first, with Holm's adjustment over them.
fn compare_all(arms: &[SetArm], budget: f64) -> Vec<SetComparison> {
    let Some((base, rest)) = arms.split_first() else {
        return Vec::new();
    };
    let events = |a: &SetArm| -> Vec<(f64, bool)> {
        a.per_pair
            .iter()
            .map(|p| {
                (
                    p.steps_to_threshold.unwrap_or(budget),
                    p.steps_to_threshold.is_some(),
                )
            })
            .collect()
    };
    let solved_pairs = |a: &SetArm| -> std::collections::BTreeMap<(String, u64), bool> {
        a.per_pair
            .iter()
            .map(|p| ((p.world.clone(), p.seed), p.steps_to_threshold.is_some()))
            .collect()
    };
    let base_solved = solved_pairs(base);
    let mut out: Vec<SetComparison> = rest
        .iter()
        .map(|a| {
            let (mut only_base, mut only_arm) = (0, 0);
            for (k, &s) in &solved_pairs(a) {
                match (base_solved.get(k), s) {
                    (Some(true), false) => only_base += 1,
                    (Some(false), true) => only_arm += 1,
                    _ => {}
                }
            }
            SetComparison {
                arm: a.name.clone(),
                against: base.name.clone(),
                log_rank: stats::log_rank(&events(a), &events(base)),
                log_rank_holm: None,
                only_against: only_base,
                only_arm,
                mcnemar_p: stats::mcnemar_exact(only_base, only_arm),
                mcnemar_holm: f64::NAN,
            }
        })
        .collect();
    let lr: Vec<f64> = out
        .iter()
        .map(|c| c.log_rank.map_or(f64::NAN, |l| l.p))
        .collect();
    let mc: Vec<f64> = out.iter().map(|c| c.mcnemar_p).collect();
    for ((c, l), m) in out.iter_mut().zip(stats::holm(&lr)).zip(stats::holm(&mc)) {
        c.log_rank_holm = l.is_finite().then_some(l);
        c.mcnemar_holm = m;
    }
    out
}

fn markdown(s: &SetSummary, smooth: usize) -> String {
    let mut t = format!(
        "Worlds `{}`: {} worlds x {} seeds, {} env steps per run; a pair (world, seed) is solved when its success rate, pooled over {smooth} updates, reaches {} within the budget.\n\n\
         | arm | pairs solved | share (95% CI) | IQM steps to {} (95% CI) | median | log-rank p vs {} (Holm) | solved by {} only / by the arm only | McNemar p (Holm) | pairs marked as trapped |\n\
         |---|---|---|---|---|---|---|---|---|\n",
        s.set,
        s.worlds.len(),
        s.seeds,
        s.steps,
        s.threshold,
        s.threshold,
        s.arms.first().map_or("-", |a| a.name.as_str()),
        s.arms.first().map_or("-", |a| a.name.as_str()),
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
        let lr = c.map_or("-".into(), |c| match (&c.log_rank, c.log_rank_holm) {
            (Some(l), Some(h)) => format!(
                "{} ({}) ({})",
                p_text(l.p),
                if l.observed_a > l.expected_a {
                    "faster"
                } else {
                    "slower"
                },
                p_text(h)
            ),
            _ => "- (no pair solved)".into(),
        });
        t += &format!(
            "| {} | {}/{} | {:.2} ({:.2} - {:.2}) | {} | {} | {} | {} | {} | {}/{} |\n",
            a.name,
            a.solved,
            a.pairs,
            a.share,
            a.share_ci.0,
            a.share_ci.1,
            iqm,
            a.median_steps.map_or("-".into(), steps_text),
            lr,
            c.map_or("-".into(), |c| format!(
                "{} / {}",
                c.only_against, c.only_arm
            )),
            c.map_or("-".into(), |c| format!(
                "{} ({})",
                p_text(c.mcnemar_p),
                p_text(c.mcnemar_holm)
            )),
            a.trapped,
            a.pairs,
        );
    }
    t += "\nPer world, the seeds that solved it (the fewest steps its task takes in brackets):\n\n| world |";
    for a in &s.arms {
        t += &format!(" {} |", a.name);
    }
    t += "\n|---|";
    t += &"---|".repeat(s.arms.len());
    t += "\n";
    for (w, d) in &s.worlds {
        t += &format!("| {w} ({d}) |");
        for a in &s.arms {
            let mine: Vec<&Pair> = a.per_pair.iter().filter(|p| &p.world == w).collect();
            let solved = mine
                .iter()
                .filter(|p| p.steps_to_threshold.is_some())
                .count();
            let trapped = mine.iter().filter(|p| p.trap_updates > 0).count();
            t += &format!(
                " {solved}/{}{} |",
                mine.len(),
                if trapped > 0 {
                    format!(", {trapped} trapped")
                } else {
                    String::new()
                }
            );
        }
        t += "\n";
    }
    t
}

/// [`super::launch`] for a set of worlds: every world's experiment directory made ready (as
/// [`run_set`] makes them), then one array of the unfinished (world, arm, seed)
/// triples of them all, its script and Slurm's logs in the set's directory. `fulcrum
/// experiment --collect` on the set's directory pools them as the local set does.
pub fn launch_set(req: &SetRequest, o: &SlurmOptions) -> Result<Launch> {
    slurm::check_options(o)?;
    let dir = slurm::absolute(&req.dir.path)?;
    let mut tasks = Vec::new();
    let mut cpus = o.cpus.unwrap_or(1);
    for w in &req.worlds {
        let p = super::prepare(&w.request)?;
        let d = slurm::absolute(&p.dir)?;
        tasks.extend(slurm::unfinished(&p.spec, &p.jobs, &d));
        cpus = o.cpus.unwrap_or(p.spec.actors);
    }
    let title = format!(
        "{} (world, arm, seed) triples of the set {} ({} worlds), one array task each",
        tasks.len(),
        req.description,
        req.worlds.len()
    );
    slurm::write_and_submit(&dir, &title, &req.description, &tasks, o, cpus)
}
