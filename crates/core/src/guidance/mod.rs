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
//! 4. **Heading source** by [`GuidanceConfig::heading_mode`] ([`HeadingMode`]): `Cog` (the default, the
//!    rule from before the compass) takes COG when moving at least [`GuidanceConfig::cog_min_speed_m_s`],
//!    else true heading (HDT/THS), else a magnetic compass corrected by the declination; `Auto` prefers a
//!    fresh, good compass ([`CompassReading`]); `Compass` uses nothing else. Compass and COG disagreeing
//!    while walking fast raises "compass disturbed?" ([`Decision::compass_disturbed`]). None → `Attention`.
//! 5. **Strategy.** A [`Strategy`] gives the point to aim at (on a route with a path, a point
//!    [`GuidanceConfig::lookahead_m`] along the path past the wearer's nearest point on it); the bearing error to it picks the cue
//!    ([`CueThresholds`]). Standing still (below `cog_min_speed_m_s`) with a heading, an aim outside the
//!    forward cone gives a graded turn-in-place cue ([`Cue::RotateLeft`]/[`Cue::RotateRight`]) instead,
//!    then `Forward` once faced ([`GuidanceConfig::turn_in_place`]).
//! 6. **Rate limit.** One cue at a time (not before the previous pattern ended plus a gap), the same cue not
//!    again before its repeat interval (longer for `Forward`).
//!
//! ```
//! use vestnav_core::geo::LatLon;
//! use vestnav_core::guidance::{Guidance, GuidanceConfig, NavInput, Route, RouteConfig, StrategyKind, Waypoint};
//! use vestnav_core::vest::Cue;
//! let route = Route::new(vec![Waypoint::at("gate", LatLon::new(42.3570, -71.1010))], RouteConfig::default())
//!     .unwrap();
//! let mut g = Guidance::new(route, GuidanceConfig::default(), StrategyKind::BearingOnly);
//! // Walking due east, 1.4 m/s, 50 m south of the waypoint: it is to the left (bearing ~ 0 deg).
//! let here = LatLon::new(42.35655, -71.1010);
//! let d = g.update(&NavInput::moving(here, 90.0, 1.4), 0.0);
//! assert_eq!(d.cue, Some(Cue::TurnLeft));
//! ```

mod cue;
mod engine;
mod heading;
mod path;
mod route;
mod strategy;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_heading;

use serde::{Deserialize, Serialize};

use crate::geo::{Earth, LatLon};
use crate::vest::{Cue, DEFAULT_ON_MS, Pattern};

pub use cue::CueThresholds;
pub use engine::Guidance;
pub use heading::{CompassReading, HeadingMode};
pub use path::{MAX_PATH_POINTS, PathOffset, RoutePath, path_offset};
pub use route::{Route, RouteConfig, RouteError, RouteEvent, Waypoint};
pub use strategy::{BearingOnly, LegGeometry, Pursuit, Strategy, StrategyKind};

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
    /// Magnetic compass heading [deg] (corrected with [`GuidanceConfig::declination_deg`]), taken as fresh
    /// with no quality figure; [`Guidance::update_with_compass`] gives a reading with its age and quality.
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
    /// Heading source selector (default [`HeadingMode::Cog`], the rule from before the compass).
    #[serde(default)]
    pub heading_mode: HeadingMode,
    /// A compass reading older than this is not used in auto or compass mode [s] (default 1 s: ten
    /// reports at the unit's 10 Hz).
    #[serde(default = "defaults::compass_max_age_s")]
    pub compass_max_age_s: f64,
    /// A compass reading whose calibration quality is below this is not used in auto or compass mode [%]
    /// (default 60: a field magnitude 20 % off, see `compass::Calibration::quality_pct`).
    #[serde(default = "defaults::compass_min_quality_pct")]
    pub compass_min_quality_pct: u8,
    /// Compass and COG differing by more than this while walking fast counts as disagreement [deg]
    /// (default 30°: COG noise at a walk plus the body's sway stay well inside it).
    #[serde(default = "defaults::disagree_deg")]
    pub disagree_deg: f64,
    /// Disagreement (or, once warned, agreement) must hold this long to change the warning [s]
    /// (default 5 s: about 7 m at 1.4 m/s, longer than passing a parked car or a lamp post).
    #[serde(default = "defaults::disagree_s")]
    pub disagree_s: f64,
    /// Compass and COG are only compared at or above this speed [m/s] (default 1.0).
    #[serde(default = "defaults::disagree_min_speed_m_s")]
    pub disagree_min_speed_m_s: f64,
    /// Standing still (speed below `cog_min_speed_m_s` or unknown) with a heading: turn the wearer on the
    /// spot with graded turn-in-place cues until the aim is within the forward cone (default true).
    #[serde(default = "defaults::turn_in_place")]
    pub turn_in_place: bool,
    /// On a route with a path: farther than this from the path counts as off it [m] (default 20 m: beyond
    /// a `SiRF` III's noise near buildings, about the width of a street).
    #[serde(default = "defaults::off_path_m")]
    pub off_path_m: f64,
    /// Off the path this long asks for a new route from where the wearer is ([`Decision::reroute`]) [s]
    /// (default 15 s: about 20 m at a walk, more than a detour round an obstacle).
    #[serde(default = "defaults::off_path_s")]
    pub off_path_s: f64,
}

/// Serde defaults of the settings added with the compass (files saved before them still load).
mod defaults {
    pub fn compass_max_age_s() -> f64 {
        1.0
    }
    pub fn compass_min_quality_pct() -> u8 {
        60
    }
    pub fn disagree_deg() -> f64 {
        30.0
    }
    pub fn disagree_s() -> f64 {
        5.0
    }
    pub fn disagree_min_speed_m_s() -> f64 {
        1.0
    }
    pub fn turn_in_place() -> bool {
        true
    }
    pub fn off_path_m() -> f64 {
        20.0
    }
    pub fn off_path_s() -> f64 {
        15.0
    }
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
            heading_mode: HeadingMode::Cog,
            compass_max_age_s: defaults::compass_max_age_s(),
            compass_min_quality_pct: defaults::compass_min_quality_pct(),
            disagree_deg: defaults::disagree_deg(),
            disagree_s: defaults::disagree_s(),
            disagree_min_speed_m_s: defaults::disagree_min_speed_m_s(),
            turn_in_place: defaults::turn_in_place(),
            off_path_m: defaults::off_path_m(),
            off_path_s: defaults::off_path_s(),
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

impl NavState {
    /// Its name for the operator ("guiding", "hold", "manual", "halted", "finished").
    pub fn name(self) -> &'static str {
        match self {
            Self::Guiding => "guiding",
            Self::Hold => "hold",
            Self::Manual => "manual",
            Self::Halted => "halted",
            Self::Finished => "finished",
        }
    }
}

/// What guidance decided, and why (the app shows `reason` and the numbers).
// Each flag is a separate fact the operator reads (stop, disturbed compass, standing, re-route), not a
// state machine in disguise.
#[allow(clippy::struct_excessive_bools)]
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
    /// The heading selector's mode and rule in words, for the operator, e.g.
    /// "compass (auto: compass fresh, quality 92 %)".
    pub heading_rule: String,
    /// "Compass disturbed?": compass and COG have disagreed by more than
    /// [`GuidanceConfig::disagree_deg`] for [`GuidanceConfig::disagree_s`] while walking fast.
    pub compass_disturbed: bool,
    /// Compass (true) minus COG at the last comparison [deg], when compared.
    pub compass_minus_cog_deg: Option<f64>,
    /// Standing still: the cue (if directional) is a turn-in-place one, or `Forward` to start walking.
    pub standing: bool,
    /// Bearing to the aim point [deg, true].
    pub bearing_deg: Option<f64>,
    /// Bearing error `bearing - heading` in (-180, 180] [deg], positive = aim point to the right.
    pub bearing_error_deg: Option<f64>,
    /// Distance to the active waypoint [m].
    pub distance_m: Option<f64>,
    /// Cross-track error to the active leg [m], positive = right of the leg: from the route's path toward
    /// the active waypoint when it has one ([`Route::active_path`]), else from the straight leg.
    pub cross_track_m: Option<f64>,
    /// How long the wearer has been farther than [`GuidanceConfig::off_path_m`] from the path [s] (by fix
    /// time); `None` on the path or without one.
    #[serde(default)]
    pub off_path_s: Option<f64>,
    /// Off the path for [`GuidanceConfig::off_path_s`] or longer: plan a new route from here. Stays set
    /// until the wearer is back within [`GuidanceConfig::off_path_m`] or the route changes.
    #[serde(default)]
    pub reroute: bool,
    /// Index of the active waypoint (after the update).
    pub waypoint_index: usize,
    /// Name of the active waypoint.
    pub waypoint_name: String,
    /// One line for the operator: what and why.
    pub reason: String,
}
