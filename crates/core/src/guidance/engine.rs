//! The guidance engine: fix checks, route progress, heading selection, rate limiting and manual overrides.

use crate::geo::{LatLon, LocalFrame, bearing_of_enu_deg, leg_offset, wrap_deg_180};
use crate::vest::Cue;

use super::heading::{self, CompassReading, Disagreement, HeadingChoice};
use super::path::aim_along;
use super::{
    Decision, GuidanceConfig, HeadingSource, LegGeometry, NavInput, NavState, Route, RouteEvent, Strategy,
    StrategyKind,
};

/// The guidance engine: route, strategy, rate limiter and override state.
#[derive(Debug)]
pub struct Guidance {
    route: Route,
    config: GuidanceConfig,
    strategy: Box<dyn Strategy>,
    busy_until_s: f64,
    last_cue: Option<(Cue, f64)>,
    last_directional: Option<Cue>,
    manual_until_s: f64,
    halted: bool,
    pending_event_cue: Option<Cue>,
    last_fix_time_s: Option<f64>,
    frozen: Option<(LatLon, f64)>,
    /// A pinned receiver diagnosed outside (the station's detector, with evidence the engine lacks): why.
    position_frozen: Option<String>,
    /// The rate limiter as it was before the cue of the last update was counted as played.
    undo: Option<RateState>,
    disagreement: Disagreement,
    /// Fix time since which the wearer has been off the route's path.
    off_path_since_s: Option<f64>,
}

/// What the rate limiter remembers, saved so a cue that never reached the wearer can be taken back.
#[derive(Debug, Clone, Copy)]
struct RateState {
    busy_until_s: f64,
    last_cue: Option<(Cue, f64)>,
    pending_event_cue: Option<Cue>,
}

impl Guidance {
    /// Tells guidance that the receiver's position is frozen (a pinned receiver, diagnosed by whoever sees
    /// more than the fixes: the station's detector with the compass and the stream's family) with why, or
    /// that it no longer is. While it is, every update holds (attention cues, no directional cue) and no
    /// fix counts towards an arrival: a frozen position says nothing of where the wearer is.
    pub fn set_position_frozen(&mut self, why: Option<String>) {
        self.position_frozen = why;
    }

    /// Why guidance holds on a position diagnosed frozen ([`Self::set_position_frozen`]), if it is.
    fn frozen_reason(&self) -> Option<String> {
        let why = self.position_frozen.as_ref()?;
        Some(format!("position frozen ({why}); no cue or arrival from it until it moves"))
    }

    /// Guidance along `route` with a built-in strategy.
    pub fn new(route: Route, config: GuidanceConfig, kind: StrategyKind) -> Self {
        let strategy = kind.build(&config);
        Self::with_strategy(route, config, strategy)
    }

    /// Guidance with any [`Strategy`] implementation.
    pub fn with_strategy(route: Route, config: GuidanceConfig, strategy: Box<dyn Strategy>) -> Self {
        Self {
            route,
            config,
            strategy,
            busy_until_s: f64::NEG_INFINITY,
            last_cue: None,
            last_directional: None,
            manual_until_s: f64::NEG_INFINITY,
            halted: false,
            pending_event_cue: None,
            last_fix_time_s: None,
            frozen: None,
            position_frozen: None,
            undo: None,
            disagreement: Disagreement::default(),
            off_path_since_s: None,
        }
    }

    fn rate_state(&self) -> RateState {
        RateState {
            busy_until_s: self.busy_until_s,
            last_cue: self.last_cue,
            pending_event_cue: self.pending_event_cue,
        }
    }

    /// The cue of the last [`Guidance::update`] did not reach the wearer (no vest, the vest refused it,
    /// automatic cues off or halted): the rate limiter forgets it, so it is not counted as played — the same
    /// cue may go at the next update instead of after its repeat interval, and an arrival announcement stays
    /// pending.
    pub fn not_played(&mut self) {
        if let Some(s) = self.undo.take() {
            self.busy_until_s = s.busy_until_s;
            self.last_cue = s.last_cue;
            self.pending_event_cue = s.pending_event_cue;
        }
    }

    /// The route (read-only).
    pub fn route(&self) -> &Route {
        &self.route
    }

    /// The route, for operator commands ([`Route::skip`], [`Route::back`]).
    pub fn route_mut(&mut self) -> &mut Route {
        &mut self.route
    }

    /// The settings.
    pub fn config(&self) -> &GuidanceConfig {
        &self.config
    }

    /// Sets the compass declination [deg, east +] (e.g. from WMM at the route start).
    pub fn set_declination_deg(&mut self, declination_deg: Option<f64>) {
        self.config.declination_deg = declination_deg;
    }

    /// The strategy's name.
    pub fn strategy_name(&self) -> &'static str {
        self.strategy.name()
    }

    /// Whether STOP ALL is in force.
    pub fn is_halted(&self) -> bool {
        self.halted
    }

    /// STOP ALL: turn every tactor off now and send nothing automatic until [`Guidance::resume`]. Always
    /// wins over everything else, including a pattern that is playing.
    pub fn stop_all(&mut self, now_s: f64) -> Decision {
        self.halted = true;
        self.busy_until_s = now_s;
        let mut d = self.blank(NavState::Halted, "STOP ALL: all tactors off, guidance halted".to_owned());
        d.stop_all = true;
        d
    }

    /// Ends a STOP ALL; automatic cues start again at the next update.
    pub fn resume(&mut self) {
        self.halted = false;
    }

    /// A manual cue from the operator: plays now (cutting a playing automatic pattern) and mutes automatic
    /// cues for [`GuidanceConfig::manual_hold_s`] after it ends. Refused (no cue) while halted: STOP ALL wins.
    pub fn manual(&mut self, cue: Cue, now_s: f64) -> Decision {
        if self.halted {
            return self.blank(NavState::Halted, format!("manual {} refused: STOP ALL in force", cue.name()));
        }
        let pattern = cue.pattern(self.config.on_ms);
        let end_s = now_s + f64::from(pattern.total_ms()) / 1000.0;
        self.busy_until_s = end_s;
        self.manual_until_s = end_s + self.config.manual_hold_s;
        self.last_cue = Some((cue, end_s));
        let mut d = self.blank(NavState::Manual, format!("manual {}", cue.name()));
        d.cue = Some(cue);
        d.wanted = Some(cue);
        d.pattern = Some(pattern);
        d
    }

    fn blank(&self, state: NavState, reason: String) -> Decision {
        Decision {
            cue: None,
            pattern: None,
            stop_all: false,
            wanted: None,
            state,
            event: None,
            heading_source: HeadingSource::None,
            heading_deg: None,
            heading_rule: String::new(),
            compass_disturbed: self.disagreement.disturbed(),
            compass_minus_cog_deg: self.disagreement.last_diff_deg,
            standing: false,
            bearing_deg: None,
            bearing_error_deg: None,
            distance_m: None,
            cross_track_m: None,
            off_path_s: None,
            reroute: false,
            waypoint_index: self.route.active_index(),
            waypoint_name: self.route.active().name.clone(),
            reason,
        }
    }

    /// Picks the heading by [`GuidanceConfig::heading_mode`] for `input` alone (its `compass_deg` taken as
    /// a fresh reading without quality), with the current "compass disturbed?" verdict. In the default
    /// [`super::HeadingMode::Cog`]: COG if `speed >= cog_min_speed`, else true heading, else compass +
    /// declination.
    pub fn select_heading(&self, input: &NavInput) -> (HeadingSource, Option<f64>) {
        let compass = input.compass_deg.map(CompassReading::fresh);
        let c = heading::choose(&self.config, input, compass.as_ref(), self.disagreement.disturbed());
        (c.source, c.heading_deg)
    }

    /// Whether the compass is currently suspected disturbed (see [`Decision::compass_disturbed`]).
    pub fn compass_disturbed(&self) -> bool {
        self.disagreement.disturbed()
    }

    fn estimated_error_m(&self, input: &NavInput) -> Option<f64> {
        input
            .accuracy_m
            .filter(|a| a.is_finite() && *a >= 0.0)
            .or_else(|| input.hdop.filter(|h| h.is_finite() && *h >= 0.0).map(|h| h * self.config.uere_m))
    }

    /// Whether the rate limiter lets `cue` play at `now_s`: see [`Guidance::allowed_from_s`].
    fn allowed(&self, cue: Cue, now_s: f64) -> bool {
        now_s >= self.allowed_from_s(cue)
    }

    /// From when the rate limiter lets `cue` play [s, on [`Guidance::update`]'s clock]: once the previous
    /// pattern has ended and `gap_s` passed; for the same cue again, once its repeat interval has also passed
    /// since that cue's pattern **ended** (so a long pattern plus the wearer's reaction and turn are over
    /// before it is repeated).
    pub fn allowed_from_s(&self, cue: Cue) -> f64 {
        let free_s = self.busy_until_s + self.config.gap_s;
        // Turn-in-place cues of one side count as the same cue whatever their size: a smaller turn to the
        // same side while the wearer is still turning would add to the first one.
        let family = |c: Cue| match c {
            Cue::RotateLeft(_) => Cue::TurnLeft,
            Cue::RotateRight(_) => Cue::TurnRight,
            other => other,
        };
        match self.last_cue {
            Some((last, end_s)) if last == cue || (cue.is_turn_in_place() && family(last) == family(cue)) => {
                let interval = match cue {
                    Cue::Forward => self.config.forward_repeat_s,
                    Cue::Attention => self.config.attention_repeat_s,
                    _ => self.config.repeat_s,
                };
                free_s.max(end_s + interval)
            }
            _ => free_s,
        }
    }

    fn emit(&mut self, d: &mut Decision, cue: Cue, now_s: f64) {
        d.wanted = Some(cue);
        if self.allowed(cue, now_s) {
            let before = self.rate_state();
            self.undo.get_or_insert(before);
            let pattern = cue.pattern(self.config.on_ms);
            self.busy_until_s = now_s + f64::from(pattern.total_ms()) / 1000.0;
            self.last_cue = Some((cue, self.busy_until_s));
            d.cue = Some(cue);
            d.pattern = Some(pattern);
        }
    }

    /// One guidance step at time `now_s` [s]. See the module doc for the order of the rules.
    /// `input.compass_deg`, if any, counts as a fresh reading without a quality figure.
    pub fn update(&mut self, input: &NavInput, now_s: f64) -> Decision {
        let compass = input.compass_deg.map(CompassReading::fresh);
        self.update_with_compass(input, compass, now_s)
    }

    /// [`Guidance::update`] with a compass reading that carries its age and quality (`compass` replaces
    /// `input.compass_deg`; `None` = no compass).
    pub fn update_with_compass(
        &mut self,
        input: &NavInput,
        compass: Option<CompassReading>,
        now_s: f64,
    ) -> Decision {
        self.undo = None;
        if self.halted {
            return self.blank(NavState::Halted, "STOP ALL in force (resume to guide)".to_owned());
        }
        let manual = now_s < self.manual_until_s;

        // Fix checks.
        let pos = input.position.and_then(|p| p.validated().ok());
        let compass = compass.as_ref();
        let Some(pos) = pos else {
            return self.hold(input, compass, now_s, manual, "no GPS fix");
        };
        if !(input.fix_age_s.is_finite() && input.fix_age_s <= self.config.max_fix_age_s) {
            let why = format!("GPS fix stale ({:.1} s old)", input.fix_age_s);
            return self.hold(input, compass, now_s, manual, &why);
        }
        if let Some(err) = self.estimated_error_m(input).filter(|e| *e > self.config.max_error_m) {
            return self.hold(input, compass, now_s, manual, &format!("GPS fix too poor (~{err:.0} m)"));
        }
        // Compass against COG: only a fresh, trustworthy fix is evidence.
        self.disagreement.observe(&self.config, input, compass, now_s);

        // Route progress, once per fix: `update` may run more often than fixes arrive (the fix's time is
        // `now - age`), and arrival confirmation counts fixes, not updates.
        let fix_time_s = now_s - input.fix_age_s;
        let new_fix = self.last_fix_time_s.is_none_or(|t| (t - fix_time_s).abs() > 1e-6);
        self.last_fix_time_s = Some(fix_time_s);
        if let Some(why) = self.frozen_reason() {
            return self.hold(input, compass, now_s, manual, &why);
        }
        // Pinned receiver: the same position for a while although the receiver says it moves.
        let same =
            |a: LatLon| (a.lat_deg - pos.lat_deg).abs() < 1e-9 && (a.lon_deg - pos.lon_deg).abs() < 1e-9;
        let since_s = match self.frozen {
            Some((p, t)) if same(p) => t,
            _ => fix_time_s,
        };
        self.frozen = Some((pos, since_s));
        let moving = input.speed_m_s.is_some_and(|v| v.is_finite() && v >= self.config.cog_min_speed_m_s);
        if moving && fix_time_s - since_s > self.config.max_frozen_s {
            let why = format!(
                "position frozen for {:.0} s while moving: receiver pinned (static navigation?), walk faster",
                fix_time_s - since_s
            );
            return self.hold(input, compass, now_s, manual, &why);
        }
        let event = if new_fix { self.route.observe(self.config.earth, pos) } else { None };
        match event {
            Some(RouteEvent::Arrived(_)) => self.pending_event_cue = Some(Cue::Arrived),
            Some(RouteEvent::Finished) => self.pending_event_cue = Some(Cue::Stop),
            _ => {}
        }
        let choice = heading::choose(&self.config, input, compass, self.disagreement.disturbed());
        let heading = choice.heading_deg;
        let earth = self.config.earth;
        let target = self.route.active().pos();
        let distance_m = earth.distance_m(pos, target);
        let along = if self.route.is_finished() {
            None
        } else {
            self.route.active_path().and_then(|leg| aim_along(earth, leg, pos, self.config.lookahead_m))
        };
        let cross_track_m = match &along {
            Some(a) => Some(a.cross_track_m),
            None => self.route.previous().map(|w| leg_offset(earth, w.pos(), target, pos).cross_track_m),
        };
        let off = along.is_some_and(|a| a.cross_track_m.abs() > self.config.off_path_m);
        if !off {
            self.off_path_since_s = None;
        } else if self.off_path_since_s.is_none() {
            self.off_path_since_s = Some(fix_time_s);
        }

        let mut d = self.blank(NavState::Guiding, String::new());
        d.event = event;
        d.cross_track_m = cross_track_m;
        d.off_path_s = self.off_path_since_s.map(|t| fix_time_s - t);
        d.reroute = d.off_path_s.is_some_and(|s| s >= self.config.off_path_s);
        Self::show_heading(&mut d, choice);

        if self.route.is_finished() {
            d.state = NavState::Finished;
            "route finished".clone_into(&mut d.reason);
            self.play_pending(&mut d, now_s, manual);
            return d;
        }
        d.distance_m = Some(distance_m);
        if let Some(cue) = self.pending_event_cue {
            // An arrival announcement goes first; directional cues wait for it.
            d.reason = format!("reached a waypoint; next {} at {distance_m:.0} m", self.route.active().name);
            d.wanted = Some(cue);
            self.play_pending(&mut d, now_s, manual);
            return d;
        }

        let frame = LocalFrame::new(pos, earth);
        let leg = match along {
            // Along a path every strategy aims at the point ahead on it: a straight line to the waypoint
            // would cut through what the path goes round.
            Some(a) => LegGeometry { target_en_m: a.aim_en_m, from_en_m: Some(a.foot_en_m) },
            None => LegGeometry {
                target_en_m: frame.enu_from_wgs84(target),
                from_en_m: self.route.previous().map(|w| frame.enu_from_wgs84(w.pos())),
            },
        };
        let aim = self.strategy.aim_en_m(&leg);
        let bearing = bearing_of_enu_deg(aim);
        d.bearing_deg = Some(bearing);
        let Some(heading) = heading else {
            let why = format!("no heading: {}", d.heading_rule);
            return self.hold_with(d, now_s, manual, &why);
        };
        self.direct(d, input, heading, now_s, manual)
    }

    /// The directional cue for the wearer at heading `heading_deg` (the decision `d` carries the bearing
    /// to the aim, the distances and the heading source): turn-in-place standing, the walking vocabulary
    /// moving, rate-limited or muted by a manual hold.
    fn direct(
        &mut self,
        mut d: Decision,
        input: &NavInput,
        heading: f64,
        now_s: f64,
        manual: bool,
    ) -> Decision {
        let (Some(bearing), Some(distance_m)) = (d.bearing_deg, d.distance_m) else { return d };
        let (source, cross_track_m) = (d.heading_source, d.cross_track_m);
        let error = wrap_deg_180(bearing - heading);
        d.bearing_error_deg = Some(error);
        let speed = input.speed_m_s.filter(|s| s.is_finite());
        let standing = self.config.turn_in_place && speed.is_none_or(|s| s < self.config.cog_min_speed_m_s);
        d.standing = standing;
        if standing && self.route.is_armed() && distance_m <= self.route.active_radii_m().0 {
            // On the waypoint its bearing is GPS noise: no turning on the spot toward it while arrival is
            // being confirmed (the next update after arrival aims at the next waypoint).
            d.reason =
                format!("standing at {} ({distance_m:.0} m): confirming arrival", self.route.active().name);
            return d;
        }
        let cue = if standing {
            self.config.thresholds.classify_in_place(error)
        } else {
            self.config.thresholds.classify(error, self.last_directional)
        };
        self.last_directional = Some(cue);
        let xt = cross_track_m.map_or(String::new(), |x| format!(", cross-track {x:+.1} m"));
        let still = if standing { " standing," } else { "" };
        let warn = if d.compass_disturbed { " [compass disturbed?]" } else { "" };
        d.reason = format!(
            "{}:{still} bearing error {error:+.0}° ({} {heading:.0}°, aim {bearing:.0}°), {} at {distance_m:.0} m{xt}{warn}",
            cue.name(),
            source.name(),
            self.route.active().name,
        );
        if manual {
            d.state = NavState::Manual;
            d.wanted = Some(cue);
            d.reason = format!("manual hold; would say {}", d.reason);
        } else {
            self.emit(&mut d, cue, now_s);
        }
        d
    }

    fn play_pending(&mut self, d: &mut Decision, now_s: f64, manual: bool) {
        let Some(cue) = self.pending_event_cue else { return };
        d.wanted = Some(cue);
        if manual {
            // Arrival news is kept until the manual hold ends.
            return;
        }
        // Announcements override the per-cue repeat interval, but never cut a playing pattern.
        if now_s >= self.busy_until_s + self.config.gap_s {
            self.undo = Some(self.rate_state());
            self.last_cue = None;
            self.emit(d, cue, now_s);
            self.pending_event_cue = None;
        }
    }

    fn show_heading(d: &mut Decision, choice: HeadingChoice) {
        d.heading_source = choice.source;
        d.heading_deg = choice.heading_deg;
        d.heading_rule = choice.rule;
    }

    fn hold(
        &mut self,
        input: &NavInput,
        compass: Option<&CompassReading>,
        now_s: f64,
        manual: bool,
        why: &str,
    ) -> Decision {
        let mut d = self.blank(NavState::Hold, String::new());
        Self::show_heading(
            &mut d,
            heading::choose(&self.config, input, compass, self.disagreement.disturbed()),
        );
        self.hold_with(d, now_s, manual, why)
    }

    fn hold_with(&mut self, mut d: Decision, now_s: f64, manual: bool, why: &str) -> Decision {
        d.state = if manual { NavState::Manual } else { NavState::Hold };
        d.reason = format!("hold: {why}");
        self.last_directional = None;
        if manual {
            d.wanted = Some(Cue::Attention);
        } else {
            self.emit(&mut d, Cue::Attention, now_s);
        }
        d
    }
}
