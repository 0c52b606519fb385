//! Landscape heatmaps: one square cell per map cell, values printed inside.

use std::path::Path;

use crate::canvas::{draw_err, fill_rect, line, render_png};
use crate::error::PlotError;
use crate::style::{
    text_on, viridis, AXIS, LABEL_SIZE, MAX_GRID_SIDE, MAX_IMAGE_SIDE, NO_VALUE, ROCK, ROCK_EDGE,
    TICK_SIZE, TITLE_SIZE,
};
use crate::text::{fit_size, font, fonts, text_width, HAlign, Label, VAlign};
use crate::ticks::{cell_decimals, decimals_for, finite, format_value};
use ab_glyph::FontRef;
use plotters::prelude::*;

/// A landscape heatmap: one square cell per map cell.
///
/// Rows may have different lengths; the picture is as wide as the longest row of
/// `values` or `rock`, and missing entries count as "no value" / "not rock".
#[derive(Debug, Clone, Copy)]
pub struct Heatmap<'a> {
    /// Title drawn on top.
    pub title: &'a str,
    /// `values[y][x]`; None = no value on that cell (drawn as a neutral grey with no number).
    /// NaN and infinite values are treated as None.
    pub values: &'a [Vec<Option<f64>>],
    /// `rock[y][x]` = true for static rock cells: drawn as dark wall blocks.
    pub rock: &'a [Vec<bool>],
    /// Optional per-cell glyph drawn small in a corner (e.g. 'T', 'a', '+'), None = nothing.
    pub glyphs: Option<&'a [Vec<Option<char>>]>,
    /// Unit for the colour bar, e.g. "bits".
    pub unit: &'a str,
}

/// Draws `h` as a PNG at `path` (written atomically).
///
/// Cells are about 40 px square (smaller for grids wider or taller than 40 cells); values
/// are printed inside when the cell is large enough. Errors if the grid has no cells or
/// a side is longer than 2000 cells.
pub fn heatmap_png(path: &Path, h: &Heatmap) -> Result<(), PlotError> {
    let font = fonts(path)?;
    let layout = HeatmapLayout::new(path, h, font)?;
    render_png(path, font, (layout.width, layout.height), |buf, labels| {
        draw_heatmap(buf, &layout, h, labels)
    })
}

/// Where everything of a heatmap goes, in pixels.
#[derive(Debug, Clone)]
pub(crate) struct HeatmapLayout {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) cols: usize,
    pub(crate) rows: usize,
    pub(crate) cell: i32,
    pub(crate) grid_left: i32,
    pub(crate) grid_top: i32,
    pub(crate) bar_left: i32,
    pub(crate) bar_top: i32,
    pub(crate) bar_width: i32,
    pub(crate) bar_height: i32,
    /// Colour scale: values map from lo (0) to hi (1).
    pub(crate) lo: f64,
    pub(crate) hi: f64,
    /// Tick values of the colour bar and their labels.
    pub(crate) ticks: Vec<(f64, String)>,
    pub(crate) tick_label_width: f64,
}

impl HeatmapLayout {
    pub(crate) fn new(
        path: &Path,
        h: &Heatmap,
        font: &FontRef<'static>,
    ) -> Result<Self, PlotError> {
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
    pub(crate) fn scale(&self, v: f64) -> f64 {
        let t = (v - self.lo) / (self.hi - self.lo);
        if t.is_finite() {
            t.clamp(0.0, 1.0)
        } else {
            0.5
        }
    }

    /// Top-left pixel of cell (x, y).
    pub(crate) fn cell_origin(&self, x: usize, y: usize) -> (i32, i32) {
        (
            self.grid_left + x as i32 * self.cell,
            self.grid_top + y as i32 * self.cell,
        )
    }
}

pub(crate) fn draw_heatmap(
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
