//! Band charts like the paper's Figs. 4, 7 and 13: per arm, the mean over seeds as a
//! line and mean +/- one standard deviation as a shaded band, one colour per arm, over
//! environment steps; as PNG ([`band_chart_png`]) and SVG ([`band_chart_svg`]).
//!
//! The chart is laid out once as a list of shapes and labels in pixels; the PNG renders
//! it with plotters' bitmap backend and this module's text renderer, the SVG writes the
//! same shapes as SVG elements, so the two files show the same picture.

use std::fmt::Write as _;
use std::path::Path;

use plotters::prelude::*;

use super::{
    draw_err, fonts, format_steps, nice_range, nice_ticks, rgb, save_png, text_width, write_atomic,
    Canvas, HAlign, Label, PlotError, Rgb, VAlign, AXIS, GRID, LABEL_SIZE, TICK_SIZE, TITLE_SIZE,
};

/// One arm's curve: mean and standard deviation at each x (NaN = no value there).
#[derive(Debug, Clone)]
pub struct Band {
    /// Legend name.
    pub name: String,
    /// Mean at each x.
    pub mean: Vec<f64>,
    /// Standard deviation at each x.
    pub std: Vec<f64>,
}

/// A band chart.
#[derive(Debug, Clone)]
pub struct BandChart {
    /// Title on top.
    pub title: String,
    /// y-axis title.
    pub y_label: String,
    /// Env steps of the points (shared by all bands).
    pub x: Vec<f64>,
    /// The arms, drawn in order (first underneath).
    pub bands: Vec<Band>,
    /// Fixed y range (e.g. 0..1 for a rate); None = fit the bands.
    pub y_range: Option<(f64, f64)>,
}

/// Arm colours: blue and green first, as in the paper (baseline blue, empowerment green).
const PALETTE: [Rgb; 8] = [
    [31, 119, 180],
    [44, 160, 44],
    [214, 39, 40],
    [255, 127, 14],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [23, 190, 207],
];
const BAND_ALPHA: f64 = 0.22;
const WIDTH: u32 = 820;
const HEIGHT: u32 = 520;

enum Shape {
    /// Filled polygon with opacity.
    Fill(Vec<(f64, f64)>, Rgb, f64),
    /// Polyline of a width.
    Line(Vec<(f64, f64)>, Rgb, f64),
    Text(Label),
}

/// The chart as shapes in pixel coordinates.
fn layout(c: &BandChart, font: &ab_glyph::FontRef<'static>) -> Vec<Shape> {
    let mut out = Vec::new();
    let x_lo = 0.0;
    let x_hi =
        c.x.iter()
            .copied()
            .filter(|v| v.is_finite())
            .fold(10.0, f64::max);
    let (y_lo, y_hi, y_ticks) = match c.y_range {
        Some((lo, hi)) => nice_range(lo, hi, 5),
        None => {
            let vals = c.bands.iter().flat_map(|b| {
                b.mean
                    .iter()
                    .zip(&b.std)
                    .flat_map(|(m, s)| [m - s.max(0.0), m + s.max(0.0), *m])
            });
            let (lo, hi) = vals
                .filter(|v| v.is_finite())
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(v), b.max(v))
                });
            let (lo, hi) = if !(lo.is_finite() && hi.is_finite()) {
                (0.0, 1.0)
            } else if hi - lo <= 0.0 {
                (lo.min(0.0), hi.max(lo + 1.0))
            } else {
                (lo.min(0.0), hi)
            };
            nice_range(lo, hi, 6)
        }
    };
    let tick_w = y_ticks
        .iter()
        .map(|(_, s)| text_width(font, s, TICK_SIZE))
        .fold(0.0, f64::max);
    let left = 24.0 + 14.0 + tick_w.ceil() + 12.0;
    let top = 80.0;
    let right = f64::from(WIDTH) - 24.0;
    let bottom = f64::from(HEIGHT) - 70.0;
    let px = |x: f64| left + (x - x_lo) / (x_hi - x_lo) * (right - left);
    let py = |y: f64| bottom - (y - y_lo) / (y_hi - y_lo) * (bottom - top);

    out.push(Shape::Text(Label::new(
        c.title.clone(),
        f64::from(WIDTH) / 2.0,
        24.0,
        super::fit_size(font, &c.title, TITLE_SIZE, 9.0, f64::from(WIDTH) - 28.0),
        HAlign::Center,
        VAlign::Middle,
    )));
    // Grid, ticks, frame.
    let (x_ticks, x_step) = nice_ticks(x_lo, x_hi, 9);
    for &x in &x_ticks {
        out.push(Shape::Line(vec![(px(x), top), (px(x), bottom)], GRID, 1.0));
        out.push(Shape::Line(
            vec![(px(x), bottom), (px(x), bottom + 5.0)],
            AXIS,
            1.0,
        ));
        out.push(Shape::Text(Label::new(
            format_steps(x, x_step, x_hi),
            px(x),
            bottom + 9.0,
            TICK_SIZE,
            HAlign::Center,
            VAlign::Top,
        )));
    }
    for (y, text) in &y_ticks {
        out.push(Shape::Line(
            vec![(left, py(*y)), (right, py(*y))],
            GRID,
            1.0,
        ));
        out.push(Shape::Line(
            vec![(left - 5.0, py(*y)), (left, py(*y))],
            AXIS,
            1.0,
        ));
        out.push(Shape::Text(Label::new(
            text.clone(),
            left - 8.0,
            py(*y),
            TICK_SIZE,
            HAlign::Right,
            VAlign::Middle,
        )));
    }
    out.push(Shape::Line(
        vec![
            (left, top),
            (right, top),
            (right, bottom),
            (left, bottom),
            (left, top),
        ],
        AXIS,
        1.0,
    ));
    out.push(Shape::Text(Label::new(
        "environment steps",
        (left + right) / 2.0,
        bottom + 48.0,
        LABEL_SIZE,
        HAlign::Center,
        VAlign::Middle,
    )));
    out.push(Shape::Text(
        Label::new(
            c.y_label.clone(),
            24.0,
            (top + bottom) / 2.0,
            super::fit_size(font, &c.y_label, LABEL_SIZE, 9.0, bottom - top),
            HAlign::Center,
            VAlign::Middle,
        )
        .vertical(),
    ));

    let clamp = |y: f64| y.clamp(top, bottom);
    // Bands first (all of them), then the mean lines on top.
    for (i, b) in c.bands.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        for run in finite_runs(&c.x, &b.mean, &b.std) {
            let mut poly: Vec<(f64, f64)> = run
                .iter()
                .map(|&(x, m, s)| (px(x), clamp(py(m + s))))
                .collect();
            poly.extend(run.iter().rev().map(|&(x, m, s)| (px(x), clamp(py(m - s)))));
            out.push(Shape::Fill(poly, color, BAND_ALPHA));
        }
    }
    for (i, b) in c.bands.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        for run in finite_runs(&c.x, &b.mean, &b.std) {
            let pts = run.iter().map(|&(x, m, _)| (px(x), clamp(py(m)))).collect();
            out.push(Shape::Line(pts, color, 2.5));
        }
    }
    // Legend above the panel, right-aligned: a swatch and a name per arm.
    let mut x = right;
    let y = top - 20.0;
    for (i, b) in c.bands.iter().enumerate().rev() {
        let color = PALETTE[i % PALETTE.len()];
        let w = text_width(font, &b.name, TICK_SIZE);
        out.push(Shape::Text(Label::new(
            b.name.clone(),
            x,
            y,
            TICK_SIZE,
            HAlign::Right,
            VAlign::Middle,
        )));
        x -= w + 6.0;
        out.push(Shape::Fill(
            vec![
                (x - 24.0, y - 7.0),
                (x, y - 7.0),
                (x, y + 7.0),
                (x - 24.0, y + 7.0),
            ],
            color,
            BAND_ALPHA,
        ));
        out.push(Shape::Line(vec![(x - 24.0, y), (x, y)], color, 2.5));
        x -= 24.0 + 18.0;
    }
    out
}

/// Maximal runs of consecutive points where x, mean and std are all finite.
fn finite_runs(x: &[f64], mean: &[f64], std: &[f64]) -> Vec<Vec<(f64, f64, f64)>> {
    let mut runs = Vec::new();
    let mut cur = Vec::new();
    for ((&x, &m), &s) in x.iter().zip(mean).zip(std) {
        if x.is_finite() && m.is_finite() && s.is_finite() {
            cur.push((x, m, s.max(0.0)));
        } else if !cur.is_empty() {
            runs.push(std::mem::take(&mut cur));
        }
    }
    if !cur.is_empty() {
        runs.push(cur);
    }
    runs
}

fn check(path: &Path, c: &BandChart) -> Result<(), PlotError> {
    if c.x.is_empty() || c.bands.is_empty() {
        return Err(PlotError::NoData {
            path: path.to_path_buf(),
            reason: "there are no curves",
        });
    }
    Ok(())
}

/// Draws the chart as a PNG (820 x 520 pixels) at `path`, written atomically.
pub fn band_chart_png(path: &Path, c: &BandChart) -> Result<(), PlotError> {
    check(path, c)?;
    let font = fonts(path)?;
    let shapes = layout(c, font);
    let mut buf = vec![255u8; WIDTH as usize * HEIGHT as usize * 3];
    {
        let area = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        let pix = |pts: &[(f64, f64)]| -> Vec<(i32, i32)> {
            pts.iter()
                .map(|&(x, y)| (x.round() as i32, y.round() as i32))
                .collect()
        };
        let fail = |message: String| PlotError::Draw {
            path: path.to_path_buf(),
            message,
        };
        for s in &shapes {
            match s {
                Shape::Fill(pts, color, alpha) => area
                    .draw(&Polygon::new(pix(pts), rgb(*color).mix(*alpha).filled()))
                    .map_err(|e| fail(draw_err(e)))?,
                Shape::Line(pts, color, width) => area
                    .draw(&PathElement::new(
                        pix(pts),
                        rgb(*color).stroke_width(width.round() as u32),
                    ))
                    .map_err(|e| fail(draw_err(e)))?,
                Shape::Text(_) => {}
            }
        }
        area.present().map_err(|e| fail(draw_err(e)))?;
    }
    let mut canvas = Canvas {
        buf: &mut buf,
        width: WIDTH,
        height: HEIGHT,
    };
    for s in &shapes {
        if let Shape::Text(l) = s {
            canvas.text(font, l);
        }
    }
    save_png(path, &buf, WIDTH, HEIGHT)
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

/// Draws the chart as an SVG at `path`, written atomically (text as SVG text, in the
/// Hack font where installed, else any monospace font).
pub fn band_chart_svg(path: &Path, c: &BandChart) -> Result<(), PlotError> {
    check(path, c)?;
    let font = fonts(path)?;
    let shapes = layout(c, font);
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{WIDTH}\" height=\"{HEIGHT}\" viewBox=\"0 0 {WIDTH} {HEIGHT}\" font-family=\"Hack, DejaVu Sans Mono, monospace\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    for shape in &shapes {
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
