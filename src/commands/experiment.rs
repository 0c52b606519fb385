//! `fulcrum experiment`: the arms asked for as `train` flag lists, each checked exactly
//! as `train` will check it, then the experiment run by [`fulcrum_run::experiment`]
//! (scheduling, resuming, aggregation, report) and its table printed; with `--worlds
//! gen:N`, the same on every world of a generated set, pooled.

use std::path::PathBuf;

use crate::commands::bad;
use anyhow::{Context, Result};
use clap::Parser;
use fulcrum_run::argv;
use fulcrum_run::experiment::{
    prepare_set, Arm, ExperimentRequest, SetRequest, SetWorld, SlurmOptions,
};
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
    if let Some(dir) = &a.collect {
        return collect(a, dir);
    }
    if let Some(dir) = &a.task {
        let (Some(arm), Some(seed)) = (&a.arm, a.seed) else {
            return bad("--task needs --arm and --seed");
        };
        fulcrum_run::experiment::run_task(dir, arm, seed)?;
        return Ok(());
    }
    let slurm = a.launcher == "slurm";
    if a.dry_run && !slurm {
        return bad(
            "--dry-run goes with --launcher slurm (a local experiment has no script to print)",
        );
    }
    if !slurm
        && (a.slurm_partition.is_some()
            || a.slurm_cpus.is_some()
            || a.slurm_mem.is_some()
            || !a.sbatch.is_empty())
    {
        return bad("the --slurm-* and --sbatch flags go with --launcher slurm");
    }
    if a.seeds == 0 {
        return bad("--seeds must be at least 1");
    }
    if a.actors == 0 {
        return bad("--actors must be at least 1");
    }
    check_statistics(a)?;
    let arms = arms(a)?;
    if let Some(set) = &a.worlds {
        // Slurm's options are checked before the set's files are written.
        let slurm_opts = slurm.then(|| slurm_options(a)).transpose()?;
        if let Some(o) = &slurm_opts {
            fulcrum_run::experiment::check_options(o)?;
        }
        let req = set_request(a, set, arms)?;
        return match slurm_opts {
            Some(o) => report_launch(&fulcrum_run::experiment::launch_set(&req, &o)?),
            None => {
                print!("{}", fulcrum_run::experiment::run_set(&req)?);
                Ok(())
            }
        };
    }
    let world = a.world.clone().unwrap_or_default();
    let req = request(a, &world, &arms, a.out.clone())?;
    if slurm {
        let l = fulcrum_run::experiment::launch(&req, &slurm_options(a)?)?;
        return report_launch(&l);
    }
    let markdown = fulcrum_run::experiment::run(&req)?;
    print!("{markdown}");
    Ok(())
}

/// What `--launcher slurm` asks of Slurm.
fn slurm_options(a: &ExperimentArgs) -> Result<SlurmOptions> {
    Ok(SlurmOptions {
        partition: a.slurm_partition.clone(),
        time: a.slurm_time.clone(),
        cpus: a.slurm_cpus,
        mem: a.slurm_mem.clone(),
        extra: a.sbatch.clone(),
        submit: !a.dry_run,
        exe: std::env::current_exe().context("cannot find the fulcrum executable")?,
    })
}

/// `fulcrum experiment ... --launcher slurm`: what was written and submitted (or the
/// script printed, with `--dry-run`).
fn report_launch(l: &fulcrum_run::experiment::Launch) -> Result<()> {
    let dir = l.dir.display();
    let Some(script) = &l.script else {
        eprintln!("fulcrum experiment: every run in {dir} has finished; the summary: fulcrum experiment --collect {dir}");
        return Ok(());
    };
    match &l.job {
        Some(job) => {
            eprintln!(
                "fulcrum experiment: submitted {} array tasks as Slurm job {job} ({})\nwhen they have ended: fulcrum experiment --collect {dir}",
                l.tasks,
                script.display()
            );
            println!("{job}");
        }
        None => {
            eprintln!(
                "fulcrum experiment: wrote {} ({} array tasks), not submitted; submit it with: sbatch {}",
                script.display(),
                l.tasks,
                script.display()
            );
            print!("{}", l.text);
        }
    }
    Ok(())
}

/// `--threshold` and `--smooth`, which the summary uses.
fn check_statistics(a: &ExperimentArgs) -> Result<()> {
    if !(a.threshold > 0.0 && a.threshold <= 1.0) {
        return bad(format!(
            "--threshold {} must be a success rate in (0, 1]",
            a.threshold
        ));
    }
    if a.smooth == 0 {
        return bad("--smooth must be at least 1 update");
    }
    Ok(())
}

/// `fulcrum experiment --collect DIR`.
fn collect(a: &ExperimentArgs, dir: &std::path::Path) -> Result<()> {
    if a.world.is_some() || a.worlds.is_some() || a.launcher != "local" || a.dry_run {
        return bad("--collect DIR takes no world, --worlds, --launcher or --dry-run: the directory says what the experiment is");
    }
    check_statistics(a)?;
    let c = fulcrum_run::experiment::collect(dir, a.threshold, a.smooth)?;
    print!("{}", c.markdown);
    let total = c.finished + c.missing.len() + c.failed.len() + c.unfinished.len();
    eprintln!(
        "fulcrum experiment: {} of {total} runs finished; summary: {}",
        c.finished,
        dir.join("summary.md").display()
    );
    for (name, why) in &c.failed {
        eprintln!("  failed: {name}: {why}");
    }
    for (name, steps) in &c.unfinished {
        eprintln!("  unfinished: {name} (checkpoint at {steps} env steps)");
    }
    for name in &c.missing {
        eprintln!("  missing: {name} (never started)");
    }
    if c.finished < total {
        anyhow::bail!(
            "{} of {total} runs have not finished: the summary pools the finished ones; submit the experiment again (the same command) to run the rest",
            total - c.finished
        );
    }
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
/// world's experiment checked (then run and pooled, or launched on Slurm).
fn set_request(a: &ExperimentArgs, set: &str, arms: Vec<Arm>) -> Result<SetRequest> {
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
    let files: Vec<(String, String, u32)> = worlds
        .iter()
        .map(|w| (w.world.name.clone(), w.text.clone(), w.fewest_steps))
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
    Ok(SetRequest {
        description: gen.to_string(),
        dir: set_dir,
        worlds: reqs,
    })
}
