//! `fulcrum eval RUN`: the run's policy played for N episodes, greedy or sampled, on its
//! world or another of the same shape; prints success, return, length and tool use with
//! 95% intervals and appends a row to `RUN/eval.csv`.

use crate::commands::bad;
use anyhow::{Context, Result};
use fulcrum_contracts::config::RunConfig;
use fulcrum_run::eval::{evaluate, summarise, Estimate};
use fulcrum_world::load_world;

use crate::cli::EvalArgs;

/// `fulcrum eval`.
pub fn run(a: &EvalArgs) -> Result<()> {
    let paths = fulcrum_run::plan::run_dir(&a.run)?;
    if !(1..=100_000).contains(&a.episodes) {
        return bad(format!("--episodes {} must be 1 to 100000", a.episodes));
    }
    let cfg = RunConfig::load(&paths.config())?;
    let run_world = load_world(&cfg.world)?;
    let world = match &a.world {
        Some(w) => load_world(w)?,
        None => run_world.clone(),
    };
    let ckpt = a.checkpoint.clone().unwrap_or_else(|| paths.checkpoint());
    let greedy = !a.sample;
    let seed = a.seed.unwrap_or(cfg.seed);
    let (eps, update, steps) = evaluate(
        &paths, &cfg, &run_world, &world, &ckpt, a.episodes, greedy, seed,
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
    println!(
        "{}: {} episodes of the policy of update {update} ({steps} env steps), {mode}, on world '{}'",
        a.run.display(),
        s.episodes,
        world.name
    );
    println!("success rate    {}", iv(&s.success, true));
    println!("return          {}", iv(&s.ret, false));
    println!("episode length  {}", iv(&s.length, false));
    println!("tool use        {}", iv(&s.tool_use, true));
    match world.fitting_tools() {
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
    fulcrum_learner::evalcsv::append(&path, &s.row(update, steps, &world.name, mode, seed))
        .with_context(|| format!("cannot write {}", path.display()))?;
    println!("appended to {}", path.display());
    Ok(())
}
