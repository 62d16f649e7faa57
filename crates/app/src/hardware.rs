//! The real devices: `vestnav-device`'s GPS sources and WTCU worker behind the console's [`DeviceFactory`].
//!
//! Each adapter is a small pump thread: it waits for the device worker's wake-up, drains its events,
//! converts them to the console's [`crate::model`] types and hands them to the console's outbox.

use std::sync::mpsc::{RecvTimeoutError, sync_channel};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use vestnav_core::vest::TactorMask;
use vestnav_device::gps as dgps;
use vestnav_device::wtcu::{self, VestHandle};

use crate::config::{GpsSourceConfig, VestSourceConfig};
use crate::devices::{DeviceFactory, VestLink, Worker};
use crate::model::{FixMode, GpsEvent, GpsFix, LinkState, Outbox, Satellite, VestCommand, VestEvent};
use crate::route::Waypoint;

/// Baud rate used for a WTCU serial port (Bluetooth SPP ignores it).
pub const WTCU_BAUD: u32 = 115_200;

/// Opens devices through `vestnav-device`.
#[derive(Debug, Default)]
pub struct Hardware;

impl DeviceFactory for Hardware {
    fn open_gps(
        &self,
        source: &GpsSourceConfig,
        route: &[Waypoint],
        events: Outbox<GpsEvent>,
    ) -> Result<Box<dyn Worker>, String> {
        crate::gps_source::open(source, route, events)
    }

    fn open_vest(
        &self,
        source: &VestSourceConfig,
        events: Outbox<VestEvent>,
    ) -> Result<Arc<dyn VestLink>, String> {
        let config = match source {
            VestSourceConfig::Emulated => wtcu::VestConfig::Emulated(wtcu::engine::EngineConfig::default()),
            VestSourceConfig::Serial { port } if port.trim().is_empty() => {
                return Err("pick the vest's port".into());
            }
            VestSourceConfig::Serial { port } => {
                wtcu::VestConfig::Serial { port: port.trim().to_owned(), baud: WTCU_BAUD }
            }
        };
        let (wake_tx, wake_rx) = sync_channel::<()>(1);
        let handle = VestHandle::spawn(config, move || {
            let _ = wake_tx.try_send(());
        })
        .map_err(|e| format!("cannot start the vest worker: {e}"))?;
        let link = Arc::new(DeviceVest { handle: Mutex::new(Some(handle)) });
        let pump = link.clone();
        std::thread::Builder::new()
            .name("vestnav-vest-pump".into())
            .spawn(move || {
                while let Ok(()) | Err(RecvTimeoutError::Timeout) =
                    wake_rx.recv_timeout(Duration::from_millis(200))
                {
                    let mut batch = Vec::new();
                    {
                        let Ok(guard) = pump.handle.lock() else { break };
                        let Some(h) = guard.as_ref() else { break };
                        while let Some(ev) = h.try_recv() {
                            batch.push(ev);
                        }
                    }
                    for ev in batch {
                        for e in convert_vest_event(ev) {
                            if !events.send(e) {
                                return;
                            }
                        }
                    }
                }
                events.send(VestEvent::State(LinkState::Disconnected));
            })
            .map_err(|e| format!("cannot start the vest pump: {e}"))?;
        Ok(link)
    }
}

/// The device crate's vest worker, shareable between the UI and the guidance thread.
struct DeviceVest {
    handle: Mutex<Option<VestHandle>>,
}

impl VestLink for DeviceVest {
    fn send(&self, command: VestCommand) -> Result<(), String> {
        let cmd = match command {
            VestCommand::Fire { mask, on_ms } => wtcu::VestCommand::Fire { mask, duration_ms: on_ms },
            VestCommand::Play(p) => wtcu::VestCommand::Play(p),
            VestCommand::StopAll => wtcu::VestCommand::StopAll,
        };
        let guard = self.handle.lock().map_err(|_| "vest worker poisoned".to_owned())?;
        let h = guard.as_ref().ok_or_else(|| "vest disconnected".to_owned())?;
        h.send(cmd).map_err(|e| e.to_string())
    }

    fn close(&self) {
        // VestHandle::stop sends STOP ALL and waits for it before closing the port.
        let h = self.handle.lock().ok().and_then(|mut g| g.take());
        if let Some(h) = h {
            h.stop();
        }
    }
}

impl Drop for DeviceVest {
    fn drop(&mut self) {
        self.close();
    }
}

fn convert_link_state(s: &wtcu::LinkState) -> LinkState {
    match s {
        wtcu::LinkState::Disconnected => LinkState::Disconnected,
        wtcu::LinkState::Connecting { attempt } => LinkState::Connecting { attempt: *attempt },
        wtcu::LinkState::Handshaking => LinkState::Connecting { attempt: 1 },
        wtcu::LinkState::Ready => LinkState::Live,
        wtcu::LinkState::Lost { reason } => LinkState::Lost { reason: reason.clone() },
    }
}

/// Converts one vest worker event into what the console shows.
fn convert_vest_event(ev: wtcu::VestEvent) -> Vec<VestEvent> {
    match ev {
        wtcu::VestEvent::State(s) => vec![VestEvent::State(convert_link_state(&s))],
        wtcu::VestEvent::Identified(info) => vec![
            VestEvent::Status { battery_pct: None, firmware: info.firmware.to_string() },
            VestEvent::Notice(format!(
                "unit identified: protocol v{}, firmware {}, {} tactors, watchdog {} ms",
                info.protocol_version, info.firmware, info.tactor_count, info.watchdog_ms
            )),
        ],
        wtcu::VestEvent::TactorsOn(m) => vec![VestEvent::TactorsOn(m.unwrap_or(TactorMask::NONE))],
        wtcu::VestEvent::Acked { seq, kind } => {
            vec![VestEvent::Ack { what: format!("{} #{seq}", kind.name()) }]
        }
        wtcu::VestEvent::Rejected { kind, reason } => {
            vec![VestEvent::Rejected { reason: format!("{}: {reason}", kind.name()) }]
        }
        wtcu::VestEvent::Status(st) => vec![
            VestEvent::Status { battery_pct: Some(st.battery_pct), firmware: st.firmware.to_string() },
            VestEvent::TactorsOn(st.tactors_on),
        ],
        wtcu::VestEvent::Transport(e) => vec![VestEvent::Notice(format!("transport: {e}"))],
    }
}

/// Converts the device crate's fix into the console's.
///
/// When the receiver sent a position with a valid GGA quality but no GSA mode (GGA-only streams), the mode
/// is inferred: 3D with an altitude, else 2D, so the position is shown and used.
pub fn convert_fix(f: &dgps::Fix) -> GpsFix {
    let mode = match f.mode {
        Some(dgps::FixMode::Fix3D) => FixMode::Fix3d,
        Some(dgps::FixMode::Fix2D) => FixMode::Fix2d,
        None if f.quality.is_some_and(dgps::FixQuality::has_position)
            && f.lat_deg.is_some()
            && f.lon_deg.is_some() =>
        {
            if f.alt_m.is_some() {
                FixMode::Fix3d
            } else {
                FixMode::Fix2d
            }
        }
        Some(dgps::FixMode::NoFix) | None => FixMode::NoFix,
    };
    let time_utc = f
        .time
        .map(|t| t.to_rfc3339_opts(chrono::SecondsFormat::Millis, true))
        .or_else(|| f.time_of_day.map(|t| format!("{}", t.format("%H:%M:%S%.3f"))));
    GpsFix {
        time_utc,
        lat_deg: f.lat_deg.unwrap_or(f64::NAN),
        lon_deg: f.lon_deg.unwrap_or(f64::NAN),
        alt_m: f.alt_m,
        mode,
        quality: f.quality.map(|q| format!("{q:?}")).unwrap_or_default(),
        sats_used: f.sats_used,
        sats_visible: f.sats_visible,
        hdop: f.hdop,
        pdop: f.pdop,
        error_m: f.error.map(|e| e.horizontal_m),
        speed_m_s: f.speed_m_s,
        course_deg: f.course_deg,
        satellites: f
            .satellites
            .iter()
            .map(|s| Satellite {
                prn: s.prn,
                elevation_deg: s.elevation_deg,
                azimuth_deg: s.azimuth_deg,
                snr_db: s.snr_dbhz,
                used: s.used,
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gga_only_fix_gets_a_mode() {
        let f = dgps::Fix {
            lat_deg: Some(57.1),
            lon_deg: Some(-2.1),
            alt_m: Some(59.3),
            quality: Some(dgps::FixQuality::Gps),
            ..dgps::Fix::default()
        };
        let g = convert_fix(&f);
        assert_eq!(g.mode, FixMode::Fix3d);
        assert!(g.has_position());
        let none = convert_fix(&dgps::Fix::default());
        assert!(!none.has_position());
    }
}
