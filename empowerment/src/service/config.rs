//! What a service computes and how it serves.

use std::time::Duration;

use fulcrum_world::ObjectSet;

use crate::engine::ToolSel;

/// What a service computes for LOOKUP.
#[derive(Debug, Clone)]
pub struct ServeConfig {
    /// Namespace: `fulcrum/<namespace>/empowerment`.
    pub namespace: String,
    /// Tool whose actions drive the channel.
    pub tool: ToolSel,
    /// Objects of interest.
    pub objects: ObjectSet,
    /// Horizon where the tool is not held.
    pub horizon_unequipped: u32,
    /// Horizon where it is held.
    pub horizon_equipped: u32,
    /// LOOKUP answers Phi(s) = sum over h = 1..H of E^h(s), H the larger horizon, in every
    /// state (the potential of `train --intrinsic horizon-potential`) instead of E.
    pub horizon_sum: bool,
    /// Bytes the QUERY cache may hold.
    pub cache_bytes: usize,
    /// How long to poll for the next request before blocking.
    pub spin: Duration,
    /// Clients the service takes at once ([`fulcrum_contracts::msg::MAX_CLIENTS`] by
    /// default; a training run's, its actors and spares).
    pub max_clients: usize,
}
