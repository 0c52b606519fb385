//! Band charts like the paper's Figs. 4, 7 and 13: per arm, the mean over seeds as a
//! line and mean +/- one standard deviation as a shaded band, one colour per arm, over
//! environment steps; as PNG ([`band_chart_png`]) and SVG ([`band_chart_svg`]).
//!
//! The chart is laid out once as a list of shapes and labels in pixels; the PNG renders
//! it with plotters' bitmap backend and this module's text renderer, the SVG writes the
//! same shapes as SVG elements, so the two files show the same picture.

use std::path::Path;

use crate::curve::{format_steps, nice_range};
use crate::error::PlotError;
use crate::scene::{self, Shape};
use crate::style::{Rgb, AXIS, GRID, LABEL_SIZE, TICK_SIZE, TITLE_SIZE};
use crate::text::{fonts, text_width, HAlign, Label, VAlign};
use crate::ticks::nice_ticks;

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
    /// x-axis title.
    pub x_label: String,
    /// y-axis title.
    pub y_label: String,
    /// x of the points (shared by all bands), e.g. env steps.
    pub x: Vec<f64>,
    /// The arms, drawn in order (first underneath).
    pub bands: Vec<Band>,
    /// Fixed y range (e.g. 0..1 for a rate); None = fit the bands.
    pub y_range: Option<(f64, f64)>,
    /// Logarithmic x axis (decades); points with x <= 0 are left out.
    pub x_log: bool,
    /// Logarithmic y axis (decades); values <= 0 are left out.
    pub y_log: bool,
}

impl BandChart {
    /// A linear chart over environment steps.
    pub fn over_steps(title: String, y_label: String, x: Vec<f64>, bands: Vec<Band>) -> Self {
        BandChart {
            title,
            x_label: "environment steps".into(),
            y_label,
            x,
            bands,
            y_range: None,
            x_log: false,
            y_log: false,
        }
    }
}

/// A decade's label: 1k, 10M, 0.01, 1.
fn decade_label(e: i32) -> String {
    match e {
        e if e >= 9 => format!("{}G", 10f64.powi(e - 9)),
        e if e >= 6 => format!("{}M", 10f64.powi(e - 6)),
        e if e >= 3 => format!("{}k", 10f64.powi(e - 3)),
        e if e >= 0 => format!("{}", 10f64.powi(e)),
        e => format!("{:.*}", (-e) as usize, 10f64.powi(e)),
    }
}

/// Decades covering lo..hi (both > 0): (log lo, log hi, ticks as (log value, label)).
fn decades(lo: f64, hi: f64) -> (f64, f64, Vec<(f64, String)>) {
    let (a, b) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let b = b.max(a + 1);
    (
        f64::from(a),
        f64::from(b),
        (a..=b).map(|e| (f64::from(e), decade_label(e))).collect(),
    )
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

/// `v` on an axis: log10 on a log axis (non-positive values vanish as NaN).
fn axis_value(log: bool, v: f64) -> f64 {
    match (log, v > 0.0) {
        (false, _) => v,
        (true, true) => v.log10(),
        (true, false) => f64::NAN,
    }
}

/// Decades covering the positive finite values (1..10 when there are none).
fn positive_range(vals: impl Iterator<Item = f64>) -> (f64, f64, Vec<(f64, String)>) {
    let (lo, hi) = vals
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    if lo.is_finite() {
        decades(lo, hi)
    } else {
        decades(1.0, 10.0)
    }
}

/// Every value a band reaches: mean - std, mean + std and the mean.
fn band_values(c: &BandChart) -> impl Iterator<Item = f64> + '_ {
    c.bands.iter().flat_map(|b| {
        b.mean
            .iter()
            .zip(&b.std)
            .flat_map(|(m, s)| [m - s.max(0.0), m + s.max(0.0), *m])
    })
}

/// The x axis: (low, high, ticks), in axis units.
fn x_axis(c: &BandChart) -> (f64, f64, Vec<(f64, String)>) {
    if c.x_log {
        return positive_range(c.x.iter().copied());
    }
    let x_hi =
        c.x.iter()
            .copied()
            .filter(|v| v.is_finite())
            .fold(10.0, f64::max);
    let (ticks, step) = nice_ticks(0.0, x_hi, 9);
    let t = ticks
        .into_iter()
        .map(|x| (x, format_steps(x, step, x_hi)))
        .collect();
    (0.0, x_hi, t)
}

/// The y axis: (low, high, ticks), in axis units.
fn y_axis(c: &BandChart) -> (f64, f64, Vec<(f64, String)>) {
    match c.y_range {
        _ if c.y_log => positive_range(band_values(c)),
        Some((lo, hi)) => nice_range(lo, hi, 5),
        None => {
            let (lo, hi) = band_values(c)
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
    }
}

/// Legend rows (a swatch and a name per arm), as many as the width `right` needs.
fn legend_rows(c: &BandChart, font: &ab_glyph::FontRef<'static>, right: f64) -> Vec<Vec<usize>> {
    let entry_w = |b: &Band| 24.0 + 6.0 + text_width(font, &b.name, TICK_SIZE) + 18.0;
    let mut rows: Vec<Vec<usize>> = vec![Vec::new()];
    let mut used = 0.0;
    for (i, b) in c.bands.iter().enumerate() {
        let w = entry_w(b);
        if used + w > right - 24.0 && rows.last().is_some_and(|r| !r.is_empty()) {
            rows.push(Vec::new());
            used = 0.0;
        }
        rows.last_mut().expect("one row at least").push(i);
        used += w;
    }
    rows
}

/// The plotting rectangle in pixels and the axis ranges it shows.
struct Panel {
    left: f64,
    right: f64,
    top: f64,
    bottom: f64,
    x: (f64, f64),
    y: (f64, f64),
}

impl Panel {
    fn px(&self, x: f64) -> f64 {
        self.left + (x - self.x.0) / (self.x.1 - self.x.0) * (self.right - self.left)
    }

    fn py(&self, y: f64) -> f64 {
        self.bottom - (y - self.y.0) / (self.y.1 - self.y.0) * (self.bottom - self.top)
    }
}

/// The chart as shapes in pixel coordinates.
fn layout(c: &BandChart, font: &ab_glyph::FontRef<'static>) -> Vec<Shape> {
    let (x_lo, x_hi, x_ticks) = x_axis(c);
    let (y_lo, y_hi, y_ticks) = y_axis(c);
    let tick_w = y_ticks
        .iter()
        .map(|(_, s)| text_width(font, s, TICK_SIZE))
        .fold(0.0, f64::max);
    let left = 24.0 + 14.0 + tick_w.ceil() + 12.0;
    let right = f64::from(WIDTH) - 24.0;
    // The panel starts below the last legend row.
    let rows = legend_rows(c, font, right);
    let panel = Panel {
        left,
        right,
        top: 80.0 + 20.0 * (rows.len() - 1) as f64,
        bottom: f64::from(HEIGHT) - 70.0,
        x: (x_lo, x_hi),
        y: (y_lo, y_hi),
    };
    let mut out = Vec::new();
    out.push(Shape::Text(Label::new(
        c.title.clone(),
        f64::from(WIDTH) / 2.0,
        24.0,
        crate::text::fit_size(font, &c.title, TITLE_SIZE, 9.0, f64::from(WIDTH) - 28.0),
        HAlign::Center,
        VAlign::Middle,
    )));
    axes(&mut out, c, font, &panel, &x_ticks, &y_ticks);
    bands(&mut out, c, &panel);
    legend(&mut out, c, font, &rows, right);
    out
}

/// Grid, ticks, frame and axis titles.
fn axes(
    out: &mut Vec<Shape>,
    c: &BandChart,
    font: &ab_glyph::FontRef<'static>,
    p: &Panel,
    x_ticks: &[(f64, String)],
    y_ticks: &[(f64, String)],
) {
    let (left, right, top, bottom) = (p.left, p.right, p.top, p.bottom);
    for (x, text) in x_ticks {
        let x = p.px(*x);
        out.push(Shape::Line(vec![(x, top), (x, bottom)], GRID, 1.0));
        out.push(Shape::Line(vec![(x, bottom), (x, bottom + 5.0)], AXIS, 1.0));
        out.push(Shape::Text(Label::new(
            text.clone(),
            x,
            bottom + 9.0,
            TICK_SIZE,
            HAlign::Center,
            VAlign::Top,
        )));
    }
    for (y, text) in y_ticks {
        let y = p.py(*y);
        out.push(Shape::Line(vec![(left, y), (right, y)], GRID, 1.0));
        out.push(Shape::Line(vec![(left - 5.0, y), (left, y)], AXIS, 1.0));
        out.push(Shape::Text(Label::new(
            text.clone(),
            left - 8.0,
            y,
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
        c.x_label.clone(),
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
            crate::text::fit_size(font, &c.y_label, LABEL_SIZE, 9.0, bottom - top),
            HAlign::Center,
            VAlign::Middle,
        )
        .vertical(),
    ));
}

/// The bands (all of them), then the mean lines on top.
fn bands(out: &mut Vec<Shape>, c: &BandChart, p: &Panel) {
    let xs: Vec<f64> = c.x.iter().map(|&v| axis_value(c.x_log, v)).collect();
    let ly = |v: f64| axis_value(c.y_log, v);
    let clamp = |y: f64| y.clamp(p.top, p.bottom);
    for (i, b) in c.bands.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        for run in finite_runs(&xs, &b.mean, &b.std) {
            let band = |m: f64, s: f64, sign: f64| clamp(p.py(ly(m + sign * s)));
            let mut poly: Vec<(f64, f64)> = run
                .iter()
                .map(|&(x, m, s)| (p.px(x), band(m, s, 1.0)))
                .collect();
            // On a log axis a band reaching 0 or below is cut at the bottom.
            poly.extend(run.iter().rev().map(|&(x, m, s)| {
                let lo = band(m, s, -1.0);
                (p.px(x), if lo.is_finite() { lo } else { p.bottom })
            }));
            out.push(Shape::Fill(poly, color, BAND_ALPHA));
        }
    }
    for (i, b) in c.bands.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        for run in finite_runs(
            &xs,
            &b.mean.iter().map(|&m| ly(m)).collect::<Vec<_>>(),
            &b.std,
        ) {
            let pts: Vec<(f64, f64)> = run
                .iter()
                .map(|&(x, m, _)| (p.px(x), clamp(p.py(m))))
                .collect();
            if pts.len() <= 12 {
                // Few points: a marker on each.
                for &(x, y) in &pts {
                    out.push(Shape::Fill(
                        vec![(x - 4.0, y), (x, y - 4.0), (x + 4.0, y), (x, y + 4.0)],
                        color,
                        1.0,
                    ));
                }
            }
            out.push(Shape::Line(pts, color, 2.5));
        }
    }
}

/// The legend above the panel, right-aligned: a swatch and a name per arm.
fn legend(
    out: &mut Vec<Shape>,
    c: &BandChart,
    font: &ab_glyph::FontRef<'static>,
    rows: &[Vec<usize>],
    right: f64,
) {
    for (r, row) in rows.iter().enumerate() {
        let mut x = right;
        let y = 60.0 + 20.0 * r as f64;
        for &i in row.iter().rev() {
            let b = &c.bands[i];
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
    }
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
    let shapes = layout(c, fonts(path)?);
    scene::png(path, WIDTH, HEIGHT, &shapes)
}

/// Draws the chart as an SVG at `path`, written atomically.
pub fn band_chart_svg(path: &Path, c: &BandChart) -> Result<(), PlotError> {
    check(path, c)?;
    let shapes = layout(c, fonts(path)?);
    scene::svg(path, WIDTH, HEIGHT, &shapes)
}
