//! The measures of one navigation trial ([`NavMeter`]), from the positions the wearer's receiver gave while
//! the trial ran: the distance walked, the route's length, the cross-track error's root mean square and the
//! waypoints never reached. The results columns `path_m`, `route_m`, `cross_track_rms_m` and
//! `missed_waypoints` (`docs/study.md`) come from here.

use crate::geo::{Earth, LatLon};
use crate::guidance::path_offset;

/// Accumulates one trial's fixes against the route's polyline (its planned path when it has one, else
/// the straight legs between its waypoints).
#[derive(Debug, Clone)]
pub struct NavMeter {
    earth: Earth,
    route: Vec<LatLon>,
    route_m: f64,
    last: Option<LatLon>,
    path_m: f64,
    sum_sq_m2: f64,
    samples: usize,
    last_cross_track_m: Option<f64>,
    /// Each waypoint with its arrival radius [m], and whether a position came inside it.
    waypoints: Vec<(LatLon, f64, bool)>,
}

impl NavMeter {
    /// A meter for the polyline `route` (at least two points; `None` otherwise).
    ///
    /// The route's length is the sum of the geodesic distances between its consecutive points on `earth`.
    pub fn new(route: Vec<LatLon>, earth: Earth) -> Option<Self> {
        if route.len() < 2 {
            return None;
        }
        let route_m = route.windows(2).map(|w| earth.distance_m(w[0], w[1])).sum();
        Some(Self {
            earth,
            route,
            route_m,
            last: None,
            path_m: 0.0,
            sum_sq_m2: 0.0,
            samples: 0,
            last_cross_track_m: None,
            waypoints: Vec::new(),
        })
    }

    /// The route's waypoints, each with its arrival radius [m]: one counts as reached once a position
    /// comes within its radius. The route's length becomes the walk that completes it: its polyline up to
    /// the last waypoint's arrival circle, `length - radius` (at least 0), as guidance ends the route there.
    #[must_use]
    pub fn with_waypoints(mut self, waypoints: impl IntoIterator<Item = (LatLon, f64)>) -> Self {
        self.waypoints = waypoints.into_iter().map(|(p, r)| (p, r, false)).collect();
        if let Some((_, radius_m, _)) = self.waypoints.last() {
            self.route_m = (self.route_m - radius_m).max(0.0);
        }
        self
    }

    /// Waypoints no position came within the arrival radius of (so far).
    pub fn missed_waypoints(&self) -> usize {
        self.waypoints.iter().filter(|w| !w.2).count()
    }

    /// One position of the wearer, in the order they came.
    ///
    /// The path grows by the geodesic distance from the previous position; the cross-track error is the
    /// distance to the nearest segment of the route's polyline ([`crate::guidance::path_offset`], the same
    /// geometry guidance steers by), signed positive to the right.
    pub fn fix(&mut self, p: LatLon) {
        if let Some(last) = self.last {
            self.path_m += self.earth.distance_m(last, p);
        }
        self.last = Some(p);
        for (w, radius_m, reached) in &mut self.waypoints {
            if !*reached && self.earth.distance_m(*w, p) <= *radius_m {
                *reached = true;
            }
        }
        if let Some(off) = path_offset(self.earth, &self.route, p) {
            self.sum_sq_m2 += off.cross_track_m * off.cross_track_m;
            self.samples += 1;
            self.last_cross_track_m = Some(off.cross_track_m);
        }
    }

    /// The route's length [m]: along its polyline, less the last waypoint's arrival radius when the
    /// waypoints are known ([`Self::with_waypoints`]).
    pub fn route_m(&self) -> f64 {
        self.route_m
    }

    /// The distance walked so far: the sum of the distances between consecutive positions [m].
    pub fn path_m(&self) -> f64 {
        self.path_m
    }

    /// Positions taken.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// The latest position's signed cross-track error [m].
    pub fn last_cross_track_m(&self) -> Option<f64> {
        self.last_cross_track_m
    }

    /// `sqrt(Σ xt² / n)` over the positions taken [m]; `None` before the first.
    pub fn cross_track_rms_m(&self) -> Option<f64> {
        #[allow(clippy::cast_precision_loss, reason = "a trial's fixes are far below 2^52")]
        (self.samples > 0).then(|| (self.sum_sq_m2 / self.samples as f64).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;

    use super::*;

    fn ll(lat: f64, lon: f64) -> LatLon {
        LatLon::new(lat, lon)
    }

    #[test]
    fn a_walk_beside_a_straight_route_has_its_offsets_rms_and_its_length() {
        // On the sphere a degree of latitude is R·π/180 metres and one of longitude that times cos(lat):
        // closed forms, to far better than the tolerance for offsets of metres.
        let earth = Earth::ThesisSphere;
        let deg_m = earth_deg_m();
        // A route due north along the meridian 11° E, 100 m long.
        let route = vec![ll(48.0, 11.0), ll(48.0 + 100.0 / deg_m, 11.0)];
        let mut m = NavMeter::new(route, earth).unwrap();
        assert_relative_eq!(m.route_m(), 100.0, max_relative = 1e-9);
        // Positions 3 m east and 4 m west of it, alternately, every 10 m north: RMS sqrt((9 + 16) / 2).
        let east_deg = |x_m: f64| x_m / (deg_m * 48f64.to_radians().cos());
        for k in 0..10 {
            let x = if k % 2 == 0 { 3.0 } else { -4.0 };
            m.fix(ll(48.0 + f64::from(k) * 10.0 / deg_m, 11.0 + east_deg(x)));
        }
        assert_relative_eq!(m.cross_track_rms_m().unwrap(), 12.5f64.sqrt(), max_relative = 1e-4);
        assert!(m.last_cross_track_m().unwrap() < 0.0, "west is left of a northward route");
        // Each step: 10 m north and 7 m across.
        assert_relative_eq!(m.path_m(), 9.0 * (100.0f64 + 49.0).sqrt(), max_relative = 1e-4);
        assert_eq!(m.samples(), 10);
    }

    #[test]
    fn a_waypoint_counts_as_reached_inside_its_radius_only() {
        let earth = Earth::ThesisSphere;
        let deg_m = earth_deg_m();
        let (a, b, c) = (ll(0.0, 0.0), ll(0.0, 50.0 / deg_m), ll(0.0, 100.0 / deg_m));
        let mut m =
            NavMeter::new(vec![a, b, c], earth).unwrap().with_waypoints([(a, 5.0), (b, 5.0), (c, 5.0)]);
        assert_eq!(m.missed_waypoints(), 3);
        m.fix(ll(4.9 / deg_m, 0.0));
        m.fix(ll(5.1 / deg_m, 50.0 / deg_m));
        m.fix(c);
        assert_eq!(m.missed_waypoints(), 1, "b was passed 5.1 m off");
        assert_relative_eq!(m.route_m(), 95.0, max_relative = 1e-9);
    }

    fn earth_deg_m() -> f64 {
        crate::geo::THESIS_EARTH_RADIUS_M * std::f64::consts::PI / 180.0
    }

    #[test]
    fn a_route_needs_two_points() {
        assert!(NavMeter::new(vec![ll(0.0, 0.0)], Earth::default()).is_none());
    }
}
