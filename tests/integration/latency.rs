//! End-to-end latency of the console's guidance path over real pseudo-terminals, through the threads the
//! console itself starts: from the last NMEA sentence of an epoch written into the GPS PTY to the PLAY
//! frame read from the vest PTY by the unit.
//!
//! The chain under test is the station's own, with no window (`Station::new` with the real `Hardware`
//! factory, as the console and `vestnav station` run it):
//! - a PTY pair for the GPS: the test writes NMEA (`gps::nmea_out::epoch_sentences`) into the master; the
//!   console's GPS source (serial, fixed baud) opens the slave path like hardware and decodes it;
//! - the source hands each `GpsEvent::Fix` straight to the console's guidance worker (its outbox), which
//!   runs `Guidance::update` (pursuit) and hands the decided cue to the vest worker;
//! - the vest worker on the slave of a second PTY pair, with the WTCU engine served on its master
//!   (`emulator::serve`, so the handshake, ACKs and heartbeats are the real ones). A tap between the master
//!   and the engine timestamps every read and decodes the console's bytes with its own `FrameCodec`.
//!
//! Each measured epoch moves the walker 1.4 m up a northbound leg and flips its course over ground between
//! 90° and 270°, so the bearing error flips between -90° and +90° and every epoch asks for a new cue
//! (turn left, turn right, ...). The next epoch is written only after the previous pattern and the
//! engine's minimum gap between cues have passed, so the rate limiter never holds a cue back. No timing
//! assertions (speed goals live in benches): the test prints p50/p99/max and asserts that at least 90 % of
//! the epochs produced the expected PLAY frame (within the stage's 1 s) and that every frame decodes and is
//! accepted by the unit. The cue interval is the longest, so guidance never repeats the previous epoch's
//! cue between two fixes: with 0.5 s a repeat now and then fell just before the next fix and held that
//! fix's cue back for the rate limiter's whole gap and then to guidance's next 250 ms update (the 750 ms
//! "stall" earlier runs printed as p99). A PLAY of another cue while an epoch's is awaited is still counted
//! and printed, not taken for this epoch's, so one late cue cannot fail the next epochs in a cascade.

// Pseudo-terminals are Unix-only.
#![cfg(unix)]

use std::io::{Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Sender, channel};
use std::time::{Duration, Instant};

use chrono::{DateTime, TimeZone, Utc};
use vestnav_core::geo::{Earth, LatLon};
use vestnav_core::guidance::GuidanceConfig;
use vestnav_core::vest::{Cue, Frame};
use vestnav_device::gps::SourceState;
use vestnav_device::gps::nmea_out::{EpochOut, SimSatellite, epoch_sentences};
use vestnav_device::serial::Pty as GpsPty;
use vestnav_device::wtcu::LinkState;
use vestnav_device::wtcu::codec::{DecodeError, FrameCodec, WireCodec};
use vestnav_device::wtcu::emulator::UnitConfig;
use vestnav_device::wtcu::emulator::{EmulatorControl, Pty as VestPty, serve};
use vestnav_device::wtcu::engine::EngineEvent;
use vestnav_device::wtcu::message::{CommandKind, Packet, Request};
use vestnav_station::hardware::Hardware;
use vestnav_station::route::Waypoint;
use vestnav_station::sources::{GpsSourceConfig, VestSourceConfig};
use vestnav_station::{Station, StationOptions, StationSettings};

/// Epochs measured.
const EPOCHS: usize = 40;
/// Epochs before the measurement: the live decoder learns the cycle's last sentence from two epochs (until
/// then an epoch is closed by the 400 ms quiet gap), the third is the first emitted at its last sentence.
const WARMUP: usize = 3;
/// Pattern step on-time [ms]: the console's shortest (its settings clamp to 20..2000 ms).
const ON_MS: u16 = 20;
/// Extra wait after a PLAY arrived before the next epoch, on top of the pattern's length and the engine's
/// minimum gap between two cues.
const PACE_MARGIN: Duration = Duration::from_millis(40);
/// How long one stage may take before the epoch counts as failed (generous: a loaded 2-core CI machine).
const STAGE_TIMEOUT: Duration = Duration::from_secs(1);
/// Measurement stops after this, so the test ends in bounded time however slow the machine is.
const BUDGET: Duration = Duration::from_secs(45);
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
    codec: FrameCodec,
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
    let _exclusive = crate::timing_exclusive();
    let test_start = Instant::now();

    // The unit: the WTCU engine served on the master of the vest PTY, behind the tap.
    let VestPty { mut master, path: vest_path, slave } =
        VestPty::open_with_timeout(vestnav_device::wtcu::emulator::SERVE_POLL).unwrap();
    let control = Arc::new(EmulatorControl::default());
    let counts = Arc::new(UnitCounts::default());
    let (play_tx, play_rx) = channel();
    let unit = {
        let (control, counts) = (control.clone(), counts.clone());
        std::thread::Builder::new()
            .name("latency-unit".into())
            .spawn(move || {
                let _slave = slave;
                let mut engine = UnitConfig::default().build();
                let mut tap = Tap {
                    port: &mut master,
                    codec: FrameCodec::new(),
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

    // The console, with its own threads, on the two PTYs' slaves, guiding along a 1 km northbound leg and
    // heading for its end; the walker starts 10 m up the leg.
    let threads_before = thread_names();
    let mut gps_pty = GpsPty::open().unwrap();
    let end = Earth::Wgs84.direct(START, 0.0, 1000.0);
    let mut settings = StationSettings::default();
    settings.guidance.auto = true;
    settings.guidance.on_ms = ON_MS;
    // No repeats of a cue within the test (the station's longest interval): a repeat of the previous
    // epoch's cue falling just before the next fix holds that fix's cue for the whole gap, which is the rate
    // limiter's policy (`Guidance::allowed_from_s`), not the chain's latency.
    settings.guidance.cue_interval_s = 60.0;
    let log_dir = std::env::temp_dir().join(format!("vestnav-latency-{}", std::process::id()));
    let mut console = Station::new(
        Box::new(Hardware::default()),
        StationOptions {
            settings,
            gps: Some(GpsSourceConfig::Serial { port: gps_pty.path().to_owned(), baud: Some(4800) }),
            vest: Some(VestSourceConfig::Serial { port: vest_path }),
            log_dir: Some(log_dir.clone()),
            ..StationOptions::default()
        },
    );
    let leg = vec![
        Waypoint {
            name: "start".into(),
            lat_deg: START.lat_deg,
            lon_deg: START.lon_deg,
            arrival_radius_m: None,
        },
        Waypoint { name: "end".into(), lat_deg: end.lat_deg, lon_deg: end.lon_deg, arrival_radius_m: None },
    ];
    console.route_mut().replace("leg".into(), leg).unwrap();
    console.route_mut().set_next(1);
    console.connect_vest();
    console.connect_gps(Vec::new());
    let started: Vec<String> = thread_names().into_iter().filter(|n| !threads_before.contains(n)).collect();
    eprintln!("threads the console started: {} {started:?}", started.len());

    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline
        && !(console.vest.state == Some(LinkState::Ready)
            && matches!(console.gps.state, Some(SourceState::Live { .. })))
    {
        console.pump(|_| {});
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(console.vest.state, Some(LinkState::Ready), "vest link not ready within 5 s");
    assert!(matches!(console.gps.state, Some(SourceState::Live { .. })), "GPS source not live within 5 s");

    let gap = Duration::from_secs_f64(GuidanceConfig::default().gap_s);
    let pattern_len = Duration::from_millis(u64::from(Cue::TurnLeft.pattern(ON_MS).total_ms()))
        .max(Duration::from_millis(u64::from(Cue::TurnRight.pattern(ON_MS).total_ms())));

    let mut total = Vec::new();
    let (mut no_play, mut wrong_play, mut stale) = (0u32, 0u32, 0u32);
    for k in 0..WARMUP + EPOCHS {
        if test_start.elapsed() > BUDGET {
            break;
        }
        let measured = k >= WARMUP;
        while play_rx.try_recv().is_ok() {
            stale += u32::from(measured);
        }
        let (body, last) = epoch_text(k);
        gps_pty.write_all(body.as_bytes()).unwrap();
        let t_write = Instant::now();
        gps_pty.write_all(last.as_bytes()).unwrap();
        gps_pty.flush().unwrap();

        // Warm-up epochs are closed by the decoder's 400 ms quiet gap: allow for it.
        let timeout = if measured { STAGE_TIMEOUT } else { STAGE_TIMEOUT + Duration::from_millis(400) };
        let waited = Instant::now() + timeout;
        let expected = course_and_cue(k).1.pattern(ON_MS);
        let play = loop {
            // The test thread is the station's view here: drain as a view would.
            console.pump(|_| {});
            if let Ok(p) = play_rx.recv_timeout(Duration::from_millis(5)) {
                if p.frames == expected.frames && p.repeats == expected.repeats {
                    break Some(p);
                }
                // Another cue than this fix's (the previous epoch's, played late): counted, not taken for
                // this epoch's, which is still awaited within the stage's bound.
                wrong_play += u32::from(measured);
                continue;
            }
            if Instant::now() > waited {
                break None;
            }
        };
        let Some(play) = play else {
            no_play += u32::from(measured);
            continue;
        };
        let pace_until = Instant::now() + pattern_len + gap + PACE_MARGIN;
        while Instant::now() < pace_until {
            console.pump(|_| {});
            std::thread::sleep(Duration::from_millis(5));
        }
        if !measured {
            continue;
        }
        total.push(play.at.saturating_duration_since(t_write));
    }

    let acked_plays = console.vest.last_reply.is_some();
    console.shutdown();
    drop(console);
    let _ = std::fs::remove_dir_all(&log_dir);
    control.stop.store(true, Ordering::Relaxed);
    unit.join().unwrap().unwrap();

    eprintln!(
        "NMEA fix -> the console's guidance -> vest PLAY over two PTYs, {} of {EPOCHS} epochs measured \
         (no PLAY of the epoch's cue {no_play}, other cues while waiting {wrong_play}, stale {stale}; {} s in all)",
        total.len(),
        test_start.elapsed().as_secs_f64().round()
    );
    assert!(!total.is_empty(), "no epoch produced a PLAY");
    eprintln!("  {}", summary("last NMEA sentence written -> PLAY frame read by the unit", total.clone()));
    eprintln!(
        "  unit: {} PLAY accepted, {} refused, {} undecodable blocks, {} retransmitted PLAYs; console saw replies: {}",
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
}

/// This process's threads as "tid name" (Linux `/proc/self/task/*/comm`); run the test alone
/// (`--test-threads=1`) for the list of the console's own.
fn thread_names() -> Vec<String> {
    std::fs::read_dir("/proc/self/task")
        .map(|d| {
            d.flatten()
                .filter_map(|e| {
                    let name = std::fs::read_to_string(e.path().join("comm")).ok()?;
                    Some(format!("{} {}", e.file_name().to_string_lossy(), name.trim()))
                })
                .collect()
        })
        .unwrap_or_default()
}
