//! The command line: clap types only. The work is in `commands/`.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};
use fulcrum_learner::preset::Preset;
use fulcrum_run::child::ChildRequest;
use fulcrum_run::plan::TrainRequest;
use fulcrum_run::BadRequest;
use fulcrum_shared::config::ChannelTool;
use fulcrum_shared::intrinsic::Intrinsic;

/// fulcrum: tool worlds, exact object empowerment, and PPO agents that learn to use tools.
#[derive(Debug, Parser)]
#[command(name = "fulcrum", version, about, propagate_version = true)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
#[allow(clippy::large_enum_variant)] // parsed once per process
pub enum Command {
    /// Inspect or generate tool worlds.
    #[command(subcommand)]
    World(WorldCmd),
    /// Exact object empowerment: matrix, landscape, trace, query.
    #[command(subcommand)]
    Empowerment(EmpCmd),
    /// Run the empowerment service for one world (until Ctrl-C or SIGTERM).
    Serve(ServeArgs),
    /// Train a PPO agent with reward R + beta * E: actor processes, the empowerment
    /// service and a candle learner, connected by shared memory.
    Train(TrainArgs),
    /// Every (arm, seed) pair trained with `train`, then mean +/- std curves and a
    /// summary table per arm (steps to a success rate, final success, Welch's t-test).
    Experiment(ExperimentArgs),
    /// Episodes of a run's policy as strips of frames (PNG): where the agent goes and
    /// where the empowerment bonus is.
    Record(RecordArgs),
    /// Play a run's policy for N episodes (greedy or sampled, on its world or another of
    /// the same shape): success, return, length and tool use with 95% intervals, appended
    /// to RUN/eval.csv.
    Eval(EvalArgs),
    /// The throughput suite: timings with the machine they ran on.
    Bench(BenchArgs),
    /// Actors on this host for a run whose learner is on another host (`train
    /// --listen`); needs the `multihost` feature.
    ActorHost(ActorHostArgs),
    /// Forward a run's chunks, weights and empowerment lookups between this host's
    /// shared memory and zenoh (started by `train --listen` and `actor-host`); needs the
    /// `multihost` feature.
    Bridge(BridgeArgs),
    /// (train helper) the learner process of a run.
    #[command(hide = true, name = "__learner")]
    Learner(ChildArgs),
    /// (train helper) an actor process of a run.
    #[command(hide = true, name = "__actor")]
    Actor(ChildArgs),
    /// (bench helper) a client process that looks states up for a while.
    #[command(hide = true, name = "__bench-client")]
    BenchClient {
        /// Service namespace.
        #[arg(long)]
        namespace: String,
        /// World the service serves.
        #[arg(long)]
        world: String,
        /// How long to run.
        #[arg(long)]
        seconds: f64,
        /// States per request.
        #[arg(long)]
        batch: usize,
    },
    /// (test helper) count visits of one state at a running service, printing each
    /// count the service answers.
    #[command(hide = true, name = "__visit")]
    Visit {
        /// Service namespace.
        #[arg(long)]
        namespace: String,
        /// World the service serves.
        #[arg(long)]
        world: String,
        /// The state, as a description.
        #[arg(long)]
        state: String,
        /// Visits, one request each.
        #[arg(long)]
        times: usize,
    },
    /// (bench helper) the far end of `bench --remote`: chunk sink and lookups.
    #[command(hide = true, name = "__remote-peer")]
    RemotePeer {
        /// Where to listen (host:port or a zenoh locator).
        #[arg(long)]
        listen: String,
    },
    /// (bench helper) echo Unix datagrams on a socket path until told to stop.
    #[command(hide = true, name = "__pingpong")]
    PingPong {
        /// Socket path to bind.
        path: std::path::PathBuf,
    },
}

/// `fulcrum serve`
#[derive(Debug, Args)]
pub struct ServeArgs {
    /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room, and the stochastic exp1-tree-slip, exp2-slip).
    #[arg(required_unless_present = "run")]
    pub world: Option<String>,
    /// The service of a training run: world, tool, objects, horizons, the table's form,
    /// model and clients all from RUN/config.toml (what `fulcrum train` starts).
    #[arg(long, value_name = "RUN", conflicts_with_all = ["world", "tool", "objects", "horizon_unequipped", "horizon_equipped", "horizon_sum", "model", "max_clients"])]
    pub run: Option<PathBuf>,
    /// Tool of the lookup table: a tool name, `all`, or `auto` (tool selection by the
    /// matrix). Default: the world's [empowerment] tool.
    #[arg(long)]
    pub tool: Option<String>,
    /// Objects of interest, joint: `a,b` or `agent`. Default: the world's.
    #[arg(long)]
    pub objects: Option<String>,
    /// Horizon where the tool is not held (default: the world's).
    #[arg(long)]
    pub horizon_unequipped: Option<u32>,
    /// Horizon where the tool is held (default: the world's).
    #[arg(long)]
    pub horizon_equipped: Option<u32>,
    /// LOOKUP answers Phi = sum over h = 1..H of E^h (H the larger horizon) instead of E:
    /// the potential of `train --intrinsic horizon-potential`.
    #[arg(long)]
    pub horizon_sum: bool,
    /// The dynamics the table is computed on: exact (the world as it is) or
    /// deterministic (the same map with slip 0 and every rule's p 1); either way the
    /// service answers for the world's own states and hash.
    #[arg(long, default_value = "exact", value_parser = ["exact", "deterministic"])]
    pub model: String,
    /// Service namespace: the service is `fulcrum/<namespace>/empowerment`.
    #[arg(long, default_value = "default")]
    pub namespace: String,
    /// Memory for cached ad-hoc query tables, in MiB.
    #[arg(long, default_value_t = 256)]
    pub cache_mib: usize,
    /// Clients the service takes at once. Its shared memory grows with them (about
    /// 1.2 MiB a client); `fulcrum train` makes its service for its own actors and 8
    /// more.
    #[arg(long, default_value_t = fulcrum_shared::msg::MAX_CLIENTS)]
    pub max_clients: usize,
}

/// `fulcrum world ...`
#[derive(Debug, Subcommand)]
pub enum WorldCmd {
    /// Map, tools, objects, actions and state-space size of a world.
    Show {
        /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room, and the stochastic exp1-tree-slip, exp2-slip).
        world: String,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Write a random valid world file (an open room with tools and objects).
    Generate(GenerateArgs),
}

/// `fulcrum world generate`
#[derive(Debug, Args)]
pub struct GenerateArgs {
    /// Map width, rock border included (3..=64).
    #[arg(long, default_value_t = 12)]
    pub width: usize,
    /// Map height, rock border included (3..=64).
    #[arg(long, default_value_t = 8)]
    pub height: usize,
    /// Number of tools (kinds cycle through axe, pickaxe, key, wand, tin_opener, katana).
    #[arg(long, default_value_t = 4)]
    pub tools: usize,
    /// Number of objects (kinds drawn from tree, wall, door, boulder).
    #[arg(long, default_value_t = 2)]
    pub objects: usize,
    /// Fraction of inner cells turned to rock, in [0, 0.5).
    #[arg(long, default_value_t = 0.0)]
    pub rock: f64,
    /// Seed: the same parameters and seed give the same file.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Write to this file (atomically) instead of standard output.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// How values are computed.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum MethodArg {
    /// Set propagation over the state space (exact, fast).
    Dp,
    /// Enumerate every action sequence (the paper's method; slow reference).
    Enumerate,
}

/// What every empowerment question names.
#[derive(Debug, Args)]
pub struct Channel {
    /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room, and the stochastic exp1-tree-slip, exp2-slip).
    pub world: String,
    /// Tool whose actions drive the channel: a tool name, kind or letter, or `all`.
    /// Default: the world's [empowerment] tool (auto = the matrix's selection).
    #[arg(long)]
    pub tool: Option<String>,
    /// Object set D, joint: `a,b` (or `a+b`), or `agent`. Default: the world's.
    #[arg(long)]
    pub objects: Option<String>,
    /// Horizon h. Default: the world's, by whether the tool is held.
    #[arg(long)]
    pub horizon: Option<u32>,
    /// dp (default) or enumerate.
    #[arg(long, value_enum, default_value_t = MethodArg::Dp)]
    pub method: MethodArg,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `fulcrum empowerment ...`
#[derive(Debug, Subcommand)]
pub enum EmpCmd {
    /// The tool-object empowerment matrix and tool selection.
    Matrix(MatrixArgs),
    /// Values over the map for one inventory.
    Landscape(LandscapeArgs),
    /// Values along an action sequence from the initial state.
    Trace(TraceArgs),
    /// The value at one state, or at each state of a file.
    Query(QueryArgs),
}

/// `fulcrum empowerment matrix`
#[derive(Debug, Args)]
pub struct MatrixArgs {
    /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room, and the stochastic exp1-tree-slip, exp2-slip).
    pub world: String,
    /// One horizon for held and not-held states.
    #[arg(long, conflicts_with_all = ["horizon_unequipped", "horizon_equipped"])]
    pub horizon: Option<u32>,
    /// Horizon where the row's tool is not held (default: the world's).
    #[arg(long)]
    pub horizon_unequipped: Option<u32>,
    /// Horizon where the row's tool is held (default: the world's).
    #[arg(long)]
    pub horizon_equipped: Option<u32>,
    /// Single-object columns, comma separated (default: every object).
    #[arg(long)]
    pub objects: Option<String>,
    /// A joint column `a+b` (repeatable).
    #[arg(long)]
    pub joint: Vec<String>,
    /// Also draw the matrix as a PNG (cells coloured by value, the selection framed).
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// dp (default) or enumerate.
    #[arg(long, value_enum, default_value_t = MethodArg::Dp)]
    pub method: MethodArg,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `fulcrum empowerment landscape`
#[derive(Debug, Args)]
pub struct LandscapeArgs {
    /// World, tool, objects, horizon.
    #[command(flatten)]
    pub channel: Channel,
    /// Inventory: tools held, comma separated (default: none).
    #[arg(long, default_value = "")]
    pub holding: String,
    /// Also write a heatmap PNG.
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// `fulcrum empowerment trace`
#[derive(Debug, Args)]
pub struct TraceArgs {
    /// World, tool, objects, horizon.
    #[command(flatten)]
    pub channel: Channel,
    /// Actions, comma separated: N, E, S, W, apply, or a tool name (= select it).
    #[arg(long)]
    pub actions: String,
    /// Also write the time plot as a PNG.
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// `fulcrum empowerment query`
#[derive(Debug, Args)]
pub struct QueryArgs {
    /// World, tool, objects, horizon.
    #[command(flatten)]
    pub channel: Channel,
    /// A state: `agent=X,Y holding=a,b mode=normal door=open boulder=7,3 ...`.
    #[arg(long, required_unless_present = "states_file")]
    pub state: Option<String>,
    /// A file with one state description per line (blank lines and # comments skipped).
    #[arg(long, conflicts_with = "state")]
    pub states_file: Option<PathBuf>,
    /// Ask a running service (`fulcrum serve`) instead of computing here.
    #[arg(long)]
    pub service: bool,
    /// The service's namespace.
    #[arg(long, default_value = "default", requires = "service")]
    pub namespace: String,
    /// Seconds to wait for the service to appear.
    #[arg(long, default_value_t = 5.0, requires = "service")]
    pub wait: f64,
}

/// `fulcrum bench`
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Fewer repetitions and smaller worlds (CI).
    #[arg(long)]
    pub quick: bool,
    /// Also write the figures as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Run the scaling study instead (several minutes): end-to-end training steps/s
    /// over 1, 2, 4 actors x 16, 64, 256 worlds per actor, and empowerment table time
    /// over 10^3..10^7 states; draws two PNGs into --plots.
    #[arg(long, conflicts_with = "quick")]
    pub scaling: bool,
    /// Where the scaling study draws its pictures.
    #[arg(long, default_value = "docs", requires = "scaling")]
    pub plots: PathBuf,
    /// Scaling study: leave out state counts above this (e.g. 1000000 on a small machine).
    #[arg(long, requires = "scaling")]
    pub max_states: Option<u64>,
    /// The link between hosts instead (feature `multihost`): chunk throughput (64 KiB,
    /// 1 MiB) and lookup round trips against a peer at ADDR (`fulcrum __remote-peer
    /// --listen ADDR` there; `scripts/two-hosts.sh bench`), or one started on 127.0.0.1.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "", conflicts_with = "scaling")]
    pub remote: Option<String>,
}

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

/// How a host reaches the others (feature `multihost`).
#[derive(Debug, Clone, Args)]
pub struct ZenohArgs {
    /// Seconds without a word from the other host before its session is closed (zenoh's
    /// link lease); a host whose session closed reconnects by itself.
    #[arg(long, value_name = "SECS", default_value_t = 10.0)]
    #[cfg_attr(not(feature = "multihost"), arg(hide = true))]
    pub session_timeout: f64,
    /// A zenoh configuration file (JSON5) to start from; fulcrum sets mode, endpoints
    /// and lease on top of it.
    #[arg(long, value_name = "FILE")]
    #[cfg_attr(not(feature = "multihost"), arg(hide = true))]
    pub zenoh_config: Option<PathBuf>,
}

/// `fulcrum actor-host`
#[derive(Debug, Args)]
pub struct ActorHostArgs {
    /// The learner's host: the ADDR its `train --listen` listens on (`host:port` or a
    /// zenoh locator).
    #[arg(long, value_name = "ADDR")]
    pub connect: String,
    /// Actor processes on this host [default: cores - 1, at least 1].
    #[arg(long)]
    pub actors: Option<usize>,
    /// This host's name in the run's metrics [default: the hostname].
    #[arg(long)]
    pub name: Option<String>,
    /// Refuse to join unless the run trains this world (a file or built-in name).
    #[arg(long)]
    pub world: Option<String>,
    /// Refuse to join unless the run has this id (its run directory's name by default,
    /// as `train` prints it).
    #[arg(long)]
    pub run_id: Option<String>,
    /// Working directory (the run's config and world as received, logs)
    /// [default: runs/remote-<name>].
    #[arg(long)]
    pub dir: Option<PathBuf>,
    /// Seconds to wait for the learner, at the start and after a lost link.
    #[arg(long, value_name = "SECS", default_value_t = 600.0)]
    pub give_up: f64,
    /// Restarts each of this host's actors may have within --restart-window seconds;
    /// one more stop ends the host. Restarts wait a back-off of 100 ms doubling to 10 s.
    #[arg(long, default_value_t = fulcrum_run::restart::DEFAULT_MAX_RESTARTS)]
    pub max_restarts: u32,
    /// The window of --max-restarts, seconds.
    #[arg(long, value_name = "SECS", default_value_t = fulcrum_run::restart::DEFAULT_WINDOW_S)]
    pub restart_window: f64,
    /// A file holding the run's secret (a copy of the run directory's `secret`);
    /// without it the secret is taken from the environment variable FULCRUM_SECRET.
    #[arg(long, value_name = "FILE")]
    pub secret_file: Option<PathBuf>,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
}

/// `fulcrum bridge`
#[derive(Debug, Args)]
pub struct BridgeArgs {
    /// The learner's side: listen on ADDR for actor hosts.
    #[arg(
        long,
        value_name = "ADDR",
        conflicts_with = "connect",
        required_unless_present = "connect"
    )]
    pub listen: Option<String>,
    /// An actor host's side: connect to the learner's host at ADDR.
    #[arg(long, value_name = "ADDR")]
    pub connect: Option<String>,
    /// The run directory (--listen), or this host's working directory (--connect).
    #[arg(long)]
    pub run: PathBuf,
    /// --listen: the run's shared-memory namespace.
    #[arg(long, required_unless_present = "connect")]
    pub namespace: Option<String>,
    /// --connect: this host's name [default: the hostname].
    #[arg(long)]
    pub name: Option<String>,
    /// --connect: refuse to join unless the run trains this world.
    #[arg(long)]
    pub world: Option<String>,
    /// --connect: refuse to join unless the run has this id.
    #[arg(long)]
    pub run_id: Option<String>,
    /// --connect: seconds to wait for the learner, at the start and after a lost link.
    #[arg(long, value_name = "SECS", default_value_t = 600.0)]
    pub give_up: f64,
    /// --connect: a file holding the run's secret [default: FULCRUM_SECRET].
    #[arg(long, value_name = "FILE")]
    pub secret_file: Option<PathBuf>,
    /// Stop when this process is gone.
    #[arg(long, hide = true)]
    pub parent: Option<u32>,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
}

/// `fulcrum record`
#[derive(Debug, Args)]
pub struct RecordArgs {
    /// A run directory (with its checkpoint).
    pub run: PathBuf,
    /// Episodes to play and draw (1 to 100).
    #[arg(long, default_value_t = 3)]
    pub episodes: usize,
    /// Where the pictures go [default: RUN/episodes].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Seed of the action sampling [default: the run's seed].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Also write each episode as an animated GIF (`episode-<k>.gif`, one frame per
    /// step, looping).
    #[arg(long)]
    pub gif: bool,
}

/// `fulcrum eval`
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// A run directory (with its checkpoint).
    pub run: PathBuf,
    /// Episodes to play (1 to 100000).
    #[arg(long, default_value_t = 100)]
    pub episodes: usize,
    /// The most probable allowed action at each step (the default).
    #[arg(long, conflicts_with = "sample")]
    pub greedy: bool,
    /// Sample actions from the policy, as the actors do.
    #[arg(long)]
    pub sample: bool,
    /// Seed of the sampling [default: the run's seed].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Play on this world (a file or a built-in name) instead of the run's: one with the
    /// same number of tools, and of the same size unless the run's view is a crop.
    #[arg(long)]
    pub world: Option<String>,
    /// A checkpoint file [default: RUN/checkpoints/latest.safetensors].
    #[arg(long)]
    pub checkpoint: Option<PathBuf>,
}

/// `fulcrum experiment`
#[derive(Debug, Args)]
pub struct ExperimentArgs {
    /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room).
    #[arg(required_unless_present = "worlds", conflicts_with = "worlds")]
    pub world: Option<String>,
    /// Instead of one world, a set of generated worlds nobody wrote: gen:N, or
    /// gen:N:width=W,height=H,tools=T,objects=O,rock=R,seed=S (defaults 12 x 8, 3
    /// tools, 2 objects, rock 0.1, seed 1): the first N worlds of `world generate`
    /// from that seed on whose task can be done within an episode (a search over the
    /// world's states), every arm and seed on each, and the (world, seed) pairs pooled
    /// per arm in DIR/summary.md.
    #[arg(long, value_name = "gen:N[:KEY=VALUE,...]")]
    pub worlds: Option<String>,
    /// Seeds per arm (seeds 1..=N).
    #[arg(long, default_value_t = 10)]
    pub seeds: u64,
    /// Env steps per run [default: train's].
    #[arg(long)]
    pub steps: Option<u64>,
    /// Beta of the empowerment arm [default: the world's].
    #[arg(long, allow_negative_numbers = true)]
    pub beta: Option<f64>,
    /// Arms, comma separated: baseline (no intrinsic reward), empowerment (the
    /// --intrinsic form), a form by name (none, additive, potential, count,
    /// horizon-potential, first-visit), additive-fixed (additive with --horizon-mode
    /// fixed), horizon-potential-deterministic (horizon-potential with
    /// --empowerment-model deterministic: E of the same map without its noise), paper
    /// (train --paper: additive, unmasked, RLlib's PPO), a baseline with another PPO
    /// preset (cleanrl, rllib), or baseline-unmasked (the baseline with
    /// --no-action-mask).
    #[arg(long, default_value = "baseline,empowerment")]
    pub arms: String,
    /// The intrinsic reward form of the `empowerment` arm and of --beta-sweep's arms
    /// (train's default form).
    #[arg(long, default_value = "horizon-potential", value_parser = ["additive", "potential", "count", "horizon-potential", "first-visit"])]
    pub intrinsic: String,
    /// Also one arm per beta, comma separated, with the --intrinsic form (named
    /// beta-<b> for additive, <form>-beta-<b> otherwise).
    #[arg(long, allow_hyphen_values = true)]
    pub beta_sweep: Option<String>,
    /// Views, comma separated (full, crop:R): every arm once per view, the full view's
    /// under the arm's name, a crop's as <arm>-crop<R> (train --view) [default: full].
    #[arg(long, value_name = "VIEWS")]
    pub views: Option<String>,
    /// Experiment directory [default: experiments/<world>-<time>]; the same command
    /// with the same directory resumes.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Runs at a time [default: cores / --actors].
    #[arg(long)]
    pub parallel: Option<usize>,
    /// Actor processes per run.
    #[arg(long, default_value_t = 1)]
    pub actors: usize,
    /// Worlds per actor.
    #[arg(long, default_value_t = 8)]
    pub envs_per_actor: usize,
    /// Success rate whose first crossing is reported.
    #[arg(long, default_value_t = 0.9)]
    pub threshold: f64,
    /// Updates over which the success rate is pooled (episode-weighted).
    #[arg(long, default_value_t = 10)]
    pub smooth: usize,
    /// More `train` flags for every run, after `--` (e.g. `-- --lr 3e-4`).
    #[arg(last = true, allow_hyphen_values = true)]
    pub train_args: Vec<String>,
}

/// Hidden child processes of `fulcrum train`.
#[derive(Debug, Args)]
pub struct ChildArgs {
    /// The run directory.
    #[arg(long)]
    pub run: PathBuf,
    /// The run's namespace (service names).
    #[arg(long)]
    pub namespace: String,
    /// The supervisor's pid (the child stops when it is gone).
    #[arg(long)]
    pub parent: u32,
    /// Actor index.
    #[arg(long, default_value_t = 0)]
    pub index: u32,
    /// Actor restarts before this one.
    #[arg(long, default_value_t = 0)]
    pub incarnation: u32,
    /// Learner: stop after this many updates of this session.
    #[arg(long)]
    pub stop_after_updates: Option<u64>,
    /// Actor on another host: the run's tag (hex) for its chunks, when the local
    /// namespace is not the run's.
    #[arg(long)]
    pub run_tag: Option<String>,
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

impl ZenohArgs {
    /// The bridge's zenoh settings.
    #[cfg(feature = "multihost")]
    pub fn options(&self) -> fulcrum_bridge::ZenohOptions {
        fulcrum_bridge::ZenohOptions {
            session_timeout: self.session_timeout,
            zenoh_config: self.zenoh_config.clone(),
        }
    }
}

impl ChildArgs {
    /// What the supervisor asked the child process for.
    pub fn request(&self) -> ChildRequest {
        ChildRequest {
            run: self.run.clone(),
            namespace: self.namespace.clone(),
            parent: self.parent,
            index: self.index,
            incarnation: self.incarnation,
            stop_after_updates: self.stop_after_updates,
            run_tag: self.run_tag.clone(),
        }
    }
}
