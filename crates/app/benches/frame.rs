//! One frame's CPU time with a 100k-point track and 1,000 waypoints, and the memory cost of 24 h of 1 Hz
//! fixes pushed through the real channels (the outboxes of the UI, the guidance worker and the session
//! log, as a GPS source feeds them).
//!
//! Run: `cargo bench -p vestnav-app --bench frame`. The memory figure is printed before the timings.

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use vestnav_app::config::{Config, GpsSourceConfig, VestSourceConfig};
use vestnav_app::console::{Console, ConsoleOptions};
use vestnav_device::gps::{ErrorEstimate, ErrorSource, Fix, FixMode, FixQuality, GpsEvent};
use vestnav_device::outbox::Outbox;
use vestnav_device::wtcu::emulator::UnitConfig;
use vestnav_device::wtcu::{VestConfig, VestEvent, VestHandle};
use vestnav_station::devices::{DeviceFactory, GpsWorker};
use vestnav_station::route::Waypoint;

/// Hands the GPS outboxes to the bench so it can push fixes as fast as it likes; the vest is the
/// emulated unit.
#[derive(Default, Clone)]
struct Tap(Arc<Mutex<Vec<Outbox<GpsEvent>>>>);

struct Idle;
impl GpsWorker for Idle {
    fn stop(&mut self) {}
}

impl DeviceFactory for Tap {
    fn open_gps(
        &self,
        _s: &GpsSourceConfig,
        _r: &[Waypoint],
        out: Vec<Outbox<GpsEvent>>,
    ) -> Result<Box<dyn GpsWorker>, String> {
        *self.0.lock().map_err(|e| e.to_string())? = out;
        Ok(Box::new(Idle))
    }
    fn open_vest(&self, _s: &VestSourceConfig, out: Vec<Outbox<VestEvent>>) -> Result<VestHandle, String> {
        VestHandle::spawn(VestConfig::Emulated(UnitConfig::default()), out).map_err(|e| e.to_string())
    }
}

fn fix(k: usize) -> Fix {
    let t = k as f64;
    Fix {
        lat_deg: Some(42.3562 + 0.002 * (t / 3000.0).sin()),
        lon_deg: Some(-71.1 + 0.003 * (t / 3000.0).cos()),
        mode: Some(FixMode::Fix3D),
        quality: Some(FixQuality::Gps),
        error: Some(ErrorEstimate { horizontal_m: 4.0, vertical_m: None, source: ErrorSource::Gst }),
        speed_m_s: Some(1.3),
        course_deg: Some((t * 0.1) % 360.0),
        sats_used: Some(8),
        sats_visible: Some(11),
        hdop: Some(1.1),
        received_at: Some(Instant::now()),
        ..Fix::default()
    }
}

fn rss_kib() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn console(tap: &Tap, log_dir: Option<std::path::PathBuf>) -> Console {
    let cfg = Config { map_tiles: false, ..Config::default() };
    Console::new(Box::new(tap.clone()), ConsoleOptions { cfg, log_dir, ..ConsoleOptions::default() })
}

fn frame(ctx: &egui::Context, c: &mut Console, t: f64) {
    let input = egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(1400.0, 880.0))),
        time: Some(t),
        ..egui::RawInput::default()
    };
    let mut out = ctx.run_ui(input, |ui| c.ui(ui));
    out.textures_delta.clear();
    // Tessellation is part of the CPU cost of a frame (the GPU upload is not).
    let prims = ctx.tessellate(out.shapes, out.pixels_per_point);
    std::hint::black_box(prims);
}

fn memory_24h() {
    let tap = Tap::default();
    let dir = std::env::temp_dir().join(format!("vestnav-bench-{}", std::process::id()));
    let mut c = console(&tap, Some(dir.clone()));
    let ctx = egui::Context::default();
    frame(&ctx, &mut c, 0.0);
    let before = rss_kib().unwrap_or(0);
    let Some(outs) = tap.0.lock().ok().map(|g| g.clone()) else { return };
    let start = std::time::Instant::now();
    let n = 86_400;
    feed(&mut c, &tap, n);
    frame(&ctx, &mut c, n as f64);
    let after = rss_kib().unwrap_or(0);
    eprintln!(
        "24 h at 1 Hz: {} fixes pushed in {:.2} s, {} in the track, {} dropped by the bounded channel; RSS {} KiB -> {} KiB (+{} KiB)",
        n,
        start.elapsed().as_secs_f64(),
        c.station.track().points().len(),
        outs.iter().map(Outbox::dropped).sum::<u64>(),
        before,
        after,
        after.saturating_sub(before)
    );
    drop(c);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Takes `n` fixes into the console's station through its real channels, as a walk would deliver them.
fn feed(c: &mut Console, tap: &Tap, n: usize) {
    let Some(outs) = tap.0.lock().ok().map(|g| g.clone()) else { return };
    let cancel = AtomicBool::new(false);
    let mut k = 0;
    while k < n {
        for _ in 0..500 {
            if k >= n {
                break;
            }
            for out in &outs {
                out.send(GpsEvent::Fix(Box::new(fix(k))), &cancel);
            }
            k += 1;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
        c.pump();
    }
    for _ in 0..20 {
        std::thread::sleep(std::time::Duration::from_millis(5));
        c.pump();
    }
}

/// `n` waypoints on a ring round the walk, or, beyond a thousand, a grid covering the map view.
fn waypoints(n: usize) -> Vec<Waypoint> {
    if n <= 1000 {
        return (0..n)
            .map(|k| {
                let a = k as f64 * 0.00628;
                Waypoint {
                    name: format!("W{k}"),
                    lat_deg: 42.3572 + 0.0015 * a.sin(),
                    lon_deg: -71.1 + 0.002 * a.cos(),
                    arrival_radius_m: None,
                }
            })
            .collect();
    }
    let side = (n as f64).sqrt().ceil() as usize;
    (0..n)
        .map(|k| {
            let (i, j) = ((k / side) as f64, (k % side) as f64);
            Waypoint::new(format!("W{k}"), 42.3555 + i * 3e-5, -71.1025 + j * 4e-5)
        })
        .collect()
}

fn bench(cr: &mut Criterion) {
    memory_24h();
    let ctx = egui::Context::default();
    let mut t = 0.0;
    for (name, track, route) in [
        ("frame_100k_track_1000_waypoints", 100_000, 1000),
        // The documented limits: the most waypoints a route takes, the most track points kept.
        (
            "frame_at_limits_200k_track_10000_waypoints",
            vestnav_station::route::TRACK_MAX_POINTS,
            vestnav_station::route::MAX_WAYPOINTS,
        ),
    ] {
        let tap = Tap::default();
        let mut c = console(&tap, None);
        c.station.route_mut().replace("bench".into(), waypoints(route)).unwrap_or_default();
        feed(&mut c, &tap, track);
        eprintln!(
            "{name}: {} track points, {} waypoints",
            c.station.track().points().len(),
            c.station.route().waypoints().len()
        );
        for _ in 0..5 {
            t += 0.016;
            frame(&ctx, &mut c, t);
        }
        cr.bench_function(name, |b| {
            b.iter(|| {
                t += 0.016;
                frame(&ctx, &mut c, t);
            });
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
