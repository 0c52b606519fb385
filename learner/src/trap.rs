//! The beacon-trap detector: a run of the additive bonus that has learnt to stand
//! where E is high instead of doing the task.
//!
//! The additive bonus pays beta * E(s') on every step, so a policy that stays where
//! E > 0 for the whole episode collects up to beta * E * max_steps, while the task pays
//! its reward once. When that sum beats the discounted task reward as the learner sees
//! it, standing still is the better policy (RESULTS.md, "The trap, seen"). The
//! potential-based forms cannot trap: their terms telescope over an episode, so the
//! optimal policies of the task are kept (Ng, Harada and Russell 1999); first-visit pays
//! at most once per inventory and episode. The detector therefore watches the additive
//! form only.
//!
//! Over the trailing window of updates (the fewest last updates that span at least
//! [`WINDOW_STEPS`](crate::trap::WINDOW_STEPS) env steps; the run must have made that
//! many), the update's row is marked `trap = 1` when all of these hold:
//!
//! * no episode of the window succeeded (and at least one ended);
//! * the episodes ran to their limit: mean length >= 0.95 * max_steps;
//! * the intrinsic part dominates the return: beta * (mean intrinsic return per
//!   episode) > 0 and at least the mean task return per episode, i.e. at least half of
//!   what the episodes earned;
//! * and it is worth having: beta * (mean intrinsic return per episode) is at least
//!   [`WORTH_FRACTION`](crate::trap::WORTH_FRACTION) of the reward the whole task pays
//!   (1 per object to destroy, 1 for a push);
//! * the agent dwells where the bonus pays: E(s') > 0 on at least half of the window's
//!   steps.
//!
//! A random policy spends few of its steps where E > 0 on the paper's worlds (the
//! cells from which the tool can change the object within the horizon), so the last
//! condition separates a learnt dwelling from early exploration; the first separates it
//! from a run on its way to solving. The worth condition separates a bonus that the
//! policy collects on purpose from one it collects on the way: on exp3, where E > 0
//! over much of the map and beta is 0.00006, runs that go on to solve spend up to
//! 500k env steps without a success on E > 0 cells, but the bonus they collect is worth
//! at most 0.03 of the task; the trapped runs seen on exp1-tree and on a world written
//! later collected 0.08 to 0.09 (88 to 95 bits at beta 0.0009). Every quantity is a
//! column of `metrics.csv` or a setting of the run, so the mark is a function of the
//! rows and a resume recomputes it exactly.

use std::collections::VecDeque;

use fulcrum_contracts::intrinsic::Intrinsic;
use fulcrum_world::{Task, World};

use crate::metrics::MetricsRow;

/// The window the conditions are pooled over, env steps.
pub const WINDOW_STEPS: u64 = 100_000;
/// Episodes whose mean length is at least this fraction of `max_steps` ran to their
/// limit.
pub const LIMIT_FRACTION: f64 = 0.95;
/// The least fraction of steps with E(s') > 0.
pub const DWELL_FRACTION: f64 = 0.5;
/// The least worth of the bonus an episode collects, as a fraction of the task's reward.
pub const WORTH_FRACTION: f64 = 0.05;

/// One update's share of the window.
#[derive(Debug, Clone, Copy)]
struct Entry {
    env_steps: u64,
    steps: u64,
    episodes: f64,
    successes: f64,
    length: f64,
    ext: f64,
    int: f64,
    e_positive: f64,
}

/// The detector of one run (see the module's documentation).
#[derive(Debug, Clone)]
pub struct TrapDetector {
    watch: bool,
    beta: f64,
    max_steps: f64,
    task_reward: f64,
    window: VecDeque<Entry>,
    last_steps: u64,
}

/// What the window shows when the detector marks an update.
pub use fulcrum_contracts::lines::TrapSigns;

impl TrapDetector {
    /// The detector of a run of `world` with this form and beta (a world without a task
    /// is not watched: nothing there can succeed).
    pub fn new(form: Intrinsic, beta: f64, world: &World) -> TrapDetector {
        let task_reward = match &world.task {
            Task::None => 0.0,
            Task::Destroy(list) => list.len() as f64,
            Task::Push(_) => 1.0,
        };
        TrapDetector {
            watch: form == Intrinsic::Additive && beta > 0.0 && task_reward > 0.0,
            beta,
            max_steps: world.max_steps as f64,
            task_reward,
            window: VecDeque::new(),
            last_steps: 0,
        }
    }

    /// Whether the form is one that can trap (the detector watches it).
    pub fn watches(&self) -> bool {
        self.watch
    }

    /// Take the next update's row; `Some` when the window ending with it shows the trap.
    pub fn observe(&mut self, row: &MetricsRow) -> Option<TrapSigns> {
        let steps = row.env_steps.saturating_sub(self.last_steps);
        self.last_steps = row.env_steps;
        if !self.watch {
            return None;
        }
        let eps = row.episodes as f64;
        let nz = |x: f64| if x.is_finite() { x } else { 0.0 };
        self.window.push_back(Entry {
            env_steps: row.env_steps,
            steps,
            episodes: eps,
            successes: nz(row.success_rate) * eps,
            length: nz(row.episode_length) * eps,
            ext: nz(row.extrinsic_return) * eps,
            int: nz(row.intrinsic_return) * eps,
            e_positive: nz(row.e_positive_frac) * steps as f64,
        });
        // The window: the fewest last updates that span at least WINDOW_STEPS env steps.
        let start = |e: &Entry| e.env_steps - e.steps;
        while self
            .window
            .get(1)
            .is_some_and(|e| row.env_steps - start(e) >= WINDOW_STEPS)
        {
            self.window.pop_front();
        }
        let since = start(self.window.front()?);
        if row.env_steps - since < WINDOW_STEPS {
            return None;
        }
        let sum = |f: fn(&Entry) -> f64| self.window.iter().map(f).sum::<f64>();
        let episodes = sum(|e| e.episodes);
        let steps = sum(|e| e.steps as f64);
        if episodes < 1.0 || sum(|e| e.successes) > 0.0 {
            return None;
        }
        let length = sum(|e| e.length) / episodes;
        let int = self.beta * sum(|e| e.int) / episodes;
        let ext = sum(|e| e.ext) / episodes;
        let dwell = sum(|e| e.e_positive) / steps;
        let share = int / (int + ext.max(0.0));
        let trapped = length >= LIMIT_FRACTION * self.max_steps
            && int > 0.0
            && int >= ext
            && int >= WORTH_FRACTION * self.task_reward
            && dwell >= DWELL_FRACTION;
        trapped.then_some(TrapSigns {
            max_steps: self.max_steps as u32,
            since_step: since,
            episode_length: length,
            intrinsic_share: share,
            bonus: int,
            worth: int / self.task_reward,
            e_positive_frac: dwell,
        })
    }

    /// The sentence a run prints the first time its detector marks an update.
    pub fn warning(signs: &TrapSigns) -> String {
        let max_steps = signs.max_steps;
        format!(
            "likely beacon trap: no episode has succeeded since env step {}, episodes run to their {max_steps}-step limit (mean {:.0}), E > 0 on {:.0}% of steps, and the intrinsic bonus makes up {:.0}% of the return ({:.3} an episode, {:.0}% of the task's reward); the additive bonus pays for standing where E is high: `--intrinsic horizon-potential` (the default) cannot trap",
            signs.since_step,
            signs.episode_length,
            100.0 * signs.e_positive_frac,
            100.0 * signs.intrinsic_share,
            signs.bonus,
            100.0 * signs.worth
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// exp1-tree: a destroy task of one object, 100-step episodes.
    fn world() -> World {
        fulcrum_world::load_world("exp1-tree").unwrap()
    }

    /// An update of 1024 steps, 10 episodes: `success` of them, every one `length` long,
    /// `bits` of E an episode, E > 0 on `dwell` of the steps.
    fn row(update: u64, success: f64, length: f64, bits: f64, dwell: f64) -> MetricsRow {
        MetricsRow {
            update,
            env_steps: 1024 * update,
            episodes: 10,
            extrinsic_return: success,
            success_rate: success,
            intrinsic_return: bits,
            episode_length: length,
            e_positive_frac: dwell,
            ..MetricsRow::default()
        }
    }

    /// The updates the detector marks over `rows`.
    fn marked(d: &mut TrapDetector, rows: &[MetricsRow]) -> Vec<u64> {
        rows.iter()
            .filter_map(|r| d.observe(r).map(|_| r.update))
            .collect()
    }

    /// 200 updates of a trapped run: 88 bits an episode at beta 0.0009 (0.079 of the
    /// task), E > 0 on 89% of steps, no success, every episode at the limit.
    fn trapped() -> Vec<MetricsRow> {
        (1..=200).map(|u| row(u, 0.0, 100.0, 88.0, 0.89)).collect()
    }

    #[test]
    fn a_trapped_run_is_marked_once_its_window_is_full() {
        let mut d = TrapDetector::new(Intrinsic::Additive, 0.0009, &world());
        // 100,000 / 1024 = 97.66: the window is full at update 98 (100,352 steps).
        let m = marked(&mut d, &trapped());
        assert_eq!(m.first(), Some(&98));
        assert_eq!(m.len(), 200 - 97);
        let signs = d.observe(&row(201, 0.0, 100.0, 88.0, 0.89)).unwrap();
        // The window of update 201: updates 104..=201 (98 x 1024 = 100,352 steps).
        assert_eq!(signs.since_step, 103 * 1024);
        assert!((signs.bonus - 0.0792).abs() < 1e-12);
        assert!((signs.worth - 0.0792).abs() < 1e-12);
        assert_eq!(signs.intrinsic_share, 1.0);
        assert!((signs.e_positive_frac - 0.89).abs() < 1e-12);
        let text = TrapDetector::warning(&signs);
        assert!(text.contains("beacon trap") && text.contains("--intrinsic horizon-potential"));
    }

    #[test]
    fn one_success_in_the_window_holds_the_mark_back_for_a_window() {
        let mut d = TrapDetector::new(Intrinsic::Additive, 0.0009, &world());
        let mut rows = trapped();
        // One episode of ten succeeds at update 150: no mark until its update has left
        // the window, 98 updates later.
        rows[149] = row(150, 0.1, 100.0, 88.0, 0.89);
        let m = marked(&mut d, &rows);
        assert!(m.iter().all(|&u| !(150..248).contains(&u)), "{m:?}");
        assert_eq!(m.last(), Some(&149));
    }

    #[test]
    fn each_condition_is_needed() {
        let w = world();
        let all = |d: &mut TrapDetector, f: &dyn Fn(u64) -> MetricsRow| {
            (1..=200).filter(|&u| d.observe(&f(u)).is_some()).count()
        };
        let additive = || TrapDetector::new(Intrinsic::Additive, 0.0009, &w);
        // Dwelling on less than half of the steps (early exploration).
        assert_eq!(all(&mut additive(), &|u| row(u, 0.0, 100.0, 88.0, 0.49)), 0);
        // Episodes that end before their limit.
        assert_eq!(all(&mut additive(), &|u| row(u, 0.0, 90.0, 88.0, 0.89)), 0);
        // A bonus worth less than a twentieth of the task (exp3's slow runs: 0.021):
        // 55 bits at 0.0009 = 0.0495.
        assert_eq!(all(&mut additive(), &|u| row(u, 0.0, 100.0, 55.0, 0.89)), 0);
        assert_eq!(
            all(&mut additive(), &|u| row(u, 0.0, 100.0, 56.0, 0.89)),
            103
        );
        // A task return larger than the bonus: the bonus does not dominate (a partial
        // task, as exp2's one object of two; success stays 0).
        let partial = |u| MetricsRow {
            extrinsic_return: 0.5,
            ..row(u, 0.0, 100.0, 88.0, 0.89)
        };
        assert_eq!(all(&mut additive(), &partial), 0);
        // Forms that cannot trap are not watched, nor a world without a task.
        for form in [
            Intrinsic::HorizonPotential,
            Intrinsic::Potential,
            Intrinsic::FirstVisit,
            Intrinsic::Count,
            Intrinsic::None,
        ] {
            let mut d = TrapDetector::new(form, 0.0009, &w);
            assert!(!d.watches());
            assert_eq!(all(&mut d, &|u| row(u, 0.0, 100.0, 88.0, 0.89)), 0);
        }
        let open = fulcrum_world::parse_world(
            "name = \"open\"\nmap = \"\"\"\n#####\n#@aT#\n#####\n\"\"\"\n[tools]\na = \"axe\"\n",
            "open.toml",
        )
        .unwrap();
        assert!(!TrapDetector::new(Intrinsic::Additive, 0.0009, &open).watches());
    }

    #[test]
    fn the_task_reward_scales_the_worth() {
        // exp2 pays 2 for its two objects: 88 bits at 0.0009 is 0.0396 of it, too little;
        // 120 bits (0.054 of 2 = 0.108 / 2) is enough.
        let exp2 = fulcrum_world::load_world("exp2").unwrap();
        let count = |bits: f64| {
            let mut d = TrapDetector::new(Intrinsic::Additive, 0.0009, &exp2);
            (1..=200)
                .filter(|&u| d.observe(&row(u, 0.0, 100.0, bits, 0.89)).is_some())
                .count()
        };
        assert_eq!(count(88.0), 0);
        assert_eq!(count(120.0), 103);
    }
}
