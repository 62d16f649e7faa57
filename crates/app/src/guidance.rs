//! The guidance worker: a thread fed with fixes that picks a cue and sends it to the vest.
//!
//! It runs outside the frame update so guidance keeps going when the window is hidden or busy. The rule
//! for manual commands: any command the operator sends by hand (a tactor, a pattern, STOP ALL) holds the
//! automatic cues off for `manual_hold_s`; STOP ALL also switches automatic guidance off.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use vestnav_core::vest::Cue;

use crate::devices::VestLink;
use crate::model::{CommandOrigin, GpsFix, Outbox, VestCommand};
use crate::route::{Waypoint, cross_track_m, distance_bearing};
use crate::session_log::{LogEntry, LogSender};

/// Guidance settings the operator controls.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuidanceSettings {
    /// Send cues automatically.
    pub auto: bool,
    /// A waypoint counts as reached inside this radius [m].
    pub arrival_radius_m: f64,
    /// Minimum time between two automatic cues [s].
    pub cue_interval_s: f64,
    /// How long a manual command holds automatic cues off [s].
    pub manual_hold_s: f64,
    /// Fix age after which no directional cue is given [s].
    pub stale_after_s: f64,
    /// On-time per pattern step [ms].
    pub on_ms: u16,
}

/// Messages to the guidance worker.
#[derive(Clone)]
pub enum GuidanceInput {
    /// A new fix.
    Fix(GpsFix),
    /// The route changed (edited on the map, imported); `next` is the waypoint to head for.
    Route {
        /// The waypoints.
        waypoints: Vec<Waypoint>,
        /// Index of the next waypoint.
        next: usize,
    },
    /// Settings changed.
    Settings(GuidanceSettings),
    /// The operator sent a manual command: hold automatic cues off.
    ManualOverride,
    /// The vest link changed (connected / gone).
    Vest(Option<Arc<dyn VestLink>>),
}

/// What the worker tells the UI.
#[derive(Debug, Clone, PartialEq)]
pub struct GuidanceStatus {
    /// The cue chosen for the latest fix (sent or not).
    pub cue: Option<Cue>,
    /// Why, in words (bearing error, distance, cross-track, or why no direction).
    pub reason: String,
    /// Whether that cue was sent to the vest.
    pub sent: bool,
    /// Index of the next waypoint.
    pub next: usize,
    /// Distance to the next waypoint [m].
    pub distance_m: Option<f64>,
    /// Bearing to the next waypoint [deg].
    pub bearing_deg: Option<f64>,
    /// Bearing error (bearing to target minus heading) [deg, -180..180].
    pub bearing_error_deg: Option<f64>,
    /// Cross-track distance from the current leg (positive = right of it) [m].
    pub cross_track_m: Option<f64>,
    /// The route is finished.
    pub finished: bool,
}

/// Minimum speed for the course over ground to count as a heading [m/s].
pub const MIN_SPEED_FOR_COURSE_M_S: f64 = 0.5;

/// One guidance decision for a fix, without side effects.
///
/// Heading = course over ground when speed >= [`MIN_SPEED_FOR_COURSE_M_S`], else unknown (attention cue).
/// Bearing error `e = wrap(bearing_to_target - heading)` in (-180, 180]; the cue is forward for |e| <= 20°,
/// slight left/right up to 60°, turn left/right up to 135°, turn around beyond (the vocabulary of
/// `vestnav_core::vest::Cue`). Inside the arrival radius the cue is "arrived".
pub fn decide(fix: &GpsFix, route: &[Waypoint], next: usize, arrival_radius_m: f64) -> GuidanceStatus {
    let mut st = GuidanceStatus {
        cue: None,
        reason: String::new(),
        sent: false,
        next,
        distance_m: None,
        bearing_deg: None,
        bearing_error_deg: None,
        cross_track_m: None,
        finished: false,
    };
    let Some(target) = route.get(next) else {
        st.finished = !route.is_empty();
        st.reason = if route.is_empty() { "no waypoints".into() } else { "route finished".into() };
        return st;
    };
    if !fix.has_position() {
        st.cue = Some(Cue::Attention);
        st.reason = "no position fix".into();
        return st;
    }
    let (d, b) = distance_bearing(fix.lat_deg, fix.lon_deg, target.lat_deg, target.lon_deg);
    st.distance_m = Some(d);
    st.bearing_deg = Some(b);
    if next > 0 {
        if let Some(prev) = route.get(next - 1) {
            st.cross_track_m = Some(cross_track_m(
                (prev.lat_deg, prev.lon_deg),
                (target.lat_deg, target.lon_deg),
                (fix.lat_deg, fix.lon_deg),
            ));
        }
    }
    if d <= arrival_radius_m {
        st.cue = Some(Cue::Arrived);
        st.reason = format!("{:.1} m from '{}' (inside {:.0} m)", d, target.name, arrival_radius_m);
        return st;
    }
    let heading = match (fix.speed_m_s, fix.course_deg) {
        (Some(v), Some(c)) if v >= MIN_SPEED_FOR_COURSE_M_S && c.is_finite() => c,
        (v, _) => {
            st.cue = Some(Cue::Attention);
            st.reason = format!(
                "heading unknown (speed {} < {MIN_SPEED_FOR_COURSE_M_S} m/s); {d:.0} m to '{}'",
                v.map_or_else(|| "n/a".to_owned(), |v| format!("{v:.1}")),
                target.name
            );
            return st;
        }
    };
    let e = (b - heading + 540.0).rem_euclid(360.0) - 180.0;
    st.bearing_error_deg = Some(e);
    let cue = match e.abs() {
        a if a <= 20.0 => Cue::Forward,
        a if a <= 60.0 && e < 0.0 => Cue::SlightLeft,
        a if a <= 60.0 => Cue::SlightRight,
        a if a <= 135.0 && e < 0.0 => Cue::TurnLeft,
        a if a <= 135.0 => Cue::TurnRight,
        _ => Cue::TurnAround,
    };
    st.cue = Some(cue);
    st.reason = format!("bearing error {e:+.0}°, {d:.0} m to '{}'", target.name);
    if let Some(x) = st.cross_track_m {
        st.reason.push_str(&format!(", cross-track {x:+.1} m"));
    }
    st
}

/// Starts the guidance worker; it ends when every sender of `rx` is gone.
pub fn spawn(
    rx: Receiver<GuidanceInput>,
    settings: GuidanceSettings,
    ui: Outbox<GuidanceStatus>,
    log: Option<LogSender>,
) -> std::io::Result<std::thread::JoinHandle<()>> {
    std::thread::Builder::new().name("vestnav-guidance".into()).spawn(move || {
        let mut w = GuidanceWorker {
            settings,
            route: Vec::new(),
            next: 0,
            vest: None,
            last_cue_at: None,
            last_fix_at: None,
            manual_until: None,
            stale_reported: false,
            ui,
            log,
        };
        loop {
            match rx.recv_timeout(Duration::from_millis(250)) {
                Ok(msg) => w.handle(msg, Instant::now()),
                Err(RecvTimeoutError::Timeout) => w.tick(Instant::now()),
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
    })
}

struct GuidanceWorker {
    settings: GuidanceSettings,
    route: Vec<Waypoint>,
    next: usize,
    vest: Option<Arc<dyn VestLink>>,
    last_cue_at: Option<Instant>,
    last_fix_at: Option<Instant>,
    manual_until: Option<Instant>,
    stale_reported: bool,
    ui: Outbox<GuidanceStatus>,
    log: Option<LogSender>,
}

impl GuidanceWorker {
    fn handle(&mut self, msg: GuidanceInput, now: Instant) {
        match msg {
            GuidanceInput::Fix(fix) => self.on_fix(&fix, now),
            GuidanceInput::Route { waypoints, next } => {
                self.route = waypoints;
                self.next = next.min(self.route.len());
            }
            GuidanceInput::Settings(s) => self.settings = s,
            GuidanceInput::ManualOverride => {
                self.manual_until = Some(now + Duration::from_secs_f64(self.settings.manual_hold_s));
            }
            GuidanceInput::Vest(v) => self.vest = v,
        }
    }

    /// Without fixes, say so once (attention cue) instead of steering on an old position.
    fn tick(&mut self, now: Instant) {
        let Some(at) = self.last_fix_at else { return };
        if self.stale_reported || now.duration_since(at).as_secs_f64() < self.settings.stale_after_s {
            return;
        }
        self.stale_reported = true;
        let st = GuidanceStatus {
            cue: Some(Cue::Attention),
            reason: format!("no fix for {:.0} s: holding", now.duration_since(at).as_secs_f64()),
            sent: false,
            next: self.next,
            distance_m: None,
            bearing_deg: None,
            bearing_error_deg: None,
            cross_track_m: None,
            finished: false,
        };
        self.emit(st, now);
    }

    fn on_fix(&mut self, fix: &GpsFix, now: Instant) {
        self.last_fix_at = Some(now);
        self.stale_reported = false;
        let st = decide(fix, &self.route, self.next, self.settings.arrival_radius_m);
        let arrived = st.cue == Some(Cue::Arrived);
        self.emit(st, now);
        if arrived {
            self.next += 1;
        }
    }

    fn emit(&mut self, mut st: GuidanceStatus, now: Instant) {
        let held = self.manual_until.is_some_and(|t| now < t);
        let due = self
            .last_cue_at
            .is_none_or(|t| now.duration_since(t).as_secs_f64() >= self.settings.cue_interval_s);
        // Arrival is announced at once (it also advances the route), other cues respect the interval.
        let urgent = st.cue == Some(Cue::Arrived);
        if let (Some(cue), true, false, Some(vest)) = (st.cue, self.settings.auto, held, &self.vest) {
            if due || urgent {
                let cmd = VestCommand::Play(cue.pattern(self.settings.on_ms));
                match vest.send(cmd.clone()) {
                    Ok(()) => {
                        st.sent = true;
                        self.last_cue_at = Some(now);
                        if let Some(log) = &self.log {
                            log.log(LogEntry::Command {
                                origin: CommandOrigin::Guidance,
                                command: cmd,
                                reason: st.reason.clone(),
                            });
                        }
                    }
                    Err(e) => st.reason = format!("{} (not sent: {e})", st.reason),
                }
            }
        } else if held {
            st.reason = format!("{} (manual override)", st.reason);
        }
        self.ui.send(st);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fix(lat: f64, lon: f64, speed: f64, course: f64) -> GpsFix {
        GpsFix {
            lat_deg: lat,
            lon_deg: lon,
            mode: crate::model::FixMode::Fix3d,
            speed_m_s: Some(speed),
            course_deg: Some(course),
            ..GpsFix::default()
        }
    }

    fn route() -> Vec<Waypoint> {
        vec![
            Waypoint { name: "A".into(), lat_deg: 42.0, lon_deg: -71.0 },
            Waypoint { name: "B".into(), lat_deg: 42.001, lon_deg: -71.0 },
        ]
    }

    #[test]
    fn cue_follows_the_bearing_error() {
        let r = route();
        // Walking north toward B (due north): forward.
        assert_eq!(decide(&fix(42.0, -71.0, 1.3, 0.0), &r, 1, 5.0).cue, Some(Cue::Forward));
        // Heading east: the target is 90° to the left.
        let st = decide(&fix(42.0, -71.0, 1.3, 90.0), &r, 1, 5.0);
        assert_eq!(st.cue, Some(Cue::TurnLeft));
        assert!((st.bearing_error_deg.unwrap() + 90.0).abs() < 0.1);
        assert_eq!(decide(&fix(42.0, -71.0, 1.3, 330.0), &r, 1, 5.0).cue, Some(Cue::SlightRight));
        assert_eq!(decide(&fix(42.0, -71.0, 1.3, 180.0), &r, 1, 5.0).cue, Some(Cue::TurnAround));
        // Standing still: no direction from course over ground.
        assert_eq!(decide(&fix(42.0, -71.0, 0.1, 0.0), &r, 1, 5.0).cue, Some(Cue::Attention));
        // At B.
        assert_eq!(decide(&fix(42.001, -71.0, 1.3, 0.0), &r, 1, 5.0).cue, Some(Cue::Arrived));
        assert!(decide(&fix(42.001, -71.0, 1.3, 0.0), &r, 2, 5.0).finished);
    }
}
