//! The stop path under attack: the console's real worker threads (GPS source, vest worker, guidance,
//! session log) against a hostile gpsd on 127.0.0.1 and a WTCU on a real PTY, and the real binary ended
//! by signals.
//!
//! The unit side is the device crate's `Engine` (the unit's half of the real protocol) served on the
//! master of a PTY pair; the console opens the slave exactly as it opens `/dev/rfcomm0`. Every command the
//! unit accepts is logged with the instant its frame arrived, so the tests measure what reached the vest,
//! not what the console meant to send.

#![cfg(unix)]

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use vestnav_app::config::{Config, GpsSourceConfig, VestSourceConfig};
use vestnav_app::console::{Console, ConsoleOptions, Liveness};
use vestnav_app::hardware::Hardware;
use vestnav_device::wtcu::CommandKind;
use vestnav_device::wtcu::emulator::UnitConfig;
use vestnav_device::wtcu::emulator::{Pty, SERVE_POLL};
use vestnav_device::wtcu::engine::EngineEvent;

/// A WTCU on the master of a PTY pair, logging what it accepted and when.
struct Unit {
    path: String,
    log: Arc<Mutex<Vec<(Instant, EngineEvent)>>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Unit {
    fn spawn() -> Self {
        let Pty { mut master, path, slave } = Pty::open_with_timeout(SERVE_POLL).unwrap();
        let log = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let (l, s) = (log.clone(), stop.clone());
        let thread = std::thread::spawn(move || {
            let _slave = slave;
            let mut engine = UnitConfig::default().build();
            let mut buf = [0u8; 1024];
            while !s.load(Ordering::Relaxed) {
                match master.read(&mut buf) {
                    Ok(0) => break,
                    Ok(n) => engine.handle_bytes(&buf[..n], Instant::now()),
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                        ) => {}
                    Err(_) => std::thread::sleep(Duration::from_millis(5)),
                }
                let now = Instant::now();
                engine.handle_timeout(now);
                while let Some(frame) = engine.poll_transmit() {
                    let _ = master.write_all(&frame);
                }
                let mut l = l.lock().unwrap();
                while let Some(ev) = engine.poll_event() {
                    l.push((now, ev));
                }
            }
        });
        Self { path, log, stop, thread: Some(thread) }
    }

    /// When the unit accepted commands of `kind`, in order.
    fn accepted(&self, kind: CommandKind) -> Vec<Instant> {
        let log = self.log.lock().unwrap();
        log.iter()
            .filter_map(|(t, e)| {
                matches!(e, EngineEvent::Accepted { kind: k, .. } if *k == kind).then_some(*t)
            })
            .collect()
    }

    fn ready(&self) -> bool {
        self.log.lock().unwrap().iter().any(|(_, e)| matches!(e, EngineEvent::SessionStarted))
    }
}

impl Drop for Unit {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// How the fake gpsd misbehaves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Hostile {
    /// Valid moving fixes at 10 Hz with absurd ones among them (lon -1e15, lat 91/lon 181, lat 9999, 1e20).
    Absurd,
    /// One byte every 50 ms, never a newline.
    Trickle,
    /// A line with no newline, as fast as the socket takes it (up to 200 MB).
    Endless,
    /// Valid TPVs as fast as the socket takes them.
    Flood,
    /// Half a TPV, then the connection closes; again on every reconnect.
    CloseMidLine,
}

/// A TPV `d_m` metres south of the demo route's first waypoint, walking south (away from it).
fn tpv(k: u64, lat: f64, lon: f64) -> String {
    let secs = 1_700_000_000 + k;
    let t = chrono::DateTime::from_timestamp(i64::try_from(secs).unwrap(), 0).unwrap();
    format!(
        "{{\"class\":\"TPV\",\"device\":\"/dev/fake\",\"mode\":3,\"time\":\"{}\",\"lat\":{lat},\"lon\":{lon},\
         \"altMSL\":10.0,\"speed\":1.4,\"track\":180.0,\"eph\":3.0}}\n",
        t.to_rfc3339_opts(chrono::SecondsFormat::Millis, true)
    )
}

/// A fake gpsd on 127.0.0.1 that stops by itself after `life`.
struct FakeGpsd {
    port: u16,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl FakeGpsd {
    fn spawn(mode: Hostile, life: Duration) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        listener.set_nonblocking(true).unwrap();
        let port = listener.local_addr().unwrap().port();
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        let thread = std::thread::spawn(move || {
            let end = Instant::now() + life;
            while !s.load(Ordering::Relaxed) && Instant::now() < end {
                match listener.accept() {
                    Ok((stream, _)) => serve(stream, mode, &s, end),
                    Err(_) => std::thread::sleep(Duration::from_millis(5)),
                }
            }
        });
        Self { port, stop, thread: Some(thread) }
    }
}

impl Drop for FakeGpsd {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn serve(mut s: TcpStream, mode: Hostile, stop: &AtomicBool, end: Instant) {
    let _ = s.set_nodelay(true);
    let _ = s.set_write_timeout(Some(Duration::from_millis(200)));
    let live = || !stop.load(Ordering::Relaxed) && Instant::now() < end;
    let _ =
        s.write_all(b"{\"class\":\"VERSION\",\"release\":\"3.22\",\"proto_major\":3,\"proto_minor\":14}\n");
    let mut k = 0u64;
    match mode {
        Hostile::Absurd => {
            let absurd =
                [(42.3558, -1e15), (91.0, 181.0), (9999.0, -71.1), (1e20, -71.1), (42.3558, f64::MAX)];
            while live() {
                k += 1;
                let lat = 42.3558 - 0.000_01 * (k % 50) as f64;
                let line = if k.is_multiple_of(5) {
                    let (a, b) = absurd[(k / 5) as usize % absurd.len()];
                    tpv(k, a, b)
                } else {
                    tpv(k, lat, -71.1)
                };
                if s.write_all(line.as_bytes()).is_err() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(100));
            }
        }
        Hostile::Trickle => {
            while live() {
                if s.write_all(b"x").is_err() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        }
        Hostile::Endless => {
            let chunk = vec![b'x'; 64 * 1024];
            let mut sent = 0usize;
            while live() && sent < 200 << 20 {
                match s.write(&chunk) {
                    Ok(n) => sent += n,
                    Err(e)
                        if e.kind() == std::io::ErrorKind::WouldBlock
                            || e.kind() == std::io::ErrorKind::TimedOut => {}
                    Err(_) => return,
                }
            }
        }
        Hostile::Flood => {
            while live() {
                k += 1;
                if s.write_all(tpv(k, 42.3558, -71.1).as_bytes()).is_err() {
                    return;
                }
            }
        }
        Hostile::CloseMidLine => {
            let line = tpv(1, 42.3558, -71.1);
            let _ = s.write_all(&line.as_bytes()[..line.len() / 2]);
        }
    }
}

fn rss_kib() -> u64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines()
        .find(|l| l.starts_with("VmRSS:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(0)
}

/// Liveness bounds for the tests whose subject is not liveness: generous, so a loaded CI machine does not
/// trip them (the stalled-UI test uses the console's defaults).
const RELAXED: Liveness = Liveness { ui: Duration::from_secs(5), guidance: Duration::from_secs(5) };

fn console(gpsd_port: u16, vest_path: &str, log_dir: Option<std::path::PathBuf>) -> Console {
    console_with(gpsd_port, vest_path, log_dir, RELAXED)
}

fn console_with(
    gpsd_port: u16,
    vest_path: &str,
    log_dir: Option<std::path::PathBuf>,
    liveness: Liveness,
) -> Console {
    let cfg = Config {
        gps: GpsSourceConfig::Gpsd { host: "127.0.0.1".into(), port: gpsd_port },
        vest: VestSourceConfig::Serial { port: vest_path.to_owned() },
        map_tiles: false,
        guidance_auto: true,
        cue_interval_s: 1.0,
        ..Config::default()
    };
    Console::new(
        Box::new(Hardware::default()),
        ConsoleOptions { cfg, log_dir, liveness: Some(liveness), ..ConsoleOptions::default() },
    )
}

/// Runs the UI thread's work (drain + one drawn frame) for `d`.
fn run_ui(c: &mut Console, ctx: &egui::Context, d: Duration) {
    let end = Instant::now() + d;
    while Instant::now() < end {
        let input = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(1400.0, 880.0))),
            ..egui::RawInput::default()
        };
        let mut out = ctx.run_ui(input, |ui| c.ui(ui));
        out.textures_delta.clear();
        std::thread::sleep(Duration::from_millis(16));
    }
}

/// STOP ALL from the button's code path, and how long until the unit accepted it.
fn stop_latency(c: &mut Console, unit: &Unit) -> Duration {
    let before = unit.accepted(CommandKind::StopAll).len();
    let t0 = Instant::now();
    c.stop_all();
    let end = t0 + Duration::from_secs(2);
    while Instant::now() < end {
        if let Some(t) = unit.accepted(CommandKind::StopAll).get(before) {
            return t.saturating_duration_since(t0);
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    panic!("STOP ALL never reached the unit");
}

fn wait_for(what: &str, d: Duration, mut ok: impl FnMut() -> bool) {
    let end = Instant::now() + d;
    while Instant::now() < end {
        if ok() {
            return;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    panic!("timed out waiting for {what}");
}

/// Each hostile gpsd in turn: the console keeps drawing, STOP ALL reaches the unit within 50 ms, memory
/// stays bounded, and disconnecting the GPS does not block.
#[test]
fn stop_all_reaches_the_vest_within_50_ms_whatever_gpsd_sends() {
    let _exclusive = crate::timing_exclusive();
    for mode in [Hostile::Absurd, Hostile::Trickle, Hostile::Endless, Hostile::Flood, Hostile::CloseMidLine] {
        let unit = Unit::spawn();
        let gpsd = FakeGpsd::spawn(mode, Duration::from_secs(20));
        let dir = std::env::temp_dir().join(format!("vestnav-safety-{}-{mode:?}", std::process::id()));
        let mut c = console(gpsd.port, &unit.path, Some(dir.clone()));
        let ctx = egui::Context::default();
        wait_for("the unit's handshake", Duration::from_secs(5), || {
            c.tick();
            unit.ready()
        });
        let rss0 = rss_kib();
        run_ui(&mut c, &ctx, Duration::from_secs(2));
        let lat = stop_latency(&mut c, &unit);
        eprintln!("{mode:?}: STOP ALL reached the unit after {:.2} ms", lat.as_secs_f64() * 1e3);
        assert!(lat < Duration::from_millis(50), "{mode:?}: STOP ALL took {lat:?}");
        run_ui(&mut c, &ctx, Duration::from_millis(500));
        let grown_mib = rss_kib().saturating_sub(rss0) / 1024;
        eprintln!("{mode:?}: RSS grew by {grown_mib} MiB");
        assert!(grown_mib < 100, "{mode:?}: memory grew by {grown_mib} MiB");
        if mode == Hostile::Absurd {
            let shown = c.gps.last_position.as_ref().and_then(|f| f.lon_deg);
            assert!(shown.is_some_and(|lon| (-180.0..=180.0).contains(&lon)), "{shown:?}");
            assert!(c.map.track.iter().all(|p| p.lat_deg.abs() <= 90.0 && p.lon_deg.abs() <= 180.0));
        }
        let t0 = Instant::now();
        c.disconnect_gps();
        assert!(t0.elapsed() < Duration::from_millis(400), "{mode:?}: disconnect took {:?}", t0.elapsed());
        let t0 = Instant::now();
        c.shutdown();
        assert!(t0.elapsed() < Duration::from_millis(400), "{mode:?}: shutdown took {:?}", t0.elapsed());
        drop(c);
        if let Ok(entries) = std::fs::read_dir(&dir) {
            for e in entries.flatten() {
                let len = e.metadata().map_or(0, |m| m.len());
                assert!(len < 8 << 20, "{mode:?}: session log {} is {len} bytes", e.path().display());
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// After STOP ALL no automatic pattern reaches the unit until the operator resumes; then cues come again.
#[test]
fn guidance_cannot_start_a_pattern_after_stop_until_resumed() {
    let unit = Unit::spawn();
    let gpsd = FakeGpsd::spawn(Hostile::Absurd, Duration::from_secs(20));
    let mut c = console(gpsd.port, &unit.path, None);
    let ctx = egui::Context::default();
    wait_for("an automatic cue", Duration::from_secs(8), || {
        run_ui(&mut c, &ctx, Duration::from_millis(50));
        !unit.accepted(CommandKind::Play).is_empty()
    });
    let lat = stop_latency(&mut c, &unit);
    assert!(lat < Duration::from_millis(50), "{lat:?}");
    let stopped_at = Instant::now();
    run_ui(&mut c, &ctx, Duration::from_secs(3));
    let after: Vec<_> = unit.accepted(CommandKind::Play).into_iter().filter(|t| *t > stopped_at).collect();
    assert!(after.is_empty(), "{} automatic patterns after STOP ALL", after.len());
    assert!(c.vest.halted.is_some(), "the screen shows guidance halted");
    c.resume_guidance();
    let resumed_at = Instant::now();
    wait_for("a cue after resuming", Duration::from_secs(8), || {
        run_ui(&mut c, &ctx, Duration::from_millis(50));
        unit.accepted(CommandKind::Play).iter().any(|t| *t > resumed_at)
    });
}

/// A stalled UI thread: the vest worker stops the tactors by itself within the liveness bound.
#[test]
fn a_stalled_ui_stops_the_vest_by_itself() {
    let unit = Unit::spawn();
    let gpsd = FakeGpsd::spawn(Hostile::Absurd, Duration::from_secs(20));
    // The console's own UI bound; guidance's is relaxed so that only the UI's stall is under test.
    let liveness = Liveness { guidance: Duration::from_secs(5), ..Liveness::default() };
    let mut c = console_with(gpsd.port, &unit.path, None, liveness);
    let ctx = egui::Context::default();
    wait_for("an automatic cue", Duration::from_secs(8), || {
        run_ui(&mut c, &ctx, Duration::from_millis(50));
        !unit.accepted(CommandKind::Play).is_empty()
    });
    let before = unit.accepted(CommandKind::StopAll).len();
    // The UI thread stops drawing (a stall): nobody could press STOP ALL now.
    let stalled_at = Instant::now();
    wait_for("the liveness stop", Duration::from_secs(5), || {
        unit.accepted(CommandKind::StopAll).len() > before
    });
    let t = unit.accepted(CommandKind::StopAll)[before].saturating_duration_since(stalled_at);
    let bound = Liveness::default().ui;
    eprintln!(
        "UI stalled: the unit got STOP ALL after {:.0} ms (bound {:.0} ms)",
        t.as_secs_f64() * 1e3,
        bound.as_secs_f64() * 1e3
    );
    assert!(t < bound + Duration::from_millis(200), "{t:?}");
    std::thread::sleep(Duration::from_secs(2));
    let plays_after: Vec<_> =
        unit.accepted(CommandKind::Play).into_iter().filter(|p| *p > stalled_at + t).collect();
    assert!(plays_after.is_empty(), "automatic cues went on while the UI was stalled");
    run_ui(&mut c, &ctx, Duration::from_millis(100));
    assert!(c.vest.halted.as_deref().is_some_and(|r| r.contains("console UI")), "{:?}", c.vest.halted);
}

/// The real binary, ended by SIGTERM, SIGINT and SIGHUP while guidance plays: STOP ALL reaches the unit
/// within 200 ms of the signal. Needs an X server: runs under Xvfb when it is installed (CI installs it).
#[test]
fn signals_stop_the_vest_before_the_process_exits() {
    let _exclusive = crate::timing_exclusive();
    let Some(mut xvfb) = Xvfb::start() else {
        eprintln!("signals_stop_the_vest_before_the_process_exits: no Xvfb on this machine, skipped");
        return;
    };
    for (sig, name) in [(15, "TERM"), (2, "INT"), (1, "HUP")] {
        let unit = Unit::spawn();
        let gpsd = FakeGpsd::spawn(Hostile::Absurd, Duration::from_secs(30));
        let home = std::env::temp_dir().join(format!("vestnav-sig-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&home).unwrap();
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_vestnav"))
            .args([
                "--gps",
                &format!("gpsd://127.0.0.1:{}", gpsd.port),
                "--vest",
                &format!("serial:{}", unit.path),
            ])
            .env("DISPLAY", &xvfb.display)
            .env("HOME", &home)
            .env("XDG_CONFIG_HOME", home.join("config"))
            .env("XDG_DATA_HOME", home.join("data"))
            .env("XDG_CACHE_HOME", home.join("cache"))
            .env_remove("WAYLAND_DISPLAY")
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::inherit())
            .spawn()
            .unwrap();
        let played = {
            let end = Instant::now() + Duration::from_secs(20);
            loop {
                if !unit.accepted(CommandKind::Play).is_empty() {
                    break true;
                }
                if Instant::now() > end || child.try_wait().unwrap().is_some() {
                    break false;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        };
        if !played {
            let _ = child.kill();
            let status = child.wait().unwrap();
            let log =
                unit.log.lock().unwrap().iter().map(|(_, e)| format!("{e:?}")).collect::<Vec<_>>().join("\n");
            panic!("SIG{name}: the console never guided ({status}); the unit saw:\n{log}");
        }
        let before = unit.accepted(CommandKind::StopAll).len();
        let t0 = Instant::now();
        let ok = std::process::Command::new("kill")
            .arg(format!("-{name}"))
            .arg(child.id().to_string())
            .status()
            .unwrap();
        assert!(ok.success());
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            assert!(t0.elapsed() < Duration::from_secs(3), "SIG{name}: the console did not exit");
            std::thread::sleep(Duration::from_millis(2));
        };
        let exited = t0.elapsed();
        let stops = unit.accepted(CommandKind::StopAll);
        let stop = stops.get(before).map(|t| t.saturating_duration_since(t0));
        eprintln!("SIG{name}: STOP ALL at the unit after {stop:?}, process gone after {exited:?}, {status}");
        let stop = stop.unwrap_or_else(|| panic!("SIG{name}: no STOP ALL reached the unit"));
        assert!(stop < Duration::from_millis(200), "SIG{name}: {stop:?}");
        assert_eq!(std::os::unix::process::ExitStatusExt::signal(&status), None);
        assert_eq!(status.code(), Some(128 + sig));
        let _ = std::fs::remove_dir_all(&home);
    }
    xvfb.stop();
}

/// An Xvfb server on a free display number, for the real window.
struct Xvfb {
    child: std::process::Child,
    display: String,
}

impl Xvfb {
    fn start() -> Option<Self> {
        for n in 90..110 {
            if std::path::Path::new(&format!("/tmp/.X11-unix/X{n}")).exists() {
                continue;
            }
            let display = format!(":{n}");
            let mut child = std::process::Command::new("Xvfb")
                .args([&display, "-screen", "0", "1600x1000x24", "-nolisten", "tcp"])
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::null())
                .spawn()
                .ok()?;
            let end = Instant::now() + Duration::from_secs(5);
            while Instant::now() < end {
                if std::path::Path::new(&format!("/tmp/.X11-unix/X{n}")).exists() {
                    return Some(Self { child, display });
                }
                if child.try_wait().ok().flatten().is_some() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            let _ = child.kill();
        }
        None
    }

    fn stop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        self.stop();
    }
}

/// `vestnav ... | head`: the reader goes away; every CLI command that streams output ends quietly with
/// the shell's broken-pipe status, never a panic.
#[test]
fn broken_pipes_end_cli_commands_quietly() {
    let logs = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gpsd-logs");
    let mut big = Vec::new();
    for _ in 0..8 {
        for e in std::fs::read_dir(&logs).unwrap().flatten() {
            if e.path().extension().is_some_and(|x| x == "log") {
                big.extend(std::fs::read(e.path()).unwrap());
            }
        }
    }
    let nmea = std::env::temp_dir().join(format!("vestnav-pipe-{}.nmea", std::process::id()));
    std::fs::write(&nmea, &big).unwrap();
    let session = std::env::temp_dir().join(format!("vestnav-pipe-{}.jsonl", std::process::id()));
    let lines: Vec<String> = (0..4000)
        .map(|i| {
            format!(
                "{{\"t_s\":{i}.0,\"utc\":\"2026-06-15T15:00:00.000Z\",\"kind\":\"fix\",\"lat_deg\":{},\
                 \"lon_deg\":-71.0936,\"error_m\":null,\"speed_m_s\":null,\"course_deg\":null,\"gps_utc\":null}}",
                42.3581 + 1e-6 * f64::from(i % 7)
            )
        })
        .collect();
    std::fs::write(&session, lines.join("\n") + "\n").unwrap();
    let (n, s) = (nmea.to_str().unwrap(), session.to_str().unwrap());
    for args in [
        vec!["nmea", "decode", n, "--json"],
        vec!["nmea", "decode", n],
        vec!["fieldtest", "drift", s, "--json"],
        vec!["fieldtest", "drift", s],
    ] {
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_vestnav"))
            .args(&args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let mut first = [0u8; 16];
        let mut out = child.stdout.take().unwrap();
        let _ = out.read(&mut first);
        drop(out);
        let done = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&done.stderr);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(!err.contains("Broken pipe"), "{args:?}: {err}");
        assert!(matches!(done.status.code(), Some(0 | 141)), "{args:?}: {:?} {err}", done.status);
    }
    let _ = std::fs::remove_file(nmea);
    let _ = std::fs::remove_file(session);
}
