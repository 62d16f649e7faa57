//! The station's side of the study runner: the [`StudyIo`] it gives the runner (the session clock, the
//! markers into the session log, the operator's manual path to the vest, the stop path) and the
//! [`Station`] methods that apply [`StudyCommand`]s, turn the runner in each pump and show its view.

use std::time::{Duration, Instant};

use vestnav_core::geo::LatLon;
use vestnav_core::guidance::{HeadingMode, StrategyKind};
use vestnav_core::study::Stimulus;
use vestnav_device::gps::GpsEvent;
use vestnav_device::session_log::LogEntry;
use vestnav_device::wtcu::{CommandKind, CommandOrigin, Limits, VestCommand, VestEvent};

use super::{NavRoute, NavTick, StudyCommand, StudyIo, StudyPhase, StudyRunner, StudyView, Timing};
use crate::guidance::GuidanceStatus;
use crate::lab::LabOutputs;
use crate::sources::GpsSourceConfig;
use crate::{Station, StationSettings};

/// The station's study: the session loaded, if any, and the timing the next one is loaded with.
#[derive(Debug, Default)]
pub struct StudySlot {
    runner: Option<StudyRunner>,
    timing: Timing,
    /// The lab outputs of the session loaded: its clock and its markers for the whole session (lab
    /// outputs turned on later serve the next session).
    lab: Option<LabOutputs>,
    /// The navigation trial under way: fixes received from this instant on are its, and guidance's
    /// statuses from this route revision on.
    nav_since: Option<(Instant, u64)>,
    /// The operator's settings before the session's first navigation trial: each trial's condition is
    /// applied to them, and they come back (automatic cues off) after each trial.
    operator_settings: Option<StationSettings>,
}

/// The station as the runner sees it.
struct Io<'a>(&'a mut Station);

impl StudyIo for Io<'_> {
    fn now_s(&self) -> f64 {
        self.0.study_clock_s()
    }

    fn marker(&mut self, text: &str, at_s: f64) {
        if let Some(lab) = &self.0.study.lab {
            lab.marker(text, at_s);
        }
        self.0.log(LogEntry::Note { text: format!("study marker {at_s:.6} {text}") });
    }

    fn send(&mut self, command: VestCommand) -> Result<(), String> {
        self.0.send_manual(command, None)
    }

    fn stop_vest(&mut self) {
        self.0.stop_all();
    }

    fn hold_guidance(&mut self) {
        if self.0.settings.guidance.auto {
            let mut s = self.0.settings;
            s.guidance.auto = false;
            self.0.set_settings(s);
        }
    }

    fn start_navigation(&mut self, stimulus: &Stimulus) -> Result<NavRoute, String> {
        let Stimulus::Navigation { route, strategy, heading, cue_set, cue_interval_s, .. } = stimulus else {
            return Err("not a navigation trial".to_owned());
        };
        let st = &mut *self.0;
        let gpx = crate::route::read_gpx(route)?;
        if gpx.waypoints.len() < 2 {
            return Err(format!("{}: a route of at least two points is needed", route.display()));
        }
        let name = gpx.name.clone().unwrap_or_else(|| {
            route.file_stem().map_or_else(|| "route".to_owned(), |s| s.to_string_lossy().into_owned())
        });
        let operator = *st.study.operator_settings.get_or_insert(st.settings);
        let mut s = operator;
        s.guidance.strategy =
            StrategyKind::from_name(strategy).ok_or_else(|| format!("unknown strategy {strategy:?}"))?;
        s.guidance.heading_mode =
            HeadingMode::from_name(heading).ok_or_else(|| format!("unknown heading source {heading:?}"))?;
        s.guidance.cue_interval_s = *cue_interval_s;
        s.guidance.turn_in_place = cue_set == "turn-in-place";
        s.guidance.loop_route = false;
        // The arrival ends the trial: guidance itself sends nothing after it (no race with end_navigation).
        s.guidance.end_at_finish = true;
        s.guidance.auto = false;
        s.check()?;
        // The route through the station's one route model (undo brings the operator's back), guidance
        // told on this pump; then the condition, and automatic cues on (the operator started the trial).
        st.route
            .replace_with_path(name.clone(), gpx.waypoints.clone(), gpx.path.clone())
            .map_err(|e| format!("{}: {e}", route.display()))?;
        // Guidance takes the route before the settings that turn its cues on: no cue toward the old route.
        st.push_route();
        if st.route_sent != Some(st.route.revision()) {
            return Err("guidance did not take the route (its queue is full)".to_owned());
        }
        st.set_settings(s);
        s.guidance.auto = true;
        st.set_settings(s);
        // The built-in simulator walks the station's route: it starts again on this one, from its start.
        // The old walker has ended before the trial's first instant, the new one starts after it.
        let restart =
            matches!(st.gps_source, GpsSourceConfig::Simulator { route: None }) && st.gps_worker.is_some();
        if restart {
            st.disconnect_gps();
        }
        let (since, start_s) = (Instant::now(), st.study_clock_s());
        if restart {
            st.connect_gps(st.gps_taps.clone());
        }
        st.study.nav_since = Some((since, st.route.revision()));
        let radius = |w: &crate::route::Waypoint| w.arrival_radius_m.unwrap_or(s.guidance.arrival_radius_m);
        Ok(NavRoute {
            start_s,
            name,
            polyline: gpx.path.as_ref().map_or_else(
                || gpx.waypoints.iter().map(crate::route::Waypoint::pos).collect(),
                |p| p.points().to_vec(),
            ),
            waypoints: gpx.waypoints.iter().map(|w| (w.pos(), radius(w))).collect(),
        })
    }

    fn end_navigation(&mut self) {
        let st = &mut *self.0;
        st.study.nav_since = None;
        let mut s = st.study.operator_settings.unwrap_or(st.settings);
        s.guidance.auto = false;
        st.set_settings(s);
    }
}

impl Station {
    /// The clock of the study session loaded [s]: liblsl's clock when the lab outputs had LSL on at load,
    /// else seconds since the load; before any load, seconds since the station started.
    pub fn study_clock_s(&self) -> f64 {
        match &self.study.lab {
            Some(lab) => lab.now(),
            None => self.epoch.elapsed().as_secs_f64(),
        }
    }

    /// The study loaded, if any.
    pub fn study(&self) -> Option<&StudyRunner> {
        self.study.runner.as_ref()
    }

    /// The timing between trials of the sessions loaded from now on.
    pub fn set_study_timing(&mut self, timing: Timing) {
        self.study.timing = timing;
    }

    /// What a view shows of the study loaded.
    pub fn study_view(&self) -> Option<StudyView> {
        self.study.runner.as_ref().map(StudyRunner::view)
    }

    /// How soon the runner needs the next pump (a view that sleeps between events wakes by then).
    pub fn study_wake_in(&self) -> Option<Duration> {
        let until = self.study.runner.as_ref()?.next_deadline_s()?;
        Some(Duration::from_secs_f64((until - self.study_clock_s()).clamp(0.0, 3600.0)))
    }

    /// Applies a study command; `Err` says why it was refused.
    pub fn study_command(&mut self, cmd: StudyCommand) -> Result<(), String> {
        self.log(LogEntry::Note { text: cmd.describe() });
        match cmd {
            StudyCommand::Load { protocol, participant, session, out_dir } => {
                if self
                    .study
                    .runner
                    .as_ref()
                    .is_some_and(|s| !s.phase().is_over() && s.phase() != StudyPhase::Ready)
                {
                    return Err("study load refused: a session runs; abort or unload it first".to_owned());
                }
                let limits =
                    self.vest.device.map_or_else(Limits::default, |d| Limits::default().tighter(&d.limits));
                let runner = StudyRunner::load(
                    &protocol,
                    &participant,
                    &session,
                    &out_dir,
                    &limits,
                    self.study.timing,
                )?;
                self.study.runner = Some(runner);
                self.study.operator_settings = None;
                Ok(())
            }
            StudyCommand::Unload => {
                self.with_study(|r, io| {
                    if !r.phase().is_over() && r.phase() != StudyPhase::Ready {
                        let _ = r.command(StudyCommand::Abort, io);
                    }
                });
                self.study.runner = None;
                self.study.lab = None;
                Ok(())
            }
            cmd => {
                let Some(mut r) = self.study.runner.take() else {
                    return Err(format!("{} refused: no study loaded", cmd.describe()));
                };
                let result = r.command(cmd, &mut Io(self));
                self.study.runner = Some(r);
                result
            }
        }
    }

    /// The runner's share of a pump: the vest's events of this pump, the walk of a navigation trial (this
    /// pump's fixes and guidance statuses), then its timers.
    pub(crate) fn study_pump(
        &mut self,
        events: &[VestEvent],
        fixes: &[GpsEvent],
        statuses: &[GuidanceStatus],
    ) {
        let tick =
            self.study.nav_since.map(|(since, revision)| nav_tick(since, revision, events, fixes, statuses));
        self.with_study(|r, io| {
            for ev in events {
                r.vest_event(ev, io);
            }
            if let Some(tick) = &tick {
                r.navigation_tick(tick, io);
            }
            r.turn(io);
        });
    }

    /// Ends a running session because the station ends (its vest already stopped).
    pub(crate) fn study_exit(&mut self) {
        self.with_study(StudyRunner::exit);
    }

    fn with_study(&mut self, f: impl FnOnce(&mut StudyRunner, &mut dyn StudyIo)) {
        if let Some(mut r) = self.study.runner.take() {
            f(&mut r, &mut Io(self));
            self.study.runner = Some(r);
        }
    }
}

/// What a pump tells a navigation trial that started at `since` on route revision `revision`: the fixes
/// that arrived since then, guidance's cues on that route minus the ones the vest refused or cancelled (each
/// refusal names its sender, wherever it happened), and its arrival at the last waypoint.
fn nav_tick(
    since: Instant,
    revision: u64,
    events: &[VestEvent],
    fixes: &[GpsEvent],
    statuses: &[GuidanceStatus],
) -> NavTick {
    let positions = fixes
        .iter()
        .filter_map(|ev| match ev {
            GpsEvent::Fix(f) if f.has_position() && f.received_at.is_some_and(|t| t >= since) => {
                f.lat_deg.zip(f.lon_deg).map(|(la, lo)| LatLon::new(la, lo))
            }
            _ => None,
        })
        .collect();
    let ours = |s: &&GuidanceStatus| s.route_revision >= revision;
    let sent = statuses.iter().filter(ours).filter(|s| s.sent && s.cue.is_some()).count();
    let refused = events
        .iter()
        .filter(|e| {
            matches!(
                e,
                VestEvent::Rejected { kind: CommandKind::Play, origin: Some(CommandOrigin::Guidance), .. }
            )
        })
        .count();
    NavTick {
        positions,
        cues: u32::try_from(sent.saturating_sub(refused)).unwrap_or(u32::MAX),
        finished: statuses.iter().filter(ours).any(|s| s.finished),
    }
}
