//! Intrinsic reward forms: what an actor adds to the task reward r_t (times beta).
//!
//! For a transition s_t -> s_{t+1} with task reward r_t, the learner trains on
//! r_t + beta * b_t, where b_t is, by form:
//!
//! * **additive** (the paper's equation (1)): b_t = E(s_{t+1}).
//! * **potential** (potential-based shaping, Ng, Harada and Russell 1999, with the
//!   potential Phi = E): b_t = gamma * E(s_{t+1}) - E(s_t). A terminal s_{t+1} is
//!   absorbing, so its potential is 0 and b_t = -E(s_t); then the shaping terms of an
//!   episode telescope to gamma^T * 0 - E(s_0), a constant, and the optimal policies of
//!   the task are kept. A truncated s_{t+1} (the time limit) is not terminal: the episode
//!   would go on, the learner bootstraps from V(s_{t+1}), and the potential is the state's
//!   own, b_t = gamma * E(s_{t+1}) - E(s_t). Staying where E is high pays
//!   (gamma - 1) * E < 0 per step: only raising E is paid.
//! * **horizon-potential**: potential-based shaping as `potential`, with the potential
//!   Phi(s) = sum over h = 1..H of E^h(s), H the form's horizon (one horizon in every
//!   state, the larger of the two configured). For an object with two states, such as
//!   the tree, E^h(s) is 1 bit when the agent can change the object within h steps and 0
//!   otherwise, so Phi(s) = H + 1 - d(s), d(s) being the fewest steps in which the agent
//!   can change it (0 when d(s) > H): every step that brings the object one step
//!   closer to being affected raises Phi by one. The service computes Phi for every
//!   state in the same backward set propagation that gives E (every horizon at once).
//!   As with `potential`, the terms telescope and the task's optimal policies are kept.
//!   Both potential forms count a destroy task's boulders by their condition only
//!   (intact or destroyed, not their cell) unless the run says otherwise
//!   ([`crate::config::PotentialObjects`]): then Phi(s) = H + 1 - d(s) for a boulder too.
//! * **first-visit**: b_t = E(s_{t+1}) the first time in an episode that E > 0 is
//!   reached with the inventory s_{t+1} holds, 0 otherwise. Inventories only grow
//!   within an episode (tools are picked up, never dropped), so one flag per world says
//!   whether the current inventory has been paid. At most one payment per inventory
//!   state per episode: standing where E is high earns nothing more (no beacon trap).
//! * **count** (a novelty bonus over the exact state index): b_t = 1 / sqrt(N(s_{t+1})),
//!   N counting every visit by every actor of the run so far, this one included (kept by
//!   the empowerment service, which indexes every state).
//! * **none**: b_t = 0 (the baseline).

use std::fmt;
use std::str::FromStr;

/// What the shaping of horizon-potential may pay along a path at most, with the default
/// beta: beta * max Phi ([`Intrinsic::default_beta`]).
pub const HORIZON_POTENTIAL_WORTH: f64 = 0.4;

/// The form of the intrinsic reward. The default of a new run is
/// [`Intrinsic::HorizonPotential`]: potential-based shaping keeps the task's optimal
/// policies, so unlike the paper's additive bonus it cannot make standing where E is
/// high pay more than doing the task (the beacon trap). A `config.toml` without the
/// field was written when the additive bonus was the default and reads as additive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Intrinsic {
    /// No intrinsic reward.
    None,
    /// beta * E(s_{t+1}).
    Additive,
    /// beta * (gamma * E(s_{t+1}) - E(s_t)), 0 potential at terminal states.
    Potential,
    /// beta / sqrt(N(s_{t+1})).
    Count,
    /// beta * (gamma * Phi(s_{t+1}) - Phi(s_t)), Phi = sum over h = 1..H of E^h.
    #[default]
    HorizonPotential,
    /// beta * E(s_{t+1}), paid once per inventory state per episode.
    FirstVisit,
}

impl Intrinsic {
    /// Every form, in the order of the documentation.
    pub const ALL: [Intrinsic; 6] = [
        Intrinsic::None,
        Intrinsic::Additive,
        Intrinsic::Potential,
        Intrinsic::Count,
        Intrinsic::HorizonPotential,
        Intrinsic::FirstVisit,
    ];

    /// The name used on the command line and in `config.toml`.
    pub fn name(self) -> &'static str {
        match self {
            Intrinsic::None => "none",
            Intrinsic::Additive => "additive",
            Intrinsic::Potential => "potential",
            Intrinsic::Count => "count",
            Intrinsic::HorizonPotential => "horizon-potential",
            Intrinsic::FirstVisit => "first-visit",
        }
    }

    /// The default beta of the form, given the world file's (which is the paper's, for
    /// the additive bonus) and, for horizon-potential, the largest potential
    /// `max_phi` = max over the state space of Phi(s). The two forms that pay a bounded
    /// amount per episode get a beta of their own, because they sum to a few units where
    /// the additive bonus sums to a bit per step:
    ///
    /// * horizon-potential: the shaping terms of a path telescope to
    ///   beta * (Phi(end) - Phi(start)), at most beta * max Phi. The default keeps that at
    ///   [`HORIZON_POTENTIAL_WORTH`] = 0.4, well under the task's reward of 1, so that the
    ///   task stays the larger part of the return on any world: beta = 0.4 / max Phi. For
    ///   an object with two states, such as the tree, E^h is at most 1 bit and max Phi is
    ///   H (8 on the exp1 worlds: beta 0.05, each step closer paid 0.05, not lost in the
    ///   value noise); an object with many states, such as a boulder whose cells the
    ///   agent can push it to, has a larger Phi (19.5 bits on a generated world, 42.7 on
    ///   exp3) and gets a smaller beta. Without a positive potential anywhere (no E > 0
    ///   in the state space) beta is 0.05, the two-state value, and pays nothing.
    /// * first-visit: at most one payment of E (1-2 bits on the paper's worlds) per
    ///   inventory state; beta = 0.1 pays 0.1-0.2, again under the task's reward.
    pub fn default_beta(self, world_beta: f64, max_phi: f64) -> f64 {
        match self {
            Intrinsic::None => 0.0,
            Intrinsic::HorizonPotential if max_phi > 0.0 && max_phi.is_finite() => {
                HORIZON_POTENTIAL_WORTH / max_phi
            }
            Intrinsic::HorizonPotential => 0.05,
            Intrinsic::FirstVisit => 0.1,
            _ => world_beta,
        }
    }

    /// Whether the service answers Phi = sum over h of E^h instead of E.
    pub fn horizon_sum(self) -> bool {
        self == Intrinsic::HorizonPotential
    }

    /// Whether b_t needs the potential of the current state (E(s_t) or Phi(s_t)).
    pub fn is_potential(self) -> bool {
        matches!(self, Intrinsic::Potential | Intrinsic::HorizonPotential)
    }

    /// Whether the form needs E from the service (the count form needs visit counts).
    pub fn uses_empowerment(self) -> bool {
        matches!(
            self,
            Intrinsic::Additive
                | Intrinsic::Potential
                | Intrinsic::HorizonPotential
                | Intrinsic::FirstVisit
        )
    }

    /// Whether the form needs the service at all.
    pub fn uses_service(self) -> bool {
        self != Intrinsic::None
    }
}

impl fmt::Display for Intrinsic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl serde::Serialize for Intrinsic {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for Intrinsic {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        name.parse().map_err(serde::de::Error::custom)
    }
}

impl FromStr for Intrinsic {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Intrinsic::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| {
                format!(
                    "unknown intrinsic reward form '{s}' (forms: none, additive, potential, count, horizon-potential, first-visit)"
                )
            })
    }
}

/// b_t for one transition. `value_next` is E(s_{t+1}) (bits) for additive, potential
/// and first-visit, Phi(s_{t+1}) for horizon-potential, N(s_{t+1}) (>= 1) for count;
/// `value_now` is the potential of s_t (the potential forms only). First-visit's "once
/// per inventory" is kept by [`Shaping::chunk`]; here it pays E(s_{t+1}).
#[inline]
pub fn bonus(
    form: Intrinsic,
    gamma: f32,
    value_now: f32,
    value_next: f32,
    terminated: bool,
) -> f32 {
    match form {
        Intrinsic::None => 0.0,
        Intrinsic::Additive => value_next,
        Intrinsic::Potential | Intrinsic::HorizonPotential => {
            let next = if terminated { 0.0 } else { value_next };
            gamma * next - value_now
        }
        Intrinsic::Count => 1.0 / value_next.max(1.0).sqrt(),
        Intrinsic::FirstVisit => value_next,
    }
}

/// The intrinsic reward of one run: its form, gamma, and E of the initial state (the
/// potential of every world after an episode ends and the world resets).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shaping {
    /// The form.
    pub form: Intrinsic,
    /// The discount of the run's returns.
    pub gamma: f32,
    /// The potential of the initial state (potential forms only).
    pub phi_reset: f32,
    /// The initial state's inventory (first-visit).
    pub inventory_reset: u16,
}

impl Shaping {
    /// One transition of one world: b_t (before first-visit's once-per-inventory rule)
    /// from the potential `phi` of s_t and the value `next` of s_{t+1}, and `phi` carried
    /// on: `next`, or `reset` (the potential the next episode starts from) where the
    /// episode ended.
    #[inline]
    pub fn advance(
        &self,
        phi: &mut f32,
        next: f32,
        terminated: bool,
        truncated: bool,
        reset: f32,
    ) -> f32 {
        let b = bonus(self.form, self.gamma, *phi, next, terminated);
        *phi = if terminated || truncated { reset } else { next };
        b
    }

    /// b_t for a chunk laid out time-major (index t * m + e), from the service's values
    /// for each s_{t+1} (`next`), the inventory of each s_{t+1} and the
    /// termination/truncation flags.
    ///
    /// `phi[e]` holds the potential of world e's current state on entry (the first step
    /// of the chunk) and of its current state on return (potential forms); `inv[e]` and
    /// `paid[e]` the current state's inventory and whether first-visit has paid for it in
    /// this episode (first-visit). Both carry over between chunks (and checkpoints).
    #[allow(clippy::too_many_arguments)]
    pub fn chunk(
        &self,
        next: &[f32],
        next_inventory: &[u16],
        terminated: &[u8],
        truncated: &[u8],
        phi: &mut [f32],
        inv: &mut [u16],
        paid: &mut [bool],
        out: &mut [f32],
    ) {
        let (flags, state) = ((terminated, truncated), (phi, inv, paid));
        self.chunk_by(next, next_inventory, flags, state, out, |_| self.phi_reset);
    }

    /// [`Shaping::chunk`] where each world may reset to a state of its own (a family's
    /// layouts): `reset_phi[i]` is the potential of the state world e starts its next
    /// episode in when transition i ends one (read only there); `phi_reset` is unused.
    #[allow(clippy::too_many_arguments)]
    pub fn chunk_reset(
        &self,
        next: &[f32],
        next_inventory: &[u16],
        terminated: &[u8],
        truncated: &[u8],
        reset_phi: &[f32],
        phi: &mut [f32],
        inv: &mut [u16],
        paid: &mut [bool],
        out: &mut [f32],
    ) {
        let (flags, state) = ((terminated, truncated), (phi, inv, paid));
        self.chunk_by(next, next_inventory, flags, state, out, |i| reset_phi[i]);
    }

    fn chunk_by(
        &self,
        next: &[f32],
        next_inventory: &[u16],
        (terminated, truncated): (&[u8], &[u8]),
        (phi, inv, paid): (&mut [f32], &mut [u16], &mut [bool]),
        out: &mut [f32],
        phi_reset: impl Fn(usize) -> f32,
    ) {
        let m = phi.len();
        // Time-major, i = t * m + e: `e` counts round the worlds (no division per item).
        let mut e = 0;
        for (i, b) in out.iter_mut().enumerate() {
            let (term, trunc) = (terminated[i] == 1, truncated[i] == 1);
            let ended = term || trunc;
            *b = self.advance(&mut phi[e], next[i], term, trunc, phi_reset(i));
            if self.form == Intrinsic::FirstVisit {
                if next_inventory[i] != inv[e] {
                    paid[e] = false;
                }
                if paid[e] || next[i] <= 0.0 {
                    *b = 0.0;
                } else {
                    paid[e] = true;
                }
            }
            inv[e] = next_inventory[i];
            if ended {
                // The next episode starts from the initial state: nothing paid yet.
                paid[e] = false;
                inv[e] = self.inventory_reset;
            }
            e += 1;
            if e == m {
                e = 0;
            }
        }
    }
}
