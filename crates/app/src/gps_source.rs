//! GPS sources: `vestnav-device`'s workers (serial/Bluetooth with baud detection, NMEA replay, gpsd, and the
//! simulated receiver) behind a small pump thread that converts their events for the console.
//!
//! The simulator walks the console's route with the `SiRF` Star III open-sky error model
//! (`GnssErrorModel::sirf3_open_sky`: wandering bias, white noise, static navigation below 1.2 m/s) at 1 Hz,
//! producing real NMEA that goes through the same decoder as a receiver's; when the route is finished the
//! pump starts it over, so the demo never stops.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::sync_channel;
use std::time::Duration;

use vestnav_core::gnss_sim::GnssErrorModel;
use vestnav_device::gps::{self as dgps, GpsSource, SourceConfig, SourceState};

use crate::config::GpsSourceConfig;
use crate::devices::Worker;
use crate::model::{GpsEvent, LinkState, Outbox};
use crate::route::Waypoint;

/// Walking pace of the simulated wearer [m/s] (a brisk walk, above the static-navigation threshold).
pub const SIM_PACE_M_S: f64 = 1.4;

/// The pump thread; stopping it stops the device worker.
struct Pump {
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Worker for Pump {
    fn stop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Pump {
    fn drop(&mut self) {
        Worker::stop(self);
    }
}

/// The device crate's configuration for `source`.
pub fn device_config(
    source: &GpsSourceConfig,
    route: &[Waypoint],
    seed: u64,
) -> Result<SourceConfig, String> {
    Ok(match source {
        GpsSourceConfig::Simulator => {
            if route.is_empty() {
                return Err("the simulator needs a route: add waypoints first".into());
            }
            SourceConfig::Simulator {
                route: route.iter().map(|w| (w.lat_deg, w.lon_deg)).collect(),
                pace_m_s: SIM_PACE_M_S,
                model: GnssErrorModel::sirf3_open_sky(),
                seed,
                period: Duration::from_secs(1),
            }
        }
        GpsSourceConfig::Serial { port, baud } => SourceConfig::Serial { port: port.clone(), baud: *baud },
        GpsSourceConfig::Replay { path, speed } => {
            if !path.is_file() {
                return Err(format!("no such file: {}", path.display()));
            }
            SourceConfig::Replay { path: path.clone(), speed: (*speed > 0.0).then_some(*speed) }
        }
        GpsSourceConfig::Gpsd { host, port } => SourceConfig::Gpsd { host: host.clone(), port: *port },
    })
}

/// Starts the worker for `source`.
pub fn open(
    source: &GpsSourceConfig,
    route: &[Waypoint],
    events: Outbox<GpsEvent>,
) -> Result<Box<dyn Worker>, String> {
    open_with(device_config(source, route, 2026)?, events)
}

/// Starts the device worker for `config` and the pump that converts its events.
pub fn open_with(config: SourceConfig, events: Outbox<GpsEvent>) -> Result<Box<dyn Worker>, String> {
    let looping = matches!(config, SourceConfig::Simulator { .. });
    let spawn = |cfg: SourceConfig| {
        let (wake_tx, wake_rx) = sync_channel::<()>(1);
        GpsSource::spawn(cfg, move || {
            let _ = wake_tx.try_send(());
        })
        .map(|h| (h, wake_rx))
        .map_err(|e| format!("cannot start the GPS worker: {e}"))
    };
    let (mut handle, mut wake) = spawn(config.clone())?;
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let thread = std::thread::Builder::new()
        .name("vestnav-gps-pump".into())
        .spawn(move || {
            let mut round = 0u64;
            'outer: while !flag.load(Ordering::SeqCst) {
                let _ = wake.recv_timeout(Duration::from_millis(100));
                while let Some(ev) = handle.try_recv() {
                    let finished = matches!(ev, dgps::GpsEvent::State(SourceState::Finished));
                    if finished && looping {
                        // Start the walk over (new seed: a different error realisation each lap).
                        round += 1;
                        let mut cfg = config.clone();
                        if let SourceConfig::Simulator { seed, .. } = &mut cfg {
                            *seed = seed.wrapping_add(round);
                        }
                        events
                            .send(GpsEvent::Notice(format!("simulator: route finished, lap {}", round + 1)));
                        match spawn(cfg) {
                            Ok((h, w)) => {
                                handle.stop();
                                (handle, wake) = (h, w);
                                continue 'outer;
                            }
                            Err(e) => {
                                events.send(GpsEvent::Notice(e));
                                break 'outer;
                            }
                        }
                    }
                    for out in convert_event(ev) {
                        // The router is a worker thread: wait for it rather than lose a fix (the device
                        // worker then waits for us in turn).
                        if !events.send_wait(out) {
                            break 'outer;
                        }
                    }
                }
            }
            handle.stop();
            events.send(GpsEvent::State(LinkState::Disconnected));
        })
        .map_err(|e| format!("cannot start the GPS pump: {e}"))?;
    Ok(Box::new(Pump { stop, thread: Some(thread) }))
}

/// Converts one device event into what the console shows.
fn convert_event(ev: dgps::GpsEvent) -> Vec<GpsEvent> {
    match ev {
        dgps::GpsEvent::Fix(f) => vec![GpsEvent::Fix(crate::hardware::convert_fix(&f))],
        dgps::GpsEvent::Mark(m) => {
            vec![GpsEvent::Notice(format!("mark {} {} in the input", m.number, m.label))]
        }
        dgps::GpsEvent::Stats(s) => {
            let rejected = s.bad_checksum + s.missing_checksum + s.overlong + s.truncated + s.malformed;
            vec![GpsEvent::Notice(format!(
                "{} sentences, {} epochs, {rejected} rejected ({} bad checksums), {} binary frames",
                s.sentences, s.epochs, s.bad_checksum, s.binary_frames
            ))]
        }
        dgps::GpsEvent::State(s) => match s {
            SourceState::Connecting { detail } => {
                vec![GpsEvent::State(LinkState::Connecting { attempt: 1 }), GpsEvent::Notice(detail)]
            }
            SourceState::Live { detail } => vec![GpsEvent::State(LinkState::Live), GpsEvent::Notice(detail)],
            SourceState::Stale => vec![GpsEvent::State(LinkState::Stale)],
            SourceState::Lost { reason } => vec![GpsEvent::State(LinkState::Lost { reason })],
            SourceState::Reconnecting { attempt, delay_ms } => vec![
                GpsEvent::State(LinkState::Connecting { attempt: attempt + 1 }),
                GpsEvent::Notice(format!("retrying in {:.1} s", delay_ms as f64 / 1000.0)),
            ],
            SourceState::Finished => {
                vec![GpsEvent::State(LinkState::Disconnected), GpsEvent::Notice("end of the input".into())]
            }
            SourceState::Stopped => vec![GpsEvent::State(LinkState::Disconnected)],
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simulator_walks_the_demo_route() {
        let route = crate::route::parse_gpx(crate::route::DEMO_GPX).unwrap().waypoints;
        let (tx, rx) = std::sync::mpsc::sync_channel(256);
        let SourceConfig::Simulator { route: r, pace_m_s, model, seed, .. } =
            device_config(&GpsSourceConfig::Simulator, &route, 1).unwrap()
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
        };
        let mut w = open_with(cfg, Outbox::new(tx, None)).unwrap();
        let mut fixes = Vec::new();
        while fixes.len() < 60 {
            if let GpsEvent::Fix(f) = rx.recv_timeout(Duration::from_secs(5)).unwrap() {
                fixes.push(f);
            }
        }
        w.stop();
        // 60 s at 1.4 m/s along the first leg (105.9 m long, bearing 50.9°): 84 m out, give or take the
        // simulated receiver error (~3 m).
        let f = &fixes[59];
        let (d, b) = crate::route::distance_bearing(route[0].lat_deg, route[0].lon_deg, f.lat_deg, f.lon_deg);
        assert!((d - 84.0).abs() < 12.0, "{d}");
        assert!((b - 50.9).abs() < 15.0, "{b}");
        assert!(fixes.iter().all(crate::model::GpsFix::has_position));
        assert!(!f.satellites.is_empty());
    }

    #[test]
    fn missing_replay_file_is_a_clear_error() {
        let src = GpsSourceConfig::Replay { path: "/nonexistent/x.nmea".into(), speed: 1.0 };
        let (tx, _rx) = std::sync::mpsc::sync_channel(4);
        let err = open(&src, &[], Outbox::new(tx, None)).err().unwrap();
        assert!(err.contains("/nonexistent/x.nmea"));
    }
}
