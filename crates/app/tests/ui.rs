//! The console driven by label with `egui_kittest`, devices injected.
#![allow(clippy::unwrap_used)]

mod common;

use std::io::{Read, Write};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use vestnav_app::config::{Config, GpsSourceConfig, VestSourceConfig};
use vestnav_app::console::{Console, ConsoleOptions, GpsAlarm};
use vestnav_core::guidance::HeadingSource;
use vestnav_core::vest::TactorMask;
use vestnav_device::gps::{ErrorEstimate, ErrorSource, Fix, FixMode, GpsEvent};
use vestnav_device::outbox::Outbox;
use vestnav_device::session_log::LogEntry;
use vestnav_device::sim::{CompassSetup, SimulatedCompass, WearerMotion};
use vestnav_device::wtcu::codec::{FrameCodec, WireCodec};
use vestnav_device::wtcu::emulator::UnitConfig;
use vestnav_device::wtcu::engine::HeadingSensor as _;
use vestnav_device::wtcu::worker::{EmulatedPort, Transport, WorkerSettings};
use vestnav_device::wtcu::{LinkState, Request, VestCommand, VestEvent, VestHandle};
use vestnav_station::devices::{DeviceFactory, GpsWorker};
use vestnav_station::route::Waypoint;

/// The emulated unit behind a transport that also records every command it was sent (decoded with the
/// unit-side codec): the device side of the real protocol, seen from the vest.
struct RecordingUnit {
    port: EmulatedPort,
    codec: FrameCodec,
    sent: Arc<Mutex<Vec<Request>>>,
}

impl Read for RecordingUnit {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.port.read(buf)
    }
}

impl Write for RecordingUnit {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let mut out = Vec::new();
        self.codec.decode_requests(buf, &mut out);
        for p in out.into_iter().flatten() {
            if !matches!(p.message, Request::Hello | Request::Heartbeat | Request::GetStatus) {
                self.sent.lock().unwrap().push(p.message);
            }
        }
        self.port.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.port.flush()
    }
}

/// GPS: the shared test factory's injected events; vest: the emulated unit behind a recording transport.
#[derive(Default, Clone)]
struct Fake {
    sent: Arc<Mutex<Vec<Request>>>,
    gps: common::Devices,
    /// The emulated unit's magnetometer (none: the unit offers no heading, and the console sends none of
    /// the v2 heading requests).
    compass: Option<CompassSetup>,
}

impl Fake {
    fn sent(&self) -> Vec<Request> {
        self.sent.lock().unwrap().clone()
    }

    fn gps(&self, ev: &GpsEvent) {
        self.gps.gps(ev);
    }
}

impl DeviceFactory for Fake {
    fn open_gps(
        &self,
        s: &GpsSourceConfig,
        r: &[Waypoint],
        out: Vec<Outbox<GpsEvent>>,
    ) -> Result<Box<dyn GpsWorker>, String> {
        self.gps.open_gps(s, r, out)
    }
    fn open_vest(&self, _s: &VestSourceConfig, out: Vec<Outbox<VestEvent>>) -> Result<VestHandle, String> {
        let sent = self.sent.clone();
        let compass = self.compass.clone();
        let connector = Box::new(move || {
            let port = EmulatedPort::new(
                &UnitConfig { compass: compass.clone(), ..UnitConfig::default() },
                Duration::from_millis(2),
            );
            Ok(Box::new(RecordingUnit { port, codec: FrameCodec::new(), sent: sent.clone() })
                as Box<dyn Transport>)
        });
        VestHandle::spawn_with(connector, WorkerSettings::default(), out).map_err(|e| e.to_string())
    }
}

fn harness(fake: &Fake) -> Harness<'static, Console> {
    harness_with(fake, Config { map_tiles: false, guidance_auto: false, ..Config::default() })
}

fn harness_with(fake: &Fake, cfg: Config) -> Harness<'static, Console> {
    harness_sized(fake, cfg, egui::vec2(1400.0, 900.0))
}

/// The console in a window of `size`, once the emulated unit is live.
fn harness_sized(fake: &Fake, cfg: Config, size: egui::Vec2) -> Harness<'static, Console> {
    let console = Console::new(Box::new(fake.clone()), ConsoleOptions { cfg, ..ConsoleOptions::default() });
    let mut h = Harness::builder().with_size(size).build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    settle(&mut h, |c| c.station.vest.is_live());
    assert!(
        h.state().station.vest.is_live(),
        "the emulated unit did not come up: {:?}",
        h.state().station.vest.state
    );
    h
}

/// Steps frames until `done` holds (workers run on their own threads), at most ~2 s.
fn settle(h: &mut Harness<'static, Console>, done: impl Fn(&Console) -> bool) {
    for _ in 0..200 {
        h.step();
        if done(h.state()) {
            return;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// A 3D fix whose bytes arrived `age` ago.
fn fix(lat: f64, lon: f64, age: Duration) -> Fix {
    Fix {
        lat_deg: Some(lat),
        lon_deg: Some(lon),
        mode: Some(FixMode::Fix3D),
        error: Some(ErrorEstimate { horizontal_m: 3.0, vertical_m: None, source: ErrorSource::Gst }),
        received_at: Some(Instant::now().checked_sub(age).unwrap()),
        ..Fix::default()
    }
}

fn on(c: &Console) -> TactorMask {
    c.station.vest.tactors_on.unwrap_or(TactorMask::NONE)
}

#[test]
fn clicking_a_tactor_fires_it_and_shows_it_on() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("T5").click();
    settle(&mut h, |c| !on(c).is_empty());
    assert_eq!(fake.sent(), vec![Request::Fire { mask: TactorMask::from_indices([5]), duration_ms: 500 }]);
    assert_eq!(on(h.state()), TactorMask::from_indices([5]));
}

#[test]
fn stop_all_button_and_key() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("STOP ALL").click();
    settle(&mut h, |_| fake.sent().len() == 1);
    h.key_press(egui::Key::Space);
    settle(&mut h, |_| fake.sent().len() == 2);
    assert_eq!(fake.sent(), vec![Request::StopAll, Request::StopAll]);
    assert!(!h.state().cfg.guidance_auto);
}

#[test]
fn escape_closes_a_menu_without_stopping_the_vest() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.state_mut().cfg.guidance_auto = true;
    h.run_steps(2);
    h.get_by_label("GPS source").click();
    h.run_steps(2);
    assert!(h.query_by_label("NMEA file replay").is_some(), "the combo box is open");
    h.key_press(egui::Key::Escape);
    h.run_steps(3);
    assert!(h.query_by_label("NMEA file replay").is_none(), "Esc closed it");
    std::thread::sleep(Duration::from_millis(50));
    assert!(fake.sent().is_empty(), "{:?}", fake.sent());
    assert!(h.state().cfg.guidance_auto, "automatic guidance untouched");
}

#[test]
fn the_grid_is_disabled_while_the_vest_is_not_live() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Disconnect vest").click();
    settle(&mut h, |c| !c.station.vest.is_live());
    h.run_steps(1);
    assert!(h.query_by_label_contains("tactors cannot be fired").is_some());
    h.get_by_label("T5").click();
    h.run_steps(2);
    assert!(fake.sent().iter().all(|r| *r == Request::StopAll), "{:?}", fake.sent());
}

#[test]
fn multi_select_fires_several() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Multi-select").click();
    h.run_steps(1);
    for t in ["T0", "T3", "T12"] {
        h.get_by_label(t).click();
        h.run_steps(2);
    }
    assert!(h.state().vest_ui.select_mode);
    assert_eq!(h.state().vest_ui.selected, TactorMask::from_indices([0, 3, 12]));
    h.get_by_label("Fire selected (3)").click();
    settle(&mut h, |_| !fake.sent().is_empty());
    assert_eq!(
        fake.sent(),
        vec![Request::Fire { mask: TactorMask::from_indices([0, 3, 12]), duration_ms: 500 }]
    );
}

#[test]
fn add_waypoint_with_the_mouse() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    let before = h.state().station.route().waypoints().len();
    h.get_by_label("Add waypoints").click();
    h.run_steps(2);
    // Click somewhere on the map, away from the panels and the existing waypoints.
    let pos = egui::pos2(900.0, 700.0);
    h.hover_at(pos);
    h.event(egui::Event::PointerButton {
        pos,
        button: egui::PointerButton::Primary,
        pressed: true,
        modifiers: egui::Modifiers::default(),
    });
    h.step();
    h.event(egui::Event::PointerButton {
        pos,
        button: egui::PointerButton::Primary,
        pressed: false,
        modifiers: egui::Modifiers::default(),
    });
    h.run_steps(2);
    let wps = &h.state().station.route().waypoints();
    assert_eq!(wps.len(), before + 1);
    let w = wps.last().unwrap();
    assert!((w.lat_deg - 42.357).abs() < 0.01 && (w.lon_deg + 71.10).abs() < 0.02, "{w:?}");
}

#[test]
fn a_fix_shows_and_losing_it_raises_the_alarm() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1, Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fix.is_some());
    assert!(h.query_by_label_contains("42.3562000°").is_some());
    assert!(h.query_by_label_contains("GPS FIX LOST").is_none());
    // The last position's bytes arrived longer ago than the lost limit (ages run on the real clock, from
    // the instant the bytes arrived).
    let lost = h.state().cfg.lost_after_s;
    fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1, Duration::from_secs_f64(lost + 1.0)))));
    settle(&mut h, |c| c.station.gps.fixes == 2);
    assert!(matches!(h.state().gps_alarm(Instant::now()), Some(GpsAlarm::Lost { .. })));
    h.run_steps(1);
    assert!(h.query_by_label_contains("GPS FIX LOST").is_some());
    // A fresh fix clears it; a receiver that reports "no fix" raises it at once.
    fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1, Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fixes == 3);
    assert!(h.query_by_label_contains("GPS FIX LOST").is_none());
    let no_fix = Fix { mode: Some(FixMode::NoFix), received_at: Some(Instant::now()), ..Fix::default() };
    fake.gps(&GpsEvent::Fix(Box::new(no_fix)));
    settle(&mut h, |c| c.station.gps.fix.as_ref().is_some_and(|f| f.mode == Some(FixMode::NoFix)));
    h.run_steps(1);
    assert!(h.query_by_label_contains("receiver reports no fix").is_some());
}

/// The console on the real device layer: the device crate's emulated WTCU and the built-in simulator.
fn real_harness(log_dir: Option<std::path::PathBuf>) -> Harness<'static, Console> {
    let cfg = Config { map_tiles: false, guidance_auto: false, ..Config::default() };
    let console = Console::new(
        Box::new(vestnav_station::hardware::Hardware::default()),
        ConsoleOptions { cfg, log_dir, ..ConsoleOptions::default() },
    );
    Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console)
}

#[test]
fn emulated_vest_reports_the_clicked_tactor_on_then_stop_all_clears_it() {
    let dir = std::env::temp_dir().join(format!("vestnav-ui-{}", std::process::id()));
    let mut h = real_harness(Some(dir.clone()));
    settle(&mut h, |c| c.station.vest.state == Some(LinkState::Ready));
    assert_eq!(h.state().station.vest.state, Some(LinkState::Ready), "emulated vest did not come up");
    // Above the fold of the 1400x900 window (the status bar takes the last ~25 points).
    let t15 = h.get_by_label("T15").rect();
    assert!(t15.bottom() <= 875.0, "the vest grid ends at y = {}", t15.bottom());
    h.get_by_label("T9").click();
    // The orange state comes from the unit's acks/status, not from what we sent.
    settle(&mut h, |c| on(c).contains(9));
    assert_eq!(on(h.state()), TactorMask::from_indices([9]));
    h.get_by_label("STOP ALL").click();
    settle(&mut h, |c| on(c).is_empty());
    assert!(on(h.state()).is_empty());
    // The simulator walks the demo route: a fix arrives within about a second.
    settle(&mut h, |c| c.station.gps.fix.is_some());
    assert!(h.state().station.gps.fix.as_ref().unwrap().has_position());
    let log_path = h.state().log_path().unwrap().to_path_buf();
    drop(h);
    std::thread::sleep(std::time::Duration::from_millis(300));
    let (records, _) = vestnav_device::session_log::read_log(&log_path).unwrap();
    assert!(
        records
            .iter()
            .any(|r| matches!(&r.entry, LogEntry::Command { command: VestCommand::Fire { .. }, .. }))
    );
    assert!(
        records.iter().any(|r| matches!(&r.entry, LogEntry::Command { command: VestCommand::StopAll, .. }))
    );
    assert!(records.iter().any(|r| matches!(&r.entry, LogEntry::Ack { .. })));
    assert!(records.iter().any(|r| matches!(&r.entry, LogEntry::Fix { .. })));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn nmea_replay_shows_the_fix_then_the_no_fix_alarm() {
    let mut h = real_harness(None);
    settle(&mut h, |c| c.station.gps.fix.is_some());
    h.get_by_label("Disconnect GPS").click();
    h.run_steps(2);
    assert!(!h.state().gps_connected());
    // Pick the replay source in the combo box, by label.
    h.get_by_label("GPS source").click();
    h.run_steps(2);
    h.get_by_label("NMEA file replay").click();
    h.run_steps(2);
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/walk_then_lost.nmea");
    {
        let p = &mut h.state_mut().gps_ui.picker;
        assert_eq!(p.kind, vestnav_app::gps_panel::SourceKind::Replay);
        p.replay_path = file.to_owned();
        p.replay_speed = 10.0;
    }
    h.get_by_label("Connect GPS").click();
    // Epoch 12:00:04 is the last with a position (42.3562667 N, independent: 42° 21.3760').
    let t4 = "2026-11-22T12:00:04Z".parse::<chrono::DateTime<chrono::Utc>>().unwrap();
    settle(&mut h, |c| c.station.gps.fix.as_ref().is_some_and(|f| f.time == Some(t4)));
    let f = h.state().station.gps.fix.clone().unwrap();
    let (lat, lon) = (f.lat_deg.unwrap(), f.lon_deg.unwrap());
    assert!((lat - (42.0 + 21.376 / 60.0)).abs() < 1e-9, "{lat}");
    assert!((lon + 71.1).abs() < 1e-9);
    assert!(h.query_by_label_contains("-71.1000000°").is_some());
    // Then the receiver reports no fix: the alarm is raised at once.
    settle(&mut h, |c| c.station.gps.fix.as_ref().is_some_and(|f| !f.has_position()));
    h.run_steps(1);
    assert!(h.query_by_label_contains("GPS FIX LOST: receiver reports no fix").is_some());
    assert!(h.query_by_label_contains("GPS: FIX LOST").is_some());
    assert_eq!(
        h.state().cfg.gps,
        GpsSourceConfig::Replay { path: file.into(), speed: vestnav_device::gps::ReplaySpeed::Times(10.0) },
        "the chosen source is remembered in the config"
    );
}

/// The vest's compass steers guidance through the console's own threads: the unit (protocol v2, an ideal
/// sensor, the wearer standing facing 90° true) streams its magnetic heading, the console loads the
/// calibration kept for the unit, and guidance, adding the WMM declination at the wearer's position, steers
/// by 90° true. Truth: the emulated wearer's body heading.
#[test]
fn the_vest_compass_reaches_guidance_and_steers_by_true_heading() {
    let setup = CompassSetup {
        motion: WearerMotion::Still { heading_deg: 90.0 },
        steel_east_m: None,
        ideal: true,
        seed: 5,
    };
    let (raw, _) = SimulatedCompass::new(&setup).sample(Instant::now());
    let field = raw.iter().map(|v| v * v).sum::<f64>().sqrt();
    let fake = Fake { compass: Some(setup), ..Fake::default() };
    let mut cfg = Config {
        map_tiles: false,
        guidance_auto: false,
        heading_mode: vestnav_core::guidance::HeadingMode::Compass,
        ..Config::default()
    };
    cfg.compass_calibrations.insert("emulated".into(), vestnav_core::compass::Calibration::identity(field));
    let mut h = harness_with(&fake, cfg);
    // The console asked for the stream and loaded the unit's calibration when it identified itself.
    settle(&mut h, |_| fake.sent().iter().any(|r| matches!(r, Request::SetCalibration(_))));
    let sent = fake.sent();
    assert!(sent.contains(&Request::HeadingStart { rate_hz: 5 }), "{sent:?}");
    assert!(sent.iter().any(|r| matches!(r, Request::SetCalibration(_))), "{sent:?}");
    settle(&mut h, |c| c.station.vest.heading.is_some_and(|a| a.quality_pct == Some(100)));
    let a = h.state().station.vest.heading.unwrap();
    assert_eq!(a.quality_pct, Some(100), "{a:?}");
    // A standing wearer near the emulated place (same WMM declination): guidance steers by the compass.
    for _ in 0..40 {
        fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1000, Duration::ZERO))));
        h.step();
        if h.state().station.guidance.as_ref().is_some_and(|g| g.heading_source == HeadingSource::Compass) {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let g = h.state().station.guidance.clone().unwrap();
    assert_eq!(g.heading_source, HeadingSource::Compass, "{g:?}");
    let heading = g.heading_deg.unwrap();
    assert!((heading - 90.0).abs() < 0.5, "guidance steers by {heading:.2}° true, the wearer faces 90°");
    assert!(g.declination_deg.is_some());
    // The Vest tab shows the reading as the unit reports it, with its true heading.
    h.get_by_label("Vest").click();
    h.run_steps(2);
    h.get_by_label_contains("quality 100 %");
}

/// Great-circle distance on a sphere of the WGS84 mean radius [m] (haversine): the test's own geometry.
fn haversine_m(a: (f64, f64), b: (f64, f64)) -> f64 {
    let (la1, lo1, la2, lo2) = (a.0.to_radians(), a.1.to_radians(), b.0.to_radians(), b.1.to_radians());
    let h = ((la2 - la1) / 2.0).sin().powi(2) + la1.cos() * la2.cos() * ((lo2 - lo1) / 2.0).sin().powi(2);
    2.0 * 6_371_008.8 * h.sqrt().asin()
}

/// Fault 3 of issue 15: during a stale or lost fix the panel no longer shows the last mode and satellite
/// count as current, and the wearer's dot is not the live one. Ages come from the injected fixes' arrival
/// instants (small limits keep the test short).
#[test]
fn a_stale_or_lost_fix_is_shown_as_last_known_not_live() {
    let fake = Fake::default();
    let cfg = Config {
        map_tiles: false,
        guidance_auto: false,
        stale_after_s: 2.0,
        lost_after_s: 4.0,
        ..Config::default()
    };
    let mut h = harness_with(&fake, cfg);
    let with_sats = |age: Duration| Fix {
        sats_used: Some(8),
        sats_visible: Some(9),
        satellites: (1..=9)
            .map(|prn| vestnav_device::gps::Satellite {
                prn,
                constellation: vestnav_device::gps::Constellation::Gps,
                elevation_deg: Some(45.0),
                azimuth_deg: Some(f64::from(prn) * 40.0),
                snr_dbhz: Some(42.0),
                used: prn <= 8,
            })
            .collect(),
        ..fix(42.3562, -71.1, age)
    };
    fake.gps(&GpsEvent::Fix(Box::new(with_sats(Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fixes == 1);
    h.run_steps(1);
    assert!(h.query_by_label("3D · —").is_some(), "a fresh fix shows its mode as current");
    assert!(h.query_by_label("8 used / 9 in view").is_some());
    assert!(h.query_by_label_contains("showing the last known fix").is_none());
    assert!(h.state().map.wearer_shown.is_some_and(|m| m.live));

    // Stale: the newest fix's bytes arrived 3 s ago (past 2 s).
    fake.gps(&GpsEvent::Fix(Box::new(with_sats(Duration::from_secs(3)))));
    settle(&mut h, |c| c.station.gps.fixes == 2);
    h.run_steps(1);
    assert!(matches!(h.state().gps_alarm(Instant::now()), Some(GpsAlarm::Stale { .. })));
    assert!(h.query_by_label_contains("NOT CURRENT: showing the last known fix, 3 s ago").is_some());
    assert!(h.query_by_label("3D · —").is_none(), "the live mode label is gone");
    assert!(h.query_by_label("8 used / 9 in view").is_none(), "the live satellite count is gone");
    assert!(h.query_by_label_contains("3D · — (last known, 3 s ago)").is_some());
    assert!(h.query_by_label_contains("sky and signal: last known").is_some());
    let m = h.state().map.wearer_shown.unwrap();
    assert!(!m.live && m.age_s.is_some_and(|a| a >= 3.0), "{m:?}");

    // Lost: 5 s (past 4 s).
    fake.gps(&GpsEvent::Fix(Box::new(with_sats(Duration::from_secs(5)))));
    settle(&mut h, |c| c.station.gps.fixes == 3);
    h.run_steps(1);
    assert!(matches!(h.state().gps_alarm(Instant::now()), Some(GpsAlarm::Lost { .. })));
    assert!(h.query_by_label_contains("FIX LOST: showing the last known fix, 5 s ago").is_some());
    assert!(h.query_by_label("3D · —").is_none());
    assert!(h.query_by_label_contains("8 used / 9 in view (last known, 5 s ago)").is_some());
    assert!(h.state().map.wearer_shown.is_some_and(|m| !m.live));

    // A fresh fix makes it live again.
    fake.gps(&GpsEvent::Fix(Box::new(with_sats(Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fixes == 4);
    h.run_steps(1);
    assert!(h.query_by_label("3D · —").is_some());
    assert!(h.state().map.wearer_shown.is_some_and(|m| m.live));
}

/// Fault 6a of issue 15: a waypoint 15,000 km away (on the equator, a * 134.75° in radians with the WGS84
/// a = 6378137 m) shows a warning with the distance in km, and no time to go.
#[test]
fn an_absurdly_far_waypoint_warns_instead_of_a_time_to_go() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    let far_lon = (15_000_000.0_f64 / 6_378_137.0).to_degrees();
    let far = vec![
        Waypoint { name: "Far".into(), lat_deg: 0.0, lon_deg: far_lon, arrival_radius_m: None },
        Waypoint { name: "Farther".into(), lat_deg: 0.0, lon_deg: far_lon + 1.0, arrival_radius_m: None },
    ];
    h.state_mut().station.route_mut().replace("far".into(), far).unwrap();
    for _ in 0..100 {
        fake.gps(&GpsEvent::Fix(Box::new(fix(0.0, 0.0, Duration::ZERO))));
        h.step();
        let revision = h.state().station.route().revision();
        if h.state()
            .station
            .guidance
            .as_ref()
            .is_some_and(|g| g.route_revision == revision && g.distance_m.is_some_and(|d| d > 1e6))
        {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    h.run_steps(2);
    assert!(h.query_by_label_contains("too far to walk").is_some());
    assert!(h.query_by_label_contains("to go").is_none(), "no time to go is shown for 15,000 km");
    // A label's text is its accesskit value.
    let line = h.get_by_label_contains("next: Far (1/2)").value().unwrap_or_default();
    let km: f64 = line
        .split(" km away")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no distance in {line:?}"));
    assert!((km - 15_000.0).abs() < 15_000.0 * 0.01, "{km} km shown for a 15,000 km leg ({line})");
}

/// Fault 6b of issue 15: the track does not join positions a walker cannot have walked between, nor two
/// GPS sources. Truth: the injected fixes' geometry (haversine) and the walking bound.
#[test]
fn the_track_starts_a_new_segment_on_a_jump_or_a_source_change() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    let boston = (42.3562, -71.1);
    let far = (42.3562, -5.1);
    let step = (42.3562, -5.09988); // ~10 m east of `far`
    assert!(haversine_m(boston, far) > 4_900_000.0, "the jump is ~5000 km");
    assert!(haversine_m(far, step) < 15.0, "the step is a walker's");
    for (k, p) in [boston, far, step].into_iter().enumerate() {
        fake.gps(&GpsEvent::Fix(Box::new(fix(p.0, p.1, Duration::ZERO))));
        settle(&mut h, |c| c.station.gps.fixes == k as u64 + 1);
    }
    let segs: Vec<Vec<(f64, f64)>> = h
        .state()
        .station
        .track()
        .segments()
        .iter()
        .map(|s| s.iter().map(|p| (p.lat_deg, p.lon_deg)).collect())
        .collect();
    assert_eq!(
        segs,
        vec![vec![boston], vec![far, step]],
        "5000 km in no time splits the track, 10 m does not"
    );

    // Another source: its first position, though only ~1 m away, starts a new segment.
    h.get_by_label("Disconnect GPS").click();
    h.run_steps(2);
    h.get_by_label("Connect GPS").click();
    h.run_steps(2);
    assert!(h.state().gps_connected());
    let near = (42.3562, -5.099_87);
    fake.gps(&GpsEvent::Fix(Box::new(fix(near.0, near.1, Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fixes == 1);
    let lens: Vec<usize> = h.state().station.track().segments().iter().map(|s| s.len()).collect();
    assert_eq!(lens, vec![1, 2, 1]);
}

/// The console with the route autosaved to (and restored from) `autosave`.
fn harness_autosaving(fake: &Fake, autosave: &std::path::Path) -> Harness<'static, Console> {
    let cfg = Config { map_tiles: false, guidance_auto: false, ..Config::default() };
    let opts =
        ConsoleOptions { cfg, route_autosave: Some(autosave.to_path_buf()), ..ConsoleOptions::default() };
    let console = Console::new(Box::new(fake.clone()), opts);
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    settle(&mut h, |c| c.station.vest.is_live());
    h
}

/// A fresh directory for one test's files.
fn test_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("vestnav-ui-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Three waypoints with coordinates the tests compare against.
fn three_waypoints() -> Vec<Waypoint> {
    vec![
        Waypoint { name: "Alpha".into(), lat_deg: 42.3571, lon_deg: -71.1012, arrival_radius_m: None },
        Waypoint { name: "Bravo".into(), lat_deg: 42.3577, lon_deg: -71.1003, arrival_radius_m: None },
        Waypoint { name: "Charlie".into(), lat_deg: 42.3581, lon_deg: -71.0995, arrival_radius_m: None },
    ]
}

fn set_route(h: &mut Harness<'static, Console>, waypoints: Vec<Waypoint>, next: usize) {
    let c = h.state_mut();
    c.station.route_mut().replace("Test loop".into(), waypoints).unwrap();
    c.station.route_mut().set_next(next);
    h.run_steps(2);
}

const UNDO_KEYS: egui::Modifiers = egui::Modifiers { ctrl: true, command: true, ..egui::Modifiers::NONE };

/// Fault 4 of issue 15: route edits survive a restart. Truth: the route the test set.
#[test]
fn the_autosaved_route_comes_back_after_a_restart() {
    let dir = test_dir("autosave");
    let path = dir.join("route-autosave.gpx");
    let fake = Fake::default();
    let mut h = harness_autosaving(&fake, &path);
    assert_eq!(h.state().station.route().waypoints().len(), 7, "no autosave yet: the demo route");
    set_route(&mut h, three_waypoints(), 1);
    // The edit is on disk while the console runs (not only at exit).
    settle(&mut h, |_| std::fs::read_to_string(&path).is_ok_and(|t| t.contains("Charlie")));
    assert!(std::fs::read_to_string(&path).unwrap().contains("Charlie"));
    // Deleting through the list is saved too; no temp file is left behind.
    h.get_all_by_label("Del").nth(2).unwrap().click();
    h.run_steps(2);
    drop(h);
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().map(|e| e.file_name()).collect();
    assert_eq!(left.len(), 1, "no temporary file is left behind: {left:?}");

    let mut h = harness_autosaving(&Fake::default(), &path);
    h.run_steps(2);
    let m = h.state().station.route();
    assert_eq!(m.name(), "Test loop");
    assert_eq!(m.waypoints(), three_waypoints()[..2].to_vec());
    assert_eq!(m.next(), 1);
    assert!(h.query_by_label_contains("next: Bravo (2/2)").is_some());
    drop(h);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Fault 4 of issue 15: Delete is undoable at once (the notice says so), Undo brings the waypoint back
/// with its name and coordinates, Redo deletes it again; the same with Ctrl+Z / Ctrl+Shift+Z / Ctrl+Y.
#[test]
fn undo_restores_a_deleted_waypoint_and_redo_deletes_it_again() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    set_route(&mut h, three_waypoints(), 0);
    h.get_all_by_label("Del").nth(1).unwrap().click();
    h.run_steps(2);
    let without_bravo = vec![three_waypoints()[0].clone(), three_waypoints()[2].clone()];
    assert_eq!(h.state().station.route().waypoints(), without_bravo);
    assert!(h.query_by_label("Deleted Bravo").is_some(), "the delete says it can be undone");
    h.get_by_label("Undo").click();
    h.run_steps(2);
    assert_eq!(
        h.state().station.route().waypoints(),
        three_waypoints(),
        "Bravo is back, same name and coordinates"
    );
    assert!(h.query_by_label("Deleted Bravo").is_none());
    h.get_by_label("Redo").click();
    h.run_steps(2);
    assert_eq!(h.state().station.route().waypoints(), without_bravo);
    // The notice's own button.
    h.get_all_by_label("Del").next().unwrap().click();
    h.run_steps(2);
    assert!(h.query_by_label("Deleted Alpha").is_some());
    h.get_by_label("Undo delete").click();
    h.run_steps(2);
    assert_eq!(h.state().station.route().waypoints(), without_bravo, "Alpha is back");
    // The keys: Ctrl+Z, Ctrl+Shift+Z, Ctrl+Y.
    h.key_press_modifiers(UNDO_KEYS, egui::Key::Z);
    h.run_steps(2);
    assert_eq!(h.state().station.route().waypoints(), three_waypoints());
    h.key_press_modifiers(UNDO_KEYS | egui::Modifiers::SHIFT, egui::Key::Z);
    h.run_steps(2);
    assert_eq!(h.state().station.route().waypoints(), without_bravo);
    h.key_press_modifiers(UNDO_KEYS, egui::Key::Z);
    h.run_steps(2);
    h.key_press_modifiers(UNDO_KEYS, egui::Key::Y);
    h.run_steps(2);
    assert_eq!(h.state().station.route().waypoints(), without_bravo);
}

/// The fake's emulated unit behind a switch: while `dead` is set every read and write fails (the unit
/// switched off or out of range) and no new transport opens.
struct Killable {
    fake: Fake,
    dead: Arc<AtomicBool>,
}

struct MortalUnit {
    unit: RecordingUnit,
    dead: Arc<AtomicBool>,
}

impl MortalUnit {
    fn check(&self) -> std::io::Result<()> {
        if self.dead.load(std::sync::atomic::Ordering::SeqCst) {
            Err(std::io::Error::new(std::io::ErrorKind::BrokenPipe, "unit switched off"))
        } else {
            Ok(())
        }
    }
}

impl Read for MortalUnit {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.check()?;
        self.unit.read(buf)
    }
}

impl Write for MortalUnit {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.check()?;
        self.unit.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.unit.flush()
    }
}

impl DeviceFactory for Killable {
    fn open_gps(
        &self,
        s: &GpsSourceConfig,
        r: &[Waypoint],
        out: Vec<Outbox<GpsEvent>>,
    ) -> Result<Box<dyn GpsWorker>, String> {
        self.fake.open_gps(s, r, out)
    }
    fn open_vest(&self, _s: &VestSourceConfig, out: Vec<Outbox<VestEvent>>) -> Result<VestHandle, String> {
        let (sent, dead) = (self.fake.sent.clone(), self.dead.clone());
        let connector = Box::new(move || {
            if dead.load(std::sync::atomic::Ordering::SeqCst) {
                return Err(std::io::Error::new(std::io::ErrorKind::NotFound, "no unit on the port"));
            }
            let port = EmulatedPort::new(&UnitConfig::default(), Duration::from_millis(2));
            let unit = RecordingUnit { port, codec: FrameCodec::new(), sent: sent.clone() };
            Ok(Box::new(MortalUnit { unit, dead: dead.clone() }) as Box<dyn Transport>)
        });
        // Quick reconnection attempts keep the test short.
        let settings = WorkerSettings {
            backoff: vestnav_device::backoff::Backoff::new(
                Duration::from_millis(20),
                Duration::from_millis(100),
            ),
            ..WorkerSettings::default()
        };
        VestHandle::spawn_with(connector, settings, out).map_err(|e| e.to_string())
    }
}

/// A walking wearer's fix (speed and course, so guidance has a heading), fresh.
fn walking_fix() -> Fix {
    Fix { speed_m_s: Some(1.3), course_deg: Some(90.0), ..fix(42.3562, -71.1, Duration::ZERO) }
}

/// Steps frames feeding fresh fixes until `done` holds, at most `limit`.
fn walk_until(
    h: &mut Harness<'static, Console>,
    fake: &Fake,
    limit: Duration,
    done: impl Fn(&Console) -> bool,
) {
    let end = Instant::now() + limit;
    while Instant::now() < end && !done(h.state()) {
        fake.gps(&GpsEvent::Fix(Box::new(walking_fix())));
        h.step();
        std::thread::sleep(Duration::from_millis(20));
    }
}

use vestnav_app::console::{Banner, BannerSubject, Severity};

fn banner_of(c: &Console, subject: BannerSubject) -> Option<Banner> {
    c.banners(Instant::now()).into_iter().find(|b| b.subject == subject)
}

/// Issue 15, "one unmistakable state": the vest's transport dies while guiding. The banner strip says VEST
/// LOST with what to do (derived from the vest worker's link state), guidance is on hold in the banner and
/// in its panel, and the grid is disabled; when the unit comes back the vest and guidance lines go.
#[test]
fn a_killed_vest_shows_in_the_banner_and_guidance_holds() {
    let fake = Fake::default();
    let dead = Arc::new(AtomicBool::new(false));
    let factory = Killable { fake: fake.clone(), dead: dead.clone() };
    let cfg = Config { map_tiles: false, guidance_auto: true, ..Config::default() };
    let console = Console::new(Box::new(factory), ConsoleOptions { cfg, ..ConsoleOptions::default() });
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    settle(&mut h, |c| c.station.vest.is_live());
    walk_until(&mut h, &fake, Duration::from_secs(3), |c| {
        c.station
            .guidance
            .as_ref()
            .is_some_and(|g| g.hold.is_none() && g.heading_source != HeadingSource::None)
    });
    h.run_steps(1);
    let c = h.state();
    assert!(banner_of(c, BannerSubject::Vest).is_none(), "{:?}", c.banners(Instant::now()));
    assert!(banner_of(c, BannerSubject::Guidance).is_none(), "{:?}", c.station.guidance);
    assert!(h.query_by_label_contains("VEST LOST").is_none());

    dead.store(true, std::sync::atomic::Ordering::SeqCst);
    walk_until(&mut h, &fake, Duration::from_secs(3), |c| {
        !c.station.vest.is_live() && c.station.guidance.as_ref().is_some_and(|g| g.hold.is_some())
    });
    h.run_steps(1);
    let vest = banner_of(h.state(), BannerSubject::Vest).expect("a vest line");
    assert_eq!(vest.severity, Severity::Alarm);
    assert!(vest.text.starts_with("VEST LOST: ") && vest.text.contains("Check the unit's power"), "{vest:?}");
    assert!(h.query_by_label_contains("VEST LOST: ").is_some());
    let guidance = banner_of(h.state(), BannerSubject::Guidance).expect("a guidance line");
    assert!(guidance.text.starts_with("GUIDANCE ON HOLD: no vest"), "{guidance:?}");
    assert!(h.query_by_label_contains("GUIDANCE ON HOLD: no vest").is_some());
    assert!(h.query_by_label_contains("On hold: vest").is_some(), "the Guidance panel says hold");
    assert!(h.query_by_label_contains("tactors cannot be fired").is_some());

    dead.store(false, std::sync::atomic::Ordering::SeqCst);
    walk_until(&mut h, &fake, Duration::from_secs(5), |c| {
        c.station.vest.is_live() && c.station.guidance.as_ref().is_some_and(|g| g.hold.is_none())
    });
    h.run_steps(1);
    assert!(h.state().station.vest.is_live());
    assert!(banner_of(h.state(), BannerSubject::Vest).is_none());
    assert!(banner_of(h.state(), BannerSubject::Guidance).is_none(), "{:?}", h.state().station.guidance);
    assert!(h.query_by_label_contains("VEST LOST").is_none());
    assert!(h.query_by_label_contains("GUIDANCE ON HOLD").is_none());
}

/// Disconnecting the vest by hand: the banner says so, and automatic guidance is on hold.
#[test]
fn a_disconnected_vest_shows_in_the_banner() {
    let fake = Fake::default();
    let cfg = Config { map_tiles: false, guidance_auto: true, ..Config::default() };
    let mut h = harness_with(&fake, cfg);
    h.get_by_label("Disconnect vest").click();
    settle(&mut h, |c| !c.station.vest.is_live());
    h.run_steps(1);
    assert!(h.query_by_label_contains("VEST DISCONNECTED: ").is_some());
    assert!(h.query_by_label_contains("GUIDANCE ON HOLD: no vest").is_some());
}

/// A stale fix raises the GPS line of the banner (amber, with its age and what to do); a fresh one clears it.
#[test]
fn a_stale_fix_shows_in_the_banner() {
    let fake = Fake::default();
    let cfg = Config {
        map_tiles: false,
        guidance_auto: false,
        stale_after_s: 2.0,
        lost_after_s: 30.0,
        ..Config::default()
    };
    let mut h = harness_with(&fake, cfg);
    fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1, Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fixes == 1);
    h.run_steps(1);
    assert!(banner_of(h.state(), BannerSubject::Gps).is_none());
    assert!(h.query_by_label_contains("GPS STALE").is_none());
    fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1, Duration::from_secs(3)))));
    settle(&mut h, |c| c.station.gps.fixes == 2);
    h.run_steps(1);
    let gps = banner_of(h.state(), BannerSubject::Gps).expect("a GPS line");
    assert_eq!(gps.severity, Severity::Warning);
    assert!(gps.text.starts_with("GPS STALE: last position 3 s old"), "{gps:?}");
    assert!(h.query_by_label_contains("GPS STALE: last position 3 s old").is_some());
    fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1, Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fixes == 3);
    h.run_steps(1);
    assert!(banner_of(h.state(), BannerSubject::Gps).is_none());
    assert!(h.query_by_label_contains("GPS STALE").is_none());
}

/// The View menu switches the light high-contrast theme and large text: the context's visuals and text
/// sizes change, and the choice is written to the config file.
#[test]
fn view_menu_switches_theme_and_text_size_and_remembers_them() {
    let dir = std::env::temp_dir().join(format!("vestnav-ui-theme-{}", std::process::id()));
    let path = dir.join("console.json");
    let fake = Fake::default();
    let cfg = Config { map_tiles: false, guidance_auto: false, ..Config::default() };
    let console = Console::new(
        Box::new(fake.clone()),
        ConsoleOptions { cfg, cfg_path: Some(path.clone()), ..ConsoleOptions::default() },
    );
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    h.run_steps(2);
    let body = |h: &Harness<'static, Console>| h.ctx.global_style().text_styles[&egui::TextStyle::Body].size;
    assert!(h.ctx.global_style().visuals.dark_mode);
    let body_before = body(&h);

    for option in ["Light high-contrast theme", "Large text"] {
        if h.query_by_label(option).is_none() {
            h.get_by_label("View").click();
            h.run_steps(2);
        }
        h.get_by_label(option).click();
        h.run_steps(3);
    }
    assert!(h.state().cfg.light_theme && h.state().cfg.large_text);
    let style = h.ctx.global_style();
    assert!(!style.visuals.dark_mode, "the light theme is active");
    assert_eq!(style.visuals.panel_fill, egui::Color32::WHITE);
    assert!(body(&h) >= 18.0 && body(&h) > body_before, "{} pt", body(&h));
    let (saved, err) = Config::load(&path);
    assert!(err.is_none(), "{err:?}");
    assert!(saved.light_theme && saved.large_text, "remembered in the config file");
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The GPS panel's satellite table (opened by its header) lists each satellite of the epoch with its PRN,
/// system, elevation, azimuth, SNR and use, on one row; a stale epoch is labelled last known.
#[test]
fn the_satellite_table_lists_prn_and_snr() {
    use vestnav_device::gps::Constellation;
    let fake = Fake::default();
    let cfg = Config { map_tiles: false, guidance_auto: false, stale_after_s: 2.0, ..Config::default() };
    let mut h = harness_with(&fake, cfg);
    let sat = |prn, constellation, el, az, snr, used| vestnav_device::gps::Satellite {
        prn,
        constellation,
        elevation_deg: Some(el),
        azimuth_deg: Some(az),
        snr_dbhz: Some(snr),
        used,
    };
    let with_sats = |age| Fix {
        satellites: vec![
            sat(27, Constellation::Gps, 61.0, 123.0, 47.0, true),
            sat(71, Constellation::Glonass, 12.0, 301.0, 19.0, false),
        ],
        ..fix(42.3562, -71.1, age)
    };
    fake.gps(&GpsEvent::Fix(Box::new(with_sats(Duration::ZERO))));
    settle(&mut h, |c| c.station.gps.fixes == 1);
    h.run_steps(2);
    h.get_by_label_contains("Satellites (2 in view)").click();
    h.run_steps(2);
    let prn = h.get_by_label("27").rect();
    let snr = h.get_by_label("47").rect();
    assert!((prn.center().y - snr.center().y).abs() < 2.0 && snr.left() > prn.right(), "{prn:?} {snr:?}");
    for cell in ["61°", "123°", "GLONASS", "71", "19", "301°"] {
        assert!(h.query_by_label(cell).is_some(), "{cell}");
    }
    assert_eq!(h.query_all_by_label("GPS").count(), 2, "the section header and the system cell");
    fake.gps(&GpsEvent::Fix(Box::new(with_sats(Duration::from_secs(5)))));
    settle(&mut h, |c| c.station.gps.fixes == 2);
    h.run_steps(2);
    assert!(h.query_by_label_contains("Satellites (2 in view, last known, 5 s ago)").is_some());
    assert!(h.query_by_label("27").is_some(), "the last known sky stays listed, greyed");
}

/// Issue 15: a waypoint is renamed and given typed coordinates from the list; a bad value is refused
/// with a message naming the field; the edit is one undo step. Truth: the values the test typed.
#[test]
fn rename_and_typed_coordinates_change_the_waypoint_and_can_be_undone() {
    use egui::accesskit::Role;
    let fake = Fake::default();
    let mut h = harness(&fake);
    set_route(&mut h, three_waypoints(), 0);
    h.get_all_by_label("Edit").nth(1).unwrap().click();
    h.run_steps(2);
    let field = |h: &Harness<'static, Console>, label: &str, text: &str| {
        h.get_by_role_and_label(Role::TextInput, label).set_text_value_accesskit(text);
    };
    field(&h, "Name", "Gate 2");
    field(&h, "Latitude (deg)", "95");
    field(&h, "Longitude (deg)", "-71.0987");
    h.run_steps(2);
    h.get_by_label("Apply").click();
    h.run_steps(2);
    assert!(h.query_by_label_contains("Latitude: 95 is outside [-90, 90]").is_some());
    assert_eq!(h.state().station.route().waypoints(), three_waypoints(), "nothing changed");
    field(&h, "Latitude (deg)", "42.35795");
    h.run_steps(2);
    h.get_by_label("Apply").click();
    h.run_steps(2);
    let edited =
        Waypoint { name: "Gate 2".into(), lat_deg: 42.35795, lon_deg: -71.0987, arrival_radius_m: None };
    assert_eq!(h.state().station.route().waypoints()[1], edited);
    assert!(h.query_by_label_contains("Gate 2").is_some(), "the list shows the new name");
    h.get_by_label("Undo").click();
    h.run_steps(2);
    assert_eq!(
        h.state().station.route().waypoints(),
        three_waypoints(),
        "one undo step takes back name and position"
    );
    h.get_by_label("Redo").click();
    h.run_steps(2);
    assert_eq!(h.state().station.route().waypoints()[1], edited);
}

/// Issue 15: a corrupt autosave does not stop the console: it says which file, keeps it aside, starts
/// with the demo route, and autosaves again after the next edit.
#[test]
fn a_corrupt_autosave_gives_a_message_and_the_console_still_starts() {
    let dir = test_dir("corrupt");
    let path = dir.join("route-autosave.gpx");
    std::fs::write(&path, "<gpx><rte><rtept lat=\"400\" lon=\"0\"/></rte></gpx>").unwrap();
    let fake = Fake::default();
    let mut h = harness_autosaving(&fake, &path);
    assert!(h.state().station.vest.is_live(), "the console started");
    h.run_steps(2);
    let shown = path.display().to_string();
    let messages: Vec<String> =
        h.query_all_by_label_contains("is unreadable").map(|n| n.value().unwrap_or_default()).collect();
    assert!(messages.iter().any(|m| m.contains(&shown)), "{messages:?}");
    assert_eq!(h.state().station.route().waypoints().len(), 7, "the demo route");
    let kept = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .any(|e| e.file_name().to_string_lossy().starts_with("route-autosave.gpx.corrupt-"));
    assert!(kept, "the broken file is kept aside");
    h.get_all_by_label("Del").next().unwrap().click();
    settle(&mut h, |_| path.exists());
    assert!(path.exists(), "the next edit is autosaved again");
    drop(h);
    let mut h = harness_autosaving(&Fake::default(), &path);
    h.run_steps(1);
    assert_eq!(h.state().station.route().waypoints().len(), 6);
    assert!(h.query_all_by_label_contains("is unreadable").next().is_none());
    drop(h);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Opens the pattern editor from the Vest panel.
fn open_pattern_editor(h: &mut Harness<'static, Console>) {
    h.get_by_label("Pattern editor...").click();
    h.run_steps(2);
    assert!(h.state().pattern_editor.open);
}

fn paint(h: &mut Harness<'static, Console>, tactors: &[usize]) {
    for t in tactors {
        h.get_by_label(&format!("Paint T{t}")).click();
        h.run_steps(1);
    }
}

fn set_frame_duration(h: &mut Harness<'static, Console>, frame: usize, duration_ms: u16) {
    h.get_by_role_and_label(egui::accesskit::Role::SpinButton, &format!("Frame {frame} duration"))
        .set_value_accesskit(f64::from(duration_ms));
    h.run_steps(2);
}

fn disabled(h: &Harness<'static, Console>, label: &str) -> bool {
    use egui_kittest::kittest::NodeT as _;
    h.get_by_label(label).accesskit_node().is_disabled()
}

fn plays(fake: &Fake) -> Vec<Request> {
    fake.sent().into_iter().filter(|r| matches!(r, Request::Play { .. })).collect()
}

/// Issue 15, pattern editor: what is painted on two frames is exactly what the unit is told to play.
/// Truth: the tactors and durations the test painted and typed.
#[test]
fn the_pattern_editor_previews_exactly_the_painted_frames() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    open_pattern_editor(&mut h);
    paint(&mut h, &[0, 5]);
    set_frame_duration(&mut h, 1, 300);
    h.get_by_label("Add frame").click();
    h.run_steps(2);
    paint(&mut h, &[10, 15]);
    set_frame_duration(&mut h, 2, 700);
    h.get_by_label("Preview").click();
    settle(&mut h, |_| !plays(&fake).is_empty());
    let frame = |tactors: [usize; 2], duration_ms| vestnav_core::vest::Frame {
        mask: TactorMask::from_indices(tactors),
        duration_ms,
    };
    assert_eq!(
        plays(&fake),
        vec![Request::Play { frames: vec![frame([0, 5], 300), frame([10, 15], 700)], repeats: 1 }]
    );
}

/// Issue 15: an open pattern editor stays open and usable when the Vest section is collapsed (the window is
/// the frame's, not the section's).
#[test]
fn the_pattern_editor_survives_collapsing_the_vest_section() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    open_pattern_editor(&mut h);
    h.get_by_label("Vest").click();
    h.run_steps(2);
    assert!(h.query_by_label("Pattern editor...").is_none(), "the Vest section is collapsed");
    paint(&mut h, &[3]);
    h.get_by_label("Preview").click();
    settle(&mut h, |_| !plays(&fake).is_empty());
    assert_eq!(
        plays(&fake),
        vec![Request::Play {
            frames: vec![vestnav_core::vest::Frame {
                mask: TactorMask::from_indices([3]),
                duration_ms: h.state().pattern_editor.pattern.frames[0].duration_ms,
            }],
            repeats: 1
        }]
    );
}

/// Issue 15, pattern editor: a pattern outside the limits says why and cannot be previewed. Truth: the
/// limits of `vestnav_device::wtcu::limits` (8 tactors at once, 2000 ms continuous).
#[test]
fn an_invalid_pattern_shows_the_reason_and_preview_is_disabled() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    open_pattern_editor(&mut h);
    paint(&mut h, &[0, 1, 2, 3, 4, 5, 6, 7, 8]);
    h.run_steps(1);
    assert!(h.query_by_label_contains("9 tactors at once").is_some());
    assert!(disabled(&h, "Preview"));
    assert!(disabled(&h, "Save to file"));
    paint(&mut h, &[8]);
    h.run_steps(1);
    assert!(h.query_by_label_contains("Refused").is_none());
    assert!(!disabled(&h, "Preview"));
    set_frame_duration(&mut h, 1, 2500);
    assert!(h.query_by_label_contains("2500 ms exceeds the limit of 2000 ms").is_some());
    assert!(disabled(&h, "Preview"));
    h.get_by_label("Preview").click();
    h.run_steps(2);
    std::thread::sleep(Duration::from_millis(50));
    h.run_steps(1);
    assert!(plays(&fake).is_empty(), "{:?}", fake.sent());
}

/// Issue 15, pattern editor: a pattern saved to a file loads back equal, and saving again does not replace
/// the file without asking. Truth: the pattern the test built.
#[test]
fn a_saved_pattern_loads_back_equal_and_is_not_overwritten_unasked() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    open_pattern_editor(&mut h);
    paint(&mut h, &[3, 6]);
    h.get_by_label("Duplicate frame").click();
    h.run_steps(2);
    paint(&mut h, &[6, 9]);
    let path = test_dir("pattern-editor").join("sweep.json");
    {
        let ed = &mut h.state_mut().pattern_editor;
        ed.pattern.name = "diagonal".into();
        ed.pattern.repeats = 2;
        ed.path = path.display().to_string();
    }
    h.run_steps(1);
    let saved = h.state().pattern_editor.pattern.clone();
    assert_eq!(saved.frames.len(), 2);
    assert_eq!(saved.frames[1].mask, TactorMask::from_indices([3, 9]));
    h.get_by_label("Save to file").click();
    h.run_steps(2);
    assert!(path.exists(), "{:?}", h.state().pattern_editor.message);
    let on_disk = std::fs::read_to_string(&path).unwrap();

    // Change it, save again: the file stays as it was until replacing is confirmed.
    h.state_mut().pattern_editor.pattern.repeats = 1;
    h.get_by_label("Save to file").click();
    h.run_steps(2);
    assert!(h.query_by_label("Replace file").is_some());
    assert_eq!(std::fs::read_to_string(&path).unwrap(), on_disk);
    h.get_by_label("Cancel").click();
    h.run_steps(2);
    assert_eq!(std::fs::read_to_string(&path).unwrap(), on_disk);

    h.get_by_label("Load file").click();
    h.run_steps(2);
    assert_eq!(h.state().pattern_editor.pattern, saved);

    // Confirmed, the file is replaced.
    h.state_mut().pattern_editor.pattern.repeats = 1;
    h.get_by_label("Save to file").click();
    h.run_steps(2);
    h.get_by_label("Replace file").click();
    h.run_steps(2);
    h.get_by_label("Load file").click();
    h.run_steps(2);
    assert_eq!(h.state().pattern_editor.pattern, vestnav_core::vest::Pattern { repeats: 1, ..saved });
    let _ = std::fs::remove_dir_all(path.parent().unwrap());
}

/// Issue 15, pattern editor: per-tactor intensity goes to the unit as `SET_INTENSITY` before the PLAY.
/// Truth: the levels the test set.
#[test]
fn intensity_is_sent_before_the_play() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    open_pattern_editor(&mut h);
    paint(&mut h, &[1, 2]);
    h.state_mut().pattern_editor.levels[2] = 80;
    h.run_steps(1);
    h.get_by_label("Preview").click();
    settle(&mut h, |_| !plays(&fake).is_empty());
    assert_eq!(
        fake.sent(),
        vec![
            Request::SetIntensity { mask: TactorMask::from_indices([1]), level: 255 },
            Request::SetIntensity { mask: TactorMask::from_indices([2]), level: 80 },
            Request::Play {
                frames: vec![vestnav_core::vest::Frame {
                    mask: TactorMask::from_indices([1, 2]),
                    duration_ms: 500
                }],
                repeats: 1
            },
        ]
    );
}

/// A fix of [`fix`] whose receiver UTC time of day is `tod_s` seconds after midnight, moving at `speed`.
fn timed_fix(lat: f64, lon: f64, tod_s: f64, speed_m_s: Option<f64>) -> Fix {
    let secs = tod_s.floor();
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss, reason = "a time of day in a test")]
    let time_of_day =
        chrono::NaiveTime::from_num_seconds_from_midnight_opt(secs as u32, ((tod_s - secs) * 1e9) as u32);
    Fix { time_of_day, speed_m_s, ..fix(lat, lon, Duration::ZERO) }
}

/// Sends `f` and waits until the console has taken it (the `n`-th positioned fix).
fn send_fix(h: &mut Harness<'static, Console>, fake: &Fake, f: Fix, n: u64) {
    fake.gps(&GpsEvent::Fix(Box::new(f)));
    settle(h, |c| c.station.gps.fixes == n);
}

/// A point `north_m` metres north of `(lat, lon)` (spherical, enough for tens of metres).
fn north_of(lat: f64, lon: f64, north_m: f64) -> (f64, f64) {
    (lat + (north_m / 6_371_000.0).to_degrees(), lon)
}

/// Fault 7 of issue 15: a drift test fed fixes whose receiver times span 200 s, arriving within a few
/// seconds (a fast replay), reports 200 s and says it is on the receiver's clock. Truth: the receiver
/// times the test set, and the wall clock measured around the feed.
#[test]
fn the_drift_test_runs_on_the_receiver_clock() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Field tests").click();
    h.run_steps(2);
    h.get_by_label("duration target").set_value_accesskit(5.0);
    h.run_steps(2);
    let (lat, lon) = (42.3575, -71.1010);
    let tod0 = 12.0 * 3600.0;
    send_fix(&mut h, &fake, timed_fix(lat, lon, tod0 - 1.0, Some(0.0)), 1);
    h.run_steps(1);
    h.get_by_label("Start drift test").click();
    h.run_steps(2);
    let started = Instant::now();
    let (n, span_s) = (201_u64, 200.0);
    for k in 0..n {
        #[allow(clippy::cast_precision_loss, reason = "k < 201")]
        let tod = tod0 + span_s * k as f64 / (n - 1) as f64;
        send_fix(&mut h, &fake, timed_fix(lat, lon, tod, Some(0.0)), k + 2);
    }
    let wall_s = started.elapsed().as_secs_f64();
    assert!(wall_s < 20.0, "the fixes arrived within {wall_s:.1} s");
    h.run_steps(2);
    let want = format!("{n} fixes over {span_s:.0} s");
    assert!(h.query_by_label(&want).is_some(), "{want:?} shown");
    assert!(h.query_by_label_contains("time base: receiver UTC").is_some());
    assert!(h.query_by_label_contains("walking speed").is_none(), "a still receiver");
}

/// Fault 7 of issue 15: a receiver carried at walking speed during a stationary drift test raises the
/// warning. Truth: the 1.3 m/s walk the test feeds.
#[test]
fn a_walking_receiver_warns_during_the_drift_test() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Field tests").click();
    h.run_steps(2);
    let (lat, lon) = (42.3575, -71.1010);
    send_fix(&mut h, &fake, timed_fix(lat, lon, 100.0, Some(0.0)), 1);
    h.run_steps(1);
    h.get_by_label("Start drift test").click();
    h.run_steps(2);
    let mut n = 1;
    for k in 0..5 {
        n += 1;
        send_fix(&mut h, &fake, timed_fix(lat, lon, 101.0 + f64::from(k), Some(0.0)), n);
    }
    h.run_steps(1);
    assert!(h.query_by_label_contains("walking speed").is_none(), "still so far");
    for k in 1..=8 {
        n += 1;
        let (la, lo) = north_of(lat, lon, 1.3 * f64::from(k));
        send_fix(&mut h, &fake, timed_fix(la, lo, 105.0 + f64::from(k), Some(1.3)), n);
    }
    h.run_steps(2);
    assert!(
        h.query_by_label_contains("moving at 1.3 m/s (walking speed)").is_some(),
        "the walk's speed shown"
    );
}

/// Fault 7 of issue 15: while a cone test runs the mark count is a live count, not a "missed or marked
/// twice" alarm; finishing with fewer marks than cones gives the verdict. Truth: 2 marks for 10 cones.
#[test]
fn the_cone_test_does_not_cry_missed_while_running() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Field tests").click();
    h.run_steps(2);
    h.get_by_label("Cone test").click();
    h.run_steps(2);
    let (lat, lon) = (42.3575, -71.1010);
    send_fix(&mut h, &fake, timed_fix(lat, lon, 200.0, Some(1.5)), 1);
    h.run_steps(1);
    h.get_by_label("Start cone test").click();
    h.run_steps(2);
    for (k, north_m) in [0.0, 10.0].into_iter().enumerate() {
        let (la, lo) = north_of(lat, lon, north_m);
        #[allow(clippy::cast_precision_loss, reason = "k < 2")]
        send_fix(&mut h, &fake, timed_fix(la, lo, 201.0 + 7.0 * k as f64, Some(1.5)), k as u64 + 2);
        h.run_steps(1);
        h.get_by_label_contains(&format!("Mark cone {}", k + 1)).click();
        h.run_steps(2);
    }
    assert!(h.query_by_label("2 of 10 cones marked").is_some(), "the live count");
    assert!(h.query_by_label_contains("missed").is_none(), "no alarm while running");
    h.get_by_label("Finish").click();
    h.run_steps(2);
    assert!(h.query_by_label_contains("2 marks for 10 cones").is_some(), "the verdict once finished");
}

/// Issue 15 fault 5: at 1024x680 (a small laptop) nothing of any tab lies beyond the window's right edge,
/// STOP ALL is on screen, and the Two-point view fits the width.
#[test]
fn every_tab_fits_a_1024_by_680_window() {
    use egui_kittest::kittest::{NodeT as _, by};
    let fake = Fake::default();
    let cfg = Config { map_tiles: false, guidance_auto: false, ..Config::default() };
    let mut h = harness_sized(&fake, cfg, egui::vec2(1024.0, 680.0));
    let mut offenders = Vec::new();
    let mut check = |h: &mut Harness<'static, Console>, what: &str| {
        for _ in 0..30 {
            h.step();
            std::thread::sleep(Duration::from_millis(20));
        }
        for node in h.query_all(by().predicate(|n| n.label().is_some_and(|l| !l.is_empty()))) {
            let r = node.rect();
            if r.right() > 1024.5 && r.width() > 0.0 {
                offenders.push(format!(
                    "{what}: {:?} {:?} ends at x = {}",
                    node.accesskit_node().role(),
                    node.accesskit_node().label(),
                    r.right()
                ));
            }
        }
        if std::env::var("VESTNAV_DEBUG_LAYOUT").is_ok() {
            for node in h.query_all(by().predicate(|n| n.label().is_some_and(|l| !l.is_empty()))) {
                eprintln!(
                    "{what}: {:?} {:?} {:?}",
                    node.accesskit_node().role(),
                    node.accesskit_node().label(),
                    node.rect()
                );
            }
        }
        // The side panel's splitter: the tall one of the panels' resize handles.
        let side = h
            .query_all_by_label("Resize panel")
            .map(|n| n.rect())
            .find(|r| r.height() > r.width())
            .expect("the side panel's splitter");
        assert!(side.left() <= 400.0, "{what}: the side panel takes {} of 1024 points", side.left());
        let stop = h.get_by_label_contains("STOP ALL").rect();
        assert!(stop.bottom() <= 680.0 && stop.right() <= 1024.0, "{what}: STOP ALL at {stop:?}");
    };
    check(&mut h, "Map");
    h.get_by_label("Simulation").click();
    h.run_steps(2);
    for view in ["Tactor model", "Damping sweep", "Skin waves", "Two-point"] {
        h.get_by_label(view).click();
        check(&mut h, view);
    }
    h.get_by_label("Field tests").click();
    h.run_steps(2);
    check(&mut h, "Field tests");
    assert!(offenders.is_empty(), "{}", offenders.join("\n"));
}

/// Issue 13: the error figure on screen says whose it is — the receiver's own estimate (UBX hAcc here)
/// when it sends one, else the DOP model.
#[test]
fn the_error_estimate_names_its_source() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Connect GPS").click();
    h.run_steps(2);
    let mut f = fix(42.0, -71.0, Duration::ZERO);
    f.error = Some(ErrorEstimate { horizontal_m: 1.25, vertical_m: Some(2.0), source: ErrorSource::Ubx });
    fake.gps(&GpsEvent::Fix(Box::new(f)));
    settle(&mut h, |c| c.station.gps.fixes >= 1);
    h.run_steps(2);
    assert!(h.query_by_label_contains("1.2 m · UBX hAcc").is_some());
    let mut f = fix(42.0, -71.0, Duration::ZERO);
    f.error = Some(ErrorEstimate {
        horizontal_m: 7.5,
        vertical_m: None,
        source: ErrorSource::DopModel { uere_m: vestnav_device::gps::UERE_M },
    });
    fake.gps(&GpsEvent::Fix(Box::new(f)));
    settle(&mut h, |c| c.station.gps.fixes >= 2);
    h.run_steps(2);
    assert!(h.query_by_label_contains("7.5 m · HDOP x 5 m").is_some());
}
