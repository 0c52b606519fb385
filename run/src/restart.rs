//! The supervisor's restart policy: each child that may be restarted (each actor slot,
//! the empowerment service, the bridge) has a budget of its own, `R` restarts in any
//! `T` seconds, and waits an exponential back-off before each restart.
//!
//! Defaults: `R = 5` in `T = 60 s`. A child that crashes at once on every start (a
//! broken build, a world it cannot load, memory it cannot get) uses its budget in
//! about 0.1 + 0.2 + 0.4 + 0.8 + 1.6 s plus its start times, so the run ends within
//! seconds with a sentence naming it; a child killed now and then (the OOM killer, an
//! operator) gets a new budget once its stops are a window apart, so a long run is
//! never ended by rare, unrelated crashes. The budget of one child never pays for
//! another's: a crashing actor slot cannot use up the service's restarts.
//!
//! Back-off: the n-th stop within the window waits `min(100 ms x 2^(n-1), 10 s)`
//! before the restart, so a crash loop does not spin the machine; the first restart
//! after a calm window is quick again.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// The first back-off.
pub const BACKOFF_START: Duration = Duration::from_millis(100);
/// The longest back-off.
pub const BACKOFF_CAP: Duration = Duration::from_secs(10);
/// Restarts each child may have within the window, by default.
pub const DEFAULT_MAX_RESTARTS: u32 = 5;
/// The window of the budget by default, seconds.
pub const DEFAULT_WINDOW_S: f64 = 60.0;

/// `max` restarts per child within any `window`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RestartPolicy {
    /// Restarts allowed within the window.
    pub max: u32,
    /// The window.
    pub window: Duration,
}

impl Default for RestartPolicy {
    fn default() -> Self {
        RestartPolicy {
            max: DEFAULT_MAX_RESTARTS,
            window: Duration::from_secs_f64(DEFAULT_WINDOW_S),
        }
    }
}

/// A restart the policy allows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Allowed {
    /// This restart's number within the window (1 for the first).
    pub n: u32,
    /// The back-off before it.
    pub delay: Duration,
}

/// A restart the policy refuses: the child stopped `n` times within the window.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OverBudget {
    /// Stops within the window, this one included.
    pub n: u32,
}

/// One child's stops within the window.
#[derive(Debug, Default, Clone)]
pub struct Budget {
    stops: VecDeque<Instant>,
}

impl Budget {
    /// The child stopped at `now`: its restart and back-off, or over budget.
    pub fn stopped(&mut self, policy: &RestartPolicy, now: Instant) -> Result<Allowed, OverBudget> {
        while self
            .stops
            .front()
            .is_some_and(|&t| now.duration_since(t) > policy.window)
        {
            self.stops.pop_front();
        }
        self.stops.push_back(now);
        let n = self.stops.len() as u32;
        if n > policy.max {
            return Err(OverBudget { n });
        }
        Ok(Allowed {
            n,
            delay: backoff(n),
        })
    }
}

/// The back-off before the `n`-th restart within the window.
pub fn backoff(n: u32) -> Duration {
    let doublings = n.saturating_sub(1).min(16);
    (BACKOFF_START * (1u32 << doublings)).min(BACKOFF_CAP)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_back_off_doubles_from_100_ms_to_its_cap() {
        let ms: Vec<u128> = (1..=9).map(|n| backoff(n).as_millis()).collect();
        assert_eq!(ms, [100, 200, 400, 800, 1600, 3200, 6400, 10000, 10000]);
        assert_eq!(backoff(1000), BACKOFF_CAP);
    }

    #[test]
    fn a_budget_counts_stops_within_its_window_only() {
        let p = RestartPolicy {
            max: 2,
            window: Duration::from_secs(10),
        };
        let t0 = Instant::now();
        let s = |x: u64| t0 + Duration::from_secs(x);
        let mut b = Budget::default();
        assert_eq!(b.stopped(&p, s(0)).unwrap().n, 1);
        assert_eq!(b.stopped(&p, s(1)).unwrap().n, 2);
        assert_eq!(b.stopped(&p, s(2)), Err(OverBudget { n: 3 }));
        // Spread out: every stop more than a window after the one before.
        let mut b = Budget::default();
        for k in 0..10 {
            let a = b.stopped(&p, s(11 * k)).unwrap();
            assert_eq!(a.n, 1);
            assert_eq!(a.delay, BACKOFF_START);
        }
    }

    #[test]
    fn actors_wait_for_the_service_longer_than_it_may_take_to_restart() {
        use fulcrum_actors::{SERVICE_START_LIMIT, SERVICE_WAIT};
        assert!(SERVICE_WAIT >= SERVICE_START_LIMIT + BACKOFF_CAP);
    }
}
