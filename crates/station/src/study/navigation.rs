//! Navigation trials in the runner: one route walked under one condition.
//!
//! A trial: `trial_start` → the station loads the route and applies the condition through its own
//! commands and starts guidance ([`StudyIo::start_navigation`]; the runner never steers) →
//! `navigation_start ROUTE/CONDITION` (the trial's time origin, `stimulus_on_s`) → `Navigating`: each pump
//! hands the runner the positions the receiver gave since the start, the cues guidance played and whether
//! guidance reached the route's last waypoint ([`NavTick`]), measured by core's
//! [`NavMeter`](vestnav_core::study::navigation::NavMeter) → the trial ends at that arrival (`completed`),
//! by the operator's End trial or its `time_limit_s` (the block's, else the protocol's; `ended`), by STOP ALL (`stopped`) or a
//! pause or abort (`aborted`) → guidance's automatic cues off ([`StudyIo::end_navigation`]), the row
//! written with the navigation columns → the inter-trial interval.

use serde::{Deserialize, Serialize};
use vestnav_core::geo::{Earth, LatLon};
use vestnav_core::study::navigation::NavMeter;
use vestnav_core::study::{Outcome, PlannedTrial, Protocol, Stimulus, TrialRecord};

use super::{StudyIo, StudyPhase, StudyRunner};

/// A navigation trial runs for at most this long unless its block or the protocol sets `time_limit_s` [s]
/// (the station's default, [`super::Timing::time_limit_s`]).
pub const DEFAULT_TIME_LIMIT_S: f64 = 3600.0;

/// The route a navigation trial walks, as the station loaded it.
#[derive(Debug, Clone, PartialEq)]
pub struct NavRoute {
    /// The trial's first instant on the session clock: fixes from then on are the trial's.
    pub start_s: f64,
    /// The route's name.
    pub name: String,
    /// Its polyline: the planned path when the file has one, else the straight legs between waypoints.
    pub polyline: Vec<LatLon>,
    /// Each waypoint with its arrival radius [m].
    pub waypoints: Vec<(LatLon, f64)>,
}

/// What one pump tells the runner about the trial under way.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NavTick {
    /// Positions the receiver gave since the trial started, in order.
    pub positions: Vec<LatLon>,
    /// Cues guidance handed to the vest and the vest did not refuse.
    pub cues: u32,
    /// Guidance reached (or passed) the route's last waypoint.
    pub finished: bool,
}

/// What a view shows of a navigation trial under way (or the last one).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NavView {
    /// The route's name.
    pub route: String,
    /// The condition's name.
    pub condition: String,
    /// Its strategy, heading source, cue set and cue interval in words.
    pub setup: String,
    /// Time since the trial started [s] (at the runner's last turn).
    pub elapsed_s: f64,
    /// The trial's time limit [s].
    pub time_limit_s: f64,
    /// The latest position's cross-track error [m] (positive: right of the route).
    pub cross_track_m: Option<f64>,
    /// Cross-track RMS so far [m].
    pub cross_track_rms_m: Option<f64>,
    /// Distance walked so far [m].
    pub path_m: f64,
    /// The route's length [m].
    pub route_m: f64,
    /// Cues played so far.
    pub cues: u32,
    /// Waypoints not reached so far.
    pub missed_waypoints: usize,
    /// Positions received.
    pub fixes: usize,
}

/// The navigation trial under way.
#[derive(Debug, Clone)]
pub(super) struct NavRun {
    meter: NavMeter,
    route: String,
    condition: String,
    setup: String,
    start_s: f64,
    elapsed_s: f64,
    limit_s: f64,
    cues: u32,
    stops: u32,
    arrived_s: Option<f64>,
}

impl NavRun {
    pub(super) fn view(&self) -> NavView {
        NavView {
            route: self.route.clone(),
            condition: self.condition.clone(),
            setup: self.setup.clone(),
            elapsed_s: self.elapsed_s,
            time_limit_s: self.limit_s,
            cross_track_m: self.meter.last_cross_track_m(),
            cross_track_rms_m: self.meter.cross_track_rms_m(),
            path_m: self.meter.path_m(),
            route_m: self.meter.route_m(),
            cues: self.cues,
            missed_waypoints: self.meter.missed_waypoints(),
            fixes: self.meter.samples(),
        }
    }

    /// The navigation columns of the trial's row.
    pub(super) fn fill(&self, r: &mut TrialRecord) {
        r.completion_s = self.arrived_s.map(|a| a - self.start_s);
        r.path_m = Some(self.meter.path_m());
        r.route_m = Some(self.meter.route_m());
        r.cross_track_rms_m = self.meter.cross_track_rms_m();
        r.cues = Some(self.cues);
        r.stops = Some(self.stops);
        r.missed_waypoints = Some(u32::try_from(self.meter.missed_waypoints()).unwrap_or(u32::MAX));
    }

    /// STOP ALL during the walk.
    pub(super) fn stopped(&mut self) {
        self.stops += 1;
    }
}

/// Checks what the station will apply of each condition that the protocol's own checks do not: the cue
/// interval within the station's setting range. The error names the condition's line.
pub(super) fn check_conditions(p: &Protocol) -> Result<(), String> {
    let range = crate::command::ranges::CUE_INTERVAL_S;
    for (s, line) in p.stimuli.iter().zip(&p.stimulus_lines) {
        if let Stimulus::Navigation { condition, cue_interval_s, .. } = s
            && !range.contains(cue_interval_s)
        {
            return Err(format!(
                "{}:{line}: condition {condition}: cue_interval_s = {cue_interval_s} is outside the station's \
                 {}..={} s",
                p.source,
                range.start(),
                range.end()
            ));
        }
    }
    Ok(())
}

impl StudyRunner {
    /// Starts navigation trial `t` (its `trial_start` already marked).
    pub(super) fn start_navigation(&mut self, t: &PlannedTrial, note: String, io: &mut dyn StudyIo) {
        let Stimulus::Navigation { condition, strategy, heading, cue_set, cue_interval_s, .. } = &t.stimulus
        else {
            return;
        };
        self.running = Some(super::Running { on_s: None, acked: true, note });
        self.phase = StudyPhase::Navigating;
        let route = match io.start_navigation(&t.stimulus) {
            Ok(r) => r,
            Err(e) => {
                self.refused(&format!("navigation not started: {e}"), io);
                return;
            }
        };
        let Some(meter) = NavMeter::new(route.polyline, Earth::default()) else {
            self.refused("navigation not started: the route has fewer than two points", io);
            return;
        };
        let now = route.start_s;
        io.marker(&format!("navigation_start {}", t.stimulus.label()), now);
        if let Some(r) = &mut self.running {
            r.on_s = Some(now);
        }
        let limit_s = self.timing.time_limit_s;
        self.nav = Some(NavRun {
            meter: meter.with_waypoints(route.waypoints),
            route: route.name,
            condition: condition.clone(),
            setup: format!("{strategy}, heading {heading}, {cue_set} cues every {cue_interval_s} s"),
            start_s: now,
            elapsed_s: 0.0,
            limit_s,
            cues: 0,
            stops: 0,
            arrived_s: None,
        });
        self.until_s = Some(now + limit_s);
        self.error = None;
    }

    /// One pump's news of the walk: positions measured, cues counted, the arrival ending the trial.
    pub fn navigation_tick(&mut self, tick: &NavTick, io: &mut dyn StudyIo) {
        if self.phase != StudyPhase::Navigating {
            return;
        }
        let now = io.now_s();
        let Some(n) = &mut self.nav else { return };
        for p in &tick.positions {
            n.meter.fix(*p);
        }
        n.cues += tick.cues;
        n.elapsed_s = now - n.start_s;
        if tick.finished {
            n.arrived_s = Some(now);
            io.marker("arrived", now);
            self.end_trial(Outcome::Completed, "", io);
            self.at += 1;
            self.next_or_finish(now, io);
        }
    }

    /// The operator's End trial, or the time limit (`why`): the walk ends before the last waypoint.
    pub(super) fn end_navigation_trial(&mut self, why: &str, io: &mut dyn StudyIo) -> Result<(), String> {
        if self.phase != StudyPhase::Navigating {
            return Err(format!("end trial refused: the session is {}", self.phase.name()));
        }
        let now = io.now_s();
        if let Some(n) = &mut self.nav {
            n.elapsed_s = now - n.start_s;
        }
        self.end_trial(Outcome::Ended, why, io);
        self.at += 1;
        self.next_or_finish(now, io);
        Ok(())
    }
}
