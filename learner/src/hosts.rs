//! `hosts.csv` of a run with actors on other hosts: per update and host, the actors
//! live, the chunks used, their env steps and the chunks lost in transit.

use std::collections::BTreeMap;
use std::io::Write;

use fulcrum_contracts::traj;

use crate::batch::Chunk;
use crate::csv::open_csv;
use crate::error::LearnerError;
use crate::paths::RunPaths;

/// The columns of `hosts.csv`.
pub const HOSTS_COLUMNS: &[&str] = &[
    "update",
    "host",
    "name",
    "actors",
    "chunks",
    "env_steps",
    "lost_chunks",
];

/// `hosts.csv` of a run with remote hosts: one row per update and host.
pub(crate) struct HostsLog {
    file: std::fs::File,
    names: BTreeMap<u32, String>,
    /// Chunks lost per host so far (this session).
    pub(crate) lost: BTreeMap<u32, u64>,
}

impl HostsLog {
    pub(crate) fn open(paths: &RunPaths) -> Result<HostsLog, LearnerError> {
        let file = open_csv(&paths.hosts(), HOSTS_COLUMNS)?;
        Ok(HostsLog {
            file,
            names: BTreeMap::from([(0, "local".to_string())]),
            lost: BTreeMap::new(),
        })
    }

    pub(crate) fn append(
        &mut self,
        paths: &RunPaths,
        update: u64,
        batch: &[Chunk],
        steps_per_chunk: u64,
        roster: &BTreeMap<u32, bool>,
    ) -> Result<(), LearnerError> {
        let mut per: BTreeMap<u32, (u64, u64)> = BTreeMap::new(); // host -> (actors, chunks)
        for c in batch {
            per.entry(traj::host_of(c.h.actor)).or_default().1 += 1;
        }
        for (&a, &live) in roster {
            let e = per.entry(traj::host_of(a)).or_default();
            e.0 += live as u64;
        }
        for h in self.lost.keys() {
            per.entry(*h).or_default();
        }
        if per.keys().any(|h| !self.names.contains_key(h)) {
            // Names of hosts that joined since: `index name address` lines.
            if let Ok(text) = std::fs::read_to_string(paths.host_names()) {
                for line in text.lines() {
                    let mut w = line.split_whitespace();
                    if let (Some(i), Some(name)) = (w.next().and_then(|i| i.parse().ok()), w.next())
                    {
                        self.names.insert(i, name.to_string());
                    }
                }
            }
        }
        let mut out = String::new();
        for (h, (actors, chunks)) in per {
            let actors = if h == 0 { chunks } else { actors };
            let name = self
                .names
                .get(&h)
                .cloned()
                .unwrap_or_else(|| format!("host{h}"));
            out.push_str(&format!(
                "{update},{h},{name},{actors},{chunks},{},{}\n",
                chunks * steps_per_chunk,
                self.lost.get(&h).copied().unwrap_or(0)
            ));
        }
        self.file
            .write_all(out.as_bytes())
            .and_then(|_| self.file.flush())
            .map_err(|e| {
                LearnerError::Run(format!("cannot append to {}: {e}", paths.hosts().display()))
            })
    }
}
