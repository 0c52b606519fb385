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
//! Crashed actors are restarted after a back-off, each within its own budget of
//! restarts in a window (as the supervisor's children: `fulcrum_run::restart`); a lost link is the bridge's business (zenoh
//! reconnects, the actors wait for weights meanwhile). The host stops when the run is
//! over (the learner's bridge says so), on SIGINT/SIGTERM, or when the bridge fails.

use std::os::unix::process::CommandExt;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};

use crate::cli::ActorHostArgs;
use fulcrum_bridge::{actor_id, default_dir, parse_joined};
use fulcrum_run::argv::{self, ChildKind};
use fulcrum_run::bad;
use fulcrum_run::child::ChildRequest;
use fulcrum_run::process::{
    cores, hostname, install_signal_handlers, spawn_until, stop_children, Ready, STOP,
};
use fulcrum_run::restart::{Budget, RestartPolicy};
use fulcrum_shared::lines::ChildLine;

/// `fulcrum actor-host`.
pub fn run(a: &ActorHostArgs) -> Result<()> {
    install_signal_handlers();
    let k = a.actors.unwrap_or_else(|| cores().saturating_sub(1).max(1));
    if k == 0 || k > fulcrum_shared::traj::MAX_ACTORS {
        return bad(format!(
            "--actors {k} must be 1 to {}",
            fulcrum_shared::traj::MAX_ACTORS
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
    let (mut bridge, joined, rx) = match spawn_until(cmd, "the bridge", None, parse_joined)? {
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
    let start = |j: usize, inc: u32| -> Result<Child> {
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
            .with_context(|| format!("cannot start actor {j}"))
    };
    let mut actors: Vec<(Child, u32)> = Vec::with_capacity(k);
    for j in 0..k {
        actors.push((start(j, 0)?, 0));
    }
    // Each actor has its own budget of restarts in a window, and waits a back-off
    // before each restart (as the supervisor's children do).
    let policy = RestartPolicy {
        max: a.max_restarts,
        window: Duration::from_secs_f64(a.restart_window),
    };
    let mut budgets = vec![Budget::default(); k];
    // An actor that stopped and waits for its back-off: when to restart it.
    let mut due: Vec<Option<Instant>> = vec![None; k];
    let mut over = false;
    let result = loop {
        while let Ok(line) = rx.try_recv() {
            if ChildLine::parse(&line) == Some(ChildLine::RunOver) {
                over = true;
            }
        }
        if STOP.load(Ordering::Relaxed) {
            break Ok(());
        }
        if let Some(s) = bridge.try_wait()? {
            while let Ok(line) = rx.recv_timeout(Duration::from_millis(100)) {
                over |= ChildLine::parse(&line) == Some(ChildLine::RunOver);
            }
            break if over || s.success() {
                eprintln!("fulcrum actor-host: the run is over");
                Ok(())
            } else {
                Err(anyhow::anyhow!("the bridge stopped ({s})"))
            };
        }
        let mut failure = None;
        let now = Instant::now();
        for (j, slot) in actors.iter_mut().enumerate() {
            if let Some(at) = due[j] {
                if now >= at {
                    due[j] = None;
                    let inc = slot.1 + 1;
                    *slot = (start(j, inc)?, inc);
                }
                continue;
            }
            if let Some(s) = slot.0.try_wait()? {
                match budgets[j].stopped(&policy, now) {
                    Ok(r) => {
                        eprintln!(
                            "fulcrum actor-host: actor {j} stopped ({s}); restarting it after {:.1} s (restart {} of {} allowed in {} s)",
                            r.delay.as_secs_f64(),
                            r.n,
                            policy.max,
                            policy.window.as_secs_f64()
                        );
                        due[j] = Some(now + r.delay);
                    }
                    Err(o) => {
                        failure = Some(anyhow::anyhow!(
                            "actor {j} stopped ({s}), its stop number {} within {} s: over its budget of {} restarts in {} s",
                            o.n,
                            policy.window.as_secs_f64(),
                            policy.max,
                            policy.window.as_secs_f64()
                        ));
                        break;
                    }
                }
            }
        }
        if let Some(e) = failure {
            break Err(e);
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    // Stop actors and the bridge.
    let mut all: Vec<Child> = actors.into_iter().map(|(c, _)| c).collect();
    all.push(bridge);
    stop_children(all);
    fulcrum_empowerment::service::clean_dead_nodes();
    result
}
