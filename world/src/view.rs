//! What of the map the learner sees: all of it, or an egocentric window.
//!
//! [`View::Full`] is the observation of [`crate::env`]: the whole `W x H` glyph grid.
//! [`View::Crop`]`(R)` is the `(2R+1) x (2R+1)` window centred on the agent, as
//! MiniHack's `glyphs_crop`: window cell `(i, j)` (row `i`, column `j`, both in
//! `0..2R+1`) shows map cell `(x + j - R, y + i - R)` for an agent at `(x, y)`, so the
//! agent is always at the centre `(R, R)`; cells beyond the map read as rock (glyph
//! [`crate::env::G_ROCK`], the terrain nothing passes), never as the destructible wall block. The
//! flags (held tools, mode) are the same in both views.
//!
//! The network's input shape follows the view: `cells` is `W * H` or `(2R+1)^2`, so a
//! policy trained with one view cannot be run with another, and a cropped policy can be
//! played on a world of another size with the same tools.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::env::{ObsSpec, G_ROCK};
use crate::state::State;
use crate::world::World;

/// The largest crop radius: a window of 127 x 127 holds a 64 x 64 map (the largest a
/// world file may draw) from any agent cell.
pub const MAX_CROP_RADIUS: u8 = 63;

/// The part of the map in the observation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum View {
    /// The whole map.
    #[default]
    Full,
    /// The `(2R+1) x (2R+1)` window centred on the agent, of radius `R >= 1`.
    Crop(u8),
}

impl View {
    /// The observation's shapes in this view: the window's side replaces the map's
    /// width and height.
    pub fn spec(self, world: &World) -> ObsSpec {
        let full = world.obs_spec();
        match self {
            View::Full => full,
            View::Crop(r) => {
                let side = 2 * r as usize + 1;
                ObsSpec {
                    width: side,
                    height: side,
                    ..full
                }
            }
        }
    }

    /// Write the observation of `s` into `glyphs` (`spec().cells()`) and `flags`.
    pub fn observe(self, world: &World, s: &State, glyphs: &mut [u8], flags: &mut [u8]) {
        match self {
            View::Full => world.observe(s, glyphs, flags),
            View::Crop(r) => {
                crop(world, s, r, glyphs);
                world.observe_flags(s, flags);
            }
        }
    }

    /// Bring an observation of `prev` up to date for `next` (as
    /// [`World::observe_update`]); afterwards `glyphs` and `flags` equal
    /// [`View::observe`] of `next`. A crop is redrawn whenever the agent moved or an
    /// object or tool changed (a window is small); a change of mode alone touches only
    /// the flags.
    pub fn update(
        self,
        world: &World,
        prev: &State,
        next: &State,
        glyphs: &mut [u8],
        flags: &mut [u8],
    ) {
        match self {
            View::Full => world.observe_update(prev, next, glyphs, flags),
            View::Crop(r) => {
                if (prev.x, prev.y) != (next.x, next.y)
                    || prev.objects != next.objects
                    || prev.inventory != next.inventory
                {
                    crop(world, next, r, glyphs);
                    world.observe_flags(next, flags);
                } else if prev.mode != next.mode {
                    world.observe_flags(next, flags);
                }
            }
        }
    }
}

/// The window of radius `r` around the agent of `s`, rock beyond the map.
fn crop(world: &World, s: &State, r: u8, glyphs: &mut [u8]) {
    let (r, side) = (r as isize, 2 * r as usize + 1);
    let (w, h) = (world.width as isize, world.height as isize);
    let (ax, ay) = (s.x as isize, s.y as isize);
    for (i, row) in glyphs[..side * side].chunks_exact_mut(side).enumerate() {
        let y = ay + i as isize - r;
        for (j, g) in row.iter_mut().enumerate() {
            let x = ax + j as isize - r;
            *g = if (0..w).contains(&x) && (0..h).contains(&y) {
                world.cell_glyph(s, (y * w + x) as usize)
            } else {
                G_ROCK
            };
        }
    }
}

impl FromStr for View {
    type Err = String;
    fn from_str(s: &str) -> Result<View, String> {
        let bad = || {
            format!(
                "unknown view '{s}' (views: full, or crop:R for the window of radius R around the agent, R from 1 to {MAX_CROP_RADIUS})"
            )
        };
        if s == "full" {
            return Ok(View::Full);
        }
        let r = s.strip_prefix("crop:").ok_or_else(bad)?;
        match r.parse::<u8>() {
            Ok(r @ 1..=MAX_CROP_RADIUS) => Ok(View::Crop(r)),
            _ => Err(bad()),
        }
    }
}

impl fmt::Display for View {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            View::Full => f.write_str("full"),
            View::Crop(r) => write!(f, "crop:{r}"),
        }
    }
}

impl Serialize for View {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for View {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        String::deserialize(d)?
            .parse()
            .map_err(serde::de::Error::custom)
    }
}
