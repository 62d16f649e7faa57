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
//! **Time base.** Both tests run on the receiver's clock: the UTC time of day of each fix (`Fix::time_of_day`,
//! unwrapped across midnight), so replaying a log at x10 still reports "201 fixes over 200 s". Only when the
//! receiver sends no time are the fixes' arrival instants at the console used instead (a test falls back to
//! them for good as soon as one of its fixes has no receiver time). The panel says which clock a test is on.
//!
//! **Moving during a drift test.** A drift test is for a receiver lying still; the panel warns in amber while
//! the receiver moves at walking speed, and keeps a note that it did: either the reported speed over ground
//! is at least [`WALKING_SPEED_M_S`] on every fix of the last [`WALK_SUSTAIN_S`] s, or the straight-line
//! displacement over the last [`WALK_WINDOW_S`] s is at least that speed times the window (a walker's
//! progress, well above the noise of a still receiver, which wanders a few decimetres in a few seconds).
//!
//! **Cone count.** While a cone test runs the panel counts marks ("3 of 10 cones marked"); whether a cone
//! was missed or marked twice is judged only when the test is finished.
//!
//! **Exports.** The drift and cone tests each have their own export path (`vestnav-drift.*`,
//! `vestnav-cones.*`), a relative one taken in the console's files folder (`~/Documents/vestnav`) and
//! shown as the absolute path it uses, **Browse…** for the desktop's save dialog; an export
//! never replaces an existing file silently: the panel asks "Replace X?" first (**Replace** / **Cancel**).
//!
//! Both warn when the receiver looks pinned: `SiRF` Star III "static navigation" holds the position while the
//! speed is below about 1.2 m/s (physics.md §5), which flatters a drift test and distorts cone marks.
//! Statistics come from `vestnav_core::fieldtest`, geodesy from `vestnav_core::geo`; the sheets shown and
//! exported and the JSON reports come from `vestnav_report::fieldtest`, the same as `vestnav fieldtest drift|
//! cones --png/--json` write for the same fixes.

use std::path::PathBuf;

use chrono::Timelike as _;
use vestnav_core::fieldtest::{self, ConeConfig, ConeMark, ConeStats, DriftStats, TimedFix};
use vestnav_core::geo::{Earth, LatLon};
use vestnav_device::gps::Fix;
use vestnav_report::Figure;
use vestnav_report::fieldtest::{ConesReport, DriftReport, Source, cones_figure, drift_figure, drift_rows};

use crate::export::{ExportFormat, ExportRequest, Exporter};
use crate::sim_panel::figure_grid;

/// Speed below which `SiRF` Star III static navigation may pin the position [m/s] (physics.md §5).
pub const STATIC_NAV_SPEED_M_S: f64 = 1.2;
/// Default drift-test duration [s] (thesis: 3 min).
pub const DEFAULT_DRIFT_TARGET_S: f64 = 180.0;
/// Default export path of the drift test (the extension follows the format).
pub const DRIFT_EXPORT_PATH: &str = "vestnav-drift.json";
/// Default export path of the cone test (the extension follows the format).
pub const CONES_EXPORT_PATH: &str = "vestnav-cones.json";
/// Default nominal cone spacing [m] (thesis: 10 m).
pub const DEFAULT_CONE_SPACING_M: f64 = 10.0;
/// Default number of cones (thesis: 10).
pub const DEFAULT_CONE_COUNT: usize = 10;
/// Identical consecutive fixes for this long while walking raise the live pinning warning [s].
const LIVE_PINNED_RUN_S: f64 = 5.0;
/// Speed at or above which a "stationary" receiver is taken to be carried at walking pace [m/s] (a slow
/// walk is about 1 m/s; a still receiver's reported speed stays below ~0.2 m/s).
pub const WALKING_SPEED_M_S: f64 = 0.5;
/// The reported speed must stay at or above [`WALKING_SPEED_M_S`] this long to warn [s].
pub const WALK_SUSTAIN_S: f64 = 3.0;
/// Window of the displacement check [s]: moving `WALKING_SPEED_M_S * WALK_WINDOW_S` (2.5 m) in it warns.
pub const WALK_WINDOW_S: f64 = 5.0;
/// Seconds in a day, for unwrapping the receiver's time of day across midnight.
const DAY_S: f64 = 86_400.0;

/// The clock a test's times are on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Clock {
    /// The receiver's UTC time of each fix.
    Receiver,
    /// The instant each fix arrived at the console (the receiver sends no time).
    Arrival,
}

impl Clock {
    /// How the panel names it.
    pub fn describe(self) -> &'static str {
        match self {
            Clock::Receiver => "receiver UTC time of each fix",
            Clock::Arrival => {
                "arrival time at the console (the receiver sends no time: a faster-than-real-time replay \
                 shortens durations)"
            }
        }
    }

    /// Short name, as written in the JSON report's `clock`.
    pub fn key(self) -> &'static str {
        match self {
            Clock::Receiver => "receiver",
            Clock::Arrival => "arrival",
        }
    }
}

/// One fix as the panel received it: both clocks, position and speed.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sample {
    /// Arrival time at the console [s].
    arrival_s: f64,
    /// Receiver UTC time of day, unwrapped across midnight [s], when the receiver sent one.
    receiver_s: Option<f64>,
    pos: LatLon,
    speed_m_s: Option<f64>,
}

impl Sample {
    fn time_on(&self, clock: Clock) -> Option<f64> {
        match clock {
            Clock::Receiver => self.receiver_s,
            Clock::Arrival => Some(self.arrival_s),
        }
    }
}

/// The fixes of one test, with the times on the test's clock.
#[derive(Debug, Clone, Default)]
struct Recording {
    samples: Vec<Sample>,
    /// `None` before the first fix.
    clock: Option<Clock>,
    /// `samples` on `clock`.
    fixes: Vec<TimedFix>,
    /// The last receiver time of day seen [s] and the days added so far [s].
    last_tod_s: Option<f64>,
    day_offset_s: f64,
}

impl Recording {
    fn clear(&mut self) {
        *self = Self::default();
    }

    /// Records a fix (receiver time of day `tod_s` [s], if any). Returns `false`, recording nothing, when the
    /// fix's time on the test's clock is earlier than the previous fix's.
    fn push(&mut self, arrival_s: f64, tod_s: Option<f64>, pos: LatLon, speed_m_s: Option<f64>) -> bool {
        let receiver_s = tod_s.map(|tod| {
            // A time of day more than half a day earlier than the last one is the next day.
            if self.last_tod_s.is_some_and(|last| tod < last - DAY_S / 2.0) {
                self.day_offset_s += DAY_S;
            }
            self.last_tod_s = Some(tod);
            tod + self.day_offset_s
        });
        let sample = Sample { arrival_s, receiver_s, pos, speed_m_s };
        let clock = match (self.clock, receiver_s) {
            (None | Some(Clock::Receiver), Some(_)) => Clock::Receiver,
            _ => Clock::Arrival,
        };
        let Some(t_s) = sample.time_on(clock) else { return false };
        if self.clock != Some(clock) {
            self.clock = Some(clock);
            self.fixes = self
                .samples
                .iter()
                .filter_map(|s| s.time_on(clock).map(|t_s| TimedFix { t_s, pos: s.pos }))
                .collect();
        }
        if self.fixes.last().is_some_and(|l| t_s < l.t_s) {
            return false;
        }
        self.samples.push(sample);
        self.fixes.push(TimedFix { t_s, pos });
        true
    }

    fn elapsed_s(&self) -> f64 {
        match (self.fixes.first(), self.fixes.last()) {
            (Some(a), Some(b)) => b.t_s - a.t_s,
            _ => 0.0,
        }
    }

    fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The speed [m/s] at which the receiver is moving like a walker at the latest fix, if it is (see the
    /// module doc): the lowest reported speed over the last [`WALK_SUSTAIN_S`] s when all are at least
    /// [`WALKING_SPEED_M_S`], else the displacement over the last [`WALK_WINDOW_S`] s divided by its time.
    fn walking_speed_m_s(&self, earth: Earth) -> Option<f64> {
        let last = self.fixes.last()?;
        let mut slowest = f64::INFINITY;
        for (f, s) in self.fixes.iter().zip(&self.samples).rev() {
            match s.speed_m_s {
                Some(v) if v >= WALKING_SPEED_M_S => slowest = slowest.min(v),
                _ => break,
            }
            if last.t_s - f.t_s >= WALK_SUSTAIN_S {
                return Some(slowest);
            }
        }
        let before = self.fixes.iter().rev().find(|f| last.t_s - f.t_s >= WALK_WINDOW_S)?;
        let dt_s = last.t_s - before.t_s;
        let v = earth.distance_m(before.pos, last.pos) / dt_s;
        (v >= WALKING_SPEED_M_S).then_some(v)
    }
}

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
    rec: Recording,
    /// The walking speed [m/s] at the latest fix, when the receiver is moving like a walker.
    walking_now_m_s: Option<f64>,
    /// When (test time [s] from the first fix) and how fast the receiver first moved like a walker.
    walked: Option<(f64, f64)>,
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
            rec: Recording::default(),
            walking_now_m_s: None,
            walked: None,
            stats: None,
            error: None,
            revision: 0,
        }
    }

    fn elapsed_s(&self) -> f64 {
        self.rec.elapsed_s()
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
    rec: Recording,
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
            rec: Recording::default(),
            marks: Vec::new(),
            stats: None,
            error: None,
            revision: 0,
        }
    }

    /// The settings; the expected count is left out while the test runs (a missing mark is only a mistake
    /// once the operator has finished).
    fn config(&self, earth: Earth) -> ConeConfig {
        ConeConfig {
            count: (self.phase != Phase::Running).then_some(self.count),
            line_bearing_deg: self.use_bearing.then_some(self.bearing_deg),
            earth,
            ..ConeConfig::with_spacing(self.spacing_m)
        }
    }
}

/// The latest fix the panel was given.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Latest {
    /// Arrival time [s] and position.
    fix: TimedFix,
    /// Receiver UTC time of day [s], when sent.
    tod_s: Option<f64>,
    speed_m_s: Option<f64>,
}

/// Drift-test fixes the map draws at most (the newest).
pub const MAP_DRIFT_POINTS: usize = 5000;

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
    /// The drift test's export path and state.
    drift_exporter: Exporter,
    /// The cone test's export path and state.
    cones_exporter: Exporter,
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
            drift_exporter: Exporter::new(DRIFT_EXPORT_PATH, "Export the drift test to"),
            cones_exporter: Exporter::new(CONES_EXPORT_PATH, "Export the cone test to"),
            base: crate::file_dialog::documents_dir(),
        }
    }

    /// What the map draws while a test runs: the cone test's marks, the drift test's newest fixes (at most
    /// [`MAP_DRIFT_POINTS`]). Nothing for a test that is not running.
    pub fn map_overlay(&self) -> crate::map_tools::FieldOverlay {
        let mut o = crate::map_tools::FieldOverlay::default();
        if self.cones.phase == Phase::Running {
            o.cones = self.cones.marks.iter().map(|m| (m.label.clone(), m.pos)).collect();
        }
        if self.drift.phase == Phase::Running {
            let f = &self.drift.rec.fixes;
            o.drift = f[f.len().saturating_sub(MAP_DRIFT_POINTS)..].iter().map(|f| f.pos).collect();
        }
        o
    }

    /// Feeds one fix from the GPS: `arrival_s` is when it reached the console [s] (any origin, increasing);
    /// the receiver's UTC time of day comes from the fix (`time_of_day`, else `time`). Call it for every fix
    /// with a position; a running test records it. See [`Self::push_sample`] for what is refused.
    pub fn push_fix(&mut self, arrival_s: f64, fix: &Fix) {
        let (Some(lat), Some(lon)) = (fix.lat_deg, fix.lon_deg) else { return };
        let tod = fix.time_of_day.or_else(|| fix.time.map(|t| t.time()));
        let tod_s = tod.map(|t| f64::from(t.num_seconds_from_midnight()) + f64::from(t.nanosecond()) * 1e-9);
        self.push_sample(arrival_s, tod_s, lat, lon, fix.speed_m_s);
    }

    /// Feeds one fix: arrival time [s] (any origin, increasing), receiver UTC time of day [s] if sent,
    /// WGS-84 latitude/longitude [deg], speed over ground [m/s] if known. Fixes with non-finite or
    /// out-of-range coordinates, an arrival time earlier than the previous fix's, or a time earlier than the
    /// previous fix's on a running test's clock, are counted and ignored.
    fn push_sample(
        &mut self,
        arrival_s: f64,
        tod_s: Option<f64>,
        lat_deg: f64,
        lon_deg: f64,
        speed: Option<f64>,
    ) {
        let Ok(pos) = LatLon::new(lat_deg, lon_deg).validated() else {
            self.rejected += 1;
            return;
        };
        if !arrival_s.is_finite() || self.latest.is_some_and(|l| arrival_s < l.fix.t_s) {
            self.rejected += 1;
            return;
        }
        let tod_s = tod_s.filter(|t| t.is_finite() && (0.0..DAY_S + 1.0).contains(t));
        let speed_m_s = speed.filter(|s| s.is_finite() && *s >= 0.0);
        self.latest = Some(Latest { fix: TimedFix { t_s: arrival_s, pos }, tod_s, speed_m_s });
        let mut refused = false;
        if self.drift.phase == Phase::Running {
            if self.drift.rec.push(arrival_s, tod_s, pos, speed_m_s) {
                self.drift.revision += 1;
                self.update_drift_stats();
                self.drift.walking_now_m_s = self.drift.rec.walking_speed_m_s(self.earth);
                if let Some(v) = self.drift.walking_now_m_s
                    && self.drift.walked.is_none()
                {
                    self.drift.walked = Some((self.drift.elapsed_s(), v));
                }
                if self.drift.elapsed_s() >= self.drift.target_s {
                    self.drift.phase = Phase::Done;
                }
            } else {
                refused = true;
            }
        }
        if self.cones.phase == Phase::Running {
            if self.cones.rec.push(arrival_s, tod_s, pos, speed_m_s) {
                self.cones.revision += 1;
                self.update_cone_stats();
            } else {
                refused = true;
            }
        }
        if refused {
            self.rejected += 1;
        }
    }

    fn update_drift_stats(&mut self) {
        match fieldtest::drift(&self.drift.rec.fixes, self.earth) {
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
        match fieldtest::cones(&self.cones.marks, &self.cones.rec.fixes, &self.cones.config(self.earth)) {
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
        self.drift.rec.clear();
        self.drift.walking_now_m_s = None;
        self.drift.walked = None;
        self.drift.stats = None;
        self.drift.error = None;
        self.drift.revision += 1;
    }

    /// Stops the drift test; its results stay shown.
    fn stop_drift(&mut self) {
        if self.drift.phase == Phase::Running {
            self.drift.phase = Phase::Done;
            self.drift.walking_now_m_s = None;
        }
    }

    /// Starts a new cone test (discarding the previous one).
    fn start_cones(&mut self) {
        self.cones.phase = Phase::Running;
        self.cones.rec.clear();
        self.cones.marks.clear();
        self.cones.stats = None;
        self.cones.error = None;
        self.cones.revision += 1;
    }

    /// Ends the cone test; its results stay shown.
    fn finish_cones(&mut self) {
        if self.cones.phase == Phase::Running {
            self.cones.phase = Phase::Done;
            // Now the mark count is judged against the expected count.
            self.update_cone_stats();
            self.cones.revision += 1;
        }
    }

    /// Marks the next cone at the latest fix. `None` when no test runs or no fix has arrived yet.
    fn mark_cone(&mut self) -> Option<FieldTestAction> {
        if self.cones.phase != Phase::Running {
            return None;
        }
        // The mark is at the test's latest fix, on the test's clock.
        let at = self.cones.rec.fixes.last().copied().or_else(|| self.latest.map(|l| l.fix))?;
        let label = format!("cone {}", self.cones.marks.len() + 1);
        let pos = fieldtest::position_at(&self.cones.rec.fixes, at.t_s).unwrap_or(at.pos);
        self.cones.marks.push(ConeMark { t_s: at.t_s, label: label.clone(), pos });
        self.cones.revision += 1;
        self.update_cone_stats();
        Some(FieldTestAction::Mark { label })
    }

    /// The live pinning hint: a run of identical fixes during the last seconds, or a speed below the `SiRF`
    /// static-navigation threshold while a cone test runs.
    fn live_pinning_warning(&self) -> Option<String> {
        let (track, what) = match self.procedure {
            Procedure::Drift => (&self.drift.rec.fixes, "drift test"),
            Procedure::Cones => (&self.cones.rec.fixes, "cone test"),
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
                    "latest fix: {}, arrived at t = {:.1} s, {:.7}°, {:.7}°{}",
                    l.tod_s.map_or_else(|| "no receiver time".to_owned(), utc_of_day),
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
        if !self.drift.rec.is_empty() {
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
            let name = ui.label("duration target");
            ui.add_enabled(
                self.drift.phase != Phase::Running,
                egui::DragValue::new(&mut minutes).range(0.5..=60.0).speed(0.1).suffix(" min"),
            )
            .labelled_by(name.id);
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
        if let Some(clock) = self.drift.rec.clock {
            ui.label(format!("time base: {}", clock.describe()));
        }
        let amber = ui.visuals().warn_fg_color;
        if let Some(v) = self.drift.walking_now_m_s {
            ui.label(
                egui::RichText::new(format!(
                    "Warning: the receiver is moving at {v:.1} m/s (walking speed) during a stationary drift \
                     test: put it down and start again"
                ))
                .color(amber)
                .strong()
                .size(16.0),
            );
        } else if let Some((at_s, v)) = self.drift.walked {
            ui.label(
                egui::RichText::new(format!(
                    "Warning: the receiver moved at {v:.1} m/s (walking speed) {at_s:.0} s into this test: \
                     the figures are not those of a stationary receiver"
                ))
                .color(amber)
                .strong(),
            );
        }
        if let Some(e) = &self.drift.error {
            ui.colored_label(ui.visuals().error_fg_color, e);
        }
        if let Some(s) = &self.drift.stats {
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
                // A live count, not a verdict: the count is checked when the test is finished.
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
        if let Some(clock) = self.cones.rec.clock {
            ui.label(format!("time base: {}", clock.describe()));
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
                Procedure::Cones => cones_figure(
                    self.cones.stats.as_ref(),
                    &self.cones.marks,
                    &self.cones.rec.fixes,
                    self.earth,
                ),
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
        let mut report = DriftReport::new(
            Source::live(),
            self.earth,
            Some(self.drift.target_s),
            stats,
            &self.drift.rec.fixes,
        );
        report.clock = self.drift.rec.clock.map(|c| c.key().to_owned());
        report
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
            &self.cones.rec.fixes,
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
        let procedure = self.procedure;
        let has_data = match procedure {
            Procedure::Drift => !self.drift.rec.is_empty(),
            Procedure::Cones => !self.cones.rec.is_empty() || !self.cones.marks.is_empty(),
        };
        if !has_data {
            return;
        }
        let base = self.base.clone();
        if let Some(request) =
            self.exporter_mut(procedure).ui(ui, &[ExportFormat::Json, ExportFormat::Png], &base)
        {
            self.start_export(ui.ctx(), request);
        }
        let id = match procedure {
            Procedure::Drift => "fieldtest-drift",
            Procedure::Cones => "fieldtest-cones",
        };
        let figure = self.figure().clone();
        egui::ScrollArea::vertical().id_salt(id).show(ui, |ui| figure_grid(ui, id, &figure, 260.0));
    }

    fn exporter_mut(&mut self, procedure: Procedure) -> &mut Exporter {
        match procedure {
            Procedure::Drift => &mut self.drift_exporter,
            Procedure::Cones => &mut self.cones_exporter,
        }
    }

    /// Writes the current procedure's export the operator asked for on the exporter's thread.
    fn start_export(&mut self, ctx: &egui::Context, request: ExportRequest) {
        let bytes: Box<dyn FnOnce() -> Result<Vec<u8>, String> + Send> = match request.format {
            ExportFormat::Json => {
                let json = self.report_json();
                Box::new(move || json)
            }
            ExportFormat::Png | ExportFormat::Csv => {
                let figure = self.figure().clone();
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

    const C: LatLon = LatLon::new(42.3575, -71.1010);

    /// A point `along_m` metres north of C and `east_m` east of that (WGS-84 geodesics).
    fn at(along_m: f64, east_m: f64) -> LatLon {
        let p = Earth::Wgs84.direct(C, 0.0, along_m);
        Earth::Wgs84.direct(p, 90.0, east_m)
    }

    fn push(panel: &mut FieldTestPanel, t_s: f64, p: LatLon, speed: Option<f64>) {
        panel.push_sample(t_s, None, p.lat_deg, p.lon_deg, speed);
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
        assert!(
            s.warnings.iter().all(|w| !w.contains("missed")),
            "no verdict on the count while the test runs: {:?}",
            s.warnings
        );
        // The last cone marked 3 m east (right of the northward line), line bearing fixed at 0 degrees.
        panel.cones.use_bearing = true;
        panel.cones.marks.last_mut().unwrap().pos = at(30.0, 3.0);
        panel.update_cone_stats();
        let s = panel.cones.stats.as_ref().unwrap();
        assert_relative_eq!(s.cross_m[2], 3.0, max_relative = 1e-6); // east of a northward line = right
        assert_relative_eq!(s.along_m[2], 8.0, max_relative = 1e-6);
        panel.finish_cones();
        assert_eq!(panel.mark_cone(), None, "finished");
        let s = panel.cones.stats.as_ref().unwrap();
        assert!(s.warnings.iter().any(|w| w.contains("4 marks for 10 cones")), "{:?}", s.warnings);
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
        assert_eq!(panel.drift.rec.fixes.len(), 181, "recording stops at the 3 min target");
        assert_eq!(panel.drift.rec.clock, Some(Clock::Arrival), "no receiver time was given");
        assert_eq!(panel.drift.walked, None, "a 2 m circle at 0 m/s is not a walk");
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
        panel.push_sample(f64::NAN, None, 42.0, -71.0, None);
        panel.push_sample(1.0, None, f64::NAN, -71.0, None);
        panel.push_sample(1.0, None, 95.0, -71.0, None);
        panel.push_sample(1.0, None, 42.0, f64::INFINITY, None);
        assert!(panel.latest.is_none());
        panel.push_sample(5.0, Some(f64::NAN), 42.0, -71.0, Some(f64::NAN));
        panel.push_sample(4.0, None, 42.0, -71.0, None);
        assert_eq!(panel.rejected, 5);
        assert_eq!(panel.latest.unwrap().speed_m_s, None);
        assert_eq!(panel.latest.unwrap().tod_s, None, "a NaN receiver time is no time");
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
    /// Issue 15 fault 7: the drift test's time base is the receiver's UTC, not the arrival instants (a x10
    /// replay), across midnight too; a fix without receiver time puts the test on the arrival clock.
    #[test]
    fn drift_runs_on_the_receiver_clock() {
        let mut panel = FieldTestPanel::new();
        panel.drift.target_s = 300.0;
        let tod0 = DAY_S - 100.0; // midnight falls 100 s into the test
        panel.push_sample(0.0, Some(tod0), C.lat_deg, C.lon_deg, Some(0.0));
        panel.start_drift();
        for k in 0..=200 {
            let k = f64::from(k);
            panel.push_sample(0.1 * k, Some((tod0 + k) % DAY_S), C.lat_deg, C.lon_deg, Some(0.0));
        }
        assert_eq!(panel.drift.rec.clock, Some(Clock::Receiver));
        assert_eq!(panel.rejected, 0);
        let s = panel.drift.stats.as_ref().unwrap();
        assert_eq!(s.fixes, 201);
        assert_relative_eq!(s.duration_s, 200.0, max_relative = 1e-9);
        assert_eq!(panel.drift.phase, Phase::Running, "200 s of a 300 s target");
        panel.procedure = Procedure::Drift;
        let json: serde_json::Value = serde_json::from_slice(&panel.report_json().unwrap()).unwrap();
        assert_eq!(json["clock"], "receiver");
        assert_relative_eq!(json["duration_s"].as_f64().unwrap(), 200.0, max_relative = 1e-9);
        // The receiver stops sending time: the whole test is re-timed on arrival (0 .. 20.1 s).
        panel.push_sample(20.1, None, C.lat_deg, C.lon_deg, Some(0.0));
        assert_eq!(panel.drift.rec.clock, Some(Clock::Arrival));
        assert_relative_eq!(panel.drift.elapsed_s(), 20.1, max_relative = 1e-9);
    }

    /// Issue 15 fault 7: a receiver carried at walking pace during a drift test raises the warning, from
    /// the reported speed or, without one, from its displacement; a still receiver does not.
    #[test]
    fn a_walking_receiver_warns_during_a_drift_test() {
        for reports_speed in [true, false] {
            let mut panel = FieldTestPanel::new();
            let speed = |v: f64| reports_speed.then_some(v);
            panel.push_sample(0.0, Some(0.0), C.lat_deg, C.lon_deg, speed(0.0));
            panel.start_drift();
            // Still for 10 s (a few centimetres of noise).
            for k in 0..10 {
                let p = at(0.03 * f64::from(k % 3), 0.0);
                panel.push_sample(f64::from(k), Some(f64::from(k)), p.lat_deg, p.lon_deg, speed(0.05));
            }
            assert_eq!(panel.drift.walking_now_m_s, None, "a still receiver");
            // Carried north at 1.2 m/s for 8 s.
            for k in 1..=8 {
                let p = at(1.2 * f64::from(k), 0.0);
                let t = 9.0 + f64::from(k);
                panel.push_sample(t, Some(t), p.lat_deg, p.lon_deg, speed(1.2));
            }
            let v = panel.drift.walking_now_m_s.expect("walking warning");
            assert_relative_eq!(v, 1.2, max_relative = 0.01);
            assert!(panel.drift.walked.is_some());
            // Put down again: the live warning ends once the window has passed, the note stays.
            for k in 1..=8 {
                let p = at(9.6, 0.0);
                let t = 17.0 + f64::from(k);
                panel.push_sample(t, Some(t), p.lat_deg, p.lon_deg, speed(0.0));
            }
            assert_eq!(panel.drift.walking_now_m_s, None);
            assert!(panel.drift.walked.is_some_and(|(at_s, _)| at_s > 10.0 && at_s < 17.0));
        }
    }

    /// Issue 15 fault 4: drift and cone exports have their own paths, and an existing file is kept until
    /// the operator answers **Replace** to "Replace X?".
    #[test]
    fn exports_have_separate_paths_and_ask_before_overwriting() {
        use egui_kittest::Harness;
        use egui_kittest::kittest::Queryable as _;
        let panel = FieldTestPanel::new();
        assert_ne!(
            panel.drift_exporter.target(ExportFormat::Json, &panel.base),
            panel.cones_exporter.target(ExportFormat::Json, &panel.base)
        );
        let dir = std::env::temp_dir().join(format!("vestnav-ft-export-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("drift.json");
        std::fs::write(&path, "keep me").unwrap();
        let mut panel = panel;
        panel.drift_exporter.path = path.display().to_string();
        push(&mut panel, 0.0, C, None);
        panel.start_drift();
        push(&mut panel, 1.0, C, None);
        push(&mut panel, 2.0, C, None);
        let mut h = Harness::new_ui_state(
            |ui, p: &mut FieldTestPanel| {
                let _ = p.ui(ui);
            },
            panel,
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
        h.state_mut().drift_exporter.wait();
        let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        assert_eq!(json["test"], "drift");
        assert_eq!(json["fixes"], 2);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
