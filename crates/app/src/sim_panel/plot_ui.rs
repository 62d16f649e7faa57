//! Draws a `vestnav_plot::Figure` on screen with `egui_plot`, panel by panel: the same figure the views
//! export as PNG, so what the operator sees is what they save. Colours come from `vestnav_plot` (its series
//! palette and its viridis colour map).

use egui_plot::{Legend, Line, LineStyle, MarkerShape, Plot, PlotPoint, Points, Text, VLine};
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

/// A series' finite points as markers (line series with markers and scatter series alike).
fn markers(s: &Series, points: Vec<[f64; 2]>, color: egui::Color32) -> Points<'static> {
    let finite: Vec<[f64; 2]> = points.into_iter().filter(|p| p[0].is_finite() && p[1].is_finite()).collect();
    Points::new(s.label.clone(), finite).shape(marker_shape(s.marker)).radius(2.5).color(color)
}

/// The smallest of 1, 2 or 5 times a power of ten that is at least `v` (`v` > 0 and finite).
fn next_one_two_five(v: f64) -> f64 {
    let decade = 10f64.powf(v.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|&s| s >= v * (1.0 - 1e-12))
        .unwrap_or(10.0 * decade)
}

/// Grid steps of a linear axis in the 1-2-5 sequence: the finest at least egui's suggested step, and the
/// next two of the sequence. `egui_plot`'s default steps go up by factors of ten, so a 220-point-high plot
/// of 0..900 gets lines every 100 (too close to label) or every 1000 (only "0" in view): the rotor-speed
/// plot at 3.3 V showed its "0" tick alone. With 1-2-5 steps it is labelled every 200.
fn one_two_five_steps(input: &egui_plot::GridInput) -> [f64; 3] {
    let base = input.base_step_size;
    if !(base.is_finite() && base > 0.0) {
        return [1.0, 2.0, 5.0];
    }
    let fine = next_one_two_five(base);
    let mid = next_one_two_five(fine * 1.5);
    let coarse = next_one_two_five(mid * 1.5);
    [fine, mid, coarse]
}

/// Draws a chart (drag pans, Ctrl + wheel zooms, double-click resets; the plain wheel scrolls the page the
/// plots sit in, as it does everywhere else).
fn show_chart(ui: &mut egui::Ui, c: &Chart, id_salt: &str, height: f32) {
    let (xs, ys) = (c.x_scale, c.y_scale);
    let at = move |x: f64, y: f64| [on_axis(xs, x), on_axis(ys, y)];
    ui.label(egui::RichText::new(&c.title).strong());
    let mut plot = Plot::new(id_salt)
        .allow_scroll(false)
        .height(height)
        .legend(Legend::default())
        .x_axis_label(c.x_label.clone())
        .y_axis_label(c.y_label.clone());
    if c.equal_aspect {
        plot = plot.data_aspect(1.0);
    }
    if xs == Scale::Linear {
        plot = plot.x_grid_spacer(egui_plot::uniform_grid_spacer(|i| one_two_five_steps(&i)));
    }
    if ys == Scale::Linear {
        plot = plot.y_grid_spacer(egui_plot::uniform_grid_spacer(|i| one_two_five_steps(&i)));
    }
    if let Some((lo, hi)) = c.y_range {
        plot = plot.include_y(on_axis(ys, lo)).include_y(on_axis(ys, hi));
    }
    if xs == Scale::Log10 {
        plot = plot.x_axis_formatter(|mark, _| format!("{:.0e}", 10f64.powf(mark.value)));
    }
    if ys == Scale::Log10 {
        plot = plot.y_axis_formatter(|mark, _| format!("{:.0e}", 10f64.powf(mark.value)));
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
            let color = color32(s.color.unwrap_or_else(|| Color::palette(idx)));
            let points: Vec<[f64; 2]> = s.x.iter().zip(&s.y).map(|(&x, &y)| at(x, y)).collect();
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
        for l in &c.hlines {
            plot_ui.hline(
                egui_plot::HLine::new(l.label.clone(), on_axis(ys, l.value)).style(LineStyle::dashed_dense()),
            );
        }
        for l in &c.vlines {
            plot_ui.vline(VLine::new(l.label.clone(), on_axis(xs, l.value)).style(LineStyle::dashed_dense()));
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
    Plot::new(id_salt)
        .allow_scroll(false)
        .height(height)
        .data_aspect(1.0)
        .x_axis_label(h.x_label.clone())
        .y_axis_label(h.y_label.clone())
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

    #[test]
    fn finite_runs_split_at_nan() {
        let pts = [[0.0, 1.0], [1.0, f64::NAN], [2.0, 3.0], [3.0, 4.0], [f64::INFINITY, 0.0]];
        let runs = finite_runs(&pts);
        assert_eq!(runs, vec![vec![[0.0, 1.0]], vec![[2.0, 3.0], [3.0, 4.0]]]);
    }

    #[test]
    fn grid_steps_follow_one_two_five() {
        let check = |base: f64, want: [f64; 3]| {
            let got =
                one_two_five_steps(&egui_plot::GridInput { bounds: (0.0, 900.0), base_step_size: base });
            for (g, w) in got.iter().zip(want) {
                assert!((g / w - 1.0).abs() < 1e-12, "base {base}: {got:?} != {want:?}");
            }
        };
        check(13.0, [20.0, 50.0, 100.0]);
        check(20.0, [20.0, 50.0, 100.0]);
        check(0.3, [0.5, 1.0, 2.0]);
        check(60.0, [100.0, 200.0, 500.0]);
        check(f64::NAN, [1.0, 2.0, 5.0]);
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
