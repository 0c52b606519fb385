//! The command line: clap types only. The work is in `commands/`.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

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
pub enum Command {
    /// Inspect or generate tool worlds.
    #[command(subcommand)]
    World(WorldCmd),
    /// Exact object empowerment: matrix, landscape, trace, query.
    #[command(subcommand)]
    Empowerment(EmpCmd),
    /// Run the empowerment service for one world (until Ctrl-C or SIGTERM).
    Serve(ServeArgs),
    /// The throughput suite: timings with the machine they ran on.
    Bench(BenchArgs),
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
    /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room).
    pub world: String,
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
    /// Service namespace: the service is `fulcrum/<namespace>/empowerment`.
    #[arg(long, default_value = "default")]
    pub namespace: String,
    /// Memory for cached ad-hoc query tables, in MiB.
    #[arg(long, default_value_t = 256)]
    pub cache_mib: usize,
}

/// `fulcrum world ...`
#[derive(Debug, Subcommand)]
pub enum WorldCmd {
    /// Map, tools, objects, actions and state-space size of a world.
    Show {
        /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room).
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
    /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room).
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
    /// A world file, or a built-in world (exp1-tree, exp1-wall, exp2, exp3, room).
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
}
