//! A simulated GNSS receiver: an error model on local east/north metres, and a walker along a route.
//!
//! Pure: the random generator is seeded and owned, time is a parameter (`dt_s`), there is no clock.
//! The error model has three parts, each switchable:
//! - white noise, independent per axis and per epoch (`noise_sigma_m`);
//! - a slowly wandering bias per axis, a first-order Gauss–Markov process (`bias_sigma_m`, `bias_tau_s`),
//!   the usual model of multipath/ionosphere/ephemeris errors that make a stationary receiver drift;
//! - SiRF-style static navigation (thesis §5, physics.md §5): while the true speed is below a threshold
//!   (~1.2 m/s on a `SiRF` Star III) the receiver keeps reporting the position it last reported.
//!
//! ```
//! use glam::DVec2;
//! use vestnav_core::gnss_sim::{GnssErrorModel, GnssErrorState};
//! let mut err = GnssErrorState::new(GnssErrorModel::perfect(), 7);
//! let p = err.apply(1.0, DVec2::new(3.0, 4.0), 1.4);
//! assert!((p - DVec2::new(3.0, 4.0)).length() < 1e-12);
//! ```

use glam::DVec2;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};

use crate::geo::{Earth, LatLon, LocalFrame};

/// Parameters of the simulated receiver error, per horizontal axis (east and north independently).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GnssErrorModel {
    /// Standard deviation of the white noise added to every epoch, per axis [m].
    pub noise_sigma_m: f64,
    /// Stationary standard deviation of the Gauss–Markov bias, per axis [m].
    pub bias_sigma_m: f64,
    /// Correlation time of the Gauss–Markov bias [s].
    pub bias_tau_s: f64,
    /// Static navigation: hold the last reported position while the true speed is below this [m/s].
    pub static_nav_threshold_m_s: Option<f64>,
}

impl GnssErrorModel {
    /// A `SiRF` Star III receiver under open sky, as in the thesis's field tests (§5).
    ///
    /// Rated 10 m RMSE (1–5 m with WAAS); the thesis's stationary drift stayed within 1.17 m over 3 min,
    /// which is static navigation pinning more than accuracy. We use a 2 m per-axis bias wandering with a
    /// 300 s correlation time (per-axis horizontal error ~2.1 m, 2D RMS ~3 m: the WAAS-class figure),
    /// 0.5 m white noise, and static navigation below 1.2 m/s (physics.md §5).
    pub fn sirf3_open_sky() -> Self {
        Self { noise_sigma_m: 0.5, bias_sigma_m: 2.0, bias_tau_s: 300.0, static_nav_threshold_m_s: Some(1.2) }
    }

    /// The same receiver with static navigation switched off (what a u-blox-class receiver does).
    pub fn sirf3_no_static_nav() -> Self {
        Self { static_nav_threshold_m_s: None, ..Self::sirf3_open_sky() }
    }

    /// No error at all: the output is the true position.
    pub fn perfect() -> Self {
        Self { noise_sigma_m: 0.0, bias_sigma_m: 0.0, bias_tau_s: 1.0, static_nav_threshold_m_s: None }
    }

    /// Expected horizontal RMS error (2D, "DRMS") of a moving receiver: `sqrt(2 (sigma_n^2 + sigma_b^2))`.
    ///
    /// Both components are zero-mean and independent per axis, so their variances add, and the two axes
    /// add again for the horizontal distance.
    pub fn horizontal_rms_m(&self) -> f64 {
        (2.0 * (self.noise_sigma_m.powi(2) + self.bias_sigma_m.powi(2))).sqrt()
    }
}

impl Default for GnssErrorModel {
    fn default() -> Self {
        Self::sirf3_open_sky()
    }
}

/// The evolving state of one simulated receiver's error: owns its seeded random generator.
#[derive(Debug)]
pub struct GnssErrorState {
    model: GnssErrorModel,
    rng: StdRng,
    bias_m: DVec2,
    last_output_m: Option<DVec2>,
    static_max_dist_m: Option<f64>,
    pinned: bool,
}

impl GnssErrorState {
    /// A new receiver; the initial bias is drawn from the bias's stationary distribution `N(0, sigma_b^2)`.
    pub fn new(model: GnssErrorModel, seed: u64) -> Self {
        let mut rng = StdRng::seed_from_u64(seed);
        let bias_m = DVec2::new(normal(&mut rng), normal(&mut rng)) * model.bias_sigma_m;
        Self { model, rng, bias_m, last_output_m: None, static_max_dist_m: None, pinned: false }
    }

    /// The model this state follows.
    pub fn model(&self) -> &GnssErrorModel {
        &self.model
    }

    /// Changes the static-navigation (static-hold) threshold while running, as a receiver configured by
    /// its host does: `None` turns it off. `max_dist_m` is u-blox's `staticHoldMaxDist`: the hold is left
    /// once the fresh solution is more than this far from the held one (`None`: no limit, as `SiRF`'s
    /// static navigation).
    pub fn set_static_hold(&mut self, threshold_m_s: Option<f64>, max_dist_m: Option<f64>) {
        self.model.static_nav_threshold_m_s = threshold_m_s.filter(|t| t.is_finite() && *t > 0.0);
        self.static_max_dist_m = max_dist_m.filter(|d| d.is_finite() && *d > 0.0);
    }

    /// Whether the last [`Self::apply`] repeated the previous report (static navigation holding it).
    pub fn pinned(&self) -> bool {
        self.pinned
    }

    /// The current bias (east, north) [m].
    pub fn bias_m(&self) -> DVec2 {
        self.bias_m
    }

    /// Advances the error by `dt_s` and returns the reported east/north position for a true one.
    ///
    /// Gauss–Markov bias, exact discretisation of `db/dt = -b/tau + w`:
    /// `b_k+1 = b_k exp(-dt/tau) + sigma_b sqrt(1 - exp(-2 dt/tau)) n_k`, `n_k ~ N(0, 1)`,
    /// which keeps the stationary variance at `sigma_b^2` for any step (Brown & Hwang, *Introduction to
    /// Random Signals and Applied Kalman Filtering*, §4.2). The reported position is
    /// `p = true + b + sigma_n m_k`; with static navigation on and `speed_m_s` below the threshold the
    /// previous report is repeated instead (thesis §5; with a `staticHoldMaxDist` set by
    /// [`Self::set_static_hold`], only while the fresh solution stays that close). Non-finite or negative `dt_s` is treated as 0.
    pub fn apply(&mut self, dt_s: f64, true_en_m: DVec2, speed_m_s: f64) -> DVec2 {
        let dt_s = if dt_s.is_finite() && dt_s > 0.0 { dt_s } else { 0.0 };
        let tau_s = self.model.bias_tau_s.max(f64::MIN_POSITIVE);
        let phi = (-dt_s / tau_s).exp();
        let drive = self.model.bias_sigma_m * (1.0 - phi * phi).max(0.0).sqrt();
        let n_bias = DVec2::new(normal(&mut self.rng), normal(&mut self.rng));
        let n_white = DVec2::new(normal(&mut self.rng), normal(&mut self.rng));
        self.bias_m = self.bias_m * phi + n_bias * drive;
        let fresh = true_en_m + self.bias_m + n_white * self.model.noise_sigma_m;
        let within = |last: DVec2| self.static_max_dist_m.is_none_or(|d| (fresh - last).length() <= d);
        let out = match (self.model.static_nav_threshold_m_s, self.last_output_m) {
            (Some(threshold), Some(last)) if speed_m_s < threshold && within(last) => last,
            _ => fresh,
        };
        self.pinned = self.last_output_m == Some(out) && self.model.static_nav_threshold_m_s.is_some();
        self.last_output_m = Some(out);
        out
    }
}

fn normal(rng: &mut StdRng) -> f64 {
    StandardNormal.sample(rng)
}

/// Where the walker is at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WalkerSample {
    /// True latitude [deg].
    pub lat_deg: f64,
    /// True longitude [deg].
    pub lon_deg: f64,
    /// True position in the route's local frame (origin = first waypoint) [m].
    pub en_m: DVec2,
    /// Speed over ground [m/s] (0 once the route is finished).
    pub speed_m_s: f64,
    /// Course over ground, degrees clockwise from true north, in [0, 360).
    pub course_deg: f64,
    /// Distance walked along the route [m].
    pub along_m: f64,
    /// True once the last waypoint is reached (the walker then stands still there).
    pub finished: bool,
}

/// A walker following a route of lat/lon waypoints at a constant pace, straight between waypoints.
#[derive(Debug, Clone)]
pub struct RouteWalker {
    frame: LocalFrame,
    points_m: Vec<DVec2>,
    cumulative_m: Vec<f64>,
    pace_m_s: f64,
}

/// Errors building a [`RouteWalker`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RouteError {
    /// A route needs at least one waypoint.
    #[error("the route has no waypoints")]
    Empty,
    /// A waypoint is not a finite latitude in [-90, 90] and longitude in [-180, 180].
    #[error("waypoint {index} ({lat_deg}, {lon_deg}) is not a valid latitude/longitude")]
    BadWaypoint {
        /// Index of the waypoint in the route.
        index: usize,
        /// Its latitude [deg].
        lat_deg: f64,
        /// Its longitude [deg].
        lon_deg: f64,
    },
    /// The pace must be finite and non-negative.
    #[error("pace {0} m/s is not a finite non-negative speed")]
    BadPace(f64),
}

impl RouteWalker {
    /// A walker along `waypoints` (latitude, longitude in degrees) at `pace_m_s`.
    pub fn new(waypoints: &[(f64, f64)], pace_m_s: f64) -> Result<Self, RouteError> {
        let &(lat0, lon0) = waypoints.first().ok_or(RouteError::Empty)?;
        if !(pace_m_s.is_finite() && pace_m_s >= 0.0) {
            return Err(RouteError::BadPace(pace_m_s));
        }
        for (index, &(lat_deg, lon_deg)) in waypoints.iter().enumerate() {
            let ok = lat_deg.is_finite()
                && lon_deg.is_finite()
                && (-90.0..=90.0).contains(&lat_deg)
                && (-180.0..=180.0).contains(&lon_deg);
            if !ok {
                return Err(RouteError::BadWaypoint { index, lat_deg, lon_deg });
            }
        }
        let frame = LocalFrame::new(LatLon::new(lat0, lon0), Earth::Wgs84);
        let points_m: Vec<DVec2> =
            waypoints.iter().map(|&(la, lo)| frame.enu_from_wgs84(LatLon::new(la, lo))).collect();
        let mut cumulative_m = Vec::with_capacity(points_m.len());
        let mut total = 0.0;
        cumulative_m.push(0.0);
        for pair in points_m.windows(2) {
            total += (pair[1] - pair[0]).length();
            cumulative_m.push(total);
        }
        Ok(Self { frame, points_m, cumulative_m, pace_m_s })
    }

    /// The local frame of the route (origin = first waypoint, WGS-84).
    pub fn frame(&self) -> &LocalFrame {
        &self.frame
    }

    /// Total length of the route [m] (sum of the straight legs in the local frame).
    pub fn length_m(&self) -> f64 {
        self.cumulative_m.last().copied().unwrap_or(0.0)
    }

    /// The walking pace [m/s].
    pub fn pace_m_s(&self) -> f64 {
        self.pace_m_s
    }

    /// Where the walker is `t_s` seconds after starting at the first waypoint.
    ///
    /// Distance along the route `s = pace t` (clamped to the route), then linear interpolation on the leg
    /// containing `s`. The course is the leg's bearing `atan2(east, north)`.
    pub fn sample(&self, t_s: f64) -> WalkerSample {
        let total = self.length_m();
        let s = (self.pace_m_s * t_s.max(0.0)).min(total);
        let finished = s >= total;
        // The leg whose start is the last cumulative distance <= s.
        let leg = self.cumulative_m.partition_point(|&c| c <= s).saturating_sub(1);
        let (en_m, course_deg) = match (self.points_m.get(leg), self.points_m.get(leg + 1)) {
            (Some(&a), Some(&b)) => {
                let len = (b - a).length();
                let frac = if len > 0.0 { (s - self.cumulative_m[leg]) / len } else { 0.0 };
                (a + (b - a) * frac.clamp(0.0, 1.0), bearing_deg(b - a))
            }
            (Some(&a), None) => {
                // At (or past) the last waypoint: keep the last leg's course.
                let course = if leg > 0 { bearing_deg(a - self.points_m[leg - 1]) } else { 0.0 };
                (a, course)
            }
            _ => (DVec2::ZERO, 0.0),
        };
        let LatLon { lat_deg, lon_deg } = self.frame.wgs84_from_enu(en_m);
        WalkerSample {
            lat_deg,
            lon_deg,
            en_m,
            speed_m_s: if finished { 0.0 } else { self.pace_m_s },
            course_deg,
            along_m: s,
            finished,
        }
    }
}

/// Bearing of an east/north vector, degrees clockwise from north in [0, 360).
fn bearing_deg(d: DVec2) -> f64 {
    let b = d.x.atan2(d.y).to_degrees();
    if b < 0.0 { b + 360.0 } else { b }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn perfect_model_is_identity() {
        let mut s = GnssErrorState::new(GnssErrorModel::perfect(), 1);
        for k in 0..100 {
            let p = DVec2::new(f64::from(k), -2.0 * f64::from(k));
            assert!((s.apply(1.0, p, 1.4) - p).length() < 1e-12);
        }
    }

    #[test]
    fn same_seed_same_errors() {
        let mut a = GnssErrorState::new(GnssErrorModel::sirf3_no_static_nav(), 42);
        let mut b = GnssErrorState::new(GnssErrorModel::sirf3_no_static_nav(), 42);
        for _ in 0..50 {
            assert_eq!(a.apply(1.0, DVec2::ZERO, 1.4), b.apply(1.0, DVec2::ZERO, 1.4));
        }
    }

    /// Over many independent receivers the per-axis variance matches `sigma_n^2 + sigma_b^2` (closed form).
    #[test]
    fn error_variance_matches_model() {
        let model = GnssErrorModel::sirf3_no_static_nav();
        let mut sum_sq = 0.0;
        let mut n = 0.0;
        for seed in 0..400 {
            let mut s = GnssErrorState::new(model, seed);
            for _ in 0..25 {
                let e = s.apply(60.0, DVec2::ZERO, 1.4);
                sum_sq += e.x * e.x + e.y * e.y;
                n += 2.0;
            }
        }
        let expected = model.noise_sigma_m.powi(2) + model.bias_sigma_m.powi(2);
        assert_relative_eq!(sum_sq / n, expected, max_relative = 0.08);
        assert_relative_eq!((2.0 * expected).sqrt(), model.horizontal_rms_m(), max_relative = 1e-12);
    }

    /// The bias's lag-k autocorrelation is exp(-k dt / tau) (Gauss–Markov closed form).
    #[test]
    fn bias_autocorrelation_decays_with_tau() {
        let model = GnssErrorModel {
            noise_sigma_m: 0.0,
            bias_sigma_m: 1.0,
            bias_tau_s: 10.0,
            static_nav_threshold_m_s: None,
        };
        let mut s = GnssErrorState::new(model, 9);
        let xs: Vec<f64> = (0..200_000).map(|_| s.apply(1.0, DVec2::ZERO, 1.4).x).collect();
        let var: f64 = xs.iter().map(|x| x * x).sum::<f64>() / xs.len() as f64;
        let lag = 10;
        let cov: f64 = xs.windows(lag + 1).map(|w| w[0] * w[lag]).sum::<f64>() / (xs.len() - lag) as f64;
        assert_relative_eq!(cov / var, (-1.0f64).exp(), max_relative = 0.08);
    }

    #[test]
    fn static_nav_pins_below_threshold_and_releases_above() {
        let mut s = GnssErrorState::new(GnssErrorModel::sirf3_open_sky(), 3);
        let first = s.apply(1.0, DVec2::ZERO, 0.0);
        for k in 1..30 {
            let p = s.apply(1.0, DVec2::new(0.5 * f64::from(k), 0.0), 0.5);
            assert_eq!(p, first);
        }
        let moving = s.apply(1.0, DVec2::new(100.0, 0.0), 1.4);
        assert!((moving - DVec2::new(100.0, 0.0)).length() < 20.0);
        assert!(moving != first);
    }

    #[test]
    fn walker_follows_legs() {
        let f = LocalFrame::new(LatLon::new(42.0, -71.0), Earth::Wgs84);
        let ll = |en: DVec2| {
            let p = f.wgs84_from_enu(en);
            (p.lat_deg, p.lon_deg)
        };
        let (a, b, c) = (ll(DVec2::ZERO), ll(DVec2::new(0.0, 100.0)), ll(DVec2::new(50.0, 100.0)));
        let w = RouteWalker::new(&[a, b, c], 1.25).unwrap();
        assert_relative_eq!(w.length_m(), 150.0, max_relative = 1e-9);
        let s = w.sample(40.0); // 50 m along the first leg, heading north
        assert_relative_eq!(s.en_m.y, 50.0, max_relative = 1e-9);
        assert!(s.course_deg.abs() < 1e-9);
        let s = w.sample(100.0); // 125 m: 25 m into the eastbound leg
        assert_relative_eq!(s.en_m.x, 25.0, max_relative = 1e-9);
        assert_relative_eq!(s.course_deg, 90.0, max_relative = 1e-9);
        let end = w.sample(1e6);
        assert!(end.finished);
        assert!(end.speed_m_s.abs() < f64::EPSILON);
        assert_relative_eq!(end.lat_deg, c.0, max_relative = 1e-12);
    }

    #[test]
    fn walker_rejects_bad_routes() {
        assert_eq!(RouteWalker::new(&[], 1.0).unwrap_err(), RouteError::Empty);
        assert!(RouteWalker::new(&[(91.0, 0.0)], 1.0).is_err());
        assert!(RouteWalker::new(&[(0.0, 0.0)], f64::NAN).is_err());
        let single = RouteWalker::new(&[(1.0, 2.0)], 1.0).unwrap();
        assert!(single.sample(10.0).finished);
    }
}
