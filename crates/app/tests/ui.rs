//! The console driven by label with `egui_kittest`, devices injected.
#![allow(clippy::unwrap_used)]

use std::sync::{Arc, Mutex};

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use vestnav_app::config::{Config, GpsSourceConfig, VestSourceConfig};
use vestnav_app::console::{Console, ConsoleOptions, GpsAlarm};
use vestnav_app::devices::{DeviceFactory, VestLink, Worker};
use vestnav_app::model::{FixMode, GpsEvent, GpsFix, LinkState, Outbox, VestCommand, VestEvent};
use vestnav_app::route::Waypoint;
use vestnav_app::session_log::LogEntry;
use vestnav_core::vest::TactorMask;

/// A vest that records every command and answers like a unit would: ack, then the tactors it turned on.
#[derive(Default)]
struct RecordingVest {
    sent: Mutex<Vec<VestCommand>>,
    out: Mutex<Option<Outbox<VestEvent>>>,
}

impl VestLink for RecordingVest {
    fn send(&self, c: VestCommand) -> Result<(), String> {
        let on = match &c {
            VestCommand::Fire { mask, .. } => *mask,
            VestCommand::Play(p) => p.frames.first().map_or(TactorMask::NONE, |f| f.mask),
            VestCommand::StopAll => TactorMask::NONE,
        };
        self.sent.lock().unwrap().push(c);
        if let Some(o) = self.out.lock().unwrap().as_ref() {
            o.send(VestEvent::Ack { what: "ok".into() });
            o.send(VestEvent::TactorsOn(on));
        }
        Ok(())
    }
    fn close(&self) {}
}

struct Idle;
impl Worker for Idle {
    fn stop(&mut self) {}
}

#[derive(Default, Clone)]
struct Fake {
    vest: Arc<RecordingVest>,
    gps: Arc<Mutex<Option<Outbox<GpsEvent>>>>,
}

impl DeviceFactory for Fake {
    fn open_gps(
        &self,
        _s: &GpsSourceConfig,
        _r: &[Waypoint],
        out: Outbox<GpsEvent>,
    ) -> Result<Box<dyn Worker>, String> {
        out.send(GpsEvent::State(LinkState::Live));
        *self.gps.lock().unwrap() = Some(out);
        Ok(Box::new(Idle))
    }
    fn open_vest(&self, _s: &VestSourceConfig, out: Outbox<VestEvent>) -> Result<Arc<dyn VestLink>, String> {
        out.send(VestEvent::State(LinkState::Live));
        *self.vest.out.lock().unwrap() = Some(out);
        Ok(self.vest.clone())
    }
}

fn harness(fake: &Fake) -> Harness<'static, Console> {
    let cfg = Config { map_tiles: false, guidance_auto: false, ..Config::default() };
    let console = Console::new(
        Box::new(fake.clone()),
        ConsoleOptions { cfg, cfg_path: None, log_dir: None, waker: None },
    );
    Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console)
}

/// Steps frames until `done` holds (workers run on their own threads), at most ~2 s.
fn settle(h: &mut Harness<'static, Console>, done: impl Fn(&Console) -> bool) {
    for _ in 0..200 {
        h.step();
        if done(h.state()) {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
}

fn fix(lat: f64, lon: f64) -> GpsFix {
    GpsFix { lat_deg: lat, lon_deg: lon, mode: FixMode::Fix3d, error_m: Some(3.0), ..GpsFix::default() }
}

#[test]
fn clicking_a_tactor_fires_it_and_shows_it_on() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("T5").click();
    settle(&mut h, |c| !c.vest.tactors_on.is_empty());
    let sent = fake.vest.sent.lock().unwrap().clone();
    assert_eq!(sent, vec![VestCommand::Fire { mask: TactorMask::from_indices([5]), on_ms: 500 }]);
    assert_eq!(h.state().vest.tactors_on, TactorMask::from_indices([5]));
}

#[test]
fn stop_all_button_and_key() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("STOP ALL").click();
    h.run_steps(2);
    h.key_press(egui::Key::Escape);
    h.run_steps(2);
    let sent = fake.vest.sent.lock().unwrap().clone();
    assert_eq!(sent, vec![VestCommand::StopAll, VestCommand::StopAll]);
    assert!(!h.state().cfg.guidance_auto);
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
    assert!(h.state().vest.select_mode);
    assert_eq!(h.state().vest.selected, TactorMask::from_indices([0, 3, 12]));
    h.get_by_label("Fire selected (3)").click();
    h.run_steps(1);
    let sent = fake.vest.sent.lock().unwrap().clone();
    assert_eq!(sent, vec![VestCommand::Fire { mask: TactorMask::from_indices([0, 3, 12]), on_ms: 500 }]);
}

#[test]
fn add_waypoint_with_the_mouse() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    let before = h.state().map.waypoints.len();
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
    let wps = &h.state().map.waypoints;
    assert_eq!(wps.len(), before + 1);
    let w = wps.last().unwrap();
    assert!((w.lat_deg - 42.357).abs() < 0.01 && (w.lon_deg + 71.10).abs() < 0.02, "{w:?}");
}

#[test]
fn a_fix_shows_and_losing_it_raises_the_alarm() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    let gps = fake.gps.lock().unwrap().clone().unwrap();
    gps.send(GpsEvent::Fix(fix(42.3562, -71.1)));
    settle(&mut h, |c| c.gps.fix.is_some());
    assert!(h.query_by_label_contains("42.3562000°").is_some());
    assert!(h.query_by_label_contains("GPS FIX LOST").is_none());
    // No more fixes: kittest's clock runs one step_dt per frame; step past the stale and lost limits.
    let now = h.ctx.input(|i| i.time);
    let lost = h.state().cfg.lost_after_s;
    let steps = ((lost + 1.0) / f64::from(h.ctx.input(|i| i.stable_dt).max(1e-3))).ceil() as usize;
    h.run_steps(steps.min(2000));
    let later = h.ctx.input(|i| i.time);
    assert!(later - now > lost, "clock advanced only {}", later - now);
    assert!(matches!(h.state().gps_alarm(later), Some(GpsAlarm::Lost { .. })));
    assert!(h.query_by_label_contains("GPS FIX LOST").is_some());
    // A receiver that reports "no fix" raises it at once.
    gps.send(GpsEvent::Fix(fix(42.3562, -71.1)));
    settle(&mut h, |c| c.gps.fixes == 2);
    assert!(h.query_by_label_contains("GPS FIX LOST").is_none());
    gps.send(GpsEvent::Fix(GpsFix { mode: FixMode::NoFix, ..GpsFix::default() }));
    settle(&mut h, |c| c.gps.fix.as_ref().is_some_and(|f| f.mode == FixMode::NoFix));
    assert!(h.query_by_label_contains("receiver reports no fix").is_some());
}

/// The console on the real device layer: the device crate's emulated WTCU and the built-in simulator.
fn real_harness(log_dir: Option<std::path::PathBuf>) -> Harness<'static, Console> {
    let cfg = Config { map_tiles: false, guidance_auto: false, ..Config::default() };
    let console = Console::new(
        Box::new(vestnav_app::hardware::Hardware),
        ConsoleOptions { cfg, cfg_path: None, log_dir, waker: None },
    );
    Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console)
}

#[test]
fn emulated_vest_reports_the_clicked_tactor_on_then_stop_all_clears_it() {
    let dir = std::env::temp_dir().join(format!("vestnav-ui-{}", std::process::id()));
    let mut h = real_harness(Some(dir.clone()));
    settle(&mut h, |c| c.vest.link == LinkState::Live);
    assert_eq!(h.state().vest.link, LinkState::Live, "emulated vest did not come up");
    h.get_by_label("T9").click();
    // The orange state comes from the unit's acks/status, not from what we sent.
    settle(&mut h, |c| c.vest.tactors_on.contains(9));
    assert_eq!(h.state().vest.tactors_on, TactorMask::from_indices([9]));
    h.get_by_label("STOP ALL").click();
    settle(&mut h, |c| c.vest.tactors_on.is_empty());
    assert!(h.state().vest.tactors_on.is_empty());
    // The simulator walks the demo route: a fix arrives within about a second.
    settle(&mut h, |c| c.gps.fix.is_some());
    assert!(h.state().gps.fix.as_ref().unwrap().has_position());
    let log_path = h.state().log_path().unwrap().to_path_buf();
    drop(h);
    std::thread::sleep(std::time::Duration::from_millis(300));
    let log = vestnav_app::session_log::read_log(&log_path).unwrap();
    assert!(
        log.records
            .iter()
            .any(|r| matches!(&r.entry, LogEntry::Command { command: VestCommand::Fire { .. }, .. }))
    );
    assert!(
        log.records
            .iter()
            .any(|r| matches!(&r.entry, LogEntry::Command { command: VestCommand::StopAll, .. }))
    );
    assert!(log.records.iter().any(|r| matches!(&r.entry, LogEntry::Ack { .. })));
    assert!(log.records.iter().any(|r| matches!(&r.entry, LogEntry::Fix { .. })));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn nmea_replay_shows_the_fix_then_the_no_fix_alarm() {
    let mut h = real_harness(None);
    settle(&mut h, |c| c.gps.fix.is_some());
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
        let p = &mut h.state_mut().gps.picker;
        assert_eq!(p.kind, vestnav_app::gps_panel::SourceKind::Replay);
        p.replay_path = file.to_owned();
        p.replay_speed = 10.0;
    }
    h.get_by_label("Connect GPS").click();
    // Epoch 12:00:04 is the last with a position (42.3562667 N, independent: 42° 21.3760').
    settle(&mut h, |c| {
        c.gps.fix.as_ref().is_some_and(|f| f.time_utc.as_deref() == Some("2026-11-22T12:00:04.000Z"))
    });
    let f = h.state().gps.fix.clone().unwrap();
    assert!((f.lat_deg - (42.0 + 21.376 / 60.0)).abs() < 1e-9, "{}", f.lat_deg);
    assert!((f.lon_deg + 71.1).abs() < 1e-9);
    assert!(h.query_by_label_contains("-71.1000000°").is_some());
    // Then the receiver reports no fix: the alarm is raised at once.
    settle(&mut h, |c| c.gps.fix.as_ref().is_some_and(|f| !f.has_position()));
    h.run_steps(1);
    assert!(h.query_by_label_contains("GPS FIX LOST: receiver reports no fix").is_some());
    assert!(h.query_by_label_contains("GPS: FIX LOST").is_some());
    assert_eq!(
        h.state().cfg.gps,
        GpsSourceConfig::Replay { path: file.into(), speed: 10.0 },
        "the chosen source is remembered in the config"
    );
}
