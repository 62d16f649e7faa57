//! The built-in simulated receiver: a walker along a route plus the error model, as NMEA.
//!
//! Routes come from GPX through [`crate::route_file`] (the one reader: size limit, checked coordinates,
//! the one choice of what to walk); with no file, the simulator walks the one demo route,
//! [`crate::route_file::DEMO_GPX`].

use std::path::Path;

use std::collections::VecDeque;

use chrono::{DateTime, TimeDelta, Utc};
use glam::DVec2;
use rand::SeedableRng as _;
use rand::rngs::StdRng;
use vestnav_core::geo::{bearing_of_enu_deg, normalize_deg};
use vestnav_core::gnss_sim::{GnssErrorModel, GnssErrorState, RouteWalker, WalkerSample};
use vestnav_core::vest::{Cue, TactorMask};
use vestnav_core::wearer::{Body, Skin, WearerModel};

use super::GpsError;
use super::nmea_out::{EpochOut, SimSatellite, epoch_sentences};
use crate::route_file::{DEMO_GPX, DefaultRoute, parse_gpx, read_gpx};

/// The points of a GPX file's route to walk, as (latitude, longitude) \[deg\]: what
/// [`crate::route_file::RouteFile::default_route`] picks (the first route, else the waypoints, else the first
/// track).
pub fn load_route_gpx(path: &Path) -> Result<Vec<(f64, f64)>, GpsError> {
    let err = |reason: String| GpsError::Route { path: path.display().to_string(), reason };
    let file = read_gpx(path).map_err(|e| err(e.to_string()))?;
    file.default_route().as_ref().map(points).ok_or_else(|| err("no route, track or waypoints".into()))
}

/// The demo route (`assets/routes/demo.gpx`, a loop around MIT's Briggs Field) as (latitude, longitude)
/// \[deg\]: what the simulator walks when no route is given.
pub fn demo_route() -> Result<Vec<(f64, f64)>, GpsError> {
    let err = |reason: String| GpsError::Route { path: "(built-in demo route)".into(), reason };
    let file = parse_gpx(DEMO_GPX).map_err(|e| err(e.to_string()))?;
    file.default_route().as_ref().map(points).ok_or_else(|| err("no route, track or waypoints".into()))
}

/// What the simulated walker walks: the route's path when it follows one (a planner's GPX), else its points.
fn points(route: &DefaultRoute) -> Vec<(f64, f64)> {
    match &route.path {
        Some(p) => p.points().iter().map(|q| (q.lat_deg, q.lon_deg)).collect(),
        None => route.waypoints.iter().map(|w| (w.lat_deg, w.lon_deg)).collect(),
    }
}

/// The current UTC time truncated to a whole second (receivers report epochs on the second).
pub fn whole_second_now() -> DateTime<Utc> {
    DateTime::from_timestamp(Utc::now().timestamp(), 0).unwrap_or(DateTime::UNIX_EPOCH)
}

/// A walker steered by the vest instead of the route: core's wearer model ([`Body`], [`WearerModel`]'s
/// defaults: 92 % of cues recognised, 0.8 s reaction, 70° turns with 10° of noise, veering) feeling the
/// emulated unit's tactors through a [`Skin`]. It starts at the route's first point facing its first leg
/// and stops when told "arrived" within [`CueWalker::END_RADIUS_M`] of the route's last point.
#[derive(Debug)]
struct CueWalker {
    body: Body,
    model: WearerModel,
    rng: StdRng,
    skin: Skin,
    /// Tactor changes not yet felt: (receiver clock [s], tactors on).
    touches: VecDeque<(f64, TactorMask)>,
    /// The walker's clock [s] (the receiver's, in sub-steps).
    t_s: f64,
    walked_m: f64,
    /// The route's last point in the route's frame [m].
    end_m: DVec2,
}

impl CueWalker {
    /// The wearer's sub-step [s] (as in `vestnav nav simulate`).
    const STEP_S: f64 = 0.1;
    /// "Arrived" within this of the route's end stops the wearer [m].
    const END_RADIUS_M: f64 = 15.0;

    fn new(walker: &RouteWalker, route: &[(f64, f64)], seed: u64) -> Self {
        let frame = walker.frame();
        let pts: Vec<DVec2> = route
            .iter()
            .map(|&(la, lo)| frame.enu_from_wgs84(vestnav_core::geo::LatLon::new(la, lo)))
            .collect();
        let first_leg =
            pts.iter().skip(1).map(|p| *p - pts[0]).find(|d| d.length() > 0.0).unwrap_or(DVec2::Y);
        Self {
            body: Body::new(DVec2::ZERO, normalize_deg(bearing_of_enu_deg(first_leg)), true),
            model: WearerModel::default(),
            rng: StdRng::seed_from_u64(seed ^ 0x5EED_0FF0_110E),
            skin: Skin::default(),
            touches: VecDeque::new(),
            t_s: 0.0,
            walked_m: 0.0,
            end_m: pts.last().copied().unwrap_or(DVec2::ZERO),
        }
    }

    /// Walks on to `until_s` feeling the tactor changes up to each step; standing still (turning on the
    /// spot for a calibration) it still feels, but does not move.
    fn walk_to(&mut self, until_s: f64, standing: bool) {
        while self.t_s + Self::STEP_S <= until_s + 1e-9 {
            let t = self.t_s;
            while let Some(&(at, mask)) = self.touches.front()
                && at <= t
            {
                self.skin.touch(mask, at);
                self.touches.pop_front();
            }
            if let Some((cue, end_s)) = self.skin.felt(t) {
                if cue == Cue::Arrived && (self.body.pos_en_m - self.end_m).length() <= Self::END_RADIUS_M {
                    self.body.walking = false;
                    self.body.stopped = true;
                } else {
                    self.body.feel(&self.model, cue, end_s, t, &mut self.rng);
                }
            }
            if !standing {
                self.walked_m += self.body.advance(&self.model, None, t, Self::STEP_S, &mut self.rng);
            }
            self.t_s += Self::STEP_S;
        }
    }

    fn sample(&self, walker: &RouteWalker) -> WalkerSample {
        let en_m = self.body.pos_en_m;
        let p = walker.frame().wgs84_from_enu(en_m);
        WalkerSample {
            lat_deg: p.lat_deg,
            lon_deg: p.lon_deg,
            en_m,
            speed_m_s: self.body.speed_m_s(&self.model),
            course_deg: self.body.heading_deg,
            along_m: self.walked_m,
            finished: false,
        }
    }
}

/// A simulated receiver walking a route: call [`Self::next_epoch`] once per second.
#[derive(Debug)]
pub struct SimulatedReceiver {
    walker: RouteWalker,
    /// Steered by the vest instead ([`Self::steered_by_vest`]).
    follower: Option<CueWalker>,
    error: GnssErrorState,
    start: DateTime<Utc>,
    t_s: f64,
    /// Time spent standing ([`Self::next_epoch_standing`]): the walker's own time is `t_s - stood_s`.
    stood_s: f64,
    sigma_m: f64,
}

impl SimulatedReceiver {
    /// A receiver at the route's start at `start` (UTC), walking at `pace_m_s`.
    pub fn new(
        route: &[(f64, f64)],
        pace_m_s: f64,
        model: GnssErrorModel,
        seed: u64,
        start: DateTime<Utc>,
    ) -> Result<Self, GpsError> {
        let walker = RouteWalker::new(route, pace_m_s)
            .map_err(|e| GpsError::Route { path: "(route)".into(), reason: e.to_string() })?;
        let sigma_m = (model.noise_sigma_m.powi(2) + model.bias_sigma_m.powi(2)).sqrt();
        Ok(Self {
            walker,
            follower: None,
            error: GnssErrorState::new(model, seed),
            start,
            t_s: 0.0,
            stood_s: 0.0,
            sigma_m,
        })
    }

    /// The same receiver carried by a wearer whom the vest steers: from the route's first point, facing
    /// its first leg, the walker goes where the cues it feels ([`Self::touch`]) turn it, as core's wearer
    /// model does, and never finishes by itself.
    #[must_use]
    pub fn steered_by_vest(mut self, route: &[(f64, f64)], seed: u64) -> Self {
        self.follower = Some(CueWalker::new(&self.walker, route, seed));
        self
    }

    /// Whether the vest steers the walker.
    pub fn is_steered_by_vest(&self) -> bool {
        self.follower.is_some()
    }

    /// The vest switched the tactors in `mask` on (every other off) `t_s` seconds after the receiver's
    /// start: felt by a walker the vest steers (ignored otherwise). Changes must come in time order.
    pub fn touch(&mut self, mask: TactorMask, t_s: f64) {
        if let Some(f) = &mut self.follower {
            // Bounded like the shared queue it is fed from.
            if f.touches.len() >= 4096 {
                f.touches.pop_front();
            }
            f.touches.push_back((t_s.max(0.0), mask));
        }
    }

    /// The walker's true state at the last epoch (position, course, speed): the simulation's truth.
    pub fn truth(&self) -> WalkerSample {
        match &self.follower {
            Some(f) => f.sample(&self.walker),
            None => self.walker.sample(self.t_s - self.stood_s),
        }
    }

    /// Reconfigures static navigation (`SiRF`) / static hold (u-blox) while running: below `threshold_m_s`
    /// the reported position is held and the reported speed is 0; `None` turns it off. `max_dist_m` is
    /// u-blox's `staticHoldMaxDist` (see `GnssErrorState::set_static_hold`).
    pub fn set_static_hold(&mut self, threshold_m_s: Option<f64>, max_dist_m: Option<f64>) {
        self.error.set_static_hold(threshold_m_s, max_dist_m);
    }

    /// True once the walker has reached the end of the route.
    pub fn finished(&self) -> bool {
        self.truth().finished
    }

    /// UTC time of the last epoch returned (the start time before the first).
    pub fn time(&self) -> DateTime<Utc> {
        self.start + TimeDelta::milliseconds((self.t_s * 1000.0).round() as i64)
    }

    /// Advances by `dt_s` and returns that epoch's NMEA sentences (GGA, GSA, GSV, RMC, GST). While static
    /// navigation holds the position, RMC's speed reads 0 (what the thesis's BT-359 reported).
    pub fn next_epoch(&mut self, dt_s: f64) -> String {
        self.epoch(dt_s, false)
    }

    /// Advances the clock by `dt_s` with the walker standing where it is (turning on the spot for a
    /// compass calibration) and returns that epoch's sentences: the receiver sees a standing wearer.
    pub fn next_epoch_standing(&mut self, dt_s: f64) -> String {
        self.epoch(dt_s, true)
    }

    fn epoch(&mut self, dt_s: f64, standing: bool) -> String {
        self.t_s += dt_s;
        if standing {
            self.stood_s += dt_s;
        }
        if let Some(f) = &mut self.follower {
            f.walk_to(self.t_s, standing);
        }
        let mut truth = self.truth();
        if standing {
            truth.speed_m_s = 0.0;
        }
        let en = self.error.apply(dt_s, truth.en_m, truth.speed_m_s);
        let vestnav_core::geo::LatLon { lat_deg: lat, lon_deg: lon } = self.walker.frame().wgs84_from_enu(en);
        let time = self.time();
        let satellites = (0u16..10)
            .map(|k| SimSatellite {
                prn: [2, 5, 7, 12, 13, 15, 18, 20, 25, 29][usize::from(k)],
                elevation_deg: 15.0 + 7.0 * f64::from(k),
                azimuth_deg: f64::from((k * 37) % 360),
                snr_dbhz: 30.0 + f64::from(k),
                used: k >= 2,
            })
            .collect();
        epoch_sentences(&EpochOut {
            time,
            lat_deg: Some(lat),
            lon_deg: Some(lon),
            alt_m: 10.0,
            // A receiver holding its position (static navigation) reports it standing still.
            speed_m_s: if self.error.pinned() { 0.0 } else { truth.speed_m_s },
            course_deg: truth.course_deg,
            satellites,
            hdop: 1.0,
            pdop: 1.8,
            vdop: 1.5,
            sigma_m: self.sigma_m,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gps::decode_reader;
    use vestnav_core::geo::{Earth, LatLon, LocalFrame};

    /// The tactor changes of `cue`'s pattern played from `start_s` [s], ending off.
    fn played(cue: Cue, start_s: f64) -> Vec<(f64, TactorMask)> {
        let p = cue.pattern(vestnav_core::vest::DEFAULT_ON_MS);
        let mut t = start_s;
        let mut out = Vec::new();
        for f in &p.frames {
            out.push((t, f.mask));
            t += f64::from(f.duration_ms) / 1000.0;
        }
        out.push((t, TactorMask::NONE));
        out
    }

    #[test]
    fn a_walker_steered_by_the_vest_turns_where_the_cues_say() {
        // A 300 m leg due north; the walker starts at its first point facing north.
        let start = LatLon::new(42.3562, -71.1);
        let end = Earth::Wgs84.direct(start, 0.0, 300.0);
        let route = [(start.lat_deg, start.lon_deg), (end.lat_deg, end.lon_deg)];
        let model = GnssErrorModel::perfect();
        let (mut turned, mut seeds) = (0, 0);
        for seed in 1..=20 {
            let mut rx = SimulatedReceiver::new(&route, 1.4, model, seed, whole_second_now())
                .unwrap()
                .steered_by_vest(&route, seed);
            assert!(rx.is_steered_by_vest());
            for _ in 0..3 {
                rx.next_epoch(1.0);
            }
            let before = rx.truth();
            // Walking north (veering a little), 3 s at 1.4 m/s, not along the route by construction.
            assert!(before.course_deg < 20.0 || before.course_deg > 340.0, "{before:?}");
            assert!((before.en_m.length() - 4.2).abs() < 0.2, "{before:?}");
            // "Turn right" felt from 3.2 s (1 s pattern), then 5 s to react and turn.
            for (t, m) in played(Cue::TurnRight, 3.2) {
                rx.touch(m, t);
            }
            for _ in 0..5 {
                rx.next_epoch(1.0);
            }
            let after = rx.truth();
            seeds += 1;
            // 70° right with N(0, 10°) of noise and some veer, when recognised (92 %).
            if (40.0..=100.0).contains(&after.course_deg) {
                turned += 1;
            } else {
                assert!(after.course_deg < 30.0 || after.course_deg > 330.0, "seed {seed}: {after:?}");
            }
            assert!(!rx.finished(), "a steered walker never finishes by itself");
        }
        // Binomial(20, 0.92): at least 15 turned with probability > 0.99 (the runs are seeded: fixed).
        eprintln!("{turned} of {seeds} walkers turned right");
        assert!(turned >= 15, "{turned} of {seeds} turned right");
    }

    #[test]
    fn a_walker_told_arrived_at_the_end_stops_there() {
        let start = LatLon::new(42.3562, -71.1);
        let end = Earth::Wgs84.direct(start, 0.0, 10.0);
        let route = [(start.lat_deg, start.lon_deg), (end.lat_deg, end.lon_deg)];
        let mut rx = SimulatedReceiver::new(&route, 1.4, GnssErrorModel::perfect(), 3, whole_second_now())
            .unwrap()
            .steered_by_vest(&route, 3);
        for _ in 0..7 {
            rx.next_epoch(1.0);
        }
        // Arrived is recognised with the model's 92 %: played until it takes (seeded, so fixed).
        let mut t = 7.2;
        for _ in 0..5 {
            for (at, m) in played(Cue::Arrived, t) {
                rx.touch(m, at);
            }
            t += 3.0;
            for _ in 0..3 {
                rx.next_epoch(1.0);
            }
        }
        let a = rx.truth();
        assert!(a.speed_m_s.abs() < f64::EPSILON, "{a:?}");
        rx.next_epoch(1.0);
        assert_eq!(rx.truth().en_m, a.en_m, "standing");
    }

    #[test]
    fn bad_gpx_is_refused_by_the_one_reader() {
        let dir = std::env::temp_dir().join(format!("vestnav-simgpx-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bad.gpx");
        let gpx = r#"<gpx version="1.1"><rte><rtept lat="95" lon="0"/></rte></gpx>"#;
        std::fs::write(&path, gpx).unwrap();
        let e = load_route_gpx(&path).unwrap_err().to_string();
        assert!(e.contains("bad.gpx") && e.contains("rtept #1") && e.contains("latitude"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn demo_gpx_loads_and_simulation_decodes() {
        let gpx = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/routes/demo.gpx");
        let route = load_route_gpx(&gpx).unwrap();
        assert_eq!(route, demo_route().unwrap());
        // The first point as typed in the file.
        assert_eq!(route.len(), 7);
        assert!((route[0].0 - 42.3562).abs() < 1e-12 && (route[0].1 + 71.1).abs() < 1e-12);
        let mut rx =
            SimulatedReceiver::new(&route, 1.4, GnssErrorModel::perfect(), 1, DateTime::UNIX_EPOCH).unwrap();
        let text: String = (0..30).map(|_| rx.next_epoch(1.0)).collect();
        let (fixes, stats) = decode_reader(text.as_bytes()).unwrap();
        assert_eq!(stats.rejected(), 0);
        assert_eq!(fixes.len(), 30);
        // Perfect model: 1.4 m/s along the first leg, so fix 10 is 14 m from the start.
        let frame = LocalFrame::new(LatLon::new(route[0].0, route[0].1), Earth::Wgs84);
        let d =
            frame.enu_from_wgs84(LatLon::new(fixes[9].lat_deg.unwrap(), fixes[9].lon_deg.unwrap())).length();
        assert!((d - 14.0).abs() < 0.05, "{d}");
    }
}
