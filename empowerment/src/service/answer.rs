//! What answers a service's requests, whoever it is.

use fulcrum_contracts::msg::{Describe, EmpRequest, EmpResponse};

/// What answers a service's requests: its own [`Tables`](super::Tables), or a bridge that asks the
/// service of another host (feature `multihost`).
pub trait Answer {
    /// The DESCRIBE answer.
    fn describe(&self) -> &Describe;
    /// Answer one request into `out` (all-zero on entry). Never panics on input.
    fn answer(&mut self, req: &EmpRequest, out: &mut EmpResponse);
}
