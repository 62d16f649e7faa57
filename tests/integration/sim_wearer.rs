//! The station's simulated wearer steered by its emulated vest: the built-in GPS simulator's walker feels
//! the in-process unit's tactors, recognises the cues (core's wearer model) and turns, so automatic
//! guidance closes its loop without hardware.
//!
//! The route turns a right angle: 10 m north, then 22 m east. The walker starts at the first waypoint
//! facing north and nothing but the vest turns it, so reaching the last waypoint is guidance's doing: with
//! no cue the walker goes on north (veering a little) and passes no closer than about 20 m to it.

use std::time::{Duration, Instant};

use vestnav_core::geo::{Earth, LatLon};
use vestnav_core::guidance::NavState;
use vestnav_core::vest::Cue;
use vestnav_device::sim::BodyTruth;
use vestnav_device::wtcu::LinkState;
use vestnav_station::devices::DeviceFactory as _;
use vestnav_station::hardware::Hardware;
use vestnav_station::route::Waypoint;
use vestnav_station::sources::{GpsSourceConfig, VestSourceConfig};
use vestnav_station::{Station, StationOptions, StationSettings};

const START: LatLon = LatLon::new(42.3562, -71.1);

fn wp(name: &str, p: LatLon) -> Waypoint {
    Waypoint { name: name.into(), lat_deg: p.lat_deg, lon_deg: p.lon_deg, arrival_radius_m: None }
}

#[test]
fn guidance_steers_the_simulated_wearer_round_a_corner_to_the_end() {
    let hardware = Hardware::default();
    let wearer = hardware.simulated_wearer().unwrap();
    let mut settings = StationSettings { sim_follows_vest: true, ..StationSettings::default() };
    settings.guidance.auto = true;
    settings.guidance.loop_route = false;
    settings.guidance.arrival_radius_m = 6.0;
    let mut s = Station::new(
        Box::new(hardware),
        StationOptions {
            settings,
            gps: Some(GpsSourceConfig::Simulator { route: None }),
            vest: Some(VestSourceConfig::Emulated),
            liveness: None,
            ..StationOptions::default()
        },
    );
    let corner = Earth::Wgs84.direct(START, 0.0, 10.0);
    let end = Earth::Wgs84.direct(corner, 90.0, 22.0);
    s.route_mut()
        .replace("corner".into(), vec![wp("start", START), wp("corner", corner), wp("end", end)])
        .unwrap();
    s.connect_vest();
    let t0 = Instant::now();
    while s.vest.state != Some(LinkState::Ready) {
        assert!(t0.elapsed() < Duration::from_secs(5), "the emulated vest ready");
        s.pump(|_| {});
        std::thread::sleep(Duration::from_millis(5));
    }
    s.connect_gps(Vec::new());

    let mut truths: Vec<BodyTruth> = Vec::new();
    let mut sent: Vec<Cue> = Vec::new();
    let mut notice = false;
    let until = Instant::now() + Duration::from_secs(90);
    loop {
        s.pump(|_| {});
        if let Some(b) = wearer.get()
            && truths.last() != Some(&b)
        {
            truths.push(b);
        }
        if let Some(g) = &s.guidance
            && g.sent
            && let Some(c) = g.cue
            && sent.last() != Some(&c)
        {
            sent.push(c);
        }
        notice |= s.gps.notice.as_ref().is_some_and(|n| n.contains("follows the emulated vest"));
        if s.guidance.as_ref().is_some_and(|g| g.finished || g.state == NavState::Finished) {
            break;
        }
        assert!(
            Instant::now() < until,
            "the wearer reached the end within 90 s (cues sent {sent:?}; last truth {:?})",
            truths.last()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let took = t0.elapsed().as_secs_f64();
    eprintln!("finished in {took:.0} s; cues sent {sent:?}; {} truths", truths.len());
    s.shutdown();

    // The simulator said what it walks.
    assert!(notice, "the simulator's notice that the vest steers the walker");
    // The walker went north first, then was turned right by cues (not along the route's exact legs: a
    // turned wearer's course carries the model's turn noise and veer).
    let first = truths.first().unwrap();
    assert!(first.heading_true_deg < 20.0 || first.heading_true_deg > 340.0, "{first:?}");
    assert!(
        sent.iter().any(|c| matches!(c, Cue::TurnRight | Cue::SlightRight | Cue::RotateRight(_))),
        "{sent:?}"
    );
    let east: Vec<&BodyTruth> = truths.iter().filter(|b| b.east_m > 8.0).collect();
    assert!(!east.is_empty(), "the wearer went east");
    assert!(
        truths.iter().any(|b| b.pace_m_s > 0.0
            && (b.heading_true_deg - 90.0).abs() > 0.5
            && b.heading_true_deg > 30.0
            && b.heading_true_deg < 150.0),
        "a course toward the east that is not the route's exact 90°"
    );
    // At the end the wearer is where guidance says: within the arrival radius (+ the fix's error) of it.
    let last = truths.last().unwrap();
    let frame_end_east = 22.0;
    let frame_end_north = 10.0;
    let miss = ((last.east_m - frame_end_east).powi(2) + (last.north_m - frame_end_north).powi(2)).sqrt();
    assert!(miss < 15.0, "the wearer is near the end: {miss:.1} m off ({last:?})");
}
