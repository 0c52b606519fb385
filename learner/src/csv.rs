//! The learner's CSV files (`metrics.csv`, `hosts.csv`): appended row by row under a
//! header, and trimmed back to a checkpoint's update on resume.

use std::io::Write;
use std::path::Path;

use crate::error::LearnerError;

/// Open a CSV file for appending, writing `columns` as its header if it is new.
pub(crate) fn open_csv(path: &Path, columns: &[&str]) -> Result<std::fs::File, LearnerError> {
    let fresh = !path.exists()
        || std::fs::metadata(path)
            .map(|m| m.len() == 0)
            .unwrap_or(true);
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .map_err(|e| LearnerError::Run(format!("cannot open {}: {e}", path.display())))?;
    if fresh {
        writeln!(f, "{}", columns.join(","))
            .map_err(|e| LearnerError::Run(format!("cannot write {}: {e}", path.display())))?;
    }
    Ok(f)
}

/// Keep the header and the whole rows of updates `<= upto` of a CSV file whose first
/// column is the update (`hosts.csv`); rewritten atomically.
pub(crate) fn trim_rows(path: &Path, columns: &[&str], upto: u64) -> Result<(), LearnerError> {
    rewrite_rows(path, columns, |line| {
        line.split(',').count() == columns.len()
            && line
                .split(',')
                .next()
                .and_then(|u| u.parse::<u64>().ok())
                .is_some_and(|u| u <= upto)
    })
}

/// Rewrite a CSV file (atomically, and only if something changes) with the header
/// `columns` and the rows that `keep`.
pub(crate) fn rewrite_rows(
    path: &Path,
    columns: &[&str],
    keep: impl Fn(&str) -> bool,
) -> Result<(), LearnerError> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Ok(());
    };
    let mut out = columns.join(",") + "\n";
    for line in text.lines().skip(1).filter(|l| keep(l)) {
        out.push_str(line);
        out.push('\n');
    }
    if out != text {
        fulcrum_contracts::fsio::write_atomic(path, out.as_bytes())
            .map_err(|e| LearnerError::Run(format!("cannot rewrite {}: {e}", path.display())))?;
    }
    Ok(())
}
