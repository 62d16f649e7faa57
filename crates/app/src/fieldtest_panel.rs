//! The Field-test panel: the thesis's GPS accuracy tests (§5) as guided procedures on live fixes.
//!
//! - **Drift test** (thesis Fig 65): the receiver lies still; Start records every fix until the duration target
//!   (default 3 min) is reached or Stop is pressed. Live: the distance of each fix from the first against time,
//!   the scatter in local metres about the mean with the CEP50/CEP95 circles, and max / CEP50 / CEP95 / DRMS /
//!   2DRMS.
//! - **Cone test** (Figs 67–70): cones every `spacing` metres on a line (default 10 cones, 10 m); the operator
//!   walks the line and presses **Mark cone N** (or the key **M**) at each cone. The panel returns
//!   [`FieldTestAction::Mark`] so the app logs the mark, and shows the consecutive distances, their mean, the
//!   RMSE against the spacing and the along-/cross-line components.
//!
//! Both warn when the receiver looks pinned: `SiRF` Star III "static navigation" holds the position while the
//! speed is below about 1.2 m/s (physics.md §5), which flatters a drift test and distorts cone marks.
//! Statistics come from `vestnav_core::fieldtest`, geodesy from `vestnav_core::geo`; the sheets shown and
//! exported and the JSON reports come from `vestnav_report::fieldtest`, the same as `vestnav fieldtest drift|
//! cones --png/--json` write for the same fixes.

use vestnav_core::fieldtest::{self, ConeConfig, ConeMark, ConeStats, DriftStats, TimedFix};
use vestnav_core::geo::{Earth, LatLon};
use vestnav_report::Figure;
use vestnav_report::fieldtest::{ConesReport, DriftReport, Source, cones_figure, drift_figure, drift_rows};

use crate::sim_panel::{ExportFormat, Exporter, figure_grid};

/// Speed below which `SiRF` Star III static navigation may pin the position [m/s] (physics.md §5).
pub const STATIC_NAV_SPEED_M_S: f64 = 1.2;
/// Default drift-test duration [s] (thesis: 3 min).
pub const DEFAULT_DRIFT_TARGET_S: f64 = 180.0;
/// Default nominal cone spacing [m] (thesis: 10 m).
pub const DEFAULT_CONE_SPACING_M: f64 = 10.0;
/// Default number of cones (thesis: 10).
pub const DEFAULT_CONE_COUNT: usize = 10;
/// Identical consecutive fixes for this long while walking raise the live pinning warning [s].
const LIVE_PINNED_RUN_S: f64 = 5.0;

/// What the operator did in the panel that the app must act on.
#[derive(Debug, Clone, PartialEq)]
pub enum FieldTestAction {
    /// The operator marked a cone: the app logs it in the session log.
    Mark {
        /// Label of the mark, `"cone N"` (N counts from 1).
        label: String,
    },
}

/// Which procedure the panel shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Procedure {
    Drift,
    Cones,
}

/// Where a procedure is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Not started (or reset).
    Idle,
    /// Recording fixes.
    Running,
    /// Stopped; results frozen until a new run starts.
    Done,
}

/// Stationary drift test state.
struct DriftTest {
    phase: Phase,
    target_s: f64,
    fixes: Vec<TimedFix>,
    stats: Option<DriftStats>,
    error: Option<String>,
    /// Bumped whenever `fixes` changes; derived plots are cached per revision.
    revision: u64,
}

impl DriftTest {
    fn new() -> Self {
        Self {
            phase: Phase::Idle,
            target_s: DEFAULT_DRIFT_TARGET_S,
            fixes: Vec::new(),
            stats: None,
            error: None,
            revision: 0,
        }
    }

    fn elapsed_s(&self) -> f64 {
        match (self.fixes.first(), self.fixes.last()) {
            (Some(a), Some(b)) => b.t_s - a.t_s,
            _ => 0.0,
        }
    }
}

/// Cone test state.
struct ConeTest {
    phase: Phase,
    spacing_m: f64,
    count: usize,
    /// Use a typed true bearing for the line instead of the first-to-last mark direction.
    use_bearing: bool,
    bearing_deg: f64,
    track: Vec<TimedFix>,
    marks: Vec<ConeMark>,
    stats: Option<ConeStats>,
    error: Option<String>,
    revision: u64,
}

impl ConeTest {
    fn new() -> Self {
        Self {
            phase: Phase::Idle,
            spacing_m: DEFAULT_CONE_SPACING_M,
            count: DEFAULT_CONE_COUNT,
            use_bearing: false,
            bearing_deg: 0.0,
            track: Vec::new(),
            marks: Vec::new(),
            stats: None,
            error: None,
            revision: 0,
        }
    }

    fn config(&self, earth: Earth) -> ConeConfig {
        ConeConfig {
            count: Some(self.count),
            line_bearing_deg: self.use_bearing.then_some(self.bearing_deg),
            earth,
            ..ConeConfig::with_spacing(self.spacing_m)
        }
    }
}

/// The latest fix the panel was given.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Latest {
    fix: TimedFix,
    speed_m_s: Option<f64>,
}

/// Guided drift and cone tests fed with every GPS fix.
pub struct FieldTestPanel {
    procedure: Procedure,
    earth: Earth,
    latest: Option<Latest>,
    /// Fixes refused: non-finite or out-of-range coordinates, or time going backwards.
    rejected: usize,
    drift: DriftTest,
    cones: ConeTest,
    plots: Option<(PlotKey, Figure)>,
    exporter: Exporter,
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

impl FieldTestPanel {
    /// An idle panel: drift test selected, WGS-84 distances, thesis defaults (3 min; 10 cones, 10 m).
    pub fn new() -> Self {
        Self {
            procedure: Procedure::Drift,
            earth: Earth::Wgs84,
            latest: None,
            rejected: 0,
            drift: DriftTest::new(),
            cones: ConeTest::new(),
            plots: None,
            exporter: Exporter::new("vestnav-fieldtest.json"),
        }
    }

    /// Feeds one fix: time [s] (any origin, increasing), WGS-84 latitude/longitude [deg], speed over ground
    /// [m/s] if known. Call it for every fix; a running test records it. Fixes with non-finite or
    /// out-of-range coordinates, or a time earlier than the previous fix, are counted and ignored.
    pub fn push_position(&mut self, t_s: f64, lat_deg: f64, lon_deg: f64, speed_m_s: Option<f64>) {
        let Ok(pos) = LatLon::new(lat_deg, lon_deg).validated() else {
            self.rejected += 1;
            return;
        };
        if !t_s.is_finite() || self.latest.is_some_and(|l| t_s < l.fix.t_s) {
            self.rejected += 1;
            return;
        }
        let fix = TimedFix { t_s, pos };
        self.latest = Some(Latest { fix, speed_m_s: speed_m_s.filter(|s| s.is_finite() && *s >= 0.0) });
        if self.drift.phase == Phase::Running {
            self.drift.fixes.push(fix);
            self.drift.revision += 1;
            self.update_drift_stats();
            if self.drift.elapsed_s() >= self.drift.target_s {
                self.drift.phase = Phase::Done;
            }
        }
        if self.cones.phase == Phase::Running {
            self.cones.track.push(fix);
            self.cones.revision += 1;
            self.update_cone_stats();
        }
    }

    fn update_drift_stats(&mut self) {
        match fieldtest::drift(&self.drift.fixes, self.earth) {
            Ok(s) => {
                self.drift.stats = Some(s);
                self.drift.error = None;
            }
            Err(e) => {
                self.drift.stats = None;
                self.drift.error = Some(e.to_string());
            }
        }
    }

    fn update_cone_stats(&mut self) {
        if self.cones.marks.len() < 2 {
            self.cones.stats = None;
            self.cones.error = None;
            return;
        }
        match fieldtest::cones(&self.cones.marks, &self.cones.track, &self.cones.config(self.earth)) {
            Ok(s) => {
                self.cones.stats = Some(s);
                self.cones.error = None;
            }
            Err(e) => {
                self.cones.stats = None;
                self.cones.error = Some(e.to_string());
            }
        }
    }

    /// Starts a new drift test (discarding the previous one).
    fn start_drift(&mut self) {
        self.drift.phase = Phase::Running;
        self.drift.fixes.clear();
        self.drift.stats = None;
        self.drift.error = None;
        self.drift.revision += 1;
    }

    /// Stops the drift test; its results stay shown.
    fn stop_drift(&mut self) {
        if self.drift.phase == Phase::Running {
            self.drift.phase = Phase::Done;
        }
    }

    /// Starts a new cone test (discarding the previous one).
    fn start_cones(&mut self) {
        self.cones.phase = Phase::Running;
        self.cones.track.clear();
        self.cones.marks.clear();
        self.cones.stats = None;
        self.cones.error = None;
        self.cones.revision += 1;
    }

    /// Ends the cone test; its results stay shown.
    fn finish_cones(&mut self) {
        if self.cones.phase == Phase::Running {
            self.cones.phase = Phase::Done;
        }
    }

    /// Marks the next cone at the latest fix. `None` when no test runs or no fix has arrived yet.
    fn mark_cone(&mut self) -> Option<FieldTestAction> {
        if self.cones.phase != Phase::Running {
            return None;
        }
        let latest = self.latest?;
        let label = format!("cone {}", self.cones.marks.len() + 1);
        let pos = fieldtest::position_at(&self.cones.track, latest.fix.t_s).unwrap_or(latest.fix.pos);
        self.cones.marks.push(ConeMark { t_s: latest.fix.t_s, label: label.clone(), pos });
        self.cones.revision += 1;
        self.update_cone_stats();
        Some(FieldTestAction::Mark { label })
    }

    /// The live pinning hint: a run of identical fixes during the last seconds, or a speed below the `SiRF`
    /// static-navigation threshold while a cone test runs.
    fn live_pinning_warning(&self) -> Option<String> {
        let (track, what) = match self.procedure {
            Procedure::Drift => (&self.drift.fixes, "drift test"),
            Procedure::Cones => (&self.cones.track, "cone test"),
        };
        let last = track.last()?;
        let start = track.iter().rposition(|f| last.t_s - f.t_s > 30.0).map_or(0, |i| i + 1);
        let pin = fieldtest::pinning(&track[start..]);
        let ongoing = (pin.longest_run_start_s + pin.longest_run_s - last.t_s).abs() < 1e-6;
        if ongoing && pin.longest_run_s >= LIVE_PINNED_RUN_S {
            return Some(format!(
                "{what}: the receiver has repeated one position for {:.0} s — it looks pinned (SiRF static \
                 navigation)",
                pin.longest_run_s
            ));
        }
        if self.procedure == Procedure::Cones
            && let Some(speed) = self.latest.and_then(|l| l.speed_m_s)
            && speed < STATIC_NAV_SPEED_M_S
            && self.cones.phase == Phase::Running
        {
            return Some(format!(
                "speed {speed:.2} m/s is below ~{STATIC_NAV_SPEED_M_S} m/s: SiRF static navigation may pin the \
                 position — walk briskly between cones"
            ));
        }
        None
    }

    /// Draws the panel; returns an action when the operator marked a cone (button or key M).
    pub fn ui(&mut self, ui: &mut egui::Ui) -> Option<FieldTestAction> {
        let mut action = None;
        ui.horizontal(|ui| {
            ui.selectable_value(&mut self.procedure, Procedure::Drift, "Drift test");
            ui.selectable_value(&mut self.procedure, Procedure::Cones, "Cone test");
            ui.separator();
            ui.label("distances:");
            let before = self.earth;
            ui.radio_value(&mut self.earth, Earth::Wgs84, "WGS-84 geodesic");
            ui.radio_value(&mut self.earth, Earth::ThesisSphere, "thesis sphere (haversine)");
            if before != self.earth {
                self.update_drift_stats_if_any();
                self.update_cone_stats();
                self.drift.revision += 1;
                self.cones.revision += 1;
            }
        });
        ui.horizontal(|ui| {
            match self.latest {
                Some(l) => ui.label(format!(
                    "latest fix: t = {:.1} s, {:.7}°, {:.7}°{}",
                    l.fix.t_s,
                    l.fix.pos.lat_deg,
                    l.fix.pos.lon_deg,
                    l.speed_m_s.map_or(String::new(), |s| format!(", {s:.2} m/s"))
                )),
                None => ui.label("no fix yet: connect a GPS (or the simulator) first"),
            };
            if self.rejected > 0 {
                ui.weak(format!("({} invalid or out-of-order fixes ignored)", self.rejected));
            }
        });
        if let Some(w) = self.live_pinning_warning() {
            ui.colored_label(ui.visuals().warn_fg_color, format!("Warning: {w}"));
        }
        ui.separator();
        match self.procedure {
            Procedure::Drift => self.drift_ui(ui),
            Procedure::Cones => action = self.cones_ui(ui),
        }
        action
    }

    fn update_drift_stats_if_any(&mut self) {
        if !self.drift.fixes.is_empty() {
            self.update_drift_stats();
        }
    }

    fn drift_ui(&mut self, ui: &mut egui::Ui) {
        ui.label(
            "Lay the receiver still with a clear sky view, press Start and wait. The thesis recorded 3 min \
             (max 1.17 m from the first fix).",
        );
        ui.horizontal(|ui| {
            let mut minutes = self.drift.target_s / 60.0;
            ui.add_enabled(
                self.drift.phase != Phase::Running,
                egui::DragValue::new(&mut minutes)
                    .range(0.5..=60.0)
                    .speed(0.1)
                    .suffix(" min")
                    .prefix("target "),
            );
            self.drift.target_s = minutes * 60.0;
            match self.drift.phase {
                Phase::Running => {
                    if ui.button("Stop").clicked() {
                        self.stop_drift();
                    }
                }
                Phase::Idle | Phase::Done => {
                    let label =
                        if self.drift.phase == Phase::Idle { "Start drift test" } else { "Start again" };
                    if ui.add_enabled(self.latest.is_some(), egui::Button::new(label)).clicked() {
                        self.start_drift();
                    }
                }
            }
            let frac = (self.drift.elapsed_s() / self.drift.target_s).clamp(0.0, 1.0) as f32;
            ui.add(egui::ProgressBar::new(frac).desired_width(200.0).text(format!(
                "{:.0} / {:.0} s",
                self.drift.elapsed_s(),
                self.drift.target_s
            )));
            ui.label(match self.drift.phase {
                Phase::Idle => "idle",
                Phase::Running => "recording",
                Phase::Done => "done",
            });
        });
        if let Some(e) = &self.drift.error {
            ui.colored_label(ui.visuals().error_fg_color, e);
        }
        if let Some(s) = &self.drift.stats {
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
        self.export_and_plots(ui);
    }

    fn cones_ui(&mut self, ui: &mut egui::Ui) -> Option<FieldTestAction> {
        ui.label(
            "Lay the cones on a line, walk it briskly (above ~1.2 m/s) and press Mark (or the key M) at each cone.",
        );
        let running = self.cones.phase == Phase::Running;
        ui.add_enabled_ui(!running, |ui| {
            ui.horizontal(|ui| {
                ui.add(
                    egui::DragValue::new(&mut self.cones.spacing_m)
                        .range(0.5..=1000.0)
                        .speed(0.1)
                        .prefix("spacing ")
                        .suffix(" m"),
                );
                ui.add(egui::DragValue::new(&mut self.cones.count).range(2..=200).prefix("cones "));
                ui.checkbox(&mut self.cones.use_bearing, "line bearing (true)");
                ui.add_enabled(
                    self.cones.use_bearing,
                    egui::DragValue::new(&mut self.cones.bearing_deg)
                        .range(0.0..=360.0)
                        .speed(0.5)
                        .suffix("°"),
                );
                if !self.cones.use_bearing {
                    ui.weak("(else: first to last mark)");
                }
            });
        });
        let mut action = None;
        ui.horizontal(|ui| {
            if running {
                let n = self.cones.marks.len() + 1;
                let big =
                    egui::Button::new(egui::RichText::new(format!("Mark cone {n}  [M]")).size(22.0).strong())
                        .min_size(egui::vec2(220.0, 48.0));
                if ui.add_enabled(self.latest.is_some(), big).clicked() {
                    action = self.mark_cone();
                }
                if ui.button("Finish").clicked() {
                    self.finish_cones();
                }
                ui.label(format!("{} of {} cones marked", self.cones.marks.len(), self.cones.count));
            } else {
                let label = if self.cones.phase == Phase::Idle { "Start cone test" } else { "Start again" };
                if ui.add_enabled(self.latest.is_some(), egui::Button::new(label)).clicked() {
                    self.start_cones();
                }
            }
        });
        if running
            && action.is_none()
            && !ui.ctx().egui_wants_keyboard_input()
            && ui.input(|i| i.key_pressed(egui::Key::M))
        {
            action = self.mark_cone();
        }
        if running && self.cones.marks.len() == self.cones.count {
            ui.colored_label(ui.visuals().hyperlink_color, "All cones marked: press Finish.");
        }
        if let Some(e) = &self.cones.error {
            ui.colored_label(ui.visuals().error_fg_color, e);
        }
        if let Some(s) = &self.cones.stats {
            cone_stats_ui(ui, s);
        } else if running {
            ui.label(format!("{} mark(s): statistics appear from the second mark.", self.cones.marks.len()));
        }
        self.export_and_plots(ui);
        action
    }

    /// The current procedure's sheet, rebuilt when its data changed.
    fn figure(&mut self) -> &Figure {
        let key = PlotKey {
            procedure: self.procedure,
            revision: match self.procedure {
                Procedure::Drift => self.drift.revision,
                Procedure::Cones => self.cones.revision,
            },
        };
        if self.plots.as_ref().is_none_or(|(k, _)| *k != key) {
            let figure = match self.procedure {
                Procedure::Drift => self.drift.stats.as_ref().map_or_else(Figure::new, drift_figure),
                Procedure::Cones => {
                    cones_figure(self.cones.stats.as_ref(), &self.cones.marks, &self.cones.track, self.earth)
                }
            };
            self.plots = Some((key, figure));
        }
        &self.plots.get_or_insert_with(|| (key, Figure::new())).1
    }

    /// The drift test's report.
    fn drift_report(&self) -> DriftReport {
        let stats = match (&self.drift.stats, &self.drift.error) {
            (Some(s), _) => Ok(s.clone()),
            (None, e) => Err(e.clone().unwrap_or_else(|| "no fixes recorded".to_string())),
        };
        DriftReport::new(Source::live(), self.earth, Some(self.drift.target_s), stats, &self.drift.fixes)
    }

    /// The cone test's report.
    fn cones_report(&self) -> ConesReport {
        let stats = match (&self.cones.stats, &self.cones.error) {
            (Some(s), _) => Some(Ok(s.clone())),
            (None, Some(e)) => Some(Err(e.clone())),
            (None, None) => None,
        };
        ConesReport::new(
            Source::live(),
            self.cones.config(self.earth),
            None,
            stats,
            &self.cones.marks,
            &self.cones.track,
        )
    }

    /// The JSON report of the current procedure.
    fn report_json(&self) -> Result<Vec<u8>, String> {
        let text = match self.procedure {
            Procedure::Drift => vestnav_report::to_json(&self.drift_report()),
            Procedure::Cones => vestnav_report::to_json(&self.cones_report()),
        };
        text.map(String::into_bytes).map_err(|e| format!("cannot encode the report: {e}"))
    }

    fn export_and_plots(&mut self, ui: &mut egui::Ui) {
        let has_data = match self.procedure {
            Procedure::Drift => !self.drift.fixes.is_empty(),
            Procedure::Cones => !self.cones.track.is_empty() || !self.cones.marks.is_empty(),
        };
        if !has_data {
            return;
        }
        if let Some(format) = self.exporter.ui(ui, &[ExportFormat::Json, ExportFormat::Png]) {
            let ctx = ui.ctx().clone();
            match format {
                ExportFormat::Json => {
                    let json = self.report_json();
                    self.exporter.start(&ctx, format, move || json);
                }
                ExportFormat::Png | ExportFormat::Csv => {
                    let figure = self.figure().clone();
                    self.exporter.start(&ctx, ExportFormat::Png, move || {
                        figure.render_png().map_err(|e| format!("cannot render the figure: {e}"))
                    });
                }
            }
        }
        let id = match self.procedure {
            Procedure::Drift => "fieldtest-drift",
            Procedure::Cones => "fieldtest-cones",
        };
        let figure = self.figure().clone();
        egui::ScrollArea::vertical().id_salt(id).show(ui, |ui| figure_grid(ui, id, &figure, 260.0));
    }
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

    const C: LatLon = LatLon::new(42.3575, -71.1010);

    /// A point `along_m` metres north of C and `east_m` east of that (WGS-84 geodesics).
    fn at(along_m: f64, east_m: f64) -> LatLon {
        let p = Earth::Wgs84.direct(C, 0.0, along_m);
        Earth::Wgs84.direct(p, 90.0, east_m)
    }

    fn push(panel: &mut FieldTestPanel, t_s: f64, p: LatLon, speed: Option<f64>) {
        panel.push_position(t_s, p.lat_deg, p.lon_deg, speed);
    }

    #[test]
    fn cone_marks_give_consecutive_distances_mean_and_rmse() {
        let mut panel = FieldTestPanel::new();
        assert_eq!(panel.mark_cone(), None, "no test running");
        push(&mut panel, 0.0, at(0.0, 0.0), Some(1.5));
        panel.start_cones();
        // Cones reached at 0, 10, 22 and 30 m along the line: distances 10, 12, 8.
        let mut t = 0.0;
        let mut labels = Vec::new();
        for along in [0.0, 10.0, 22.0, 30.0] {
            t += 7.0;
            push(&mut panel, t, at(along, 0.0), Some(1.5));
            match panel.mark_cone() {
                Some(FieldTestAction::Mark { label }) => labels.push(label),
                None => panic!("mark refused"),
            }
        }
        assert_eq!(labels, ["cone 1", "cone 2", "cone 3", "cone 4"]);
        let s = panel.cones.stats.as_ref().unwrap();
        for (d, want) in s.distances_m.iter().zip([10.0, 12.0, 8.0]) {
            assert_relative_eq!(*d, want, max_relative = 1e-9);
        }
        assert_relative_eq!(s.mean_m, 10.0, max_relative = 1e-9);
        assert_relative_eq!(s.rmse_m, (8.0_f64 / 3.0).sqrt(), max_relative = 1e-9);
        // The line runs north: the components are all along-line.
        assert_relative_eq!(s.line_bearing_deg, 0.0, epsilon = 1e-6);
        assert!(s.cross_m.iter().all(|c| c.abs() < 1e-6));
        assert!(s.warnings.iter().any(|w| w.contains("4 marks for 10 cones")), "{:?}", s.warnings);
        // The last cone marked 3 m east (right of the northward line), line bearing fixed at 0 degrees.
        panel.cones.use_bearing = true;
        panel.cones.marks.last_mut().unwrap().pos = at(30.0, 3.0);
        panel.update_cone_stats();
        let s = panel.cones.stats.as_ref().unwrap();
        assert_relative_eq!(s.cross_m[2], 3.0, max_relative = 1e-6); // east of a northward line = right
        assert_relative_eq!(s.along_m[2], 8.0, max_relative = 1e-6);
        panel.finish_cones();
        assert_eq!(panel.mark_cone(), None, "finished");
        // The JSON report carries the statistics and the marks.
        panel.procedure = Procedure::Cones;
        let json: serde_json::Value = serde_json::from_slice(&panel.report_json().unwrap()).unwrap();
        assert_eq!(json["test"], "cones");
        assert_eq!(json["cone_marks"].as_array().unwrap().len(), 4);
        assert_eq!(json["marks"], 4);
        assert_eq!(json["distances_m"].as_array().unwrap().len(), 3);
        assert_eq!(json["config"]["spacing_m"], 10.0);
        // The report round-trips through its schema.
        let back: ConesReport = serde_json::from_slice(&panel.report_json().unwrap()).unwrap();
        let labels: Vec<&str> = back.cone_marks.iter().map(|m| m.label.as_str()).collect();
        assert_eq!(labels, ["cone 1", "cone 2", "cone 3", "cone 4"]);
        let rmse = panel.cones.stats.as_ref().unwrap().rmse_m;
        assert_relative_eq!(back.stats.unwrap().rmse_m, rmse, max_relative = 1e-12);
    }

    #[test]
    fn drift_test_stops_at_its_target_and_matches_a_circle() {
        let mut panel = FieldTestPanel::new();
        push(&mut panel, 100.0, C, None);
        panel.start_drift();
        // One fix per second on a 2 m circle about C for 3 min: CEP50 = CEP95 = DRMS = 2 m about the mean
        // (the mean of a full circle is its centre); the farthest fix from the first is across, 4 m.
        for k in 0..=200 {
            let p = Earth::Wgs84.direct(C, 10.0 * f64::from(k), 2.0);
            push(&mut panel, 101.0 + f64::from(k), p, Some(0.0));
        }
        assert_eq!(panel.drift.phase, Phase::Done);
        assert_eq!(panel.drift.fixes.len(), 181, "recording stops at the 3 min target");
        let s = panel.drift.stats.as_ref().unwrap();
        assert_relative_eq!(s.duration_s, 180.0);
        assert_relative_eq!(s.cep50_m, 2.0, max_relative = 1e-3);
        assert_relative_eq!(s.drms_m, 2.0, max_relative = 1e-3);
        assert_relative_eq!(s.max_from_first_m, 4.0, max_relative = 1e-6);
        let cep50 = s.cep50_m;
        panel.procedure = Procedure::Drift;
        let Some(vestnav_plot::Panel::Chart(scatter)) = panel.figure().panels.get(1) else {
            panic!("chart expected")
        };
        assert_eq!(scatter.circles.len(), 3, "CEP50, CEP95, 2DRMS");
        assert_relative_eq!(scatter.circles[0].r, cep50);
        let json: serde_json::Value = serde_json::from_slice(&panel.report_json().unwrap()).unwrap();
        assert_eq!(json["test"], "drift");
        assert_eq!(json["fixes"], 181);
        assert_eq!(json["track"].as_array().unwrap().len(), 181);
        assert!(json["cep95_m"].is_number() && json["twodrms_m"].is_number());
    }

    #[test]
    fn hostile_fixes_are_ignored() {
        let mut panel = FieldTestPanel::new();
        panel.push_position(f64::NAN, 42.0, -71.0, None);
        panel.push_position(1.0, f64::NAN, -71.0, None);
        panel.push_position(1.0, 95.0, -71.0, None);
        panel.push_position(1.0, 42.0, f64::INFINITY, None);
        assert!(panel.latest.is_none());
        panel.push_position(5.0, 42.0, -71.0, Some(f64::NAN));
        panel.push_position(4.0, 42.0, -71.0, None);
        assert_eq!(panel.rejected, 5);
        assert_eq!(panel.latest.unwrap().speed_m_s, None);
    }

    #[test]
    fn pinned_receiver_raises_the_live_warning() {
        let mut panel = FieldTestPanel::new();
        panel.procedure = Procedure::Cones;
        push(&mut panel, 0.0, C, Some(1.5));
        panel.start_cones();
        for k in 1..=4 {
            push(&mut panel, f64::from(k), at(1.5 * f64::from(k), 0.0), Some(1.5));
        }
        assert_eq!(panel.live_pinning_warning(), None);
        for k in 5..=12 {
            push(&mut panel, f64::from(k), at(6.0, 0.0), Some(1.5));
        }
        assert!(panel.live_pinning_warning().is_some_and(|w| w.contains("pinned")));
        push(&mut panel, 13.0, at(8.0, 0.0), Some(0.6));
        assert!(panel.live_pinning_warning().is_some_and(|w| w.contains("static navigation")));
    }

    #[test]
    fn mark_button_and_key_return_the_action() {
        use egui_kittest::Harness;
        use egui_kittest::kittest::Queryable as _;
        let mut panel = FieldTestPanel::new();
        push(&mut panel, 0.0, C, Some(1.5));
        let mut harness = Harness::new_ui_state(
            |ui, state: &mut (FieldTestPanel, Vec<FieldTestAction>)| {
                if let Some(a) = state.0.ui(ui) {
                    state.1.push(a);
                }
            },
            (panel, Vec::new()),
        );
        harness.set_size(egui::vec2(1200.0, 900.0));
        harness.run();
        harness.get_by_label("Cone test").click();
        harness.run();
        harness.get_by_label("Start cone test").click();
        harness.run();
        harness.get_by_label_contains("Mark cone 1").click();
        harness.run();
        push(&mut harness.state_mut().0, 7.0, at(10.0, 0.0), Some(1.5));
        harness.key_press(egui::Key::M);
        harness.run();
        let labels: Vec<String> =
            harness.state().1.iter().map(|FieldTestAction::Mark { label }| label.clone()).collect();
        assert_eq!(labels, ["cone 1", "cone 2"]);
        assert_relative_eq!(
            harness.state().0.cones.stats.as_ref().unwrap().distances_m[0],
            10.0,
            max_relative = 1e-9
        );
    }
}
