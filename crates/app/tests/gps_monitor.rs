//! The GPS panel's raw NMEA monitor and Record toggle, driven by label with `egui_kittest`; the GPS
//! source is the test's fake (its events are handed to every consumer the console gave it).
#![allow(clippy::unwrap_used)]

mod common;

use std::time::{Duration, Instant};

use egui::accesskit::Role;
use egui_kittest::kittest::Queryable as _;
use vestnav_device::gps::{GpsEvent, RawLine};

/// A GGA as a receiver sends it (57° 09.8067' N, 2° 07.2822' W), checksum included.
const GGA: &str = "$GPGGA,110518.000,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.2,M,,0000*77";
const RMC: &str = "$GPRMC,110518.000,A,5709.8067,N,00207.2822,W,0.5,54.7,230326,,,A*4C";

fn raw(text: &str) -> GpsEvent {
    GpsEvent::Raw(RawLine { text: text.into(), received_at: Instant::now() })
}

#[test]
fn the_monitor_lists_raw_sentences_and_record_writes_a_replayable_file() {
    let devices = common::Devices::default();
    let mut h = common::console(&devices);
    if !h.state().gps_connected() {
        h.get_by_label("Connect GPS").click();
        h.run_steps(2);
    }
    let folder = std::env::temp_dir().join(format!("vestnav-gps-monitor-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&folder);
    h.state_mut().gps_ui.recording.folder = folder.display().to_string();
    h.run_steps(2);

    h.get_by_label("Record NMEA").click();
    assert!(common::settle(&mut h, |c| c.gps_ui.recording.tap.is_recording()), "Record started a recording");
    devices.gps(&raw(GGA));
    devices.gps(&raw(RMC));
    assert!(common::settle(&mut h, |c| c.gps_ui.monitor.lines.len() == 2), "the monitor got both lines");

    // The monitor, opened, lists each sentence with its arrival time.
    h.get_by_label_contains("NMEA monitor").click();
    h.run_steps(3);
    assert!(h.query_by_label_contains(GGA).is_some(), "the GGA is listed");
    assert!(h.query_by_label_contains(RMC).is_some(), "the RMC is listed");
    // Filtered by type: only the RMC remains.
    h.get_by_role_and_label(Role::TextInput, "Filter").set_text_value_accesskit("RMC");
    h.run_steps(3);
    assert!(h.query_by_label_contains(GGA).is_none(), "the filter hides the GGA");
    assert!(h.query_by_label_contains(RMC).is_some(), "the filter keeps the RMC");

    // The status names the file and counts what was written.
    assert!(h.query_by_label_contains("2 sentences, ").is_some(), "the status counts the sentences");
    h.get_by_label("Stop recording").click();
    assert!(common::settle(&mut h, |c| !c.gps_ui.recording.tap.is_recording()), "Stop ended the recording");
    h.run_steps(2);

    let files: Vec<_> = std::fs::read_dir(&folder).unwrap().map(|e| e.unwrap().path()).collect();
    assert_eq!(files.len(), 1, "{files:?}");
    let name = files[0].file_name().unwrap().to_string_lossy().into_owned();
    assert!(name.starts_with("vestnav-gps-"), "{name}");
    assert_eq!(files[0].extension().and_then(|e| e.to_str()), Some("nmea"));
    assert!(h.query_by_label_contains(&name).is_some(), "the status names the file");
    let text = std::fs::read_to_string(&files[0]).unwrap();
    assert!(text.starts_with("$PVNAV,TS,"), "{text}");
    assert!(text.contains(&format!("{GGA}\r\n{RMC}\r\n")), "{text}");
    // What was recorded decodes to the epoch the sentences describe.
    let (fixes, _) = vestnav_device::gps::decode_file(&files[0]).unwrap();
    assert_eq!(fixes.len(), 1);
    assert!((fixes[0].lat_deg.unwrap() - 57.163_445).abs() < 1e-6);
    assert!((fixes[0].lon_deg.unwrap() + 2.121_37).abs() < 1e-6);

    // Recording again never replaces the file: a second one appears.
    h.get_by_label("Record NMEA").click();
    h.run_steps(2);
    std::thread::sleep(Duration::from_millis(10));
    h.get_by_label("Stop recording").click();
    h.run_steps(2);
    assert_eq!(std::fs::read_dir(&folder).unwrap().count(), 2);
    assert_eq!(std::fs::read_to_string(&files[0]).unwrap(), text);
    let _ = std::fs::remove_dir_all(&folder);
}

/// A factory whose GPS is the device crate's real replay source on one file; the vest is the emulator.
#[derive(Clone)]
struct ReplayDevices {
    file: std::path::PathBuf,
    vest: common::Devices,
}

impl vestnav_station::devices::DeviceFactory for ReplayDevices {
    fn open_gps(
        &self,
        _s: &vestnav_app::config::GpsSourceConfig,
        _r: &[vestnav_station::route::Waypoint],
        out: Vec<vestnav_device::outbox::Outbox<GpsEvent>>,
    ) -> Result<Box<dyn vestnav_station::devices::GpsWorker>, String> {
        let cfg = vestnav_device::gps::SourceConfig::Replay {
            path: self.file.clone(),
            speed: vestnav_device::gps::ReplaySpeed::Times(1.0),
        };
        Ok(Box::new(vestnav_device::gps::GpsSource::spawn(cfg, out).map_err(|e| e.to_string())?))
    }
    fn open_vest(
        &self,
        s: &vestnav_app::config::VestSourceConfig,
        out: Vec<vestnav_device::outbox::Outbox<vestnav_device::wtcu::VestEvent>>,
    ) -> Result<vestnav_device::wtcu::VestHandle, String> {
        self.vest.open_vest(s, out)
    }
}

/// A replay shows its controls: Pause holds the source, the time shows the file's 20 s span, and a seek
/// made through the control is announced in the panel.
#[test]
fn a_replay_can_be_paused_and_shows_its_span() {
    let mut text = String::new();
    for k in 0..21 {
        let body = format!("GPGGA,1200{k:02}.00,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.2,M,,");
        text += &vestnav_device::gps::framing::with_checksum(&body);
    }
    let file = std::env::temp_dir().join(format!("vestnav-gps-monitor-replay-{}.nmea", std::process::id()));
    std::fs::write(&file, &text).unwrap();
    let devices = ReplayDevices { file: file.clone(), vest: common::Devices::default() };
    let cfg = vestnav_app::config::Config {
        map_tiles: false,
        guidance_auto: false,
        follow: false,
        ..vestnav_app::config::Config::default()
    };
    let console = vestnav_app::console::Console::new(
        Box::new(devices.clone()),
        vestnav_app::console::ConsoleOptions { cfg, ..vestnav_app::console::ConsoleOptions::default() },
    );
    let mut h = egui_kittest::Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut vestnav_app::console::Console| c.ui(ui), console);
    h.run_steps(3);
    if !h.state().gps_connected() {
        h.get_by_label("Connect GPS").click();
    }
    assert!(common::settle(&mut h, |c| !c.gps_ui.monitor.lines.is_empty()), "the replay's sentences arrive");
    assert!(h.query_by_label_contains("/ 0:20").is_some(), "the total time is the file's 20 s");
    h.get_by_label("Pause replay").click();
    h.run_steps(2);
    let ctl = h.state().gps_replay().unwrap();
    assert!(ctl.is_paused());
    assert!(h.query_by_label("Resume replay").is_some());
    ctl.seek_fraction(0.5);
    assert!(
        common::settle(&mut h, |c| c.station.gps.notice.as_deref().is_some_and(|n| n.contains("0:10.0"))),
        "the seek to the middle (10 s) is announced"
    );
    h.get_by_label("Resume replay").click();
    h.run_steps(2);
    assert!(!ctl.is_paused());
    h.state_mut().disconnect_gps();
    let _ = std::fs::remove_file(&file);
}

/// The monitor shows a long sentence on one line at body size (issue 23, item 11: it was small and
/// wrapped into fragments), scrolling sideways instead.
#[test]
fn a_long_sentence_is_one_legible_line() {
    let devices = common::Devices::default();
    let mut h = common::console(&devices);
    if !h.state().gps_connected() {
        h.get_by_label("Connect GPS").click();
        h.run_steps(2);
    }
    devices.gps(&raw(GGA));
    assert!(common::settle(&mut h, |c| c.gps_ui.monitor.lines.len() == 1), "the monitor got the line");
    h.get_by_label_contains("NMEA monitor").click();
    h.run_steps(3);
    let line = h.get_by_label_contains(GGA).rect();
    let body = h.ctx.global_style().text_styles[&egui::TextStyle::Body].size;
    assert!(line.height() < body * 1.8, "one line, not wrapped: {line:?}");
    assert!(line.height() >= body * 0.9, "body size, not small: {line:?}");
}

/// Esc closes an open drop-down (issue 23, item 11) — the console's own Strategy drop-down in the
/// Guidance section, guiding: egui closes it, and nothing in the console takes the key first (Esc is no
/// stop key: only Space and the button stop). Truth: the requests that reached the emulated unit (no STOP
/// ALL), the station's guidance (still automatic, not halted) and the strategy (unchanged).
#[test]
fn escape_closes_the_consoles_strategy_drop_down_without_side_effects() {
    use common::console::{Fake, harness_with};
    use vestnav_device::wtcu::Request;
    let fake = Fake::default();
    let cfg = vestnav_app::config::Config { map_tiles: false, guidance_auto: true, ..Default::default() };
    let mut h = harness_with(&fake, cfg);
    h.run_steps(2);
    let strategy = h.state().cfg.strategy.clone();
    assert!(h.query_by_label("bearing").is_none());
    h.get_by_role_and_label(Role::ComboBox, "Strategy").click();
    h.run_steps(2);
    assert!(h.query_by_label("bearing").is_some(), "the drop-down opened");
    h.key_press(egui::Key::Escape);
    h.run_steps(3);
    assert!(h.query_by_label("bearing").is_none(), "Esc closed it");
    std::thread::sleep(Duration::from_millis(50));
    h.run_steps(2);
    assert!(!fake.sent().contains(&Request::StopAll), "no STOP ALL: {:?}", fake.sent());
    let c = h.state();
    assert!(c.cfg.guidance_auto && c.station.settings().guidance.auto, "automatic guidance untouched");
    assert!(c.station.vest.halted.is_none(), "not halted");
    assert_eq!(c.cfg.strategy, strategy, "the strategy unchanged");
}
