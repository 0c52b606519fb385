//! One module per subcommand, and what they share: resolving a world, a tool, an
//! object set and horizons from the command line, and telling bad input from failure.

use anyhow::Result;
use fulcrum_empowerment::{Engine, EngineError, Limits, Method, ToolSel};
use fulcrum_shared::{load_world, ObjectSet, ToolChoice, World};

use crate::cli::{Command, MethodArg};

#[cfg(feature = "multihost")]
pub mod actor_host;
pub mod bench;
#[cfg(feature = "multihost")]
pub mod bridge;
pub mod empowerment;
pub mod experiment;
pub mod record;
pub mod serve;
pub mod train;
pub mod world;

/// This machine's hostname (or `host`).
pub fn bridge_hostname() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|s| s.trim().to_string())
        .ok()
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "host".into())
}

/// What a command of the `multihost` feature says in a build without it.
pub const NO_MULTIHOST: &str =
    "{} needs fulcrum built with the multihost feature: cargo build --release --features multihost";

/// A mistake in what the user asked for: one sentence, exit code 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// Shorthand for a [`BadInput`] error.
pub fn bad<T>(msg: impl Into<String>) -> Result<T> {
    Err(BadInput(msg.into()).into())
}

/// Whether an error is the user's (exit 2) rather than a failure (exit 1).
pub fn is_bad_input(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.is::<BadInput>()
            || c.is::<fulcrum_shared::WorldError>()
            || c.is::<fulcrum_shared::DescribeError>()
            || c.is::<fulcrum_shared::generate::GenError>()
            || c.is::<EngineError>()
            || matches!(
                c.downcast_ref::<fulcrum_empowerment::service::ServiceError>(),
                Some(
                    fulcrum_empowerment::service::ServiceError::AlreadyRunning(_)
                        | fulcrum_empowerment::service::ServiceError::BadNamespace(_)
                )
            )
            || matches!(
                c.downcast_ref::<fulcrum_empowerment::service::ClientError>(),
                Some(
                    fulcrum_empowerment::service::ClientError::WrongWorld { .. }
                        | fulcrum_empowerment::service::ClientError::Refused(_)
                )
            )
    })
}

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
        #[cfg(feature = "multihost")]
        Command::ActorHost(a) => actor_host::run(&a),
        #[cfg(feature = "multihost")]
        Command::Bridge(a) => bridge::run(&a),
        #[cfg(feature = "multihost")]
        Command::RemotePeer { listen } => bench::remote::peer(&listen),
        #[cfg(not(feature = "multihost"))]
        Command::RemotePeer { .. } => bad(NO_MULTIHOST.replace("{}", "__remote-peer")),
        #[cfg(not(feature = "multihost"))]
        Command::ActorHost(_) => bad(NO_MULTIHOST.replace("{}", "actor-host")),
        #[cfg(not(feature = "multihost"))]
        Command::Bridge(_) => bad(NO_MULTIHOST.replace("{}", "bridge")),
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

/// A progress bar of `len` with `template` when stderr is a terminal (None elsewhere:
/// callers print a line now and then instead).
pub fn terminal_bar(len: u64, template: &str) -> Option<indicatif::ProgressBar> {
    use std::io::IsTerminal;
    std::io::stderr().is_terminal().then(|| {
        let b = indicatif::ProgressBar::new(len);
        b.set_style(
            indicatif::ProgressStyle::with_template(template)
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        b
    })
}

/// Load a world by name or path.
pub fn world(name: &str) -> Result<World> {
    Ok(load_world(name)?)
}

/// Enumerate a world's state space with the default limits.
pub fn engine(world: &World) -> Result<Engine<'_>> {
    Ok(Engine::new(world, Limits::default())?)
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Method {
        match m {
            MethodArg::Dp => Method::Dp,
            MethodArg::Enumerate => Method::Enumerate,
        }
    }
}

/// Parse an object set: `agent`, or names joined by `,` or `+`.
pub fn object_set(world: &World, text: &str) -> Result<ObjectSet> {
    if text == "agent" {
        return Ok(ObjectSet::Agent);
    }
    let mut v = Vec::new();
    for name in text.split([',', '+']).map(str::trim) {
        if name.is_empty() {
            return bad(format!(
                "'{text}' is not an object list: write names like tree,wall or door+boulder"
            ));
        }
        match world.object_index(name) {
            Some(i) if !v.contains(&i) => v.push(i),
            Some(_) => {}
            None => {
                let list = if world.objects.is_empty() {
                    "none".to_string()
                } else {
                    world.object_list()
                };
                return bad(format!(
                    "unknown object '{name}' in world '{}' (objects: {list}; or agent)",
                    world.name
                ));
            }
        }
    }
    v.sort_unstable();
    Ok(ObjectSet::Objects(v))
}

/// The object set asked for, or the world's `[empowerment]` objects.
pub fn objects_or_default(world: &World, text: Option<&str>) -> Result<ObjectSet> {
    match text {
        Some(t) => object_set(world, t),
        None => match &world.empowerment.objects {
            Some(s) => Ok(s.clone()),
            None => bad(format!(
                "world '{}' names no [empowerment] objects: give --objects (objects: {})",
                world.name,
                world.object_list()
            )),
        },
    }
}

/// Parse a tool name (`all`, `auto`, a name, kind or letter); `auto` selects by the
/// matrix column of `set` at the world's horizons.
pub fn tool_sel(
    world: &World,
    engine: &Engine,
    text: Option<&str>,
    set: &ObjectSet,
) -> Result<ToolSel> {
    let choice = match text {
        None => world.empowerment.tool.clone(),
        Some("auto") => ToolChoice::Auto,
        Some("all") => ToolChoice::All,
        Some(t) => match world.tool_index(t) {
            Some(k) => ToolChoice::Tool(k),
            None => {
                return bad(format!(
                    "unknown tool '{t}' in world '{}' (tools: {}; or all, auto)",
                    world.name,
                    if world.tools.is_empty() {
                        "none".to_string()
                    } else {
                        world.tool_list()
                    }
                ))
            }
        },
    };
    Ok(match choice {
        ToolChoice::All => ToolSel::All,
        ToolChoice::Tool(k) => ToolSel::Tool(k),
        ToolChoice::Auto => {
            let e = &world.empowerment;
            let m = engine.matrix(
                std::slice::from_ref(set),
                e.horizon_unequipped,
                e.horizon_equipped,
                Method::Dp,
            )?;
            match m.selection[0] {
                Some(k) => {
                    tracing::info!(tool = %m.tools[k], "tool selection");
                    ToolSel::Tool(k)
                }
                None => {
                    return bad(format!(
                        "tool selection: no tool of world '{}' has empowerment over {}; name one with --tool",
                        world.name,
                        fulcrum_empowerment::set_name(world, set)
                    ))
                }
            }
        }
    })
}

/// Parse a comma-separated inventory into a bit mask.
pub fn holding_mask(world: &World, text: &str) -> Result<u16> {
    let mut m = 0u16;
    for t in text.split(',').map(str::trim).filter(|t| !t.is_empty()) {
        match world.tool_index(t) {
            Some(k) => m |= 1 << k,
            None => {
                return bad(format!(
                    "--holding: unknown tool '{t}' in world '{}' (tools: {})",
                    world.name,
                    world.tool_list()
                ))
            }
        }
    }
    Ok(m)
}
