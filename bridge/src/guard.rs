//! What the learner's bridge lets through from other hosts, and why.
//!
//! Authentication ([`crate::secret`]) keeps out hosts without the run's secret; a host
//! that holds it may still be broken or misbehave, so every message it sends is
//! checked before it reaches the run's processes:
//!
//! - a chunk must come under the key of a host that joined (`chunks/<name>`), carry an
//!   actor id of that host's range (`index * HOST_STRIDE + j`, `j < MAX_ACTORS`), the
//!   run's tag and world hash, and pass [`check_chunk`], the learner's own check
//!   (shape, length, and every byte a state of the world). Its length is checked before any shared memory is loaned for it, so an
//!   oversized body is a refusal, never a failed loan;
//! - a lookup must be of a kind the run's actors send: DESCRIBE (asked once by the
//!   host's bridge) and LOOKUP, or VISIT for the count bonus. QUERY (a fresh dynamic
//!   programme in the single-threaded service) and VISIT in a run that does not count
//!   visits are refused;
//! - `done` and weights flow from the learner's bridge to the hosts only. zenoh routes
//!   for a session in client mode, so a host's `done` would otherwise reach every other
//!   host; [`access_control`] makes the learner's zenoh refuse, on arrival, every
//!   message from another host but the few the run needs (chunks, the two requests,
//!   subscriptions to weights and `done`), wildcards included. Those refusals are
//!   zenoh's and are not counted by the bridge; zenoh drops them silently.
//!
//! What this does not stop: a host is known by the name it joined under, and zenoh's
//! stable API does not say which session sent a sample, so a host that holds the
//! secret can join under another host's name and send chunks for that host's actors.
//! The secret is the boundary of trust; these checks keep a broken or confused host
//! from harming the run, and confine each name to its own actor ids.
//!
//! Each refusal of the bridge's own checks is counted in `BridgeStats` and said on
//! stderr (the first few of each kind); the bridge goes on.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use fulcrum_contracts::chunk_check::check_chunk;
use fulcrum_contracts::config::RunConfig;
use fulcrum_contracts::intrinsic::Intrinsic;
use fulcrum_contracts::msg::kind;
use fulcrum_contracts::traj::{self, ChunkHeader, ChunkLayout, HOST_STRIDE, MAX_ACTORS};
use fulcrum_world::family::Family;
use fulcrum_world::{LayoutPool, World};

/// The learner's zenoh access control for run `ns` (JSON): deny by default, on both
/// flows, and allow only what the run needs. A rule allows a message when its key
/// expression includes the message's, so a wildcard put such as `fulcrum/**` matches no
/// rule and is refused.
pub fn access_control(ns: &str) -> serde_json::Value {
    let chunks = format!("fulcrum/{ns}/chunks/*");
    let lookups = format!("fulcrum/{ns}/empowerment");
    let out = [format!("fulcrum/{ns}/policy"), format!("fulcrum/{ns}/done")];
    let rule = |id: &str, messages: &[&str], flow: &str, keys: Vec<String>| {
        serde_json::json!({
            "id": id, "messages": messages, "flows": [flow],
            "permission": "allow", "key_exprs": keys,
        })
    };
    let asks = vec!["fulcrum/hello".to_string(), lookups];
    serde_json::json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": [
            rule("chunks-in", &["put"], "ingress", vec![chunks.clone()]),
            rule("chunks-wanted", &["declare_subscriber"], "egress", vec![chunks]),
            rule("asks-in", &["query"], "ingress", asks.clone()),
            rule("answers-out", &["declare_queryable", "reply"], "egress", asks),
            rule("weights-wanted", &["declare_subscriber"], "ingress", out.to_vec()),
            rule("weights-out", &["put"], "egress", out.to_vec()),
        ],
        "subjects": [{"id": "every-host"}],
        "policies": [{
            "rules": ["chunks-in", "chunks-wanted", "asks-in", "answers-out",
                      "weights-wanted", "weights-out"],
            "subjects": ["every-host"],
        }],
    })
}

/// The hosts that joined: `name -> (index, address)`.
pub type Hosts = Arc<Mutex<BTreeMap<String, (u32, String)>>>;

/// The learner's side checks of what other hosts send.
#[derive(Debug, Clone)]
pub struct Guard {
    layout: ChunkLayout,
    world: Arc<World>,
    /// On a world family: its layouts (states are checked against each chunk row's own).
    family: Option<Arc<Mutex<LayoutPool>>>,
    layouts: Option<fulcrum_world::Layouts>,
    action_mask: bool,
    run: u64,
    world_hash: u64,
    lookup_kind: u32,
    hosts: Hosts,
}

impl Guard {
    /// The checks for run namespace `ns` with `cfg` on `world` (on a family, its run
    /// world and the family); `hosts` is the live table the hello fills.
    pub fn new(
        ns: &str,
        cfg: &RunConfig,
        world: &World,
        family: Option<Family>,
        hosts: Hosts,
    ) -> Guard {
        let family = family
            .zip(cfg.layouts)
            .map(|(f, l)| Arc::new(Mutex::new(LayoutPool::new(f, l.pool_size(256)))));
        let shape = cfg.shape(world);
        Guard {
            layout: ChunkLayout {
                envs: cfg.envs_per_actor,
                steps: cfg.steps_per_chunk,
                cells: shape.cells,
                flags: shape.flags,
            },
            world: Arc::new(world.clone()),
            family,
            layouts: cfg.layouts,
            action_mask: cfg.action_mask,
            run: traj::run_tag(ns),
            world_hash: world.content_hash(),
            lookup_kind: if cfg.form() == Intrinsic::Count {
                kind::VISIT
            } else {
                kind::LOOKUP
            },
            hosts,
        }
    }

    /// The most bytes a chunk of this run has on the wire.
    pub fn chunk_wire_bytes(&self) -> usize {
        ChunkHeader::WIRE_BYTES + self.layout.bytes()
    }

    /// Check a chunk that arrived under `chunks/<name>`; the header when it may go on.
    pub fn chunk(&self, name: &str, bytes: &[u8]) -> Result<ChunkHeader, String> {
        if bytes.len() > self.chunk_wire_bytes() {
            return Err("larger than a chunk of this run".into());
        }
        let h = ChunkHeader::from_wire(bytes).ok_or("its header does not parse")?;
        let index = {
            let hosts = self.hosts.lock().unwrap_or_else(|p| p.into_inner());
            hosts.get(name).map(|(i, _)| *i)
        };
        let index = index.ok_or("from a host that has not joined")?;
        if traj::host_of(h.actor) != index || (h.actor % HOST_STRIDE) as usize >= MAX_ACTORS {
            return Err("for an actor id not given to this host".into());
        }
        if h.run != self.run || h.world_hash != self.world_hash {
            return Err("of another run or world".into());
        }
        let body = &bytes[ChunkHeader::WIRE_BYTES..];
        let mut pool = self
            .family
            .as_ref()
            .map(|p| p.lock().unwrap_or_else(|p| p.into_inner()));
        let layouts = self.layouts;
        let family = pool.as_deref_mut().zip(layouts);
        check_chunk(
            &self.world,
            family,
            &self.layout,
            self.action_mask,
            &h,
            body,
        )
        .map_err(|e| e.to_string())?;
        Ok(h)
    }

    /// Whether a lookup of `k` may be forwarded to the run's service.
    pub fn lookup(&self, k: u32) -> Result<(), &'static str> {
        if k == kind::DESCRIBE || k == self.lookup_kind {
            Ok(())
        } else if k == kind::QUERY {
            Err("QUERY is not a request actors send")
        } else if k == kind::VISIT || k == kind::LOOKUP {
            Err("a lookup kind this run's actors do not send")
        } else {
            Err("an unknown request kind")
        }
    }
}
