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
//! * **count** (a novelty bonus over the exact state index): b_t = 1 / sqrt(N(s_{t+1})),
//!   N counting every visit by every actor of the run so far, this one included (kept by
//!   the empowerment service, which indexes every state).
//! * **none**: b_t = 0 (the baseline).

use std::fmt;
use std::str::FromStr;

/// The form of the intrinsic reward.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Intrinsic {
    /// No intrinsic reward.
    None,
    /// beta * E(s_{t+1}).
    #[default]
    Additive,
    /// beta * (gamma * E(s_{t+1}) - E(s_t)), 0 potential at terminal states.
    Potential,
    /// beta / sqrt(N(s_{t+1})).
    Count,
}

impl Intrinsic {
    /// Every form, in the order of the documentation.
    pub const ALL: [Intrinsic; 4] = [
        Intrinsic::None,
        Intrinsic::Additive,
        Intrinsic::Potential,
        Intrinsic::Count,
    ];

    /// The name used on the command line and in `config.toml`.
    pub fn name(self) -> &'static str {
        match self {
            Intrinsic::None => "none",
            Intrinsic::Additive => "additive",
            Intrinsic::Potential => "potential",
            Intrinsic::Count => "count",
        }
    }

    /// Whether the form needs E from the service (the count form needs visit counts).
    pub fn uses_empowerment(self) -> bool {
        matches!(self, Intrinsic::Additive | Intrinsic::Potential)
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

impl FromStr for Intrinsic {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Intrinsic::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| {
                format!(
                    "unknown intrinsic reward form '{s}' (forms: none, additive, potential, count)"
                )
            })
    }
}

/// b_t for one transition. `value_next` is E(s_{t+1}) (bits) for additive and
/// potential, N(s_{t+1}) (>= 1) for count; `value_now` is E(s_t) (potential only).
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
        Intrinsic::Potential => {
            let next = if terminated { 0.0 } else { value_next };
            gamma * next - value_now
        }
        Intrinsic::Count => 1.0 / value_next.max(1.0).sqrt(),
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
    /// E of the initial state (potential only).
    pub phi_reset: f32,
}

impl Shaping {
    /// b_t for a chunk laid out time-major (index t * m + e), from the service's values
    /// for each s_{t+1} (`next`) and the termination/truncation flags.
    ///
    /// `phi[e]` holds E(s_t) of world e's current state on entry (the first step of the
    /// chunk) and of its current state on return.
    pub fn chunk(
        &self,
        next: &[f32],
        terminated: &[u8],
        truncated: &[u8],
        phi: &mut [f32],
        out: &mut [f32],
    ) {
        let m = phi.len();
        for (i, b) in out.iter_mut().enumerate() {
            let e = i % m;
            let ended = terminated[i] == 1 || truncated[i] == 1;
            *b = bonus(self.form, self.gamma, phi[e], next[i], terminated[i] == 1);
            phi[e] = if ended { self.phi_reset } else { next[i] };
        }
    }
}
