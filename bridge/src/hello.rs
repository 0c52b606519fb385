//! Joining a run: the hello a host is answered with, the hosts file of the learner's
//! side, and where an actor host's actors live.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use crate::error::refuse;
use crate::error::{fail, Context, Result};
use fulcrum_contracts::lines::ChildLine;
use fulcrum_contracts::stop::STOP;
use fulcrum_contracts::traj::HOST_STRIDE;
use serde::{Deserialize, Serialize};
use zenoh::Wait;

use crate::error::ZenohError;

/// What a joining host learns (the reply to `fulcrum/hello`), as TOML.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Hello {
    /// The run's namespace on the learner's host (the key expressions' `<run>`).
    pub run: String,
    /// The run's tag ([`fulcrum_contracts::traj::run_tag`] of `run`): chunks carry it.
    pub run_tag: u64,
    /// The run's id (its directory name by default).
    pub run_id: String,
    /// The world's text; its hash is the run's world hash.
    pub world_source: String,
    /// [`fulcrum_world::World::content_hash`], hex.
    pub world_hash: String,
    /// The world's name.
    pub world_name: String,
    /// The run's `config.toml`.
    pub config: String,
    /// This host's index: its actors are `index * HOST_STRIDE + j`.
    pub host: u32,
}

/// Whether a host name can be used in a key expression and a CSV field.
pub(crate) fn valid_host_name(n: &str) -> bool {
    !n.is_empty()
        && n.len() <= 64
        && n.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_' || b == b'.')
}

/// `name -> (index, address)` from `hosts.txt` (`index name address` lines).
pub(crate) fn read_hosts(path: &Path) -> BTreeMap<String, (u32, String)> {
    let mut out = BTreeMap::new();
    if let Ok(text) = std::fs::read_to_string(path) {
        for line in text.lines() {
            let w: Vec<&str> = line.split_whitespace().collect();
            if let [i, name, rest @ ..] = w.as_slice() {
                if let Ok(i) = i.parse::<u32>() {
                    out.insert(name.to_string(), (i, rest.join(" ")));
                }
            }
        }
    }
    out
}

pub(crate) fn write_hosts(path: &Path, hosts: &BTreeMap<String, (u32, String)>) -> Result<()> {
    let mut rows: Vec<(u32, &String, &String)> =
        hosts.iter().map(|(n, (i, a))| (*i, n, a)).collect();
    rows.sort();
    let text: String = rows
        .iter()
        .map(|(i, n, a)| format!("{i} {n} {a}\n"))
        .collect();
    write_atomic(path, text.as_bytes())
}

/// Writes a file atomically, the error naming it.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    fulcrum_contracts::fsio::write_atomic(path, bytes)
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

/// What an actor host needs to start its actors (printed by the bridge when ready, as
/// [`ChildLine::BridgeJoined`]).
pub use fulcrum_contracts::lines::Joined;

/// The `ready` line the bridge prints once joined.
pub fn joined_line(j: &Joined) -> String {
    ChildLine::BridgeJoined(j.clone()).to_string()
}

/// A bridge's line read as its `ready` line once joined (`None`: another line).
pub fn parse_joined(line: &str) -> Option<Joined> {
    match ChildLine::parse(line) {
        Some(ChildLine::BridgeJoined(j)) => Some(j),
        _ => None,
    }
}

/// Ask the learner's host to join, until it answers or `give_up` passes.
pub fn join(session: &zenoh::Session, endpoint: &str, name: &str, give_up: f64) -> Result<Hello> {
    let t0 = Instant::now();
    let mut said = false;
    loop {
        if STOP.load(Ordering::Relaxed) {
            fail!("stopped before the learner answered");
        }
        let replies = session
            .get(format!(
                "fulcrum/hello?name={name};from={}",
                fulcrum_contracts::host::hostname()
            ))
            .timeout(Duration::from_secs(2))
            .wait()
            .map_err(|e| ZenohError::new("get", e))?;
        if let Ok(reply) = replies.recv() {
            match reply.result() {
                Ok(sample) => {
                    let text = sample
                        .payload()
                        .try_to_string()
                        .unwrap_or_default()
                        .to_string();
                    return Ok(toml::from_str(&text)
                        .context("the learner's host sent a join reply that does not parse")?);
                }
                Err(e) => {
                    let why = e.payload().try_to_string().unwrap_or_default().to_string();
                    return refuse(format!("the learner's host refused this host: {why}"));
                }
            }
        }
        if t0.elapsed().as_secs_f64() > give_up {
            fail!("no learner answered at {endpoint} within {give_up} s");
        }
        if !said {
            // A wrong secret looks the same from here as a learner not yet up: zenoh
            // closes the session before any answer (and logs why).
            eprintln!(
                "fulcrum bridge: waiting for the learner at {endpoint} (no answer yet: is the run up, and is this its secret?)"
            );
            said = true;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// The actor id of actor `j` of host `host`.
pub fn actor_id(host: u32, j: usize) -> u32 {
    host * HOST_STRIDE + j as u32
}

/// Where an actor host works by default.
pub fn default_dir(name: &str) -> PathBuf {
    PathBuf::from("runs").join(format!("remote-{name}"))
}
