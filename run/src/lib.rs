//! fulcrum-run: training runs and experiments of many runs, as the `fulcrum` binary
//! asks for them.
//!
//! A request is planned into a checked configuration and a run directory ([`plan`]),
//! then the supervisor ([`supervisor`]) starts the empowerment service, the learner,
//! the actors (and a bridge to other hosts) as child processes ([`child`]) and waits on
//! their events until the run ends. An experiment ([`experiment`]) schedules many such
//! runs over the cores and aggregates their curves with [`stats`].
//!
//! | module | what it owns |
//! |---|---|
//! | [`settings`] | a run's settings, each declared once: the fixed ones and those a resume may change |
//! | [`plan`] | a request -> a checked `RunConfig`, its world and run directory |
//! | [`lock`] | one invocation per run or experiment directory (`flock` on `.lock`) |
//! | [`sizes`] | the shared memory a run needs, checked before it starts |
//! | [`supervisor`] | the run's child processes, restarts, progress, shutdown |
//! | [`child`] | the learner and actor processes as the supervisor starts them |
//! | [`process`] | the one stop flag, signals, die-with-parent, spawn-until-ready |
//! | [`restart`] | per-child restart budgets in a window, exponential back-off |
//! | [`watchdog`] | ending a run that makes no update for too long, naming who stalled |
//! | [`progress`] | a bar on a terminal, a line now and then elsewhere |
//! | [`curve`] | the learning curve drawn when a run ends |
//! | [`eval`] | a run's policy played greedily or sampled: success, return, length, tool use with 95% intervals |
//! | [`record`] | episodes of a run's policy as strips of frames |
//! | [`experiment`] | many runs: scheduling (here, or as a Slurm job array), resuming, aggregation, report |
//! | [`stats`] | curves over seeds, censored times to solve, tests |
//! | [`error`] | the library's typed errors: bad requests, interruptions, a child's exit code, failures with their sources ([`Kind`] is what the binary's exit code is decided from) |
//! | [`host`] | an actor host's supervision: its bridge and actors, restarted as the supervisor restarts its own |
//! | [`argv`] | the command lines of fulcrum's own child processes, one typed builder each |

pub mod argv;
pub mod child;
pub mod curve;
pub mod error;
pub mod eval;
pub mod experiment;
pub mod host;
pub mod lock;
pub mod plan;
pub mod process;
pub mod progress;
pub mod record;
pub mod restart;
pub mod settings;
pub mod sizes;
pub mod stats;
pub mod supervisor;
pub mod watchdog;

pub use error::{bad, BadRequest, Error, Interrupted, Kind};
