//! Reading the finished runs into the experiment's numbers: curves on a common grid,
//! per-seed and per-arm summaries, and each arm compared with the first.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use fulcrum_learner::run::{read_metrics, MetricsRow, RunPaths};
use serde::Serialize;

use super::report::{draw, markdown};
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

/// Reads the finished runs of `jobs`, writes summary.{md,json} and the plots.
pub(super) fn aggregate(
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
                .map(Point::from)
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
