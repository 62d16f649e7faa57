//! Timing of the closed-loop simulation against the number of route points (`nav simulate` on long
//! routes). Ignored by default; run in release:
//! `cargo test -p vestnav-core --release --test sim_scaling -- --ignored --nocapture`
//! (`VESTNAV_SCALING_POINTS=1000,10000,100000` and `VESTNAV_SCALING_RUNS=20` choose the sizes).

use std::time::Instant;

use vestnav_core::geo::{Earth, LatLon};
use vestnav_core::guidance::{StrategyKind, Waypoint};
use vestnav_core::wearer::{SimConfig, simulate_many};

/// A recorded-track-like route: `n` points 3 m apart, heading `45° + 60° sin(i / 150)`.
fn route(n: usize) -> Vec<Waypoint> {
    let mut pos = LatLon::new(42.3562, -71.1);
    (0..n)
        .map(|i| {
            let w = Waypoint::at(format!("P{i}"), pos);
            let h = 45.0 + 60.0 * (i as f64 / 150.0).sin();
            pos = Earth::Wgs84.direct(pos, h, 3.0);
            w
        })
        .collect()
}

#[test]
#[ignore = "timing; run in release with --ignored --nocapture"]
#[allow(clippy::print_stdout)]
fn simulate_time_against_route_points() {
    let sizes: Vec<usize> = std::env::var("VESTNAV_SCALING_POINTS")
        .ok()
        .map_or_else(|| vec![1000, 10_000], |s| s.split(',').filter_map(|x| x.trim().parse().ok()).collect());
    let runs: usize = std::env::var("VESTNAV_SCALING_RUNS").ok().and_then(|s| s.parse().ok()).unwrap_or(20);
    for n in sizes {
        let wps = route(n);
        let cfg = SimConfig::new(StrategyKind::Pursuit);
        let t = Instant::now();
        let (_, s) = simulate_many(&wps, &cfg, runs, 1).unwrap();
        let dt = t.elapsed().as_secs_f64();
        println!(
            "{n:>7} points, {runs} runs: {dt:8.2} s ({:.2} us per point per run); finished {:.0} %, xtrack RMSE {:.2} m, time {:.0} s",
            1e6 * dt / (n * runs) as f64,
            100.0 * s.finish_rate,
            s.cross_track_rmse_m.mean,
            s.time_s.mean
        );
    }
}
