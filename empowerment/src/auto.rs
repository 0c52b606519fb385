//! Tool selection and LOOKUP's table for the tool it selects, in one propagation: every
//! tool's reachable sets side by side.
//!
//! What a world family's service makes for a layout it has never seen, with
//! `tool = "auto"`: the matrix column of the task object (equation 6 selects its
//! argmax), then the selected tool's value in every state. Done one after the other
//! ([`Engine::matrix`], then [`Engine::lookup_values`]) that is T + 1 propagations over
//! the layout's states. Tool j's actions are {N, E, S, W, apply, select_j}: the tools
//! share five of their six actions, so with the sets of all T tools stored together per
//! state (`cur[s T + j]` = R^j_k(s), one 64-bit word each), one step reads each
//! successor's row once for the shared actions and one word more per tool:
//!
//! ```text
//! R^j_0(s) = { proj_D(s) }
//! R^j_k(s) = U_{a in {N,E,S,W,apply}} R^j_{k-1}(T(s, a))  U  R^j_{k-1}(T(s, select_j))
//! ```
//!
//! One pass up to H (the largest horizon of the selection and of the table) keeps
//! |R^j_h(s)| for every h, tool and state (one byte each), from which:
//!
//! ```text
//! column[j] = mean over normal s of log2 |R^j_{H_sel}(s)|     (H_sel: the selection's one horizon)
//! j*        = select(column)                                  (argmax, ties to the lower index, zeros: none)
//! value(s)  = sum_{h=1..H_table} log2 |R^{j*}_h(s)|           (Phi, `horizon_sum`)
//!           | log2 |R^{j*}_{h(s)}(s)|                         (otherwise)
//! ```
//!
//! These are the numbers the two computations give, to the bit: the same counts, the
//! same logarithms summed in the same order (a test checks it on every built-in world
//! and on layouts). Cost per step: `(5 + T)` successor rows of `T` words against `6 T`
//! single words, one projection instead of `T + 1`; the counts with the CPU's `popcnt`
//! where it has one (detected at run time: the release build targets x86-64's baseline,
//! which lacks it, and a count is then a dozen instructions). Memory: `2 |S| T` words
//! of sets and `|S| T H` bytes of counts. It applies to deterministic worlds whose
//! projection has at most 64 values (one word a set), horizons 1 to `MAX_HORIZON` and 1
//! to 16 tools;
//! [`Engine::auto_table`] says `None` elsewhere and the caller computes the two apart.

use fulcrum_world::{ObjectSet, MAX_HORIZON, SELECT0};
use rayon::prelude::*;

use crate::engine::{normal_mean, select, Engine, ToolSel};
use crate::propagate::Projection;

/// Tool selection and the selected tool's table (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct AutoTable {
    /// The matrix column: each tool's mean value over the normal states.
    pub column: Vec<f64>,
    /// The tool equation 6 selects (`None`: no tool has empowerment over the set).
    pub tool: Option<usize>,
    /// LOOKUP's value in every state (by state id) for the selected tool; empty when
    /// no tool is selected.
    pub values: Vec<f32>,
}

/// Horizons of one [`Engine::auto_table`]: the selection's (one for every state and
/// row, [`crate::request::selection_horizon`]) and the table's (the service's).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AutoHorizons {
    /// The selection's horizon.
    pub select: u32,
    /// The table's horizon where the tool is not held.
    pub unequipped: u32,
    /// The table's horizon where it is held.
    pub equipped: u32,
    /// The table holds Phi = sum over h <= max(unequipped, equipped) of E^h.
    pub horizon_sum: bool,
}

/// The actions every tool's subset holds.
const SHARED: [u8; 5] = [
    fulcrum_world::NORTH,
    fulcrum_world::EAST,
    fulcrum_world::SOUTH,
    fulcrum_world::WEST,
    fulcrum_world::APPLY,
];

/// States of one piece of [`propagate_step`]'s work. A thread takes at least four
/// (2,048 states): a small layout (a `toolbox` tree, ~2,000 states) stays on one
/// thread, where handing half a level to another costs more than it saves.
const CHUNK: usize = 512;

/// One step of the propagation for `T` tools: `next` from `cur`, and each set's size
/// into `cnt` (both `T` per state).
fn propagate_step<const T: usize>(
    succ: &[u32],
    na: usize,
    cur: &[u64],
    next: &mut [u64],
    cnt: &mut [u8],
) {
    let popcnt = has_popcnt();
    next.par_chunks_mut(T * CHUNK)
        .zip(cnt.par_chunks_mut(T * CHUNK))
        .with_min_len(4)
        .enumerate()
        .for_each(|(i, (dst, c))| {
            let rows = &succ[i * CHUNK * na..];
            if popcnt {
                // SAFETY: the CPU has `popcnt` (checked at run time just above).
                #[cfg(target_arch = "x86_64")]
                unsafe {
                    step_rows_popcnt::<T>(rows, na, cur, dst, c)
                }
            } else {
                step_rows::<T>(rows, na, cur, dst, c);
            }
        });
}

/// Whether this CPU counts a word's bits in one instruction. x86-64's baseline, which
/// the release build targets, has no `popcnt`: `count_ones` is then a dozen
/// instructions (callgrind: a tenth of all a boulder layout's instructions, from its
/// draw to its table, went there).
fn has_popcnt() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("popcnt")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// [`step_rows`] compiled with the `popcnt` instruction.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "popcnt")]
fn step_rows_popcnt<const T: usize>(
    rows: &[u32],
    na: usize,
    cur: &[u64],
    dst: &mut [u64],
    cnt: &mut [u8],
) {
    step_rows::<T>(rows, na, cur, dst, cnt);
}

/// The propagation step for consecutive states: `rows` their successor rows, `dst` and
/// `cnt` their `T` words and counts.
#[inline(always)]
fn step_rows<const T: usize>(
    rows: &[u32],
    na: usize,
    cur: &[u64],
    dst: &mut [u64],
    cnt: &mut [u8],
) {
    for ((row, dst), c) in rows
        .chunks_exact(na)
        .zip(dst.chunks_exact_mut(T))
        .zip(cnt.chunks_exact_mut(T))
    {
        let mut acc = [0u64; T];
        for &a in &SHARED {
            let r = row[a as usize] as usize * T;
            let from: &[u64; T] = cur[r..r + T].try_into().expect("T words a state");
            for j in 0..T {
                acc[j] |= from[j];
            }
        }
        for (j, d) in acc.iter_mut().enumerate() {
            *d |= cur[row[SELECT0 as usize + j] as usize * T + j];
        }
        dst.copy_from_slice(&acc);
        for (c, x) in c.iter_mut().zip(acc) {
            *c = x.count_ones() as u8;
        }
    }
}

/// log2 of the counts a set of at most 64 projections can have, as `f64::log2` gives them.
fn log2_table() -> [f64; 65] {
    let mut t = [0.0; 65];
    for (c, v) in t.iter_mut().enumerate() {
        *v = (c as f64).log2();
    }
    t
}

impl Engine<'_> {
    /// Tool selection over `set` and the selected tool's LOOKUP table, in one
    /// propagation (module docs); `None` where this path does not apply (a stochastic
    /// world, more than 64 projections, a horizon of 0 or above `MAX_HORIZON`, no tools or
    /// more than 16, or tables beyond the memory limit): compute the two apart there.
    pub fn auto_table(&self, set: &ObjectSet, hz: AutoHorizons) -> Option<AutoTable> {
        let world = self.world;
        let t = world.tools.len();
        let table_h = hz.unequipped.max(hz.equipped);
        let all_h = [hz.select, hz.unequipped, hz.equipped];
        if world.is_stochastic()
            || !(1..=16).contains(&t)
            || all_h.iter().any(|&h| h == 0 || h > MAX_HORIZON)
        {
            return None;
        }
        let hmax = all_h.into_iter().max().unwrap_or(0) as usize;
        let proj = Projection::new(&self.space, set);
        let n = self.space.len();
        let bytes = n * t * 8 * 2 + n * t * hmax;
        if proj.words() != 1 || self.space.bytes() + bytes > self.limits.max_bytes {
            return None;
        }
        let na = self.space.num_actions();
        let succ = self.space.succ_table();
        // Sets: row s holds the T tools' words.
        let mut cur: Vec<u64> = Vec::with_capacity(n * t);
        for &p in &proj.ids {
            cur.extend(std::iter::repeat_n(1u64 << p, t));
        }
        let mut next = vec![0u64; n * t];
        // counts[(h - 1) n T + s T + j] = |R^j_h(s)|.
        let mut counts = vec![0u8; hmax * n * t];
        for step in counts.chunks_mut(n * t) {
            // One instance per tool count (`T` words a state, known to the compiler).
            macro_rules! by_tools {
                ($($n:literal)*) => {
                    match t {
                        $($n => propagate_step::<$n>(succ, na, &cur, &mut next, step),)*
                        _ => unreachable!("1 to 16 tools, checked above"),
                    }
                };
            }
            by_tools!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16);
            std::mem::swap(&mut cur, &mut next);
        }
        let log2 = log2_table();
        let count = |h: u32, s: usize, j: usize| counts[(h as usize - 1) * n * t + s * t + j];
        let states = self.space.states();
        let normal: Vec<u32> = self.space.normal_ids().collect();
        let column: Vec<f64> = (0..t)
            .map(|j| {
                normal_mean(
                    normal
                        .iter()
                        .map(|&i| log2[count(hz.select, i as usize, j) as usize]),
                )
            })
            .collect();
        let tool = select(column.iter().copied());
        let values = match tool {
            None => Vec::new(),
            Some(j) if hz.horizon_sum => (0..n)
                .map(|s| {
                    (1..=table_h)
                        .map(|h| log2[count(h, s, j) as usize])
                        .sum::<f64>() as f32
                })
                .collect(),
            Some(j) => (0..n)
                .map(|s| {
                    let h = if ToolSel::Tool(j).held(&states[s]) {
                        hz.equipped
                    } else {
                        hz.unequipped
                    };
                    log2[count(h, s, j) as usize] as f32
                })
                .collect(),
        };
        Some(AutoTable {
            column,
            tool,
            values,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both builds of the step (with `popcnt` where this CPU has it, and without) give
    /// the sets and counts written out by hand for three states and two tools.
    #[test]
    fn the_step_with_and_without_popcnt_gives_the_hand_counted_sets() {
        // 8 actions a state: N E S W apply select0 select1 (and one spare).
        let na = 8;
        // State 0 goes everywhere to 1 but select1 -> 2; states 1 and 2 stay put.
        let mut succ = vec![1u32, 1, 1, 1, 1, 1, 2, 0];
        succ.extend([1u32; 8]);
        succ.extend([2u32; 8]);
        let cur = vec![0b1, 0b1, 0b110, 0b1010, u64::MAX, 1 << 63];
        // State 0: tool 0 = state 1's word 0 | state 1's (select0) = 0b110;
        // tool 1 = 0b1010 | state 2's tool-1 word (select1) = 1 << 63 | 0b1010.
        let want_sets = [0b110, 0b1010 | 1 << 63, 0b110, 0b1010, u64::MAX, 1 << 63];
        let want_counts = [2u8, 3, 2, 2, 64, 1];
        let (mut next, mut cnt) = (vec![0u64; 6], vec![0u8; 6]);
        step_rows::<2>(&succ, na, &cur, &mut next, &mut cnt);
        assert_eq!(
            (next.as_slice(), cnt.as_slice()),
            (&want_sets[..], &want_counts[..])
        );
        #[cfg(target_arch = "x86_64")]
        {
            assert!(
                has_popcnt(),
                "every x86-64 machine this runs on counts bits in one instruction"
            );
            let (mut next, mut cnt) = (vec![0u64; 6], vec![0u8; 6]);
            // SAFETY: the CPU has `popcnt` (asserted just above).
            unsafe { step_rows_popcnt::<2>(&succ, na, &cur, &mut next, &mut cnt) };
            assert_eq!(
                (next.as_slice(), cnt.as_slice()),
                (&want_sets[..], &want_counts[..])
            );
        }
    }
}
