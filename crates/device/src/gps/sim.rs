//! The built-in simulated receiver: a walker along a route plus the error model, as NMEA.
//!
//! Routes come from GPX through [`crate::route_file`] (the one reader: size limit, checked coordinates,
//! the one choice of what to walk); with no file, the simulator walks the one demo route,
//! [`crate::route_file::DEMO_GPX`].

use std::path::Path;

use chrono::{DateTime, TimeDelta, Utc};
use vestnav_core::gnss_sim::{GnssErrorModel, GnssErrorState, RouteWalker};

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

/// A simulated receiver walking a route: call [`Self::next_epoch`] once per second.
#[derive(Debug)]
pub struct SimulatedReceiver {
    walker: RouteWalker,
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
        Ok(Self { walker, error: GnssErrorState::new(model, seed), start, t_s: 0.0, stood_s: 0.0, sigma_m })
    }

    /// The walker's true state at the last epoch (position, course, speed): the simulation's truth.
    pub fn truth(&self) -> vestnav_core::gnss_sim::WalkerSample {
        self.walker.sample(self.t_s - self.stood_s)
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
