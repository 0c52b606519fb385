//! The learner's counters, which a checkpoint carries beside the weights so that a
//! resumed run continues where it stopped.

use crate::checkpoint::Extra;
use crate::running_std::RunningStd;

/// Counters a checkpoint carries.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Counters {
    pub(crate) update: u64,
    pub(crate) env_steps: u64,
    pub(crate) episodes: u64,
    pub(crate) dropped: u64,
    pub(crate) wall_s: f64,
    /// Env steps at the first update with a pick-up (0 = none yet).
    pub(crate) first_pickup: u64,
    /// Chunks lost in transit (sequence gaps).
    pub(crate) lost: u64,
    /// The KL penalty's coefficient now (it adapts after each update).
    pub(crate) kl_coef: f32,
    /// The intrinsic rewards' running scale (intrinsic value head).
    pub(crate) int_std: RunningStd,
}

impl Counters {
    /// The counters of a checkpoint's `extra` (those it lacks are 0; the KL coefficient
    /// stays `self`'s when the checkpoint has none).
    pub(crate) fn restore(&mut self, extra: &Extra) {
        let get = |k: &str| extra.counters.get(k).copied().unwrap_or(0);
        self.update = get("update");
        self.env_steps = get("env_steps");
        self.episodes = get("episodes");
        self.dropped = get("dropped_chunks");
        self.first_pickup = get("first_pickup_step");
        self.lost = get("lost_chunks");
        self.wall_s = extra.floats.get("wall_s").copied().unwrap_or(0.0);
        if let Some(&k) = extra.floats.get("kl_coef") {
            self.kl_coef = k as f32;
        }
        let f = |k: &str| extra.floats.get(k).copied().unwrap_or(0.0);
        self.int_std = RunningStd {
            count: f("int_std_count"),
            mean: f("int_std_mean"),
            m2: f("int_std_m2"),
        };
    }

    /// Into a checkpoint's `extra`.
    pub(crate) fn store(&self, extra: &mut Extra) {
        extra.counters.insert("update".into(), self.update);
        extra.counters.insert("env_steps".into(), self.env_steps);
        extra.counters.insert("episodes".into(), self.episodes);
        extra
            .counters
            .insert("first_pickup_step".into(), self.first_pickup);
        extra.counters.insert("dropped_chunks".into(), self.dropped);
        extra.counters.insert("lost_chunks".into(), self.lost);
        extra.floats.insert("wall_s".into(), self.wall_s);
        extra.floats.insert("kl_coef".into(), self.kl_coef as f64);
        extra
            .floats
            .insert("int_std_count".into(), self.int_std.count);
        extra
            .floats
            .insert("int_std_mean".into(), self.int_std.mean);
        extra.floats.insert("int_std_m2".into(), self.int_std.m2);
    }
}
