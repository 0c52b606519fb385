//! Planning a training run: a request (what the user asked for) becomes a checked
//! [`RunConfig`], its world and its run directory, before any process starts.
//!
//! A new run gets its settings from the request, the world's `[empowerment]` table and
//! the machine (actors default to one per core but one); a resumed run keeps the
//! settings in its `config.toml` but for the few that may change (length,
//! checkpointing, threads, policy lag, remote actors), and is refused if its world
//! changed or its checkpoint does not load.

use std::path::{Path, PathBuf};

use crate::error::{Context, Result};
use fulcrum_contracts::config::{
    ChannelTool, EmpowermentModel, HorizonMode, PotentialObjects, RunConfig,
};
use fulcrum_contracts::intrinsic::Intrinsic;
use fulcrum_contracts::ppo_config::PpoConfig;
use fulcrum_learner::paths::RunPaths;
use fulcrum_learner::preset::Preset;
use fulcrum_world::World;

use crate::error::{bad, BadRequest};
use crate::lock::{lock_for_run, DirLock};
use crate::process::{cores, utc_stamp};
use crate::settings::{Fixed, Resumable};
use fulcrum_empowerment::request::{objects_or_default, potential_objects};
use fulcrum_empowerment::ToolSel;
use fulcrum_world::family::load_world_or_family;
use fulcrum_world::{Layouts, ObjectSet};

/// What the user asked for; `None` = the default (or, on a resume, the run's own).
#[derive(Debug, Clone, Default)]
pub struct TrainRequest {
    /// A built-in world's name or a world file (default: the first built-in world).
    pub world: Option<String>,
    /// The settings a run keeps from start to end.
    pub fixed: Fixed,
    /// The settings a resume may change.
    pub resumable: Resumable,
    /// The run directory of a new run (default `runs/<run id>`).
    pub out: Option<PathBuf>,
    /// A run directory to continue.
    pub resume: Option<PathBuf>,
    /// Actors on other hosts join through a bridge.
    pub remote: bool,
    /// Seconds without chunks from a remote host before the learner gives up on it.
    pub stall_timeout: Option<f64>,
}

impl TrainRequest {
    /// Refuses what only the request's flags can get wrong: contradicting settings, and
    /// fixed settings given with `--resume` (each named by its flag).
    pub fn check(&self) -> Result<(), BadRequest> {
        self.fixed.check()?;
        if let Some(dir) = &self.resume {
            let changed = self.fixed.given();
            if !changed.is_empty() {
                return Err(BadRequest(format!(
                    "--resume continues a run with the settings in {}; {} cannot be changed (start a new run instead)",
                    dir.join("config.toml").display(),
                    changed.join(", ")
                )));
            }
        }
        Ok(())
    }
}

/// A planned run: ready to start.
#[derive(Debug)]
pub struct Planned {
    /// The checked configuration (already written to `config.toml`).
    pub cfg: RunConfig,
    /// Its world.
    pub world: World,
    /// Its directory.
    pub paths: RunPaths,
    /// Whether it continues an earlier run.
    pub resumed: bool,
    /// The run directory's lock, held by this invocation and the children it starts
    /// (keep it until the run ends).
    pub lock: DirLock,
}

/// The resolved configuration, its world, the run's paths, and whether it is a resume.
pub fn resolve(a: &TrainRequest) -> Result<Planned> {
    if let Some(dir) = &a.resume {
        return resume(a, dir);
    }
    let (cfg, w) = plan(a)?;
    let dir = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("runs").join(&cfg.run_id));
    let paths = RunPaths { dir: dir.clone() };
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let lock = lock_for_run(&dir)?;
    if paths.config().exists() {
        return bad(format!(
            "{} already holds a run; continue it with `fulcrum train --resume {}` or choose another run directory",
            dir.display(),
            dir.display()
        ));
    }
    std::fs::create_dir_all(paths.plots())
        .with_context(|| format!("cannot create {}", dir.display()))?;
    if let Some(from) = &cfg.empowerment_from {
        // The run keeps its own copy: a resume serves the same table whatever became
        // of the file.
        let bytes = std::fs::read(from).with_context(|| format!("cannot read {from}"))?;
        fulcrum_contracts::fsio::write_atomic(&paths.estimates(), &bytes)
            .with_context(|| format!("cannot write {}", paths.estimates().display()))?;
    }
    write_config(&paths, &cfg)?;
    Ok(Planned {
        cfg,
        world: w,
        paths,
        resumed: false,
        lock,
    })
}

/// The paths of the run directory `dir`, refused when it holds no `config.toml`.
pub fn run_dir(dir: &Path) -> Result<RunPaths> {
    let paths = RunPaths {
        dir: dir.to_path_buf(),
    };
    if !paths.config().exists() {
        return bad(format!(
            "{}: no config.toml there (is it a run directory?)",
            dir.display()
        ));
    }
    Ok(paths)
}

/// A run directory's configuration with what may change on a resume changed, checked
/// against its world and its checkpoint.
fn resume(a: &TrainRequest, dir: &Path) -> Result<Planned> {
    a.check()?;
    let r = &a.resumable;
    {
        let paths = run_dir(dir)?;
        let lock = lock_for_run(dir)?;
        clean_stale_temps(&paths)?;
        let mut cfg = RunConfig::load(&paths.config())?;
        if let Some(w) = &a.world {
            if w != &cfg.world && w != &cfg.world_name {
                return bad(format!(
                    "{}: that run trains world '{}', not '{w}'",
                    dir.display(),
                    cfg.world_name
                ));
            }
        }
        if let Some(s) = r.steps {
            cfg.total_steps = s;
            whole_updates(&cfg)?;
        }
        if let Some(k) = r.checkpoint_every {
            cfg.checkpoint_every = k;
        }
        if let Some(k) = r.eval_every {
            cfg.eval_every = k;
        }
        if let Some(n) = r.eval_episodes {
            cfg.eval_episodes = n;
        }
        if r.eval_sample {
            cfg.eval_sample = true;
        }
        if let Some(l) = r.max_policy_lag {
            cfg.max_policy_lag = l;
        }
        if let Some(t) = r.learner_threads {
            cfg.learner_threads = t;
        }
        if a.remote {
            cfg.remote = true;
        }
        if let Some(t) = a.stall_timeout {
            cfg.stall_timeout_s = t;
        }
        cfg.check()?;
        let (w, _) = load_world_or_family(&cfg.world)?;
        if format!("{:016x}", w.content_hash()) != cfg.world_hash {
            return bad(format!(
                "{}: the world '{}' has changed since the run started (hash {:016x}, the run has {})",
                dir.display(),
                cfg.world,
                w.content_hash(),
                cfg.world_hash
            ));
        }
        if let Some(t) = &cfg.selected_tool {
            if w.tool_index(t).is_none() {
                return bad(format!(
                    "{}: the run's config.toml records the selected tool '{t}', which is not a tool of world '{}' (tools: {})",
                    dir.display(),
                    w.name,
                    w.tool_list()
                ));
            }
        }
        // A damaged checkpoint is refused here, before any process starts.
        let ckpt = paths.checkpoint();
        if ckpt.exists() {
            // The whole file (weights, Adam's moments, counters) against the layout.
            const CANNOT: &str =
                "the run cannot continue from it (start a new run, or restore the file)";
            let params = cfg.shape(&w).params();
            let extra = match fulcrum_contracts::checkpoint::read(&ckpt, &params) {
                Ok(contents) => contents.extra,
                Err(e) => return bad(format!("{e}; {CANNOT}")),
            };
            if let Err(e) = cfg.fits_checkpoint(&extra) {
                return bad(format!("{}: {e}", dir.display()));
            }
            rows_reach_checkpoint(&paths, &extra)?;
        }
        crate::sizes::check_memory(&cfg, &w)?;
        write_config(&paths, &cfg)?;
        Ok(Planned {
            cfg,
            world: w,
            paths,
            resumed: true,
            lock,
        })
    }
}

/// The resolved and checked configuration of a new run, and its world: no file is
/// written and no process started (an experiment checks every run with it before
/// starting any).
pub fn plan(request: &TrainRequest) -> Result<(RunConfig, World)> {
    request.check()?;
    let (a, r) = (&request.fixed, &request.resumable);
    let spec = request.world.clone().unwrap_or_default();
    let (w, family) = load_world_or_family(&spec)?;
    let layouts = match (&family, a.layouts) {
        (Some(_), l) => Some(l.unwrap_or(Layouts::All)),
        (None, None) => None,
        (None, Some(_)) => {
            return bad(format!(
                "--layouts needs a world family, and '{spec}' is one world (families: {})",
                fulcrum_world::builtin::FAMILIES.join(", ")
            ))
        }
    };
    if family.is_some() && a.objects.is_some() {
        return bad(format!(
            "--objects does not fit a world family: each layout of '{spec}' names its own task object"
        ));
    }
    if family.is_some() && a.empowerment_from.is_some() {
        return bad(format!(
            "--empowerment-from does not fit a world family: estimates name the states of one world, and '{spec}' makes a new one each episode"
        ));
    }
    // A file path is stored absolute so that a resume from elsewhere finds it.
    let world_spec = if fulcrum_world::builtin::source(&spec).is_none() && Path::new(&spec).exists()
    {
        std::fs::canonicalize(&spec)
            .map(|p| p.display().to_string())
            .unwrap_or(spec.clone())
    } else {
        spec.clone()
    };
    // The default form is potential-based (`Intrinsic::default`): it cannot trap.
    let form = a.form().unwrap_or_default();
    let mode = a.horizon_mode.unwrap_or_default();
    let fixed = mode == HorizonMode::Fixed;
    let preset = a.preset().unwrap_or(Preset::Fulcrum);
    let n = cores();
    let actors = a.actors.unwrap_or(n.saturating_sub(1).max(1));
    let seed = a.seed.unwrap_or(1);
    let e = &w.empowerment;
    let time = utc_stamp();
    let run_id = format!("{}-{time}-{seed}", w.name);
    let cfg = RunConfig {
        fulcrum_version: env!("CARGO_PKG_VERSION").to_string(),
        run_id: run_id.clone(),
        world: world_spec,
        world_name: w.name.clone(),
        world_hash: format!("{:016x}", w.content_hash()),
        seed,
        total_steps: r.steps.unwrap_or(500_000),
        actors,
        envs_per_actor: a.envs_per_actor.unwrap_or(8),
        steps_per_chunk: a
            .steps_per_chunk
            .or(preset.steps_per_chunk())
            .unwrap_or(128),
        learner_threads: r.learner_threads.unwrap_or(n.saturating_sub(actors).max(1)),
        hidden: a.hidden.unwrap_or(64),
        // horizon-potential's default needs the potential's maximum: set below, once the
        // settings are checked.
        beta: match (form, a.beta) {
            (Intrinsic::None, _) => 0.0,
            (_, Some(b)) => b,
            (_, None) => form.default_beta(e.beta, 0.0),
        },
        empowerment: form.uses_service(),
        intrinsic: form,
        horizon_mode: mode,
        // A new run counts what its task is about; an old config.toml without the field
        // reads as `full`, the way it was trained.
        potential_objects: a.potential_objects.unwrap_or(PotentialObjects::Task),
        empowerment_model: a.empowerment_model.unwrap_or_default(),
        empowerment_from: None,
        tool: a.tool.clone().unwrap_or_default(),
        // Set below, once the settings are checked.
        selected_tool: None,
        objects: a.objects.clone().unwrap_or_default(),
        horizon_unequipped: a.horizon_unequipped.unwrap_or(e.horizon_unequipped),
        horizon_equipped: match (fixed, a.horizon_equipped) {
            (true, None) => a.horizon_unequipped.unwrap_or(e.horizon_unequipped),
            (_, h) => h.unwrap_or(e.horizon_equipped),
        },
        max_policy_lag: r.max_policy_lag.unwrap_or(0),
        checkpoint_every: r.checkpoint_every.unwrap_or(10),
        eval_every: r.eval_every.unwrap_or(0),
        eval_episodes: r.eval_episodes.unwrap_or(10),
        eval_sample: r.eval_sample,
        remote: request.remote,
        stall_timeout_s: request.stall_timeout.unwrap_or(10.0),
        action_mask: a.action_mask(),
        view: a.view.unwrap_or_default(),
        layouts,
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
    let mut cfg = cfg;
    cfg.check()?;
    if r.steps.is_some() {
        whole_updates(&cfg)?;
    }
    crate::sizes::check_memory(&cfg, &w)?;
    if cfg.empowerment {
        // Tool and objects are resolved (and refused) here, before any process starts.
        objects_or_default(
            &w,
            (!cfg.objects.is_empty()).then_some(cfg.objects.as_str()),
        )?;
        if let Some(ChannelTool::Named(t)) = &a.tool {
            if w.tool_index(t).is_none() {
                return bad(format!(
                    "unknown tool '{t}' in world '{}' (tools: {}; or all, auto)",
                    w.name,
                    w.tool_list()
                ));
            }
        }
        // On one world, one state space serves the selection's record, the default beta
        // and the estimates' check.
        let mw = model_world(&w, cfg.empowerment_model);
        let one = match family {
            None if form.uses_empowerment() => Some(channel(&mw, &cfg)?),
            _ => None,
        };
        if let Some(ch) = &one {
            let choice = fulcrum_empowerment::request::tool_choice(&mw, cfg.tool.as_request())?;
            if let (fulcrum_world::ToolChoice::Auto, ToolSel::Tool(k)) = (choice, ch.tool) {
                cfg.selected_tool = Some(mw.tools[k].name.clone());
            }
        }
        if form == Intrinsic::HorizonPotential && a.beta.is_none() {
            // A family's potential differs from layout to layout: the largest over its
            // first layouts (the training layouts, at most POTENTIAL_LAYOUTS of them).
            let max = match (&family, layouts, &one) {
                (Some(f), Some(l), _) => {
                    let mut max = 0.0f64;
                    for seed in 0..l.range().end.min(POTENTIAL_LAYOUTS) {
                        let lw = f.layout(seed)?;
                        let lw = model_world(&lw, cfg.empowerment_model);
                        max = max.max(max_potential(&channel(&lw, &cfg)?, &cfg)?);
                    }
                    max
                }
                (_, _, Some(ch)) => max_potential(ch, &cfg)?,
                _ => 0.0,
            };
            cfg.beta = form.default_beta(e.beta, max);
        }
        if let (Some(file), Some(ch)) = (&a.empowerment_from, &one) {
            // Every state needs its estimates: checked now, before any process starts.
            estimates_table(ch, &cfg, file)?;
            cfg.empowerment_from = Some(
                std::fs::canonicalize(file)
                    .unwrap_or(file.clone())
                    .display()
                    .to_string(),
            );
        }
    }
    Ok((cfg, w))
}

/// The LOOKUP table a run's service serves from the estimates in `file`
/// ([`fulcrum_empowerment::estimates`]), for the run's channel and form.
fn estimates_table(ch: &Channel<'_>, cfg: &RunConfig, file: &Path) -> Result<Vec<f32>> {
    let text = std::fs::read_to_string(file).map_err(|e| {
        BadRequest(format!(
            "cannot read --empowerment-from {}: {e}",
            file.display()
        ))
    })?;
    Ok(fulcrum_empowerment::estimates::lookup_from_estimates(
        &ch.engine,
        ch.tool,
        cfg.horizon_unequipped,
        cfg.horizon_equipped,
        cfg.intrinsic.horizon_sum(),
        &text,
        &file.display().to_string(),
    )?)
}

/// A run's channel on a world: its state space, the objects its service counts and the
/// tool (the one the run recorded at its start, else as its settings ask).
pub(crate) struct Channel<'w> {
    /// The world's state space.
    pub(crate) engine: fulcrum_empowerment::Engine<'w>,
    /// The objects the run's service counts ([`potential_objects`]).
    pub(crate) set: ObjectSet,
    /// The tool whose actions drive the channel.
    pub(crate) tool: ToolSel,
}

/// The channel of the run `cfg` on `w` (the world E is computed on).
pub(crate) fn channel<'w>(w: &'w World, cfg: &RunConfig) -> Result<Channel<'w>> {
    let engine = fulcrum_empowerment::Engine::new(w, fulcrum_empowerment::Limits::default())?;
    let set = potential_objects(
        w,
        (!cfg.objects.is_empty()).then_some(cfg.objects.as_str()),
        cfg.task_conditions(),
    )?;
    let asked = cfg.selected_tool.as_deref().or(cfg.tool.as_request());
    let tool = fulcrum_empowerment::request::tool_sel(w, &engine, asked, &set)?;
    Ok(Channel { engine, set, tool })
}

/// Layouts of a family whose potentials set horizon-potential's default beta.
const POTENTIAL_LAYOUTS: u64 = 16;

/// The largest potential Phi(s) = sum over h = 1..H of E^h(s) over the channel's state
/// space, at the run's horizons: horizon-potential's default beta is
/// `HORIZON_POTENTIAL_WORTH / max Phi` ([`Intrinsic::default_beta`]).
fn max_potential(ch: &Channel<'_>, cfg: &RunConfig) -> Result<f64> {
    let phi = ch.engine.lookup_values(
        ch.tool,
        &ch.set,
        cfg.horizon_unequipped,
        cfg.horizon_equipped,
        true,
    )?;
    Ok(phi.iter().copied().fold(0.0f32, f32::max) as f64)
}

/// The world E is computed on under `model`: the world itself, or its deterministic
/// twin (the same file with nothing left to chance, the same content hash).
pub fn model_world(w: &World, model: EmpowermentModel) -> std::borrow::Cow<'_, World> {
    match model {
        EmpowermentModel::Exact => std::borrow::Cow::Borrowed(w),
        EmpowermentModel::Deterministic => std::borrow::Cow::Owned(w.without_chance()),
    }
}

/// An explicit step count must be whole updates: a run never stops in the middle of
/// one, and a silent round-up would train for more steps than asked.
fn whole_updates(cfg: &RunConfig) -> Result<()> {
    let b = cfg.batch() as u64;
    let s = cfg.total_steps;
    if s % b != 0 {
        let below = s / b * b;
        return bad(format!(
            "{s} env steps is not a whole number of updates of {b} steps (actors x worlds per actor x steps per chunk): use {}{}",
            if below > 0 { format!("{below} or ") } else { String::new() },
            below + b
        ));
    }
    Ok(())
}

/// Temporary files that writers killed mid-write left in the run directory (its
/// checkpoints and plots too): none of them can be a live writer's, since the run
/// directory is locked.
fn clean_stale_temps(paths: &RunPaths) -> Result<()> {
    let ckpt_dir = paths.checkpoint().parent().map(Path::to_path_buf);
    for d in [Some(paths.dir.clone()), ckpt_dir, Some(paths.plots())]
        .into_iter()
        .flatten()
        .filter(|d| d.is_dir())
    {
        fulcrum_contracts::fsio::remove_stale_temps(&d)
            .with_context(|| format!("cannot clean temporary files in {}", d.display()))?;
    }
    Ok(())
}

/// `metrics.csv` must hold every update up to the checkpoint's: the learner syncs the
/// rows before each checkpoint, so rows missing below it mean the file was lost or cut
/// by hand, and a resume would leave a hole in the run's curve. Refused (rows after
/// the checkpoint are fine: the learner drops and redoes them).
fn rows_reach_checkpoint(
    paths: &RunPaths,
    extra: &fulcrum_contracts::checkpoint::Extra,
) -> Result<()> {
    let upto = extra.counters.get("update").copied().unwrap_or(0);
    if upto == 0 {
        return Ok(());
    }
    let path = paths.metrics();
    let rows = fulcrum_learner::metrics::read_metrics(&path).unwrap_or_default();
    let mut have = 0;
    for r in rows.iter().filter(|r| r.update <= upto) {
        if r.update != have + 1 {
            break;
        }
        have = r.update;
    }
    if have < upto {
        return bad(format!(
            "{} holds the rows of updates 1 to {have} without a gap, but the checkpoint is at update {upto}: rows {} to {upto} are missing (restore the file, or start a new run)",
            path.display(),
            have + 1
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
    fulcrum_contracts::fsio::write_atomic(&paths.config(), text.as_bytes())
        .with_context(|| format!("cannot write {}", paths.config().display()))?;
    Ok(())
}
