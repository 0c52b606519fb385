//! The run configuration lives in [`fulcrum_shared::config`] (the learner and every
//! actor read `config.toml`); this path stays for the binary's callers.

pub use fulcrum_shared::config::RunConfig;
