//! `eval.csv`: evaluations of a run's policy, one row per evaluation, appended by
//! `fulcrum eval` and, every `eval_every` updates, by the learner of
//! `train --eval-every` (mode `train-greedy`, [`PERIODIC`](crate::evalcsv::PERIODIC):
//! greedy actions, during training; `train-sample`,
//! [`PERIODIC_SAMPLE`](crate::evalcsv::PERIODIC_SAMPLE), with `--eval-sample`).
//!
//! Columns ([`EVAL_COLUMNS`](crate::evalcsv::EVAL_COLUMNS)): the policy's update and
//! env steps, the world played (a family's name on a family), the layouts played
//! (`test:K`, `test:A..B`, `train:K`; empty for one world), the mode (`greedy`, `sample`,
//! `train-greedy` or `train-sample`), the
//! sampling seed, the episodes, then success rate, mean return, mean length, tool-use
//! rate and tool-choice rate (the first tool used fits the task), each followed by its
//! 95% interval's ends. A resumed run drops the periodic rows after its checkpoint (it
//! makes them again) and keeps every row `fulcrum eval` wrote. A file written before the
//! tool-choice or layouts columns existed is rewritten with them (tool choice `NaN`,
//! layouts empty) before a row is added.

use std::io::Write as _;
use std::path::Path;

/// The header of `eval.csv`.
pub const EVAL_COLUMNS: &str = "update,env_steps,world,layouts,mode,seed,episodes,success,success_lo,success_hi,return,return_lo,return_hi,length,length_lo,length_hi,tool_use,tool_use_lo,tool_use_hi,tool_choice,tool_choice_lo,tool_choice_hi";

/// The mode of the rows `train --eval-every` writes: greedy actions, during training.
pub const PERIODIC: &str = "train-greedy";

/// The mode of a periodic evaluation with sampled actions (`train --eval-sample`).
pub const PERIODIC_SAMPLE: &str = "train-sample";

/// Whether a row's mode is a periodic evaluation's (greedy or sampled).
pub fn is_periodic(mode: &str) -> bool {
    mode == PERIODIC || mode == PERIODIC_SAMPLE
}

/// One evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalRow {
    /// The policy's update.
    pub update: u64,
    /// Env steps of training behind the policy.
    pub env_steps: u64,
    /// The world played.
    pub world: String,
    /// The layouts of a family played (empty for one world).
    pub layouts: String,
    /// `greedy`, `sample`, [`PERIODIC`] or [`PERIODIC_SAMPLE`].
    pub mode: String,
    /// The sampling seed.
    pub seed: u64,
    /// Episodes played.
    pub episodes: usize,
    /// Success rate, and its 95% interval (Wilson).
    pub success: [f64; 3],
    /// Mean return, and its 95% interval (Student's t).
    pub ret: [f64; 3],
    /// Mean episode length, and its 95% interval.
    pub length: [f64; 3],
    /// Tool-use rate, and its 95% interval (Wilson).
    pub tool_use: [f64; 3],
    /// Tool-choice rate (the first tool used fits the task), and its 95% interval
    /// (Wilson); NaN where no tool can fit.
    pub tool_choice: [f64; 3],
}

impl EvalRow {
    /// The row as CSV (no newline).
    pub fn csv(&self) -> String {
        let f = |v: &[f64; 3]| format!("{},{},{}", v[0], v[1], v[2]);
        format!(
            "{},{},{},{},{},{},{},{},{},{},{},{}",
            self.update,
            self.env_steps,
            self.world,
            self.layouts,
            self.mode,
            self.seed,
            self.episodes,
            f(&self.success),
            f(&self.ret),
            f(&self.length),
            f(&self.tool_use),
            f(&self.tool_choice)
        )
    }

    /// A row of the file (of today's 22 columns, the 21 before layouts, which read as
    /// empty, or the 18 before tool choice, which reads as NaN); `None` for the header or
    /// a torn line.
    pub fn parse(line: &str) -> Option<EvalRow> {
        let mut v: Vec<&str> = line.split(',').collect();
        let layouts = if v.len() == 22 { v.remove(3) } else { "" };
        if v.len() != 18 && v.len() != 21 {
            return None;
        }
        let x = |i: usize| v[i].parse::<f64>().ok();
        let three = |i: usize| Some([x(i)?, x(i + 1)?, x(i + 2)?]);
        Some(EvalRow {
            update: v[0].parse().ok()?,
            env_steps: v[1].parse().ok()?,
            world: v[2].to_string(),
            layouts: layouts.to_string(),
            mode: v[3].to_string(),
            seed: v[4].parse().ok()?,
            episodes: v[5].parse().ok()?,
            success: three(6)?,
            ret: three(9)?,
            length: three(12)?,
            tool_use: three(15)?,
            tool_choice: if v.len() == 21 {
                three(18)?
            } else {
                [f64::NAN; 3]
            },
        })
    }

    /// TensorBoard's scalars of a periodic evaluation (the point estimates; a NaN one,
    /// tool choice where no tool fits, is not written).
    pub fn scalars(&self) -> [(&'static str, f64); 5] {
        [
            ("eval/success_rate", self.success[0]),
            ("eval/return", self.ret[0]),
            ("eval/episode_length", self.length[0]),
            ("eval/tool_use", self.tool_use[0]),
            ("eval/tool_choice", self.tool_choice[0]),
        ]
    }
}

/// Append `row` to `path` (with the header when the file is new), in one write, synced
/// (the learner's checkpoint after it must not outlive it): a crash leaves whole rows.
pub fn append(path: &Path, row: &EvalRow) -> std::io::Result<()> {
    upgrade(path)?;
    let new = !path.exists();
    let mut file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)?;
    let mut text = String::new();
    if new {
        text.push_str(EVAL_COLUMNS);
        text.push('\n');
    }
    text.push_str(&row.csv());
    text.push('\n');
    file.write_all(text.as_bytes())?;
    file.sync_data()
}

/// A file of an older header rewritten with today's columns (atomically), its rows
/// kept; nothing to do for a new or current file.
fn upgrade(path: &Path) -> std::io::Result<()> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Ok(());
    };
    if text.lines().next().is_none_or(|h| h == EVAL_COLUMNS) {
        return Ok(());
    }
    let mut out = String::from(EVAL_COLUMNS);
    out.push('\n');
    for row in text.lines().filter_map(EvalRow::parse) {
        out.push_str(&row.csv());
        out.push('\n');
    }
    fulcrum_contracts::fsio::write_atomic(path, out.as_bytes())
}

/// Drop the periodic rows of updates after `update` (and torn lines), keeping every
/// other row, atomically; returns the periodic rows kept, for TensorBoard.
pub fn trim_periodic(path: &Path, update: u64) -> std::io::Result<Vec<EvalRow>> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Ok(Vec::new());
    };
    let mut out = String::from(EVAL_COLUMNS);
    out.push('\n');
    let mut kept = Vec::new();
    for row in text.lines().filter_map(EvalRow::parse) {
        let periodic = is_periodic(&row.mode);
        if periodic && row.update > update {
            continue;
        }
        out.push_str(&row.csv());
        out.push('\n');
        if periodic {
            kept.push(row);
        }
    }
    if out != text {
        fulcrum_contracts::fsio::write_atomic(path, out.as_bytes())?;
    }
    Ok(kept)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rows of `path` (none when it does not exist; torn lines skipped).
    fn read(path: &Path) -> std::io::Result<Vec<EvalRow>> {
        match std::fs::read_to_string(path) {
            Ok(text) => Ok(text.lines().filter_map(EvalRow::parse).collect()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Vec::new()),
            Err(e) => Err(e),
        }
    }

    fn row(update: u64, mode: &str) -> EvalRow {
        EvalRow {
            update,
            env_steps: update * 1024,
            world: "room".into(),
            layouts: String::new(),
            mode: mode.into(),
            seed: 1,
            episodes: 10,
            success: [0.7, 0.3967781, 0.8922087],
            ret: [0.7, 0.35, 1.05],
            length: [12.5, 10.0, 15.0],
            tool_use: [1.0, 0.72, 1.0],
            tool_choice: [0.5, 0.2366, 0.7634],
        }
    }

    #[test]
    fn rows_round_trip_and_a_resume_drops_only_later_periodic_rows() {
        let dir = std::env::temp_dir().join(format!("fulcrum-evalcsv-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("eval.csv");
        let rows = [
            row(2, PERIODIC),
            row(3, "greedy"),
            row(4, PERIODIC_SAMPLE),
            row(6, PERIODIC),
            row(9, "sample"),
            row(7, PERIODIC_SAMPLE),
        ];
        for r in &rows {
            append(&path, r).unwrap();
        }
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text.lines().next(), Some(EVAL_COLUMNS));
        assert_eq!(text.lines().count(), 7);
        assert_eq!(read(&path).unwrap(), rows);
        // A torn last line (a crash mid-write) is dropped with the later periodic rows.
        std::fs::write(&path, format!("{text}5,5120,room,train-gr")).unwrap();
        let kept = trim_periodic(&path, 4).unwrap();
        assert_eq!(kept, vec![rows[0].clone(), rows[2].clone()]);
        assert_eq!(
            read(&path).unwrap(),
            vec![
                rows[0].clone(),
                rows[1].clone(),
                rows[2].clone(),
                rows[4].clone()
            ]
        );
        assert_eq!(rows[0].scalars()[0], ("eval/success_rate", 0.7));
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[cfg(test)]
mod upgrade_tests {
    use super::*;

    /// A file of the 18 columns before tool choice and layouts: its rows are kept, read
    /// with NaN tool choice and no layouts, and the file gets today's header before the
    /// next row is added.
    #[test]
    fn an_old_file_is_upgraded_before_a_row_is_added() {
        let dir = std::env::temp_dir().join(format!("fulcrum-evalcsv-old-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("eval.csv");
        let old_header = "update,env_steps,world,mode,seed,episodes,success,success_lo,success_hi,return,return_lo,return_hi,length,length_lo,length_hi,tool_use,tool_use_lo,tool_use_hi";
        let old_row = "3,3072,room,greedy,1,10,1,0.7224672,1,1,1,1,12,12,12,1,0.7224672,1";
        std::fs::write(&path, format!("{old_header}\n{old_row}\n")).unwrap();
        let old = EvalRow::parse(old_row).unwrap();
        assert!(old.tool_choice.iter().all(|x| x.is_nan()));
        let mut new = old.clone();
        new.update = 4;
        new.tool_choice = [1.0, 0.7224672, 1.0];
        append(&path, &new).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], EVAL_COLUMNS);
        assert_eq!(lines.len(), 3);
        // The old row gains an empty `layouts` column and NaN tool choice.
        assert!(lines[1].starts_with("3,3072,room,,greedy,") && lines[1].ends_with(",NaN,NaN,NaN"));
        assert_eq!(lines[1].split(',').count(), 22);
        assert_eq!(EvalRow::parse(lines[2]).unwrap(), new);
        // A row of the 21 columns before layouts reads with its tool choice, no layouts.
        let r21 = EvalRow::parse(&format!("{old_row},0.5,0.2,0.8")).unwrap();
        assert_eq!(
            (r21.layouts.as_str(), r21.tool_choice),
            ("", [0.5, 0.2, 0.8])
        );
        assert_eq!(r21.mode, "greedy");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
