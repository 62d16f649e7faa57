//! Figures: a sheet of panels rendered to PNG.

use std::path::Path;

use tiny_skia::{Pixmap, PixmapPaint, Transform};

use crate::canvas;
use crate::draw_chart;
use crate::text::{HAlign, TextStyle, VAlign, draw_text};
use crate::{Chart, Heatmap, PlotError};

/// Largest sheet side in pixels (a 16k x 16k RGBA sheet is already 1 GiB).
const MAX_SIDE_PX: u32 = 16_384;
/// Smallest panel side that still leaves room for axes.
const MIN_PANEL_PX: u32 = 64;
const SHEET_TITLE_PX: f32 = 18.0;

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
    /// Sheet title (empty: none).
    pub title: String,
    /// Panels per row.
    pub columns: usize,
    /// Width of one panel [px].
    pub panel_width_px: u32,
    /// Height of one panel [px].
    pub panel_height_px: u32,
    /// The panels, row by row.
    pub panels: Vec<Panel>,
}

impl Default for Figure {
    fn default() -> Self {
        Self::new()
    }
}

impl Figure {
    /// An empty sheet: one column, 640x400 px panels.
    pub fn new() -> Self {
        Self {
            title: String::new(),
            columns: 1,
            panel_width_px: 640,
            panel_height_px: 400,
            panels: Vec::new(),
        }
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

    /// Pixel size of the whole sheet: `columns` panels wide (fewer if there are fewer panels), as many rows
    /// as needed, plus the sheet title band.
    pub fn size_px(&self) -> (u32, u32) {
        let count = self.panels.len().max(1);
        let columns = self.columns.clamp(1, count);
        let rows = count.div_ceil(columns);
        let width = u64::from(self.panel_width_px) * columns as u64;
        let height = u64::from(self.panel_height_px) * rows as u64 + u64::from(self.title_band_px());
        (u32::try_from(width).unwrap_or(u32::MAX), u32::try_from(height).unwrap_or(u32::MAX))
    }

    fn title_band_px(&self) -> u32 {
        if self.title.is_empty() { 0 } else { 40 }
    }

    /// Render to an RGBA pixmap (white background), e.g. to inspect pixels.
    pub fn render_pixmap(&self) -> Result<tiny_skia::Pixmap, PlotError> {
        let (width, height) = self.size_px();
        let (pw, ph) = (self.panel_width_px, self.panel_height_px);
        let too_small = pw < MIN_PANEL_PX || ph < MIN_PANEL_PX;
        if too_small || width > MAX_SIDE_PX || height > MAX_SIDE_PX {
            return Err(PlotError::InvalidSize { width, height });
        }
        let mut sheet = Pixmap::new(width, height).ok_or(PlotError::InvalidSize { width, height })?;
        sheet.fill(tiny_skia::Color::WHITE);
        if !self.title.is_empty() {
            let title = canvas::fit_text(&self.title, SHEET_TITLE_PX, width as f32 - 16.0);
            let style = TextStyle::new(SHEET_TITLE_PX).bold();
            draw_text(&mut sheet, &title, width as f32 / 2.0, 12.0, HAlign::Center, VAlign::Top, 0.0, style);
        }
        let columns = self.columns.clamp(1, self.panels.len().max(1));
        for (index, panel) in self.panels.iter().enumerate() {
            let mut pixmap = Pixmap::new(pw, ph).ok_or(PlotError::InvalidSize { width: pw, height: ph })?;
            pixmap.fill(tiny_skia::Color::WHITE);
            match panel {
                Panel::Chart(chart) => draw_chart::draw(chart, &mut pixmap),
                Panel::Heatmap(heatmap) => heatmap.draw(&mut pixmap),
            }
            let x = (index % columns) as u32 * pw;
            let y = (index / columns) as u32 * ph + self.title_band_px();
            sheet.draw_pixmap(
                i32::try_from(x).unwrap_or(i32::MAX),
                i32::try_from(y).unwrap_or(i32::MAX),
                pixmap.as_ref(),
                &PixmapPaint::default(),
                Transform::identity(),
                None,
            );
        }
        Ok(sheet)
    }

    /// Render to PNG bytes.
    pub fn render_png(&self) -> Result<Vec<u8>, PlotError> {
        self.render_pixmap()?.encode_png().map_err(|e| PlotError::Encode(e.to_string()))
    }

    /// Render and write a PNG file atomically ([`vestnav_files::write_atomic`]: a unique temporary file
    /// beside it, synced, then renamed over it).
    pub fn save_png(&self, path: &Path) -> Result<(), PlotError> {
        let bytes = self.render_png()?;
        vestnav_files::write_atomic(path, &bytes)
            .map_err(|source| PlotError::Io { path: path.to_path_buf(), source })
    }
}
