//! What answers a service's requests, whoever it is.

use fulcrum_contracts::msg::{kind, status, Describe, EmpRequest, EmpResponse, MAX_BATCH};

/// What answers a service's requests: its own [`Tables`](super::Tables), or a bridge that asks the
/// service of another host (feature `multihost`).
pub trait Answer {
    /// The DESCRIBE answer.
    fn describe(&self) -> &Describe;
    /// Answer one request into `out` (all-zero on entry). Never panics on input.
    fn answer(&mut self, req: &EmpRequest, out: &mut EmpResponse);
    /// Whether [`Answer::prepare`] does anything: the serving loop then gathers every
    /// waiting request before it answers the first.
    fn prepares(&self) -> bool {
        false
    }
    /// Get ready to answer `reqs`, the requests waiting now, which are then answered one
    /// by one in their order (a family's service makes their new layouts' tables at
    /// once). Never panics on input; the answers are the same with or without it.
    fn prepare(&mut self, _reqs: &[&EmpRequest]) {}
}

/// What every answer starts with: the request's sequence number and `describe` copied
/// into `out`; false (with `out.status` set) for a request of another world (DESCRIBE
/// excepted) or with more than [`MAX_BATCH`] states.
pub(super) fn admit(describe: &Describe, req: &EmpRequest, out: &mut EmpResponse) -> bool {
    out.seq = req.seq;
    out.describe = *describe;
    if req.kind != kind::DESCRIBE && req.world_hash != describe.world_hash {
        out.status = status::WRONG_WORLD;
        return false;
    }
    if req.count as usize > MAX_BATCH {
        out.status = status::BAD_COUNT;
        return false;
    }
    true
}
