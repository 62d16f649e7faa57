//! The Field-test panel: the thesis's GPS accuracy tests (§5) as guided procedures on live fixes — a view
//! over the station's runs (`vestnav_core::fieldtest_live::FieldTests`, fed by the station with every fix
//! of whatever source runs: time base, walking detection, live pinning, source ended are core's).
//!
//! - **Drift test** (thesis Fig 65): the receiver lies still; Start records every fix until the duration target
//!   (default 3 min) is reached, Stop is pressed, or the source ends. Live: the distance of each fix from the
//!   first against time, the scatter in local metres about the mean with the CEP50/CEP95 circles, and max /
//!   CEP50 / CEP95 / DRMS / 2DRMS.
//! - **Cone test** (Figs 67–70): cones every `spacing` metres on a line (default 10 cones, 10 m); the operator
//!   walks the line and presses **Mark cone N** (or the key **M**) at each cone. The panel returns
//!   [`FieldTestAction::Mark`] so the app logs the mark, and shows the consecutive distances, their mean, the
//!   RMSE against the spacing and the along-/cross-line components.
//!
//! - **Reference and accuracy test** (issue 27, `reference` module): the truth typed, from a GPX waypoint or
//!   averaged from good fixes, with its stated uncertainty; the **Accuracy test** measures every fix against
//!   it (bias, CEP50/CEP95, 2DRMS, R95, shares within 0.1–5 m, vertical error), and with a reference set the
//!   drift and cone tests show their statistics against it too. The station's field tests compute all of it.
//!
//! The panel says which clock a test is on (the receiver's UTC time, or arrival when the receiver sends
//! none), warns in amber while a drift test's receiver moves at walking pace, and when the receiver looks
//! pinned (`SiRF` Star III static navigation holds the position below about 1.2 m/s, physics.md §5).
//!
//! **Cone count.** While a cone test runs the panel counts marks ("3 of 10 cones marked"); whether a cone
//! was missed or marked twice is judged only when the test is finished.
//!
//! **Exports.** The drift and cone tests each have their own export path (`vestnav-drift.*`,
//! `vestnav-cones.*`), a relative one taken in the console's files folder (`~/Documents/vestnav`) and
//! shown as the absolute path it uses, **Browse…** for the desktop's save dialog; an export
//! never replaces an existing file silently: the panel asks "Replace X?" first (**Replace** / **Cancel**).
//! The sheets shown and exported and the JSON reports come from `vestnav_report::fieldtest` and
//! `vestnav_report::accuracy`, the same as `vestnav fieldtest drift|cones|accuracy [--reference ...]
//! --png/--json` write for the same fixes (`vestnav-accuracy.*` for the accuracy test).

use std::path::PathBuf;

use vestnav_core::fieldtest::{ConeStats, DAY_S};
use vestnav_core::fieldtest_live::{FieldTests, Phase, Procedure};
use vestnav_core::geo::Earth;
use vestnav_report::Figure;
use vestnav_report::accuracy::{AgainstReference, CONES_AGAINST_LABEL, DRIFT_AGAINST_LABEL};
use vestnav_report::fieldtest::{ConesReport, DriftReport, Source, drift_rows};

use crate::export::{ExportFormat, ExportRequest, Exporter};
use crate::sim_panel::figure_grid;

mod receivers;
mod reference;

pub use receivers::ReceiversView;
pub use reference::ReferenceForm;

/// Default export path of the drift test (the extension follows the format).
pub const DRIFT_EXPORT_PATH: &str = "vestnav-drift.json";
/// Default export path of the cone test (the extension follows the format).
pub const CONES_EXPORT_PATH: &str = "vestnav-cones.json";
/// Default export path of the accuracy test (the extension follows the format).
pub const ACCURACY_EXPORT_PATH: &str = "vestnav-accuracy.json";

/// What the operator did in the panel that the app must act on.
#[derive(Debug, Clone, PartialEq)]
pub enum FieldTestAction {
    /// The operator marked a cone (already recorded by the test): the app logs it in the session log.
    Mark {
        /// Label of the mark, `"cone N"` (N counts from 1).
        label: String,
    },
}

/// Drift-test fixes the map draws at most (the newest).
pub const MAP_DRIFT_POINTS: usize = 5000;

/// The field tests' view: which procedure is shown, the cached sheet, the exports.
pub struct FieldTestPanel {
    procedure: Procedure,
    plots: Option<(PlotKey, Figure)>,
    /// The drift test's export path and state.
    drift_exporter: Exporter,
    /// The cone test's export path and state.
    cones_exporter: Exporter,
    /// The accuracy test's export path and state.
    accuracy_exporter: Exporter,
    /// The reference being entered.
    pub reference: ReferenceForm,
    /// Compare receivers is shown instead of a procedure.
    pub comparing: bool,
    /// Compare receivers: the source being typed and the cached sheet.
    pub receivers: ReceiversView,
    /// Where a relative export path is taken (the console sets `cfg.recent.base()` each frame).
    pub base: PathBuf,
}

/// What the cached plots were derived from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct PlotKey {
    procedure: Procedure,
    revision: u64,
}

impl Default for FieldTestPanel {
    fn default() -> Self {
        Self::new()
    }
}

/// A phase in words.
fn phase_text(p: &Phase) -> String {
    match p {
        Phase::Idle => "idle".into(),
        Phase::Running => "recording".into(),
        Phase::Done => "done".into(),
        Phase::Ended(why) => format!("ended: {why}"),
    }
}

impl FieldTestPanel {
    /// An idle view: drift test shown.
    pub fn new() -> Self {
        Self {
            procedure: Procedure::Drift,
            plots: None,
            drift_exporter: Exporter::new(DRIFT_EXPORT_PATH, "Export the drift test to"),
            cones_exporter: Exporter::new(CONES_EXPORT_PATH, "Export the cone test to"),
            accuracy_exporter: Exporter::new(ACCURACY_EXPORT_PATH, "Export the accuracy test to"),
            reference: ReferenceForm::default(),
            comparing: false,
            receivers: ReceiversView::default(),
            base: crate::file_dialog::documents_dir(),
        }
    }

    /// What the map draws: the reference whenever one is set, and while a test runs the cone test's marks
    /// and the drift test's newest fixes (at most [`MAP_DRIFT_POINTS`]).
    pub fn map_overlay(t: &FieldTests) -> crate::map_tools::FieldOverlay {
        let mut o = crate::map_tools::FieldOverlay {
            reference: t.reference().map(crate::map_tools::ReferenceMark::of),
            ..crate::map_tools::FieldOverlay::default()
        };
        if t.cones.phase == Phase::Running {
            o.cones = t.cones.marks.iter().map(|m| (m.label.clone(), m.pos)).collect();
        }
        if t.drift.phase == Phase::Running {
            let f = t.drift.recording().fixes();
            o.drift = f[f.len().saturating_sub(MAP_DRIFT_POINTS)..].iter().map(|f| f.pos).collect();
        }
        o
    }

    /// Draws the station's field tests `t`; returns an action when the operator marked a cone (button or
    /// key M; the mark is already recorded by the test).
    pub fn ui(&mut self, t: &mut FieldTests, ui: &mut egui::Ui) -> Option<FieldTestAction> {
        let mut action = None;
        // Wrapped: at 1024 px the distance choice goes to a second line rather than past the window's edge.
        ui.horizontal_wrapped(|ui| {
            for (p, label) in [
                (Procedure::Drift, "Drift test"),
                (Procedure::Cones, "Cone test"),
                (Procedure::Accuracy, "Accuracy test"),
            ] {
                if ui.selectable_label(!self.comparing && self.procedure == p, label).clicked() {
                    self.procedure = p;
                    self.comparing = false;
                }
            }
            if ui.selectable_label(self.comparing, "Compare receivers").clicked() {
                self.comparing = true;
            }
            ui.separator();
            ui.label("distances:");
            let before = t.earth;
            ui.radio_value(&mut t.earth, Earth::Wgs84, "WGS-84 geodesic");
            ui.radio_value(&mut t.earth, Earth::ThesisSphere, "thesis sphere (haversine)");
            if before != t.earth {
                t.recompute();
            }
        });
        ui.horizontal(|ui| {
            match t.latest() {
                Some(l) => ui.label(format!(
                    "latest fix: {}, arrived at t = {:.1} s, {:.7}°, {:.7}°{}",
                    l.tod_s.map_or_else(|| "no receiver time".to_owned(), utc_of_day),
                    l.fix.t_s,
                    l.fix.pos.lat_deg,
                    l.fix.pos.lon_deg,
                    l.speed_m_s.map_or(String::new(), |s| format!(", {s:.2} m/s"))
                )),
                None => ui.label("no fix yet: connect a GPS (or the simulator) first"),
            };
            if t.rejected > 0 {
                ui.weak(format!("({} invalid or out-of-order fixes ignored)", t.rejected));
            }
        });
        if let Some(w) = t.live_pinning_warning(self.procedure) {
            ui.colored_label(ui.visuals().warn_fg_color, format!("Warning: {w}"));
        }
        let base = self.base.clone();
        self.reference.ui(t, ui, &base);
        ui.separator();
        if self.comparing {
            // The console draws the receivers (`ReceiversView::ui`): they are the station's, not the tests'.
            return action;
        }
        match self.procedure {
            Procedure::Drift => self.drift_ui(t, ui),
            Procedure::Cones => action = self.cones_ui(t, ui),
            Procedure::Accuracy => self.accuracy_ui(t, ui),
        }
        action
    }

    fn drift_ui(&mut self, t: &mut FieldTests, ui: &mut egui::Ui) {
        ui.label(
            "Lay the receiver still with a clear sky view, press Start and wait. The thesis recorded 3 min \
             (max 1.17 m from the first fix).",
        );
        ui.horizontal(|ui| {
            let mut minutes = t.drift.target_s / 60.0;
            let name = ui.label("duration target");
            ui.add_enabled(
                t.drift.phase != Phase::Running,
                egui::DragValue::new(&mut minutes).range(0.5..=60.0).speed(0.1).suffix(" min"),
            )
            .labelled_by(name.id);
            t.drift.target_s = minutes * 60.0;
            match &t.drift.phase {
                Phase::Running => {
                    if ui.button("Stop").clicked() {
                        t.stop_drift();
                    }
                }
                Phase::Idle | Phase::Done | Phase::Ended(_) => {
                    let label = if t.drift.phase == Phase::Idle { "Start drift test" } else { "Start again" };
                    if ui.add_enabled(t.latest().is_some(), egui::Button::new(label)).clicked() {
                        t.start_drift();
                    }
                }
            }
            let frac = (t.drift.elapsed_s() / t.drift.target_s).clamp(0.0, 1.0) as f32;
            ui.add(egui::ProgressBar::new(frac).desired_width(200.0).text(format!(
                "{:.0} / {:.0} s",
                t.drift.elapsed_s(),
                t.drift.target_s
            )));
            let phase = phase_text(&t.drift.phase);
            if matches!(t.drift.phase, Phase::Ended(_)) {
                ui.colored_label(ui.visuals().warn_fg_color, phase);
            } else {
                ui.label(phase);
            }
        });
        if let Some(clock) = t.drift.recording().clock() {
            ui.label(format!("time base: {}", clock.describe()));
        }
        let amber = ui.visuals().warn_fg_color;
        if let Some(v) = t.drift.walking_now_m_s {
            ui.label(
                egui::RichText::new(format!(
                    "Warning: the receiver is moving at {v:.1} m/s (walking speed) during a stationary drift \
                     test: put it down and start again"
                ))
                .color(amber)
                .strong()
                .size(16.0),
            );
        } else if let Some((at_s, v)) = t.drift.walked {
            ui.label(
                egui::RichText::new(format!(
                    "Warning: the receiver moved at {v:.1} m/s (walking speed) {at_s:.0} s into this test: \
                     the figures are not those of a stationary receiver"
                ))
                .color(amber)
                .strong(),
            );
        }
        if let Some(e) = &t.drift.error {
            ui.colored_label(ui.visuals().error_fg_color, e);
        }
        if let Some(s) = &t.drift.stats {
            ui.strong(format!("{} fixes over {:.0} s", s.fixes, s.duration_s));
            egui::Grid::new("fieldtest-drift-stats").striped(true).show(ui, |ui| {
                for (name, value) in drift_rows(s) {
                    ui.label(name);
                    ui.monospace(value);
                    ui.end_row();
                }
            });
            for w in &s.warnings {
                ui.colored_label(ui.visuals().warn_fg_color, format!("Warning: {w}"));
            }
        }
        reference::against_ui(ui, "fieldtest-drift-against", DRIFT_AGAINST_LABEL, t.drift.against.as_ref());
        self.export_and_plots(t, ui);
    }

    fn cones_ui(&mut self, t: &mut FieldTests, ui: &mut egui::Ui) -> Option<FieldTestAction> {
        ui.label(
            "Lay the cones on a line, walk it briskly (above ~1.2 m/s) and press Mark (or the key M) at each cone.",
        );
        let running = t.cones.phase == Phase::Running;
        ui.add_enabled_ui(!running, |ui| {
            ui.horizontal(|ui| {
                ui.add(
                    egui::DragValue::new(&mut t.cones.spacing_m)
                        .range(0.5..=1000.0)
                        .speed(0.1)
                        .prefix("spacing ")
                        .suffix(" m"),
                );
                ui.add(egui::DragValue::new(&mut t.cones.count).range(2..=200).prefix("cones "));
                ui.checkbox(&mut t.cones.use_bearing, "line bearing (true)");
                ui.add_enabled(
                    t.cones.use_bearing,
                    egui::DragValue::new(&mut t.cones.bearing_deg).range(0.0..=360.0).speed(0.5).suffix("°"),
                );
                if !t.cones.use_bearing {
                    ui.weak("(else: first to last mark)");
                }
            });
        });
        let mut action = None;
        ui.horizontal(|ui| {
            if running {
                let n = t.cones.marks.len() + 1;
                let big =
                    egui::Button::new(egui::RichText::new(format!("Mark cone {n}  [M]")).size(22.0).strong())
                        .min_size(egui::vec2(220.0, 48.0));
                if ui.add_enabled(t.latest().is_some(), big).clicked() {
                    action = t.mark_cone().map(|label| FieldTestAction::Mark { label });
                }
                if ui.button("Finish").clicked() {
                    t.finish_cones();
                }
                // A live count, not a verdict: the count is checked when the test is finished.
                ui.label(format!("{} of {} cones marked", t.cones.marks.len(), t.cones.count));
            } else {
                let label = if t.cones.phase == Phase::Idle { "Start cone test" } else { "Start again" };
                if ui.add_enabled(t.latest().is_some(), egui::Button::new(label)).clicked() {
                    t.start_cones();
                }
                if let Phase::Ended(why) = t.cones.phase {
                    ui.colored_label(ui.visuals().warn_fg_color, format!("ended: {why}"));
                }
            }
        });
        if running
            && action.is_none()
            && !ui.ctx().egui_wants_keyboard_input()
            && ui.input(|i| i.key_pressed(egui::Key::M))
        {
            action = t.mark_cone().map(|label| FieldTestAction::Mark { label });
        }
        if running && t.cones.marks.len() == t.cones.count {
            ui.colored_label(ui.visuals().hyperlink_color, "All cones marked: press Finish.");
        }
        if let Some(clock) = t.cones.recording().clock() {
            ui.label(format!("time base: {}", clock.describe()));
        }
        if let Some(e) = &t.cones.error {
            ui.colored_label(ui.visuals().error_fg_color, e);
        }
        if let Some(s) = &t.cones.stats {
            cone_stats_ui(ui, s);
        } else if running {
            ui.label(format!("{} mark(s): statistics appear from the second mark.", t.cones.marks.len()));
        }
        reference::against_ui(ui, "fieldtest-cones-against", CONES_AGAINST_LABEL, t.cones.against.as_ref());
        self.export_and_plots(t, ui);
        action
    }

    /// The current procedure's sheet, rebuilt when its data changed.
    fn figure(&mut self, t: &FieldTests) -> &Figure {
        let key = PlotKey {
            procedure: self.procedure,
            revision: match self.procedure {
                Procedure::Drift => t.drift.revision,
                Procedure::Cones => t.cones.revision,
                Procedure::Accuracy => t.accuracy.revision,
            },
        };
        if self.plots.as_ref().is_none_or(|(k, _)| *k != key) {
            // The reports' own sheets: the same as `vestnav fieldtest ... --png` draws for these fixes.
            let figure = match self.procedure {
                Procedure::Drift => match Self::drift_against(t) {
                    Some(both) => both.figure(DriftReport::figure, DRIFT_AGAINST_LABEL),
                    None => Self::drift_report(t).figure(),
                },
                Procedure::Cones => match Self::cones_against(t) {
                    Some(both) => both.figure(ConesReport::figure, CONES_AGAINST_LABEL),
                    None => Self::cones_report(t).figure(),
                },
                Procedure::Accuracy => reference::accuracy_report(t).map_or_else(Figure::new, |r| r.figure()),
            };
            self.plots = Some((key, figure));
        }
        &self.plots.get_or_insert_with(|| (key, Figure::new())).1
    }

    /// The drift test's report.
    fn drift_report(t: &FieldTests) -> DriftReport {
        let stats = match (&t.drift.stats, &t.drift.error) {
            (Some(s), _) => Ok(s.clone()),
            (None, e) => Err(e.clone().unwrap_or_else(|| "no fixes recorded".to_string())),
        };
        let mut report = DriftReport::new(
            Source::live(),
            t.earth,
            Some(t.drift.target_s),
            stats,
            t.drift.recording().fixes(),
        );
        report.clock = t.drift.recording().clock().map(|c| c.key().to_owned());
        report
    }

    /// The cone test's report.
    fn cones_report(t: &FieldTests) -> ConesReport {
        let stats = match (&t.cones.stats, &t.cones.error) {
            (Some(s), _) => Some(Ok(s.clone())),
            (None, Some(e)) => Some(Err(e.clone())),
            (None, None) => None,
        };
        ConesReport::new(
            Source::live(),
            t.cones.config(t.earth),
            None,
            stats,
            &t.cones.marks,
            t.cones.recording().fixes(),
        )
    }

    /// The drift report with its statistics against the reference, when one is set.
    fn drift_against(t: &FieldTests) -> Option<AgainstReference<DriftReport>> {
        let r = t.reference()?;
        let stats = t.drift.against.clone().unwrap_or_else(|| Err("no fixes recorded".to_string()));
        Some(AgainstReference::new(Self::drift_report(t), r.clone(), stats))
    }

    /// The cone report with the marks against their cones, when a reference is set.
    fn cones_against(t: &FieldTests) -> Option<AgainstReference<ConesReport>> {
        let r = t.reference()?;
        let stats = t.cones.against.clone().unwrap_or_else(|| Err("no cone statistics".to_string()));
        Some(AgainstReference::new(Self::cones_report(t), r.clone(), stats))
    }

    /// The JSON report of the current procedure (with `reference_point` and `against_reference` when a
    /// reference is set, as `vestnav fieldtest drift|cones --reference` writes it).
    fn report_json(&self, t: &FieldTests) -> Result<Vec<u8>, String> {
        let text = match self.procedure {
            Procedure::Drift => match Self::drift_against(t) {
                Some(both) => vestnav_report::to_json(&both),
                None => vestnav_report::to_json(&Self::drift_report(t)),
            },
            Procedure::Cones => match Self::cones_against(t) {
                Some(both) => vestnav_report::to_json(&both),
                None => vestnav_report::to_json(&Self::cones_report(t)),
            },
            Procedure::Accuracy => match reference::accuracy_report(t) {
                Some(r) => vestnav_report::to_json(&r),
                None => return Err("no reference set".to_string()),
            },
        };
        text.map(String::into_bytes).map_err(|e| format!("cannot encode the report: {e}"))
    }

    fn export_and_plots(&mut self, t: &FieldTests, ui: &mut egui::Ui) {
        let procedure = self.procedure;
        let has_data = match procedure {
            Procedure::Drift => !t.drift.recording().is_empty(),
            Procedure::Cones => !t.cones.recording().is_empty() || !t.cones.marks.is_empty(),
            Procedure::Accuracy => !t.accuracy.recording().is_empty(),
        };
        if !has_data {
            return;
        }
        let base = self.base.clone();
        if let Some(request) =
            self.exporter_mut(procedure).ui(ui, &[ExportFormat::Json, ExportFormat::Png], &base)
        {
            self.start_export(t, ui.ctx(), request);
        }
        let id = match procedure {
            Procedure::Drift => "fieldtest-drift",
            Procedure::Cones => "fieldtest-cones",
            Procedure::Accuracy => "fieldtest-accuracy",
        };
        let figure = self.figure(t).clone();
        egui::ScrollArea::vertical().id_salt(id).show(ui, |ui| figure_grid(ui, id, &figure, 260.0));
    }

    fn exporter_mut(&mut self, procedure: Procedure) -> &mut Exporter {
        match procedure {
            Procedure::Drift => &mut self.drift_exporter,
            Procedure::Cones => &mut self.cones_exporter,
            Procedure::Accuracy => &mut self.accuracy_exporter,
        }
    }

    /// Writes the current procedure's export the operator asked for on the exporter's thread.
    fn start_export(&mut self, t: &FieldTests, ctx: &egui::Context, request: ExportRequest) {
        let bytes: Box<dyn FnOnce() -> Result<Vec<u8>, String> + Send> = match request.format {
            ExportFormat::Json => {
                let json = self.report_json(t);
                Box::new(move || json)
            }
            ExportFormat::Png | ExportFormat::Csv => {
                let figure = self.figure(t).clone();
                Box::new(move || figure.render_png().map_err(|e| format!("cannot render the figure: {e}")))
            }
        };
        self.exporter_mut(self.procedure).start(ctx, request, bytes);
    }
}

/// A UTC time of day [s] as `hh:mm:ss.s UTC`.
fn utc_of_day(tod_s: f64) -> String {
    let t = tod_s.rem_euclid(DAY_S);
    let (h, m, s) = ((t / 3600.0).floor(), ((t % 3600.0) / 60.0).floor(), t % 60.0);
    format!("{h:02.0}:{m:02.0}:{s:04.1} UTC")
}

/// The cone statistics: summary line, consecutive distances table and warnings.
fn cone_stats_ui(ui: &mut egui::Ui, s: &ConeStats) {
    ui.horizontal_wrapped(|ui| {
        ui.label(format!(
            "mean {:.2} m; RMSE vs {} m: {:.2} m; range {:.2}..{:.2} m; along-line RMSE {:.2} m; \
                 cross-line RMS {:.2} m; line bearing {:.1}°",
            s.mean_m,
            crate::sim_panel::sig(s.spacing_m, 4),
            s.rmse_m,
            s.min_m,
            s.max_m,
            s.along_rmse_m,
            s.cross_rms_m,
            s.line_bearing_deg
        ));
    });
    egui::CollapsingHeader::new("Consecutive distances").default_open(true).show(ui, |ui| {
        egui::Grid::new("fieldtest-cone-distances").striped(true).show(ui, |ui| {
            ui.strong("from -> to");
            ui.strong("distance [m]");
            ui.strong("along [m]");
            ui.strong("cross [m]");
            ui.end_row();
            for (k, d) in s.distances_m.iter().enumerate() {
                let from = s.labels.get(k).map_or("?", String::as_str);
                let to = s.labels.get(k + 1).map_or("?", String::as_str);
                ui.label(format!("{from} -> {to}"));
                ui.monospace(format!("{d:.2}"));
                ui.monospace(format!("{:.2}", s.along_m.get(k).copied().unwrap_or(f64::NAN)));
                ui.monospace(format!("{:.2}", s.cross_m.get(k).copied().unwrap_or(f64::NAN)));
                ui.end_row();
            }
        });
    });
    for w in &s.warnings {
        ui.colored_label(ui.visuals().warn_fg_color, format!("Warning: {w}"));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use vestnav_core::geo::LatLon;

    const C: LatLon = LatLon::new(42.3575, -71.1010);

    /// A point `along_m` metres north of C and `east_m` east of that (WGS-84 geodesics).
    fn at(along_m: f64, east_m: f64) -> LatLon {
        let p = Earth::Wgs84.direct(C, 0.0, along_m);
        Earth::Wgs84.direct(p, 90.0, east_m)
    }

    fn push(t: &mut FieldTests, t_s: f64, p: LatLon, speed: Option<f64>) {
        t.push(t_s, None, p.lat_deg, p.lon_deg, speed);
    }

    #[test]
    fn cone_marks_give_consecutive_distances_mean_and_rmse() {
        let panel = FieldTestPanel { procedure: Procedure::Cones, ..FieldTestPanel::new() };
        let mut t = FieldTests::new();
        assert_eq!(t.mark_cone(), None, "no test running");
        push(&mut t, 0.0, at(0.0, 0.0), Some(1.5));
        t.start_cones();
        // Cones reached at 0, 10, 22 and 30 m along the line: distances 10, 12, 8.
        let mut s_t = 0.0;
        let mut labels = Vec::new();
        for along in [0.0, 10.0, 22.0, 30.0] {
            s_t += 7.0;
            push(&mut t, s_t, at(along, 0.0), Some(1.5));
            labels.push(t.mark_cone().expect("mark refused"));
        }
        assert_eq!(labels, ["cone 1", "cone 2", "cone 3", "cone 4"]);
        let s = t.cones.stats.as_ref().unwrap();
        for (d, want) in s.distances_m.iter().zip([10.0, 12.0, 8.0]) {
            assert_relative_eq!(*d, want, max_relative = 1e-9);
        }
        assert_relative_eq!(s.mean_m, 10.0, max_relative = 1e-9);
        assert_relative_eq!(s.rmse_m, (8.0_f64 / 3.0).sqrt(), max_relative = 1e-9);
        assert_relative_eq!(s.line_bearing_deg, 0.0, epsilon = 1e-6);
        assert!(s.cross_m.iter().all(|c| c.abs() < 1e-6));
        assert!(s.warnings.iter().all(|w| !w.contains("missed")), "{:?}", s.warnings);
        // The last cone marked 3 m east (right of the northward line), line bearing fixed at 0 degrees.
        t.cones.use_bearing = true;
        t.cones.marks.last_mut().unwrap().pos = at(30.0, 3.0);
        t.update_cone_stats();
        let s = t.cones.stats.as_ref().unwrap();
        assert_relative_eq!(s.cross_m[2], 3.0, max_relative = 1e-6);
        assert_relative_eq!(s.along_m[2], 8.0, max_relative = 1e-6);
        t.finish_cones();
        assert_eq!(t.mark_cone(), None, "finished");
        let s = t.cones.stats.as_ref().unwrap();
        assert!(s.warnings.iter().any(|w| w.contains("4 marks for 10 cones")), "{:?}", s.warnings);
        let json: serde_json::Value = serde_json::from_slice(&panel.report_json(&t).unwrap()).unwrap();
        assert_eq!(json["test"], "cones");
        assert_eq!(json["cone_marks"].as_array().unwrap().len(), 4);
        assert_eq!(json["distances_m"].as_array().unwrap().len(), 3);
        let back: ConesReport = serde_json::from_slice(&panel.report_json(&t).unwrap()).unwrap();
        let labels: Vec<&str> = back.cone_marks.iter().map(|m| m.label.as_str()).collect();
        assert_eq!(labels, ["cone 1", "cone 2", "cone 3", "cone 4"]);
    }

    #[test]
    fn drift_test_stops_at_its_target_and_matches_a_circle() {
        let mut panel = FieldTestPanel::new();
        let mut t = FieldTests::new();
        push(&mut t, 100.0, C, None);
        t.start_drift();
        // One fix per second on a 2 m circle about C for 3 min: CEP50 = DRMS = 2 m about the mean; the
        // farthest fix from the first is across, 4 m.
        for k in 0..=200 {
            let p = Earth::Wgs84.direct(C, 10.0 * f64::from(k), 2.0);
            push(&mut t, 101.0 + f64::from(k), p, Some(0.0));
        }
        assert_eq!(t.drift.phase, Phase::Done);
        assert_eq!(t.drift.recording().fixes().len(), 181, "recording stops at the 3 min target");
        let s = t.drift.stats.as_ref().unwrap();
        assert_relative_eq!(s.duration_s, 180.0);
        assert_relative_eq!(s.cep50_m, 2.0, max_relative = 1e-3);
        assert_relative_eq!(s.max_from_first_m, 4.0, max_relative = 1e-6);
        let cep50 = s.cep50_m;
        let Some(vestnav_plot::Panel::Chart(scatter)) = panel.figure(&t).panels.get(1) else {
            panic!("chart expected")
        };
        assert_eq!(scatter.circles.len(), 3, "CEP50, CEP95, 2DRMS");
        assert_relative_eq!(scatter.circles[0].r, cep50);
        let json: serde_json::Value = serde_json::from_slice(&panel.report_json(&t).unwrap()).unwrap();
        assert_eq!(json["test"], "drift");
        assert_eq!(json["fixes"], 181);
        assert_eq!(json["clock"], "arrival");
    }

    #[test]
    fn mark_button_and_key_return_the_action() {
        use egui_kittest::Harness;
        use egui_kittest::kittest::Queryable as _;
        let mut t = FieldTests::new();
        push(&mut t, 0.0, C, Some(1.5));
        let mut harness = Harness::new_ui_state(
            |ui, state: &mut (FieldTestPanel, FieldTests, Vec<FieldTestAction>)| {
                if let Some(a) = state.0.ui(&mut state.1, ui) {
                    state.2.push(a);
                }
            },
            (FieldTestPanel::new(), t, Vec::new()),
        );
        harness.set_size(egui::vec2(1200.0, 900.0));
        harness.run();
        harness.get_by_label("Cone test").click();
        harness.run();
        harness.get_by_label("Start cone test").click();
        harness.run();
        harness.get_by_label_contains("Mark cone 1").click();
        harness.run();
        push(&mut harness.state_mut().1, 7.0, at(10.0, 0.0), Some(1.5));
        harness.key_press(egui::Key::M);
        harness.run();
        let labels: Vec<String> =
            harness.state().2.iter().map(|FieldTestAction::Mark { label }| label.clone()).collect();
        assert_eq!(labels, ["cone 1", "cone 2"]);
        assert_relative_eq!(
            harness.state().1.cones.stats.as_ref().unwrap().distances_m[0],
            10.0,
            max_relative = 1e-9
        );
    }

    /// Issue 23 item 6: a drift test whose source ended says so in the panel.
    #[test]
    fn an_ended_source_shows_on_the_drift_test() {
        use egui_kittest::Harness;
        use egui_kittest::kittest::Queryable as _;
        let mut t = FieldTests::new();
        push(&mut t, 0.0, C, None);
        t.start_drift();
        push(&mut t, 1.0, C, None);
        t.source_ended();
        let mut h = Harness::new_ui_state(
            |ui, s: &mut (FieldTestPanel, FieldTests)| {
                let _ = s.0.ui(&mut s.1, ui);
            },
            (FieldTestPanel::new(), t),
        );
        h.set_size(egui::vec2(1200.0, 900.0));
        h.run();
        assert!(h.query_by_label("ended: source ended").is_some());
        assert!(h.query_by_label("Start again").is_some());
    }

    /// Issue 15 fault 4: drift and cone exports have their own paths, and an existing file is kept until
    /// the operator answers **Replace** to "Replace X?".
    #[test]
    fn exports_have_separate_paths_and_ask_before_overwriting() {
        use egui_kittest::Harness;
        use egui_kittest::kittest::Queryable as _;
        let mut panel = FieldTestPanel::new();
        assert_ne!(
            panel.drift_exporter.target(ExportFormat::Json, &panel.base),
            panel.cones_exporter.target(ExportFormat::Json, &panel.base)
        );
        let dir = std::env::temp_dir().join(format!("vestnav-ft-export-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("drift.json");
        std::fs::write(&path, "keep me").unwrap();
        panel.drift_exporter.path = path.display().to_string();
        let mut t = FieldTests::new();
        push(&mut t, 0.0, C, None);
        t.start_drift();
        push(&mut t, 1.0, C, None);
        push(&mut t, 2.0, C, None);
        let mut h = Harness::new_ui_state(
            |ui, s: &mut (FieldTestPanel, FieldTests)| {
                let _ = s.0.ui(&mut s.1, ui);
            },
            (panel, t),
        );
        h.set_size(egui::vec2(1200.0, 900.0));
        h.run();
        let question = format!("Replace {}?", path.display());
        h.get_by_label("Save JSON").click();
        h.run();
        assert!(h.query_by_label(&question).is_some());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "keep me");
        h.get_by_label("Cancel").click();
        h.run();
        assert!(h.query_by_label(&question).is_none());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "keep me");
        h.get_by_label("Save JSON").click();
        h.run();
        h.get_by_label("Replace").click();
        h.step(); // the export runs on its thread (a spinner keeps repainting)
        h.state_mut().0.drift_exporter.wait();
        let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        assert_eq!(json["test"], "drift");
        assert_eq!(json["fixes"], 2);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
