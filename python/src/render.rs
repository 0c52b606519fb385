//! A state as an RGB picture: one `tile x tile` square per cell, coloured by what the
//! cell shows (the observation's glyph ids), with a mark in the middle of the agent and
//! of tools lying on the floor.

use fulcrum_world::env::{
    G_AGENT, G_BOULDER, G_DOOR_CLOSED, G_DOOR_OPEN, G_FLOOR, G_GOAL, G_ROCK, G_TOOL0, G_TREE,
    G_WALL,
};
use fulcrum_world::{State, World};
use numpy::{PyArray1, PyArray3, PyArrayMethods};
use pyo3::prelude::*;

use crate::errors::value_error;

/// The largest tile side (pixels).
const MAX_TILE: usize = 64;

/// The colour of a glyph id, and the colour of the mark in its middle (if any).
fn colours(g: u8) -> ([u8; 3], Option<[u8; 3]>) {
    match g {
        G_ROCK => ([38, 38, 42], None),
        G_FLOOR => ([222, 222, 214], None),
        G_GOAL => ([240, 200, 60], None),
        G_AGENT => ([222, 222, 214], Some([200, 40, 40])),
        G_TREE => ([40, 140, 60], None),
        G_WALL => ([140, 110, 80], None),
        G_DOOR_CLOSED => ([120, 70, 30], None),
        G_DOOR_OPEN => ([200, 160, 110], None),
        G_BOULDER => ([120, 120, 130], None),
        t => {
            // Tools: a mark whose hue follows the tool index.
            const HUES: [[u8; 3]; 6] = [
                [31, 119, 180],
                [148, 103, 189],
                [23, 190, 207],
                [227, 119, 194],
                [188, 189, 34],
                [255, 127, 14],
            ];
            let k = (t - G_TOOL0) as usize;
            ([222, 222, 214], Some(HUES[k % HUES.len()]))
        }
    }
}

/// Draws the glyph grid `glyphs` (`w * h`, row-major) into `out` (`h*tile x w*tile x 3`).
pub(crate) fn draw(glyphs: &[u8], w: usize, tile: usize, out: &mut [u8]) {
    let row = w * tile * 3;
    let (lo, hi) = (tile / 4, tile - tile / 4);
    for (c, &g) in glyphs.iter().enumerate() {
        let (bg, mark) = colours(g);
        let (cx, cy) = (c % w, c / w);
        for py in 0..tile {
            for px in 0..tile {
                let inner = (lo..hi).contains(&px) && (lo..hi).contains(&py);
                let rgb = match mark {
                    Some(m) if inner => m,
                    _ => bg,
                };
                let at = (cy * tile + py) * row + (cx * tile + px) * 3;
                out[at..at + 3].copy_from_slice(&rgb);
            }
        }
    }
}

/// The picture of `s`: uint8 `(H * tile, W * tile, 3)`.
pub(crate) fn rgb<'py>(
    py: Python<'py>,
    world: &World,
    s: &State,
    tile: usize,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    if !(1..=MAX_TILE).contains(&tile) {
        return Err(value_error(format!(
            "tile is {tile} pixels: give 1 to {MAX_TILE}"
        )));
    }
    let spec = world.obs_spec();
    let mut glyphs = vec![0u8; spec.cells()];
    let mut flags = vec![0u8; spec.flags];
    world.observe(s, &mut glyphs, &mut flags);
    let mut out = vec![0u8; spec.cells() * tile * tile * 3];
    draw(&glyphs, spec.width, tile, &mut out);
    PyArray1::from_vec(py, out).reshape([spec.height * tile, spec.width * tile, 3])
}
