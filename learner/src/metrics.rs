//! `metrics.csv`: one row per update, written by the learner and read back by
//! `fulcrum train` and `fulcrum experiment`.
//!
//! Durability: a row is appended with one `write` (`append_row`), so a failure
//! (a full disk) leaves at most one torn row, which a resume drops; the rows are synced
//! to disk (`sync_rows`) before each checkpoint is written, so a checkpoint never
//! refers to an update whose row a crash can lose. A resume keeps the rows up to the
//! checkpoint (`trim_metrics`); a start without a checkpoint keeps none.

use std::path::Path;

use crate::csv::{open_csv, rewrite_rows};
use crate::diagnostics::Stats;
use crate::error::LearnerError;

/// The columns of `metrics.csv`, in order.
pub const METRICS_COLUMNS: &[&str] = &[
    "update",
    "env_steps",
    "episodes",
    "extrinsic_return",
    "success_rate",
    "intrinsic_return",
    "intrinsic_mean",
    "episode_length",
    "pickup_rate",
    "policy_loss",
    "value_loss",
    "entropy",
    "approx_kl",
    "clip_frac",
    "sps",
    "policy_lag",
    "dropped_chunks",
    "actor_restarts",
    "wall_s",
    "e_positive_frac",
    "first_pickup_step",
    "lost_chunks",
    "remote_actors",
    "trap",
];

/// Columns of `metrics.csv` files written before `e_positive_frac` and
/// `first_pickup_step`, before `lost_chunks` and `remote_actors`, and before `trap`
/// (still read).
const LEGACY_COLUMNS: [usize; 3] = [19, 21, 23];

/// One row of `metrics.csv`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MetricsRow {
    /// Updates done (1-based).
    pub update: u64,
    /// Env steps so far.
    pub env_steps: u64,
    /// Episodes finished in this update.
    pub episodes: u64,
    /// Mean extrinsic return of those episodes (NaN when none finished).
    pub extrinsic_return: f64,
    /// Fraction of those that reached the task's terminal state.
    pub success_rate: f64,
    /// Mean intrinsic return (sum of E in bits) of those episodes.
    pub intrinsic_return: f64,
    /// Mean E(s_{t+1}) per step in this update, bits.
    pub intrinsic_mean: f64,
    /// Mean length of those episodes.
    pub episode_length: f64,
    /// Fraction of those episodes in which a tool was picked up.
    pub pickup_rate: f64,
    /// PPO diagnostics.
    pub stats: Stats,
    /// Env steps per second over this update (collection + learning).
    pub sps: f64,
    /// Mean policy lag of the chunks used (0 in synchronous mode).
    pub policy_lag: f64,
    /// Chunks dropped so far (invalid or stale).
    pub dropped_chunks: u64,
    /// Actor restarts so far.
    pub actor_restarts: u64,
    /// Wall time of the run so far (seconds, over all resumes).
    pub wall_s: f64,
    /// Fraction of this update's transitions whose E(s_{t+1}) > 0 (NaN for forms that
    /// do not look E up).
    pub e_positive_frac: f64,
    /// Env steps at the end of the first update in which an episode with a tool pick-up
    /// ended (None before that).
    pub first_pickup_step: Option<u64>,
    /// Chunks that never arrived so far: gaps in an actor's chunk sequence (remote
    /// hosts whose link went down; 0 on one machine).
    pub lost_chunks: u64,
    /// Actors of other hosts whose chunks this update used.
    pub remote_actors: u64,
    /// Whether the beacon-trap detector marks this update ([`crate::trap`]; 0 in files
    /// written before the column).
    pub trap: bool,
}

impl MetricsRow {
    /// The CSV line (no newline).
    pub fn csv(&self) -> String {
        let f = |x: f64| {
            if x.is_finite() {
                format!("{x}")
            } else {
                String::new()
            }
        };
        [
            self.update.to_string(),
            self.env_steps.to_string(),
            self.episodes.to_string(),
            f(self.extrinsic_return),
            f(self.success_rate),
            f(self.intrinsic_return),
            f(self.intrinsic_mean),
            f(self.episode_length),
            f(self.pickup_rate),
            f(self.stats.policy_loss as f64),
            f(self.stats.value_loss as f64),
            f(self.stats.entropy as f64),
            f(self.stats.approx_kl as f64),
            f(self.stats.clip_frac as f64),
            f(self.sps),
            f(self.policy_lag),
            self.dropped_chunks.to_string(),
            self.actor_restarts.to_string(),
            f(self.wall_s),
            f(self.e_positive_frac),
            self.first_pickup_step
                .map(|s| s.to_string())
                .unwrap_or_default(),
            self.lost_chunks.to_string(),
            self.remote_actors.to_string(),
            u8::from(self.trap).to_string(),
        ]
        .join(",")
    }

    /// Parse a CSV line written by [`MetricsRow::csv`] (empty fields are NaN).
    pub fn parse(line: &str) -> Option<MetricsRow> {
        let v: Vec<&str> = line.trim_end().split(',').collect();
        if v.len() != METRICS_COLUMNS.len() && !LEGACY_COLUMNS.contains(&v.len()) {
            return None;
        }
        let f = |i: usize| -> Option<f64> {
            if v[i].is_empty() {
                Some(f64::NAN)
            } else {
                v[i].parse().ok()
            }
        };
        let u = |i: usize| -> Option<u64> { v[i].parse().ok() };
        Some(MetricsRow {
            update: u(0)?,
            env_steps: u(1)?,
            episodes: u(2)?,
            extrinsic_return: f(3)?,
            success_rate: f(4)?,
            intrinsic_return: f(5)?,
            intrinsic_mean: f(6)?,
            episode_length: f(7)?,
            pickup_rate: f(8)?,
            stats: Stats {
                policy_loss: f(9)? as f32,
                value_loss: f(10)? as f32,
                entropy: f(11)? as f32,
                approx_kl: f(12)? as f32,
                clip_frac: f(13)? as f32,
            },
            sps: f(14)?,
            policy_lag: f(15)?,
            dropped_chunks: u(16)?,
            actor_restarts: u(17)?,
            wall_s: f(18)?,
            e_positive_frac: if v.len() > 19 { f(19)? } else { f64::NAN },
            first_pickup_step: match v.get(20) {
                None | Some(&"") => None,
                Some(_) => Some(u(20)?),
            },
            lost_chunks: if v.len() > 21 { u(21)? } else { 0 },
            remote_actors: if v.len() > 22 { u(22)? } else { 0 },
            trap: v.len() > 23 && u(23)? == 1,
        })
    }
}

/// Read a run's `metrics.csv` (rows that do not parse are skipped).
pub fn read_metrics(path: &Path) -> std::io::Result<Vec<MetricsRow>> {
    let text = std::fs::read_to_string(path)?;
    Ok(text.lines().skip(1).filter_map(MetricsRow::parse).collect())
}

/// Open `metrics.csv` for appending, writing the header if it is new.
pub(crate) fn open_metrics(path: &Path) -> Result<std::fs::File, LearnerError> {
    open_csv(path, METRICS_COLUMNS)
}

/// Append `row` to the open `metrics.csv` at `path` in one write; the error names the
/// file and says why (a full disk: "No space left on device").
pub(crate) fn append_row(
    file: &mut std::fs::File,
    path: &Path,
    row: &MetricsRow,
) -> Result<(), LearnerError> {
    use std::io::Write;
    let line = row.csv() + "\n";
    file.write_all(line.as_bytes())
        .map_err(|e| LearnerError::Run(format!("cannot append to {}: {e}", path.display())))
}

/// Sync the rows appended so far to disk (before a checkpoint refers to them).
pub(crate) fn sync_rows(file: &std::fs::File, path: &Path) -> Result<(), LearnerError> {
    file.sync_data()
        .map_err(|e| LearnerError::Run(format!("cannot sync {}: {e}", path.display())))
}

/// Keep the header and the rows of updates `<= upto` (rows written after the last
/// checkpoint belong to updates that will be redone); rewritten atomically. A file from
/// an older version gains the new columns' header; a row torn by a crash does not parse
/// and goes.
pub(crate) fn trim_metrics(path: &Path, upto: u64) -> Result<(), LearnerError> {
    rewrite_rows(path, METRICS_COLUMNS, |line| {
        MetricsRow::parse(line).is_some_and(|r| r.update <= upto)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metrics_row_round_trips() {
        let r = MetricsRow {
            update: 3,
            env_steps: 3072,
            episodes: 7,
            extrinsic_return: 0.5,
            success_rate: 0.25,
            intrinsic_return: f64::NAN,
            intrinsic_mean: 0.125,
            episode_length: 43.5,
            pickup_rate: 1.0,
            stats: Stats {
                policy_loss: -0.01,
                value_loss: 0.2,
                entropy: 1.9,
                approx_kl: 0.003,
                clip_frac: 0.1,
            },
            sps: 1234.5,
            policy_lag: 0.0,
            dropped_chunks: 2,
            actor_restarts: 1,
            wall_s: 9.75,
            e_positive_frac: 0.375,
            first_pickup_step: Some(2048),
            lost_chunks: 5,
            remote_actors: 2,
            trap: true,
        };
        let line = r.csv();
        assert_eq!(line.split(',').count(), METRICS_COLUMNS.len());
        let back = MetricsRow::parse(&line).unwrap();
        assert!(back.intrinsic_return.is_nan());
        assert_eq!(back.first_pickup_step, Some(2048));
        assert_eq!(back.csv(), line);
        // No pick-up yet: an empty field.
        let none = MetricsRow {
            first_pickup_step: None,
            ..r
        };
        assert!(none.csv().ends_with(",0.375,,5,2,1"));
        assert_eq!(
            MetricsRow::parse(&none.csv()).unwrap().first_pickup_step,
            None
        );
        // Rows of files written before the last columns still parse.
        let before_trap: Vec<&str> = line.split(',').take(23).collect();
        let before_trap = MetricsRow::parse(&before_trap.join(",")).unwrap();
        assert_eq!((before_trap.remote_actors, before_trap.trap), (2, false));
        let mid: Vec<&str> = line.split(',').take(21).collect();
        let mid = MetricsRow::parse(&mid.join(",")).unwrap();
        assert_eq!((mid.first_pickup_step, mid.lost_chunks), (Some(2048), 0));
        let legacy: Vec<&str> = line.split(',').take(19).collect();
        let old = MetricsRow::parse(&legacy.join(",")).unwrap();
        assert_eq!(old.wall_s, 9.75);
        assert!(old.e_positive_frac.is_nan() && old.first_pickup_step.is_none());
    }
}
