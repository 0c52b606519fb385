//! The zenoh settings shared by `train --listen`, `actor-host` and `bridge`.

use std::path::PathBuf;

use clap::Args;

/// How a host reaches the others (feature `multihost`).
#[derive(Debug, Clone, Args)]
pub struct ZenohArgs {
    /// Seconds without a word from the other host before its session is closed (zenoh's
    /// link lease); a host whose session closed reconnects by itself.
    #[arg(long, value_name = "SECS", default_value_t = 10.0)]
    #[cfg_attr(not(feature = "multihost"), arg(hide = true))]
    pub session_timeout: f64,
    /// A zenoh configuration file (JSON5) to start from; fulcrum sets mode, endpoints
    /// and lease on top of it.
    #[arg(long, value_name = "FILE")]
    #[cfg_attr(not(feature = "multihost"), arg(hide = true))]
    pub zenoh_config: Option<PathBuf>,
}

impl ZenohArgs {
    /// The bridge's zenoh settings.
    #[cfg(feature = "multihost")]
    pub fn options(&self) -> fulcrum_bridge::ZenohOptions {
        fulcrum_bridge::ZenohOptions {
            session_timeout: self.session_timeout,
            zenoh_config: self.zenoh_config.clone(),
        }
    }
}
