//! The `fulcrum` binary: parse the command line, run the command, map errors to exit
//! codes (2 for bad input, 1 for failures), never a backtrace for a user's mistake.

use std::process::ExitCode;

use clap::Parser;
use fulcrum_run::Kind;

// candle frees large per-op buffers; glibc's allocator turns that into page faults
// (candle allocates and frees a buffer per op).
#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;

mod cli;
mod commands;

/// A command line clap refuses. A value that does not parse (`--view crop:0`,
/// `--beta nan`) is one sentence naming the flag, exit 2, as every other bad input;
/// clap's own messages (help, version, a missing or unknown argument, which show the
/// usage they need) are printed as clap prints them.
fn bad_command_line(e: clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(
        e.kind(),
        ErrorKind::ValueValidation | ErrorKind::InvalidValue
    ) {
        // The message and its possible values: the lines before the first blank one.
        let text = e.render().to_string();
        let lines: Vec<&str> = text
            .lines()
            .take_while(|l| !l.trim().is_empty())
            .map(str::trim)
            .collect();
        eprintln!("fulcrum: {}", lines.join(" ").trim_start_matches("error: "));
        return ExitCode::from(2);
    }
    e.exit()
}

fn main() -> ExitCode {
    let cli = match cli::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return bad_command_line(e),
    };
    if !matches!(cli.command, cli::Command::Serve(_)) {
        // A command whose output is cut short (`fulcrum ... | head`) ends quietly, as
        // Unix tools do, instead of panicking on the broken pipe. The service keeps
        // ignoring SIGPIPE: its last line may go to a reader that has left, and it must
        // still stop cleanly.
        // SAFETY: called first thing in main, before any thread exists.
        unsafe {
            libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        }
    }
    fulcrum_empowerment::service::quiet_ipc_logs();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("FULCRUM_LOG")
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn,zenoh=error")),
        )
        .with_writer(std::io::stderr)
        .init();
    match commands::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        // A child process of a run ends with the code its supervisor reads, quietly.
        Err(e) if let Some(Kind::ChildExit(code)) = run_kind(&e) => ExitCode::from(code),
        Err(e) => {
            eprintln!("fulcrum: {}", one_line(&e));
            ExitCode::from(exit_code(&e))
        }
    }
}

/// The one place where errors become exit codes: 130 when interrupted (the run kept
/// its checkpoint), 2 when the request was wrong (bad input: a world file, a state
/// description, a flag's value, a namespace taken), 1 for every failure.
fn exit_code(e: &anyhow::Error) -> u8 {
    use fulcrum_empowerment::service::{ClientError, ServiceError};
    if e.is::<fulcrum_run::Interrupted>() || run_kind(e) == Some(Kind::Interrupted) {
        return 130;
    }
    let bad_input = |c: &(dyn std::error::Error + 'static)| {
        c.is::<fulcrum_run::BadRequest>()
            || c.downcast_ref::<fulcrum_run::Error>()
                .is_some_and(|r| r.kind() == Kind::BadRequest)
            || c.is::<fulcrum_world::WorldError>()
            || c.is::<fulcrum_contracts::config::ConfigError>()
            || c.is::<fulcrum_world::DescribeError>()
            || c.is::<fulcrum_world::generate::GenError>()
            || c.is::<fulcrum_empowerment::EngineError>()
            || matches!(
                c.downcast_ref::<ServiceError>(),
                Some(ServiceError::AlreadyRunning(_) | ServiceError::BadNamespace(_))
            )
            || matches!(
                c.downcast_ref::<ClientError>(),
                Some(ClientError::WrongWorld { .. } | ClientError::Refused(_))
            )
    };
    #[cfg(feature = "multihost")]
    let bad_input = |c: &(dyn std::error::Error + 'static)| {
        bad_input(c)
            || c.is::<fulcrum_bridge::Refused>()
            || c.downcast_ref::<fulcrum_bridge::error::Error>()
                .is_some_and(fulcrum_bridge::error::Error::is_refusal)
    };
    if e.chain().any(bad_input) {
        2
    } else {
        1
    }
}

/// What the run library says the error is, if it came from there.
fn run_kind(e: &anyhow::Error) -> Option<Kind> {
    e.chain()
        .find_map(|c| c.downcast_ref::<fulcrum_run::Error>())
        .map(fulcrum_run::Error::kind)
}

/// The error and its causes as one sentence.
fn one_line(e: &anyhow::Error) -> String {
    let mut parts: Vec<String> = Vec::new();
    for c in e.chain() {
        let s = c.to_string();
        if !parts.iter().any(|p| p.contains(&s)) {
            parts.push(s);
        }
    }
    parts.join(": ")
}
