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
    s.check(path)?;
    let font = fonts(path)?;
    let (fw, fh) = (s.width as f64 * CELL, s.height as f64 * CELL + CAPTION);
    let cols = COLS.min(s.frames.len());
    let rows = s.frames.len().div_ceil(cols);
    let top = 40.0;
    let width = (GAP + cols as f64 * (fw + GAP)).max(320.0);
    let height = top + rows as f64 * (fh + GAP) + GAP;
    check_side(path, "the picture side (pixels)", width.max(height), 8000)?;
    let max = s.max_value();
    let mut shapes = vec![Shape::Text(Label::new(
        s.title.clone(),
        width / 2.0,
        20.0,
        fit_size(font, &s.title, 16.0, 8.0, width - 16.0),
        HAlign::Center,
        VAlign::Middle,
    ))];
    for (k, f) in s.frames.iter().enumerate() {
        let x0 = GAP + (k % cols) as f64 * (fw + GAP);
        let y0 = top + (k / cols) as f64 * (fh + GAP);
        frame_shapes(font, s, f, (x0, y0), max, &mut shapes);
    }
    scene::png(path, width.ceil() as u32, height.ceil() as u32, &shapes)
}

/// Frame delay of the animation, in hundredths of a second.
const GIF_DELAY: u16 = 25;

/// Draws the episode as an animated GIF at `path` (written atomically): one frame per
/// step, each as a frame of the strip (cells coloured by E, the glyphs, the caption)
/// under a line with the world and the step; it loops.
pub fn episode_gif(path: &Path, s: &Strip) -> Result<(), PlotError> {
    s.check(path)?;
    let font = fonts(path)?;
    let (fw, fh) = (s.width as f64 * CELL, s.height as f64 * CELL + CAPTION);
    let width = (fw + 2.0 * GAP).max(160.0);
    let top = 22.0;
    let height = top + fh + GAP;
    check_side(path, "the frame side (pixels)", width.max(height), 4000)?;
    let max = s.max_value();
    let (w, h) = (width.ceil() as u16, height.ceil() as u16);
    let encode = |error| PlotError::EncodeGif {
        path: path.to_path_buf(),
        error,
    };
    let mut bytes = Vec::new();
    {
        let mut enc = gif::Encoder::new(&mut bytes, w, h, &[]).map_err(encode)?;
        enc.set_repeat(gif::Repeat::Infinite).map_err(encode)?;
        for (k, f) in s.frames.iter().enumerate() {
            let title = format!("{} {}/{}", s.title_short(), k + 1, s.frames.len());
            let mut shapes = vec![Shape::Text(Label::new(
                title.clone(),
                width / 2.0,
                top / 2.0,
                fit_size(font, &title, 12.0, 6.0, width - 8.0),
                HAlign::Center,
                VAlign::Middle,
            ))];
            frame_shapes(font, s, f, ((width - fw) / 2.0, top), max, &mut shapes);
            let rgb = scene::rasterize(path, w as u32, h as u32, &shapes)?;
            let mut frame = gif::Frame::from_rgb_speed(w, h, &rgb, 10);
            frame.delay = GIF_DELAY;
            enc.write_frame(&frame).map_err(encode)?;
        }
    }
    fulcrum_contracts::fsio::write_atomic(path, &bytes).map_err(|error| PlotError::Io {
        path: path.to_path_buf(),
        error,
    })
}

/// Refuses a picture side over `limit` pixels.
fn check_side(path: &Path, what: &'static str, side: f64, limit: usize) -> Result<(), PlotError> {
    if side > limit as f64 {
        return Err(PlotError::TooLarge {
            path: path.to_path_buf(),
            what,
            size: side as usize,
            limit,
        });
    }
    Ok(())
}

impl Strip {
    /// Refuses a strip with nothing to draw.
    fn check(&self, path: &Path) -> Result<(), PlotError> {
        if self.frames.is_empty() || self.width == 0 || self.height == 0 {
            return Err(PlotError::NoData {
                path: path.to_path_buf(),
                reason: "the episode has no frames",
            });
        }
        Ok(())
    }

    /// The largest finite value of any frame (0 when there is none): the top of the
    /// colour scale.
    fn max_value(&self) -> f64 {
        self.frames
            .iter()
            .flat_map(|f| f.values.iter().flatten())
            .copied()
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max)
    }

    /// The title's first clause (up to the first comma): a GIF frame's heading.
    fn title_short(&self) -> &str {
        self.title.split(',').next().unwrap_or(&self.title)
    }
}

/// The shapes of one frame with its top-left corner at `(x0, y0)`: the caption, then
/// each cell coloured by E (viridis up to `max`), its glyph on top, the agent as '@' on a
/// white disc.
fn frame_shapes(
    font: &ab_glyph::FontRef<'static>,
    s: &Strip,
    f: &Frame,
    (x0, y0): (f64, f64),
    max: f64,
    shapes: &mut Vec<Shape>,
) {
    let fw = s.width as f64 * CELL;
    let rect =
        |x: f64, y: f64, w: f64, h: f64| vec![(x, y), (x + w, y), (x + w, y + h), (x, y + h)];
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
