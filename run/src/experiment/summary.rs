//! Reading the finished runs into the experiment's numbers: curves on a common grid,
//! per-seed and per-arm summaries, and each arm compared with the first.

use std::path::Path;

use crate::error::{Context, Result};
use fulcrum_contracts::config::RunConfig;
use fulcrum_learner::metrics::{read_metrics, MetricsRow};
use fulcrum_learner::paths::RunPaths;
use fulcrum_learner::trap::TrapDetector;
use serde::Serialize;

use super::{state, Arm, Job, Spec, State, FINAL_FRACTION, GRID};
use crate::stats::{self, LogRank, Point, Welch};

/// Mean and standard deviation, as written to JSON.
#[derive(Debug, Clone, Copy, Serialize)]
pub(super) struct MeanStd {
    pub(super) mean: Option<f64>,
    pub(super) std: Option<f64>,
}

pub(super) fn finite(x: f64) -> Option<f64> {
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
pub(super) struct SeedSummary {
    pub(super) seed: u64,
    pub(super) steps_to_threshold: Option<f64>,
    pub(super) final_success: Option<f64>,
    pub(super) final_return: Option<f64>,
    pub(super) auc: Option<f64>,
    /// Diagnostics over the last 10 % of updates: intrinsic return per episode (the
    /// form's b_t summed, before beta), tool pick-up rate per episode, fraction of steps
    /// whose E(s') > 0.
    pub(super) final_intrinsic_return: Option<f64>,
    pub(super) final_pickup_rate: Option<f64>,
    pub(super) final_e_positive: Option<f64>,
    /// Env steps of the first update in which an episode with a pick-up ended.
    pub(super) first_pickup_step: Option<f64>,
    /// Updates the beacon-trap detector marked (`metrics.csv`'s `trap` column).
    pub(super) trap_updates: u64,
}

/// Episode-weighted mean of `f` over the last `frac` of the rows (NaN without episodes).
pub(super) fn tail_per_episode(rows: &[MetricsRow], frac: f64, f: fn(&MetricsRow) -> f64) -> f64 {
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
pub(super) fn tail_mean_e_positive(rows: &[MetricsRow], frac: f64) -> f64 {
    let k = ((rows.len() as f64 * frac).ceil() as usize).clamp(1, rows.len().max(1));
    let v: Vec<f64> = rows[rows.len().saturating_sub(k)..]
        .iter()
        .map(|r| r.e_positive_frac)
        .filter(|x| x.is_finite())
        .collect();
    stats::mean_std(&v).0
}

#[derive(Debug, Serialize)]
pub(super) struct ArmSummary {
    pub(super) name: String,
    pub(super) args: Vec<String>,
    pub(super) seeds: usize,
    pub(super) finished: usize,
    pub(super) reached: usize,
    pub(super) steps_to_threshold: MeanStd,
    pub(super) final_success: MeanStd,
    pub(super) final_return: MeanStd,
    pub(super) auc: MeanStd,
    pub(super) final_intrinsic_return: MeanStd,
    pub(super) final_pickup_rate: MeanStd,
    pub(super) final_e_positive: MeanStd,
    /// Over the seeds that picked a tool up; `picked` says how many did.
    pub(super) first_pickup_step: MeanStd,
    pub(super) picked: usize,
    /// Seeds with an update the beacon-trap detector marked.
    pub(super) trapped: usize,
    pub(super) per_seed: Vec<SeedSummary>,
    pub(super) success_mean: Vec<Option<f64>>,
    pub(super) success_std: Vec<Option<f64>>,
    pub(super) return_mean: Vec<Option<f64>>,
    pub(super) return_std: Vec<Option<f64>>,
    /// Steps to threshold with a seed that never got there counted at the budget
    /// (censored): interquartile mean, its percentile-bootstrap 95% interval, median.
    pub(super) iqm_steps: Option<f64>,
    pub(super) iqm_ci: Option<(f64, f64)>,
    pub(super) median_steps: Option<f64>,
    /// Kaplan-Meier fraction of seeds solved by each grid step.
    pub(super) solved_by: Vec<Option<f64>>,
}

#[derive(Debug, Serialize)]
pub(super) struct Comparison {
    pub(super) arm: String,
    pub(super) against: String,
    /// Steps to threshold, a seed that never reached it counted at the budget.
    pub(super) steps_to_threshold: Option<Welch>,
    pub(super) auc: Option<Welch>,
    /// Fisher's exact test (two-sided) on the seeds that reached the threshold.
    pub(super) fisher_p: f64,
    /// The log-rank test of the two "solved by step t" curves (censored at the budget).
    pub(super) log_rank: Option<LogRank>,
}

#[derive(Debug, Serialize)]
pub(super) struct Summary {
    pub(super) world: String,
    pub(super) steps: u64,
    pub(super) threshold: f64,
    pub(super) smooth_updates: usize,
    pub(super) grid: Vec<f64>,
    pub(super) arms: Vec<ArmSummary>,
    pub(super) comparisons: Vec<Comparison>,
}

/// What one finished seed gives: its summary, its curves on the grid and the samples
/// the arms are compared by.
struct SeedRun {
    summary: SeedSummary,
    success: Vec<f64>,
    ret: Vec<f64>,
    auc: f64,
    reach: Option<f64>,
}

/// The samples of one arm the tests compare: steps to threshold censored at the budget,
/// the areas, the (time, solved) events and (solved, seeds).
#[derive(Default)]
struct Samples {
    censored: Vec<f64>,
    aucs: Vec<f64>,
    events: Vec<(f64, bool)>,
    solved: (usize, usize),
}

/// Reads the finished runs of `jobs` into the summary (`report::write` writes it).
pub(super) fn aggregate(
    spec: &Spec,
    arms: &[Arm],
    jobs: &[Job],
    threshold: f64,
    smooth: usize,
) -> Result<Summary> {
    let g = stats::grid(spec.steps as f64, GRID);
    let mut out = Vec::new();
    let mut samples = Vec::new();
    for arm in arms {
        let mine: Vec<&Job> = jobs
            .iter()
            .filter(|j| spec.arms[j.arm].name == arm.name)
            .collect();
        let mut runs = Vec::new();
        for j in &mine {
            if state(&j.dir, spec.steps) == State::Done {
                runs.push(seed_run(j, spec, &g, threshold, smooth)?);
            }
        }
        let (summary, s) = arm_summary(arm, mine.len(), runs, &g, spec.steps as f64);
        out.push(summary);
        samples.push(s);
    }
    let comparisons = arms
        .iter()
        .zip(&samples)
        .skip(1)
        .map(|(arm, s)| compare(&arm.name, s, &arms[0].name, &samples[0]))
        .collect();
    Ok(Summary {
        world: spec.world.clone(),
        steps: spec.steps,
        threshold,
        smooth_updates: smooth,
        grid: g,
        arms: out,
        comparisons,
    })
}

/// One finished seed's metrics, smoothed and put on the grid `g`.
fn seed_run(j: &Job, spec: &Spec, g: &[f64], threshold: f64, smooth: usize) -> Result<SeedRun> {
    let rows = read_metrics(&RunPaths { dir: j.dir.clone() }.metrics())
        .with_context(|| format!("cannot read the metrics of {}", j.dir.display()))?;
    let pts: Vec<Point> = rows
        .iter()
        .filter(|r| r.env_steps <= spec.steps)
        .map(Point::from)
        .collect();
    let sm = stats::smooth(&pts, smooth);
    let success = stats::interpolate(&sm.iter().map(|p| (p.0, p.1)).collect::<Vec<_>>(), g);
    let ret = stats::interpolate(&sm.iter().map(|p| (p.0, p.2)).collect::<Vec<_>>(), g);
    let (fs, fr) = stats::final_rates(&pts, FINAL_FRACTION);
    let auc = stats::area(g, &success);
    let reach = stats::steps_to(&sm, threshold);
    let summary = SeedSummary {
        seed: j.seed,
        steps_to_threshold: reach,
        final_success: finite(fs),
        final_return: finite(fr),
        auc: finite(auc),
        final_intrinsic_return: finite(tail_per_episode(&rows, FINAL_FRACTION, |r| {
            r.intrinsic_return
        })),
        final_pickup_rate: finite(tail_per_episode(&rows, FINAL_FRACTION, |r| r.pickup_rate)),
        final_e_positive: finite(tail_mean_e_positive(&rows, FINAL_FRACTION)),
        first_pickup_step: rows
            .iter()
            .find(|r| r.episodes > 0 && r.pickup_rate > 0.0)
            .map(|r| r.env_steps as f64),
        trap_updates: trap_updates(&j.dir, &rows),
    };
    Ok(SeedRun {
        summary,
        success,
        ret,
        auc,
        reach,
    })
}

/// The updates the beacon-trap detector marks in a run's rows: the detector replayed
/// over them with the run's form, beta and world (so that runs made before the
/// detector, or with another version of it, are judged by this one), or the rows' own
/// `trap` column when the run's configuration or world cannot be read.
fn trap_updates(dir: &Path, rows: &[MetricsRow]) -> u64 {
    let paths = RunPaths {
        dir: dir.to_path_buf(),
    };
    let replayed = RunConfig::load(&paths.config()).ok().and_then(|cfg| {
        let world = fulcrum_world::load_world(&cfg.world).ok()?;
        let mut d = TrapDetector::new(cfg.form(), cfg.beta, &world);
        Some(rows.iter().filter(|r| d.observe(r).is_some()).count() as u64)
    });
    replayed.unwrap_or_else(|| rows.iter().filter(|r| r.trap).count() as u64)
}

/// The median of `x` (NaN when empty).
fn median(x: &[f64]) -> f64 {
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
}

/// An arm's summary over its finished seeds (of `seeds`), and its samples.
fn arm_summary(
    arm: &Arm,
    seeds: usize,
    runs: Vec<SeedRun>,
    g: &[f64],
    budget: f64,
) -> (ArmSummary, Samples) {
    let s = Samples {
        censored: runs.iter().map(|r| r.reach.unwrap_or(budget)).collect(),
        aucs: runs.iter().map(|r| r.auc).collect(),
        events: runs
            .iter()
            .map(|r| (r.reach.unwrap_or(budget), r.reach.is_some()))
            .collect(),
        solved: (
            runs.iter().filter(|r| r.reach.is_some()).count(),
            runs.len(),
        ),
    };
    let succ_curves: Vec<Vec<f64>> = runs.iter().map(|r| r.success.clone()).collect();
    let ret_curves: Vec<Vec<f64>> = runs.iter().map(|r| r.ret.clone()).collect();
    let per_seed: Vec<SeedSummary> = runs.into_iter().map(|r| r.summary).collect();
    let reached: Vec<f64> = per_seed
        .iter()
        .filter_map(|s| s.steps_to_threshold)
        .collect();
    let col = |f: fn(&SeedSummary) -> Option<f64>| -> Vec<f64> {
        per_seed.iter().filter_map(f).collect()
    };
    let (sb, rb) = (stats::band(&succ_curves), stats::band(&ret_curves));
    let summary = ArmSummary {
        iqm_steps: finite(stats::iqm(&s.censored)),
        iqm_ci: stats::bootstrap_ci(&s.censored, stats::iqm, 2000, 0x1a2b, 0.95),
        median_steps: finite(median(&s.censored)),
        solved_by: stats::solved_by(&s.events, g)
            .into_iter()
            .map(finite)
            .collect(),
        name: arm.name.clone(),
        args: arm.args.clone(),
        seeds,
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
        trapped: per_seed.iter().filter(|s| s.trap_updates > 0).count(),
        success_mean: sb.iter().map(|b| finite(b.0)).collect(),
        success_std: sb.iter().map(|b| finite(b.1)).collect(),
        return_mean: rb.iter().map(|b| finite(b.0)).collect(),
        return_std: rb.iter().map(|b| finite(b.1)).collect(),
        per_seed,
    };
    (summary, s)
}

/// Arm `a` against arm `b` (the first arm).
fn compare(a: &str, sa: &Samples, b: &str, sb: &Samples) -> Comparison {
    Comparison {
        arm: a.to_string(),
        against: b.to_string(),
        steps_to_threshold: stats::welch(&sa.censored, &sb.censored),
        auc: stats::welch(&sa.aucs, &sb.aucs),
        fisher_p: stats::fisher_exact(sa.solved.0, sa.solved.1, sb.solved.0, sb.solved.1),
        log_rank: stats::log_rank(&sa.events, &sb.events),
    }
}
