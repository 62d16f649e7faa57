//! The damping-sweep view: peak frequency against force as the damping varies, the power-law fit, the
//! current line and the calibration curve (thesis §3.2.2–3.2.3, Figs 35–38, `vestnav_report`'s sweep figure),
//! and "damping for frequency" with a button that simulates the calibrated tactor in the tactor view.

use std::sync::Arc;

use vestnav_core::sweep::{self, Calibration, SweepOptions};
use vestnav_core::tactor::{self, BodyMass, Preset, SimOptions, TactorParams};
use vestnav_report::sweep::{SweepReport, SweepSet, header, sweep_figure};

use super::PLOT_HEIGHT;
use super::jobs::{Derived, Recompute, ViewOutput, export_row};
use super::plot_ui::figure_grid;
use crate::export::Exporter;

/// Inputs of the damping sweep (those of `vestnav sim sweep`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SweepInputs {
    pub preset: Preset,
    pub voltage_v: f64,
    pub body: BodyMass,
    pub radius_m: f64,
    pub options: SweepOptions,
}

impl SweepInputs {
    /// The defaults of `vestnav sim sweep`.
    pub fn thesis() -> Self {
        Self {
            preset: Preset::ThesisSim,
            voltage_v: TactorParams::preset(Preset::ThesisSim).voltage_v,
            body: BodyMass::Unencased,
            radius_m: tactor::RADIUS_CAD_M,
            options: SweepOptions::default(),
        }
    }

    pub fn params(&self) -> TactorParams {
        TactorParams::preset(self.preset)
            .with_body(self.body)
            .with_voltage(self.voltage_v)
            .with_radius(self.radius_m)
    }
}

pub(super) fn compute(i: &SweepInputs) -> Result<SweepSet, String> {
    SweepSet::compute(&i.params(), &i.options).map_err(|e| e.to_string())
}

/// Inputs of the damping calibration ("damping for frequency").
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct CalibrationInputs {
    pub params: TactorParams,
    pub frequency_hz: f64,
}

fn compute_calibration(i: &CalibrationInputs) -> Result<Calibration, String> {
    sweep::calibrate_damping(&i.params, i.frequency_hz, &SimOptions::default()).map_err(|e| e.to_string())
}

/// The figure, header and JSON of the sweeps.
pub(super) fn output(set: &SweepSet) -> ViewOutput {
    ViewOutput {
        figure: Arc::new(sweep_figure(set)),
        header: header(set),
        json: vestnav_report::to_json(&SweepReport::new(&set.main)).map_err(|e| e.to_string()),
    }
}

pub(super) struct SweepView {
    pub inputs: SweepInputs,
    pub frequency_hz: f64,
    pub job: Recompute<SweepInputs, SweepSet>,
    pub calibration: Recompute<CalibrationInputs, Calibration>,
    derived: Option<Derived<u64>>,
    exporter: Exporter,
}

impl SweepView {
    pub fn new() -> Self {
        Self {
            inputs: SweepInputs::thesis(),
            frequency_hz: 133.2,
            job: Recompute::new(compute),
            calibration: Recompute::new(compute_calibration),
            derived: None,
            exporter: Exporter::new("vestnav-sweep.png", "Export the damping sweep to"),
        }
    }

    fn calibration_inputs(&self) -> CalibrationInputs {
        CalibrationInputs { params: self.inputs.params(), frequency_hz: self.frequency_hz }
    }

    fn refresh(&mut self, ctx: &egui::Context) {
        self.job.update(ctx, &self.inputs);
        let cal_inputs = self.calibration_inputs();
        self.calibration.update(ctx, &cal_inputs);
        let key = self.job.generation();
        if self.derived.as_ref().is_some_and(|d| d.key == key) {
            return;
        }
        let Some((_, set)) = self.job.shown() else { return };
        self.derived = Some(Derived { key, out: output(set) });
    }

    /// Draws the view; returns a damping the operator wants simulated in the tactor view.
    pub fn ui(&mut self, ui: &mut egui::Ui, base: &std::path::Path) -> Option<f64> {
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
            let o = &mut i.options;
            super::add_wrapping(
                ui,
                egui::Slider::new(&mut i.voltage_v, 0.5..=6.0).text("voltage [V]").fixed_decimals(3),
            );
            ui.add(egui::DragValue::new(&mut o.min_hz).range(10.0..=1000.0).prefix("from ").suffix(" Hz"));
            ui.add(egui::DragValue::new(&mut o.max_hz).range(10.0..=2000.0).prefix("to ").suffix(" Hz"));
            ui.add(egui::DragValue::new(&mut o.points).range(4..=200).prefix("points "));
            ui.add(
                egui::DragValue::new(&mut o.sim.duration_s)
                    .range(0.2..=10.0)
                    .speed(0.1)
                    .prefix("each ")
                    .suffix(" s"),
            );
        });
        if i.options.max_hz <= i.options.min_hz + 1.0 {
            i.options.max_hz = i.options.min_hz + 1.0;
        }
        let mut apply = None;
        ui.horizontal_wrapped(|ui| {
            ui.label("Damping for frequency:");
            ui.add(egui::DragValue::new(&mut self.frequency_hz).range(1.0..=2000.0).speed(0.1).suffix(" Hz"));
            if let Some((inputs, c)) = self.calibration.shown() {
                ui.monospace(format!(
                    "b = {:.5e} N m s (closed form {:.5e}) -> f_rot {:.3} Hz after {} simulations",
                    c.damping_n_m_s, c.damping_closed_form_n_m_s, c.achieved_f_rot_hz, c.iterations
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
        if let Some(Derived { out, .. }) = &self.derived {
            for line in &out.header {
                ui.label(line);
            }
            export_row(ui, &mut self.exporter, out, base);
            egui::ScrollArea::vertical().id_salt("sim-sweep-scroll").show(ui, |ui| {
                figure_grid(ui, "sim-sweep", &out.figure, PLOT_HEIGHT);
            });
        }
        apply
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use vestnav_plot::Panel;

    #[test]
    fn sweep_figure_draws_the_closed_form_inverse_and_current_line() {
        // The defaults are `vestnav sim sweep`'s.
        assert_eq!(
            SweepInputs::thesis().params(),
            TactorParams::preset(Preset::ThesisSim).with_body(BodyMass::Unencased)
        );
        let inputs = SweepInputs {
            options: SweepOptions { min_hz: 100.0, max_hz: 160.0, points: 6, ..SweepOptions::default() },
            ..SweepInputs::thesis()
        };
        let set = compute(&inputs).unwrap();
        assert_relative_eq!(set.other_body.params.body_mass_kg, 4.95e-3);
        assert_relative_eq!(set.other_radius.params.radius_m, 3.2e-3);
        assert_relative_eq!(set.measured.params.resistance_ohm, 67.0);
        let out = output(&set);
        assert_eq!(out.figure.panels.len(), 4);
        // Fig 38: b(f) = (Kt u / (2 pi f) - Kt^2) / R in units of 1e-8 N m s (physics.md §1 steady state).
        let Panel::Chart(fig38) = &out.figure.panels[3] else { panic!("chart expected") };
        let exact = &fig38.series[1];
        let (kt, u, r) = (0.0019, 3.3, 62.0);
        for (&f, &b) in exact.x.iter().zip(&exact.y) {
            let want = (kt * u / (std::f64::consts::TAU * f) - kt * kt) / r * 1e8;
            assert_relative_eq!(b, want, max_relative = 1e-9);
        }
        // Fig 37 (measured preset, R = 67 ohm): f = u/(2 pi Kt) - R/(2 pi Kt) i, drawn against mA.
        let Panel::Chart(fig37) = &out.figure.panels[2] else { panic!("chart expected") };
        let line = &fig37.series[1];
        let f_of_ma = |i_ma: f64| (u - 67.0 * i_ma * 1e-3) / (std::f64::consts::TAU * kt);
        assert_relative_eq!(line.y[0], f_of_ma(line.x[0]), max_relative = 1e-3);
        let cal =
            compute_calibration(&CalibrationInputs { params: inputs.params(), frequency_hz: 133.2 }).unwrap();
        assert_relative_eq!(cal.achieved_f_rot_hz, 133.2, max_relative = 1e-5);
    }
}
