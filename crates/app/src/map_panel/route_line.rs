//! A route's path on the map, drawn the same way for this console's route and for a remote station's: the
//! part already walked (up to the last waypoint passed), the section ahead (toward the next waypoint,
//! [`RoutePath::leg`]) and the rest, each in its own stroke. One frame draws at most about the budget
//! given, whatever the path's length: the path is thinned by one stride over its whole length, so the
//! three parts together cost no more than the budget (plus their six end points, kept exactly).

use egui::{Color32, Pos2, Stroke};
use vestnav_core::geo::LatLon;
use vestnav_core::guidance::RoutePath;
use walkers::{Projector, lat_lon};

use super::decimation_stride;

/// Most points of route paths drawn in one frame: this console's route has it all; the remote stations'
/// paths share one more (a longer path is drawn thinned).
pub const PATH_DRAWN_MAX: usize = 20_000;

/// The strokes of a path's three parts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathStyle {
    /// Up to the vertex of the last waypoint passed.
    pub passed: Stroke,
    /// From there to the next waypoint's vertex.
    pub ahead: Stroke,
    /// From the next waypoint's vertex to the end.
    pub rest: Stroke,
}

impl PathStyle {
    /// This console's route: the colours of its waypoint markers (passed green-grey, next orange, later
    /// blue).
    pub const LOCAL: Self = Self {
        passed: Stroke { width: 2.0, color: Color32::from_rgb(120, 160, 120) },
        ahead: Stroke { width: 3.0, color: Color32::from_rgb(240, 140, 0) },
        rest: Stroke { width: 2.0, color: Color32::from_rgb(60, 120, 220) },
    };

    /// A remote station's route in the station's `colour`: the section ahead in full colour and wider, the
    /// rest lighter, the passed part faint.
    pub fn remote(colour: Color32) -> Self {
        Self {
            passed: Stroke::new(2.0, colour.gamma_multiply(0.35)),
            ahead: Stroke::new(3.0, colour),
            rest: Stroke::new(2.0, colour.gamma_multiply(0.7)),
        }
    }
}

/// The index ranges (inclusive) of the passed part, the section ahead and the rest of `path` when
/// waypoint `next` is the next one. A part with fewer than two points is `None`. When every waypoint is
/// passed (`next` past the last), the whole path is the passed part.
pub fn parts(path: &RoutePath, next: usize) -> [Option<(usize, usize)>; 3] {
    let last = path.points().len().saturating_sub(1);
    let at = path.waypoint_vertices();
    let span = |a: usize, b: usize| (b > a).then_some((a, b.min(last)));
    let Some(&end) = at.get(next) else { return [span(0, last), None, None] };
    let start = next.checked_sub(1).and_then(|k| at.get(k)).copied().unwrap_or(0);
    [span(0, start), span(start, end), span(end, last)]
}

/// The points `a..=b` of `points` with a stride of `stride` counted from the path's start (so the parts of
/// one path thin alike), both ends kept.
fn thinned(points: &[LatLon], (a, b): (usize, usize), stride: usize) -> impl Iterator<Item = &LatLon> {
    (a..=b).filter(move |&i| i == a || i == b || i % stride == 0).filter_map(|i| points.get(i))
}

/// Draws `path` with waypoint `next` ahead in `style`, at most about `max_points` points (see the module
/// doc). Returns how many points were drawn.
pub(super) fn draw(
    painter: &egui::Painter,
    projector: &Projector,
    path: &RoutePath,
    next: usize,
    style: &PathStyle,
    max_points: usize,
) -> usize {
    let points = path.points();
    let stride = decimation_stride(points.len(), max_points);
    let mut drawn = 0;
    // Passed first, the section ahead last: where two parts meet, the one ahead is on top.
    let [passed, ahead, rest] = parts(path, next);
    for (range, stroke) in [(passed, style.passed), (rest, style.rest), (ahead, style.ahead)] {
        let Some(range) = range else { continue };
        let line: Vec<Pos2> = thinned(points, range, stride)
            .map(|q| {
                let v = projector.project(lat_lon(q.lat_deg, q.lon_deg));
                Pos2::new(v.x, v.y)
            })
            .collect();
        drawn += line.len();
        painter.line(line, stroke);
    }
    drawn
}

#[cfg(test)]
mod tests {
    use super::*;

    fn path(n: usize, at: Vec<usize>) -> RoutePath {
        let pts = (0..n).map(|i| LatLon::new(60.0 + i as f64 * 1e-5, 24.9)).collect();
        RoutePath::new(pts, at).unwrap()
    }

    #[test]
    fn the_parts_split_at_the_waypoints_around_the_next_one() {
        let p = path(10, vec![0, 4, 9]);
        assert_eq!(parts(&p, 0), [None, None, Some((0, 9))], "nothing passed, nothing before the first");
        assert_eq!(parts(&p, 1), [None, Some((0, 4)), Some((4, 9))]);
        assert_eq!(parts(&p, 2), [Some((0, 4)), Some((4, 9)), None]);
        assert_eq!(parts(&p, 3), [Some((0, 9)), None, None], "finished: all of it passed");
        assert_eq!(parts(&p, usize::MAX), [Some((0, 9)), None, None]);
    }

    #[test]
    fn the_largest_path_over_the_wire_is_thinned_to_the_budget_with_its_ends() {
        let n = vestnav_remote::wire::MAX_WIRE_PATH_POINTS;
        let p = path(n, vec![0, 12_345, n - 1]);
        let stride = decimation_stride(n, PATH_DRAWN_MAX);
        let [passed, ahead, rest] = parts(&p, 2);
        let mut count = 0;
        for r in [passed, ahead, rest].into_iter().flatten() {
            let pts: Vec<&LatLon> = thinned(p.points(), r, stride).collect();
            assert_eq!(pts.first(), p.points().get(r.0).as_ref(), "each part starts at its vertex");
            assert_eq!(pts.last(), p.points().get(r.1).as_ref(), "and ends at its vertex");
            count += pts.len();
        }
        assert!(count <= PATH_DRAWN_MAX + 6, "{count} points drawn");
    }
}
