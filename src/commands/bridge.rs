//! `fulcrum bridge` (feature `multihost`): the bridge between this host's processes
//! and the other hosts of a run; the work is in [`fulcrum_bridge`].

use anyhow::Result;
use std::path::Path;

use crate::commands::bad;
use fulcrum_bridge::{connect, listen, Secret, Want, SECRET_ENV, SECRET_FILE};
use fulcrum_run::process::{die_with_parent, hostname, install_signal_handlers};

use crate::cli::BridgeArgs;

/// `fulcrum bridge`.
pub fn run(a: &BridgeArgs) -> Result<()> {
    install_signal_handlers();
    if let Some(p) = a.parent {
        die_with_parent(p);
    }
    match (&a.listen, &a.connect) {
        (Some(addr), _) => {
            let Some(ns) = &a.namespace else {
                return bad("bridge --listen needs --namespace (the run's)");
            };
            Ok(listen(addr, &a.run, ns, &a.zenoh.options())?)
        }
        (None, Some(addr)) => {
            let host = a.name.clone().unwrap_or_else(hostname);
            let want = Want {
                world: a.world.as_deref(),
                run_id: a.run_id.as_deref(),
            };
            let secret = secret(a.secret_file.as_deref())?;
            Ok(connect(
                addr,
                &a.run,
                &host,
                want,
                a.give_up,
                &a.zenoh.options(),
                &secret,
            )?)
        }
        (None, None) => bad("bridge needs --listen ADDR or --connect ADDR"),
    }
}

/// The run's secret for an actor host: from `--secret-file`, else from the environment.
pub fn secret(file: Option<&Path>) -> Result<Secret> {
    match Secret::from_file_or_env(file)? {
        Some(s) => Ok(s),
        None => bad(format!(
            "joining a run needs its secret: set {SECRET_ENV} or give --secret-file (a copy of the run directory's '{SECRET_FILE}' file)"
        )),
    }
}
