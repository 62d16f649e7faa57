//! Heatmaps of a regular grid with a colorbar.

/// A colour-mapped image of values on a regular `nx` by `ny` grid, with a colorbar.
#[derive(Debug, Clone)]
pub struct Heatmap {
    pub(crate) title: String,
    pub(crate) x_extent: (f64, f64),
    pub(crate) y_extent: (f64, f64),
    pub(crate) nx: usize,
    pub(crate) ny: usize,
    pub(crate) values: Vec<f64>,
    pub(crate) x_label: String,
    pub(crate) y_label: String,
    pub(crate) colorbar_label: String,
    pub(crate) value_range: Option<(f64, f64)>,
    pub(crate) points: Vec<(f64, f64, String)>,
}

impl Heatmap {
    /// A heatmap covering `x_extent` by `y_extent` (data units) with `nx * ny` cells.
    ///
    /// `values` is row-major: `values[j * nx + i]` is the cell in column `i` (from `x_extent.0`) and row `j`
    /// (row 0 at `y_extent.0`, drawn at the bottom). Missing or non-finite values are drawn blank.
    pub fn new(
        title: impl Into<String>,
        x_extent: (f64, f64),
        y_extent: (f64, f64),
        nx: usize,
        ny: usize,
        values: Vec<f64>,
    ) -> Self {
        Self {
            title: title.into(),
            x_extent,
            y_extent,
            nx,
            ny,
            values,
            x_label: String::new(),
            y_label: String::new(),
            colorbar_label: String::new(),
            value_range: None,
            points: Vec::new(),
        }
    }

    /// Label of the x axis, with units.
    #[must_use]
    pub fn x_label(mut self, label: impl Into<String>) -> Self {
        self.x_label = label.into();
        self
    }

    /// Label of the y axis, with units.
    #[must_use]
    pub fn y_label(mut self, label: impl Into<String>) -> Self {
        self.y_label = label.into();
        self
    }

    /// Label of the colorbar, with units.
    #[must_use]
    pub fn colorbar_label(mut self, label: impl Into<String>) -> Self {
        self.colorbar_label = label.into();
        self
    }

    /// Fix the value range mapped onto the colormap (default: min..max of the finite values).
    #[must_use]
    pub fn value_range(mut self, min: f64, max: f64) -> Self {
        self.value_range = Some((min, max));
        self
    }

    /// Labelled markers drawn on top, at `(x, y)` in data units.
    #[must_use]
    pub fn points(mut self, points: Vec<(f64, f64, String)>) -> Self {
        self.points = points;
        self
    }
}
