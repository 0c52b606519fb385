//! One module per subcommand: each turns its flags into a request, calls the library
//! that does the work, and prints the result. No command imports another.

use anyhow::Result;
use fulcrum_empowerment::Method;

use crate::cli::{Command, MethodArg};

#[cfg(feature = "multihost")]
pub mod actor_host;
pub mod bench;
#[cfg(feature = "multihost")]
pub mod bridge;
pub mod empowerment;
pub mod eval;
pub mod experiment;
pub mod record;
pub mod serve;
pub mod train;
pub mod world;

/// What a command of the `multihost` feature says in a build without it.
pub const NO_MULTIHOST: &str =
    "{} needs fulcrum built with the multihost feature: cargo build --release --features multihost";

/// Run a parsed command line.
pub fn run(cli: crate::cli::Cli) -> Result<()> {
    match cli.command {
        Command::World(c) => world::run(c),
        Command::Empowerment(c) => empowerment::run(c),
        Command::Serve(a) => serve::run(&a),
        Command::Bench(a) => bench::run(a),
        Command::Train(a) => train::run(&a),
        Command::Experiment(a) => experiment::run(&a),
        Command::Record(a) => record::run(&a),
        Command::Eval(a) => eval::run(&a),
        #[cfg(feature = "multihost")]
        Command::ActorHost(a) => actor_host::run(&a),
        #[cfg(feature = "multihost")]
        Command::Bridge(a) => bridge::run(&a),
        #[cfg(feature = "multihost")]
        Command::RemotePeer { listen } => bench::remote::peer(&listen),
        #[cfg(not(feature = "multihost"))]
        Command::RemotePeer { .. } => {
            crate::commands::bad(NO_MULTIHOST.replace("{}", "__remote-peer"))
        }
        #[cfg(not(feature = "multihost"))]
        Command::ActorHost(_) => crate::commands::bad(NO_MULTIHOST.replace("{}", "actor-host")),
        #[cfg(not(feature = "multihost"))]
        Command::Bridge(_) => crate::commands::bad(NO_MULTIHOST.replace("{}", "bridge")),
        Command::Learner(a) => train::learner_process(&a),
        Command::Actor(a) => train::actor_process(&a),
        Command::BenchClient {
            namespace,
            world,
            seconds,
            batch,
        } => bench::client_process(&namespace, &world, seconds, batch),
        Command::PingPong { path } => bench::pingpong_echo(&path),
        Command::Visit {
            namespace,
            world,
            state,
            times,
        } => serve::visit_process(&namespace, &world, &state, times),
    }
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Method {
        match m {
            MethodArg::Dp => Method::Dp,
            MethodArg::Enumerate => Method::Enumerate,
        }
    }
}

/// A mistake in what was asked for: one sentence, exit code 2 (`main.rs`).
pub(crate) fn bad<T>(msg: impl Into<String>) -> anyhow::Result<T> {
    Err(fulcrum_run::BadRequest(msg.into()).into())
}
