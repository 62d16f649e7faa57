//! The guidance worker: a thread that runs `vestnav_core::guidance::Guidance` on every fix and sends its cues
//! to the vest.
//!
//! It runs outside the frame update so guidance keeps going when the window is hidden or busy. Every 250 ms
//! without a fix it updates the engine with the age of the last fix, so a stale or lost fix turns into the
//! engine's "attention / hold" instead of a directional cue. Override rules (the engine's, see
//! `docs/guidance.md`): STOP ALL halts automatic cues until automatic guidance is switched on again; a manual
//! cue or tactor mutes automatic cues for the manual hold time.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use vestnav_core::geo::LatLon;
use vestnav_core::guidance::{
    Decision, Guidance, GuidanceConfig, NavInput, NavState, Route, RouteConfig, StrategyKind,
    Waypoint as CoreWaypoint,
};
use vestnav_core::vest::Cue;

use crate::devices::VestLink;
use crate::model::{CommandOrigin, GpsFix, Outbox, VestCommand};
use crate::route::Waypoint;
use crate::session_log::{LogEntry, LogSender};

/// Guidance settings the operator controls.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuidanceSettings {
    /// Send cues automatically.
    pub auto: bool,
    /// A waypoint counts as reached inside this radius [m].
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
}

/// Messages to the guidance worker.
#[derive(Clone)]
pub enum GuidanceInput {
    /// A new fix.
    Fix(GpsFix),
    /// The route changed (edited on the map, imported, skipped); `next` is the waypoint to head for.
    Route {
        /// The waypoints.
        waypoints: Vec<Waypoint>,
        /// Index of the next waypoint.
        next: usize,
    },
    /// Settings changed.
    Settings(GuidanceSettings),
    /// The operator sent a manual command (`Some(cue)` when it was one of the named cues).
    ManualOverride(Option<Cue>),
    /// The operator pressed STOP ALL.
    StopAll,
    /// The vest link changed (connected / gone).
    Vest(Option<Arc<dyn VestLink>>),
}

/// What the worker tells the UI after each update.
#[derive(Debug, Clone, PartialEq)]
pub struct GuidanceStatus {
    /// The cue the engine wants now (sent or not).
    pub cue: Option<Cue>,
    /// Why, in words (the engine's reason, plus what happened to the cue).
    pub reason: String,
    /// Whether a cue was sent to the vest by this update.
    pub sent: bool,
    /// Index of the next waypoint.
    pub next: usize,
    /// Distance to the next waypoint [m].
    pub distance_m: Option<f64>,
    /// Bearing to the aim point [deg].
    pub bearing_deg: Option<f64>,
    /// Bearing error (aim bearing minus heading) [deg, -180..180].
    pub bearing_error_deg: Option<f64>,
    /// Cross-track distance from the current leg (positive = right of it) [m].
    pub cross_track_m: Option<f64>,
    /// Heading source used ("COG", "true heading", "none").
    pub heading_source: &'static str,
    /// The engine's state ("guiding", "hold", "manual", "halted", "finished").
    pub state: &'static str,
    /// The route is finished.
    pub finished: bool,
}

fn state_name(s: NavState) -> &'static str {
    match s {
        NavState::Guiding => "guiding",
        NavState::Hold => "hold",
        NavState::Manual => "manual",
        NavState::Halted => "halted",
        NavState::Finished => "finished",
    }
}

/// The engine's configuration for the operator's settings.
pub fn engine_config(s: &GuidanceSettings) -> (GuidanceConfig, RouteConfig) {
    let g = GuidanceConfig {
        max_fix_age_s: s.stale_after_s,
        on_ms: s.on_ms,
        repeat_s: s.cue_interval_s,
        forward_repeat_s: s.cue_interval_s.max(10.0),
        manual_hold_s: s.manual_hold_s,
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

/// The engine's input for a fix `age_s` old.
pub fn nav_input(fix: &GpsFix, age_s: f64) -> NavInput {
    NavInput {
        position: fix.has_position().then(|| LatLon::new(fix.lat_deg, fix.lon_deg)),
        fix_age_s: age_s,
        speed_m_s: fix.speed_m_s,
        cog_deg: fix.course_deg,
        true_heading_deg: None,
        compass_deg: None,
        hdop: fix.hdop,
        accuracy_m: fix.error_m,
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
            engine: None,
            vest: None,
            last_fix: None,
            ui,
            log,
        };
        loop {
            let msg = rx.recv_timeout(Duration::from_millis(250));
            let now_s = start.elapsed().as_secs_f64();
            match msg {
                Ok(m) => w.handle(m, now_s),
                Err(RecvTimeoutError::Timeout) => w.tick(now_s),
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
    })
}

struct GuidanceWorker {
    settings: GuidanceSettings,
    waypoints: Vec<Waypoint>,
    engine: Option<Guidance>,
    vest: Option<Arc<dyn VestLink>>,
    last_fix: Option<(GpsFix, f64)>,
    ui: Outbox<GuidanceStatus>,
    log: Option<LogSender>,
}

impl GuidanceWorker {
    fn handle(&mut self, msg: GuidanceInput, now_s: f64) {
        match msg {
            GuidanceInput::Fix(fix) => {
                let input = nav_input(&fix, 0.0);
                self.last_fix = Some((fix, now_s));
                self.update(&input, now_s);
            }
            GuidanceInput::Route { waypoints, next } => {
                self.waypoints = waypoints;
                self.rebuild(next);
            }
            GuidanceInput::Settings(s) => {
                let was_auto = self.settings.auto;
                // Anything but the auto switch changes the engine's configuration.
                let structural = GuidanceSettings { auto: s.auto, ..self.settings } != s;
                self.settings = s;
                if structural {
                    let next = self.engine.as_ref().map_or(0, |g| g.route().active_index());
                    self.rebuild(next);
                }
                if s.auto
                    && !was_auto
                    && let Some(g) = &mut self.engine
                {
                    g.resume();
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
            GuidanceInput::Vest(v) => self.vest = v,
        }
    }

    /// Builds the engine for the current waypoints, heading for waypoint `next`.
    fn rebuild(&mut self, next: usize) {
        let (gcfg, rcfg) = engine_config(&self.settings);
        let wps: Vec<CoreWaypoint> = self
            .waypoints
            .iter()
            .map(|w| CoreWaypoint::new(w.name.clone(), LatLon::new(w.lat_deg, w.lon_deg)))
            .collect();
        let halted = self.engine.as_ref().is_some_and(Guidance::is_halted);
        self.engine = match Route::new(wps, rcfg) {
            Ok(route) => {
                let mut g = Guidance::new(route, gcfg, self.settings.strategy);
                for _ in 0..next.min(self.waypoints.len()) {
                    let _ = g.route_mut().skip();
                }
                if halted {
                    let _ = g.stop_all(0.0);
                }
                Some(g)
            }
            Err(e) => {
                self.ui.send(GuidanceStatus {
                    cue: None,
                    reason: format!("no guidance: {e}"),
                    sent: false,
                    next: 0,
                    distance_m: None,
                    bearing_deg: None,
                    bearing_error_deg: None,
                    cross_track_m: None,
                    heading_source: "none",
                    state: "hold",
                    finished: false,
                });
                None
            }
        };
    }

    /// Without new fixes, keep the engine informed of the fix age (stale fix: attention, not a direction).
    fn tick(&mut self, now_s: f64) {
        if let Some((fix, at)) = &self.last_fix {
            let input = nav_input(fix, now_s - at);
            self.update(&input, now_s);
        }
    }

    fn update(&mut self, input: &NavInput, now_s: f64) {
        let Some(g) = &mut self.engine else { return };
        let d = g.update(input, now_s);
        let mut sent = false;
        let mut reason = d.reason.clone();
        if let Some(pattern) = d.pattern.clone().filter(|_| d.cue.is_some()) {
            if !self.settings.auto {
                reason.push_str(" (automatic cues off)");
            } else if let Some(vest) = &self.vest {
                let cmd = VestCommand::Play(pattern);
                match vest.send(cmd.clone()) {
                    Ok(()) => {
                        sent = true;
                        if let Some(log) = &self.log {
                            log.log(LogEntry::Command {
                                origin: CommandOrigin::Guidance,
                                command: cmd,
                                reason: d.reason.clone(),
                            });
                        }
                    }
                    Err(e) => reason = format!("{reason} (not sent: {e})"),
                }
            } else {
                reason.push_str(" (no vest)");
            }
        }
        self.ui.send(status(&d, reason, sent));
    }
}

fn status(d: &Decision, reason: String, sent: bool) -> GuidanceStatus {
    GuidanceStatus {
        cue: d.cue.or(d.wanted),
        reason,
        sent,
        next: d.waypoint_index,
        distance_m: d.distance_m,
        bearing_deg: d.bearing_deg,
        bearing_error_deg: d.bearing_error_deg,
        cross_track_m: d.cross_track_m,
        heading_source: d.heading_source.name(),
        state: state_name(d.state),
        finished: d.state == NavState::Finished,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;
    use std::sync::mpsc::sync_channel;

    #[derive(Default)]
    struct Rec(Mutex<Vec<VestCommand>>);
    impl VestLink for Rec {
        fn send(&self, c: VestCommand) -> Result<(), String> {
            self.0.lock().unwrap().push(c);
            Ok(())
        }
        fn close(&self) {}
    }

    fn settings() -> GuidanceSettings {
        GuidanceSettings {
            auto: true,
            arrival_radius_m: 8.0,
            cue_interval_s: 3.0,
            manual_hold_s: 10.0,
            stale_after_s: 3.0,
            on_ms: 500,
            loop_route: false,
            strategy: StrategyKind::BearingOnly,
        }
    }

    fn moving(lat: f64, lon: f64, course: f64) -> GpsFix {
        GpsFix {
            lat_deg: lat,
            lon_deg: lon,
            mode: crate::model::FixMode::Fix3d,
            speed_m_s: Some(1.4),
            course_deg: Some(course),
            error_m: Some(3.0),
            ..GpsFix::default()
        }
    }

    #[test]
    fn a_fix_heading_away_from_the_waypoint_sends_a_turn_and_stop_all_halts() {
        let (in_tx, in_rx) = sync_channel(16);
        let (ui_tx, ui_rx) = sync_channel(64);
        let _t = spawn(in_rx, settings(), Outbox::new(ui_tx, None), None).unwrap();
        let vest = Arc::new(Rec::default());
        in_tx.send(GuidanceInput::Vest(Some(vest.clone()))).unwrap();
        // One waypoint 100 m due north; the wearer walks due east: it is 90° to the left.
        let wp = Waypoint { name: "N".into(), lat_deg: 42.0009, lon_deg: -71.0 };
        in_tx.send(GuidanceInput::Route { waypoints: vec![wp], next: 0 }).unwrap();
        in_tx.send(GuidanceInput::Fix(moving(42.0, -71.0, 90.0))).unwrap();
        let st = ui_rx.recv_timeout(Duration::from_secs(2)).unwrap();
        assert_eq!(st.cue, Some(Cue::TurnLeft), "{st:?}");
        assert!(st.sent);
        assert!((st.bearing_error_deg.unwrap() + 90.0).abs() < 1.0);
        assert_eq!(vest.0.lock().unwrap().as_slice(), &[VestCommand::Play(Cue::TurnLeft.pattern(500))]);
        in_tx.send(GuidanceInput::StopAll).unwrap();
        in_tx.send(GuidanceInput::Fix(moving(42.0, -71.0, 180.0))).unwrap();
        let st = ui_rx.recv_timeout(Duration::from_secs(2)).unwrap();
        assert_eq!(st.state, "halted");
        assert_eq!(vest.0.lock().unwrap().len(), 1, "nothing automatic after STOP ALL");
    }
}
