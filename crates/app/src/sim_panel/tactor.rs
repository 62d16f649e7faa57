//! The tactor view: the pancake-motor ODE (thesis §3.2, Figs 28–34) with sliders for the preset, body mass,
//! voltage, damping and radius; the summary numbers and `vestnav_report`'s tactor figure.

use std::sync::Arc;

use vestnav_core::tactor::{self, BodyMass, Preset, SimOptions, TactorParams};
use vestnav_report::tactor::{DEFAULT_SPAN_S, TactorReport, TactorRuns, header, summary_rows, tactor_figure};

use super::PLOT_HEIGHT;
use super::jobs::{Derived, Recompute, ViewOutput, export_row};
use super::plot_ui::figure_grid;
use crate::export::Exporter;

/// Output sampling rate of the traces [Hz] (the thesis's 10 kHz, as `vestnav sim tactor`).
const RATE_HZ: f64 = 10_000.0;

/// Inputs of the tactor view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct TactorInputs {
    pub preset: Preset,
    pub body: BodyMass,
    pub voltage_v: f64,
    pub damping_n_m_s: f64,
    pub radius_m: f64,
    pub duration_s: f64,
    /// Also simulate the other body mass (Figs 28–31 compare unencased and encased).
    pub compare_bodies: bool,
}

impl TactorInputs {
    /// The defaults of `vestnav sim tactor`: thesis-sim preset, unencased, 3.3 V, b = 6.3e-8 N m s,
    /// l = 2.57 mm, 10 s, both bodies in the figure.
    pub fn thesis() -> Self {
        let p = TactorParams::preset(Preset::ThesisSim);
        Self {
            preset: Preset::ThesisSim,
            body: BodyMass::Unencased,
            voltage_v: p.voltage_v,
            damping_n_m_s: tactor::DAMPING_THESIS_N_M_S,
            radius_m: tactor::RADIUS_CAD_M,
            duration_s: 10.0,
            compare_bodies: true,
        }
    }

    pub fn params(&self) -> TactorParams {
        TactorParams::preset(self.preset)
            .with_body(self.body)
            .with_voltage(self.voltage_v)
            .with_damping(self.damping_n_m_s)
            .with_radius(self.radius_m)
    }
}

pub(super) fn compute(i: &TactorInputs) -> Result<TactorRuns, String> {
    let options = SimOptions { duration_s: i.duration_s, output_rate_hz: RATE_HZ };
    TactorRuns::simulate(&i.params(), &options, tactor::DEFAULT_STEP_ANGLE_RAD, i.compare_bodies)
        .map_err(|e| e.to_string())
}

/// The figure, header and JSON of the runs, traces shown over `0..=span_s`.
pub(super) fn output(runs: &TactorRuns, span_s: f64) -> ViewOutput {
    ViewOutput {
        figure: Arc::new(tactor_figure(runs, span_s)),
        header: header(runs),
        json: vestnav_report::to_json(&TactorReport::new(&runs.main.summary)).map_err(|e| e.to_string()),
    }
}

pub(super) struct TactorView {
    pub inputs: TactorInputs,
    /// Traces are drawn over `0..=span_s`.
    pub span_s: f64,
    pub job: Recompute<TactorInputs, TactorRuns>,
    /// Output keyed by (result generation, bits of `span_s`).
    pub derived: Option<Derived<(u64, u64)>>,
    pub exporter: Exporter,
}

impl TactorView {
    pub fn new() -> Self {
        Self {
            inputs: TactorInputs::thesis(),
            span_s: DEFAULT_SPAN_S,
            job: Recompute::new(compute),
            derived: None,
            exporter: Exporter::new("vestnav-tactor.png", "Export the tactor figure to"),
        }
    }

    /// Recomputes if needed and refreshes the derived output.
    pub fn refresh(&mut self, ctx: &egui::Context) {
        self.job.update(ctx, &self.inputs);
        let key = (self.job.generation(), self.span_s.to_bits());
        let Some((_, runs)) = self.job.shown() else { return };
        if self.derived.as_ref().is_none_or(|d| d.key != key) {
            self.derived = Some(Derived { key, out: output(runs, self.span_s) });
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
            super::add_wrapping(
                ui,
                egui::Slider::new(&mut i.voltage_v, 0.5..=6.0).text("voltage [V]").fixed_decimals(3),
            );
            super::add_wrapping(
                ui,
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
            super::add_wrapping(
                ui,
                egui::Slider::new(&mut radius_mm, 1.0..=5.0)
                    .text("eccentric radius l [mm]")
                    .fixed_decimals(2),
            );
            if ui.small_button("CAD 2.57").clicked() {
                i.radius_m = tactor::RADIUS_CAD_M;
            } else if ui.small_button("fitted 3.2").clicked() {
                i.radius_m = tactor::RADIUS_FITTED_M;
            } else if (radius_mm * 1e-3 - i.radius_m).abs() > 1e-12 {
                i.radius_m = radius_mm * 1e-3;
            }
            super::add_wrapping(
                ui,
                egui::Slider::new(&mut i.duration_s, 0.2..=10.0).text("simulated [s]").fixed_decimals(1),
            );
            super::add_wrapping(
                ui,
                egui::Slider::new(&mut self.span_s, 0.005..=10.0)
                    .logarithmic(true)
                    .text("traces shown [s]")
                    .fixed_decimals(3),
            );
        });
    }

    pub fn ui(&mut self, ui: &mut egui::Ui, base: &std::path::Path) {
        self.controls(ui);
        let ctx = ui.ctx().clone();
        self.refresh(&ctx);
        self.job.status_ui(ui);
        let Some(Derived { out, .. }) = &self.derived else { return };
        if let Some((_, runs)) = self.job.shown() {
            summary_table(ui, runs);
        }
        export_row(ui, &mut self.exporter, out, base);
        egui::ScrollArea::vertical().id_salt("sim-tactor-scroll").show(ui, |ui| {
            figure_grid(ui, "sim-tactor", &out.figure, PLOT_HEIGHT);
        });
    }
}

/// The summary numbers of every run side by side.
fn summary_table(ui: &mut egui::Ui, runs: &TactorRuns) {
    egui::CollapsingHeader::new("Summary (window = last half of the run)").default_open(false).show(
        ui,
        |ui| {
            egui::Grid::new("sim-tactor-summary").striped(true).show(ui, |ui| {
                ui.strong("quantity");
                for run in runs.all() {
                    ui.strong(run.summary.params.body.name());
                }
                ui.end_row();
                let rows: Vec<Vec<(&str, String)>> = runs.all().map(|r| summary_rows(&r.summary)).collect();
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

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use vestnav_plot::Panel;

    #[test]
    fn figure_follows_the_closed_form_and_the_export_is_the_report() {
        // The console's defaults are the command line's (`ModelArgs::params` with no option given), so the
        // CLI-side tests in tests/integration/sim_tactor.rs compare the same inputs.
        assert_eq!(
            TactorInputs::thesis().params(),
            TactorParams::preset(Preset::ThesisSim).with_body(BodyMass::Unencased)
        );
        let inputs = TactorInputs { duration_s: 1.0, ..TactorInputs::thesis() };
        let runs = compute(&inputs).unwrap();
        assert!(runs.other.is_some());
        let out = output(&runs, 0.5);
        // Panel 0 is Fig 28, the eccentric angle (physics.md §7); the rotor speed is the last panel, with
        // the closed form omega = Kt u / (R b + Kt^2) = 834.22 rad/s (physics.md §1).
        let Panel::Chart(fig28) = &out.figure.panels[0] else { panic!("chart expected") };
        assert!(fig28.title.starts_with("Fig 28: eccentric angle"), "{}", fig28.title);
        let Some(Panel::Chart(speed)) = out.figure.panels.last() else { panic!("chart expected") };
        let kt = 0.0019;
        assert_relative_eq!(speed.hlines[0].value, kt * 3.3 / (62.0 * 6.3e-8 + kt * kt), max_relative = 1e-9);
        assert!(speed.series[0].x.iter().all(|&t| t <= 0.5));
        // x amplitude m l / Mt = 0.382 mm: the position trace (Fig 29) stays within it.
        let Panel::Chart(fig29) = &out.figure.panels[1] else { panic!("chart expected") };
        let x_amp_mm = 0.55e-3 * 2.57e-3 / 3.7e-3 * 1e3;
        assert!(fig29.series[0].y.iter().all(|x| x.abs() <= x_amp_mm * 1.01));
        // The export writes what vestnav-report makes of the same runs.
        let json = String::from_utf8(out.bytes(crate::export::ExportFormat::Json).unwrap()).unwrap();
        assert_eq!(json, vestnav_report::to_json(&TactorReport::new(&runs.main.summary)).unwrap());
        let csv = String::from_utf8(out.bytes(crate::export::ExportFormat::Csv).unwrap()).unwrap();
        assert!(csv.contains("mean omega [rad/s]") && csv.lines().count() > 1000);
    }
}
