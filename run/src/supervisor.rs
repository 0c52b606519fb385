//! The supervisor of a training run: it starts the empowerment service, the learner,
//! the bridge to other hosts and the actors as child processes of the `fulcrum`
//! executable, shows the learner's progress, restarts crashed actors, bridge and
//! service (each within its own budget, after a back-off: [`crate::restart`]), ends a
//! run that makes no update for too long ([`crate::watchdog`]), and stops everything in
//! order.
//!
//! ```text
//! fulcrum train WORLD            supervisor: run directory, config.toml, children, progress
//!  |- fulcrum serve WORLD        empowerment service   (fulcrum/<ns>/empowerment)
//!  |- fulcrum __learner          PPO learner           (subscribes chunks, publishes weights)
//!  '- fulcrum __actor  x K       actors                (publish chunks, subscribe weights)
//! ```
//!
//! Children run in their own process group (a terminal's Ctrl-C reaches only the
//! supervisor, which stops them in order: the learner first, so that it writes its
//! checkpoint) and die with the supervisor (`PR_SET_PDEATHSIG`). A crashed learner
//! ends the run with its last checkpoint and a message saying how to resume.
//!
//! The loop waits on events: one `select!` over the learner's lines, the children's
//! exits, the stop signal, the lines of a restarting service, and a timer for the
//! restarts due and the watchdog. Nothing in it blocks for long: a restarted service
//! builds its table while the loop goes on (the watchdog held meanwhile), within
//! [`fulcrum_actors::SERVICE_START_LIMIT`], the limit its actors wait for too.

use std::collections::BTreeMap;
use std::os::unix::process::CommandExt;
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use crate::error::{Context, Result};
use crossbeam_channel::{after, never, select, Receiver, Sender};
use fulcrum_actors::SERVICE_START_LIMIT;
use fulcrum_contracts::config::RunConfig;
use fulcrum_learner::paths::RunPaths;

use crate::argv::{self, ChildKind, ChildRequest};
use crate::error::bad;
use crate::process::{
    cores, describe_status, hostname, send_on_exit, signal, spawn_until_ready, stop_children,
    stop_events, Ready,
};
use crate::progress::Progress;
use crate::restart::{Budget, RestartPolicy};
use crate::watchdog::Watchdog;
use fulcrum_contracts::lines::{ChildLine, LearnerProgress};
use fulcrum_learner::trap::TrapDetector;
use fulcrum_learner::watch::Notice;

/// Exit code of a learner that stopped early on request (after a set number of updates).
pub const EXIT_PAUSED: i32 = 3;
/// Exit code of a learner stopped by a signal after writing its checkpoint.
pub const EXIT_INTERRUPTED: i32 = 130;

/// How long the bridge may take to listen.
const BRIDGE_READY: Duration = Duration::from_secs(60);
/// How often the loop looks at the restarts due and the watchdog, at least.
const TICK: Duration = Duration::from_millis(250);

/// How a supervised run ended (failures are errors).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Every update was made.
    Finished,
    /// The learner stopped after the updates it was asked to make; checkpoint written.
    Paused,
    /// A signal stopped the run; checkpoint written.
    Interrupted,
}

/// What the supervisor needs besides the run's configuration.
#[derive(Debug, Clone)]
pub struct Options {
    /// The iceoryx2 namespace of the run's services.
    pub namespace: String,
    /// The `fulcrum` executable the children are started from.
    pub exe: PathBuf,
    /// Address the bridge listens on for actors on other hosts (none: one host).
    pub listen: Option<String>,
    /// The bridge's zenoh session timeout, seconds.
    pub session_timeout: f64,
    /// A zenoh configuration file for the bridge.
    pub zenoh_config: Option<PathBuf>,
    /// Restarts each child (actor slot, service, bridge) may have within a window.
    pub restarts: RestartPolicy,
    /// The watchdog's floor: no run is ended sooner for making no update.
    pub watchdog_floor: Duration,
    /// The learner stops (checkpoint written) after this many updates.
    pub stop_after: Option<u64>,
}

/// Which child an exit event is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Who {
    Learner,
    Service,
    Bridge,
    /// Actor index and incarnation.
    Actor(usize, u32),
}

/// A child that is restarted when it stops, with a restart budget of its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Slot {
    Service,
    Bridge,
    /// Actor index.
    Actor(usize),
}

impl Slot {
    fn name(self) -> String {
        match self {
            Slot::Service => "the empowerment service".into(),
            Slot::Bridge => "the bridge".into(),
            Slot::Actor(i) => format!("actor {i}"),
        }
    }
}

/// A restart waiting for its back-off to pass.
#[derive(Debug)]
struct Due {
    at: Instant,
    slot: Slot,
    /// How the child stopped, the restart's number in the window and its back-off.
    status: ExitStatus,
    n: u32,
    delay: Duration,
}

/// Runs `cfg` in `paths` to its end: starts every child, waits, stops them all.
pub fn supervise(cfg: &RunConfig, paths: &RunPaths, opts: &Options) -> Result<Outcome> {
    let (exits_tx, exits) = crossbeam_channel::unbounded();
    let mut sup = Supervisor {
        cfg: cfg.clone(),
        paths: paths.clone(),
        opts: opts.clone(),
        exits_tx,
        exits,
        service: None,
        bridge: None,
        learner: None,
        learner_lines: never(),
        actors: Vec::new(),
        budgets: BTreeMap::new(),
        due: Vec::new(),
        service_lines: never(),
        service_deadline: None,
        watchdog: Watchdog::new(opts.watchdog_floor),
    };
    let result = sup.run();
    sup.shutdown();
    fulcrum_empowerment::service::clean_dead_nodes();
    result
}

struct Supervisor {
    cfg: RunConfig,
    paths: RunPaths,
    opts: Options,
    /// Every child's exit, as it happens.
    exits_tx: Sender<Who>,
    exits: Receiver<Who>,
    service: Option<Child>,
    bridge: Option<Child>,
    learner: Option<Child>,
    /// The learner's stdout lines, until it closes (then `never()`).
    learner_lines: Receiver<String>,
    /// Each actor and its incarnation.
    actors: Vec<(Option<Child>, u32)>,
    /// Each restartable child's stops within its window.
    budgets: BTreeMap<Slot, Budget>,
    /// Restarts waiting for their back-off.
    due: Vec<Due>,
    /// A restarting service's lines until it is ready (then `never()`), and its limit.
    service_lines: Receiver<String>,
    service_deadline: Option<Instant>,
    watchdog: Watchdog,
}

impl Supervisor {
    /// A child of the `fulcrum` executable with `threads` threads, in its own process
    /// group.
    fn command(&self, args: &[String], threads: usize) -> Command {
        let mut c = Command::new(&self.opts.exe);
        c.args(args)
            .env("RAYON_NUM_THREADS", threads.to_string())
            .env("CANDLE_NUM_THREADS", threads.to_string())
            .stdin(Stdio::null())
            .process_group(0);
        c
    }

    /// What a hidden child process of this run is asked for.
    fn child_request(&self, index: u32, incarnation: u32) -> ChildRequest {
        ChildRequest {
            run: self.paths.dir.clone(),
            namespace: self.opts.namespace.clone(),
            parent: std::process::id(),
            index,
            incarnation,
            stop_after_updates: None,
            run_tag: None,
        }
    }

    /// Tells the loop when `child` exits.
    fn watch(&self, child: &Child, who: Who) {
        send_on_exit(child, self.exits_tx.clone(), who);
    }

    /// The empowerment service's command: it reads what to serve from the run's
    /// `config.toml`.
    fn service_command(&self) -> Command {
        let args = argv::serve_run(&self.paths.dir, &self.opts.namespace);
        let mut cmd = self.command(&args, cores());
        // SAFETY: prctl is async-signal-safe; nothing else runs between fork and exec.
        unsafe {
            cmd.pre_exec(|| {
                libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
                Ok(())
            });
        }
        cmd
    }

    /// The empowerment service at the run's start; returns once its table is built (or
    /// the run stops).
    fn start_service(&mut self) -> Result<()> {
        let cmd = self.service_command();
        match spawn_until_ready(cmd, "the empowerment service", Some(SERVICE_START_LIMIT))? {
            Ready::Ready(child, (), _) => {
                self.watch(&child, Who::Service);
                self.service = Some(child);
                Ok(())
            }
            Ready::Stopped => Ok(()),
            Ready::Exited(s) => crate::fail!(
                "the empowerment service stopped before it was ready ({})",
                describe_status(s)
            ),
        }
    }

    /// The bridge to other hosts; returns once it listens.
    fn start_bridge(&mut self) -> Result<()> {
        let Some(addr) = self.opts.listen.clone() else {
            return Ok(());
        };
        let args = argv::bridge_listen(&argv::BridgeListen {
            addr: addr.clone(),
            run: self.paths.dir.clone(),
            namespace: self.opts.namespace.clone(),
            parent: std::process::id(),
            zenoh: argv::Zenoh {
                session_timeout: self.opts.session_timeout,
                config: self.opts.zenoh_config.clone(),
            },
        });
        let cmd = self.command(&args, 1);
        let child = match spawn_until_ready(cmd, "the bridge", Some(BRIDGE_READY))? {
            Ready::Ready(child, (), _) => child,
            Ready::Stopped => return Ok(()),
            Ready::Exited(s) if s.code() == Some(2) => {
                return bad(format!(
                    "the bridge refused the address {addr} (its message is above)"
                ))
            }
            Ready::Exited(s) => crate::fail!(
                "the bridge stopped before it listened ({})",
                describe_status(s)
            ),
        };
        // A wildcard address is not one to connect to: name this host instead.
        let hint = match addr.trim_start_matches("tcp/").rsplit_once(':') {
            Some((h, port)) if h == "0.0.0.0" || h == "[::]" => {
                format!("{}:{port}", hostname())
            }
            _ => addr.clone(),
        };
        // The bridge wrote the run's secret (owner-only) before it listened; said once.
        let secret_file = self.paths.dir.join("secret");
        let secret = std::fs::read_to_string(&secret_file).unwrap_or_default();
        let secret = secret.trim().trim_start_matches("fulcrum:");
        eprintln!(
            "fulcrum train: actors on other hosts may join: FULCRUM_SECRET={secret} fulcrum actor-host --connect {hint} (or --secret-file with a copy of {}; keep it private)",
            secret_file.display()
        );
        self.watch(&child, Who::Bridge);
        self.bridge = Some(child);
        Ok(())
    }

    fn start_learner(&mut self) -> Result<()> {
        let args = argv::child(
            ChildKind::Learner,
            &ChildRequest {
                stop_after_updates: self.opts.stop_after,
                ..self.child_request(0, 0)
            },
        );
        let mut cmd = self.command(&args, self.cfg.learner_threads);
        cmd.stdout(Stdio::piped());
        let mut child = cmd.spawn().context("cannot start the learner")?;
        self.learner_lines = crate::process::lines(&mut child)?;
        self.watch(&child, Who::Learner);
        self.learner = Some(child);
        Ok(())
    }

    fn start_actor(&mut self, i: usize, incarnation: u32) -> Result<()> {
        let args = argv::child(ChildKind::Actor, &self.child_request(i as u32, incarnation));
        let child = self
            .command(&args, 1)
            .spawn()
            .with_context(|| format!("cannot start actor {i}"))?;
        self.watch(&child, Who::Actor(i, incarnation));
        if i == self.actors.len() {
            self.actors.push((Some(child), incarnation));
        } else {
            self.actors[i] = (Some(child), incarnation);
        }
        Ok(())
    }

    fn run(&mut self) -> Result<Outcome> {
        let stop = stop_events()?;
        if self.cfg.empowerment {
            self.start_service()?;
            if crate::process::stopping() {
                return Ok(Outcome::Interrupted);
            }
        }
        self.start_learner()?;
        self.start_bridge()?;
        for i in 0..self.cfg.actors {
            self.start_actor(i, 0)?;
        }
        let mut progress = Progress::new(
            "fulcrum train",
            self.cfg.updates(),
            "{elapsed_precise} [{bar:30}] {pos}/{len} updates  {msg}",
            Duration::from_secs(5),
        );
        let mut stopping = false;
        self.watchdog = Watchdog::new(self.opts.watchdog_floor);
        loop {
            let stop_now = if stopping { never() } else { stop.clone() };
            let wake = if stopping {
                never()
            } else {
                after(self.next_wake())
            };
            select! {
                recv(self.learner_lines) -> line => match line {
                    Ok(l) => self.learner_said(&mut progress, &l),
                    // Closed: the learner is exiting; its exit event follows.
                    Err(_) => self.learner_lines = never(),
                },
                recv(self.service_lines) -> line => match line {
                    Ok(l) if ChildLine::says_ready(&l) => {
                        self.service_ready(&progress)
                    }
                    Ok(_) => {}
                    // Closed: the service is exiting; its exit event follows.
                    Err(_) => self.service_lines = never(),
                },
                recv(wake) -> _ => self.on_time(&mut progress)?,
                recv(stop_now) -> _ => {
                    // The learner writes its checkpoint and exits; then the rest stop.
                    if let Some(l) = &self.learner {
                        signal(l, libc::SIGINT);
                    }
                    stopping = true;
                },
                recv(self.exits) -> who => {
                    let who = who.context("the exit watchers are gone")?;
                    if who == Who::Learner {
                        return self.learner_ended(&mut progress, stopping);
                    }
                    if !stopping {
                        self.stopped(who, &progress)?;
                    }
                },
            }
        }
    }

    /// The learner has exited: its last lines, then what its exit code means.
    fn learner_ended(&mut self, progress: &mut Progress, stopping: bool) -> Result<Outcome> {
        let mut l = self.learner.take().context("no learner")?;
        let s = l.wait().context("cannot wait for the learner")?;
        // Its stdout is closed: the lines not yet seen are all in the channel (unless
        // they were all seen and the channel is `never()` already).
        let lines = std::mem::replace(&mut self.learner_lines, never());
        for line in lines.try_iter() {
            progress_only(progress, &line);
        }
        // The reader thread may still be between its last read and its last send:
        // wait for it to close the channel, a moment at most.
        while let Ok(line) = lines.recv_timeout(Duration::from_millis(100)) {
            progress_only(progress, &line);
        }
        progress.finish();
        match s.code() {
            Some(0) => Ok(Outcome::Finished),
            Some(EXIT_PAUSED) => Ok(Outcome::Paused),
            Some(EXIT_INTERRUPTED) if stopping => Ok(Outcome::Interrupted),
            _ if !self.paths.checkpoint().exists() => Err(crate::failure!(
                "the learner failed ({}) before its first checkpoint; `fulcrum train --resume {}` starts the run over",
                describe_status(s),
                self.paths.dir.display()
            )),
            _ => Err(crate::failure!(
                "the learner failed ({}); the last checkpoint is in {}; continue with `fulcrum train --resume {}`",
                describe_status(s),
                self.paths.checkpoint().display(),
                self.paths.dir.display()
            )),
        }
    }

    /// A child stopped: reap it and schedule its restart after its back-off, or end
    /// the run when it is over its budget.
    fn stopped(&mut self, who: Who, progress: &Progress) -> Result<()> {
        let (slot, status) = match who {
            Who::Learner => return Ok(()),
            Who::Actor(i, inc) => {
                let current = self.actors[i].1 == inc;
                (Slot::Actor(i), reap(&mut self.actors[i].0, current)?)
            }
            Who::Bridge => (Slot::Bridge, reap(&mut self.bridge, true)?),
            Who::Service => {
                self.service_lines = never();
                self.service_deadline = None;
                (Slot::Service, reap(&mut self.service, true)?)
            }
        };
        let Some(status) = status else {
            return Ok(());
        };
        let policy = self.opts.restarts;
        let budget = self.budgets.entry(slot).or_default();
        let allowed = budget.stopped(&policy, Instant::now()).map_err(|over| {
            crate::failure!(
                "{} stopped ({}), its stop number {} within {:.0} s: over its budget of {} restarts in {:.0} s",
                slot.name(),
                describe_status(status),
                over.n,
                policy.window.as_secs_f64(),
                policy.max,
                policy.window.as_secs_f64()
            )
        })?;
        if slot == Slot::Service || slot == Slot::Bridge {
            // Actor restarts are told when they happen (the tests count those lines).
            progress.note(&format!(
                "{} stopped ({}); restarting it in {:.1} s (restart {} of {} allowed in {:.0} s)",
                slot.name(),
                describe_status(status),
                allowed.delay.as_secs_f64(),
                allowed.n,
                policy.max,
                policy.window.as_secs_f64()
            ));
        }
        if slot == Slot::Service {
            // Actors wait for the new service by design: hold the watchdog meanwhile.
            self.watchdog.hold();
        }
        self.due.push(Due {
            at: Instant::now() + allowed.delay,
            slot,
            status,
            n: allowed.n,
            delay: allowed.delay,
        });
        Ok(())
    }

    /// How long the loop may sleep: until the next restart due, a tick at most.
    fn next_wake(&self) -> Duration {
        let now = Instant::now();
        self.due
            .iter()
            .map(|d| d.at.saturating_duration_since(now))
            .min()
            .unwrap_or(TICK)
            .min(TICK)
    }

    /// The timer: restarts whose back-off has passed, the service's start limit, the
    /// watchdog.
    fn on_time(&mut self, progress: &mut Progress) -> Result<()> {
        let now = Instant::now();
        let (ready, waiting): (Vec<Due>, Vec<Due>) = std::mem::take(&mut self.due)
            .into_iter()
            .partition(|d| d.at <= now);
        self.due = waiting;
        for d in ready {
            self.restart(d, progress)?;
        }
        if self.service_deadline.is_some_and(|t| now > t) {
            crate::fail!(
                "the restarted empowerment service was not ready within {:.0} s",
                SERVICE_START_LIMIT.as_secs_f64()
            );
        }
        if let Some(why) = self.watchdog.check() {
            crate::fail!(
                "{why}; the last checkpoint is in {}; continue with `fulcrum train --resume {}`",
                self.paths.checkpoint().display(),
                self.paths.dir.display()
            );
        }
        Ok(())
    }

    /// Restart a child whose back-off has passed.
    fn restart(&mut self, d: Due, progress: &Progress) -> Result<()> {
        match d.slot {
            Slot::Actor(i) => {
                progress.note(&format!(
                    "actor {i} stopped ({}); restarted after {:.1} s (restart {} of {} allowed in {:.0} s)",
                    describe_status(d.status),
                    d.delay.as_secs_f64(),
                    d.n,
                    self.opts.restarts.max,
                    self.opts.restarts.window.as_secs_f64()
                ));
                // The dead actor's ports hold places in services made for the run's
                // actors and a few spares: free them before its successor comes.
                fulcrum_empowerment::service::clean_dead_nodes();
                let inc = self.actors[i].1;
                self.start_actor(i, inc + 1)
            }
            Slot::Bridge => self.start_bridge(),
            Slot::Service => {
                fulcrum_empowerment::service::clean_dead_nodes();
                self.begin_service()
            }
        }
    }

    /// Start the empowerment service again without waiting for it: its `ready` line
    /// comes through the loop.
    fn begin_service(&mut self) -> Result<()> {
        let mut cmd = self.service_command();
        cmd.stdout(Stdio::piped());
        let mut child = cmd
            .spawn()
            .context("cannot start the empowerment service")?;
        self.service_lines = crate::process::lines(&mut child)?;
        self.service_deadline = Some(Instant::now() + SERVICE_START_LIMIT);
        self.watch(&child, Who::Service);
        self.service = Some(child);
        Ok(())
    }

    /// The restarted service is ready: the watchdog's clock runs again.
    fn service_ready(&mut self, progress: &Progress) {
        self.service_lines = never();
        self.service_deadline = None;
        self.watchdog.release();
        progress.note("the empowerment service is ready again");
    }

    /// A line from the learner: its progress, or a notice.
    fn learner_said(&mut self, progress: &mut Progress, line: &str) {
        let notice = match ChildLine::parse(line) {
            Some(ChildLine::Progress(p)) => {
                self.watchdog.updated();
                return learner_progress(progress, &p);
            }
            Some(ChildLine::Notice(n)) => n,
            _ => return,
        };
        match notice {
            Notice::Waiting { actors, .. } => self.watchdog.waiting(actors),
            Notice::Stalled {
                actor,
                waited_s,
                refused,
            } => progress.note(&if refused {
                format!("the learner refused a chunk of actor {actor}: it goes on without it until its next chunk")
            } else {
                format!("no chunk from actor {actor} for {waited_s:.1} s: the learner goes on without it until its next chunk")
            }),
            Notice::Trap(signs) => progress.note(&format!(
                "warning: {} (metrics.csv marks the updates in its `trap` column)",
                TrapDetector::warning(&signs)
            )),
        }
    }

    /// Stop every child: SIGTERM, then SIGKILL after a grace period.
    fn shutdown(&mut self) {
        let mut all: Vec<Child> = Vec::new();
        all.extend(self.learner.take());
        all.extend(self.actors.drain(..).filter_map(|(c, _)| c));
        all.extend(self.service.take());
        all.extend(self.bridge.take());
        stop_children(all);
    }
}

/// The exit status of the child in `slot` if `current` (the event is about it) and it
/// has exited; the slot is emptied.
fn reap(slot: &mut Option<Child>, current: bool) -> Result<Option<ExitStatus>> {
    if !current {
        return Ok(None);
    }
    let s = crate::process::exited(slot)?;
    if s.is_some() {
        *slot = None;
    }
    Ok(s)
}

/// A learner's line if it is its progress (its last lines, after it exited).
fn progress_only(progress: &mut Progress, line: &str) {
    if let Some(ChildLine::Progress(p)) = ChildLine::parse(line) {
        learner_progress(progress, &p);
    }
}

/// The learner's progress after an update, on the progress line.
fn learner_progress(progress: &mut Progress, p: &LearnerProgress) {
    // Runs with actors on other hosts re-plan their updates as hosts come and go.
    if p.total != progress.total() && p.total > 0 {
        progress.set_total(p.total);
    }
    let msg = format!(
        "steps {}  success {:.3}  return {:.3}  {:.0} steps/s",
        p.env_steps, p.success_rate, p.extrinsic_return, p.sps
    );
    let (u, total) = (p.update, progress.total());
    progress.set(u, msg, |m| format!("update {u}/{total}  {m}"));
}
