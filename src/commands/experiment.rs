//! `fulcrum experiment`: the arms asked for as `train` flag lists, each checked exactly
//! as `train` will check it, then the experiment run by [`fulcrum_run::experiment`]
//! (scheduling, resuming, aggregation, report) and its table printed; with `--worlds
//! gen:N`, the same on every world of a generated set, pooled.

use std::path::PathBuf;

use crate::commands::bad;
use anyhow::{Context, Result};
use clap::Parser;
use fulcrum_run::argv;
use fulcrum_run::experiment::{prepare_set, Arm, ExperimentRequest, SetRequest, SetWorld};
use fulcrum_run::plan::plan;
use fulcrum_run::process::utc_stamp;
use fulcrum_run::BadRequest;
use fulcrum_world::generate::{GenError, GenSet};
use fulcrum_world::View;

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
    let form = a.intrinsic.as_str();
    for name in a.arms.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let Some(args) = argv::arm_flags(name, form, a.beta) else {
            return bad(format!(
                "--arms: unknown arm '{name}' (arms: {}; for betas use --beta-sweep)",
                argv::ARMS
            ));
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
                args: argv::form_flags(form, Some(v)),
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
                    args: [&arm.args[..], &argv::view_flags(&view)[..]].concat(),
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
    if let Some(set) = &a.worlds {
        return run_set(a, set, arms);
    }
    let world = a.world.clone().unwrap_or_default();
    let req = request(a, &world, &arms, a.out.clone())?;
    let markdown = fulcrum_run::experiment::run(&req)?;
    print!("{markdown}");
    Ok(())
}

/// The experiment of `arms` on `world` (a built-in name or a file), every arm's runs
/// checked exactly as `train` will check them, before anything starts.
fn request(
    a: &ExperimentArgs,
    world: &str,
    arms: &[Arm],
    out: Option<PathBuf>,
) -> Result<ExperimentRequest> {
    let mut world_hash = String::new();
    let mut steps = 0;
    let mut world_name = String::new();
    for arm in arms {
        let argv = argv::train(&argv::TrainJob::New(argv::NewRun {
            world: world.to_string(),
            seed: None,
            steps: a.steps,
            actors: Some(a.actors),
            envs_per_actor: Some(a.envs_per_actor),
            checkpoint_every: None,
            out: None,
            flags: [&arm.args[..], &a.train_args[..]].concat(),
        }));
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
            || parsed.train.fixed.seed.is_some()
        {
            return bad("the flags after -- may not set --resume, --out or --seed: the experiment chooses them");
        }
        let (cfg, w) =
            plan(&parsed.train.request()?).with_context(|| format!("arm '{}'", arm.name))?;
        world_hash = cfg.world_hash.clone();
        world_name = w.name.clone();
        steps = cfg.updates() * cfg.batch() as u64;
    }
    Ok(ExperimentRequest {
        world: world.to_string(),
        world_name,
        world_hash,
        steps,
        seeds: a.seeds,
        actors: a.actors,
        envs_per_actor: a.envs_per_actor,
        extra: a.train_args.clone(),
        arms: arms.to_vec(),
        parallel: a.parallel,
        out,
        threshold: a.threshold,
        smooth: a.smooth,
    })
}

/// `fulcrum experiment --worlds gen:N...`: the set's worlds generated and written, each
/// world's experiment checked, then all run and pooled.
fn run_set(a: &ExperimentArgs, set: &str, arms: Vec<Arm>) -> Result<()> {
    let gen: GenSet = set
        .parse()
        .map_err(|e: GenError| BadRequest(format!("--worlds {}", e.0)))?;
    let worlds = gen
        .worlds()
        .map_err(|e| BadRequest(format!("--worlds {}", e.0)))?;
    let dir = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("experiments").join(format!("gen-{}", utc_stamp())));
    let files: Vec<(String, String)> = worlds
        .iter()
        .map(|w| (w.world.name.clone(), w.text.clone()))
        .collect();
    let (set_dir, paths) = prepare_set(&dir, &gen.to_string(), &files)?;
    let mut reqs = Vec::with_capacity(worlds.len());
    for (w, path) in worlds.iter().zip(&paths) {
        let name = w.world.name.clone();
        let request = request(a, &path.display().to_string(), &arms, Some(dir.join(&name)))
            .with_context(|| format!("world {name}"))?;
        reqs.push(SetWorld {
            name,
            fewest_steps: w.fewest_steps,
            request,
        });
    }
    let markdown = fulcrum_run::experiment::run_set(&SetRequest {
        description: gen.to_string(),
        dir: set_dir,
        worlds: reqs,
    })?;
    print!("{markdown}");
    Ok(())
}
