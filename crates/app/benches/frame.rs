//! One frame's CPU time with a 100k-point track and 1,000 waypoints, and the memory cost of 24 h of 1 Hz
//! fixes pushed through the real channels (router, guidance worker, session log, UI state).
//!
//! Run: `cargo bench -p vestnav-app --bench frame`. The memory figure is printed before the timings.

use std::sync::{Arc, Mutex};

use criterion::{Criterion, criterion_group, criterion_main};
use vestnav_app::config::{Config, GpsSourceConfig, VestSourceConfig};
use vestnav_app::console::{Console, ConsoleOptions};
use vestnav_app::devices::{DeviceFactory, VestLink, Worker};
use vestnav_app::model::{FixMode, GpsEvent, GpsFix, Outbox, VestCommand, VestEvent};
use vestnav_app::route::Waypoint;

/// Hands the GPS outbox to the bench so it can push fixes as fast as it likes.
#[derive(Default, Clone)]
struct Tap(Arc<Mutex<Option<Outbox<GpsEvent>>>>);

struct Idle;
impl Worker for Idle {
    fn stop(&mut self) {}
}
struct NullVest;
impl VestLink for NullVest {
    fn send(&self, _c: VestCommand) -> Result<(), String> {
        Ok(())
    }
    fn close(&self) {}
}

impl DeviceFactory for Tap {
    fn open_gps(
        &self,
        _s: &GpsSourceConfig,
        _r: &[Waypoint],
        out: Outbox<GpsEvent>,
    ) -> Result<Box<dyn Worker>, String> {
        *self.0.lock().map_err(|e| e.to_string())? = Some(out);
        Ok(Box::new(Idle))
    }
    fn open_vest(&self, _s: &VestSourceConfig, _e: Outbox<VestEvent>) -> Result<Arc<dyn VestLink>, String> {
        Ok(Arc::new(NullVest))
    }
}

fn fix(k: usize) -> GpsFix {
    let t = k as f64;
    GpsFix {
        lat_deg: 42.3562 + 0.002 * (t / 3000.0).sin(),
        lon_deg: -71.1 + 0.003 * (t / 3000.0).cos(),
        mode: FixMode::Fix3d,
        quality: "GPS".into(),
        error_m: Some(4.0),
        speed_m_s: Some(1.3),
        course_deg: Some((t * 0.1) % 360.0),
        sats_used: Some(8),
        sats_visible: Some(11),
        hdop: Some(1.1),
        ..GpsFix::default()
    }
}

fn rss_kib() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn console(tap: &Tap, log_dir: Option<std::path::PathBuf>) -> Console {
    let cfg = Config { map_tiles: false, ..Config::default() };
    Console::new(Box::new(tap.clone()), ConsoleOptions { cfg, cfg_path: None, log_dir, waker: None })
}

fn frame(ctx: &egui::Context, c: &mut Console, t: f64) {
    let input = egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(1400.0, 880.0))),
        time: Some(t),
        ..egui::RawInput::default()
    };
    let out = ctx.run_ui(input, |ui| c.ui(ui));
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
    let Some(out) = tap.0.lock().ok().and_then(|g| g.clone()) else { return };
    let start = std::time::Instant::now();
    let n = 86_400;
    let mut k = 0;
    while k < n {
        for _ in 0..500 {
            if k >= n {
                break;
            }
            out.send_wait(GpsEvent::Fix(fix(k)));
            k += 1;
        }
        // Let the router drain into the UI channel, then take it in as a frame would.
        std::thread::sleep(std::time::Duration::from_millis(2));
        c.pump(k as f64);
    }
    for _ in 0..50 {
        std::thread::sleep(std::time::Duration::from_millis(5));
        c.pump(n as f64);
    }
    frame(&ctx, &mut c, n as f64);
    let after = rss_kib().unwrap_or(0);
    eprintln!(
        "24 h at 1 Hz: {} fixes pushed in {:.2} s, {} in the track, {} dropped by the bounded channel; RSS {} KiB -> {} KiB (+{} KiB)",
        n,
        start.elapsed().as_secs_f64(),
        c.map.track.len(),
        out.dropped(),
        before,
        after,
        after.saturating_sub(before)
    );
    drop(c);
    let _ = std::fs::remove_dir_all(&dir);
}

fn bench(cr: &mut Criterion) {
    memory_24h();
    let tap = Tap::default();
    let mut c = console(&tap, None);
    c.map.track = (0..100_000).map(|k| (fix(k).lat_deg, fix(k).lon_deg)).collect();
    c.map.waypoints = (0..1000)
        .map(|k| {
            let a = f64::from(k) * 0.00628;
            Waypoint {
                name: format!("W{k}"),
                lat_deg: 42.3572 + 0.0015 * a.sin(),
                lon_deg: -71.1 + 0.002 * a.cos(),
            }
        })
        .collect();
    c.gps.fix = Some(fix(99_999));
    c.gps.fix_at_s = Some(0.0);
    let ctx = egui::Context::default();
    let mut t = 0.0;
    for _ in 0..5 {
        t += 0.016;
        frame(&ctx, &mut c, t);
    }
    cr.bench_function("frame_100k_track_1000_waypoints", |b| {
        b.iter(|| {
            t += 0.016;
            frame(&ctx, &mut c, t);
        });
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
