//! The files of a run directory.

use std::path::PathBuf;

/// Paths inside a run directory.
#[derive(Debug, Clone)]
pub struct RunPaths {
    /// The directory.
    pub dir: PathBuf,
}

impl RunPaths {
    /// `config.toml`.
    pub fn config(&self) -> PathBuf {
        self.dir.join("config.toml")
    }
    /// `empowerment-estimates.csv`: the copy of `train --empowerment-from FILE` the run's
    /// service serves from.
    pub fn estimates(&self) -> PathBuf {
        self.dir.join("empowerment-estimates.csv")
    }
    /// `metrics.csv`.
    pub fn metrics(&self) -> PathBuf {
        self.dir.join("metrics.csv")
    }
    /// `checkpoints/latest.safetensors`.
    pub fn checkpoint(&self) -> PathBuf {
        self.dir.join("checkpoints").join("latest.safetensors")
    }
    /// `eval.csv`: evaluations of the policy ([`crate::evalcsv`]).
    pub fn eval(&self) -> PathBuf {
        self.dir.join("eval.csv")
    }
    /// `tb/`: TensorBoard event files.
    pub fn tb(&self) -> PathBuf {
        self.dir.join("tb")
    }
    /// `plots/`.
    pub fn plots(&self) -> PathBuf {
        self.dir.join("plots")
    }
    /// `hosts.csv`: per update and host, the chunks used (runs with `--listen`).
    pub fn hosts(&self) -> PathBuf {
        self.dir.join("hosts.csv")
    }
    /// `hosts.txt`: `index name address` per remote host, written by the bridge.
    pub fn host_names(&self) -> PathBuf {
        self.dir.join("hosts.txt")
    }
}
