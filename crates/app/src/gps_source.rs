//! GPS workers for each source kind, reporting [`GpsEvent`]s to the console.
//!
//! The simulator walks the console's route with `vestnav_core::gnss_sim` (SiRF Star III open-sky error
//! model: wandering bias, white noise, static navigation below 1.2 m/s) at 1 Hz of wall-clock time and starts
//! over when the route is finished, so the demo never stops.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use vestnav_core::gnss_sim::{GnssErrorModel, GnssErrorState, RouteWalker};

use crate::config::GpsSourceConfig;
use crate::devices::Worker;
use crate::model::{FixMode, GpsEvent, GpsFix, LinkState, Outbox};
use crate::route::Waypoint;

/// Walking pace of the simulated wearer [m/s] (a brisk walk, above the static-navigation threshold).
pub const SIM_PACE_M_S: f64 = 1.4;

/// A worker thread that stops when asked or dropped.
struct Thread {
    stop: Arc<AtomicBool>,
    handle: Option<std::thread::JoinHandle<()>>,
}

impl Worker for Thread {
    fn stop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

impl Drop for Thread {
    fn drop(&mut self) {
        Worker::stop(self);
    }
}

/// Starts the worker for `source`.
pub fn open(source: &GpsSourceConfig, route: &[Waypoint], events: Outbox<GpsEvent>) -> Result<Box<dyn Worker>, String> {
    match source {
        GpsSourceConfig::Simulator => simulator(route, events, Duration::from_secs(1)),
        other => crate::gps_device::open(other, events),
    }
}

/// The simulator, one fix per `period` of wall-clock time.
pub fn simulator(route: &[Waypoint], events: Outbox<GpsEvent>, period: Duration) -> Result<Box<dyn Worker>, String> {
    let pts: Vec<(f64, f64)> = route.iter().map(|w| (w.lat_deg, w.lon_deg)).collect();
    let walker = RouteWalker::new(&pts, SIM_PACE_M_S).map_err(|e| format!("simulator: {e}"))?;
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let handle = std::thread::Builder::new()
        .name("vestnav-gps-sim".into())
        .spawn(move || {
            let model = GnssErrorModel::sirf3_open_sky();
            let mut err = GnssErrorState::new(model, 2026);
            let dt_s = 1.0;
            let loop_s = walker.length_m() / SIM_PACE_M_S + 10.0;
            let mut k = 0u64;
            let mut last: Option<(f64, f64)> = None;
            events.send(GpsEvent::State(LinkState::Live));
            let start = Instant::now();
            while !flag.load(Ordering::SeqCst) {
                let t_s = (k as f64 * dt_s) % loop_s;
                let s = walker.sample(t_s);
                let p = err.apply(dt_s, s.en_m, s.speed_m_s);
                let (lat, lon) = walker.frame().latlon_from_en(p);
                // Reported speed and course come from the reported positions, as a receiver's Doppler-free
                // solution would: zero while static navigation pins the position.
                let (speed, course) = match last {
                    Some((la, lo)) => {
                        let (d, b) = crate::route::distance_bearing(la, lo, lat, lon);
                        (d / dt_s, if d > 0.05 { Some(b) } else { None })
                    }
                    None => (0.0, None),
                };
                last = Some((lat, lon));
                let fix = GpsFix {
                    time_utc: Some(chrono::Utc::now().to_rfc3339_opts(chrono::SecondsFormat::Millis, true)),
                    lat_deg: lat,
                    lon_deg: lon,
                    alt_m: Some(5.0),
                    mode: FixMode::Fix3d,
                    quality: "Simulation".into(),
                    error_m: Some(model.horizontal_rms_m()),
                    speed_m_s: Some(speed),
                    course_deg: course,
                    ..GpsFix::default()
                };
                if !events.send(GpsEvent::Fix(fix)) {
                    break;
                }
                k += 1;
                // Sleep to the next epoch in small steps so a stop request is served quickly.
                let due = start + period.mul_f64(k as f64);
                while !flag.load(Ordering::SeqCst) {
                    let now = Instant::now();
                    if now >= due {
                        break;
                    }
                    std::thread::sleep((due - now).min(Duration::from_millis(50)));
                }
            }
            events.send(GpsEvent::State(LinkState::Disconnected));
        })
        .map_err(|e| format!("cannot start the GPS simulator: {e}"))?;
    Ok(Box::new(Thread { stop, handle: Some(handle) }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simulator_walks_the_demo_route() {
        let route = crate::route::parse_gpx(crate::route::DEMO_GPX).unwrap().waypoints;
        let (tx, rx) = std::sync::mpsc::sync_channel(256);
        let mut w = simulator(&route, Outbox::new(tx, None), Duration::from_millis(5)).unwrap();
        let mut fixes = Vec::new();
        while fixes.len() < 60 {
            match rx.recv_timeout(Duration::from_secs(5)).unwrap() {
                GpsEvent::Fix(f) => fixes.push(f),
                _ => {}
            }
        }
        w.stop();
        // 60 s at 1.4 m/s along the first leg (~105 m long, heading ~50°): about 80 m from the start.
        let (d, b) = crate::route::distance_bearing(route[0].lat_deg, route[0].lon_deg, fixes[59].lat_deg, fixes[59].lon_deg);
        assert!((d - 84.0).abs() < 12.0, "{d}");
        assert!((b - 50.0).abs() < 15.0, "{b}");
        assert!(fixes.iter().all(GpsFix::has_position));
    }
}
