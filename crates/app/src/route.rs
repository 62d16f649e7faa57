//! Waypoints, the wearer's track, and GPX import/export.
//!
//! Distances and bearings are WGS-84 geodesics (geographiclib, Karney 2013), the default of the guidance
//! issue; the thesis's spherical formula is not used in the console.

use geographiclib_rs::{Geodesic, InverseGeodesic};
use serde::{Deserialize, Serialize};

/// The demo route shipped with vestnav (Briggs Field loop, MIT), loaded when nothing else is.
pub const DEMO_GPX: &str = include_str!("../../../assets/routes/demo.gpx");

/// A named point the wearer should reach.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Waypoint {
    /// Name shown on the map.
    pub name: String,
    /// Latitude [deg].
    pub lat_deg: f64,
    /// Longitude [deg].
    pub lon_deg: f64,
}

/// Geodesic distance [m] and initial bearing [deg, 0..360 clockwise from true north] from point 1 to 2.
///
/// Solves the inverse geodesic problem on the WGS-84 ellipsoid (Karney, "Algorithms for geodesics", 2013).
pub fn distance_bearing(lat1_deg: f64, lon1_deg: f64, lat2_deg: f64, lon2_deg: f64) -> (f64, f64) {
    let g = Geodesic::wgs84();
    let (s12_m, azi1_deg, _azi2, _a12): (f64, f64, f64, f64) =
        g.inverse(lat1_deg, lon1_deg, lat2_deg, lon2_deg);
    (s12_m, azi1_deg.rem_euclid(360.0))
}

/// East/north offset [m] of a point from an origin, on the local tangent plane.
///
/// Equirectangular approximation: `east = R_N cos(lat0) dlon`, `north = R_M dlat` with the WGS-84 radii of
/// curvature `R_M = a(1-e^2)/(1-e^2 sin^2 lat0)^1.5`, `R_N = a/(1-e^2 sin^2 lat0)^0.5`; good to well under a
/// centimetre over the few hundred metres of a walk (used only for drawing and cross-track display).
pub fn enu_from_wgs84(lat0_deg: f64, lon0_deg: f64, lat_deg: f64, lon_deg: f64) -> (f64, f64) {
    const A_M: f64 = 6_378_137.0;
    const E2: f64 = 6.694_379_990_14e-3;
    let phi = lat0_deg.to_radians();
    let w = 1.0 - E2 * phi.sin().powi(2);
    let r_m = A_M * (1.0 - E2) / w.powf(1.5);
    let r_n = A_M / w.sqrt();
    let east_m = r_n * phi.cos() * (lon_deg - lon0_deg).to_radians();
    let north_m = r_m * (lat_deg - lat0_deg).to_radians();
    (east_m, north_m)
}

/// Signed cross-track distance [m] of point `p` from the leg `a -> b` (positive = right of the leg).
///
/// On the local plane around `a`: `xtd = (d x p) / |d|` with `d = b - a` (2-D cross product, east/north).
pub fn cross_track_m(a: (f64, f64), b: (f64, f64), p: (f64, f64)) -> f64 {
    let (bx, by) = enu_from_wgs84(a.0, a.1, b.0, b.1);
    let (px, py) = enu_from_wgs84(a.0, a.1, p.0, p.1);
    let len = bx.hypot(by);
    if len < 1e-9 {
        return 0.0;
    }
    // d x p in an east-north frame is positive when p is left (counter-clockwise) of d.
    -(bx * py - by * px) / len
}

/// What was in a GPX file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GpxContent {
    /// Route name, if any.
    pub name: Option<String>,
    /// Route points (the first route), else the standalone waypoints.
    pub waypoints: Vec<Waypoint>,
    /// Track points of every track and segment, as `(lat_deg, lon_deg)`.
    pub track: Vec<(f64, f64)>,
}

/// Parses GPX text: the first route becomes the waypoints (standalone `<wpt>` when there is no route),
/// tracks become the track. Points with non-finite or out-of-range coordinates are an error.
pub fn parse_gpx(text: &str) -> Result<GpxContent, String> {
    let g = gpx::read(text.as_bytes()).map_err(|e| format!("not a readable GPX file: {e}"))?;
    let to_wp = |i: usize, w: &gpx::Waypoint| -> Result<Waypoint, String> {
        let p = w.point();
        let (lat, lon) = (p.y(), p.x());
        if !(lat.is_finite() && lon.is_finite() && lat.abs() <= 90.0 && lon.abs() <= 180.0) {
            return Err(format!("point {} has invalid coordinates ({lat}, {lon})", i + 1));
        }
        Ok(Waypoint {
            name: w.name.clone().unwrap_or_else(|| format!("WP{}", i + 1)),
            lat_deg: lat,
            lon_deg: lon,
        })
    };
    let (name, pts) = match g.routes.first() {
        Some(r) => (r.name.clone(), &r.points),
        None => (g.metadata.as_ref().and_then(|m| m.name.clone()), &g.waypoints),
    };
    let waypoints = pts.iter().enumerate().map(|(i, w)| to_wp(i, w)).collect::<Result<Vec<_>, _>>()?;
    let mut track = Vec::new();
    for t in &g.tracks {
        for s in &t.segments {
            for (i, w) in s.points.iter().enumerate() {
                let wp = to_wp(i, w)?;
                track.push((wp.lat_deg, wp.lon_deg));
            }
        }
    }
    Ok(GpxContent { name, waypoints, track })
}

/// Writes the waypoints as a GPX 1.1 route (and as `<wpt>`s, for tools that only read those) and the
/// track as one track segment.
pub fn write_gpx(name: &str, waypoints: &[Waypoint], track: &[(f64, f64)]) -> Result<String, String> {
    let mk = |name: Option<&str>, lat: f64, lon: f64| {
        let mut w = gpx::Waypoint::new(walkers::geo_types::Point::new(lon, lat));
        w.name = name.map(str::to_owned);
        w
    };
    let mut route = gpx::Route::new();
    route.name = Some(name.to_owned());
    route.points = waypoints.iter().map(|w| mk(Some(&w.name), w.lat_deg, w.lon_deg)).collect();
    let mut g = gpx::Gpx {
        version: gpx::GpxVersion::Gpx11,
        creator: Some("vestnav".to_owned()),
        waypoints: route.points.clone(),
        routes: vec![route],
        ..Default::default()
    };
    if !track.is_empty() {
        let mut seg = gpx::TrackSegment::new();
        seg.points = track.iter().map(|&(lat, lon)| mk(None, lat, lon)).collect();
        let mut t = gpx::Track::new();
        t.name = Some(format!("{name} track"));
        t.segments.push(seg);
        g.tracks.push(t);
    }
    let mut out = Vec::new();
    gpx::write(&g, &mut out).map_err(|e| format!("cannot write GPX: {e}"))?;
    String::from_utf8(out).map_err(|e| format!("cannot write GPX: {e}"))
}

/// Picks at most about `max_points` of `n` points for drawing: a fixed stride, always keeping the last.
///
/// A 100k-point track drawn at full resolution costs tens of milliseconds per frame; the stride keeps the
/// frame time bounded while the most recent points (drawn separately in full) stay exact.
pub fn decimation_stride(n: usize, max_points: usize) -> usize {
    n.div_ceil(max_points.max(1)).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn geodesic_matches_published_values() {
        // One degree of latitude at the equator on WGS-84 is 110 574.389 m (Karney's GeodSolve).
        let (d, b) = distance_bearing(0.0, 0.0, 1.0, 0.0);
        assert_relative_eq!(d, 110_574.389, max_relative = 1e-8);
        assert_relative_eq!(b, 0.0, epsilon = 1e-9);
        let (_, b) = distance_bearing(0.0, 0.0, 0.0, -1.0);
        assert_relative_eq!(b, 270.0, max_relative = 1e-12);
    }

    #[test]
    fn local_plane_agrees_with_the_geodesic_over_a_walk() {
        let (e, n) = enu_from_wgs84(42.3562, -71.1, 42.3584, -71.1008);
        let (d, _) = distance_bearing(42.3562, -71.1, 42.3584, -71.1008);
        assert_relative_eq!(e.hypot(n), d, max_relative = 1e-4);
    }

    #[test]
    fn cross_track_sign() {
        // Leg due north; a point to the east is on the right.
        let a = (42.0, -71.0);
        let b = (42.001, -71.0);
        let right = cross_track_m(a, b, (42.0005, -70.9999));
        assert!(right > 0.0);
        let (e, _) = enu_from_wgs84(42.0, -71.0, 42.0, -70.9999);
        assert_relative_eq!(right, e, max_relative = 1e-6);
        assert!(cross_track_m(a, b, (42.0005, -71.0001)) < 0.0);
    }

    #[test]
    fn demo_route_loads_and_round_trips() {
        let c = parse_gpx(DEMO_GPX).unwrap();
        assert_eq!(c.waypoints.len(), 7);
        assert_eq!(c.waypoints[0].name, "Start (SE gate)");
        let text = write_gpx("demo", &c.waypoints, &[(42.0, -71.0), (42.1, -71.1)]).unwrap();
        let back = parse_gpx(&text).unwrap();
        assert_eq!(back.waypoints, c.waypoints);
        assert_eq!(back.track, vec![(42.0, -71.0), (42.1, -71.1)]);
        assert!(parse_gpx("<gpx><rte><rtept lat=\"99\" lon=\"0\"/></rte></gpx>").is_err());
        assert!(parse_gpx("garbage").is_err());
    }

    #[test]
    fn stride_bounds_points() {
        assert_eq!(decimation_stride(10, 5000), 1);
        assert!(100_000 / decimation_stride(100_000, 5000) <= 5000);
    }
}
