//! `fulcrum actor-host` (feature `multihost`): actors on this host for a run whose
//! learner is on another.
//!
//! ```text
//! fulcrum actor-host --connect ADDR     supervisor
//!  |- fulcrum bridge --connect ADDR     joins the run, writes its config and world into
//!  |                                    DIR, forwards chunks / weights / lookups
//!  '- fulcrum __actor x K               this host's actors (ids host * 1024 + j), on
//!                                       the host's own shared-memory namespace
//! ```
//!
//! This command checks the host's settings, starts the bridge and waits until it has
//! joined; the supervision is the run library's (`fulcrum_run::host`): crashed actors
//! are restarted after a back-off, each within its own budget of restarts in a window
//! (as the supervisor's children: `fulcrum_run::restart`); a lost link is the bridge's
//! business (zenoh reconnects, the actors wait for weights meanwhile). The host stops
//! when the run is over (the learner's bridge says so), on SIGINT/SIGTERM, or when the
//! bridge fails.

use std::os::unix::process::CommandExt;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use anyhow::{Context, Result};

use crate::cli::ActorHostArgs;
use crate::commands::bad;
use fulcrum_bridge::{actor_id, default_dir, parse_joined};
use fulcrum_run::argv::{self, ChildKind};
use fulcrum_run::child::ChildRequest;
use fulcrum_run::host::{supervise_host, HostRun};
use fulcrum_run::process::{cores, hostname, install_signal_handlers, spawn_until, Ready};
use fulcrum_run::restart::RestartPolicy;

/// `fulcrum actor-host`.
pub fn run(a: &ActorHostArgs) -> Result<()> {
    install_signal_handlers();
    let k = a.actors.unwrap_or_else(|| cores().saturating_sub(1).max(1));
    if k == 0 || k > fulcrum_contracts::traj::MAX_ACTORS {
        return bad(format!(
            "--actors {k} must be 1 to {}",
            fulcrum_contracts::traj::MAX_ACTORS
        ));
    }
    if !(a.restart_window.is_finite() && a.restart_window > 0.0 && a.restart_window < 1e9) {
        return bad(format!(
            "--restart-window {} must be a positive number of seconds",
            a.restart_window
        ));
    }
    // Checked here so that a host without the secret stops before it starts anything;
    // the bridge gets it through its environment, never its command line.
    let secret = super::bridge::secret(a.secret_file.as_deref())?;
    let name = a.name.clone().unwrap_or_else(hostname);
    let dir = a.dir.clone().unwrap_or_else(|| default_dir(&name));
    let exe = std::env::current_exe().context("cannot find the fulcrum executable")?;
    let args = argv::bridge_connect(&argv::BridgeConnect {
        connect: a.connect.clone(),
        run: dir.clone(),
        name: name.clone(),
        give_up: a.give_up,
        parent: std::process::id(),
        world: a.world.clone(),
        run_id: a.run_id.clone(),
        zenoh: argv::Zenoh {
            session_timeout: a.zenoh.session_timeout,
            config: a.zenoh.zenoh_config.clone(),
        },
    });
    eprintln!(
        "fulcrum actor-host: '{name}' joining the run at {} with {k} actors",
        a.connect
    );
    let mut cmd = Command::new(&exe);
    cmd.args(&args)
        .env(fulcrum_bridge::SECRET_ENV, secret.expose())
        .stdin(Stdio::null())
        .process_group(0);
    // Wait for the bridge to join.
    let (bridge, joined, rx) = match spawn_until(cmd, "the bridge", None, parse_joined)? {
        Ready::Ready(bridge, joined, rx) => (bridge, joined, rx),
        Ready::Stopped => return Ok(()),
        Ready::Exited(s) => {
            return match s.code() {
                Some(2) => bad("the bridge refused to join (its message is above)"),
                _ => Err(anyhow::anyhow!("the bridge stopped before it joined ({s})")),
            }
        }
    };
    eprintln!(
        "fulcrum actor-host: joined run {} as host {}; actors {}..{}",
        joined.local_ns,
        joined.host,
        actor_id(joined.host, 0),
        actor_id(joined.host, k - 1)
    );
    let start = |j: usize, inc: u32| -> fulcrum_run::error::Result<Child> {
        Command::new(&exe)
            .args(argv::child(
                ChildKind::Actor,
                &ChildRequest {
                    run: dir.clone(),
                    namespace: joined.local_ns.clone(),
                    parent: std::process::id(),
                    index: actor_id(joined.host, j),
                    incarnation: inc,
                    stop_after_updates: None,
                    run_tag: Some(format!("{:016x}", joined.run_tag)),
                },
            ))
            .env("RAYON_NUM_THREADS", "1")
            .env("CANDLE_NUM_THREADS", "1")
            .stdin(Stdio::null())
            .process_group(0)
            .spawn()
            .map_err(|e| {
                fulcrum_run::Error::Context(fulcrum_contracts::context::Contextual {
                    what: format!("cannot start actor {j}"),
                    source: Some(Box::new(e)),
                })
            })
    };
    // Each actor has its own budget of restarts in a window, and waits a back-off
    // before each restart (as the supervisor's children do).
    supervise_host(HostRun {
        bridge,
        bridge_lines: rx,
        actors: k,
        policy: RestartPolicy {
            max: a.max_restarts,
            window: Duration::from_secs_f64(a.restart_window),
        },
        start: Box::new(start),
    })?;
    Ok(())
}
