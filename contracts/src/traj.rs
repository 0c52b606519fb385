//! Trajectory chunks and policy weights in shared memory.
//!
//! ## Trajectories (publish-subscribe, actors -> learner)
//!
//! `fulcrum/<namespace>/trajectories` carries one chunk per message: a [`ChunkHeader`]
//! (iceoryx2 user header) and a byte payload laid out by [`ChunkLayout`]. With M worlds
//! per actor and T steps per chunk, N = M * T transitions, C cells and F flags, the
//! payload is, in order (step-major: transition `i = t * M + e`):
//!
//! ```text
//! glyphs      N*C  u8    observation o_t
//! flags       N*F  u8
//! actions     N    u8    a_t
//! terminated  N    u8    s_{t+1} is the task's terminal state
//! truncated   N    u8    the episode ran out of steps at s_{t+1} (not terminal)
//! env_state   M*56 u8    each world's episode after the chunk (for exact resume)
//! logprob     N    f32   log pi(a_t | o_t) under the chunk's policy version
//! value       N    f32   V(o_t)
//! ext_reward  N    f32   the task's reward r_t
//! int_reward  N    f32   E(s_{t+1}) in bits, from the empowerment service (0 without)
//! trunc_value N    f32   V(o_{t+1}) where truncated (bootstrap), else 0
//! last_value  M    f32   V of each world's observation after the chunk
//! ```
//!
//! f32 sections are little-endian bytes (no alignment assumed). Actors write straight
//! into the loaned sample; the learner copies every chunk out of shared memory and then
//! checks the copy whole ([`crate::chunk_check::check_chunk`], which starts with
//! [`ChunkLayout::validate`]) before it uses any of it. The service is built with safe overflow off: a full
//! learner queue blocks actors (backpressure), it never drops chunks.
//!
//! ## Policy weights (publish-subscribe, learner -> actors)
//!
//! `fulcrum/<namespace>/policy` carries the network's parameters as one flat `f32`
//! slice with a [`WeightsHeader`]; history 1, so an actor that starts (or restarts)
//! late receives the current weights at once.
//!
//! Each data service has an event service beside it (`.../wake`): senders notify after
//! sending so that receivers can block on a listener instead of polling.
//!
//! [`ChunkHeader`]: crate::traj::ChunkHeader
//! [`ChunkLayout`]: crate::traj::ChunkLayout
//! [`ChunkLayout::validate`]: crate::traj::ChunkLayout::validate
//! [`WeightsHeader`]: crate::traj::WeightsHeader

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;

use crate::ipc_error::IpcError;
use fulcrum_world::env::Episode;
use fulcrum_world::state::State;

/// Most actor processes of one run.
pub const MAX_ACTORS: usize = 64;
/// Actor ids of remote hosts: host h (1, 2, ...) runs actors `h * HOST_STRIDE + j`;
/// host 0 is the learner's own.
pub const HOST_STRIDE: u32 = 1024;

/// The host an actor id belongs to (0 = the learner's host).
pub fn host_of(actor: u32) -> u32 {
    actor / HOST_STRIDE
}

/// Chunks the learner's queue holds per actor before actors block.
pub const CHUNK_QUEUE: usize = 4;
/// Subscribers of the trajectory service (the learner, and one spare).
pub const CHUNK_SUBSCRIBERS: usize = 2;
/// Subscribers of the weights service of a run with actors on other hosts (whose
/// counts differ from host to host): every local actor the run may have, the bridge,
/// and spares for actors restarted while their predecessor's port is not yet cleaned
/// up. A run on one host makes it for its own actors
/// ([`crate::config::RunConfig::weights_subscribers`]).
pub const WEIGHTS_SUBSCRIBERS: usize = MAX_ACTORS + 4;
/// Spare weights subscribers of a run on one host: actors restarted while their
/// predecessor's port is not yet cleaned up.
pub const SPARE_SUBSCRIBERS: usize = 4;
/// Weights a subscriber keeps queued, and borrows at a time: one each, since an actor
/// only wants the newest weights (safe overflow replaces older ones) and reads one
/// sample at a time. iceoryx2 keeps `subscribers x (queued + borrowed) + history +
/// loaned` samples of the weights in shared memory (`fulcrum_run::sizes`), so each
/// one more here costs the weights `2 x WEIGHTS_SUBSCRIBERS` times over.
pub const WEIGHTS_BUFFER: usize = 1;
/// Weights samples the learner's publisher loans at a time.
pub const WEIGHTS_LOANED: usize = 1;
/// Chunks an actor's publisher loans at a time.
pub const CHUNKS_LOANED: usize = 2;
/// Bytes of one world's episode record in `env_state`.
pub const ENV_BYTES: usize = 64;
/// Bytes of a record written before families (no layout seed): a checkpoint of that
/// time still resumes.
pub const OLD_ENV_BYTES: usize = 56;

/// Metadata of one trajectory chunk.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("fulcrum::ChunkHeader")]
#[repr(C)]
pub struct ChunkHeader {
    /// The run's tag ([`run_tag`] of the namespace): chunks of other runs are refused.
    pub run: u64,
    /// [`fulcrum_world::World::content_hash`].
    pub world_hash: u64,
    /// The actor's chunk counter (per incarnation, from 0).
    pub seq: u64,
    /// The policy version that chose the actions.
    pub policy_version: u64,
    /// Actor index.
    pub actor: u32,
    /// How many times this actor was restarted before this process.
    pub incarnation: u32,
    /// M.
    pub envs: u32,
    /// T.
    pub steps: u32,
    /// C.
    pub cells: u32,
    /// F.
    pub flags: u32,
    /// Number of actions (for the range check).
    pub actions: u32,
    /// Episodes that ended in this chunk.
    pub episodes: u32,
    /// Of those, how many reached the task's terminal state.
    pub successes: u32,
    /// Episodes in which a tool was picked up.
    pub pickups: u32,
    /// Transitions whose E(s_{t+1}) > 0 (forms that look E up; 0 otherwise).
    pub e_positive: u32,
    /// Padding (keeps the sums 8-byte aligned).
    pub reserved: u32,
    /// Sum over ended episodes of the extrinsic return.
    pub ext_return_sum: f64,
    /// Sum over ended episodes of the intrinsic return (sum of E, bits).
    pub int_return_sum: f64,
    /// Sum over ended episodes of their length.
    pub length_sum: f64,
    /// Sum over all N transitions of the intrinsic term b_t (before beta; E(s_{t+1})
    /// for the additive form).
    pub int_reward_sum: f64,
    /// Payload bytes.
    pub len: u64,
}

/// Little-endian writer/reader for the wire forms of the headers below (messages
/// between hosts carry them in front of the payload; shared memory carries the structs).
struct Wire<'a> {
    buf: &'a [u8],
    at: usize,
}

impl Wire<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let b = self.buf.get(self.at..self.at + N)?;
        self.at += N;
        b.try_into().ok()
    }
    fn u64(&mut self) -> Option<u64> {
        self.take().map(u64::from_le_bytes)
    }
    fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_le_bytes)
    }
    fn f64(&mut self) -> Option<f64> {
        self.take().map(f64::from_le_bytes)
    }
}

impl ChunkHeader {
    /// Bytes of [`ChunkHeader::to_wire`].
    pub const WIRE_BYTES: usize = 120;

    /// The header as little-endian bytes, field by field in declaration order.
    pub fn to_wire(&self) -> [u8; Self::WIRE_BYTES] {
        let mut out = [0u8; Self::WIRE_BYTES];
        let mut at = 0;
        let mut put = |b: &[u8]| {
            out[at..at + b.len()].copy_from_slice(b);
            at += b.len();
        };
        for v in [self.run, self.world_hash, self.seq, self.policy_version] {
            put(&v.to_le_bytes());
        }
        for v in [
            self.actor,
            self.incarnation,
            self.envs,
            self.steps,
            self.cells,
            self.flags,
            self.actions,
            self.episodes,
            self.successes,
            self.pickups,
            self.e_positive,
            self.reserved,
        ] {
            put(&v.to_le_bytes());
        }
        for v in [
            self.ext_return_sum,
            self.int_return_sum,
            self.length_sum,
            self.int_reward_sum,
        ] {
            put(&v.to_le_bytes());
        }
        put(&self.len.to_le_bytes());
        out
    }

    /// Read a header written by [`ChunkHeader::to_wire`] from the front of `bytes`
    /// (None when there are too few). The values are checked later, as for chunks
    /// from shared memory ([`ChunkLayout::validate`]).
    pub fn from_wire(bytes: &[u8]) -> Option<ChunkHeader> {
        let mut r = Wire { buf: bytes, at: 0 };
        Some(ChunkHeader {
            run: r.u64()?,
            world_hash: r.u64()?,
            seq: r.u64()?,
            policy_version: r.u64()?,
            actor: r.u32()?,
            incarnation: r.u32()?,
            envs: r.u32()?,
            steps: r.u32()?,
            cells: r.u32()?,
            flags: r.u32()?,
            actions: r.u32()?,
            episodes: r.u32()?,
            successes: r.u32()?,
            pickups: r.u32()?,
            e_positive: r.u32()?,
            reserved: r.u32()?,
            ext_return_sum: r.f64()?,
            int_return_sum: r.f64()?,
            length_sum: r.f64()?,
            int_reward_sum: r.f64()?,
            len: r.u64()?,
        })
    }
}

/// Metadata of a weights message.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("fulcrum::WeightsHeader")]
#[repr(C)]
pub struct WeightsHeader {
    /// The run's tag.
    pub run: u64,
    /// World hash.
    pub world_hash: u64,
    /// Policy version (0 = the initial weights; +1 per update).
    pub version: u64,
    /// Floats in the payload.
    pub len: u64,
}

impl WeightsHeader {
    /// Bytes of [`WeightsHeader::to_wire`].
    pub const WIRE_BYTES: usize = 32;

    /// The header as little-endian bytes (run, world hash, version, len).
    pub fn to_wire(&self) -> [u8; Self::WIRE_BYTES] {
        let mut out = [0u8; Self::WIRE_BYTES];
        for (i, v) in [self.run, self.world_hash, self.version, self.len]
            .into_iter()
            .enumerate()
        {
            out[i * 8..(i + 1) * 8].copy_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Read a header written by [`WeightsHeader::to_wire`] (None when too short).
    pub fn from_wire(bytes: &[u8]) -> Option<WeightsHeader> {
        let mut r = Wire { buf: bytes, at: 0 };
        Some(WeightsHeader {
            run: r.u64()?,
            world_hash: r.u64()?,
            version: r.u64()?,
            len: r.u64()?,
        })
    }
}

/// A section of a chunk's payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Section {
    /// `u8`, N*C.
    Glyphs,
    /// `u8`, N*F.
    Flags,
    /// `u8`, N.
    Actions,
    /// `u8`, N (0/1).
    Terminated,
    /// `u8`, N (0/1).
    Truncated,
    /// M * [`ENV_BYTES`].
    EnvState,
    /// `f32`, N.
    Logprob,
    /// `f32`, N.
    Value,
    /// `f32`, N.
    ExtReward,
    /// `f32`, N.
    IntReward,
    /// `f32`, N.
    TruncValue,
    /// `f32`, M.
    LastValue,
    /// `f32`, N: the intrinsic value head's V_int(s_t) (0 without it).
    ValueInt,
    /// `f32`, N: V_int of truncated episodes' final observations.
    TruncValueInt,
    /// `f32`, M: V_int after the chunk.
    LastValueInt,
}

/// Offsets of a chunk's sections.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChunkLayout {
    /// M.
    pub envs: usize,
    /// T.
    pub steps: usize,
    /// C.
    pub cells: usize,
    /// F.
    pub flags: usize,
}

impl ChunkLayout {
    /// N = M * T.
    pub fn n(&self) -> usize {
        self.envs * self.steps
    }

    /// Byte range of a section.
    pub fn range(&self, s: Section) -> std::ops::Range<usize> {
        let n = self.n();
        let m = self.envs;
        let order = [
            (Section::Glyphs, n * self.cells),
            (Section::Flags, n * self.flags),
            (Section::Actions, n),
            (Section::Terminated, n),
            (Section::Truncated, n),
            (Section::EnvState, m * ENV_BYTES),
            (Section::Logprob, 4 * n),
            (Section::Value, 4 * n),
            (Section::ExtReward, 4 * n),
            (Section::IntReward, 4 * n),
            (Section::TruncValue, 4 * n),
            (Section::LastValue, 4 * m),
            (Section::ValueInt, 4 * n),
            (Section::TruncValueInt, 4 * n),
            (Section::LastValueInt, 4 * m),
        ];
        let mut off = 0;
        for (k, len) in order {
            if k == s {
                return off..off + len;
            }
            off += len;
        }
        unreachable!("every section is in the table")
    }

    /// Payload bytes.
    pub fn bytes(&self) -> usize {
        self.range(Section::LastValueInt).end
    }

    /// The layout a header announces.
    pub fn of(h: &ChunkHeader) -> ChunkLayout {
        ChunkLayout {
            envs: h.envs as usize,
            steps: h.steps as usize,
            cells: h.cells as usize,
            flags: h.flags as usize,
        }
    }

    /// Check a received chunk's form against what the learner expects: sizes, action
    /// range, 0/1 done bytes, finite floats. Returns a short reason when the chunk must
    /// be dropped. The world-dependent rest (glyphs, flags, episode records, bounds) is
    /// [`crate::chunk_check::check_chunk`], which calls this first.
    pub fn validate(
        &self,
        h: &ChunkHeader,
        actions: usize,
        payload: &[u8],
    ) -> Result<(), &'static str> {
        if ChunkLayout::of(h) != *self || h.actions as usize != actions {
            return Err("shape differs from the run's");
        }
        if h.len as usize != self.bytes() || payload.len() != self.bytes() {
            return Err("payload length differs from its layout");
        }
        if payload[self.range(Section::Actions)]
            .iter()
            .any(|&a| a as usize >= actions)
        {
            return Err("action out of range");
        }
        for s in [Section::Terminated, Section::Truncated] {
            if payload[self.range(s)].iter().any(|&b| b > 1) {
                return Err("done flag not 0 or 1");
            }
        }
        for s in [
            Section::Logprob,
            Section::Value,
            Section::ExtReward,
            Section::IntReward,
            Section::TruncValue,
            Section::LastValue,
            Section::ValueInt,
            Section::TruncValueInt,
            Section::LastValueInt,
        ] {
            if payload[self.range(s)]
                .chunks_exact(4)
                .any(|b| !f32::from_le_bytes([b[0], b[1], b[2], b[3]]).is_finite())
            {
                return Err("a number is not finite");
            }
        }
        let sums = [
            h.ext_return_sum,
            h.int_return_sum,
            h.length_sum,
            h.int_reward_sum,
        ];
        if sums.iter().any(|x| !x.is_finite()) || h.successes > h.episodes {
            return Err("episode statistics are not valid");
        }
        Ok(())
    }
}

/// Read an f32 section into `out`.
pub fn read_f32s(bytes: &[u8], out: &mut [f32]) {
    for (o, b) in out.iter_mut().zip(bytes.chunks_exact(4)) {
        *o = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    }
}

/// Write `v` as the `i`-th f32 of a section.
#[inline]
pub fn put_f32(bytes: &mut [u8], i: usize, v: f32) {
    bytes[4 * i..4 * i + 4].copy_from_slice(&v.to_le_bytes());
}

/// One world's episode record: the episode and its running returns, for exact resume.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnvRecord {
    /// The episode.
    pub episode: Episode,
    /// Extrinsic return so far.
    pub ext_return: f32,
    /// Intrinsic return so far.
    pub int_return: f32,
    /// Whether a tool was picked up in this episode.
    pub picked: bool,
    /// Whether the first-visit bonus has paid for the current inventory in this episode.
    pub paid: bool,
    /// The layout seed of the episode (a run on a world family; 0 otherwise).
    pub layout: u64,
}

impl EnvRecord {
    /// A fresh record.
    pub fn new(episode: Episode) -> EnvRecord {
        EnvRecord {
            episode,
            ext_return: 0.0,
            int_return: 0.0,
            picked: false,
            paid: false,
            layout: 0,
        }
    }

    /// A fresh record of an episode on layout `layout`.
    pub fn on_layout(episode: Episode, layout: u64) -> EnvRecord {
        EnvRecord {
            layout,
            ..EnvRecord::new(episode)
        }
    }

    /// [`ENV_BYTES`] bytes: state (38), t (4), rewarded (2), returns (2 x 4), picked (1),
    /// paid (1), padding (2), layout seed (8).
    pub fn to_bytes(&self) -> [u8; ENV_BYTES] {
        let mut b = [0u8; ENV_BYTES];
        b[..38].copy_from_slice(&self.episode.state.to_bytes());
        b[38..42].copy_from_slice(&self.episode.t.to_le_bytes());
        b[42..44].copy_from_slice(&self.episode.rewarded.to_le_bytes());
        b[44..48].copy_from_slice(&self.ext_return.to_le_bytes());
        b[48..52].copy_from_slice(&self.int_return.to_le_bytes());
        b[52] = self.picked as u8;
        b[53] = self.paid as u8;
        b[56..64].copy_from_slice(&self.layout.to_le_bytes());
        b
    }

    /// From [`EnvRecord::to_bytes`], or from the [`OLD_ENV_BYTES`] of a record written
    /// before families (layout 0).
    pub fn from_bytes(b: &[u8]) -> Option<EnvRecord> {
        if b.len() != ENV_BYTES && b.len() != OLD_ENV_BYTES {
            return None;
        }
        let sb: [u8; 38] = b[..38].try_into().ok()?;
        let f = |i: usize| [b[i], b[i + 1], b[i + 2], b[i + 3]];
        Some(EnvRecord {
            episode: Episode {
                state: State::from_bytes(&sb),
                t: u32::from_le_bytes(f(38)),
                rewarded: u16::from_le_bytes([b[42], b[43]]),
            },
            ext_return: f32::from_le_bytes(f(44)),
            int_return: f32::from_le_bytes(f(48)),
            picked: b[52] == 1,
            paid: b[53] == 1,
            layout: match b.get(56..64) {
                Some(l) => u64::from_le_bytes(l.try_into().ok()?),
                None => 0,
            },
        })
    }
}

/// Service names of a training run.
#[derive(Debug, Clone)]
pub struct TrainNames {
    /// Chunks.
    pub trajectories: String,
    /// Actors notify the learner here after sending a chunk.
    pub trajectories_wake: String,
    /// Weights.
    pub policy: String,
    /// The learner notifies actors here after publishing weights.
    pub policy_wake: String,
}

impl TrainNames {
    /// `fulcrum/<namespace>/...`.
    pub fn new(namespace: &str) -> TrainNames {
        TrainNames {
            trajectories: format!("fulcrum/{namespace}/trajectories"),
            trajectories_wake: format!("fulcrum/{namespace}/trajectories/wake"),
            policy: format!("fulcrum/{namespace}/policy"),
            policy_wake: format!("fulcrum/{namespace}/policy/wake"),
        }
    }
}

/// A run's tag: FNV-1a of its namespace (never 0).
pub fn run_tag(namespace: &str) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in namespace.bytes() {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h.max(1)
}

/// The trajectory service.
pub type TrajFactory = PubSubFactory<ipc::Service, [u8], ChunkHeader>;
/// The weights service.
pub type PolicyFactory = PubSubFactory<ipc::Service, [f32], WeightsHeader>;
/// A chunk publisher.
pub type ChunkPublisher = Publisher<ipc::Service, [u8], ChunkHeader>;
/// A chunk subscriber.
pub type ChunkSubscriber = Subscriber<ipc::Service, [u8], ChunkHeader>;
/// A weights publisher.
pub type WeightsPublisher = Publisher<ipc::Service, [f32], WeightsHeader>;
/// A weights subscriber.
pub type WeightsSubscriber = Subscriber<ipc::Service, [f32], WeightsHeader>;

fn name(s: &str) -> Result<ServiceName, IpcError> {
    ServiceName::new(s).map_err(|e| IpcError::new(format!("service name {s}"), e))
}

/// The trajectory service, built the same way by every process (the first fixes QoS).
pub fn trajectory_service(
    node: &Node<ipc::Service>,
    n: &TrainNames,
) -> Result<TrajFactory, IpcError> {
    node.service_builder(&name(&n.trajectories)?)
        .publish_subscribe::<[u8]>()
        .user_header::<ChunkHeader>()
        .max_publishers(MAX_ACTORS + 4)
        .max_subscribers(CHUNK_SUBSCRIBERS)
        .max_nodes(MAX_ACTORS + 8)
        .subscriber_max_buffer_size(CHUNK_QUEUE)
        .subscriber_max_borrowed_samples(CHUNK_QUEUE)
        .history_size(0)
        .enable_safe_overflow(false)
        .open_or_create()
        .map_err(|e| IpcError::new("trajectory service", e))
}

/// The weights service (history 1: late subscribers get the current weights), made for
/// `subscribers` subscribers: every process of a host passes the same number
/// ([`crate::config::RunConfig::weights_subscribers`], or [`WEIGHTS_SUBSCRIBERS`] on a
/// run across hosts), since the first to come creates the service and the publisher's
/// memory grows with it (`2 x subscribers + 2` samples of all the weights).
pub fn policy_service(
    node: &Node<ipc::Service>,
    n: &TrainNames,
    subscribers: usize,
) -> Result<PolicyFactory, IpcError> {
    node.service_builder(&name(&n.policy)?)
        .publish_subscribe::<[f32]>()
        .user_header::<WeightsHeader>()
        .max_publishers(2)
        .max_subscribers(subscribers)
        .max_nodes(MAX_ACTORS + 8)
        .subscriber_max_buffer_size(WEIGHTS_BUFFER)
        .subscriber_max_borrowed_samples(WEIGHTS_BUFFER)
        .history_size(1)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| IpcError::new("policy service", e))
}

/// An event service for wake-ups.
pub fn wake_service(
    node: &Node<ipc::Service>,
    service: &str,
) -> Result<EventFactory<ipc::Service>, IpcError> {
    node.service_builder(&name(service)?)
        .event()
        .max_listeners(MAX_ACTORS + 4)
        .max_notifiers(MAX_ACTORS + 4)
        .max_nodes(MAX_ACTORS + 8)
        .open_or_create()
        .map_err(|e| IpcError::new(format!("event service {service}"), e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_have_a_fixed_little_endian_wire_form() {
        let h = ChunkHeader {
            run: 0x0102_0304_0506_0708,
            world_hash: 9,
            seq: 10,
            policy_version: 11,
            actor: 1025,
            incarnation: 2,
            envs: 8,
            steps: 128,
            cells: 99,
            flags: 4,
            actions: 12,
            episodes: 3,
            successes: 1,
            pickups: 2,
            e_positive: 77,
            reserved: 0,
            ext_return_sum: 1.5,
            int_return_sum: -0.25,
            length_sum: 300.0,
            int_reward_sum: 2.0,
            len: 65536,
        };
        let b = h.to_wire();
        // Offsets by hand: 4 u64 (0..32), 12 u32 (32..80), 4 f64 (80..112), len (112..120).
        assert_eq!(&b[0..8], &[8, 7, 6, 5, 4, 3, 2, 1]);
        assert_eq!(&b[32..36], &[1, 4, 0, 0]); // actor 1025 = 0x401
        assert_eq!(&b[72..76], &[77, 0, 0, 0]); // e_positive
        assert_eq!(&b[80..88], &1.5f64.to_le_bytes());
        assert_eq!(&b[112..120], &[0, 0, 1, 0, 0, 0, 0, 0]); // 65536
        assert_eq!(ChunkHeader::from_wire(&b), Some(h));
        assert_eq!(ChunkHeader::from_wire(&b[..119]), None);
        let w = WeightsHeader {
            run: 1,
            world_hash: 2,
            version: 3,
            len: 4,
        };
        let wb = w.to_wire();
        assert_eq!(wb[16], 3);
        assert_eq!(wb[24], 4);
        assert_eq!(WeightsHeader::from_wire(&wb), Some(w));
        assert_eq!(WeightsHeader::from_wire(&wb[..31]), None);
    }

    #[test]
    fn sections_tile_the_payload() {
        let l = ChunkLayout {
            envs: 3,
            steps: 5,
            cells: 7,
            flags: 2,
        };
        // By hand: 15*7 + 15*2 + 15*3 + 3*64 + 4*15*5 + 4*3, then the intrinsic head's
        // 4*15 + 4*15 + 4*3.
        assert_eq!(l.bytes(), 105 + 30 + 45 + 192 + 300 + 12 + 60 + 60 + 12);
        assert_eq!(l.range(Section::Flags), 105..135);
        assert_eq!(l.range(Section::EnvState), 180..372);
        assert_eq!(l.range(Section::LastValue), 672..684);
        assert_eq!(l.range(Section::ValueInt), 684..744);
        assert_eq!(l.range(Section::TruncValueInt), 744..804);
        assert_eq!(l.range(Section::LastValueInt), 804..816);
    }

    fn valid_chunk(l: &ChunkLayout) -> (ChunkHeader, Vec<u8>) {
        let h = ChunkHeader {
            envs: l.envs as u32,
            steps: l.steps as u32,
            cells: l.cells as u32,
            flags: l.flags as u32,
            actions: 5,
            len: l.bytes() as u64,
            episodes: 2,
            successes: 1,
            ..ChunkHeader::default()
        };
        (h, vec![0u8; l.bytes()])
    }

    #[test]
    fn validate_refuses_each_kind_of_bad_chunk() {
        let l = ChunkLayout {
            envs: 2,
            steps: 3,
            cells: 4,
            flags: 2,
        };
        let (h, p) = valid_chunk(&l);
        assert_eq!(l.validate(&h, 5, &p), Ok(()));
        // Shape, length, action range, done flags, numbers, statistics.
        let mut hh = h;
        hh.envs = 3;
        assert!(l.validate(&hh, 5, &p).is_err());
        assert!(l.validate(&h, 5, &p[1..]).is_err());
        assert!(l.validate(&h, 4, &p).is_err());
        let mut q = p.clone();
        q[l.range(Section::Actions).start + 5] = 5;
        assert_eq!(l.validate(&h, 5, &q), Err("action out of range"));
        let mut q = p.clone();
        q[l.range(Section::Truncated).start] = 2;
        assert_eq!(l.validate(&h, 5, &q), Err("done flag not 0 or 1"));
        for s in [Section::Logprob, Section::LastValue] {
            let mut q = p.clone();
            put_f32(&mut q[l.range(s)], 1, f32::NAN);
            assert_eq!(l.validate(&h, 5, &q), Err("a number is not finite"));
        }
        let mut hh = h;
        hh.successes = 3;
        assert!(l.validate(&hh, 5, &p).is_err());
    }

    #[test]
    fn env_record_round_trips() {
        let st = State {
            x: 3,
            y: 2,
            inventory: 5,
            ..State::default()
        };
        let r = EnvRecord {
            episode: Episode {
                state: st,
                t: 77,
                rewarded: 2,
            },
            ext_return: 1.5,
            int_return: 0.123_456_79,
            picked: true,
            paid: true,
            layout: (1 << 40) + 7,
        };
        let b = r.to_bytes();
        assert_eq!(EnvRecord::from_bytes(&b), Some(r));
        // The layout seed is the last 8 bytes, little-endian.
        assert_eq!(b[56..], [7, 0, 0, 0, 0, 1, 0, 0]);
        // A record written before families (56 bytes) reads as layout 0.
        let old = EnvRecord::from_bytes(&b[..OLD_ENV_BYTES]).unwrap();
        assert_eq!(old, EnvRecord { layout: 0, ..r });
    }
}
