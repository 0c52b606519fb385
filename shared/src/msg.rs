//! Shared-memory message layouts and service names.
//!
//! Plain data only: `#[repr(C)]`, `ZeroCopySend`, stable type names, no heap, no
//! pointers. Every process builds each iceoryx2 service with the functions here, so the
//! first one to create it fixes the same quality of service for all.
//!
//! ## The empowerment service (request-response)
//!
//! `fulcrum/<namespace>/empowerment`: a client sends an [`EmpRequest`] (a batch of up to
//! [`MAX_BATCH`] packed states, `State::to_bytes`) and receives one [`EmpResponse`]
//! (one `f32` and one status byte per state). Wake-ups travel on two event services:
//! clients notify `.../server-wake` after sending; the server notifies the client's own
//! listener on `.../client-wake`, whose id the client puts in the request's user header.

use iceoryx2::prelude::*;

/// States in one request.
pub const MAX_BATCH: usize = 1024;
/// Bytes of a packed state.
pub const STATE_BYTES: usize = 38;
/// Bytes of a name in a [`Describe`].
pub const NAME_BYTES: usize = 32;

/// Request kinds.
pub mod kind {
    /// E at each state with the service's configuration (tool, objects, held/not-held
    /// horizons).
    pub const LOOKUP: u32 = 1;
    /// E at each state for any tool, object set and horizon.
    pub const QUERY: u32 = 2;
    /// The world and the service's configuration.
    pub const DESCRIBE: u32 = 3;
    /// Count one visit of each state and answer its visit count so far (this visit
    /// included), shared by every client: the count-based novelty bonus.
    pub const VISIT: u32 = 4;
}

/// Whole-request statuses ([`EmpResponse::status`]).
pub mod status {
    /// Answered (see the per-item statuses).
    pub const OK: u32 = 0;
    /// Unknown request kind.
    pub const BAD_KIND: u32 = 1;
    /// `count` over [`super::MAX_BATCH`].
    pub const BAD_COUNT: u32 = 2;
    /// Tool index out of range.
    pub const BAD_TOOL: u32 = 3;
    /// Object mask names objects the world does not have, or none.
    pub const BAD_OBJECTS: u32 = 4;
    /// Horizon over the limit.
    pub const BAD_HORIZON: u32 = 5;
    /// The request's world hash is not the service's world.
    pub const WRONG_WORLD: u32 = 6;
    /// The table for the query would not fit in the service's memory bound.
    pub const TOO_LARGE: u32 = 7;

    /// A sentence for a status.
    pub fn describe(s: u32) -> &'static str {
        match s {
            OK => "ok",
            BAD_KIND => "unknown request kind",
            BAD_COUNT => "more states than a request can carry",
            BAD_TOOL => "tool index out of range",
            BAD_OBJECTS => "object set names objects the world does not have",
            BAD_HORIZON => "horizon over the limit",
            WRONG_WORLD => "the request is for another world",
            TOO_LARGE => "the table would not fit in the service's memory bound",
            _ => "unknown status",
        }
    }
}

/// Per-state statuses ([`EmpResponse::item_status`]).
pub mod item {
    /// The value is valid.
    pub const OK: u8 = 0;
    /// The bytes are not a state of the world's state space.
    pub const NOT_IN_SPACE: u8 = 1;
}

/// `objects` mask bit meaning the pseudo-object `agent`.
pub const AGENT_BIT: u32 = 1 << 31;
/// `tool` value meaning the full action set.
pub const TOOL_ALL: i32 = -1;

/// A request to the empowerment service. 38,936 bytes.
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("fulcrum::EmpRequest")]
#[repr(C)]
pub struct EmpRequest {
    /// [`crate::World::content_hash`] of the world the client speaks of.
    pub world_hash: u64,
    /// One of [`kind`].
    pub kind: u32,
    /// States in `states` (<= [`MAX_BATCH`]).
    pub count: u32,
    /// QUERY: tool index, or [`TOOL_ALL`].
    pub tool: i32,
    /// QUERY: horizon.
    pub horizon: u32,
    /// QUERY: bit i = object i; [`AGENT_BIT`] = the agent.
    pub objects: u32,
    /// Sequence number chosen by the client, echoed in the response.
    pub seq: u32,
    /// Packed states (`State::to_bytes`).
    pub states: [[u8; STATE_BYTES]; MAX_BATCH],
}

/// The world and configuration a service serves (DESCRIBE).
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("fulcrum::Describe")]
#[repr(C)]
pub struct Describe {
    /// World name, NUL padded.
    pub world: [u8; 64],
    /// [`crate::World::content_hash`].
    pub world_hash: u64,
    /// States in the state space.
    pub states: u64,
    /// Normal-mode states.
    pub normal_states: u64,
    /// Tools.
    pub n_tools: u32,
    /// Objects.
    pub n_objects: u32,
    /// Tool names, NUL padded.
    pub tools: [[u8; NAME_BYTES]; 16],
    /// Object names, NUL padded.
    pub objects: [[u8; NAME_BYTES]; 16],
    /// Configured tool index ([`TOOL_ALL`] for all).
    pub tool: i32,
    /// Configured object mask.
    pub object_mask: u32,
    /// Horizon where the tool is not held.
    pub horizon_unequipped: u32,
    /// Horizon where it is held.
    pub horizon_equipped: u32,
}

/// The answer to one [`EmpRequest`].
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("fulcrum::EmpResponse")]
#[repr(C)]
pub struct EmpResponse {
    /// One of [`status`].
    pub status: u32,
    /// States answered.
    pub count: u32,
    /// The request's sequence number.
    pub seq: u32,
    /// Padding.
    pub reserved: u32,
    /// E in bits per state.
    pub values: [f32; MAX_BATCH],
    /// One of [`item`] per state.
    pub item_status: [u8; MAX_BATCH],
    /// DESCRIBE's answer (also filled for the others: it is cheap).
    pub describe: Describe,
}

/// Write a name into a fixed NUL-padded field (cut at the field's size).
pub fn put_name<const N: usize>(dst: &mut [u8; N], s: &str) {
    *dst = [0; N];
    let b = s.as_bytes();
    let n = b.len().min(N);
    dst[..n].copy_from_slice(&b[..n]);
}

/// Read a NUL-padded name.
pub fn get_name(src: &[u8]) -> String {
    let end = src.iter().position(|&b| b == 0).unwrap_or(src.len());
    String::from_utf8_lossy(&src[..end]).into_owned()
}

/// Service names of a namespace.
#[derive(Debug, Clone)]
pub struct Names {
    /// Request-response.
    pub empowerment: String,
    /// Clients notify the server here.
    pub server_wake: String,
    /// The server notifies a client's listener here.
    pub client_wake: String,
}

impl Names {
    /// `fulcrum/<namespace>/...`.
    pub fn new(namespace: &str) -> Names {
        let base = format!("fulcrum/{namespace}/empowerment");
        Names {
            server_wake: format!("{base}/server-wake"),
            client_wake: format!("{base}/client-wake"),
            empowerment: base,
        }
    }
}

/// Clients a service takes at once (actors, CLI users, benchmarks).
pub const MAX_CLIENTS: usize = 64;
/// Requests one client may have in flight (pipelining depth).
pub const MAX_IN_FLIGHT: usize = 8;

/// Whether a namespace is usable in a service name: `[A-Za-z0-9_.-]+`, at most 64.
pub fn valid_namespace(ns: &str) -> bool {
    !ns.is_empty()
        && ns.len() <= 64
        && ns
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-' || b == b'.')
}
