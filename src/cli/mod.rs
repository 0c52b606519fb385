//! The command line: clap types only. The work is in `commands/`; `fulcrum train`'s
//! flags and the request they make are in `train`.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

#[cfg(test)]
mod argv_tests;
mod train;
mod zenoh;
pub use train::TrainArgs;
pub use zenoh::ZenohArgs;

use fulcrum_run::child::ChildRequest;

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
    #[arg(long, value_name = "RUN", conflicts_with_all = ["world", "tool", "objects", "horizon_unequipped", "horizon_equipped", "horizon_sum", "model", "max_clients", "empowerment_from"])]
    pub run: Option<PathBuf>,
    /// LOOKUP answers from these estimates of E instead of the exact table: a CSV with
    /// the columns state (76 hex digits of the packed state), horizon and estimate, every
    /// state at the horizons the table uses (as `train --empowerment-from`).
    #[arg(long, value_name = "FILE")]
    pub empowerment_from: Option<PathBuf>,
    /// Tool of the lookup table: a tool name, `all`, or `auto` (tool selection by the
    /// matrix). Default: the world's [empowerment] tool.
    #[arg(long)]
    pub tool: Option<String>,
    /// Objects of interest, joint: `a,b` or `agent`; `conditions:a,b` counts them by their
    /// conditions only (a boulder intact or destroyed). Default: the world's.
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
    #[arg(long, default_value_t = fulcrum_contracts::msg::MAX_CLIENTS)]
    pub max_clients: usize,
}

/// `fulcrum world ...`
#[derive(Debug, Subcommand)]
pub enum WorldCmd {
    /// Map, tools, objects, actions and state-space size of a world, or of one layout of
    /// a world family.
    Show {
        /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room, and the stochastic exp1-tree-slip, exp2-slip); or a family (a file with a [family] table, or the built-in toolbox, two-rooms).
        world: String,
        /// The layout of a family to show (its seed) [default: 0].
        #[arg(long, value_name = "N")]
        layout: Option<u64>,
        /// Print JSON instead of text.
        #[arg(long, conflicts_with = "toml")]
        json: bool,
        /// Print the world (a family's layout) as an ordinary world file.
        #[arg(long)]
        toml: bool,
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
    /// Object set D, joint: `a,b` (or `a+b`), or `agent`; `conditions:a,b` counts them by
    /// their conditions only (a boulder intact or destroyed, whatever its cell). Default:
    /// the world's.
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
    /// A dataset for learned estimators: observations, exact E and sampled action
    /// sequences with where they end, one row per state (NumPy .npz).
    Dataset(DatasetArgs),
    /// Score estimates of E (a CSV) against a dataset's exact values.
    Score(ScoreArgs),
}

/// `fulcrum empowerment matrix`
#[derive(Debug, Args)]
pub struct MatrixArgs {
    /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room, and the stochastic exp1-tree-slip, exp2-slip).
    pub world: String,
    /// One horizon for every state and row (default: the world's horizon_unequipped, the
    /// one horizon of `tool = "auto"`'s selection).
    #[arg(long, conflicts_with_all = ["horizon_unequipped", "horizon_equipped"])]
    pub horizon: Option<u32>,
    /// Horizon where the row's tool is not held (and where it is, unless
    /// --horizon-equipped is given).
    #[arg(long)]
    pub horizon_unequipped: Option<u32>,
    /// Horizon where the row's tool is held: the matrix whose rows switch horizon (not
    /// the selection's; such rows are not comparable, see docs/world.md).
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

/// `fulcrum empowerment dataset`
#[derive(Debug, Args)]
pub struct DatasetArgs {
    /// World, tool, objects, horizon.
    #[command(flatten)]
    pub channel: Channel,
    /// Which states: `all`, or `sample:N` (N distinct states drawn uniformly).
    #[arg(long, default_value = "all", value_name = "all|sample:N", value_parser = |s: &str| s.parse::<fulcrum_empowerment::dataset::Rows>())]
    pub states: fulcrum_empowerment::dataset::Rows,
    /// Seed of the state sample, the action sequences and (in a stochastic world) their
    /// outcomes.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// The observation's view, as in training.
    #[arg(long, default_value = "full", value_name = "full|crop:R", value_parser = |s: &str| s.parse::<fulcrum_world::View>())]
    pub view: fulcrum_world::View,
    /// Action sequences sampled per state (uniform over the tool's actions, the row's
    /// horizon long), each stored with the state it ends in.
    #[arg(long, default_value_t = 16)]
    pub sequences: usize,
    /// The .npz file to write (atomically).
    #[arg(long)]
    pub out: PathBuf,
}

/// `fulcrum empowerment score`
#[derive(Debug, Args)]
pub struct ScoreArgs {
    /// A dataset written by `fulcrum empowerment dataset` (or `fulcrum.empowerment.dataset`).
    pub dataset: PathBuf,
    /// A CSV with a header and a column `estimate` (bits): one line per dataset row in
    /// order, or with a column `row` naming each line's row (then only those are scored).
    #[arg(long)]
    pub estimates: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
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
    /// Only these groups of the suite, in the suite's order (comma-separated), to
    /// reproduce one section of BENCHMARKS.md without the rest.
    #[arg(long, value_enum, value_delimiter = ',', value_name = "GROUP", conflicts_with_all = ["scaling", "remote"])]
    pub only: Vec<BenchGroup>,
}

/// A group of `fulcrum bench`'s figures.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum BenchGroup {
    /// Exact empowerment: exp2's matrix, the propagations, the stochastic tables, the
    /// 10^6-state world.
    Empowerment,
    /// A family's layouts never seen: the whole table of each.
    Layouts,
    /// The empowerment service: round trips (after idle too), lookups/s, idle CPU,
    /// the floors.
    Service,
    /// World steps, the learner's update, chunk transport, end-to-end training.
    Training,
    /// Time to solve exp1-tree, and (full run) generated worlds solved by the defaults.
    Solve,
    /// The Python package (needs FULCRUM_PYTHON or `python3` with the package).
    Python,
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
    /// Episodes to play (1 to 100000) [default: 100; with --layouts, one per layout].
    #[arg(long)]
    pub episodes: Option<usize>,
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
    /// A run on a world family: the layouts to play, episode i on layout i (round them
    /// when there are more episodes): test:K (K held-out layouts, which no run trains
    /// on), test:A..B (the seeds A to B-1, refused where they fall among the run's
    /// training layouts) or train:K (the run's first K training layouts) [default for
    /// a family run: test:100].
    #[arg(long, value_name = "test:K|test:A..B|train:K")]
    pub layouts: Option<String>,
}

/// `fulcrum experiment`
#[derive(Debug, Args)]
pub struct ExperimentArgs {
    /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room).
    #[arg(required_unless_present_any = ["worlds", "collect", "task"], conflicts_with = "worlds")]
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
    /// Where the runs go: local (this machine, --parallel at a time) or slurm (a Slurm
    /// job array, one task per arm and seed still to run, per world of a --worlds set:
    /// the script is written to DIR/slurm/ and submitted with sbatch; see --dry-run and
    /// --collect).
    #[arg(long, default_value = "local", value_parser = ["local", "slurm"])]
    pub launcher: String,
    /// With --launcher slurm: write the array script and print it, submit nothing.
    #[arg(long)]
    pub dry_run: bool,
    /// With --launcher slurm: the partition [default: the cluster's].
    #[arg(long, value_name = "NAME")]
    pub slurm_partition: Option<String>,
    /// With --launcher slurm: each task's time limit, in Slurm's form. A task that
    /// runs out is not requeued by Slurm: submit the experiment again to continue.
    #[arg(long, value_name = "TIME", default_value = "4:00:00")]
    pub slurm_time: String,
    /// With --launcher slurm: cores per task [default: --actors, each run's share on a
    /// local machine].
    #[arg(long, value_name = "N")]
    pub slurm_cpus: Option<usize>,
    /// With --launcher slurm: memory per task in Slurm's form (e.g. 4G) [default: the
    /// cluster's].
    #[arg(long, value_name = "SIZE")]
    pub slurm_mem: Option<String>,
    /// With --launcher slurm: one more #SBATCH option, as written after '#SBATCH '
    /// (e.g. --sbatch=--account=rl); may be given again.
    #[arg(long, value_name = "OPTION", allow_hyphen_values = true)]
    pub sbatch: Vec<String>,
    /// Make the summary and plots of the experiment in DIR from its finished runs (after
    /// a Slurm array, or any time), and name the runs that are missing, failed or
    /// unfinished (exit 1 while any is).
    #[arg(long, value_name = "DIR", conflicts_with_all = ["world", "worlds", "task"])]
    pub collect: Option<PathBuf>,
    /// Train one run of the experiment in DIR, given by --arm and --seed, to its
    /// budget (resuming from its checkpoint where it has one): what each Slurm array
    /// task runs.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["world", "worlds"], requires_all = ["arm", "seed"])]
    pub task: Option<PathBuf>,
    /// With --task: the arm.
    #[arg(long, requires = "task")]
    pub arm: Option<String>,
    /// With --task: the seed.
    #[arg(long, requires = "task")]
    pub seed: Option<u64>,
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
