//! The console in a test harness with injected devices (the vest's emulated unit behind a transport that
//! records every command): the helpers the console UI tests share.

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use std::io::{Read, Write};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use vestnav_app::config::{Config, GpsSourceConfig, VestSourceConfig};
use vestnav_app::console::{Console, ConsoleOptions};
use vestnav_core::vest::TactorMask;
use vestnav_device::gps::{ErrorEstimate, ErrorSource, Fix, FixMode, GpsEvent};
use vestnav_device::outbox::Outbox;
use vestnav_device::sim::CompassSetup;
use vestnav_device::wtcu::codec::{FrameCodec, WireCodec};
use vestnav_device::wtcu::emulator::UnitConfig;
use vestnav_device::wtcu::worker::{EmulatedPort, Transport, WorkerSettings};
use vestnav_device::wtcu::{Request, VestEvent, VestHandle};
use vestnav_station::devices::{DeviceFactory, GpsWorker};
use vestnav_station::route::Waypoint;

/// The emulated unit behind a transport that also records every command it was sent (decoded with the
/// unit-side codec): the device side of the real protocol, seen from the vest.
pub struct RecordingUnit {
    pub port: EmulatedPort,
    pub codec: FrameCodec,
    pub sent: Arc<Mutex<Vec<Request>>>,
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
pub struct Fake {
    pub sent: Arc<Mutex<Vec<Request>>>,
    pub gps: super::Devices,
    /// The emulated unit's magnetometer (none: the unit offers no heading, and the console sends none of
    /// the v2 heading requests).
    pub compass: Option<CompassSetup>,
}

impl Fake {
    pub fn sent(&self) -> Vec<Request> {
        self.sent.lock().unwrap().clone()
    }

    pub fn gps(&self, ev: &GpsEvent) {
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

pub fn harness(fake: &Fake) -> Harness<'static, Console> {
    harness_with(fake, Config { map_tiles: false, guidance_auto: false, ..Config::default() })
}

pub fn harness_with(fake: &Fake, cfg: Config) -> Harness<'static, Console> {
    harness_sized(fake, cfg, egui::vec2(1400.0, 900.0))
}

/// The console in a window of `size`, once the emulated unit is live.
pub fn harness_sized(fake: &Fake, cfg: Config, size: egui::Vec2) -> Harness<'static, Console> {
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
pub fn settle(h: &mut Harness<'static, Console>, done: impl Fn(&Console) -> bool) {
    for _ in 0..200 {
        h.step();
        if done(h.state()) {
            return;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// A 3D fix whose bytes arrived `age` ago.
pub fn fix(lat: f64, lon: f64, age: Duration) -> Fix {
    Fix {
        lat_deg: Some(lat),
        lon_deg: Some(lon),
        mode: Some(FixMode::Fix3D),
        error: Some(ErrorEstimate { horizontal_m: 3.0, vertical_m: None, source: ErrorSource::Gst }),
        received_at: Some(Instant::now().checked_sub(age).unwrap()),
        ..Fix::default()
    }
}

pub fn on(c: &Console) -> TactorMask {
    c.station.vest.tactors_on.unwrap_or(TactorMask::NONE)
}

/// The console on the real device layer: the device crate's emulated WTCU and the built-in simulator.
pub fn real_harness(log_dir: Option<std::path::PathBuf>) -> Harness<'static, Console> {
    let cfg = Config { map_tiles: false, guidance_auto: false, ..Config::default() };
    let console = Console::new(
        Box::new(vestnav_station::hardware::Hardware::default()),
        ConsoleOptions { cfg, log_dir, ..ConsoleOptions::default() },
    );
    Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console)
}

/// Great-circle distance on a sphere of the WGS84 mean radius [m] (haversine): the test's own geometry.
pub fn haversine_m(a: (f64, f64), b: (f64, f64)) -> f64 {
    let (la1, lo1, la2, lo2) = (a.0.to_radians(), a.1.to_radians(), b.0.to_radians(), b.1.to_radians());
    let h = ((la2 - la1) / 2.0).sin().powi(2) + la1.cos() * la2.cos() * ((lo2 - lo1) / 2.0).sin().powi(2);
    2.0 * 6_371_008.8 * h.sqrt().asin()
}

/// The console with the route autosaved to (and restored from) `autosave`.
pub fn harness_autosaving(fake: &Fake, autosave: &std::path::Path) -> Harness<'static, Console> {
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
pub fn test_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("vestnav-ui-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Three waypoints with coordinates the tests compare against.
pub fn three_waypoints() -> Vec<Waypoint> {
    vec![
        Waypoint { name: "Alpha".into(), lat_deg: 42.3571, lon_deg: -71.1012, arrival_radius_m: None },
        Waypoint { name: "Bravo".into(), lat_deg: 42.3577, lon_deg: -71.1003, arrival_radius_m: None },
        Waypoint { name: "Charlie".into(), lat_deg: 42.3581, lon_deg: -71.0995, arrival_radius_m: None },
    ]
}

pub fn set_route(h: &mut Harness<'static, Console>, waypoints: Vec<Waypoint>, next: usize) {
    let c = h.state_mut();
    c.station.route_mut().replace("Test loop".into(), waypoints).unwrap();
    c.station.route_mut().set_next(next);
    h.run_steps(2);
}

pub const UNDO_KEYS: egui::Modifiers = egui::Modifiers { ctrl: true, command: true, ..egui::Modifiers::NONE };

/// The fake's emulated unit behind a switch: while `dead` is set every read and write fails (the unit
/// switched off or out of range) and no new transport opens.
pub struct Killable {
    pub fake: Fake,
    pub dead: Arc<AtomicBool>,
}

pub struct MortalUnit {
    pub unit: RecordingUnit,
    pub dead: Arc<AtomicBool>,
}

impl MortalUnit {
    pub fn check(&self) -> std::io::Result<()> {
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
pub fn walking_fix() -> Fix {
    Fix { speed_m_s: Some(1.3), course_deg: Some(90.0), ..fix(42.3562, -71.1, Duration::ZERO) }
}

/// Steps frames feeding fresh fixes until `done` holds, at most `limit`.
pub fn walk_until(
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

pub use vestnav_app::console::{Banner, BannerSubject};

pub fn banner_of(c: &Console, subject: BannerSubject) -> Option<Banner> {
    c.banners(Instant::now()).into_iter().find(|b| b.subject == subject)
}

/// Opens the pattern editor from the Vest panel.
pub fn open_pattern_editor(h: &mut Harness<'static, Console>) {
    h.get_by_label("Pattern editor...").click();
    h.run_steps(2);
    assert!(h.state().pattern_editor.open);
}

pub fn paint(h: &mut Harness<'static, Console>, tactors: &[usize]) {
    for t in tactors {
        h.get_by_label(&format!("Paint T{t}")).click();
        h.run_steps(1);
    }
}

pub fn set_frame_duration(h: &mut Harness<'static, Console>, frame: usize, duration_ms: u16) {
    h.get_by_role_and_label(egui::accesskit::Role::SpinButton, &format!("Frame {frame} duration"))
        .set_value_accesskit(f64::from(duration_ms));
    h.run_steps(2);
}

pub fn disabled(h: &Harness<'static, Console>, label: &str) -> bool {
    use egui_kittest::kittest::NodeT as _;
    h.get_by_label(label).accesskit_node().is_disabled()
}

pub fn plays(fake: &Fake) -> Vec<Request> {
    fake.sent().into_iter().filter(|r| matches!(r, Request::Play { .. })).collect()
}

/// A fix of [`fix`] whose receiver UTC time of day is `tod_s` seconds after midnight, moving at `speed`.
pub fn timed_fix(lat: f64, lon: f64, tod_s: f64, speed_m_s: Option<f64>) -> Fix {
    let secs = tod_s.floor();
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss, reason = "a time of day in a test")]
    let time_of_day =
        chrono::NaiveTime::from_num_seconds_from_midnight_opt(secs as u32, ((tod_s - secs) * 1e9) as u32);
    Fix { time_of_day, speed_m_s, ..fix(lat, lon, Duration::ZERO) }
}

/// Sends `f` and waits until the console has taken it (the `n`-th positioned fix).
pub fn send_fix(h: &mut Harness<'static, Console>, fake: &Fake, f: Fix, n: u64) {
    fake.gps(&GpsEvent::Fix(Box::new(f)));
    settle(h, |c| c.station.gps.fixes == n);
}

/// A point `north_m` metres north of `(lat, lon)` (spherical, enough for tens of metres).
pub fn north_of(lat: f64, lon: f64, north_m: f64) -> (f64, f64) {
    (lat + (north_m / 6_371_000.0).to_degrees(), lon)
}
