//! The hidden child processes of a run, as the supervisor starts them: the learner
//! and the actors. Each dies with the supervisor, stops on SIGINT/SIGTERM, and checks
//! that the world it loads is the run's.

use std::io::Write;
use std::sync::atomic::Ordering;

use crate::error::Result;
use fulcrum_contracts::config::RunConfig;
use fulcrum_learner::metrics::MetricsRow;
use fulcrum_learner::paths::RunPaths;
use fulcrum_learner::process::{run_learner_with, Hooks, LearnerExit};
use fulcrum_learner::watch::Notice;
use fulcrum_world::World;

use crate::error::bad;
use crate::process::{die_with_parent, install_signal_handlers, signalled, STOP};
use crate::supervisor::{EXIT_INTERRUPTED, EXIT_PAUSED};
use fulcrum_contracts::lines::{ChildLine, LearnerProgress};
use fulcrum_world::family::load_world_or_family;

/// What the supervisor tells a child process (built into a command line by
/// [`crate::argv::child`]).
pub use crate::argv::ChildRequest;

/// A run directory's configuration and its world, refused where the world file has
/// changed since the run began (its content hash is the run's).
pub fn load_run(paths: &RunPaths) -> Result<(RunConfig, World)> {
    let cfg = RunConfig::load(&paths.config())?;
    let (w, _) = load_world_or_family(&cfg.world)?;
    if format!("{:016x}", w.content_hash()) != cfg.world_hash {
        return bad(format!(
            "the world '{}' differs from the run's (hash {})",
            cfg.world, cfg.world_hash
        ));
    }
    Ok((cfg, w))
}

fn child_setup(a: &ChildRequest) -> Result<(RunConfig, World, RunPaths)> {
    die_with_parent(a.parent);
    install_signal_handlers();
    let paths = RunPaths { dir: a.run.clone() };
    let (cfg, w) = load_run(&paths)?;
    Ok((cfg, w, paths))
}

/// The learner process: trains until the run's last update, a stop request or a
/// signal; exits 3 when paused on request, 130 when stopped by a signal.
pub fn learner_main(a: &ChildRequest) -> Result<()> {
    let (cfg, w, paths) = child_setup(a)?;
    let stop_after = a.stop_after_updates;
    let mut first: Option<u64> = None;
    let mut paused = false;
    let progress = |row: &MetricsRow, updates: u64| {
        let mut out = std::io::stdout().lock();
        let line = ChildLine::Progress(LearnerProgress {
            update: row.update,
            total: updates,
            env_steps: row.env_steps,
            success_rate: row.success_rate,
            extrinsic_return: row.extrinsic_return,
            sps: row.sps,
        });
        let _ = writeln!(out, "{line}");
        let _ = out.flush();
        let f = *first.get_or_insert(row.update - 1);
        if stop_after.is_some_and(|n| row.update - f >= n) {
            paused = true;
            STOP.store(true, Ordering::Relaxed);
        }
    };
    let notice = |n: &Notice| {
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{}", ChildLine::Notice(n.clone()));
        let _ = out.flush();
    };
    let hooks = Hooks {
        notice: Box::new(notice),
        evaluate: match cfg.eval_every {
            0 => None,
            _ => Some(crate::eval::periodic(&cfg, &w)?),
        },
    };
    let exit = run_learner_with(&w, &cfg, &paths, &a.namespace, &STOP, progress, hooks)?;
    match exit {
        LearnerExit::Finished => Ok(()),
        LearnerExit::Interrupted if paused && !signalled() => {
            Err(crate::error::Error::ChildExit(EXIT_PAUSED as u8))
        }
        LearnerExit::Interrupted => Err(crate::error::Error::ChildExit(EXIT_INTERRUPTED as u8)),
    }
}

/// An actor process.
pub fn actor_main(a: &ChildRequest) -> Result<()> {
    let (cfg, w, paths) = child_setup(a)?;
    let run_tag = match &a.run_tag {
        Some(t) => match u64::from_str_radix(t, 16) {
            Ok(v) => Some(v),
            Err(_) => return bad(format!("the run tag '{t}' is not a hex number")),
        },
        None => None,
    };
    fulcrum_actors::run_actor(
        &w,
        &cfg,
        &paths.checkpoint(),
        &a.namespace,
        run_tag,
        fulcrum_actors::ActorId {
            index: a.index,
            incarnation: a.incarnation,
        },
        &STOP,
    )?;
    Ok(())
}
