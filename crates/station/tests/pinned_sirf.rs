//! Issue 23 item 3: the thesis's `SiRF` problem, diagnosed. The emulated `SiRF` III (static navigation on,
//! as shipped) walks the demo route at 0.8 m/s — below its 1.2 m/s threshold — behind a real PTY; the
//! station reads it as a serial receiver. It must name the cause from the stream ("`SiRF` static navigation
//! is pinning the position"), and its one-click remedy, sent through the receiver configuration path,
//! must free the position.
#![cfg(unix)]
#![allow(clippy::unwrap_used)]

use std::io::{Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use vestnav_core::gnss_sim::GnssErrorModel;
use vestnav_device::gps::receiver_config::emulator::{EmulatedFamily, EmulatedReceiver, Protocol};
use vestnav_device::gps::receiver_config::{ConfigEvent, Family};
use vestnav_device::gps::sim::{SimulatedReceiver, demo_route, whole_second_now};
use vestnav_device::serial::Pty;
use vestnav_station::hardware::Hardware;
use vestnav_station::sources::GpsSourceConfig;
use vestnav_station::{Station, StationOptions};

/// Epochs a second the emulated receiver sends (each one simulated second apart).
const EPOCHS_PER_S: u32 = 5;

/// Runs the emulated `SiRF` III on a PTY until `stop`; returns the PTY's path.
fn start_sirf3(stop: Arc<AtomicBool>) -> (String, std::thread::JoinHandle<()>) {
    let mut pty = Pty::open_with_timeout(Duration::from_millis(10)).unwrap();
    let path = pty.path().to_owned();
    let thread = std::thread::spawn(move || {
        let mut emu = EmulatedReceiver::new(EmulatedFamily::Sirf3, true);
        let route = demo_route().unwrap();
        let model = GnssErrorModel::sirf3_no_static_nav();
        let mut rx = SimulatedReceiver::new(&route, 0.8, model, 7, whole_second_now()).unwrap();
        let s = emu.settings();
        rx.set_static_hold(s.static_hold_m_s, s.static_hold_max_dist_m);
        let mut buf = [0u8; 512];
        let mut k = 0u32;
        while !stop.load(Ordering::Relaxed) {
            let epoch = rx.next_epoch(1.0);
            if emu.settings().protocol == Protocol::Nmea {
                if k.is_multiple_of(2 * EPOCHS_PER_S) {
                    let _ = pty.write_all(&emu.banner());
                }
                let _ = pty.write_all(epoch.as_bytes());
            }
            k += 1;
            let due = Instant::now() + Duration::from_secs(1) / EPOCHS_PER_S;
            while Instant::now() < due {
                if let Ok(n) = pty.read(&mut buf)
                    && n > 0
                {
                    emu.handle_bytes(&buf[..n]);
                    let _ = pty.write_all(&emu.take_output());
                    if emu.take_changed() {
                        let s = emu.settings();
                        rx.set_static_hold(s.static_hold_m_s, s.static_hold_max_dist_m);
                    }
                }
            }
        }
    });
    (path, thread)
}

fn pump_until(station: &mut Station, within: Duration, mut done: impl FnMut(&Station) -> bool) -> bool {
    let end = Instant::now() + within;
    while Instant::now() < end {
        station.pump(|_| {});
        if done(station) {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}

#[test]
fn sirf_static_navigation_is_named_and_turned_off() {
    let stop = Arc::new(AtomicBool::new(false));
    let (path, thread) = start_sirf3(stop.clone());
    let gps = GpsSourceConfig::Serial { port: path, baud: Some(4800) };
    let mut station =
        Station::new(Box::new(Hardware::default()), StationOptions { gps: Some(gps), ..Default::default() });
    station.connect_gps(Vec::new());
    assert!(
        pump_until(&mut station, Duration::from_secs(20), |s| s
            .pinned(Instant::now())
            .is_some_and(|p| p.family == Some(Family::Sirf))),
        "no SiRF pinning diagnosis; family {:?}",
        station.gps_family()
    );
    let p = station.pinned(Instant::now()).unwrap();
    assert!(p.text().starts_with("SiRF static navigation is pinning the position"), "{}", p.text());
    // The one click: static navigation off through the serial source's configuration path.
    let remedy = p.remedy().unwrap();
    assert_eq!(remedy.sirf_static_nav, Some(false));
    let ticket = station.gps_worker().unwrap().configure(remedy).unwrap();
    let end = Instant::now() + Duration::from_secs(15);
    let mut finished = false;
    while Instant::now() < end && !finished {
        station.pump(|_| {});
        while let Some(ev) = ticket.try_recv() {
            finished |= matches!(ev, ConfigEvent::Finished);
            assert!(!matches!(ev, ConfigEvent::Failed(_)), "{ev:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(finished, "the configuration did not finish");
    // Free: the position moves again and the diagnosis ends.
    let before = station.gps.last_position.as_ref().and_then(|f| f.lat_deg);
    assert!(
        pump_until(&mut station, Duration::from_secs(10), |s| s.pinned(Instant::now()).is_none()
            && s.gps.last_position.as_ref().and_then(|f| f.lat_deg) != before),
        "still pinned after static navigation off"
    );
    stop.store(true, Ordering::Relaxed);
    station.disconnect_gps();
    thread.join().unwrap();
}
