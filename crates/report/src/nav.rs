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

/// One panel per strategy: the route, the waypoints with their arrival circles, the first run's true path
/// and its GPS fixes, in east/north metres.
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
            Series::line("route", xs(&r.waypoints_en_m), ys(&r.waypoints_en_m))
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
