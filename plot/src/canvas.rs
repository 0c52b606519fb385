//! The RGB buffer figures are drawn into, and writing it as a PNG.

use std::path::Path;

use crate::error::PlotError;
use crate::style::{rgb, Rgb};
use crate::text::{render_mask, Label};
use ab_glyph::FontRef;
use fulcrum_contracts::fsio::write_atomic;
use plotters::prelude::*;

pub(crate) fn save_png(path: &Path, rgb: &[u8], width: u32, height: u32) -> Result<(), PlotError> {
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

/// Draws a `width x height` picture: `draw` fills the RGB buffer with shapes and
/// collects the text, which is rendered on top with `font`; the PNG is written to
/// `path` atomically.
pub(crate) fn render_png(
    path: &Path,
    font: &FontRef<'static>,
    (width, height): (u32, u32),
    draw: impl FnOnce(&mut [u8], &mut Vec<Label>) -> Result<(), String>,
) -> Result<(), PlotError> {
    let mut buf = vec![255u8; width as usize * height as usize * 3];
    let mut labels = Vec::new();
    draw(&mut buf, &mut labels).map_err(|message| PlotError::Draw {
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

pub(crate) struct Canvas<'b> {
    pub(crate) buf: &'b mut [u8],
    pub(crate) width: u32,
    pub(crate) height: u32,
}

impl Canvas<'_> {
    pub(crate) fn blend(&mut self, x: i64, y: i64, color: Rgb, alpha: f32) {
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

    pub(crate) fn text(&mut self, font: &FontRef<'static>, label: &Label) {
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
pub(crate) fn draw_err<E: std::error::Error + Send + Sync>(
    e: plotters::drawing::DrawingAreaErrorKind<E>,
) -> String {
    e.to_string()
}

pub(crate) type Area<'b> = DrawingArea<BitMapBackend<'b>, plotters::coord::Shift>;

pub(crate) fn fill_rect(
    area: &Area<'_>,
    x0: i32,
    y0: i32,
    x1: i32,
    y1: i32,
    c: Rgb,
) -> Result<(), String> {
    area.draw(&Rectangle::new([(x0, y0), (x1, y1)], rgb(c).filled()))
        .map_err(draw_err)
}

pub(crate) fn line(
    area: &Area<'_>,
    pts: Vec<(i32, i32)>,
    c: Rgb,
    width: u32,
) -> Result<(), String> {
    area.draw(&PathElement::new(pts, rgb(c).stroke_width(width)))
        .map_err(draw_err)
}
