//! A training run's resolved configuration: what `config.toml` in the run directory
//! holds, and what the supervisor, the learner and every actor read.
//!
//! One update consumes `actors` chunks of `envs_per_actor x steps_per_chunk`
//! transitions: the batch is `B = actors * envs_per_actor * steps_per_chunk` env steps,
//! and the run makes `ceil(total_steps / B)` updates.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::checkpoint::Extra;
use crate::intrinsic::Intrinsic;
use crate::layout::{shape_for, NetShape};
use crate::ppo_config::PpoConfig;
use fulcrum_world::layouts::Layouts;
use fulcrum_world::view::View;
use fulcrum_world::world::World;

/// The resolved configuration of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunConfig {
    /// fulcrum's version that wrote the file.
    pub fulcrum_version: String,
    /// The run's id (its directory name by default).
    pub run_id: String,
    /// World as given: a built-in name or a path.
    pub world: String,
    /// The world's name.
    pub world_name: String,
    /// [`World::content_hash`], hex: a resumed run checks it.
    pub world_hash: String,
    /// Seed of weights, sampling, minibatches and worlds.
    pub seed: u64,
    /// Env steps in all (rounded up to whole updates).
    pub total_steps: u64,
    /// Actor processes.
    pub actors: usize,
    /// Worlds per actor (M).
    pub envs_per_actor: usize,
    /// Steps per chunk (T).
    pub steps_per_chunk: usize,
    /// Threads of the learner process.
    pub learner_threads: usize,
    /// Hidden units.
    pub hidden: usize,
    /// Intrinsic reward weight (0 with `empowerment = false`).
    pub beta: f64,
    /// Whether the run has an empowerment service (every intrinsic form but `none`).
    pub empowerment: bool,
    /// The intrinsic reward form, written by its name (`none`, `additive`, ...).
    #[serde(default = "default_intrinsic")]
    pub intrinsic: Intrinsic,
    /// How the horizon follows the inventory (`switch` or `fixed`).
    #[serde(default)]
    pub horizon_mode: HorizonMode,
    /// What of a destroy task's objects the potential forms count (a configuration
    /// written before the field reads as `full`, the way those runs were trained).
    #[serde(default)]
    pub potential_objects: PotentialObjects,
    /// The dynamics the service's table is computed on (a configuration written before
    /// stochastic worlds reads as `exact`, which is what it meant).
    #[serde(default)]
    pub empowerment_model: EmpowermentModel,
    /// Where the service's LOOKUP table came from when it is someone's estimates of E
    /// (`train --empowerment-from FILE`: the file as given; the run serves its copy,
    /// `empowerment-estimates.csv`). Absent: the exact table.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub empowerment_from: Option<String>,
    /// Tool of the channel (`default`, `auto`, `all` or a tool).
    pub tool: ChannelTool,
    /// The tool the selection (`auto`) gave when the run started on one world. A
    /// resumed run keeps it, whatever the selection gives then. Absent for a named tool,
    /// a family (a selection per layout) and a configuration written before the field,
    /// whose service selects again at every start.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub selected_tool: Option<String>,
    /// Objects of interest, comma separated (empty = the world's default).
    pub objects: String,
    /// Horizon where the tool is not held.
    pub horizon_unequipped: u32,
    /// Horizon where it is held.
    pub horizon_equipped: u32,
    /// 0 = synchronous PPO; N = chunks may be made by a policy up to N versions old.
    pub max_policy_lag: u64,
    /// Checkpoint every this many updates (and at the end).
    pub checkpoint_every: u64,
    /// Evaluate the policy greedily every this many updates (and at the end) into
    /// `eval.csv` and TensorBoard; 0 = never.
    #[serde(default)]
    pub eval_every: u64,
    /// Episodes of each periodic evaluation.
    #[serde(default = "default_eval_episodes")]
    pub eval_episodes: usize,
    /// Whether the periodic evaluation samples its actions from the policy (seeded by
    /// `seed`) instead of playing greedy (a config without the field: greedy).
    #[serde(default)]
    pub eval_sample: bool,
    /// Whether actors on other hosts may join (`train --listen`, feature `multihost`).
    /// Then an update takes one chunk from every local actor and every live remote one,
    /// and the run ends after `total_steps` env steps, whatever the batches were.
    #[serde(default)]
    pub remote: bool,
    /// Seconds the learner waits for a remote actor's chunk before it goes on without
    /// it (the actor rejoins with its next chunk).
    #[serde(default = "default_stall_timeout")]
    pub stall_timeout_s: f64,
    /// Per-mode action masking ([`fulcrum_world::mask`]) in the actors' sampling and the
    /// learner's log-probabilities and entropy. A configuration written before masking
    /// existed reads as `false`, the way those runs were trained.
    #[serde(default)]
    pub action_mask: bool,
    /// What of the map the policy sees (`full`, or `crop:R`, the window of radius R
    /// around the agent; [`fulcrum_world::view`]). A configuration written before views existed
    /// reads as `full`, the way those runs were trained.
    #[serde(default)]
    pub view: View,
    /// Two value heads (RND's arrangement): the task reward and the intrinsic reward get
    /// their own value estimates and GAE (the intrinsic one with `gamma_int`), the
    /// intrinsic reward divided by the running standard deviation of the intrinsic
    /// rewards so far; the policy's advantage is `A_ext + beta * A_int`.
    #[serde(default)]
    pub intrinsic_value_head: bool,
    /// The intrinsic return's discount (two value heads only).
    #[serde(default = "default_gamma_int")]
    pub gamma_int: f32,
    /// A run on a world family: the layouts it trains on (`16`: the seeds 0..16; `all`: a
    /// fresh layout every episode; [`fulcrum_world::layouts`]). Absent for a run on one
    /// world (and in every configuration written before families).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layouts: Option<Layouts>,
    /// PPO hyperparameters (the `[ppo]` table).
    pub ppo: PpoConfig,
}

/// The form of a `config.toml` without the field: written when the additive bonus was
/// the default, it keeps meaning what it meant (not [`Intrinsic::default`]).
fn default_intrinsic() -> Intrinsic {
    Intrinsic::Additive
}

fn default_gamma_int() -> f32 {
    0.99
}

fn default_eval_episodes() -> usize {
    10
}

fn default_stall_timeout() -> f64 {
    10.0
}

/// What is wrong with a run's configuration: bad input, one sentence each (the binary
/// exits 2).
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// `config.toml` cannot be read.
    #[error("cannot read {}: {source}", path.display())]
    Read {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// `config.toml` is not a run configuration.
    #[error("{} is not a valid run configuration: {message}", path.display())]
    Invalid {
        /// The file.
        path: std::path::PathBuf,
        /// TOML's or serde's sentence.
        message: String,
    },
    /// A setting is out of range or contradicts another ([`RunConfig::check`]).
    #[error("{0}")]
    Setting(String),
    /// A checkpoint was trained with another action space or view.
    #[error("the checkpoint was trained with {key} = {checkpoint}, but config.toml says {config}")]
    CheckpointMismatch {
        /// The mark.
        key: &'static str,
        /// The checkpoint's value.
        checkpoint: String,
        /// The configuration's.
        config: String,
    },
}

/// How the empowerment horizon follows the inventory.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum HorizonMode {
    /// `h_e` where the channel's tool is held, `h_u` elsewhere.
    #[default]
    Switch,
    /// One horizon everywhere (`h_u = h_e`).
    Fixed,
}

impl FromStr for HorizonMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "switch" => Ok(HorizonMode::Switch),
            "fixed" => Ok(HorizonMode::Fixed),
            other => Err(format!(
                "unknown horizon mode '{other}' (modes: switch, fixed)"
            )),
        }
    }
}

/// What of a destroy task's objects the potential forms (`potential`,
/// `horizon-potential`) count. E itself, and every other form, counts the objects' full
/// state (a boulder's cell too), as the paper does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PotentialObjects {
    /// The objects' full state, as E (a configuration written before the field reads so,
    /// the way those runs were trained).
    #[default]
    Full,
    /// What the task is about: a destroy task's objects by their conditions only (a
    /// boulder intact or destroyed, not its cell); the full state for any other task.
    /// The default of a new run.
    Task,
}

impl PotentialObjects {
    /// The name `--potential-objects` takes and `config.toml` writes.
    pub fn name(self) -> &'static str {
        match self {
            PotentialObjects::Full => "full",
            PotentialObjects::Task => "task",
        }
    }
}

impl FromStr for PotentialObjects {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "full" => Ok(PotentialObjects::Full),
            "task" => Ok(PotentialObjects::Task),
            other => Err(format!(
                "unknown potential objects '{other}' (task: a destroy task's objects by their conditions; full: their full state)"
            )),
        }
    }
}

/// The dynamics the empowerment table is computed on. In a deterministic world both
/// models are the same table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EmpowermentModel {
    /// The world as it is: in a stochastic world the channel capacity of its noisy
    /// dynamics (Blahut-Arimoto).
    #[default]
    Exact,
    /// The same map with nothing left to chance (slip 0, every rule's p 1;
    /// [`fulcrum_world::World::without_chance`]): the values an agent that ignores the noise
    /// would compute.
    Deterministic,
}

impl EmpowermentModel {
    /// The name `--empowerment-model` takes and `config.toml` writes.
    pub fn name(self) -> &'static str {
        match self {
            EmpowermentModel::Exact => "exact",
            EmpowermentModel::Deterministic => "deterministic",
        }
    }
}

impl FromStr for EmpowermentModel {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "exact" => Ok(EmpowermentModel::Exact),
            "deterministic" => Ok(EmpowermentModel::Deterministic),
            other => Err(format!(
                "unknown empowerment model '{other}' (models: exact, deterministic)"
            )),
        }
    }
}

/// The empowerment channel's tool as a run names it, written as text in `config.toml`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum ChannelTool {
    /// The world's `[empowerment]` tool.
    #[default]
    Default,
    /// Tool selection by the matrix.
    Auto,
    /// Every action (no tool).
    All,
    /// A tool by name, kind or letter.
    Named(String),
}

impl ChannelTool {
    /// The tool as a request names it (`None` for the world's own).
    pub fn as_request(&self) -> Option<&str> {
        match self {
            ChannelTool::Default => None,
            ChannelTool::Auto => Some("auto"),
            ChannelTool::All => Some("all"),
            ChannelTool::Named(t) => Some(t),
        }
    }
}

impl From<&str> for ChannelTool {
    fn from(s: &str) -> ChannelTool {
        match s {
            "default" => ChannelTool::Default,
            "auto" => ChannelTool::Auto,
            "all" => ChannelTool::All,
            t => ChannelTool::Named(t.to_string()),
        }
    }
}

impl fmt::Display for ChannelTool {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_request().unwrap_or("default"))
    }
}

impl Serialize for ChannelTool {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for ChannelTool {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Ok(ChannelTool::from(String::deserialize(d)?.as_str()))
    }
}

impl RunConfig {
    /// The network's shape for this run on `world`.
    pub fn shape(&self, world: &World) -> NetShape {
        NetShape {
            int_value: self.intrinsic_value_head,
            ..shape_for(world, self.view, self.hidden)
        }
    }

    /// The intrinsic reward form (`none` without a service, whatever the field says).
    pub fn form(&self) -> Intrinsic {
        if !self.empowerment {
            return Intrinsic::None;
        }
        self.intrinsic
    }

    /// Whether the service counts a destroy task's objects by their conditions: a
    /// potential form with `potential_objects = "task"` ([`PotentialObjects::Task`]).
    pub fn task_conditions(&self) -> bool {
        self.form().is_potential() && self.potential_objects == PotentialObjects::Task
    }

    /// Whether a checkpoint's metadata fits this configuration: the action space (masked
    /// or not) and the view are part of what the policy learnt, so a checkpoint is never
    /// continued with another setting. Checkpoints from before masking or views carry
    /// no mark (and were trained unmasked or with the full view, as their configuration
    /// files read).
    pub fn fits_checkpoint(&self, extra: &Extra) -> Result<(), ConfigError> {
        for (key, ours) in self.checkpoint_marks() {
            match extra.meta.get(key) {
                Some(m) if *m != ours => {
                    return Err(ConfigError::CheckpointMismatch {
                        key,
                        checkpoint: m.clone(),
                        config: ours,
                    })
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// The marks [`RunConfig::fits_checkpoint`] reads, for a checkpoint's metadata.
    pub fn checkpoint_marks(&self) -> [(&'static str, String); 2] {
        [
            ("action_mask", self.action_mask.to_string()),
            ("view", self.view.to_string()),
        ]
    }

    /// Subscribers the run's weights service is made for: its actors and
    /// [`crate::traj::SPARE_SUBSCRIBERS`]; a run across hosts, whose hosts each have
    /// their own number of actors, keeps [`crate::traj::WEIGHTS_SUBSCRIBERS`].
    pub fn weights_subscribers(&self) -> usize {
        if self.remote {
            crate::traj::WEIGHTS_SUBSCRIBERS
        } else {
            self.actors + crate::traj::SPARE_SUBSCRIBERS
        }
    }

    /// Clients the run's empowerment service is made for: its actors and
    /// [`crate::msg::SPARE_CLIENTS`] (restarted actors, and clients from outside the run
    /// such as `empowerment query --service`); a run across hosts keeps
    /// [`crate::msg::MAX_CLIENTS`].
    pub fn service_clients(&self) -> usize {
        if self.remote {
            crate::msg::MAX_CLIENTS
        } else {
            self.actors + crate::msg::SPARE_CLIENTS
        }
    }

    /// Env steps per update.
    pub fn batch(&self) -> usize {
        self.actors * self.envs_per_actor * self.steps_per_chunk
    }

    /// Updates in the run.
    pub fn updates(&self) -> u64 {
        self.total_steps.div_ceil(self.batch().max(1) as u64).max(1)
    }

    /// The first thing wrong with the configuration, as one sentence.
    pub fn check(&self) -> Result<(), ConfigError> {
        self.first_problem().map_err(ConfigError::Setting)
    }

    fn first_problem(&self) -> Result<(), String> {
        let b = self.batch();
        let checks: [(bool, String); 14] = [
            (
                self.eval_episodes == 0 || self.eval_episodes > 100_000,
                format!(
                    "{} episodes per evaluation: must be 1 to 100000",
                    self.eval_episodes
                ),
            ),
            (
                !(self.stall_timeout_s.is_finite() && self.stall_timeout_s > 0.0),
                format!(
                    "the stall timeout {} must be a positive number of seconds",
                    self.stall_timeout_s
                ),
            ),
            (
                self.actors == 0,
                "the number of actors must be at least 1".into(),
            ),
            (
                self.actors > crate::traj::MAX_ACTORS,
                format!(
                    "{} actors are over the limit of {}",
                    self.actors,
                    crate::traj::MAX_ACTORS
                ),
            ),
            (
                self.envs_per_actor == 0 || self.envs_per_actor > 4096,
                format!(
                    "{} worlds per actor: must be 1 to 4096",
                    self.envs_per_actor
                ),
            ),
            (
                self.steps_per_chunk == 0 || self.steps_per_chunk > 4096,
                format!(
                    "{} steps per chunk: must be 1 to 4096",
                    self.steps_per_chunk
                ),
            ),
            (
                self.learner_threads == 0,
                "the learner's threads must be at least 1".into(),
            ),
            (
                self.hidden == 0 || self.hidden > 4096,
                format!("{} hidden units: must be 1 to 4096", self.hidden),
            ),
            (
                !self.beta.is_finite() || self.beta < 0.0,
                format!("beta {} must be a finite number >= 0", self.beta),
            ),
            (
                self.total_steps == 0,
                "the run's env steps must be at least 1".into(),
            ),
            (
                self.ppo.minibatches == 0 || self.ppo.minibatches > b,
                format!(
                    "{} minibatches do not fit a batch of {b} steps",
                    self.ppo.minibatches
                ),
            ),
            (self.ppo.epochs == 0, "epochs must be at least 1".into()),
            (
                self.checkpoint_every == 0,
                "the checkpoint interval must be at least 1 update".into(),
            ),
            (
                !(self.ppo.lr.is_finite() && self.ppo.lr > 0.0),
                format!("learning rate {} must be positive", self.ppo.lr),
            ),
        ];
        for (bad, why) in checks {
            if bad {
                return Err(why);
            }
        }
        let form = self.intrinsic;
        if self.intrinsic_value_head && !form.uses_service() {
            return Err(
                "the intrinsic value head needs an intrinsic reward (an empowerment service)"
                    .into(),
            );
        }
        if !(self.gamma_int > 0.0 && self.gamma_int <= 1.0) {
            return Err(format!(
                "the intrinsic discount gamma_int {} must be in (0, 1]",
                self.gamma_int
            ));
        }
        if form.uses_service() != self.empowerment {
            return Err(format!(
                "the intrinsic reward '{form}' {} an empowerment service",
                if self.empowerment {
                    "does not use"
                } else {
                    "needs"
                }
            ));
        }
        match self.horizon_mode {
            HorizonMode::Switch => {}
            HorizonMode::Fixed if self.horizon_unequipped == self.horizon_equipped => {}
            HorizonMode::Fixed => {
                return Err(format!(
                    "horizon mode 'fixed' uses one horizon, but the horizons without and with the tool ({} and {}) differ",
                    self.horizon_unequipped, self.horizon_equipped
                ))
            }
        }
        for (h, which) in [
            (self.horizon_unequipped, "the horizon without the tool"),
            (self.horizon_equipped, "the horizon with the tool"),
        ] {
            if self.empowerment && (h == 0 || h > fulcrum_world::parse::MAX_HORIZON) {
                return Err(format!(
                    "{which} {h} must be 1 to {}",
                    fulcrum_world::parse::MAX_HORIZON
                ));
            }
        }
        Ok(())
    }

    /// Read `config.toml`.
    pub fn load(path: &Path) -> Result<RunConfig, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        toml::from_str(&text).map_err(|e| ConfigError::Invalid {
            path: path.to_path_buf(),
            message: e.message().to_string(),
        })
    }

    /// As TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> RunConfig {
        RunConfig {
            fulcrum_version: "0".into(),
            run_id: "r".into(),
            world: "room".into(),
            world_name: "room".into(),
            world_hash: "0".into(),
            seed: 1,
            total_steps: 10_000,
            actors: 2,
            envs_per_actor: 4,
            steps_per_chunk: 128,
            learner_threads: 1,
            hidden: 64,
            beta: 0.0,
            empowerment: false,
            intrinsic: Intrinsic::None,
            horizon_mode: HorizonMode::Switch,
            potential_objects: PotentialObjects::Task,
            empowerment_model: EmpowermentModel::Exact,
            empowerment_from: None,
            tool: ChannelTool::Auto,
            selected_tool: None,
            objects: String::new(),
            horizon_unequipped: 2,
            horizon_equipped: 1,
            max_policy_lag: 0,
            remote: false,
            stall_timeout_s: 10.0,
            checkpoint_every: 10,
            eval_every: 0,
            eval_episodes: 10,
            eval_sample: false,
            action_mask: true,
            view: View::Full,
            intrinsic_value_head: false,
            gamma_int: 0.99,
            layouts: None,
            ppo: PpoConfig::default(),
        }
    }

    /// A configuration written before masking and the new PPO fields reads as those runs
    /// were trained: unmasked, no advantage floor, annealed learning rate, no KL term.
    #[test]
    fn old_files_keep_their_meaning() {
        let mut text = cfg().to_toml();
        for key in [
            "action_mask",
            "view",
            "adv_std_floor",
            "lr_anneal",
            "adv_norm_batch",
            "vf_loss_clip",
            "kl_coef",
            "kl_target",
        ] {
            let start = text.find(&format!("{key} = ")).unwrap();
            let end = start + text[start..].find('\n').unwrap() + 1;
            text.replace_range(start..end, "");
        }
        let old: RunConfig = toml::from_str(&text).unwrap();
        assert!(!old.action_mask);
        assert_eq!(old.view, View::Full);
        assert_eq!(old.ppo.adv_std_floor, 0.0);
        assert!(old.ppo.lr_anneal && !old.ppo.adv_norm_batch);
        assert_eq!((old.ppo.vf_loss_clip, old.ppo.kl_coef), (0.0, 0.0));
        assert_eq!(old.ppo.lr_at(5, 10), 2.5e-4 * 0.5);
    }

    /// A checkpoint's marks must match the configuration: the mask and the view.
    #[test]
    fn checkpoints_are_continued_only_with_their_mask_and_view() {
        let c = cfg();
        let mut extra = Extra::default();
        assert!(
            c.fits_checkpoint(&extra).is_ok(),
            "old checkpoints carry no marks"
        );
        for (k, v) in c.checkpoint_marks() {
            extra.meta.insert(k.into(), v);
        }
        assert_eq!(extra.meta["view"], "full");
        assert!(c.fits_checkpoint(&extra).is_ok());
        let mut crop = c.clone();
        crop.view = View::Crop(4);
        let e = crop.fits_checkpoint(&extra).unwrap_err().to_string();
        assert!(
            e.contains("trained with view = full") && e.contains("crop:4"),
            "{e}"
        );
        let text = crop.to_toml();
        assert!(text.contains("view = \"crop:4\""), "{text}");
        assert_eq!(toml::from_str::<RunConfig>(&text).unwrap(), crop);
        let e = toml::from_str::<RunConfig>(&text.replace("crop:4", "crop:0")).unwrap_err();
        assert!(e.to_string().contains("unknown view 'crop:0'"), "{e}");
    }

    #[test]
    fn a_config_without_the_form_reads_as_the_additive_bonus() {
        // Runs made while the additive bonus was the default wrote no `intrinsic`: they
        // keep meaning what they meant, whatever a new run's default is.
        let mut c = cfg();
        c.empowerment = true;
        c.intrinsic = Intrinsic::HorizonPotential;
        let text = c.to_toml();
        assert!(
            text.contains("intrinsic = \"horizon-potential\"\n"),
            "{text}"
        );
        let old = text.replace("intrinsic = \"horizon-potential\"\n", "");
        let back: RunConfig = toml::from_str(&old).unwrap();
        assert_eq!(back.intrinsic, Intrinsic::Additive);
        assert_eq!(Intrinsic::default(), Intrinsic::HorizonPotential);
    }

    #[test]
    fn a_config_without_potential_objects_reads_as_the_full_state() {
        // Runs made before the field counted a destroy task's objects in full; a new
        // run writes `task`, and only the potential forms read it.
        let mut c = cfg();
        c.empowerment = true;
        c.intrinsic = Intrinsic::HorizonPotential;
        let text = c.to_toml();
        assert!(text.contains("potential_objects = \"task\"\n"), "{text}");
        assert!(c.task_conditions());
        let old = text.replace("potential_objects = \"task\"\n", "");
        let back: RunConfig = toml::from_str(&old).unwrap();
        assert_eq!(back.potential_objects, PotentialObjects::Full);
        assert!(!back.task_conditions());
        c.intrinsic = Intrinsic::Additive;
        assert!(!c.task_conditions(), "E itself counts the full state");
        let e = toml::from_str::<RunConfig>(&text.replace("\"task\"", "\"cells\"")).unwrap_err();
        assert!(e.to_string().contains("potential_objects"), "{e}");
    }

    #[test]
    fn batch_and_updates() {
        let c = cfg();
        assert_eq!(c.batch(), 1024);
        // ceil(10000 / 1024) = 10.
        assert_eq!(c.updates(), 10);
    }

    #[test]
    fn toml_round_trip_and_checks() {
        let c = cfg();
        let back: RunConfig = toml::from_str(&c.to_toml()).unwrap();
        assert_eq!(back, c);
        assert!(c.check().is_ok());
        let mut bad = c.clone();
        bad.beta = -1.0;
        assert!(bad.check().unwrap_err().to_string().contains("beta -1"));
        let mut bad = c.clone();
        bad.actors = 0;
        assert!(bad
            .check()
            .unwrap_err()
            .to_string()
            .contains("number of actors"));
        let mut bad = c.clone();
        bad.empowerment = true;
        bad.intrinsic = Intrinsic::Potential;
        bad.horizon_equipped = 0;
        assert!(bad
            .check()
            .unwrap_err()
            .to_string()
            .contains("the horizon with the tool"));
        let mut bad = c.clone();
        bad.intrinsic = Intrinsic::Potential;
        assert!(bad
            .check()
            .unwrap_err()
            .to_string()
            .contains("needs an empowerment service"));
        // An unknown form or mode cannot be represented: the file is refused on load.
        let text = c
            .to_toml()
            .replace("intrinsic = \"none\"", "intrinsic = \"novelty\"");
        let err = toml::from_str::<RunConfig>(&text).unwrap_err().to_string();
        assert!(err.contains("'novelty'"), "{err}");
        let text = c
            .to_toml()
            .replace("horizon_mode = \"switch\"", "horizon_mode = \"often\"");
        assert!(toml::from_str::<RunConfig>(&text).is_err());
        let mut bad = c;
        bad.horizon_mode = HorizonMode::Fixed;
        assert!(bad.check().unwrap_err().to_string().contains("differ"));
    }
}
