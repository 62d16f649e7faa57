//! End-to-end latency of the console's guidance path over real pseudo-terminals: from the last NMEA sentence
//! of an epoch written into the GPS PTY to the PLAY frame read from the vest PTY by the unit.
//!
//! The chain under test, each part the production code:
//! - a PTY pair for the GPS: the test writes NMEA (`gps::nmea_out::epoch_sentences`) into the master;
//!   `GpsSource` (`SourceConfig::Serial`, fixed baud) opens the slave path like hardware and decodes it;
//! - the steps of the app's guidance worker on one thread: `GpsEvent::Fix` -> `hardware::convert_fix` ->
//!   `guidance::nav_input` (age 0, wall-clock `now_s`) -> `Guidance::update` (pursuit) -> for a decided cue
//!   `VestHandle::send(VestCommand::Play(pattern))` (the app routes the fix through a router thread and a
//!   channel first; those hops are not included);
//! - `VestHandle` (`VestConfig::Serial`) on the slave of a second PTY pair, with the WTCU engine served on its
//!   master (`emulator::serve`, so the handshake, ACKs and heartbeats are the real ones). A tap between the
//!   master and the engine timestamps every read and decodes the console's bytes with its own `V1Codec`.
//!
//! Each measured epoch moves the walker 1.4 m up a northbound leg and flips its course over ground between
//! 90° and 270°, so the bearing error flips between -90° and +90° and every epoch asks for a new cue
//! (turn left, turn right, ...). Patterns are shortened (`on_ms` 10) and the next epoch is written only after
//! the previous pattern has ended, so the rate limiter never holds a cue back. No timing assertions (speed
//! goals live in benches): the test prints p50/p99/max and asserts that at least 90 % of the epochs produced
//! the expected PLAY frame and that every frame decodes and is accepted by the unit.

// Pseudo-terminals are Unix-only.
#![cfg(unix)]

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use chrono::{DateTime, NaiveTime, TimeZone, Utc};
use vestnav_core::geo::{Earth, LatLon};
use vestnav_core::guidance::{Guidance, GuidanceConfig, Route, RouteConfig, StrategyKind, Waypoint};
use vestnav_core::vest::{Cue, Frame};
use vestnav_device::gps::nmea_out::{EpochOut, SimSatellite, epoch_sentences};
use vestnav_device::gps::{GpsEvent, GpsSource, SourceConfig, SourceState};
use vestnav_device::serial::Pty as GpsPty;
use vestnav_device::wtcu::codec::{DecodeError, V1Codec, WireCodec};
use vestnav_device::wtcu::emulator::{EmulatorControl, Pty as VestPty, serve};
use vestnav_device::wtcu::engine::{Engine, EngineConfig, EngineEvent};
use vestnav_device::wtcu::link::LinkState;
use vestnav_device::wtcu::message::{CommandKind, Packet, Request};
use vestnav_device::wtcu::worker::{VestCommand, VestConfig, VestEvent, VestHandle};

/// Epochs measured.
const EPOCHS: usize = 100;
/// Epochs before the measurement: the live decoder learns the cycle's last sentence from two epochs (until
/// then an epoch is closed by the 400 ms quiet gap), the third is the first emitted at its last sentence.
const WARMUP: usize = 3;
/// Pattern step on-time [ms]: short patterns so a cue has ended well before the next epoch.
const ON_MS: u16 = 10;
/// Extra wait after a PLAY arrived before the next epoch, on top of the pattern's length.
const PACE_MARGIN: Duration = Duration::from_millis(20);
/// How long one stage may take before the epoch counts as failed (generous: a loaded 2-core CI machine).
const STAGE_TIMEOUT: Duration = Duration::from_secs(1);
/// Measurement stops after this, so the test ends in bounded time however slow the machine is.
const BUDGET: Duration = Duration::from_secs(12);
/// Walking speed in the NMEA [m/s] (above the 0.8 m/s at which guidance trusts the course over ground).
const SPEED_M_S: f64 = 1.4;
/// Start of the leg (Briggs Field, Cambridge MA).
const START: LatLon = LatLon::new(42.3575, -71.1010);

/// A PLAY frame as the unit side read it.
#[derive(Debug)]
struct UnitPlay {
    /// When the read that completed the frame returned.
    at: Instant,
    frames: Vec<Frame>,
    repeats: u8,
}

/// What the pipeline did with one fix.
#[derive(Debug)]
struct Decided {
    /// UTC time of day of the fix.
    tod: Option<NaiveTime>,
    /// When the pipeline received the `Fix` event.
    fix_rx: Instant,
    /// The cue guidance decided, if any.
    cue: Option<Cue>,
    /// When `VestHandle::send` returned (`None`: no cue, or the send failed).
    sent: Option<Instant>,
}

/// Counters of the unit side.
#[derive(Debug, Default)]
struct UnitCounts {
    /// Blocks the tap's codec could not decode.
    decode_errors: AtomicU64,
    /// Retransmitted PLAY frames (same sequence number again), not forwarded.
    retransmissions: AtomicU64,
    /// PLAY requests the engine accepted.
    plays_accepted: AtomicU64,
    /// Requests the engine refused (NAK).
    rejected: AtomicU64,
}

/// Reads the vest PTY's master for the engine, timestamping and decoding the console's bytes on the way.
struct Tap<'a, P: Read + Write> {
    port: &'a mut P,
    codec: V1Codec,
    decoded: Vec<Result<Packet<Request>, DecodeError>>,
    last_play_seq: Option<u8>,
    plays: Sender<UnitPlay>,
    counts: Arc<UnitCounts>,
}

impl<P: Read + Write> Read for Tap<'_, P> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.port.read(buf)?;
        let at = Instant::now();
        self.codec.decode_requests(buf.get(..n).unwrap_or(&[]), &mut self.decoded);
        for packet in self.decoded.drain(..) {
            match packet {
                Ok(p) => {
                    if let Request::Play { frames, repeats } = p.message {
                        if self.last_play_seq == Some(p.seq) {
                            self.counts.retransmissions.fetch_add(1, Ordering::Relaxed);
                        } else {
                            self.last_play_seq = Some(p.seq);
                            let _ = self.plays.send(UnitPlay { at, frames, repeats });
                        }
                    }
                }
                Err(_) => {
                    self.counts.decode_errors.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        Ok(n)
    }
}

impl<P: Read + Write> Write for Tap<'_, P> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.port.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.port.flush()
    }
}

/// The UTC time of epoch `k`.
fn epoch_time(k: usize) -> DateTime<Utc> {
    Utc.with_ymd_and_hms(2025, 6, 1, 12, 0, 0).unwrap() + chrono::Duration::seconds(i64::try_from(k).unwrap())
}

/// Course over ground of epoch `k` [deg] and the cue it must produce on a northbound leg.
fn course_and_cue(k: usize) -> (f64, Cue) {
    if k.is_multiple_of(2) { (90.0, Cue::TurnLeft) } else { (270.0, Cue::TurnRight) }
}

/// The sentences of epoch `k`, split into everything but the last sentence and the last sentence.
fn epoch_text(k: usize) -> (String, String) {
    let pos = Earth::Wgs84.direct(START, 0.0, 10.0 + SPEED_M_S * k as f64);
    let satellites = (1..=8)
        .map(|prn| SimSatellite {
            prn,
            elevation_deg: 20.0 + 5.0 * f64::from(prn),
            azimuth_deg: 40.0 * f64::from(prn),
            snr_dbhz: 40.0,
            used: true,
        })
        .collect();
    let text = epoch_sentences(&EpochOut {
        time: epoch_time(k),
        lat_deg: Some(pos.lat_deg),
        lon_deg: Some(pos.lon_deg),
        alt_m: 10.0,
        speed_m_s: SPEED_M_S,
        course_deg: course_and_cue(k).0,
        satellites,
        hdop: 0.9,
        pdop: 1.6,
        vdop: 1.3,
        sigma_m: 1.0,
    });
    let split = text.rfind('$').unwrap();
    (text[..split].to_owned(), text[split..].to_owned())
}

/// The app's guidance steps for every fix until `stop`, reporting each decision on `decided`.
fn run_pipeline(
    gps: &vestnav_device::gps::GpsHandle,
    vest: &VestHandle,
    mut guidance: Guidance,
    stop: &AtomicBool,
    decided: &Sender<Decided>,
) -> (u64, Vec<String>) {
    let start = Instant::now();
    let mut acked_plays = 0;
    let mut problems = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        if let Some(GpsEvent::Fix(fix)) = gps.recv_timeout(Duration::from_millis(10)) {
            let fix_rx = Instant::now();
            let now_s = start.elapsed().as_secs_f64();
            let input = vestnav_app::guidance::nav_input(&vestnav_app::hardware::convert_fix(&fix), 0.0);
            let d = guidance.update(&input, now_s);
            let mut sent = None;
            if let (Some(_), Some(pattern)) = (d.cue, d.pattern) {
                match vest.send(VestCommand::Play(pattern)) {
                    Ok(()) => sent = Some(Instant::now()),
                    Err(e) => problems.push(format!("send failed: {e}")),
                }
            }
            let _ = decided.send(Decided { tod: fix.time_of_day, fix_rx, cue: d.cue, sent });
        }
        while let Some(ev) = vest.try_recv() {
            match ev {
                VestEvent::Acked { kind: CommandKind::Play, .. } => acked_plays += 1,
                VestEvent::Rejected { kind, reason } => {
                    problems.push(format!("{} rejected: {reason}", kind.name()));
                }
                VestEvent::State(s) if s != LinkState::Ready => problems.push(format!("vest link {s:?}")),
                _ => {}
            }
        }
    }
    (acked_plays, problems)
}

/// Waits for the pipeline's decision on the fix of time `tod`, skipping others (counted in `stale`).
fn wait_decided(
    rx: &Receiver<Decided>,
    tod: NaiveTime,
    timeout: Duration,
    stale: &mut u32,
) -> Option<Decided> {
    let deadline = Instant::now() + timeout;
    loop {
        let left = deadline.checked_duration_since(Instant::now())?;
        let d = rx.recv_timeout(left).ok()?;
        if d.tod == Some(tod) {
            return Some(d);
        }
        *stale += 1;
    }
}

/// Nearest-rank percentile of sorted `xs` [ms].
fn percentile_ms(sorted: &[Duration], q: f64) -> f64 {
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1].as_secs_f64() * 1e3
}

fn summary(name: &str, mut xs: Vec<Duration>) -> String {
    xs.sort_unstable();
    format!(
        "{name}: p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
        percentile_ms(&xs, 0.5),
        percentile_ms(&xs, 0.99),
        percentile_ms(&xs, 1.0)
    )
}

#[test]
#[allow(clippy::too_many_lines)] // one measurement, set up, run and torn down in order
fn nmea_fix_to_vest_play_latency_p50_p99() {
    let test_start = Instant::now();

    // The unit: the WTCU engine served on the master of the vest PTY, behind the tap.
    let VestPty { mut master, path: vest_path, slave } = VestPty::open().unwrap();
    let control = Arc::new(EmulatorControl::default());
    let counts = Arc::new(UnitCounts::default());
    let (play_tx, play_rx) = channel();
    let unit = {
        let (control, counts) = (control.clone(), counts.clone());
        std::thread::Builder::new()
            .name("latency-unit".into())
            .spawn(move || {
                let _slave = slave;
                let mut engine = Engine::new(EngineConfig::default());
                let mut tap = Tap {
                    port: &mut master,
                    codec: V1Codec::new(),
                    decoded: Vec::new(),
                    last_play_seq: None,
                    plays: play_tx,
                    counts: counts.clone(),
                };
                serve(&mut engine, &mut tap, &control, |_, ev| match ev {
                    EngineEvent::Accepted { kind: CommandKind::Play, .. } => {
                        counts.plays_accepted.fetch_add(1, Ordering::Relaxed);
                    }
                    EngineEvent::Rejected { .. } => {
                        counts.rejected.fetch_add(1, Ordering::Relaxed);
                    }
                    _ => {}
                })
            })
            .unwrap()
    };

    // The console's ends: the vest worker on the vest PTY's slave, the GPS source on the GPS PTY's slave.
    let vest = VestHandle::spawn(VestConfig::Serial { port: vest_path, baud: 115_200 }, || {}).unwrap();
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut ready = false;
    while !ready && Instant::now() < deadline {
        ready =
            matches!(vest.recv_timeout(Duration::from_millis(20)), Some(VestEvent::State(LinkState::Ready)));
    }
    assert!(ready, "vest link not ready within 5 s");

    let mut gps_pty = GpsPty::open().unwrap();
    let mut gps =
        GpsSource::spawn(SourceConfig::Serial { port: gps_pty.path().to_owned(), baud: Some(4800) }, || {})
            .unwrap();
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut live = false;
    while !live && Instant::now() < deadline {
        live = matches!(
            gps.recv_timeout(Duration::from_millis(20)),
            Some(GpsEvent::State(SourceState::Live { .. }))
        );
    }
    assert!(live, "GPS source not live within 5 s");

    // Guidance on a 1 km northbound leg, heading for its end; the walker starts 10 m up the leg.
    let end = Earth::Wgs84.direct(START, 0.0, 1000.0);
    let mut route =
        Route::new(vec![Waypoint::new("start", START), Waypoint::new("end", end)], RouteConfig::default())
            .unwrap();
    let _ = route.skip();
    let config = GuidanceConfig { on_ms: ON_MS, gap_s: 0.0, repeat_s: 0.0, ..GuidanceConfig::default() };
    let guidance = Guidance::new(route, config, StrategyKind::Pursuit);
    let pattern_len = Duration::from_millis(u64::from(Cue::TurnLeft.pattern(ON_MS).total_ms()))
        .max(Duration::from_millis(u64::from(Cue::TurnRight.pattern(ON_MS).total_ms())));

    let stop = Arc::new(AtomicBool::new(false));
    let (decided_tx, decided_rx) = channel();
    let problems = Arc::new(Mutex::new(Vec::new()));
    let pipeline = {
        let (stop, problems) = (stop.clone(), problems.clone());
        std::thread::Builder::new()
            .name("latency-pipeline".into())
            .spawn(move || {
                let (acked, found) = run_pipeline(&gps, &vest, guidance, &stop, &decided_tx);
                problems.lock().unwrap_or_else(PoisonError::into_inner).extend(found);
                vest.stop();
                gps.stop();
                acked
            })
            .unwrap()
    };

    let mut total = Vec::new();
    let mut gps_stage = Vec::new();
    let mut vest_stage = Vec::new();
    let (mut no_fix, mut no_cue, mut no_play, mut wrong_play, mut stale) = (0u32, 0u32, 0u32, 0u32, 0u32);
    for k in 0..WARMUP + EPOCHS {
        if test_start.elapsed() > BUDGET {
            break;
        }
        let measured = k >= WARMUP;
        while play_rx.try_recv().is_ok() {
            stale += u32::from(measured);
        }
        while decided_rx.try_recv().is_ok() {
            stale += u32::from(measured);
        }
        let (body, last) = epoch_text(k);
        gps_pty.write_all(body.as_bytes()).unwrap();
        let t_write = Instant::now();
        gps_pty.write_all(last.as_bytes()).unwrap();
        gps_pty.flush().unwrap();

        // Warm-up epochs are closed by the decoder's 400 ms quiet gap: allow for it.
        let timeout = if measured { STAGE_TIMEOUT } else { STAGE_TIMEOUT + Duration::from_millis(400) };
        let tod = epoch_time(k).time();
        let Some(decided) = wait_decided(&decided_rx, tod, timeout, &mut stale) else {
            no_fix += u32::from(measured);
            continue;
        };
        let (expected_cue, Some(sent)) = (course_and_cue(k).1, decided.sent) else {
            no_cue += u32::from(measured);
            std::thread::sleep(PACE_MARGIN);
            continue;
        };
        let Ok(play) = play_rx.recv_timeout(STAGE_TIMEOUT) else {
            no_play += u32::from(measured);
            continue;
        };
        std::thread::sleep(pattern_len + PACE_MARGIN);
        if !measured {
            continue;
        }
        let expected = expected_cue.pattern(ON_MS);
        if decided.cue != Some(expected_cue)
            || play.frames != expected.frames
            || play.repeats != expected.repeats
        {
            wrong_play += 1;
            continue;
        }
        total.push(play.at.saturating_duration_since(t_write));
        gps_stage.push(decided.fix_rx.saturating_duration_since(t_write));
        vest_stage.push(play.at.saturating_duration_since(sent));
    }

    stop.store(true, Ordering::Relaxed);
    let acked_plays = pipeline.join().unwrap();
    control.stop.store(true, Ordering::Relaxed);
    unit.join().unwrap().unwrap();
    let problems = problems.lock().unwrap_or_else(PoisonError::into_inner).clone();

    eprintln!(
        "NMEA fix -> guidance -> vest PLAY over two PTYs, {} of {EPOCHS} epochs measured \
         (no fix {no_fix}, no cue {no_cue}, no PLAY {no_play}, wrong PLAY {wrong_play}, stale {stale}; \
         {} s in all)",
        total.len(),
        test_start.elapsed().as_secs_f64().round()
    );
    assert!(!total.is_empty(), "no epoch produced a PLAY; problems: {problems:?}");
    eprintln!("  {}", summary("last NMEA sentence written -> PLAY frame read by the unit", total.clone()));
    eprintln!("  {}", summary("  of which: last sentence written -> Fix event in the pipeline", gps_stage));
    eprintln!("  {}", summary("  of which: VestHandle::send returned -> PLAY frame read", vest_stage));
    eprintln!(
        "  unit: {} PLAY accepted, {} refused, {} undecodable blocks, {} retransmitted PLAYs; console: {} PLAY ACKs",
        counts.plays_accepted.load(Ordering::Relaxed),
        counts.rejected.load(Ordering::Relaxed),
        counts.decode_errors.load(Ordering::Relaxed),
        counts.retransmissions.load(Ordering::Relaxed),
        acked_plays
    );

    assert!(
        total.len() * 10 >= EPOCHS * 9,
        "only {} of {EPOCHS} epochs produced the expected PLAY",
        total.len()
    );
    assert_eq!(counts.decode_errors.load(Ordering::Relaxed), 0, "the console sent undecodable bytes");
    assert_eq!(counts.rejected.load(Ordering::Relaxed), 0, "the unit refused a command");
    assert!(
        counts.plays_accepted.load(Ordering::Relaxed) >= total.len() as u64,
        "the unit accepted fewer PLAYs than were measured"
    );
    assert!(problems.is_empty(), "{problems:?}");
}
