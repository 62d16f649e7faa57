//! `SkyTraq` tests: frames written field by field from the application notes' tables (AN0003, AN0028,
//! AN0037; an independent writer, not the decoder's readers), decoded through the whole NMEA decoder.

use proptest::prelude::*;

use crate::gps::fix::{Constellation, FixMode, FixQuality};
use crate::gps::framing::{Frame, Framer};
use crate::gps::{Fix, decode_reader};

/// A frame as the notes describe it: A0 A1, payload length big-endian, payload, XOR of the payload
/// computed byte by byte, 0D 0A.
fn spec_frame(payload: &[u8]) -> Vec<u8> {
    let mut out = vec![0xA0, 0xA1, (payload.len() >> 8) as u8, (payload.len() & 0xFF) as u8];
    out.extend_from_slice(payload);
    let mut cs = 0u8;
    for b in payload {
        cs ^= b;
    }
    out.push(cs);
    out.extend_from_slice(&[0x0D, 0x0A]);
    out
}

/// Writes `bytes` at `offset` of a payload.
fn put(p: &mut [u8], offset: usize, bytes: &[u8]) {
    p[offset..offset + bytes.len()].copy_from_slice(bytes);
}

/// WGS-84 semi-major axis [m]: a point on the equator at longitude 0 is (a + h, 0, 0).
const A_M: f64 = 6_378_137.0;

struct Nav {
    mode: u8,
    svs: u8,
    week: u16,
    tow_cs: u32,
    lat_e7: i32,
    lon_e7: i32,
    hae_cm: i32,
    msl_cm: i32,
    dops: [u16; 5],
    ecef_cm: [i32; 3],
    vel_cm_s: [i32; 3],
}

/// 0xA8 Navigation Data Message, 59 bytes, by the notes' table.
fn nav_data(v: &Nav) -> Vec<u8> {
    let mut p = vec![0u8; 59];
    p[0] = 0xA8;
    p[1] = v.mode;
    p[2] = v.svs;
    put(&mut p, 3, &v.week.to_be_bytes());
    put(&mut p, 5, &v.tow_cs.to_be_bytes());
    put(&mut p, 9, &v.lat_e7.to_be_bytes());
    put(&mut p, 13, &v.lon_e7.to_be_bytes());
    put(&mut p, 17, &v.hae_cm.to_be_bytes());
    put(&mut p, 21, &v.msl_cm.to_be_bytes());
    for (i, d) in v.dops.iter().enumerate() {
        put(&mut p, 25 + 2 * i, &d.to_be_bytes());
    }
    for i in 0..3 {
        put(&mut p, 35 + 4 * i, &v.ecef_cm[i].to_be_bytes());
        put(&mut p, 47 + 4 * i, &v.vel_cm_s[i].to_be_bytes());
    }
    spec_frame(&p)
}

/// A stationary-ish fix on the equator at longitude 0, moving 3 m/s east and 4 m/s north.
fn nav(mode: u8) -> Nav {
    Nav {
        mode,
        svs: 7,
        week: 2258,
        tow_cs: 24_444_749,
        lat_e7: 0,
        lon_e7: 0,
        hae_cm: 2757,
        msl_cm: 6247,
        dops: [242, 213, 105, 185, 113],
        ecef_cm: [(A_M * 100.0) as i32 + 2757, 0, 0],
        vel_cm_s: [0, 300, 400],
    }
}

/// 0xDF Navigation Data (raw-measurement output), 81 bytes, by the notes' table.
fn nav_raw(iod: u8, state: u8, week: u16, tow_s: f64, ecef_m: [f64; 3], vel_m_s: [f32; 3]) -> Vec<u8> {
    let mut p = vec![0u8; 81];
    p[0] = 0xDF;
    p[1] = iod;
    p[2] = state;
    put(&mut p, 3, &week.to_be_bytes());
    put(&mut p, 5, &tow_s.to_be_bytes());
    for i in 0..3 {
        put(&mut p, 13 + 8 * i, &ecef_m[i].to_be_bytes());
        put(&mut p, 37 + 4 * i, &vel_m_s[i].to_be_bytes());
    }
    put(&mut p, 49, &(-326_336.23_f64).to_be_bytes());
    put(&mut p, 57, &1.5_f32.to_be_bytes());
    for (i, d) in [2.2_f32, 1.98, 1.73, 0.97, 1.0].iter().enumerate() {
        put(&mut p, 61 + 4 * i, &d.to_be_bytes());
    }
    spec_frame(&p)
}

/// 0xDE SV and channel status by the notes' table: (PRN, C/N0, elevation, azimuth, channel status).
fn sv_status(iod: u8, sats: &[(u8, u8, i16, i16, u8)]) -> Vec<u8> {
    let mut p = vec![0u8; 3 + 10 * sats.len()];
    p[0] = 0xDE;
    p[1] = iod;
    p[2] = sats.len() as u8;
    for (i, &(prn, cno, elev, azim, chan)) in sats.iter().enumerate() {
        let b = 3 + 10 * i;
        p[b] = i as u8;
        p[b + 1] = prn;
        p[b + 4] = cno;
        put(&mut p, b + 5, &elev.to_be_bytes());
        put(&mut p, b + 7, &azim.to_be_bytes());
        p[b + 9] = chan;
    }
    spec_frame(&p)
}

fn decode(data: &[u8]) -> (Vec<Fix>, crate::gps::DecodeStats) {
    decode_reader(data).unwrap()
}

#[test]
fn the_library_checksum_and_frame_are_the_notes() {
    let payload: Vec<u8> = (0u8..59).map(|i| i.wrapping_mul(37).wrapping_add(200)).collect();
    assert_eq!(super::frame(&payload), spec_frame(&payload));
    // The notes' example, the software-version query (message 0x02, type 0x01): A0 A1 00 02 02 01 03 0D 0A.
    assert_eq!(super::frame(&[0x02, 0x01]), [0xA0, 0xA1, 0x00, 0x02, 0x02, 0x01, 0x03, 0x0D, 0x0A]);
}

#[test]
fn a_navigation_data_message_decodes_field_by_field() {
    let (fixes, stats) = decode(&nav_data(&nav(2)));
    assert_eq!((fixes.len(), stats.skytraq_frames, stats.rejected()), (1, 1, 0), "{stats}");
    let f = &fixes[0];
    // GPS week 2258, 244447.49 s, less the 18 s of GPS - UTC in force in 2023.
    assert_eq!(f.time.unwrap().to_rfc3339(), "2023-04-18T19:53:49.490+00:00");
    assert_eq!((f.mode, f.quality), (Some(FixMode::Fix3D), Some(FixQuality::Gps)));
    assert_eq!((f.lat_deg, f.lon_deg), (Some(0.0), Some(0.0)));
    approx::assert_relative_eq!(f.alt_m.unwrap(), 62.47);
    approx::assert_relative_eq!(f.geoid_sep_m.unwrap(), 27.57 - 62.47);
    assert_eq!(f.sats_used, Some(7));
    approx::assert_relative_eq!(f.pdop.unwrap(), 2.13);
    approx::assert_relative_eq!(f.hdop.unwrap(), 1.05);
    approx::assert_relative_eq!(f.vdop.unwrap(), 1.85);
    // At (0, 0) east is ECEF y and north ECEF z: 3 m/s east, 4 m/s north.
    approx::assert_relative_eq!(f.speed_m_s.unwrap(), 5.0, max_relative = 1e-12);
    approx::assert_relative_eq!(f.course_deg.unwrap(), 3f64.atan2(4.0).to_degrees(), max_relative = 1e-12);
    // A real latitude/longitude in 1e-7 deg is taken exactly (gpsd's skytraq-A8.log).
    let (fixes, _) = decode(&nav_data(&Nav { lat_e7: 389_073_528, lon_e7: -770_475_822, ..nav(2) }));
    assert_eq!((fixes[0].lat_deg, fixes[0].lon_deg), (Some(38.907_352_8), Some(-77.047_582_2)));
}

#[test]
fn fix_modes_follow_the_notes() {
    for (mode, want, quality, altitude) in [
        (0, FixMode::NoFix, FixQuality::Invalid, false),
        (1, FixMode::Fix2D, FixQuality::Gps, false),
        (2, FixMode::Fix3D, FixQuality::Gps, true),
        (3, FixMode::Fix3D, FixQuality::Dgps, true),
        (9, FixMode::NoFix, FixQuality::Invalid, false),
    ] {
        let (fixes, _) = decode(&nav_data(&Nav { lat_e7: 123_456_789, ..nav(mode) }));
        let f = &fixes[0];
        assert_eq!((f.mode, f.quality), (Some(want), Some(quality)), "mode {mode}");
        assert_eq!(f.has_position(), want != FixMode::NoFix, "mode {mode}");
        // A 2D fix's altitude is held, not measured: not reported.
        assert_eq!(f.alt_m.is_some(), altitude, "mode {mode}");
    }
}

#[test]
fn the_raw_navigation_data_gives_the_ecef_solution_and_its_satellites() {
    let mut data = sv_status(
        148,
        &[
            (2, 33, 45, 180, 0x1F),
            (12, 19, 48, 308, 0x0F),
            (211, 0, 77, 31, 0x01),
            (0, 0, 0, 0, 0),
            (72, 30, 20, 10, 0x2F),
        ],
    );
    let ecef = [A_M + 100.0, 0.0, 0.0];
    data.extend(nav_raw(148, 3, 1890, 444_957.999_088_545, ecef, [0.0, 3.0, 4.0]));
    // The next solution's satellites have not come: no satellites rather than the last solution's.
    data.extend(nav_raw(149, 2, 1890, 444_958.999, ecef, [0.0, 0.0, 0.0]));
    let (fixes, stats) = decode(&data);
    assert_eq!((fixes.len(), stats.skytraq_frames, stats.rejected()), (2, 3, 0), "{stats}");
    let f = &fixes[0];
    // 2016-04-01: GPS - UTC was 17 s (the leap second of 2016-12-31 was still to come).
    assert_eq!(f.time.unwrap().to_rfc3339(), "2016-04-01T03:35:40.999+00:00");
    assert_eq!((f.mode, f.quality), (Some(FixMode::Fix3D), Some(FixQuality::Gps)));
    assert!(f.lat_deg.unwrap().abs() < 1e-12 && f.lon_deg.unwrap().abs() < 1e-12);
    // The ECEF point has no mean-sea-level altitude.
    assert_eq!(f.alt_m, None);
    approx::assert_relative_eq!(f.speed_m_s.unwrap(), 5.0, max_relative = 1e-12);
    approx::assert_relative_eq!(f.hdop.unwrap(), 1.73, max_relative = 1e-6);
    // GPS 2 and 12, `BeiDou` 11 (the Venus 8's 211; gpsd's SKY: gnssid 3, svid 11) as 411, PRN 0 an idle
    // channel (left out), GLONASS 72; used = channel status 0x10 or 0x20.
    let ids: Vec<(u16, Constellation, bool)> =
        f.satellites.iter().map(|s| (s.prn, s.constellation, s.used)).collect();
    assert_eq!(
        ids,
        [
            (2, Constellation::Gps, true),
            (12, Constellation::Gps, false),
            (411, Constellation::Beidou, false),
            (72, Constellation::Glonass, true)
        ]
    );
    assert_eq!((f.sats_used, f.sats_visible), (Some(2), Some(4)));
    assert_eq!(f.satellites[0].elevation_deg, Some(45.0));
    assert_eq!(f.satellites[0].azimuth_deg, Some(180.0));
    assert_eq!(f.satellites[1].snr_dbhz, Some(19.0));
    let g = &fixes[1];
    assert_eq!(g.mode, Some(FixMode::Fix2D));
    assert!(g.satellites.is_empty() && g.sats_used.is_none());
    // A fix prediction and no fix carry no position.
    for state in [0, 1, 7] {
        let (fixes, _) = decode(&nav_raw(1, state, 1890, 1.0, ecef, [0.0; 3]));
        assert_eq!(fixes[0].mode, Some(FixMode::NoFix), "state {state}");
        assert!(!fixes[0].has_position());
    }
    // An ECEF point at the earth's centre is no place: no fix.
    let (fixes, _) = decode(&nav_raw(1, 3, 1890, 1.0, [0.0; 3], [0.0; 3]));
    assert_eq!(fixes[0].mode, Some(FixMode::NoFix));
}

#[test]
fn utc_follows_the_leap_seconds_in_force() {
    use crate::gps::gps_time::utc_from_gps_by_history;
    let utc =
        |week, ms| utc_from_gps_by_history(week, ms).unwrap().format("%Y-%m-%dT%H:%M:%S%.3f").to_string();
    // 2017-01-01 00:00:00 UTC is GPS week 1930, 18 s (GPS - UTC 18 from then on).
    assert_eq!(utc(1930, 18_000), "2017-01-01T00:00:00.000");
    // The last millisecond before the leap second, at 17 s.
    assert_eq!(utc(1930, 16_999), "2016-12-31T23:59:59.999");
    // The GPS epoch itself: no leap second yet.
    assert_eq!(utc(0, 0), "1980-01-06T00:00:00.000");
    // 2009-01-01 .. 2012-06-30: 15 s. 2010-01-01 00:00:00 UTC = GPS week 1564, 5 days + 15 s.
    assert_eq!(utc(1564, 5 * 86_400_000 + 15_000), "2010-01-01T00:00:00.000");
}

#[test]
fn the_framer_tells_skytraq_from_sirf_and_rejects_broken_frames() {
    let good = nav_data(&nav(2));
    let mut bad = good.clone();
    bad[20] ^= 0x01; // payload byte: the XOR no longer agrees
    let mut bad_end = good.clone();
    let n = bad_end.len();
    bad_end[n - 1] = 0x0B; // end 0D 0B
    let empty = [0xA0, 0xA1, 0x00, 0x00, 0x00, 0x0D, 0x0A]; // no message id
    let sirf = crate::gps::sirf::frame(&[0x29, 0x00]);
    let gga = "$GPGGA,110518.000,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.2,M,,0000*77\r\n";
    let mut data = bad;
    data.extend(bad_end);
    data.extend(empty);
    data.extend(gga.as_bytes());
    data.extend(&sirf);
    data.extend(&good);
    let mut f = Framer::new();
    let mut seen = Vec::new();
    let mut push = |fr: Frame<'_>, _: &mut crate::gps::DecodeStats| {
        seen.push(match fr {
            Frame::SkyTraq { payload } => format!("SkyTraq {:02X} {}", payload[0], payload.len()),
            Frame::Sirf { payload } => format!("SiRF {:02X}", payload[0]),
            Frame::Nmea(_) => "NMEA".to_owned(),
            _ => "other".to_owned(),
        });
    };
    f.feed(&data, &mut push);
    f.finish(&mut push);
    assert_eq!(seen, ["NMEA", "SiRF 29", "SkyTraq A8 59"]);
    assert_eq!((f.stats().skytraq_frames, f.stats().binary_bad_checksum), (1, 3));
    // A frame whose length runs past the end of the stream: rejected, the sentence inside still comes out.
    let mut cut = vec![0xA0, 0xA1, 0x01, 0x00];
    cut.extend(gga.as_bytes());
    let (fixes, stats) = decode(&cut);
    assert_eq!((fixes.len(), stats.sentences, stats.binary_bad_checksum), (1, 1, 1));
}

#[test]
fn short_and_foreign_messages_are_counted_not_trusted() {
    let mut data = spec_frame(&[0xA8; 40]); // 0xA8 cut to 40 bytes
    data.extend(spec_frame(&[0xDF, 1, 3])); // 0xDF cut to 3 bytes
    data.extend(spec_frame(&[0xDE, 1, 5, 0, 2])); // 5 satellites announced, none sent
    data.extend(spec_frame(&[0x80, 0x01, 0x00, 0x01])); // software version: not decoded
    data.extend(spec_frame(&[0xDC, 149, 0x07, 0x62, 0, 0, 0, 0, 0x03, 0xE8])); // measurement time: no position
    let (fixes, stats) = decode(&data);
    assert!(fixes.is_empty());
    assert_eq!((stats.binary_malformed, stats.binary_frames, stats.skytraq_frames), (3, 2, 5), "{stats}");
    assert_eq!(stats.undecoded_protocol, None);
}

/// A stream of `SkyTraq` frames is decoded, not reported as an undecoded binary protocol.
#[test]
fn a_skytraq_stream_is_not_called_undecoded() {
    let data: Vec<u8> =
        (0..10).flat_map(|i| nav_data(&Nav { tow_cs: 24_444_749 + 50 * i, ..nav(2) })).collect();
    let (fixes, stats) = decode(&data);
    assert_eq!(fixes.len(), 10);
    assert_eq!(stats.undecoded_protocol, None);
    assert!(stats.to_string().contains("10 SkyTraq frames"), "{stats}");
}

proptest! {
    #[test]
    fn a_frame_round_trips(payload in proptest::collection::vec(any::<u8>(), 1..2000)) {
        let mut f = Framer::new();
        let mut out = Vec::new();
        f.feed(&spec_frame(&payload), |fr, _| {
            if let Frame::SkyTraq { payload } = fr {
                out.push(payload.to_vec());
            }
        });
        prop_assert_eq!(out, vec![payload]);
        prop_assert_eq!((f.stats().skytraq_frames, f.stats().rejected()), (1, 0));
    }

    #[test]
    fn a_flipped_byte_is_rejected(payload in proptest::collection::vec(any::<u8>(), 1..300), at: usize, flip in 1u8..) {
        let mut f = spec_frame(&payload);
        // Payload, checksum or end (a flipped length byte moves the frame's end instead).
        let i = 4 + at % (f.len() - 4);
        f[i] ^= flip;
        let mut framer = Framer::new();
        let mut got = false;
        framer.feed(&f, |fr, _| got |= matches!(fr, Frame::SkyTraq { payload: p } if p == payload.as_slice()));
        framer.finish(|_, _| {});
        prop_assert!(!got);
        prop_assert!(framer.stats().binary_bad_checksum >= 1);
    }

    #[test]
    fn any_payload_never_panics_the_decoder(
        msgs in proptest::collection::vec(
            (prop_oneof![Just(0xA8u8), Just(0xDE), Just(0xDF), any::<u8>()], proptest::collection::vec(any::<u8>(), 0..120)),
            1..20,
        ),
    ) {
        let mut bytes = Vec::new();
        for (id, rest) in &msgs {
            let mut p = vec![*id];
            p.extend_from_slice(rest);
            bytes.extend(spec_frame(&p));
        }
        let (fixes, stats) = decode(&bytes);
        prop_assert_eq!(stats.skytraq_frames, msgs.len() as u64);
        for f in &fixes {
            prop_assert!(f.lat_deg.is_none_or(|l| l.abs() <= 90.0));
            prop_assert!(f.lon_deg.is_none_or(|l| l.abs() <= 180.0));
        }
    }
}
