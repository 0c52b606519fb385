//! Text from the embedded Hack font: labels, measuring, fitting and rasterising.

use std::path::Path;
use std::sync::OnceLock;

use crate::error::PlotError;
use crate::style::{Rgb, BLACK_TEXT, MAX_IMAGE_SIDE};
use ab_glyph::{point, Font, FontRef, PxScale, ScaleFont};
use plotters::prelude::*;

/// Registers the embedded Hack font with plotters under the families `sans-serif`,
/// `serif` and `monospace`, once per process; returns whether the font is usable.
///
/// [`crate::heatmap_png`] and [`crate::trace_png`] call this themselves. Code that draws plotters
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

/// The embedded font, parsed once.
pub(crate) fn font() -> Option<&'static FontRef<'static>> {
    static FONT: OnceLock<Option<FontRef<'static>>> = OnceLock::new();
    FONT.get_or_init(|| FontRef::try_from_slice(epaint_default_fonts::HACK_REGULAR).ok())
        .as_ref()
}

pub(crate) fn fonts(path: &Path) -> Result<&'static FontRef<'static>, PlotError> {
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

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum HAlign {
    Left,
    Center,
    Right,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum VAlign {
    Top,
    /// Centred on the capital / digit height: what looks centred for numbers.
    Middle,
}

/// A piece of text to draw after the shapes.
#[derive(Debug, Clone)]
pub(crate) struct Label {
    pub(crate) text: String,
    pub(crate) x: f64,
    pub(crate) y: f64,
    /// Pixel size (ab_glyph's `PxScale`: ascent - descent).
    pub(crate) size: f32,
    pub(crate) color: Rgb,
    pub(crate) h: HAlign,
    pub(crate) v: VAlign,
    /// Rotated 90° counter-clockwise (reads bottom to top); alignment is along the text.
    pub(crate) vertical: bool,
}

impl Label {
    pub(crate) fn new(
        text: impl Into<String>,
        x: f64,
        y: f64,
        size: f32,
        h: HAlign,
        v: VAlign,
    ) -> Self {
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

    pub(crate) fn color(mut self, color: Rgb) -> Self {
        self.color = color;
        self
    }

    pub(crate) fn vertical(mut self) -> Self {
        self.vertical = true;
        self
    }
}

/// Horizontal advance of `text` at `size` in pixels.
pub(crate) fn text_width(font: &FontRef<'static>, text: &str, size: f32) -> f64 {
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
pub(crate) fn fit_size(
    font: &FontRef<'static>,
    text: &str,
    size: f32,
    min: f32,
    avail: f64,
) -> f32 {
    let mut s = size;
    while s > min && text_width(font, text, s) > avail {
        s -= 0.5;
    }
    s
}

/// Text rendered to a coverage mask, with the anchor point in mask coordinates.
pub(crate) struct Mask {
    pub(crate) w: usize,
    pub(crate) h: usize,
    pub(crate) cover: Vec<f32>,
    pub(crate) anchor: (f64, f64),
}

pub(crate) fn render_mask(font: &FontRef<'static>, label: &Label) -> Option<Mask> {
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
