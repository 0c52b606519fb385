//! What keeps the learner from hanging or spreading a divergence: the finite-weight
//! check before every publication, the deadline on local actors in synchronous mode,
//! and the notices the learner gives its supervisor while it waits.
//!
//! **Finite weights.** Every flat weights buffer is checked (one pass: any NaN or
//! infinity) before it is published; non-finite weights end the learner with
//! [`crate::error::LearnerError::Diverged`] naming the update, so no actor ever receives them and no
//! checkpoint holds them (the last checkpoint keeps the weights from before).
//!
//! **Local deadline.** In synchronous mode an update waits for one chunk per actor made
//! by the current policy. A local actor whose chunk has not come after
//! `max(floor, 10 x median of the last 16 gathers)` (floor: the run's stall timeout,
//! 10 s by default) is left out of this update and of the next ones until its next
//! chunk arrives, as a stalled remote actor is. A local actor whose chunk for the current
//! version was refused (it failed validation) is left out at once: it waits for the next
//! weights and sends no other chunk for this version. An update is never made of zero
//! chunks: when no actor delivers, the learner goes on waiting and says so (the
//! supervisor's watchdog ends such a run).
//!
//! **Fault injection (tests only).** The environment variable
//! `FULCRUM_FAULT_NONFINITE_AT_UPDATE=N` makes the learner put a NaN into its weights
//! right after update N, as a diverged update would; the check then ends the run. It
//! is read once when the learner starts and does nothing when unset.

use std::collections::{BTreeSet, VecDeque};
use std::time::Duration;

use crate::error::LearnerError;
use crate::net::Net;

/// The environment variable of the fault-injection hook (tests only).
pub const FAULT_NONFINITE_ENV: &str = "FULCRUM_FAULT_NONFINITE_AT_UPDATE";

/// Gathers the local deadline is measured from.
const RECENT: usize = 16;
/// The local deadline in multiples of the median gather time.
const FACTOR: u32 = 10;

/// What the learner tells its supervisor besides its metrics rows (a line of the
/// child protocol, [`fulcrum_contracts::lines`]).
pub use fulcrum_contracts::lines::Notice;

/// Refuses a weights buffer with any non-finite number: the weights after `update`.
pub fn ensure_finite(flat: &[f32], update: u64) -> Result<(), LearnerError> {
    // One pass, no branch per element: the sum of squares of a buffer holding a NaN or
    // an infinity is not finite (in f64 no square of a finite f32 overflows).
    let ss: f64 = flat.iter().map(|&x| f64::from(x) * f64::from(x)).sum();
    if ss.is_finite() {
        return Ok(());
    }
    let bad = flat.iter().filter(|x| !x.is_finite()).count();
    Err(LearnerError::Diverged { update, bad })
}

/// The fault-injection hook: the update after which the weights get a NaN.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Fault(Option<u64>);

impl Fault {
    /// Read [`FAULT_NONFINITE_ENV`] (unset or not a number: no fault).
    pub(crate) fn from_env() -> Fault {
        Fault(
            std::env::var(FAULT_NONFINITE_ENV)
                .ok()
                .and_then(|v| v.trim().parse().ok()),
        )
    }

    /// After update `update`: poison the weights if this is the update asked for.
    pub(crate) fn inject(&self, net: &Net, update: u64) -> Result<(), LearnerError> {
        if self.0 == Some(update) {
            let mut flat = net.flat()?;
            if let Some(x) = flat.first_mut() {
                *x = f32::NAN;
            }
            net.set_flat(&flat)?;
        }
        Ok(())
    }
}

/// The local actors the learner goes on without, and the recent gather times its
/// deadline comes from.
#[derive(Debug, Default)]
pub(crate) struct LocalStall {
    recent: VecDeque<Duration>,
    /// Local actors left out until their next chunk.
    pub(crate) stalled: BTreeSet<u32>,
}

impl LocalStall {
    /// A gather that filled its batch took `d`.
    pub(crate) fn gathered(&mut self, d: Duration) {
        if self.recent.len() == RECENT {
            self.recent.pop_front();
        }
        self.recent.push_back(d);
    }

    /// How long to wait for a local actor: `max(floor, 10 x median recent gather)`.
    pub(crate) fn deadline(&self, floor: Duration) -> Duration {
        let mut v: Vec<Duration> = self.recent.iter().copied().collect();
        v.sort();
        let median = v.get(v.len() / 2).copied().unwrap_or_default();
        floor.max(median * FACTOR)
    }

    /// A valid chunk of `actor` arrived: it is awaited again. True if it was stalled.
    pub(crate) fn back(&mut self, actor: u32) -> bool {
        self.stalled.remove(&actor)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_weights_are_refused_with_their_update() {
        assert!(ensure_finite(&[0.0, 1.5, -2.0], 3).is_ok());
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let e = ensure_finite(&[0.0, bad, 1.0, bad], 5).unwrap_err();
            assert!(matches!(e, LearnerError::Diverged { update: 5, bad: 2 }));
            assert!(e.to_string().contains("update 5"), "{e}");
        }
        // Large but finite weights are not refused.
        assert!(ensure_finite(&[3e38, -3e38], 1).is_ok());
    }

    #[test]
    fn the_local_deadline_follows_recent_gathers_above_its_floor() {
        let mut s = LocalStall::default();
        let floor = Duration::from_secs(10);
        assert_eq!(s.deadline(floor), floor);
        for _ in 0..RECENT {
            s.gathered(Duration::from_secs(3));
        }
        assert_eq!(s.deadline(floor), Duration::from_secs(30));
        // One slow gather does not move the median.
        s.gathered(Duration::from_secs(100));
        assert_eq!(s.deadline(floor), Duration::from_secs(30));
        for _ in 0..RECENT {
            s.gathered(Duration::from_millis(5));
        }
        assert_eq!(s.deadline(floor), floor);
    }
}
