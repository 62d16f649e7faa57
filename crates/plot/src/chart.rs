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

/// How a [`Series`] is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeriesKind {
    /// A polyline (non-finite values break it).
    Line,
    /// One marker per point.
    Scatter,
}

/// One data series of a [`Chart`]: a line or a scatter of points.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label (empty: not in the legend).
    pub label: String,
    /// X values (data units).
    pub x: Vec<f64>,
    /// Y values (data units), paired with `x`.
    pub y: Vec<f64>,
    /// Line or scatter.
    pub kind: SeriesKind,
    /// Whether the line is dashed.
    pub dashed: bool,
    /// Line width [px] (also scales markers).
    pub width_px: f32,
    /// Marker at each point.
    pub marker: Marker,
    /// Explicit colour, or the palette colour of the series index when `None`.
    pub color: Option<Color>,
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
pub struct RefLine {
    /// Position in data units (y of a horizontal line, x of a vertical one).
    pub value: f64,
    /// Label drawn next to the line.
    pub label: String,
}

/// A circle in data units.
#[derive(Debug, Clone)]
pub struct DataCircle {
    /// Centre x (data units).
    pub cx: f64,
    /// Centre y (data units).
    pub cy: f64,
    /// Radius (data units).
    pub r: f64,
    /// Legend label (empty: none).
    pub label: String,
}

/// Text placed at a data point.
#[derive(Debug, Clone)]
pub struct Annotation {
    /// X of the anchor point (data units).
    pub x: f64,
    /// Y of the anchor point (data units).
    pub y: f64,
    /// The text.
    pub text: String,
}

/// One chart panel: axes, ticks, grid, series, reference lines, legend and title.
#[derive(Debug, Clone)]
pub struct Chart {
    /// Panel title.
    pub title: String,
    /// X axis label with units.
    pub x_label: String,
    /// Y axis label with units.
    pub y_label: String,
    /// X axis scale.
    pub x_scale: Scale,
    /// Y axis scale.
    pub y_scale: Scale,
    /// Explicit x range, else automatic.
    pub x_range: Option<(f64, f64)>,
    /// Explicit y range, else automatic.
    pub y_range: Option<(f64, f64)>,
    /// One x unit as long as one y unit.
    pub equal_aspect: bool,
    /// X ticks only at whole numbers (the x axis counts things: cone pairs, trials).
    pub x_integer: bool,
    /// Data series, drawn in order.
    pub series: Vec<Series>,
    /// Horizontal reference lines.
    pub hlines: Vec<RefLine>,
    /// Vertical reference lines.
    pub vlines: Vec<RefLine>,
    /// Circles in data units.
    pub circles: Vec<DataCircle>,
    /// Texts at data points.
    pub annotations: Vec<Annotation>,
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
            x_integer: false,
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

    /// Number the x axis with whole numbers only (1, 2, 3 …, never 1.2, 1.4): for axes that count things.
    #[must_use]
    pub fn x_integer(mut self) -> Self {
        self.x_integer = true;
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
