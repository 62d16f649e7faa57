//! Report-quality PNG figures for vestnav, rasterised with tiny-skia and an embedded font.
//!
//! Placeholder crate doc while the renderer is being written.

mod chart;
mod figure;
mod heatmap;
mod style;

pub use chart::{Chart, Marker, Scale, Series};
pub use figure::{Figure, Panel};
pub use heatmap::Heatmap;
pub use style::Color;

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
