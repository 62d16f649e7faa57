//! Line/scatter charts: the builder API.

use crate::Color;

/// Axis scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    /// Linear axis.
    #[default]
    Linear,
    /// Base-10 logarithmic axis; non-positive values are skipped.
    Log10,
}

/// Marker drawn at each point of a series.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Marker {
    /// No marker.
    #[default]
    None,
    /// Filled circle.
    Circle,
    /// Filled square.
    Square,
    /// Diagonal cross.
    Cross,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SeriesKind {
    Line,
    Scatter,
}

/// One data series of a [`Chart`]: a line or a scatter of points.
#[derive(Debug, Clone)]
pub struct Series {
    pub(crate) label: String,
    pub(crate) x: Vec<f64>,
    pub(crate) y: Vec<f64>,
    pub(crate) kind: SeriesKind,
    pub(crate) dashed: bool,
    pub(crate) width_px: f32,
    pub(crate) marker: Marker,
    pub(crate) color: Option<Color>,
}

impl Series {
    /// A polyline through `(x[i], y[i])`; a NaN or infinite value breaks the line.
    /// Extra values of the longer vector are ignored.
    pub fn line(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self::new(label.into(), x, y, SeriesKind::Line, Marker::None)
    }

    /// Points at `(x[i], y[i])` drawn with a marker (default [`Marker::Circle`]).
    pub fn scatter(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self::new(label.into(), x, y, SeriesKind::Scatter, Marker::Circle)
    }

    fn new(label: String, x: Vec<f64>, y: Vec<f64>, kind: SeriesKind, marker: Marker) -> Self {
        Self { label, x, y, kind, dashed: false, width_px: 1.5, marker, color: None }
    }

    /// Draw the line dashed.
    #[must_use]
    pub fn dashed(mut self) -> Self {
        self.dashed = true;
        self
    }

    /// Line width in pixels (also scales markers).
    #[must_use]
    pub fn width(mut self, width_px: f32) -> Self {
        self.width_px = width_px;
        self
    }

    /// Marker at each point (lines default to none, scatters to circles).
    #[must_use]
    pub fn marker(mut self, marker: Marker) -> Self {
        self.marker = marker;
        self
    }

    /// Explicit colour (default: the palette by series index).
    #[must_use]
    pub fn color(mut self, color: Color) -> Self {
        self.color = Some(color);
        self
    }
}

/// A labelled horizontal or vertical reference line.
#[derive(Debug, Clone)]
pub(crate) struct RefLine {
    pub(crate) value: f64,
    pub(crate) label: String,
}

/// A circle in data units.
#[derive(Debug, Clone)]
pub(crate) struct DataCircle {
    pub(crate) cx: f64,
    pub(crate) cy: f64,
    pub(crate) r: f64,
    pub(crate) label: String,
}

/// Text placed at a data point.
#[derive(Debug, Clone)]
pub(crate) struct Annotation {
    pub(crate) x: f64,
    pub(crate) y: f64,
    pub(crate) text: String,
}

/// One chart panel: axes, ticks, grid, series, reference lines, legend and title.
#[derive(Debug, Clone)]
pub struct Chart {
    pub(crate) title: String,
    pub(crate) x_label: String,
    pub(crate) y_label: String,
    pub(crate) x_scale: Scale,
    pub(crate) y_scale: Scale,
    pub(crate) x_range: Option<(f64, f64)>,
    pub(crate) y_range: Option<(f64, f64)>,
    pub(crate) equal_aspect: bool,
    pub(crate) series: Vec<Series>,
    pub(crate) hlines: Vec<RefLine>,
    pub(crate) vlines: Vec<RefLine>,
    pub(crate) circles: Vec<DataCircle>,
    pub(crate) annotations: Vec<Annotation>,
}

impl Chart {
    /// An empty chart with a panel title.
    pub fn new(title: impl Into<String>) -> Self {
        Self {
            title: title.into(),
            x_label: String::new(),
            y_label: String::new(),
            x_scale: Scale::Linear,
            y_scale: Scale::Linear,
            x_range: None,
            y_range: None,
            equal_aspect: false,
            series: Vec::new(),
            hlines: Vec::new(),
            vlines: Vec::new(),
            circles: Vec::new(),
            annotations: Vec::new(),
        }
    }

    /// Label of the x axis, with units, e.g. `"time [s]"`.
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

    /// Scale of the x axis (default linear).
    #[must_use]
    pub fn x_scale(mut self, scale: Scale) -> Self {
        self.x_scale = scale;
        self
    }

    /// Scale of the y axis (default linear).
    #[must_use]
    pub fn y_scale(mut self, scale: Scale) -> Self {
        self.y_scale = scale;
        self
    }

    /// Explicit x range in data units (default: automatic with nice ticks).
    #[must_use]
    pub fn x_range(mut self, min: f64, max: f64) -> Self {
        self.x_range = Some((min, max));
        self
    }

    /// Explicit y range in data units (default: automatic with nice ticks).
    #[must_use]
    pub fn y_range(mut self, min: f64, max: f64) -> Self {
        self.y_range = Some((min, max));
        self
    }

    /// Make one x unit as long as one y unit on screen (for maps in metres).
    #[must_use]
    pub fn equal_aspect(mut self) -> Self {
        self.equal_aspect = true;
        self
    }

    /// Add a series.
    #[must_use]
    pub fn series(mut self, series: Series) -> Self {
        self.series.push(series);
        self
    }

    /// Add a labelled horizontal reference line at `y` (data units).
    #[must_use]
    pub fn hline(mut self, y: f64, label: impl Into<String>) -> Self {
        self.hlines.push(RefLine { value: y, label: label.into() });
        self
    }

    /// Add a labelled vertical reference line at `x` (data units).
    #[must_use]
    pub fn vline(mut self, x: f64, label: impl Into<String>) -> Self {
        self.vlines.push(RefLine { value: x, label: label.into() });
        self
    }

    /// Add a labelled circle with centre `(cx, cy)` and radius `r`, all in data units.
    #[must_use]
    pub fn circle(mut self, cx: f64, cy: f64, r: f64, label: impl Into<String>) -> Self {
        self.circles.push(DataCircle { cx, cy, r, label: label.into() });
        self
    }

    /// Write `text` at the data point `(x, y)`.
    #[must_use]
    pub fn annotate(mut self, x: f64, y: f64, text: impl Into<String>) -> Self {
        self.annotations.push(Annotation { x, y, text: text.into() });
        self
    }
}
