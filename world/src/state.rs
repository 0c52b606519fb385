//! The packed state (its text form is in `describe`).
//!
//! [`State`] is the whole dynamic state of a world in 38 bytes: the agent's cell, its
//! mode, the inventory (one bit per tool) and one `u16` per object. It is `Copy`,
//! hashable, `#[repr(C)]` with no padding, so it can serve as a key in shared memory.
//!
//! Object slots: trees, walls and doors hold their condition (0 intact/closed, 1 open,
//! 2 destroyed); a boulder holds its cell index `y * width + x`, or
//! [`BOULDER_DESTROYED`]. Unused slots are 0.

use std::hash::{Hash, Hasher};

/// At most this many tools (one inventory bit each).
pub const MAX_TOOLS: usize = 16;
/// At most this many objects (one `u16` slot each in [`State`]).
pub const MAX_OBJECTS: usize = 16;

/// A destroyed boulder's slot value.
pub const BOULDER_DESTROYED: u16 = u16::MAX;

/// The agent's mode (the MiniHack prompt it is in).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Moving.
    Normal,
    /// `apply` was pressed: the next action picks a held tool.
    ChoosingTool,
    /// A tool was picked: the next direction uses it.
    ChoosingDirection(u8),
}

/// The dynamic state of a world. See the module docs for the layout.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct State {
    /// Agent column.
    pub x: u8,
    /// Agent row.
    pub y: u8,
    /// 0 normal, 1 choosing-tool, 2 + k choosing-direction(k).
    pub mode: u8,
    /// Always 0 (keeps the layout free of padding).
    pub reserved: u8,
    /// Bit k set = tool k held.
    pub inventory: u16,
    /// One slot per object.
    pub objects: [u16; MAX_OBJECTS],
}

impl Hash for State {
    #[inline]
    fn hash<H: Hasher>(&self, h: &mut H) {
        let w = self.words();
        for x in w {
            h.write_u64(x);
        }
    }
}

impl State {
    /// The state as five little-endian words (agent, mode and inventory first).
    #[inline]
    pub fn words(&self) -> [u64; 5] {
        let o = &self.objects;
        let q = |i: usize| {
            o[i] as u64
                | (o[i + 1] as u64) << 16
                | (o[i + 2] as u64) << 32
                | (o[i + 3] as u64) << 48
        };
        [
            self.x as u64
                | (self.y as u64) << 8
                | (self.mode as u64) << 16
                | (self.inventory as u64) << 32,
            q(0),
            q(4),
            q(8),
            q(12),
        ]
    }

    /// The 38 bytes of the packed state.
    pub fn to_bytes(&self) -> [u8; 38] {
        let mut b = [0u8; 38];
        b[0] = self.x;
        b[1] = self.y;
        b[2] = self.mode;
        b[3] = self.reserved;
        b[4..6].copy_from_slice(&self.inventory.to_le_bytes());
        for (i, v) in self.objects.iter().enumerate() {
            b[6 + 2 * i..8 + 2 * i].copy_from_slice(&v.to_le_bytes());
        }
        b
    }

    /// The inverse of [`State::to_bytes`] (no validation: check membership in a state space).
    pub fn from_bytes(b: &[u8; 38]) -> State {
        let mut s = State {
            x: b[0],
            y: b[1],
            mode: b[2],
            reserved: b[3],
            inventory: u16::from_le_bytes([b[4], b[5]]),
            objects: [0; MAX_OBJECTS],
        };
        for i in 0..MAX_OBJECTS {
            s.objects[i] = u16::from_le_bytes([b[6 + 2 * i], b[7 + 2 * i]]);
        }
        s
    }

    /// The mode.
    #[inline]
    pub fn mode(&self) -> Mode {
        match self.mode {
            0 => Mode::Normal,
            1 => Mode::ChoosingTool,
            m => Mode::ChoosingDirection(m - 2),
        }
    }

    /// Set the mode.
    #[inline]
    pub fn set_mode(&mut self, m: Mode) {
        self.mode = match m {
            Mode::Normal => 0,
            Mode::ChoosingTool => 1,
            Mode::ChoosingDirection(k) => 2 + k,
        };
    }

    /// Whether tool `k` is held.
    #[inline]
    pub fn holds(&self, k: usize) -> bool {
        self.inventory >> k & 1 == 1
    }
}
