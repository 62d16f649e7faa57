//! A closed-loop simulated wearer: a person walking a route, guided only by vest cues, seen through a
//! simulated GPS receiver.
//!
//! Each run is seeded and deterministic. The loop, at a fixed step `dt_s` (default 0.1 s):
//! 1. the wearer walks at `pace_m_s` on their heading, which wanders as a random walk
//!    (`veer_deg_per_sqrt_s`: nobody walks perfectly straight without sight of the goal);
//! 2. every `fix_interval_s` (1 Hz like the `SiRF` III) the true position goes through
//!    [`crate::gnss_sim::GnssErrorState`] (noise, wandering bias, static-navigation pinning); the receiver's
//!    COG is the true heading plus `cog_noise_deg` noise and its speed the true speed;
//! 3. [`crate::guidance::Guidance::update`] runs every step with the last fix and its age;
//! 4. a cue is *recognised* with probability `recognition` (thesis §6: ~92 % while walking); a recognised
//!    cue is acted on `reaction_s` after its pattern **ends**, by turning toward a new heading at
//!    `turn_rate_deg_s`. Turn amounts per cue: Forward 0, Slight ±`slight_turn_deg` (20°), Turn
//!    ±`turn_deg` (70°), `TurnAround` 180°, each plus N(0, `turn_noise_deg`²); Stop halts the walker;
//!    Attention and Arrived change nothing.
//!
//! With [`SimConfig::heading`] set ([`HeadingSim`]) the wearer also has a heading of their own to be steered
//! by: they start **standing** at the first waypoint facing a random direction; guidance picks its heading
//! source by [`HeadingSim::mode`] from the vest's compass ([`crate::compass::MagnetometerSim`]: calibrated
//! hard/soft iron, noise, gait tilt, WMM field, steel objects beside the route; read every step) and the
//! receiver's COG (scattering as `atan(sigma_v / v)` at low speed); the declination is WMM's at the start.
//! A recognised turn-in-place cue ([`Cue::RotateLeft`]/[`Cue::RotateRight`]) stops the wearer, who turns on
//! the spot by the cue's grade (plus N(0, `turn_noise_deg`²)) at `rotate_rate_deg_s`; `Forward` or any
//! walking cue sets them walking; a standing wearer told nothing directional for `idle_walk_s` walks off the
//! way they face (the only way COG-only guidance gets a heading). Without it (the default) the wearer walks
//! from the start exactly as described above.
//!
//! Metrics: cross-track RMSE of the **true** path to the route polyline (the route's path when it follows
//! one, [`simulate_along`]), from leaving the first waypoint to the finish; time to finish, cues per
//! minute, waypoints reached and missed (passed abeam or never reached), time to face the first waypoint (true heading within the standing forward cone,
//! [`crate::guidance::CueThresholds::in_place_cone_deg`], of the true bearing from the true position), time
//! per heading source and with "compass disturbed?" raised, and both paths for plotting.
//!
//! ```
//! use vestnav_core::geo::LatLon;
//! use vestnav_core::guidance::{StrategyKind, Waypoint};
//! use vestnav_core::wearer::{SimConfig, simulate};
//! let wps = vec![
//!     Waypoint::at("a", LatLon::new(42.3562, -71.1000)),
//!     Waypoint::at("b", LatLon::new(42.3572, -71.1000)),
//! ];
//! let r = simulate(&wps, &SimConfig::new(StrategyKind::Pursuit), 1).unwrap();
//! assert!(r.finished && r.cross_track_rmse_m < 10.0);
//! ```

use std::collections::BTreeMap;

use glam::DVec2;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use crate::geo::{LatLon, LocalFrame, bearing_of_enu_deg, normalize_deg, wrap_deg_180};
use crate::gnss_sim::{GnssErrorModel, GnssErrorState};
use crate::guidance::{
    Guidance, GuidanceConfig, HeadingMode, NavInput, NavState, Route, RouteConfig, RouteError, RouteEvent,
    RoutePath, StrategyKind, Waypoint,
};
use crate::vest::Cue;

mod body;
mod heading;

pub use body::{Body, Skin};
use heading::CompassSensor;
pub use heading::{HeadingSim, SIM_DATE, SteelPlacement};

/// How the simulated person walks and reacts.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WearerModel {
    /// Walking speed [m/s] (default 1.4, a normal walk; above the `SiRF` static-navigation threshold 1.2).
    pub pace_m_s: f64,
    /// Delay from the end of a cue's pattern to the start of the turn [s] (default 0.8).
    pub reaction_s: f64,
    /// Turning rate of a walking person [deg/s] (default 90).
    pub turn_rate_deg_s: f64,
    /// Heading change for SlightLeft/Right [deg] (default 20).
    pub slight_turn_deg: f64,
    /// Heading change for TurnLeft/Right [deg] (default 70).
    pub turn_deg: f64,
    /// Standard deviation of every executed turn [deg] (default 10).
    pub turn_noise_deg: f64,
    /// Heading random walk while walking [deg/sqrt(s)] (default 2).
    pub veer_deg_per_sqrt_s: f64,
    /// Probability that a cue is recognised (default 0.92, thesis §6 while walking).
    pub recognition: f64,
    /// Initial heading error from the first leg's direction, drawn uniformly in ±this [deg] (default 30).
    pub initial_heading_error_deg: f64,
}

impl Default for WearerModel {
    fn default() -> Self {
        Self {
            pace_m_s: 1.4,
            reaction_s: 0.8,
            turn_rate_deg_s: 90.0,
            slight_turn_deg: 20.0,
            turn_deg: 70.0,
            turn_noise_deg: 10.0,
            veer_deg_per_sqrt_s: 2.0,
            recognition: 0.92,
            initial_heading_error_deg: 30.0,
        }
    }
}

impl WearerModel {
    /// The heading change a recognised cue asks for [deg] (before noise); `None` for cues that do not turn.
    pub fn turn_for(&self, cue: Cue) -> Option<f64> {
        match cue {
            Cue::Forward => Some(0.0),
            Cue::SlightLeft => Some(-self.slight_turn_deg),
            Cue::SlightRight => Some(self.slight_turn_deg),
            Cue::TurnLeft => Some(-self.turn_deg),
            Cue::TurnRight => Some(self.turn_deg),
            Cue::TurnAround => Some(180.0),
            Cue::RotateLeft(step) => Some(-step.degrees()),
            Cue::RotateRight(step) => Some(step.degrees()),
            Cue::Stop | Cue::Attention | Cue::Arrived => None,
        }
    }
}

/// Settings of one simulation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SimConfig {
    /// Strategy under test.
    pub strategy: StrategyKind,
    /// Guidance settings.
    pub guidance: GuidanceConfig,
    /// Route settings.
    pub route: RouteConfig,
    /// The walker.
    pub wearer: WearerModel,
    /// The receiver's error model.
    pub gnss: GnssErrorModel,
    /// COG noise of the receiver while moving [deg] (default 5).
    pub cog_noise_deg: f64,
    /// Simulation step [s] (default 0.1).
    pub dt_s: f64,
    /// Interval between fixes [s] (default 1: 1 Hz).
    pub fix_interval_s: f64,
    /// Give up after this many times the nominal walking time, plus 120 s (default 3).
    pub timeout_factor: f64,
    /// The wearer's own heading, the compass and the heading source selector; `None` (the default): the
    /// wearer walks from the start and guidance steers by its configured rule (see the module doc).
    #[serde(default)]
    pub heading: Option<HeadingSim>,
}

impl SimConfig {
    /// Defaults with the given strategy: `SiRF` III open-sky errors, 1 Hz, thesis vest timing.
    pub fn new(strategy: StrategyKind) -> Self {
        Self {
            strategy,
            guidance: GuidanceConfig::default(),
            route: RouteConfig::default(),
            wearer: WearerModel::default(),
            gnss: GnssErrorModel::sirf3_open_sky(),
            cog_noise_deg: 5.0,
            dt_s: 0.1,
            fix_interval_s: 1.0,
            timeout_factor: 3.0,
            heading: None,
        }
    }
}

/// Outcome of one simulated walk. Serialised (as one run of `nav simulate --json`) without its paths.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimResult {
    /// Strategy name.
    pub strategy: String,
    /// Seed of the run.
    pub seed: u64,
    /// Whether the route was finished before the timeout.
    pub finished: bool,
    /// Time of the finish (or of the timeout) [s].
    pub time_s: f64,
    /// Nominal time: route length / pace [s].
    pub nominal_time_s: f64,
    /// Distance actually walked [m].
    pub walked_m: f64,
    /// RMS distance of the true path to the route polyline [m].
    pub cross_track_rmse_m: f64,
    /// Largest distance of the true path to the route [m].
    pub max_cross_track_m: f64,
    /// Cues sent.
    pub cues: usize,
    /// Cues per minute.
    pub cues_per_min: f64,
    /// Cues by name.
    pub cue_counts: BTreeMap<String, usize>,
    /// Waypoints reached (arrival radius).
    pub waypoints_reached: usize,
    /// Waypoints missed: passed abeam, or not reached before the timeout.
    pub waypoints_missed: usize,
    /// Heading source selector of the run (`auto`, `compass`, `cog`); `None` without [`SimConfig::heading`].
    #[serde(default)]
    pub heading_mode: Option<String>,
    /// Time until the wearer first faced the first waypoint after the start (true heading within the
    /// standing forward cone of the true bearing to it) [s]; `None` if never.
    #[serde(default)]
    pub time_to_face_s: Option<f64>,
    /// Time guidance steered by each heading source (`COG`, `compass`, `true heading`, `none`) [s].
    #[serde(default)]
    pub heading_source_s: BTreeMap<String, f64>,
    /// Time with "compass disturbed?" raised [s].
    #[serde(default)]
    pub compass_disturbed_s: f64,
    /// True path, east/north about the first waypoint [m], one point per fix (for figures; not in JSON).
    #[serde(skip)]
    pub path_true_en_m: Vec<DVec2>,
    /// Reported fixes, east/north about the first waypoint [m] (for figures; not in JSON).
    #[serde(skip)]
    pub path_fix_en_m: Vec<DVec2>,
    /// Waypoints, east/north about the first waypoint [m] (for figures; not in JSON).
    #[serde(skip)]
    pub waypoints_en_m: Vec<DVec2>,
    /// The line the wearer should walk — the route's path when it has one, else the straight legs through
    /// the waypoints — east/north about the first waypoint [m] (for figures; not in JSON).
    #[serde(skip)]
    pub route_line_en_m: Vec<DVec2>,
    /// Steel objects disturbing the compass, east/north about the first waypoint [m] (for figures; not in
    /// JSON).
    #[serde(skip)]
    pub steel_en_m: Vec<DVec2>,
}

/// Distance from `p` to the polyline through `pts` [m] (planar): min over segments of the distance to the
/// segment, `|p - (a + clamp(t, 0, 1)(b - a))|` with `t = (p - a)·(b - a)/|b - a|^2`.
///
/// Linear in the number of points; for many queries on one polyline use [`PolylineIndex`].
pub fn distance_to_polyline_m(p: DVec2, pts: &[DVec2]) -> f64 {
    match pts {
        [] => f64::INFINITY,
        [only] => (p - *only).length(),
        _ => pts.windows(2).map(|w| distance_to_segment_m(p, w[0], w[1])).fold(f64::INFINITY, f64::min),
    }
}

/// Distance from `p` to the segment `a b` [m] (planar), see [`distance_to_polyline_m`].
fn distance_to_segment_m(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 { ((p - a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + ab * t)).length()
}

/// [`distance_to_polyline_m`] for many queries on one polyline, in about constant time per query near
/// the line: the segments are binned in a uniform grid of square cells (side twice the mean segment
/// length, at least 5 m), and a query scans rings of cells around its own, nearest first.
///
/// Exact, not approximate: after scanning every cell within Chebyshev distance `r` of the query's cell, any
/// segment not yet seen lies outside a square of `2r + 1` cells whose border is at least `r s` from the
/// query (`s` the cell side), so the scan stops once the best distance found is at most `r s`. The answer is the same
/// minimum of the same per-segment distances as the linear scan. A query far from the line (more cells to
/// scan than there are segments) falls back to the linear scan, so no query costs more than that.
#[derive(Debug, Clone)]
pub struct PolylineIndex {
    pts: Vec<DVec2>,
    cell_m: f64,
    origin: DVec2,
    cells: std::collections::HashMap<(i64, i64), Vec<u32>>,
}

impl PolylineIndex {
    /// Polylines with fewer segments are scanned linearly (the grid would not pay).
    const MIN_SEGMENTS: usize = 32;
    /// A segment whose bounding box spans more cells than this is binned by sampling along it.
    const MAX_BOX_CELLS: i64 = 16;

    /// Bins the segments of the polyline through `pts`.
    pub fn new(pts: &[DVec2]) -> Self {
        let mut index = Self {
            pts: pts.to_vec(),
            cell_m: 1.0,
            origin: pts.first().copied().unwrap_or(DVec2::ZERO),
            cells: std::collections::HashMap::new(),
        };
        let segments = pts.len().saturating_sub(1);
        let finite = pts.iter().all(|p| p.is_finite());
        if segments < Self::MIN_SEGMENTS || !finite || u32::try_from(segments).is_err() {
            return index;
        }
        let length_m: f64 = pts.windows(2).map(|w| (w[1] - w[0]).length()).sum();
        index.cell_m = (2.0 * length_m / segments as f64).max(5.0);
        for (k, w) in pts.windows(2).enumerate() {
            let (a, b) = (index.cell_of(w[0]), index.cell_of(w[1]));
            let (x0, x1, y0, y1) = (a.0.min(b.0), a.0.max(b.0), a.1.min(b.1), a.1.max(b.1));
            let k = k as u32;
            if (x1 - x0 + 1).saturating_mul(y1 - y0 + 1) <= Self::MAX_BOX_CELLS {
                // Every cell the segment crosses lies in its bounding box.
                for x in x0..=x1 {
                    for y in y0..=y1 {
                        index.cells.entry((x, y)).or_default().push(k);
                    }
                }
            } else {
                // Samples at most half a cell apart: every point of the segment is within a quarter cell
                // of a sample, so every cell it crosses is the cell of a sample or one of its neighbours.
                let n = ((w[1] - w[0]).length() / (0.5 * index.cell_m)).ceil().max(1.0) as u64;
                let mut last = None;
                for i in 0..=n {
                    let c = index.cell_of(w[0].lerp(w[1], i as f64 / n as f64));
                    if last == Some(c) {
                        continue;
                    }
                    last = Some(c);
                    for x in c.0 - 1..=c.0 + 1 {
                        for y in c.1 - 1..=c.1 + 1 {
                            let v = index.cells.entry((x, y)).or_default();
                            if v.last() != Some(&k) {
                                v.push(k);
                            }
                        }
                    }
                }
            }
        }
        index
    }

    fn cell_of(&self, p: DVec2) -> (i64, i64) {
        let c = (p - self.origin) / self.cell_m;
        (c.x.floor() as i64, c.y.floor() as i64)
    }

    /// Distance from `p` to the polyline [m]; equal to [`distance_to_polyline_m`]`(p, pts)`.
    pub fn distance_m(&self, p: DVec2) -> f64 {
        if self.cells.is_empty() || !p.is_finite() {
            return distance_to_polyline_m(p, &self.pts);
        }
        let budget = self.pts.len();
        let c = self.cell_of(p);
        let mut best = f64::INFINITY;
        let mut visited = 0usize;
        for r in 0i64.. {
            visited += if r == 0 { 1 } else { 8 * r as usize };
            if visited > budget {
                return distance_to_polyline_m(p, &self.pts);
            }
            let mut visit = |x: i64, y: i64| {
                if let Some(segs) = self.cells.get(&(x, y)) {
                    for &k in segs {
                        let k = k as usize;
                        best = best.min(distance_to_segment_m(p, self.pts[k], self.pts[k + 1]));
                    }
                }
            };
            if r == 0 {
                visit(c.0, c.1);
            } else {
                for x in c.0 - r..=c.0 + r {
                    visit(x, c.1 - r);
                    visit(x, c.1 + r);
                }
                for y in c.1 - r + 1..c.1 + r {
                    visit(c.0 - r, y);
                    visit(c.0 + r, y);
                }
            }
            // Rings 0..=r scanned: p is at least r cells from the border of that block, so every segment not
            // seen yet is at least that far (less a rounding margin).
            if best <= r as f64 * self.cell_m * (1.0 - 1e-9) {
                return best;
            }
        }
        best
    }
}

fn normal(rng: &mut StdRng) -> f64 {
    StandardNormal.sample(rng)
}

/// Runs one closed-loop walk along `waypoints` (see the module doc). Deterministic for a given `seed`.
pub fn simulate(waypoints: &[Waypoint], config: &SimConfig, seed: u64) -> Result<SimResult, RouteError> {
    simulate_along(waypoints, None, config, seed)
}

/// [`simulate`] on a route that follows `path` between its waypoints (a planner's dense route): guidance
/// steers along the path ([`Route::with_path`]) and the cross-track metric is measured from the path.
// One simulation step reads top to bottom (sense, decide, react, walk, score); splitting it would scatter
// the shared state over many parameters.
#[allow(clippy::too_many_lines)]
pub fn simulate_along(
    waypoints: &[Waypoint],
    path: Option<&RoutePath>,
    config: &SimConfig,
    seed: u64,
) -> Result<SimResult, RouteError> {
    let route = Route::new(waypoints.to_vec(), config.route)?.with_path(path.cloned())?;
    let frame = LocalFrame::new(waypoints[0].pos(), config.guidance.earth);
    let wps_en: Vec<DVec2> = waypoints.iter().map(|w| frame.enu_from_wgs84(w.pos())).collect();
    // The line the wearer should walk: the path when there is one, else the straight legs.
    let line_en: Vec<DVec2> = path
        .map_or_else(|| wps_en.clone(), |p| p.points().iter().map(|q| frame.enu_from_wgs84(*q)).collect());
    let hs = config.heading;
    let mut guidance_config = config.guidance;
    let mut compass = match &hs {
        Some(h) => {
            let c =
                CompassSensor::new(h, waypoints[0].pos(), &wps_en, seed.wrapping_add(0x00C0_4A55)).map_err(
                    |source| RouteError::BadWaypoint { index: 0, name: waypoints[0].name.clone(), source },
                )?;
            guidance_config.heading_mode = h.mode;
            // The console sets the declination from WMM at the route start; guidance applies it once.
            guidance_config.declination_deg = Some(c.declination_deg());
            Some(c)
        }
        None => None,
    };
    let mut guidance = Guidance::new(route, guidance_config, config.strategy);
    // The heading sensors draw from their own generator: without `heading` the walk is the same as ever.
    let mut sensor_rng = StdRng::seed_from_u64(seed ^ 0xC0FF_EE00_D15E_A5E5);
    let face_cone_deg = config.guidance.thresholds.in_place_cone_deg();
    // The cross-track metric runs every step: an index keeps a walk linear in the route's length.
    let route_line = PolylineIndex::new(&line_en);
    let length_m: f64 = line_en.windows(2).map(|w| (w[1] - w[0]).length()).sum();
    let w = config.wearer;
    let pace = w.pace_m_s.max(0.1);
    let nominal_time_s = length_m / pace;
    // Hostile settings (NaN, huge) must not make the loop endless.
    let factor =
        if config.timeout_factor.is_finite() { config.timeout_factor.clamp(1.0, 100.0) } else { 3.0 };
    let timeout_s = factor * nominal_time_s + 120.0;
    let dt = if config.dt_s.is_finite() { config.dt_s.clamp(0.01, 1.0) } else { 0.1 };
    let fix_interval_s =
        if config.fix_interval_s.is_finite() { config.fix_interval_s.clamp(dt, 60.0) } else { 1.0 };
    let fix_every = (fix_interval_s / dt).round().max(1.0) as u64;

    let mut rng = StdRng::seed_from_u64(seed);
    let mut gnss = GnssErrorState::new(config.gnss, seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(1));
    let first_leg = line_en.get(1).map_or(DVec2::Y, |b| *b - line_en[0]);
    let spread = w.initial_heading_error_deg.abs();
    let mut heading = normalize_deg(bearing_of_enu_deg(first_leg) + rng.random_range(-spread..=spread));
    if hs.is_some() {
        heading = sensor_rng.random_range(0.0..360.0);
    }
    let mut body = Body::new(line_en[0], heading, hs.is_none());
    // (time, position, cog, speed); the position is mapped to WGS-84 once per fix, not once per step.
    let mut last_fix: Option<(f64, LatLon, f64, f64)> = None;
    let mut result = SimResult {
        strategy: config.strategy.name().to_owned(),
        seed,
        finished: false,
        time_s: 0.0,
        nominal_time_s,
        walked_m: 0.0,
        cross_track_rmse_m: 0.0,
        max_cross_track_m: 0.0,
        cues: 0,
        cues_per_min: 0.0,
        cue_counts: BTreeMap::new(),
        waypoints_reached: 0,
        waypoints_missed: 0,
        heading_mode: hs.map(|h| h.mode.name().to_owned()),
        time_to_face_s: None,
        heading_source_s: BTreeMap::new(),
        compass_disturbed_s: 0.0,
        path_true_en_m: Vec::new(),
        path_fix_en_m: Vec::new(),
        waypoints_en_m: wps_en.clone(),
        route_line_en_m: line_en.clone(),
        steel_en_m: compass.as_ref().map_or_else(Vec::new, |c| c.steel_en_m.clone()),
    };
    let (mut xt_sum2, mut xt_n) = (0.0, 0usize);
    let mut left_start = false;
    let mut step: u64 = 0;
    loop {
        let t = step as f64 * dt;
        if t > timeout_s {
            break;
        }
        // Sensor: a fix every `fix_every` steps.
        let (pos, heading) = (body.pos_en_m, body.heading_deg);
        let speed = body.speed_m_s(&w);
        if step.is_multiple_of(fix_every) {
            let fix_en = gnss.apply(fix_interval_s, pos, speed);
            let cog = match &hs {
                Some(h) => {
                    heading::cog_deg(&mut sensor_rng, heading, speed, config.cog_noise_deg, h.speed_noise_m_s)
                }
                None => normalize_deg(heading + config.cog_noise_deg * normal(&mut rng)),
            };
            last_fix = Some((t, frame.wgs84_from_enu(fix_en), cog, speed));
            result.path_true_en_m.push(pos);
            result.path_fix_en_m.push(fix_en);
        }
        let input = last_fix.map_or_else(NavInput::default, |(tf, fix_pos, cog, spd)| NavInput {
            fix_age_s: t - tf,
            ..NavInput::moving(fix_pos, cog, spd)
        });
        let decision = match (compass.as_mut(), &hs) {
            // `cog` is today's vest, without a magnetometer: its rule then has COG or nothing.
            (_, Some(h)) if h.mode == HeadingMode::Cog => guidance.update_with_compass(&input, None, t),
            (Some(c), _) => {
                let reading = c.read(t, pos, heading, speed);
                guidance.update_with_compass(&input, reading, t)
            }
            (None, _) => guidance.update(&input, t),
        };
        *result.heading_source_s.entry(decision.heading_source.name().to_owned()).or_default() += dt;
        if decision.compass_disturbed {
            result.compass_disturbed_s += dt;
        }
        if result.time_to_face_s.is_none()
            && let Some(first) = wps_en.get(1)
            && wrap_deg_180(bearing_of_enu_deg(*first - pos) - heading).abs() <= face_cone_deg
        {
            result.time_to_face_s = Some(t);
        }
        match decision.event {
            Some(RouteEvent::Arrived(_)) => {
                result.waypoints_reached += 1;
                left_start = true;
            }
            Some(RouteEvent::Passed(_)) => result.waypoints_missed += 1,
            Some(RouteEvent::Finished) => {
                // The last waypoint: reached unless it was passed (the route reports Finished for both).
                let last = wps_en[wps_en.len() - 1];
                if (pos - last).length() <= config.route.pass_radius_m {
                    result.waypoints_reached += 1;
                } else {
                    result.waypoints_missed += 1;
                }
            }
            None => {}
        }
        if let (Some(cue), Some(pattern)) = (decision.cue, decision.pattern.as_ref()) {
            result.cues += 1;
            *result.cue_counts.entry(cue.name().to_owned()).or_default() += 1;
            body.feel(&w, cue, t + f64::from(pattern.total_ms()) / 1000.0, t, &mut rng);
        }
        if decision.state == NavState::Finished && guidance.route().is_finished() && !result.finished {
            result.finished = true;
            result.time_s = t;
            break;
        }
        // Act on each recognised cue when its reaction time has come, turn, veer, walk.
        result.walked_m += body.advance(&w, hs.as_ref(), t, dt, &mut rng);
        let pos = body.pos_en_m;
        if left_start || (pos - line_en[0]).length() > config.route.arrival_radius_m {
            left_start = true;
            let xt = route_line.distance_m(pos);
            xt_sum2 += xt * xt;
            xt_n += 1;
            result.max_cross_track_m = result.max_cross_track_m.max(xt);
        }
        step += 1;
    }
    if !result.finished {
        result.time_s = timeout_s;
        let active = guidance.route().active_index();
        result.waypoints_missed += waypoints.len().saturating_sub(active);
    }
    result.cross_track_rmse_m = if xt_n > 0 { (xt_sum2 / xt_n as f64).sqrt() } else { 0.0 };
    result.cues_per_min = if result.time_s > 0.0 { result.cues as f64 / (result.time_s / 60.0) } else { 0.0 };
    Ok(result)
}

/// Mean, standard deviation and extremes of one metric over runs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Spread {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (n - 1); 0 for one run.
    pub sd: f64,
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
}

impl Spread {
    /// The statistics of no values (all zeros).
    pub fn empty() -> Self {
        Self::of(&[])
    }

    /// Statistics of `values` (all zeros when empty).
    pub fn of(values: &[f64]) -> Self {
        if values.is_empty() {
            return Self { mean: 0.0, sd: 0.0, min: 0.0, max: 0.0 };
        }
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let sd = if values.len() > 1 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        let min = values.iter().copied().fold(f64::INFINITY, f64::min);
        let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Self { mean, sd, min, max }
    }
}

/// Summary of many runs of one strategy.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimSummary {
    /// Strategy name.
    pub strategy: String,
    /// Number of runs.
    pub runs: usize,
    /// Fraction of runs that finished.
    pub finish_rate: f64,
    /// Cross-track RMSE [m].
    pub cross_track_rmse_m: Spread,
    /// Time to finish (timeout for unfinished runs) [s].
    pub time_s: Spread,
    /// Cues per minute.
    pub cues_per_min: Spread,
    /// Waypoints missed per run.
    pub waypoints_missed: Spread,
    /// Heading source selector of the runs (`auto`, `compass`, `cog`); `None` without a heading simulation.
    #[serde(default)]
    pub heading_mode: Option<String>,
    /// Fraction of runs in which the wearer came to face the first waypoint.
    #[serde(default)]
    pub faced_rate: f64,
    /// Time to face the first waypoint, over the runs that did [s].
    #[serde(default = "Spread::empty")]
    pub time_to_face_s: Spread,
}

impl SimSummary {
    /// Summarises `results` (all of one strategy).
    pub fn of(results: &[SimResult]) -> Self {
        let get = |f: fn(&SimResult) -> f64| Spread::of(&results.iter().map(f).collect::<Vec<_>>());
        Self {
            strategy: results.first().map_or_else(String::new, |r| r.strategy.clone()),
            runs: results.len(),
            finish_rate: if results.is_empty() {
                0.0
            } else {
                results.iter().filter(|r| r.finished).count() as f64 / results.len() as f64
            },
            cross_track_rmse_m: get(|r| r.cross_track_rmse_m),
            time_s: get(|r| r.time_s),
            cues_per_min: get(|r| r.cues_per_min),
            waypoints_missed: get(|r| r.waypoints_missed as f64),
            heading_mode: results.first().and_then(|r| r.heading_mode.clone()),
            faced_rate: if results.is_empty() {
                0.0
            } else {
                results.iter().filter(|r| r.time_to_face_s.is_some()).count() as f64 / results.len() as f64
            },
            time_to_face_s: Spread::of(&results.iter().filter_map(|r| r.time_to_face_s).collect::<Vec<_>>()),
        }
    }
}

/// Runs `runs` walks with seeds `seed, seed + 1, ...` and summarises them.
pub fn simulate_many(
    waypoints: &[Waypoint],
    config: &SimConfig,
    runs: usize,
    seed: u64,
) -> Result<(Vec<SimResult>, SimSummary), RouteError> {
    simulate_many_along(waypoints, None, config, runs, seed)
}

/// [`simulate_many`] along a path ([`simulate_along`]).
pub fn simulate_many_along(
    waypoints: &[Waypoint],
    path: Option<&RoutePath>,
    config: &SimConfig,
    runs: usize,
    seed: u64,
) -> Result<(Vec<SimResult>, SimSummary), RouteError> {
    let results = (0..runs as u64)
        .map(|i| simulate_along(waypoints, path, config, seed.wrapping_add(i)))
        .collect::<Result<Vec<_>, _>>()?;
    let summary = SimSummary::of(&results);
    Ok((results, summary))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::{Earth, LatLon};
    use approx::assert_relative_eq;

    fn square() -> Vec<Waypoint> {
        let o = LatLon::new(42.3575, -71.1010);
        let e = Earth::Wgs84;
        let a = e.direct(o, 0.0, 100.0);
        let b = e.direct(a, 90.0, 100.0);
        let c = e.direct(b, 180.0, 100.0);
        vec![Waypoint::at("o", o), Waypoint::at("a", a), Waypoint::at("b", b), Waypoint::at("c", c)]
    }

    fn brief(r: &SimResult) -> String {
        format!(
            "finished {} t {:.0}/{:.0} s, xt {:.1} m, cues {:?}, reached {}, missed {}",
            r.finished,
            r.time_s,
            r.nominal_time_s,
            r.cross_track_rmse_m,
            r.cue_counts,
            r.waypoints_reached,
            r.waypoints_missed
        )
    }

    #[test]
    fn polyline_distance_closed_form() {
        let pts = [DVec2::ZERO, DVec2::new(10.0, 0.0), DVec2::new(10.0, 10.0)];
        assert_relative_eq!(distance_to_polyline_m(DVec2::new(5.0, 3.0), &pts), 3.0);
        assert_relative_eq!(distance_to_polyline_m(DVec2::new(13.0, 5.0), &pts), 3.0);
        assert_relative_eq!(distance_to_polyline_m(DVec2::new(-3.0, -4.0), &pts), 5.0);
    }

    #[test]
    fn polyline_index_gives_the_linear_scan_s_answer() {
        let mut rng = StdRng::seed_from_u64(7);
        // A wandering 3 m-step walk that crosses itself, with a few long legs and a repeated point.
        let mut pts = vec![DVec2::ZERO];
        let mut h: f64 = 0.0;
        for i in 0..2000 {
            h += 0.3 * normal(&mut rng);
            let step = if i % 500 == 250 { 400.0 } else { 3.0 };
            let last = pts[pts.len() - 1];
            pts.push(last + DVec2::new(h.sin(), h.cos()) * step);
            if i == 1000 {
                pts.push(last + DVec2::new(h.sin(), h.cos()) * step);
            }
        }
        let index = PolylineIndex::new(&pts);
        assert!(!index.cells.is_empty());
        let (lo, hi) =
            pts.iter().fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
        for i in 0..3000 {
            // Near the line (most queries) and anywhere in and around its box.
            let p = if i % 3 == 0 {
                lo - DVec2::splat(200.0)
                    + (hi - lo + DVec2::splat(400.0)) * DVec2::new(rng.random(), rng.random())
            } else {
                pts[rng.random_range(0..pts.len())] + DVec2::new(normal(&mut rng), normal(&mut rng)) * 15.0
            };
            let (fast, slow) = (index.distance_m(p), distance_to_polyline_m(p, &pts));
            assert!(fast.to_bits() == slow.to_bits(), "{p}: {fast} vs {slow}");
        }
        // Short and degenerate lines.
        for short in [vec![], vec![DVec2::ONE], vec![DVec2::ZERO, DVec2::X]] {
            let q = DVec2::new(0.5, 2.0);
            let (fast, slow) = (PolylineIndex::new(&short).distance_m(q), distance_to_polyline_m(q, &short));
            assert_eq!(fast.to_bits(), slow.to_bits());
        }
    }

    #[test]
    fn a_long_route_of_short_legs_is_walked() {
        // A 2000-point, 6 km route of 3 m legs (a recorded track used as a route).
        let o = LatLon::new(42.3575, -71.1010);
        let mut wps = vec![Waypoint::at("0", o)];
        for i in 1..2000 {
            let h = 45.0 + 60.0 * (f64::from(i) / 150.0).sin();
            let last = wps[wps.len() - 1].pos();
            wps.push(Waypoint::at(format!("{i}"), Earth::Wgs84.direct(last, h, 3.0)));
        }
        let mut cfg = SimConfig::new(StrategyKind::Pursuit);
        cfg.gnss = GnssErrorModel::perfect();
        let t = std::time::Instant::now();
        let r = simulate(&wps, &cfg, 1).unwrap();
        println!("{} in {:?}", brief(&r), t.elapsed());
        assert!(r.finished, "{}", brief(&r));
        assert!(r.cross_track_rmse_m < 10.0, "{}", brief(&r));
    }

    #[test]
    fn perfect_wearer_and_gps_follow_the_route() {
        let mut cfg = SimConfig::new(StrategyKind::Pursuit);
        cfg.gnss = GnssErrorModel::perfect();
        cfg.cog_noise_deg = 0.0;
        cfg.wearer = WearerModel {
            turn_noise_deg: 0.0,
            veer_deg_per_sqrt_s: 0.0,
            recognition: 1.0,
            initial_heading_error_deg: 0.0,
            ..WearerModel::default()
        };
        let r = simulate(&square(), &cfg, 3).unwrap();
        assert!(r.finished, "{}", brief(&r));
        assert_eq!(r.waypoints_reached, 4);
        assert_eq!(r.waypoints_missed, 0);
        // 300 m at 1.4 m/s = 214 s; the corners and their cues add some.
        assert!(r.time_s > r.nominal_time_s && r.time_s < 1.5 * r.nominal_time_s, "{}", brief(&r));
        assert!(r.cross_track_rmse_m < 5.0, "{}", r.cross_track_rmse_m);
    }

    #[test]
    fn non_finite_settings_terminate() {
        let mut cfg = SimConfig::new(StrategyKind::Pursuit);
        cfg.dt_s = f64::NAN;
        cfg.fix_interval_s = f64::INFINITY;
        cfg.timeout_factor = f64::NAN;
        cfg.wearer.pace_m_s = f64::NAN;
        let r = simulate(&square(), &cfg, 1).unwrap();
        assert!(r.time_s.is_finite());
    }

    #[test]
    fn runs_are_deterministic_per_seed() {
        let cfg = SimConfig::new(StrategyKind::BearingOnly);
        let a = simulate(&square(), &cfg, 11).unwrap();
        let b = simulate(&square(), &cfg, 11).unwrap();
        assert!(a == b, "same seed, different runs");
        let c = simulate(&square(), &cfg, 12).unwrap();
        assert_ne!(a.path_true_en_m, c.path_true_en_m);
    }

    #[test]
    fn realistic_runs_mostly_finish() {
        for kind in StrategyKind::ALL {
            let (_, s) = simulate_many(&square(), &SimConfig::new(kind), 8, 100).unwrap();
            println!("{s:?}");
            assert!(s.finish_rate >= 0.75, "{s:?}");
            assert!(s.cross_track_rmse_m.mean < 15.0, "{s:?}");
            assert!(s.cues_per_min.mean > 1.0 && s.cues_per_min.mean < 30.0, "{s:?}");
        }
    }
}
