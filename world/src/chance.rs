//! Stochastic dynamics (`docs/world.md`, "Stochastic worlds"): the exact transition
//! distribution P(s' | s, a) and sampling from it with a draw the caller supplies.
//!
//! A world leaves two things to chance, and at most one of them in any step:
//!
//! - **slip** q: in normal mode a move N/E/S/W goes the intended way with probability
//!   1 - q and each of the three other ways with q / 3; the move that happens follows
//!   the ordinary rules;
//! - **a rule's p**: at the direction prompt, the rule that would act acts with
//!   probability p and otherwise nothing changes; either way the agent is back in
//!   normal mode.
//!
//! So a step has at most four outcomes (fewer after merging equal ones: a blocked slip
//! and a blocked move both stay). Everything else is exact. In a deterministic world
//! (q = 0, every p = 1) [`World::outcomes`] is the one outcome of [`World::step`] with
//! probability 1 and the sampling functions never call for a draw.
//!
//! Sampling maps a uniform `u64` draw to x = (u >> 11) / 2^53 in [0, 1) and picks the
//! outcome whose interval holds x, in the order [`World::outcomes`] lists them before
//! merging: the intended move on [0, 1 - q), then the other three directions in
//! increasing order on intervals of q / 3; the rule acting on [0, p).

use crate::env::{Episode, Outcome};
use crate::state::{Mode, State};
use crate::world::World;

/// A uniform `u64` draw as a number in [0, 1) (its top 53 bits).
#[inline]
pub fn unit(u: u64) -> f64 {
    (u >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Add `p` to the outcome `s` in `out`, or list it.
#[inline]
fn push_merged(out: &mut Vec<(State, f64)>, s: State, p: f64) {
    match out.iter_mut().find(|(t, _)| *t == s) {
        Some((_, q)) => *q += p,
        None => out.push((s, p)),
    }
}

impl World {
    /// Whether anything is left to chance: a slip above 0 or a rule with p below 1.
    #[inline]
    pub fn is_stochastic(&self) -> bool {
        self.stochastic
    }

    /// The same map with nothing left to chance: slip 0 and every rule's p 1. Its
    /// dynamics are [`World::step`]'s (the intended outcome), and it keeps the source
    /// text, name and content hash of `self`: it is the same file read as if it were
    /// deterministic (what `--empowerment-model deterministic` computes E on). A
    /// deterministic world is returned as it is.
    pub fn without_chance(&self) -> World {
        let mut w = self.clone();
        w.slip = 0.0;
        for r in w.rules.iter_mut().chain(w.tool_rules.iter_mut().flatten()) {
            r.p = 1.0;
        }
        w.stochastic = false;
        w
    }

    /// The directions a move `a` (0..4) may go, with their probabilities: the intended
    /// one first, then the other three in increasing order.
    fn slip_dirs(&self, a: u8) -> [(u8, f64); 4] {
        let q = self.slip;
        let mut v = [(a, 1.0 - q); 4];
        let mut i = 1;
        for d in 0..4u8 {
            if d != a {
                v[i] = (d, q / 3.0);
                i += 1;
            }
        }
        v
    }

    /// P(. | s, a): every outcome of action `a` in `s` with its probability, equal
    /// outcomes merged, probabilities summing to 1 (`out` is cleared first). One
    /// outcome with probability 1 where nothing is left to chance.
    pub fn outcomes(&self, s: &State, a: u8, out: &mut Vec<(State, f64)>) {
        out.clear();
        if self.stochastic {
            match s.mode {
                0 if a < 4 && self.slip > 0.0 => {
                    for (d, p) in self.slip_dirs(a) {
                        let mut t = *s;
                        self.walk(&mut t, d);
                        push_merged(out, t, p);
                    }
                    return;
                }
                m if m >= 2 && a < 4 => {
                    let mut t = *s;
                    t.set_mode(Mode::Normal);
                    let before = t;
                    let p = self.use_tool(&mut t, (m - 2) as usize, a);
                    push_merged(out, t, p);
                    if p < 1.0 {
                        push_merged(out, before, 1.0 - p);
                    }
                    return;
                }
                _ => {}
            }
        }
        out.push((self.step(s, a), 1.0));
    }

    /// One outcome of action `a` in `s`, drawn with the uniform `u` (see the module
    /// doc for how `u` picks it). Equals [`World::step`] in a deterministic world,
    /// whatever `u`.
    pub fn step_sampled(&self, s: &State, a: u8, u: u64) -> State {
        let mut n = *s;
        self.step_sampled_in_place(&mut n, a, u);
        n
    }

    /// [`World::step_sampled`] in place.
    pub fn step_sampled_in_place(&self, n: &mut State, a: u8, u: u64) {
        if !self.stochastic {
            self.step_inline(n, a);
            return;
        }
        let x = unit(u);
        match n.mode {
            0 if a < 4 && self.slip > 0.0 => {
                let q = self.slip;
                let d = if x < 1.0 - q {
                    a
                } else {
                    let j = (((x - (1.0 - q)) / (q / 3.0)) as usize).min(2);
                    self.slip_dirs(a)[1 + j].0
                };
                self.walk(n, d);
            }
            m if m >= 2 && a < 4 => {
                n.set_mode(Mode::Normal);
                let before = *n;
                let p = self.use_tool(n, (m - 2) as usize, a);
                if x >= p {
                    *n = before;
                }
            }
            _ => self.step_inline(n, a),
        }
    }

    /// [`World::env_step`] with chance: in a stochastic world the step's outcome is
    /// drawn with one call of `draw` (a uniform `u64` from the caller's generator); in
    /// a deterministic world `draw` is never called and the step is exactly
    /// [`World::env_step`], so runs on deterministic worlds consume no draws.
    #[inline]
    pub fn env_step_drawn(&self, ep: &mut Episode, a: u8, draw: impl FnOnce() -> u64) -> Outcome {
        if !self.stochastic {
            return self.env_step(ep, a);
        }
        self.step_sampled_in_place(&mut ep.state, a, draw());
        self.finish_step(ep)
    }
}
