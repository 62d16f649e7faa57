//! The path a route follows between its waypoints: a dense polyline (a footway route from a planner), each
//! waypoint sitting on one of its vertices. Guidance measures the cross-track error from it and aims along
//! it instead of along the straight leg; arrival stays per waypoint.

use glam::DVec2;
use serde::{Deserialize, Serialize};

use super::{RouteError, Waypoint};
use crate::geo::{Earth, LatLon, LocalFrame};

/// Most points a path may have (a day's walk planned node by node stays far below it).
pub const MAX_PATH_POINTS: usize = 200_000;

/// A route's path: the polyline and, for each waypoint, the index of the vertex it sits on (non-decreasing).
///
/// The section the wearer follows toward waypoint `k` runs from waypoint `k - 1`'s vertex to waypoint `k`'s
/// (from the path's first point for `k = 0`): see [`RoutePath::leg`].
///
/// Read from JSON (`{"points": [...], "at": [...]}`) through [`RoutePath::new`], so a path from a file or
/// the network is checked like one built here.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawPath")]
pub struct RoutePath {
    points: Vec<LatLon>,
    at: Vec<usize>,
}

/// A path as read, before [`RoutePath::new`] checks it.
#[derive(Deserialize)]
struct RawPath {
    points: Vec<LatLon>,
    at: Vec<usize>,
}

impl TryFrom<RawPath> for RoutePath {
    type Error = RouteError;
    fn try_from(r: RawPath) -> Result<Self, RouteError> {
        Self::new(r.points, r.at)
    }
}

/// Where a point is relative to a polyline: the nearest point of its nearest segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathOffset {
    /// Distance to the polyline [m], signed: positive to the **right** of the direction of travel of the
    /// nearest segment (0 on it).
    pub cross_track_m: f64,
    /// Index `i` of the nearest segment (`points[i] -> points[i + 1]`; 0 for a one-point polyline).
    pub segment: usize,
    /// Fraction along that segment of the nearest point, in [0, 1].
    pub t: f64,
}

impl RoutePath {
    /// A path through `points` with waypoint `k` on vertex `at[k]`. Refused: fewer than two points, more than
    /// [`MAX_PATH_POINTS`], a bad position, an index out of range or going backwards.
    pub fn new(points: Vec<LatLon>, at: Vec<usize>) -> Result<Self, RouteError> {
        if points.len() < 2 || points.len() > MAX_PATH_POINTS {
            return Err(RouteError::BadConfig("a path needs 2 to 200000 points"));
        }
        if points.iter().any(|p| p.validated().is_err()) {
            return Err(RouteError::BadConfig("a path point is not a valid position"));
        }
        if at.iter().any(|&i| i >= points.len()) || at.windows(2).any(|w| w[1] < w[0]) {
            return Err(RouteError::BadConfig("waypoints must sit on the path in order"));
        }
        Ok(Self { points, at })
    }

    /// The path through `points` for `waypoints` that lie along it in order, each within `max_gap_m` of a
    /// vertex (a GPX file's route with the track a planner drew through it). `None` when one does not.
    ///
    /// Waypoint `k` takes the vertex of the path's first approach to it after waypoint `k - 1`'s vertex:
    /// scanning forward, the first vertex within `max_gap_m`, then on while the distance shrinks. A route
    /// that ends where it began thus gets its first waypoint at the start, its last at the end.
    pub fn along(points: Vec<LatLon>, waypoints: &[Waypoint], earth: Earth, max_gap_m: f64) -> Option<Self> {
        let mut at = Vec::with_capacity(waypoints.len());
        let mut from = 0;
        for w in waypoints {
            let d = |i: usize| earth.distance_m(points[i], w.pos());
            let first = (from..points.len()).find(|&i| d(i) <= max_gap_m)?;
            let (mut best, mut best_d) = (first, d(first));
            for i in first + 1..points.len() {
                let di = d(i);
                if di > best_d {
                    break;
                }
                (best, best_d) = (i, di);
            }
            at.push(best);
            from = best;
        }
        Self::new(points, at).ok()
    }

    /// Whether `waypoints` are the ones this path was made for: one per waypoint vertex, each within
    /// `max_gap_m` of its vertex. `Err` names the first that is not.
    pub fn fits(&self, waypoints: &[Waypoint], earth: Earth, max_gap_m: f64) -> Result<(), String> {
        if waypoints.len() != self.at.len() {
            return Err(format!(
                "the path passes {} waypoints, the route has {}",
                self.at.len(),
                waypoints.len()
            ));
        }
        for (k, (w, &i)) in waypoints.iter().zip(&self.at).enumerate() {
            let d = self.points.get(i).map_or(f64::INFINITY, |p| earth.distance_m(*p, w.pos()));
            if d.is_nan() || d > max_gap_m {
                return Err(format!(
                    "waypoint {} ({}) is {d:.0} m from its point of the path (at most {max_gap_m:.0} m)",
                    k + 1,
                    w.name
                ));
            }
        }
        Ok(())
    }

    /// The polyline.
    pub fn points(&self) -> &[LatLon] {
        &self.points
    }

    /// The vertex of each waypoint.
    pub fn waypoint_vertices(&self) -> &[usize] {
        &self.at
    }

    /// The section toward waypoint `k`: from waypoint `k - 1`'s vertex (the path's start for `k = 0`) to
    /// waypoint `k`'s, both included. Empty when `k` has no vertex.
    pub fn leg(&self, k: usize) -> &[LatLon] {
        let Some(&end) = self.at.get(k) else { return &[] };
        let start = if k == 0 { 0 } else { self.at.get(k - 1).copied().unwrap_or(0) };
        self.points.get(start..=end).unwrap_or(&[])
    }

    /// Whether `p` is past waypoint `k` along the path (the "passed without arriving" test of
    /// [`super::Route::observe`] where the route has a path); `None` when the section toward `k` has fewer
    /// than two points (the straight leg decides then).
    ///
    /// With a section after `k` (toward `k + 1`): the nearest point of the two sections joined lies beyond
    /// `k`'s vertex (position along the polyline `segment + t` greater than the vertex's index, as in
    /// [`path_offset`]). At the last waypoint: `p` is beyond the vertex along the section's final segment
    /// `a -> b`, `(p - b)·(b - a) > 0`. Planar geometry in the frame centred on `p` ([`LocalFrame`]).
    pub fn passed(&self, earth: Earth, k: usize, p: LatLon) -> Option<bool> {
        let section = self.leg(k);
        if section.len() < 2 {
            return None;
        }
        let frame = LocalFrame::new(p, earth);
        let after = self.leg(k + 1);
        let vertex = section.len() - 1;
        if after.len() >= 2 {
            let en: Vec<DVec2> =
                section.iter().chain(&after[1..]).map(|q| frame.enu_from_wgs84(*q)).collect();
            let off = offset_en(&en)?;
            return Some(off.segment as f64 + off.t > vertex as f64);
        }
        let b = frame.enu_from_wgs84(section[vertex]);
        // The last point before the vertex that is not on it gives the direction of arrival.
        let a = section[..vertex].iter().rev().map(|q| frame.enu_from_wgs84(*q)).find(|a| *a != b)?;
        Some((-b).dot(b - a) > 0.0)
    }

    /// Replaces the path from waypoint `k` on (re-routing): the path up to waypoint `k - 1`'s vertex is
    /// kept, then `new_points`, a path from where the wearer is through waypoints `k..` with their vertices
    /// `new_at` (indices into `new_points`). Refused like [`RoutePath::new`].
    pub fn replaced_from(
        &self,
        k: usize,
        new_points: &[LatLon],
        new_at: &[usize],
    ) -> Result<Self, RouteError> {
        let keep = if k == 0 { 0 } else { self.at.get(k - 1).map_or(0, |&i| i + 1) };
        let mut points: Vec<LatLon> = self.points.get(..keep).unwrap_or(&[]).to_vec();
        let mut at: Vec<usize> = self.at.get(..k).unwrap_or(&[]).to_vec();
        points.extend_from_slice(new_points);
        at.extend(new_at.iter().map(|i| i + keep));
        Self::new(points, at)
    }
}

/// Where `p` is relative to the polyline `points`: the nearest point of the nearest segment, with the
/// cross-track distance signed by that segment's direction. `None` for an empty polyline.
///
/// Planar geometry in the azimuthal-equidistant frame centred on `p` ([`LocalFrame`]), where distances from
/// `p` are exact on `earth`: for a segment `a -> b` the nearest point is `a + t (b - a)` with
/// `t = clamp(-a·(b - a) / |b - a|², 0, 1)`, its distance the length of that vector, its side the sign of
/// `(p - a) x (b - a)` (z of the 2-D cross product; positive = right), as in [`crate::geo::leg_offset`].
/// The nearest of all segments wins (the first on a tie).
pub fn path_offset(earth: Earth, points: &[LatLon], p: LatLon) -> Option<PathOffset> {
    let frame = LocalFrame::new(p, earth);
    let en: Vec<DVec2> = points.iter().map(|q| frame.enu_from_wgs84(*q)).collect();
    offset_en(&en)
}

/// [`path_offset`] for a polyline already in a frame centred on the point (the point at the origin).
fn offset_en(en: &[DVec2]) -> Option<PathOffset> {
    let first = *en.first()?;
    let mut best = PathOffset { cross_track_m: first.length(), segment: 0, t: 0.0 };
    let mut best_d = f64::INFINITY;
    if en.len() == 1 {
        return Some(best);
    }
    for (i, w) in en.windows(2).enumerate() {
        let (a, b) = (w[0], w[1]);
        let ab = b - a;
        let len2 = ab.length_squared();
        let t = if len2 > 0.0 { (-a.dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
        let d = (a + ab * t).length();
        if d < best_d {
            best_d = d;
            let side = (-a).perp_dot(ab);
            let signed = if side < 0.0 { -d } else { d };
            best = PathOffset { cross_track_m: signed, segment: i, t };
        }
    }
    Some(best)
}

/// Where the wearer stands relative to the path section `leg` and where to aim along it.
// Units in names are the house style (`_m`), even when every field has the same one.
#[allow(clippy::struct_field_names)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PathAim {
    /// Signed cross-track distance from the section [m] (see [`PathOffset`]).
    pub cross_track_m: f64,
    /// The nearest point of the section, east/north of the wearer [m].
    pub foot_en_m: DVec2,
    /// The point `lookahead_m` further along the section than the foot point (its end at most) [m].
    pub aim_en_m: DVec2,
}

/// The wearer's offset from the section `leg` (at least two points) and the point `lookahead_m` along it
/// beyond the nearest point ("carrot"), in the frame centred on the wearer at `p`.
pub(super) fn aim_along(earth: Earth, leg: &[LatLon], p: LatLon, lookahead_m: f64) -> Option<PathAim> {
    if leg.len() < 2 {
        return None;
    }
    let frame = LocalFrame::new(p, earth);
    let en: Vec<DVec2> = leg.iter().map(|q| frame.enu_from_wgs84(*q)).collect();
    let off = offset_en(&en)?;
    let (a, b) = (en[off.segment], en[off.segment + 1]);
    let foot = a + (b - a) * off.t;
    let mut left = lookahead_m.max(0.0);
    let mut at = foot;
    let mut aim = *en.last()?;
    for &next in en.get(off.segment + 1..).unwrap_or(&[]) {
        let step = (next - at).length();
        if step >= left && step > 0.0 {
            aim = at + (next - at) * (left / step);
            break;
        }
        left -= step;
        at = next;
    }
    Some(PathAim { cross_track_m: off.cross_track_m, foot_en_m: foot, aim_en_m: aim })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    const E: Earth = Earth::Wgs84;

    #[test]
    fn distance_to_a_polyline_matches_geographiclib() {
        // An L-shaped path in Helsinki: 300 m east along the parallel 60.17 N, then 200 m north.
        // References from python geographiclib 2.1 (Karney), independent of this crate's geometry: the point
        // is Geodesic.WGS84.Direct(60.17, 24.9427, 180, 25) -> lat 60.16977561, due south of the first
        // segment's midpoint; the least Inverse distance from it to 4001 points along that segment's geodesic
        // (which bows 3 mm north of the parallel) is 25.00306 m, to the RIGHT of eastward travel.
        let a = LatLon::new(60.17, 24.94);
        let b = LatLon::new(60.17, 24.9454);
        let c = E.direct(b, 0.0, 200.0);
        let p = LatLon::new(60.169_775_614, 24.9427);
        let off = path_offset(E, &[a, b, c], p).unwrap();
        assert_relative_eq!(off.cross_track_m, 25.003_06, max_relative = 1e-4);
        assert_eq!(off.segment, 0);
        assert_relative_eq!(off.t, 0.5, epsilon = 1e-3);
        // 40 m east of the corner's northern leg, 100 m up it: Inverse from the point to the leg's foot.
        let foot = E.direct(b, 0.0, 100.0);
        let q = E.direct(foot, 90.0, 40.0);
        let off = path_offset(E, &[a, b, c], q).unwrap();
        assert_relative_eq!(off.cross_track_m, 40.0, max_relative = 1e-3);
        assert_eq!(off.segment, 1);
        // West of the northern leg, inside the corner: to the LEFT of northward travel.
        let r = E.direct(foot, 270.0, 12.0);
        let off = path_offset(E, &[a, b, c], r).unwrap();
        assert_relative_eq!(off.cross_track_m, -12.0, max_relative = 1e-3);
    }

    #[test]
    fn distance_to_a_diagonal_segment_matches_dense_geodesic_sampling() {
        // The independent truth: the least geographiclib distance from the point to 2001 points spaced
        // evenly along the geodesic of the segment.
        let a = LatLon::new(42.3560, -71.1030);
        let b = LatLon::new(42.3590, -71.0990);
        let p = LatLon::new(42.3582, -71.1030);
        let inv = E.inverse(a, b);
        let truth = (0..=2000)
            .map(|k| {
                E.distance_m(p, E.direct(a, inv.initial_bearing_deg, inv.distance_m * f64::from(k) / 2000.0))
            })
            .fold(f64::INFINITY, f64::min);
        let off = path_offset(E, &[a, b], p).unwrap();
        // Travelling north-east, a point to the north-west is on the left.
        assert!(off.cross_track_m < 0.0);
        assert_relative_eq!(-off.cross_track_m, truth, max_relative = 1e-4);
    }

    #[test]
    fn the_path_ends_are_points_past_them() {
        let a = LatLon::new(60.0, 25.0);
        let b = E.direct(a, 90.0, 100.0);
        let beyond = E.direct(b, 90.0, 30.0);
        let off = path_offset(E, &[a, b], beyond).unwrap();
        assert_relative_eq!(off.cross_track_m.abs(), 30.0, max_relative = 1e-6);
        assert_relative_eq!(off.t, 1.0);
    }

    #[test]
    fn legs_are_the_sections_between_waypoints() {
        let pts: Vec<LatLon> = (0..6).map(|i| LatLon::new(60.0, 25.0 + 0.001 * f64::from(i))).collect();
        let path = RoutePath::new(pts.clone(), vec![2, 5]).unwrap();
        assert_eq!(path.leg(0), &pts[0..=2]);
        assert_eq!(path.leg(1), &pts[2..=5]);
        assert!(path.leg(2).is_empty());
        assert!(RoutePath::new(pts.clone(), vec![3, 2]).is_err(), "backwards");
        assert!(RoutePath::new(pts.clone(), vec![6]).is_err(), "out of range");
        assert!(RoutePath::new(pts[..1].to_vec(), vec![0]).is_err(), "one point");
        // Re-routing from waypoint 1 keeps the path up to waypoint 0's vertex.
        let detour = [LatLon::new(60.0005, 25.003), LatLon::new(60.0, 25.005)];
        let r = path.replaced_from(1, &detour, &[1]).unwrap();
        assert_eq!(r.points().len(), 3 + 2);
        assert_eq!(r.waypoint_vertices(), &[2, 4]);
        assert_eq!(r.leg(1), &[pts[2], detour[0], detour[1]]);
    }

    #[test]
    fn waypoints_are_found_along_a_track_in_order() {
        // Out and back along a parallel: waypoints at the far end and back at the start.
        let out: Vec<LatLon> = (0..=10).map(|i| LatLon::new(60.0, 25.0 + 0.0005 * f64::from(i))).collect();
        let mut pts = out.clone();
        pts.extend(out.iter().rev().skip(1));
        let wps =
            vec![Waypoint::at("start", out[0]), Waypoint::at("far", out[10]), Waypoint::at("home", out[0])];
        let path = RoutePath::along(pts.clone(), &wps, E, 5.0).unwrap();
        assert_eq!(path.waypoint_vertices(), &[0, 10, 20]);
        // A waypoint 100 m off the track is not on it.
        let off = Waypoint::at("off", E.direct(out[5], 0.0, 100.0));
        assert!(RoutePath::along(pts, &[wps[0].clone(), off], E, 30.0).is_none());
    }

    #[test]
    fn the_aim_runs_along_a_bend() {
        // East 50 m, then north 100 m. The wearer stands 5 m south of the first segment, 40 m along it:
        // 15 m ahead along the path is 5 m past the corner, up the northern leg.
        let a = LatLon::new(60.0, 25.0);
        let b = E.direct(a, 90.0, 50.0);
        let c = E.direct(b, 0.0, 100.0);
        let p = E.direct(E.direct(a, 90.0, 40.0), 180.0, 5.0);
        let aim = aim_along(E, &[a, b, c], p, 15.0).unwrap();
        assert_relative_eq!(aim.cross_track_m, 5.0, max_relative = 1e-4);
        assert_relative_eq!(aim.aim_en_m.x, 10.0, epsilon = 0.01);
        assert_relative_eq!(aim.aim_en_m.y, 10.0, epsilon = 0.01);
        // Beyond the end: the end.
        let end = aim_along(E, &[a, b, c], p, 1000.0).unwrap();
        assert_relative_eq!(end.aim_en_m.y, 105.0, epsilon = 0.01);
    }
}
