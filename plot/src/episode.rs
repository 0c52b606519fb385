//! An episode as a strip of frames: one small map per step, each cell coloured by the
//! empowerment the agent would have standing there (the landscape of that moment: the
//! current inventory and object states), the map's glyphs on top, the agent as '@' on a
//! white disc, and the action taken and the value under the agent above each frame.

use std::path::Path;

use crate::error::PlotError;
use crate::scene::{self, Shape};
use crate::style::{text_on, viridis, AXIS, ROCK};
use crate::text::{fit_size, fonts, HAlign, Label, VAlign};

/// One step of an episode.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Caption, e.g. `t=3 apply`.
    pub caption: String,
    /// Glyph per cell, row-major (`#` rock, `.` floor, `@` the agent, ...).
    pub glyphs: Vec<char>,
    /// Value per cell (None: no such state, e.g. a wall or a tool's cell).
    pub values: Vec<Option<f64>>,
}

/// An episode to draw.
#[derive(Debug, Clone)]
pub struct Strip {
    /// Title on top.
    pub title: String,
    /// Map width and height in cells.
    pub width: usize,
    /// Map height in cells.
    pub height: usize,
    /// The frames, in order.
    pub frames: Vec<Frame>,
}

const CELL: f64 = 14.0;
const COLS: usize = 10;
const CAPTION: f64 = 16.0;
const GAP: f64 = 8.0;

/// Draws the strip as a PNG at `path`, written atomically.
pub fn episode_png(path: &Path, s: &Strip) -> Result<(), PlotError> {
    if s.frames.is_empty() || s.width == 0 || s.height == 0 {
        return Err(PlotError::NoData {
            path: path.to_path_buf(),
            reason: "the episode has no frames",
        });
    }
    let font = fonts(path)?;
    let (fw, fh) = (s.width as f64 * CELL, s.height as f64 * CELL + CAPTION);
    let cols = COLS.min(s.frames.len());
    let rows = s.frames.len().div_ceil(cols);
    let top = 40.0;
    let width = (GAP + cols as f64 * (fw + GAP)).max(320.0);
    let height = top + rows as f64 * (fh + GAP) + GAP;
    if width > 8000.0 || height > 8000.0 {
        return Err(PlotError::TooLarge {
            path: path.to_path_buf(),
            what: "the picture side (pixels)",
            size: width.max(height) as usize,
            limit: 8000,
        });
    }
    let max = s
        .frames
        .iter()
        .flat_map(|f| f.values.iter().flatten())
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let mut shapes = vec![Shape::Text(Label::new(
        s.title.clone(),
        width / 2.0,
        20.0,
        fit_size(font, &s.title, 16.0, 8.0, width - 16.0),
        HAlign::Center,
        VAlign::Middle,
    ))];
    let rect =
        |x: f64, y: f64, w: f64, h: f64| vec![(x, y), (x + w, y), (x + w, y + h), (x, y + h)];
    for (k, f) in s.frames.iter().enumerate() {
        let x0 = GAP + (k % cols) as f64 * (fw + GAP);
        let y0 = top + (k / cols) as f64 * (fh + GAP);
        shapes.push(Shape::Text(
            Label::new(
                f.caption.clone(),
                x0 + fw / 2.0,
                y0 + CAPTION / 2.0,
                fit_size(font, &f.caption, 11.0, 6.0, fw),
                HAlign::Center,
                VAlign::Middle,
            )
            .color(AXIS),
        ));
        for cy in 0..s.height {
            for cx in 0..s.width {
                let c = cy * s.width + cx;
                let g = f.glyphs.get(c).copied().unwrap_or(' ');
                let v = f.values.get(c).copied().flatten().filter(|v| v.is_finite());
                let bg = match (g, v) {
                    ('#', _) => ROCK,
                    (_, Some(v)) => viridis(if max > 0.0 { v / max } else { 0.0 }),
                    _ => [200, 200, 200],
                };
                let (px, py) = (x0 + cx as f64 * CELL, y0 + CAPTION + cy as f64 * CELL);
                shapes.push(Shape::Fill(rect(px, py, CELL, CELL), bg, 1.0));
                if g == '@' {
                    let r = CELL * 0.45;
                    let (mx, my) = (px + CELL / 2.0, py + CELL / 2.0);
                    let disc: Vec<(f64, f64)> = (0..12)
                        .map(|i| {
                            let a = i as f64 * std::f64::consts::TAU / 12.0;
                            (mx + r * a.cos(), my + r * a.sin())
                        })
                        .collect();
                    shapes.push(Shape::Fill(disc, [255, 255, 255], 1.0));
                    shapes.push(Shape::Text(Label::new(
                        "@",
                        mx,
                        my,
                        10.0,
                        HAlign::Center,
                        VAlign::Middle,
                    )));
                } else if g != '.' && g != '#' {
                    shapes.push(Shape::Text(
                        Label::new(
                            g.to_string(),
                            px + CELL / 2.0,
                            py + CELL / 2.0,
                            10.0,
                            HAlign::Center,
                            VAlign::Middle,
                        )
                        .color(text_on(bg)),
                    ));
                }
            }
        }
    }
    scene::png(path, width.ceil() as u32, height.ceil() as u32, &shapes)
}
