//! The experiment's report: the Markdown table and the two figures.

use std::path::Path;

use crate::error::{Context, Result};

use super::summary::{ArmSummary, MeanStd, Summary};
use super::FINAL_FRACTION;
use crate::stats::Welch;

/// Writes `summary.json`, `summary.md` and the plots into `dir`; the Markdown.
pub(super) fn write(summary: &Summary, dir: &Path) -> Result<String> {
    let md = markdown(summary);
    let json = serde_json::to_string_pretty(summary).context("cannot encode summary.json")?;
    fulcrum_contracts::fsio::write_atomic(&dir.join("summary.json"), json.as_bytes())
        .with_context(|| format!("cannot write {}", dir.join("summary.json").display()))?;
    fulcrum_contracts::fsio::write_atomic(&dir.join("summary.md"), md.as_bytes())
        .with_context(|| format!("cannot write {}", dir.join("summary.md").display()))?;
    draw(summary, dir)?;
    Ok(md)
}

pub(super) fn steps_text(x: f64) -> String {
    if x >= 1e6 {
        format!("{:.2}M", x / 1e6)
    } else if x >= 1e3 {
        format!("{:.0}k", x / 1e3)
    } else {
        format!("{x:.0}")
    }
}

pub(super) fn ms(v: &MeanStd, f: fn(f64) -> String) -> String {
    match (v.mean, v.std) {
        (Some(m), Some(s)) => format!("{} ± {}", f(m), f(s)),
        _ => "-".into(),
    }
}

pub(super) fn markdown(s: &Summary) -> String {
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
         | arm | intrinsic return per episode | steps with E > 0 | tool pick-up rate | first pick-up at (seeds) | seeds marked as trapped |\n|---|---|---|---|---|---|\n",
        FINAL_FRACTION * 100.0
    );
    for a in &s.arms {
        t += &format!(
            "| {} | {} | {} | {} | {} ({}/{}) | {}/{} |\n",
            a.name,
            ms(&a.final_intrinsic_return, two),
            ms(&a.final_e_positive, two),
            ms(&a.final_pickup_rate, two),
            ms(&a.first_pickup_step, steps_text),
            a.picked,
            a.finished,
            a.trapped,
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

pub(super) fn p_text(p: f64) -> String {
    if p < 0.001 {
        "< 0.001".into()
    } else {
        format!("{p:.3}")
    }
}

/// The two figures, each as PNG and SVG.
pub(super) fn draw(s: &Summary, dir: &Path) -> Result<()> {
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
