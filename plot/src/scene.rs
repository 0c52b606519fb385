//! A picture as a list of shapes and labels in pixels, rendered the same way to PNG
//! (plotters' bitmap backend for shapes, this crate's text renderer for labels) and to
//! SVG (the same shapes as SVG elements, labels as SVG text).

use std::fmt::Write as _;
use std::path::Path;

use crate::canvas::{draw_err, save_png, Canvas};
use crate::error::PlotError;
use crate::style::{rgb, Rgb};
use crate::text::{HAlign, Label, VAlign};
use fulcrum_contracts::fsio::write_atomic;
use plotters::prelude::*;

/// One element of a picture.
pub(crate) enum Shape {
    /// Filled polygon with an opacity in [0, 1].
    Fill(Vec<(f64, f64)>, Rgb, f64),
    /// Polyline of a width in pixels.
    Line(Vec<(f64, f64)>, Rgb, f64),
    /// Text.
    Text(Label),
}

/// Renders `shapes` on a white `width` x `height` picture and writes it as a PNG.
pub(crate) fn png(path: &Path, width: u32, height: u32, shapes: &[Shape]) -> Result<(), PlotError> {
    let buf = rasterize(path, width, height, shapes)?;
    save_png(path, &buf, width, height)
}

/// Renders `shapes` on a white `width` x `height` picture: RGB bytes, row-major
/// (`path` names the picture in errors).
pub(crate) fn rasterize(
    path: &Path,
    width: u32,
    height: u32,
    shapes: &[Shape],
) -> Result<Vec<u8>, PlotError> {
    let font = crate::text::fonts(path)?;
    let mut buf = vec![255u8; width as usize * height as usize * 3];
    {
        let area = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        let pix = |pts: &[(f64, f64)]| -> Vec<(i32, i32)> {
            pts.iter()
                .map(|&(x, y)| (x.round() as i32, y.round() as i32))
                .collect()
        };
        let fail = |message: String| PlotError::Draw {
            path: path.to_path_buf(),
            message,
        };
        for s in shapes {
            match s {
                Shape::Fill(pts, color, alpha) => area
                    .draw(&Polygon::new(pix(pts), rgb(*color).mix(*alpha).filled()))
                    .map_err(|e| fail(draw_err(e)))?,
                Shape::Line(pts, color, w) => area
                    .draw(&PathElement::new(
                        pix(pts),
                        rgb(*color).stroke_width(w.round() as u32),
                    ))
                    .map_err(|e| fail(draw_err(e)))?,
                Shape::Text(_) => {}
            }
        }
        area.present().map_err(|e| fail(draw_err(e)))?;
    }
    let mut canvas = Canvas {
        buf: &mut buf,
        width,
        height,
    };
    for s in shapes {
        if let Shape::Text(l) = s {
            canvas.text(font, l);
        }
    }
    Ok(buf)
}

fn hex(c: Rgb) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn points(pts: &[(f64, f64)]) -> String {
    pts.iter()
        .map(|(x, y)| format!("{x:.1},{y:.1}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Writes `shapes` as an SVG picture (text in the Hack font where installed, else any
/// monospace font).
pub(crate) fn svg(path: &Path, width: u32, height: u32, shapes: &[Shape]) -> Result<(), PlotError> {
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" viewBox=\"0 0 {width} {height}\" font-family=\"Hack, DejaVu Sans Mono, monospace\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    for shape in shapes {
        // Writing to a String cannot fail.
        let _ = match shape {
            Shape::Fill(pts, color, alpha) => writeln!(
                s,
                "<polygon points=\"{}\" fill=\"{}\" fill-opacity=\"{alpha}\" stroke=\"none\"/>",
                points(pts),
                hex(*color)
            ),
            Shape::Line(pts, color, width) => writeln!(
                s,
                "<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"{width}\" stroke-linejoin=\"round\"/>",
                points(pts),
                hex(*color)
            ),
            Shape::Text(l) => {
                let anchor = match l.h {
                    HAlign::Left => "start",
                    HAlign::Center => "middle",
                    HAlign::Right => "end",
                };
                let baseline = match l.v {
                    VAlign::Top => "hanging",
                    VAlign::Middle => "central",
                };
                let rotate = if l.vertical {
                    format!(" transform=\"rotate(-90 {:.1} {:.1})\"", l.x, l.y)
                } else {
                    String::new()
                };
                writeln!(
                    s,
                    "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"{:.1}\" fill=\"{}\" text-anchor=\"{anchor}\" dominant-baseline=\"{baseline}\"{rotate}>{}</text>",
                    l.x,
                    l.y,
                    l.size * 0.8,
                    hex(l.color),
                    escape(&l.text)
                )
            }
        };
    }
    s.push_str("</svg>\n");
    write_atomic(path, s.as_bytes()).map_err(|error| PlotError::Io {
        path: path.to_path_buf(),
        error,
    })
}
