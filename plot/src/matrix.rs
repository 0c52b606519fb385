//! The tool-object empowerment matrix as a picture (the paper's Tables II and III):
//! one row per tool, one column per object set, each cell coloured by its value
//! (viridis, 0 to the matrix's largest value) with the value printed, and the tool that
//! tool selection picks for a column framed.

use std::path::Path;

use crate::error::PlotError;
use crate::scene::{self, Shape};
use crate::style::{text_on, viridis, AXIS, LABEL_SIZE, TICK_SIZE, TITLE_SIZE};
use crate::text::{fit_size, fonts, text_width, HAlign, Label};

/// A matrix to draw.
#[derive(Debug, Clone)]
pub struct MatrixPicture {
    /// Title on top.
    pub title: String,
    /// Row names (tools).
    pub rows: Vec<String>,
    /// Column names (object sets).
    pub columns: Vec<String>,
    /// values[row][column], in bits.
    pub values: Vec<Vec<f64>>,
    /// The selected row of each column, if any.
    pub selected: Vec<Option<usize>>,
}

const CELL_W: f64 = 130.0;
const CELL_H: f64 = 42.0;

/// Draws the matrix as a PNG at `path`, written atomically.
pub fn matrix_png(path: &Path, m: &MatrixPicture) -> Result<(), PlotError> {
    if m.rows.is_empty() || m.columns.is_empty() {
        return Err(PlotError::NoData {
            path: path.to_path_buf(),
            reason: "the matrix has no rows or no columns",
        });
    }
    let font = fonts(path)?;
    let row_w = m
        .rows
        .iter()
        .map(|r| text_width(font, r, LABEL_SIZE))
        .fold(40.0, f64::max)
        .ceil();
    let left = 16.0 + row_w + 12.0;
    let top = 64.0;
    let width = (left + CELL_W * m.columns.len() as f64 + 16.0).max(360.0);
    let height = top + CELL_H * m.rows.len() as f64 + 40.0;
    let max = m
        .values
        .iter()
        .flatten()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let mut shapes = Vec::new();
    shapes.push(Shape::Text(Label::new(
        m.title.clone(),
        width / 2.0,
        20.0,
        fit_size(font, &m.title, TITLE_SIZE * 0.8, 9.0, width - 24.0),
        HAlign::Center,
        crate::text::VAlign::Middle,
    )));
    for (c, name) in m.columns.iter().enumerate() {
        let x = left + CELL_W * (c as f64 + 0.5);
        shapes.push(Shape::Text(Label::new(
            name.clone(),
            x,
            top - 14.0,
            fit_size(font, name, LABEL_SIZE, 9.0, CELL_W - 8.0),
            HAlign::Center,
            crate::text::VAlign::Middle,
        )));
    }
    for (r, name) in m.rows.iter().enumerate() {
        let y0 = top + CELL_H * r as f64;
        shapes.push(Shape::Text(Label::new(
            name.clone(),
            left - 10.0,
            y0 + CELL_H / 2.0,
            LABEL_SIZE,
            HAlign::Right,
            crate::text::VAlign::Middle,
        )));
        for c in 0..m.columns.len() {
            let v = m.values.get(r).and_then(|row| row.get(c)).copied();
            let x0 = left + CELL_W * c as f64;
            let rect = vec![
                (x0, y0),
                (x0 + CELL_W, y0),
                (x0 + CELL_W, y0 + CELL_H),
                (x0, y0 + CELL_H),
            ];
            let bg = match v {
                Some(v) if v.is_finite() => viridis(if max > 0.0 { v / max } else { 0.0 }),
                _ => [190, 190, 190],
            };
            shapes.push(Shape::Fill(rect.clone(), bg, 1.0));
            let mut outline = rect;
            outline.push((x0, y0));
            shapes.push(Shape::Line(outline, [255, 255, 255], 1.0));
            if let Some(v) = v.filter(|v| v.is_finite()) {
                shapes.push(Shape::Text(
                    Label::new(
                        format!("{v:.4}"),
                        x0 + CELL_W / 2.0,
                        y0 + CELL_H / 2.0,
                        TICK_SIZE,
                        HAlign::Center,
                        crate::text::VAlign::Middle,
                    )
                    .color(text_on(bg)),
                ));
            }
        }
    }
    // Frames around the selected cells, drawn last so that neighbours do not cover them.
    for (c, sel) in m.selected.iter().enumerate() {
        if let Some(r) = sel {
            let (x0, y0) = (left + CELL_W * c as f64, top + CELL_H * *r as f64);
            shapes.push(Shape::Line(
                vec![
                    (x0 + 2.0, y0 + 2.0),
                    (x0 + CELL_W - 2.0, y0 + 2.0),
                    (x0 + CELL_W - 2.0, y0 + CELL_H - 2.0),
                    (x0 + 2.0, y0 + CELL_H - 2.0),
                    (x0 + 2.0, y0 + 2.0),
                ],
                [230, 40, 40],
                3.0,
            ));
        }
    }
    let note = "bits, mean over normal-mode states; red frame = selected tool";
    shapes.push(Shape::Text(
        Label::new(
            note,
            width / 2.0,
            height - 18.0,
            fit_size(font, note, TICK_SIZE * 0.9, 8.0, width - 24.0),
            HAlign::Center,
            crate::text::VAlign::Middle,
        )
        .color(AXIS),
    ));
    scene::png(path, width.ceil() as u32, height.ceil() as u32, &shapes)
}
