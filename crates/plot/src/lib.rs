//! Report-quality PNG figures for vestnav: line, scatter and log-log charts, maps with equal axes, and
//! heatmaps with a colorbar, laid out on a sheet and rasterised with tiny-skia.
//!
//! Every figure has a title, axis labels with units, "nice" 1-2-5 ticks (decades with minor ticks on log
//! axes), a light grid, a frame and a legend in the emptiest corner, or in a band below the plot when every
//! corner holds data (a legend never hides data). Text is drawn from glyph outlines of fonts embedded in the
//! binary (egui's Ubuntu Light with Hack as fallback), so rendering needs no system
//! fonts. Any input is accepted: NaN/inf values break lines and are skipped, log axes skip non-positive values,
//! empty or degenerate ranges get a visible default, and lines of millions of points are reduced per pixel
//! column (first, min, max, last) so they draw fast with every peak kept.
//!
//! ```
//! use vestnav_plot::{Chart, Figure, Scale, Series};
//!
//! let t: Vec<f64> = (0..500).map(|i| f64::from(i) * 1e-3).collect();
//! let theta: Vec<f64> = t.iter().map(|t| 1160.0 * t).collect();
//! let chart = Chart::new("eccentric angle")
//!     .x_label("time [s]")
//!     .y_label("theta [rad]")
//!     .y_scale(Scale::Linear)
//!     .series(Series::line("unencased", t, theta))
//!     .hline(300.0, "reference");
//! let png = Figure::single(chart).render_png()?;
//! assert_eq!(&png[1..4], b"PNG");
//! # Ok::<(), vestnav_plot::PlotError>(())
//! ```

mod canvas;
mod chart;
mod colormap;
mod decimate;
mod draw_chart;
mod figure;
mod heatmap;
mod style;
mod text;
mod ticks;

pub use chart::{Annotation, Chart, DataCircle, Marker, RefLine, Scale, Series, SeriesKind};
pub use colormap::viridis;
pub use decimate::decimate_minmax;
pub use figure::{Figure, Panel};
pub use heatmap::Heatmap;
pub use style::Color;
pub use text::{draw_label, label_width};
pub use ticks::{Ticks, axis_ticks};
/// The RGBA image type returned by [`Figure::render_pixmap`].
pub use tiny_skia::Pixmap;

/// Everything that can go wrong while rendering or saving a figure.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The requested image is empty or too large to allocate.
    #[error("invalid image size {width}x{height} px")]
    InvalidSize {
        /// Requested width in pixels.
        width: u32,
        /// Requested height in pixels.
        height: u32,
    },
    /// PNG encoding failed.
    #[error("PNG encoding failed: {0}")]
    Encode(String),
    /// Writing the PNG file failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file that could not be written.
        path: std::path::PathBuf,
        /// The underlying IO error.
        source: std::io::Error,
    },
}
