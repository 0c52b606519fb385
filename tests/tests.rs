//! Tests of the `fulcrum` binary as a user runs it: one test binary, modules by topic.

mod cli;
mod experiment;
#[cfg(feature = "multihost")]
mod multihost;
mod service;
#[cfg(feature = "slurm")]
mod slurm;
mod train;
mod util;
