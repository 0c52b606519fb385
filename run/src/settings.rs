//! The settings of a training run, each declared once.
//!
//! `fulcrum train` flattens [`Fixed`] and [`Resumable`] into its flags (their doc
//! comments are its `--help`), a [`TrainRequest`](crate::plan::TrainRequest) carries them,
//! and [`plan`](crate::plan::plan) builds the run's `RunConfig` from them. A resumed run
//! keeps its `config.toml`: every fixed setting given with `--resume` is refused, named by
//! its flag ([`Fixed::given`], read off the declaration below), and the resumable ones
//! replace the run's.

use clap::builder::{PossibleValuesParser, TypedValueParser};
use fulcrum_contracts::config::{ChannelTool, EmpowermentModel, HorizonMode, PotentialObjects};
use fulcrum_contracts::intrinsic::Intrinsic;
use fulcrum_learner::preset::Preset;
use fulcrum_world::{Layouts, View};

use crate::error::BadRequest;

/// A value parser for a type named on the command line by one of `names`.
fn named<T>(names: &'static [&'static str]) -> impl TypedValueParser<Value = T>
where
    T: std::str::FromStr<Err = String> + Clone + Send + Sync + 'static,
{
    PossibleValuesParser::new(names).try_map(|s| s.parse::<T>())
}

/// A finite number (NaN and infinities are refused where they are typed).
fn finite(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("'{s}' is not a finite number")),
    }
}

/// What a run is: the settings it keeps from its first start to its end.
#[derive(Debug, Clone, Default, PartialEq, clap::Args, serde::Serialize)]
pub struct Fixed {
    /// Weight of the intrinsic reward [default: for horizon-potential 0.4 / max Phi, so that
    /// the shaping along any path pays at most 0.4 (0.05 for a two-state object such as
    /// the tree at H = 8); 0.1 for first-visit; the world's `[empowerment]` beta for the
    /// others].
    #[arg(long, allow_negative_numbers = true, value_parser = finite)]
    pub beta: Option<f64>,
    /// The baseline: no empowerment service, reward R only (= `--intrinsic none`).
    #[arg(long)]
    pub no_empowerment: bool,
    /// The intrinsic reward form: horizon-potential (R + beta (gamma Phi(s') -
    /// Phi(s)), Phi = sum over h <= H of E^h: potential-based shaping, which keeps the
    /// task's optimal policies and so cannot trap), additive (R + beta E(s'), the
    /// paper's; it pays for standing where E is high and can trap a run there),
    /// potential (the same shaping with Phi = E), first-visit (beta E(s') once per
    /// inventory per episode), count (R + beta / sqrt N(s')) or none
    /// [default: horizon-potential].
    #[arg(long, value_parser = named::<Intrinsic>(&["additive", "potential", "horizon-potential", "first-visit", "count", "none"]))]
    pub intrinsic: Option<Intrinsic>,
    /// The paper's setting in one flag: the additive bonus with the world's beta, every
    /// action in every mode (no mask) and RLlib's PPO defaults (= `--intrinsic additive
    /// --no-action-mask --ppo-preset rllib`).
    #[arg(long, conflicts_with_all = ["intrinsic", "no_empowerment", "ppo_preset"])]
    pub paper: bool,
    /// switch: the held / not-held horizons of the world file (the paper's); fixed: the
    /// not-held horizon everywhere [default: switch].
    #[arg(long, value_parser = named::<HorizonMode>(&["switch", "fixed"]))]
    pub horizon_mode: Option<HorizonMode>,
    /// What of a destroy task's objects the potential forms count: task (their
    /// conditions only: a boulder intact or destroyed, not its cell, so that the shaping
    /// does not pay for pushing it about) or full (their full state, as E) [default:
    /// task]. Objects named with --objects are counted as named.
    #[arg(long, value_parser = named::<PotentialObjects>(&["task", "full"]))]
    pub potential_objects: Option<PotentialObjects>,
    /// The dynamics E is computed on: exact (the world as it is; in a stochastic world
    /// the channel capacity of its noisy dynamics) or deterministic (the same map with
    /// slip 0 and every rule's p 1: what ignoring the noise gives) [default: exact].
    #[arg(long, value_parser = named::<EmpowermentModel>(&["exact", "deterministic"]))]
    pub empowerment_model: Option<EmpowermentModel>,
    /// Serve the intrinsic reward from someone's estimates of E instead of the exact
    /// values: a CSV with the columns state (76 hex digits of the packed state),
    /// horizon and estimate (bits), every state of the space at the horizons the form
    /// uses (`examples/python/learned_empowerment.py` writes one from a dataset made
    /// with --states all). Beta's default stays the exact table's, so the two runs
    /// differ only in E.
    #[arg(long, value_name = "FILE")]
    pub empowerment_from: Option<std::path::PathBuf>,
    /// Two value heads, as RND: the task reward and the intrinsic reward get their own
    /// value estimates and GAE, the intrinsic reward divided by the running standard
    /// deviation of the intrinsic rewards so far, so that beta weighs the intrinsic
    /// advantage the same way on every world (A = A_ext + beta * A_int).
    #[arg(long)]
    pub intrinsic_value_head: bool,
    /// The intrinsic return's discount with --intrinsic-value-head [default: 0.99].
    #[arg(long, requires = "intrinsic_value_head")]
    pub gamma_int: Option<f32>,
    /// Sample every action in every mode, as the paper's agent does, instead of only the
    /// actions the mode allows (moves and, holding a tool, apply; at the tool prompt a
    /// held tool; at the direction prompt a direction).
    #[arg(long)]
    pub no_action_mask: bool,
    /// What of the map the policy sees: full (the whole map), or crop:R (the
    /// (2R+1) x (2R+1) window centred on the agent, as MiniHack's glyphs_crop; cells
    /// beyond the map read as rock) [default: full].
    #[arg(long, value_name = "full|crop:R", value_parser = |s: &str| s.parse::<View>())]
    pub view: Option<View>,
    /// A world family's layouts to train on: N (the layout seeds 0..N, each episode one
    /// of them) or all (a fresh layout every episode); held-out layouts lie beyond both
    /// (`eval --layouts test:K`) [default for a family: all].
    #[arg(long, value_name = "N|all", value_parser = |s: &str| s.parse::<Layouts>())]
    pub layouts: Option<Layouts>,
    /// Seed of weights, sampling, minibatches and worlds.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Actor processes [default: cores - 1, at least 1].
    #[arg(long)]
    pub actors: Option<usize>,
    /// Worlds per actor [default: 8].
    #[arg(long)]
    pub envs_per_actor: Option<usize>,
    /// Steps per chunk (per world per update) [default: 128].
    #[arg(long)]
    pub steps_per_chunk: Option<usize>,
    /// Hidden units of the network [default: 64].
    #[arg(long)]
    pub hidden: Option<usize>,
    /// Tool of the empowerment channel: a tool, `all`, or `auto` [default: the world's].
    #[arg(long, value_parser = |s: &str| Ok::<_, String>(ChannelTool::from(s)))]
    pub tool: Option<ChannelTool>,
    /// Objects of interest, joint (`a,b`; `conditions:a,b` by their conditions only)
    /// [default: the world's].
    #[arg(long)]
    pub objects: Option<String>,
    /// Horizon where the tool is not held [default: the world's].
    #[arg(long)]
    pub horizon_unequipped: Option<u32>,
    /// Horizon where the tool is held [default: the world's].
    #[arg(long)]
    pub horizon_equipped: Option<u32>,
    /// Adam learning rate at the start, annealed to 0 [default: 2.5e-4].
    #[arg(long)]
    pub lr: Option<f64>,
    /// PPO epochs per update [default: 4].
    #[arg(long)]
    pub epochs: Option<usize>,
    /// Minibatches per epoch [default: 4].
    #[arg(long)]
    pub minibatches: Option<usize>,
    /// PPO settings: fulcrum (CleanRL's ppo.py with an advantage floor of 0.1), cleanrl
    /// (CleanRL's exactly), rllib (RLlib's defaults, the paper's learner: lr 5e-5
    /// constant, 8 x 512 steps, 30 epochs of 32 minibatches, lambda 1, clip 0.3, no
    /// entropy bonus, adaptive KL penalty) [default: fulcrum]. --lr, --epochs,
    /// --minibatches and --steps-per-chunk override the preset's.
    #[arg(long, value_parser = named::<Preset>(&["fulcrum", "cleanrl", "rllib"]))]
    pub ppo_preset: Option<Preset>,
}

/// What a resume may change: how long the run goes on, how often it saves and
/// evaluates, and how the learner is scheduled.
#[derive(Debug, Clone, Default, PartialEq, clap::Args)]
pub struct Resumable {
    /// Env steps in all: a multiple of the batch (actors x worlds per actor x steps per
    /// chunk) [default: 500000 rounded up to whole updates].
    #[arg(long)]
    pub steps: Option<u64>,
    /// Threads of the learner [default: the cores the actors leave, at least 1].
    #[arg(long)]
    pub learner_threads: Option<usize>,
    /// Asynchronous actors: chunks may come from a policy up to N updates old
    /// [default: 0 = synchronous PPO].
    #[arg(long)]
    pub max_policy_lag: Option<u64>,
    /// Checkpoint every N updates (and at the end) [default: 10].
    #[arg(long)]
    pub checkpoint_every: Option<u64>,
    /// Evaluate the policy every U updates (and after the last): --eval-episodes
    /// episodes with greedy actions (the most probable allowed action; sampled with
    /// --eval-sample), a row in
    /// RUN/eval.csv and eval/* scalars in TensorBoard [default: 0, never]. A resume may
    /// change it.
    #[arg(long, value_name = "U")]
    pub eval_every: Option<u64>,
    /// Episodes of each periodic evaluation [default: 10]. The worlds and greedy actions
    /// are deterministic, so a greedy evaluation's episodes are one episode repeated.
    #[arg(long, value_name = "N")]
    pub eval_episodes: Option<usize>,
    /// Play the periodic evaluation with actions sampled from the policy (seeded by the
    /// run's seed) instead of greedy: rows of mode `train-sample`. A policy that has not
    /// converged on many layouts is judged by its sampled play. A resume may turn it on.
    #[arg(long)]
    pub eval_sample: bool,
}

impl Fixed {
    /// The flags of the settings given (a value, or a switch that is on), in the order
    /// they are declared: what a resume refuses.
    pub fn given(&self) -> Vec<String> {
        let values = serde_json::to_value(self).unwrap_or_default();
        let flags = <Fixed as clap::Args>::augment_args(clap::Command::new("train"));
        flags
            .get_arguments()
            .filter(|a| {
                values
                    .get(a.get_id().as_str())
                    .is_some_and(|v| !v.is_null() && *v != serde_json::Value::Bool(false))
            })
            .filter_map(|a| a.get_long().map(|l| format!("--{l}")))
            .collect()
    }

    /// Refuses settings that contradict each other (each sentence names its flags).
    pub fn check(&self) -> Result<(), BadRequest> {
        let refuse = |m: &str| Err(BadRequest(m.to_string()));
        if self.no_empowerment && self.intrinsic.is_some_and(|f| f != Intrinsic::None) {
            return Err(BadRequest(format!(
                "--no-empowerment and --intrinsic {} contradict each other: choose one",
                self.intrinsic.unwrap_or_default()
            )));
        }
        let none = self.form() == Some(Intrinsic::None);
        if none && self.beta.is_some() {
            return refuse(
                "--beta and --no-empowerment (or --intrinsic none) contradict each other: choose one",
            );
        }
        if self.empowerment_from.is_some() && (none || self.form() == Some(Intrinsic::Count)) {
            return refuse(
                "--empowerment-from needs a form that uses E (not --no-empowerment, --intrinsic none or count)",
            );
        }
        if none && self.empowerment_model.is_some() {
            return refuse(
                "--empowerment-model and --no-empowerment (or --intrinsic none) contradict each other: a run without empowerment computes none",
            );
        }
        Ok(())
    }

    /// The intrinsic reward form asked for (`--no-empowerment`: none; `--paper`:
    /// additive), `None` for the default.
    pub fn form(&self) -> Option<Intrinsic> {
        if self.no_empowerment {
            Some(Intrinsic::None)
        } else if self.paper {
            Some(Intrinsic::Additive)
        } else {
            self.intrinsic
        }
    }

    /// Whether actions that cannot change anything are masked out (not with
    /// `--no-action-mask` or `--paper`).
    pub fn action_mask(&self) -> bool {
        !(self.no_action_mask || self.paper)
    }

    /// The PPO preset asked for (`--paper`: RLlib's), `None` for the default.
    pub fn preset(&self) -> Option<Preset> {
        if self.paper {
            Some(Preset::Rllib)
        } else {
            self.ppo_preset
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every fixed setting is named by its own flag when given, in declaration order,
    /// and nothing is named when nothing is given. The expected flags are spelt out by
    /// hand: a field the derivation missed (or named wrongly) fails here.
    #[test]
    fn given_names_each_fixed_setting_by_its_flag() {
        assert!(Fixed::default().given().is_empty());
        let all = Fixed {
            beta: Some(0.5),
            no_empowerment: true,
            intrinsic: Some(Intrinsic::Count),
            paper: true,
            horizon_mode: Some(HorizonMode::Fixed),
            potential_objects: Some(PotentialObjects::Full),
            empowerment_model: Some(EmpowermentModel::Deterministic),
            empowerment_from: Some("e.csv".into()),
            intrinsic_value_head: true,
            gamma_int: Some(0.9),
            no_action_mask: true,
            view: Some(View::Crop(2)),
            layouts: Some(Layouts::All),
            seed: Some(0),
            actors: Some(1),
            envs_per_actor: Some(1),
            steps_per_chunk: Some(1),
            hidden: Some(1),
            tool: Some(ChannelTool::All),
            objects: Some(String::new()),
            horizon_unequipped: Some(0),
            horizon_equipped: Some(0),
            lr: Some(0.0),
            epochs: Some(1),
            minibatches: Some(1),
            ppo_preset: Some(Preset::CleanRl),
        };
        let want = "--beta --no-empowerment --intrinsic --paper --horizon-mode --potential-objects --empowerment-model --empowerment-from --intrinsic-value-head --gamma-int --no-action-mask --view --layouts --seed --actors --envs-per-actor --steps-per-chunk --hidden --tool --objects --horizon-unequipped --horizon-equipped --lr --epochs --minibatches --ppo-preset";
        assert_eq!(all.given().join(" "), want);
        let two = Fixed {
            view: Some(View::Full),
            seed: Some(3),
            ..Fixed::default()
        };
        assert_eq!(two.given(), ["--view", "--seed"]);
    }

    #[test]
    fn the_paper_flag_sets_form_mask_and_preset() {
        let p = Fixed {
            paper: true,
            ..Fixed::default()
        };
        assert_eq!(
            (p.form(), p.action_mask(), p.preset()),
            (Some(Intrinsic::Additive), false, Some(Preset::Rllib))
        );
        let d = Fixed::default();
        assert_eq!((d.form(), d.action_mask(), d.preset()), (None, true, None));
        let b = Fixed {
            no_empowerment: true,
            beta: Some(0.1),
            ..Fixed::default()
        };
        assert!(b
            .check()
            .unwrap_err()
            .0
            .contains("--beta and --no-empowerment"));
    }
}
