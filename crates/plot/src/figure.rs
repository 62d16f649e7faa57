//! Figures: a sheet of panels rendered to PNG.

use std::path::Path;

use crate::{Chart, Heatmap, PlotError};

/// One panel of a [`Figure`].
#[derive(Debug, Clone)]
pub enum Panel {
    /// A line/scatter chart.
    Chart(Chart),
    /// A heatmap with colorbar.
    Heatmap(Heatmap),
}

impl From<Chart> for Panel {
    fn from(chart: Chart) -> Self {
        Panel::Chart(chart)
    }
}

impl From<Heatmap> for Panel {
    fn from(heatmap: Heatmap) -> Self {
        Panel::Heatmap(heatmap)
    }
}

/// A figure: an optional sheet title above a grid of panels, on a white background.
#[derive(Debug, Clone)]
pub struct Figure {
    pub(crate) title: String,
    pub(crate) columns: usize,
    pub(crate) panel_width_px: u32,
    pub(crate) panel_height_px: u32,
    pub(crate) panels: Vec<Panel>,
}

impl Default for Figure {
    fn default() -> Self {
        Self::new()
    }
}

impl Figure {
    /// An empty sheet: one column, 640x400 px panels.
    pub fn new() -> Self {
        Self { title: String::new(), columns: 1, panel_width_px: 640, panel_height_px: 400, panels: Vec::new() }
    }

    /// A figure of one panel, 900x560 px.
    pub fn single(panel: impl Into<Panel>) -> Self {
        Self::new().panel_size(900, 560).push(panel)
    }

    /// Sheet title drawn above all panels.
    #[must_use]
    pub fn title(mut self, title: impl Into<String>) -> Self {
        self.title = title.into();
        self
    }

    /// Number of panel columns (at least 1); panels fill rows left to right.
    #[must_use]
    pub fn columns(mut self, columns: usize) -> Self {
        self.columns = columns.max(1);
        self
    }

    /// Size of each panel in pixels.
    #[must_use]
    pub fn panel_size(mut self, width_px: u32, height_px: u32) -> Self {
        self.panel_width_px = width_px;
        self.panel_height_px = height_px;
        self
    }

    /// Append a panel.
    #[must_use]
    pub fn push(mut self, panel: impl Into<Panel>) -> Self {
        self.panels.push(panel.into());
        self
    }

    /// Render to an RGBA pixmap (white background).
    pub fn render_pixmap(&self) -> Result<tiny_skia::Pixmap, PlotError> {
        let (width, height) = (self.panel_width_px, self.panel_height_px);
        let mut pixmap = tiny_skia::Pixmap::new(width, height).ok_or(PlotError::InvalidSize { width, height })?;
        pixmap.fill(tiny_skia::Color::WHITE);
        Ok(pixmap)
    }

    /// Render to PNG bytes.
    pub fn render_png(&self) -> Result<Vec<u8>, PlotError> {
        self.render_pixmap()?.encode_png().map_err(|e| PlotError::Encode(e.to_string()))
    }

    /// Render and write a PNG file atomically (a temporary file in the same directory, then a rename).
    pub fn save_png(&self, path: &Path) -> Result<(), PlotError> {
        let bytes = self.render_png()?;
        let io = |source| PlotError::Io { path: path.to_path_buf(), source };
        let mut tmp_name = path.file_name().map(std::ffi::OsStr::to_os_string).unwrap_or_default();
        tmp_name.push(format!(".{}.tmp", std::process::id()));
        let tmp = path.with_file_name(tmp_name);
        std::fs::write(&tmp, &bytes).map_err(io)?;
        std::fs::rename(&tmp, path).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            io(e)
        })
    }
}
