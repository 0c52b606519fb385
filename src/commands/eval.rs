//! `fulcrum eval RUN`: the run's policy played for N episodes, greedy or sampled, on its
//! world or another of the same shape, or (a run on a world family) on held-out or
//! training layouts; prints success, return, length, tool use and tool choice with 95%
//! intervals and appends a row to `RUN/eval.csv`.

use crate::commands::bad;
use anyhow::{Context, Result};
use fulcrum_contracts::config::RunConfig;
use fulcrum_run::eval::{evaluate, summarise, Estimate};
use fulcrum_run::BadRequest;
use fulcrum_world::family::load_world_or_family;
use fulcrum_world::{load_world, EvalLayouts};

use crate::cli::EvalArgs;

/// `fulcrum eval`.
pub fn run(a: &EvalArgs) -> Result<()> {
    let paths = fulcrum_run::plan::run_dir(&a.run)?;
    let cfg = RunConfig::load(&paths.config())?;
    let (run_world, _) = load_world_or_family(&cfg.world)?;
    let which = match (&a.layouts, cfg.layouts) {
        (None, None) => None,
        (Some(l), Some(_)) => Some(EvalLayouts::parse(l).map_err(BadRequest)?),
        // A run on a family is evaluated on held-out layouts unless told otherwise.
        (None, Some(_)) => Some(EvalLayouts::parse("test:100").map_err(BadRequest)?),
        (Some(l), None) => {
            return bad(format!(
                "--layouts {l} needs a run on a world family, and {} trained on the world '{}'",
                a.run.display(),
                cfg.world_name
            ))
        }
    };
    let (worlds, label) =
        match (&a.world, &which, cfg.layouts) {
            (Some(_), Some(_), Some(_)) => return bad(
                "--world and --layouts contradict each other: a run on a family plays its layouts",
            ),
            (_, Some(which), Some(train)) => (
                fulcrum_run::eval::layout_worlds(&cfg.world, which, train)?,
                which.label(),
            ),
            (Some(w), _, _) => (vec![load_world(w)?], String::new()),
            _ => (vec![run_world.clone()], String::new()),
        };
    let episodes = a
        .episodes
        .unwrap_or(if label.is_empty() { 100 } else { worlds.len() });
    if !(1..=100_000).contains(&episodes) {
        return bad(format!("--episodes {episodes} must be 1 to 100000"));
    }
    let world = &worlds[0];
    let name = if label.is_empty() {
        world.name.clone()
    } else {
        cfg.world_name.clone()
    };
    let ckpt = a.checkpoint.clone().unwrap_or_else(|| paths.checkpoint());
    let greedy = !a.sample;
    let seed = a.seed.unwrap_or(cfg.seed);
    let (eps, update, steps) = evaluate(
        &paths, &cfg, &run_world, &worlds, &ckpt, episodes, greedy, seed,
    )?;
    let s = summarise(&eps);
    let mode = if greedy { "greedy" } else { "sample" };
    let iv = |e: &Estimate, pct: bool| {
        if pct {
            format!("{:.3} (95% CI {:.3} to {:.3})", e.value, e.lo, e.hi)
        } else {
            format!("{:.2} (95% CI {:.2} to {:.2})", e.value, e.lo, e.hi)
        }
    };
    let on = if label.is_empty() {
        format!("world '{name}'")
    } else {
        format!("{} layouts of '{name}' ({label})", worlds.len())
    };
    println!(
        "{}: {} episodes of the policy of update {update} ({steps} env steps), {mode}, on {on}",
        a.run.display(),
        s.episodes,
    );
    println!("success rate    {}", iv(&s.success, true));
    println!("return          {}", iv(&s.ret, false));
    println!("episode length  {}", iv(&s.length, false));
    println!("tool use        {}", iv(&s.tool_use, true));
    match world.fitting_tools().filter(|_| label.is_empty()) {
        None if !label.is_empty() => println!(
            "tool choice     {} (first tool used is one that fits the layout's task object)",
            iv(&s.tool_choice, true)
        ),
        Some(fit) => println!(
            "tool choice     {} (first tool used is one that fits the task: {})",
            iv(&s.tool_choice, true),
            fit.iter()
                .map(|&k| world.tools[k].name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ),
        None => println!("tool choice     - (no tool fits a task of this world)"),
    }
    let path = paths.eval();
    let mut row = s.row(update, steps, &name, mode, seed);
    row.layouts = label;
    fulcrum_learner::evalcsv::append(&path, &row)
        .with_context(|| format!("cannot write {}", path.display()))?;
    println!("appended to {}", path.display());
    Ok(())
}
