//! Opening a zenoh session towards the other hosts, and the iceoryx2 node a bridge
//! uses on its own host.

use std::path::PathBuf;

use anyhow::Result;
use fulcrum_run::bad;
use fulcrum_shared::IpcError;
use iceoryx2::prelude::*;
use zenoh::Wait;

use crate::error::ZenohError;

/// How a bridge's zenoh session behaves.
#[derive(Debug, Clone)]
pub struct ZenohOptions {
    /// Seconds without a sign of life after which the link counts as lost.
    pub session_timeout: f64,
    /// A zenoh configuration file to start from.
    pub zenoh_config: Option<PathBuf>,
}

/// An address as a zenoh locator: `host:port` becomes `tcp/host:port`.
pub fn locator(addr: &str) -> Result<String> {
    if addr.contains('/') {
        return Ok(addr.to_string());
    }
    let port_ok = addr
        .rsplit_once(':')
        .is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok());
    if !port_ok {
        return bad(format!(
            "'{addr}' is not an address: give host:port (e.g. 0.0.0.0:7447) or a zenoh locator (tcp/host:port)"
        ));
    }
    Ok(format!("tcp/{addr}"))
}

/// Open a zenoh session: a peer that listens on or connects to `endpoint`, no
/// multicast scouting, the link lease from the session timeout.
pub fn open_session(z: &ZenohOptions, endpoint: &str, listen: bool) -> Result<zenoh::Session> {
    if !(z.session_timeout.is_finite() && z.session_timeout >= 0.5) {
        return bad(format!(
            "a session timeout of {} s is too short: it must be at least 0.5 seconds",
            z.session_timeout
        ));
    }
    let mut c = match &z.zenoh_config {
        Some(p) => match zenoh::Config::from_file(p) {
            Ok(c) => c,
            Err(e) => return bad(format!("{} is not a zenoh configuration: {e}", p.display())),
        },
        None => zenoh::Config::default(),
    };
    let lease_ms = (z.session_timeout * 1000.0).round() as u64;
    let loc = serde_json::to_string(&[endpoint]).expect("a string list serialises");
    let mut set = |k: &str, v: String| -> Result<()> {
        c.insert_json5(k, &v)
            .map_err(|e| ZenohError::new(format!("configuration {k} = {v}"), e).into())
    };
    set("mode", "\"peer\"".into())?;
    set("scouting/multicast/enabled", "false".into())?;
    if listen {
        set("listen/endpoints", loc)?;
    } else {
        set("connect/endpoints", loc)?;
        // Keep trying while the learner's host is away (zenoh's default for peers,
        // stated here because the link-cut recovery depends on it).
        set("connect/timeout_ms", "-1".into())?;
        set("connect/exit_on_failure", "false".into())?;
        set(
            "connect/retry",
            "{period_init_ms: 500, period_max_ms: 2000, period_increase_factor: 2.0}".into(),
        )?;
    }
    set("transport/link/tx/lease", lease_ms.to_string())?;
    set(
        "transport/link/tx/queue/congestion_control/block/wait_before_close",
        (lease_ms * 1000).to_string(),
    )?;
    match zenoh::open(c).wait() {
        Ok(s) => Ok(s),
        Err(e) if listen => bad(format!("cannot listen on {endpoint}: {e}")),
        Err(e) => Err(ZenohError::new(format!("a session towards {endpoint}"), e).into()),
    }
}

/// The bridge's iceoryx2 node (signals are the process's stop flag's business).
pub fn node() -> Result<Node<ipc::Service>> {
    NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| IpcError::new("iceoryx2 node", e).into())
}
