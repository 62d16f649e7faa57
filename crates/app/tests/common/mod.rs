//! A small device factory for console UI tests: GPS events injected by the test, the emulated vest unit.
#![allow(dead_code, clippy::unwrap_used)]

pub mod console;

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use egui_kittest::Harness;
use vestnav_app::config::{Config, GpsSourceConfig, VestSourceConfig};
use vestnav_app::console::{Console, ConsoleOptions};
use vestnav_device::gps::{GpsEvent, SourceState};
use vestnav_device::outbox::Outbox;
use vestnav_device::wtcu::emulator::UnitConfig;
use vestnav_device::wtcu::worker::{EmulatedPort, Transport, WorkerSettings};
use vestnav_device::wtcu::{VestEvent, VestHandle};
use vestnav_station::devices::{DeviceFactory, GpsWorker};
use vestnav_station::route::Waypoint;

struct NoGps;
impl GpsWorker for NoGps {
    fn stop(&mut self) {}
}

/// GPS: whatever the test sends with [`Devices::gps`]; vest: the emulated unit.
#[derive(Default, Clone)]
pub struct Devices {
    gps: Arc<Mutex<Vec<Outbox<GpsEvent>>>>,
}

impl Devices {
    /// Hands `ev` to every consumer of the GPS source (UI, guidance, log).
    pub fn gps(&self, ev: &GpsEvent) {
        for o in self.gps.lock().unwrap().iter() {
            o.send(ev.clone(), &AtomicBool::new(false));
        }
    }
}

impl DeviceFactory for Devices {
    fn open_gps(
        &self,
        _s: &GpsSourceConfig,
        _r: &[Waypoint],
        out: Vec<Outbox<GpsEvent>>,
    ) -> Result<Box<dyn GpsWorker>, String> {
        for o in &out {
            o.send(GpsEvent::State(SourceState::Live { detail: "test".into() }), &AtomicBool::new(false));
        }
        *self.gps.lock().unwrap() = out;
        Ok(Box::new(NoGps))
    }
    fn open_vest(&self, _s: &VestSourceConfig, out: Vec<Outbox<VestEvent>>) -> Result<VestHandle, String> {
        let connector = Box::new(|| {
            Ok(Box::new(EmulatedPort::new(&UnitConfig::default(), Duration::from_millis(2)))
                as Box<dyn Transport>)
        });
        VestHandle::spawn_with(connector, WorkerSettings::default(), out).map_err(|e| e.to_string())
    }
}

/// The console on `devices`, tiles off, automatic cues off, 1400 x 900 points.
pub fn console(devices: &Devices) -> Harness<'static, Console> {
    let cfg = Config { map_tiles: false, guidance_auto: false, follow: false, ..Config::default() };
    let console =
        Console::new(Box::new(devices.clone()), ConsoleOptions { cfg, ..ConsoleOptions::default() });
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    h.run_steps(3);
    h
}

/// Steps frames until `done` holds (workers run on their own threads), at most ~3 s.
pub fn settle(h: &mut Harness<'static, Console>, done: impl Fn(&Console) -> bool) -> bool {
    for _ in 0..300 {
        h.step();
        if done(h.state()) {
            return true;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    false
}

/// A primary click at `pos` (press, a frame, release).
pub fn click_at(h: &mut Harness<'static, Console>, pos: egui::Pos2) {
    h.hover_at(pos);
    h.step();
    for pressed in [true, false] {
        h.event(egui::Event::PointerButton {
            pos,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: egui::Modifiers::default(),
        });
        h.step();
    }
    h.run_steps(2);
}
