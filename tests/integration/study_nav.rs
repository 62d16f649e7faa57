//! A whole navigation study on the station: two tiny routes × two conditions, the vest a WTCU served on a
//! real PTY (the device crate's emulated unit), the wearer the station's GPS simulator walking each trial's
//! route. Every trial must end by arrival; each row's cross-track RMS and path length are checked against
//! closed forms on the fixes the station received, and its cue count against the PLAY frames the unit saw.

#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use vestnav_core::study::{Outcome, TrialRecord};
use vestnav_device::gps::GpsEvent;
use vestnav_device::wtcu::emulator::{PtyEmulator, UnitConfig};
use vestnav_device::wtcu::{CommandKind, LinkState};
use vestnav_station::command::Command as StationCommand;
use vestnav_station::hardware::Hardware;
use vestnav_station::sources::{GpsSourceConfig, VestSourceConfig};
use vestnav_station::study::{StudyCommand, StudyPhase, Timing};
use vestnav_station::{Station, StationEvent, StationOptions, StationSettings};

/// WGS-84 near the equator: metres per radian along a meridian (its radius of curvature a(1 - e²)) and
/// along the equator (a).
fn radii_m() -> (f64, f64) {
    let a = 6_378_137.0;
    let f = 1.0 / 298.257_223_563;
    (a * (1.0 - f * (2.0 - f)), a)
}

/// The routes: 12 m due north along the meridian 10° E from the equator, and 12 m due east along the
/// equator from 10.01° E (both geodesics, so the distance to them has a closed form).
const LEN_M: f64 = 12.0;
const NORTH: (f64, f64) = (0.0, 10.0);
const EAST: (f64, f64) = (0.0, 10.01);

fn end_of(start: (f64, f64), north: bool) -> (f64, f64) {
    let (m, a) = radii_m();
    if north {
        (start.0 + (LEN_M / m).to_degrees(), start.1)
    } else {
        (start.0, start.1 + (LEN_M / a).to_degrees())
    }
}

/// (along, across) of `p` relative to the route from `start` [m], in the closed forms of `radii_m`.
fn along_across(start: (f64, f64), north: bool, p: (f64, f64)) -> (f64, f64) {
    let (m, a) = radii_m();
    let dn = m * (p.0 - start.0).to_radians();
    let de = a * p.0.to_radians().cos() * (p.1 - start.1).to_radians();
    if north { (dn, de) } else { (de, dn) }
}

/// Distance from `p` to the route segment: across it, or to the nearer end beyond them.
fn distance_to_route(start: (f64, f64), north: bool, p: (f64, f64)) -> f64 {
    let (along, across) = along_across(start, north, p);
    let beyond = if along < 0.0 { -along } else { (along - LEN_M).max(0.0) };
    beyond.hypot(across)
}

fn gpx(name: &str, a: (f64, f64), b: (f64, f64)) -> String {
    format!(
        "<?xml version=\"1.0\"?>\n<gpx version=\"1.1\" creator=\"test\" xmlns=\"http://www.topografix.com/GPX/1/1\">\
         <rte><name>{name}</name><rtept lat=\"{}\" lon=\"{}\"><name>start</name></rtept>\
         <rtept lat=\"{}\" lon=\"{}\"><name>end</name></rtept></rte></gpx>\n",
        a.0, a.1, b.0, b.1
    )
}

fn protocol(dir: &Path) -> PathBuf {
    std::fs::write(dir.join("north.gpx"), gpx("north", NORTH, end_of(NORTH, true))).unwrap();
    std::fs::write(dir.join("east.gpx"), gpx("east", EAST, end_of(EAST, false))).unwrap();
    let text = r#"
name = "nav2x2"
task = "navigation"
order = "blocked"
iti_ms = 100
[navigation]
routes = ["north.gpx", "east.gpx"]
time_limit_s = 60.0
[[condition]]
name = "bearing-walking"
strategy = "bearing"
heading = "cog"
cue_set = "walking"
cue_interval_s = 1.0
[[condition]]
name = "pursuit-in-place"
strategy = "pursuit"
heading = "cog"
cue_set = "turn-in-place"
cue_interval_s = 2.0
[[block]]
name = "test"
repetitions = 1
"#;
    let p = dir.join("nav2x2.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// The PLAY frames the unit accepted since it started (its own count: sequence numbers wrap at 256, and a
/// session of this length uses more than that).
fn plays_accepted(unit: &PtyEmulator) -> u64 {
    unit.view().accepted.get(&CommandKind::Play).copied().unwrap_or(0)
}

#[test]
fn a_navigation_study_walked_by_the_simulator_completes_every_trial_with_checked_measures() {
    let dir = std::env::temp_dir().join(format!("vestnav-study-nav-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let protocol = protocol(&dir);
    let unit = PtyEmulator::spawn(UnitConfig::default()).unwrap();
    let mut settings = StationSettings::default();
    settings.guidance.auto = false;
    settings.guidance.arrival_radius_m = 3.0;
    let mut s = Station::new(
        Box::new(Hardware::default()),
        StationOptions {
            settings,
            gps: Some(GpsSourceConfig::Simulator { route: None }),
            vest: Some(VestSourceConfig::Serial { port: unit.path().to_owned() }),
            liveness: None,
            ..StationOptions::default()
        },
    );
    // The station's own defaults lose to the protocol's iti_ms.
    s.set_study_timing(Timing {
        iti_s: 30.0,
        feedback_s: 0.0,
        response_timeout_s: None,
        ..Timing::default()
    });
    s.connect_vest();
    s.connect_gps(Vec::new());
    let start = Instant::now();
    while s.vest.state != Some(LinkState::Ready) {
        assert!(start.elapsed() < Duration::from_secs(5), "vest ready");
        s.pump(|_| {});
        std::thread::sleep(Duration::from_millis(2));
    }
    s.apply(StationCommand::Study(StudyCommand::Load {
        protocol,
        participant: "P01".into(),
        session: "S1".into(),
        out_dir: dir.clone(),
    }))
    .unwrap();
    // The session clock as an instant: fixes belong to a trial from its start on.
    let epoch = Instant::now().checked_sub(Duration::from_secs_f64(s.study_clock_s())).unwrap();
    s.apply(StationCommand::Study(StudyCommand::Start)).unwrap();
    let fixes = run_to_the_end(&mut s);
    check_rows(&s, epoch, &fixes, &unit);
    drop(s);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Fixes by trial: when each arrived, where.
type Walks = Vec<Vec<(Instant, (f64, f64))>>;

/// Pumps until the session is over: every fix a pump hands out while a trial walks, by trial.
fn run_to_the_end(s: &mut Station) -> Walks {
    let mut fixes: Walks = vec![Vec::new(); 4];
    let end = Instant::now() + Duration::from_mins(2);
    loop {
        let v = s.study_view().unwrap();
        if v.phase.is_over() {
            break;
        }
        assert!(Instant::now() < end, "the study within 120 s: {v:?}");
        assert!(!matches!(v.phase, StudyPhase::Paused), "{v:?}");
        let walking = (v.phase == StudyPhase::Navigating).then_some(v.trial);
        s.pump(|ev| {
            if let (Some(k), StationEvent::Gps(GpsEvent::Fix(f))) = (walking, ev)
                && let (Some(at), Some(la), Some(lo)) = (f.received_at, f.lat_deg, f.lon_deg)
                && f.has_position()
            {
                fixes[k].push((at, (la, lo)));
            }
        });
        std::thread::sleep(Duration::from_millis(2));
    }
    fixes
}

/// Every row completed, its measures against the closed forms on the trial's fixes, its cues against the
/// unit's PLAY frames.
fn check_rows(s: &Station, epoch: Instant, fixes: &Walks, unit: &PtyEmulator) {
    let v = s.study_view().unwrap();
    assert_eq!(v.phase, StudyPhase::Finished);
    let rows: Vec<TrialRecord> = vestnav_core::study::record::read_csv_file(&v.results_csv).unwrap();
    assert_eq!(rows.len(), 4);
    let labels: Vec<&str> = rows.iter().map(|r| r.stimulus.as_str()).collect();
    assert_eq!(
        labels,
        ["north/bearing-walking", "north/pursuit-in-place", "east/bearing-walking", "east/pursuit-in-place"]
    );
    let mut cues = 0;
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r.outcome, Outcome::Completed, "{r:?}");
        let (start, north) = if k < 2 { (NORTH, true) } else { (EAST, false) };
        let from = epoch + Duration::from_secs_f64(r.stimulus_on_s.unwrap());
        let walk: Vec<(f64, f64)> = fixes[k].iter().filter(|(at, _)| *at >= from).map(|f| f.1).collect();
        assert!(walk.len() >= 3, "trial {k}: {} fixes", walk.len());
        // Every fix near this trial's route: none of the previous walk's.
        assert!(walk.iter().all(|p| distance_to_route(start, north, *p) < 15.0), "trial {k}: {walk:?}");
        let n = walk.len() as f64;
        let rms = (walk.iter().map(|p| distance_to_route(start, north, *p).powi(2)).sum::<f64>() / n).sqrt();
        let path: f64 = walk
            .windows(2)
            .map(|w| {
                let (a0, c0) = along_across(start, north, w[0]);
                let (a1, c1) = along_across(start, north, w[1]);
                (a1 - a0).hypot(c1 - c0)
            })
            .sum();
        eprintln!(
            "trial {k}: {} fixes, path {path:.2} m, RMS {rms:.3} m, {:.1} s, {} cues",
            walk.len(),
            r.completion_s.unwrap_or(f64::NAN),
            r.cues.unwrap_or(0)
        );
        // The route up to the last waypoint's arrival circle (the station's 3 m).
        approx::assert_relative_eq!(r.route_m.unwrap(), LEN_M - 3.0, max_relative = 1e-4);
        approx::assert_relative_eq!(r.cross_track_rms_m.unwrap(), rms, max_relative = 1e-3);
        approx::assert_relative_eq!(r.path_m.unwrap(), path, max_relative = 1e-3);
        assert!(r.path_ratio().unwrap() >= 1.0, "trial {k}: path {path:.2} m of {:?} m", r.route_m);
        assert!(r.completion_s.unwrap() > 0.0 && r.completion_s.unwrap() < 60.0);
        assert_eq!((r.stops, r.missed_waypoints), (Some(0), Some(0)), "{r:?}");
        cues += r.cues.unwrap();
    }
    // Every cue the rows count is one PLAY frame at the unit, and nothing else played (a cue handed to the
    // vest as the last trial ended reaches the unit a moment later).
    let until = Instant::now() + Duration::from_secs(5);
    while plays_accepted(unit) < u64::from(cues) && Instant::now() < until {
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(plays_accepted(unit), u64::from(cues));
    assert!(cues > 0);
    let analysis = vestnav_core::study::analyze(&rows);
    assert_eq!(analysis.navigation.len(), 2);
    assert!(analysis.navigation.iter().all(|c| c.trials == 2 && c.completed == 2));
}
