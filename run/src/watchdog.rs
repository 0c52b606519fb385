//! The supervisor's watchdog: a run that makes no update for too long is ended (exit
//! 1) with a sentence saying who stalled, instead of hanging silently.
//!
//! The limit is `max(floor, N x median of the last 32 update intervals)` with
//! [`FACTOR`] `N = 20`: an update 20 times slower than the recent ones is not a slow
//! update but a stall, and the floor (300 s by default, a setting) covers the first
//! update, whose interval includes the actors' start, and runs whose updates are
//! uneven. The clock is held while the empowerment service restarts (actors wait for
//! it by design; the service's own start limit bounds that wait).
//!
//! Who stalled comes from the learner's notices ([`fulcrum_learner::watch::Notice`]),
//! which it prints on its stdout as lines of the child protocol
//! ([`fulcrum_contracts::lines::ChildLine`]): `waiting SECS ACTORS` once a second while it
//! waits for chunks, `stalled ACTOR SECS late|refused` when it goes on without a local
//! actor. A learner that says nothing for several seconds is itself the one that
//! stalled. (`trap LIMIT SINCE LENGTH SHARE BONUS WORTH DWELL` is no stall: the beacon-trap detector's
//! first mark, which the supervisor prints as a warning.)

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// The watchdog's limit in multiples of the median recent update interval.
pub const FACTOR: u32 = 20;
/// The default floor of the limit, seconds.
pub const DEFAULT_FLOOR_S: f64 = 300.0;
/// Update intervals the limit is measured from.
const RECENT: usize = 32;
/// A `waiting` line older than this is no news: the learner itself went quiet.
const QUIET: Duration = Duration::from_secs(3);

/// Watches the time since the last update.
#[derive(Debug)]
pub struct Watchdog {
    floor: Duration,
    last: Instant,
    recent: VecDeque<Duration>,
    /// The learner's last `waiting` notice: when, and the actors it named.
    waiting: Option<(Instant, Vec<u32>)>,
    /// Held since (the service restarts).
    held: Option<Instant>,
}

impl Watchdog {
    /// A watchdog with the limit's `floor`, its clock starting now.
    pub fn new(floor: Duration) -> Watchdog {
        Watchdog {
            floor,
            last: Instant::now(),
            recent: VecDeque::new(),
            waiting: None,
            held: None,
        }
    }

    /// An update was made.
    pub fn updated(&mut self) {
        let now = Instant::now();
        if self.held.is_none() {
            if self.recent.len() == RECENT {
                self.recent.pop_front();
            }
            self.recent.push_back(now - self.last);
        }
        self.last = now;
        self.waiting = None;
    }

    /// The learner says it waits for `actors`.
    pub fn waiting(&mut self, actors: Vec<u32>) {
        self.waiting = Some((Instant::now(), actors));
    }

    /// Hold the clock (the service is restarting).
    pub fn hold(&mut self) {
        self.held.get_or_insert_with(Instant::now);
    }

    /// Start the clock again, from now.
    pub fn release(&mut self) {
        if self.held.take().is_some() {
            self.last = Instant::now();
        }
    }

    /// The time without an update after which the run is ended.
    pub fn limit(&self) -> Duration {
        let mut v: Vec<Duration> = self.recent.iter().copied().collect();
        v.sort();
        let median = v.get(v.len() / 2).copied().unwrap_or_default();
        self.floor.max(median * FACTOR)
    }

    /// The sentence that ends the run, once no update came within the limit.
    pub fn check(&self) -> Option<String> {
        if self.held.is_some() {
            return None;
        }
        let quiet = self.last.elapsed();
        let limit = self.limit();
        if quiet < limit {
            return None;
        }
        let who = match &self.waiting {
            Some((at, actors)) if at.elapsed() < QUIET && !actors.is_empty() => {
                let names: Vec<String> = actors.iter().map(|a| format!("actor {a}")).collect();
                format!(
                    "the learner is waiting for {} (no chunk from {} for this update)",
                    names.join(", "),
                    if actors.len() == 1 { "it" } else { "them" }
                )
            }
            Some((at, _)) if at.elapsed() < QUIET => {
                "the learner is waiting for chunks from any actor".to_string()
            }
            _ => "the learner itself stalled (it has said nothing for several seconds)".into(),
        };
        Some(format!(
            "no update for {:.0} s (the limit is {FACTOR} times the recent update time, at least {:.0} s): {who}",
            quiet.as_secs_f64(),
            self.floor.as_secs_f64()
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fulcrum_learner::trap::TrapSigns;
    use fulcrum_learner::watch::Notice;

    #[test]
    fn notices_survive_their_line() {
        use fulcrum_contracts::lines::ChildLine;
        for n in [
            Notice::Waiting {
                waited_s: 2.5,
                actors: vec![0, 3, 1025],
            },
            Notice::Waiting {
                waited_s: 1.0,
                actors: vec![],
            },
            Notice::Stalled {
                actor: 1,
                waited_s: 10.0,
                refused: false,
            },
            Notice::Trap(TrapSigns {
                max_steps: 100,
                since_step: 12288,
                episode_length: 100.0,
                intrinsic_share: 1.0,
                bonus: 0.0792,
                worth: 0.0792,
                e_positive_frac: 0.890625,
            }),
            Notice::Stalled {
                actor: 2,
                waited_s: 0.0,
                refused: true,
            },
        ] {
            let line = ChildLine::Notice(n.clone()).to_string();
            assert_eq!(ChildLine::parse(&line), Some(ChildLine::Notice(n)));
        }
    }

    #[test]
    fn the_limit_is_twenty_recent_updates_above_the_floor() {
        let mut w = Watchdog::new(Duration::from_millis(100));
        assert_eq!(w.limit(), Duration::from_millis(100));
        w.recent.extend([Duration::from_millis(20); 5]);
        assert_eq!(w.limit(), Duration::from_millis(400));
        assert!(w.check().is_none());
        w.last = Instant::now() - Duration::from_millis(500);
        w.waiting(vec![1]);
        let m = w.check().expect("past the limit");
        assert!(m.contains("waiting for actor 1 "), "{m}");
        w.hold();
        assert!(w.check().is_none(), "held while the service restarts");
        w.release();
        assert!(w.check().is_none(), "the clock starts again");
        w.last = Instant::now() - Duration::from_millis(500);
        w.waiting = None;
        assert!(w.check().unwrap().contains("the learner itself stalled"));
    }
}
