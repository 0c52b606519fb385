//! Learning curves: success rate on top, extrinsic and intrinsic reward below.

use std::path::Path;

use crate::canvas::{draw_err, line, render_png, Area};
use crate::error::PlotError;
use crate::style::{
    rgb, Rgb, AXIS, CATEGORY_LINE, GRID, LABEL_SIZE, TICK_SIZE, TITLE_SIZE, VALUE_LINE,
};
use crate::text::{fit_size, font, fonts, text_width, HAlign, Label, VAlign};
use crate::ticks::{decimals_for, format_value, nice_ticks};
use crate::trace::{frame, Panel};
use ab_glyph::FontRef;
use plotters::prelude::*;

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

pub(crate) const CURVE_WIDTH: u32 = 800;
pub(crate) const CURVE_HEIGHT: u32 = 600;
pub(crate) const SUCCESS_LINE: Rgb = [44, 160, 44];
pub(crate) const EXTRINSIC_LINE: Rgb = VALUE_LINE;
pub(crate) const INTRINSIC_LINE: Rgb = CATEGORY_LINE;

/// Where everything of a learning curve goes, in pixels.
#[derive(Debug, Clone)]
pub(crate) struct CurveLayout {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) title_size: f32,
    pub(crate) x_lo: f64,
    pub(crate) x_hi: f64,
    pub(crate) x_ticks: Vec<(f64, String)>,
    pub(crate) success: Panel,
    pub(crate) success_ticks: Vec<(f64, String)>,
    pub(crate) returns: Panel,
    pub(crate) returns_ticks: Vec<(f64, String)>,
    /// x of the rotated y axis titles.
    pub(crate) y_title_x: i32,
    /// Top of the x tick labels.
    pub(crate) x_labels_top: i32,
    /// Centre line of the x axis title.
    pub(crate) x_title_y: i32,
    /// Centre line of the legend (between the panels).
    pub(crate) legend_y: i32,
}

/// `lo..hi` widened to whole multiples of a nice step; ticks in it with their labels.
pub(crate) fn nice_range(lo: f64, hi: f64, max_ticks: usize) -> (f64, f64, Vec<(f64, String)>) {
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
pub(crate) fn format_steps(v: f64, step: f64, hi: f64) -> String {
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
    pub(crate) fn new(points: &[CurvePoint], title: &str, font: &FontRef<'static>) -> Self {
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
    pub(crate) fn px(&self, steps: f64) -> f64 {
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
    render_png(path, font, (layout.width, layout.height), |buf, labels| {
        draw_curve(buf, &layout, title, points, labels)
    })
}

/// One series in a panel: a line through its finite points, markers when they are few,
/// a dot when there is only one. Values outside the panel's range are clamped to it.
pub(crate) fn series(
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
pub(crate) fn curve_panel(
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

pub(crate) fn draw_curve(
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
        ("intrinsic term per step (before beta)", INTRINSIC_LINE),
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
