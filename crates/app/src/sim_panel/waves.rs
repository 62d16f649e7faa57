//! The skin-wave view (thesis §4.1.3): the superposed field of any set of firing tactors on the vest plane
//! (exported: the same figure and JSON as `vestnav sim wave --view vest`), the attenuation of Fig 52 and the
//! travelling wave of Fig 57 for the chosen source.

use std::sync::Arc;

use vestnav_core::vest::{GRID, TactorMask};
use vestnav_core::wave::{self, DVec2, Skin, WaveSource};
use vestnav_report::Figure;
use vestnav_report::wave::{
    Attenuation, DEFAULT_TRAVELLING_S, DEFAULT_VEST_SPACING_MM, THESIS_DISTANCES_MM, Travelling, VestField,
    VestFieldInputs,
};

use super::jobs::{Recompute, ViewOutput, export_row};
use super::plot_ui::figure_grid;
use crate::export::Exporter;

/// Height of the heat maps on screen [points].
const FIELD_HEIGHT: f32 = 320.0;

/// Inputs of the skin-wave view (lengths in mm, times in ms, as the sliders show them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct WaveInputs {
    /// Firing tactors (vest numbering).
    pub mask: TactorMask,
    /// Centre-to-centre tactor spacing [mm].
    pub spacing_mm: f64,
    /// Source amplitude a0 [m/s^2].
    pub amplitude_m_s2: f64,
    /// Gaussian width b [mm].
    pub width_mm: f64,
    /// Vibration frequency [Hz].
    pub frequency_hz: f64,
    /// Wave speed on the skin [m/s].
    pub speed_m_s: f64,
    /// Time of the snapshot [ms].
    pub t_ms: f64,
}

impl WaveInputs {
    /// The defaults of `vestnav sim wave --view vest`: tactor 5, 60 mm, the measured travelling wave.
    pub fn thesis() -> Self {
        let d = VestFieldInputs::default();
        Self {
            mask: TactorMask::from_indices(d.tactors.iter().copied()),
            spacing_mm: d.spacing_mm,
            amplitude_m_s2: d.source.amplitude_m_s2,
            width_mm: d.source.width_m * 1e3,
            frequency_hz: d.source.frequency_hz,
            speed_m_s: d.skin.speed_m_s,
            t_ms: d.time_s * 1e3,
        }
    }

    pub fn field_inputs(&self) -> VestFieldInputs {
        VestFieldInputs {
            tactors: self.mask.indices().collect(),
            spacing_mm: self.spacing_mm,
            source: WaveSource {
                amplitude_m_s2: self.amplitude_m_s2,
                width_m: self.width_mm * 1e-3,
                frequency_hz: self.frequency_hz,
                ..WaveSource::measured(DVec2::ZERO)
            },
            skin: Skin { speed_m_s: self.speed_m_s },
            time_s: self.t_ms * 1e-3,
        }
    }
}

/// The exported vest field, and the other figures shown.
pub(super) struct WaveOutput {
    pub field: ViewOutput,
    pub attenuation: Figure,
    pub travelling: Figure,
}

pub(super) fn compute(i: &WaveInputs) -> Result<WaveOutput, String> {
    let inputs = i.field_inputs();
    let field = VestField::compute(&inputs).map_err(|e| e.to_string())?;
    let attenuation = Attenuation::compute(wave::SPACING_RULE_FRACTION).map_err(|e| e.to_string())?;
    let travelling =
        Travelling::compute(&inputs.skin, &inputs.source, &THESIS_DISTANCES_MM, 0.0, DEFAULT_TRAVELLING_S);
    Ok(WaveOutput {
        field: ViewOutput {
            figure: Arc::new(field.figure()),
            header: field.header(),
            json: vestnav_report::to_json(&field).map_err(|e| e.to_string()),
        },
        attenuation: attenuation.figure(),
        travelling: travelling.figure(),
    })
}

pub(super) struct WaveView {
    pub inputs: WaveInputs,
    pub job: Recompute<WaveInputs, WaveOutput>,
    exporter: Exporter,
}

impl WaveView {
    pub fn new() -> Self {
        Self {
            inputs: WaveInputs::thesis(),
            job: Recompute::new(compute),
            exporter: Exporter::new("vestnav-vest-field.png", "Export the vest field to"),
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
                if ui.small_button(format!("vest spacing {DEFAULT_VEST_SPACING_MM} mm")).clicked() {
                    i.spacing_mm = DEFAULT_VEST_SPACING_MM;
                }
                ui.add(egui::Slider::new(&mut i.amplitude_m_s2, 1.0..=50.0).text("a0 [m/s^2]"));
                ui.add(egui::Slider::new(&mut i.width_mm, 10.0..=60.0).text("Gaussian width b [mm]"));
                ui.add(egui::Slider::new(&mut i.frequency_hz, 20.0..=250.0).text("frequency [Hz]"));
                ui.add(egui::Slider::new(&mut i.speed_m_s, 0.5..=10.0).text("wave speed c [m/s]"));
                let period_ms = 1e3 / i.frequency_hz;
                ui.add(
                    egui::Slider::new(&mut i.t_ms, 0.0..=3.0 * period_ms)
                        .text("snapshot t [ms]")
                        .fixed_decimals(2),
                );
                if ui.small_button("thesis Skinsim values").clicked() {
                    let d = WaveInputs::thesis();
                    (i.amplitude_m_s2, i.width_mm, i.frequency_hz, i.speed_m_s) =
                        (d.amplitude_m_s2, d.width_mm, d.frequency_hz, d.speed_m_s);
                }
            });
        });
    }

    pub fn ui(&mut self, ui: &mut egui::Ui, base: &std::path::Path) {
        self.controls(ui);
        let ctx = ui.ctx().clone();
        self.job.update(&ctx, &self.inputs);
        self.job.status_ui(ui);
        let Some((_, out)) = self.job.shown() else { return };
        let out = Arc::clone(out);
        for line in &out.field.header {
            ui.label(line);
        }
        export_row(ui, &mut self.exporter, &out.field, base);
        egui::ScrollArea::vertical().id_salt("sim-wave-scroll").show(ui, |ui| {
            figure_grid(ui, "sim-wave-field", &out.field.figure, FIELD_HEIGHT);
            figure_grid(ui, "sim-wave-attenuation", &out.attenuation, super::PLOT_HEIGHT);
            figure_grid(ui, "sim-wave-travelling", &out.travelling, super::PLOT_HEIGHT);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use vestnav_plot::Panel;

    #[test]
    fn one_tactor_field_is_its_gaussian_and_the_default_spacing_is_the_cli_one() {
        let inputs = WaveInputs { mask: TactorMask::single(5).unwrap(), ..WaveInputs::thesis() };
        assert_relative_eq!(inputs.spacing_mm, 60.0);
        let out = compute(&inputs).unwrap();
        let Panel::Heatmap(h) = &out.field.figure.panels[0] else { panic!("heat map expected") };
        let n = h.nx;
        assert_eq!(h.values.len(), n * n);
        // Tactor 5 = row 1, column 1: x = -30 mm, y = +30 mm on a 60 mm grid; peak a0 exp(-(r/b)^2).
        let (tx, ty) = (-30.0, 30.0);
        let cell = (h.x_extent.1 - h.x_extent.0) / n as f64;
        for (k, v) in h.values.iter().enumerate().step_by(97) {
            let x = h.x_extent.0 + ((k % n) as f64 + 0.5) * cell;
            let y = h.y_extent.0 + ((k / n) as f64 + 0.5) * cell;
            let r2 = (x - tx).powi(2) + (y - ty).powi(2);
            assert_relative_eq!(
                *v,
                26.02 * (-r2 / 28.18_f64.powi(2)).exp(),
                max_relative = 1e-9,
                epsilon = 1e-12
            );
        }
        // Spacing rule for b = 28.18 mm: b sqrt(ln 10) = 42.76 mm.
        assert!(out.field.header.iter().any(|l| l.contains("42.76")), "{:?}", out.field.header);
    }
}
