//! `fulcrum train`: plan the run, supervise it, say how it ended; and the hidden child
//! processes `__learner` and `__actor` the supervisor starts.
//!
//! The work is in `fulcrum_run`: [`fulcrum_run::plan`] checks the request and writes the
//! run directory, [`fulcrum_run::supervisor`] runs the children until the run ends.

use crate::commands::bad;
use anyhow::{Context, Result};
use fulcrum_contracts::config::HorizonMode;
use fulcrum_learner::metrics::read_metrics;
use fulcrum_run::plan::{resolve, Planned};
use fulcrum_run::supervisor::{supervise, Options, Outcome};
use fulcrum_run::Interrupted;

use crate::cli::{ChildArgs, TrainArgs};

/// `fulcrum train`.
pub fn run(a: &TrainArgs) -> Result<()> {
    if a.listen.is_some() && !cfg!(feature = "multihost") {
        return bad(super::NO_MULTIHOST.replace("{}", "--listen"));
    }
    if a.stall_timeout.is_some() && a.listen.is_none() {
        return bad("--stall-timeout applies to runs with --listen (actors on other hosts)");
    }
    let (restarts, watchdog_floor) = a.supervision()?;
    let Planned {
        cfg,
        world: w,
        paths,
        resumed,
        lock: _lock,
    } = resolve(&a.request()?)?;
    fulcrum_run::process::install_signal_handlers();
    let ns = format!(
        "t{:x}{:x}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.subsec_nanos())
            .unwrap_or(0)
    );
    eprintln!(
        "fulcrum train: {} run {} in {} ({} actors x {} worlds, {} learner threads, {} updates of {} steps{}{}{}; namespace {ns})",
        if resumed { "resuming" } else { "starting" },
        cfg.run_id,
        paths.dir.display(),
        cfg.actors,
        cfg.envs_per_actor,
        cfg.learner_threads,
        cfg.updates(),
        cfg.batch(),
        if cfg.empowerment {
            format!(
                ", {} intrinsic reward, beta {}{}",
                cfg.intrinsic,
                // Four significant digits (config.toml holds the exact value).
                format!("{:.4e}", cfg.beta)
                    .parse::<f64>()
                    .unwrap_or(cfg.beta),
                if cfg.horizon_mode == HorizonMode::Fixed {
                    ", one horizon"
                } else {
                    ""
                }
            )
        } else {
            ", no empowerment".into()
        },
        if cfg.intrinsic_value_head {
            ", two value heads"
        } else {
            ""
        },
        if cfg.action_mask {
            ""
        } else {
            ", unmasked actions"
        },
    );
    let opts = Options {
        namespace: ns,
        exe: std::env::current_exe().context("cannot find the fulcrum executable")?,
        listen: a.listen.clone(),
        session_timeout: a.zenoh.session_timeout,
        zenoh_config: a.zenoh.zenoh_config.clone(),
        restarts,
        watchdog_floor,
        stop_after: a.stop_after_updates,
    };
    let result = supervise(&cfg, &paths, &opts);
    let drawn = fulcrum_run::curve::draw_curve(&w, &paths);
    match result? {
        Outcome::Finished => {
            let rows = read_metrics(&paths.metrics()).unwrap_or_default();
            if let Some(r) = rows.last() {
                println!(
                    "fulcrum train: done: {} env steps in {:.1} s; last update: success rate {:.2}, extrinsic return {:.3}, intrinsic {:.4} bits/step",
                    r.env_steps, r.wall_s, r.success_rate, r.extrinsic_return, r.intrinsic_mean
                );
            }
            println!("run directory: {}", paths.dir.display());
            if let Some(p) = drawn {
                println!("learning curve: {}", p.display());
            }
            if let Some(n) = a.record.filter(|&n| n > 0) {
                let out = paths.dir.join("episodes");
                let files =
                    fulcrum_run::record::record(&paths, &cfg, &w, n, cfg.seed, &out, false)?;
                println!(
                    "{} episodes of the final policy: {}",
                    files.len(),
                    out.display()
                );
            }
            Ok(())
        }
        Outcome::Paused => {
            println!(
                "fulcrum train: stopped as asked, checkpoint written; continue with `fulcrum train --resume {}`",
                paths.dir.display()
            );
            Ok(())
        }
        Outcome::Interrupted => Err(Interrupted(format!(
            "interrupted; checkpoint written; continue with `fulcrum train --resume {}`",
            paths.dir.display()
        ))
        .into()),
    }
}

/// `fulcrum __learner`.
pub fn learner_process(a: &ChildArgs) -> Result<()> {
    Ok(fulcrum_run::child::learner_main(&a.request())?)
}

/// `fulcrum __actor`.
pub fn actor_process(a: &ChildArgs) -> Result<()> {
    Ok(fulcrum_run::child::actor_main(&a.request())?)
}
