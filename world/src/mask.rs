//! Per-mode action masking: which actions can do something in a state, read off the
//! observation's flags.
//!
//! With `n` tools the flags are `[held_0 .. held_{n-1}, normal, choosing-tool,
//! choosing-direction(0) .. choosing-direction(n-1)]` (see [`crate::env`]) and the actions
//! are `N, E, S, W, apply, select_0 .. select_{n-1}` (|A| = 5 + n). The mask allows:
//!
//! | mode | allowed |
//! |---|---|
//! | normal | N, E, S, W; apply only when some tool is held |
//! | choosing-tool | select_k for each held tool k |
//! | choosing-direction(k) | N, E, S, W |
//!
//! Every masked action is one the world would turn into "nothing happens" (a select in
//! normal mode, apply without a tool) or into "cancel back to normal" (a wrong key at a
//! prompt): masking removes no outcome the world can produce, it only stops the policy
//! from spending probability on the no-ops. Bit `a` of the mask is action `a`.
//!
//! Because the mask is a function of the flags alone, the actor (which samples) and the
//! learner (which recomputes log-probabilities and entropy) derive the same bits from the
//! same observation: chunks need no extra field. Empowerment does not use the mask: it is
//! a property of the world over the world's full action set.

use crate::world::{APPLY, SELECT0};

/// Bits of the four moves (N, E, S, W).
pub const MOVES: u32 = 0b1111;

/// The allowed actions of an observation's flags (`2n + 2` bytes, `n` tools), bit `a` for
/// action `a`. A flag vector that names no mode (never produced by
/// [`crate::World::observe`]) allows every action, so a mask is never empty.
pub fn action_mask(flags: &[u8]) -> u32 {
    let n = flags.len().saturating_sub(2) / 2;
    let all = (1u32 << (SELECT0 as usize + n)) - 1;
    if flags.len() != 2 * n + 2 {
        return all;
    }
    let held = flags[..n].iter().enumerate().fold(0u32, |m, (k, &h)| {
        m | ((h != 0) as u32) << (SELECT0 as usize + k)
    });
    let mask = if flags[n] != 0 {
        MOVES | if held != 0 { 1 << APPLY } else { 0 }
    } else if flags[n + 1] != 0 {
        held
    } else if flags[n + 2..].iter().any(|&x| x != 0) {
        MOVES
    } else {
        all
    };
    if mask == 0 {
        all
    } else {
        mask
    }
}

/// [`action_mask`] of flags held as `f32` (the learner's copy of a batch's flags): a flag
/// is set when it is not 0.
pub fn action_mask_f32(flags: &[f32]) -> u32 {
    let mut bytes = [0u8; 2 * 16 + 2];
    let n = flags.len().min(bytes.len());
    for (b, &x) in bytes.iter_mut().zip(&flags[..n]) {
        *b = (x != 0.0) as u8;
    }
    action_mask(&bytes[..n])
}

#[cfg(test)]
mod tests {
    use super::*;

    // Two tools: flags [held0, held1, normal, choosing-tool, dir0, dir1]; 7 actions.
    #[test]
    fn hand_counted_masks() {
        // Normal, nothing held: the four moves.
        assert_eq!(action_mask(&[0, 0, 1, 0, 0, 0]), 0b000_1111);
        // Normal, tool 1 held: moves and apply.
        assert_eq!(action_mask(&[0, 1, 1, 0, 0, 0]), 0b001_1111);
        // Choosing a tool, tool 1 held: select_1 (action 6) only.
        assert_eq!(action_mask(&[0, 1, 0, 1, 0, 0]), 0b100_0000);
        // Choosing a tool, both held: select_0 and select_1.
        assert_eq!(action_mask(&[1, 1, 0, 1, 0, 0]), 0b110_0000);
        // Choosing a direction for tool 0: the four directions.
        assert_eq!(action_mask(&[1, 0, 0, 0, 1, 0]), 0b000_1111);
        // No mode at all: everything (never empty).
        assert_eq!(action_mask(&[0, 0, 0, 0, 0, 0]), 0b111_1111);
        // Choosing a tool while holding none cannot arise; it allows everything.
        assert_eq!(action_mask(&[0, 0, 0, 1, 0, 0]), 0b111_1111);
        assert_eq!(action_mask_f32(&[0.0, 1.0, 1.0, 0.0, 0.0, 0.0]), 0b001_1111);
    }
}
