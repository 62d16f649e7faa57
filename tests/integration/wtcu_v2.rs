//! Protocol v2 (heading from the unit's magnetometer): the v2 test vectors of `docs/wtcu-protocol.md`,
//! version negotiation (a v1 unit keeps working with a v2 console), and the heading stream end to end over
//! real pseudo-terminals (worker <-> emulator), with truths independent of the implementation: the
//! vectors come from a separate Python framing, the emulated wearer's true heading minus the WMM
//! declination is what an ideal sensor must report.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use vestnav_core::compass::Calibration;
use vestnav_device::heading::{HeadingOrigin, HeadingReference};
use vestnav_device::sim::{CompassSetup, SimulatedCompass, WearerMotion};
use vestnav_device::wtcu::codec::{FrameCodec, WireCodec, hex};
use vestnav_device::wtcu::emulator::{PtyEmulator, UnitConfig};
use vestnav_device::wtcu::engine::{Engine, EngineConfig, HeadingSensor, heading_report};
use vestnav_device::wtcu::limits::Limits;
use vestnav_device::wtcu::link::{Link, LinkConfig, LinkEvent, LinkState};
use vestnav_device::wtcu::message::{
    CalibrationWire, Capabilities, DeviceInfo, FirmwareVersion, HeadingReport, NakReason, Packet, Reply,
    Request,
};
use vestnav_device::wtcu::worker::{VestCommand, VestEvent, WorkerSettings};

use super::wtcu::{Vest, pty_connector, wait_for};

const DOC: &str = include_str!("../../docs/wtcu-protocol.md");

fn unhex(s: &str) -> Vec<u8> {
    s.split_whitespace().map(|b| u8::from_str_radix(b, 16).unwrap()).collect()
}

// ---------------------------------------------------------------------------------------------------------
// Test vectors (produced by an independent Python implementation of the framing, printed in the document).

#[test]
fn v2_vectors_match_the_document_both_ways() {
    let requests: Vec<(u8, Request, &str)> = vec![
        (0, Request::Hello, "00 03 02 01 01 03 98 5e 00"),
        (1, Request::HeadingStart { rate_hz: 5 }, "00 08 02 08 01 01 05 e8 84 00"),
        (2, Request::HeadingStop, "00 04 02 09 02 03 5b 91 00"),
        (
            3,
            Request::SetCalibration(CalibrationWire {
                hard_iron_dut: [123, -300, 255],
                soft_iron_q12: [4096, 0, 0, 0, 4096, 0, 0, 0, 4096],
                field_dut: 500,
            }),
            "00 06 02 0a 03 1a 7b 04 d4 fe ff 01 02 10 01 01 01 01 01 01 02 10 01 01 01 01 01 01 06 10 f4 01 5a \
             82 00",
        ),
    ];
    let mut codec = FrameCodec::new();
    for (seq, request, want) in requests {
        let want = want.split_whitespace().collect::<Vec<_>>().join(" ");
        assert!(DOC.contains(&want), "vector missing from docs/wtcu-protocol.md: {want}");
        assert_eq!(hex(&codec.encode_request(seq, &request).unwrap()), want, "{request:?}");
        let mut out = Vec::new();
        codec.decode_requests(&unhex(&want), &mut out);
        assert_eq!(out, vec![Ok(Packet { version: 2, seq, message: request })]);
    }
    let info = DeviceInfo {
        protocol_version: 2,
        firmware: FirmwareVersion { major: 2, minor: 0, patch: 0 },
        tactor_count: 16,
        capabilities: Capabilities::INTENSITY | Capabilities::PATTERNS | Capabilities::HEADING,
        limits: Limits::default(),
        watchdog_ms: 1500,
    };
    let heading = HeadingReport {
        heading_cdeg: 12_345,
        pitch_cdeg: -250,
        roll_cdeg: 100,
        quality_pct: 87,
        raw_mag_dut: [182, -31, 410],
    };
    let replies: Vec<(u8, Reply, &str)> = vec![
        (
            0,
            Reply::Identify(info),
            "00 03 02 81 03 11 02 01 11 10 07 d0 07 08 10 27 88 13 20 10 27 dc 05 fa cc 00",
        ),
        (9, Reply::Heading(heading), "00 0a 02 86 09 0d 39 30 06 ff 64 03 57 b6 07 e1 ff 9a 01 79 41 00"),
    ];
    for (seq, reply, want) in replies {
        assert!(DOC.contains(want), "vector missing from docs/wtcu-protocol.md: {want}");
        assert_eq!(hex(&codec.encode_reply(seq, &reply)), want, "{reply:?}");
        let mut out = Vec::new();
        codec.decode_replies(&unhex(want), &mut out);
        assert_eq!(out, vec![Ok(Packet { version: 2, seq, message: reply })]);
    }
    // The v1 unit's refusal of a v2 header, in a v1 header.
    let nak = "00 03 01 83 03 03 04 01 03 73 14 00";
    assert!(DOC.contains(nak));
    let mut v1_unit = Engine::new(EngineConfig { protocol_version: 1, ..EngineConfig::default() });
    v1_unit.handle_bytes(&unhex("00 03 02 01 01 03 98 5e 00"), Instant::now());
    assert_eq!(hex(&v1_unit.poll_transmit().unwrap()), nak);
}

#[test]
fn v2_messages_are_unknown_in_a_v1_frame_and_bad_headings_are_refused() {
    // A v2 type in a v1 header decodes as on a v1 unit: unknown type.
    let v1 = FrameCodec::with_max_version(1);
    let frame = v1.encode_request(4, &Request::HeadingStart { rate_hz: 5 }).unwrap();
    let mut out = Vec::new();
    FrameCodec::new().decode_requests(&frame, &mut out);
    assert!(matches!(out[0], Err(ref e) if e.nak_reason() == Some(NakReason::UnknownCommand)), "{out:?}");
    // A heading of 360.00° or a pitch past 90° never decodes.
    let codec = FrameCodec::new();
    for bad in [
        HeadingReport {
            heading_cdeg: 36_000,
            pitch_cdeg: 0,
            roll_cdeg: 0,
            quality_pct: 0,
            raw_mag_dut: [0; 3],
        },
        HeadingReport {
            heading_cdeg: 0,
            pitch_cdeg: 9_001,
            roll_cdeg: 0,
            quality_pct: 0,
            raw_mag_dut: [0; 3],
        },
        HeadingReport { heading_cdeg: 0, pitch_cdeg: 0, roll_cdeg: 0, quality_pct: 101, raw_mag_dut: [0; 3] },
    ] {
        let mut out = Vec::new();
        FrameCodec::new().decode_replies(&codec.encode_reply(1, &Reply::Heading(bad)), &mut out);
        assert!(matches!(out[0], Err(ref e) if e.nak_reason() == Some(NakReason::Malformed)), "{bad:?}");
    }
}

// ---------------------------------------------------------------------------------------------------------
// Negotiation and the stream on a simulated clock (link <-> engine, no IO).

/// Runs a link against an engine for `ms` of simulated time in 1 ms steps; returns the link's events.
fn run(link: &mut Link, unit: &mut Engine, t0: Instant, from_ms: u64, to_ms: u64) -> Vec<LinkEvent> {
    let mut events = Vec::new();
    for ms in from_ms..to_ms {
        let now = t0 + Duration::from_millis(ms);
        unit.handle_timeout(now);
        link.handle_timeout(now);
        while let Some(b) = link.poll_transmit() {
            unit.handle_bytes(&b, now);
        }
        while let Some(b) = unit.poll_transmit() {
            link.handle_bytes(&b, now);
        }
        while let Some(e) = link.poll_event() {
            events.push(e);
        }
    }
    events
}

fn ideal_compass(heading_deg: f64) -> CompassSetup {
    CompassSetup { motion: WearerMotion::Still { heading_deg }, steel_east_m: None, ideal: true, seed: 7 }
}

#[test]
fn a_v1_unit_still_works_with_a_v2_console() {
    let t0 = Instant::now();
    let mut unit = Engine::new(EngineConfig { protocol_version: 1, ..EngineConfig::default() });
    let mut link = Link::new(LinkConfig::default());
    link.connect(t0);
    let events = run(&mut link, &mut unit, t0, 0, 50);
    assert_eq!(*link.state(), LinkState::Ready, "{events:?}");
    assert_eq!(link.stats().version_fallbacks, 1);
    let info = link.device().unwrap();
    assert_eq!(info.protocol_version, 1);
    assert!(!info.capabilities.contains(Capabilities::HEADING));
    assert_eq!(unit.session_version(), 1);
    // Cues work as before; the heading stream is refused before anything is sent.
    link.fire(vestnav_core::vest::TactorMask::CORNERS, 300, t0 + Duration::from_millis(50)).unwrap();
    let events = run(&mut link, &mut unit, t0, 50, 100);
    assert!(events.iter().any(|e| matches!(e, LinkEvent::Acked { .. })), "{events:?}");
    assert!(link.heading_start(5, t0 + Duration::from_millis(100)).is_err());
}

#[test]
fn a_v2_unit_streams_heading_at_the_asked_rate_and_takes_a_calibration() {
    let t0 = Instant::now();
    let mut unit = Engine::with_codec(EngineConfig::default(), FrameCodec::new())
        .with_heading_sensor(Box::new(SimulatedCompass::new(&ideal_compass(90.0))));
    let mut link = Link::new(LinkConfig::default());
    link.connect(t0);
    run(&mut link, &mut unit, t0, 0, 50);
    let info = link.device().unwrap();
    assert_eq!((info.protocol_version, link.stats().version_fallbacks), (2, 0));
    assert!(info.capabilities.contains(Capabilities::HEADING));
    link.heading_start(5, t0 + Duration::from_millis(50)).unwrap();
    let events = run(&mut link, &mut unit, t0, 50, 2_050);
    let headings: Vec<HeadingReport> =
        events.iter().filter_map(|e| if let LinkEvent::Heading(h) = e { Some(*h) } else { None }).collect();
    // 5 Hz for 2 s, the first at once: 10 or 11 readings.
    assert!((10..=11).contains(&headings.len()), "{} readings", headings.len());
    // Uncalibrated: quality 0. The ideal sensor's raw field is the Earth's; its heading is the true heading
    // (90°) minus the declination of the emulated place.
    let declination = SimulatedCompass::new(&ideal_compass(90.0)).declination_deg();
    for h in &headings {
        assert_eq!(h.quality_pct, 0);
        let want = (90.0 - declination).rem_euclid(360.0);
        assert!((f64::from(h.heading_cdeg) / 100.0 - want).abs() < 0.02, "{h:?} want {want}");
    }
    // A calibration with the field's strength makes the quality 100 for an ideal sensor.
    let raw = headings[0].raw_mag_dut.map(|v| f64::from(v) / 10.0);
    let field = raw.iter().map(|v| v * v).sum::<f64>().sqrt();
    let cal = Calibration::identity(field).to_wire().unwrap();
    link.set_calibration(cal, t0 + Duration::from_millis(2_050)).unwrap();
    let events = run(&mut link, &mut unit, t0, 2_050, 2_500);
    assert!(events.iter().any(|e| matches!(e, LinkEvent::Acked { .. })), "{events:?}");
    let last = events.iter().rev().find_map(|e| if let LinkEvent::Heading(h) = e { Some(*h) } else { None });
    assert!(last.unwrap().quality_pct >= 99, "{last:?}");
    // A calibration that is not positive definite is refused and the old one kept.
    let mut bad = cal;
    bad.soft_iron_q12[0] = -4096;
    link.set_calibration(bad, t0 + Duration::from_millis(2_500)).unwrap();
    let events = run(&mut link, &mut unit, t0, 2_500, 2_600);
    assert!(
        events.iter().any(|e| matches!(e, LinkEvent::Rejected { reason: NakReason::Malformed, .. })),
        "{events:?}"
    );
    assert_eq!(unit.calibration(), Calibration::from_wire(&cal));
    // Stopping ends the stream.
    link.heading_stop(t0 + Duration::from_millis(2_600)).unwrap();
    run(&mut link, &mut unit, t0, 2_600, 2_700);
    let after = run(&mut link, &mut unit, t0, 2_700, 3_700);
    assert!(!after.iter().any(|e| matches!(e, LinkEvent::Heading(_))), "{after:?}");
}

#[test]
fn heading_report_is_the_tilt_compensated_heading_of_the_calibrated_field() {
    // Closed form: a level sensor facing east in a field of 20 µT north and 45 µT down reads the north
    // field on its left (-y): m = (0, -20, 45). With hard iron (5, 5, 5) added, the calibration removes it.
    let cal = Calibration { hard_iron_ut: [5.0, 5.0, 5.0], ..Calibration::identity((20.0f64).hypot(45.0)) };
    let r = heading_report([5.0, -15.0, 50.0], [0.0, 0.0, -9.81], &cal).unwrap();
    assert_eq!(r.heading_cdeg, 9_000);
    assert_eq!((r.pitch_cdeg, r.roll_cdeg), (0, 0));
    assert_eq!(r.quality_pct, 100);
    assert_eq!(r.raw_mag_dut, [50, -150, 500]);
    // Free fall: no heading at all.
    assert!(heading_report([5.0, -15.0, 50.0], [0.0, 0.0, 0.0], &cal).is_none());
}

#[test]
fn a_full_unread_queue_drops_headings_first_and_keeps_answers() {
    let t0 = Instant::now();
    let mut unit = Engine::with_codec(EngineConfig::default(), FrameCodec::new())
        .with_heading_sensor(Box::new(SimulatedCompass::new(&ideal_compass(0.0))));
    let codec = FrameCodec::new();
    unit.handle_bytes(&codec.encode_request(0, &Request::Hello).unwrap(), t0);
    unit.handle_bytes(&codec.encode_request(1, &Request::HeadingStart { rate_hz: 10 }).unwrap(), t0);
    // Nobody drains the unit for a minute; heartbeats keep arriving.
    for s in 1..60u8 {
        let now = t0 + Duration::from_secs(u64::from(s));
        unit.handle_bytes(&codec.encode_request(s.wrapping_add(1), &Request::Heartbeat).unwrap(), now);
    }
    let mut frames = Vec::new();
    while let Some(f) = unit.poll_transmit() {
        frames.push(f);
    }
    let mut out = Vec::new();
    let mut decoder = FrameCodec::new();
    for f in &frames {
        decoder.decode_replies(f, &mut out);
    }
    let headings = out.iter().filter(|r| matches!(r, Ok(Packet { message: Reply::Heading(_), .. }))).count();
    // Unsent headings are superseded: at most one waits at a time.
    assert!(headings <= 1, "{headings} headings queued");
    let acks = out.iter().filter(|r| matches!(r, Ok(Packet { message: Reply::Ack { .. }, .. }))).count();
    assert_eq!(acks, 60, "every answer kept (HEADING_START and 59 heartbeats)");
}

// ---------------------------------------------------------------------------------------------------------
// Over real pseudo-terminals: the worker against the emulator program's engine.

#[test]
fn pty_heading_stream_reaches_the_console_and_a_v1_emulator_still_works() {
    // v2 unit, wearer turning in place at 30°/s: the readings follow the turn, received-at stamped.
    let setup = CompassSetup {
        motion: WearerMotion::Turning { start_deg: 0.0, rate_deg_s: 30.0 },
        steel_east_m: None,
        ideal: true,
        seed: 3,
    };
    let emu = PtyEmulator::spawn(UnitConfig { compass: Some(setup), ..UnitConfig::default() }).unwrap();
    let vest =
        Vest::spawn(pty_connector(Arc::new(Mutex::new(emu.path().to_owned()))), WorkerSettings::default());
    let mut seen = Vec::new();
    let s = Duration::from_secs(3);
    let id = wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::Identified(_)));
    assert!(matches!(id, VestEvent::Identified(d) if d.protocol_version == 2));
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::State(LinkState::Ready)));
    vest.send(VestCommand::HeadingStart { rate_hz: 10 }).unwrap();
    let mut readings = Vec::new();
    let start = Instant::now();
    while readings.len() < 15 && start.elapsed() < Duration::from_secs(4) {
        if let VestEvent::Heading(a) = wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::Heading(_))) {
            assert!(a.validate().is_ok());
            assert_eq!((a.origin, a.reference), (HeadingOrigin::Vest, HeadingReference::Magnetic));
            assert!(a.received_at >= start && a.received_at <= Instant::now());
            readings.push(a);
        }
    }
    assert!(readings.len() >= 15, "{} readings in 4 s at 10 Hz", readings.len());
    // Turning clockwise at 30°/s: successive readings 0.1 s apart advance by about 3° (unwrapped).
    let steps: Vec<f64> =
        readings.windows(2).map(|w| (w[1].heading_deg - w[0].heading_deg).rem_euclid(360.0)).collect();
    let mean = steps.iter().sum::<f64>() / steps.len() as f64;
    assert!((mean - 3.0).abs() < 1.0, "mean step {mean:.2}° ({steps:?})");
    assert!(vest.stop());
    drop(emu);

    // A v1 unit: the console falls back, cues work, and asking for heading is refused with a reason.
    let emu = PtyEmulator::spawn(EngineConfig { protocol_version: 1, ..EngineConfig::default() }).unwrap();
    let vest =
        Vest::spawn(pty_connector(Arc::new(Mutex::new(emu.path().to_owned()))), WorkerSettings::default());
    let mut seen = Vec::new();
    let id = wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::Identified(_)));
    assert!(matches!(id, VestEvent::Identified(d) if d.protocol_version == 1));
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::State(LinkState::Ready)));
    vest.send(VestCommand::Fire { mask: vestnav_core::vest::TactorMask::CORNERS, duration_ms: 200 }).unwrap();
    wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::Acked { .. }));
    vest.send(VestCommand::HeadingStart { rate_hz: 5 }).unwrap();
    let refused = wait_for(&vest, &mut seen, s, |e| matches!(e, VestEvent::Rejected { .. }));
    assert!(
        matches!(&refused, VestEvent::Rejected { reason, .. } if reason.contains("heading")),
        "{refused:?}"
    );
    assert!(vest.stop());
}

/// The emulated sensor with a parked car 1.5 m away: the heading is off by degrees and the quality drops,
/// as the sensor model says (the truth here is the undisturbed reading of the same sensor).
#[test]
fn steel_near_the_emulated_unit_shows_in_heading_and_quality() {
    let mut clean = SimulatedCompass::new(&ideal_compass(45.0));
    let mut near_car =
        SimulatedCompass::new(&CompassSetup { steel_east_m: Some(1.5), ..ideal_compass(45.0) });
    let t = Instant::now();
    let (m0, a0) = clean.sample(t);
    let field = m0.iter().map(|v| v * v).sum::<f64>().sqrt();
    let cal = Calibration::identity(field);
    let r0 = heading_report(m0, a0, &cal).unwrap();
    let (m1, a1) = near_car.sample(t);
    let r1 = heading_report(m1, a1, &cal).unwrap();
    assert_eq!(r0.quality_pct, 100);
    assert!(r1.quality_pct < 90, "{r1:?}");
    let diff = (f64::from(r1.heading_cdeg) - f64::from(r0.heading_cdeg)) / 100.0;
    assert!(diff.abs() > 2.0, "a car at 1.5 m moved the heading by only {diff:.2}°");
}

/// One simulated wearer for both simulated devices: the GPS simulator publishes its walker's truth and the
/// emulated unit's compass measures that body. Truth: the first leg's geodesic bearing (the walker's course
/// on it) minus the WMM declination is what an ideal compass reads.
#[test]
fn the_emulated_compass_follows_the_gps_simulator_s_walker() {
    use vestnav_core::geo::{Earth, LatLon};
    use vestnav_core::gnss_sim::GnssErrorModel;
    use vestnav_device::gps::{GpsEvent, GpsSource, SourceConfig};
    use vestnav_device::sim::SharedTruth;

    let route = vec![(42.3562, -71.1000), (42.3572, -71.0985), (42.3580, -71.1000)];
    let truth = SharedTruth::default();
    let (mut gps, rx) = GpsSource::spawn_channel(
        SourceConfig::Simulator {
            route: route.clone(),
            pace_m_s: 1.4,
            model: GnssErrorModel::perfect(),
            seed: 1,
            period: Duration::from_millis(100),
            looped: false,
            truth: Some(truth.clone()),
        },
        64,
        None,
    )
    .unwrap();
    let deadline = Instant::now() + Duration::from_secs(3);
    while !matches!(rx.recv_timeout(Duration::from_millis(50)), Ok(GpsEvent::Fix(_))) {
        assert!(Instant::now() < deadline, "no fix from the simulator");
    }
    gps.stop();
    let body = truth.get().expect("the simulator published its walker");
    let leg_deg = Earth::Wgs84
        .initial_bearing_deg(LatLon::new(route[0].0, route[0].1), LatLon::new(route[1].0, route[1].1));
    assert!((body.heading_true_deg - leg_deg).abs() < 0.5, "{body:?} vs leg {leg_deg:.2}°");
    assert!((body.pace_m_s - 1.4).abs() < 1e-9);

    let setup = CompassSetup { motion: WearerMotion::Follow(truth), ..ideal_compass(0.0) };
    let mut compass = SimulatedCompass::new(&setup);
    let (raw, accel) = compass.sample(Instant::now());
    let r = heading_report(raw, accel, &Calibration::identity(50.0)).unwrap();
    let want = (body.heading_true_deg - compass.declination_deg()).rem_euclid(360.0);
    let got = f64::from(r.heading_cdeg) / 100.0;
    assert!((got - want).abs() < 0.05, "compass {got:.2}°, walker {want:.2}° magnetic");
}
