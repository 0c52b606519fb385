//! Opening a zenoh session towards the other hosts, and the iceoryx2 node a bridge
//! uses on its own host.

use std::path::PathBuf;

use crate::error::refuse;
use crate::error::Result;
use fulcrum_contracts::IpcError;
use iceoryx2::prelude::*;
use zenoh::Wait;

use crate::error::ZenohError;
use crate::guard::access_control;
use crate::secret::Secret;

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
        return refuse(format!(
            "'{addr}' is not an address: give host:port (e.g. 0.0.0.0:7447) or a zenoh locator (tcp/host:port)"
        ));
    }
    Ok(format!("tcp/{addr}"))
}

/// Whether a locator names a loopback address (`127.x.x.x`, `[::1]`, `localhost`).
pub fn is_loopback(endpoint: &str) -> bool {
    let addr = endpoint.split_once('/').map_or(endpoint, |(_, a)| a);
    let host = addr.rsplit_once(':').map_or(addr, |(h, _)| h);
    let host = host.trim_start_matches('[').trim_end_matches(']');
    host == "localhost"
        || host
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

/// How a session proves it belongs to the run: the secret it presents, and (the
/// listening side) the dictionary it checks joining hosts against.
#[derive(Debug, Clone)]
pub struct Auth {
    pub secret: Secret,
    pub dictionary: Option<PathBuf>,
    /// The listening side's run namespace: zenoh refuses what other hosts may not send
    /// ([`crate::guard::access_control`]).
    pub run: Option<String>,
}

/// Open a zenoh session: a peer that listens on or connects to `endpoint`, no
/// multicast or gossip scouting, the link lease from the session timeout. The
/// connecting side listens on nothing: it accepts no connection from anyone. Listening
/// on an address other than loopback without authentication is refused.
pub fn open_session(
    z: &ZenohOptions,
    endpoint: &str,
    listen: bool,
    auth: Option<&Auth>,
) -> Result<zenoh::Session> {
    if listen && auth.is_none() && !is_loopback(endpoint) {
        return refuse(format!(
            "refusing to listen on {endpoint} without authentication: only a loopback address may be used without the run's secret"
        ));
    }
    if !(z.session_timeout.is_finite() && z.session_timeout >= 0.5) {
        return refuse(format!(
            "a session timeout of {} s is too short: it must be at least 0.5 seconds",
            z.session_timeout
        ));
    }
    let mut c = match &z.zenoh_config {
        Some(p) => match zenoh::Config::from_file(p) {
            Ok(c) => c,
            Err(e) => return refuse(format!("{} is not a zenoh configuration: {e}", p.display())),
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
    // Hosts are not told about one another: each talks to the learner's host only.
    set("scouting/gossip/enabled", "false".into())?;
    if listen {
        set("listen/endpoints", loc)?;
    } else {
        set("listen/endpoints", "[]".into())?;
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
    if let Some(ns) = auth.and_then(|a| a.run.as_deref()) {
        set("access_control", access_control(ns).to_string())?;
    }
    if let Some(a) = auth {
        a.secret
            .configure(&mut c, a.dictionary.as_deref())
            .map_err(|e| ZenohError::new("configuration transport/auth/usrpwd", e))?;
    }
    match zenoh::open(c).wait() {
        Ok(s) => Ok(s),
        Err(e) if listen => refuse(format!("cannot listen on {endpoint}: {e}")),
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
