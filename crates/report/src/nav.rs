//! Closed-loop guidance simulation: the JSON schema of `vestnav nav simulate --json` and its figure.

use serde::{Deserialize, Serialize};
use vestnav_core::wearer::{SimResult, SimSummary};
use vestnav_plot::{Chart, Color, Figure, Marker, Series};

/// One strategy's (and heading source's) summary and runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StrategyReport {
    /// Means and spreads over the runs.
    pub summary: SimSummary,
    /// Every run (core's result, serialised without its paths).
    pub runs: Vec<SimResult>,
}

/// JSON of `vestnav nav simulate --json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NavReport {
    /// The route file.
    pub route: String,
    /// Number of waypoints.
    pub waypoints: usize,
    /// Runs per strategy.
    pub runs: usize,
    /// First seed.
    pub seed: u64,
    /// Walking pace of the simulated wearer [m/s] (absent in reports written before it was recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pace_m_s: Option<f64>,
    /// Points of the path the route follows, when it follows one (its cross-track errors are measured
    /// from that path, not from the straight legs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path_points: Option<usize>,
    /// One entry per strategy simulated, and per heading source when `--heading` named several (each
    /// summary says its `heading_mode`).
    pub strategies: Vec<StrategyReport>,
}

impl NavReport {
    /// The report of the simulations `all` (summary and runs per strategy).
    pub fn new(
        route: String,
        waypoints: usize,
        runs: usize,
        seed: u64,
        all: &[(SimSummary, Vec<SimResult>)],
    ) -> Self {
        let strategies =
            all.iter().map(|(s, rs)| StrategyReport { summary: s.clone(), runs: rs.clone() }).collect();
        Self { route, waypoints, runs, seed, pace_m_s: None, path_points: None, strategies }
    }
}

/// The line the wearer was guided along: the route's path when it has one, else the straight legs.
fn route_line(r: &SimResult) -> &[vestnav_core::wave::DVec2] {
    if r.route_line_en_m.is_empty() { &r.waypoints_en_m } else { &r.route_line_en_m }
}

/// The legend of [`route_line`].
fn route_label(r: &SimResult) -> String {
    if r.route_line_en_m.len() > r.waypoints_en_m.len() {
        format!("route path ({} points)", r.route_line_en_m.len())
    } else {
        "route".to_owned()
    }
}

/// One panel per strategy: the route (along its path when it has one: a planned walk's dense polyline,
/// not the straight legs), the waypoints with their arrival circles, the first run's true path and its GPS
/// fixes, in east/north metres.
pub fn nav_figure(all: &[(SimSummary, Vec<SimResult>)], arrival_radius_m: f64) -> Figure {
    let mut fig = Figure::new()
        .title("Closed-loop guidance: simulated wearer (first run)")
        .columns(all.len().max(1))
        .panel_size(640, 560);
    for (s, runs) in all {
        let Some(r) = runs.first() else { continue };
        let xs = |v: &[vestnav_core::wave::DVec2]| v.iter().map(|p| p.x).collect::<Vec<f64>>();
        let ys = |v: &[vestnav_core::wave::DVec2]| v.iter().map(|p| p.y).collect::<Vec<f64>>();
        let heading = s.heading_mode.as_deref().map_or(String::new(), |h| format!(" / {h}"));
        let mut chart = Chart::new(format!(
            "{}{heading}: xtrack RMSE {:.1} m, {:.0} s, {:.1} cues/min, {} missed",
            s.strategy, r.cross_track_rmse_m, r.time_s, r.cues_per_min, r.waypoints_missed
        ))
        .x_label("east [m]")
        .y_label("north [m]")
        .equal_aspect()
        .series(
            // The line guidance follows: the route's path (a planned walk) when it has one.
            Series::line(route_label(r), xs(route_line(r)), ys(route_line(r)))
                .dashed()
                .width(2.0)
                .color(Color::rgb(90, 90, 90)),
        )
        .series(
            Series::scatter("GPS fixes", xs(&r.path_fix_en_m), ys(&r.path_fix_en_m))
                .marker(Marker::Cross)
                .color(Color::rgb(230, 140, 30)),
        )
        .series(
            Series::line("true path", xs(&r.path_true_en_m), ys(&r.path_true_en_m))
                .width(2.0)
                .color(Color::rgb(30, 90, 200)),
        );
        if !r.steel_en_m.is_empty() {
            chart = chart.series(
                Series::scatter("steel", xs(&r.steel_en_m), ys(&r.steel_en_m))
                    .marker(Marker::Square)
                    .color(Color::rgb(200, 40, 40)),
            );
        }
        for (i, w) in r.waypoints_en_m.iter().enumerate() {
            let label = if i == 0 { "arrival radius" } else { "" };
            chart = chart.circle(w.x, w.y, arrival_radius_m, label).annotate(w.x, w.y, format!("{}", i + 1));
        }
        fig = fig.push(chart);
    }
    fig
}

#[cfg(test)]
mod tests {
    use super::*;
    use vestnav_core::geo::{Earth, LatLon, LocalFrame};
    use vestnav_core::guidance::{RoutePath, StrategyKind, Waypoint};
    use vestnav_core::wearer::{SimConfig, simulate_many_along};

    /// The figure of a route with a path draws the path — every point of it, where a local frame about the
    /// first waypoint puts it — not the straight leg between the two waypoints.
    #[test]
    fn a_route_with_a_path_is_drawn_along_the_path() {
        let e = Earth::Wgs84;
        let o = LatLon::new(60.17, 24.94);
        let corner = e.direct(o, 90.0, 80.0);
        let mut pts: Vec<LatLon> = (0..=8).map(|i| e.direct(o, 90.0, 10.0 * f64::from(i))).collect();
        pts.extend((1..=8).map(|i| e.direct(corner, 0.0, 10.0 * f64::from(i))));
        let wps = vec![Waypoint::at("start", pts[0]), Waypoint::at("end", pts[16])];
        let path = RoutePath::new(pts.clone(), vec![0, 16]).unwrap();
        let cfg = SimConfig::new(StrategyKind::Pursuit);
        let (runs, summary) = simulate_many_along(&wps, Some(&path), &cfg, 1, 7).unwrap();
        let fig = nav_figure(&[(summary, runs)], 4.0);
        let vestnav_plot::Panel::Chart(chart) = &fig.panels[0] else { panic!("not a chart") };
        let route = &chart.series[0];
        assert_eq!(route.label, "route path (17 points)");
        let frame = LocalFrame::new(o, e);
        assert_eq!(route.x.len(), 17);
        for (i, p) in pts.iter().enumerate() {
            let want = frame.enu_from_wgs84(*p);
            assert!((route.x[i] - want.x).abs() < 1e-6 && (route.y[i] - want.y).abs() < 1e-6, "point {i}");
        }
        // The corner is drawn: 80 m east, on the ground, where the straight leg would be 57 m off it.
        assert!((route.x[8] - 80.0).abs() < 0.01 && route.y[8].abs() < 0.01);
        fig.render_png().unwrap();
    }
}
