//! `fulcrum train`'s flags, and the request they make (`TrainArgs::request`).

use std::path::PathBuf;

use clap::Args;
use fulcrum_learner::preset::Preset;
use fulcrum_run::plan::TrainRequest;
use fulcrum_run::BadRequest;
use fulcrum_shared::config::ChannelTool;
use fulcrum_shared::intrinsic::Intrinsic;

use super::zenoh::ZenohArgs;

/// `fulcrum train`
#[derive(Debug, Args)]
pub struct TrainArgs {
    /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room).
    #[arg(required_unless_present = "resume")]
    pub world: Option<String>,
    /// Weight of the intrinsic reward [default: for horizon-potential 0.4 / max Phi, so that
    /// the shaping along any path pays at most 0.4 (0.05 for a two-state object such as
    /// the tree at H = 8); 0.1 for first-visit; the world's [empowerment] beta for the
    /// others].
    #[arg(long, allow_negative_numbers = true)]
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
    #[arg(long, value_parser = ["additive", "potential", "horizon-potential", "first-visit", "count", "none"])]
    pub intrinsic: Option<String>,
    /// The paper's setting in one flag: the additive bonus with the world's beta, every
    /// action in every mode (no mask) and RLlib's PPO defaults (= `--intrinsic additive
    /// --no-action-mask --ppo-preset rllib`).
    #[arg(long, conflicts_with_all = ["intrinsic", "no_empowerment", "ppo_preset"])]
    pub paper: bool,
    /// switch: the held / not-held horizons of the world file (the paper's); fixed: the
    /// not-held horizon everywhere [default: switch].
    #[arg(long, value_parser = ["switch", "fixed"])]
    pub horizon_mode: Option<String>,
    /// The dynamics E is computed on: exact (the world as it is; in a stochastic world
    /// the channel capacity of its noisy dynamics) or deterministic (the same map with
    /// slip 0 and every rule's p 1: what ignoring the noise gives) [default: exact].
    #[arg(long, value_parser = ["exact", "deterministic"])]
    pub empowerment_model: Option<String>,
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
    #[arg(long, value_name = "full|crop:R")]
    pub view: Option<String>,
    /// Seed of weights, sampling, minibatches and worlds.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Env steps in all: a multiple of the batch (actors x worlds per actor x steps per
    /// chunk) [default: 500000 rounded up to whole updates].
    #[arg(long)]
    pub steps: Option<u64>,
    /// Run directory [default: runs/<world>-<time>-<seed>].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Continue the run in this directory from its last checkpoint (its config.toml
    /// holds the settings; only --steps may raise the budget).
    #[arg(long, conflicts_with = "out")]
    pub resume: Option<PathBuf>,
    /// Actor processes [default: cores - 1, at least 1].
    #[arg(long)]
    pub actors: Option<usize>,
    /// Worlds per actor [default: 8].
    #[arg(long)]
    pub envs_per_actor: Option<usize>,
    /// Steps per chunk (per world per update) [default: 128].
    #[arg(long)]
    pub steps_per_chunk: Option<usize>,
    /// Threads of the learner [default: the cores the actors leave, at least 1].
    #[arg(long)]
    pub learner_threads: Option<usize>,
    /// Hidden units of the network [default: 64].
    #[arg(long)]
    pub hidden: Option<usize>,
    /// Tool of the empowerment channel: a tool, `all`, or `auto` [default: the world's].
    #[arg(long)]
    pub tool: Option<String>,
    /// Objects of interest, joint (`a,b`) [default: the world's].
    #[arg(long)]
    pub objects: Option<String>,
    /// Horizon where the tool is not held [default: the world's].
    #[arg(long)]
    pub horizon_unequipped: Option<u32>,
    /// Horizon where the tool is held [default: the world's].
    #[arg(long)]
    pub horizon_equipped: Option<u32>,
    /// Asynchronous actors: chunks may come from a policy up to N updates old
    /// [default: 0 = synchronous PPO].
    #[arg(long)]
    pub max_policy_lag: Option<u64>,
    /// Checkpoint every N updates (and at the end) [default: 10].
    #[arg(long)]
    pub checkpoint_every: Option<u64>,
    /// Evaluate the policy every U updates (and after the last): --eval-episodes
    /// episodes with greedy actions (the most probable allowed action), a row in
    /// RUN/eval.csv and eval/* scalars in TensorBoard [default: 0, never]. A resume may
    /// change it.
    #[arg(long, value_name = "U")]
    pub eval_every: Option<u64>,
    /// Episodes of each periodic evaluation [default: 10]. The worlds and greedy actions
    /// are deterministic, so a greedy evaluation's episodes are one episode repeated.
    #[arg(long, value_name = "N")]
    pub eval_episodes: Option<usize>,
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
    #[arg(long, value_parser = ["fulcrum", "cleanrl", "rllib"])]
    pub ppo_preset: Option<String>,
    /// Stop (with a checkpoint, resumable) after this many updates in this session.
    #[arg(long, hide = true)]
    pub stop_after_updates: Option<u64>,
    /// Restarts each child (each actor slot, the empowerment service, the bridge) may
    /// have within --restart-window seconds; one more stop ends the run. Restarts wait
    /// a back-off of 100 ms doubling to 10 s.
    #[arg(long, default_value_t = fulcrum_run::restart::DEFAULT_MAX_RESTARTS)]
    pub max_restarts: u32,
    /// The window of --max-restarts, seconds.
    #[arg(long, value_name = "SECS", default_value_t = fulcrum_run::restart::DEFAULT_WINDOW_S)]
    pub restart_window: f64,
    /// End the run (exit 1, naming who stalled) when no update came for this many
    /// seconds and 20 times the recent update time.
    #[arg(long, value_name = "SECS", default_value_t = fulcrum_run::watchdog::DEFAULT_FLOOR_S)]
    pub hang_timeout: f64,
    /// At the end, play N episodes of the final policy and draw each as a strip of
    /// frames in RUN/episodes/ (as `fulcrum record`).
    #[arg(long)]
    pub record: Option<usize>,
    /// Let actors on other hosts join (`fulcrum actor-host --connect ADDR` there):
    /// listen for zenoh peers on ADDR (`host:port` or a zenoh locator such as
    /// `tcp/0.0.0.0:7447`). Needs the `multihost` feature.
    #[arg(long, value_name = "ADDR")]
    #[cfg_attr(not(feature = "multihost"), arg(hide = true))]
    pub listen: Option<String>,
    /// With --listen: seconds the learner waits for a remote actor's chunk before it
    /// goes on without it [default: 10].
    #[arg(long, value_name = "SECS")]
    #[cfg_attr(not(feature = "multihost"), arg(hide = true))]
    pub stall_timeout: Option<f64>,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
}

impl TrainArgs {
    /// The run this command line asks for, with the mistakes only flags can make
    /// (contradicting flags, a setting that a resume cannot change) refused, each
    /// naming its flags.
    pub fn request(&self) -> Result<TrainRequest, BadRequest> {
        let a = self;
        let refuse = |m: String| Err(BadRequest(m));
        if a.no_empowerment && a.intrinsic.as_deref().is_some_and(|f| f != "none") {
            return refuse(format!(
                "--no-empowerment and --intrinsic {} contradict each other: choose one",
                a.intrinsic.as_deref().unwrap_or_default()
            ));
        }
        let none = a.no_empowerment || a.intrinsic.as_deref() == Some("none");
        if none && a.beta.is_some() {
            return refuse(
                "--beta and --no-empowerment (or --intrinsic none) contradict each other: choose one"
                    .into(),
            );
        }
        if none && a.empowerment_model.is_some() {
            return refuse(
                "--empowerment-model and --no-empowerment (or --intrinsic none) contradict each other: a run without empowerment computes none"
                    .into(),
            );
        }
        if let Some(dir) = &a.resume {
            let changed: Vec<&str> = [
                (a.beta.is_some(), "--beta"),
                (a.no_empowerment, "--no-empowerment"),
                (a.no_action_mask, "--no-action-mask"),
                (a.paper, "--paper"),
                (a.view.is_some(), "--view"),
                (a.intrinsic_value_head, "--intrinsic-value-head"),
                (a.gamma_int.is_some(), "--gamma-int"),
                (a.intrinsic.is_some(), "--intrinsic"),
                (a.horizon_mode.is_some(), "--horizon-mode"),
                (a.empowerment_model.is_some(), "--empowerment-model"),
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
                return refuse(format!(
                    "--resume continues a run with the settings in {}; {} cannot be changed (start a new run instead)",
                    dir.join("config.toml").display(),
                    changed.join(", ")
                ));
            }
        }
        Ok(TrainRequest {
            world: a.world.clone(),
            beta: a.beta,
            intrinsic: if a.no_empowerment {
                Some(Intrinsic::None)
            } else if a.paper {
                Some(Intrinsic::Additive)
            } else {
                a.intrinsic
                    .as_deref()
                    .map(str::parse)
                    .transpose()
                    .map_err(BadRequest)?
            },
            horizon_mode: a
                .horizon_mode
                .as_deref()
                .map(str::parse)
                .transpose()
                .map_err(BadRequest)?,
            empowerment_model: a
                .empowerment_model
                .as_deref()
                .map(str::parse)
                .transpose()
                .map_err(BadRequest)?,
            intrinsic_value_head: a.intrinsic_value_head,
            gamma_int: a.gamma_int,
            action_mask: !(a.no_action_mask || a.paper),
            view: a
                .view
                .as_deref()
                .map(str::parse)
                .transpose()
                .map_err(|e| BadRequest(format!("--view: {e}")))?,
            seed: a.seed,
            steps: a.steps,
            out: a.out.clone(),
            resume: a.resume.clone(),
            actors: a.actors,
            envs_per_actor: a.envs_per_actor,
            steps_per_chunk: a.steps_per_chunk,
            learner_threads: a.learner_threads,
            hidden: a.hidden,
            tool: a.tool.as_deref().map(ChannelTool::from),
            objects: a.objects.clone(),
            horizon_unequipped: a.horizon_unequipped,
            horizon_equipped: a.horizon_equipped,
            max_policy_lag: a.max_policy_lag,
            checkpoint_every: a.checkpoint_every,
            eval_every: a.eval_every,
            eval_episodes: a.eval_episodes,
            lr: a.lr,
            epochs: a.epochs,
            minibatches: a.minibatches,
            ppo_preset: if a.paper {
                Some(Preset::Rllib)
            } else {
                a.ppo_preset
                    .as_deref()
                    .map(str::parse)
                    .transpose()
                    .map_err(BadRequest)?
            },
            remote: a.listen.is_some(),
            stall_timeout: a.stall_timeout,
        })
    }
}

impl TrainArgs {
    /// The supervisor's restart policy and watchdog floor, from --max-restarts,
    /// --restart-window and --hang-timeout.
    pub fn supervision(
        &self,
    ) -> Result<(fulcrum_run::restart::RestartPolicy, std::time::Duration), BadRequest> {
        let secs = |v: f64, flag: &str| {
            if v.is_finite() && v > 0.0 && v < 1e9 {
                Ok(std::time::Duration::from_secs_f64(v))
            } else {
                Err(BadRequest(format!(
                    "{flag} {v} must be a positive number of seconds"
                )))
            }
        };
        let policy = fulcrum_run::restart::RestartPolicy {
            max: self.max_restarts,
            window: secs(self.restart_window, "--restart-window")?,
        };
        Ok((policy, secs(self.hang_timeout, "--hang-timeout")?))
    }
}
