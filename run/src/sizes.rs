//! The shared memory a run needs, checked before anything starts.
//!
//! iceoryx2 gives every publisher a data segment in `/dev/shm` big enough for every
//! sample that can be alive at once, and zeroes it when the port is made (so the whole
//! segment is real memory from the first moment): `samples x sample`, with
//!
//! ```text
//! samples = max_subscribers x (subscriber buffer + subscriber borrowed) + history + loaned
//! sample  = iceoryx2's headers + the user header + the payload, aligned
//! ```
//!
//! (`required_amount_of_samples_per_data_segment` and `chunk_layout` in iceoryx2 0.10).
//! A run has K actor publishers of chunks (`envs x steps` transitions each, [`ChunkLayout`])
//! and one publisher of the weights (every parameter as f32), configured in
//! [`fulcrum_contracts::traj`]. With empowerment, the service's server holds
//! `max_clients x 2 x in_flight x (response buffer + borrowed + loaned)` responses (a
//! run's service takes its actors and a few more, `RunConfig::service_clients`; the
//! weights' subscribers are its actors and a few more too) and
//! each actor's client `max_servers x 2 x in_flight + loaned` requests
//! (`required_amount_of_chunks_per_{server,client}_data_segment`), configured in
//! `fulcrum_empowerment::service`; the event services and the management segments add
//! a fixed amount ([`FIXED_BYTES`], measured).
//!
//! Without this check a run too big for the machine started its processes and then
//! failed in one of them with iceoryx2's error, and the suggested `--resume` could not
//! fix it. Now it is refused first, saying how much it needs and how much is free.

use std::path::Path;

use fulcrum_contracts::config::RunConfig;
use fulcrum_contracts::msg::{EmpRequest, EmpResponse, MAX_IN_FLIGHT};
use fulcrum_contracts::traj::{
    ChunkHeader, ChunkLayout, WeightsHeader, CHUNKS_LOANED, CHUNK_QUEUE, CHUNK_SUBSCRIBERS,
    WEIGHTS_BUFFER, WEIGHTS_LOANED,
};
use fulcrum_world::World;

use crate::error::bad;

/// The largest chunk one actor may publish. A chunk is copied whole into the learner's
/// batch and kept `CHUNK_SUBSCRIBERS x 2 x CHUNK_QUEUE + CHUNKS_LOANED` times over in
/// shared memory; 64 MiB (about 18 x 64 MiB = 1.1 GiB per actor) is far above any
/// useful setting (the defaults make chunks of about 100 KiB) and below what takes a
/// machine down.
pub const MAX_CHUNK_BYTES: u64 = 64 << 20;

/// What iceoryx2 puts in front of each sample besides the user header (its chunk
/// header and alignment), rounded up.
const SAMPLE_OVERHEAD: u64 = 128;

/// The shared memory of a run that does not depend on its settings: the event
/// services, the connections between ports and iceoryx2's management segments
/// (measured: about 0.1 MiB for an exp2 run of two actors, in a `/dev/shm` of its own),
/// rounded up.
pub const FIXED_BYTES: u64 = 1 << 20;

/// The empowerment service's request-response settings (`fulcrum_empowerment`'s
/// `rr_service`): servers, and iceoryx2's defaults for borrowed and loaned responses.
const SERVICE_SERVERS: u64 = 2;
const RESPONSES_BORROWED: u64 = 2;
const RESPONSES_LOANED: u64 = 2;

const MIB: f64 = (1 << 20) as f64;

/// The shared memory a run needs, by part.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SharedMemory {
    /// One actor's chunk, bytes.
    pub chunk: u64,
    /// All actors' chunk segments.
    pub chunks: u64,
    /// The weights' segment.
    pub weights: u64,
    /// The empowerment service's response segment and the actors' request segments
    /// (0 without empowerment).
    pub service: u64,
    /// Everything else ([`FIXED_BYTES`]).
    pub fixed: u64,
}

impl SharedMemory {
    /// The whole.
    pub fn total(&self) -> u64 {
        self.chunks + self.weights + self.service + self.fixed
    }
}

/// The shared memory the run `cfg` of world `w` needs (see the module doc).
pub fn shared_memory(cfg: &RunConfig, w: &World) -> SharedMemory {
    let shape = cfg.shape(w);
    let layout = ChunkLayout {
        envs: cfg.envs_per_actor,
        steps: cfg.steps_per_chunk,
        cells: shape.cells,
        flags: shape.flags,
    };
    let chunk = layout.bytes() as u64;
    let chunk_sample = chunk + std::mem::size_of::<ChunkHeader>() as u64 + SAMPLE_OVERHEAD;
    // Subscribers x (queued + borrowed, both CHUNK_QUEUE) + no history + loaned.
    let chunk_samples = (CHUNK_SUBSCRIBERS * 2 * CHUNK_QUEUE + CHUNKS_LOANED) as u64;
    // With actors on other hosts the bridge publishes their chunks too: one more
    // publisher, sized like an actor's.
    let publishers = cfg.actors as u64 + cfg.remote as u64;
    let floats: u64 = shape
        .params()
        .iter()
        .map(|(_, dims)| dims.iter().product::<usize>() as u64)
        .sum();
    let weights_sample = 4 * floats + std::mem::size_of::<WeightsHeader>() as u64 + SAMPLE_OVERHEAD;
    // Subscribers x (queued + borrowed, both WEIGHTS_BUFFER) + a history of 1 + loaned.
    let subscribers = cfg.weights_subscribers();
    let weights_samples = (subscribers * 2 * WEIGHTS_BUFFER + 1 + WEIGHTS_LOANED) as u64;
    let service = if cfg.empowerment {
        let (clients, in_flight) = (cfg.service_clients() as u64, MAX_IN_FLIGHT as u64);
        let response = std::mem::size_of::<EmpResponse>() as u64 + SAMPLE_OVERHEAD;
        // Requests carry a u128 user header (the client's id).
        let request = std::mem::size_of::<EmpRequest>() as u64 + 16 + SAMPLE_OVERHEAD;
        let responses =
            clients * 2 * in_flight * (in_flight + RESPONSES_BORROWED + RESPONSES_LOANED);
        let requests = SERVICE_SERVERS * 2 * in_flight + in_flight;
        responses * response + cfg.actors as u64 * requests * request
    } else {
        0
    };
    SharedMemory {
        chunk,
        chunks: publishers * chunk_samples * chunk_sample,
        weights: weights_samples * weights_sample,
        service,
        fixed: FIXED_BYTES,
    }
}

/// Free bytes of the file system holding `path` (for an unprivileged user).
pub fn free_bytes(path: &Path) -> Option<u64> {
    let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).ok()?;
    // SAFETY: statvfs fills the struct it is given; `c` is a valid C string.
    let mut s: libc::statvfs = unsafe { std::mem::zeroed() };
    if unsafe { libc::statvfs(c.as_ptr(), &mut s) } != 0 {
        return None;
    }
    Some(s.f_bavail as u64 * s.f_frsize as u64)
}

/// `MemAvailable` of `/proc/meminfo`, bytes.
pub fn mem_available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Refuse a run whose chunks are over [`MAX_CHUNK_BYTES`], or whose shared memory is
/// more than `/dev/shm` has free or the machine has available: one sentence saying how
/// much it needs and how much there is.
pub fn check_memory(cfg: &RunConfig, w: &World) -> crate::error::Result<()> {
    let need = shared_memory(cfg, w);
    if need.chunk > MAX_CHUNK_BYTES {
        return bad(format!(
            "a chunk of {} worlds x {} steps is {:.0} MiB of shared memory, over the limit of {:.0} MiB per chunk: use fewer worlds per actor or steps per chunk",
            cfg.envs_per_actor,
            cfg.steps_per_chunk,
            need.chunk as f64 / MIB,
            MAX_CHUNK_BYTES as f64 / MIB
        ));
    }
    let total = need.total();
    let parts = format!(
        "{:.0} MiB of shared memory ({:.0} MiB of chunks for {} actor{}, {:.0} MiB of weights, {:.0} MiB for the empowerment service, {:.0} MiB for the rest)",
        total as f64 / MIB,
        need.chunks as f64 / MIB,
        cfg.actors,
        if cfg.actors == 1 { "" } else { "s" },
        need.weights as f64 / MIB,
        need.service as f64 / MIB,
        need.fixed as f64 / MIB
    );
    if let Some(free) = free_bytes(Path::new("/dev/shm")).filter(|&f| f < total) {
        return bad(format!(
            "this run needs about {parts}, but /dev/shm has {:.0} MiB free: use fewer actors, worlds per actor, steps per chunk or hidden units, or give /dev/shm more room",
            free as f64 / MIB
        ));
    }
    if let Some(avail) = mem_available().filter(|&a| a < total) {
        return bad(format!(
            "this run needs about {parts}, but the machine has only {:.0} MiB of memory available: use fewer actors, worlds per actor, steps per chunk or hidden units",
            avail as f64 / MIB
        ));
    }
    Ok(())
}
