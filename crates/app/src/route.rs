//! Waypoints and the wearer's track on the map: geometry for drawing, and the console's use of the GPX
//! files read and written by `vestnav_device::route_file` (the one home of the format).
//!
//! Distances and bearings to waypoints are core guidance's (WGS-84 geodesics, `vestnav_core::geo`); this
//! module only projects points onto the map's local plane.

use std::path::Path;

use vestnav_device::route_file::{self, RouteFile, Track, TrackPoint};

pub use vestnav_device::route_file::{DEMO_GPX, Waypoint};

/// East/north offset [m] of a point from an origin, on the local tangent plane.
///
/// Equirectangular approximation: `east = R_N cos(lat0) dlon`, `north = R_M dlat` with the WGS-84 radii of
/// curvature `R_M = a(1-e^2)/(1-e^2 sin^2 lat0)^1.5`, `R_N = a/(1-e^2 sin^2 lat0)^0.5`; good to well under a
/// centimetre over the few hundred metres of a walk (used only for drawing).
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

/// What the console takes from a GPX file: the route to guide along (its first route, else its
/// waypoints, else its first track), and every track point for the replayed track.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GpxContent {
    /// Route name, if any.
    pub name: Option<String>,
    /// The route's points.
    pub waypoints: Vec<Waypoint>,
    /// Track points of every track and segment, as `(lat_deg, lon_deg)`.
    pub track: Vec<(f64, f64)>,
}

impl GpxContent {
    fn from_file(file: &RouteFile) -> Self {
        let route = file.default_route();
        Self {
            name: route.as_ref().and_then(|r| r.name.clone()).or_else(|| file.name.clone()),
            waypoints: route.map(|r| r.waypoints).unwrap_or_default(),
            track: file.tracks.iter().flat_map(Track::points).map(|p| (p.lat_deg, p.lon_deg)).collect(),
        }
    }
}

/// Parses GPX text (see [`GpxContent`]); errors name the bad point.
pub fn parse_gpx(text: &str) -> Result<GpxContent, String> {
    route_file::parse_gpx(text).map(|f| GpxContent::from_file(&f)).map_err(|e| e.to_string())
}

/// Reads a GPX file (size-limited); errors name the file.
pub fn read_gpx(path: &Path) -> Result<GpxContent, String> {
    route_file::read_gpx(path).map(|f| GpxContent::from_file(&f)).map_err(|e| e.to_string())
}

/// The route (and the track, when there is one) as a GPX file.
pub fn to_route_file(name: &str, waypoints: &[Waypoint], track: &[(f64, f64)]) -> RouteFile {
    let mut file = RouteFile::from_route(name, waypoints.to_vec());
    if !track.is_empty() {
        file.tracks.push(Track {
            name: Some(format!("{name} track")),
            segments: vec![
                track
                    .iter()
                    .map(|&(lat_deg, lon_deg)| TrackPoint { lat_deg, lon_deg, ele_m: None, time: None })
                    .collect(),
            ],
        });
    }
    file
}

/// GPX 1.1 text of the route and track.
pub fn write_gpx(name: &str, waypoints: &[Waypoint], track: &[(f64, f64)]) -> Result<String, String> {
    Ok(route_file::to_gpx(&to_route_file(name, waypoints, track)))
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
    use vestnav_core::geo::{Earth, LatLon};

    #[test]
    fn local_plane_agrees_with_the_geodesic_over_a_walk() {
        let (e, n) = enu_from_wgs84(42.3562, -71.1, 42.3584, -71.1008);
        let d = Earth::Wgs84.distance_m(LatLon::new(42.3562, -71.1), LatLon::new(42.3584, -71.1008));
        assert_relative_eq!(e.hypot(n), d, max_relative = 1e-4);
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
        let missing = read_gpx(Path::new("/nonexistent/route.gpx")).unwrap_err();
        assert!(missing.contains("/nonexistent/route.gpx"), "{missing}");
    }

    #[test]
    fn stride_bounds_points() {
        assert_eq!(decimation_stride(10, 5000), 1);
        assert!(100_000 / decimation_stride(100_000, 5000) <= 5000);
    }
}
