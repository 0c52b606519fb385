//! Datasets of exact empowerment, for training and scoring learned estimators.
//!
//! One row per chosen state s (every state of the space, or N drawn without
//! replacement):
//!
//! ```text
//! glyphs[r]  (H_v, W_v) u8   the observation's grid in the chosen view (what a policy sees)
//! flags[r]   (F,)       u8   its flag vector (inventory, selected tool, mode)
//! state[r]   (38,)      u8   the packed state
//! normal[r]  bool            mode(s) == normal
//! E[r]       f64             E^h_{j,D}(s) in bits, exact (a channel capacity in a
//!                            stochastic world, then within gap[r] bits below the truth)
//! horizon[r] u32             h: the one asked for, else the world's by whether j is held
//! ```
//!
//! and K sampled action sequences per row, drawn uniformly from `(A_j)^h` with the row's
//! horizon, each with where it ends:
//!
//! ```text
//! seq_row[k]          u32        the row it starts from
//! seq_actions[k]      (h_max,) u8  world action indices; 255 after the row's horizon
//! seq_final_state[k]  (38,)    u8  s_h, the state after the sequence (in a stochastic
//!                                  world one outcome, drawn with the dataset's seed)
//! seq_proj[k]         u32        proj_D(s_h) as a dense id
//! proj_key[p]         (k_D,) u16 what projection p is: the agent's (x, y) when D is the
//!                                  agent, else the packed slot of each object of D
//!                                  (a `conditions:` set: a boulder's slot is 0 intact,
//!                                  1 destroyed)
//! ```
//!
//! With these an estimator can be trained and scored without stepping the world: in a
//! deterministic world `E(s) = log2 |{ seq_proj[k] }|` over all `(A_j)^h` sequences, of
//! which the dataset holds a uniform sample. Every draw comes from one ChaCha8 stream
//! per purpose and row, so a dataset is a pure function of its request, whatever the
//! number of threads.

use fulcrum_world::hash::FastMap;
use fulcrum_world::{Mode, ObjectSet, State, View, World};
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::engine::{Engine, Method, ToolSel};
use crate::error::EngineError;
use crate::propagate::project_key;

/// The padding of `seq_actions` after a row's horizon.
pub const NO_ACTION: u8 = 255;

/// Which states a dataset holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rows {
    /// Every state of the space, in state-id order.
    All,
    /// N distinct states drawn uniformly, in state-id order.
    Sample(usize),
}

impl std::str::FromStr for Rows {
    type Err = String;
    fn from_str(s: &str) -> Result<Rows, String> {
        if s == "all" {
            return Ok(Rows::All);
        }
        let bad = || format!("'{s}' is not a choice of states: all or sample:N (N >= 1)");
        let n: usize = s
            .strip_prefix("sample:")
            .ok_or_else(bad)?
            .parse()
            .map_err(|_| bad())?;
        if n == 0 {
            return Err(bad());
        }
        Ok(Rows::Sample(n))
    }
}

impl std::fmt::Display for Rows {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Rows::All => write!(f, "all"),
            Rows::Sample(n) => write!(f, "sample:{n}"),
        }
    }
}

/// What a dataset is made of.
#[derive(Clone, Debug)]
pub struct Spec {
    /// Whose actions drive the channel.
    pub tool: ToolSel,
    /// The objects D.
    pub set: ObjectSet,
    /// One horizon for every row, else the world's by whether the tool is held.
    pub horizon: Option<u32>,
    /// Which states.
    pub rows: Rows,
    /// Seed of every draw.
    pub seed: u64,
    /// The observation's view.
    pub view: View,
    /// Action sequences sampled per row.
    pub sequences: usize,
}

/// A dataset: row arrays, then sequence arrays (shapes in the module doc), row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Dataset {
    /// The observation's grid height and width in the view.
    pub grid: (usize, usize),
    /// Length of the flag vector.
    pub flag_len: usize,
    /// State id of each row in the engine's space.
    pub ids: Vec<u32>,
    /// `(rows, H_v, W_v)`.
    pub glyphs: Vec<u8>,
    /// `(rows, F)`.
    pub flags: Vec<u8>,
    /// `(rows, 38)`.
    pub state: Vec<u8>,
    /// Mode normal.
    pub normal: Vec<bool>,
    /// Exact E in bits.
    pub e: Vec<f64>,
    /// The capacity's gap in bits (0 in a deterministic world).
    pub gap: Vec<f64>,
    /// The horizon of each row.
    pub horizon: Vec<u32>,
    /// The longest horizon: the width of `seq_actions`.
    pub h_max: usize,
    /// Row of each sequence.
    pub seq_row: Vec<u32>,
    /// `(sequences, h_max)`, padded with [`NO_ACTION`].
    pub seq_actions: Vec<u8>,
    /// `(sequences, 38)`.
    pub seq_final_state: Vec<u8>,
    /// Dense projection id of each sequence's final state.
    pub seq_proj: Vec<u32>,
    /// Width of a projection key: 2 for the agent, else |D|.
    pub key_len: usize,
    /// `(projections, key_len)`.
    pub proj_key: Vec<u16>,
    /// The tool's actions (world action indices), in the order of `A_j`.
    pub tool_actions: Vec<u8>,
}

impl Dataset {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// Whether it has no rows.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }
}

/// The horizon of a row: the one given, else the world's by whether the tool is held.
pub fn row_horizon(w: &World, given: Option<u32>, tool: ToolSel, s: &State) -> u32 {
    given.unwrap_or(if tool.held(s) {
        w.empowerment.horizon_equipped
    } else {
        w.empowerment.horizon_unequipped
    })
}

/// A ChaCha8 stream for one purpose and one row of a seed.
fn stream(seed: u64, purpose: u64, row: u64) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::seed_from_u64(seed ^ purpose.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    r.set_stream(row);
    r
}

/// The state ids of a dataset, ascending.
pub fn choose_rows(space_len: usize, rows: Rows, seed: u64) -> Result<Vec<u32>, EngineError> {
    match rows {
        Rows::All => Ok((0..space_len as u32).collect()),
        Rows::Sample(n) if n > space_len => Err(EngineError::Request(format!(
            "--states sample:{n} asks for more states than the space has ({space_len})"
        ))),
        Rows::Sample(n) => {
            // A partial Fisher-Yates shuffle: the first n of a uniform permutation.
            let mut ids: Vec<u32> = (0..space_len as u32).collect();
            let mut rng = stream(seed, 1, 0);
            for i in 0..n {
                let j = rng.random_range(i..space_len);
                ids.swap(i, j);
            }
            ids.truncate(n);
            ids.sort_unstable();
            Ok(ids)
        }
    }
}

/// Build the dataset of `spec` over the engine's space.
pub fn build(e: &Engine<'_>, spec: &Spec, method: Method) -> Result<Dataset, EngineError> {
    let w = e.world;
    if let Some(h) = spec.horizon.filter(|&h| h > fulcrum_world::MAX_HORIZON) {
        return Err(EngineError::HorizonTooLarge {
            h,
            max: fulcrum_world::MAX_HORIZON,
        });
    }
    let ids = choose_rows(e.space.len(), spec.rows, spec.seed)?;
    let states: Vec<State> = ids.iter().map(|&i| *e.space.state(i)).collect();
    let horizon: Vec<u32> = states
        .iter()
        .map(|s| row_horizon(w, spec.horizon, spec.tool, s))
        .collect();

    // E and its gap, one computation per distinct horizon.
    let mut e_bits = vec![0.0; ids.len()];
    let mut gap = vec![0.0; ids.len()];
    let mut hs = horizon.clone();
    hs.sort_unstable();
    hs.dedup();
    for &h in &hs {
        let rows: Vec<usize> = (0..ids.len()).filter(|&r| horizon[r] == h).collect();
        let at: Vec<u32> = rows.iter().map(|&r| ids[r]).collect();
        let caps = e.values_at(spec.tool, &spec.set, h, &at, method)?;
        for (&r, c) in rows.iter().zip(caps) {
            e_bits[r] = c.bits;
            gap[r] = c.gap;
        }
    }

    // Observations.
    let obs = spec.view.spec(w);
    let (cells, flag_len) = (obs.cells(), obs.flags);
    let mut glyphs = vec![0u8; ids.len() * cells];
    let mut flags = vec![0u8; ids.len() * flag_len];
    glyphs
        .par_chunks_mut(cells.max(1))
        .zip(flags.par_chunks_mut(flag_len.max(1)))
        .zip(&states)
        .for_each(|((g, f), s)| spec.view.observe(w, s, g, f));
    let state: Vec<u8> = states.iter().flat_map(|s| s.to_bytes()).collect();
    let normal: Vec<bool> = states.iter().map(|s| s.mode() == Mode::Normal).collect();

    // Sampled sequences: uniform over (A_j)^h, each ending in one outcome.
    let acts = spec.tool.actions(w);
    let h_max = horizon.iter().copied().max().unwrap_or(0) as usize;
    let k = spec.sequences;
    let per_row: Vec<Vec<(Vec<u8>, State)>> = states
        .par_iter()
        .zip(&ids)
        .zip(&horizon)
        .map(|((s, &id), &h)| {
            let mut rng = stream(spec.seed, 2, id as u64);
            (0..k)
                .map(|_| {
                    let mut seq = vec![NO_ACTION; h_max];
                    let mut t = *s;
                    for slot in seq.iter_mut().take(h as usize) {
                        let a = acts[rng.random_range(0..acts.len())];
                        *slot = a;
                        t = w.step_sampled(&t, a, rng.next_u64());
                    }
                    (seq, t)
                })
                .collect()
        })
        .collect();
    let mut keys: FastMap<[u16; 16], u32> = FastMap::default();
    let key_len = match &spec.set {
        ObjectSet::Agent => 2,
        set => set.indices().len(),
    };
    let mut proj_key = Vec::new();
    let (mut seq_row, mut seq_actions, mut seq_final_state, mut seq_proj) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (r, seqs) in per_row.into_iter().enumerate() {
        for (seq, t) in seqs {
            let key = project_key(&spec.set, &t);
            let n = keys.len() as u32;
            let p = *keys.entry(key).or_insert_with(|| {
                match &spec.set {
                    ObjectSet::Agent => proj_key.extend_from_slice(&key[..2]),
                    set => proj_key.extend(set.indices().iter().map(|&i| key[i])),
                }
                n
            });
            seq_row.push(r as u32);
            seq_actions.extend_from_slice(&seq);
            seq_final_state.extend_from_slice(&t.to_bytes());
            seq_proj.push(p);
        }
    }
    Ok(Dataset {
        grid: (obs.height, obs.width),
        flag_len,
        ids,
        glyphs,
        flags,
        state,
        normal,
        e: e_bits,
        gap,
        horizon,
        h_max,
        seq_row,
        seq_actions,
        seq_final_state,
        seq_proj,
        key_len,
        proj_key,
        tool_actions: acts,
    })
}

impl Dataset {
    /// The dataset as named arrays (the `.npz` layout of the module doc), with what was
    /// asked: `world`, `tool`, `objects`, `view` (strings), `seed`, and `actions` (the
    /// world's action names, indexed as in `seq_actions`).
    pub fn into_arrays(self, w: &World, spec: &Spec) -> Vec<crate::npz::Array> {
        use crate::npz::{Array, Data};
        let (n, m) = (self.len(), self.seq_row.len());
        let (gh, gw) = self.grid;
        let objects = crate::engine::set_objects(w, &spec.set);
        let actions: Vec<String> = (0..w.num_actions() as u8)
            .map(|a| w.action_name(a))
            .collect();
        let p = self.proj_key.len() / self.key_len.max(1);
        vec![
            Array::new("glyphs", &[n, gh, gw], Data::U8(self.glyphs)),
            Array::new("flags", &[n, self.flag_len], Data::U8(self.flags)),
            Array::new("state", &[n, 38], Data::U8(self.state)),
            Array::new("normal", &[n], Data::Bool(self.normal)),
            Array::new("E", &[n], Data::F64(self.e)),
            Array::new("gap", &[n], Data::F64(self.gap)),
            Array::new("horizon", &[n], Data::U32(self.horizon)),
            Array::new("state_id", &[n], Data::U32(self.ids)),
            Array::new("seq_row", &[m], Data::U32(self.seq_row)),
            Array::new("seq_actions", &[m, self.h_max], Data::U8(self.seq_actions)),
            Array::new("seq_final_state", &[m, 38], Data::U8(self.seq_final_state)),
            Array::new("seq_proj", &[m], Data::U32(self.seq_proj)),
            Array::new("proj_key", &[p, self.key_len], Data::U16(self.proj_key)),
            Array::new(
                "tool_actions",
                &[self.tool_actions.len()],
                Data::U8(self.tool_actions),
            ),
            Array::new("world", &[], Data::Str(vec![w.name.clone()])),
            Array::new("tool", &[], Data::Str(vec![spec.tool.name(w)])),
            Array::new("objects", &[objects.len()], Data::Str(objects)),
            Array::new("view", &[], Data::Str(vec![spec.view.to_string()])),
            Array::new("seed", &[], Data::U64(vec![spec.seed])),
            Array::new("actions", &[actions.len()], Data::Str(actions)),
        ]
    }
}
