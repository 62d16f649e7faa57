//! Tests of the GPS sources: replay, simulator, serial over a PTY, and hostile gpsd servers.

use super::super::Fix;
use super::*;
use std::io::{Read, Write};
use std::net::TcpStream;

use super::super::gpsd::WATCH;

fn collect(rx: &Receiver<GpsEvent>, until: impl Fn(&[GpsEvent]) -> bool, timeout: Duration) -> Vec<GpsEvent> {
    let end = Instant::now() + timeout;
    let mut out = Vec::new();
    while Instant::now() < end && !until(&out) {
        if let Ok(e) = rx.recv_timeout(Duration::from_millis(50)) {
            out.push(e);
        }
    }
    out
}

fn spawn(config: SourceConfig) -> (GpsHandle, Receiver<GpsEvent>) {
    GpsSource::spawn_channel(config, 1024, None).unwrap()
}

fn logs() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/gpsd-logs")
}

#[test]
fn replay_as_fast_as_possible_gives_every_epoch() {
    let (mut h, rx) = spawn(SourceConfig::Replay {
        path: logs().join("nd-1005.log"),
        speed: ReplaySpeed::AsFastAsPossible,
    });
    let ev = collect(&rx, |e| e.contains(&GpsEvent::State(SourceState::Finished)), Duration::from_secs(10));
    let fixes = ev.iter().filter(|e| matches!(e, GpsEvent::Fix(_))).count();
    assert_eq!(fixes, 16);
    h.stop();
}

#[test]
fn replay_paces_by_utc_time() {
    // mr-350p: 14 epochs over 13 s; at 26x that is 0.5 s.
    let t0 = Instant::now();
    let (mut h, rx) =
        spawn(SourceConfig::Replay { path: logs().join("mr-350p.log"), speed: ReplaySpeed::Times(26.0) });
    let ev = collect(&rx, |e| e.contains(&GpsEvent::State(SourceState::Finished)), Duration::from_secs(10));
    let dt = t0.elapsed().as_secs_f64();
    assert!(ev.contains(&GpsEvent::State(SourceState::Finished)));
    assert!((0.45..2.0).contains(&dt), "{dt}");
    h.stop();
}

/// Issue 23 item 6: a looped replay starts again at the end of its file (saying so, as a discontinuity)
/// instead of finishing; un-looped, the same replay finishes.
#[test]
fn looped_replay_starts_again_and_unlooped_finishes() {
    let (mut h, rx) =
        spawn(SourceConfig::Replay { path: logs().join("mr-350p.log"), speed: ReplaySpeed::Times(26.0) });
    let ctl = h.replay_control().unwrap();
    ctl.set_looped(true);
    let looped = |e: &GpsEvent| matches!(e, GpsEvent::Discontinuity(n) if n.contains("looped"));
    let ev = collect(&rx, |e| e.iter().filter(|x| looped(x)).count() >= 2, Duration::from_secs(10));
    assert_eq!(ev.iter().filter(|x| looped(x)).count(), 2);
    assert!(!ev.contains(&GpsEvent::State(SourceState::Finished)));
    let fixes = ev.iter().filter(|e| matches!(e, GpsEvent::Fix(f) if f.has_position())).count();
    assert!(fixes >= 2 * 13, "two whole passes: {fixes}");
    ctl.set_looped(false);
    let ev = collect(&rx, |e| e.contains(&GpsEvent::State(SourceState::Finished)), Duration::from_secs(10));
    assert!(ev.contains(&GpsEvent::State(SourceState::Finished)));
    h.stop();
}

#[test]
fn simulator_emits_fixes_and_stops() {
    let (mut h, rx) = spawn(SourceConfig::Simulator {
        route: super::super::sim::demo_route().unwrap(),
        pace_m_s: 1.4,
        model: GnssErrorModel::sirf3_open_sky(),
        seed: 5,
        period: Duration::from_millis(20),
        looped: false,
        truth: None,
    });
    let ev = collect(
        &rx,
        |e| e.iter().filter(|x| matches!(x, GpsEvent::Fix(_))).count() >= 5,
        Duration::from_secs(10),
    );
    assert!(ev.iter().filter(|x| matches!(x, GpsEvent::Fix(f) if f.has_position())).count() >= 5);
    h.stop();
}

/// Issue 23 item 2: every simulated fix is stamped when it was made (never in the future), and both its
/// arrival instant and its receiver time go forwards from one fix to the next — the first fixes used to be
/// stamped an hour ahead, so the field tests refused every later one as out of order.
#[test]
fn simulator_fixes_arrive_in_order_and_never_from_the_future() {
    let (mut h, rx) = spawn(SourceConfig::Simulator {
        route: super::super::sim::demo_route().unwrap(),
        pace_m_s: 1.4,
        model: GnssErrorModel::sirf3_open_sky(),
        seed: 5,
        period: Duration::from_millis(20),
        looped: false,
        truth: None,
    });
    let ev = collect(
        &rx,
        |e| e.iter().filter(|x| matches!(x, GpsEvent::Fix(_))).count() >= 8,
        Duration::from_secs(10),
    );
    let seen = Instant::now();
    let fixes: Vec<&Fix> =
        ev.iter().filter_map(|e| if let GpsEvent::Fix(f) = e { Some(&**f) } else { None }).collect();
    assert!(fixes.len() >= 8);
    for pair in fixes.windows(2) {
        let (a, b) = (pair[0].received_at.unwrap(), pair[1].received_at.unwrap());
        assert!(b >= a, "arrival went backwards");
        assert!(pair[1].time.unwrap() > pair[0].time.unwrap(), "receiver time did not advance");
    }
    assert!(fixes.iter().all(|f| f.received_at.unwrap() <= seen), "a fix stamped in the future");
    h.stop();
}

#[cfg(unix)]
#[test]
fn gpsd_refused_reports_lost_then_reconnecting() {
    let refusing = crate::testkit::RefusingPort::bind().unwrap();
    let (mut h, rx) = spawn(SourceConfig::Gpsd { host: "127.0.0.1".into(), port: refusing.port() });
    let ev = collect(
        &rx,
        |e| e.iter().any(|x| matches!(x, GpsEvent::State(SourceState::Reconnecting { .. }))),
        Duration::from_secs(5),
    );
    assert!(ev.iter().any(|x| matches!(x, GpsEvent::State(SourceState::Lost { .. }))));
    assert!(ev.iter().any(|x| matches!(x, GpsEvent::State(SourceState::Reconnecting { attempt: 1, .. }))));
    h.stop();
}

/// Fix-in to event-out latency over a real PTY: an epoch's sentences written to the master, the serial
/// source (fixed baud) reading the slave, until its Fix event is received. Prints p50/p99 (no timing
/// assertion: speed goals live in benches).
#[cfg(unix)]
#[test]
fn pty_fix_latency_p50_p99() {
    use std::io::Write as _;
    let mut pty = crate::serial::Pty::open().unwrap();
    let (_h, events) = spawn(SourceConfig::Serial { port: pty.path().to_owned(), baud: Some(4800) });
    let mut rx = super::super::sim::SimulatedReceiver::new(
        &super::super::sim::demo_route().unwrap(),
        1.4,
        GnssErrorModel::perfect(),
        1,
        chrono::DateTime::UNIX_EPOCH,
    )
    .unwrap();
    let mut live = false;
    let end = Instant::now() + Duration::from_secs(5);
    while !live && Instant::now() < end {
        live = matches!(
            events.recv_timeout(Duration::from_millis(50)),
            Ok(GpsEvent::State(SourceState::Live { .. }))
        );
    }
    assert!(live);
    let mut lat_us = Vec::new();
    for k in 0..60 {
        let text = rx.next_epoch(1.0);
        let t0 = Instant::now();
        pty.write_all(text.as_bytes()).unwrap();
        let deadline = t0 + Duration::from_secs(2);
        while Instant::now() < deadline {
            if let Ok(GpsEvent::Fix(_)) = events.recv_timeout(Duration::from_millis(5)) {
                // The first epochs are closed by the next one (cycle end not yet learned).
                if k >= 3 {
                    lat_us.push(t0.elapsed().as_micros());
                }
                break;
            }
        }
    }
    lat_us.sort_unstable();
    assert!(lat_us.len() >= 50, "{}", lat_us.len());
    let p = |q: f64| lat_us[((lat_us.len() - 1) as f64 * q).round() as usize];
    eprintln!(
        "PTY fix-in to event-out latency: p50 {} us, p99 {} us (n = {})",
        p(0.5),
        p(0.99),
        lat_us.len()
    );
}

#[test]
fn backoff_doubles_and_caps() {
    assert_eq!(backoff(1), Duration::from_millis(500));
    assert_eq!(backoff(2), Duration::from_secs(1));
    assert_eq!(backoff(9), Duration::from_secs(8));
}

#[test]
fn baud_score_counts_valid_sentences() {
    assert_eq!(score_baud(b"\xf0\x0f\x88garbage$GPGGA,1*00\r\n"), 0);
    let good = std::fs::read(logs().join("nd-1005.log")).unwrap();
    assert!(score_baud(&good) > 50);
}

// ---- Hostile gpsd servers ("Safety first"): each is a fake gpsd on 127.0.0.1 started by the test,
// serving a fixed number of connections, with write timeouts so that it always ends by itself.

use std::net::TcpListener;

/// Serves `conns` connections on a fresh 127.0.0.1 port with `serve(stream, n)`; stops accepting after
/// 10 s. Writes time out after 1 s, so a server whose client has gone ends.
fn fake_gpsd(
    conns: usize,
    serve: impl Fn(TcpStream, usize) + Send + 'static,
) -> (u16, std::thread::JoinHandle<()>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    listener.set_nonblocking(true).unwrap();
    let t = std::thread::spawn(move || {
        let end = Instant::now() + Duration::from_secs(10);
        let mut n = 0;
        while n < conns && Instant::now() < end {
            match listener.accept() {
                Ok((stream, _)) => {
                    stream.set_nonblocking(false).unwrap();
                    stream.set_write_timeout(Some(Duration::from_secs(1))).unwrap();
                    stream.set_read_timeout(Some(Duration::from_secs(1))).unwrap();
                    // Read the client's ?WATCH first, as gpsd does: closing a socket with unread
                    // input would reset the connection instead of closing it.
                    let mut watch = Vec::new();
                    let mut byte = [0u8; 1];
                    while watch.last() != Some(&b'\n') && matches!((&stream).read(&mut byte), Ok(1)) {
                        watch.push(byte[0]);
                    }
                    assert_eq!(watch, WATCH.as_bytes());
                    serve(stream, n);
                    n += 1;
                }
                Err(_) => std::thread::sleep(Duration::from_millis(5)),
            }
        }
    });
    (port, t)
}

fn gpsd_at(port: u16) -> SourceConfig {
    SourceConfig::Gpsd { host: "127.0.0.1".into(), port }
}

/// A TPV report as gpsd writes it (`gpsd_json(5)`); `k` makes the time unique.
fn tpv(k: u32, lat_lon: &str) -> String {
    format!(
        "{{\"class\":\"TPV\",\"device\":\"/dev/ttyUSB0\",\"mode\":3,\"time\":\"2011-03-14T{:02}:{:02}:{:02}.{:03}Z\",\
         {lat_lon},\"altMSL\":59.3,\"speed\":0.0,\"track\":0.0,\"eph\":7.4}}\n",
        k / 3_600_000 % 24,
        k / 60_000 % 60,
        k / 1000 % 60,
        k % 1000
    )
}

const GOOD: &str = r#""lat":57.163445,"lon":-2.12137"#;

fn is_state(e: &GpsEvent, f: impl Fn(&SourceState) -> bool) -> bool {
    matches!(e, GpsEvent::State(s) if f(s))
}

fn stats_of(ev: &[GpsEvent]) -> Option<DecodeStatsCopy> {
    ev.iter().rev().find_map(|e| if let GpsEvent::Stats(s) = e { Some(*s) } else { None })
}
type DecodeStatsCopy = super::super::DecodeStats;

/// The issue's values never reach the consumer as positions, and are counted.
#[test]
fn gpsd_absurd_positions_never_reach_the_consumer() {
    let (port, server) = fake_gpsd(1, |mut s, _| {
        let bad = [
            r#""lat":57.0,"lon":-1e15"#,
            r#""lat":91.0,"lon":181.0"#,
            r#""lat":9999,"lon":2.0"#,
            r#""lat":1e20,"lon":2.0"#,
            r#""lat":-1e-400e,"lon":NaN"#,
        ];
        let mut text: String = bad.iter().zip(1..).map(|(b, k)| tpv(k * 1000, b)).collect();
        text += &tpv(9000, GOOD);
        let _ = s.write_all(text.as_bytes());
        std::thread::sleep(Duration::from_millis(300));
    });
    let (mut h, rx) = spawn(gpsd_at(port));
    let ev = collect(
        &rx,
        |e| e.iter().any(|e| is_state(e, |s| matches!(s, SourceState::Lost { .. }))),
        Duration::from_secs(5),
    );
    h.stop();
    server.join().unwrap();
    let fixes: Vec<&Fix> =
        ev.iter().filter_map(|e| if let GpsEvent::Fix(f) = e { Some(&**f) } else { None }).collect();
    assert_eq!(fixes.len(), 5, "four absurd TPVs and the good one; the NaN line is not JSON: {ev:?}");
    let positions: Vec<(f64, f64)> =
        fixes.iter().filter(|f| f.has_position()).map(|f| (f.lat_deg.unwrap(), f.lon_deg.unwrap())).collect();
    assert_eq!(positions, [(57.163_445, -2.121_37)]);
    assert!(fixes.iter().all(|f| f.has_position() || (f.lat_deg.is_none() && f.lon_deg.is_none())));
    let st = stats_of(&ev).expect("final counts before Lost");
    assert_eq!(st.invalid_positions, 4, "{st:?}");
    assert_eq!(st.malformed, 1, "the NaN line");
}

/// One byte per 50 ms and never a newline: the source goes stale (no complete line for 3 s) and a stop
/// while bytes keep trickling returns within 300 ms.
#[test]
fn gpsd_trickle_goes_stale_and_stop_is_prompt() {
    let (port, server) = fake_gpsd(1, |mut s, _| {
        let end = Instant::now() + Duration::from_secs(8);
        let _ = s.write_all(b"{\"class\":\"TPV\"");
        while Instant::now() < end && s.write_all(b"a").is_ok() {
            std::thread::sleep(Duration::from_millis(50));
        }
    });
    let (mut h, rx) = spawn(gpsd_at(port));
    let ev =
        collect(&rx, |e| e.iter().any(|e| is_state(e, |s| *s == SourceState::Stale)), Duration::from_secs(6));
    assert!(ev.iter().any(|e| is_state(e, |s| *s == SourceState::Stale)), "{ev:?}");
    assert!(!ev.iter().any(|e| is_state(e, |s| matches!(s, SourceState::Lost { .. }))), "{ev:?}");
    let t0 = Instant::now();
    h.stop();
    let dt = t0.elapsed();
    assert!(dt < Duration::from_millis(300), "stop took {dt:?}");
    assert!(!h.is_running());
    server.join().unwrap();
}

/// Resident memory of this process [bytes] (Linux), for the unbounded-line test.
fn rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let kb = status.lines().find_map(|l| l.strip_prefix("VmRSS:"))?.trim().strip_suffix("kB")?;
    kb.trim().parse::<u64>().ok().map(|k| k * 1024)
}

/// A 200 MB line without a newline: dropped without being buffered (counted as overlong), the next
/// line still decodes, memory stays bounded, and a stop during a second endless line is prompt.
#[test]
fn gpsd_endless_line_keeps_memory_bounded() {
    let (port, server) = fake_gpsd(1, |mut s, _| {
        let chunk = vec![b'x'; 1 << 20];
        for _ in 0..200 {
            if s.write_all(&chunk).is_err() {
                return;
            }
        }
        if s.write_all(format!("\n{}", tpv(1000, GOOD)).as_bytes()).is_err() {
            return;
        }
        let end = Instant::now() + Duration::from_secs(8);
        while Instant::now() < end && s.write_all(&chunk).is_ok() {}
    });
    let rss0 = rss_bytes();
    let (mut h, rx) = spawn(gpsd_at(port));
    let mut peak = 0;
    let mut ev = Vec::new();
    let end = Instant::now() + Duration::from_secs(30);
    while Instant::now() < end {
        peak = peak.max(rss_bytes().unwrap_or(0));
        if let Ok(e) = rx.recv_timeout(Duration::from_millis(20)) {
            ev.push(e);
        }
        let fixed = ev.iter().any(|e| matches!(e, GpsEvent::Fix(f) if f.has_position()));
        if fixed && stats_of(&ev).is_some_and(|s| s.overlong >= 1 && s.epochs >= 1) {
            break;
        }
    }
    let fix = ev.iter().find_map(|e| if let GpsEvent::Fix(f) = e { Some(f) } else { None });
    assert!((fix.expect("the line after the endless one").lat_deg.unwrap() - 57.163_445).abs() < 1e-9);
    let st = stats_of(&ev).unwrap();
    assert!(st.overlong >= 1 && st.bytes >= 200 << 20, "{st:?}");
    if let Some(rss0) = rss0 {
        // The line alone is 200 MB; the framer holds at most 2 x 64 KiB of it.
        let grew = peak.saturating_sub(rss0);
        assert!(grew < 64 << 20, "RSS grew by {} MB", grew >> 20);
    }
    let t0 = Instant::now();
    h.stop();
    let dt = t0.elapsed();
    assert!(dt < Duration::from_millis(300), "stop took {dt:?}");
    server.join().unwrap();
}

/// A flood of TPVs into a consumer that reads nothing: with `DropNewest` its channel holds at most its
/// capacity, the rest is counted as dropped, and the worker never waits.
#[test]
fn gpsd_flood_into_a_drop_newest_consumer_stays_bounded() {
    const N: u32 = 20_000;
    let (port, server) = fake_gpsd(1, |mut s, _| {
        let text: String = (0..N).map(|k| tpv(k, GOOD)).collect();
        let _ = s.write_all(text.as_bytes());
        std::thread::sleep(Duration::from_millis(200));
    });
    let (out, rx) = Outbox::channel(16, Overflow::DropNewest, None);
    let mut h = GpsSource::spawn(gpsd_at(port), vec![out.clone()]).unwrap();
    let end = Instant::now() + Duration::from_secs(10);
    while out.dropped() < u64::from(N) - 16 && Instant::now() < end {
        std::thread::sleep(Duration::from_millis(20));
    }
    let t0 = Instant::now();
    h.stop();
    assert!(t0.elapsed() < Duration::from_millis(300));
    server.join().unwrap();
    let kept = rx.try_iter().count();
    assert!(kept <= 16, "{kept}");
    // Every TPV (and the Live state before them) was either kept or counted as dropped.
    assert!(out.dropped() + kept as u64 > u64::from(N), "dropped {}, kept {kept}", out.dropped());
}

/// gpsd closes the connection in the middle of a line: the source reports the link lost, backs off and
/// reconnects, and fixes flow again.
#[test]
fn gpsd_closing_mid_line_is_lost_then_reconnected() {
    let (port, server) = fake_gpsd(2, |mut s, n| {
        let k = u32::try_from(n).unwrap() * 1000;
        let _ = s.write_all(format!("{}{{\"class\":\"TPV\",\"ti", tpv(k, GOOD)).as_bytes());
        if n == 1 {
            std::thread::sleep(Duration::from_millis(300));
        }
    });
    let (mut h, rx) = spawn(gpsd_at(port));
    let fixes =
        |e: &[GpsEvent]| e.iter().filter(|e| matches!(e, GpsEvent::Fix(f) if f.has_position())).count();
    let ev = collect(&rx, |e| fixes(e) >= 2, Duration::from_secs(8));
    h.stop();
    server.join().unwrap();
    assert_eq!(fixes(&ev), 2, "{ev:?}");
    let lost = ev.iter().position(|e| {
        is_state(e, |s| matches!(s, SourceState::Lost { reason } if reason.contains("closed")))
    });
    let retry =
        ev.iter().position(|e| is_state(e, |s| matches!(s, SourceState::Reconnecting { attempt: 1, .. })));
    let second_fix = ev.iter().rposition(|e| matches!(e, GpsEvent::Fix(_)));
    assert!(lost < retry && retry < second_fix && lost.is_some(), "{ev:?}");
}

/// `stop` never waits for a worker stuck in an uninterruptible call: here, a lossless consumer's full
/// channel is the only thing the worker could wait on, and the stop flag wins.
#[test]
fn stop_wins_over_a_stalled_lossless_consumer() {
    let (mut h, rx) = GpsSource::spawn_channel(
        SourceConfig::Replay { path: logs().join("nd-1005.log"), speed: ReplaySpeed::AsFastAsPossible },
        1,
        None,
    )
    .unwrap();
    std::thread::sleep(Duration::from_millis(100));
    assert!(h.is_running(), "waiting for the consumer");
    let t0 = Instant::now();
    h.stop();
    assert!(t0.elapsed() < Duration::from_millis(300));
    assert!(!h.is_running());
    assert!(rx.try_iter().count() <= 2);
}

/// A looped simulator starts over at the end of its route with a new seed, and says so.
#[test]
fn looped_simulator_starts_over_with_a_new_seed() {
    // A 50 m route at 50 m/s with 0.1 s epochs: about 10 epochs (1 s) per lap.
    let start = (42.356_2, -71.1);
    let end = (42.356_2 + 50.0 / 111_132.0, -71.1);
    let (mut h, rx) = spawn(SourceConfig::Simulator {
        route: vec![start, end],
        pace_m_s: 50.0,
        model: GnssErrorModel::sirf3_open_sky(),
        seed: 7,
        period: Duration::from_millis(100),
        looped: true,
        truth: None,
    });
    let notices = |e: &[GpsEvent]| e.iter().filter(|e| matches!(e, GpsEvent::Notice(_))).count();
    let ev = collect(&rx, |e| notices(e) >= 2, Duration::from_secs(10));
    h.stop();
    assert!(!ev.iter().any(|e| is_state(e, |s| *s == SourceState::Finished)));
    let texts: Vec<&String> =
        ev.iter().filter_map(|e| if let GpsEvent::Notice(t) = e { Some(t) } else { None }).collect();
    assert_eq!(texts.len(), 2, "{ev:?}");
    assert!(texts[0].contains("lap 2") && texts[0].contains("seed 8"), "{texts:?}");
    assert!(texts[1].contains("lap 3") && texts[1].contains("seed 9"), "{texts:?}");
    // Epoch times keep increasing across laps.
    let fixes: Vec<&Fix> =
        ev.iter().filter_map(|e| if let GpsEvent::Fix(f) = e { Some(&**f) } else { None }).collect();
    assert!(fixes.windows(2).all(|w| w[0].time < w[1].time));
    // Laps differ: the same point of the route has a different error realisation.
    let laps: Vec<Vec<f64>> = ev
        .split(|e| matches!(e, GpsEvent::Notice(_)))
        .map(|lap| {
            lap.iter().filter_map(|e| if let GpsEvent::Fix(f) = e { f.lat_deg } else { None }).collect()
        })
        .collect();
    let (a, b) = (&laps[0], &laps[1]);
    assert!(a.len() >= 5 && b.len() >= 5, "{laps:?}");
    assert!(a.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-9), "lap 2 repeats lap 1: {laps:?}");
}

/// An HDG compass in a replayed log reaches the consumer as an attitude, between unchanged fixes.
#[test]
fn replay_delivers_hdg_as_attitude() {
    let path = std::env::temp_dir().join(format!("vestnav-hdg-{}.log", std::process::id()));
    // Checksums computed with Python (XOR of the bytes between `$` and `*`).
    let text = "$GPGGA,110518.000,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.2,M,,0000*77\r\n\
                $HCHDG,98.3,0.0,E,12.6,W*57\r\n\
                $GPGGA,110519.000,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.2,M,,0000*76\r\n";
    std::fs::write(&path, text).unwrap();
    let (mut h, rx) =
        spawn(SourceConfig::Replay { path: path.clone(), speed: ReplaySpeed::AsFastAsPossible });
    let ev = collect(&rx, |e| e.contains(&GpsEvent::State(SourceState::Finished)), Duration::from_secs(10));
    h.stop();
    let _ = std::fs::remove_file(&path);
    let attitudes: Vec<_> =
        ev.iter().filter_map(|e| if let GpsEvent::Attitude(a) = e { Some(a) } else { None }).collect();
    assert_eq!(attitudes.len(), 1, "{ev:?}");
    assert!((attitudes[0].heading_deg - 98.3).abs() < 1e-12);
    assert_eq!(attitudes[0].origin, crate::heading::HeadingOrigin::Nmea);
    assert_eq!(ev.iter().filter(|e| matches!(e, GpsEvent::Fix(f) if f.has_position())).count(), 2);
}
