//! fulcrum's figures, as PNG (and SVG for band charts), drawn without system fonts.
//!
//! The three single-run pictures:
//!
//! * [`heatmap_png`]: a map-shaped heatmap, one square cell per map cell, coloured with
//!   a viridis-like perceptual colour map, the value printed inside each cell with two
//!   decimals, static rock drawn as dark wall blocks, cells without a value in neutral
//!   grey, optional small glyphs in a cell corner, a colour bar labelled with the unit on
//!   the right and a title on top.
//! * [`trace_png`]: a time trace (like Fig. 12 of the paper): the value per step as a line
//!   with markers, the actions taken as x tick labels when there are few steps, and an
//!   optional categorical series (e.g. the door state) as a step plot in a smaller panel
//!   underneath.
//! * [`learning_curve_png`]: a training run's learning curve: the success rate over
//!   environment steps on top, the mean extrinsic return and the mean intrinsic reward
//!   per step (two colours, with a legend) underneath.
//!
//! Shapes are rasterised with `plotters`' bitmap backend; all text is rendered by this
//! module from the Hack font embedded in the `epaint_default_fonts` crate (MIT /
//! Bitstream Vera licence), so nothing depends on fonts installed on the machine.
//! (Plotters' own `ab_glyph` text path drops the glyphs' side bearings, which makes
//! monospaced numbers like `1.00` look broken, hence the own text renderer.)
//! [`register_plotters_fonts`] registers the same font with plotters for code that
//! draws plotters charts with plotters' text (e.g. SVG output).
//!
//! Every file is written with [`fulcrum_contracts::fsio::write_atomic`]: a half-written PNG never appears at the
//! final path.
//!
//! | module | what it draws or holds |
//! |---|---|
//! | [`heatmap`] | landscape heatmaps |
//! | [`trace`] | time traces |
//! | [`curve`] | a run's learning curve |
//! | [`bands`] | experiment band charts (mean and spread per arm) |
//! | [`episode`] | an episode as a strip of frames |
//! | [`matrix`] | the empowerment matrix |
//! | `scene`, `canvas`, `text`, `style`, `ticks` | the drawing kit the figures share |
//! | [`error`] | why a figure could not be drawn or written |

pub mod bands;
mod canvas;
pub mod curve;
pub mod episode;
pub mod error;
pub mod heatmap;
pub mod matrix;
mod scene;
mod style;
mod text;
mod ticks;
pub mod trace;

pub use bands::{band_chart_png, band_chart_svg, Band, BandChart};
pub use curve::{learning_curve_png, CurvePoint};
pub use episode::{episode_gif, episode_png, Frame, Strip};
pub use error::PlotError;
pub use heatmap::{heatmap_png, Heatmap};
pub use matrix::{matrix_png, MatrixPicture};
pub use text::register_plotters_fonts;
pub use trace::{trace_png, Trace};

#[cfg(test)]
mod tests;
