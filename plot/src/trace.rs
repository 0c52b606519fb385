//! Time traces: a value per step, the actions as ticks, an optional categorical panel.

use std::path::Path;

use crate::canvas::{draw_err, line, render_png, Area};
use crate::error::PlotError;
use crate::style::{
    rgb, AXIS, CATEGORY_LINE, GRID, LABEL_SIZE, MAX_IMAGE_SIDE, MAX_TRACE_STEPS, TICK_SIZE,
    TITLE_SIZE, VALUE_LINE,
};
use crate::text::{fit_size, font, fonts, text_width, HAlign, Label, VAlign};
use crate::ticks::{decimals_for, format_value, nice_ticks};
use ab_glyph::FontRef;
use plotters::prelude::*;

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

/// Draws `t` as a PNG at `path` (written atomically).
///
/// The y axis runs from 0 (or below, for negative values) to max(value) * 1.1, at least
/// to 1. Errors if the trace has no steps or more than 100 000 steps.
pub fn trace_png(path: &Path, t: &Trace) -> Result<(), PlotError> {
    let font = fonts(path)?;
    let layout = TraceLayout::new(path, t, font)?;
    render_png(path, font, (layout.width, layout.height), |buf, labels| {
        draw_trace(buf, &layout, t, labels)
    })
}

pub(crate) const FEW_STEPS: usize = 40;

/// A panel's plotting rectangle in pixels and its y range.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Panel {
    pub(crate) left: i32,
    pub(crate) top: i32,
    pub(crate) width: i32,
    pub(crate) height: i32,
    pub(crate) y_lo: f64,
    pub(crate) y_hi: f64,
}

impl Panel {
    pub(crate) fn py(&self, y: f64) -> f64 {
        let t = (y - self.y_lo) / (self.y_hi - self.y_lo);
        let t = if t.is_finite() { t } else { 0.0 };
        f64::from(self.top + self.height) - t * f64::from(self.height)
    }
}

#[derive(Debug, Clone)]
pub(crate) struct TraceLayout {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) steps: usize,
    pub(crate) value: Panel,
    pub(crate) category: Option<Panel>,
    pub(crate) y_ticks: Vec<(f64, String)>,
    /// Steps with a tick (and a step number).
    pub(crate) x_ticks: Vec<usize>,
    /// Print actions under the step numbers, and whether rotated.
    pub(crate) actions: Option<bool>,
    /// Top of the x tick labels.
    pub(crate) x_labels_top: i32,
    /// Centre line of the x axis title.
    pub(crate) x_title_y: i32,
    /// x of the rotated y axis titles.
    pub(crate) y_title_x: i32,
}

impl TraceLayout {
    pub(crate) fn new(path: &Path, t: &Trace, font: &FontRef<'static>) -> Result<Self, PlotError> {
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
    pub(crate) fn px(&self, s: f64) -> f64 {
        f64::from(self.value.left) + (s + 0.5) / self.steps as f64 * f64::from(self.value.width)
    }
}

pub(crate) fn frame(area: &Area<'_>, p: &Panel) -> Result<(), String> {
    let (x0, y0, x1, y1) = (p.left, p.top, p.left + p.width, p.top + p.height);
    line(
        area,
        vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)],
        AXIS,
        1,
    )
}

pub(crate) fn draw_trace(
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
    value_panel(&area, l, t, font, labels)?;
    if let (Some(c), Some(category)) = (l.category, t.category) {
        category_panel(&area, l, c, category, font, labels)?;
    }
    x_axis(
        &area,
        l,
        t,
        panels.last().copied().unwrap_or(l.value),
        labels,
    )?;
    area.present().map_err(draw_err)
}

/// The value panel: y ticks, frame, the value line with markers, its title.
fn value_panel(
    area: &Area<'_>,
    l: &TraceLayout,
    t: &Trace,
    font: &FontRef<'static>,
    labels: &mut Vec<Label>,
) -> Result<(), String> {
    let v = l.value;
    for (y, text) in &l.y_ticks {
        let py = v.py(*y);
        let yi = py.round() as i32;
        line(area, vec![(v.left, yi), (v.left + v.width, yi)], GRID, 1)?;
        line(area, vec![(v.left - 5, yi), (v.left, yi)], AXIS, 1)?;
        labels.push(Label::new(
            text.clone(),
            f64::from(v.left - 8),
            py,
            TICK_SIZE,
            HAlign::Right,
            VAlign::Middle,
        ));
    }
    frame(area, &v)?;
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
            line(area, run, VALUE_LINE, 2)?;
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

    Ok(())
}

/// The categorical panel: one level per name, the step line with markers, its title.
fn category_panel(
    area: &Area<'_>,
    l: &TraceLayout,
    c: Panel,
    (label, names, idx): (&str, &[String], &[usize]),
    font: &FontRef<'static>,
    labels: &mut Vec<Label>,
) -> Result<(), String> {
    for (k, name) in names.iter().enumerate() {
        let py = c.py(k as f64);
        let yi = py.round() as i32;
        line(area, vec![(c.left, yi), (c.left + c.width, yi)], GRID, 1)?;
        line(area, vec![(c.left - 5, yi), (c.left, yi)], AXIS, 1)?;
        labels.push(Label::new(
            name.clone(),
            f64::from(c.left - 8),
            py,
            TICK_SIZE,
            HAlign::Right,
            VAlign::Middle,
        ));
    }
    frame(area, &c)?;
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
                line(area, std::mem::take(&mut path), CATEGORY_LINE, 2)?;
            }
            path.clear();
            continue;
        };
        let x = l.px(s as f64);
        path.push(((x - half).round() as i32, y));
        path.push(((x + half).round() as i32, y));
    }
    if path.len() >= 2 {
        line(area, path, CATEGORY_LINE, 2)?;
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
    Ok(())
}

/// The x axis under the lowest panel: ticks, step numbers, actions, title.
fn x_axis(
    area: &Area<'_>,
    l: &TraceLayout,
    t: &Trace,
    bottom: Panel,
    labels: &mut Vec<Label>,
) -> Result<(), String> {
    let v = l.value;
    let axis_y = bottom.top + bottom.height;
    for &s in &l.x_ticks {
        let x = l.px(s as f64);
        let xi = x.round() as i32;
        line(area, vec![(xi, axis_y), (xi, axis_y + 5)], AXIS, 1)?;
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
    Ok(())
}
