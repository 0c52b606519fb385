//! PNG figures for the `fulcrum` binary: landscape heatmaps and time traces.
//!
//! Three pictures are drawn:
//!
//! * [`heatmap_png`]: a map-shaped heatmap, one square cell per map cell, coloured with
//!   a viridis-like perceptual colour map, the value printed inside each cell with two
//!   decimals, static rock drawn as dark wall blocks, cells without a value in neutral
//!   grey, optional small glyphs in a cell corner, a colour bar labelled with the unit on
//!   the right and a title on top.
//! * [`trace_png`]: a time trace (like Fig. 12 of the paper): the value per step as a line
//!   with markers, the actions taken as x tick labels when there are few steps, and an
//!   optional categorical series (e.g. the door state) as a step plot in a smaller panel
//!   underneath.
//! * [`learning_curve_png`]: a training run's learning curve: the success rate over
//!   environment steps on top, the mean extrinsic return and the mean intrinsic reward
//!   per step (two colours, with a legend) underneath.
//!
//! Shapes are rasterised with `plotters`' bitmap backend; all text is rendered by this
//! module from the Hack font embedded in the `epaint_default_fonts` crate (MIT /
//! Bitstream Vera licence), so nothing depends on fonts installed on the machine.
//! (Plotters' own `ab_glyph` text path drops the glyphs' side bearings, which makes
//! monospaced numbers like `1.00` look broken, hence the own text renderer.)
//! [`register_plotters_fonts`] registers the same font with plotters for code that
//! draws plotters charts with plotters' text (e.g. SVG output).
//!
//! Every file is written with [`write_atomic`]: a half-written PNG never appears at the
//! final path.

mod bands;
mod episode;
mod matrix;
mod scene;
pub use bands::{band_chart_png, band_chart_svg, Band, BandChart};
pub use episode::{episode_png, Frame, Strip};
pub use matrix::{matrix_png, MatrixPicture};

use std::io;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use ab_glyph::{point, Font, FontRef, PxScale, ScaleFont};
use plotters::prelude::*;

/// Largest grid side (in cells) that [`heatmap_png`] accepts.
const MAX_GRID_SIDE: usize = 2000;
/// Largest number of steps that [`trace_png`] accepts.
const MAX_TRACE_STEPS: usize = 100_000;
/// Largest picture side in pixels; longer titles are clipped rather than widening more.
const MAX_IMAGE_SIDE: u32 = 8000;

/// Why a figure could not be drawn or written. Each message is one sentence naming the file.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// There is nothing to draw (an empty grid, a trace with no steps).
    #[error("cannot plot {}: {reason}", path.display())]
    NoData {
        /// The figure that was asked for.
        path: PathBuf,
        /// What is missing, e.g. "the grid has no cells".
        reason: &'static str,
    },
    /// The input is too large to be drawn as one picture.
    #[error(
        "cannot plot {}: {what} is {size}, more than the {limit} this plotter draws",
        path.display()
    )]
    TooLarge {
        /// The figure that was asked for.
        path: PathBuf,
        /// What is too large, e.g. "the grid side (cells)".
        what: &'static str,
        /// Its size.
        size: usize,
        /// The largest size accepted.
        limit: usize,
    },
    /// The embedded font could not be parsed (should never happen).
    #[error("cannot plot {}: the embedded font could not be loaded", path.display())]
    Font {
        /// The figure that was asked for.
        path: PathBuf,
    },
    /// The rasteriser reported an error.
    #[error("drawing {} failed: {message}", path.display())]
    Draw {
        /// The figure that was being drawn.
        path: PathBuf,
        /// The rasteriser's message.
        message: String,
    },
    /// PNG encoding failed.
    #[error("encoding {} as PNG failed: {error}", path.display())]
    Encode {
        /// The figure that was being encoded.
        path: PathBuf,
        /// The encoder's error.
        error: png::EncodingError,
    },
    /// Writing the file failed (the temporary file has been removed).
    #[error("cannot write {}: {error}", path.display())]
    Io {
        /// The file that was being written.
        path: PathBuf,
        /// The I/O error.
        error: io::Error,
    },
}

/// A landscape heatmap: one square cell per map cell.
///
/// Rows may have different lengths; the picture is as wide as the longest row of
/// `values` or `rock`, and missing entries count as "no value" / "not rock".
#[derive(Debug, Clone, Copy)]
pub struct Heatmap<'a> {
    /// Title drawn on top.
    pub title: &'a str,
    /// values[y][x]; None = no value on that cell (drawn as a neutral grey with no number).
    /// NaN and infinite values are treated as None.
    pub values: &'a [Vec<Option<f64>>],
    /// rock[y][x] = true for static rock cells: drawn as dark wall blocks.
    pub rock: &'a [Vec<bool>],
    /// Optional per-cell glyph drawn small in a corner (e.g. 'T', 'a', '+'), None = nothing.
    pub glyphs: Option<&'a [Vec<Option<char>>]>,
    /// Unit for the colour bar, e.g. "bits".
    pub unit: &'a str,
}

/// A time trace like Fig. 12 of the paper: value per step, plus an optional categorical
/// series drawn as a step line on a second panel below (e.g. the door state per step).
#[derive(Debug, Clone, Copy)]
pub struct Trace<'a> {
    /// Title drawn on top.
    pub title: &'a str,
    /// y-axis label of the value panel, e.g. "E^3 key -> door (bits)".
    pub value_label: &'a str,
    /// Value at t = 0..n; NaN and infinite values are left out (a gap in the line).
    pub values: &'a [f64],
    /// Action taken before step t (None at t = 0), drawn as tick labels on the x axis
    /// when there are <= 40 steps.
    pub actions: &'a [Option<String>],
    /// Optional categorical series: (label, category names in order low->high, index per
    /// step). Indices outside the names are left out (a gap in the step line).
    pub category: Option<(&'a str, &'a [String], &'a [usize])>,
}

/// Registers the embedded Hack font with plotters under the families `sans-serif`,
/// `serif` and `monospace`, once per process; returns whether the font is usable.
///
/// [`heatmap_png`] and [`trace_png`] call this themselves. Code that draws plotters
/// charts with plotters' own text (axis labels, SVG output) must call it first: with
/// plotters' `ab_glyph` feature, text in an unregistered family is an error.
pub fn register_plotters_fonts() -> bool {
    static DONE: OnceLock<bool> = OnceLock::new();
    *DONE.get_or_init(|| {
        ["sans-serif", "serif", "monospace"].iter().all(|family| {
            plotters::style::register_font(
                family,
                FontStyle::Normal,
                epaint_default_fonts::HACK_REGULAR,
            )
            .is_ok()
        })
    })
}

/// Draws `h` as a PNG at `path` (written atomically).
///
/// Cells are about 40 px square (smaller for grids wider or taller than 40 cells); values
/// are printed inside when the cell is large enough. Errors if the grid has no cells or
/// a side is longer than 2000 cells.
pub fn heatmap_png(path: &Path, h: &Heatmap) -> Result<(), PlotError> {
    let font = fonts(path)?;
    let layout = HeatmapLayout::new(path, h, font)?;
    let (width, height) = (layout.width, layout.height);
    let mut buf = vec![255u8; width as usize * height as usize * 3];
    let mut labels = Vec::new();
    draw_heatmap(&mut buf, &layout, h, &mut labels).map_err(|message| PlotError::Draw {
        path: path.to_path_buf(),
        message,
    })?;
    let mut canvas = Canvas {
        buf: &mut buf,
        width,
        height,
    };
    for label in &labels {
        canvas.text(font, label);
    }
    save_png(path, &buf, width, height)
}

/// Draws `t` as a PNG at `path` (written atomically).
///
/// The y axis runs from 0 (or below, for negative values) to max(value) * 1.1, at least
/// to 1. Errors if the trace has no steps or more than 100 000 steps.
pub fn trace_png(path: &Path, t: &Trace) -> Result<(), PlotError> {
    let font = fonts(path)?;
    let layout = TraceLayout::new(path, t, font)?;
    let (width, height) = (layout.width, layout.height);
    let mut buf = vec![255u8; width as usize * height as usize * 3];
    let mut labels = Vec::new();
    draw_trace(&mut buf, &layout, t, &mut labels).map_err(|message| PlotError::Draw {
        path: path.to_path_buf(),
        message,
    })?;
    let mut canvas = Canvas {
        buf: &mut buf,
        width,
        height,
    };
    for label in &labels {
        canvas.text(font, label);
    }
    save_png(path, &buf, width, height)
}

pub use fulcrum_shared::fsio::write_atomic;

// ---------------------------------------------------------------------------------------
// Shared helpers
// ---------------------------------------------------------------------------------------

/// The embedded font, parsed once.
fn font() -> Option<&'static FontRef<'static>> {
    static FONT: OnceLock<Option<FontRef<'static>>> = OnceLock::new();
    FONT.get_or_init(|| FontRef::try_from_slice(epaint_default_fonts::HACK_REGULAR).ok())
        .as_ref()
}

fn fonts(path: &Path) -> Result<&'static FontRef<'static>, PlotError> {
    let font = font().ok_or_else(|| PlotError::Font {
        path: path.to_path_buf(),
    })?;
    if !register_plotters_fonts() {
        return Err(PlotError::Font {
            path: path.to_path_buf(),
        });
    }
    Ok(font)
}

fn save_png(path: &Path, rgb: &[u8], width: u32, height: u32) -> Result<(), PlotError> {
    let encode = |error| PlotError::Encode {
        path: path.to_path_buf(),
        error,
    };
    let mut bytes = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut bytes, width, height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(encode)?;
        writer.write_image_data(rgb).map_err(encode)?;
        writer.finish().map_err(encode)?;
    }
    write_atomic(path, &bytes).map_err(|error| PlotError::Io {
        path: path.to_path_buf(),
        error,
    })
}

type Rgb = [u8; 3];

const BLACK_TEXT: Rgb = [20, 20, 20];
const WHITE_TEXT: Rgb = [255, 255, 255];
const AXIS: Rgb = [60, 60, 60];
const GRID: Rgb = [225, 225, 225];
const ROCK: Rgb = [38, 38, 42];
const ROCK_EDGE: Rgb = [72, 72, 78];
const NO_VALUE: Rgb = [190, 190, 190];
const VALUE_LINE: Rgb = [31, 119, 180];
const CATEGORY_LINE: Rgb = [214, 110, 20];

fn rgb(c: Rgb) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// Viridis, sampled at nine evenly spaced points.
const VIRIDIS: [Rgb; 9] = [
    [68, 1, 84],
    [71, 44, 122],
    [59, 81, 139],
    [44, 113, 142],
    [33, 144, 141],
    [39, 173, 129],
    [92, 200, 99],
    [170, 220, 50],
    [253, 231, 37],
];

/// Colour of `t` in [0, 1] (clamped; NaN counts as 0).
fn viridis(t: f64) -> Rgb {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |k: usize| (f64::from(a[k]) + (f64::from(b[k]) - f64::from(a[k])) * f).round() as u8;
    [mix(0), mix(1), mix(2)]
}

/// Black or white, whichever reads better on `bg`.
fn text_on(bg: Rgb) -> Rgb {
    let l = 0.2126 * f64::from(bg[0]) + 0.7152 * f64::from(bg[1]) + 0.0722 * f64::from(bg[2]);
    if l > 140.0 {
        BLACK_TEXT
    } else {
        WHITE_TEXT
    }
}

/// `v` if finite.
fn finite(v: Option<f64>) -> Option<f64> {
    v.filter(|x| x.is_finite())
}

/// Number of decimals that shows multiples of `step` exactly (0..=6).
fn decimals_for(step: f64) -> usize {
    if !step.is_finite() || step <= 0.0 {
        return 2;
    }
    (0..=6)
        .find(|&d| {
            let s = step * 10f64.powi(d as i32);
            (s - s.round()).abs() < 1e-6 * s.abs().max(1.0)
        })
        .unwrap_or(6)
}

/// `v` with `decimals` decimals, or in scientific notation when it is very large.
fn format_value(v: f64, decimals: usize) -> String {
    if v.abs() >= 1e6 {
        format!("{v:.2e}")
    } else {
        let s = format!("{v:.decimals$}");
        // Avoid "-0.00".
        if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
            s[1..].to_string()
        } else {
            s
        }
    }
}

/// Decimals printed inside a heatmap cell: 2, fewer for large values so they fit.
fn cell_decimals(v: f64) -> usize {
    match v.abs() {
        a if a < 100.0 => 2,
        a if a < 1000.0 => 1,
        _ => 0,
    }
}

/// "Nice" ticks (steps of 1, 2, 2.5 or 5 times a power of ten) in [lo, hi].
fn nice_ticks(lo: f64, hi: f64, max_ticks: usize) -> (Vec<f64>, f64) {
    let span = hi - lo;
    if !span.is_finite() || span <= 0.0 || max_ticks < 2 {
        return (if lo.is_finite() { vec![lo] } else { vec![] }, 1.0);
    }
    let raw = span / (max_ticks - 1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw * (1.0 - 1e-9))
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil();
    let ticks = (0..=max_ticks * 3)
        .map(|i| (first + i as f64) * step)
        .take_while(|v| *v <= hi + step * 1e-9)
        .collect();
    (ticks, step)
}

// ---------------------------------------------------------------------------------------
// Text
// ---------------------------------------------------------------------------------------

#[derive(Debug, Clone, Copy, PartialEq)]
enum HAlign {
    Left,
    Center,
    Right,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum VAlign {
    Top,
    /// Centred on the capital / digit height: what looks centred for numbers.
    Middle,
}

/// A piece of text to draw after the shapes.
#[derive(Debug, Clone)]
struct Label {
    text: String,
    x: f64,
    y: f64,
    /// Pixel size (ab_glyph's `PxScale`: ascent - descent).
    size: f32,
    color: Rgb,
    h: HAlign,
    v: VAlign,
    /// Rotated 90° counter-clockwise (reads bottom to top); alignment is along the text.
    vertical: bool,
}

impl Label {
    fn new(text: impl Into<String>, x: f64, y: f64, size: f32, h: HAlign, v: VAlign) -> Self {
        Self {
            text: text.into(),
            x,
            y,
            size,
            color: BLACK_TEXT,
            h,
            v,
            vertical: false,
        }
    }

    fn color(mut self, color: Rgb) -> Self {
        self.color = color;
        self
    }

    fn vertical(mut self) -> Self {
        self.vertical = true;
        self
    }
}

/// Horizontal advance of `text` at `size` in pixels.
fn text_width(font: &FontRef<'static>, text: &str, size: f32) -> f64 {
    let scaled = font.as_scaled(PxScale::from(size));
    let mut width = 0.0f32;
    let mut prev = None;
    for c in text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = prev {
            width += scaled.kern(p, id);
        }
        width += scaled.h_advance(id);
        prev = Some(id);
    }
    f64::from(width)
}

/// Largest size <= `size` (down to `min`) at which `text` fits in `avail` pixels.
fn fit_size(font: &FontRef<'static>, text: &str, size: f32, min: f32, avail: f64) -> f32 {
    let mut s = size;
    while s > min && text_width(font, text, s) > avail {
        s -= 0.5;
    }
    s
}

/// Text rendered to a coverage mask, with the anchor point in mask coordinates.
struct Mask {
    w: usize,
    h: usize,
    cover: Vec<f32>,
    anchor: (f64, f64),
}

fn render_mask(font: &FontRef<'static>, label: &Label) -> Option<Mask> {
    let scale = PxScale::from(label.size);
    let scaled = font.as_scaled(scale);
    let advance = text_width(font, &label.text, label.size);
    if label.text.is_empty() || !advance.is_finite() || advance > f64::from(MAX_IMAGE_SIDE) * 2.0 {
        return None;
    }
    let ascent = f64::from(scaled.ascent());
    let descent = f64::from(scaled.descent());
    let cap = scaled
        .outline_glyph(scaled.scaled_glyph('0'))
        .map_or(ascent * 0.75, |g| -f64::from(g.px_bounds().min.y));
    let pad = (f64::from(label.size) * 0.3).ceil() + 1.0;
    let w = (advance + 2.0 * pad).ceil() as usize;
    let h = (ascent - descent + 2.0 * pad).ceil() as usize;
    let baseline = pad + ascent;
    let mut cover = vec![0f32; w * h];
    let mut pen = pad as f32;
    let mut prev = None;
    for c in label.text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = prev {
            pen += scaled.kern(p, id);
        }
        prev = Some(id);
        let glyph = id.with_scale_and_position(scale, point(pen, baseline as f32));
        pen += scaled.h_advance(id);
        let Some(outline) = scaled.outline_glyph(glyph) else {
            continue;
        };
        let bounds = outline.px_bounds();
        outline.draw(|gx, gy, c| {
            let x = bounds.min.x as i64 + i64::from(gx);
            let y = bounds.min.y as i64 + i64::from(gy);
            if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
                let i = y as usize * w + x as usize;
                cover[i] = (cover[i] + c).min(1.0);
            }
        });
    }
    let ax = match label.h {
        HAlign::Left => pad,
        HAlign::Center => pad + advance / 2.0,
        HAlign::Right => pad + advance,
    };
    let ay = match label.v {
        VAlign::Top => baseline - ascent,
        VAlign::Middle => baseline - cap / 2.0,
    };
    Some(Mask {
        w,
        h,
        cover,
        anchor: (ax, ay),
    })
}

/// An RGB buffer to draw text on after plotters has drawn the shapes.
struct Canvas<'b> {
    buf: &'b mut [u8],
    width: u32,
    height: u32,
}

impl Canvas<'_> {
    fn blend(&mut self, x: i64, y: i64, color: Rgb, alpha: f32) {
        if x < 0 || y < 0 || x >= i64::from(self.width) || y >= i64::from(self.height) {
            return;
        }
        // Slightly heavier than linear coverage: reads better on coloured cells.
        let a = alpha.clamp(0.0, 1.0).powf(0.8);
        let i = (y as usize * self.width as usize + x as usize) * 3;
        for (dst, &c) in self.buf[i..i + 3].iter_mut().zip(&color) {
            let d = f32::from(*dst);
            *dst = (d + (f32::from(c) - d) * a).round() as u8;
        }
    }

    fn text(&mut self, font: &FontRef<'static>, label: &Label) {
        let Some(mask) = render_mask(font, label) else {
            return;
        };
        let (ax, ay) = mask.anchor;
        if label.vertical {
            // Mask (mx, my) -> (my, w - 1 - mx): rotated 90° counter-clockwise.
            let left = (label.x - ay).round() as i64;
            let top = (label.y - (mask.w as f64 - ax)).round() as i64;
            for my in 0..mask.h {
                for mx in 0..mask.w {
                    let c = mask.cover[my * mask.w + mx];
                    if c > 0.0 {
                        let x = left + my as i64;
                        let y = top + (mask.w - 1 - mx) as i64;
                        self.blend(x, y, label.color, c);
                    }
                }
            }
        } else {
            let left = (label.x - ax).round() as i64;
            let top = (label.y - ay).round() as i64;
            for my in 0..mask.h {
                for mx in 0..mask.w {
                    let c = mask.cover[my * mask.w + mx];
                    if c > 0.0 {
                        self.blend(left + mx as i64, top + my as i64, label.color, c);
                    }
                }
            }
        }
    }
}

/// Converts a plotters error into its message.
fn draw_err<E: std::error::Error + Send + Sync>(
    e: plotters::drawing::DrawingAreaErrorKind<E>,
) -> String {
    e.to_string()
}

type Area<'b> = DrawingArea<BitMapBackend<'b>, plotters::coord::Shift>;

fn fill_rect(area: &Area<'_>, x0: i32, y0: i32, x1: i32, y1: i32, c: Rgb) -> Result<(), String> {
    area.draw(&Rectangle::new([(x0, y0), (x1, y1)], rgb(c).filled()))
        .map_err(draw_err)
}

fn line(area: &Area<'_>, pts: Vec<(i32, i32)>, c: Rgb, width: u32) -> Result<(), String> {
    area.draw(&PathElement::new(pts, rgb(c).stroke_width(width)))
        .map_err(draw_err)
}

// ---------------------------------------------------------------------------------------
// Heatmap
// ---------------------------------------------------------------------------------------

const TITLE_SIZE: f32 = 22.0;
const LABEL_SIZE: f32 = 16.0;
const TICK_SIZE: f32 = 15.0;

/// Where everything of a heatmap goes, in pixels.
#[derive(Debug, Clone)]
struct HeatmapLayout {
    width: u32,
    height: u32,
    cols: usize,
    rows: usize,
    cell: i32,
    grid_left: i32,
    grid_top: i32,
    bar_left: i32,
    bar_top: i32,
    bar_width: i32,
    bar_height: i32,
    /// Colour scale: values map from lo (0) to hi (1).
    lo: f64,
    hi: f64,
    /// Tick values of the colour bar and their labels.
    ticks: Vec<(f64, String)>,
    tick_label_width: f64,
}

impl HeatmapLayout {
    fn new(path: &Path, h: &Heatmap, font: &FontRef<'static>) -> Result<Self, PlotError> {
        let rows = h.values.len().max(h.rock.len());
        let cols = h
            .values
            .iter()
            .map(Vec::len)
            .chain(h.rock.iter().map(Vec::len))
            .max()
            .unwrap_or(0);
        if rows == 0 || cols == 0 {
            return Err(PlotError::NoData {
                path: path.to_path_buf(),
                reason: "the grid has no cells",
            });
        }
        let side = rows.max(cols);
        if side > MAX_GRID_SIDE {
            return Err(PlotError::TooLarge {
                path: path.to_path_buf(),
                what: "the grid side (cells)",
                size: side,
                limit: MAX_GRID_SIDE,
            });
        }
        // 40 px cells up to 40 cells a side, then shrink to keep the picture <= ~1600 px.
        let cell = (1600 / side).clamp(2, 40) as i32;

        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for v in h.values.iter().flatten().filter_map(|v| finite(*v)) {
            lo = lo.min(v);
            hi = hi.max(v);
        }
        if !(lo.is_finite() && hi.is_finite()) {
            (lo, hi) = (0.0, 1.0);
        } else if hi - lo <= 0.0 || !(hi - lo).is_finite() {
            // All values equal (or a span too large for f64): a bar from 0 to the value,
            // or from the value to 0, or 0..1 when it is 0.
            let v = lo;
            (lo, hi) = if v > 0.0 {
                (0.0, v)
            } else if v < 0.0 {
                (v, 0.0)
            } else {
                (0.0, 1.0)
            };
            if !(hi - lo).is_finite() {
                (lo, hi) = (-f64::MAX / 2.0, f64::MAX / 2.0);
            }
        }

        let grid_w = cols as i32 * cell;
        let grid_h = rows as i32 * cell;
        let bar_height = grid_h.max(160);
        let n_ticks = if bar_height >= 120 { 5 } else { 3 };
        let step = (hi - lo) / (n_ticks - 1) as f64;
        let decimals = decimals_for(step).max(2);
        let ticks: Vec<(f64, String)> = (0..n_ticks)
            .map(|i| {
                let v = if i == n_ticks - 1 {
                    hi
                } else {
                    lo + step * i as f64
                };
                (v, format_value(v, decimals))
            })
            .collect();
        let tick_label_width = ticks
            .iter()
            .map(|(_, s)| text_width(font, s, TICK_SIZE))
            .fold(0.0, f64::max);

        let margin = 16;
        let title_h = 44;
        let grid_left = margin;
        let grid_top = title_h;
        let bar_left = grid_left + grid_w + 24;
        let bar_width = 22;
        let unit_w = if h.unit.is_empty() { 0 } else { 24 };
        let content_w = bar_left + bar_width + 6 + 6 + tick_label_width.ceil() as i32 + 12 + unit_w;
        let title_w = text_width(font, h.title, TITLE_SIZE).ceil() as i32 + 2 * margin;
        let width = (content_w + margin).max(title_w).min(MAX_IMAGE_SIDE as i32) as u32;
        let height = (grid_top + bar_height + margin + 8) as u32;
        Ok(Self {
            width,
            height,
            cols,
            rows,
            cell,
            grid_left,
            grid_top,
            bar_left,
            bar_top: grid_top,
            bar_width,
            bar_height,
            lo,
            hi,
            ticks,
            tick_label_width,
        })
    }

    /// Position of the colour scale of `v` in [0, 1].
    fn scale(&self, v: f64) -> f64 {
        let t = (v - self.lo) / (self.hi - self.lo);
        if t.is_finite() {
            t.clamp(0.0, 1.0)
        } else {
            0.5
        }
    }

    /// Top-left pixel of cell (x, y).
    fn cell_origin(&self, x: usize, y: usize) -> (i32, i32) {
        (
            self.grid_left + x as i32 * self.cell,
            self.grid_top + y as i32 * self.cell,
        )
    }
}

fn draw_heatmap(
    buf: &mut [u8],
    l: &HeatmapLayout,
    h: &Heatmap,
    labels: &mut Vec<Label>,
) -> Result<(), String> {
    let font = font().ok_or("the embedded font could not be loaded")?;
    let area = BitMapBackend::with_buffer(buf, (l.width, l.height)).into_drawing_area();
    area.fill(&WHITE).map_err(draw_err)?;

    labels.push(Label::new(
        h.title,
        f64::from(l.width) / 2.0,
        22.0,
        TITLE_SIZE,
        HAlign::Center,
        VAlign::Middle,
    ));

    let cell = l.cell;
    // Thin separating lines between cells when cells are large enough.
    let gap = i32::from(cell >= 8);
    let value_size = (cell as f32 * 0.38).min(15.5);
    let glyph_size = (cell as f32 * 0.35).min(14.0);
    for y in 0..l.rows {
        for x in 0..l.cols {
            let (x0, y0) = l.cell_origin(x, y);
            let (x1, y1) = (x0 + cell - 1 - gap, y0 + cell - 1 - gap);
            let is_rock = h
                .rock
                .get(y)
                .and_then(|r| r.get(x))
                .copied()
                .unwrap_or(false);
            let value = finite(h.values.get(y).and_then(|r| r.get(x)).copied().flatten());
            let bg = if is_rock {
                fill_rect(&area, x0, y0, x1, y1, ROCK_EDGE)?;
                if cell >= 8 {
                    fill_rect(&area, x0 + 2, y0 + 2, x1 - 2, y1 - 2, ROCK)?;
                }
                ROCK
            } else if let Some(v) = value {
                let c = viridis(l.scale(v));
                fill_rect(&area, x0, y0, x1, y1, c)?;
                c
            } else {
                fill_rect(&area, x0, y0, x1, y1, NO_VALUE)?;
                NO_VALUE
            };
            let fg = if is_rock {
                [205, 205, 205]
            } else {
                text_on(bg)
            };
            let (cx, cy) = (
                f64::from(x0) + f64::from(cell - gap) / 2.0,
                f64::from(y0) + f64::from(cell - gap) / 2.0,
            );
            let glyph = h
                .glyphs
                .and_then(|g| g.get(y))
                .and_then(|r| r.get(x))
                .copied()
                .flatten();
            if let (Some(v), false) = (value, is_rock) {
                if cell >= 24 {
                    let text = format_value(v, cell_decimals(v));
                    let avail = f64::from(cell - gap - 4);
                    let size = fit_size(font, &text, value_size, 9.0, avail);
                    if text_width(font, &text, size) <= avail {
                        let dy = if glyph.is_some() {
                            f64::from(cell) * 0.1
                        } else {
                            0.0
                        };
                        labels.push(
                            Label::new(text, cx, cy + dy, size, HAlign::Center, VAlign::Middle)
                                .color(fg),
                        );
                    }
                }
            }
            if let Some(g) = glyph {
                if cell >= 12 {
                    labels.push(
                        Label::new(
                            g.to_string(),
                            f64::from(x0) + 3.0,
                            f64::from(y0) + 2.0,
                            glyph_size,
                            HAlign::Left,
                            VAlign::Top,
                        )
                        .color(fg),
                    );
                }
            }
        }
    }

    // Colour bar: one row of pixels per colour, hi on top.
    let (bx0, by0) = (l.bar_left, l.bar_top);
    let (bx1, by1) = (l.bar_left + l.bar_width - 1, l.bar_top + l.bar_height - 1);
    for row in 0..l.bar_height {
        let t = 1.0 - f64::from(row) / f64::from((l.bar_height - 1).max(1));
        fill_rect(&area, bx0, by0 + row, bx1, by0 + row, viridis(t))?;
    }
    line(
        &area,
        vec![(bx0, by0), (bx1, by0), (bx1, by1), (bx0, by1), (bx0, by0)],
        AXIS,
        1,
    )?;
    for (v, text) in &l.ticks {
        let y = f64::from(by1) - l.scale(*v) * f64::from(l.bar_height - 1);
        let yi = y.round() as i32;
        line(&area, vec![(bx1, yi), (bx1 + 5, yi)], AXIS, 1)?;
        labels.push(Label::new(
            text.clone(),
            f64::from(bx1 + 9),
            y,
            TICK_SIZE,
            HAlign::Left,
            VAlign::Middle,
        ));
    }
    if !h.unit.is_empty() {
        let x = f64::from(bx1 + 9) + l.tick_label_width + 14.0;
        let size = fit_size(font, h.unit, LABEL_SIZE, 9.0, f64::from(l.bar_height));
        labels.push(
            Label::new(
                h.unit,
                x,
                f64::from(by0) + f64::from(l.bar_height) / 2.0,
                size,
                HAlign::Center,
                VAlign::Middle,
            )
            .vertical(),
        );
    }
    area.present().map_err(draw_err)
}

// ---------------------------------------------------------------------------------------
// Trace
// ---------------------------------------------------------------------------------------

/// Steps up to which every step gets a tick and its action is printed.
const FEW_STEPS: usize = 40;

/// A panel's plotting rectangle in pixels and its y range.
#[derive(Debug, Clone, Copy)]
struct Panel {
    left: i32,
    top: i32,
    width: i32,
    height: i32,
    y_lo: f64,
    y_hi: f64,
}

impl Panel {
    fn py(&self, y: f64) -> f64 {
        let t = (y - self.y_lo) / (self.y_hi - self.y_lo);
        let t = if t.is_finite() { t } else { 0.0 };
        f64::from(self.top + self.height) - t * f64::from(self.height)
    }
}

#[derive(Debug, Clone)]
struct TraceLayout {
    width: u32,
    height: u32,
    steps: usize,
    value: Panel,
    category: Option<Panel>,
    y_ticks: Vec<(f64, String)>,
    /// Steps with a tick (and a step number).
    x_ticks: Vec<usize>,
    /// Print actions under the step numbers, and whether rotated.
    actions: Option<bool>,
    /// Top of the x tick labels.
    x_labels_top: i32,
    /// Centre line of the x axis title.
    x_title_y: i32,
    /// x of the rotated y axis titles.
    y_title_x: i32,
}

impl TraceLayout {
    fn new(path: &Path, t: &Trace, font: &FontRef<'static>) -> Result<Self, PlotError> {
        let cat_len = t.category.map_or(0, |(_, _, idx)| idx.len());
        let steps = t.values.len().max(cat_len);
        if steps == 0 {
            return Err(PlotError::NoData {
                path: path.to_path_buf(),
                reason: "the trace has no steps",
            });
        }
        if steps > MAX_TRACE_STEPS {
            return Err(PlotError::TooLarge {
                path: path.to_path_buf(),
                what: "the number of steps",
                size: steps,
                limit: MAX_TRACE_STEPS,
            });
        }
        let fin = t.values.iter().copied().filter(|v| v.is_finite());
        let (vmin, vmax) = fin.fold((0.0f64, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
        let mut y_hi = (vmax * 1.1).max(1.0);
        let mut y_lo = if vmin < 0.0 { vmin * 1.1 } else { 0.0 };
        if !y_hi.is_finite() {
            y_hi = f64::MAX;
        }
        if !y_lo.is_finite() {
            y_lo = -f64::MAX;
        }
        if !(y_hi - y_lo).is_finite() {
            (y_lo, y_hi) = (y_lo / 2.0, y_hi / 2.0);
        }
        let (ticks, step) = nice_ticks(y_lo, y_hi, 7);
        let decimals = decimals_for(step);
        let y_ticks: Vec<(f64, String)> = ticks
            .into_iter()
            .map(|v| (v, format_value(v, decimals)))
            .collect();

        let few = steps <= FEW_STEPS;
        let action_texts: Vec<&str> = (0..steps)
            .filter_map(|i| t.actions.get(i).and_then(Option::as_deref))
            .collect();
        let max_action_w = action_texts
            .iter()
            .map(|a| text_width(font, a, TICK_SIZE))
            .fold(0.0, f64::max);
        let show_actions = few && !action_texts.is_empty();

        // Plot width: room for horizontal action labels if that stays reasonable.
        let mut rotated = false;
        let plot_w = if show_actions {
            let spacing = max_action_w + 12.0;
            if spacing * steps as f64 <= 1500.0 {
                (spacing * steps as f64).max(640.0)
            } else {
                rotated = true;
                (26.0 * steps as f64).max(640.0)
            }
        } else if few {
            (30.0 * steps as f64).max(640.0)
        } else {
            900.0
        };
        let plot_w = plot_w.ceil() as i32;

        let x_ticks: Vec<usize> = if few {
            (0..steps).collect()
        } else {
            let (ticks, _) = nice_ticks(0.0, (steps - 1) as f64, 11);
            ticks.into_iter().map(|v| v.round() as usize).collect()
        };

        let names: &[String] = t.category.map_or(&[], |(_, names, _)| names);
        let name_w = names
            .iter()
            .map(|n| text_width(font, n, TICK_SIZE))
            .fold(0.0, f64::max);
        let tick_w = y_ticks
            .iter()
            .map(|(_, s)| text_width(font, s, TICK_SIZE))
            .fold(0.0, f64::max)
            .max(name_w);

        let margin = 14;
        let y_title_x = margin + 10;
        let left = y_title_x + 14 + tick_w.ceil() as i32 + 12;
        let right = 24;
        let top = 48;
        let value_h = 320;
        let value = Panel {
            left,
            top,
            width: plot_w,
            height: value_h,
            y_lo,
            y_hi,
        };
        let category = (!names.is_empty()).then(|| {
            let k = names.len();
            Panel {
                left,
                top: top + value_h + 18,
                width: plot_w,
                height: (k as i32 * 30).clamp(60, 240),
                y_lo: -0.5,
                y_hi: k as f64 - 0.5,
            }
        });
        let bottom_of_panels = category.map_or(top + value_h, |c| c.top + c.height);
        let x_labels_top = bottom_of_panels + 8;
        let number_row = 20;
        let action_rows = match (show_actions, rotated) {
            (false, _) => 0,
            (true, false) => 20,
            (true, true) => max_action_w.ceil() as i32 + 8,
        };
        let x_title_y = x_labels_top + number_row + action_rows + 14;
        let height = (x_title_y + 14 + margin) as u32;
        let title_w = text_width(font, t.title, TITLE_SIZE).ceil() as i32 + 2 * margin;
        let width = (left + plot_w + right)
            .max(title_w)
            .min(MAX_IMAGE_SIDE as i32) as u32;
        Ok(Self {
            width,
            height,
            steps,
            value,
            category,
            y_ticks,
            x_ticks,
            actions: show_actions.then_some(rotated),
            x_labels_top,
            x_title_y,
            y_title_x,
        })
    }

    /// Pixel x of step `s`.
    fn px(&self, s: f64) -> f64 {
        f64::from(self.value.left) + (s + 0.5) / self.steps as f64 * f64::from(self.value.width)
    }
}

fn frame(area: &Area<'_>, p: &Panel) -> Result<(), String> {
    let (x0, y0, x1, y1) = (p.left, p.top, p.left + p.width, p.top + p.height);
    line(
        area,
        vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)],
        AXIS,
        1,
    )
}

fn draw_trace(
    buf: &mut [u8],
    l: &TraceLayout,
    t: &Trace,
    labels: &mut Vec<Label>,
) -> Result<(), String> {
    let font = font().ok_or("the embedded font could not be loaded")?;
    let area = BitMapBackend::with_buffer(buf, (l.width, l.height)).into_drawing_area();
    area.fill(&WHITE).map_err(draw_err)?;
    labels.push(Label::new(
        t.title,
        f64::from(l.width) / 2.0,
        24.0,
        TITLE_SIZE,
        HAlign::Center,
        VAlign::Middle,
    ));

    let panels: Vec<Panel> = std::iter::once(l.value).chain(l.category).collect();
    // Vertical grid lines at the x ticks, in every panel.
    for p in &panels {
        for &s in &l.x_ticks {
            let x = l.px(s as f64).round() as i32;
            line(&area, vec![(x, p.top), (x, p.top + p.height)], GRID, 1)?;
        }
    }

    // Value panel.
    let v = l.value;
    for (y, text) in &l.y_ticks {
        let py = v.py(*y);
        let yi = py.round() as i32;
        line(&area, vec![(v.left, yi), (v.left + v.width, yi)], GRID, 1)?;
        line(&area, vec![(v.left - 5, yi), (v.left, yi)], AXIS, 1)?;
        labels.push(Label::new(
            text.clone(),
            f64::from(v.left - 8),
            py,
            TICK_SIZE,
            HAlign::Right,
            VAlign::Middle,
        ));
    }
    frame(&area, &v)?;
    let points: Vec<Option<(i32, i32)>> = t
        .values
        .iter()
        .enumerate()
        .map(|(s, &y)| {
            y.is_finite()
                .then(|| (l.px(s as f64).round() as i32, v.py(y).round() as i32))
        })
        .collect();
    for run in points.split(Option::is_none) {
        let run: Vec<(i32, i32)> = run.iter().flatten().copied().collect();
        if run.len() >= 2 {
            line(&area, run, VALUE_LINE, 2)?;
        }
    }
    // Markers only while they stay apart.
    let radius = if l.steps <= 100 { 4 } else { 0 };
    for &(x, y) in points.iter().flatten().filter(|_| radius > 0) {
        area.draw(&Circle::new((x, y), radius, rgb(VALUE_LINE).filled()))
            .map_err(draw_err)?;
    }
    let value_title_size = fit_size(
        font,
        t.value_label,
        LABEL_SIZE,
        9.0,
        f64::from(v.height) - 8.0,
    );
    labels.push(
        Label::new(
            t.value_label,
            f64::from(l.y_title_x),
            f64::from(v.top) + f64::from(v.height) / 2.0,
            value_title_size,
            HAlign::Center,
            VAlign::Middle,
        )
        .vertical(),
    );

    // Category panel.
    if let (Some(c), Some((label, names, idx))) = (l.category, t.category) {
        for (k, name) in names.iter().enumerate() {
            let py = c.py(k as f64);
            let yi = py.round() as i32;
            line(&area, vec![(c.left, yi), (c.left + c.width, yi)], GRID, 1)?;
            line(&area, vec![(c.left - 5, yi), (c.left, yi)], AXIS, 1)?;
            labels.push(Label::new(
                name.clone(),
                f64::from(c.left - 8),
                py,
                TICK_SIZE,
                HAlign::Right,
                VAlign::Middle,
            ));
        }
        frame(&area, &c)?;
        let half = f64::from(c.width) / l.steps as f64 / 2.0;
        let levels: Vec<Option<i32>> = idx
            .iter()
            .map(|&k| (k < names.len()).then(|| c.py(k as f64).round() as i32))
            .collect();
        // Step line: level k_s held over [s - 1/2, s + 1/2], joined vertically.
        let mut path: Vec<(i32, i32)> = Vec::new();
        for (s, level) in levels.iter().enumerate() {
            let Some(y) = *level else {
                if path.len() >= 2 {
                    line(&area, std::mem::take(&mut path), CATEGORY_LINE, 2)?;
                }
                path.clear();
                continue;
            };
            let x = l.px(s as f64);
            path.push(((x - half).round() as i32, y));
            path.push(((x + half).round() as i32, y));
        }
        if path.len() >= 2 {
            line(&area, path, CATEGORY_LINE, 2)?;
        }
        let r = if l.steps <= 100 { 3 } else { 0 };
        for (s, level) in levels.iter().enumerate().filter(|_| r > 0) {
            if let Some(y) = *level {
                let x = l.px(s as f64).round() as i32;
                area.draw(&Circle::new((x, y), r, rgb(CATEGORY_LINE).filled()))
                    .map_err(draw_err)?;
            }
        }
        let size = fit_size(font, label, LABEL_SIZE, 9.0, f64::from(c.height) - 4.0);
        labels.push(
            Label::new(
                label,
                f64::from(l.y_title_x),
                f64::from(c.top) + f64::from(c.height) / 2.0,
                size,
                HAlign::Center,
                VAlign::Middle,
            )
            .vertical(),
        );
    }

    // x axis: ticks under the lowest panel, step numbers, actions, title.
    let bottom = panels.last().map_or(v, |p| *p);
    let axis_y = bottom.top + bottom.height;
    for &s in &l.x_ticks {
        let x = l.px(s as f64);
        let xi = x.round() as i32;
        line(&area, vec![(xi, axis_y), (xi, axis_y + 5)], AXIS, 1)?;
        labels.push(Label::new(
            s.to_string(),
            x,
            f64::from(l.x_labels_top),
            TICK_SIZE,
            HAlign::Center,
            VAlign::Top,
        ));
        if let (Some(rotated), Some(Some(action))) = (l.actions, t.actions.get(s)) {
            let y = f64::from(l.x_labels_top + 22);
            let label = if rotated {
                Label::new(
                    action.clone(),
                    x,
                    y,
                    TICK_SIZE,
                    HAlign::Right,
                    VAlign::Middle,
                )
                .vertical()
            } else {
                Label::new(action.clone(), x, y, TICK_SIZE, HAlign::Center, VAlign::Top)
            };
            labels.push(label.color([70, 70, 70]));
        }
    }
    let x_title = if l.actions.is_some() {
        "step t (action taken before the step)"
    } else {
        "step t"
    };
    labels.push(Label::new(
        x_title,
        f64::from(v.left) + f64::from(v.width) / 2.0,
        f64::from(l.x_title_y),
        LABEL_SIZE,
        HAlign::Center,
        VAlign::Middle,
    ));
    area.present().map_err(draw_err)
}

// ---------------------------------------------------------------------------------------
// Learning curve
// ---------------------------------------------------------------------------------------

/// One row of a learning curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurvePoint {
    /// Environment steps taken so far (the x axis).
    pub env_steps: u64,
    /// Fraction of the finished episodes that succeeded, in [0, 1]; NaN = none finished.
    pub success_rate: f64,
    /// Mean extrinsic return of the finished episodes; NaN = none finished.
    pub extrinsic_return: f64,
    /// Mean intrinsic reward per step; NaN = not computed.
    pub intrinsic_mean: f64,
}

const CURVE_WIDTH: u32 = 800;
const CURVE_HEIGHT: u32 = 600;
const SUCCESS_LINE: Rgb = [44, 160, 44];
const EXTRINSIC_LINE: Rgb = VALUE_LINE;
const INTRINSIC_LINE: Rgb = CATEGORY_LINE;

/// Where everything of a learning curve goes, in pixels.
#[derive(Debug, Clone)]
struct CurveLayout {
    width: u32,
    height: u32,
    title_size: f32,
    x_lo: f64,
    x_hi: f64,
    x_ticks: Vec<(f64, String)>,
    success: Panel,
    success_ticks: Vec<(f64, String)>,
    returns: Panel,
    returns_ticks: Vec<(f64, String)>,
    /// x of the rotated y axis titles.
    y_title_x: i32,
    /// Top of the x tick labels.
    x_labels_top: i32,
    /// Centre line of the x axis title.
    x_title_y: i32,
    /// Centre line of the legend (between the panels).
    legend_y: i32,
}

/// `lo..hi` widened to whole multiples of a nice step; ticks in it with their labels.
fn nice_range(lo: f64, hi: f64, max_ticks: usize) -> (f64, f64, Vec<(f64, String)>) {
    let (_, step) = nice_ticks(lo, hi, max_ticks);
    let (mut a, mut b) = ((lo / step).floor() * step, (hi / step).ceil() * step);
    if !(a.is_finite() && b.is_finite() && (b - a).is_finite() && b > a) {
        (a, b) = (lo, hi);
    }
    let (ticks, step) = nice_ticks(a, b, max_ticks + 1);
    let d = decimals_for(step);
    let ticks = ticks.into_iter().map(|v| (v, format_value(v, d))).collect();
    (a, b, ticks)
}

/// A step count as a short label: `0`, `500`, `25k`, `2.5M`, `1G`.
fn format_steps(v: f64, step: f64, hi: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let (unit, suffix) = match hi {
        h if h >= 1e9 => (1e9, "G"),
        h if h >= 1e6 => (1e6, "M"),
        h if h >= 1e4 => (1e3, "k"),
        _ => (1.0, ""),
    };
    let d = decimals_for(step / unit);
    format!("{}{suffix}", format_value(v / unit, d))
}

impl CurveLayout {
    fn new(points: &[CurvePoint], title: &str, font: &FontRef<'static>) -> Self {
        let (width, height) = (CURVE_WIDTH, CURVE_HEIGHT);
        let margin = 14;
        let title_size = fit_size(
            font,
            title,
            TITLE_SIZE,
            9.0,
            f64::from(width) - 2.0 * f64::from(margin),
        );

        // x: from 0 to just past the last step, so that its marker clears the frame; at
        // least to 10, so that the ticks stay whole steps.
        let max_steps = points.iter().map(|p| p.env_steps).max().unwrap_or(0);
        let x_hi = (max_steps as f64).max(10.0) * 1.02;
        let (ticks, step) = nice_ticks(0.0, x_hi, 9);
        let x_ticks = ticks
            .into_iter()
            .map(|v| (v, format_steps(v, step, x_hi)))
            .collect();

        // Success rate: always 0..1.
        let (_, _, success_ticks) = nice_range(0.0, 1.0, 5);

        // Returns and intrinsic reward share the lower panel's axis.
        let fin = points
            .iter()
            .flat_map(|p| [p.extrinsic_return, p.intrinsic_mean])
            .filter(|v| v.is_finite());
        let (mut lo, mut hi) = fin.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        if !(lo.is_finite() && hi.is_finite()) {
            (lo, hi) = (0.0, 1.0);
        } else if hi - lo <= 0.0 {
            // One value: a range around it (0..v or v..0, 0..1 for 0).
            let v = lo;
            (lo, hi) = if v > 0.0 {
                (0.0, v)
            } else if v < 0.0 {
                (v, 0.0)
            } else {
                (0.0, 1.0)
            };
        }
        if !(hi - lo).is_finite() {
            (lo, hi) = (lo / 2.0, hi / 2.0);
        }
        let (r_lo, r_hi, returns_ticks) = nice_range(lo, hi, 6);

        let tick_w = success_ticks
            .iter()
            .chain(&returns_ticks)
            .map(|(_, s)| text_width(font, s, TICK_SIZE))
            .fold(0.0, f64::max)
            .min(200.0);
        let y_title_x = margin + 10;
        let left = y_title_x + 14 + tick_w.ceil() as i32 + 12;
        let plot_w = width as i32 - left - 28;
        let top = 46;
        let panel_h = 205;
        let legend_gap = 40;
        let success = Panel {
            left,
            top,
            width: plot_w,
            height: panel_h,
            y_lo: 0.0,
            y_hi: 1.0,
        };
        let returns = Panel {
            left,
            top: top + panel_h + legend_gap,
            width: plot_w,
            height: panel_h + 20,
            y_lo: r_lo,
            y_hi: r_hi,
        };
        let x_labels_top = returns.top + returns.height + 8;
        Self {
            width,
            height,
            title_size,
            x_lo: 0.0,
            x_hi,
            x_ticks,
            success,
            success_ticks,
            returns,
            returns_ticks,
            y_title_x,
            x_labels_top,
            x_title_y: x_labels_top + 20 + 18,
            legend_y: top + panel_h + legend_gap / 2,
        }
    }

    /// Pixel x of `steps`.
    fn px(&self, steps: f64) -> f64 {
        let t = (steps - self.x_lo) / (self.x_hi - self.x_lo);
        let t = if t.is_finite() { t } else { 0.0 };
        f64::from(self.success.left) + t * f64::from(self.success.width)
    }
}

/// Draws a learning curve as a PNG at `path` (written atomically), 800 x 600 pixels:
/// the success rate (0..1) over environment steps on top; the mean extrinsic return and
/// the mean intrinsic reward per step (on the same axis, with a legend) below.
///
/// Points are drawn in order of `env_steps`; NaN and infinite values are skipped (the
/// line joins the neighbouring points). With no points the axes are drawn empty; a
/// single point is drawn as a dot.
pub fn learning_curve_png(
    path: &Path,
    title: &str,
    points: &[CurvePoint],
) -> Result<(), PlotError> {
    let font = fonts(path)?;
    let layout = CurveLayout::new(points, title, font);
    let (width, height) = (layout.width, layout.height);
    let mut buf = vec![255u8; width as usize * height as usize * 3];
    let mut labels = Vec::new();
    draw_curve(&mut buf, &layout, title, points, &mut labels).map_err(|message| {
        PlotError::Draw {
            path: path.to_path_buf(),
            message,
        }
    })?;
    let mut canvas = Canvas {
        buf: &mut buf,
        width,
        height,
    };
    for label in &labels {
        canvas.text(font, label);
    }
    save_png(path, &buf, width, height)
}

/// One series in a panel: a line through its finite points, markers when they are few,
/// a dot when there is only one. Values outside the panel's range are clamped to it.
fn series(
    area: &Area<'_>,
    l: &CurveLayout,
    p: &Panel,
    pts: &[(f64, f64)],
    color: Rgb,
) -> Result<(), String> {
    let clamp = |y: f64| y.clamp(f64::from(p.top), f64::from(p.top + p.height));
    let pix: Vec<(i32, i32)> = pts
        .iter()
        .filter(|(_, y)| y.is_finite())
        .map(|&(x, y)| (l.px(x).round() as i32, clamp(p.py(y)).round() as i32))
        .collect();
    if pix.len() >= 2 {
        line(area, pix.clone(), color, 2)?;
    }
    let radius = match pix.len() {
        1 => 4,
        n if n <= 25 => 3,
        _ => 0,
    };
    for &(x, y) in pix.iter().filter(|_| radius > 0) {
        area.draw(&Circle::new((x, y), radius, rgb(color).filled()))
            .map_err(draw_err)?;
    }
    Ok(())
}

/// Grid lines, the frame, y ticks and the rotated y title of a panel.
fn curve_panel(
    area: &Area<'_>,
    l: &CurveLayout,
    p: &Panel,
    ticks: &[(f64, String)],
    title: &str,
    labels: &mut Vec<Label>,
) -> Result<(), String> {
    let font = font().ok_or("the embedded font could not be loaded")?;
    for (x, _) in &l.x_ticks {
        let xi = l.px(*x).round() as i32;
        line(area, vec![(xi, p.top), (xi, p.top + p.height)], GRID, 1)?;
    }
    for (y, text) in ticks {
        let py = p.py(*y);
        let yi = py.round() as i32;
        line(area, vec![(p.left, yi), (p.left + p.width, yi)], GRID, 1)?;
        line(area, vec![(p.left - 5, yi), (p.left, yi)], AXIS, 1)?;
        labels.push(Label::new(
            text.clone(),
            f64::from(p.left - 8),
            py,
            TICK_SIZE,
            HAlign::Right,
            VAlign::Middle,
        ));
    }
    frame(area, p)?;
    let size = fit_size(font, title, LABEL_SIZE, 9.0, f64::from(p.height) - 8.0);
    labels.push(
        Label::new(
            title,
            f64::from(l.y_title_x),
            f64::from(p.top) + f64::from(p.height) / 2.0,
            size,
            HAlign::Center,
            VAlign::Middle,
        )
        .vertical(),
    );
    Ok(())
}

fn draw_curve(
    buf: &mut [u8],
    l: &CurveLayout,
    title: &str,
    points: &[CurvePoint],
    labels: &mut Vec<Label>,
) -> Result<(), String> {
    let font = font().ok_or("the embedded font could not be loaded")?;
    let area = BitMapBackend::with_buffer(buf, (l.width, l.height)).into_drawing_area();
    area.fill(&WHITE).map_err(draw_err)?;
    labels.push(Label::new(
        title,
        f64::from(l.width) / 2.0,
        22.0,
        l.title_size,
        HAlign::Center,
        VAlign::Middle,
    ));

    let mut sorted: Vec<&CurvePoint> = points.iter().collect();
    sorted.sort_by_key(|p| p.env_steps);
    let xy = |f: fn(&CurvePoint) -> f64| -> Vec<(f64, f64)> {
        sorted.iter().map(|p| (p.env_steps as f64, f(p))).collect()
    };

    curve_panel(
        &area,
        l,
        &l.success,
        &l.success_ticks,
        "success rate",
        labels,
    )?;
    series(&area, l, &l.success, &xy(|p| p.success_rate), SUCCESS_LINE)?;

    let r = l.returns;
    curve_panel(&area, l, &r, &l.returns_ticks, "reward", labels)?;
    if r.y_lo < 0.0 && r.y_hi > 0.0 {
        let y0 = r.py(0.0).round() as i32;
        line(
            &area,
            vec![(r.left, y0), (r.left + r.width, y0)],
            [170, 170, 170],
            1,
        )?;
    }
    series(&area, l, &r, &xy(|p| p.intrinsic_mean), INTRINSIC_LINE)?;
    series(&area, l, &r, &xy(|p| p.extrinsic_return), EXTRINSIC_LINE)?;

    // Legend, right-aligned between the panels: a line sample and a name per series.
    let entries = [
        ("extrinsic return (mean per episode)", EXTRINSIC_LINE),
        ("E per step (bits, before beta)", INTRINSIC_LINE),
    ];
    let mut x = f64::from(r.left + r.width);
    let y = l.legend_y;
    for (name, color) in entries.iter().rev() {
        let w = text_width(font, name, TICK_SIZE);
        labels.push(Label::new(
            *name,
            x,
            f64::from(y),
            TICK_SIZE,
            HAlign::Right,
            VAlign::Middle,
        ));
        x -= w + 6.0;
        let xi = x.round() as i32;
        line(&area, vec![(xi - 22, y), (xi, y)], *color, 3)?;
        x -= 22.0 + 18.0;
    }

    // x axis under the lower panel.
    let axis_y = r.top + r.height;
    for (v, text) in &l.x_ticks {
        let x = l.px(*v);
        let xi = x.round() as i32;
        line(&area, vec![(xi, axis_y), (xi, axis_y + 5)], AXIS, 1)?;
        labels.push(Label::new(
            text.clone(),
            x,
            f64::from(l.x_labels_top),
            TICK_SIZE,
            HAlign::Center,
            VAlign::Top,
        ));
    }
    labels.push(Label::new(
        "environment steps",
        f64::from(r.left) + f64::from(r.width) / 2.0,
        f64::from(l.x_title_y),
        LABEL_SIZE,
        HAlign::Center,
        VAlign::Middle,
    ));
    area.present().map_err(draw_err)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs;
    use std::sync::atomic::{AtomicU64, Ordering};

    /// A fresh directory under the system temp dir, removed on drop.
    struct TempDir(PathBuf);

    impl TempDir {
        fn new(tag: &str) -> Self {
            static N: AtomicU64 = AtomicU64::new(0);
            let dir = std::env::temp_dir().join(format!(
                "fulcrum-plot-{tag}-{}-{}",
                std::process::id(),
                N.fetch_add(1, Ordering::Relaxed)
            ));
            fs::create_dir_all(&dir).expect("create temp dir");
            Self(dir)
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = fs::remove_dir_all(&self.0);
        }
    }

    struct Image {
        width: u32,
        height: u32,
        rgb: Vec<u8>,
    }

    impl Image {
        fn pixel(&self, x: i32, y: i32) -> Rgb {
            let i = (y as usize * self.width as usize + x as usize) * 3;
            [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
        }
    }

    fn decode(path: &Path) -> Image {
        let bytes = fs::read(path).expect("read png");
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
        let decoder = png::Decoder::new(io::Cursor::new(bytes));
        let mut reader = decoder.read_info().expect("png header");
        let mut rgb = vec![0; reader.output_buffer_size().expect("buffer size")];
        let info = reader.next_frame(&mut rgb).expect("png frame");
        assert_eq!(info.color_type, png::ColorType::Rgb);
        assert_eq!(info.bit_depth, png::BitDepth::Eight);
        rgb.truncate(info.buffer_size());
        Image {
            width: info.width,
            height: info.height,
            rgb,
        }
    }

    fn no_temp_files(dir: &Path) -> bool {
        fs::read_dir(dir).expect("read dir").all(|e| {
            !e.expect("entry")
                .file_name()
                .to_string_lossy()
                .contains(".tmp-")
        })
    }

    type Grid<T> = Vec<Vec<T>>;
    type Category<'a> = Option<(&'a str, &'a [String], &'a [usize])>;
    type Case<'a> = (Vec<f64>, &'a [Option<String>], Category<'a>);

    /// A 12x8 map with a rock border and a few values.
    fn example_grid() -> (Grid<Option<f64>>, Grid<bool>, Grid<Option<char>>) {
        let (w, h) = (12, 8);
        let mut values = vec![vec![None; w]; h];
        let mut rock = vec![vec![false; w]; h];
        let mut glyphs = vec![vec![None; w]; h];
        for y in 0..h {
            for x in 0..w {
                if x == 0 || y == 0 || x == w - 1 || y == h - 1 || (x == 6 && y != 4) {
                    rock[y][x] = true;
                } else if (x + y) % 7 != 3 {
                    let v = [0.0, 1.0, 1.58, 2.0, 0.58][(x * 3 + y) % 5];
                    values[y][x] = Some(v);
                }
            }
        }
        values[1][1] = Some(0.0);
        values[1][2] = Some(2.0);
        values[2][2] = Some(f64::NAN);
        glyphs[2][3] = Some('T');
        glyphs[3][8] = Some('a');
        glyphs[5][9] = Some('+');
        (values, rock, glyphs)
    }

    fn example_trace() -> (Vec<f64>, Vec<Option<String>>, Vec<String>, Vec<usize>) {
        let values = vec![0.0, 0.0, 0.58, 1.0, 1.0, 1.58, 2.0, 2.0, 1.0, 0.0, 0.0, 0.0];
        let names = [
            "right", "right", "pick up", "down", "down", "toggle", "right", "open", "left", "noop",
            "noop",
        ];
        let mut actions = vec![None];
        actions.extend(names.iter().map(|s| Some((*s).to_string())));
        let cats = vec!["closed".to_string(), "open".into(), "destroyed".into()];
        let door = vec![0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 2, 2];
        (values, actions, cats, door)
    }

    #[test]
    fn heatmap_png_has_cells_colours_and_dark_rock() {
        let dir = TempDir::new("heatmap");
        let path = dir.0.join("heat.png");
        let (values, rock, glyphs) = example_grid();
        let h = Heatmap {
            title: "E^3 of the key per cell",
            values: &values,
            rock: &rock,
            glyphs: Some(&glyphs),
            unit: "bits",
        };
        heatmap_png(&path, &h).expect("heatmap");
        let img = decode(&path);
        let layout = HeatmapLayout::new(&path, &h, font().expect("font")).expect("layout");
        assert_eq!((img.width, img.height), (layout.width, layout.height));
        assert_eq!(layout.cell, 40);
        assert!(img.width >= 12 * 40 && img.height >= 8 * 40);
        // A pixel near the bottom-right corner of a cell: away from the printed text.
        let probe = |x: usize, y: usize| {
            let (x0, y0) = layout.cell_origin(x, y);
            img.pixel(x0 + layout.cell - 5, y0 + layout.cell - 5)
        };
        let low = probe(1, 1); // 0.0
        let high = probe(2, 1); // 2.0
        assert_ne!(low, high, "high and low cells share a colour");
        assert_eq!(low, viridis(0.0));
        assert_eq!(high, viridis(1.0));
        let luma = |c: Rgb| c.iter().map(|&v| u32::from(v)).sum::<u32>() / 3;
        for (x, y) in [(0, 0), (11, 7), (6, 2)] {
            let (x0, y0) = layout.cell_origin(x, y);
            let centre = img.pixel(x0 + layout.cell / 2, y0 + layout.cell / 2);
            assert!(
                luma(centre) < 60,
                "rock cell ({x},{y}) is not dark: {centre:?}"
            );
        }
        // NaN is drawn as "no value".
        assert_eq!(probe(2, 2), NO_VALUE);
        // The value is printed: the centre of a cell holds text-coloured pixels.
        let (x0, y0) = layout.cell_origin(2, 1);
        let text = text_on(viridis(1.0));
        let near = |a: Rgb, b: Rgb| (0..3).all(|k| a[k].abs_diff(b[k]) < 80);
        let inked = (x0..x0 + layout.cell)
            .flat_map(|x| (y0..y0 + layout.cell).map(move |y| (x, y)))
            .filter(|&(x, y)| near(img.pixel(x, y), text))
            .count();
        assert!(
            inked > 20,
            "no printed value in the cell ({inked} ink pixels)"
        );
        assert!(no_temp_files(&dir.0));
    }

    #[test]
    fn trace_png_writes_a_picture_with_both_panels() {
        let dir = TempDir::new("trace");
        let path = dir.0.join("trace.png");
        let (values, actions, cats, door) = example_trace();
        let t = Trace {
            title: "E^3 key -> door along an episode",
            value_label: "E^3 key -> door (bits)",
            values: &values,
            actions: &actions,
            category: Some(("door", &cats, &door)),
        };
        trace_png(&path, &t).expect("trace");
        let img = decode(&path);
        let layout = TraceLayout::new(&path, &t, font().expect("font")).expect("layout");
        assert_eq!((img.width, img.height), (layout.width, layout.height));
        assert!(layout.category.is_some());
        assert_eq!(layout.actions, Some(false));
        assert!((layout.value.y_hi - 2.2).abs() < 1e-9);
        // The marker of step 6 (value 2) is drawn in the line colour.
        let (x, y) = (layout.px(6.0), layout.value.py(2.0));
        assert_eq!(img.pixel(x.round() as i32, y.round() as i32), VALUE_LINE);
        // The door is "destroyed" at the last step.
        let c = layout.category.expect("category panel");
        let (x, y) = (layout.px(11.0), c.py(2.0));
        assert_eq!(img.pixel(x.round() as i32, y.round() as i32), CATEGORY_LINE);
        assert!(no_temp_files(&dir.0));
    }

    #[test]
    fn degenerate_inputs_do_not_panic() {
        let dir = TempDir::new("degenerate");
        let p = |name: &str| dir.0.join(name);
        // Empty grids are an error naming the file.
        let e = heatmap_png(
            &p("empty.png"),
            &Heatmap {
                title: "",
                values: &[],
                rock: &[],
                glyphs: None,
                unit: "",
            },
        )
        .expect_err("empty grid");
        assert!(matches!(e, PlotError::NoData { .. }));
        assert!(e.to_string().contains("empty.png"), "{e}");
        assert!(!p("empty.png").exists());
        let empty_rows = vec![Vec::new(), Vec::new()];
        assert!(heatmap_png(
            &p("rows.png"),
            &Heatmap {
                title: "t",
                values: &empty_rows,
                rock: &[],
                glyphs: None,
                unit: "bits",
            },
        )
        .is_err());

        // All equal, all NaN / infinite, ragged rows, extreme values, one cell.
        let grids: Vec<Vec<Vec<Option<f64>>>> = vec![
            vec![vec![Some(1.0); 3]; 2],
            vec![vec![Some(0.0); 3]; 2],
            vec![vec![Some(-2.0); 3]; 2],
            vec![vec![Some(f64::NAN), Some(f64::INFINITY), None]],
            vec![vec![Some(1.0)], vec![Some(2.0), None, Some(3.0)], vec![]],
            vec![vec![
                Some(f64::MAX),
                Some(-f64::MAX),
                Some(1e300),
                Some(-12345.678),
            ]],
            vec![vec![Some(1e-9), Some(2e-9)]],
            vec![vec![Some(0.5)]],
            vec![vec![None; 300]; 90],
        ];
        let rock = vec![vec![true, false], vec![false; 7]];
        let glyphs = vec![vec![Some('é'), Some('\u{1F600}'), Some('\0')]];
        for (i, g) in grids.iter().enumerate() {
            let path = p(&format!("grid{i}.png"));
            heatmap_png(
                &path,
                &Heatmap {
                    title: "a title that is rather long for such a small grid, isn't it?",
                    values: g,
                    rock: &rock,
                    glyphs: Some(&glyphs),
                    unit: "",
                },
            )
            .expect("degenerate grid draws");
            decode(&path);
        }
        let huge = vec![vec![None; MAX_GRID_SIDE + 1]];
        assert!(matches!(
            heatmap_png(
                &p("huge.png"),
                &Heatmap {
                    title: "",
                    values: &huge,
                    rock: &[],
                    glyphs: None,
                    unit: "",
                }
            ),
            Err(PlotError::TooLarge { .. })
        ));

        // Traces.
        let e = trace_png(
            &p("t0.png"),
            &Trace {
                title: "",
                value_label: "",
                values: &[],
                actions: &[],
                category: None,
            },
        )
        .expect_err("empty trace");
        assert!(matches!(e, PlotError::NoData { .. }));
        assert!(e.to_string().contains("t0.png"), "{e}");
        let names = vec!["a".to_string(), "b".to_string()];
        let no_names: Vec<String> = Vec::new();
        let long: Vec<f64> = (0..500).map(|i| f64::from(i).sin()).collect();
        let many_actions: Vec<Option<String>> = (0..40)
            .map(|i| Some(format!("action number {i}")))
            .collect();
        let cases: Vec<Case<'_>> = vec![
            (vec![1.0], &[], None),
            (vec![f64::NAN, f64::INFINITY, -f64::INFINITY], &[], None),
            (
                vec![-3.0, 2.0, f64::NAN, 4.0],
                &[],
                Some(("c", &names, &[0, 5, 1])),
            ),
            (vec![], &[], Some(("c", &names, &[0, 1, 1]))),
            (vec![1.0, 2.0], &[], Some(("c", &no_names, &[0, 1]))),
            (vec![f64::MAX, -f64::MAX], &[], None),
            (long, &[], Some(("door", &names, &[1; 500]))),
            (vec![0.5; 40], &many_actions, None),
        ];
        for (i, (values, actions, category)) in cases.iter().enumerate() {
            let path = p(&format!("trace{i}.png"));
            trace_png(
                &path,
                &Trace {
                    title: "trace",
                    value_label:
                        "a y label much longer than the panel is high, so it has to shrink",
                    values,
                    actions,
                    category: *category,
                },
            )
            .expect("degenerate trace draws");
            decode(&path);
        }
        assert!(no_temp_files(&dir.0));
    }

    #[test]
    fn plot_errors_name_the_file() {
        let dir = TempDir::new("atomic");
        // Errors from the plot functions name the file.
        let e = heatmap_png(
            &dir.0.join("missing").join("h.png"),
            &Heatmap {
                title: "",
                values: &[vec![Some(1.0)]],
                rock: &[],
                glyphs: None,
                unit: "",
            },
        )
        .expect_err("missing dir");
        assert!(matches!(e, PlotError::Io { .. }));
        assert!(e.to_string().contains("h.png"), "{e}");
    }

    #[test]
    fn helpers_are_sane() {
        assert_eq!(viridis(f64::NAN), VIRIDIS[0]);
        assert_eq!(viridis(2.0), VIRIDIS[8]);
        assert_eq!(format_value(1.0, 2), "1.00");
        assert_eq!(format_value(1.584_962_5, 2), "1.58");
        assert_eq!(format_value(-0.001, 2), "0.00");
        let (ticks, step) = nice_ticks(0.0, 2.2, 7);
        assert_eq!(step, 0.5);
        assert_eq!(ticks, vec![0.0, 0.5, 1.0, 1.5, 2.0]);
        assert_eq!(decimals_for(0.5), 1);
        assert_eq!(decimals_for(0.25), 2);
        assert_eq!(decimals_for(2.0), 0);
        assert!(nice_ticks(f64::NAN, 1.0, 5).0.is_empty());
    }

    fn synthetic_curve(n: usize) -> Vec<CurvePoint> {
        (0..n)
            .map(|i| {
                let t = i as f64 / n.max(2) as f64;
                CurvePoint {
                    env_steps: (i as u64 + 1) * 40_960,
                    success_rate: 1.0 / (1.0 + (-10.0 * (t - 0.5)).exp()),
                    extrinsic_return: -0.4 + 1.3 * t + 0.05 * (i as f64).sin(),
                    intrinsic_mean: 0.3 * (-3.0 * t).exp(),
                }
            })
            .collect()
    }

    #[test]
    fn learning_curve_png_draws_both_panels() {
        let dir = TempDir::new("curve");
        let path = dir.0.join("curve.png");
        let points = synthetic_curve(50);
        learning_curve_png(&path, "PPO + object empowerment, key-door", &points).expect("curve");
        let img = decode(&path);
        assert_eq!((img.width, img.height), (CURVE_WIDTH, CURVE_HEIGHT));
        let first = img.pixel(0, 0);
        assert!(
            img.rgb.chunks_exact(3).any(|p| p != first),
            "the picture is a single colour"
        );
        let count = |c: Rgb| img.rgb.chunks_exact(3).filter(|p| *p == c).count();
        for (name, c) in [
            ("success", SUCCESS_LINE),
            ("extrinsic", EXTRINSIC_LINE),
            ("intrinsic", INTRINSIC_LINE),
        ] {
            assert!(
                count(c) > 200,
                "the {name} line is missing ({} px)",
                count(c)
            );
        }
        // The success line reaches the last point where the layout says.
        let layout = CurveLayout::new(&points, "t", font().expect("font"));
        let last = points[49];
        let (x, y) = (
            layout.px(last.env_steps as f64),
            layout.success.py(last.success_rate),
        );
        let (x, y) = (x.round() as i32, y.round() as i32);
        assert!(
            (-2..=2).any(|dx| (-2..=2).any(|dy| img.pixel(x + dx, y + dy) == SUCCESS_LINE)),
            "no success line at the last point ({x}, {y})"
        );
        assert!(layout.returns.y_lo <= -0.4 && layout.returns.y_hi >= 0.9);
        assert!(layout.x_hi >= 50.0 * 40_960.0);
        // Tick labels of steps are short.
        assert!(
            layout.x_ticks.iter().any(|(_, s)| s.ends_with('M')),
            "{:?}",
            layout.x_ticks
        );
        assert!(no_temp_files(&dir.0));
    }

    #[test]
    fn learning_curve_edge_cases_do_not_panic() {
        let dir = TempDir::new("curve-edge");
        let nan = f64::NAN;
        let pt = |s: u64, a: f64, b: f64, c: f64| CurvePoint {
            env_steps: s,
            success_rate: a,
            extrinsic_return: b,
            intrinsic_mean: c,
        };
        let mut mixed = synthetic_curve(30);
        for (i, p) in mixed.iter_mut().enumerate() {
            if i % 4 == 1 {
                p.success_rate = nan;
                p.extrinsic_return = f64::INFINITY;
            }
        }
        mixed.reverse();
        let cases: Vec<Vec<CurvePoint>> = vec![
            vec![],
            vec![pt(0, 0.5, 1.0, 0.1)],
            vec![pt(12_345, nan, nan, nan)],
            vec![pt(0, nan, nan, nan), pt(10, nan, nan, nan)],
            vec![pt(100, 2.0, -5.0, -5.0), pt(100, -1.0, -5.0, -5.0)],
            vec![
                pt(u64::MAX, 1.0, f64::MAX, -f64::MAX),
                pt(0, 0.0, 0.0, 1e-300),
            ],
            vec![pt(5, 0.0, 0.0, 0.0); 3],
            mixed,
            synthetic_curve(5000),
        ];
        for (i, points) in cases.iter().enumerate() {
            let path = dir.0.join(format!("curve{i}.png"));
            learning_curve_png(&path, "a learning curve", points).expect("curve draws");
            let img = decode(&path);
            assert_eq!((img.width, img.height), (CURVE_WIDTH, CURVE_HEIGHT));
        }
        // A single point is drawn as a dot.
        let path = dir.0.join("dot.png");
        learning_curve_png(&path, "", &[pt(1000, 0.5, 1.0, 0.1)]).expect("dot");
        let img = decode(&path);
        let count = |c: Rgb| img.rgb.chunks_exact(3).filter(|p| *p == c).count();
        assert!(count(SUCCESS_LINE) > 10 && count(EXTRINSIC_LINE) > 10);
        // A long title shrinks rather than widening the picture.
        let path = dir.0.join("long.png");
        learning_curve_png(&path, &"a very long title ".repeat(20), &[]).expect("long");
        assert_eq!(decode(&path).width, CURVE_WIDTH);
        // Errors name the file.
        let e = learning_curve_png(&dir.0.join("missing").join("c.png"), "", &[])
            .expect_err("missing dir");
        assert!(e.to_string().contains("c.png"), "{e}");
        assert!(no_temp_files(&dir.0));
        assert_eq!(format_steps(0.0, 500.0, 5000.0), "0");
        assert_eq!(format_steps(2_500_000.0, 2_500_000.0, 1e7), "2.5M");
        assert_eq!(format_steps(20_000.0, 10_000.0, 1e5), "20k");
        assert_eq!(format_steps(750.0, 250.0, 1000.0), "750");
        // Step ticks are whole numbers even for a run with almost no steps.
        for n in [0, 1, 3] {
            let layout = CurveLayout::new(&[pt(n, 0.0, 0.0, 0.0)], "", font().expect("font"));
            assert!(
                layout
                    .x_ticks
                    .iter()
                    .all(|(v, s)| v.fract() == 0.0 && !s.contains('.')),
                "{:?}",
                layout.x_ticks
            );
        }
    }

    /// Renders the example pictures for looking at:
    /// `cargo test plot::tests::render_examples -- --ignored`.
    #[test]
    #[ignore = "writes /tmp/plot-heatmap.png, /tmp/plot-trace.png and /tmp/plot-curve.png for inspection"]
    fn render_examples() {
        let (values, rock, glyphs) = example_grid();
        heatmap_png(
            Path::new("/tmp/plot-heatmap.png"),
            &Heatmap {
                title: "E^3 of the key, per agent cell",
                values: &values,
                rock: &rock,
                glyphs: Some(&glyphs),
                unit: "bits",
            },
        )
        .expect("heatmap");
        let (values, actions, cats, door) = example_trace();
        trace_png(
            Path::new("/tmp/plot-trace.png"),
            &Trace {
                title: "E^3 key -> door along an episode",
                value_label: "E^3 key -> door (bits)",
                values: &values,
                actions: &actions,
                category: Some(("door", &cats, &door)),
            },
        )
        .expect("trace");
        learning_curve_png(
            Path::new("/tmp/plot-curve.png"),
            "PPO + object empowerment on key-door",
            &synthetic_curve(50),
        )
        .expect("curve");
    }
}
