//! Issue 27 in the console: the Field tests panel's reference (typed through core's parser) and the live
//! accuracy statistics against it (closed form), and the RTK (NTRIP) window's status line with the console
//! on a real serial receiver (a PTY) and a caster on 127.0.0.1 serving gpsd's RTCM 3 log.
#![allow(clippy::unwrap_used)]

mod common;

use std::io::{BufRead as _, BufReader, Read as _, Write as _};
use std::net::TcpListener;
use std::time::{Duration, Instant};

use common::console::*;
use egui::accesskit::Role;
use egui_kittest::kittest::Queryable as _;
use vestnav_app::config::{Config, GpsSourceConfig};
use vestnav_app::console::{Console, ConsoleOptions};
use vestnav_core::geo::{Earth, LatLon};
use vestnav_device::gps::{Fix, GpsEvent};

const C: LatLon = LatLon::new(42.3575, -71.1010);

/// A fix `east_m` east of C, arrived now, with its height.
fn east_fix(east_m: f64, height_m: f64) -> Fix {
    let p = Earth::Wgs84.direct(C, 90.0, east_m);
    Fix { alt_m: Some(height_m), ..fix(p.lat_deg, p.lon_deg, Duration::ZERO) }
}

/// The operator types the reference (decimal degrees, its uncertainty and height), starts the accuracy
/// test and the fixes come: the bias, the shares within 0.1 / 0.5 / 1 / 2 / 5 m and the vertical error
/// are shown as the closed form gives them for six fixes due east at known distances.
#[test]
fn typed_reference_and_live_accuracy_statistics() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    fake.gps(&GpsEvent::Fix(Box::new(east_fix(0.0, 100.0))));
    settle(&mut h, |c| c.station.field_tests.latest().is_some());
    h.get_by_label("Field tests").click();
    h.run_steps(2);
    h.get_by_label("Accuracy test").click();
    h.run_steps(2);
    assert!(h.query_by_label_contains("No reference").is_some());
    assert!(h.query_by_label("Set a reference above first.").is_some());
    h.get_by_role_and_label(Role::TextInput, "position").set_text_value_accesskit("42.3575, -71.1010");
    h.run_steps(1);
    h.get_by_label("height above mean sea level").click();
    h.run_steps(1);
    h.state_mut().field_panel.reference.height_m = 100.0;
    h.get_by_label("Set reference").click();
    h.run_steps(2);
    let r = h.state().station.field_tests.reference().cloned().expect("reference set");
    assert!((r.pos.lat_deg - 42.3575).abs() < 1e-12 && (r.pos.lon_deg + 71.1010).abs() < 1e-12);
    assert!(h.query_by_label_contains("Reference: 42.35750000, -71.10100000 ± 0.020 m (typed").is_some());
    h.get_by_label("Start accuracy test").click();
    h.run_steps(1);
    let east = [0.05, 0.3, 0.8, 1.5, 3.0, 6.0];
    for (k, d) in east.iter().enumerate() {
        std::thread::sleep(Duration::from_millis(2)); // arrival times increase
        fake.gps(&GpsEvent::Fix(Box::new(east_fix(*d, 100.5))));
        settle(&mut h, |c| c.station.field_tests.accuracy.recording().fixes().len() == k + 1);
    }
    h.run_steps(2);
    // Closed form: one fix in six within each radius more; the bias is the mean distance, due east.
    assert!(h.query_by_label("16.7 % / 33.3 % / 50.0 % / 66.7 % / 83.3 %").is_some());
    let mean: f64 = east.iter().sum::<f64>() / 6.0;
    let bias = format!("{mean:+.3} / +0.000 m (|bias| {mean:.3} m)");
    assert!(h.query_by_label(&bias).is_some(), "{bias}");
    assert!(h.query_by_label("+0.500 / 0.500 / 0.500 m (6 fixes)").is_some(), "vertical bias / RMS / P95");
    assert!(h.query_by_label("6 fixes over 0 s against the reference").is_some());
    // A malformed position is refused with the parser's reason, and the reference stays.
    h.get_by_role_and_label(Role::TextInput, "position").set_text_value_accesskit("north pole-ish");
    h.run_steps(1);
    h.get_by_label("Set reference").click();
    h.run_steps(2);
    assert!(h.state().field_panel.reference.error.is_some());
    assert_eq!(h.state().station.field_tests.reference(), Some(&r));
}

/// `$BODY*hh` with its checksum.
fn nmea(body: &str) -> String {
    let sum = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{sum:02X}")
}

/// gpsd's RTCM 3 regression log (BSD-2): the bytes after its `#` comment lines.
fn rtcm_stream() -> Vec<u8> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/data/gpsd-rtcm/rtcm3.2.log");
    let raw = std::fs::read(path).unwrap();
    let mut i = 0;
    while raw.get(i) == Some(&b'#') {
        i += raw[i..].iter().position(|b| *b == b'\n').unwrap() + 1;
    }
    raw[i..].to_vec()
}

/// How many messages gpsd decoded from that log (its `.chk`, one JSON line each).
fn gpsd_frames() -> usize {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/data/gpsd-rtcm/rtcm3.2.log.chk");
    std::fs::read_to_string(path).unwrap().lines().filter(|l| !l.trim().is_empty()).count()
}

/// An NTRIP 1.0 caster on 127.0.0.1 (no credentials): each connection gets `ICY 200 OK`, the first one
/// the log's stream, then silence (a stalled caster) until the client leaves. Only the first: the
/// receiver's count of frames is the log's, however soon the client reconnects.
fn caster() -> String {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    std::thread::spawn(move || {
        for (k, stream) in listener.incoming().enumerate() {
            let Ok(mut stream) = stream else { return };
            std::thread::spawn(move || {
                let mut reader = BufReader::new(stream.try_clone().unwrap());
                let mut line = String::new();
                while reader.read_line(&mut line).unwrap_or(0) > 0 && line != "\r\n" {
                    line.clear();
                }
                let _ = stream.write_all(b"ICY 200 OK\r\n");
                if k == 0 {
                    let _ = stream.write_all(&rtcm_stream());
                }
                std::thread::sleep(Duration::from_secs(20));
            });
        }
    });
    addr
}

/// The console on a serial receiver (a PTY): the operator opens **Receiver → RTK corrections (NTRIP)…**, types the caster and
/// mountpoint and starts the corrections; they reach the receiver's port (as many frames as gpsd decodes
/// in the log, each whole), and the GPS panel's status line says connected, the message types, and the
/// receiver's RTK float from its GGA quality 5. When the caster then goes silent, the line says the
/// corrections are reconnecting after the stall, in amber, while the console goes on.
#[test]
fn ntrip_status_line_with_a_serial_receiver() {
    let addr = caster();
    let mut pty = vestnav_device::serial::Pty::open().unwrap();
    let mut cfg = Config { map_tiles: false, guidance_auto: false, ..Config::default() };
    cfg.gps = GpsSourceConfig::Serial { port: pty.path().to_owned(), baud: Some(115_200) };
    cfg.ntrip.stall_s = 1.0;
    let console = Console::new(
        Box::new(vestnav_station::hardware::Hardware::default()),
        ConsoleOptions { cfg, ..ConsoleOptions::default() },
    );
    let mut h = egui_kittest::Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    h.run_steps(3);
    h.get_by_label("Receiver").click();
    h.run_steps(2);
    h.get_by_label("RTK corrections (NTRIP)…").click();
    h.run_steps(2);
    h.get_by_role_and_label(Role::TextInput, "caster").set_text_value_accesskit(&addr);
    h.get_by_role_and_label(Role::TextInput, "mountpoint").set_text_value_accesskit("RTCM32");
    h.run_steps(1);
    h.get_by_label("NTRIP 1.0").click();
    h.run_steps(1);
    h.get_by_label("Start corrections").click();
    h.run_steps(1);
    assert_eq!(h.state().gps_ui.ntrip.error, None);
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    let deadline = Instant::now() + Duration::from_secs(15);
    let mut k = 0u32;
    let mut saw_connected = false;
    while Instant::now() < deadline {
        let gga = nmea(&format!(
            "GPGGA,1200{:02}.00,4807.038,N,01131.000,E,5,12,0.6,545.4,M,46.9,M,1.0,0000",
            k % 60
        ));
        pty.write_all(format!("{gga}\r\n").as_bytes()).unwrap();
        k += 1;
        // Everything the port holds (a full read means there may be more).
        while let Ok(n) = pty.read(&mut buf) {
            got.extend_from_slice(&buf[..n]);
            if n < buf.len() {
                break;
            }
        }
        h.step();
        // The line shows twice (the GPS panel and the open window).
        let shown = |text: &str| h.query_all_by_label_contains(text).next().is_some();
        if shown("RTK corrections connected") && shown("receiver RTK float") {
            saw_connected = true;
        }
        if saw_connected && shown("RTK corrections reconnecting") {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(saw_connected, "the status line showed the connection and the receiver's RTK float");
    let line = h.state().station.ntrip_line(Instant::now()).unwrap();
    assert!(line.contains("reconnecting") && line.contains("stalled"), "{line}");
    // The receiver got whole frames back to back, as many as gpsd decodes in the log.
    let (mut i, mut frames) = (0, 0);
    while i + 3 <= got.len() {
        assert_eq!(got[i], 0xD3, "a frame starts at byte {i}");
        i += ((usize::from(got[i + 1]) & 3) << 8 | usize::from(got[i + 2])) + 6;
        frames += 1;
    }
    assert_eq!(i, got.len(), "no partial frame");
    assert_eq!(frames, gpsd_frames());
    h.get_by_label("Stop corrections").click();
    h.run_steps(2);
    assert!(!h.state().station.ntrip().unwrap().running());
}

/// The console with its settings saved to (and restored from) `cfg_path`.
fn console_saving(fake: &Fake, cfg_path: &std::path::Path) -> egui_kittest::Harness<'static, Console> {
    let (cfg, problem) = Config::load(cfg_path);
    assert!(problem.is_none(), "{problem:?}");
    let cfg = Config { map_tiles: false, guidance_auto: false, ..cfg };
    let console = Console::new(
        Box::new(fake.clone()),
        ConsoleOptions { cfg, cfg_path: Some(cfg_path.to_path_buf()), ..ConsoleOptions::default() },
    );
    let mut h = egui_kittest::Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    h.run_steps(2);
    h
}

/// A reference set in the Field tests tab is drawn on the map (its marker, its uncertainty as the circle's
/// radius, its label) and is there again after a restart: it is kept in the console's settings file.
#[test]
fn reference_is_on_the_map_and_survives_a_restart() {
    let dir = test_dir("reference-restart");
    let cfg_path = dir.join("console.json");
    let fake = Fake::default();
    let mut h = console_saving(&fake, &cfg_path);
    assert!(h.state().map.tools.field.reference.is_none(), "no reference, nothing drawn");
    h.get_by_label("Field tests").click();
    h.run_steps(2);
    h.get_by_role_and_label(Role::TextInput, "position")
        .set_text_value_accesskit("45 52 39.333 S 170 30 0.4554 E");
    h.run_steps(1);
    h.state_mut().field_panel.reference.uncertainty_m = 0.25;
    h.get_by_label("Set reference").click();
    h.run_steps(2);
    let set = h.state().station.field_tests.reference().cloned().expect("reference set");
    h.get_by_label("Map").click();
    h.run_steps(2);
    let mark = h.state().map.tools.field.reference.clone().expect("the reference is drawn on the map");
    assert_eq!((mark.pos, mark.uncertainty_m), (set.pos, 0.25));
    assert_eq!(mark.label, "reference ±0.250 m");
    drop(h);
    let h = console_saving(&fake, &cfg_path);
    let restored = h.state().station.field_tests.reference().cloned().expect("restored at start");
    assert_eq!(restored, set);
    assert!((restored.pos.lat_deg + 45.877_592_5).abs() < 1e-7, "DMS read as published");
    drop(h);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A FIFO given as the GPX file of a waypoint reference is refused with its name, read on its own thread:
/// the view keeps turning (no frame waits on the file) and the reference stays unset.
#[cfg(unix)]
#[test]
fn a_fifo_as_gpx_is_refused_without_blocking_the_view() {
    let dir = test_dir("reference-fifo");
    let fifo = dir.join("marker.gpx");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Field tests").click();
    h.run_steps(2);
    h.get_by_label("GPX waypoint").click();
    h.run_steps(1);
    h.state_mut().field_panel.reference.gpx_path = fifo.display().to_string();
    h.run_steps(1);
    let started = Instant::now();
    h.get_by_label("Set reference").click();
    h.run_steps(1);
    // A frame that waited on the FIFO would never come back (nobody writes to it).
    assert!(started.elapsed() < Duration::from_secs(2), "the click's frame returned");
    settle(&mut h, |c| c.field_panel.reference.error.is_some());
    let e = h.state().field_panel.reference.error.clone().expect("refused");
    assert!(e.contains("marker.gpx"), "{e}");
    assert!(!h.state().field_panel.reference.reading());
    assert!(h.state().station.field_tests.reference().is_none());
    std::fs::remove_dir_all(&dir).unwrap();
}
