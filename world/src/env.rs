//! Episodes: task rewards, termination, truncation, and the learner's observation.
//!
//! Observation of a state, for a `W x H` map with `n` tools:
//! - `glyphs: [u8; W*H]`, row-major, ids: 0 rock, 1 floor, 2 goal, 3 agent, 4 tree,
//!   5 wall, 6 closed door, 7 open door, 8 boulder, 9 + k tool k lying on the floor
//!   (so `9 + n` glyph ids); destroyed objects show the floor beneath;
//! - `flags: [u8; 2n + 2]`: held tool k at `k`, then mode one-hot: normal at `n`,
//!   choosing-tool at `n + 1`, choosing-direction(k) at `n + 2 + k`.

use crate::state::{State, BOULDER_DESTROYED, MAX_OBJECTS};
use crate::world::{ObjectKind, Task, Terrain, World, DESTROYED, INTACT, OPEN};

/// Glyph id of rock.
pub const G_ROCK: u8 = 0;
/// Glyph id of floor.
pub const G_FLOOR: u8 = 1;
/// Glyph id of a goal cell.
pub const G_GOAL: u8 = 2;
/// Glyph id of the agent.
pub const G_AGENT: u8 = 3;
/// Glyph id of an intact tree.
pub const G_TREE: u8 = 4;
/// Glyph id of an intact wall block.
pub const G_WALL: u8 = 5;
/// Glyph id of a closed door.
pub const G_DOOR_CLOSED: u8 = 6;
/// Glyph id of an open door.
pub const G_DOOR_OPEN: u8 = 7;
/// Glyph id of an intact boulder.
pub const G_BOULDER: u8 = 8;
/// Glyph id of tool 0 on the floor; tool k is `G_TOOL0 + k`.
pub const G_TOOL0: u8 = 9;

/// The shapes of a world's observation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ObsSpec {
    /// Map width.
    pub width: usize,
    /// Map height.
    pub height: usize,
    /// Number of glyph ids (9 + tools).
    pub glyphs: usize,
    /// Length of the flag vector (2 * tools + 2).
    pub flags: usize,
}

impl ObsSpec {
    /// Cells of the grid.
    pub fn cells(&self) -> usize {
        self.width * self.height
    }
}

/// One step's result for the learner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    /// Task reward R.
    pub reward: f32,
    /// The task's terminal state was reached.
    pub terminated: bool,
    /// `max_steps` ran out (not terminal: bootstrap from the next state's value).
    pub truncated: bool,
}

/// An episode in progress: the state, the step count and which task objects paid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Episode {
    /// The current state.
    pub state: State,
    /// Steps taken.
    pub t: u32,
    /// Task objects already rewarded (bit per object index).
    pub rewarded: u16,
}

impl World {
    /// The observation shapes.
    pub fn obs_spec(&self) -> ObsSpec {
        ObsSpec {
            width: self.width,
            height: self.height,
            glyphs: G_TOOL0 as usize + self.tools.len(),
            flags: 2 * self.tools.len() + 2,
        }
    }

    /// Write the observation of `s` into `glyphs` (`W*H`) and `flags` (`2n + 2`).
    pub fn observe(&self, s: &State, glyphs: &mut [u8], flags: &mut [u8]) {
        let w = self.width;
        for (c, g) in glyphs.iter_mut().enumerate().take(w * self.height) {
            *g = match self.terrain[c] {
                Terrain::Rock => G_ROCK,
                Terrain::Floor => G_FLOOR,
                Terrain::Goal => G_GOAL,
            };
            match self.static_at[c] {
                0 => {}
                o => {
                    let o = o as usize - 1;
                    match (self.objects[o].kind, s.objects[o] as u8) {
                        (_, DESTROYED) => {}
                        (ObjectKind::Tree, _) => *g = G_TREE,
                        (ObjectKind::Wall, _) => *g = G_WALL,
                        (ObjectKind::Door, INTACT) => *g = G_DOOR_CLOSED,
                        (ObjectKind::Door, OPEN) => *g = G_DOOR_OPEN,
                        _ => {}
                    }
                }
            }
            match self.tool_at[c] {
                0 => {}
                t if !s.holds(t as usize - 1) => *g = G_TOOL0 + t - 1,
                _ => {}
            }
        }
        for b in self.boulder_indices() {
            let v = s.objects[b];
            if v != BOULDER_DESTROYED {
                glyphs[v as usize] = G_BOULDER;
            }
        }
        glyphs[s.y as usize * w + s.x as usize] = G_AGENT;
        self.observe_flags(s, flags);
    }

    /// The glyph id of cell `c` in `s` (agent over boulder over lying tool over object
    /// over terrain, as [`World::observe`] draws them).
    pub fn cell_glyph(&self, s: &State, c: usize) -> u8 {
        if s.y as usize * self.width + s.x as usize == c {
            return G_AGENT;
        }
        self.glyph_under_agent(s, c)
    }

    /// [`World::cell_glyph`] of a cell the agent does not stand on.
    #[inline]
    fn glyph_under_agent(&self, s: &State, c: usize) -> u8 {
        if self
            .boulders
            .iter()
            .any(|&b| s.objects[b as usize] == c as u16)
        {
            return G_BOULDER;
        }
        if let t @ 1.. = self.tool_at[c] {
            if !s.holds(t as usize - 1) {
                return G_TOOL0 + t - 1;
            }
        }
        if let o @ 1.. = self.static_at[c] {
            let o = o as usize - 1;
            match (self.objects[o].kind, s.objects[o] as u8) {
                (_, DESTROYED) => {}
                (ObjectKind::Tree, _) => return G_TREE,
                (ObjectKind::Wall, _) => return G_WALL,
                (ObjectKind::Door, INTACT) => return G_DOOR_CLOSED,
                (ObjectKind::Door, OPEN) => return G_DOOR_OPEN,
                _ => {}
            }
        }
        match self.terrain[c] {
            Terrain::Rock => G_ROCK,
            Terrain::Floor => G_FLOOR,
            Terrain::Goal => G_GOAL,
        }
    }

    /// Bring an observation of `prev` up to date for `next`, rewriting only the cells a
    /// step can change (the agent's, the boulders', changed objects' and picked-up
    /// tools' cells) and the flags that changed (held tools, the mode one-hot).
    /// `glyphs` and `flags` must hold the observation of `prev` (as from
    /// [`World::observe`] or an earlier update); they then equal [`World::observe`] of
    /// `next`, for any two states, episode resets included (tested), at a fraction of
    /// the cost: a step changes a few cells of the grid and at most a few flags.
    pub fn observe_update(&self, prev: &State, next: &State, glyphs: &mut [u8], flags: &mut [u8]) {
        let w = self.width;
        let from = prev.y as usize * w + prev.x as usize;
        let agent = next.y as usize * w + next.x as usize;
        if from != agent {
            glyphs[from] = self.glyph_under_agent(next, from);
        }
        glyphs[agent] = G_AGENT;
        if prev.objects != next.objects {
            self.update_objects(prev, next, glyphs, agent);
        }
        if prev.inventory != next.inventory {
            self.update_inventory(prev, next, glyphs, flags, agent);
        }
        if prev.mode != next.mode {
            // The mode one-hot sits at n + the mode byte (0 normal, 1 choosing-tool,
            // 2 + k choosing-direction(k)).
            let n = self.tools.len();
            flags[n + prev.mode as usize] = 0;
            flags[n + next.mode as usize] = 1;
        }
    }

    /// The cells of objects whose slot changed between `prev` and `next`.
    #[cold]
    #[inline(never)]
    fn update_objects(&self, prev: &State, next: &State, glyphs: &mut [u8], agent: usize) {
        let w = self.width;
        let mut touch = |c: usize| {
            glyphs[c] = if c == agent {
                G_AGENT
            } else {
                self.glyph_under_agent(next, c)
            }
        };
        for (i, o) in self.objects.iter().enumerate().take(MAX_OBJECTS) {
            let (a, b) = (prev.objects[i], next.objects[i]);
            if a == b {
                continue;
            }
            if o.kind == ObjectKind::Boulder {
                for v in [a, b] {
                    if v != BOULDER_DESTROYED {
                        touch(v as usize);
                    }
                }
            } else {
                touch(o.pos.1 as usize * w + o.pos.0 as usize);
            }
        }
    }

    /// The start cells and held flags of tools picked up (or dropped, across a reset).
    #[cold]
    #[inline(never)]
    fn update_inventory(
        &self,
        prev: &State,
        next: &State,
        glyphs: &mut [u8],
        flags: &mut [u8],
        agent: usize,
    ) {
        let w = self.width;
        let mut changed = prev.inventory ^ next.inventory;
        while changed != 0 {
            let k = changed.trailing_zeros() as usize;
            changed &= changed - 1;
            if let Some(t) = self.tools.get(k) {
                let c = t.pos.1 as usize * w + t.pos.0 as usize;
                glyphs[c] = if c == agent {
                    G_AGENT
                } else {
                    self.glyph_under_agent(next, c)
                };
                flags[k] = next.holds(k) as u8;
            }
        }
    }

    /// Write the flags of `s` (held tools, the mode one-hot) into `flags` (`2n + 2`).
    pub fn observe_flags(&self, s: &State, flags: &mut [u8]) {
        let n = self.tools.len();
        flags[..2 * n + 2].fill(0);
        for (k, f) in flags.iter_mut().enumerate().take(n) {
            *f = s.holds(k) as u8;
        }
        // The mode one-hot: normal at n, choosing-tool at n + 1, choosing-direction(k)
        // at n + 2 + k, i.e. at n + the mode byte.
        flags[n + s.mode as usize] = 1;
    }

    /// A fresh episode at the initial state.
    pub fn reset(&self) -> Episode {
        Episode {
            state: self.initial,
            t: 0,
            rewarded: 0,
        }
    }

    /// Take action `a` in the episode: the state moves, the task pays, the episode may
    /// end. The caller resets after `terminated || truncated`.
    #[inline]
    pub fn env_step(&self, ep: &mut Episode, a: u8) -> Outcome {
        self.step_inline(&mut ep.state, a);
        self.finish_step(ep)
    }

    /// What follows a step of an episode whose state has moved: the count, the task's
    /// pay and the episode's end.
    #[inline(always)]
    pub(crate) fn finish_step(&self, ep: &mut Episode) -> Outcome {
        ep.t += 1;
        let (reward, terminated) = self.task_reward(&ep.state, &mut ep.rewarded);
        Outcome {
            reward,
            terminated,
            truncated: !terminated && ep.t >= self.max_steps,
        }
    }

    /// The task's reward for arriving in `s`, and whether `s` is terminal. `rewarded`
    /// remembers which objects have already paid in this episode.
    #[inline]
    pub fn task_reward(&self, s: &State, rewarded: &mut u16) -> (f32, bool) {
        match &self.task {
            Task::None => (0.0, false),
            Task::Destroy(list) => {
                let mut r = 0.0;
                let mut done = true;
                for &i in list {
                    let bit = 1u16 << i;
                    if *rewarded & bit == 0 {
                        if self.cond(s, i) == DESTROYED {
                            *rewarded |= bit;
                            r += 1.0;
                        } else {
                            done = false;
                        }
                    }
                }
                (r, done)
            }
            Task::Push(b) => {
                if self.boulder_on_goal(s, *b) {
                    (1.0, true)
                } else {
                    (0.0, false)
                }
            }
        }
    }
}
