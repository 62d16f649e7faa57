//! Guidance: from a GPS fix and a heading to one tactile cue (thesis §5–§6).
//!
//! Pure and clock-free: [`Guidance::update`] takes a [`NavInput`] and the current time `now_s` (any
//! monotonic seconds) and returns a [`Decision`]: at most one [`Cue`] with its [`Pattern`], and why.
//!
//! Pipeline of one update (details in `docs/guidance.md`):
//! 1. **Manual priority.** STOP ALL ([`Guidance::stop_all`]) halts everything until [`Guidance::resume`];
//!    a manual cue ([`Guidance::manual`]) plays at once and mutes automatic cues for
//!    [`GuidanceConfig::manual_hold_s`].
//! 2. **Fix checks.** No fix, a fix older than [`GuidanceConfig::max_fix_age_s`], or an estimated error above
//!    [`GuidanceConfig::max_error_m`] gives no directional cue: `Attention` (hold).
//! 3. **Route.** Arrival at the active waypoint (within the arrival radius for
//!    [`RouteConfig::confirm_fixes`] consecutive fixes) plays `Arrived` and advances; the last waypoint plays
//!    `Stop` (or wraps round when the route loops).
//! 4. **Heading source.** COG when moving at least [`GuidanceConfig::cog_min_speed_m_s`], else true heading
//!    (HDT/THS), else a magnetic compass corrected by the declination; none → `Attention`.
//! 5. **Strategy.** A [`Strategy`] gives the point to aim at; the bearing error to it picks the cue
//!    ([`CueThresholds`]).
//! 6. **Rate limit.** One cue at a time (not before the previous pattern ended plus a gap), the same cue not
//!    again before its repeat interval (longer for `Forward`).
//!
//! ```
//! use vestnav_core::geo::LatLon;
//! use vestnav_core::guidance::{Guidance, GuidanceConfig, NavInput, Route, RouteConfig, StrategyKind, Waypoint};
//! use vestnav_core::vest::Cue;
//! let route = Route::new(vec![Waypoint::new("gate", LatLon::new(42.3570, -71.1010))], RouteConfig::default())
//!     .unwrap();
//! let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::BearingOnly);
//! // Walking due east, 1.4 m/s, 50 m south of the waypoint: it is to the left (bearing ~ 0 deg).
//! let here = LatLon::new(42.35655, -71.1010);
//! let d = g.update(&NavInput::moving(here, 90.0, 1.4), 0.0);
//! assert_eq!(d.cue, Some(Cue::TurnLeft));
//! ```

use glam::DVec2;
use serde::{Deserialize, Serialize};

use crate::geo::{
    Earth, LatLon, LocalFrame, bearing_of_enu_deg, leg_offset, true_from_magnetic_deg, wrap_deg_180,
};
use crate::vest::{Cue, DEFAULT_ON_MS, Pattern};

/// Errors building a route.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RouteError {
    /// A route needs at least one waypoint.
    #[error("the route has no waypoints")]
    Empty,
    /// A waypoint with a bad latitude/longitude.
    #[error("waypoint {index} ({name}): {source}")]
    BadWaypoint {
        /// Index of the waypoint.
        index: usize,
        /// Its name.
        name: String,
        /// What is wrong.
        source: crate::geo::GeoError,
    },
    /// Arrival radius not positive and finite, or confirm count zero.
    #[error("invalid route setting: {0}")]
    BadConfig(&'static str),
}

/// A named waypoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Waypoint {
    /// Name shown to the operator.
    pub name: String,
    /// Position.
    pub pos: LatLon,
}

impl Waypoint {
    /// A waypoint named `name` at `pos`.
    pub fn new(name: impl Into<String>, pos: LatLon) -> Self {
        Self { name: name.into(), pos }
    }
}

/// Settings of a route: arrival and its hysteresis, looping.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RouteConfig {
    /// A waypoint is reached within this distance [m]. Default 8 m: about 2.5x the `SiRF` III's open-sky
    /// horizontal RMS (~3 m), so a noisy fix rarely misses it.
    pub arrival_radius_m: f64,
    /// Consecutive fixes inside the radius needed to count an arrival (default 2): one noisy fix does not
    /// arrive.
    pub confirm_fixes: u32,
    /// After [`Route::back`] the waypoint only arms again once the wearer is farther than this [m] (default
    /// 1.5x the arrival radius), so stepping back while standing on it does not re-arrive at once.
    pub rearm_radius_m: f64,
    /// A waypoint passed abeam within this distance [m] counts as *passed* (advance, logged as missed)
    /// instead of making the wearer turn around (default 2x the arrival radius).
    pub pass_radius_m: f64,
    /// After the last waypoint, start again at the first.
    pub looped: bool,
}

impl Default for RouteConfig {
    fn default() -> Self {
        Self {
            arrival_radius_m: 8.0,
            confirm_fixes: 2,
            rearm_radius_m: 12.0,
            pass_radius_m: 16.0,
            looped: false,
        }
    }
}

/// What happened to the route in one update.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RouteEvent {
    /// The active waypoint was reached (index); the next one is active.
    Arrived(usize),
    /// The active waypoint was passed close by without reaching the arrival radius (index).
    Passed(usize),
    /// The last waypoint was reached (or passed): the route is finished.
    Finished,
}

/// A route of waypoints with the index of the active one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Route {
    waypoints: Vec<Waypoint>,
    config: RouteConfig,
    active: usize,
    finished: bool,
    inside_count: u32,
    armed: bool,
    laps: u32,
}

impl Route {
    /// A route; the first waypoint is active.
    pub fn new(waypoints: Vec<Waypoint>, config: RouteConfig) -> Result<Self, RouteError> {
        if waypoints.is_empty() {
            return Err(RouteError::Empty);
        }
        for (index, w) in waypoints.iter().enumerate() {
            w.pos.validated().map_err(|source| RouteError::BadWaypoint {
                index,
                name: w.name.clone(),
                source,
            })?;
        }
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if !positive(config.arrival_radius_m)
            || !positive(config.rearm_radius_m)
            || !positive(config.pass_radius_m)
        {
            return Err(RouteError::BadConfig("radii must be positive"));
        }
        if config.confirm_fixes == 0 {
            return Err(RouteError::BadConfig("confirm_fixes must be at least 1"));
        }
        Ok(Self { waypoints, config, active: 0, finished: false, inside_count: 0, armed: true, laps: 0 })
    }

    /// The waypoints.
    pub fn waypoints(&self) -> &[Waypoint] {
        &self.waypoints
    }

    /// The settings.
    pub fn config(&self) -> &RouteConfig {
        &self.config
    }

    /// Index of the active waypoint.
    pub fn active_index(&self) -> usize {
        self.active
    }

    /// The active waypoint.
    pub fn active(&self) -> &Waypoint {
        // `active` is always < len (kept by every mutator) and the route is never empty.
        &self.waypoints[self.active.min(self.waypoints.len() - 1)]
    }

    /// The waypoint before the active one (start of the active leg), if any.
    pub fn previous(&self) -> Option<&Waypoint> {
        if self.active > 0 {
            self.waypoints.get(self.active - 1)
        } else if self.config.looped && self.waypoints.len() > 1 && self.laps > 0 {
            // In a loop, the leg into waypoint 0 comes from the last waypoint after the first lap.
            self.waypoints.last()
        } else {
            None
        }
    }

    /// Completed laps of a looped route.
    pub fn laps(&self) -> u32 {
        self.laps
    }

    /// Whether the route is finished (never for a looped route).
    pub fn is_finished(&self) -> bool {
        self.finished
    }

    /// Skips the active waypoint (operator command): the next one becomes active. At the last waypoint of an
    /// open route this finishes the route.
    pub fn skip(&mut self) -> Option<RouteEvent> {
        self.advance()
    }

    /// Goes back to the previous waypoint (operator command). It arms only after the wearer is farther than
    /// [`RouteConfig::rearm_radius_m`] from it. Un-finishes a finished route.
    pub fn back(&mut self) {
        if self.finished {
            self.finished = false;
        } else if self.active > 0 {
            self.active -= 1;
        } else if self.config.looped && self.laps > 0 {
            self.active = self.waypoints.len() - 1;
            self.laps -= 1;
        }
        self.inside_count = 0;
        self.armed = false;
    }

    fn advance(&mut self) -> Option<RouteEvent> {
        if self.finished {
            return None;
        }
        self.inside_count = 0;
        self.armed = true;
        if self.active + 1 < self.waypoints.len() {
            self.active += 1;
            None
        } else if self.config.looped {
            self.active = 0;
            self.laps += 1;
            None
        } else {
            self.finished = true;
            Some(RouteEvent::Finished)
        }
    }

    /// Feeds one fix: arrival with confirmation and re-arming, or passing abeam. Returns what happened.
    ///
    /// Arrival: `d <= arrival_radius` for `confirm_fixes` consecutive fixes while armed. Passing: the fix is
    /// past the waypoint along the active leg (`along > leg length`) and within `pass_radius`. Re-arming:
    /// `d > rearm_radius`.
    pub fn observe(&mut self, earth: Earth, pos: LatLon) -> Option<RouteEvent> {
        if self.finished {
            return None;
        }
        let index = self.active;
        let target = self.active().pos;
        let d = earth.distance_m(pos, target);
        if !self.armed {
            if d > self.config.rearm_radius_m {
                self.armed = true;
            }
            return None;
        }
        if d <= self.config.arrival_radius_m {
            self.inside_count += 1;
            if self.inside_count >= self.config.confirm_fixes {
                return Some(self.advance().unwrap_or(RouteEvent::Arrived(index)));
            }
            return None;
        }
        self.inside_count = 0;
        if let Some(prev) = self.previous().map(|w| w.pos) {
            let off = leg_offset(earth, prev, target, pos);
            if off.leg_length_m > 0.0
                && off.along_track_m > off.leg_length_m
                && d <= self.config.pass_radius_m
            {
                return Some(self.advance().map_or(RouteEvent::Passed(index), |_| RouteEvent::Finished));
            }
        }
        None
    }
}

/// Which heading was used for a decision.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum HeadingSource {
    /// Course over ground from the receiver (RMC/VTG), used while moving fast enough.
    Cog,
    /// True heading from the receiver (HDT/THS).
    TrueHeading,
    /// Magnetic compass plus the configured declination.
    Compass,
    /// No usable heading.
    None,
}

impl HeadingSource {
    /// Short name for the operator.
    pub fn name(self) -> &'static str {
        match self {
            Self::Cog => "COG",
            Self::TrueHeading => "true heading",
            Self::Compass => "compass",
            Self::None => "none",
        }
    }
}

/// Everything guidance needs from the sensors at one instant (the app converts the device's fixes to this).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct NavInput {
    /// Last fix position; `None` when there has been no fix.
    pub position: Option<LatLon>,
    /// Age of that fix at `now_s` [s].
    pub fix_age_s: f64,
    /// Speed over ground [m/s].
    pub speed_m_s: Option<f64>,
    /// Course over ground, true [deg].
    pub cog_deg: Option<f64>,
    /// True heading from the receiver (HDT/THS) [deg].
    pub true_heading_deg: Option<f64>,
    /// Magnetic compass heading [deg] (corrected with [`GuidanceConfig::declination_deg`]).
    pub compass_deg: Option<f64>,
    /// Horizontal dilution of precision.
    pub hdop: Option<f64>,
    /// Horizontal accuracy estimate from the receiver [m] (e.g. GST or PGRME), preferred to HDOP.
    pub accuracy_m: Option<f64>,
}

impl NavInput {
    /// A fresh fix of a walker moving at `speed_m_s` on course `cog_deg` (convenience for tests and docs).
    pub fn moving(position: LatLon, cog_deg: f64, speed_m_s: f64) -> Self {
        Self {
            position: Some(position),
            speed_m_s: Some(speed_m_s),
            cog_deg: Some(cog_deg),
            ..Self::default()
        }
    }
}

/// Bearing-error thresholds of the cues [deg] (|error| measured from the heading to the aim point).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CueThresholds {
    /// Up to this: `Forward` (default 15°, about the walking heading wobble).
    pub forward_deg: f64,
    /// Up to this: `SlightLeft/Right` (default 45°).
    pub slight_deg: f64,
    /// Up to this: `TurnLeft/Right` (default 135°); beyond: `TurnAround`.
    pub turn_deg: f64,
    /// Hysteresis at each boundary (default 5°): the previous class is kept while the error is within this of
    /// the boundary, so a bearing error hovering at 15° does not alternate Forward/Slight.
    pub hysteresis_deg: f64,
}

impl Default for CueThresholds {
    fn default() -> Self {
        Self { forward_deg: 15.0, slight_deg: 45.0, turn_deg: 135.0, hysteresis_deg: 5.0 }
    }
}

impl CueThresholds {
    /// The cue for a bearing error `e` (deg, positive = target to the right), given the previous directional
    /// cue for hysteresis.
    ///
    /// Class by |e|: `<= forward` Forward, `<= slight` Slight, `<= turn` Turn, else `TurnAround`; the side is the
    /// sign of `e`. With a previous class, a boundary between it and a neighbour moves by `hysteresis` away
    /// from the previous class (so leaving it takes `hysteresis` more error).
    pub fn classify(&self, error_deg: f64, previous: Option<Cue>) -> Cue {
        let mag = error_deg.abs();
        let bounds = [self.forward_deg, self.slight_deg, self.turn_deg];
        let prev_level = previous.and_then(level_of);
        let level = |m: f64| -> usize {
            bounds
                .iter()
                .enumerate()
                .map(|(i, &b)| {
                    // Boundary i separates level i and i+1.
                    match prev_level {
                        Some(p) if p <= i => b + self.hysteresis_deg,
                        Some(_) => b - self.hysteresis_deg,
                        None => b,
                    }
                })
                .filter(|&b| m > b)
                .count()
        };
        let right = error_deg > 0.0;
        match level(mag) {
            0 => Cue::Forward,
            1 if right => Cue::SlightRight,
            1 => Cue::SlightLeft,
            2 if right => Cue::TurnRight,
            2 => Cue::TurnLeft,
            _ => Cue::TurnAround,
        }
    }
}

fn level_of(cue: Cue) -> Option<usize> {
    match cue {
        Cue::Forward => Some(0),
        Cue::SlightLeft | Cue::SlightRight => Some(1),
        Cue::TurnLeft | Cue::TurnRight => Some(2),
        Cue::TurnAround => Some(3),
        _ => None,
    }
}

/// Settings of guidance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GuidanceConfig {
    /// Earth model of all distances (WGS-84 by default).
    pub earth: Earth,
    /// COG is trusted at or above this speed [m/s] (default 0.8: below a walk COG from a 1 Hz receiver is
    /// mostly noise).
    pub cog_min_speed_m_s: f64,
    /// Fixes older than this give no directional cue [s] (default 3 s = three missed 1 Hz epochs).
    pub max_fix_age_s: f64,
    /// Estimated horizontal error above this gives no directional cue [m] (default 25 m).
    pub max_error_m: f64,
    /// A position repeated unchanged for longer than this while the receiver reports at least
    /// `cog_min_speed_m_s` is treated as pinned (`SiRF` static navigation) and gives no directional cue [s]
    /// (default 5 s).
    pub max_frozen_s: f64,
    /// User equivalent range error to turn HDOP into metres when no accuracy is given [m] (default 5 m).
    pub uere_m: f64,
    /// Declination for the compass [deg, east +]; `None` = compass unusable. Set it from
    /// [`crate::geo::declination_deg`].
    pub declination_deg: Option<f64>,
    /// Cue thresholds.
    pub thresholds: CueThresholds,
    /// On-time of each pattern step [ms] (thesis: 500).
    pub on_ms: u16,
    /// Quiet gap after a pattern ends before the next cue [s] (default 0.5 s).
    pub gap_s: f64,
    /// Minimum interval from the end of a cue's pattern to the same cue again [s] (default 3 s).
    pub repeat_s: f64,
    /// Minimum interval between two `Forward` cues (from the end of the first) [s] (default 10 s:
    /// reassurance, not nagging).
    pub forward_repeat_s: f64,
    /// Minimum interval between two `Attention` cues (from the end of the first) [s] (default 5 s).
    pub attention_repeat_s: f64,
    /// A manual cue mutes automatic cues for this long [s] (default 10 s).
    pub manual_hold_s: f64,
    /// Look-ahead distance of the pursuit strategy [m] (default 15 m).
    pub lookahead_m: f64,
}

impl Default for GuidanceConfig {
    fn default() -> Self {
        Self {
            earth: Earth::Wgs84,
            cog_min_speed_m_s: 0.8,
            max_fix_age_s: 3.0,
            max_error_m: 25.0,
            max_frozen_s: 5.0,
            uere_m: 5.0,
            declination_deg: None,
            thresholds: CueThresholds::default(),
            on_ms: DEFAULT_ON_MS,
            gap_s: 0.5,
            repeat_s: 3.0,
            forward_repeat_s: 10.0,
            attention_repeat_s: 5.0,
            manual_hold_s: 10.0,
            lookahead_m: 15.0,
        }
    }
}

/// The geometry a strategy sees, in a local east/north frame centred on the wearer (wearer at the origin).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegGeometry {
    /// The active waypoint [m].
    pub target_en_m: DVec2,
    /// The start of the active leg (previous waypoint), if any [m].
    pub from_en_m: Option<DVec2>,
}

/// A guidance strategy: where to aim, given the leg. Implementations are pure.
pub trait Strategy: std::fmt::Debug + Send {
    /// Short name (`bearing`, `pursuit`).
    fn name(&self) -> &'static str;
    /// The point to aim at, in the wearer-centred frame of `leg` [m].
    fn aim_en_m(&self, leg: &LegGeometry) -> DVec2;
}

/// Bearing-only: aim straight at the active waypoint.
#[derive(Debug, Clone, Copy, Default)]
pub struct BearingOnly;

impl Strategy for BearingOnly {
    fn name(&self) -> &'static str {
        "bearing"
    }
    fn aim_en_m(&self, leg: &LegGeometry) -> DVec2 {
        leg.target_en_m
    }
}

/// Cross-track-corrected pursuit ("carrot chasing"): aim at the point `lookahead_m` further along the leg
/// than the wearer's foot point on it; once that passes the waypoint, aim at the waypoint.
///
/// With leg start `a`, end `b`, unit `u = (b - a)/|b - a|` and the wearer at the origin `p = 0`: the foot point
/// is at `s = (p - a)·u`, the aim point `a + min(s + L, |b - a|) u`. A cross-track error `x` thus turns into a
/// bearing error of `atan(x / L)` toward the leg: the wearer converges on the line instead of cutting
/// corners, like pure pursuit in path following (Coulter 1992, CMU-RI-TR-92-01).
#[derive(Debug, Clone, Copy)]
pub struct Pursuit {
    /// Look-ahead distance L [m].
    pub lookahead_m: f64,
}

impl Strategy for Pursuit {
    fn name(&self) -> &'static str {
        "pursuit"
    }
    fn aim_en_m(&self, leg: &LegGeometry) -> DVec2 {
        let Some(a) = leg.from_en_m else { return leg.target_en_m };
        let ab = leg.target_en_m - a;
        let len = ab.length();
        if len < 1e-9 {
            return leg.target_en_m;
        }
        let u = ab / len;
        let s = (-a).dot(u);
        let t = (s + self.lookahead_m.max(0.0)).clamp(0.0, len);
        a + u * t
    }
}

/// The built-in strategies, by name (for the CLI and the app).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum StrategyKind {
    /// [`BearingOnly`].
    BearingOnly,
    /// [`Pursuit`] with [`GuidanceConfig::lookahead_m`].
    Pursuit,
}

impl StrategyKind {
    /// Every strategy.
    pub const ALL: [Self; 2] = [Self::BearingOnly, Self::Pursuit];

    /// CLI name.
    pub fn name(self) -> &'static str {
        match self {
            Self::BearingOnly => "bearing",
            Self::Pursuit => "pursuit",
        }
    }

    /// Parses a CLI name (`bearing` or `pursuit`).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    fn build(self, config: &GuidanceConfig) -> Box<dyn Strategy> {
        match self {
            Self::BearingOnly => Box::new(BearingOnly),
            Self::Pursuit => Box::new(Pursuit { lookahead_m: config.lookahead_m }),
        }
    }
}

/// The state guidance is in after an update.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum NavState {
    /// Guiding toward the active waypoint.
    Guiding,
    /// Holding: no fix, stale fix, poor fix or no heading.
    Hold,
    /// A manual cue is playing or muting automatic cues.
    Manual,
    /// STOP ALL is in force.
    Halted,
    /// The route is finished.
    Finished,
}

/// What guidance decided, and why (the app shows `reason` and the numbers).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Decision {
    /// The cue to play now, if any.
    pub cue: Option<Cue>,
    /// Its pattern (with the configured on-time).
    pub pattern: Option<Pattern>,
    /// Turn every tactor off now (STOP ALL); always obey this first.
    pub stop_all: bool,
    /// The cue guidance wants at this instant before rate limiting (what `cue` would be if allowed).
    pub wanted: Option<Cue>,
    /// State after the update.
    pub state: NavState,
    /// Route event of this update (arrival, pass, finish).
    pub event: Option<RouteEvent>,
    /// Heading source used.
    pub heading_source: HeadingSource,
    /// Heading used [deg, true].
    pub heading_deg: Option<f64>,
    /// Bearing to the aim point [deg, true].
    pub bearing_deg: Option<f64>,
    /// Bearing error `bearing - heading` in (-180, 180] [deg], positive = aim point to the right.
    pub bearing_error_deg: Option<f64>,
    /// Distance to the active waypoint [m].
    pub distance_m: Option<f64>,
    /// Cross-track error to the active leg [m], positive = right of the leg.
    pub cross_track_m: Option<f64>,
    /// Index of the active waypoint (after the update).
    pub waypoint_index: usize,
    /// Name of the active waypoint.
    pub waypoint_name: String,
    /// One line for the operator: what and why.
    pub reason: String,
}

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
    /// The rate limiter as it was before the cue of the last update was counted as played.
    undo: Option<RateState>,
}

/// What the rate limiter remembers, saved so a cue that never reached the wearer can be taken back.
#[derive(Debug, Clone, Copy)]
struct RateState {
    busy_until_s: f64,
    last_cue: Option<(Cue, f64)>,
    pending_event_cue: Option<Cue>,
}

impl Guidance {
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
            undo: None,
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
            bearing_deg: None,
            bearing_error_deg: None,
            distance_m: None,
            cross_track_m: None,
            waypoint_index: self.route.active_index(),
            waypoint_name: self.route.active().name.clone(),
            reason,
        }
    }

    /// Picks the heading: COG if `speed >= cog_min_speed`, else true heading, else compass + declination.
    pub fn select_heading(&self, input: &NavInput) -> (HeadingSource, Option<f64>) {
        let finite = |x: Option<f64>| x.filter(|v| v.is_finite());
        let moving = finite(input.speed_m_s).is_some_and(|s| s >= self.config.cog_min_speed_m_s);
        if let (true, Some(cog)) = (moving, finite(input.cog_deg)) {
            return (HeadingSource::Cog, Some(crate::geo::normalize_deg(cog)));
        }
        if let Some(h) = finite(input.true_heading_deg) {
            return (HeadingSource::TrueHeading, Some(crate::geo::normalize_deg(h)));
        }
        if let (Some(m), Some(decl)) = (finite(input.compass_deg), self.config.declination_deg) {
            return (HeadingSource::Compass, Some(true_from_magnetic_deg(m, decl)));
        }
        (HeadingSource::None, None)
    }

    fn estimated_error_m(&self, input: &NavInput) -> Option<f64> {
        input
            .accuracy_m
            .filter(|a| a.is_finite() && *a >= 0.0)
            .or_else(|| input.hdop.filter(|h| h.is_finite() && *h >= 0.0).map(|h| h * self.config.uere_m))
    }

    /// Whether the rate limiter lets `cue` play at `now_s`: the previous pattern has ended and `gap_s` passed;
    /// for the same cue again, its repeat interval has passed since that cue's pattern **ended** (so a long
    /// pattern plus the wearer's reaction and turn are over before it is repeated).
    fn allowed(&self, cue: Cue, now_s: f64) -> bool {
        if now_s < self.busy_until_s + self.config.gap_s {
            return false;
        }
        match self.last_cue {
            Some((last, end_s)) if last == cue => {
                let interval = match cue {
                    Cue::Forward => self.config.forward_repeat_s,
                    Cue::Attention => self.config.attention_repeat_s,
                    _ => self.config.repeat_s,
                };
                now_s - end_s >= interval
            }
            _ => true,
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
    pub fn update(&mut self, input: &NavInput, now_s: f64) -> Decision {
        self.undo = None;
        if self.halted {
            return self.blank(NavState::Halted, "STOP ALL in force (resume to guide)".to_owned());
        }
        let manual = now_s < self.manual_until_s;

        // Fix checks.
        let pos = input.position.and_then(|p| p.validated().ok());
        let Some(pos) = pos else {
            return self.hold(input, now_s, manual, "no GPS fix");
        };
        if !(input.fix_age_s.is_finite() && input.fix_age_s <= self.config.max_fix_age_s) {
            let why = format!("GPS fix stale ({:.1} s old)", input.fix_age_s);
            return self.hold(input, now_s, manual, &why);
        }
        if let Some(err) = self.estimated_error_m(input).filter(|e| *e > self.config.max_error_m) {
            return self.hold(input, now_s, manual, &format!("GPS fix too poor (~{err:.0} m)"));
        }

        // Route progress, once per fix: `update` may run more often than fixes arrive (the fix's time is
        // `now - age`), and arrival confirmation counts fixes, not updates.
        let fix_time_s = now_s - input.fix_age_s;
        let new_fix = self.last_fix_time_s.is_none_or(|t| (t - fix_time_s).abs() > 1e-6);
        self.last_fix_time_s = Some(fix_time_s);
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
            return self.hold(input, now_s, manual, &why);
        }
        let event = if new_fix { self.route.observe(self.config.earth, pos) } else { None };
        match event {
            Some(RouteEvent::Arrived(_)) => self.pending_event_cue = Some(Cue::Arrived),
            Some(RouteEvent::Finished) => self.pending_event_cue = Some(Cue::Stop),
            _ => {}
        }
        let (source, heading) = self.select_heading(input);
        let earth = self.config.earth;
        let target = self.route.active().pos;
        let distance_m = earth.distance_m(pos, target);
        let cross_track_m =
            self.route.previous().map(|w| leg_offset(earth, w.pos, target, pos).cross_track_m);

        let mut d = self.blank(NavState::Guiding, String::new());
        d.event = event;
        d.heading_source = source;
        d.heading_deg = heading;
        d.cross_track_m = cross_track_m;

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
        let leg = LegGeometry {
            target_en_m: frame.enu_from_wgs84(target),
            from_en_m: self.route.previous().map(|w| frame.enu_from_wgs84(w.pos)),
        };
        let aim = self.strategy.aim_en_m(&leg);
        let bearing = bearing_of_enu_deg(aim);
        d.bearing_deg = Some(bearing);
        let Some(heading) = heading else {
            let why = "no heading (slow, no true heading or compass)".to_owned();
            return self.hold_with(d, now_s, manual, &why);
        };
        let error = wrap_deg_180(bearing - heading);
        d.bearing_error_deg = Some(error);
        let cue = self.config.thresholds.classify(error, self.last_directional);
        self.last_directional = Some(cue);
        let xt = cross_track_m.map_or(String::new(), |x| format!(", cross-track {x:+.1} m"));
        d.reason = format!(
            "{}: bearing error {error:+.0}° ({} {heading:.0}°, aim {bearing:.0}°), {} at {distance_m:.0} m{xt}",
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

    fn hold(&mut self, input: &NavInput, now_s: f64, manual: bool, why: &str) -> Decision {
        let mut d = self.blank(NavState::Hold, String::new());
        let (source, heading) = self.select_heading(input);
        d.heading_source = source;
        d.heading_deg = heading;
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

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    const O: LatLon = LatLon::new(42.3575, -71.1010);

    fn route_line(n: usize, spacing_m: f64, bearing_deg: f64, config: RouteConfig) -> Route {
        let wps = (0..n)
            .map(|i| {
                Waypoint::new(format!("w{i}"), Earth::Wgs84.direct(O, bearing_deg, spacing_m * i as f64))
            })
            .collect();
        Route::new(wps, config).unwrap()
    }

    /// A fix of a walker at `p` at time `t_s`, nudged ~1 cm per second so the position is never frozen.
    fn mv(p: LatLon, cog_deg: f64, t_s: f64) -> NavInput {
        NavInput::moving(LatLon::new(p.lat_deg + 1e-7 * t_s, p.lon_deg), cog_deg, 1.4)
    }

    fn at(bearing_deg: f64, distance_m: f64) -> LatLon {
        Earth::Wgs84.direct(O, bearing_deg, distance_m)
    }

    #[test]
    fn a_cue_that_never_reached_the_wearer_is_not_counted_as_played() {
        // 50 m south of the first waypoint, walking east: it is 90° to the left.
        let mut g = Guidance::new(
            route_line(3, 100.0, 0.0, RouteConfig::default()),
            GuidanceConfig::default(),
            StrategyKind::BearingOnly,
        );
        let p = at(180.0, 50.0);
        let d = g.update(&mv(p, 90.0, 0.0), 0.0);
        assert_eq!(d.cue, Some(Cue::TurnLeft));
        // Played: the pattern is running, nothing new until it ends and the repeat interval passes.
        assert_eq!(g.update(&mv(p, 90.0, 0.1), 0.1).cue, None);
        // Not played (say the vest refused it): the same cue goes at the next update.
        let mut g2 = Guidance::new(
            route_line(3, 100.0, 0.0, RouteConfig::default()),
            GuidanceConfig::default(),
            StrategyKind::BearingOnly,
        );
        assert_eq!(g2.update(&mv(p, 90.0, 0.0), 0.0).cue, Some(Cue::TurnLeft));
        g2.not_played();
        assert_eq!(g2.update(&mv(p, 90.0, 0.1), 0.1).cue, Some(Cue::TurnLeft));
        // Taking back is one-shot: an update that decided nothing has nothing to take back.
        assert_eq!(g2.update(&mv(p, 90.0, 0.2), 0.2).cue, None);
        g2.not_played();
        assert_eq!(g2.update(&mv(p, 90.0, 0.3), 0.3).cue, None);
    }

    #[test]
    fn thresholds_classify_by_bearing_error() {
        let t = CueThresholds::default();
        assert_eq!(t.classify(0.0, None), Cue::Forward);
        assert_eq!(t.classify(14.0, None), Cue::Forward);
        assert_eq!(t.classify(20.0, None), Cue::SlightRight);
        assert_eq!(t.classify(-20.0, None), Cue::SlightLeft);
        assert_eq!(t.classify(90.0, None), Cue::TurnRight);
        assert_eq!(t.classify(-90.0, None), Cue::TurnLeft);
        assert_eq!(t.classify(170.0, None), Cue::TurnAround);
        assert_eq!(t.classify(-150.0, None), Cue::TurnAround);
        // Hysteresis: at 17° a walker already told "forward" stays forward; at 21° it changes.
        assert_eq!(t.classify(17.0, Some(Cue::Forward)), Cue::Forward);
        assert_eq!(t.classify(21.0, Some(Cue::Forward)), Cue::SlightRight);
        assert_eq!(t.classify(12.0, Some(Cue::SlightRight)), Cue::SlightRight);
        assert_eq!(t.classify(9.0, Some(Cue::SlightRight)), Cue::Forward);
    }

    #[test]
    fn heading_source_rules() {
        let route = route_line(2, 100.0, 0.0, RouteConfig::default());
        let mut cfg = GuidanceConfig::default();
        let g = Guidance::new(route.clone(), cfg, StrategyKind::BearingOnly);
        let mut input =
            NavInput { position: Some(O), cog_deg: Some(10.0), speed_m_s: Some(1.2), ..NavInput::default() };
        assert_eq!(g.select_heading(&input).0, HeadingSource::Cog);
        input.speed_m_s = Some(0.3);
        assert_eq!(g.select_heading(&input), (HeadingSource::None, None));
        input.compass_deg = Some(100.0);
        // No declination configured: the compass is not trusted.
        assert_eq!(g.select_heading(&input).0, HeadingSource::None);
        cfg.declination_deg = Some(-14.2);
        let g = Guidance::new(route, cfg, StrategyKind::BearingOnly);
        let (src, h) = g.select_heading(&input);
        assert_eq!(src, HeadingSource::Compass);
        assert_relative_eq!(h.unwrap(), 85.8, max_relative = 1e-12);
        input.true_heading_deg = Some(200.0);
        assert_eq!(g.select_heading(&input), (HeadingSource::TrueHeading, Some(200.0)));
        input.speed_m_s = Some(1.0);
        assert_eq!(g.select_heading(&input).0, HeadingSource::Cog);
    }

    #[test]
    fn stale_missing_or_headingless_fix_gives_attention_only() {
        let route = route_line(2, 100.0, 0.0, RouteConfig::default());
        let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::BearingOnly);
        let d = g.update(&NavInput::default(), 0.0);
        assert_eq!((d.cue, d.state), (Some(Cue::Attention), NavState::Hold));
        let mut stale = NavInput::moving(at(180.0, 50.0), 0.0, 1.4);
        stale.fix_age_s = 4.0;
        let d = g.update(&stale, 10.0);
        assert_eq!(d.cue, Some(Cue::Attention));
        assert!(d.reason.contains("stale"), "{}", d.reason);
        // Standing still with COG only: no heading, no direction.
        let still = NavInput::moving(at(180.0, 50.0), 0.0, 0.2);
        let d = g.update(&still, 20.0);
        assert_eq!(d.cue, Some(Cue::Attention));
        assert_eq!(d.heading_source, HeadingSource::None);
        // Poor HDOP.
        let mut poor = NavInput::moving(at(180.0, 50.0), 0.0, 1.4);
        poor.hdop = Some(8.0);
        let d = g.update(&poor, 30.0);
        assert_eq!(d.state, NavState::Hold);
        // Non-finite input never panics nor directs.
        let nan = NavInput::moving(LatLon::new(f64::NAN, 0.0), f64::NAN, f64::NAN);
        let d = g.update(&nan, 40.0);
        assert_eq!(d.state, NavState::Hold);
    }

    #[test]
    fn a_pinned_position_while_moving_holds() {
        let route = route_line(2, 200.0, 0.0, RouteConfig::default());
        let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::BearingOnly);
        let p = at(180.0, 50.0);
        for t in 0..=5 {
            let d = g.update(&NavInput::moving(p, 0.0, 1.0), f64::from(t));
            assert_eq!(d.state, NavState::Guiding, "t = {t}");
        }
        let d = g.update(&NavInput::moving(p, 0.0, 1.0), 6.0);
        assert_eq!((d.state, d.cue), (NavState::Hold, Some(Cue::Attention)));
        assert!(d.reason.contains("frozen"), "{}", d.reason);
        // A new position ends it.
        let d = g.update(&NavInput::moving(at(180.0, 48.0), 0.0, 1.0), 7.0);
        assert_eq!(d.state, NavState::Guiding);
    }

    #[test]
    fn rate_limit_one_cue_at_a_time_and_repeat_intervals() {
        let route = route_line(2, 200.0, 0.0, RouteConfig::default());
        let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::BearingOnly);
        // Heading east while the waypoint is north: turn left.
        let p = at(180.0, 50.0);
        let d = g.update(&mv(p, 90.0, 0.0), 0.0);
        assert_eq!(d.cue, Some(Cue::TurnLeft));
        // Turn pattern = 4 x 250 ms = 1 s, + 0.5 s gap; the same cue needs 3 s after the pattern ended.
        assert_eq!(g.update(&mv(p, 90.0, 1.0), 1.0).cue, None);
        assert_eq!(g.update(&mv(p, 90.0, 3.9), 3.9).cue, None);
        assert_eq!(g.update(&mv(p, 90.0, 4.0), 4.0).cue, Some(Cue::TurnLeft));
        // A different cue only waits for the pattern end (5.0) + gap.
        assert_eq!(g.update(&mv(p, 0.0, 5.4), 5.4).cue, None);
        let d = g.update(&mv(p, 0.0, 5.5), 5.5);
        assert_eq!(d.cue, Some(Cue::Forward));
        // Forward (1 s pattern, ends 6.5) repeats 10 s after its end only.
        for t in [7.0, 10.0, 16.4] {
            let d = g.update(&mv(p, 0.0, t), t);
            assert_eq!((d.cue, d.wanted), (None, Some(Cue::Forward)), "t = {t}");
        }
        assert_eq!(g.update(&mv(p, 0.0, 16.5), 16.5).cue, Some(Cue::Forward));
    }

    #[test]
    fn manual_override_and_stop_all_priority() {
        let route = route_line(2, 200.0, 0.0, RouteConfig::default());
        let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::BearingOnly);
        let p = at(180.0, 50.0);
        let d = g.manual(Cue::Stop, 0.0);
        assert_eq!(d.cue, Some(Cue::Stop));
        // Muted for the pattern (0.5 s) + 10 s.
        let d = g.update(&mv(p, 90.0, 5.0), 5.0);
        assert_eq!((d.cue, d.state, d.wanted), (None, NavState::Manual, Some(Cue::TurnLeft)));
        assert_eq!(g.update(&mv(p, 90.0, 11.0), 11.0).cue, Some(Cue::TurnLeft));
        // STOP ALL wins over manual cues and automatic ones until resume.
        let d = g.stop_all(12.0);
        assert!(d.stop_all);
        assert_eq!(g.manual(Cue::Forward, 13.0).cue, None);
        assert_eq!(g.update(&mv(p, 90.0, 20.0), 20.0).cue, None);
        g.resume();
        assert_eq!(g.update(&mv(p, 90.0, 21.0), 21.0).cue, Some(Cue::TurnLeft));
    }

    #[test]
    fn arrival_needs_confirmation_and_back_rearms() {
        let mut route = route_line(3, 100.0, 90.0, RouteConfig::default());
        let near0 = at(0.0, 3.0);
        assert_eq!(route.observe(Earth::Wgs84, near0), None);
        assert_eq!(route.observe(Earth::Wgs84, at(0.0, 30.0)), None); // a noisy jump out resets
        assert_eq!(route.observe(Earth::Wgs84, near0), None);
        assert_eq!(route.observe(Earth::Wgs84, near0), Some(RouteEvent::Arrived(0)));
        assert_eq!(route.active_index(), 1);
        route.back();
        assert_eq!(route.active_index(), 0);
        // Standing on waypoint 0 after `back`: not re-arrived until we leave 12 m and come back.
        for _ in 0..5 {
            assert_eq!(route.observe(Earth::Wgs84, near0), None);
        }
        assert_eq!(route.observe(Earth::Wgs84, at(90.0, 20.0)), None);
        assert_eq!(route.observe(Earth::Wgs84, near0), None);
        assert_eq!(route.observe(Earth::Wgs84, near0), Some(RouteEvent::Arrived(0)));
        // Skip to the last, then finish.
        assert_eq!(route.skip(), None);
        assert_eq!(route.active_index(), 2);
        assert_eq!(route.skip(), Some(RouteEvent::Finished));
        assert!(route.is_finished());
    }

    #[test]
    fn passing_abeam_advances() {
        let mut route = route_line(3, 100.0, 90.0, RouteConfig::default());
        route.skip(); // active = w1 at 100 m east; leg w0 -> w1
        // 105 m east and 12 m north: past w1, outside 8 m but within 16 m.
        let p = Earth::Wgs84.direct(at(90.0, 105.0), 0.0, 12.0);
        assert_eq!(route.observe(Earth::Wgs84, p), Some(RouteEvent::Passed(1)));
        assert_eq!(route.active_index(), 2);
    }

    #[test]
    fn looped_route_wraps() {
        let cfg = RouteConfig { looped: true, confirm_fixes: 1, ..RouteConfig::default() };
        let mut route = route_line(2, 100.0, 0.0, cfg);
        assert_eq!(route.observe(Earth::Wgs84, O), Some(RouteEvent::Arrived(0)));
        assert_eq!(route.observe(Earth::Wgs84, at(0.0, 100.0)), Some(RouteEvent::Arrived(1)));
        assert_eq!(route.active_index(), 0);
        assert_eq!(route.laps(), 1);
        assert!(!route.is_finished());
        assert_eq!(route.previous().map(|w| w.name.as_str()), Some("w1"));
    }

    #[test]
    fn arrival_then_finish_cues() {
        let cfg = RouteConfig { confirm_fixes: 1, ..RouteConfig::default() };
        let route = route_line(2, 100.0, 0.0, cfg);
        let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::Pursuit);
        let d = g.update(&NavInput::moving(O, 0.0, 1.4), 0.0);
        assert_eq!((d.event, d.cue), (Some(RouteEvent::Arrived(0)), Some(Cue::Arrived)));
        let d = g.update(&NavInput::moving(at(0.0, 50.0), 0.0, 1.4), 5.0);
        assert_eq!(d.cue, Some(Cue::Forward));
        let d = g.update(&NavInput::moving(at(0.0, 99.0), 0.0, 1.4), 6.0);
        assert_eq!((d.event, d.state), (Some(RouteEvent::Finished), NavState::Finished));
        // The forward pattern (1 s) is still playing: the stop waits for it.
        assert_eq!(d.cue, None);
        let d = g.update(&mv(at(0.0, 99.0), 0.0, 7.0), 7.0);
        assert_eq!(d.cue, Some(Cue::Stop));
        let d = g.update(&mv(at(0.0, 99.0), 0.0, 20.0), 20.0);
        assert_eq!(d.cue, None);
    }

    #[test]
    fn pursuit_corrects_cross_track_and_bearing_does_not() {
        // Leg w0 -> w1 due north, 200 m; wearer 20 m east of the leg, 50 m along, heading north.
        let route = || {
            let mut r = route_line(2, 200.0, 0.0, RouteConfig::default());
            r.skip();
            r
        };
        let p = Earth::Wgs84.direct(at(0.0, 50.0), 90.0, 20.0);
        let mut bearing = Guidance::new(route(), GuidanceConfig::default(), StrategyKind::BearingOnly);
        let mut pursuit = Guidance::new(route(), GuidanceConfig::default(), StrategyKind::Pursuit);
        let db = bearing.update(&NavInput::moving(p, 0.0, 1.4), 0.0);
        let dp = pursuit.update(&NavInput::moving(p, 0.0, 1.4), 0.0);
        // Bearing-only: atan(20/150) = 7.6° left -> forward. Pursuit: atan(20/15) = 53.1° left -> turn left.
        assert_relative_eq!(
            db.bearing_error_deg.unwrap(),
            -(20.0f64 / 150.0).atan().to_degrees(),
            epsilon = 0.05
        );
        assert_relative_eq!(
            dp.bearing_error_deg.unwrap(),
            -(20.0f64 / 15.0).atan().to_degrees(),
            epsilon = 0.05
        );
        assert_eq!(db.cue, Some(Cue::Forward));
        assert_eq!(dp.cue, Some(Cue::TurnLeft));
        assert_relative_eq!(dp.cross_track_m.unwrap(), 20.0, epsilon = 0.01);
    }

    proptest::proptest! {
        #[test]
        fn no_input_panics_and_stale_fixes_never_direct(
            lat in proptest::num::f64::ANY, lon in proptest::num::f64::ANY,
            age in proptest::num::f64::ANY, speed in proptest::num::f64::ANY,
            cog in proptest::num::f64::ANY, hdg in proptest::num::f64::ANY,
            hdop in proptest::num::f64::ANY, now in -1e6..1e6f64, has_pos: bool,
        ) {
            let route = route_line(3, 100.0, 45.0, RouteConfig::default());
            let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::Pursuit);
            let input = NavInput {
                position: has_pos.then_some(LatLon::new(lat, lon)),
                fix_age_s: age,
                speed_m_s: Some(speed),
                cog_deg: Some(cog),
                true_heading_deg: Some(hdg),
                compass_deg: None,
                hdop: Some(hdop),
                accuracy_m: None,
            };
            let d = g.update(&input, now);
            let trustworthy = has_pos && age.is_finite() && age <= 3.0;
            if !trustworthy {
                proptest::prop_assert!(matches!(d.cue, None | Some(Cue::Attention)), "{:?}", d.cue);
            }
            proptest::prop_assert!(d.bearing_error_deg.is_none_or(f64::is_finite));
        }
    }
}
