//! `fulcrum experiment`: the arms asked for as `train` flag lists, each checked exactly
//! as `train` will check it, then the experiment run by [`fulcrum_run::experiment`]
//! (scheduling, resuming, aggregation, report) and its table printed.

use anyhow::{Context, Result};
use clap::Parser;
use fulcrum_run::bad;
use fulcrum_run::experiment::{Arm, ExperimentRequest};
use fulcrum_run::plan::plan;
use fulcrum_shared::View;

use crate::cli::{ExperimentArgs, TrainArgs};

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
    if let Some(views) = &a.views {
        out = with_views(out, views)?;
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

/// Every arm once per view of `views` (comma separated): the full view's keeps the arm's
/// name and flags, a crop's is `<arm>-crop<R>` with `--view crop:R`.
fn with_views(arms: Vec<Arm>, views: &str) -> Result<Vec<Arm>> {
    let mut parsed: Vec<View> = Vec::new();
    for v in views.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        match v.parse::<View>() {
            Ok(v) => parsed.push(v),
            Err(e) => return bad(format!("--views: {e}")),
        }
    }
    if parsed.is_empty() {
        return bad("--views names no view: give full, crop:R or both, comma separated");
    }
    let mut out = Vec::new();
    for view in parsed {
        for arm in &arms {
            out.push(match view {
                View::Full => arm.clone(),
                View::Crop(r) => Arm {
                    name: format!("{}-crop{r}", arm.name),
                    args: [&arm.args[..], &["--view".into(), view.to_string()]].concat(),
                },
            });
        }
    }
    Ok(out)
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
        let (cfg, w) =
            plan(&parsed.train.request()?).with_context(|| format!("arm '{}'", arm.name))?;
        world_hash = cfg.world_hash.clone();
        world_name = w.name.clone();
        steps = cfg.updates() * cfg.batch() as u64;
    }

    let markdown = fulcrum_run::experiment::run(&ExperimentRequest {
        world: a.world.clone(),
        world_name,
        world_hash,
        steps,
        seeds: a.seeds,
        actors: a.actors,
        envs_per_actor: a.envs_per_actor,
        extra: a.train_args.clone(),
        arms,
        parallel: a.parallel,
        out: a.out.clone(),
        threshold: a.threshold,
        smooth: a.smooth,
    })?;
    print!("{markdown}");
    Ok(())
}
