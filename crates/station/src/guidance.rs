//! The guidance worker: a thread that runs `vestnav_core::guidance::Guidance` on every fix and sends its cues
//! to the vest.
//!
//! It runs outside the frame update so guidance keeps going when the window is busy. The GPS and vest
//! workers deliver their events to it directly (its input channel is one of their outboxes). Every 250 ms
//! without a fix it updates the engine with the age of the last fix — measured from the instant the fix's
//! bytes arrived, the same clock the UI and the session log use — so a stale or lost fix turns into the
//! engine's "attention / hold" instead of a directional cue. When the engine's rate limiter holds a cue back,
//! the worker also wakes the moment the limiter lets it go, so a held cue is not a tick late.
//!
//! Override rules (the engine's, see `docs/guidance.md`): STOP ALL halts automatic cues until the operator
//! resumes them; a manual cue or tactor mutes automatic cues for the manual hold time. The STOP ALL latch
//! itself lives in the vest worker (it refuses automatic commands), so no ordering of messages between the
//! UI and this thread can let a cue through after a stop. The thread beats the vest worker's
//! [`Watched::Guidance`] heartbeat: if it stalls, the vest worker stops every tactor by itself.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use chrono::Datelike as _;
use vestnav_core::geo::LatLon;
use vestnav_core::guidance::{
    CompassReading, Decision, Guidance, GuidanceConfig, HeadingMode, HeadingSource, NavInput, NavState,
    Route, RouteConfig, RoutePath, StrategyKind,
};
use vestnav_core::vest::Cue;
use vestnav_device::gps::{Fix, GpsEvent};
use vestnav_device::heading::{Attitude, HeadingReference};
use vestnav_device::outbox::Outbox;
use vestnav_device::wtcu::worker::{Heartbeat, VestSendError, Watched};
use vestnav_device::wtcu::{CommandOrigin, LinkState, VestCommand, VestEvent, VestHandle};

use crate::route::Waypoint;
use vestnav_device::session_log::{LogEntry, LogSender};

/// A true heading from gpsd's ATT older than this is not used (the compass's own age limit is guidance's
/// `compass_max_age_s`).
const COMPASS_MAX_AGE: Duration = Duration::from_secs(1);

/// How often the worker re-evaluates without a new fix (and beats its heartbeat).
pub const TICK: Duration = Duration::from_millis(250);

/// Guidance settings the operator controls.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[allow(clippy::struct_excessive_bools)] // independent switches of the operator's, not a state machine
pub struct GuidanceSettings {
    /// Send cues automatically.
    pub auto: bool,
    /// A waypoint counts as reached inside this radius [m], unless it has its own
    /// (`route::Waypoint::arrival_radius_m`, edited per waypoint on the map).
    pub arrival_radius_m: f64,
    /// Minimum time before the same cue is repeated [s] (forward: at least 10 s).
    pub cue_interval_s: f64,
    /// How long a manual command holds automatic cues off [s].
    pub manual_hold_s: f64,
    /// Fix age after which no directional cue is given [s].
    pub stale_after_s: f64,
    /// On-time per pattern step [ms].
    pub on_ms: u16,
    /// After the last waypoint, head for the first again.
    pub loop_route: bool,
    /// The strategy.
    pub strategy: StrategyKind,
    /// Which heading steers: auto (a fresh, good compass, else COG), compass only, or COG only.
    pub heading_mode: HeadingMode,
    /// On a route planned along paths: farther than this from the path counts as off it [m]
    /// (`command::ranges::OFF_PATH_M`).
    #[serde(default = "default_off_path_m")]
    pub off_path_m: f64,
    /// Off the path this long re-plans the route from where the wearer is [s]
    /// (`command::ranges::REROUTE_AFTER_S`).
    #[serde(default = "default_reroute_after_s")]
    pub reroute_after_s: f64,
    /// Turn-on-the-spot cues for a wearer standing still (the `turn-in-place` cue set); off: the walking
    /// cues only (a study condition's `cue_set = "walking"`).
    #[serde(default = "default_turn_in_place")]
    pub turn_in_place: bool,
    /// Automatic cues end with the update that finishes a route (a study's navigation trial: the arrival
    /// ends the trial, so no cue may follow it, not even one the rate limiter held back at the arrival
    /// and would release a moment later, before the station's "cues off" reached guidance). Off: a held
    /// final Stop plays when the limiter lets it.
    #[serde(default)]
    pub end_at_finish: bool,
}

/// Guidance's default cue set: with the turn-in-place cues (settings saved before it existed still load).
pub fn default_turn_in_place() -> bool {
    GuidanceConfig::default().turn_in_place
}

/// Guidance's default distance off a path [m] (settings saved before it existed still load).
pub fn default_off_path_m() -> f64 {
    GuidanceConfig::default().off_path_m
}

/// Guidance's default time off a path before a re-route [s].
pub fn default_reroute_after_s() -> f64 {
    GuidanceConfig::default().off_path_s
}

/// Messages to the guidance worker.
#[derive(Clone)]
pub enum GuidanceInput {
    /// An event of the GPS source (fixes; the rest is ignored).
    Gps(GpsEvent),
    /// An event of the vest worker (link state, the STOP ALL latch, refusals).
    Vest(VestEvent),
    /// The route changed (edited on the map, imported, skipped); `next` is the waypoint to head for.
    Route {
        /// The waypoints.
        waypoints: Vec<Waypoint>,
        /// The path between them, when the route was planned along paths.
        path: Option<RoutePath>,
        /// Index of the next waypoint.
        next: usize,
        /// The route's revision (`RouteModel::revision`), echoed in the statuses computed on it.
        revision: u64,
    },
    /// Settings changed.
    Settings(GuidanceSettings),
    /// The operator sent a manual command (`Some(cue)` when it was one of the named cues).
    ManualOverride(Option<Cue>),
    /// The operator pressed STOP ALL (the vest worker already has it; this tells the engine).
    StopAll,
    /// The operator resumed automatic cues.
    Resume,
    /// The vest worker changed (connected / gone); the liveness bound of this thread's heartbeat.
    VestLink(Option<Arc<VestHandle>>, Duration),
    /// Where the cues sent are recorded for the lab (LSL, OSC).
    Lab(crate::lab::LabTap),
    /// The station's pinned-receiver diagnosis: the receiver's position is frozen, with the cause
    /// (`None`: no longer). Guidance holds on it (`Guidance::set_position_frozen`).
    PositionFrozen(Option<String>),
}

/// What the worker tells the UI after each update.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GuidanceStatus {
    /// The cue the engine wants now (sent or not).
    pub cue: Option<Cue>,
    /// Why, in words (the engine's reason, plus what happened to the cue).
    pub reason: String,
    /// Whether a cue was handed to the vest worker by this update.
    pub sent: bool,
    /// Why automatic guidance cannot steer the wearer now, when it cannot: no vest, vest not ready,
    /// halted by STOP ALL, automatic cues off. `None` while cues can reach the wearer.
    pub hold: Option<String>,
    /// Index of the next waypoint.
    pub next: usize,
    /// The revision of the route this status was computed on.
    pub route_revision: u64,
    /// Distance to the next waypoint [m].
    pub distance_m: Option<f64>,
    /// Bearing to the aim point [deg].
    pub bearing_deg: Option<f64>,
    /// Bearing error (aim bearing minus heading) [deg, -180..180].
    pub bearing_error_deg: Option<f64>,
    /// Cross-track distance from the current leg (positive = right of it) [m].
    pub cross_track_m: Option<f64>,
    /// Heading source used (COG, true heading, compass, or none).
    pub heading_source: HeadingSource,
    /// The heading used \[deg, true\], if any (the map's heading arrow).
    pub heading_deg: Option<f64>,
    /// The selection rule in words, as the operator should read it.
    pub heading_rule: String,
    /// Compass and COG disagree while walking fast: "compass disturbed?".
    pub compass_disturbed: bool,
    /// The WMM declination applied to the compass \[deg, east +\], once a position is known.
    pub declination_deg: Option<f64>,
    /// The engine's state.
    pub state: NavState,
    /// The route is finished.
    pub finished: bool,
    /// How long the wearer has been off the route's path [s] (farther than the settings' `off_path_m`).
    #[serde(default)]
    pub off_path_s: Option<f64>,
    /// Off the path for the settings' `reroute_after_s`: the wearer's position to re-plan the route from.
    #[serde(default)]
    pub reroute_from: Option<LatLon>,
}

/// The engine's configuration for the operator's settings.
pub fn engine_config(s: &GuidanceSettings) -> (GuidanceConfig, RouteConfig) {
    let g = GuidanceConfig {
        heading_mode: s.heading_mode,
        max_fix_age_s: s.stale_after_s,
        on_ms: s.on_ms,
        repeat_s: s.cue_interval_s,
        forward_repeat_s: s.cue_interval_s.max(10.0),
        manual_hold_s: s.manual_hold_s,
        off_path_m: s.off_path_m,
        off_path_s: s.reroute_after_s,
        turn_in_place: s.turn_in_place,
        ..GuidanceConfig::default()
    };
    let r = RouteConfig {
        arrival_radius_m: s.arrival_radius_m,
        rearm_radius_m: 1.5 * s.arrival_radius_m,
        pass_radius_m: 2.0 * s.arrival_radius_m,
        looped: s.loop_route,
        ..RouteConfig::default()
    };
    (g, r)
}

/// The engine's input for `fix` at `now`: its age is measured from the instant its bytes arrived (a fix
/// without that instant counts as infinitely old).
pub fn nav_input(fix: &Fix, now: Instant) -> NavInput {
    let age_s = fix.age(now).map_or(f64::INFINITY, |a| a.as_secs_f64());
    NavInput {
        position: fix
            .has_position()
            .then(|| fix.lat_deg.zip(fix.lon_deg))
            .flatten()
            .map(|(la, lo)| LatLon::new(la, lo)),
        fix_age_s: age_s,
        speed_m_s: fix.speed_m_s,
        cog_deg: fix.course_deg,
        true_heading_deg: fix.true_heading_deg,
        compass_deg: None,
        hdop: fix.hdop,
        accuracy_m: fix.error.map(|e| e.horizontal_m),
    }
}

/// Starts the guidance worker; it ends when every sender of `rx` is gone.
pub fn spawn(
    rx: Receiver<GuidanceInput>,
    settings: GuidanceSettings,
    ui: Outbox<GuidanceStatus>,
    log: Option<LogSender>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    std::thread::Builder::new().name("vestnav-guidance".into()).spawn(move || {
        let start = Instant::now();
        let mut w = GuidanceWorker {
            settings,
            waypoints: Vec::new(),
            path: None,
            route_revision: 0,
            engine: None,
            vest: None,
            beat: None,
            vest_state: None,
            halted: None,
            last_fix: None,
            compass: None,
            true_heading: None,
            declination: None,
            ui,
            log,
            lab: None,
            position_frozen: None,
            release_s: None,
        };
        let mut next_tick = Instant::now() + TICK;
        loop {
            let wake = w.release_at(start).map_or(next_tick, |r| r.min(next_tick));
            let msg = rx.recv_timeout(wake.saturating_duration_since(Instant::now()));
            if let Some(b) = &w.beat {
                b.beat();
            }
            let now = Instant::now();
            let now_s = now.duration_since(start).as_secs_f64();
            match msg {
                Ok(m) => w.handle(m, now, now_s),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            if now >= next_tick {
                next_tick = now + TICK;
                w.tick(now, now_s);
            } else if w.release_at(start).is_some_and(|r| now >= r) {
                // The cue the rate limiter held may play now: decide again at once, not at the next tick.
                w.release_s = None;
                w.tick(now, now_s);
            }
        }
    })
}

struct GuidanceWorker {
    settings: GuidanceSettings,
    waypoints: Vec<Waypoint>,
    path: Option<RoutePath>,
    route_revision: u64,
    engine: Option<Guidance>,
    vest: Option<Arc<VestHandle>>,
    beat: Option<Heartbeat>,
    vest_state: Option<LinkState>,
    /// Why automatic cues are latched off (the vest worker's word), if they are.
    halted: Option<String>,
    last_fix: Option<Fix>,
    /// Latest magnetic heading reading (the vest's compass, or an NMEA/gpsd compass).
    compass: Option<Attitude>,
    /// Latest true heading reading (gpsd's ATT), kept apart so neither kind hides the other.
    true_heading: Option<Attitude>,
    /// The WMM declination in force and the place it was computed for.
    declination: Option<(f64, LatLon)>,
    ui: Outbox<GuidanceStatus>,
    log: Option<LogSender>,
    /// The lab outputs the cues sent are recorded in.
    lab: Option<crate::lab::LabTap>,
    /// The receiver's position is frozen, and why (the station's diagnosis; kept over engine rebuilds).
    position_frozen: Option<String>,
    /// When the cue the rate limiter held at the last update may play [s, the engine's clock]: the worker
    /// decides again then instead of at its next tick, so a held cue is not up to a tick late.
    release_s: Option<f64>,
}

impl GuidanceWorker {
    fn handle(&mut self, msg: GuidanceInput, now: Instant, now_s: f64) {
        match msg {
            GuidanceInput::Gps(GpsEvent::Fix(fix)) => {
                self.refresh_declination(&fix);
                let input = self.input(&fix, now);
                self.last_fix = Some(*fix);
                self.update(&input, now, now_s);
            }
            GuidanceInput::Gps(GpsEvent::Attitude(a)) => self.take_heading(a),
            GuidanceInput::Gps(_) => {}
            GuidanceInput::Vest(ev) => match ev {
                VestEvent::State(s) => self.vest_state = Some(s),
                VestEvent::Halted { reason } => {
                    self.halted = Some(reason);
                    if let Some(g) = &mut self.engine {
                        let _ = g.stop_all(now_s);
                    }
                }
                VestEvent::Resumed => self.halted = None,
                VestEvent::Heading(a) => self.take_heading(a),
                _ => {}
            },
            GuidanceInput::Route { waypoints, path, next, revision } => {
                self.waypoints = waypoints;
                self.path = path;
                self.route_revision = revision;
                self.rebuild(next);
            }
            GuidanceInput::Settings(s) => {
                // Anything but the auto switch changes the engine's configuration.
                let structural = GuidanceSettings { auto: s.auto, ..self.settings } != s;
                self.settings = s;
                if structural {
                    let next = self.engine.as_ref().map_or(0, |g| g.route().active_index());
                    self.rebuild(next);
                }
            }
            GuidanceInput::ManualOverride(cue) => {
                if let (Some(g), Some(cue)) = (&mut self.engine, cue) {
                    // The UI already sent the pattern; the engine only needs to know, to hold off.
                    let _ = g.manual(cue, now_s);
                }
            }
            GuidanceInput::StopAll => {
                if let Some(g) = &mut self.engine {
                    let _ = g.stop_all(now_s);
                }
            }
            GuidanceInput::Resume => {
                self.halted = None;
                if let Some(g) = &mut self.engine {
                    g.resume();
                }
            }
            GuidanceInput::Lab(tap) => self.lab = Some(tap),
            GuidanceInput::PositionFrozen(why) => {
                if let Some(g) = &mut self.engine {
                    g.set_position_frozen(why.clone());
                }
                self.position_frozen = why;
            }
            GuidanceInput::VestLink(v, bound) => {
                self.beat = v.as_ref().map(|h| h.heartbeat(Watched::Guidance, bound));
                if let Some(b) = &self.beat {
                    b.beat();
                }
                self.halted = v.as_ref().filter(|h| h.is_halted()).map(|_| "STOP ALL".to_owned());
                // The new worker's state events can arrive before this message (they come straight from
                // it): keep the latest, forget it only when the vest goes away.
                if v.is_none() {
                    self.vest_state = None;
                }
                self.vest = v;
            }
        }
    }

    /// Builds the engine for the current waypoints, heading for waypoint `next`.
    fn rebuild(&mut self, next: usize) {
        let (gcfg, rcfg) = engine_config(&self.settings);
        let wps: Vec<Waypoint> = self.waypoints.clone();
        let halted = self.engine.as_ref().is_some_and(Guidance::is_halted);
        self.engine = match Route::new(wps, rcfg).and_then(|r| r.with_path(self.path.clone())) {
            Ok(route) => {
                let mut g = Guidance::new(route, gcfg, self.settings.strategy);
                g.set_declination_deg(self.declination.map(|(d, _)| d));
                for _ in 0..next.min(self.waypoints.len()) {
                    let _ = g.route_mut().skip();
                }
                if halted {
                    let _ = g.stop_all(0.0);
                }
                g.set_position_frozen(self.position_frozen.clone());
                Some(g)
            }
            Err(e) => {
                self.ui.try_send(GuidanceStatus {
                    cue: None,
                    reason: format!("no guidance: {e}"),
                    sent: false,
                    hold: Some(format!("no route: {e}")),
                    next: 0,
                    route_revision: self.route_revision,
                    distance_m: None,
                    bearing_deg: None,
                    bearing_error_deg: None,
                    cross_track_m: None,
                    heading_source: HeadingSource::None,
                    heading_deg: None,
                    heading_rule: String::new(),
                    compass_disturbed: false,
                    declination_deg: None,
                    state: NavState::Hold,
                    finished: false,
                    off_path_s: None,
                    reroute_from: None,
                });
                None
            }
        };
    }

    /// The instant of [`GuidanceWorker::release_s`] (1 ms after it, so the limiter has surely let go), if a
    /// held cue is waiting.
    fn release_at(&self, start: Instant) -> Option<Instant> {
        let s = self.release_s.filter(|s| s.is_finite() && *s >= 0.0 && *s < 1e9)?;
        Some(start + Duration::from_secs_f64(s) + Duration::from_millis(1))
    }

    /// Without new fixes, keep the engine informed of the fix age (stale fix: attention, not a direction).
    fn tick(&mut self, now: Instant, now_s: f64) {
        if let Some(fix) = &self.last_fix {
            let input = self.input(fix, now);
            self.update(&input, now, now_s);
        }
    }

    /// The engine's input for `fix` at `now`, with a fresh true heading from gpsd's ATT if there is one.
    fn input(&self, fix: &Fix, now: Instant) -> NavInput {
        let mut input = nav_input(fix, now);
        if input.true_heading_deg.is_none()
            && let Some(a) = self.true_heading
            && a.age(now) <= COMPASS_MAX_AGE
        {
            input.true_heading_deg = Some(a.heading_deg);
        }
        input
    }

    /// Keeps the newest heading reading (the age is judged at each update from its arrival instant).
    fn take_heading(&mut self, a: Attitude) {
        if a.validate().is_ok() {
            match a.reference {
                HeadingReference::Magnetic => self.compass = Some(a),
                HeadingReference::True => self.true_heading = Some(a),
            }
        }
    }

    /// Applies the WMM declination at the wearer's position once, and again only after moving 20 km.
    fn refresh_declination(&mut self, fix: &Fix) {
        let (Some(la), Some(lo)) = (fix.lat_deg, fix.lon_deg) else { return };
        let p = LatLon::new(la, lo);
        if self
            .declination
            .is_some_and(|(_, at)| vestnav_core::geo::Earth::Wgs84.distance_m(at, p) < 20_000.0)
        {
            return;
        }
        let date = fix.time.map_or_else(|| chrono::Utc::now().date_naive(), |t| t.date_naive());
        let Ok(dec) = vestnav_core::geo::declination_deg(
            p,
            fix.alt_m.unwrap_or(0.0),
            date.year(),
            date.month() as u8,
            date.day() as u8,
        ) else {
            return;
        };
        self.declination = Some((dec, p));
        if let Some(g) = &mut self.engine {
            g.set_declination_deg(Some(dec));
        }
    }

    /// Why cues cannot reach the wearer now, if they cannot.
    fn hold_reason(&self) -> Option<String> {
        if !self.settings.auto {
            return Some("automatic cues off".to_owned());
        }
        if let Some(why) = &self.halted {
            return Some(format!("halted ({why}); resume to guide again"));
        }
        match (&self.vest, &self.vest_state) {
            (None, _) => Some("no vest connected".to_owned()),
            (Some(_), Some(LinkState::Ready)) => None,
            (Some(_), Some(s)) => Some(format!("vest {s}")),
            (Some(_), None) => Some("vest not ready".to_owned()),
        }
    }

    fn update(&mut self, input: &NavInput, now: Instant, now_s: f64) {
        let hold = self.hold_reason();
        let compass = self.compass.map(|a| CompassReading {
            magnetic_deg: a.heading_deg,
            age_s: a.age(now).as_secs_f64(),
            quality_pct: a.quality_pct,
        });
        let declination = self.declination.map(|(d, _)| d);
        let Some(g) = &mut self.engine else { return };
        let d = g.update_with_compass(input, compass, now_s);
        // Wanted but not allowed yet: the rate limiter holds it until this instant.
        let release = if d.cue.is_none() { d.wanted.map(|w| g.allowed_from_s(w)) } else { None };
        let mut sent = false;
        let mut reason = d.reason.clone();
        if let Some(pattern) = d.pattern.clone().filter(|_| d.cue.is_some()) {
            match (&hold, &self.vest) {
                (Some(why), _) => reason = format!("{reason} (not sent: {why})"),
                (None, None) => reason.push_str(" (not sent: no vest)"),
                (None, Some(vest)) => {
                    let cmd = VestCommand::Play(pattern);
                    match vest.send(cmd.clone(), CommandOrigin::Guidance) {
                        Ok(()) => {
                            sent = true;
                            if let Some(lab) = &self.lab {
                                lab.command(CommandOrigin::Guidance, &cmd);
                            }
                            if let Some(log) = &self.log {
                                log.log(LogEntry::Command {
                                    origin: CommandOrigin::Guidance,
                                    command: cmd,
                                    reason: d.reason.clone(),
                                });
                            }
                        }
                        Err(e) => {
                            if let VestSendError::Halted(_) = e {
                                self.halted.get_or_insert_with(|| "STOP ALL".to_owned());
                            }
                            reason = format!("{reason} (not sent: {e})");
                        }
                    }
                }
            }
        }
        if d.cue.is_some()
            && !sent
            && let Some(g) = &mut self.engine
        {
            // It never reached the wearer: the rate limiter must not count it as played.
            g.not_played();
        }
        if self.settings.end_at_finish && self.settings.auto && d.state == NavState::Finished {
            // Latched off here, on guidance's own thread: nothing can play between the arrival and the
            // station's turn (the station's next settings say the same or start the next trial).
            self.settings.auto = false;
        }
        let hold_after = self.hold_reason();
        self.release_s = release.filter(|_| hold_after.is_none());
        let mut st = status(&d, reason, sent, hold_after);
        st.reroute_from = input.position.filter(|_| d.reroute);
        st.declination_deg = declination;
        st.route_revision = self.route_revision;
        self.ui.try_send(st);
    }
}

fn status(d: &Decision, reason: String, sent: bool, hold: Option<String>) -> GuidanceStatus {
    GuidanceStatus {
        cue: d.cue.or(d.wanted),
        reason,
        sent,
        hold,
        next: d.waypoint_index,
        route_revision: 0,
        distance_m: d.distance_m,
        bearing_deg: d.bearing_deg,
        bearing_error_deg: d.bearing_error_deg,
        cross_track_m: d.cross_track_m,
        heading_source: d.heading_source,
        heading_deg: d.heading_deg,
        heading_rule: d.heading_rule.clone(),
        compass_disturbed: d.compass_disturbed,
        declination_deg: None,
        state: d.state,
        finished: d.state == NavState::Finished,
        off_path_s: d.off_path_s,
        reroute_from: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
    use vestnav_device::gps::{Fix, FixMode};
    use vestnav_device::outbox::Overflow;
    use vestnav_device::wtcu::VestConfig;
    use vestnav_device::wtcu::emulator::UnitConfig;

    /// A guidance worker with an emulated vest that said `Ready` before it was named, automatic cues on,
    /// guiding to one waypoint 100 m due north of 42.0° N 71.0° W at `on_ms` per step: its input and the
    /// statuses it sends.
    fn guiding_north(
        on_ms: u16,
        end_at_finish: bool,
    ) -> (SyncSender<GuidanceInput>, Receiver<GuidanceStatus>) {
        let (in_tx, in_rx) = sync_channel(16);
        let (ui, ui_rx) = Outbox::channel(256, Overflow::DropNewest, None);
        let settings = GuidanceSettings {
            auto: true,
            arrival_radius_m: 8.0,
            cue_interval_s: 3.0,
            manual_hold_s: 10.0,
            stale_after_s: 3.0,
            on_ms,
            loop_route: false,
            strategy: StrategyKind::BearingOnly,
            heading_mode: HeadingMode::Cog,
            off_path_m: 20.0,
            reroute_after_s: 15.0,
            turn_in_place: true,
            end_at_finish,
        };
        // The worker ends when its input is dropped.
        let _t = spawn(in_rx, settings, ui, None).unwrap();
        let vest =
            Arc::new(VestHandle::spawn(VestConfig::Emulated(UnitConfig::default()), Vec::new()).unwrap());
        in_tx.send(GuidanceInput::Vest(VestEvent::State(LinkState::Ready))).unwrap();
        in_tx.send(GuidanceInput::VestLink(Some(vest), Duration::ZERO)).unwrap();
        let wp = Waypoint { name: "N".into(), lat_deg: 42.0009, lon_deg: -71.0, arrival_radius_m: None };
        in_tx.send(GuidanceInput::Route { waypoints: vec![wp], path: None, next: 0, revision: 1 }).unwrap();
        (in_tx, ui_rx)
    }

    /// A 3-D fix at `lat_deg` on 71.0° W, walking due east at 1.4 m/s, received now.
    fn walking_east(lat_deg: f64) -> GuidanceInput {
        let fix = Fix {
            lat_deg: Some(lat_deg),
            lon_deg: Some(-71.0),
            mode: Some(FixMode::Fix3D),
            speed_m_s: Some(1.4),
            course_deg: Some(90.0),
            received_at: Some(Instant::now()),
            ..Fix::default()
        };
        GuidanceInput::Gps(GpsEvent::Fix(Box::new(fix)))
    }

    /// The vest worker's events reach guidance straight from the worker, so its `Ready` can arrive before
    /// the console's message naming the new vest: guidance must still guide.
    #[test]
    fn a_vest_ready_before_it_is_named_still_gets_cues() {
        let (in_tx, ui_rx) = guiding_north(500, false);
        // The waypoint is due north, the wearer walks due east: a turn is wanted at once.
        in_tx.send(walking_east(42.0)).unwrap();
        let st = ui_rx.recv_timeout(Duration::from_secs(2)).unwrap();
        assert_eq!(st.cue, Some(Cue::TurnLeft), "{st:?}");
        assert!(st.sent, "{st:?}");
        assert_eq!(st.hold, None);
    }

    /// The statuses after the one that finished a one-waypoint route whose final Stop the rate limiter
    /// held (a turn had just been played), over the next 2.5 s (the Stop is due 1.5 s after the turn).
    fn after_the_finish(end_at_finish: bool) -> Vec<GuidanceStatus> {
        let (in_tx, ui_rx) = guiding_north(500, end_at_finish);
        // 100 m south of it walking east: turn left (a 1 s pattern; the next cue waits 1.5 s).
        in_tx.send(walking_east(42.0)).unwrap();
        // Then at the waypoint until the arrival is confirmed: the route is finished, its Stop held.
        let give_up = Instant::now() + Duration::from_secs(5);
        let finished = loop {
            assert!(Instant::now() < give_up, "the route finished within 5 s");
            std::thread::sleep(Duration::from_millis(20));
            in_tx.send(walking_east(42.0009)).unwrap();
            if let Some(st) = ui_rx.try_iter().find(|st| st.finished) {
                break st;
            }
        };
        assert!(!(finished.sent && finished.cue == Some(Cue::Stop)), "held, not played: {finished:?}");
        let mut after = Vec::new();
        let until = Instant::now() + Duration::from_millis(2500);
        while let Some(left) = until.checked_duration_since(Instant::now()) {
            if let Ok(st) = ui_rx.recv_timeout(left) {
                after.push(st);
            }
        }
        after
    }

    /// A cue the rate limiter holds plays once the limiter lets it, never before, and without waiting for
    /// the worker's next 250 ms update: the worker wakes at the release. Prints how late it came (no bound
    /// tighter than the tick is asserted: speed lives in benches).
    #[test]
    fn a_held_cue_plays_at_its_release_not_before() {
        let (in_tx, ui_rx) = guiding_north(500, false);
        // Half a tick after the worker started: the release falls between two of its 250 ms updates, where
        // a worker without the wake would be up to a tick late (the printed figure shows it).
        std::thread::sleep(TICK / 2);
        // The engine decides the turn after this instant, so its release is at least 1.5 s after it.
        let turned_at = Instant::now();
        in_tx.send(walking_east(42.0)).unwrap();
        let turn = ui_rx.recv_timeout(Duration::from_secs(2)).unwrap();
        assert!(turn.sent && turn.cue == Some(Cue::TurnLeft), "{turn:?}");
        // At the waypoint until the route is finished (a few fixes); its Stop is held until 1.5 s after
        // the turn began (the turn's 1 s pattern and the 0.5 s gap). No fix follows: only the worker's
        // own wake can play it.
        let give_up = Instant::now() + Duration::from_secs(5);
        loop {
            assert!(Instant::now() < give_up, "the route finished within 5 s");
            in_tx.send(walking_east(42.0009)).unwrap();
            let st = ui_rx.recv_timeout(Duration::from_secs(2)).unwrap();
            assert!(!st.sent, "nothing plays before the release: {st:?}");
            if st.finished {
                break;
            }
        }
        let stop = loop {
            let st = ui_rx.recv_timeout(Duration::from_secs(2)).expect("the held Stop plays");
            if st.sent {
                break st;
            }
        };
        let after = turned_at.elapsed().as_secs_f64();
        assert_eq!(stop.cue, Some(Cue::Stop), "{stop:?}");
        println!("the held Stop played {:.0} ms after the turn (released at 1500 ms)", after * 1e3);
        assert!(after >= 1.5, "the limiter held it: {after:.3} s");
    }

    /// A study's trial ends at the arrival: with `end_at_finish` guidance plays nothing after the update
    /// that finished the route, where without it the held Stop plays once the limiter lets it (the race
    /// a study lost when its "cues off" came after that).
    #[test]
    fn nothing_plays_after_a_finish_that_ends_the_cues() {
        let played =
            |after: &[GuidanceStatus]| after.iter().filter(|s| s.sent).map(|s| s.cue).collect::<Vec<_>>();
        assert_eq!(played(&after_the_finish(false)), [Some(Cue::Stop)], "the control: the held Stop plays");
        let after = after_the_finish(true);
        assert_eq!(played(&after), [], "{after:?}");
        assert!(after.iter().all(|s| s.hold.as_deref() == Some("automatic cues off")), "{after:?}");
    }
}
