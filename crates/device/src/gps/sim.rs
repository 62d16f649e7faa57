//! The built-in simulated receiver: a walker along a route plus the error model, as NMEA.

use std::path::Path;

use chrono::{DateTime, TimeDelta, Utc};
use vestnav_core::gnss_sim::{GnssErrorModel, GnssErrorState, RouteWalker};

use super::GpsError;
use super::nmea_out::{EpochOut, SimSatellite, epoch_sentences};

/// A demo route (a ~250 m loop near MIT's Briggs Field) used when no GPX route is given.
pub const DEFAULT_ROUTE: &[(f64, f64)] =
    &[(42.35620, -71.10000), (42.35680, -71.09900), (42.35780, -71.09950), (42.35620, -71.10000)];

/// Reads a route from a GPX file: the first route's points, else the first track's, else the waypoints.
pub fn load_route_gpx(path: &Path) -> Result<Vec<(f64, f64)>, GpsError> {
    let err = |reason: String| GpsError::Route { path: path.display().to_string(), reason };
    let file = std::fs::File::open(path).map_err(|e| err(e.to_string()))?;
    let gpx = gpx::read(std::io::BufReader::new(file)).map_err(|e| err(e.to_string()))?;
    let pts: Vec<(f64, f64)> = if let Some(r) = gpx.routes.iter().find(|r| !r.points.is_empty()) {
        r.points.iter().map(|w| (w.point().y(), w.point().x())).collect()
    } else if let Some(t) = gpx.tracks.iter().flat_map(|t| t.segments.iter()).find(|s| !s.points.is_empty()) {
        t.points.iter().map(|w| (w.point().y(), w.point().x())).collect()
    } else {
        gpx.waypoints.iter().map(|w| (w.point().y(), w.point().x())).collect()
    };
    if pts.is_empty() {
        return Err(err("no route, track or waypoints".into()));
    }
    Ok(pts)
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
        Ok(Self { walker, error: GnssErrorState::new(model, seed), start, t_s: 0.0, sigma_m })
    }

    /// The walker's true state at the last epoch (position, course, speed): the simulation's truth.
    pub fn truth(&self) -> vestnav_core::gnss_sim::WalkerSample {
        self.walker.sample(self.t_s)
    }

    /// Reconfigures static navigation (`SiRF`) / static hold (u-blox) while running: below `threshold_m_s`
    /// the reported position is held and the reported speed is 0; `None` turns it off. `max_dist_m` is
    /// u-blox's `staticHoldMaxDist` (see `GnssErrorState::set_static_hold`).
    pub fn set_static_hold(&mut self, threshold_m_s: Option<f64>, max_dist_m: Option<f64>) {
        self.error.set_static_hold(threshold_m_s, max_dist_m);
    }

    /// True once the walker has reached the end of the route.
    pub fn finished(&self) -> bool {
        self.walker.sample(self.t_s).finished
    }

    /// UTC time of the last epoch returned (the start time before the first).
    pub fn time(&self) -> DateTime<Utc> {
        self.start + TimeDelta::milliseconds((self.t_s * 1000.0).round() as i64)
    }

    /// Advances by `dt_s` and returns that epoch's NMEA sentences (GGA, GSA, GSV, RMC, GST). While static
    /// navigation holds the position, RMC's speed reads 0 (what the thesis's BT-359 reported).
    pub fn next_epoch(&mut self, dt_s: f64) -> String {
        self.t_s += dt_s;
        let truth = self.walker.sample(self.t_s);
        let en = self.error.apply(dt_s, truth.en_m, truth.speed_m_s);
        let (lat, lon) = self.walker.frame().latlon_from_en(en);
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

    #[test]
    fn demo_gpx_loads_and_simulation_decodes() {
        let gpx = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/routes/demo.gpx");
        let route = if gpx.exists() { load_route_gpx(&gpx).unwrap() } else { DEFAULT_ROUTE.to_vec() };
        let mut rx =
            SimulatedReceiver::new(&route, 1.4, GnssErrorModel::perfect(), 1, DateTime::UNIX_EPOCH).unwrap();
        let text: String = (0..30).map(|_| rx.next_epoch(1.0)).collect();
        let (fixes, stats) = decode_reader(text.as_bytes()).unwrap();
        assert_eq!(stats.rejected(), 0);
        assert_eq!(fixes.len(), 30);
        // Perfect model: 1.4 m/s along the first leg, so fix 10 is 14 m from the start.
        let frame = vestnav_core::gnss_sim::LocalFrame::new(route[0].0, route[0].1);
        let d = frame.en_from_latlon(fixes[9].lat_deg.unwrap(), fixes[9].lon_deg.unwrap()).length();
        assert!((d - 14.0).abs() < 0.05, "{d}");
    }
}
