//! The Simulation panel: interactive views of the thesis physics (vestnav-core), each exportable as PNG and CSV.
//!
//! Four views, one tab each:
//! - **Tactor**: the pancake-motor ODE (thesis §3.2, Figs 28–34) with sliders for voltage, damping, radius and
//!   body mass; traces of speed, current, torque, force envelope and position, the acceleration spectrum and the
//!   summary numbers;
//! - **Damping sweep**: peak frequency against force as the damping varies, with the power-law fit, the
//!   current line and the damping calibration curve (§3.2.2–3.2.3, Figs 35–38), and "damping for frequency";
//! - **Skin waves**: the vibration field of any set of firing tactors on the vest plane at a chosen time,
//!   attenuation curves and the travelling wave at several distances (§4.1.3, Figs 52 and 57);
//! - **Two-point**: two Gaussians, their sum, the single-Gaussian fit and RMSE against distance (§4.2,
//!   Figs 60–63).
//!
//! Every view is described once as a list of [`PanelSpec`]s (titles, axis labels, series, reference lines): the
//! same data is drawn on screen with `egui_plot`, rasterised to PNG with `vestnav_plot::Figure` and written as
//! CSV, so an exported figure always shows exactly what the operator saw.
//!
//! Computations run on a worker thread ([`Recompute`]) only when their inputs change; while one runs the last
//! result stays on screen, and a slider dragged during a run only triggers one more run with its final value.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{self, Receiver, TryRecvError};
use std::time::{Duration, Instant};

use vestnav_core::sweep::{self, Calibration, SweepOptions, SweepResult};
use vestnav_core::tactor::{self, BodyMass, Preset, SimOptions, TactorParams, TactorRun};
use vestnav_core::twopoint::{self, TwoPointResult, TwoPointSetup};
use vestnav_core::vest::{GRID, TACTOR_COUNT, TactorMask};
use vestnav_core::wave::{self, GaussianAttenuation, Skin, WaveSource};

use egui_plot::{Legend, Line, LineStyle, MarkerShape, Plot, PlotPoint, Points, Text, VLine};

// ------------------------------------------------------------------------------------------------------------
// Chart descriptions shared by the screen, the PNG and the CSV export.
// ------------------------------------------------------------------------------------------------------------

/// Series colours by index when a series has none of its own (sRGB; Tableau 10), shared by screen and PNG.
const PALETTE: [[u8; 3]; 8] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
];

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SeriesKind {
    /// A polyline; non-finite values break it.
    Line,
    /// Dashed polyline (fits, model curves).
    Dashed,
    /// One marker per point.
    Scatter,
}

/// One data series of a chart.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SeriesSpec {
    /// Legend label.
    pub label: String,
    /// X values (data units of the chart's x axis).
    pub x: Vec<f64>,
    /// Y values, same length as `x`.
    pub y: Vec<f64>,
    /// Line, dashed line or scatter.
    pub kind: SeriesKind,
    /// Fixed colour (sRGB), or the palette colour of its index when `None`.
    pub color: Option<[u8; 3]>,
}

impl SeriesSpec {
    /// A solid line.
    pub fn line(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self { label: label.into(), x, y, kind: SeriesKind::Line, color: None }
    }

    /// A dashed line.
    pub fn dashed(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self { label: label.into(), x, y, kind: SeriesKind::Dashed, color: None }
    }

    /// Markers only.
    pub fn scatter(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self { label: label.into(), x, y, kind: SeriesKind::Scatter, color: None }
    }

    /// The same series in a fixed colour.
    #[must_use]
    pub fn color(mut self, rgb: [u8; 3]) -> Self {
        self.color = Some(rgb);
        self
    }
}

/// A line/scatter chart: what `egui_plot` draws on screen and `vestnav_plot::Chart` draws in the PNG.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct ChartSpec {
    /// Panel title.
    pub title: String,
    /// X axis label with unit.
    pub x_label: String,
    /// Y axis label with unit.
    pub y_label: String,
    /// Base-10 logarithmic y axis (non-positive values are not drawn).
    pub log_y: bool,
    /// One x unit as long as one y unit (maps in metres).
    pub equal_aspect: bool,
    /// Data series.
    pub series: Vec<SeriesSpec>,
    /// Labelled horizontal reference lines `(y, label)`.
    pub hlines: Vec<(f64, String)>,
    /// Labelled vertical reference lines `(x, label)`.
    pub vlines: Vec<(f64, String)>,
    /// Labelled circles `(centre x, centre y, radius, label)` in data units.
    pub circles: Vec<(f64, f64, f64, String)>,
    /// Text labels `(x, y, text)` at data points.
    pub annotations: Vec<(f64, f64, String)>,
}

impl ChartSpec {
    /// An empty chart with a title and axis labels.
    pub fn new(title: impl Into<String>, x_label: impl Into<String>, y_label: impl Into<String>) -> Self {
        Self { title: title.into(), x_label: x_label.into(), y_label: y_label.into(), ..Self::default() }
    }

    /// Adds a series.
    #[must_use]
    pub fn with(mut self, series: SeriesSpec) -> Self {
        self.series.push(series);
        self
    }

    /// Adds a horizontal reference line.
    #[must_use]
    pub fn hline(mut self, y: f64, label: impl Into<String>) -> Self {
        if y.is_finite() {
            self.hlines.push((y, label.into()));
        }
        self
    }

    /// Adds a vertical reference line.
    #[must_use]
    pub fn vline(mut self, x: f64, label: impl Into<String>) -> Self {
        if x.is_finite() {
            self.vlines.push((x, label.into()));
        }
        self
    }

    /// Adds a circle.
    #[must_use]
    pub fn circle(mut self, cx: f64, cy: f64, r: f64, label: impl Into<String>) -> Self {
        if cx.is_finite() && cy.is_finite() && r.is_finite() && r > 0.0 {
            self.circles.push((cx, cy, r, label.into()));
        }
        self
    }

    /// Switches the y axis to log10.
    #[must_use]
    pub fn log_y(mut self) -> Self {
        self.log_y = true;
        self
    }

    /// Keeps one x unit as long as one y unit.
    #[must_use]
    pub fn equal_aspect(mut self) -> Self {
        self.equal_aspect = true;
        self
    }

    /// Converts to the PNG renderer's chart.
    pub fn to_plot(&self) -> vestnav_plot::Chart {
        use vestnav_plot::{Chart, Color, Marker, Scale, Series};
        let mut chart =
            Chart::new(self.title.clone()).x_label(self.x_label.clone()).y_label(self.y_label.clone());
        if self.log_y {
            chart = chart.y_scale(Scale::Log10);
        }
        if self.equal_aspect {
            chart = chart.equal_aspect();
        }
        for (idx, s) in self.series.iter().enumerate() {
            let series = match s.kind {
                SeriesKind::Line => Series::line(s.label.clone(), s.x.clone(), s.y.clone()),
                SeriesKind::Dashed => Series::line(s.label.clone(), s.x.clone(), s.y.clone()).dashed(),
                SeriesKind::Scatter => {
                    Series::scatter(s.label.clone(), s.x.clone(), s.y.clone()).marker(Marker::Circle)
                }
            };
            let [r, g, b] = s.color.unwrap_or(PALETTE[idx % PALETTE.len()]);
            chart = chart.series(series.color(Color::rgb(r, g, b)));
        }
        for (y, label) in &self.hlines {
            chart = chart.hline(*y, label.clone());
        }
        for (x, label) in &self.vlines {
            chart = chart.vline(*x, label.clone());
        }
        for (cx, cy, r, label) in &self.circles {
            chart = chart.circle(*cx, *cy, *r, label.clone());
        }
        for (x, y, text) in &self.annotations {
            chart = chart.annotate(*x, *y, text.clone());
        }
        chart
    }

    /// Draws the chart with `egui_plot` (pan/zoom; double-click resets).
    pub fn show(&self, ui: &mut egui::Ui, id_salt: &str, height: f32) {
        let log_y = self.log_y;
        let to_y = move |y: f64| if log_y { if y > 0.0 { y.log10() } else { f64::NAN } } else { y };
        ui.label(egui::RichText::new(&self.title).strong());
        let mut plot = Plot::new(id_salt)
            .height(height)
            .legend(Legend::default())
            .x_axis_label(self.x_label.clone())
            .y_axis_label(self.y_label.clone());
        if self.equal_aspect {
            plot = plot.data_aspect(1.0);
        }
        if log_y {
            plot = plot
                .y_axis_formatter(|mark, _range| format!("{:.0e}", 10f64.powf(mark.value)))
                .label_formatter(|pos| {
                    Some(match pos {
                        egui_plot::HoverPosition::NearDataPoint { plot_name, position, .. } => {
                            format!("{plot_name}\nx = {:.4}\ny = {:.4e}", position.x, 10f64.powf(position.y))
                        }
                        egui_plot::HoverPosition::Elsewhere { position } => {
                            format!("x = {:.4}\ny = {:.4e}", position.x, 10f64.powf(position.y))
                        }
                    })
                });
        }
        plot.show(ui, |plot_ui| {
            for (idx, s) in self.series.iter().enumerate() {
                let [r, g, b] = s.color.unwrap_or(PALETTE[idx % PALETTE.len()]);
                let color = egui::Color32::from_rgb(r, g, b);
                let points: Vec<[f64; 2]> = s.x.iter().zip(&s.y).map(|(&x, &y)| [x, to_y(y)]).collect();
                match s.kind {
                    SeriesKind::Line | SeriesKind::Dashed => {
                        // egui_plot does not break lines at NaN: draw each finite run separately.
                        for run in finite_runs(&points) {
                            let mut line = Line::new(s.label.clone(), run).color(color);
                            if s.kind == SeriesKind::Dashed {
                                line = line.style(LineStyle::dashed_loose());
                            }
                            plot_ui.line(line);
                        }
                    }
                    SeriesKind::Scatter => {
                        let finite: Vec<[f64; 2]> =
                            points.into_iter().filter(|p| p[0].is_finite() && p[1].is_finite()).collect();
                        plot_ui.points(
                            Points::new(s.label.clone(), finite)
                                .shape(MarkerShape::Circle)
                                .radius(2.5)
                                .color(color),
                        );
                    }
                }
            }
            for (y, label) in &self.hlines {
                plot_ui
                    .hline(egui_plot::HLine::new(label.clone(), to_y(*y)).style(LineStyle::dashed_dense()));
            }
            for (x, label) in &self.vlines {
                plot_ui.vline(VLine::new(label.clone(), *x).style(LineStyle::dashed_dense()));
            }
            for (cx, cy, r, label) in &self.circles {
                let ring: Vec<[f64; 2]> = (0..=128)
                    .map(|k| {
                        let a = f64::from(k) / 128.0 * std::f64::consts::TAU;
                        [cx + r * a.cos(), to_y(cy + r * a.sin())]
                    })
                    .collect();
                plot_ui.line(Line::new(label.clone(), ring).style(LineStyle::dashed_loose()));
            }
            for (x, y, text) in &self.annotations {
                plot_ui.text(Text::new(text.clone(), PlotPoint::new(*x, to_y(*y)), text.clone()));
            }
        });
    }
}

/// Splits a polyline at non-finite points into runs of at least one point.
fn finite_runs(points: &[[f64; 2]]) -> Vec<Vec<[f64; 2]>> {
    let mut runs = Vec::new();
    let mut current = Vec::new();
    for p in points {
        if p[0].is_finite() && p[1].is_finite() {
            current.push(*p);
        } else if !current.is_empty() {
            runs.push(std::mem::take(&mut current));
        }
    }
    if !current.is_empty() {
        runs.push(current);
    }
    runs
}

/// A heat map on a regular grid: what `egui_plot::Heatmap` draws and `vestnav_plot::Heatmap` renders.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct HeatSpec {
    /// Panel title.
    pub title: String,
    /// X extent of the grid `(first cell's left edge, last cell's right edge)` in data units.
    pub x_extent: (f64, f64),
    /// Y extent, row 0 at `y_extent.0` (bottom).
    pub y_extent: (f64, f64),
    /// Columns.
    pub nx: usize,
    /// Rows.
    pub ny: usize,
    /// Row-major values, `values[j * nx + i]`.
    pub values: Vec<f64>,
    /// X label with unit.
    pub x_label: String,
    /// Y label with unit.
    pub y_label: String,
    /// Colorbar label with unit.
    pub colorbar_label: String,
    /// Labelled markers `(x, y, label)` on top.
    pub points: Vec<(f64, f64, String)>,
}

impl HeatSpec {
    /// Smallest and largest finite value, or `None` if there is none (or they are equal).
    fn value_range(&self) -> Option<(f64, f64)> {
        let (lo, hi) = self
            .values
            .iter()
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        (lo.is_finite() && hi > lo).then_some((lo, hi))
    }

    /// Converts to the PNG renderer's heat map.
    pub fn to_plot(&self) -> vestnav_plot::Heatmap {
        vestnav_plot::Heatmap::new(
            self.title.clone(),
            self.x_extent,
            self.y_extent,
            self.nx,
            self.ny,
            self.values.clone(),
        )
        .x_label(self.x_label.clone())
        .y_label(self.y_label.clone())
        .colorbar_label(self.colorbar_label.clone())
        .points(self.points.clone())
    }

    /// Draws the heat map with `egui_plot` (equal aspect), a colour legend line and the labelled markers.
    pub fn show(&self, ui: &mut egui::Ui, id_salt: &str, height: f32) {
        ui.label(egui::RichText::new(&self.title).strong());
        let range = self.value_range();
        if range.is_none() {
            let value = self.values.iter().find(|v| v.is_finite()).copied().unwrap_or(0.0);
            ui.label(format!("uniform field: {} = {value:.3} everywhere", self.colorbar_label));
        }
        if let Some((lo, hi)) = range {
            ui.horizontal(|ui| {
                ui.label(format!("{}:", self.colorbar_label));
                ui.label(format!("{lo:.3}"));
                let (rect, _) = ui.allocate_exact_size(egui::vec2(160.0, 12.0), egui::Sense::hover());
                let steps = 32;
                for k in 0..steps {
                    let f0 = k as f32 / steps as f32;
                    let f1 = (k + 1) as f32 / steps as f32;
                    let seg = egui::Rect::from_x_y_ranges(
                        egui::lerp(rect.x_range(), f0)..=egui::lerp(rect.x_range(), f1),
                        rect.y_range(),
                    );
                    ui.painter().rect_filled(seg, 0.0, colormap(f64::from(f0 + f1) / 2.0));
                }
                ui.label(format!("{hi:.3}"));
            });
        }
        let valid = self.nx > 0 && self.values.len() == self.nx * self.ny;
        Plot::new(id_salt)
            .height(height)
            .data_aspect(1.0)
            .x_axis_label(self.x_label.clone())
            .y_axis_label(self.y_label.clone())
            .show(ui, |plot_ui| {
                if valid && let Some((lo, hi)) = range {
                    let w = (self.x_extent.1 - self.x_extent.0) as f32;
                    let h = (self.y_extent.1 - self.y_extent.0) as f32;
                    let heat = egui_plot::Heatmap::new(self.values.clone(), self.nx)
                        .at(PlotPoint::new(self.x_extent.0, self.y_extent.0))
                        .size(w, h)
                        .show_labels(false)
                        .custom_mapping(Box::new(move |v| colormap((v - lo) / (hi - lo))));
                    plot_ui.add(heat);
                }
                let (xs, ys): (Vec<f64>, Vec<f64>) = self.points.iter().map(|p| (p.0, p.1)).unzip();
                let pts: Vec<[f64; 2]> = xs.iter().zip(&ys).map(|(&x, &y)| [x, y]).collect();
                plot_ui.points(
                    Points::new("tactors", pts)
                        .shape(MarkerShape::Circle)
                        .radius(3.0)
                        .color(egui::Color32::WHITE),
                );
                for (x, y, label) in &self.points {
                    plot_ui.text(
                        Text::new(label.clone(), PlotPoint::new(*x, *y), label.clone())
                            .color(egui::Color32::WHITE)
                            .anchor(egui::Align2::LEFT_BOTTOM),
                    );
                }
            });
    }
}

/// A perceptually ordered dark-blue → teal → yellow colour map for `f` in `[0, 1]` (clamped; NaN is grey).
fn colormap(f: f64) -> egui::Color32 {
    const STOPS: [[f32; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [253.0, 231.0, 37.0],
    ];
    if !f.is_finite() {
        return egui::Color32::GRAY;
    }
    let t = f.clamp(0.0, 1.0) as f32 * (STOPS.len() - 1) as f32;
    let i = (t.floor() as usize).min(STOPS.len() - 2);
    let u = t - i as f32;
    let mix = |k: usize| (STOPS[i][k] + (STOPS[i + 1][k] - STOPS[i][k]) * u).round().clamp(0.0, 255.0) as u8;
    egui::Color32::from_rgb(mix(0), mix(1), mix(2))
}

/// One panel of a view.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum PanelSpec {
    /// A line/scatter chart.
    Chart(ChartSpec),
    /// A heat map.
    Heat(HeatSpec),
}

impl PanelSpec {
    /// The panel's title.
    pub fn title(&self) -> &str {
        match self {
            PanelSpec::Chart(c) => &c.title,
            PanelSpec::Heat(h) => &h.title,
        }
    }

    /// Draws the panel.
    pub fn show(&self, ui: &mut egui::Ui, id_salt: &str, height: f32) {
        match self {
            PanelSpec::Chart(c) => c.show(ui, id_salt, height),
            PanelSpec::Heat(h) => h.show(ui, id_salt, height),
        }
    }
}

/// Renders panels as one PNG sheet (two columns) with `vestnav_plot`.
pub(crate) fn render_png(title: &str, panels: &[PanelSpec]) -> Result<Vec<u8>, vestnav_plot::PlotError> {
    let columns = if panels.len() > 1 { 2 } else { 1 };
    let mut figure = vestnav_plot::Figure::new().title(title).columns(columns).panel_size(640, 400);
    for p in panels {
        figure = match p {
            PanelSpec::Chart(c) => figure.push(c.to_plot()),
            PanelSpec::Heat(h) => figure.push(h.to_plot()),
        };
    }
    figure.render_png()
}

/// Quotes a CSV field if it contains a separator, quote or line break (RFC 4180).
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() }
}

/// The panels' data as CSV in long form: one row per point, `panel,series,x,y` (heat maps: `panel,cell,x,y,
/// value` with the cell centre), reference lines as rows with an empty coordinate. `header` lines (summary
/// numbers) come first, each prefixed with `# `.
pub(crate) fn panels_csv(header: &[String], panels: &[PanelSpec]) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    for h in header {
        let _ = writeln!(out, "# {}", h.replace(['\n', '\r'], " "));
    }
    let _ = writeln!(out, "panel,series,x,y,value");
    for p in panels {
        let title = csv_field(p.title());
        match p {
            PanelSpec::Chart(c) => {
                for s in &c.series {
                    let label = csv_field(&s.label);
                    for (x, y) in s.x.iter().zip(&s.y) {
                        let _ = writeln!(out, "{title},{label},{x},{y},");
                    }
                }
                for (y, label) in &c.hlines {
                    let _ = writeln!(out, "{title},{},,{y},", csv_field(&format!("hline: {label}")));
                }
                for (x, label) in &c.vlines {
                    let _ = writeln!(out, "{title},{},{x},,", csv_field(&format!("vline: {label}")));
                }
                for (cx, cy, r, label) in &c.circles {
                    let _ = writeln!(out, "{title},{},{cx},{cy},{r}", csv_field(&format!("circle: {label}")));
                }
            }
            PanelSpec::Heat(h) => {
                let dx = (h.x_extent.1 - h.x_extent.0) / h.nx.max(1) as f64;
                let dy = (h.y_extent.1 - h.y_extent.0) / h.ny.max(1) as f64;
                for (k, v) in h.values.iter().enumerate() {
                    let (i, j) = (k % h.nx.max(1), k / h.nx.max(1));
                    let x = h.x_extent.0 + (i as f64 + 0.5) * dx;
                    let y = h.y_extent.0 + (j as f64 + 0.5) * dy;
                    let _ = writeln!(out, "{title},cell,{x},{y},{v}");
                }
                for (x, y, label) in &h.points {
                    let _ = writeln!(out, "{title},{},{x},{y},", csv_field(&format!("point: {label}")));
                }
            }
        }
    }
    out
}

/// Reduces a long trace to at most about `max_points` points for drawing, keeping each bucket's minimum and
/// maximum (in their original order) so peaks and envelopes survive. Shorter traces are returned unchanged.
pub(crate) fn decimate_minmax(x: &[f64], y: &[f64], max_points: usize) -> (Vec<f64>, Vec<f64>) {
    let n = x.len().min(y.len());
    if n <= max_points || max_points < 4 {
        return (x[..n].to_vec(), y[..n].to_vec());
    }
    let buckets = max_points / 2;
    let size = n.div_ceil(buckets);
    let mut xs = Vec::with_capacity(2 * buckets + 2);
    let mut ys = Vec::with_capacity(2 * buckets + 2);
    let mut start = 0;
    while start < n {
        let end = (start + size).min(n);
        let (mut lo, mut hi) = (start, start);
        for k in start..end {
            if y[k] < y[lo] {
                lo = k;
            }
            if y[k] > y[hi] {
                hi = k;
            }
        }
        xs.push(x[lo.min(hi)]);
        ys.push(y[lo.min(hi)]);
        if lo != hi {
            xs.push(x[lo.max(hi)]);
            ys.push(y[lo.max(hi)]);
        }
        start = end;
    }
    (xs, ys)
}

// ------------------------------------------------------------------------------------------------------------
// Background computation and export plumbing.
// ------------------------------------------------------------------------------------------------------------

type ComputeFn<I, O> = fn(&I) -> Result<O, String>;
/// A run in flight: its inputs, start time and the channel its result arrives on.
type Pending<I, O> = (I, Instant, Receiver<Result<O, String>>);

/// Panels and header lines derived from cached results, with the key they were derived from.
struct Derived<K> {
    key: K,
    panels: Vec<PanelSpec>,
    header: Vec<String>,
}

/// A cached computation that runs on a worker thread when its inputs change.
///
/// Each frame the view calls [`Recompute::update`] with the inputs it wants shown. If no run is in flight and
/// the inputs differ from the last ones requested, one run starts on a named thread; its result replaces the
/// shown one when it arrives (the thread wakes the UI with `request_repaint`). Inputs changed during a run are
/// picked up by the next run, so dragging a slider never queues more than one run.
pub(crate) struct Recompute<I, O> {
    compute: ComputeFn<I, O>,
    shown: Option<(I, Arc<O>)>,
    running: Option<Pending<I, O>>,
    requested: Option<I>,
    error: Option<String>,
    last_duration: Option<Duration>,
    generation: u64,
}

impl<I, O> Recompute<I, O>
where
    I: Clone + PartialEq + Send + 'static,
    O: Send + Sync + 'static,
{
    /// A computation with nothing computed yet.
    pub fn new(compute: ComputeFn<I, O>) -> Self {
        Self {
            compute,
            shown: None,
            running: None,
            requested: None,
            error: None,
            last_duration: None,
            generation: 0,
        }
    }

    /// Collects a finished run and starts a new one if `wanted` has not been requested yet.
    pub fn update(&mut self, ctx: &egui::Context, wanted: &I) {
        self.poll();
        if self.running.is_none() && self.requested.as_ref() != Some(wanted) {
            self.start(ctx, wanted.clone());
        }
    }

    fn poll(&mut self) {
        let Some((inputs, started, rx)) = &self.running else { return };
        let outcome = match rx.try_recv() {
            Ok(result) => result,
            Err(TryRecvError::Empty) => return,
            Err(TryRecvError::Disconnected) => {
                Err("the computation thread stopped without a result".to_string())
            }
        };
        self.last_duration = Some(started.elapsed());
        match outcome {
            Ok(output) => {
                self.shown = Some((inputs.clone(), Arc::new(output)));
                self.generation += 1;
                self.error = None;
            }
            Err(e) => self.error = Some(e),
        }
        self.running = None;
    }

    fn start(&mut self, ctx: &egui::Context, inputs: I) {
        let (tx, rx) = mpsc::sync_channel(1);
        let compute = self.compute;
        let job_inputs = inputs.clone();
        let ctx = ctx.clone();
        let spawned = std::thread::Builder::new().name("vestnav-sim".to_string()).spawn(move || {
            let result = compute(&job_inputs);
            // The panel may be gone; then nobody needs the result.
            let _ = tx.send(result);
            ctx.request_repaint();
        });
        self.requested = Some(inputs.clone());
        match spawned {
            Ok(_) => self.running = Some((inputs, Instant::now(), rx)),
            Err(e) => self.error = Some(format!("cannot start a computation thread: {e}")),
        }
    }

    /// The last successful result and the inputs it was computed for.
    pub fn shown(&self) -> Option<(&I, &Arc<O>)> {
        self.shown.as_ref().map(|(i, o)| (i, o))
    }

    /// Counts the results shown so far: derived data cached for one generation is stale for the next.
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Whether a run is in flight.
    pub fn is_running(&self) -> bool {
        self.running.is_some()
    }

    /// The error of the last run, if it failed.
    #[cfg(test)]
    pub fn error(&self) -> Option<&str> {
        self.error.as_deref()
    }

    /// Wall time of the last finished run.
    #[cfg(test)]
    pub fn last_duration(&self) -> Option<Duration> {
        self.last_duration
    }

    /// Status line: computing / error / last run time.
    pub fn status_ui(&self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            if self.is_running() {
                ui.spinner();
                ui.label("computing...");
            } else if let Some(d) = self.last_duration {
                ui.weak(format!("computed in {:.1} ms", d.as_secs_f64() * 1e3));
            }
            if let Some(e) = &self.error {
                ui.colored_label(ui.visuals().error_fg_color, format!("error: {e}"));
            }
        });
    }

    /// Blocks until the running computation (if any) has finished; for tests.
    #[cfg(test)]
    pub fn wait(&mut self) {
        while self.running.is_some() {
            std::thread::sleep(Duration::from_millis(2));
            self.poll();
        }
    }
}

/// What an export writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ExportFormat {
    /// A PNG sheet of the panels.
    Png,
    /// The panels' data as CSV.
    Csv,
    /// A JSON report.
    Json,
}

impl ExportFormat {
    fn extension(self) -> &'static str {
        match self {
            ExportFormat::Png => "png",
            ExportFormat::Csv => "csv",
            ExportFormat::Json => "json",
        }
    }

    fn button_text(self) -> &'static str {
        match self {
            ExportFormat::Png => "Save PNG",
            ExportFormat::Csv => "Save CSV",
            ExportFormat::Json => "Save JSON",
        }
    }
}

/// Where a view's export goes (a path the operator types) and how the last export went.
///
/// The path's extension is replaced by `.png`, `.csv` or `.json` according to the button pressed, so one path
/// serves every format. Writing runs on a worker thread (rasterising a sheet can take a noticeable fraction of a second).
pub(crate) struct Exporter {
    /// The path typed by the operator.
    pub path: String,
    status: Option<Result<String, String>>,
    running: Option<Receiver<Result<String, String>>>,
}

impl Exporter {
    /// An exporter proposing `default_path`.
    pub fn new(default_path: &str) -> Self {
        Self { path: default_path.to_string(), status: None, running: None }
    }

    /// The path an export in `format` writes to: the typed path with its extension replaced.
    pub fn target(&self, format: ExportFormat) -> Option<PathBuf> {
        let typed = self.path.trim();
        if typed.is_empty() {
            return None;
        }
        Some(Path::new(typed).with_extension(format.extension()))
    }

    /// Starts writing `bytes()` to the target path on a worker thread.
    pub fn start(
        &mut self,
        ctx: &egui::Context,
        format: ExportFormat,
        bytes: impl FnOnce() -> Result<Vec<u8>, String> + Send + 'static,
    ) {
        let Some(path) = self.target(format) else {
            self.status = Some(Err("type a file path first".to_string()));
            return;
        };
        let (tx, rx) = mpsc::sync_channel(1);
        let ctx = ctx.clone();
        let spawned = std::thread::Builder::new().name("vestnav-export".to_string()).spawn(move || {
            let result = bytes().and_then(|data| {
                std::fs::write(&path, &data)
                    .map(|()| format!("wrote {} ({} bytes)", path.display(), data.len()))
                    .map_err(|e| format!("cannot write {}: {e}", path.display()))
            });
            let _ = tx.send(result);
            ctx.request_repaint();
        });
        match spawned {
            Ok(_) => {
                self.running = Some(rx);
                self.status = None;
            }
            Err(e) => self.status = Some(Err(format!("cannot start the export thread: {e}"))),
        }
    }

    /// Collects a finished export.
    pub fn poll(&mut self) {
        let Some(rx) = &self.running else { return };
        match rx.try_recv() {
            Ok(result) => {
                self.status = Some(result);
                self.running = None;
            }
            Err(TryRecvError::Empty) => {}
            Err(TryRecvError::Disconnected) => {
                self.status = Some(Err("the export thread stopped without a result".to_string()));
                self.running = None;
            }
        }
    }

    /// Result of the last export: `Ok(message)` or `Err(reason)`.
    #[cfg(test)]
    pub fn status(&self) -> Option<&Result<String, String>> {
        self.status.as_ref()
    }

    /// Whether an export is being written.
    pub fn is_running(&self) -> bool {
        self.running.is_some()
    }

    /// Blocks until the running export (if any) has finished; for tests.
    #[cfg(test)]
    pub fn wait(&mut self) {
        while self.running.is_some() {
            std::thread::sleep(Duration::from_millis(2));
            self.poll();
        }
    }

    /// The export row: path field, one "Save ..." button per format, and the outcome. Returns the format of
    /// the button pressed this frame.
    pub fn ui(&mut self, ui: &mut egui::Ui, formats: &[ExportFormat]) -> Option<ExportFormat> {
        self.poll();
        let mut pressed = None;
        ui.horizontal(|ui| {
            ui.label("Export to:");
            ui.add(egui::TextEdit::singleline(&mut self.path).desired_width(260.0).hint_text("path/figure"));
            ui.add_enabled_ui(!self.is_running(), |ui| {
                for &format in formats {
                    if ui.button(format.button_text()).clicked() {
                        pressed = Some(format);
                    }
                }
            });
            if self.is_running() {
                ui.spinner();
            }
            match &self.status {
                Some(Ok(msg)) => {
                    ui.label(msg);
                }
                Some(Err(e)) => {
                    ui.colored_label(ui.visuals().error_fg_color, e);
                }
                None => {}
            }
        });
        pressed
    }
}

/// Draws the export row for `panels` and starts the export the operator asked for.
fn export_row(
    ui: &mut egui::Ui,
    exporter: &mut Exporter,
    title: &str,
    header: Vec<String>,
    panels: &[PanelSpec],
) {
    if let Some(format) = exporter.ui(ui, &[ExportFormat::Png, ExportFormat::Csv]) {
        let panels = panels.to_vec();
        let title = title.to_string();
        let ctx = ui.ctx().clone();
        match format {
            ExportFormat::Png => exporter.start(&ctx, format, move || {
                render_png(&title, &panels).map_err(|e| format!("cannot render the figure: {e}"))
            }),
            ExportFormat::Csv | ExportFormat::Json => {
                exporter.start(
                    &ctx,
                    ExportFormat::Csv,
                    move || Ok(panels_csv(&header, &panels).into_bytes()),
                );
            }
        }
    }
}

/// Draws panels in a two-column grid that fills the available width.
pub(crate) fn panels_grid(ui: &mut egui::Ui, id: &str, panels: &[PanelSpec], height: f32) {
    let columns = if ui.available_width() > 900.0 { 2 } else { 1 };
    for (row, chunk) in panels.chunks(columns).enumerate() {
        ui.columns(columns, |cols| {
            for (k, (col, panel)) in cols.iter_mut().zip(chunk).enumerate() {
                panel.show(col, &format!("{id}-{row}-{k}"), height);
            }
        });
    }
}

// ------------------------------------------------------------------------------------------------------------
// The panel and its tabs.
// ------------------------------------------------------------------------------------------------------------

/// Which view the panel shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Tab {
    Tactor,
    Sweep,
    Waves,
    TwoPoint,
}

/// Interactive simulation views: tactor model, damping sweep, skin waves and the two-point simulation, each
/// with its own inputs, cached results and PNG/CSV export.
pub struct SimPanel {
    tab: Tab,
    tactor: TactorView,
    sweep: SweepView,
    waves: WaveView,
    twopoint: TwoPointView,
}

impl Default for SimPanel {
    fn default() -> Self {
        Self::new()
    }
}

impl SimPanel {
    /// A panel with the thesis's default inputs (thesis-sim preset, unencased, 3.3 V, b = 6.3e-8 N m s).
    pub fn new() -> Self {
        Self {
            tab: Tab::Tactor,
            tactor: TactorView::new(),
            sweep: SweepView::new(),
            waves: WaveView::new(),
            twopoint: TwoPointView::new(),
        }
    }

    /// Draws the panel. Computations start on worker threads when inputs change; the frame never waits.
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.selectable_value(&mut self.tab, Tab::Tactor, "Tactor model");
            ui.selectable_value(&mut self.tab, Tab::Sweep, "Damping sweep");
            ui.selectable_value(&mut self.tab, Tab::Waves, "Skin waves");
            ui.selectable_value(&mut self.tab, Tab::TwoPoint, "Two-point");
        });
        ui.separator();
        match self.tab {
            Tab::Tactor => self.tactor.ui(ui),
            Tab::Sweep => {
                if let Some(damping_n_m_s) = self.sweep.ui(ui) {
                    let (t, s) = (&mut self.tactor.inputs, &self.sweep.inputs);
                    t.damping_n_m_s = damping_n_m_s;
                    t.preset = s.preset;
                    t.voltage_v = s.voltage_v;
                    t.body = s.body;
                    t.radius_m = s.radius_m;
                    self.tab = Tab::Tactor;
                }
            }
            Tab::Waves => self.waves.ui(ui),
            Tab::TwoPoint => self.twopoint.ui(ui),
        }
    }
}

/// Height of one plot on screen [points].
const PLOT_HEIGHT: f32 = 220.0;
/// Most points per trace drawn on screen and exported (min/max decimation keeps the envelope).
const MAX_TRACE_POINTS: usize = 4000;

// ---------------------------------------------------- Tactor ----------------------------------------------------

/// Output sampling rate of the tactor traces [Hz] (the thesis's 10 kHz).
const TACTOR_RATE_HZ: f64 = 10_000.0;

/// Inputs of the tactor view.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TactorInputs {
    preset: Preset,
    body: BodyMass,
    voltage_v: f64,
    damping_n_m_s: f64,
    radius_m: f64,
    duration_s: f64,
    /// Also simulate the other body mass (Figs 28–31 compare unencased and encased).
    compare_bodies: bool,
}

impl TactorInputs {
    fn params(&self, body: BodyMass) -> TactorParams {
        TactorParams::preset(self.preset)
            .with_body(body)
            .with_voltage(self.voltage_v)
            .with_damping(self.damping_n_m_s)
            .with_radius(self.radius_m)
    }

    fn bodies(&self) -> Vec<BodyMass> {
        let other = match self.body {
            BodyMass::Unencased => BodyMass::Encased,
            BodyMass::Encased => BodyMass::Unencased,
        };
        if self.compare_bodies { vec![self.body, other] } else { vec![self.body] }
    }
}

/// One simulation per body mass asked for; the first is the selected body.
struct TactorOutput {
    runs: Vec<TactorRun>,
}

fn compute_tactor(inputs: &TactorInputs) -> Result<TactorOutput, String> {
    let options = SimOptions { duration_s: inputs.duration_s, output_rate_hz: TACTOR_RATE_HZ };
    let runs = inputs
        .bodies()
        .into_iter()
        .map(|body| tactor::simulate(&inputs.params(body), &options).map_err(|e| e.to_string()))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(TactorOutput { runs })
}

/// Peak of `|y|` over consecutive blocks of `block` samples, at each block's centre time: the amplitude
/// envelope of an oscillation when a block spans one period (thesis Figs 30–31 plot this envelope).
fn block_envelope(t: &[f64], y: &[f64], block: usize) -> (Vec<f64>, Vec<f64>) {
    let block = block.max(1);
    let n = t.len().min(y.len());
    let mut te = Vec::with_capacity(n / block + 1);
    let mut ye = Vec::with_capacity(n / block + 1);
    for start in (0..n).step_by(block) {
        let end = (start + block).min(n);
        if end - start < block && start > 0 {
            break; // a partial last block would under-read the peak
        }
        let peak = y[start..end].iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        te.push(0.5 * (t[start] + t[end - 1]));
        ye.push(peak);
    }
    (te, ye)
}

/// The tactor view's panels for traces shown over `0..=span_s` (thesis Figs 28–34).
fn tactor_panels(out: &TactorOutput, span_s: f64) -> Vec<PanelSpec> {
    let mut omega = ChartSpec::new("Rotor speed (Fig 28 rate)", "time [s]", "omega [rad/s]");
    let mut current = ChartSpec::new("Motor current (Fig 33)", "time [s]", "current [A]");
    let mut torque = ChartSpec::new("Motor torque (Fig 32)", "time [s]", "torque [N m]");
    let mut force =
        ChartSpec::new("Force amplitude, per-revolution peak (Fig 31)", "time [s]", "|force| [N]");
    let mut position = ChartSpec::new("Body position (Fig 29)", "time [s]", "x [mm]");
    let mut spectrum =
        ChartSpec::new("Acceleration spectrum, last 1 s (Fig 34)", "frequency [Hz]", "|a| [m/s^2]").log_y();
    for (k, run) in out.runs.iter().enumerate() {
        let tr = &run.traces;
        let sm = &run.summary;
        let name = sm.params.body.name();
        let n_span = tr.t_s.iter().take_while(|&&t| t <= span_s).count().max(2).min(tr.len());
        let t = &tr.t_s[..n_span];
        let trace = |y: &[f64], scale: f64| {
            let scaled: Vec<f64> = y[..n_span].iter().map(|v| v * scale).collect();
            decimate_minmax(t, &scaled, MAX_TRACE_POINTS)
        };
        let (x, y) = trace(&tr.omega_rad_s, 1.0);
        omega = omega.with(SeriesSpec::line(name, x, y));
        let (x, y) = trace(&tr.current_a, 1.0);
        current = current.with(SeriesSpec::line(name, x, y));
        let (x, y) = trace(&tr.torque_n_m, 1.0);
        torque = torque.with(SeriesSpec::line(name, x, y));
        let (x, y) = trace(&tr.x_m, 1e3);
        position = position.with(SeriesSpec::line(name, x, y));
        let steady = sm.steady_state;
        let period_samples = (TACTOR_RATE_HZ / steady.f_rot_hz.max(1.0)).round() as usize;
        let (x, y) = block_envelope(t, &tr.force_n[..n_span], period_samples);
        let (x, y) = decimate_minmax(&x, &y, MAX_TRACE_POINTS);
        force = force.with(SeriesSpec::line(name, x, y));
        let fft_len = (TACTOR_RATE_HZ as usize).min(tr.len() / 2).max(4).min(tr.len());
        let (f, a) = tactor::amplitude_spectrum(&tr.accel_m_s2[tr.len() - fft_len..], TACTOR_RATE_HZ);
        let keep = f.iter().take_while(|&&f| f <= 1000.0).count();
        spectrum = spectrum.with(SeriesSpec::line(name, f[..keep].to_vec(), a[..keep].to_vec()));
        if k == 0 {
            omega = omega.hline(steady.omega_rad_s, "closed-form steady speed");
            if let Some(ts) = sm.settling_time_s {
                omega = omega.vline(ts, "2 % settled");
            }
            current = current.hline(steady.current_a, "closed-form steady current");
            torque = torque.hline(steady.torque_n_m, "closed-form steady torque");
            force = force.hline(steady.force_amplitude_n, "closed form m l omega^2");
            spectrum = spectrum.vline(sm.fft_peak_1s_hz, "FFT peak");
        }
    }
    [omega, current, torque, force, position, spectrum].into_iter().map(PanelSpec::Chart).collect()
}

/// The summary numbers of each run, one line each (also the CSV header).
fn tactor_header(out: &TactorOutput) -> Vec<String> {
    let mut lines = Vec::new();
    for run in &out.runs {
        let s = &run.summary;
        let p = &s.params;
        lines.push(format!(
            "{} preset ({} ohm), {}, u = {} V, b = {:.4e} N m s, l = {} mm, T = {} s, window {}..{} s",
            p.preset.name(),
            p.resistance_ohm,
            p.body.name(),
            p.voltage_v,
            p.damping_n_m_s,
            p.radius_m * 1e3,
            s.options.duration_s,
            s.window_start_s,
            s.window_end_s
        ));
        for (name, value) in summary_rows(s) {
            lines.push(format!("{}: {name} = {value}", p.body.name()));
        }
    }
    lines
}

/// Named summary values with units, for the table and the CSV header.
fn summary_rows(s: &tactor::Summary) -> Vec<(&'static str, String)> {
    let ss = &s.steady_state;
    vec![
        ("mean omega [rad/s]", format!("{:.4}", s.omega_mean_rad_s)),
        ("closed-form omega [rad/s]", format!("{:.4}", ss.omega_rad_s)),
        ("f_rot [Hz]", format!("{:.4}", s.f_rot_hz)),
        ("omega min / max [rad/s]", format!("{:.3} / {:.3}", s.omega_min_rad_s, s.omega_max_rad_s)),
        ("omega ripple", format!("{:.4}", s.omega_ripple)),
        ("FFT peak [Hz]", format!("{:.1} ({} s window)", s.fft_peak_1s_hz, s.fft_window_s)),
        ("peak acceleration [m/s^2]", format!("{:.3}", s.accel_peak_m_s2)),
        ("force amplitude [N]", format!("{:.5}", s.force_amplitude_n)),
        ("x amplitude [mm]", format!("{:.6}", s.x_amplitude_m * 1e3)),
        (
            "current peak / mean [mA]",
            format!("{:.3} / {:.3}", s.current_peak_a * 1e3, s.current_mean_a * 1e3),
        ),
        (
            "torque peak / mean [uN m]",
            format!("{:.4} / {:.4}", s.torque_peak_n_m * 1e6, s.torque_mean_n_m * 1e6),
        ),
        (
            "2 % settling time [s]",
            s.settling_time_s.map_or_else(|| "not settled".to_string(), |t| format!("{t:.4}")),
        ),
        ("start current u/R [mA]", format!("{:.3}", ss.start_current_a * 1e3)),
        ("L/R [us]", format!("{:.2}", ss.electrical_time_constant_s * 1e6)),
    ]
}

struct TactorView {
    inputs: TactorInputs,
    /// Traces are drawn over `0..=span_s`.
    span_s: f64,
    job: Recompute<TactorInputs, TactorOutput>,
    /// Panels derived from result `generation` for `span_s`.
    /// Keyed by (result generation, bits of `span_s`).
    panels: Option<Derived<(u64, u64)>>,
    exporter: Exporter,
}

impl TactorView {
    fn new() -> Self {
        Self {
            inputs: TactorInputs {
                preset: Preset::ThesisSim,
                body: BodyMass::Unencased,
                voltage_v: 3.3,
                damping_n_m_s: tactor::DAMPING_THESIS_N_M_S,
                radius_m: tactor::RADIUS_CAD_M,
                duration_s: 10.0,
                compare_bodies: true,
            },
            span_s: 0.5,
            job: Recompute::new(compute_tactor),
            panels: None,
            exporter: Exporter::new("vestnav-tactor.png"),
        }
    }

    /// Recomputes if needed and refreshes the derived panels.
    fn refresh(&mut self, ctx: &egui::Context) {
        self.job.update(ctx, &self.inputs);
        let key = (self.job.generation(), self.span_s.to_bits());
        let Some((_, out)) = self.job.shown() else { return };
        if self.panels.as_ref().is_none_or(|d| d.key != key) {
            let out = Arc::clone(out);
            self.panels =
                Some(Derived { key, panels: tactor_panels(&out, self.span_s), header: tactor_header(&out) });
        }
    }

    fn controls(&mut self, ui: &mut egui::Ui) {
        let i = &mut self.inputs;
        ui.horizontal_wrapped(|ui| {
            egui::ComboBox::from_label("preset").selected_text(i.preset.name()).show_ui(ui, |ui| {
                ui.selectable_value(&mut i.preset, Preset::ThesisSim, "thesis-sim (R = 62 ohm)");
                ui.selectable_value(&mut i.preset, Preset::Measured, "measured (R = 67 ohm)");
            });
            ui.separator();
            ui.label("body:");
            ui.radio_value(&mut i.body, BodyMass::Unencased, "unencased (3.7 g)");
            ui.radio_value(&mut i.body, BodyMass::Encased, "encased (4.95 g)");
            ui.checkbox(&mut i.compare_bodies, "overlay the other body");
        });
        ui.horizontal_wrapped(|ui| {
            ui.add(egui::Slider::new(&mut i.voltage_v, 0.5..=6.0).text("voltage [V]").fixed_decimals(3));
            ui.add(
                egui::Slider::new(&mut i.damping_n_m_s, 1e-9..=1e-6)
                    .logarithmic(true)
                    .text("damping b [N m s]")
                    .custom_formatter(|v, _| format!("{v:.3e}"))
                    .custom_parser(|s| s.trim().parse::<f64>().ok()),
            );
            if ui.small_button("thesis b").clicked() {
                i.damping_n_m_s = tactor::DAMPING_THESIS_N_M_S;
            }
        });
        ui.horizontal_wrapped(|ui| {
            let mut radius_mm = i.radius_m * 1e3;
            ui.add(
                egui::Slider::new(&mut radius_mm, 1.0..=5.0)
                    .text("eccentric radius l [mm]")
                    .fixed_decimals(2),
            );
            if ui.small_button("CAD 2.57").clicked() {
                radius_mm = tactor::RADIUS_CAD_M * 1e3;
            }
            if ui.small_button("fitted 3.2").clicked() {
                radius_mm = tactor::RADIUS_FITTED_M * 1e3;
            }
            i.radius_m = radius_mm * 1e-3;
            ui.add(egui::Slider::new(&mut i.duration_s, 0.2..=10.0).text("simulated [s]").fixed_decimals(1));
            ui.add(
                egui::Slider::new(&mut self.span_s, 0.005..=10.0)
                    .logarithmic(true)
                    .text("traces shown [s]")
                    .fixed_decimals(3),
            );
        });
    }

    fn ui(&mut self, ui: &mut egui::Ui) {
        self.controls(ui);
        let ctx = ui.ctx().clone();
        self.refresh(&ctx);
        self.job.status_ui(ui);
        let Some(Derived { panels, header, .. }) = &self.panels else {
            return;
        };
        if let Some((_, out)) = self.job.shown() {
            summary_table(ui, out);
        }
        export_row(ui, &mut self.exporter, "Simulated tactor (thesis Figs 28-34)", header.clone(), panels);
        egui::ScrollArea::vertical().id_salt("sim-tactor-scroll").show(ui, |ui| {
            panels_grid(ui, "sim-tactor", panels, PLOT_HEIGHT);
        });
    }
}

/// The summary numbers of every run side by side.
fn summary_table(ui: &mut egui::Ui, out: &TactorOutput) {
    egui::CollapsingHeader::new("Summary (window = last half of the run)").default_open(true).show(
        ui,
        |ui| {
            egui::Grid::new("sim-tactor-summary").striped(true).show(ui, |ui| {
                ui.strong("quantity");
                for run in &out.runs {
                    ui.strong(run.summary.params.body.name());
                }
                ui.end_row();
                let rows: Vec<Vec<(&str, String)>> =
                    out.runs.iter().map(|r| summary_rows(&r.summary)).collect();
                if let Some(first) = rows.first() {
                    for (k, (name, _)) in first.iter().enumerate() {
                        ui.label(*name);
                        for r in &rows {
                            ui.monospace(r.get(k).map_or("", |v| v.1.as_str()));
                        }
                        ui.end_row();
                    }
                }
            });
        },
    );
}

// ---------------------------------------------------- Skin waves ----------------------------------------------------

/// Inputs of the skin-wave view (lengths in mm as the sliders show them).
#[derive(Debug, Clone, Copy, PartialEq)]
struct WaveInputs {
    /// Firing tactors (vest numbering).
    mask: TactorMask,
    /// Centre-to-centre tactor spacing [mm].
    spacing_mm: f64,
    /// Source amplitude a0 [m/s^2].
    amplitude_m_s2: f64,
    /// Gaussian width b [mm].
    width_mm: f64,
    /// Vibration frequency [Hz].
    frequency_hz: f64,
    /// Wave speed on the skin [m/s].
    speed_m_s: f64,
    /// Time of the snapshot [ms].
    t_ms: f64,
    /// Show the peak amplitude over time instead of the snapshot.
    peak: bool,
}

/// Cells per side of the vest field heat map.
const FIELD_CELLS: usize = 81;

/// The view's panels and header lines.
struct PanelsOutput {
    panels: Vec<PanelSpec>,
    header: Vec<String>,
}

fn compute_waves(i: &WaveInputs) -> Result<PanelsOutput, String> {
    let spacing_m = i.spacing_mm * 1e-3;
    let template = WaveSource {
        amplitude_m_s2: i.amplitude_m_s2,
        width_m: i.width_mm * 1e-3,
        frequency_hz: i.frequency_hz,
        ..WaveSource::measured(wave::tactor_position_m(0, 0.0).unwrap_or_default()) // moved per tactor below
    };
    let skin = Skin { speed_m_s: i.speed_m_s };
    let sources = wave::vest_sources(i.mask, spacing_m, &template);
    let t_s = i.t_ms * 1e-3;

    // Field over the grid plus one spacing of margin on every side.
    let half_m = 2.5 * spacing_m;
    let cell_m = 2.0 * half_m / FIELD_CELLS as f64;
    // The plane's origin as the core's vector type (this crate does not depend on glam itself): every point
    // below is `origin.with_x(x).with_y(y)`.
    let origin = wave::tactor_position_m(0, 0.0).unwrap_or_default();
    let mut values = Vec::with_capacity(FIELD_CELLS * FIELD_CELLS);
    for row in 0..FIELD_CELLS {
        let y = -half_m + (row as f64 + 0.5) * cell_m;
        for col in 0..FIELD_CELLS {
            let x = -half_m + (col as f64 + 0.5) * cell_m;
            let p = origin.with_x(x).with_y(y);
            values.push(if i.peak {
                skin.peak_amplitude_m_s2(&sources, p)
            } else {
                skin.field_m_s2(&sources, p, t_s)
            });
        }
    }
    let points = (0..TACTOR_COUNT)
        .filter_map(|k| wave::tactor_position_m(k, i.spacing_mm).map(|p| (p.x, p.y, format!("{k}"))))
        .collect();
    let (title, unit) = if i.peak {
        ("Vest field: peak amplitude over time (back view)".to_string(), "peak |a| [m/s^2]")
    } else {
        (format!("Vest field at t = {:.2} ms (back view)", i.t_ms), "a [m/s^2]")
    };
    let heat = HeatSpec {
        title,
        x_extent: (-half_m * 1e3, half_m * 1e3),
        y_extent: (-half_m * 1e3, half_m * 1e3),
        nx: FIELD_CELLS,
        ny: FIELD_CELLS,
        values,
        x_label: "x, to the wearer's right [mm]".to_string(),
        y_label: "y, up [mm]".to_string(),
        colorbar_label: unit.to_string(),
        points,
    };

    // Attenuation with distance: the three tactors of Fig 52 and the source used here.
    let d_mm: Vec<f64> = (0..=120).map(f64::from).collect();
    let mut atten =
        ChartSpec::new("Attenuation with distance (Fig 52)", "distance [mm]", "amplitude [m/s^2]");
    for (k, (&a0, &b)) in wave::FIG52_A0_M_S2.iter().zip(&wave::FIG52_WIDTHS_M).enumerate() {
        let g = GaussianAttenuation { a0_m_s2: a0, width_m: b };
        let y = d_mm.iter().map(|d| g.amplitude_m_s2(d * 1e-3)).collect();
        atten = atten.with(SeriesSpec::dashed(
            format!("Fig 52 tactor {}: a0 = {a0}, b = {:.2} mm", k + 1, b * 1e3),
            d_mm.clone(),
            y,
        ));
    }
    let g = GaussianAttenuation { a0_m_s2: i.amplitude_m_s2, width_m: i.width_mm * 1e-3 };
    let y = d_mm.iter().map(|d| g.amplitude_m_s2(d * 1e-3)).collect();
    atten = atten.with(SeriesSpec::line("this source", d_mm.clone(), y).color([20, 20, 20]));
    let rule_m = wave::spacing_for_fraction_m(i.width_mm * 1e-3, wave::SPACING_RULE_FRACTION)
        .map_err(|e| e.to_string())?;
    let neighbour_m_s2 = g.amplitude_m_s2(spacing_m);
    let neighbour_fraction = neighbour_m_s2 / i.amplitude_m_s2;
    atten = atten
        .with(
            SeriesSpec::scatter(
                format!("neighbour at {} mm: {:.1} %", i.spacing_mm, neighbour_fraction * 100.0),
                vec![i.spacing_mm],
                vec![neighbour_m_s2],
            )
            .color([214, 39, 40]),
        )
        .hline(i.amplitude_m_s2 * wave::SPACING_RULE_FRACTION, "10 % of a0")
        .vline(rule_m * 1e3, format!("rule {:.1} mm", rule_m * 1e3));

    let travel = travelling_wave_chart(skin, &WaveSource { position_m: origin, ..template }, i.t_ms);

    let header = vec![
        format!(
            "firing tactors: {:?}; spacing {} mm; a0 = {} m/s^2, b = {} mm, f = {} Hz, c = {} m/s (lambda = {:.2} mm)",
            i.mask.indices().collect::<Vec<_>>(),
            i.spacing_mm,
            i.amplitude_m_s2,
            i.width_mm,
            i.frequency_hz,
            i.speed_m_s,
            skin.wavelength_m(i.frequency_hz) * 1e3
        ),
        format!("spacing rule (neighbour below 10 %): {:.2} mm", rule_m * 1e3),
        format!(
            "a neighbour at {} mm receives {:.1} % of its source",
            i.spacing_mm,
            neighbour_fraction * 100.0
        ),
    ];
    Ok(PanelsOutput {
        panels: vec![PanelSpec::Heat(heat), PanelSpec::Chart(atten), PanelSpec::Chart(travel)],
        header,
    })
}

/// One source's wave against time at 0, 20, 37 and 52 mm from it (thesis Fig 57): the phase lags by `r / c`.
fn travelling_wave_chart(skin: Skin, source: &WaveSource, snapshot_ms: f64) -> ChartSpec {
    let period_s = 1.0 / source.frequency_hz;
    let t_axis: Vec<f64> = (0..=400).map(|k| f64::from(k) / 400.0 * 3.0 * period_s).collect();
    let mut travel =
        ChartSpec::new("Travelling wave at distances from the tactor (Fig 57)", "time [ms]", "a [m/s^2]");
    for d in [0.0, 20.0, 37.0, 52.0] {
        let p = source.position_m.with_x(source.position_m.x + d * 1e-3);
        let y = t_axis.iter().map(|&t| skin.wave_m_s2(source, p, t)).collect();
        travel =
            travel.with(SeriesSpec::line(format!("{d} mm"), t_axis.iter().map(|t| t * 1e3).collect(), y));
    }
    travel.vline(snapshot_ms, "snapshot time")
}

struct WaveView {
    inputs: WaveInputs,
    job: Recompute<WaveInputs, PanelsOutput>,
    exporter: Exporter,
}

impl WaveView {
    fn new() -> Self {
        Self {
            inputs: WaveInputs {
                mask: TactorMask::CORNERS,
                spacing_mm: 50.0,
                amplitude_m_s2: wave::MEASURED_A0_M_S2,
                width_mm: wave::MEASURED_WIDTH_M * 1e3,
                frequency_hz: wave::MEASURED_FREQUENCY_HZ,
                speed_m_s: wave::MEASURED_SPEED_M_S,
                t_ms: 0.0,
                peak: true,
            },
            job: Recompute::new(compute_waves),
            exporter: Exporter::new("vestnav-waves.png"),
        }
    }

    fn controls(&mut self, ui: &mut egui::Ui) {
        let i = &mut self.inputs;
        ui.horizontal(|ui| {
            ui.vertical(|ui| {
                ui.label("Firing tactors (back view):");
                egui::Grid::new("sim-wave-mask").spacing([2.0, 2.0]).show(ui, |ui| {
                    for row in 0..GRID {
                        for col in 0..GRID {
                            let k = row * GRID + col;
                            let mut on = i.mask.contains(k);
                            if ui.toggle_value(&mut on, format!("{k:>2}")).changed() {
                                i.mask.0 ^= 1 << k;
                            }
                        }
                        ui.end_row();
                    }
                });
                ui.horizontal(|ui| {
                    if ui.small_button("all").clicked() {
                        i.mask = TactorMask::ALL;
                    }
                    if ui.small_button("none").clicked() {
                        i.mask = TactorMask::NONE;
                    }
                    if ui.small_button("corners").clicked() {
                        i.mask = TactorMask::CORNERS;
                    }
                });
            });
            ui.vertical(|ui| {
                ui.add(egui::Slider::new(&mut i.spacing_mm, 20.0..=120.0).text("tactor spacing [mm]"));
                ui.add(egui::Slider::new(&mut i.amplitude_m_s2, 1.0..=50.0).text("a0 [m/s^2]"));
                ui.add(egui::Slider::new(&mut i.width_mm, 10.0..=60.0).text("Gaussian width b [mm]"));
                ui.add(egui::Slider::new(&mut i.frequency_hz, 20.0..=250.0).text("frequency [Hz]"));
                ui.add(egui::Slider::new(&mut i.speed_m_s, 0.5..=10.0).text("wave speed c [m/s]"));
                ui.horizontal(|ui| {
                    ui.radio_value(&mut i.peak, true, "peak amplitude");
                    ui.radio_value(&mut i.peak, false, "snapshot at t");
                });
                let period_ms = 1e3 / i.frequency_hz;
                ui.add_enabled(
                    !i.peak,
                    egui::Slider::new(&mut i.t_ms, 0.0..=3.0 * period_ms).text("t [ms]").fixed_decimals(2),
                );
                if ui.small_button("thesis Skinsim values").clicked() {
                    i.amplitude_m_s2 = wave::MEASURED_A0_M_S2;
                    i.width_mm = wave::MEASURED_WIDTH_M * 1e3;
                    i.frequency_hz = wave::MEASURED_FREQUENCY_HZ;
                    i.speed_m_s = wave::MEASURED_SPEED_M_S;
                }
            });
        });
    }

    fn ui(&mut self, ui: &mut egui::Ui) {
        self.controls(ui);
        let ctx = ui.ctx().clone();
        self.job.update(&ctx, &self.inputs);
        self.job.status_ui(ui);
        let Some((_, out)) = self.job.shown() else { return };
        let out = Arc::clone(out);
        for line in &out.header {
            ui.label(line);
        }
        export_row(
            ui,
            &mut self.exporter,
            "Skin waves on the vest (thesis §4.1.3)",
            out.header.clone(),
            &out.panels,
        );
        egui::ScrollArea::vertical().id_salt("sim-wave-scroll").show(ui, |ui| {
            panels_grid(ui, "sim-wave", &out.panels, 320.0);
        });
    }
}

// ---------------------------------------------------- Two-point ----------------------------------------------------

/// Inputs of the two-point fit at one distance.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TwoPointInputs {
    setup: TwoPointSetup,
    distance_mm: f64,
}

/// Inputs of the RMSE-versus-distance sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
struct RmseSweepInputs {
    setup: TwoPointSetup,
    max_mm: f64,
}

/// RMSE against distance, and the threshold distance.
struct RmseSweep {
    distances_mm: Vec<f64>,
    rmse: Vec<f64>,
    threshold_mm: Option<f64>,
}

fn compute_two_point(i: &TwoPointInputs) -> Result<TwoPointResult, String> {
    twopoint::simulate(&i.setup, i.distance_mm).map_err(|e| e.to_string())
}

fn compute_rmse_sweep(i: &RmseSweepInputs) -> Result<RmseSweep, String> {
    let distances_mm: Vec<f64> = (0..=i.max_mm.round() as usize).map(|d| d as f64).collect();
    let results = twopoint::sweep(&i.setup, &distances_mm).map_err(|e| e.to_string())?;
    let threshold_mm = twopoint::threshold_mm(&i.setup, twopoint::DEFAULT_RELATIVE_RMSE, i.max_mm)
        .map_err(|e| e.to_string())?;
    Ok(RmseSweep { distances_mm, rmse: results.iter().map(|r| r.fit.rmse).collect(), threshold_mm })
}

/// The two-point panels (thesis Figs 60–63 and RMSE against distance).
fn two_point_panels(
    setup: &TwoPointSetup,
    result: &TwoPointResult,
    sweep: Option<&RmseSweep>,
) -> Vec<PanelSpec> {
    let d = result.distance_mm;
    let x = setup.grid_mm();
    let g1: Vec<f64> = x.iter().map(|&x| setup.single_m_s2(x, 0.0)).collect();
    let g2: Vec<f64> = x.iter().map(|&x| setup.single_m_s2(x, d)).collect();
    let sum: Vec<f64> = x.iter().map(|&x| setup.sum_m_s2(x, d)).collect();
    let fit: Vec<f64> = x.iter().map(|&x| result.fit.eval(x)).collect();
    let residual: Vec<f64> = sum.iter().zip(&fit).map(|(s, f)| s - f).collect();
    let parts = ChartSpec::new(format!("Two tactors {d:.1} mm apart (Figs 60/62)"), "x [mm]", "a [m/s^2]")
        .with(SeriesSpec::dashed("tactor at 0", x.clone(), g1))
        .with(SeriesSpec::dashed(format!("tactor at {d:.1} mm"), x.clone(), g2))
        .with(SeriesSpec::line("sum", x.clone(), sum.clone()));
    let fitted = ChartSpec::new(
        format!("Sum and single-Gaussian fit, RMSE = {:.4e} (Figs 61/63)", result.fit.rmse),
        "x [mm]",
        "a [m/s^2]",
    )
    .with(SeriesSpec::scatter("sum (grid points)", x.clone(), sum))
    .with(SeriesSpec::line(
        format!(
            "fit: A = {:.3}, mu = {:.3} mm, w = {:.3} mm",
            result.fit.amplitude_m_s2, result.fit.center_mm, result.fit.width_mm
        ),
        x.clone(),
        fit,
    ));
    let resid = ChartSpec::new("Residual of the fit", "x [mm]", "sum - fit [m/s^2]")
        .with(SeriesSpec::line("residual", x, residual))
        .hline(0.0, "");
    let mut panels = vec![PanelSpec::Chart(parts), PanelSpec::Chart(fitted), PanelSpec::Chart(resid)];
    if let Some(sw) = sweep {
        let mut chart =
            ChartSpec::new("RMSE of the single-Gaussian fit vs distance", "distance [mm]", "RMSE [m/s^2]")
                .log_y()
                .with(SeriesSpec::line("RMSE", sw.distances_mm.clone(), sw.rmse.clone()))
                .vline(d, format!("d = {d:.0} mm"))
                .vline(setup.sparrow_limit_mm(), format!("Sparrow {:.1} mm", setup.sparrow_limit_mm()));
        if let Some(t) = sw.threshold_mm {
            chart = chart.vline(t, format!("threshold {t:.1} mm"));
        }
        panels.push(PanelSpec::Chart(chart));
    }
    panels
}

struct TwoPointView {
    inputs: TwoPointInputs,
    sweep_max_mm: f64,
    fit_job: Recompute<TwoPointInputs, TwoPointResult>,
    sweep_job: Recompute<RmseSweepInputs, RmseSweep>,
    panels: Option<Derived<(u64, u64)>>,
    exporter: Exporter,
}

impl TwoPointView {
    fn new() -> Self {
        Self {
            inputs: TwoPointInputs { setup: TwoPointSetup::THESIS, distance_mm: 11.0 },
            sweep_max_mm: 120.0,
            fit_job: Recompute::new(compute_two_point),
            sweep_job: Recompute::new(compute_rmse_sweep),
            panels: None,
            exporter: Exporter::new("vestnav-two-point.png"),
        }
    }

    fn refresh(&mut self, ctx: &egui::Context) {
        self.fit_job.update(ctx, &self.inputs);
        self.sweep_job.update(ctx, &RmseSweepInputs { setup: self.inputs.setup, max_mm: self.sweep_max_mm });
        let key = (self.fit_job.generation(), self.sweep_job.generation());
        if self.panels.as_ref().is_some_and(|d| d.key == key) {
            return;
        }
        let Some((inputs, result)) = self.fit_job.shown() else { return };
        let sweep = self.sweep_job.shown().map(|(_, s)| Arc::clone(s));
        let panels = two_point_panels(&inputs.setup, result, sweep.as_deref());
        let f = &result.fit;
        let mut header = vec![
            format!(
                "setup: a = {} m/s^2 each, b = {} mm, grid {}..{} mm step {} mm",
                inputs.setup.amplitude_m_s2,
                inputs.setup.width_mm,
                inputs.setup.grid_start_mm,
                inputs.setup.grid_end_mm,
                inputs.setup.grid_step_mm
            ),
            format!(
                "d = {} mm: A = {:.4}, mu = {:.4} mm, w = {:.4} mm, RMSE = {:.6e} (sqrt(SSE/(n-3)), n = {})",
                result.distance_mm, f.amplitude_m_s2, f.center_mm, f.width_mm, f.rmse, f.points
            ),
            format!("Sparrow limit sqrt(2) b = {:.2} mm", inputs.setup.sparrow_limit_mm()),
        ];
        if let Some(sw) = &sweep {
            header.push(sw.threshold_mm.map_or_else(
                || "threshold (RMSE = 1 % of a): not reached in the sweep".to_string(),
                |t| format!("threshold (RMSE = 1 % of a): {t:.2} mm"),
            ));
        }
        self.panels = Some(Derived { key, panels, header });
    }

    fn ui(&mut self, ui: &mut egui::Ui) {
        let i = &mut self.inputs;
        ui.horizontal_wrapped(|ui| {
            ui.add(
                egui::Slider::new(&mut i.distance_mm, 0.0..=150.0).text("distance d [mm]").fixed_decimals(1),
            );
            ui.add(egui::Slider::new(&mut i.setup.width_mm, 10.0..=60.0).text("width b [mm]"));
            ui.add(egui::Slider::new(&mut i.setup.amplitude_m_s2, 1.0..=30.0).text("amplitude a [m/s^2]"));
            ui.add(egui::Slider::new(&mut self.sweep_max_mm, 20.0..=200.0).text("RMSE sweep up to [mm]"));
            if ui.small_button("thesis setup").clicked() {
                i.setup = TwoPointSetup::THESIS;
            }
        });
        let ctx = ui.ctx().clone();
        self.refresh(&ctx);
        self.fit_job.status_ui(ui);
        self.sweep_job.status_ui(ui);
        let Some(Derived { panels, header, .. }) = &self.panels else { return };
        for line in header {
            ui.label(line);
        }
        export_row(ui, &mut self.exporter, "Two-point simulation (thesis §4.2)", header.clone(), panels);
        egui::ScrollArea::vertical().id_salt("sim-twopoint-scroll").show(ui, |ui| {
            panels_grid(ui, "sim-twopoint", panels, PLOT_HEIGHT);
        });
    }
}

// ---------------------------------------------------- Damping sweep ----------------------------------------------------

/// The power law of the 207 measured trials, `f = 124.7 n^0.4839` (thesis §3.2.3, Fig 36; physics.md §1).
const MEASURED_POWER_LAW: (f64, f64) = (124.7, 0.4839);
/// Force range of the measured tactors [N] (physics.md §4: 0.52–2.01 N over all mountings).
const MEASURED_FORCE_RANGE_N: (f64, f64) = (0.5, 2.0);

/// Inputs of the damping sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
struct SweepInputs {
    preset: Preset,
    voltage_v: f64,
    body: BodyMass,
    radius_m: f64,
    min_hz: f64,
    max_hz: f64,
    points: usize,
}

impl SweepInputs {
    fn params(&self, body: BodyMass, radius_m: f64) -> TactorParams {
        TactorParams::preset(self.preset).with_body(body).with_voltage(self.voltage_v).with_radius(radius_m)
    }

    fn other_body(&self) -> BodyMass {
        match self.body {
            BodyMass::Unencased => BodyMass::Encased,
            BodyMass::Encased => BodyMass::Unencased,
        }
    }

    /// The radius compared with in Fig 36: the other of the CAD and fitted radii.
    fn other_radius_m(&self) -> f64 {
        if (self.radius_m - tactor::RADIUS_CAD_M).abs() < 1e-9 {
            tactor::RADIUS_FITTED_M
        } else {
            tactor::RADIUS_CAD_M
        }
    }
}

/// Three sweeps: the selected tactor, the other body (Fig 35) and the other radius (Fig 36).
struct SweepOutput {
    main: SweepResult,
    other_body: SweepResult,
    other_radius: SweepResult,
}

fn compute_sweeps(i: &SweepInputs) -> Result<SweepOutput, String> {
    let options =
        SweepOptions { min_hz: i.min_hz, max_hz: i.max_hz, points: i.points, ..SweepOptions::default() };
    let run = |body, radius_m| sweep::sweep(&i.params(body, radius_m), &options).map_err(|e| e.to_string());
    Ok(SweepOutput {
        main: run(i.body, i.radius_m)?,
        other_body: run(i.other_body(), i.radius_m)?,
        other_radius: run(i.body, i.other_radius_m())?,
    })
}

/// Inputs of the damping calibration ("damping for frequency").
#[derive(Debug, Clone, Copy, PartialEq)]
struct CalibrationInputs {
    params: TactorParams,
    frequency_hz: f64,
}

fn compute_calibration(i: &CalibrationInputs) -> Result<Calibration, String> {
    sweep::calibrate_damping(&i.params, i.frequency_hz, &SimOptions::default()).map_err(|e| e.to_string())
}

fn sweep_label(r: &SweepResult) -> String {
    format!("{}, l = {} mm", r.params.body.name(), r.params.radius_m * 1e3)
}

/// `n` evenly spaced values over `lo..=hi`.
fn linspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let n = n.max(2);
    (0..n).map(|k| lo + (hi - lo) * k as f64 / (n - 1) as f64).collect()
}

/// The sweep panels (thesis Figs 35–38), with the calibrated point if there is one.
fn sweep_panels(out: &SweepOutput, calibration: Option<&Calibration>) -> Vec<PanelSpec> {
    let force = |r: &SweepResult| r.points.iter().map(|p| p.force_amplitude_n).collect::<Vec<_>>();
    let freq = |r: &SweepResult| r.points.iter().map(|p| p.f_rot_hz).collect::<Vec<_>>();
    let fit_curve = |r: &SweepResult| {
        let f = force(r);
        let lo = f.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = f.iter().copied().fold(0.0, f64::max);
        let x = linspace(lo, hi, 100);
        let y = x.iter().map(|&n| r.power_law.eval(n)).collect();
        (x, y)
    };

    let mut fig35 =
        ChartSpec::new("Peak frequency vs force as b varies (Fig 35)", "force amplitude [N]", "f [Hz]");
    for r in [&out.main, &out.other_body] {
        let (x, y) = fit_curve(r);
        fig35 = fig35.with(SeriesSpec::scatter(sweep_label(r), force(r), freq(r))).with(SeriesSpec::dashed(
            format!(
                "{} fit f = {:.1} n^{:.4} (R^2 = {:.4})",
                r.params.body.name(),
                r.power_law.coefficient,
                r.power_law.exponent,
                r.power_law.r2
            ),
            x,
            y,
        ));
    }

    let mut fig36 =
        ChartSpec::new("Model curves and the measured trials' fit (Fig 36)", "force amplitude [N]", "f [Hz]");
    for r in [&out.main, &out.other_radius] {
        fig36 = fig36.with(SeriesSpec::line(format!("model, {}", sweep_label(r)), force(r), freq(r)));
    }
    let (a, b) = MEASURED_POWER_LAW;
    let x = linspace(MEASURED_FORCE_RANGE_N.0, MEASURED_FORCE_RANGE_N.1, 100);
    let y = x.iter().map(|n| a * n.powf(b)).collect();
    fig36 = fig36
        .with(SeriesSpec::dashed(format!("207 measured trials: f = {a} n^{b}"), x, y).color([20, 20, 20]));

    let r = &out.main;
    let current_ma: Vec<f64> = r.points.iter().map(|p| p.current_mean_a * 1e3).collect();
    let line_x = linspace(
        current_ma.iter().copied().fold(f64::INFINITY, f64::min),
        current_ma.iter().copied().fold(0.0, f64::max),
        50,
    );
    let line_y = line_x.iter().map(|i| r.current_line.eval(i * 1e-3)).collect();
    let fig37 = ChartSpec::new("Peak frequency vs steady current (Fig 37)", "mean current [mA]", "f [Hz]")
        .with(SeriesSpec::scatter(sweep_label(r), current_ma, freq(r)))
        .with(SeriesSpec::dashed(
            format!(
                "fit f = {:.2} {:+.2} i[A] (R^2 = {:.5})",
                r.current_line.intercept, r.current_line.slope, r.current_line.r2
            ),
            line_x,
            line_y,
        ));

    let f_axis = linspace(r.options.min_hz, r.options.max_hz, 100);
    let scale = 1e8;
    let b_sim: Vec<f64> = r.points.iter().map(|p| p.damping_n_m_s * scale).collect();
    let inv = &r.inverse_fit;
    let mut fig38 =
        ChartSpec::new("Damping vs peak frequency: calibration (Fig 38)", "f [Hz]", "b [1e-8 N m s]")
            .with(SeriesSpec::scatter("simulated", freq(r), b_sim))
            .with(SeriesSpec::line(
                "exact inverse b = a/f + c",
                f_axis.clone(),
                f_axis.iter().map(|&f| r.exact_inverse.eval(f) * scale).collect(),
            ))
            .with(SeriesSpec::dashed(
                format!("fit b = p1 (f + p2)^p3 + p4, p3 = {:.4}", inv.p3),
                f_axis.clone(),
                f_axis.iter().map(|&f| inv.eval(f) * scale).collect(),
            ));
    if let Some(c) = calibration {
        fig38 = fig38
            .with(
                SeriesSpec::scatter(
                    format!("calibrated: {:.2} Hz", c.frequency_hz),
                    vec![c.achieved_f_rot_hz],
                    vec![c.damping_n_m_s * scale],
                )
                .color([214, 39, 40]),
            )
            .vline(c.frequency_hz, "target frequency");
    }
    [fig35, fig36, fig37, fig38].into_iter().map(PanelSpec::Chart).collect()
}

/// Fit parameters and the calibration, one line each (also the CSV header).
fn sweep_header(out: &SweepOutput, calibration: Option<&Calibration>) -> Vec<String> {
    let mut lines = Vec::new();
    for r in [&out.main, &out.other_body, &out.other_radius] {
        let inv = &r.inverse_fit;
        lines.push(format!(
            "{} ({} preset, u = {} V, {} points {}..{} Hz): f = {:.3} n^{:.5} (R^2 {:.5}); f = {:.3} {:+.3} i              (R^2 {:.6}); b = {:.4e} (f {:+.4})^{:.5} {:+.4e} (max rel. residual {:.2e})",
            sweep_label(r),
            r.params.preset.name(),
            r.params.voltage_v,
            r.points.len(),
            r.options.min_hz,
            r.options.max_hz,
            r.power_law.coefficient,
            r.power_law.exponent,
            r.power_law.r2,
            r.current_line.intercept,
            r.current_line.slope,
            r.current_line.r2,
            inv.p1,
            inv.p2,
            inv.p3,
            inv.p4,
            inv.max_rel_residual
        ));
    }
    if let Some(c) = calibration {
        lines.push(format!(
            "damping for {} Hz: {:.6e} N m s (closed form {:.6e}), simulated f_rot {:.4} Hz after {} simulations",
            c.frequency_hz, c.damping_n_m_s, c.damping_closed_form_n_m_s, c.achieved_f_rot_hz, c.iterations
        ));
    }
    lines
}

struct SweepView {
    inputs: SweepInputs,
    frequency_hz: f64,
    job: Recompute<SweepInputs, SweepOutput>,
    calibration: Recompute<CalibrationInputs, Calibration>,
    panels: Option<Derived<(u64, u64)>>,
    exporter: Exporter,
}

impl SweepView {
    fn new() -> Self {
        Self {
            inputs: SweepInputs {
                preset: Preset::ThesisSim,
                voltage_v: 3.3,
                body: BodyMass::Unencased,
                radius_m: tactor::RADIUS_CAD_M,
                min_hz: 80.0,
                max_hz: 200.0,
                points: 40,
            },
            frequency_hz: 133.2,
            job: Recompute::new(compute_sweeps),
            calibration: Recompute::new(compute_calibration),
            panels: None,
            exporter: Exporter::new("vestnav-sweep.png"),
        }
    }

    fn calibration_inputs(&self) -> CalibrationInputs {
        CalibrationInputs {
            params: self.inputs.params(self.inputs.body, self.inputs.radius_m),
            frequency_hz: self.frequency_hz,
        }
    }

    fn refresh(&mut self, ctx: &egui::Context) {
        self.job.update(ctx, &self.inputs);
        let cal_inputs = self.calibration_inputs();
        self.calibration.update(ctx, &cal_inputs);
        let key = (self.job.generation(), self.calibration.generation());
        if self.panels.as_ref().is_some_and(|d| d.key == key) {
            return;
        }
        let Some((_, out)) = self.job.shown() else { return };
        let cal = self.calibration.shown().map(|(_, c)| Arc::clone(c));
        self.panels = Some(Derived {
            key,
            panels: sweep_panels(out, cal.as_deref()),
            header: sweep_header(out, cal.as_deref()),
        });
    }

    /// Draws the view; returns a damping the operator wants simulated in the tactor view.
    fn ui(&mut self, ui: &mut egui::Ui) -> Option<f64> {
        let i = &mut self.inputs;
        ui.horizontal_wrapped(|ui| {
            egui::ComboBox::from_label("preset ").selected_text(i.preset.name()).show_ui(ui, |ui| {
                ui.selectable_value(&mut i.preset, Preset::ThesisSim, "thesis-sim (R = 62 ohm)");
                ui.selectable_value(&mut i.preset, Preset::Measured, "measured (R = 67 ohm)");
            });
            ui.radio_value(&mut i.body, BodyMass::Unencased, "unencased");
            ui.radio_value(&mut i.body, BodyMass::Encased, "encased");
            ui.separator();
            ui.radio_value(&mut i.radius_m, tactor::RADIUS_CAD_M, "l = 2.57 mm (CAD)");
            ui.radio_value(&mut i.radius_m, tactor::RADIUS_FITTED_M, "l = 3.2 mm (fitted)");
        });
        ui.horizontal_wrapped(|ui| {
            ui.add(egui::Slider::new(&mut i.voltage_v, 0.5..=6.0).text("voltage [V]").fixed_decimals(3));
            ui.add(egui::DragValue::new(&mut i.min_hz).range(10.0..=1000.0).prefix("from ").suffix(" Hz"));
            ui.add(egui::DragValue::new(&mut i.max_hz).range(10.0..=2000.0).prefix("to ").suffix(" Hz"));
            ui.add(egui::DragValue::new(&mut i.points).range(4..=200).prefix("points "));
        });
        if i.max_hz <= i.min_hz + 1.0 {
            i.max_hz = i.min_hz + 1.0;
        }
        let mut apply = None;
        ui.horizontal_wrapped(|ui| {
            ui.label("Damping for frequency:");
            ui.add(egui::DragValue::new(&mut self.frequency_hz).range(1.0..=2000.0).speed(0.1).suffix(" Hz"));
            if let Some((inputs, c)) = self.calibration.shown() {
                ui.monospace(format!(
                    "b = {:.5e} N m s (closed form {:.5e}) -> f_rot {:.3} Hz",
                    c.damping_n_m_s, c.damping_closed_form_n_m_s, c.achieved_f_rot_hz
                ));
                let current = *inputs == self.calibration_inputs();
                if ui.add_enabled(current, egui::Button::new("Simulate this tactor")).clicked() {
                    apply = Some(c.damping_n_m_s);
                }
            }
        });
        let ctx = ui.ctx().clone();
        self.refresh(&ctx);
        self.job.status_ui(ui);
        self.calibration.status_ui(ui);
        if let Some(Derived { panels, header, .. }) = &self.panels {
            for line in header {
                ui.label(line);
            }
            export_row(ui, &mut self.exporter, "Damping sweep (thesis Figs 35-38)", header.clone(), panels);
            egui::ScrollArea::vertical().id_salt("sim-sweep-scroll").show(ui, |ui| {
                panels_grid(ui, "sim-sweep", panels, PLOT_HEIGHT);
            });
        }
        apply
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn tmp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("vestnav-sim-panel-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn decimation_keeps_extremes_and_bounds_the_size() {
        let x: Vec<f64> = (0..100_000).map(|k| f64::from(k) * 1e-4).collect();
        let y: Vec<f64> = x.iter().map(|t| (std::f64::consts::TAU * 133.0 * t).sin() * (1.0 + t)).collect();
        let (xs, ys) = decimate_minmax(&x, &y, 4000);
        assert!(xs.len() <= 4002 && xs.len() > 3000, "{}", xs.len());
        assert!(xs.windows(2).all(|w| w[0] < w[1]), "x stays increasing");
        let max = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
        assert_relative_eq!(max(&ys), max(&y));
        assert_relative_eq!(min(&ys), min(&y));
        // Short traces pass through.
        let (xs, ys) = decimate_minmax(&x[..10], &y[..10], 4000);
        assert_eq!((xs.len(), ys.len()), (10, 10));
    }

    #[test]
    fn envelope_of_a_sinusoid_is_its_amplitude() {
        // 100 Hz, amplitude 2, sampled at 10 kHz: one block = one period = 100 samples.
        let t: Vec<f64> = (0..10_000).map(|k| f64::from(k) * 1e-4).collect();
        let y: Vec<f64> = t.iter().map(|t| 2.0 * (std::f64::consts::TAU * 100.0 * t + 0.3).sin()).collect();
        let (te, ye) = block_envelope(&t, &y, 100);
        assert_eq!(te.len(), 100);
        for v in ye {
            assert_relative_eq!(v, 2.0, max_relative = 1e-3);
        }
    }

    #[test]
    fn finite_runs_split_at_nan() {
        let pts = [[0.0, 1.0], [1.0, f64::NAN], [2.0, 3.0], [3.0, 4.0], [f64::INFINITY, 0.0]];
        let runs = finite_runs(&pts);
        assert_eq!(runs, vec![vec![[0.0, 1.0]], vec![[2.0, 3.0], [3.0, 4.0]]]);
    }

    #[test]
    fn csv_is_long_form_and_quotes_fields() {
        let chart = ChartSpec::new("a, \"quoted\" title", "x", "y")
            .with(SeriesSpec::line("s1", vec![1.0, 2.0], vec![3.0, 4.0]))
            .hline(0.5, "ref");
        let csv = panels_csv(&["summary line".to_string()], &[PanelSpec::Chart(chart)]);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines[0], "# summary line");
        assert_eq!(lines[1], "panel,series,x,y,value");
        assert_eq!(lines[2], "\"a, \"\"quoted\"\" title\",s1,1,3,");
        assert_eq!(lines[3], "\"a, \"\"quoted\"\" title\",s1,2,4,");
        assert_eq!(lines[4], "\"a, \"\"quoted\"\" title\",hline: ref,,0.5,");
    }

    #[test]
    fn exporter_replaces_the_extension_and_reports_errors() {
        let mut ex = Exporter::new("out/figure.png");
        assert_eq!(ex.target(ExportFormat::Csv), Some(PathBuf::from("out/figure.csv")));
        ex.path = "  ".to_string();
        assert_eq!(ex.target(ExportFormat::Png), None);
        let ctx = egui::Context::default();
        ex.start(&ctx, ExportFormat::Png, || Ok(vec![1]));
        assert!(matches!(ex.status(), Some(Err(_))));
        // An unwritable path is reported, not panicked on.
        ex.path = "/nonexistent-dir-vestnav/x".to_string();
        ex.start(&ctx, ExportFormat::Csv, || Ok(b"a".to_vec()));
        ex.wait();
        assert!(matches!(ex.status(), Some(Err(e)) if e.contains("cannot write")));
    }

    #[test]
    fn recompute_runs_once_per_new_input() {
        #[allow(clippy::trivially_copy_pass_by_ref, reason = "the signature Recompute expects")]
        fn square(x: &i64) -> Result<i64, String> {
            if *x < 0 { Err("negative".to_string()) } else { Ok(x * x) }
        }
        let ctx = egui::Context::default();
        let mut job = Recompute::new(square);
        job.update(&ctx, &3);
        job.wait();
        job.update(&ctx, &3); // same input: no new run
        assert!(!job.is_running());
        assert_eq!(job.shown().map(|(i, o)| (*i, **o)), Some((3, 9)));
        assert_eq!(job.generation(), 1);
        job.update(&ctx, &-1);
        job.wait();
        assert_eq!(job.error(), Some("negative"));
        assert_eq!(job.shown().map(|(i, o)| (*i, **o)), Some((3, 9)), "the last good result stays shown");
        assert!(job.last_duration().is_some());
    }

    #[test]
    fn two_point_panels_follow_the_closed_form() {
        let setup = TwoPointSetup::THESIS;
        let result = compute_two_point(&TwoPointInputs { setup, distance_mm: 11.0 }).unwrap();
        // physics.md §3 reference at d = 11 mm.
        assert_relative_eq!(result.fit.amplitude_m_s2, 19.546, max_relative = 1e-4);
        assert_relative_eq!(result.fit.rmse, 0.001_727, max_relative = 1e-3);
        let panels = two_point_panels(&setup, &result, None);
        let PanelSpec::Chart(parts) = &panels[0] else { panic!("chart expected") };
        let sum = &parts.series[2];
        assert_eq!(sum.x.len(), 281);
        for (&x, &y) in sum.x.iter().zip(&sum.y) {
            let want =
                10.0 * (-(x / 36.2_f64).powi(2)).exp() + 10.0 * (-((x - 11.0) / 36.2_f64).powi(2)).exp();
            assert_relative_eq!(y, want, max_relative = 1e-12);
        }
    }

    #[test]
    fn rmse_sweep_grows_with_distance() {
        let sweep =
            compute_rmse_sweep(&RmseSweepInputs { setup: TwoPointSetup::THESIS, max_mm: 60.0 }).unwrap();
        assert_eq!(sweep.distances_mm.len(), 61);
        assert!(sweep.rmse[10] < sweep.rmse[30] && sweep.rmse[30] < sweep.rmse[60]);
        let t = sweep.threshold_mm.unwrap();
        assert!(t > 11.0 && t < 51.2, "threshold {t} below the Sparrow limit");
    }

    #[test]
    fn vest_field_peak_matches_the_gaussian_of_one_tactor() {
        let inputs = WaveInputs {
            mask: TactorMask::single(5).unwrap(),
            spacing_mm: 50.0,
            amplitude_m_s2: 26.02,
            width_mm: 28.18,
            frequency_hz: 70.4,
            speed_m_s: 3.023,
            t_ms: 0.0,
            peak: true,
        };
        let out = compute_waves(&inputs).unwrap();
        let PanelSpec::Heat(h) = &out.panels[0] else { panic!("heat map expected") };
        assert_eq!(h.values.len(), FIELD_CELLS * FIELD_CELLS);
        // Tactor 5 = row 1, column 1: x = -25 mm, y = +25 mm on a 50 mm grid.
        let (tx, ty) = (-25.0, 25.0);
        let cell = (h.x_extent.1 - h.x_extent.0) / FIELD_CELLS as f64;
        for (k, v) in h.values.iter().enumerate().step_by(97) {
            let x = h.x_extent.0 + ((k % FIELD_CELLS) as f64 + 0.5) * cell;
            let y = h.y_extent.0 + ((k / FIELD_CELLS) as f64 + 0.5) * cell;
            let r2 = (x - tx).powi(2) + (y - ty).powi(2);
            assert_relative_eq!(
                *v,
                26.02 * (-r2 / 28.18_f64.powi(2)).exp(),
                max_relative = 1e-9,
                epsilon = 1e-12
            );
        }
        // Spacing rule for b = 28.18 mm: b sqrt(ln 10) = 42.76 mm.
        assert!(out.header.iter().any(|l| l.contains("42.76")), "{:?}", out.header);
    }

    #[test]
    fn tactor_view_reproduces_the_reference_and_exports() {
        let inputs = TactorInputs {
            preset: Preset::ThesisSim,
            body: BodyMass::Unencased,
            voltage_v: 3.3,
            damping_n_m_s: 6.3e-8,
            radius_m: 2.57e-3,
            duration_s: 1.0,
            compare_bodies: true,
        };
        let out = compute_tactor(&inputs).unwrap();
        assert_eq!(out.runs.len(), 2);
        // Closed form omega = Kt u / (R b + Kt^2) = 834.22 rad/s (physics.md §1).
        let kt = 0.0019;
        let omega = kt * 3.3 / (62.0 * 6.3e-8 + kt * kt);
        let panels = tactor_panels(&out, 0.5);
        let PanelSpec::Chart(speed) = &panels[0] else { panic!("chart expected") };
        assert_relative_eq!(speed.hlines[0].0, omega, max_relative = 1e-9);
        assert!(speed.series[0].x.iter().all(|&t| t <= 0.5));
        // x amplitude m l / Mt = 0.382 mm: the position trace stays within it.
        let PanelSpec::Chart(pos) = &panels[4] else { panic!("chart expected") };
        let x_amp_mm = 0.55e-3 * 2.57e-3 / 3.7e-3 * 1e3;
        assert!(pos.series[0].y.iter().all(|x| x.abs() <= x_amp_mm * 1.01));
        // Spectrum peak near f_rot (133 Hz) when the sim has at least 1 s.
        let PanelSpec::Chart(spec) = &panels[5] else { panic!("chart expected") };
        let s = &spec.series[0];
        let (k, _) =
            s.y.iter().enumerate().skip(5).fold((0, 0.0), |b, (k, &v)| if v > b.1 { (k, v) } else { b });
        assert!((s.x[k] - 133.0).abs() <= 4.0, "peak at {} Hz", s.x[k]);

        let dir = tmp_dir("tactor");
        let png = render_png("test", &panels).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        let mut ex = Exporter::new(dir.join("t.png").to_str().unwrap());
        let header = tactor_header(&out);
        let p2 = panels.clone();
        ex.start(&egui::Context::default(), ExportFormat::Csv, move || {
            Ok(panels_csv(&header, &p2).into_bytes())
        });
        ex.wait();
        assert!(matches!(ex.status(), Some(Ok(_))), "{:?}", ex.status());
        let csv = std::fs::read_to_string(dir.join("t.csv")).unwrap();
        assert!(csv.contains("mean omega [rad/s]"));
        assert!(csv.lines().count() > 1000);
    }

    #[test]
    fn sweep_panels_scale_the_closed_form_inverse() {
        let inputs = SweepInputs {
            preset: Preset::ThesisSim,
            voltage_v: 3.3,
            body: BodyMass::Unencased,
            radius_m: tactor::RADIUS_CAD_M,
            min_hz: 100.0,
            max_hz: 160.0,
            points: 6,
        };
        let out = compute_sweeps(&inputs).unwrap();
        assert_relative_eq!(out.other_body.params.body_mass_kg, 4.95e-3);
        assert_relative_eq!(out.other_radius.params.radius_m, 3.2e-3);
        let cal = compute_calibration(&CalibrationInputs {
            params: inputs.params(BodyMass::Unencased, tactor::RADIUS_CAD_M),
            frequency_hz: 133.2,
        })
        .unwrap();
        assert_relative_eq!(cal.achieved_f_rot_hz, 133.2, max_relative = 1e-5);
        let panels = sweep_panels(&out, Some(&cal));
        assert_eq!(panels.len(), 4);
        let PanelSpec::Chart(fig38) = &panels[3] else { panic!("chart expected") };
        // b(f) = (Kt u / (2 pi f) - Kt^2) / R, drawn in units of 1e-8 N m s (physics.md §1 steady state).
        let exact = &fig38.series[1];
        let (kt, u, r) = (0.0019, 3.3, 62.0);
        for (&f, &b) in exact.x.iter().zip(&exact.y) {
            let want = (kt * u / (std::f64::consts::TAU * f) - kt * kt) / r * 1e8;
            assert_relative_eq!(b, want, max_relative = 1e-9);
        }
        // Fig 37: the current line of the closed form, f = u/(2 pi Kt) - R/(2 pi Kt) i, drawn against mA.
        let PanelSpec::Chart(fig37) = &panels[2] else { panic!("chart expected") };
        let line = &fig37.series[1];
        let f_of_ma = |i_ma: f64| (u - r * i_ma * 1e-3) / (std::f64::consts::TAU * kt);
        assert_relative_eq!(line.y[0], f_of_ma(line.x[0]), max_relative = 1e-3);
        assert!(sweep_header(&out, Some(&cal)).iter().any(|l| l.contains("damping for 133.2 Hz")));
    }

    #[test]
    fn panel_renders_every_tab_without_blocking() {
        use egui_kittest::Harness;
        use egui_kittest::kittest::Queryable as _;
        let mut harness = Harness::new_ui_state(|ui, panel: &mut SimPanel| panel.ui(ui), SimPanel::new());
        harness.set_size(egui::vec2(1200.0, 900.0));
        for tab in ["Damping sweep", "Skin waves", "Two-point", "Tactor model"] {
            harness.get_by_label(tab).click();
            harness.run_steps(3);
        }
        // The computations run on threads; wait for them and draw again.
        harness.state_mut().tactor.job.wait();
        harness.run_steps(2);
        assert!(harness.state().tactor.job.shown().is_some());
        harness.get_by_label("Save PNG");
    }

    #[test]
    fn calibrated_damping_goes_to_the_tactor_view_and_views_export() {
        use egui_kittest::Harness;
        use egui_kittest::kittest::Queryable as _;
        let mut harness = Harness::new_ui_state(|ui, panel: &mut SimPanel| panel.ui(ui), SimPanel::new());
        harness.set_size(egui::vec2(1400.0, 1000.0));
        harness.get_by_label("Damping sweep").click();
        harness.run_steps(2);
        harness.state_mut().sweep.job.wait();
        harness.state_mut().sweep.calibration.wait();
        harness.run_steps(2);
        let calibrated = harness.state().sweep.calibration.shown().map(|(_, c)| c.damping_n_m_s).unwrap();
        harness.get_by_label("Simulate this tactor").click();
        harness.run_steps(2);
        assert_eq!(harness.state().tab, Tab::Tactor);
        assert_relative_eq!(harness.state().tactor.inputs.damping_n_m_s, calibrated);

        let dir = tmp_dir("ui-export");
        let path = dir.join("tactor-view");
        harness.state_mut().tactor.job.wait();
        harness.state_mut().tactor.exporter.path = path.to_string_lossy().into_owned();
        harness.run_steps(2);
        harness.get_by_label("Save CSV").click();
        harness.run_steps(2);
        harness.state_mut().tactor.exporter.wait();
        assert!(matches!(harness.state().tactor.exporter.status(), Some(Ok(_))));
        let csv = std::fs::read_to_string(path.with_extension("csv")).unwrap();
        assert!(csv.contains(&format!("{calibrated:.4e}")), "the CSV header names the damping used");
    }
}
