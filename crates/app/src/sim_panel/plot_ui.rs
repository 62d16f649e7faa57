//! Draws a `vestnav_plot::Figure` on screen with `egui_plot`, panel by panel: the same figure the views
//! export as PNG, so what the operator sees is what they save. Colours come from `vestnav_plot` (its series
//! palette and its viridis colour map).

use egui_plot::{Line, LineStyle, MarkerShape, Plot, PlotPoint, Points, Text, VLine};
use vestnav_plot::{Chart, Color, Figure, Heatmap, Marker, Panel, Scale, Series, SeriesKind, viridis};

fn color32(c: Color) -> egui::Color32 {
    egui::Color32::from_rgba_unmultiplied(c.r, c.g, c.b, c.a)
}

/// Position of `v` on an axis of `scale` (log axes are drawn in decades; non-positive values vanish).
fn on_axis(scale: Scale, v: f64) -> f64 {
    match scale {
        Scale::Linear => v,
        Scale::Log10 if v > 0.0 => v.log10(),
        Scale::Log10 => f64::NAN,
    }
}

/// Value at an axis position (inverse of [`on_axis`]).
fn from_axis(scale: Scale, p: f64) -> f64 {
    match scale {
        Scale::Linear => p,
        Scale::Log10 => 10f64.powf(p),
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

fn marker_shape(m: Marker) -> MarkerShape {
    match m {
        Marker::Square => MarkerShape::Square,
        Marker::Cross => MarkerShape::Cross,
        Marker::None | Marker::Circle => MarkerShape::Circle,
    }
}

/// Most points of one line series drawn a frame: beyond, each column's extremes (`decimate_minmax`).
const LINE_DRAWN_MAX: usize = 8_000;
/// Most markers of one series drawn a frame: beyond, every k-th, and the legend says so.
const MARKERS_DRAWN_MAX: usize = 10_000;

/// The points of `s` a frame draws, on the plot's axes (`at`): a line's decimated to [`LINE_DRAWN_MAX`]
/// keeping each column's extremes, every point otherwise (markers are thinned by [`markers`]). A figure
/// of five receivers' day of fixes (432,000 points) would otherwise be tessellated on every frame.
fn drawn_points(s: &Series, at: impl Fn(f64, f64) -> [f64; 2]) -> Vec<[f64; 2]> {
    let n = s.x.len().min(s.y.len());
    if s.kind == SeriesKind::Line && n > LINE_DRAWN_MAX && s.marker == Marker::None {
        let (x, y) = vestnav_plot::decimate_minmax(&s.x, &s.y, LINE_DRAWN_MAX);
        return x.iter().zip(&y).map(|(&x, &y)| at(x, y)).collect();
    }
    s.x.iter().zip(&s.y).map(|(&x, &y)| at(x, y)).collect()
}

/// A series' finite points as markers (line series with markers and scatter series alike): at most
/// [`MARKERS_DRAWN_MAX`], every k-th beyond, with the legend saying "1 in k of N points drawn".
fn markers(s: &Series, points: Vec<[f64; 2]>, color: egui::Color32) -> Points<'static> {
    let (finite, label) = thinned_markers(&s.label, points);
    Points::new(label, finite).shape(marker_shape(s.marker)).radius(2.5).color(color)
}

/// [`markers`]' points and legend label.
fn thinned_markers(label: &str, points: Vec<[f64; 2]>) -> (Vec<[f64; 2]>, String) {
    let finite: Vec<[f64; 2]> = points.into_iter().filter(|p| p[0].is_finite() && p[1].is_finite()).collect();
    if finite.len() <= MARKERS_DRAWN_MAX {
        return (finite, label.to_owned());
    }
    let every = finite.len().div_ceil(MARKERS_DRAWN_MAX);
    let n = finite.len();
    (finite.into_iter().step_by(every).collect(), format!("{label} (1 in {every} of {n} points drawn)"))
}

/// Least distance between two labelled x ticks, points: room for a label such as "-12.5" and a gap.
const X_LABEL_PITCH: f64 = 70.0;
/// Least distance between two labelled y ticks, points.
const Y_LABEL_PITCH: f64 = 32.0;

/// One on-screen axis numbered by the figures' own tick rule ([`vestnav_plot::axis_ticks`]), so a plot on
/// screen and its PNG export carry the same ticks and labels.
///
/// `egui_plot` asks the grid spacer for the marks of a frame and then the formatter for each mark's label;
/// the spacer keeps the labels it chose so the formatter labels exactly those (and leaves the finer grid
/// marks unlabelled). Its default formatter takes decimals from `round(-log10(step))`, which labels a
/// 0.5 step "0, 0, 1, 1, 2, 2", and hides x labels closer than 60 points, which with its 8-point grid
/// left several x axes without numbers.
#[derive(Clone)]
struct ScreenAxis {
    scale: Scale,
    integer: bool,
    label_pitch: f64,
    labels: std::rc::Rc<std::cell::RefCell<Vec<(f64, String)>>>,
}

impl ScreenAxis {
    fn new(scale: Scale, integer: bool, label_pitch: f64) -> Self {
        Self { scale, integer, label_pitch, labels: std::rc::Rc::default() }
    }

    /// The marks of the visible interval: labelled ticks (in axis coordinates, decades on a log axis) and
    /// the minor grid between them.
    fn marks(&self, input: &egui_plot::GridInput) -> Vec<egui_plot::GridMark> {
        let (b0, b1) = input.bounds;
        let span = b1 - b0;
        let points = if input.base_step_size > 0.0 { span / input.base_step_size * 8.0 } else { 0.0 };
        if !(span.is_finite() && span > 0.0 && points.is_finite()) {
            self.labels.borrow_mut().clear();
            return Vec::new();
        }
        let max_ticks = ((points / self.label_pitch) as usize).clamp(2, 12);
        let ticks = match self.scale {
            Scale::Linear => vestnav_plot::axis_ticks(Scale::Linear, b0, b1, max_ticks, self.integer),
            Scale::Log10 => {
                vestnav_plot::axis_ticks(Scale::Log10, 10f64.powf(b0), 10f64.powf(b1), max_ticks, false)
            }
        };
        let major: Vec<(f64, String)> =
            ticks.major.into_iter().map(|(v, l)| (on_axis(self.scale, v), l)).collect();
        let step = major
            .windows(2)
            .map(|w| w[1].0 - w[0].0)
            .fold(f64::INFINITY, f64::min)
            .min(span)
            .max(span * 1e-6);
        let mut marks: Vec<egui_plot::GridMark> =
            major.iter().map(|(v, _)| egui_plot::GridMark { value: *v, step_size: step }).collect();
        let minor: Vec<f64> = match self.scale {
            Scale::Log10 => ticks.minor.iter().map(|v| v.log10()).collect(),
            Scale::Linear => {
                // A 1-2-5 step divides into fifths (1, 5) or quarters (2), themselves 1-2-5 values.
                let mantissa = step / 10f64.powf(step.log10().floor());
                let fine = if (mantissa - 2.0).abs() < 1e-6 { step / 4.0 } else { step / 5.0 };
                if self.integer && fine < 1.0 {
                    Vec::new()
                } else {
                    let k0 = (b0 / fine).ceil();
                    let k1 = (b1 / fine).floor();
                    if k1 - k0 > 500.0 {
                        Vec::new()
                    } else {
                        (k0 as i64..=k1 as i64).map(|k| k as f64 * fine).collect()
                    }
                }
            }
        };
        let fine_step = minor.windows(2).map(|w| (w[1] - w[0]).abs()).fold(step / 5.0, f64::min);
        for v in minor {
            if major.iter().all(|(m, _)| (m - v).abs() > step * 1e-6) {
                marks.push(egui_plot::GridMark { value: v, step_size: fine_step });
            }
        }
        *self.labels.borrow_mut() = major;
        marks
    }

    /// The label of a mark the spacer chose to label, else nothing.
    fn label(&self, mark: egui_plot::GridMark) -> String {
        let labels = self.labels.borrow();
        labels
            .iter()
            .find(|(v, _)| (v - mark.value).abs() <= mark.step_size.abs() * 1e-6)
            .map(|(_, l)| l.clone())
            .unwrap_or_default()
    }

    /// The axis's hints: its title and the rule's labels, drawn at full strength (the spacer already keeps
    /// them `label_pitch` apart).
    fn hints<'a>(&self, axis: egui_plot::Axis, title: &str) -> egui_plot::AxisHints<'a> {
        let me = self.clone();
        let hints = match axis {
            egui_plot::Axis::X => egui_plot::AxisHints::new_x(),
            egui_plot::Axis::Y => egui_plot::AxisHints::new_y(),
        };
        hints.label(title.to_owned()).label_spacing(1.0..=2.0).formatter(move |mark, _| me.label(mark))
    }
}

/// A legend row above the plot, outside the data: one swatch and name per labelled item.
fn legend_row(ui: &mut egui::Ui, items: &[(egui::Color32, bool, String)]) {
    if items.is_empty() {
        return;
    }
    ui.horizontal_wrapped(|ui| {
        for (color, dashed, label) in items {
            let (rect, _) = ui.allocate_exact_size(egui::vec2(22.0, 10.0), egui::Sense::hover());
            let y = rect.center().y;
            let stroke = egui::Stroke::new(2.0, *color);
            if *dashed {
                ui.painter().add(egui::Shape::dashed_line(
                    &[egui::pos2(rect.left(), y), egui::pos2(rect.right(), y)],
                    stroke,
                    4.0,
                    3.0,
                ));
            } else {
                ui.painter().line_segment([egui::pos2(rect.left(), y), egui::pos2(rect.right(), y)], stroke);
            }
            ui.label(egui::RichText::new(label).small());
            ui.add_space(8.0);
        }
    });
}

/// Draws a chart (drag pans, Ctrl + wheel zooms, double-click resets; the plain wheel scrolls the page the
/// plots sit in, as it does everywhere else).
fn show_chart(ui: &mut egui::Ui, c: &Chart, id_salt: &str, height: f32) {
    let (xs, ys) = (c.x_scale, c.y_scale);
    let at = move |x: f64, y: f64| [on_axis(xs, x), on_axis(ys, y)];
    ui.label(egui::RichText::new(&c.title).strong());
    let series_color = |idx: usize, s: &Series| color32(s.color.unwrap_or_else(|| Color::palette(idx)));
    let line_color = |k: usize| color32(Color::palette(c.series.len() + k));
    let mut legend: Vec<(egui::Color32, bool, String)> = c
        .series
        .iter()
        .enumerate()
        .filter(|(_, s)| !s.label.is_empty())
        .map(|(idx, s)| (series_color(idx, s), s.dashed, s.label.clone()))
        .collect();
    legend.extend(
        c.hlines
            .iter()
            .chain(&c.vlines)
            .enumerate()
            .filter(|(_, l)| !l.label.is_empty())
            .map(|(k, l)| (line_color(k), true, l.label.clone())),
    );
    legend_row(ui, &legend);
    let x_axis = ScreenAxis::new(xs, c.x_integer, X_LABEL_PITCH);
    let y_axis = ScreenAxis::new(ys, false, Y_LABEL_PITCH);
    let (x_spacer, y_spacer) = (x_axis.clone(), y_axis.clone());
    let mut plot = Plot::new(id_salt)
        .allow_scroll(false)
        .height(height)
        .custom_x_axes(vec![x_axis.hints(egui_plot::Axis::X, &c.x_label)])
        .custom_y_axes(vec![y_axis.hints(egui_plot::Axis::Y, &c.y_label)])
        .x_grid_spacer(move |input| x_spacer.marks(&input))
        .y_grid_spacer(move |input| y_spacer.marks(&input));
    if c.equal_aspect {
        plot = plot.data_aspect(1.0);
    }
    if let Some((lo, hi)) = c.y_range {
        plot = plot.include_y(on_axis(ys, lo)).include_y(on_axis(ys, hi));
    }
    if xs == Scale::Log10 || ys == Scale::Log10 {
        plot = plot.label_formatter(move |pos| {
            Some(match pos {
                egui_plot::HoverPosition::NearDataPoint { plot_name, position, .. } => format!(
                    "{plot_name}\nx = {:.4}\ny = {:.4e}",
                    from_axis(xs, position.x),
                    from_axis(ys, position.y)
                ),
                egui_plot::HoverPosition::Elsewhere { position } => {
                    format!("x = {:.4}\ny = {:.4e}", from_axis(xs, position.x), from_axis(ys, position.y))
                }
            })
        });
    }
    plot.show(ui, |plot_ui| {
        for (idx, s) in c.series.iter().enumerate() {
            let color = series_color(idx, s);
            let points = drawn_points(s, at);
            match s.kind {
                SeriesKind::Line => {
                    // egui_plot does not break lines at NaN: draw each finite run separately.
                    for run in finite_runs(&points) {
                        let mut line = Line::new(s.label.clone(), run).color(color).width(s.width_px);
                        if s.dashed {
                            line = line.style(LineStyle::dashed_loose());
                        }
                        plot_ui.line(line);
                    }
                    if s.marker != Marker::None {
                        plot_ui.points(markers(s, points, color));
                    }
                }
                SeriesKind::Scatter => plot_ui.points(markers(s, points, color)),
            }
        }
        for (k, l) in c.hlines.iter().enumerate() {
            plot_ui.hline(
                egui_plot::HLine::new(l.label.clone(), on_axis(ys, l.value))
                    .color(line_color(k))
                    .style(LineStyle::dashed_dense()),
            );
        }
        for (k, l) in c.vlines.iter().enumerate() {
            plot_ui.vline(
                VLine::new(l.label.clone(), on_axis(xs, l.value))
                    .color(line_color(c.hlines.len() + k))
                    .style(LineStyle::dashed_dense()),
            );
        }
        for k in &c.circles {
            let ring: Vec<[f64; 2]> = (0..=128)
                .map(|i| {
                    let a = f64::from(i) / 128.0 * std::f64::consts::TAU;
                    at(k.cx + k.r * a.cos(), k.cy + k.r * a.sin())
                })
                .collect();
            plot_ui.line(Line::new(k.label.clone(), ring).style(LineStyle::dashed_loose()));
        }
        for a in &c.annotations {
            let [x, y] = at(a.x, a.y);
            plot_ui.text(Text::new(a.text.clone(), PlotPoint::new(x, y), a.text.clone()));
        }
    });
}

/// Smallest and largest finite value, or `None` if there is none (or they are equal).
fn value_range(h: &Heatmap) -> Option<(f64, f64)> {
    if let Some((lo, hi)) = h.value_range {
        return (hi > lo).then_some((lo, hi));
    }
    let (lo, hi) = h
        .values
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    (lo.is_finite() && hi > lo).then_some((lo, hi))
}

/// Draws a heat map (equal aspect) with its colour scale and the labelled markers.
fn show_heatmap(ui: &mut egui::Ui, h: &Heatmap, id_salt: &str, height: f32) {
    ui.label(egui::RichText::new(&h.title).strong());
    let range = value_range(h);
    match range {
        None => {
            let value = h.values.iter().find(|v| v.is_finite()).copied().unwrap_or(0.0);
            ui.label(format!("uniform field: {} = {value:.3} everywhere", h.colorbar_label));
        }
        Some((lo, hi)) => {
            ui.horizontal(|ui| {
                ui.label(format!("{}:", h.colorbar_label));
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
                    ui.painter().rect_filled(seg, 0.0, color32(viridis(f64::from(f0 + f1) / 2.0)));
                }
                ui.label(format!("{hi:.3}"));
            });
        }
    }
    let valid = h.nx > 0 && h.values.len() == h.nx * h.ny;
    let x_axis = ScreenAxis::new(Scale::Linear, false, X_LABEL_PITCH);
    let y_axis = ScreenAxis::new(Scale::Linear, false, Y_LABEL_PITCH);
    let (x_spacer, y_spacer) = (x_axis.clone(), y_axis.clone());
    Plot::new(id_salt)
        .allow_scroll(false)
        .height(height)
        .data_aspect(1.0)
        .custom_x_axes(vec![x_axis.hints(egui_plot::Axis::X, &h.x_label)])
        .custom_y_axes(vec![y_axis.hints(egui_plot::Axis::Y, &h.y_label)])
        .x_grid_spacer(move |input| x_spacer.marks(&input))
        .y_grid_spacer(move |input| y_spacer.marks(&input))
        .show(ui, |plot_ui| {
            if valid && let Some((lo, hi)) = range {
                let w = (h.x_extent.1 - h.x_extent.0) as f32;
                let ht = (h.y_extent.1 - h.y_extent.0) as f32;
                let heat = egui_plot::Heatmap::new(h.values.clone(), h.nx)
                    .at(PlotPoint::new(h.x_extent.0, h.y_extent.0))
                    .size(w, ht)
                    .show_labels(false)
                    .custom_mapping(Box::new(move |v| color32(viridis((v - lo) / (hi - lo)))));
                plot_ui.add(heat);
            }
            let pts: Vec<[f64; 2]> = h.points.iter().map(|p| [p.0, p.1]).collect();
            plot_ui.points(
                Points::new("tactors", pts)
                    .shape(MarkerShape::Circle)
                    .radius(3.0)
                    .color(egui::Color32::WHITE),
            );
            for (x, y, label) in &h.points {
                plot_ui.text(
                    Text::new(label.clone(), PlotPoint::new(*x, *y), label.clone())
                        .color(egui::Color32::WHITE)
                        .anchor(egui::Align2::LEFT_BOTTOM),
                );
            }
        });
}

/// Draws one panel of a figure.
pub(crate) fn show_panel(ui: &mut egui::Ui, panel: &Panel, id_salt: &str, height: f32) {
    match panel {
        Panel::Chart(c) => show_chart(ui, c, id_salt, height),
        Panel::Heatmap(h) => show_heatmap(ui, h, id_salt, height),
    }
}

/// Draws a figure's panels in a two-column grid that fills the available width.
pub(crate) fn figure_grid(ui: &mut egui::Ui, id: &str, figure: &Figure, height: f32) {
    let columns = if ui.available_width() > 900.0 { 2 } else { 1 };
    for (row, chunk) in figure.panels.chunks(columns).enumerate() {
        ui.columns(columns, |cols| {
            for (k, (col, panel)) in cols.iter_mut().zip(chunk).enumerate() {
                show_panel(col, panel, &format!("{id}-{row}-{k}"), height);
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A day of five receivers' fixes: each scatter series draws at most 10,000 markers spread over the whole
    /// series, and says so; a long line keeps its extremes within 8,000 points; short series are untouched.
    #[test]
    #[allow(clippy::float_cmp)] // the drawn points are the series' own values, copied, not computed
    fn long_series_are_drawn_within_a_bound() {
        let n = 86_400;
        let xs: Vec<f64> = (0..n).map(f64::from).collect();
        let ys: Vec<f64> = (0..n).map(|i| (f64::from(i) * 0.01).sin()).collect();
        let at = |x: f64, y: f64| [x, y];
        let scatter = Series::scatter("2: serial", xs.clone(), ys.clone());
        let (drawn, label) = thinned_markers(&scatter.label, drawn_points(&scatter, at));
        assert!(drawn.len() <= MARKERS_DRAWN_MAX, "{}", drawn.len());
        assert_eq!(drawn[0], [0.0, 0.0]);
        assert!(drawn.last().unwrap()[0] > f64::from(n) - 10.0, "spread to the end");
        assert_eq!(label, "2: serial (1 in 9 of 86400 points drawn)");
        let line = Series::line("distance", xs.clone(), ys.clone());
        let drawn = drawn_points(&line, at);
        assert!(drawn.len() <= LINE_DRAWN_MAX + 2, "{}", drawn.len());
        let (lo, hi) = drawn.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| (lo.min(p[1]), hi.max(p[1])));
        let (tlo, thi) = ys.iter().fold((f64::MAX, f64::MIN), |(lo, hi), &y| (lo.min(y), hi.max(y)));
        assert!((lo, hi) == (tlo, thi), "the extremes are kept: {lo} {hi} against {tlo} {thi}");
        let short = Series::scatter("1", vec![0.0, 1.0], vec![2.0, 3.0]);
        assert_eq!(
            thinned_markers(&short.label, drawn_points(&short, at)),
            (vec![[0.0, 2.0], [1.0, 3.0]], "1".into())
        );
    }

    #[test]
    fn finite_runs_split_at_nan() {
        let pts = [[0.0, 1.0], [1.0, f64::NAN], [2.0, 3.0], [3.0, 4.0], [f64::INFINITY, 0.0]];
        let runs = finite_runs(&pts);
        assert_eq!(runs, vec![vec![[0.0, 1.0]], vec![[2.0, 3.0], [3.0, 4.0]]]);
    }

    /// A 220-point-high axis showing 0..2.5 (8 points of grid = 2.5 / 220 * 8): room for six labels at
    /// 32 points, so the figures' rule steps by 0.5 and the formatter labels exactly 0.0, 0.5, … 2.5 with one
    /// decimal, leaving the minor grid (every 0.1) unlabelled.
    #[test]
    fn screen_axis_labels_follow_the_figure_rule() {
        let axis = ScreenAxis::new(Scale::Linear, false, Y_LABEL_PITCH);
        let marks =
            axis.marks(&egui_plot::GridInput { bounds: (0.0, 2.5), base_step_size: 2.5 / 220.0 * 8.0 });
        let labelled: Vec<String> = marks.iter().map(|m| axis.label(*m)).filter(|l| !l.is_empty()).collect();
        assert_eq!(labelled, ["0.0", "0.5", "1.0", "1.5", "2.0", "2.5"]);
        let minor = marks.iter().filter(|m| axis.label(**m).is_empty()).count();
        // Fifths of 0.5 between 0 and 2.5: 26 values, 6 of them labelled.
        assert_eq!(minor, 20);
        // A wide x axis about zero: -3..3 over 600 points, a label at least every 70 points; no "-0".
        let x = ScreenAxis::new(Scale::Linear, false, X_LABEL_PITCH);
        let marks = x.marks(&egui_plot::GridInput { bounds: (-3.0, 3.0), base_step_size: 6.0 / 600.0 * 8.0 });
        let labelled: Vec<String> = marks.iter().map(|m| x.label(*m)).filter(|l| !l.is_empty()).collect();
        assert_eq!(labelled, ["-3", "-2", "-1", "0", "1", "2", "3"]);
    }

    #[test]
    fn counting_and_log_axes() {
        let pairs = ScreenAxis::new(Scale::Linear, true, X_LABEL_PITCH);
        let marks =
            pairs.marks(&egui_plot::GridInput { bounds: (0.6, 9.4), base_step_size: 8.8 / 900.0 * 8.0 });
        let labelled: Vec<String> = marks.iter().map(|m| pairs.label(*m)).filter(|l| !l.is_empty()).collect();
        assert_eq!(labelled, ["1", "2", "3", "4", "5", "6", "7", "8", "9"]);
        assert!(marks.iter().all(|m| (m.value - m.value.round()).abs() < 1e-9), "{marks:?}");
        // Six decades on a log axis (drawn in decades): labelled 0.001 … 100.
        let log = ScreenAxis::new(Scale::Log10, false, X_LABEL_PITCH);
        let marks =
            log.marks(&egui_plot::GridInput { bounds: (-3.0, 2.0), base_step_size: 5.0 / 600.0 * 8.0 });
        let labelled: Vec<String> = marks.iter().map(|m| log.label(*m)).filter(|l| !l.is_empty()).collect();
        assert_eq!(labelled, ["0.001", "0.01", "0.1", "1", "10", "100"]);
    }

    #[test]
    fn log_axes_round_trip_and_drop_non_positive_values() {
        for v in [1e-6, 0.3, 133.0] {
            assert!((from_axis(Scale::Log10, on_axis(Scale::Log10, v)) / v - 1.0).abs() < 1e-12);
        }
        assert!(on_axis(Scale::Log10, 0.0).is_nan());
        assert!(on_axis(Scale::Log10, -1.0).is_nan());
    }
}
