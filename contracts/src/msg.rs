//! Shared-memory message layouts and service names.
//!
//! Plain data only: `#[repr(C)]`, `ZeroCopySend`, stable type names, no heap, no
//! pointers. Every process builds each iceoryx2 service with the functions here, so the
//! first one to create it fixes the same quality of service for all.
//!
//! ## The empowerment service (request-response)
//!
//! `fulcrum/<namespace>/empowerment`: a client sends an [`EmpRequest`] (a batch of up to
//! [`MAX_BATCH`] packed states, `State::to_bytes`, and for a family's service the layout
//! seed of each) and receives one [`EmpResponse`]
//! (one `f32` and one status byte per state). Wake-ups travel on two event services:
//! clients notify `.../server-wake` after sending; the server notifies the client's own
//! listener on `.../client-wake`, whose id the client puts in the request's user header.
//!
//! [`EmpRequest`]: crate::msg::EmpRequest
//! [`MAX_BATCH`]: crate::msg::MAX_BATCH
//! [`EmpResponse`]: crate::msg::EmpResponse

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
    /// A bridge to another host's service got no answer in time (the link is down):
    /// ask again later.
    pub const UNAVAILABLE: u32 = 8;

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
            UNAVAILABLE => "the service on the learner's host could not be reached",
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
/// `objects` mask bit meaning the objects by their conditions only (a boulder intact or
/// destroyed, whatever its cell), with the objects' own bits.
pub const CONDITIONS_BIT: u32 = 1 << 30;
/// `tool` value meaning the full action set.
pub const TOOL_ALL: i32 = -1;

/// A request to the empowerment service. 47,128 bytes.
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("fulcrum::EmpRequest")]
#[repr(C)]
pub struct EmpRequest {
    /// [`fulcrum_world::World::content_hash`] of the world the client speaks of.
    pub world_hash: u64,
    /// One of [`kind`].
    pub kind: u32,
    /// States in `states` (<= [`MAX_BATCH`]).
    pub count: u32,
    /// QUERY: tool index, or [`TOOL_ALL`].
    pub tool: i32,
    /// QUERY: horizon.
    pub horizon: u32,
    /// QUERY: bit i = object i; [`AGENT_BIT`] = the agent; with [`CONDITIONS_BIT`], the
    /// objects by their conditions only.
    pub objects: u32,
    /// Sequence number chosen by the client, echoed in the response.
    pub seq: u32,
    /// Packed states (`State::to_bytes`).
    pub states: [[u8; STATE_BYTES]; MAX_BATCH],
    /// The layout seed of each state, where the service serves a world family (a state
    /// is a state of one layout); ignored by the service of one world.
    pub layouts: [u64; MAX_BATCH],
}

/// The world and configuration a service serves (DESCRIBE).
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("fulcrum::Describe")]
#[repr(C)]
pub struct Describe {
    /// World name, NUL padded.
    pub world: [u8; 64],
    /// [`fulcrum_world::World::content_hash`].
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

impl Describe {
    /// All zero: no world.
    pub fn empty() -> Describe {
        Describe {
            world: [0; 64],
            world_hash: 0,
            states: 0,
            normal_states: 0,
            n_tools: 0,
            n_objects: 0,
            tools: [[0; NAME_BYTES]; 16],
            objects: [[0; NAME_BYTES]; 16],
            tool: 0,
            object_mask: 0,
            horizon_unequipped: 0,
            horizon_equipped: 0,
        }
    }
}

impl EmpRequest {
    /// An all-zero request on the heap (39 KB).
    pub fn boxed() -> Box<EmpRequest> {
        Box::new(EmpRequest {
            world_hash: 0,
            kind: 0,
            count: 0,
            tool: 0,
            horizon: 0,
            objects: 0,
            seq: 0,
            states: [[0; STATE_BYTES]; MAX_BATCH],
            layouts: [0; MAX_BATCH],
        })
    }
}

impl EmpResponse {
    /// An all-zero answer on the heap.
    pub fn boxed() -> Box<EmpResponse> {
        Box::new(EmpResponse {
            status: 0,
            count: 0,
            seq: 0,
            reserved: 0,
            values: [0.0; MAX_BATCH],
            item_status: [0; MAX_BATCH],
            describe: Describe::empty(),
        })
    }
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

/// Clients a service takes at once by default (`fulcrum serve --max-clients`; actors,
/// CLI users, benchmarks). The server's memory grows with it: it holds
/// `clients x 2 x MAX_IN_FLIGHT x (MAX_IN_FLIGHT + 4)` responses of about 5 KiB, 75 MiB
/// for 64 clients, so a training run makes its service for its own actors
/// ([`crate::config::RunConfig::service_clients`]).
pub const MAX_CLIENTS: usize = 64;
/// Clients beyond its actors a training run's service takes: restarted actors whose
/// predecessor's port is not yet cleaned up, and clients from outside the run.
pub const SPARE_CLIENTS: usize = 8;
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

/// Wire forms of requests and answers for hosts that do not share memory (the
/// `multihost` bridge): little-endian, only the `count` states or values that are used.
pub mod wire {
    use super::{Describe, EmpRequest, EmpResponse, MAX_BATCH, NAME_BYTES, STATE_BYTES};

    /// Bytes in front of a request's states.
    pub const REQUEST_HEAD: usize = 32;
    /// Bytes of a [`Describe`] on the wire.
    pub const DESCRIBE_BYTES: usize = 64 + 8 * 3 + 4 * 2 + NAME_BYTES * 32 + 4 * 4;

    struct Reader<'a>(&'a [u8]);

    impl Reader<'_> {
        fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
            let (a, b) = self.0.split_first_chunk::<N>()?;
            self.0 = b;
            Some(*a)
        }
        fn u32(&mut self) -> Option<u32> {
            self.take().map(u32::from_le_bytes)
        }
        fn u64(&mut self) -> Option<u64> {
            self.take().map(u64::from_le_bytes)
        }
    }

    /// A request: header, then `count` packed states, then (on a world family, where
    /// some state's layout is not 0) each state's layout seed, 8 bytes little-endian.
    /// Layouts left off read as 0, the meaning they have for one world and for a
    /// family's layout 0, so the two forms never disagree.
    pub fn request(r: &EmpRequest) -> Vec<u8> {
        let n = (r.count as usize).min(MAX_BATCH);
        let layouts = &r.layouts[..n];
        let with_layouts = layouts.iter().any(|&l| l != 0);
        let mut out = Vec::with_capacity(
            REQUEST_HEAD + n * STATE_BYTES + if with_layouts { n * 8 } else { 0 },
        );
        out.extend_from_slice(&r.world_hash.to_le_bytes());
        for v in [r.kind, r.count, r.tool as u32, r.horizon, r.objects, r.seq] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for s in &r.states[..n] {
            out.extend_from_slice(s);
        }
        if with_layouts {
            for l in layouts {
                out.extend_from_slice(&l.to_le_bytes());
            }
        }
        out
    }

    /// Read a request written by [`request`] into `out` (whose unused states are left
    /// as they are). A sentence says what is wrong with bytes that are not one.
    pub fn read_request(bytes: &[u8], out: &mut EmpRequest) -> Result<(), String> {
        let mut r = Reader(bytes);
        let head = (|| {
            Some((
                r.u64()?,
                r.u32()?,
                r.u32()?,
                r.u32()?,
                r.u32()?,
                r.u32()?,
                r.u32()?,
            ))
        })()
        .ok_or_else(|| {
            format!(
                "a request of {} bytes is shorter than its header",
                bytes.len()
            )
        })?;
        let (world_hash, kind, count, tool, horizon, objects, seq) = head;
        let n = count as usize;
        if n > MAX_BATCH {
            return Err(format!("a request of {n} states (at most {MAX_BATCH})"));
        }
        let (states, layouts) = (n * STATE_BYTES, n * 8);
        if r.0.len() != states && r.0.len() != states + layouts {
            return Err(format!(
                "a request of {n} states carries {} bytes after its header, not {states} (states) or {} (states and layouts)",
                r.0.len(),
                states + layouts
            ));
        }
        out.world_hash = world_hash;
        out.kind = kind;
        out.count = count;
        out.tool = tool as i32;
        out.horizon = horizon;
        out.objects = objects;
        out.seq = seq;
        let (body, mut tail) = (&r.0[..states], Reader(&r.0[states..]));
        for (slot, s) in out.states.iter_mut().zip(body.chunks_exact(STATE_BYTES)) {
            slot.copy_from_slice(s);
        }
        for slot in out.layouts[..n].iter_mut() {
            *slot = tail.u64().unwrap_or(0);
        }
        Ok(())
    }

    fn describe(d: &Describe, out: &mut Vec<u8>) {
        out.extend_from_slice(&d.world);
        for v in [d.world_hash, d.states, d.normal_states] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&d.n_tools.to_le_bytes());
        out.extend_from_slice(&d.n_objects.to_le_bytes());
        for n in d.tools.iter().chain(&d.objects) {
            out.extend_from_slice(n);
        }
        for v in [
            d.tool as u32,
            d.object_mask,
            d.horizon_unequipped,
            d.horizon_equipped,
        ] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }

    fn read_describe(r: &mut Reader, d: &mut Describe) -> Option<()> {
        d.world = r.take()?;
        d.world_hash = r.u64()?;
        d.states = r.u64()?;
        d.normal_states = r.u64()?;
        d.n_tools = r.u32()?;
        d.n_objects = r.u32()?;
        for n in d.tools.iter_mut() {
            *n = r.take()?;
        }
        for n in d.objects.iter_mut() {
            *n = r.take()?;
        }
        d.tool = r.u32()? as i32;
        d.object_mask = r.u32()?;
        d.horizon_unequipped = r.u32()?;
        d.horizon_equipped = r.u32()?;
        Some(())
    }

    /// An answer: status, count, seq, then `count` values and statuses, then the
    /// service's [`Describe`].
    pub fn response(r: &EmpResponse) -> Vec<u8> {
        let n = (r.count as usize).min(MAX_BATCH);
        let mut out = Vec::with_capacity(16 + n * 5 + DESCRIBE_BYTES);
        for v in [r.status, r.count, r.seq, r.reserved] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in &r.values[..n] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&r.item_status[..n]);
        describe(&r.describe, &mut out);
        out
    }

    /// Read an answer written by [`response`] into `out`.
    pub fn read_response(bytes: &[u8], out: &mut EmpResponse) -> Result<(), String> {
        let mut r = Reader(bytes);
        let short = || format!("an answer of {} bytes is cut short", bytes.len());
        let (status, count, seq, reserved) =
            (|| Some((r.u32()?, r.u32()?, r.u32()?, r.u32()?)))().ok_or_else(short)?;
        let n = count as usize;
        if n > MAX_BATCH {
            return Err(format!("an answer of {n} values (at most {MAX_BATCH})"));
        }
        if r.0.len() != n * 5 + DESCRIBE_BYTES {
            return Err(short());
        }
        out.status = status;
        out.count = count;
        out.seq = seq;
        out.reserved = reserved;
        for v in out.values[..n].iter_mut() {
            *v = f32::from_le_bytes(r.take().ok_or_else(short)?);
        }
        for s in out.item_status[..n].iter_mut() {
            *s = r.take::<1>().ok_or_else(short)?[0];
        }
        read_describe(&mut r, &mut out.describe).ok_or_else(short)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_travel_with_only_their_states() {
        let mut r = EmpRequest::boxed();
        r.world_hash = 0xabcd;
        r.kind = kind::VISIT;
        r.count = 2;
        r.tool = TOOL_ALL;
        r.horizon = 7;
        r.objects = AGENT_BIT | 1;
        r.seq = 41;
        r.states[0] = [3; STATE_BYTES];
        r.states[1] = [5; STATE_BYTES];
        r.states[2] = [9; STATE_BYTES]; // beyond count: not sent
        let b = wire::request(&r);
        assert_eq!(b.len(), 32 + 2 * 38);
        assert_eq!(&b[0..8], &[0xcd, 0xab, 0, 0, 0, 0, 0, 0]);
        assert_eq!(&b[8..12], &[4, 0, 0, 0]); // VISIT
        assert_eq!(&b[16..20], &[0xff; 4]); // tool -1
        assert_eq!(&b[24..28], &[1, 0, 0, 0x80]); // agent bit + object 0
        let mut back = EmpRequest::boxed();
        wire::read_request(&b, &mut back).unwrap();
        assert_eq!((back.kind, back.count, back.tool, back.seq), (4, 2, -1, 41));
        assert_eq!(back.objects, AGENT_BIT | 1);
        assert_eq!(back.states[1], [5; STATE_BYTES]);
        assert_eq!(back.states[2], [0; STATE_BYTES]);
        // Cut short, one byte too many, too many states: refused with a sentence.
        assert!(wire::read_request(&b[..b.len() - 1], &mut back).is_err());
        let mut long = b.clone();
        long.push(0);
        assert!(wire::read_request(&long, &mut back).is_err());
        let mut huge = b.clone();
        huge[12..16].copy_from_slice(&(MAX_BATCH as u32 + 1).to_le_bytes());
        assert!(wire::read_request(&huge, &mut back)
            .unwrap_err()
            .contains("at most 1024"));
        assert!(wire::read_request(&b[..31], &mut back).is_err());
    }

    #[test]
    fn a_family_request_carries_each_states_layout() {
        let mut r = EmpRequest::boxed();
        r.kind = kind::LOOKUP;
        r.count = 2;
        r.states[0] = [3; STATE_BYTES];
        r.states[1] = [5; STATE_BYTES];
        r.layouts[0] = 0;
        r.layouts[1] = (1 << 40) + 7;
        r.layouts[2] = 99; // beyond count: not sent
        let b = wire::request(&r);
        // Header, two states, two layouts (hand count: 32 + 2 x 38 + 2 x 8).
        assert_eq!(b.len(), 124);
        assert_eq!(&b[108..116], &[0; 8]);
        assert_eq!(&b[116..124], &[7, 0, 0, 0, 0, 1, 0, 0]); // 2^40: byte 5
                                                             // A receiver whose slots hold an earlier request's layouts gets these.
        let mut back = EmpRequest::boxed();
        back.layouts[0] = 12;
        wire::read_request(&b, &mut back).unwrap();
        assert_eq!(&back.layouts[..3], &[0, (1 << 40) + 7, 0]);
        assert_eq!(back.states[1], [5; STATE_BYTES]);
        // Every layout 0: left off, and read back as 0 over stale slots.
        r.layouts[1] = 0;
        let b = wire::request(&r);
        assert_eq!(b.len(), 32 + 2 * 38);
        back.layouts[1] = 5;
        wire::read_request(&b, &mut back).unwrap();
        assert_eq!(&back.layouts[..2], &[0, 0]);
        // Part of the layouts: neither form, refused with a sentence.
        r.layouts[1] = 1;
        let b = wire::request(&r);
        let why = wire::read_request(&b[..b.len() - 4], &mut back).unwrap_err();
        assert!(why.contains("not 76 (states) or 92"), "{why}");
    }

    #[test]
    fn answers_keep_values_statuses_and_the_description() {
        let mut r = EmpResponse::boxed();
        r.status = status::OK;
        r.count = 3;
        r.seq = 9;
        r.values[..3].copy_from_slice(&[0.0, 1.5849625, 2.0]);
        r.item_status[..3].copy_from_slice(&[0, 1, 0]);
        put_name(&mut r.describe.world, "exp2");
        put_name(&mut r.describe.tools[1], "pickaxe");
        r.describe.world_hash = 77;
        r.describe.tool = TOOL_ALL;
        r.describe.horizon_equipped = 4;
        let b = wire::response(&r);
        assert_eq!(b.len(), 16 + 3 * 4 + 3 + wire::DESCRIBE_BYTES);
        assert_eq!(wire::DESCRIBE_BYTES, 1136);
        assert_eq!(&b[20..24], &1.5849625f32.to_le_bytes());
        let mut back = EmpResponse::boxed();
        wire::read_response(&b, &mut back).unwrap();
        assert_eq!(&back.values[..3], &[0.0, 1.5849625, 2.0]);
        assert_eq!(&back.item_status[..3], &[0, 1, 0]);
        assert_eq!(get_name(&back.describe.world), "exp2");
        assert_eq!(get_name(&back.describe.tools[1]), "pickaxe");
        assert_eq!(back.describe.tool, TOOL_ALL);
        assert_eq!(back.describe.horizon_equipped, 4);
        assert_eq!(back.describe.world_hash, 77);
        assert!(wire::read_response(&b[..b.len() - 1], &mut back).is_err());
    }
}
