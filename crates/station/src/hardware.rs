//! The real devices: `vestnav-device`'s GPS sources and vest worker behind the console's
//! [`DeviceFactory`]. Nothing is converted here: the workers deliver the device crate's events to the
//! console's consumers themselves.
//!
//! The simulator walks the console's route with the `SiRF` Star III open-sky error model
//! (`GnssErrorModel::sirf3_open_sky`: wandering bias, white noise, static navigation below 1.2 m/s) at 1 Hz,
//! producing real NMEA that goes through the same decoder as a receiver's; at the end of the route it
//! starts over with a new error realisation, so the demo never stops.

use std::time::Duration;

use vestnav_core::gnss_sim::GnssErrorModel;
use vestnav_device::gps::through_vest::{VestGpsReader, VestGpsWriter, vest_gps_pipe};
use vestnav_device::gps::{GpsEvent, GpsSource, SourceConfig};
use vestnav_device::outbox::Outbox;
use vestnav_device::sim::{CompassSetup, SharedTruth, WearerMotion};
use vestnav_device::wtcu::emulator::UnitConfig;
use vestnav_device::wtcu::worker::WorkerSettings;
use vestnav_device::wtcu::{self, VestEvent, VestHandle};

use crate::devices::{DeviceFactory, GpsWorker};
use crate::route::Waypoint;
use crate::sources::{GpsSourceConfig, VestSourceConfig};

/// Baud rate used for a WTCU serial port (Bluetooth SPP ignores it).
pub const WTCU_BAUD: u32 = 115_200;

/// Walking pace of the simulated wearer [m/s] (a brisk walk, above the static-navigation threshold).
pub const SIM_PACE_M_S: f64 = 1.4;

/// Opens devices through `vestnav-device`.
///
/// The simulated GPS and the emulated vest it starts see one simulated wearer: the simulator publishes the
/// walker's true position, course and pace ([`SharedTruth`]) and the emulated unit's compass measures that
/// body (`WearerMotion::Follow`), so the compass and the GPS course agree as they would on a real walk.
/// With [`crate::StationSettings::sim_follows_vest`] the unit also tells that wearer every tactor change
/// (`UnitConfig::skin`), and the simulator's walker goes where the cues it feels steer it.
///
/// A GPS receiver "through the vest unit" reaches its GPS source through one pipe the factory keeps: the
/// vest worker writes the unit's forwarded bytes into it, the GPS source reads them.
#[derive(Debug)]
pub struct Hardware {
    truth: SharedTruth,
    vest_gps: (VestGpsWriter, VestGpsReader),
    /// Simulators started so far: each draws its own noise and wearer (seeds 2026, 2027, ...), so two
    /// trials on the simulator are two walks, and a run of the program repeats the same sequence.
    simulators: std::sync::atomic::AtomicU64,
}

impl Default for Hardware {
    fn default() -> Self {
        Self {
            truth: SharedTruth::default(),
            vest_gps: vest_gps_pipe(),
            simulators: std::sync::atomic::AtomicU64::new(0),
        }
    }
}

impl DeviceFactory for Hardware {
    fn open_gps(
        &self,
        source: &GpsSourceConfig,
        route: &[Waypoint],
        outputs: Vec<Outbox<GpsEvent>>,
    ) -> Result<Box<dyn GpsWorker>, String> {
        let mut config = match source {
            GpsSourceConfig::ThroughVest { baud } => {
                SourceConfig::ThroughVest { reader: self.vest_gps.1.clone(), baud: *baud }
            }
            GpsSourceConfig::Simulator { .. } => {
                let n = self.simulators.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                device_config(source, route, 2026 + n)?
            }
            _ => device_config(source, route, 2026)?,
        };
        if let SourceConfig::Simulator { truth, .. } = &mut config {
            *truth = Some(self.truth.clone());
        }
        let handle =
            GpsSource::spawn(config, outputs).map_err(|e| format!("cannot start the GPS worker: {e}"))?;
        Ok(Box::new(handle))
    }

    fn simulated_wearer(&self) -> Option<SharedTruth> {
        Some(self.truth.clone())
    }

    fn open_vest(
        &self,
        source: &VestSourceConfig,
        outputs: Vec<Outbox<VestEvent>>,
    ) -> Result<VestHandle, String> {
        let config = match source {
            VestSourceConfig::Emulated => wtcu::VestConfig::Emulated(UnitConfig {
                compass: Some(CompassSetup {
                    motion: WearerMotion::Follow(self.truth.clone()),
                    ..CompassSetup::default()
                }),
                skin: Some(self.truth.clone()),
                ..UnitConfig::default()
            }),
            VestSourceConfig::Serial { port } if port.trim().is_empty() => {
                return Err("pick the vest's port".into());
            }
            VestSourceConfig::Serial { port } => {
                wtcu::VestConfig::Serial { port: port.trim().to_owned(), baud: WTCU_BAUD }
            }
        };
        let settings = WorkerSettings { gps: Some(self.vest_gps.0.clone()), ..WorkerSettings::default() };
        VestHandle::spawn_configured(config, settings, outputs)
            .map_err(|e| format!("cannot start the vest worker: {e}"))
    }
}

/// The device crate's configuration for `source`.
pub fn device_config(
    source: &GpsSourceConfig,
    route: &[Waypoint],
    seed: u64,
) -> Result<SourceConfig, String> {
    Ok(match source {
        GpsSourceConfig::Simulator { .. } => {
            if route.is_empty() {
                return Err("the simulator needs a route: add waypoints first".into());
            }
            SourceConfig::Simulator {
                route: route.iter().map(|w| (w.lat_deg, w.lon_deg)).collect(),
                pace_m_s: SIM_PACE_M_S,
                model: GnssErrorModel::sirf3_open_sky(),
                seed,
                period: Duration::from_secs(1),
                looped: true,
                truth: None,
            }
        }
        GpsSourceConfig::Serial { port, baud } => SourceConfig::Serial { port: port.clone(), baud: *baud },
        GpsSourceConfig::Replay { path, speed } => {
            if !path.is_file() {
                return Err(format!("no such file: {}", path.display()));
            }
            SourceConfig::Replay { path: path.clone(), speed: *speed }
        }
        GpsSourceConfig::Gpsd { host, port } => SourceConfig::Gpsd { host: host.clone(), port: *port },
        GpsSourceConfig::ThroughVest { .. } => {
            return Err("a receiver through the vest unit needs the console's vest link".into());
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use vestnav_core::geo::{Earth, LatLon};
    use vestnav_device::outbox::Overflow;

    #[test]
    fn simulator_walks_the_demo_route() {
        let route = crate::route::parse_gpx(crate::route::DEMO_GPX).unwrap().waypoints;
        let SourceConfig::Simulator { route: r, pace_m_s, model, seed, .. } =
            device_config(&GpsSourceConfig::default(), &route, 1).unwrap()
        else {
            panic!("not a simulator config")
        };
        // The simulator's clock steps one period per epoch: 5 ms epochs at 200x the pace walk the same
        // distance per epoch as 1 s epochs at the real pace.
        let cfg = SourceConfig::Simulator {
            route: r,
            pace_m_s: pace_m_s * 200.0,
            model,
            seed,
            period: Duration::from_millis(5),
            looped: false,
            truth: None,
        };
        let (out, rx) = Outbox::channel(256, Overflow::Wait, None);
        let mut h = GpsSource::spawn(cfg, vec![out]).unwrap();
        let mut fixes = Vec::new();
        while fixes.len() < 60 {
            if let GpsEvent::Fix(f) = rx.recv_timeout(Duration::from_secs(5)).unwrap() {
                fixes.push(*f);
            }
        }
        h.stop();
        // 60 s at 1.4 m/s along the first leg (105.9 m long, bearing 50.9°): 84 m out, give or take the
        // simulated receiver error (~3 m).
        let f = &fixes[59];
        let (lat, lon) = (f.lat_deg.unwrap(), f.lon_deg.unwrap());
        let (start, here) = (LatLon::new(route[0].lat_deg, route[0].lon_deg), LatLon::new(lat, lon));
        let (d, b) = (Earth::Wgs84.distance_m(start, here), Earth::Wgs84.initial_bearing_deg(start, here));
        assert!((d - 84.0).abs() < 12.0, "{d}");
        assert!((b - 50.9).abs() < 15.0, "{b}");
        assert!(fixes.iter().all(vestnav_device::gps::Fix::has_position));
        assert!(!f.satellites.is_empty());
    }

    #[test]
    fn missing_replay_file_is_a_clear_error() {
        let src = GpsSourceConfig::Replay {
            path: "/nonexistent/x.nmea".into(),
            speed: vestnav_device::gps::ReplaySpeed::default(),
        };
        let err = Hardware::default().open_gps(&src, &[], Vec::new()).err().unwrap();
        assert!(err.contains("/nonexistent/x.nmea"));
    }
}
