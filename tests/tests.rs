//! Tests of the `fulcrum` binary as a user runs it: one test binary, modules by topic.

mod cli;
mod experiment;
mod service;
mod train;
