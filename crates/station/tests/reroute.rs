//! Issue 26: a wearer who leaves a planned walk's path and stays off it is re-routed once, from where they
//! are, on the Helsinki extract (© OpenStreetMap contributors, `ODbL`; tests/data/osm). The walk is a real
//! NMEA file replayed through the station's GPS source; the path network is read on the station's own
//! thread.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;
use std::time::{Duration, Instant};

use chrono::{TimeZone as _, Utc};
use vestnav_core::geo::{Earth, LatLon};
use vestnav_core::guidance::{Waypoint, path_offset};
use vestnav_device::gps::nmea_out::{EpochOut, epoch_sentences};
use vestnav_device::gps::{ReplaySpeed, SourceState};
use vestnav_osm::{Extract, Profile};
use vestnav_station::hardware::Hardware;
use vestnav_station::sources::GpsSourceConfig;
use vestnav_station::{Station, StationOptions, StationSettings};

fn helsinki() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/osm/helsinki.osm.pbf")
}

fn epoch(t_s: u32, p: LatLon, speed_m_s: f64, course_deg: f64) -> String {
    epoch_sentences(&EpochOut {
        time: Utc.with_ymd_and_hms(2026, 6, 1, 10, 0, 0).unwrap() + chrono::Duration::seconds(t_s.into()),
        lat_deg: Some(p.lat_deg),
        lon_deg: Some(p.lon_deg),
        alt_m: 10.0,
        speed_m_s,
        course_deg,
        satellites: Vec::new(),
        hdop: 0.9,
        pdop: 1.5,
        vdop: 1.2,
        sigma_m: 2.0,
    })
}

#[test]
fn a_wearer_who_stays_off_the_path_is_rerouted_once_from_where_they_are() {
    let e = Earth::Wgs84;
    let extract = Extract::read(&helsinki()).unwrap();
    let (a, b) = (LatLon::new(60.1700, 24.9400), LatLon::new(60.1660, 24.9500));
    let planned = extract.graph.plan(a, b, Profile::Shortest).unwrap();
    let (wps, path) = planned.guided(&[Waypoint::at("A", a), Waypoint::at("B", b)]).unwrap();
    let leg = path.leg(1).to_vec();

    // The walk: 4 s standing on the path at one of its vertices, 10 s walking 5 m/s away from it at right
    // angles, then 20 s standing 50 m off it (the first vertex and side where that is 45 m from the path).
    let (on, along, away) = (1..leg.len() - 1)
        .flat_map(|k| [90.0, 270.0].map(|turn| (k, turn)))
        .map(|(k, turn)| {
            let along = e.initial_bearing_deg(leg[k], leg[k + 1]);
            (leg[k], along, (along + turn) % 360.0)
        })
        .find(|&(on, _, away)| {
            path_offset(e, &leg, e.direct(on, away, 50.0)).unwrap().cross_track_m.abs() > 45.0
        })
        .unwrap();
    let mut nmea = String::new();
    let mut here = on;
    for t in 0..34u32 {
        let (speed, course) = if (4..14).contains(&t) { (5.0, away) } else { (0.0, along) };
        if (4..14).contains(&t) {
            here = e.direct(on, away, 5.0 * f64::from(t - 3));
        }
        nmea.push_str(&epoch(t, here, speed, course));
    }
    let off = path_offset(e, &leg, here).unwrap();
    assert!(off.cross_track_m.abs() > 40.0, "the walk ends off the path: {off:?}");
    let dir = std::env::temp_dir().join(format!("vestnav-reroute-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("walk.nmea");
    std::fs::write(&file, nmea).unwrap();

    let mut settings = StationSettings::default();
    settings.guidance.off_path_m = 20.0;
    settings.guidance.reroute_after_s = 3.0;
    let mut station = Station::new(
        Box::new(Hardware::default()),
        StationOptions {
            settings,
            gps: Some(GpsSourceConfig::Replay { path: file, speed: ReplaySpeed::Times(4.0) }),
            ..Default::default()
        },
    );
    station.route_mut().replace_with_path("walk".into(), wps, Some(path.clone())).unwrap();
    station.route_mut().set_next(1);
    station.load_path_network(helsinki());
    let end = Instant::now() + Duration::from_secs(20);
    while !station.has_path_network() && Instant::now() < end {
        station.pump(|_| {});
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(station.has_path_network(), "the network was read on the station's thread");
    station.connect_gps(Vec::new());
    let end = Instant::now() + Duration::from_secs(30);
    while station.gps.state != Some(SourceState::Finished) && Instant::now() < end {
        station.pump(|_| {});
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(station.gps.state, Some(SourceState::Finished), "the replay ran to its end");
    // The last fixes stand still on the new path: give guidance and the planner a moment more.
    let settle = Instant::now() + Duration::from_secs(2);
    while Instant::now() < settle {
        station.pump(|_| {});
        std::thread::sleep(Duration::from_millis(20));
    }

    let rerouted: Vec<&str> = station
        .notices
        .all()
        .iter()
        .map(|n| n.text.as_str())
        .filter(|t| t.contains("re-route") || t.contains("cannot re-route"))
        .collect();
    assert_eq!(rerouted.len(), 1, "exactly one re-route: {rerouted:?}");
    assert!(rerouted[0].contains("re-routed from the wearer"), "{rerouted:?}");
    assert_eq!(station.reroute_line(), Some(rerouted[0]));
    assert_eq!(station.route().undo_label(), Some("re-route from the wearer"));
    // The new path toward B starts where the wearer stood, and they are on it now.
    let new_leg = station.route().path().unwrap().leg(1).to_vec();
    assert!(e.distance_m(new_leg[1], here) < 30.0, "starts near the wearer: {:?} vs {here:?}", new_leg[1]);
    assert!(path_offset(e, &new_leg, here).unwrap().cross_track_m.abs() < 5.0);
    assert_eq!(station.route().waypoints()[1].name, "B");
    let st = station.guidance.as_ref().unwrap();
    assert_eq!(st.off_path_s, None, "back on (the new) path: {st:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
