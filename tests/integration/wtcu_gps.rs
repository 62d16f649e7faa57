//! GPS through the vest unit (protocol v2, capability 0x08): the document's test vectors, and a real
//! receiver log forwarded by the emulated unit over a pseudo-terminal into the console's GPS decoder. The
//! truths are independent of the implementation: the vectors come from a separate Python framing, the
//! positions are read off the log's own NMEA by hand (degrees and minutes).

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use vestnav_device::gps::through_vest::vest_gps_pipe;
use vestnav_device::gps::{GpsEvent, GpsSource, SourceConfig, SourceState};
use vestnav_device::wtcu::codec::{FrameCodec, WireCodec, hex};
use vestnav_device::wtcu::emulator::PtyEmulator;
use vestnav_device::wtcu::engine::EngineConfig;
use vestnav_device::wtcu::limits::Limits;
use vestnav_device::wtcu::message::{Capabilities, DeviceInfo, FirmwareVersion, Packet, Reply, Request};
use vestnav_device::wtcu::worker::WorkerSettings;

use super::wtcu::{Vest, pty_connector};

const DOC: &str = include_str!("../../docs/wtcu-protocol.md");
/// `GlobalSat` BU-353-S4 (`SiRF` IV), gpsd's regression suite: its first fix is
/// `$GPGGA,030719.000,3747.0873,S,17518.8938,E,...`.
const LOG: &str = "tests/data/gpsd-logs/bu353s4.log";

fn unhex(s: &str) -> Vec<u8> {
    s.split_whitespace().map(|b| u8::from_str_radix(b, 16).unwrap()).collect()
}

#[test]
fn gps_vectors_match_the_document_both_ways() {
    let mut codec = FrameCodec::new();
    let requests = [
        (4, Request::GpsStart { baud: 9600 }, "00 07 02 0b 04 04 80 25 01 03 1e ca 00"),
        (5, Request::GpsStop, "00 04 02 0c 05 03 3c e3 00"),
    ];
    for (seq, request, want) in requests {
        assert!(DOC.contains(want), "vector missing from docs/wtcu-protocol.md: {want}");
        assert_eq!(hex(&codec.encode_request(seq, &request).unwrap()), want);
        let mut out = Vec::new();
        codec.decode_requests(&unhex(want), &mut out);
        assert_eq!(out, vec![Ok(Packet { version: 2, seq, message: request })]);
    }
    let info = DeviceInfo {
        protocol_version: 2,
        firmware: FirmwareVersion { major: 1, minor: 0, patch: 0 },
        tactor_count: 16,
        capabilities: Capabilities::INTENSITY
            | Capabilities::PATTERNS
            | Capabilities::HEADING
            | Capabilities::GPS,
        limits: Limits::default(),
        watchdog_ms: 1500,
    };
    let replies = [
        (
            12,
            Reply::GpsData { lost: 0, data: b"$GPZDA,1\r\n".to_vec() },
            "00 05 02 87 0c 0c 01 0d 24 47 50 5a 44 41 2c 31 0d 0a 5f 3c 00",
        ),
        (
            13,
            Reply::GpsData { lost: 300, data: b"*5B\r\n".to_vec() },
            "00 0e 02 87 0d 07 2c 01 2a 35 42 0d 0a 09 16 00",
        ),
        (
            0,
            Reply::Identify(info),
            "00 03 02 81 03 11 01 01 11 10 0f d0 07 08 10 27 88 13 20 10 27 dc 05 86 f6 00",
        ),
    ];
    for (seq, reply, want) in replies {
        assert!(DOC.contains(want), "vector missing from docs/wtcu-protocol.md: {want}");
        assert_eq!(hex(&codec.encode_reply(seq, &reply)), want);
        let mut out = Vec::new();
        codec.decode_replies(&unhex(want), &mut out);
        assert_eq!(out, vec![Ok(Packet { version: 2, seq, message: reply })]);
    }
}

#[test]
fn empty_or_oversized_gps_chunks_and_v1_headers_are_refused() {
    let codec = FrameCodec::new();
    // Hand-made payloads: lost 0 and no data; lost 0 and 199 bytes (the encoder would cut it).
    for data_len in [0usize, 199] {
        let mut payload = vec![0u8, 0];
        payload.extend(std::iter::repeat_n(b'x', data_len));
        let mut packet = vec![2u8, 0x87, 1, payload.len() as u8];
        packet.extend(&payload);
        let crc = vestnav_device::wtcu::codec::CRC16.checksum(&packet);
        packet.extend(crc.to_le_bytes());
        let mut frame = vec![0];
        vestnav_device::wtcu::codec::cobs_encode(&packet, &mut frame);
        frame.push(0);
        let mut out = Vec::new();
        FrameCodec::new().decode_replies(&frame, &mut out);
        assert!(matches!(out[..], [Err(_)]), "{data_len} data bytes: {out:?}");
    }
    // GPS_START in a v1 header is an unknown type, as on a v1 unit.
    let frame = FrameCodec::with_max_version(1).encode_request(3, &Request::GpsStart { baud: 9600 }).unwrap();
    let mut out = Vec::new();
    let _ = codec;
    FrameCodec::new().decode_requests(&frame, &mut out);
    assert!(
        matches!(out[..], [Err(ref e)] if e.nak_reason() == Some(vestnav_device::wtcu::message::NakReason::UnknownCommand))
    );
}

/// NMEA `ddmm.mmmm` plus hemisphere, in degrees.
fn nmea_deg(dm: &str, hemi: &str, deg_digits: usize) -> f64 {
    let deg: f64 = dm[..deg_digits].parse().unwrap();
    let min: f64 = dm[deg_digits..].parse().unwrap();
    let v = deg + min / 60.0;
    if hemi == "S" || hemi == "W" { -v } else { v }
}

/// The GPS source "through the vest unit" and a vest worker on an emulated unit's PTY, joined by a pipe.
fn through_vest(
    config: EngineConfig,
) -> (PtyEmulator, Vest, vestnav_device::gps::GpsHandle, std::sync::mpsc::Receiver<GpsEvent>) {
    let emu = PtyEmulator::spawn(config).unwrap();
    let (writer, reader) = vest_gps_pipe();
    let settings = WorkerSettings { gps: Some(writer), ..WorkerSettings::default() };
    let vest = Vest::spawn(pty_connector(Arc::new(Mutex::new(emu.path().to_owned()))), settings);
    let (gps, rx) =
        GpsSource::spawn_channel(SourceConfig::ThroughVest { reader, baud: 9600 }, 1024, None).unwrap();
    (emu, vest, gps, rx)
}

#[test]
fn a_receiver_log_forwarded_by_the_unit_decodes_to_its_own_positions() {
    let log = std::fs::read(LOG).unwrap();
    let config = EngineConfig { gps_nmea: Some(log.clone().into()), ..EngineConfig::default() };
    let (emu, vest, mut gps, rx) = through_vest(config);
    // The log's GGA positions, read by hand: every decoded fix must be one of them.
    let text = String::from_utf8_lossy(&log);
    let truths: Vec<(f64, f64)> = text
        .lines()
        .filter(|l| l.starts_with("$GPGGA"))
        .filter_map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f.len() > 6 && f[6] != "0" && !f[2].is_empty())
                .then(|| (nmea_deg(f[2], f[3], 2), nmea_deg(f[4], f[5], 3)))
        })
        .collect();
    let deadline = Instant::now() + Duration::from_secs(15);
    let (mut live, mut fixes) = (None, Vec::new());
    while Instant::now() < deadline && fixes.len() < 3 {
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(GpsEvent::State(SourceState::Live { detail })) => live = Some(detail),
            Ok(GpsEvent::Fix(f)) if f.has_position() => fixes.push(*f),
            _ => {}
        }
    }
    gps.stop();
    assert!(vest.stop());
    drop(emu);
    assert_eq!(live.as_deref(), Some("through the vest unit at 9600 baud"));
    assert!(fixes.len() >= 3, "{} fixes in 15 s", fixes.len());
    for f in &fixes {
        let (lat, lon) = (f.lat_deg.unwrap(), f.lon_deg.unwrap());
        assert!(
            truths.iter().any(|(a, b)| (a - lat).abs() < 1e-7 && (b - lon).abs() < 1e-7),
            "fix {lat} {lon} is not a position of the log"
        );
    }
}

#[test]
fn a_unit_without_a_receiver_is_named_as_the_reason() {
    let (emu, vest, mut gps, rx) = through_vest(EngineConfig::default());
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut reason = None;
    while Instant::now() < deadline && reason.is_none() {
        if let Ok(GpsEvent::State(SourceState::Lost { reason: r })) =
            rx.recv_timeout(Duration::from_millis(100))
        {
            reason = Some(r);
        }
    }
    gps.stop();
    assert!(vest.stop());
    drop(emu);
    let reason = reason.expect("no Lost state");
    assert!(reason.contains("no GPS receiver"), "{reason}");
}
