//! Why a figure could not be drawn or written.

use std::io;
use std::path::PathBuf;

/// Why a figure could not be drawn or written. Each message is one sentence naming the file.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// There is nothing to draw (an empty grid, a trace with no steps).
    #[error("cannot plot {}: {reason}", path.display())]
    NoData {
        /// The figure that was asked for.
        path: PathBuf,
        /// What is missing, e.g. "the grid has no cells".
        reason: &'static str,
    },
    /// The input is too large to be drawn as one picture.
    #[error(
        "cannot plot {}: {what} is {size}, more than the {limit} this plotter draws",
        path.display()
    )]
    TooLarge {
        /// The figure that was asked for.
        path: PathBuf,
        /// What is too large, e.g. "the grid side (cells)".
        what: &'static str,
        /// Its size.
        size: usize,
        /// The largest size accepted.
        limit: usize,
    },
    /// The embedded font could not be parsed (should never happen).
    #[error("cannot plot {}: the embedded font could not be loaded", path.display())]
    Font {
        /// The figure that was asked for.
        path: PathBuf,
    },
    /// The rasteriser reported an error.
    #[error("drawing {} failed: {message}", path.display())]
    Draw {
        /// The figure that was being drawn.
        path: PathBuf,
        /// The rasteriser's message.
        message: String,
    },
    /// PNG encoding failed.
    #[error("encoding {} as PNG failed: {error}", path.display())]
    Encode {
        /// The figure that was being encoded.
        path: PathBuf,
        /// The encoder's error.
        error: png::EncodingError,
    },
    /// GIF encoding failed.
    #[error("encoding {} as GIF failed: {error}", path.display())]
    EncodeGif {
        /// The animation that was being encoded.
        path: PathBuf,
        /// The encoder's error.
        error: gif::EncodingError,
    },
    /// Writing the file failed (the temporary file has been removed).
    #[error("cannot write {}: {error}", path.display())]
    Io {
        /// The file that was being written.
        path: PathBuf,
        /// The I/O error.
        error: io::Error,
    },
}
