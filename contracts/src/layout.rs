//! The network's weight layout: the contract between the learner, which trains the
//! actor-critic network and publishes its weights as one flat f32 buffer, and the
//! actors, which evaluate the policy from that buffer (and a checkpoint, which names
//! each parameter).
//!
//! With C = W * H cells, G glyph ids, F flags, H hidden units and |A| actions, the
//! parameters in order are:
//!
//! ```text
//! policy.embed     (C*G, H)   one embedding row per (cell, glyph)
//! policy.flags.w   (F, H)
//! policy.l1.b      (H)
//! policy.l2.w      (H, H)
//! policy.l2.b      (H)
//! policy.pi.w      (H, |A|)
//! policy.pi.b      (|A|)
//! policy.v.w       (H, 1)
//! policy.v.b       (1)
//! policy.v_int.w   (H, 1)     only with the intrinsic value head
//! policy.v_int.b   (1)        only with the intrinsic value head
//! ```

use fulcrum_world::view::View;
use fulcrum_world::world::World;

/// Sizes of the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NetShape {
    /// Cells of the grid (W * H).
    pub cells: usize,
    /// Glyph ids.
    pub glyphs: usize,
    /// Flag vector length.
    pub flags: usize,
    /// Hidden units.
    pub hidden: usize,
    /// Actions.
    pub actions: usize,
    /// A second value head for the intrinsic return (the run's `intrinsic_value_head`):
    /// `value_int = h2 @ Wvi + bvi`, parameters `policy.v_int.w` (H, 1), `policy.v_int.b`.
    pub int_value: bool,
}

impl NetShape {
    /// Value heads: 1, or 2 with the intrinsic one.
    pub fn heads(&self) -> usize {
        1 + self.int_value as usize
    }

    /// The parameters in their fixed order (the order of the flat weights the learner
    /// publishes and of [`Offsets`]): the name a checkpoint stores each under, and its
    /// dimensions.
    pub fn params(&self) -> Vec<(&'static str, Vec<usize>)> {
        let (c, g, f, h, a) = (
            self.cells,
            self.glyphs,
            self.flags,
            self.hidden,
            self.actions,
        );
        let mut p = vec![
            ("policy.embed", vec![c * g, h]),
            ("policy.flags.w", vec![f, h]),
            ("policy.l1.b", vec![h]),
            ("policy.l2.w", vec![h, h]),
            ("policy.l2.b", vec![h]),
            ("policy.pi.w", vec![h, a]),
            ("policy.pi.b", vec![a]),
            ("policy.v.w", vec![h, 1]),
            ("policy.v.b", vec![1]),
        ];
        if self.int_value {
            p.push(("policy.v_int.w", vec![h, 1]));
            p.push(("policy.v_int.b", vec![1]));
        }
        p
    }
}

/// Offsets of the parameters in the flat buffer (the order of [`NetShape::params`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Offsets {
    /// `policy.embed` (C*G, H).
    pub embed: usize,
    /// `policy.flags.w` (F, H).
    pub wf: usize,
    /// `policy.l1.b` (H).
    pub b1: usize,
    /// `policy.l2.w` (H, H).
    pub w2: usize,
    /// `policy.l2.b` (H).
    pub b2: usize,
    /// `policy.pi.w` (H, |A|).
    pub wp: usize,
    /// `policy.pi.b` (|A|).
    pub bp: usize,
    /// `policy.v.w` (H, 1).
    pub wv: usize,
    /// `policy.v.b` (1).
    pub bv: usize,
    /// `policy.v_int.w` (H, 1), with the intrinsic value head (else `len`).
    pub wvi: usize,
    /// `policy.v_int.b` (1), with the intrinsic value head (else `len`).
    pub bvi: usize,
    /// Total.
    pub len: usize,
}

impl Offsets {
    /// Offsets for a shape.
    pub fn new(s: NetShape) -> Offsets {
        let h = s.hidden;
        let embed = 0;
        let wf = embed + s.cells * s.glyphs * h;
        let b1 = wf + s.flags * h;
        let w2 = b1 + h;
        let b2 = w2 + h * h;
        let wp = b2 + h;
        let bp = wp + h * s.actions;
        let wv = bp + s.actions;
        let bv = wv + h;
        let (wvi, bvi, len) = if s.int_value {
            (bv + 1, bv + 1 + h, bv + 2 + h)
        } else {
            (bv + 1, bv + 1, bv + 1)
        };
        Offsets {
            embed,
            wf,
            b1,
            w2,
            b2,
            wp,
            bp,
            wv,
            bv,
            wvi,
            bvi,
            len,
        }
    }
}

/// The network's shape for a world seen through `view` (one value head;
/// [`crate::config::RunConfig::shape`] adds the intrinsic one when the run has it).
pub fn shape_for(world: &World, view: View, hidden: usize) -> NetShape {
    let spec = view.spec(world);
    NetShape {
        cells: spec.cells(),
        glyphs: spec.glyphs,
        flags: spec.flags,
        hidden,
        actions: world.num_actions(),
        int_value: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each parameter starts where the previous one ends, in the order of the table.
    #[test]
    fn offsets_follow_the_parameter_table() {
        for int_value in [false, true] {
            let s = NetShape {
                cells: 12,
                glyphs: 11,
                flags: 6,
                hidden: 16,
                actions: 7,
                int_value,
            };
            let o = Offsets::new(s);
            let mut starts = vec![o.embed, o.wf, o.b1, o.w2, o.b2, o.wp, o.bp, o.wv, o.bv];
            if int_value {
                starts.extend([o.wvi, o.bvi]);
            }
            let mut at = 0;
            for ((name, dims), start) in s.params().iter().zip(&starts) {
                assert_eq!(at, *start, "{name}");
                at += dims.iter().product::<usize>();
            }
            assert_eq!((s.params().len(), at), (starts.len(), o.len));
        }
    }
}
