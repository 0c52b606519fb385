//! `fulcrum train`: the supervisor of a training run, and the hidden child processes.
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
//! checkpoint) and die with the supervisor (`PR_SET_PDEATHSIG`). A crashed actor or
//! service is restarted (bounded); a crashed learner ends the run with its last
//! checkpoint and a message saying how to resume.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use fulcrum_learner::config::RunConfig;
use fulcrum_learner::ppo::{PpoConfig, Preset};
use fulcrum_learner::run::{read_metrics, run_learner, LearnerExit, RunPaths};
use fulcrum_shared::intrinsic::Intrinsic;
use fulcrum_shared::World;

use crate::cli::{ChildArgs, TrainArgs};
use crate::commands::{bad, world};

/// Set by SIGINT / SIGTERM.
pub(crate) static STOP: AtomicBool = AtomicBool::new(false);
/// Which signal set [`STOP`] (0 = none).
static SIGNAL: std::sync::atomic::AtomicI32 = std::sync::atomic::AtomicI32::new(0);

/// Exit code of a learner that stopped early on request (`--stop-after-updates`).
const EXIT_PAUSED: i32 = 3;
/// Exit code of a learner stopped by a signal after writing its checkpoint.
const EXIT_INTERRUPTED: i32 = 130;

/// The run was interrupted (SIGINT/SIGTERM): exit code 130.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Interrupted(pub String);

extern "C" fn on_signal(sig: libc::c_int) {
    SIGNAL.store(sig, Ordering::Relaxed);
    STOP.store(true, Ordering::Relaxed);
}

pub(crate) fn install_signal_handlers() {
    // SAFETY: the handler only stores to atomics, which is async-signal-safe.
    unsafe {
        libc::signal(
            libc::SIGINT,
            on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t,
        );
        libc::signal(
            libc::SIGTERM,
            on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t,
        );
    }
}

/// A child: stop when the supervisor dies (and if it already has, stop now).
pub(crate) fn die_with_parent(parent: u32) {
    // SAFETY: prctl with PR_SET_PDEATHSIG takes a signal number; getppid is always safe.
    unsafe {
        libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
        if libc::getppid() as u32 != parent {
            STOP.store(true, Ordering::Relaxed);
        }
    }
}

pub(crate) fn cores() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
}

/// `fulcrum train`.
pub fn run(a: &TrainArgs) -> Result<()> {
    let (cfg, w, paths, resumed) = resolve(a)?;
    install_signal_handlers();
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
                cfg.beta,
                if cfg.horizon_mode == "fixed" {
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
    let mut sup = Supervisor {
        cfg: cfg.clone(),
        paths: paths.clone(),
        ns,
        exe: std::env::current_exe().context("cannot find the fulcrum executable")?,
        service: None,
        bridge: None,
        listen: a.listen.clone(),
        zenoh: a.zenoh.clone(),
        learner: None,
        actors: Vec::new(),
        restarts: 0,
        max_restarts: a.max_restarts,
        stop_after: a.stop_after_updates,
    };
    let result = sup.run();
    sup.shutdown();
    fulcrum_empowerment::service::clean_dead_nodes();
    let drawn = draw_curve(&w, &paths);
    match result {
        Ok(Outcome::Finished) => {
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
                let files = super::record::record(&paths, &cfg, &w, n, cfg.seed, &out)?;
                println!(
                    "{} episodes of the final policy: {}",
                    files.len(),
                    out.display()
                );
            }
            Ok(())
        }
        Ok(Outcome::Paused) => {
            println!(
                "fulcrum train: stopped as asked, checkpoint written; continue with `fulcrum train --resume {}`",
                paths.dir.display()
            );
            Ok(())
        }
        Ok(Outcome::Interrupted) => Err(Interrupted(format!(
            "interrupted; checkpoint written; continue with `fulcrum train --resume {}`",
            paths.dir.display()
        ))
        .into()),
        Err(e) => Err(e),
    }
}

/// The resolved configuration, its world, the run's paths, and whether it is a resume.
fn resolve(a: &TrainArgs) -> Result<(RunConfig, World, RunPaths, bool)> {
    if a.listen.is_some() && !cfg!(feature = "multihost") {
        return bad(super::NO_MULTIHOST.replace("{}", "--listen"));
    }
    if a.stall_timeout.is_some() && a.listen.is_none() {
        return bad("--stall-timeout applies to runs with --listen (actors on other hosts)");
    }
    if let Some(dir) = &a.resume {
        let paths = RunPaths { dir: dir.clone() };
        if !paths.config().exists() {
            return bad(format!(
                "--resume {}: no config.toml there (is it a run directory?)",
                dir.display()
            ));
        }
        let mut cfg = RunConfig::load(&paths.config()).map_err(super::BadInput)?;
        let changed: Vec<&str> = [
            (a.beta.is_some(), "--beta"),
            (a.no_empowerment, "--no-empowerment"),
            (a.no_action_mask, "--no-action-mask"),
            (a.intrinsic_value_head, "--intrinsic-value-head"),
            (a.gamma_int.is_some(), "--gamma-int"),
            (a.intrinsic.is_some(), "--intrinsic"),
            (a.horizon_mode.is_some(), "--horizon-mode"),
            (a.seed.is_some(), "--seed"),
            (a.actors.is_some(), "--actors"),
            (a.envs_per_actor.is_some(), "--envs-per-actor"),
            (a.steps_per_chunk.is_some(), "--steps-per-chunk"),
            (a.hidden.is_some(), "--hidden"),
            (a.tool.is_some(), "--tool"),
            (a.objects.is_some(), "--objects"),
            (a.horizon_unequipped.is_some(), "--horizon-unequipped"),
            (a.horizon_equipped.is_some(), "--horizon-equipped"),
            (a.lr.is_some(), "--lr"),
            (a.epochs.is_some(), "--epochs"),
            (a.minibatches.is_some(), "--minibatches"),
            (a.ppo_preset.is_some(), "--ppo-preset"),
        ]
        .into_iter()
        .filter_map(|(c, n)| c.then_some(n))
        .collect();
        if !changed.is_empty() {
            return bad(format!(
                "--resume continues a run with the settings in {}; {} cannot be changed (start a new run instead)",
                paths.config().display(),
                changed.join(", ")
            ));
        }
        if let Some(w) = &a.world {
            if w != &cfg.world && w != &cfg.world_name {
                return bad(format!(
                    "--resume {}: that run trains world '{}', not '{w}'",
                    dir.display(),
                    cfg.world_name
                ));
            }
        }
        if let Some(s) = a.steps {
            cfg.total_steps = s;
            whole_updates(&cfg)?;
        }
        if let Some(k) = a.checkpoint_every {
            cfg.checkpoint_every = k;
        }
        if let Some(l) = a.max_policy_lag {
            cfg.max_policy_lag = l;
        }
        if let Some(t) = a.learner_threads {
            cfg.learner_threads = t;
        }
        if a.listen.is_some() {
            cfg.remote = true;
        }
        if let Some(t) = a.stall_timeout {
            cfg.stall_timeout_s = t;
        }
        cfg.check().map_err(super::BadInput)?;
        let w = world(&cfg.world)?;
        if format!("{:016x}", w.content_hash()) != cfg.world_hash {
            return bad(format!(
                "--resume {}: the world '{}' has changed since the run started (hash {:016x}, the run has {})",
                dir.display(),
                cfg.world,
                w.content_hash(),
                cfg.world_hash
            ));
        }
        // A damaged checkpoint is refused here, before any process starts.
        let ckpt = paths.checkpoint();
        if ckpt.exists() {
            let net =
                fulcrum_learner::net::Net::new(cfg.shape(&w), cfg.seed, &candle_core::Device::Cpu)?;
            let mut adam = fulcrum_learner::ppo::Adam::new(&net)?;
            const CANNOT: &str =
                "the run cannot continue from it (start a new run, or restore the file)";
            let extra = match fulcrum_learner::checkpoint::load(&ckpt, &net, &mut adam) {
                Ok(x) => x,
                Err(e) => return bad(format!("{e}; {CANNOT}")),
            };
            if let Err(e) = cfg.fits_checkpoint(&extra) {
                return bad(format!("--resume {}: {e}", dir.display()));
            }
        }
        write_config(&paths, &cfg)?;
        return Ok((cfg, w, paths, true));
    }
    let (cfg, w) = plan(a)?;
    let dir = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("runs").join(&cfg.run_id));
    let paths = RunPaths { dir: dir.clone() };
    if paths.config().exists() {
        return bad(format!(
            "{} already holds a run; continue it with --resume {} or choose another --out",
            dir.display(),
            dir.display()
        ));
    }
    std::fs::create_dir_all(paths.plots())
        .with_context(|| format!("cannot create {}", dir.display()))?;
    write_config(&paths, &cfg)?;
    Ok((cfg, w, paths, false))
}

/// The resolved and checked configuration of a new run, and its world: no file is
/// written and no process started (`fulcrum experiment` checks every run with it
/// before starting any).
pub fn plan(a: &TrainArgs) -> Result<(RunConfig, World)> {
    let spec = a.world.clone().unwrap_or_default();
    let w = world(&spec)?;
    // A file path is stored absolute so that a resume from elsewhere finds it.
    let world_spec =
        if fulcrum_shared::builtin::source(&spec).is_none() && Path::new(&spec).exists() {
            std::fs::canonicalize(&spec)
                .map(|p| p.display().to_string())
                .unwrap_or(spec.clone())
        } else {
            spec.clone()
        };
    if a.no_empowerment && a.intrinsic.as_deref().is_some_and(|f| f != "none") {
        return bad(format!(
            "--no-empowerment and --intrinsic {} contradict each other: choose one",
            a.intrinsic.as_deref().unwrap_or_default()
        ));
    }
    let form: Intrinsic = match (&a.intrinsic, a.no_empowerment) {
        (_, true) => Intrinsic::None,
        (Some(f), false) => f.parse().map_err(super::BadInput)?,
        (None, false) => Intrinsic::Additive,
    };
    let fixed = a.horizon_mode.as_deref() == Some("fixed");
    let preset: Preset = a
        .ppo_preset
        .as_deref()
        .unwrap_or("fulcrum")
        .parse()
        .map_err(super::BadInput)?;
    let n = cores();
    let actors = a.actors.unwrap_or(n.saturating_sub(1).max(1));
    let seed = a.seed.unwrap_or(1);
    let e = &w.empowerment;
    let time = chrono_like_now();
    let run_id = format!("{}-{time}-{seed}", w.name);
    let cfg = RunConfig {
        fulcrum_version: env!("CARGO_PKG_VERSION").to_string(),
        run_id: run_id.clone(),
        world: world_spec,
        world_name: w.name.clone(),
        world_hash: format!("{:016x}", w.content_hash()),
        seed,
        total_steps: a.steps.unwrap_or(500_000),
        actors,
        envs_per_actor: a.envs_per_actor.unwrap_or(8),
        steps_per_chunk: a
            .steps_per_chunk
            .or(preset.steps_per_chunk())
            .unwrap_or(128),
        learner_threads: a.learner_threads.unwrap_or(n.saturating_sub(actors).max(1)),
        hidden: a.hidden.unwrap_or(64),
        beta: if form == Intrinsic::None {
            0.0
        } else {
            a.beta.unwrap_or(form.default_beta(e.beta))
        },
        empowerment: form.uses_service(),
        intrinsic: form.name().into(),
        horizon_mode: a.horizon_mode.clone().unwrap_or_else(|| "switch".into()),
        tool: a.tool.clone().unwrap_or_else(|| "default".into()),
        objects: a.objects.clone().unwrap_or_default(),
        horizon_unequipped: a.horizon_unequipped.unwrap_or(e.horizon_unequipped),
        horizon_equipped: match (fixed, a.horizon_equipped) {
            (true, None) => a.horizon_unequipped.unwrap_or(e.horizon_unequipped),
            (_, h) => h.unwrap_or(e.horizon_equipped),
        },
        max_policy_lag: a.max_policy_lag.unwrap_or(0),
        checkpoint_every: a.checkpoint_every.unwrap_or(10),
        remote: a.listen.is_some(),
        stall_timeout_s: a.stall_timeout.unwrap_or(10.0),
        action_mask: !a.no_action_mask,
        intrinsic_value_head: a.intrinsic_value_head,
        gamma_int: a.gamma_int.unwrap_or(0.99),
        ppo: {
            let d = preset.ppo();
            PpoConfig {
                epochs: a.epochs.unwrap_or(d.epochs),
                minibatches: a.minibatches.unwrap_or(d.minibatches),
                lr: a.lr.unwrap_or(d.lr),
                ..d
            }
        },
    };
    if form == Intrinsic::None && a.beta.is_some() {
        return bad(
            "--beta and --no-empowerment (or --intrinsic none) contradict each other: choose one",
        );
    }
    cfg.check().map_err(super::BadInput)?;
    if a.steps.is_some() {
        whole_updates(&cfg)?;
    }
    if cfg.empowerment {
        // Tool and objects are resolved (and refused) here, before any process starts.
        super::objects_or_default(
            &w,
            (!cfg.objects.is_empty()).then_some(cfg.objects.as_str()),
        )?;
        if let Some(t) = &a.tool {
            if t != "auto" && t != "all" && w.tool_index(t).is_none() {
                return bad(format!(
                    "unknown tool '{t}' in world '{}' (tools: {}; or all, auto)",
                    w.name,
                    w.tool_list()
                ));
            }
        }
    }
    Ok((cfg, w))
}

/// An explicit `--steps` must be whole updates: a run never stops in the middle of
/// one, and a silent round-up would train for more steps than asked.
fn whole_updates(cfg: &RunConfig) -> Result<()> {
    let b = cfg.batch() as u64;
    let s = cfg.total_steps;
    if s % b != 0 {
        let below = s / b * b;
        return bad(format!(
            "--steps {s} is not a whole number of updates of {b} steps (actors x worlds per actor x steps per chunk): use {}{}",
            if below > 0 { format!("{below} or ") } else { String::new() },
            below + b
        ));
    }
    Ok(())
}

fn write_config(paths: &RunPaths, cfg: &RunConfig) -> Result<()> {
    let text = format!(
        "# fulcrum run configuration (resolved); `fulcrum train --resume {}` continues it.\n{}",
        paths.dir.display(),
        cfg.to_toml()
    );
    fulcrum_shared::fsio::write_atomic(&paths.config(), text.as_bytes())
        .with_context(|| format!("cannot write {}", paths.config().display()))
}

/// `YYYYmmdd-HHMMSS` in UTC, without a date crate.
pub(crate) fn chrono_like_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let (days, rem) = (secs / 86_400, secs % 86_400);
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + (m <= 2) as i64;
    format!(
        "{y:04}{m:02}{d:02}-{:02}{:02}{:02}",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

enum Outcome {
    Finished,
    Paused,
    Interrupted,
}

struct Supervisor {
    cfg: RunConfig,
    paths: RunPaths,
    ns: String,
    exe: PathBuf,
    service: Option<Child>,
    /// `fulcrum bridge --listen` (runs with `--listen`).
    bridge: Option<Child>,
    listen: Option<String>,
    zenoh: crate::cli::ZenohArgs,
    learner: Option<(Child, mpsc::Receiver<String>)>,
    actors: Vec<(Option<Child>, u32)>,
    restarts: u32,
    max_restarts: u32,
    stop_after: Option<u64>,
}

fn describe_status(s: ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (s.code(), s.signal()) {
        (Some(c), _) => format!("exit code {c}"),
        (None, Some(sig)) => format!("signal {sig}"),
        _ => "unknown status".into(),
    }
}

impl Supervisor {
    fn child(&self, args: &[String], threads: usize) -> Command {
        let mut c = Command::new(&self.exe);
        c.args(args)
            .env("RAYON_NUM_THREADS", threads.to_string())
            .env("CANDLE_NUM_THREADS", threads.to_string())
            .stdin(Stdio::null())
            .process_group(0);
        c
    }

    fn child_args(&self, what: &str) -> Vec<String> {
        vec![
            what.into(),
            "--run".into(),
            self.paths.dir.display().to_string(),
            "--namespace".into(),
            self.ns.clone(),
            "--parent".into(),
            std::process::id().to_string(),
        ]
    }

    fn start_service(&mut self) -> Result<()> {
        let mut args = vec![
            "serve".to_string(),
            self.cfg.world.clone(),
            "--namespace".into(),
            self.ns.clone(),
            "--horizon-unequipped".into(),
            self.cfg.horizon_unequipped.to_string(),
            "--horizon-equipped".into(),
            self.cfg.horizon_equipped.to_string(),
        ];
        if self.cfg.tool != "default" {
            args.extend(["--tool".into(), self.cfg.tool.clone()]);
        }
        if !self.cfg.objects.is_empty() {
            args.extend(["--objects".into(), self.cfg.objects.clone()]);
        }
        if self.cfg.form().horizon_sum() {
            args.push("--horizon-sum".into());
        }
        let mut cmd = self.child(&args, cores());
        cmd.stdout(Stdio::piped());
        // SAFETY: prctl is async-signal-safe; nothing else runs between fork and exec.
        unsafe {
            cmd.pre_exec(|| {
                libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
                Ok(())
            });
        }
        let mut child = cmd
            .spawn()
            .context("cannot start the empowerment service")?;
        let out = child.stdout.take().context("service stdout")?;
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(|l| l.ok()) {
                if line.contains("ready") {
                    let _ = tx.send(());
                }
            }
        });
        let t0 = Instant::now();
        loop {
            if rx.recv_timeout(Duration::from_millis(50)).is_ok() {
                break;
            }
            if let Ok(Some(s)) = child.try_wait() {
                anyhow::bail!(
                    "the empowerment service stopped before it was ready ({})",
                    describe_status(s)
                );
            }
            if STOP.load(Ordering::Relaxed) {
                let _ = child.kill();
                let _ = child.wait();
                return Ok(());
            }
            if t0.elapsed() > Duration::from_secs(600) {
                let _ = child.kill();
                anyhow::bail!("the empowerment service was not ready after 600 s");
            }
        }
        self.service = Some(child);
        Ok(())
    }

    /// The bridge to other hosts; returns once it listens.
    fn start_bridge(&mut self) -> Result<()> {
        let Some(addr) = self.listen.clone() else {
            return Ok(());
        };
        let mut args = vec![
            "bridge".to_string(),
            "--listen".into(),
            addr.clone(),
            "--run".into(),
            self.paths.dir.display().to_string(),
            "--namespace".into(),
            self.ns.clone(),
            "--parent".into(),
            std::process::id().to_string(),
            "--session-timeout".into(),
            self.zenoh.session_timeout.to_string(),
        ];
        if let Some(c) = &self.zenoh.zenoh_config {
            args.extend(["--zenoh-config".into(), c.display().to_string()]);
        }
        let mut cmd = self.child(&args, 1);
        cmd.stdout(Stdio::piped());
        let mut child = cmd.spawn().context("cannot start the bridge")?;
        let out = child.stdout.take().context("bridge stdout")?;
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(|l| l.ok()) {
                if line.contains("ready") {
                    let _ = tx.send(());
                }
            }
        });
        loop {
            if rx.recv_timeout(Duration::from_millis(50)).is_ok() {
                break;
            }
            if let Some(s) = child.try_wait()? {
                if s.code() == Some(2) {
                    return bad(format!(
                        "--listen {addr}: the bridge refused it (its message is above)"
                    ));
                }
                anyhow::bail!(
                    "the bridge stopped before it listened ({})",
                    describe_status(s)
                );
            }
            if STOP.load(Ordering::Relaxed) {
                let _ = child.kill();
                let _ = child.wait();
                return Ok(());
            }
        }
        // A wildcard address is not one to connect to: name this host instead.
        let hint = match addr.trim_start_matches("tcp/").rsplit_once(':') {
            Some((h, port)) if h == "0.0.0.0" || h == "[::]" => {
                format!("{}:{port}", super::bridge_hostname())
            }
            _ => addr.clone(),
        };
        eprintln!(
            "fulcrum train: actors on other hosts may join: fulcrum actor-host --connect {hint}"
        );
        self.bridge = Some(child);
        Ok(())
    }

    fn start_learner(&mut self) -> Result<()> {
        let mut args = self.child_args("__learner");
        if let Some(n) = self.stop_after {
            args.extend(["--stop-after-updates".into(), n.to_string()]);
        }
        let mut cmd = self.child(&args, self.cfg.learner_threads);
        cmd.stdout(Stdio::piped());
        let mut child = cmd.spawn().context("cannot start the learner")?;
        let out = child.stdout.take().context("learner stdout")?;
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(|l| l.ok()) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        self.learner = Some((child, rx));
        Ok(())
    }

    fn start_actor(&mut self, i: usize, incarnation: u32) -> Result<Child> {
        let mut args = self.child_args("__actor");
        args.extend([
            "--index".into(),
            i.to_string(),
            "--incarnation".into(),
            incarnation.to_string(),
        ]);
        self.child(&args, 1)
            .spawn()
            .with_context(|| format!("cannot start actor {i}"))
    }

    fn run(&mut self) -> Result<Outcome> {
        if self.cfg.empowerment {
            self.start_service()?;
            if STOP.load(Ordering::Relaxed) {
                return Ok(Outcome::Interrupted);
            }
        }
        self.start_learner()?;
        self.start_bridge()?;
        for i in 0..self.cfg.actors {
            let c = self.start_actor(i, 0)?;
            self.actors.push((Some(c), 0));
        }
        let mut progress = Progress::new(self.cfg.updates());
        let mut forwarded = false;
        loop {
            if STOP.load(Ordering::Relaxed) && !forwarded {
                // The learner writes its checkpoint and exits; then the rest stop.
                if let Some((l, _)) = &self.learner {
                    signal(l, libc::SIGINT);
                }
                forwarded = true;
            }
            if let Some((l, rx)) = &mut self.learner {
                while let Ok(line) = rx.try_recv() {
                    progress.line(&line);
                }
                if let Some(s) = l.try_wait()? {
                    while let Ok(line) = rx.try_recv() {
                        progress.line(&line);
                    }
                    progress.finish();
                    self.learner = None;
                    return match s.code() {
                        Some(0) => Ok(Outcome::Finished),
                        Some(EXIT_PAUSED) => Ok(Outcome::Paused),
                        Some(EXIT_INTERRUPTED) if forwarded => Ok(Outcome::Interrupted),
                        _ => Err(anyhow::anyhow!(
                            "the learner failed ({}); the last checkpoint is in {}; continue with `fulcrum train --resume {}`",
                            describe_status(s),
                            self.paths.checkpoint().display(),
                            self.paths.dir.display()
                        )),
                    };
                }
            }
            if !forwarded {
                self.watch_children(&mut progress)?;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Restart crashed actors and a crashed service.
    fn watch_children(&mut self, progress: &mut Progress) -> Result<()> {
        for i in 0..self.actors.len() {
            if let Some(s) = exited(&mut self.actors[i].0)? {
                self.count_restart(&format!("actor {i}"), s)?;
                progress.note(&format!(
                    "actor {i} stopped ({}); restarted ({} of {} restarts)",
                    describe_status(s),
                    self.restarts,
                    self.max_restarts
                ));
                let inc = self.actors[i].1 + 1;
                let c = self.start_actor(i, inc)?;
                self.actors[i] = (Some(c), inc);
            }
        }
        if let Some(s) = exited(&mut self.bridge)? {
            self.count_restart("the bridge", s)?;
            progress.note(&format!(
                "the bridge stopped ({}); restarting it",
                describe_status(s)
            ));
            self.bridge = None;
            self.start_bridge()?;
        }
        if let Some(s) = exited(&mut self.service)? {
            self.count_restart("the empowerment service", s)?;
            progress.note(&format!(
                "the empowerment service stopped ({}); restarting it",
                describe_status(s)
            ));
            self.service = None;
            fulcrum_empowerment::service::clean_dead_nodes();
            self.start_service()?;
        }
        Ok(())
    }

    /// Count the restart of a stopped child: an error once the run has used up its
    /// restarts.
    fn count_restart(&mut self, what: &str, s: ExitStatus) -> Result<()> {
        self.restarts += 1;
        if self.restarts > self.max_restarts {
            anyhow::bail!(
                "{what} stopped ({}) and the run used up its {} restarts",
                describe_status(s),
                self.max_restarts
            );
        }
        Ok(())
    }

    /// Stop every child: SIGTERM, then SIGKILL after a grace period.
    fn shutdown(&mut self) {
        let mut all: Vec<Child> = Vec::new();
        if let Some((l, _)) = self.learner.take() {
            all.push(l);
        }
        all.extend(self.actors.drain(..).filter_map(|(c, _)| c));
        if let Some(s) = self.service.take() {
            all.push(s);
        }
        if let Some(b) = self.bridge.take() {
            all.push(b);
        }
        stop_children(all);
    }
}

/// SIGTERM to every child, then SIGKILL to those still running after 4 s; all reaped.
pub(crate) fn stop_children(mut all: Vec<Child>) {
    for c in &all {
        signal(c, libc::SIGTERM);
    }
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(4) {
        if all.iter_mut().all(|c| matches!(c.try_wait(), Ok(Some(_)))) {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    for c in &mut all {
        if !matches!(c.try_wait(), Ok(Some(_))) {
            let _ = c.kill();
        }
        let _ = c.wait();
    }
}

pub(crate) fn signal(c: &Child, sig: libc::c_int) {
    // SAFETY: kill(2) on our own child's pid.
    unsafe {
        libc::kill(c.id() as libc::pid_t, sig);
    }
}

/// The progress bar (on a terminal) or a line now and then (elsewhere).
struct Progress {
    bar: Option<indicatif::ProgressBar>,
    updates: u64,
    last_line: Instant,
}

impl Progress {
    fn new(updates: u64) -> Progress {
        let bar = super::terminal_bar(
            updates,
            "{elapsed_precise} [{bar:30}] {pos}/{len} updates  {msg}",
        );
        Progress {
            bar,
            updates,
            last_line: Instant::now() - Duration::from_secs(60),
        }
    }

    /// A line from the learner: `progress U N STEPS SUCCESS RETURN SPS`.
    fn line(&mut self, line: &str) {
        let v: Vec<&str> = line.split_whitespace().collect();
        if v.first() != Some(&"progress") || v.len() < 7 {
            return;
        }
        let u: u64 = v[1].parse().unwrap_or(0);
        // Runs with actors on other hosts re-plan their updates as hosts come and go.
        if let Some(total) = v[2]
            .parse::<u64>()
            .ok()
            .filter(|&t| t != self.updates && t > 0)
        {
            self.updates = total;
            if let Some(b) = &self.bar {
                b.set_length(total);
            }
        }
        let msg = format!(
            "steps {}  success {}  return {}  {} steps/s",
            v[3], v[4], v[5], v[6]
        );
        match &self.bar {
            Some(b) => {
                b.set_position(u);
                b.set_message(msg);
            }
            None => {
                if self.last_line.elapsed() >= Duration::from_secs(5) || u == self.updates {
                    self.last_line = Instant::now();
                    eprintln!("update {u}/{}  {msg}", self.updates);
                }
            }
        }
    }

    fn note(&self, text: &str) {
        match &self.bar {
            Some(b) => b.println(format!("fulcrum train: {text}")),
            None => eprintln!("fulcrum train: {text}"),
        }
    }

    fn finish(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish();
        }
    }
}

/// Draw `plots/learning-curve.png` from metrics.csv (None when there is nothing).
fn draw_curve(w: &World, paths: &RunPaths) -> Option<PathBuf> {
    let rows = read_metrics(&paths.metrics()).ok()?;
    if rows.is_empty() {
        return None;
    }
    let pts: Vec<fulcrum_plot::CurvePoint> = rows
        .iter()
        .map(|r| fulcrum_plot::CurvePoint {
            env_steps: r.env_steps,
            success_rate: r.success_rate,
            extrinsic_return: r.extrinsic_return,
            intrinsic_mean: r.intrinsic_mean,
        })
        .collect();
    let path = paths.plots().join("learning-curve.png");
    let _ = std::fs::create_dir_all(paths.plots());
    match fulcrum_plot::learning_curve_png(&path, &format!("{}: PPO", w.name), &pts) {
        Ok(()) => Some(path),
        Err(e) => {
            eprintln!("fulcrum train: the learning curve was not drawn: {e}");
            None
        }
    }
}

fn child_setup(a: &ChildArgs) -> Result<(RunConfig, World, RunPaths)> {
    die_with_parent(a.parent);
    install_signal_handlers();
    let paths = RunPaths { dir: a.run.clone() };
    let cfg = RunConfig::load(&paths.config()).map_err(super::BadInput)?;
    let w = world(&cfg.world)?;
    if format!("{:016x}", w.content_hash()) != cfg.world_hash {
        return bad(format!(
            "the world '{}' differs from the run's (hash {})",
            cfg.world, cfg.world_hash
        ));
    }
    Ok((cfg, w, paths))
}

/// `fulcrum __learner`.
pub fn learner_process(a: &ChildArgs) -> Result<()> {
    let (cfg, w, paths) = child_setup(a)?;
    let stop_after = a.stop_after_updates;
    let mut first: Option<u64> = None;
    let mut paused = false;
    let exit = run_learner(&w, &cfg, &paths, &a.namespace, &STOP, |row, updates| {
        let mut out = std::io::stdout().lock();
        let _ = writeln!(
            out,
            "progress {} {} {} {:.3} {:.3} {:.0}",
            row.update, updates, row.env_steps, row.success_rate, row.extrinsic_return, row.sps
        );
        let _ = out.flush();
        let f = *first.get_or_insert(row.update - 1);
        if stop_after.is_some_and(|n| row.update - f >= n) {
            paused = true;
            STOP.store(true, Ordering::Relaxed);
        }
    })?;
    match exit {
        LearnerExit::Finished => Ok(()),
        LearnerExit::Interrupted if paused && SIGNAL.load(Ordering::Relaxed) == 0 => {
            std::process::exit(EXIT_PAUSED)
        }
        LearnerExit::Interrupted => std::process::exit(EXIT_INTERRUPTED),
    }
}

/// `fulcrum __actor`.
pub fn actor_process(a: &ChildArgs) -> Result<()> {
    let (cfg, w, paths) = child_setup(a)?;
    let run_tag = match &a.run_tag {
        Some(t) => match u64::from_str_radix(t, 16) {
            Ok(v) => Some(v),
            Err(_) => return bad(format!("--run-tag '{t}' is not a hex number")),
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

/// How a helper process ended, if it has (`None` also when there is none).
fn exited(child: &mut Option<Child>) -> std::io::Result<Option<ExitStatus>> {
    child
        .as_mut()
        .map(|c| c.try_wait())
        .transpose()
        .map(Option::flatten)
}
