//! Waypoints and the wearer's track on the map: geometry for drawing, and the console's use of the GPX
//! files read and written by `vestnav_device::route_file` (the one home of the format).
//!
//! Distances and bearings to waypoints are core guidance's (WGS-84 geodesics, `vestnav_core::geo`); the map's
//! metric grid uses core's `geo::LocalFrame`.

use std::path::Path;

use vestnav_device::route_file::{self, RouteFile, Track, TrackPoint};

pub use vestnav_device::route_file::{DEMO_GPX, Waypoint};

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
