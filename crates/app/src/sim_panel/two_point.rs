//! The two-point view (thesis §4.2, Figs 60–63): two Gaussians, their sum, the single-Gaussian fit and its
//! residual at one distance (exported: the same figure and JSON as `vestnav sim two-point --distance-mm d`),
//! and the RMSE against distance with the threshold (as `vestnav sim two-point --sweep`).

use std::sync::Arc;

use vestnav_core::twopoint::{DEFAULT_RELATIVE_RMSE, TwoPointResult, TwoPointSetup};
use vestnav_report::Figure;
use vestnav_report::twopoint::{
    DEFAULT_SWEEP_MAX_MM, RmseSweep, fits, fits_figure, fits_json, header, sweep_figure,
};

use super::PLOT_HEIGHT;
use super::jobs::{Recompute, ViewOutput, export_row};
use super::plot_ui::figure_grid;
use crate::export::Exporter;

/// Inputs of the two-point fit at one distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct TwoPointInputs {
    pub setup: TwoPointSetup,
    pub distance_mm: f64,
}

/// Inputs of the RMSE-versus-distance sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
struct SweepInputs {
    setup: TwoPointSetup,
    max_mm: f64,
}

pub(super) fn compute(i: &TwoPointInputs) -> Result<Vec<TwoPointResult>, String> {
    fits(&i.setup, &[i.distance_mm]).map_err(|e| e.to_string())
}

fn compute_sweep(i: &SweepInputs) -> Result<RmseSweep, String> {
    RmseSweep::compute(&i.setup, i.max_mm, DEFAULT_RELATIVE_RMSE).map_err(|e| e.to_string())
}

/// The exported fit, and the sweep figure shown below it.
pub(super) struct TwoPointOutput {
    pub fit: ViewOutput,
    pub sweep: Option<Figure>,
}

pub(super) fn output(
    setup: &TwoPointSetup,
    results: &[TwoPointResult],
    sweep: Option<&RmseSweep>,
) -> TwoPointOutput {
    let mut head = header(setup, results);
    if let Some(sw) = sweep {
        head.push(sw.threshold_mm.map_or_else(
            || {
                format!(
                    "threshold (RMSE = {} of a): not reached in the sweep",
                    super::sig(sw.relative_rmse, 3)
                )
            },
            |t| format!("threshold (RMSE = {} of a): {t:.2} mm", super::sig(sw.relative_rmse, 3)),
        ));
    }
    TwoPointOutput {
        fit: ViewOutput {
            figure: Arc::new(fits_figure(setup, results)),
            header: head,
            json: fits_json(results).map_err(|e| e.to_string()),
        },
        sweep: sweep.map(sweep_figure),
    }
}

pub(super) struct TwoPointView {
    pub inputs: TwoPointInputs,
    sweep_max_mm: f64,
    fit_job: Recompute<TwoPointInputs, Vec<TwoPointResult>>,
    sweep_job: Recompute<SweepInputs, RmseSweep>,
    derived: Option<(u64, u64, TwoPointOutput)>,
    exporter: Exporter,
}

impl TwoPointView {
    pub fn new() -> Self {
        Self {
            inputs: TwoPointInputs { setup: TwoPointSetup::THESIS, distance_mm: 11.0 },
            sweep_max_mm: DEFAULT_SWEEP_MAX_MM,
            fit_job: Recompute::new(compute),
            sweep_job: Recompute::new(compute_sweep),
            derived: None,
            exporter: Exporter::new("vestnav-two-point.png", "Export the two-point figure to"),
        }
    }

    fn refresh(&mut self, ctx: &egui::Context) {
        self.fit_job.update(ctx, &self.inputs);
        self.sweep_job.update(ctx, &SweepInputs { setup: self.inputs.setup, max_mm: self.sweep_max_mm });
        let key = (self.fit_job.generation(), self.sweep_job.generation());
        if self.derived.as_ref().is_some_and(|d| (d.0, d.1) == key) {
            return;
        }
        let Some((inputs, results)) = self.fit_job.shown() else { return };
        let sweep = self.sweep_job.shown().map(|(_, s)| Arc::clone(s));
        self.derived = Some((key.0, key.1, output(&inputs.setup, results, sweep.as_deref())));
    }

    pub fn ui(&mut self, ui: &mut egui::Ui, base: &std::path::Path) {
        let i = &mut self.inputs;
        ui.horizontal_wrapped(|ui| {
            super::add_wrapping(
                ui,
                egui::Slider::new(&mut i.distance_mm, 0.0..=150.0).text("distance d [mm]").fixed_decimals(1),
            );
            super::add_wrapping(
                ui,
                egui::Slider::new(&mut i.setup.width_mm, 10.0..=60.0).text("width b [mm]"),
            );
            super::add_wrapping(
                ui,
                egui::Slider::new(&mut i.setup.amplitude_m_s2, 1.0..=30.0).text("amplitude a [m/s^2]"),
            );
            super::add_wrapping(
                ui,
                egui::Slider::new(&mut self.sweep_max_mm, 20.0..=200.0).text("RMSE sweep up to [mm]"),
            );
            if ui.small_button("thesis setup").clicked() {
                i.setup = TwoPointSetup::THESIS;
            }
        });
        let ctx = ui.ctx().clone();
        self.refresh(&ctx);
        self.fit_job.status_ui(ui);
        self.sweep_job.status_ui(ui);
        let Some((_, _, out)) = &self.derived else { return };
        for line in &out.fit.header {
            ui.label(line);
        }
        export_row(ui, &mut self.exporter, &out.fit, base);
        egui::ScrollArea::vertical().id_salt("sim-twopoint-scroll").show(ui, |ui| {
            figure_grid(ui, "sim-twopoint", &out.fit.figure, PLOT_HEIGHT);
            if let Some(sweep) = &out.sweep {
                figure_grid(ui, "sim-twopoint-sweep", sweep, PLOT_HEIGHT);
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use vestnav_plot::Panel;

    #[test]
    fn fit_panels_follow_the_closed_form_and_the_reference() {
        let setup = TwoPointSetup::THESIS;
        let results = compute(&TwoPointInputs { setup, distance_mm: 11.0 }).unwrap();
        // physics.md §3 reference at d = 11 mm.
        assert_relative_eq!(results[0].amplitude_m_s2, 19.546, max_relative = 1e-4);
        assert_relative_eq!(results[0].rmse, 0.001_727, max_relative = 1e-3);
        let out = output(&setup, &results, None);
        let Panel::Chart(parts) = &out.fit.figure.panels[0] else { panic!("chart expected") };
        let sum = &parts.series[2];
        assert_eq!(sum.x.len(), 281);
        for (&x, &y) in sum.x.iter().zip(&sum.y) {
            let want =
                10.0 * (-(x / 36.2_f64).powi(2)).exp() + 10.0 * (-((x - 11.0) / 36.2_f64).powi(2)).exp();
            assert_relative_eq!(y, want, max_relative = 1e-12);
        }
    }

    #[test]
    fn rmse_sweep_grows_with_distance_and_crosses_below_the_sparrow_limit() {
        let sweep = compute_sweep(&SweepInputs { setup: TwoPointSetup::THESIS, max_mm: 60.0 }).unwrap();
        assert_eq!(sweep.results.len(), 61);
        let rmse: Vec<f64> = sweep.results.iter().map(|r| r.rmse).collect();
        assert!(rmse[10] < rmse[30] && rmse[30] < rmse[60]);
        let t = sweep.threshold_mm.unwrap();
        assert!(t > 11.0 && t < 51.2, "threshold {t} below the Sparrow limit sqrt(2) 36.2 = 51.2 mm");
    }
}
