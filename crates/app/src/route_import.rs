//! Choosing what to import from a GPX file that holds several things: each route, the standalone
//! waypoints, each track (simplified to a walkable number of waypoints).
//!
//! A track of hundreds of fixes is no route to guide along (a waypoint every metre); it is simplified with
//! the Ramer–Douglas–Peucker algorithm in a local east/north frame (core's `geo::LocalFrame`): a point is
//! kept when it lies more than [`TRACK_SIMPLIFY_M`] off the line between the points kept around it.

use vestnav_core::geo::{DVec2, Earth, LatLon, LocalFrame};
use vestnav_device::route_file::{RouteFile, Waypoint};

/// A track point further than this from the simplified line is kept [m]: about two GPS errors.
pub const TRACK_SIMPLIFY_M: f64 = 5.0;

/// One thing a GPX file offers to import.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportChoice {
    /// What it is, for the operator: "route 'Loop' (12 points)".
    pub label: String,
    /// The route's name once imported.
    pub name: String,
    /// The waypoints it gives.
    pub waypoints: Vec<Waypoint>,
    /// The path it follows between them (a planned walk; a route with a track through its points).
    pub path: Option<vestnav_core::guidance::RoutePath>,
}

/// Indices of the points of `pts` (east/north [m]) that the Ramer–Douglas–Peucker algorithm keeps with
/// tolerance `tol_m`: the first, the last, and recursively the farthest point from the chord when it is
/// farther than `tol_m` (distance to the segment).
pub fn simplify(pts: &[DVec2], tol_m: f64) -> Vec<usize> {
    if pts.len() <= 2 {
        return (0..pts.len()).collect();
    }
    let mut keep = vec![false; pts.len()];
    keep[0] = true;
    keep[pts.len() - 1] = true;
    let mut stack = vec![(0, pts.len() - 1)];
    while let Some((a, b)) = stack.pop() {
        let (pa, pb) = (pts[a], pts[b]);
        let mut far = (0.0, 0);
        for (i, p) in pts.iter().enumerate().take(b).skip(a + 1) {
            let d = segment_distance(*p, pa, pb);
            if d > far.0 {
                far = (d, i);
            }
        }
        if far.0 > tol_m {
            keep[far.1] = true;
            stack.push((a, far.1));
            stack.push((far.1, b));
        }
    }
    keep.iter().enumerate().filter_map(|(i, k)| k.then_some(i)).collect()
}

/// Distance from `p` to the segment `a`–`b` [m].
fn segment_distance(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2 == 0.0 {
        return (p - a).length();
    }
    let t = ((p - a).dot(ab) / len2).clamp(0.0, 1.0);
    (p - (a + ab * t)).length()
}

/// A track's points simplified (see the module doc), named `T1`, `T2`, ... in order.
pub fn simplified_track(points: &[LatLon]) -> Vec<Waypoint> {
    let Some(first) = points.first() else { return Vec::new() };
    let frame = LocalFrame::new(*first, Earth::Wgs84);
    let en: Vec<DVec2> = points.iter().map(|p| frame.enu_from_wgs84(*p)).collect();
    simplify(&en, TRACK_SIMPLIFY_M)
        .into_iter()
        .enumerate()
        .map(|(k, i)| Waypoint::new(format!("T{}", k + 1), points[i].lat_deg, points[i].lon_deg))
        .collect()
}

/// Everything `file` offers, in file order: each route with points, the standalone waypoints, each track
/// with points.
pub fn choices(file: &RouteFile) -> Vec<ImportChoice> {
    let file_name = file.name.clone().unwrap_or_else(|| "imported".to_owned());
    let mut out = Vec::new();
    for (k, r) in file.routes.iter().enumerate().filter(|(_, r)| !r.points.is_empty()) {
        let name = r.name.clone().unwrap_or_else(|| format!("route {}", k + 1));
        let path = file.route_path(&r.points);
        let along = path
            .as_ref()
            .map_or_else(String::new, |p| format!(", along a path of {} points", p.points().len()));
        out.push(ImportChoice {
            label: format!("route '{name}' ({} points{along})", r.points.len()),
            name,
            waypoints: r.points.clone(),
            path,
        });
    }
    if !file.waypoints.is_empty() {
        let n = file.waypoints.len();
        out.push(ImportChoice {
            label: format!("{n} waypoint{}", if n == 1 { "" } else { "s" }),
            name: file_name.clone(),
            waypoints: file.waypoints.clone(),
            path: None,
        });
    }
    for (k, t) in file.tracks.iter().enumerate() {
        let pts: Vec<LatLon> = t.points().map(|p| LatLon::new(p.lat_deg, p.lon_deg)).collect();
        if pts.is_empty() {
            continue;
        }
        let name = t.name.clone().unwrap_or_else(|| format!("track {}", k + 1));
        let waypoints = simplified_track(&pts);
        out.push(ImportChoice {
            label: format!("track '{name}' ({} points, simplified to {})", pts.len(), waypoints.len()),
            name,
            waypoints,
            path: None,
        });
    }
    out
}

/// The import dialog's state: the file's choices, until one is taken or the dialog is closed.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportDialog {
    /// The file read.
    pub path: String,
    /// What it offers.
    pub choices: Vec<ImportChoice>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use vestnav_device::route_file::parse_gpx;

    #[test]
    fn a_straight_track_simplifies_to_its_ends_and_corners_stay() {
        // Collinear points: only the ends are kept (every point is 0 m off the chord).
        let line: Vec<DVec2> = (0..50).map(|i| DVec2::new(f64::from(i) * 2.0, 0.0)).collect();
        assert_eq!(simplify(&line, 5.0), vec![0, 49]);
        // An L: 100 m east then 100 m north; the corner is 70.7 m off the chord, so it stays.
        let mut l: Vec<DVec2> = (0..=10).map(|i| DVec2::new(f64::from(i) * 10.0, 0.0)).collect();
        l.extend((1..=10).map(|i| DVec2::new(100.0, f64::from(i) * 10.0)));
        assert_eq!(simplify(&l, 5.0), vec![0, 10, 20]);
        // A 3 m wiggle under the 5 m tolerance goes.
        assert_eq!(simplify(&[DVec2::ZERO, DVec2::new(50.0, 3.0), DVec2::new(100.0, 0.0)], 5.0), vec![0, 2]);
    }

    #[test]
    fn the_choices_name_what_the_file_holds() {
        let gpx = r#"<?xml version="1.0"?><gpx version="1.1" creator="t">
            <wpt lat="42.0" lon="-71.0"><name>a</name></wpt>
            <wpt lat="42.001" lon="-71.0"><name>b</name></wpt>
            <rte><name>Loop</name><rtept lat="42" lon="-71"/><rtept lat="42.1" lon="-71"/></rte>
            <trk><name>Walk</name><trkseg>
              <trkpt lat="42.0" lon="-71.0"/><trkpt lat="42.0001" lon="-71.0"/><trkpt lat="42.0002" lon="-71.0"/>
            </trkseg></trk></gpx>"#;
        let c = choices(&parse_gpx(gpx).unwrap());
        let labels: Vec<&str> = c.iter().map(|c| c.label.as_str()).collect();
        assert_eq!(
            labels,
            vec!["route 'Loop' (2 points)", "2 waypoints", "track 'Walk' (3 points, simplified to 2)"]
        );
    }
}
