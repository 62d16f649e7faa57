//! The stop path under attack: the station's real worker threads (GPS source, vest worker, guidance,
//! session log), with no window, against a hostile gpsd on 127.0.0.1 and a WTCU on a real PTY; the console
//! with the largest route it accepts; and the real binary ended by signals.
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

use vestnav_core::vest::TactorMask;
use vestnav_device::wtcu::emulator::UnitConfig;
use vestnav_device::wtcu::emulator::{Pty, SERVE_POLL};
use vestnav_device::wtcu::engine::EngineEvent;
use vestnav_device::wtcu::message::Faults;
use vestnav_device::wtcu::{CommandKind, FrameCodec, Reply, WireCodec as _};
use vestnav_station::hardware::Hardware;
use vestnav_station::sources::{GpsSourceConfig, VestSourceConfig};
use vestnav_station::{Liveness, Station, StationOptions, StationSettings};

/// How the unit on the PTY behaves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Behaviour {
    /// The emulated unit, as the protocol document says.
    Honest,
    /// Never acknowledges STOP ALL; from the first STOP ALL on, every reply (acks, reports, status) says
    /// `on` is running.
    NeverAcksStop { on: TactorMask },
    /// Every reply leaves the unit this late.
    Late(Duration),
    /// Answers as the engine does, and floods REPORT frames between its replies.
    Flood,
}

/// A WTCU on the master of a PTY pair, logging what it received and accepted, and when.
struct Unit {
    path: String,
    log: Arc<Mutex<Vec<(Instant, EngineEvent)>>>,
    /// Every request frame that reached the unit (accepted or not), with its arrival.
    received: Arc<Mutex<Vec<(Instant, CommandKind)>>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Unit {
    fn spawn() -> Self {
        Self::spawn_as(Behaviour::Honest)
    }

    #[allow(clippy::too_many_lines)]
    fn spawn_as(behaviour: Behaviour) -> Self {
        let Pty { mut master, path, slave } = Pty::open_with_timeout(SERVE_POLL).unwrap();
        let log = Arc::new(Mutex::new(Vec::new()));
        let received = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let (l, r, s) = (log.clone(), received.clone(), stop.clone());
        let thread = std::thread::spawn(move || {
            let _slave = slave;
            let mut engine = UnitConfig::default().build();
            let mut requests = FrameCodec::new();
            let (mut replies_in, mut replies_out) = (FrameCodec::new(), FrameCodec::new());
            let mut stop_seqs: Vec<u8> = Vec::new();
            let mut hostile_since_stop = false;
            let mut delayed: std::collections::VecDeque<(Instant, Vec<u8>)> =
                std::collections::VecDeque::new();
            let mut buf = [0u8; 1024];
            while !s.load(Ordering::Relaxed) {
                match master.read(&mut buf) {
                    Ok(0) => break,
                    Ok(n) => {
                        let now = Instant::now();
                        let mut out = Vec::new();
                        requests.decode_requests(&buf[..n], &mut out);
                        for p in out.into_iter().flatten() {
                            let kind = p.message.kind();
                            if kind == CommandKind::StopAll {
                                stop_seqs.push(p.seq);
                                hostile_since_stop = true;
                            }
                            r.lock().unwrap().push((now, kind));
                        }
                        engine.handle_bytes(&buf[..n], now);
                    }
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                        ) => {}
                    Err(_) => std::thread::sleep(Duration::from_millis(5)),
                }
                let now = Instant::now();
                engine.handle_timeout(now);
                replies_out.set_version(engine.session_version());
                while let Some(frame) = engine.poll_transmit() {
                    match behaviour {
                        Behaviour::Honest => {
                            let _ = master.write_all(&frame);
                        }
                        Behaviour::Late(d) => delayed.push_back((now + d, frame)),
                        Behaviour::Flood => {
                            let _ = master.write_all(&frame);
                            let report = Reply::Report { tactors_on: TactorMask::NONE, faults: Faults(0) };
                            for _ in 0..20 {
                                let _ = master.write_all(&replies_out.encode_reply(0, &report));
                            }
                        }
                        Behaviour::NeverAcksStop { on } => {
                            let mut decoded = Vec::new();
                            replies_in.decode_replies(&frame, &mut decoded);
                            for p in decoded.into_iter().flatten() {
                                let message = match p.message {
                                    Reply::Ack { .. } if stop_seqs.contains(&p.seq) => continue,
                                    Reply::Ack { .. } if hostile_since_stop => Reply::Ack { tactors_on: on },
                                    Reply::Report { faults, .. } if hostile_since_stop => {
                                        Reply::Report { tactors_on: on, faults }
                                    }
                                    Reply::Status(mut st) if hostile_since_stop => {
                                        st.tactors_on = on;
                                        Reply::Status(st)
                                    }
                                    m => m,
                                };
                                let _ = master.write_all(&replies_out.encode_reply(p.seq, &message));
                            }
                        }
                    }
                }
                if let Behaviour::NeverAcksStop { on } = behaviour
                    && hostile_since_stop
                {
                    // Its REPORTs keep saying the tactors run.
                    let report = Reply::Report { tactors_on: on, faults: Faults(0) };
                    let _ = master.write_all(&replies_out.encode_reply(0, &report));
                    std::thread::sleep(Duration::from_millis(5));
                }
                while delayed.front().is_some_and(|(t, _)| *t <= now) {
                    if let Some((_, f)) = delayed.pop_front() {
                        let _ = master.write_all(&f);
                    }
                }
                let mut l = l.lock().unwrap();
                while let Some(ev) = engine.poll_event() {
                    l.push((now, ev));
                }
            }
        });
        Self { path, log, received, stop, thread: Some(thread) }
    }

    /// When request frames of `kind` reached the unit, accepted or not.
    fn received(&self, kind: CommandKind) -> Vec<Instant> {
        self.received.lock().unwrap().iter().filter(|(_, k)| *k == kind).map(|(t, _)| *t).collect()
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
/// trip them (the stalled-view test uses the defaults).
const RELAXED: Liveness = Liveness { view: Some(Duration::from_secs(5)), guidance: Duration::from_secs(5) };

fn station(gpsd_port: u16, vest_path: &str, log_dir: Option<std::path::PathBuf>) -> Station {
    station_with(gpsd_port, vest_path, log_dir, RELAXED)
}

fn station_with(
    gpsd_port: u16,
    vest_path: &str,
    log_dir: Option<std::path::PathBuf>,
    liveness: Liveness,
) -> Station {
    let mut settings = StationSettings::default();
    settings.guidance.auto = true;
    settings.guidance.cue_interval_s = 1.0;
    let mut s = Station::new(
        Box::new(Hardware::default()),
        StationOptions {
            settings,
            gps: Some(GpsSourceConfig::Gpsd { host: "127.0.0.1".into(), port: gpsd_port }),
            vest: Some(VestSourceConfig::Serial { port: vest_path.to_owned() }),
            log_dir,
            liveness: Some(liveness),
            ..StationOptions::default()
        },
    );
    s.connect_vest();
    s.connect_gps(Vec::new());
    s
}

/// Runs a view's turns (the station's pump, as a window's frame or `vestnav station`'s loop would) for `d`.
fn run_view(c: &mut Station, d: Duration) {
    let end = Instant::now() + d;
    while Instant::now() < end {
        c.pump(|_| {});
        std::thread::sleep(Duration::from_millis(16));
    }
}

/// STOP ALL from the operator's code path, and how long until the unit accepted it.
fn stop_latency(c: &mut Station, unit: &Unit) -> Duration {
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
        let mut c = station(gpsd.port, &unit.path, Some(dir.clone()));
        wait_for("the unit's handshake", Duration::from_secs(5), || {
            c.pump(|_| {});
            unit.ready()
        });
        let rss0 = rss_kib();
        run_view(&mut c, Duration::from_secs(2));
        let lat = stop_latency(&mut c, &unit);
        eprintln!("{mode:?}: STOP ALL reached the unit after {:.2} ms", lat.as_secs_f64() * 1e3);
        assert!(lat < Duration::from_millis(50), "{mode:?}: STOP ALL took {lat:?}");
        run_view(&mut c, Duration::from_millis(500));
        let grown_mib = rss_kib().saturating_sub(rss0) / 1024;
        eprintln!("{mode:?}: RSS grew by {grown_mib} MiB");
        assert!(grown_mib < 100, "{mode:?}: memory grew by {grown_mib} MiB");
        if mode == Hostile::Absurd {
            let shown = c.gps.last_position.as_ref().and_then(|f| f.lon_deg);
            assert!(shown.is_some_and(|lon| (-180.0..=180.0).contains(&lon)), "{shown:?}");
            assert!(c.track().points().iter().all(|p| p.lat_deg.abs() <= 90.0 && p.lon_deg.abs() <= 180.0));
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
    let _exclusive = crate::timing_exclusive();
    let unit = Unit::spawn();
    let gpsd = FakeGpsd::spawn(Hostile::Absurd, Duration::from_secs(20));
    let mut c = station(gpsd.port, &unit.path, None);
    wait_for("an automatic cue", Duration::from_secs(8), || {
        run_view(&mut c, Duration::from_millis(50));
        !unit.accepted(CommandKind::Play).is_empty()
    });
    let lat = stop_latency(&mut c, &unit);
    assert!(lat < Duration::from_millis(50), "{lat:?}");
    let stopped_at = Instant::now();
    run_view(&mut c, Duration::from_secs(3));
    let after: Vec<_> = unit.accepted(CommandKind::Play).into_iter().filter(|t| *t > stopped_at).collect();
    assert!(after.is_empty(), "{} automatic patterns after STOP ALL", after.len());
    assert!(c.vest.halted.is_some(), "the screen shows guidance halted");
    c.resume_guidance();
    let resumed_at = Instant::now();
    wait_for("a cue after resuming", Duration::from_secs(8), || {
        run_view(&mut c, Duration::from_millis(50));
        unit.accepted(CommandKind::Play).iter().any(|t| *t > resumed_at)
    });
}

/// A stalled view (the console's UI thread): the vest worker stops the tactors by itself within the
/// liveness bound.
#[test]
fn a_stalled_view_stops_the_vest_by_itself() {
    let _exclusive = crate::timing_exclusive();
    let unit = Unit::spawn();
    let gpsd = FakeGpsd::spawn(Hostile::Absurd, Duration::from_secs(20));
    // The view's own bound; guidance's is relaxed so that only the view's stall is under test.
    let liveness = Liveness { guidance: Duration::from_secs(5), ..Liveness::default() };
    let mut c = station_with(gpsd.port, &unit.path, None, liveness);
    wait_for("an automatic cue", Duration::from_secs(8), || {
        run_view(&mut c, Duration::from_millis(50));
        !unit.accepted(CommandKind::Play).is_empty()
    });
    let before = unit.accepted(CommandKind::StopAll).len();
    // The UI thread stops drawing (a stall): nobody could press STOP ALL now.
    let stalled_at = Instant::now();
    wait_for("the liveness stop", Duration::from_secs(5), || {
        unit.accepted(CommandKind::StopAll).len() > before
    });
    let t = unit.accepted(CommandKind::StopAll)[before].saturating_duration_since(stalled_at);
    let bound = Liveness::default().view.unwrap();
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
    run_view(&mut c, Duration::from_millis(100));
    assert!(c.vest.halted.as_deref().is_some_and(|r| r.contains("console UI")), "{:?}", c.vest.halted);
}

/// The console with the largest route it accepts (every waypoint on screen), guiding: frames stay cheap
/// and Space reaches the unit as STOP ALL within 50 ms, counted from a key press that lands just as a frame
/// begins (the worst case: the key waits for that whole frame, then is read at the start of the next).
#[test]
fn the_largest_route_keeps_stop_all_within_50_ms() {
    let _exclusive = crate::timing_exclusive();
    let unit = Unit::spawn();
    let gpsd = FakeGpsd::spawn(Hostile::Absurd, Duration::from_mins(1));
    let cfg = vestnav_app::config::Config {
        gps: GpsSourceConfig::Gpsd { host: "127.0.0.1".into(), port: gpsd.port },
        vest: VestSourceConfig::Serial { port: unit.path.clone() },
        map_tiles: false,
        follow: true,
        guidance_auto: true,
        cue_interval_s: 1.0,
        ..vestnav_app::config::Config::default()
    };
    let mut c = vestnav_app::console::Console::new(
        Box::new(Hardware::default()),
        vestnav_app::console::ConsoleOptions {
            cfg,
            liveness: Some(RELAXED),
            ..vestnav_app::console::ConsoleOptions::default()
        },
    );
    // A 100 x 100 grid of waypoints 3 m apart around the wearer: all of them inside the map view.
    let n = vestnav_station::route::MAX_WAYPOINTS;
    let side = (n as f64).sqrt().ceil() as usize;
    let wps: Vec<_> = (0..n)
        .map(|k| {
            let (i, j) = ((k / side) as f64, (k % side) as f64);
            vestnav_station::route::Waypoint::new(
                format!("W{k}"),
                42.3545 + i * 2.7e-5,
                -71.1015 + j * 3.6e-5,
            )
        })
        .collect();
    c.station.route_mut().replace("largest".into(), wps).unwrap();
    assert_eq!(c.station.route().waypoints().len(), n);
    let ctx = egui::Context::default();
    let frame = |c: &mut vestnav_app::console::Console, events: Vec<egui::Event>| {
        let input = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(1400.0, 880.0))),
            events,
            ..egui::RawInput::default()
        };
        let t = Instant::now();
        let mut out = ctx.run_ui(input, |ui| c.ui(ui));
        out.textures_delta.clear();
        t.elapsed()
    };
    wait_for("an automatic cue", Duration::from_secs(10), || {
        frame(&mut c, Vec::new());
        !unit.accepted(CommandKind::Play).is_empty()
    });
    let mut frames = Vec::new();
    let mut latencies = Vec::new();
    for _ in 0..5 {
        for _ in 0..30 {
            frames.push(frame(&mut c, Vec::new()));
            std::thread::sleep(Duration::from_millis(10));
        }
        let before = unit.accepted(CommandKind::StopAll).len();
        let pressed = Instant::now();
        frames.push(frame(&mut c, Vec::new()));
        let space = egui::Event::Key {
            key: egui::Key::Space,
            physical_key: None,
            pressed: true,
            repeat: false,
            modifiers: egui::Modifiers::default(),
        };
        frame(&mut c, vec![space]);
        wait_for("STOP ALL at the unit", Duration::from_secs(2), || {
            unit.accepted(CommandKind::StopAll).len() > before
        });
        latencies.push(unit.accepted(CommandKind::StopAll)[before].saturating_duration_since(pressed));
        c.resume_guidance();
    }
    frames.sort();
    latencies.sort();
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    eprintln!(
        "{n} waypoints: frame p50 {:.1} ms, max {:.1} ms; Space -> STOP ALL at the unit: {:?} ms",
        ms(frames[frames.len() / 2]),
        ms(*frames.last().unwrap()),
        latencies.iter().map(|d| (ms(*d) * 10.0).round() / 10.0).collect::<Vec<_>>()
    );
    assert!(latencies.iter().all(|d| *d < Duration::from_millis(50)), "{latencies:?}");
}

/// A full disk under the session log, through the station's real threads: the operator is told what is
/// not being recorded and where, nothing blocks, and recording resumes when space comes back. Needs a
/// tmpfs (root, as on CI); skipped with a message where mounting is not allowed.
#[test]
fn a_full_disk_under_the_session_log_is_shown_and_recording_resumes() {
    // It measures STOP ALL's latency too: not beside another timing test or the window test.
    let _exclusive = crate::timing_exclusive();
    let dir = std::env::temp_dir().join(format!("vestnav-fulldisk-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mounted = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=64k", "tmpfs"])
        .arg(&dir)
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        eprintln!(
            "a_full_disk_under_the_session_log_is_shown_and_recording_resumes: cannot mount a tmpfs, skipped"
        );
        let _ = std::fs::remove_dir(&dir);
        return;
    }
    let umount = |d: &std::path::Path| {
        let _ = std::process::Command::new("umount").arg(d).status();
        let _ = std::fs::remove_dir_all(d);
    };
    // Fill it to ENOSPC.
    let filler = dir.join("filler");
    {
        let mut f = std::fs::File::create(&filler).unwrap();
        let block = [0u8; 4096];
        while f.write_all(&block).is_ok() {}
    }
    let unit = Unit::spawn();
    let gpsd = FakeGpsd::spawn(Hostile::Absurd, Duration::from_secs(30));
    let mut c = station(gpsd.port, &unit.path, Some(dir.clone()));
    let storage = |c: &Station| c.notices.latest(vestnav_station::Subject::Storage).map(|n| n.text.clone());
    let failing = (|| {
        let end = Instant::now() + Duration::from_secs(10);
        while Instant::now() < end {
            c.pump(|_| {});
            if let Some(t) = storage(&c).filter(|t| t.contains("NOT recording")) {
                return Some(t);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        None
    })();
    let Some(text) = failing else {
        umount(&dir);
        panic!("no storage alarm: {:?}", storage(&c));
    };
    eprintln!("full disk: {text}");
    assert!(c.log_failing());
    assert!(text.contains(&dir.display().to_string()), "names where: {text}");
    assert!(text.to_lowercase().contains("no space"), "names why: {text}");
    // STOP ALL still reaches the unit at once while the log fails.
    let lat = stop_latency(&mut c, &unit);
    assert!(lat < Duration::from_millis(50), "{lat:?}");
    std::fs::remove_file(&filler).unwrap();
    let end = Instant::now() + Duration::from_secs(10);
    loop {
        c.pump(|_| {});
        if Instant::now() > end || storage(&c).is_some_and(|t| t.contains("recording again")) {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let recovered = storage(&c);
    assert!(!c.log_failing());
    let log_path = c.log_path().map(std::path::Path::to_path_buf);
    drop(c);
    let written = log_path.map(|p| std::fs::read_to_string(p).unwrap_or_default()).unwrap_or_default();
    umount(&dir);
    assert!(recovered.as_deref().is_some_and(|t| t.contains("recording again")), "{recovered:?}");
    assert!(written.contains("storage failure"), "the log itself says what was lost");
}

/// A unit that never acknowledges STOP ALL and keeps reporting tactors 13 and 14 on: the station keeps
/// sending STOP ALL, and the console says STOP NOT CONFIRMED — banner and top bar — naming the tactors and
/// for how long, and the session log records it.
#[test]
fn an_unconfirmed_stop_is_shown_naming_the_tactors_still_on() {
    let on = TactorMask::from_indices([13, 14]);
    let unit = Unit::spawn_as(Behaviour::NeverAcksStop { on });
    let gpsd = FakeGpsd::spawn(Hostile::Absurd, Duration::from_secs(20));
    let dir = std::env::temp_dir().join(format!("vestnav-unconfirmed-{}", std::process::id()));
    let cfg = vestnav_app::config::Config {
        gps: GpsSourceConfig::Gpsd { host: "127.0.0.1".into(), port: gpsd.port },
        vest: VestSourceConfig::Serial { port: unit.path.clone() },
        map_tiles: false,
        ..vestnav_app::config::Config::default()
    };
    let mut c = vestnav_app::console::Console::new(
        Box::new(Hardware::default()),
        vestnav_app::console::ConsoleOptions {
            cfg,
            log_dir: Some(dir.clone()),
            liveness: Some(RELAXED),
            ..vestnav_app::console::ConsoleOptions::default()
        },
    );
    wait_for("the unit's handshake", Duration::from_secs(5), || {
        c.tick();
        c.station.vest.is_live()
    });
    let t0 = Instant::now();
    c.stop_all();
    wait_for("the stop alarm", Duration::from_secs(3), || {
        c.tick();
        c.station.stop_alarm(Instant::now()).is_some_and(|a| a.on == Some(on))
    });
    let seen = t0.elapsed();
    std::thread::sleep(Duration::from_millis(600));
    c.tick();
    let a = c.station.stop_alarm(Instant::now()).unwrap();
    assert!(!a.acked);
    let banners = c.banners(Instant::now());
    let stop = banners.iter().find(|b| b.subject == vestnav_app::console::BannerSubject::Stop).unwrap();
    eprintln!("after {seen:?}: {}", stop.text);
    assert!(stop.text.starts_with("STOP NOT CONFIRMED"), "{}", stop.text);
    assert!(stop.text.contains("tactors 13, 14 on"), "{}", stop.text);
    assert!(stop.text.contains("switch the vest unit off"), "{}", stop.text);
    assert_eq!(banners.first().map(|b| b.subject), Some(vestnav_app::console::BannerSubject::Stop));
    // The station keeps asking.
    assert!(unit.received(CommandKind::StopAll).len() >= 3, "{:?}", unit.received(CommandKind::StopAll));
    let log_path = c.log_path().unwrap().to_path_buf();
    drop(c);
    let log = std::fs::read_to_string(&log_path).unwrap();
    assert!(log.contains("STOP NOT CONFIRMED"), "the session log records it");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The exit path while a STOP ALL retry is in flight and the unit never answers: a fresh STOP ALL frame
/// reaches the unit at once, and the whole close is bounded.
#[test]
fn exit_sends_a_fresh_stop_even_with_a_retry_in_flight() {
    let _exclusive = crate::timing_exclusive();
    let unit = Unit::spawn_as(Behaviour::NeverAcksStop { on: TactorMask::from_indices([13, 14]) });
    let gpsd = FakeGpsd::spawn(Hostile::Absurd, Duration::from_secs(20));
    let mut c = station(gpsd.port, &unit.path, None);
    wait_for("the unit's handshake", Duration::from_secs(5), || {
        c.pump(|_| {});
        c.vest.is_live()
    });
    c.stop_all();
    wait_for("the first STOP ALL", Duration::from_secs(5), || {
        !unit.received(CommandKind::StopAll).is_empty()
    });
    std::thread::sleep(Duration::from_millis(60));
    let before = unit.received(CommandKind::StopAll).len();
    let t0 = Instant::now();
    let acked = c.stop_path().stop_and_close_all(vestnav_station::stop::EXIT_STOP_WAIT);
    let closed = t0.elapsed();
    assert!(!acked);
    let fresh = unit.received(CommandKind::StopAll).get(before).map(|t| t.saturating_duration_since(t0));
    eprintln!("exit: fresh STOP ALL at the unit after {fresh:?}, worker closed after {closed:?}");
    assert!(fresh.is_some_and(|d| d < Duration::from_millis(50)), "{fresh:?}");
    assert!(closed < vestnav_station::stop::EXIT_STOP_WAIT + Duration::from_millis(50), "{closed:?}");
}

/// `vestnav station` (the same exit path as the window), ended by SIGTERM while a STOP ALL retry is in
/// flight or the unit misbehaves: the process is gone within the deadline and the unit heard a STOP ALL
/// after the signal.
#[test]
fn the_process_exits_in_bounded_time_whatever_the_unit_does() {
    let _exclusive = crate::timing_exclusive();
    let deadline = vestnav_station::stop::EXIT_DEADLINE;
    for behaviour in [
        Behaviour::Honest,
        Behaviour::NeverAcksStop { on: TactorMask::from_indices([13, 14]) },
        Behaviour::Late(Duration::from_millis(1500)),
        Behaviour::Flood,
    ] {
        let unit = Unit::spawn_as(behaviour);
        let gpsd = FakeGpsd::spawn(Hostile::Absurd, Duration::from_secs(30));
        let home = std::env::temp_dir().join(format!("vestnav-exit-{}-{behaviour:?}", std::process::id()));
        std::fs::create_dir_all(&home).unwrap();
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_vestnav"))
            .args([
                "station",
                "--gps",
                &format!("gpsd://127.0.0.1:{}", gpsd.port),
                "--vest",
                &format!("serial:{}", unit.path),
                "--status-every",
                "0",
            ])
            .env("HOME", &home)
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        // Guidance plays (or, for the late unit, it has had time to try).
        let end = Instant::now() + Duration::from_secs(10);
        while Instant::now() < end && unit.accepted(CommandKind::Play).is_empty() {
            std::thread::sleep(Duration::from_millis(20));
        }
        let ready = !unit.accepted(CommandKind::Play).is_empty();
        if ready {
            // A STOP ALL already in flight (the operator's, from the station's terminal).
            let stdin = child.stdin.as_mut().unwrap();
            stdin.write_all(b"stop\n").unwrap();
            stdin.flush().unwrap();
            std::thread::sleep(Duration::from_millis(80));
        }
        let before = unit.received(CommandKind::StopAll).len();
        let t0 = Instant::now();
        vestnav_device::testkit::send_signal(child.id(), 15).unwrap();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            assert!(t0.elapsed() < Duration::from_secs(3), "{behaviour:?}: the station did not exit");
            std::thread::sleep(Duration::from_millis(1));
        };
        let exited = t0.elapsed();
        let fresh = unit.received(CommandKind::StopAll).get(before).map(|t| t.saturating_duration_since(t0));
        eprintln!(
            "{behaviour:?}: guided {ready}, STOP ALL after the signal at {fresh:?}, exited after {exited:?}"
        );
        assert_eq!(status.code(), Some(128 + 15), "{behaviour:?}");
        // The deadline, plus the time this test needs to see the process gone on a loaded machine.
        assert!(exited < deadline + Duration::from_millis(100), "{behaviour:?}: exit took {exited:?}");
        if ready && behaviour != Behaviour::Late(Duration::from_millis(1500)) {
            assert!(fresh.is_some_and(|d| d < Duration::from_millis(50)), "{behaviour:?}: {fresh:?}");
        }
        let _ = std::fs::remove_dir_all(&home);
    }
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
        vestnav_device::testkit::send_signal(child.id(), sig).unwrap();
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
    /// Starts Xvfb on a display it picks itself (`-displayfd`: it writes the number once it accepts
    /// connections), so neither another server nor the stale socket of a killed one is mistaken for ours.
    fn start() -> Option<Self> {
        use std::io::BufRead as _;
        let mut child = std::process::Command::new("Xvfb")
            .args(["-displayfd", "1", "-screen", "0", "1600x1000x24", "-nolisten", "tcp"])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .ok()?;
        let mut line = String::new();
        let read = std::io::BufReader::new(child.stdout.take()?).read_line(&mut line);
        if let (Ok(_), Ok(n)) = (read, line.trim().parse::<u32>()) {
            return Some(Self { child, display: format!(":{n}") });
        }
        let _ = child.kill();
        let _ = child.wait();
        None
    }

    /// Ends the server as a user would (SIGTERM: it removes its socket and lock), killing it only if it
    /// has not gone within 2 s.
    fn stop(&mut self) {
        if self.child.try_wait().ok().flatten().is_some() {
            return;
        }
        let _ = vestnav_device::testkit::send_signal(self.child.id(), 15);
        let end = Instant::now() + Duration::from_secs(2);
        while Instant::now() < end {
            if self.child.try_wait().ok().flatten().is_some() {
                return;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
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
