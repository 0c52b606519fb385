//! The state space: every state reachable from the initial one, with dense ids and a
//! successor table.
//!
//! Breadth-first search over all |A| actions, level by level: the successors of a level
//! are computed in parallel (rayon), then deduplicated in one hash map in id order, so
//! ids are deterministic (BFS order) whatever the thread count.
//!
//! The index packs each state into a `u64` when the world's fields fit in 64 bits (agent
//! cell, mode, inventory bits, 2 bits per tree/wall/door, a cell index per boulder):
//! keys a third the size of the 38-byte state make the look-ups, which are bound by
//! memory latency, faster. Other worlds key by the whole state. Where every field's
//! range multiplied gives at most 2^20 keys (small worlds; every layout of the built-in
//! families: 9,600 keys for a toolbox layout with a tree, 259,200 with a boulder), the
//! key is that mixed-radix number and the index a direct table of ids: one array read a
//! look-up instead of a hash probe (a third off enumerating a toolbox layout). There the
//! enumeration makes a level's successors as keys only (4 bytes each, not 38) and
//! rebuilds a new state from its key when it numbers it, so its serial part is one
//! table read a successor.
//!
//! Memory: `states` (38 B each), the successor table (`4 |A|` B each) and the index
//! (16 to 60 B each, or a direct table of 4 B a key, 4 MiB at most): about
//! `100 + 4 |A|` bytes per state.
//!
//! A stochastic world (`fulcrum_world::chance`) is enumerated over every outcome with
//! positive probability, and keeps its transition distributions as well: for state s
//! and action a, [`StateSpace::outcomes`] gives the ids and probabilities of the
//! outcomes (12 B per outcome, at most 4 per pair, in one offset table of `4 |A|` B per
//! state). Its successor table holds the intended outcome ([`World::step`]), one of
//! them.

use std::collections::hash_map::Entry;

use fulcrum_world::hash::FastMap;
use fulcrum_world::{Mode, State, World};
use rayon::prelude::*;

use crate::error::EngineError;
use crate::limits::Limits;

/// Packs the states of one world into `u64` keys, checking every field's range (so a
/// garbage state never aliases a real one).
#[derive(Debug, Clone)]
struct Packer {
    width: u8,
    height: u8,
    max_mode: u8,
    tools: u32,
    /// Per object: (bits, largest valid value, is a boulder).
    objects: Vec<(u32, u16, bool)>,
    cells: u16,
}

/// Bits to hold the values 0..=n.
fn bits(n: u64) -> u32 {
    64 - n.leading_zeros()
}

impl Packer {
    fn new(world: &World) -> Option<Packer> {
        let cells = (world.width * world.height) as u16;
        let n = world.tools.len() as u32;
        let objects: Vec<(u32, u16, bool)> = world
            .objects
            .iter()
            .map(|o| {
                if o.kind == fulcrum_world::ObjectKind::Boulder {
                    // Cell index, or `cells` for destroyed.
                    (bits(cells as u64), cells, true)
                } else {
                    (2, 2, false)
                }
            })
            .collect();
        let total = bits(world.width as u64 * world.height as u64 - 1)
            + bits(1 + n as u64)
            + n
            + objects.iter().map(|o| o.0).sum::<u32>();
        (total <= 64).then_some(Packer {
            width: world.width as u8,
            height: world.height as u8,
            max_mode: 1 + n as u8,
            tools: n,
            objects,
            cells,
        })
    }

    /// Whether every field of `s` is in this world's range (the slots past its objects
    /// zero), so that no garbage state aliases a real one's key.
    #[inline]
    fn in_range(&self, s: &State) -> bool {
        self.head_in_range(s)
            && !self
                .objects
                .iter()
                .zip(&s.objects)
                .any(|(&(_, max, boulder), &raw)| Packer::object_out_of_range(max, boulder, raw))
            && self.unused_slots_zero(s)
    }

    /// Whether the cell, mode, reserved byte and inventory of `s` are in range.
    #[inline]
    fn head_in_range(&self, s: &State) -> bool {
        s.x < self.width
            && s.y < self.height
            && s.mode <= self.max_mode
            && s.reserved == 0
            && (s.inventory as u32) >> self.tools == 0
    }

    /// Whether an object's raw value is out of its range. Boulders: a cell index below
    /// `cells` (= max), or destroyed; the others: a condition 0..=2 (= max).
    #[inline]
    fn object_out_of_range(max: u16, boulder: bool, raw: u16) -> bool {
        if boulder {
            raw >= max && raw != fulcrum_world::BOULDER_DESTROYED
        } else {
            raw > max
        }
    }

    /// Whether the object slots past the world's objects are zero (four at a time).
    #[inline]
    fn unused_slots_zero(&self, s: &State) -> bool {
        let w = s.words();
        let n = self.objects.len();
        let unused = |q: usize| -> u64 {
            let first = n.saturating_sub(4 * q).min(4);
            if first >= 4 {
                0
            } else {
                u64::MAX << (16 * first)
            }
        };
        !(0..4).any(|q| w[1 + q] & unused(q) != 0)
    }

    /// The packed key of `s`, `None` where a field is out of range: the objects' range
    /// checks and their key bits in one pass (a look-up's hot path).
    #[inline]
    fn pack(&self, s: &State) -> Option<u64> {
        if !self.head_in_range(s) {
            return None;
        }
        let mut k = self.head(s);
        let mut bad = false;
        for (&(b, max, boulder), &raw) in self.objects.iter().zip(&s.objects) {
            bad |= Packer::object_out_of_range(max, boulder, raw);
            k = k << b | self.object_value(boulder, raw);
        }
        (!bad && self.unused_slots_zero(s)).then_some(k)
    }

    /// The key's first fields: cell and mode, then the inventory bits.
    #[inline]
    fn head(&self, s: &State) -> u64 {
        ((s.y as u64 * self.width as u64 + s.x as u64) * (self.max_mode as u64 + 1) + s.mode as u64)
            << self.tools
            | s.inventory as u64
    }

    /// An object's value in a key: a boulder destroyed is keyed as `cells`.
    #[inline]
    fn object_value(&self, boulder: bool, v: u16) -> u64 {
        if boulder && v == fulcrum_world::BOULDER_DESTROYED {
            self.cells as u64
        } else {
            v as u64
        }
    }

    /// How many keys [`Packer::dense_trusted`] can give: every field's range multiplied.
    fn dense_len(&self) -> u64 {
        let mut n = (self.cells as u64 * (self.max_mode as u64 + 1)) << self.tools;
        for &(_, max, _) in &self.objects {
            n = n.saturating_mul(max as u64 + 1);
        }
        n
    }

    /// The state's key in mixed radix (cell and mode, inventory bits, then each object's
    /// value over its range): dense, `0..dense_len()`, for a direct table. Fields must be
    /// in range ([`Packer::in_range`]).
    #[inline]
    fn dense_trusted(&self, s: &State) -> usize {
        let mut k = self.head(s);
        for (&(_, max, boulder), &v) in self.objects.iter().zip(&s.objects) {
            k = k * (max as u64 + 1) + self.object_value(boulder, v);
        }
        k as usize
    }

    /// The state whose [`Packer::dense_trusted`] key is `k` (the unused object slots
    /// and the reserved byte zero, as the dynamics leave them).
    fn dense_state(&self, mut k: u64) -> State {
        let mut s = State::default();
        for (i, &(_, max, boulder)) in self.objects.iter().enumerate().rev() {
            let radix = max as u64 + 1;
            let v = (k % radix) as u16;
            k /= radix;
            s.objects[i] = if boulder && v == self.cells {
                fulcrum_world::BOULDER_DESTROYED
            } else {
                v
            };
        }
        s.inventory = (k & ((1u64 << self.tools) - 1)) as u16;
        k >>= self.tools;
        let modes = self.max_mode as u64 + 1;
        s.mode = (k % modes) as u8;
        let cell = k / modes;
        s.x = (cell % self.width as u64) as u8;
        s.y = (cell / self.width as u64) as u8;
        s
    }

    /// [`Packer::pack`] without the range checks, for states the dynamics made.
    #[inline]
    fn pack_trusted(&self, s: &State) -> u64 {
        let mut k = self.head(s);
        for (&(b, _, boulder), &v) in self.objects.iter().zip(&s.objects) {
            k = k << b | self.object_value(boulder, v);
        }
        k
    }
}

/// Key spaces up to this many keys get a direct table (4 bytes a key: 4 MiB at most).
const DENSE_KEYS: u64 = 1 << 20;

/// No id in a direct table's slot.
const NO_ID: u32 = u32::MAX;

/// State -> id.
#[derive(Debug)]
enum Index {
    /// A direct table over the dense keys ([`Packer::dense_trusted`]), where they are
    /// few: one array read a look-up (small worlds, a family's layouts).
    Dense(Packer, Vec<u32>),
    Packed(Packer, FastMap<u64, u32>),
    Full(FastMap<State, u32>),
}

impl Index {
    fn new(world: &World) -> Index {
        match Packer::new(world) {
            Some(p) if p.dense_len() <= DENSE_KEYS => {
                let n = p.dense_len() as usize;
                Index::Dense(p, vec![NO_ID; n])
            }
            Some(p) => Index::Packed(p, FastMap::default()),
            None => Index::Full(FastMap::default()),
        }
    }

    #[inline]
    fn get(&self, s: &State) -> Option<u32> {
        match self {
            Index::Dense(p, t) => {
                if !p.in_range(s) {
                    return None;
                }
                let id = t[p.dense_trusted(s)];
                (id != NO_ID).then_some(id)
            }
            Index::Packed(p, m) => m.get(&p.pack(s)?).copied(),
            Index::Full(m) => m.get(s).copied(),
        }
    }

    /// Bytes held, for `states` states.
    fn bytes(&self, states: usize) -> usize {
        match self {
            Index::Dense(_, t) => t.len() * 4,
            _ => states * StateIndex::BYTES_PER_STATE,
        }
    }

    /// The id of `s`, giving it `next` if it is new (then true).
    #[inline]
    fn get_or_insert(&mut self, s: &State, next: u32) -> (u32, bool) {
        match self {
            Index::Dense(p, t) => {
                debug_assert!(p.in_range(s));
                let slot = &mut t[p.dense_trusted(s)];
                if *slot == NO_ID {
                    *slot = next;
                    (next, true)
                } else {
                    (*slot, false)
                }
            }
            Index::Packed(p, m) => {
                debug_assert_eq!(p.pack(s), Some(p.pack_trusted(s)));
                let k = p.pack_trusted(s);
                match m.entry(k) {
                    Entry::Occupied(e) => (*e.get(), false),
                    Entry::Vacant(e) => (*e.insert(next), true),
                }
            }
            Index::Full(m) => match m.entry(*s) {
                Entry::Occupied(e) => (*e.get(), false),
                Entry::Vacant(e) => (*e.insert(next), true),
            },
        }
    }

    fn reserve(&mut self, n: usize) {
        match self {
            Index::Dense(..) => {}
            Index::Packed(_, m) => m.reserve(n),
            Index::Full(m) => m.reserve(n),
        }
    }
}

/// The ids of a state space's states, without the states or their transitions
/// ([`StateSpace::into_index`]).
#[derive(Debug)]
pub struct StateIndex {
    index: Index,
    len: usize,
}

impl StateIndex {
    /// Bytes a state costs in a hashed index (a hash map entry of a packed key and an
    /// id, with the map's spare room); a direct table costs 4 bytes a key instead
    /// ([`StateIndex::bytes`]).
    pub const BYTES_PER_STATE: usize = 24;

    /// Bytes the index holds.
    pub fn bytes(&self) -> usize {
        self.index.bytes(self.len)
    }

    /// The id of a state, if it is in the space.
    pub fn id(&self, s: &State) -> Option<u32> {
        self.index.get(s)
    }

    /// States in the space.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the space is empty (never: it holds the initial state).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// An enumerated state space with its successor table.
#[derive(Debug)]
pub struct StateSpace {
    states: Vec<State>,
    index: Index,
    succ: Vec<u32>,
    actions: usize,
    /// Stochastic worlds: where the outcomes of (s, a) start in `out_ids`, `len() x
    /// num_actions() + 1` offsets; empty for deterministic worlds.
    out_start: Vec<u32>,
    /// Outcome state ids.
    out_ids: Vec<u32>,
    /// Outcome probabilities.
    out_probs: Vec<f64>,
}

/// Bytes one state costs in a [`StateSpace`] with `actions` actions.
pub fn bytes_per_state(actions: usize) -> usize {
    38 + 4 * actions + 64
}

/// The refusal of a space that has grown past `limits` after a level: `states` states
/// found so far, `per_state` bytes each.
fn check_size(
    world: &World,
    states: usize,
    per_state: usize,
    limits: &Limits,
) -> Result<(), EngineError> {
    let max_states = (limits.max_bytes / per_state).min(u32::MAX as usize - 1);
    if states > max_states {
        return Err(EngineError::StateSpaceTooLarge {
            world: world.name.clone(),
            states,
            bytes: states * per_state,
            limit: limits.max_bytes,
        });
    }
    Ok(())
}

impl StateSpace {
    /// Enumerate the states reachable from `world.initial`. Refuses, with the estimate,
    /// when the space would outgrow `limits.max_bytes`.
    pub fn enumerate(world: &World, limits: &Limits) -> Result<StateSpace, EngineError> {
        if world.is_stochastic() {
            return Self::enumerate_stochastic(world, limits);
        }
        let na = world.num_actions();
        let mut states = vec![world.initial];
        let mut index = Index::new(world);
        index.reserve(1 << 12);
        index.get_or_insert(&world.initial, 0);
        let mut succ: Vec<u32> = Vec::new();
        match &mut index {
            Index::Dense(p, table) => {
                Self::enumerate_dense(world, p, table, &mut states, &mut succ, limits)?
            }
            index => Self::enumerate_indexed(world, index, &mut states, &mut succ, limits)?,
        }
        Ok(StateSpace {
            states,
            index,
            succ,
            actions: na,
            out_start: Vec::new(),
            out_ids: Vec::new(),
            out_probs: Vec::new(),
        })
    }

    /// [`StateSpace::enumerate`] with a hashed index: level by level from `states`
    /// (the initial state, numbered), each successor numbered in (state, action) order.
    fn enumerate_indexed(
        world: &World,
        index: &mut Index,
        states: &mut Vec<State>,
        succ: &mut Vec<u32>,
        limits: &Limits,
    ) -> Result<(), EngineError> {
        let na = world.num_actions();
        let mut start = 0;
        while start < states.len() {
            let end = states.len();
            succ.reserve((end - start) * na);
            if end - start >= 2048 {
                // A large level: its successors made in parallel, then numbered in order.
                let next: Vec<State> = states[start..end]
                    .par_iter()
                    .flat_map_iter(|s| (0..na as u8).map(move |a| world.step(s, a)))
                    .collect();
                for ns in next {
                    let (id, new) = index.get_or_insert(&ns, states.len() as u32);
                    if new {
                        states.push(ns);
                    }
                    succ.push(id);
                }
            } else {
                // A small one is cheaper on one thread, each successor numbered as it
                // is made (the same order, so the same ids).
                for i in start..end {
                    let s = states[i];
                    for a in 0..na as u8 {
                        let ns = world.step(&s, a);
                        let (id, new) = index.get_or_insert(&ns, states.len() as u32);
                        if new {
                            states.push(ns);
                        }
                        succ.push(id);
                    }
                }
            }
            check_size(world, states.len(), bytes_per_state(na), limits)?;
            start = end;
        }
        Ok(())
    }

    /// [`StateSpace::enumerate`] where the index is a direct table: a level's successors
    /// are made as their keys only (4 bytes each, in parallel for a large level), and a
    /// new state is rebuilt from its key when it is numbered, so the serial part is one
    /// table read a successor. The same order as the general path, so the same ids.
    fn enumerate_dense(
        world: &World,
        p: &Packer,
        table: &mut [u32],
        states: &mut Vec<State>,
        succ: &mut Vec<u32>,
        limits: &Limits,
    ) -> Result<(), EngineError> {
        let na = world.num_actions();
        let key = |s: &State, a: u8| -> u32 {
            let n = world.step(s, a);
            debug_assert!(p.in_range(&n));
            p.dense_trusted(&n) as u32
        };
        let mut keys: Vec<u32> = Vec::new();
        let mut start = 0;
        while start < states.len() {
            let end = states.len();
            keys.clear();
            keys.resize((end - start) * na, 0);
            // One state's row of successor keys.
            let row = |(k, s): (&mut [u32], &State)| {
                for (a, k) in k.iter_mut().enumerate() {
                    *k = key(s, a as u8);
                }
            };
            let level = &states[start..end];
            if level.len() >= 2048 {
                keys.par_chunks_mut(na)
                    .zip(level)
                    .with_min_len(256)
                    .for_each(row);
            } else {
                keys.chunks_mut(na).zip(level).for_each(row);
            }
            succ.reserve(keys.len());
            for &k in &keys {
                let slot = &mut table[k as usize];
                if *slot == NO_ID {
                    *slot = states.len() as u32;
                    states.push(p.dense_state(k as u64));
                }
                succ.push(*slot);
            }
            check_size(world, states.len(), bytes_per_state(na), limits)?;
            start = end;
        }
        Ok(())
    }

    /// [`StateSpace::enumerate`] of a stochastic world: breadth-first over every outcome
    /// of every action, keeping the transition distributions.
    fn enumerate_stochastic(world: &World, limits: &Limits) -> Result<StateSpace, EngineError> {
        let na = world.num_actions();
        let per_state = bytes_per_state(na) + na * 4 * 12;
        let mut states = vec![world.initial];
        let mut index = Index::new(world);
        index.reserve(1 << 12);
        index.get_or_insert(&world.initial, 0);
        let mut succ: Vec<u32> = Vec::new();
        let mut out_start: Vec<u32> = vec![0];
        let mut out_ids: Vec<u32> = Vec::new();
        let mut out_probs: Vec<f64> = Vec::new();
        let mut start = 0;
        let expand = |s: &State| -> Vec<(u8, State, f64)> {
            let mut buf = Vec::with_capacity(4);
            let mut v = Vec::with_capacity(na * 2);
            for a in 0..na as u8 {
                world.outcomes(s, a, &mut buf);
                v.extend(buf.iter().map(|&(t, p)| (a, t, p)));
            }
            v
        };
        while start < states.len() {
            let end = states.len();
            let level = &states[start..end];
            let next: Vec<Vec<(u8, State, f64)>> = if level.len() >= 2048 {
                level.par_iter().map(expand).collect()
            } else {
                level.iter().map(expand).collect()
            };
            for per in next {
                let mut last = u8::MAX;
                for (a, t, p) in per {
                    let (id, new) = index.get_or_insert(&t, states.len() as u32);
                    if new {
                        states.push(t);
                    }
                    if a != last {
                        // The first outcome of each action is the intended one.
                        if last != u8::MAX {
                            out_start.push(out_ids.len() as u32);
                        }
                        succ.push(id);
                        last = a;
                    }
                    out_ids.push(id);
                    out_probs.push(p);
                }
                out_start.push(out_ids.len() as u32);
            }
            check_size(world, states.len(), per_state, limits)?;
            start = end;
        }
        debug_assert_eq!(out_start.len(), states.len() * na + 1);
        Ok(StateSpace {
            states,
            index,
            succ,
            actions: na,
            out_start,
            out_ids,
            out_probs,
        })
    }

    /// Whether the space keeps transition distributions (a stochastic world).
    pub fn is_stochastic(&self) -> bool {
        !self.out_start.is_empty()
    }

    /// The outcomes of action `a` in state `i`: ids and probabilities (summing to 1).
    /// For a deterministic world, the one successor with probability 1.
    #[inline]
    pub fn outcomes(&self, i: u32, a: u8) -> (&[u32], &[f64]) {
        if self.out_start.is_empty() {
            let k = i as usize * self.actions + a as usize;
            return (&self.succ[k..k + 1], &[1.0]);
        }
        let k = i as usize * self.actions + a as usize;
        let (b, e) = (self.out_start[k] as usize, self.out_start[k + 1] as usize);
        (&self.out_ids[b..e], &self.out_probs[b..e])
    }

    /// Number of states.
    pub fn len(&self) -> usize {
        self.states.len()
    }

    /// Never true: the initial state is always there.
    pub fn is_empty(&self) -> bool {
        self.states.is_empty()
    }

    /// |A|.
    pub fn num_actions(&self) -> usize {
        self.actions
    }

    /// All states by id.
    pub fn states(&self) -> &[State] {
        &self.states
    }

    /// The state with id `i`.
    pub fn state(&self, i: u32) -> &State {
        &self.states[i as usize]
    }

    /// The id of a state, if it is in the space.
    pub fn id(&self, s: &State) -> Option<u32> {
        self.index.get(s)
    }

    /// The id of T(s_i, a).
    #[inline]
    pub fn succ(&self, i: u32, a: u8) -> u32 {
        self.succ[i as usize * self.actions + a as usize]
    }

    /// The successor table, `len() x num_actions()` row-major.
    pub fn succ_table(&self) -> &[u32] {
        &self.succ
    }

    /// Ids of the normal-mode states.
    pub fn normal_ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.states
            .iter()
            .enumerate()
            .filter(|(_, s)| s.mode() == Mode::Normal)
            .map(|(i, _)| i as u32)
    }

    /// Only the index from states to ids, the rest dropped: what answering by state id
    /// needs ([`StateIndex::bytes`]).
    pub fn into_index(self) -> StateIndex {
        let len = self.states.len();
        StateIndex {
            index: self.index,
            len,
        }
    }

    /// Approximate bytes held.
    pub fn bytes(&self) -> usize {
        self.len() * bytes_per_state(self.actions)
            + self.out_start.len() * 4
            + self.out_ids.len() * 12
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fulcrum_world::load_world;

    /// The states in the order of a plain breadth-first search (a FIFO queue, actions in
    /// order, a hash map for the ids) and its successor table: the reference the
    /// level-by-level enumeration must equal, id for id.
    fn reference_bfs(w: &World) -> (Vec<State>, Vec<u32>) {
        let mut ids: FastMap<State, u32> = FastMap::default();
        ids.insert(w.initial, 0);
        let (mut states, mut succ) = (vec![w.initial], Vec::new());
        let mut i = 0;
        while i < states.len() {
            let s = states[i];
            for a in 0..w.num_actions() as u8 {
                let n = w.step(&s, a);
                let next = states.len() as u32;
                let id = *ids.entry(n).or_insert(next);
                if id == next {
                    states.push(n);
                }
                succ.push(id);
            }
            i += 1;
        }
        (states, succ)
    }

    #[test]
    fn the_direct_tables_enumeration_equals_a_plain_breadth_first_search() {
        let f = fulcrum_world::family::load_family("toolbox").unwrap();
        // A boulder layout among the largest of the first thousand (58,910 states).
        let boulder = f.layout(492).unwrap();
        assert_eq!(boulder.objects[0].kind, fulcrum_world::ObjectKind::Boulder);
        let two_rooms = fulcrum_world::family::load_family("two-rooms")
            .unwrap()
            .layout(3)
            .unwrap();
        let mut sizes = Vec::new();
        for w in [load_world("exp3").unwrap(), boulder, two_rooms] {
            let sp = StateSpace::enumerate(&w, &Limits::default()).unwrap();
            assert!(
                matches!(sp.index, Index::Dense(..)),
                "{}: a direct table",
                w.name
            );
            sizes.push(sp.len());
            let (states, succ) = reference_bfs(&w);
            assert!(
                sp.states() == states.as_slice(),
                "{}: the same states in the same order",
                w.name
            );
            assert!(
                sp.succ_table() == succ.as_slice(),
                "{}: the same successors",
                w.name
            );
        }
        // exp3 and the boulder layout are large enough that their widest levels take the
        // parallel path (2,048 states or more), the door layout small enough that none does.
        assert_eq!(sizes, [52_051, 58_910, 3_797]);
    }

    /// Each enumeration (direct table: exp3; hashed: exp2; stochastic: exp2-slip) refuses
    /// a space that outgrows its memory, naming the states it found and their bytes, and
    /// succeeds with room for exactly the states it has (worlds/EXPECTED.md: 52,051 and
    /// 10,988 states; exp2-slip has exp2's, every outcome of a slip being some action's
    /// intended one; per state 38 + 4 |A| + 64 bytes, and 48 |A| more where stochastic).
    #[test]
    fn a_space_past_its_memory_is_refused_after_the_level_that_outgrows_it() {
        for (name, states, stochastic) in [
            ("exp3", 52_051, false),
            ("exp2", 10_988, false),
            ("exp2-slip", 10_988, true),
        ] {
            let w = load_world(name).unwrap();
            let na = w.num_actions();
            let per_state = bytes_per_state(na) + if stochastic { na * 48 } else { 0 };
            let fits = Limits {
                max_bytes: states * per_state,
            };
            assert_eq!(
                StateSpace::enumerate(&w, &fits).unwrap().len(),
                states,
                "{name}"
            );
            let short = Limits {
                max_bytes: states * per_state - 1,
            };
            match StateSpace::enumerate(&w, &short) {
                Err(EngineError::StateSpaceTooLarge {
                    states: found,
                    bytes,
                    limit,
                    ..
                }) => {
                    // The last level is the one past the limit: every state is found.
                    assert_eq!(found, states, "{name}");
                    assert_eq!(
                        (bytes, limit),
                        (found * per_state, short.max_bytes),
                        "{name}"
                    );
                }
                other => panic!("{name}: {other:?}"),
            }
        }
    }

    #[test]
    fn every_state_finds_its_own_id_and_garbage_finds_none() {
        // exp2's keys are too many for a direct table (4 tools, a boulder and a door),
        // exp3's are not: both kinds of index.
        for (name, dense) in [("exp2", false), ("exp3", true)] {
            let w = load_world(name).unwrap();
            let sp = StateSpace::enumerate(&w, &Limits::default()).unwrap();
            match &sp.index {
                Index::Dense(p, t) => {
                    assert!(dense, "{name}: a direct table");
                    assert_eq!(t.len() as u64, p.dense_len());
                    assert!(t.len() as u64 <= DENSE_KEYS);
                }
                Index::Packed(p, _) => {
                    assert!(!dense, "{name}: hashed");
                    assert!(p.dense_len() > DENSE_KEYS);
                }
                Index::Full(_) => panic!("{name} fits in 64 bits"),
            }
            for (i, s) in sp.states().iter().enumerate() {
                assert_eq!(sp.id(s), Some(i as u32));
            }
            let b = w.boulder_indices().next().unwrap();
            let cells = (w.width * w.height) as u16;
            let mut bads = Vec::new();
            // A boulder slot holding the value that keys "destroyed" must not alias it,
            // here or in a state of the space whose boulder is destroyed (where there is
            // one).
            let mut bad = w.initial;
            bad.objects[b] = cells;
            bads.push(bad);
            let destroyed = sp
                .states()
                .iter()
                .find(|s| s.objects[b] == fulcrum_world::BOULDER_DESTROYED);
            if let Some(d) = destroyed {
                let mut bad = *d;
                bad.objects[b] = cells;
                bads.push(bad);
            }
            // Another object's condition past 2.
            let other = (0..w.objects.len()).find(|&i| i != b).unwrap();
            let mut bad = w.initial;
            bad.objects[other] = 3;
            bads.push(bad);
            let mut bad = w.initial;
            bad.objects[15] = 1; // a slot past the world's objects
            bads.push(bad);
            let mut bad = w.initial;
            bad.x = w.width as u8;
            bads.push(bad);
            let mut bad = w.initial;
            bad.inventory = 1 << w.tools.len();
            bads.push(bad);
            let mut bad = w.initial;
            bad.mode = 2 + w.tools.len() as u8;
            bads.push(bad);
            let packer = match &sp.index {
                Index::Dense(p, _) | Index::Packed(p, _) => p,
                Index::Full(_) => unreachable!(),
            };
            for bad in &bads {
                assert_eq!(sp.id(bad), None, "{name}: {bad:?}");
                assert_eq!(packer.pack(bad), None, "{name}: {bad:?}");
                assert!(!packer.in_range(bad), "{name}: {bad:?}");
            }
        }
    }
}
