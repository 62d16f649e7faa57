//! The Simulation panel: interactive views of the thesis physics, one file per view.
//!
//! - [`tactor`]: the pancake-motor ODE (thesis §3.2, Figs 28–34) with sliders and the summary numbers;
//! - [`sweep`]: the damping sweep and its fits (Figs 35–38), and "damping for frequency";
//! - [`waves`]: the vibration field of firing tactors on the vest plane, Fig 52 and Fig 57 (§4.1.3);
//! - [`two_point`]: two Gaussians and the single-Gaussian fit, RMSE against distance (§4.2, Figs 60–63).
//!
//! Every figure and JSON comes from `vestnav_report`, the same functions `vestnav sim ...` calls: a view
//! draws its `vestnav_plot::Figure` on screen panel by panel ([`plot_ui`]), and its Save buttons write that
//! figure as PNG, the result's JSON, or the figure's data as CSV, so for the same inputs the console and the
//! command line write the same files. Computations and exports run on worker threads ([`jobs`]).

mod jobs;
mod plot_ui;
mod sweep;
mod tactor;
mod two_point;
mod waves;

pub(crate) use plot_ui::figure_grid;

pub(crate) use vestnav_report::sig;

/// Width a slider with its value box and label takes [points] (a 100-point track, ~60 for the value, the
/// rest for the label).
const SLIDER_ROW_PT: f32 = 300.0;

/// Adds a slider (or any composite widget) to a `horizontal_wrapped` row, starting a new row first when
/// less than [`SLIDER_ROW_PT`] is left. egui wraps a row before an atomic widget that does not fit, but a
/// slider is a group of three, placed before its size is known: left alone it runs past the right edge and
/// widens everything under it (the Two-point view was wider than a 1024-point window).
pub(crate) fn add_wrapping(ui: &mut egui::Ui, widget: impl egui::Widget) -> egui::Response {
    if ui.available_size_before_wrap().x < SLIDER_ROW_PT {
        ui.end_row();
    }
    ui.add(widget)
}

/// Height of one plot on screen [points].
const PLOT_HEIGHT: f32 = 220.0;

/// Which view the panel shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Tab {
    Tactor,
    Sweep,
    Waves,
    TwoPoint,
}

/// Interactive simulation views: tactor model, damping sweep, skin waves and the two-point simulation, each
/// with its own inputs, cached results and PNG/JSON/CSV export.
pub struct SimPanel {
    tab: Tab,
    tactor: tactor::TactorView,
    sweep: sweep::SweepView,
    waves: waves::WaveView,
    twopoint: two_point::TwoPointView,
    /// Where a relative export path is taken (the console sets `cfg.recent.base()` each frame).
    pub base: std::path::PathBuf,
}

impl Default for SimPanel {
    fn default() -> Self {
        Self::new()
    }
}

impl SimPanel {
    /// A panel with the command line's default inputs (thesis-sim preset, unencased, 3.3 V, b = 6.3e-8 N m s).
    pub fn new() -> Self {
        Self {
            tab: Tab::Tactor,
            tactor: tactor::TactorView::new(),
            sweep: sweep::SweepView::new(),
            waves: waves::WaveView::new(),
            twopoint: two_point::TwoPointView::new(),
            base: crate::file_dialog::documents_dir(),
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
            Tab::Tactor => self.tactor.ui(ui, &self.base),
            Tab::Sweep => {
                if let Some(damping_n_m_s) = self.sweep.ui(ui, &self.base) {
                    let (t, s) = (&mut self.tactor.inputs, &self.sweep.inputs);
                    t.damping_n_m_s = damping_n_m_s;
                    t.preset = s.preset;
                    t.voltage_v = s.voltage_v;
                    t.body = s.body;
                    t.radius_m = s.radius_m;
                    self.tab = Tab::Tactor;
                }
            }
            Tab::Waves => self.waves.ui(ui, &self.base),
            Tab::TwoPoint => self.twopoint.ui(ui, &self.base),
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use approx::assert_relative_eq;
    use egui_kittest::Harness;
    use egui_kittest::kittest::Queryable as _;

    use super::*;

    fn tmp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("vestnav-sim-panel-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn panel_renders_every_tab_without_blocking() {
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

    /// The console's Save buttons write exactly what `vestnav_report` makes of the same inputs, which is
    /// what `vestnav sim ...` prints and writes (tests/integration/sim_*.rs check the CLI side).
    #[test]
    fn save_buttons_write_the_report_of_the_shown_inputs() {
        let mut harness = Harness::new_ui_state(|ui, panel: &mut SimPanel| panel.ui(ui), SimPanel::new());
        harness.set_size(egui::vec2(1400.0, 1000.0));
        harness.state_mut().tactor.inputs.duration_s = 1.0;
        harness.run_steps(2);
        harness.state_mut().tactor.job.wait();
        harness.run_steps(2);
        let dir = tmp_dir("save");
        let path = dir.join("tactor-view");
        harness.state_mut().tactor.exporter.path = path.to_string_lossy().into_owned();
        harness.run_steps(1);
        for (button, ext) in [("Save JSON", "json"), ("Save PNG", "png")] {
            harness.get_by_label(button).click();
            harness.run_steps(2);
            harness.state_mut().tactor.exporter.wait();
            harness.run_steps(1);
            assert!(std::fs::metadata(path.with_extension(ext)).is_ok(), "{button} wrote nothing");
        }
        let inputs = harness.state().tactor.inputs;
        let runs = tactor::compute(&inputs).unwrap();
        let json = std::fs::read_to_string(path.with_extension("json")).unwrap();
        let want =
            vestnav_report::to_json(&vestnav_report::tactor::TactorReport::new(&runs.main.summary)).unwrap();
        assert_eq!(json, want);
        let png = std::fs::read(path.with_extension("png")).unwrap();
        let want = vestnav_report::tactor::tactor_figure(&runs, vestnav_report::tactor::DEFAULT_SPAN_S)
            .render_png()
            .unwrap();
        assert!(png == want, "the saved PNG is the report's figure");
    }

    #[test]
    fn calibrated_damping_goes_to_the_tactor_view() {
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
    }
}
