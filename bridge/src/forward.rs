//! An actor host's empowerment service: it answers DESCRIBE itself and forwards every
//! other request to the learner's host.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::error::{fail, Result};
use fulcrum_contracts::msg::{self, status, wire, Describe, EmpRequest, EmpResponse};
use fulcrum_contracts::stop::STOP;
use fulcrum_empowerment::service::Answer;
use fulcrum_world::World;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::Wait;

use crate::stats::BridgeStats;

/// The empowerment service of an actor host: DESCRIBE from the learner's service (asked
/// once), everything else asked of it per request.
#[derive(Debug)]
pub struct Forwarder {
    session: zenoh::Session,
    key: String,
    describe: Describe,
    stats: Arc<BridgeStats>,
    timeout: Duration,
}

impl Forwarder {
    pub fn new(
        session: &zenoh::Session,
        run: &str,
        world: &World,
        stats: Arc<BridgeStats>,
        give_up: f64,
    ) -> Result<Forwarder> {
        let mut f = Forwarder {
            session: session.clone(),
            key: format!("fulcrum/{run}/empowerment"),
            describe: Describe::empty(),
            stats,
            timeout: Duration::from_secs(2),
        };
        let mut req = EmpRequest::boxed();
        req.kind = msg::kind::DESCRIBE;
        req.world_hash = world.content_hash();
        let mut out = EmpResponse::boxed();
        let t0 = Instant::now();
        loop {
            if f.ask(&req, &mut out) && out.status == status::OK {
                break;
            }
            if STOP.load(Ordering::Relaxed) || t0.elapsed().as_secs_f64() > give_up {
                fail!("the learner's empowerment service did not answer");
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        if out.describe.world_hash != world.content_hash() {
            fail!("the learner's empowerment service serves another world");
        }
        f.describe = out.describe;
        Ok(f)
    }

    /// One round trip; false when no answer came.
    pub fn ask(&self, req: &EmpRequest, out: &mut EmpResponse) -> bool {
        let Ok(replies) = self
            .session
            .get(&self.key)
            .payload(wire::request(req))
            .priority(Priority::InteractiveHigh)
            .congestion_control(CongestionControl::Block)
            .timeout(self.timeout)
            .wait()
        else {
            return false;
        };
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                if wire::read_response(&sample.payload().to_bytes(), out).is_ok() {
                    return true;
                }
            }
        }
        false
    }
}

impl Answer for Forwarder {
    fn describe(&self) -> &Describe {
        &self.describe
    }

    fn answer(&mut self, req: &EmpRequest, out: &mut EmpResponse) {
        out.describe = self.describe;
        out.seq = req.seq;
        if req.kind == msg::kind::DESCRIBE {
            return;
        }
        if self.ask(req, out) {
            self.stats.lookups.fetch_add(1, Ordering::Relaxed);
            out.seq = req.seq;
        } else {
            self.stats.lookups_failed.fetch_add(1, Ordering::Relaxed);
            out.status = status::UNAVAILABLE;
            out.count = 0;
        }
    }
}
