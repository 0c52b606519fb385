//! The learner process of `fulcrum train` and its files, at the paths the binary uses:
//! the loop is [`crate::process`], `metrics.csv` [`crate::metrics`], the run directory
//! [`crate::paths`].

pub use crate::metrics::{read_metrics, MetricsRow, METRICS_COLUMNS};
pub use crate::paths::RunPaths;
pub use crate::process::{run_learner, LearnerExit};
