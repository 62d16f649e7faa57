//! The GPS panel's Receiver section: Send reaches a receiver on a real PTY through the serial source, and
//! the receiver's acknowledgements come back to the panel; a source that is not a serial port says why.
#![cfg(unix)]
#![allow(clippy::unwrap_used)]

mod common;

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use egui_kittest::kittest::Queryable as _;
use vestnav_app::config::{Config, GpsSourceConfig};
use vestnav_app::console::{Console, ConsoleOptions};
use vestnav_device::gps::receiver_config::emulator::{EmulatedFamily, EmulatedReceiver};
use vestnav_device::gps::{GpsEvent, GpsSource, SourceConfig};
use vestnav_device::outbox::Outbox;

/// A u-blox 8 behind a PTY, answered by the device crate's emulated receiver on a thread.
struct PtyReceiver {
    path: String,
    receiver: Arc<Mutex<EmulatedReceiver>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl PtyReceiver {
    fn start() -> Self {
        let mut pty = vestnav_device::serial::Pty::open_with_timeout(Duration::from_millis(20)).unwrap();
        let path = pty.path().to_owned();
        let receiver = Arc::new(Mutex::new(EmulatedReceiver::new(EmulatedFamily::Ublox8, false)));
        let stop = Arc::new(AtomicBool::new(false));
        let (rx, st) = (receiver.clone(), stop.clone());
        let thread = std::thread::spawn(move || {
            let mut buf = [0u8; 512];
            while !st.load(Ordering::Relaxed) {
                if let Ok(n) = pty.read(&mut buf)
                    && n > 0
                {
                    let reply = {
                        let mut r = rx.lock().unwrap();
                        r.handle_bytes(&buf[..n]);
                        r.take_output()
                    };
                    let _ = pty.write_all(&reply);
                }
            }
        });
        Self { path, receiver, stop, thread: Some(thread) }
    }
}

impl Drop for PtyReceiver {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// GPS: the device crate's real serial source on the PTY; vest: the test helper's emulated unit.
#[derive(Clone)]
struct SerialDevices {
    vest: common::Devices,
}

impl vestnav_station::devices::DeviceFactory for SerialDevices {
    fn open_gps(
        &self,
        s: &GpsSourceConfig,
        _r: &[vestnav_station::route::Waypoint],
        out: Vec<Outbox<GpsEvent>>,
    ) -> Result<Box<dyn vestnav_station::devices::GpsWorker>, String> {
        let GpsSourceConfig::Serial { port, baud } = s else { return Err("serial only".into()) };
        let cfg = SourceConfig::Serial { port: port.clone(), baud: *baud };
        Ok(Box::new(GpsSource::spawn(cfg, out).map_err(|e| e.to_string())?))
    }
    fn open_vest(
        &self,
        s: &vestnav_app::config::VestSourceConfig,
        out: Vec<Outbox<vestnav_device::wtcu::VestEvent>>,
    ) -> Result<vestnav_device::wtcu::VestHandle, String> {
        self.vest.open_vest(s, out)
    }
}

fn harness(console: Console) -> egui_kittest::Harness<'static, Console> {
    let mut h = egui_kittest::Harness::builder()
        .with_size(egui::vec2(1400.0, 1400.0))
        // The source picker's serial port combo and baud field have no accessible names (not this
        // section's widgets; the other test runs the Receiver section with the check on).
        .with_accessibility_check(false)
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    h.run_steps(3);
    h
}

/// Opens the receiver configuration window with the GPS panel's **Receiver** toggle (again, if the panel moved
/// under the click while the source's state changed).
fn open_receiver(h: &mut egui_kittest::Harness<'static, Console>) {
    for _ in 0..5 {
        h.get_by_label("Receiver").click();
        for _ in 0..10 {
            h.step();
            if h.query_by_label("Send to receiver").is_some() {
                return;
            }
        }
    }
    panic!("the Receiver section did not open");
}

#[test]
fn send_to_receiver_configures_a_ublox_on_a_pty_and_shows_each_ack() {
    let rx = PtyReceiver::start();
    let cfg = Config {
        map_tiles: false,
        guidance_auto: false,
        follow: false,
        gps: GpsSourceConfig::Serial { port: rx.path.clone(), baud: Some(9600) },
        ..Config::default()
    };
    let devices = SerialDevices { vest: common::Devices::default() };
    let console = Console::new(Box::new(devices), ConsoleOptions { cfg, ..ConsoleOptions::default() });
    let mut h = harness(console);
    h.state_mut().connect_gps();
    h.run_steps(2);
    open_receiver(&mut h);
    h.get_by_label("Send to receiver").click();
    let mut shown = false;
    for _ in 0..400 {
        h.step();
        if h.query_by_label_contains("CFG-NAV5: accepted").is_some() {
            shown = true;
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(
        shown,
        "results: {:?}, status {:?}",
        h.state().gps_ui.receiver.results,
        h.state().gps_ui.receiver.status
    );
    assert!(h.query_by_label_contains("CFG-RATE: accepted").is_some());
    assert!(h.query_by_label_contains("CFG-GNSS: accepted").is_some());
    // The panel's defaults reached the receiver: pedestrian, static hold off, 1 Hz.
    let s = rx.receiver.lock().unwrap().settings().clone();
    assert_eq!(s.dyn_model, 3);
    assert_eq!(s.static_hold_m_s, None);
    assert_eq!(s.period, Duration::from_secs(1));
    h.state_mut().disconnect_gps();
}

#[test]
fn send_is_disabled_with_the_reason_when_the_source_is_not_a_serial_port() {
    let devices = common::Devices::default();
    let mut h = common::console(&devices);
    h.state_mut().connect_gps();
    h.run_steps(2);
    assert!(!matches!(h.state().cfg.gps, GpsSourceConfig::Serial { .. }));
    open_receiver(&mut h);
    assert!(h.query_by_label_contains("configuration needs a direct serial connection").is_some());
    h.get_by_label("Send to receiver").click();
    h.run_steps(2);
    assert!(h.state().gps_ui.receiver.ticket.is_none(), "nothing was sent");
    assert!(h.state().gps_ui.receiver.results.is_empty());
}
