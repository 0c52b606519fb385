//! Colours, font sizes and size limits shared by every figure.

use plotters::prelude::RGBColor;

/// Largest grid side (in cells) that [`heatmap_png`] accepts.
pub(crate) const MAX_GRID_SIDE: usize = 2000;
/// Largest number of steps that [`trace_png`] accepts.
pub(crate) const MAX_TRACE_STEPS: usize = 100_000;
/// Largest picture side in pixels; longer titles are clipped rather than widening more.
pub(crate) const MAX_IMAGE_SIDE: u32 = 8000;

pub(crate) type Rgb = [u8; 3];

pub(crate) const BLACK_TEXT: Rgb = [20, 20, 20];
pub(crate) const WHITE_TEXT: Rgb = [255, 255, 255];
pub(crate) const AXIS: Rgb = [60, 60, 60];
pub(crate) const GRID: Rgb = [225, 225, 225];
pub(crate) const ROCK: Rgb = [38, 38, 42];
pub(crate) const ROCK_EDGE: Rgb = [72, 72, 78];
pub(crate) const NO_VALUE: Rgb = [190, 190, 190];
pub(crate) const VALUE_LINE: Rgb = [31, 119, 180];
pub(crate) const CATEGORY_LINE: Rgb = [214, 110, 20];

pub(crate) fn rgb(c: Rgb) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// Viridis, sampled at nine evenly spaced points.
pub(crate) const VIRIDIS: [Rgb; 9] = [
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
pub(crate) fn viridis(t: f64) -> Rgb {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |k: usize| (f64::from(a[k]) + (f64::from(b[k]) - f64::from(a[k])) * f).round() as u8;
    [mix(0), mix(1), mix(2)]
}

/// Black or white, whichever reads better on `bg`.
pub(crate) fn text_on(bg: Rgb) -> Rgb {
    let l = 0.2126 * f64::from(bg[0]) + 0.7152 * f64::from(bg[1]) + 0.0722 * f64::from(bg[2]);
    if l > 140.0 {
        BLACK_TEXT
    } else {
        WHITE_TEXT
    }
}

pub(crate) const TITLE_SIZE: f32 = 22.0;
pub(crate) const LABEL_SIZE: f32 = 16.0;
pub(crate) const TICK_SIZE: f32 = 15.0;
