//! CASIC tests: frames written field by field from the protocol specification's tables (an independent
//! writer, not the decoder's readers), decoded through the whole NMEA decoder.

use std::time::Instant;

use crate::gps::fix::{Constellation, ErrorSource, FixMode, FixQuality};
use crate::gps::framing::{Frame, Framer};
use crate::gps::{Fix, GpsEvent, NmeaDecoder, decode_reader};

/// The checksum as the specification's section 2.2 states it, computed in 64 bits and reduced at the end.
fn spec_checksum(class: u8, id: u8, payload: &[u8]) -> u32 {
    let mut sum = (u64::from(id) << 24) + (u64::from(class) << 16) + payload.len() as u64;
    for w in payload.chunks(4) {
        let word = w.iter().enumerate().fold(0u64, |acc, (i, &b)| acc | (u64::from(b) << (8 * i)));
        sum += word;
    }
    (sum & 0xFFFF_FFFF) as u32
}

/// A frame written byte by byte: BA CE, length LE, class, id, payload, checksum LE.
fn spec_frame(class: u8, id: u8, payload: &[u8]) -> Vec<u8> {
    let mut out = vec![0xBA, 0xCE, (payload.len() & 0xFF) as u8, (payload.len() >> 8) as u8, class, id];
    out.extend_from_slice(payload);
    out.extend_from_slice(&spec_checksum(class, id, payload).to_le_bytes());
    out
}

/// Writes `bytes` at `offset` of a payload.
fn put(p: &mut [u8], offset: usize, bytes: &[u8]) {
    p[offset..offset + bytes.len()].copy_from_slice(bytes);
}

struct Pv {
    run_ms: u32,
    pos_valid: u8,
    num_sv: u8,
    pdop: f32,
    lat: f64,
    lon: f64,
    height: f32,
    sep: f32,
    h_var: f32,
    v_var: f32,
    speed2d: f32,
    heading: f32,
}

/// NAV-PV (0x01 0x03), 80 bytes, by the table of section 2.7.4.
fn nav_pv(v: &Pv) -> Vec<u8> {
    let mut p = vec![0u8; 80];
    put(&mut p, 0, &v.run_ms.to_le_bytes());
    p[4] = v.pos_valid;
    p[5] = v.pos_valid;
    p[6] = 0b011;
    p[7] = v.num_sv;
    put(&mut p, 12, &v.pdop.to_le_bytes());
    put(&mut p, 16, &v.lon.to_le_bytes());
    put(&mut p, 24, &v.lat.to_le_bytes());
    put(&mut p, 32, &v.height.to_le_bytes());
    put(&mut p, 36, &v.sep.to_le_bytes());
    put(&mut p, 40, &v.h_var.to_le_bytes());
    put(&mut p, 44, &v.v_var.to_le_bytes());
    put(&mut p, 64, &v.speed2d.to_le_bytes());
    put(&mut p, 68, &v.heading.to_le_bytes());
    spec_frame(0x01, 0x03, &p)
}

/// NAV-TIMEUTC (0x01 0x10), 24 bytes, by the table of section 2.7.5.
fn nav_timeutc(run_ms: u32, ymd: (u16, u8, u8), hms: (u8, u8, u8), valid: u8, date_valid: u8) -> Vec<u8> {
    let mut p = vec![0u8; 24];
    put(&mut p, 0, &run_ms.to_le_bytes());
    put(&mut p, 12, &ymd.0.to_le_bytes());
    p[14] = ymd.1;
    p[15] = ymd.2;
    p[16] = hms.0;
    p[17] = hms.1;
    p[18] = hms.2;
    p[19] = valid;
    p[21] = date_valid;
    spec_frame(0x01, 0x10, &p)
}

/// NAV-DOP (0x01 0x01), 28 bytes, by the table of section 2.7.2.
fn nav_dop(run_ms: u32, pdop: f32, hdop: f32, vdop: f32) -> Vec<u8> {
    let mut p = vec![0u8; 28];
    put(&mut p, 0, &run_ms.to_le_bytes());
    put(&mut p, 4, &pdop.to_le_bytes());
    put(&mut p, 8, &hdop.to_le_bytes());
    put(&mut p, 12, &vdop.to_le_bytes());
    spec_frame(0x01, 0x01, &p)
}

/// NAV-GPSINFO / BDSINFO / GLNINFO (0x01 0x20 + system) by section 2.7.7: (svid, used, cno, elev, azim).
fn nav_info(run_ms: u32, system: u8, sats: &[(u8, bool, u8, i8, i16)]) -> Vec<u8> {
    let mut p = vec![0u8; 8 + 12 * sats.len()];
    put(&mut p, 0, &run_ms.to_le_bytes());
    p[4] = sats.len() as u8;
    p[5] = sats.iter().filter(|s| s.1).count() as u8;
    p[6] = system;
    for (i, &(sv, used, cno, elev, azim)) in sats.iter().enumerate() {
        let b = 8 + 12 * i;
        p[b] = i as u8;
        p[b + 1] = sv;
        p[b + 2] = u8::from(used);
        p[b + 4] = cno;
        p[b + 5] = elev.to_le_bytes()[0];
        put(&mut p, b + 6, &azim.to_le_bytes());
    }
    spec_frame(0x01, 0x20 + system, &p)
}

fn pv(run_ms: u32) -> Pv {
    Pv {
        run_ms,
        pos_valid: 7,
        num_sv: 9,
        pdop: 1.6,
        lat: 30.274_812_345_678,
        lon: 120.155_123_456_789,
        height: 45.5,
        sep: 7.25,
        h_var: 6.25,
        v_var: 16.0,
        speed2d: 1.5,
        heading: 271.5,
    }
}

fn one_epoch(run_ms: u32, sec: u8) -> Vec<u8> {
    let mut data = nav_timeutc(run_ms, (2024, 6, 30), (23, 59, sec), 0x07, 3);
    data.extend(nav_dop(run_ms, 1.6, 0.9, 1.3));
    data.extend(nav_info(run_ms, 0, &[(5, true, 42, 61, 122), (12, false, 0, -3, 400)]));
    data.extend(nav_info(run_ms, 1, &[(7, true, 38, 45, 200)]));
    data.extend(nav_info(run_ms, 2, &[(3, true, 30, 20, 10)]));
    data.extend(nav_pv(&pv(run_ms)));
    data
}

#[test]
fn the_library_checksum_and_frame_are_the_specifications() {
    let payload: Vec<u8> = (0u8..80).map(|i| i.wrapping_mul(37).wrapping_add(200)).collect();
    assert_eq!(super::checksum(0x01, 0x03, &payload), spec_checksum(0x01, 0x03, &payload));
    assert_eq!(super::frame(0x01, 0x03, &payload), spec_frame(0x01, 0x03, &payload));
    // An empty poll: the checksum is the header word alone, (id << 24) + (class << 16) + 0.
    assert_eq!(super::frame(0x06, 0x01, &[]), [0xBA, 0xCE, 0, 0, 0x06, 0x01, 0x00, 0x00, 0x06, 0x01]);
}

#[test]
fn the_framer_hands_out_verified_frames_and_rejects_broken_ones() {
    let good = nav_pv(&pv(1000));
    let mut bad = good.clone();
    bad[40] ^= 0x01;
    let mut odd = spec_frame(0x01, 0x03, &[1, 2, 3, 4]);
    odd[2] = 3; // a length that is not whole words
    let gga = "$GPGGA,110518.000,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.2,M,,0000*77\r\n";
    let mut data = bad;
    data.extend(odd);
    data.extend(gga.as_bytes());
    data.extend(&good);
    let mut f = Framer::new();
    let mut seen = Vec::new();
    f.feed(&data, |fr, _| {
        seen.push(match fr {
            Frame::Casic { class, id, payload } => format!("CASIC {class} {id} {}", payload.len()),
            Frame::Nmea(_) => "NMEA".to_owned(),
            _ => "other".to_owned(),
        });
    });
    assert_eq!(seen, ["NMEA", "CASIC 1 3 80"]);
    assert_eq!(f.stats().casic_frames, 1);
    assert_eq!(f.stats().binary_bad_checksum, 2);
}

#[test]
fn an_epoch_decodes_field_by_field() {
    let mut data = one_epoch(5000, 58);
    data.extend(one_epoch(6000, 59));
    let (fixes, stats) = decode_reader(data.as_slice()).unwrap();
    assert_eq!(fixes.len(), 2, "{stats}");
    assert_eq!(stats.casic_frames, 12);
    assert_eq!(stats.rejected(), 0, "{stats}");
    let f: &Fix = &fixes[0];
    let v = pv(5000);
    assert_eq!(f.lat_deg, Some(v.lat));
    assert_eq!(f.lon_deg, Some(v.lon));
    assert_eq!(f.mode, Some(FixMode::Fix3D));
    assert_eq!(f.quality, Some(FixQuality::Gps));
    assert_eq!(f.time.unwrap().to_rfc3339(), "2024-06-30T23:59:58+00:00");
    assert_eq!(fixes[1].time.unwrap().to_rfc3339(), "2024-06-30T23:59:59+00:00");
    approx::assert_relative_eq!(f.alt_m.unwrap(), 45.5 - 7.25);
    approx::assert_relative_eq!(f.geoid_sep_m.unwrap(), 7.25);
    approx::assert_relative_eq!(f.speed_m_s.unwrap(), 1.5);
    approx::assert_relative_eq!(f.course_deg.unwrap(), 271.5);
    assert_eq!(f.sats_used, Some(9));
    approx::assert_relative_eq!(f.hdop.unwrap(), 0.9, max_relative = 1e-6);
    approx::assert_relative_eq!(f.vdop.unwrap(), 1.3, max_relative = 1e-6);
    approx::assert_relative_eq!(f.pdop.unwrap(), 1.6, max_relative = 1e-6);
    // Variances 6.25 m² and 16 m²: 1-sigma 2.5 m and 4 m.
    let e = f.error.unwrap();
    assert_eq!(e.source, ErrorSource::Casic);
    approx::assert_relative_eq!(e.horizontal_m, 2.5);
    approx::assert_relative_eq!(e.vertical_m.unwrap(), 4.0);
    assert_eq!(stats.accuracy_casic, 2);
    // Satellites: GPS 5 and 12, BeiDou 7 as 407, GLONASS 3 as 67; an azimuth of 400 is no azimuth.
    let ids: Vec<(u16, Constellation, bool)> =
        f.satellites.iter().map(|s| (s.prn, s.constellation, s.used)).collect();
    assert_eq!(
        ids,
        [
            (5, Constellation::Gps, true),
            (12, Constellation::Gps, false),
            (407, Constellation::Beidou, true),
            (67, Constellation::Glonass, true)
        ]
    );
    assert_eq!(f.satellites[0].elevation_deg, Some(61.0));
    assert_eq!(f.satellites[0].azimuth_deg, Some(122.0));
    assert_eq!(f.satellites[1].azimuth_deg, None);
    assert_eq!(f.satellites[1].snr_dbhz, None);
    assert_eq!(f.sats_visible, Some(4));
}

#[test]
fn position_flags_and_time_validity_follow_the_specification() {
    for (flag, mode, quality) in [
        (0, FixMode::NoFix, FixQuality::Invalid),
        (3, FixMode::NoFix, FixQuality::Invalid),
        (4, FixMode::Fix2D, FixQuality::Estimated),
        (5, FixMode::NoFix, FixQuality::Invalid),
        (6, FixMode::Fix2D, FixQuality::Gps),
        (7, FixMode::Fix3D, FixQuality::Gps),
        (8, FixMode::Fix3D, FixQuality::Gps),
    ] {
        let mut data = nav_timeutc(1, (2024, 1, 2), (3, 4, 5), 0x03, 3); // leap seconds not valid
        data.extend(nav_pv(&Pv { pos_valid: flag, ..pv(1) }));
        let (fixes, _) = decode_reader(data.as_slice()).unwrap();
        assert_eq!(fixes.len(), 1);
        assert_eq!((fixes[0].mode, fixes[0].quality), (Some(mode), Some(quality)), "posValid {flag}");
        assert_eq!(fixes[0].has_position(), mode != FixMode::NoFix);
        assert_eq!(fixes[0].time, None, "UTC without valid leap seconds is not UTC");
    }
}

#[test]
fn short_and_foreign_messages_are_counted_not_trusted() {
    let mut data = spec_frame(0x01, 0x03, &[0; 40]); // NAV-PV cut to 40 bytes
    data.extend(spec_frame(0x01, 0x20, &[0, 0, 0, 0, 3, 0, 0, 0])); // 3 satellites announced, none sent
    data.extend(spec_frame(0x0A, 0x04, &[0; 64])); // MON-VER: not decoded
    let (fixes, stats) = decode_reader(data.as_slice()).unwrap();
    assert!(fixes.is_empty());
    assert_eq!((stats.binary_malformed, stats.binary_frames, stats.casic_frames), (2, 1, 3));
}

#[test]
fn a_live_epoch_closes_after_the_quiet_gap() {
    let mut d = NmeaDecoder::new(crate::gps::DecoderConfig::live());
    let t0 = Instant::now();
    d.handle_bytes(&one_epoch(1000, 1), t0);
    assert!(std::iter::from_fn(|| d.poll_event()).all(|e| !matches!(e, GpsEvent::Fix(_))));
    let deadline = d.poll_timeout().expect("an open CASIC epoch wants a timeout");
    d.handle_timeout(deadline);
    assert!(std::iter::from_fn(|| d.poll_event()).any(|e| matches!(e, GpsEvent::Fix(_))));
}
