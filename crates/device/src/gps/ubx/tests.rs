//! UBX tests: the published frames, the decoder against independent truth, the framer's resync
//! properties.

use super::*;

#[test]
fn poll_of_mon_ver_matches_the_published_frame() {
    // The MON-VER poll, an empty payload: B5 62 0A 04 00 00 0E 34 as printed in u-blox's documents
    // and in every u-center log.
    assert_eq!(frame(0x0A, 0x04, &[]), [0xB5, 0x62, 0x0A, 0x04, 0x00, 0x00, 0x0E, 0x34]);
}

#[test]
fn cfg_rate_frame_matches_the_published_frame() {
    // CFG-RATE 1 Hz (measRate 1000 ms, navRate 1, timeRef GPS), the frame u-center sends:
    // B5 62 06 08 06 00 E8 03 01 00 01 00 01 39.
    assert_eq!(
        frame(0x06, 0x08, &[0xE8, 0x03, 0x01, 0x00, 0x01, 0x00]),
        [0xB5, 0x62, 0x06, 0x08, 0x06, 0x00, 0xE8, 0x03, 0x01, 0x00, 0x01, 0x00, 0x01, 0x39]
    );
}

mod decoding {
    use std::path::PathBuf;
    use std::time::Instant;

    use crate::gps::fix::{Constellation, ErrorSource, FixMode};
    use crate::gps::framing::{Frame, Framer};
    use crate::gps::ubx::decoder::nmea_id;
    use crate::gps::{Fix, decode_file};

    /// Our fix carries the crate's position, MSL height, ground speed and hAcc/vAcc (source UBX), as
    /// `(lat, lon, hmsl, hacc, vacc, gspeed)`.
    fn assert_same_pvt(f: &Fix, (lat, lon, hmsl, hacc, vacc, gspeed): (f64, f64, f64, f64, f64, f64)) {
        approx::assert_relative_eq!(f.lat_deg.unwrap(), lat, max_relative = 1e-12);
        approx::assert_relative_eq!(f.lon_deg.unwrap(), lon, max_relative = 1e-12);
        approx::assert_relative_eq!(f.alt_m.unwrap(), hmsl, max_relative = 1e-12);
        approx::assert_relative_eq!(f.speed_m_s.unwrap(), gspeed, max_relative = 1e-12, epsilon = 1e-12);
        let e = f.error.unwrap();
        assert_eq!(e.source, ErrorSource::Ubx);
        approx::assert_relative_eq!(e.horizontal_m, hacc, max_relative = 1e-12);
        approx::assert_relative_eq!(e.vertical_m.unwrap(), vacc, max_relative = 1e-12);
    }

    fn log(name: &str) -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/gpsd-logs-more").join(name)
    }

    /// Every verified UBX frame of a log, through our framer.
    fn our_frames(bytes: &[u8]) -> Vec<(u8, u8, Vec<u8>)> {
        let mut f = Framer::new();
        let mut out = Vec::new();
        let mut push = |fr: Frame<'_>, _: &mut _| {
            if let Frame::Ubx { class, id, payload } = fr {
                out.push((class, id, payload.to_vec()));
            }
        };
        f.feed(bytes, &mut push);
        f.finish(&mut push);
        out
    }

    #[test]
    fn satellite_numbering_is_gpsds() {
        // gpsd's `ubx2_to_prn` (NMEA 4.0 extended ids), as its .chk SKY reports show them: GLONASS svId 1
        // is PRN 65, SBAS 120 is 33, Galileo 1 is 301, BeiDou 1 is 401, QZSS 1 is 193.
        assert_eq!(nmea_id(0, 5), Some((Constellation::Gps, 5)));
        assert_eq!(nmea_id(6, 1), Some((Constellation::Glonass, 65)));
        assert_eq!(nmea_id(1, 120), Some((Constellation::Sbas, 33)));
        assert_eq!(nmea_id(2, 1), Some((Constellation::Galileo, 301)));
        assert_eq!(nmea_id(3, 1), Some((Constellation::Beidou, 401)));
        assert_eq!(nmea_id(5, 1), Some((Constellation::Qzss, 193)));
        assert_eq!(nmea_id(6, 255), None);
        assert_eq!(nmea_id(9, 1), None);
    }

    /// The SKY report of gpsd's `.chk` for the first NAV-SAT of the NEO-M8N log lists PRN 5 at el 19,
    /// az 284, ss 38, used; PRN 1 at el 2, az 83, not used; 28 satellites, 14 used; hdop 0.71, pdop 1.46,
    /// vdop 1.28.
    #[test]
    fn neo_m8n_sky_matches_gpsds_report() {
        let (fixes, stats) = decode_file(&log("ublox-neo-m8n.log")).unwrap();
        assert!(stats.ubx_frames > 0, "{stats}");
        let f = fixes.iter().find(|f| !f.satellites.is_empty()).expect("a fix with satellites");
        let sat = |prn| f.satellites.iter().find(|s| s.prn == prn && s.constellation == Constellation::Gps);
        let s5 = sat(5).unwrap();
        assert_eq!(
            (s5.elevation_deg, s5.azimuth_deg, s5.snr_dbhz, s5.used),
            (Some(19.0), Some(284.0), Some(38.0), true)
        );
        let s1 = sat(1).unwrap();
        assert_eq!((s1.elevation_deg, s1.azimuth_deg, s1.used), (Some(2.0), Some(83.0), false));
    }

    /// Field by field against the `ublox` crate (MIT, an independent implementation of the same
    /// documents) on every NAV-PVT, NAV-DOP and HNR-PVT of the four UBX logs.
    #[test]
    fn nav_pvt_and_dop_agree_with_the_ublox_crate() {
        use ublox::{ParserBuilder, UbxPacket, proto23::PacketRef};
        let mut total = 0;
        for name in ["ublox-glo.log", "ublox-neo-m8l.log", "ublox-neo-m8n.log", "ublox-zed-f9p-rtk.log"] {
            let bytes = std::fs::read(log(name)).unwrap();
            // Theirs: every NAV-PVT and NAV-DOP the crate's parser finds.
            let mut parser = ParserBuilder::new().with_vec_buffer();
            let mut it = parser.consume_ubx(&bytes);
            let mut pvts = Vec::new();
            let mut dops = std::collections::BTreeMap::new();
            let mut hnrs = Vec::new();
            while let Some(p) = it.next() {
                let Ok(UbxPacket::Proto23(p)) = p else { continue };
                match p {
                    PacketRef::NavPvt(p) => pvts.push((
                        p.itow(),
                        p.latitude(),
                        p.longitude(),
                        p.height_msl(),
                        p.horizontal_accuracy(),
                        p.vertical_accuracy(),
                        p.num_satellites(),
                        p.ground_speed_2d(),
                        p.fix_type() as u8,
                        p.pdop(),
                    )),
                    PacketRef::HnrPvt(h) => hnrs.push((
                        h.latitude(),
                        h.longitude(),
                        h.height_msl(),
                        h.horizontal_accuracy(),
                        h.vertical_accuracy(),
                        h.ground_speed_2d(),
                    )),
                    PacketRef::NavDop(d) => {
                        dops.insert(d.itow(), (d.position_dop(), d.horizontal_dop(), d.vertical_dop()));
                    }
                    _ => {}
                }
            }
            // Ours: the NAV epochs' fixes (HNR-PVT fixes carry no satellite count).
            let (fixes, _) = decode_file(&log(name)).unwrap();
            let ours: Vec<&Fix> = fixes.iter().filter(|f| f.sats_used.is_some()).collect();
            assert_eq!(ours.len(), pvts.len(), "{name}: one fix per NAV-PVT");
            // Our frames too: the same NAV-PVT payloads reach the decoder.
            let n_pvt = our_frames(&bytes).iter().filter(|(c, i, _)| (*c, *i) == (1, 7)).count();
            assert_eq!(n_pvt, pvts.len(), "{name}");
            for (f, &(itow, lat, lon, hmsl, hacc, vacc, nsv, gspeed, fix_type, pdop)) in
                ours.iter().zip(&pvts)
            {
                let ctx = format!("{name} iTOW {itow}");
                let mode = match fix_type {
                    0 => FixMode::NoFix,
                    1 | 2 => FixMode::Fix2D,
                    _ => FixMode::Fix3D,
                };
                assert_eq!(f.mode, Some(mode), "{ctx}");
                assert_eq!(f.sats_used, Some(u32::from(nsv)), "{ctx}");
                if mode == FixMode::NoFix {
                    continue;
                }
                assert_same_pvt(f, (lat, lon, hmsl, hacc, vacc, gspeed));
                match dops.get(&itow) {
                    // NAV-DOP is f32 in the crate: 1e-4 covers its rounding of a 0.01 step.
                    Some(&(p, h, v)) => {
                        approx::assert_relative_eq!(f.pdop.unwrap(), f64::from(p), epsilon = 1e-4);
                        approx::assert_relative_eq!(f.hdop.unwrap(), f64::from(h), epsilon = 1e-4);
                        approx::assert_relative_eq!(f.vdop.unwrap(), f64::from(v), epsilon = 1e-4);
                    }
                    None => approx::assert_relative_eq!(f.pdop.unwrap(), pdop, epsilon = 1e-9),
                }
                total += 1;
            }
            // HNR-PVT fixes: ours without a satellite count, in order.
            let ours_hnr: Vec<&Fix> = fixes.iter().filter(|f| f.sats_used.is_none()).collect();
            assert_eq!(ours_hnr.len(), hnrs.len(), "{name}: one fix per HNR-PVT");
            for (f, &pvt) in ours_hnr.iter().zip(&hnrs) {
                assert_same_pvt(f, pvt);
                total += 1;
            }
        }
        eprintln!("{total} fixes compared with the ublox crate");
        assert!(total > 300, "{total} fixes compared");
    }

    #[test]
    fn malformed_and_unknown_frames_are_counted_not_trusted() {
        let mut d = super::super::UbxDecoder::new();
        let now = Instant::now();
        assert_eq!(d.handle(0x01, 0x07, &[0; 20], now), Err(super::super::UbxUnused::Malformed));
        // NAV-SAT claiming 10 satellites with room for one.
        let mut sat = vec![0u8; 20];
        sat[5] = 10;
        assert_eq!(d.handle(0x01, 0x35, &sat, now), Err(super::super::UbxUnused::Malformed));
        assert_eq!(d.handle(0x0A, 0x04, &[], now), Err(super::super::UbxUnused::Unsupported));
        assert_eq!(d.finish(now), None);
    }
}

mod properties {
    use proptest::prelude::*;
    use proptest::test_runner::{Config, RngSeed};

    use super::frame;
    use crate::gps::framing::{DecodeStats, Frame, Framer, with_checksum};
    use crate::gps::{DecoderConfig, NmeaDecoder};

    /// Everything the framer hands out, as comparable values.
    #[derive(Debug, Clone, PartialEq, Eq)]
    enum Item {
        Nmea(String),
        Ubx(u8, u8, Vec<u8>),
        Sirf(Vec<u8>),
        SkyTraq(Vec<u8>),
        Other,
    }

    fn run(chunks: &[&[u8]]) -> (Vec<Item>, DecodeStats) {
        let mut f = Framer::new();
        let mut out = Vec::new();
        let mut push = |fr: Frame<'_>, _: &mut DecodeStats| {
            out.push(match fr {
                Frame::Nmea(s) => Item::Nmea(s.to_owned()),
                Frame::Ubx { class, id, payload } => Item::Ubx(class, id, payload.to_vec()),
                Frame::Sirf { payload } => Item::Sirf(payload.to_vec()),
                Frame::SkyTraq { payload } => Item::SkyTraq(payload.to_vec()),
                Frame::Casic { .. } | Frame::Rtcm3 { .. } => Item::Other,
            });
        };
        for c in chunks {
            f.feed(c, &mut push);
        }
        f.finish(&mut push);
        (out, *f.stats())
    }

    /// A piece of a generated stream.
    #[derive(Debug, Clone)]
    enum Piece {
        /// A real UBX frame.
        Ubx(u8, u8, Vec<u8>),
        /// A real `SkyTraq` frame (its `A0` is `SiRF`'s first sync byte too).
        SkyTraq(Vec<u8>),
        /// A real NMEA sentence (body between `$` and `*`).
        Nmea(String),
        /// Line noise: any bytes but `#` (a comment at a line start is skipped to its end by design).
        Junk(Vec<u8>),
        /// A false sync word with a header: `B5 62 class id len`, no frame behind it.
        FalseSync(u8, u8, u16),
        /// A real UBX frame cut short after this many bytes.
        Truncated(u8, u8, Vec<u8>, usize),
    }

    fn piece() -> impl Strategy<Value = Piece> {
        prop_oneof![
            (any::<u8>(), any::<u8>(), proptest::collection::vec(any::<u8>(), 0..300))
                .prop_map(|(c, i, p)| Piece::Ubx(c, i, p)),
            proptest::collection::vec(any::<u8>(), 1..300).prop_map(Piece::SkyTraq),
            "[A-Z]{5}(,[0-9A-Za-z.]{0,8}){0,12}".prop_map(Piece::Nmea),
            proptest::collection::vec(any::<u8>().prop_filter("no comment", |b| *b != b'#'), 0..40)
                .prop_map(Piece::Junk),
            (any::<u8>(), any::<u8>(), any::<u16>()).prop_map(|(c, i, l)| Piece::FalseSync(c, i, l)),
            (any::<u8>(), any::<u8>(), proptest::collection::vec(any::<u8>(), 1..100), any::<usize>())
                .prop_map(|(c, i, p, k)| Piece::Truncated(c, i, p, k)),
        ]
    }

    /// The stream's bytes and the real items in it.
    fn render(pieces: &[Piece]) -> (Vec<u8>, Vec<Item>) {
        let mut bytes = Vec::new();
        let mut real = Vec::new();
        for p in pieces {
            match p {
                Piece::Ubx(c, i, payload) => {
                    bytes.extend_from_slice(&frame(*c, *i, payload));
                    real.push(Item::Ubx(*c, *i, payload.clone()));
                }
                Piece::SkyTraq(payload) => {
                    bytes.extend_from_slice(&crate::gps::skytraq::frame(payload));
                    real.push(Item::SkyTraq(payload.clone()));
                }
                Piece::Nmea(body) => {
                    let s = with_checksum(body);
                    real.push(Item::Nmea(s.trim_end().to_owned()));
                    bytes.extend_from_slice(s.as_bytes());
                }
                Piece::Junk(j) => bytes.extend_from_slice(j),
                Piece::FalseSync(c, i, len) => {
                    bytes.extend_from_slice(&[0xB5, 0x62, *c, *i]);
                    bytes.extend_from_slice(&len.to_le_bytes());
                }
                Piece::Truncated(c, i, payload, k) => {
                    let f = frame(*c, *i, payload);
                    // Cut somewhere after the sync word and before the last byte.
                    let cut = 2 + k % (f.len() - 2);
                    bytes.extend_from_slice(&f[..cut]);
                }
            }
        }
        (bytes, real)
    }

    fn split<'a>(data: &'a [u8], cuts: &[usize]) -> Vec<&'a [u8]> {
        let mut at: Vec<usize> = cuts.iter().map(|c| c % (data.len() + 1)).collect();
        at.sort_unstable();
        let mut out = Vec::new();
        let mut prev = 0;
        for c in at.into_iter().chain([data.len()]) {
            out.push(&data[prev..c]);
            prev = c;
        }
        out
    }

    /// A fixed seed: a false frame whose 16-bit checksum happens to be right is a real frame (1 in
    /// 65,536), so a random seed would make these properties fail once in a few hundred runs.
    fn config() -> Config {
        Config { cases: 256, rng_seed: RngSeed::Fixed(0x7562_7862), ..Config::default() }
    }

    proptest! {
        #![proptest_config(config())]

        #[test]
        fn a_frame_round_trips(class: u8, id: u8, payload in proptest::collection::vec(any::<u8>(), 0..2000)) {
            let (items, stats) = run(&[&frame(class, id, &payload)]);
            prop_assert_eq!(items, vec![Item::Ubx(class, id, payload)]);
            prop_assert_eq!((stats.ubx_frames, stats.rejected(), stats.junk_bytes), (1, 0, 0));
        }

        #[test]
        fn a_flipped_byte_is_rejected_and_counted(
            class: u8,
            id: u8,
            payload in proptest::collection::vec(any::<u8>(), 0..300),
            at: usize,
            flip in 1u8..,
        ) {
            let mut f = frame(class, id, &payload);
            // Class, id, payload or checksum (a flipped length byte moves the frame's end instead).
            let positions: Vec<usize> = [2, 3].into_iter().chain(6..f.len()).collect();
            let i = positions[at % positions.len()];
            f[i] ^= flip;
            let (items, stats) = run(&[&f]);
            prop_assert!(!items.contains(&Item::Ubx(class, id, payload)));
            prop_assert!(stats.binary_bad_checksum >= 1, "{}", stats);
        }

        #[test]
        fn every_real_item_survives_junk_false_syncs_and_truncation(
            pieces in proptest::collection::vec(piece(), 1..30),
            cuts in proptest::collection::vec(any::<usize>(), 0..8),
        ) {
            let (bytes, real) = render(&pieces);
            let (whole, _) = run(&[&bytes]);
            prop_assert_eq!(&whole, &real);
            // Any chunking gives the same items.
            let (chunked, _) = run(&split(&bytes, &cuts));
            prop_assert_eq!(&chunked, &real);
        }

        #[test]
        fn arbitrary_bytes_never_panic_the_decoder(
            data in proptest::collection::vec(
                prop_oneof![any::<u8>(), Just(0xB5), Just(0x62), Just(0x01), Just(0xA0), Just(0xA1), Just(0xA2)],
                0..3000,
            ),
            cuts in proptest::collection::vec(any::<usize>(), 0..8),
        ) {
            let now = std::time::Instant::now();
            let mut d = NmeaDecoder::new(DecoderConfig::live());
            for c in split(&data, &cuts) {
                d.handle_bytes(c, now);
                while d.poll_event().is_some() {}
            }
            d.finish(now);
            while d.poll_event().is_some() {}
            prop_assert_eq!(d.stats().bytes, data.len() as u64);
        }

        #[test]
        fn any_nav_payload_never_panics_the_ubx_decoder(
            msgs in proptest::collection::vec(
                (
                    prop_oneof![Just(0x02u8), Just(0x03), Just(0x04), Just(0x06), Just(0x07), Just(0x12),
                                Just(0x20), Just(0x21), Just(0x30), Just(0x35), Just(0x61)],
                    proptest::collection::vec(any::<u8>(), 0..120),
                ),
                1..20,
            ),
        ) {
            let now = std::time::Instant::now();
            let mut bytes = Vec::new();
            for (id, p) in &msgs {
                bytes.extend_from_slice(&frame(0x01, *id, p));
            }
            bytes.extend_from_slice(&frame(0x28, 0x00, &[0x55; 72]));
            let mut d = NmeaDecoder::new(DecoderConfig::file());
            d.handle_bytes(&bytes, now);
            d.finish(now);
            let stats = d.stats();
            prop_assert_eq!(stats.ubx_frames, msgs.len() as u64 + 1);
        }
    }
}

/// The assembler's rules for UBX frames among NMEA (docs/gps.md, "Mixed streams").
mod mixed {
    use std::time::{Duration, Instant};

    use crate::gps::framing::with_checksum;
    use crate::gps::{DecoderConfig, ErrorSource, Fix, GpsEvent, NmeaDecoder};

    /// The first three NAV-PVT frames of the NEO-M8N log (5 Hz, no NAV-EOE), of 08:50:00.800, 01.000 and
    /// 01.200 UTC (gpsd's `.chk` reports TPVs of 2017-07-19T08:50:01.000Z and .200Z).
    fn pvt_frames() -> Vec<Vec<u8>> {
        let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../tests/data/gpsd-logs-more/ublox-neo-m8n.log");
        let bytes = std::fs::read(path).unwrap();
        let mut out = Vec::new();
        let mut f = crate::gps::framing::Framer::new();
        f.feed(&bytes, |fr, _| {
            if let crate::gps::framing::Frame::Ubx { class: 1, id: 7, payload } = fr {
                out.push(super::frame(1, 7, payload));
            }
        });
        out.truncate(3);
        out
    }

    fn gga(time: &str) -> String {
        with_checksum(&format!("GPGGA,{time},3454.3736,S,13836.4872,E,1,08,1.0,28.8,M,-1.7,M,,"))
    }

    fn fixes(d: &mut NmeaDecoder) -> Vec<Fix> {
        std::iter::from_fn(|| d.poll_event())
            .filter_map(|e| if let GpsEvent::Fix(f) = e { Some(*f) } else { None })
            .collect()
    }

    #[test]
    fn one_source_of_epochs_and_nmea_takes_over_when_ubx_stops() {
        let now = Instant::now();
        let mut d = NmeaDecoder::new(DecoderConfig::file());
        let mut bytes = Vec::new();
        for (frame, t) in pvt_frames().iter().zip(["085000.80", "085001.00", "085001.20"]) {
            bytes.extend_from_slice(frame);
            bytes.extend_from_slice(gga(t).as_bytes());
        }
        for t in ["085001.40", "085001.60", "085001.80", "085002.00"] {
            bytes.extend_from_slice(gga(t).as_bytes());
        }
        d.handle_bytes(&bytes, now);
        d.finish(now);
        let fixes = fixes(&mut d);
        let ms: Vec<u32> =
            fixes.iter().map(|f| crate::gps::sentence::tod_ms(f.time_of_day.unwrap())).collect();
        // One fix per time, in order: the three UBX epochs, then NMEA after three NMEA-only epochs.
        assert_eq!(ms, [31_800_800, 31_801_000, 31_801_200, 31_801_600, 31_801_800, 31_802_000]);
        assert!(fixes[..3].iter().all(|f| f.error.is_some_and(|e| e.source == ErrorSource::Ubx)));
        assert!(
            fixes[3..]
                .iter()
                .all(|f| matches!(f.error.map(|e| e.source), Some(ErrorSource::DopModel { .. })))
        );
        let st = d.stats();
        assert_eq!((st.nmea_epochs_superseded, st.accuracy_ubx, st.accuracy_dop_model), (4, 3, 3), "{st}");
    }

    #[test]
    fn a_live_ubx_epoch_without_eoe_closes_after_the_quiet_gap() {
        let t0 = Instant::now();
        let mut d = NmeaDecoder::new(DecoderConfig::live());
        d.handle_bytes(&pvt_frames()[0], t0);
        assert!(fixes(&mut d).is_empty());
        let deadline = d.poll_timeout().expect("an open UBX epoch asks for a timeout");
        assert_eq!(deadline, t0 + Duration::from_millis(400));
        d.handle_timeout(deadline);
        let f = fixes(&mut d);
        assert_eq!(f.len(), 1);
        assert_eq!(f[0].received_at, Some(deadline));
        assert_eq!(d.poll_timeout(), None);
    }
}

/// An ANTARIS / LEA-4T / timing receiver's epoch: NAV-SOL + NAV-POSLLH + NAV-TIMEUTC + NAV-DOP, no NAV-PVT,
/// with RXM-RAWX and TIM-TP frames among them. Payloads written field by field from the u-blox 6 Receiver
/// Description's tables; the epoch closes at the next iTOW, the other classes leave it intact.
mod without_nav_pvt {
    use crate::gps::fix::FixMode;
    use crate::gps::ubx::frame;

    fn put(p: &mut [u8], o: usize, b: &[u8]) {
        p[o..o + b.len()].copy_from_slice(b);
    }

    fn epoch(itow: u32, sec: u8, lat_e7: i32, lon_e7: i32) -> Vec<u8> {
        let mut sol = vec![0u8; 52];
        put(&mut sol, 0, &itow.to_le_bytes());
        put(&mut sol, 8, &1800i16.to_le_bytes()); // week
        sol[10] = 3; // gpsFix 3D
        sol[11] = 0x0D; // gpsFixOK, WKNSET, TOWSET
        put(&mut sol, 44, &156u16.to_le_bytes()); // pDOP 1.56
        sol[47] = 7; // numSV
        let mut llh = vec![0u8; 28];
        put(&mut llh, 0, &itow.to_le_bytes());
        put(&mut llh, 4, &lon_e7.to_le_bytes());
        put(&mut llh, 8, &lat_e7.to_le_bytes());
        put(&mut llh, 12, &352_000i32.to_le_bytes()); // height 352 m
        put(&mut llh, 16, &304_500i32.to_le_bytes()); // hMSL 304.5 m
        put(&mut llh, 20, &2500u32.to_le_bytes()); // hAcc 2.5 m
        put(&mut llh, 24, &4000u32.to_le_bytes()); // vAcc 4 m
        let mut utc = vec![0u8; 20];
        put(&mut utc, 0, &itow.to_le_bytes());
        put(&mut utc, 12, &2014u16.to_le_bytes());
        utc[14] = 7;
        utc[15] = 9;
        utc[16] = 10;
        utc[17] = 11;
        utc[18] = sec;
        utc[19] = 0x07; // validTOW, validWKN, validUTC
        let mut dop = vec![0u8; 18];
        put(&mut dop, 0, &itow.to_le_bytes());
        put(&mut dop, 6, &156u16.to_le_bytes());
        put(&mut dop, 10, &121u16.to_le_bytes());
        put(&mut dop, 12, &98u16.to_le_bytes());
        let rawx = vec![0x5Au8; 16 + 32 * 3]; // RXM-RAWX, 3 measurements of filler
        let tim_tp = vec![0u8; 16];
        [
            frame(0x02, 0x15, &rawx),
            frame(0x01, 0x06, &sol),
            frame(0x0D, 0x01, &tim_tp),
            frame(0x01, 0x02, &llh),
            frame(0x01, 0x21, &utc),
            frame(0x01, 0x04, &dop),
        ]
        .concat()
    }

    #[test]
    fn epochs_come_from_sol_posllh_timeutc_and_dop() {
        let data = [epoch(200_000, 58, 485_123_456, 93_456_789), epoch(201_000, 59, 485_123_457, 93_456_790)]
            .concat();
        let (fixes, stats) = crate::gps::decode_reader(data.as_slice()).unwrap();
        assert_eq!(fixes.len(), 2, "{stats}");
        assert_eq!(stats.binary_frames, 4, "RXM-RAWX and TIM-TP are counted as not decoded");
        assert_eq!(stats.rejected(), 0);
        let f = &fixes[0];
        assert_eq!(f.time.unwrap().to_rfc3339(), "2014-07-09T10:11:58+00:00");
        assert_eq!(fixes[1].time.unwrap().to_rfc3339(), "2014-07-09T10:11:59+00:00");
        assert_eq!(f.mode, Some(FixMode::Fix3D));
        approx::assert_relative_eq!(f.lat_deg.unwrap(), 48.512_345_6, max_relative = 1e-12);
        approx::assert_relative_eq!(f.lon_deg.unwrap(), 9.345_678_9, max_relative = 1e-12);
        approx::assert_relative_eq!(fixes[1].lat_deg.unwrap(), 48.512_345_7, max_relative = 1e-12);
        approx::assert_relative_eq!(f.alt_m.unwrap(), 304.5);
        approx::assert_relative_eq!(f.geoid_sep_m.unwrap(), 352.0 - 304.5);
        assert_eq!(f.sats_used, Some(7));
        approx::assert_relative_eq!(f.pdop.unwrap(), 1.56);
        approx::assert_relative_eq!(f.hdop.unwrap(), 0.98);
        approx::assert_relative_eq!(f.vdop.unwrap(), 1.21);
        approx::assert_relative_eq!(f.error.unwrap().horizontal_m, 2.5);
    }

    /// NAV-SOL of the LEA-4T log's second epoch (gpsd 3.27.5 `test/daemon/ublox-lea-4t.log`): iTOW, fTOW,
    /// week 1516, 3D, flags 0x9D, ECEF cm, pAcc 5.44 m, pDOP 2.42, 8 satellites.
    fn lea_4t_sol(itow: u32) -> Vec<u8> {
        let mut sol = vec![0u8; 52];
        put(&mut sol, 0, &itow.to_le_bytes());
        put(&mut sol, 4, &192_920i32.to_le_bytes());
        put(&mut sol, 8, &1516i16.to_le_bytes());
        sol[10] = 3;
        sol[11] = 0x9D;
        put(&mut sol, 12, &(-151_029_962i32).to_le_bytes());
        put(&mut sol, 16, &(-348_349_812i32).to_le_bytes());
        put(&mut sol, 20, &510_853_310i32.to_le_bytes());
        put(&mut sol, 24, &544u32.to_le_bytes());
        put(&mut sol, 44, &242u16.to_le_bytes());
        sol[47] = 8;
        frame(0x01, 0x06, &sol)
    }

    /// NAV-TIMEGPS with leap seconds `leap` flagged valid with time of week and week.
    fn timegps(itow: u32, leap: i8) -> Vec<u8> {
        let mut t = vec![0u8; 16];
        put(&mut t, 0, &itow.to_le_bytes());
        put(&mut t, 4, &192_920i32.to_le_bytes());
        put(&mut t, 8, &1516i16.to_le_bytes());
        t[10] = leap.to_le_bytes()[0];
        t[11] = 0x07;
        frame(0x01, 0x20, &t)
    }

    #[test]
    fn nav_sol_alone_gives_gpsds_position_and_time() {
        // gpsd's report for this epoch (ublox-lea-4t.log.chk): 2009-01-28T20:35:44.001Z, 53.563254092,
        // -113.439545157, mode 3. The next epoch has no NAV-TIMEGPS: the receiver's 15 leap seconds carry.
        let data = [lea_4t_sol(333_359_001), timegps(333_359_001, 15), lea_4t_sol(333_360_001)].concat();
        let (fixes, stats) = crate::gps::decode_reader(data.as_slice()).unwrap();
        assert_eq!(fixes.len(), 2, "{stats}");
        let f = &fixes[0];
        assert_eq!(f.time.unwrap().format("%Y-%m-%dT%H:%M:%S%.3fZ").to_string(), "2009-01-28T20:35:44.001Z");
        assert_eq!(
            fixes[1].time.unwrap().format("%Y-%m-%dT%H:%M:%S%.3fZ").to_string(),
            "2009-01-28T20:35:45.001Z"
        );
        assert_eq!(f.mode, Some(FixMode::Fix3D));
        assert!((f.lat_deg.unwrap() - 53.563_254_092).abs() < 1e-9);
        assert!((f.lon_deg.unwrap() - -113.439_545_157).abs() < 1e-9);
        assert_eq!(f.alt_m, None, "only an ellipsoidal height was sent; the fix's altitude is MSL");
        assert_eq!(f.sats_used, Some(8));
        approx::assert_relative_eq!(f.pdop.unwrap(), 2.42);
        approx::assert_relative_eq!(f.error.unwrap().horizontal_m, 5.44);
        approx::assert_relative_eq!(f.speed_m_s.unwrap(), 0.0);
    }

    #[test]
    fn without_any_leap_seconds_the_epoch_has_no_time() {
        // No NAV-TIMEGPS ever: GPS time cannot be turned into UTC, and no default is guessed.
        let data = [lea_4t_sol(333_359_001), lea_4t_sol(333_360_001)].concat();
        let (fixes, _) = crate::gps::decode_reader(data.as_slice()).unwrap();
        assert_eq!(fixes.len(), 2);
        assert!(fixes.iter().all(|f| f.time.is_none() && f.lat_deg.is_some()));
    }

    #[test]
    fn ecef_velocity_gives_speed_and_course() {
        // On the equator at longitude 0 east is +Y: 1 m/s along +Y is 1 m/s towards 90 deg.
        let mut sol = vec![0u8; 52];
        sol[10] = 3;
        sol[11] = 0x01;
        put(&mut sol, 12, &637_813_700i32.to_le_bytes());
        sol[47] = 6;
        let mut vel = vec![0u8; 20];
        put(&mut vel, 8, &100i32.to_le_bytes());
        let data = [frame(0x01, 0x06, &sol), frame(0x01, 0x11, &vel)].concat();
        let (fixes, _) = crate::gps::decode_reader(data.as_slice()).unwrap();
        let f = &fixes[0];
        assert!(f.lat_deg.unwrap().abs() < 1e-9 && f.lon_deg.unwrap().abs() < 1e-9);
        approx::assert_relative_eq!(f.speed_m_s.unwrap(), 1.0, epsilon = 1e-12);
        approx::assert_relative_eq!(f.course_deg.unwrap(), 90.0, epsilon = 1e-9);
    }

    #[test]
    fn a_fix_type_without_a_position_is_no_fix() {
        // NAV-SOL says 3D but its ECEF point is the earth's centre (no place on earth), no NAV-POSLLH.
        let mut sol = vec![0u8; 52];
        sol[10] = 3;
        sol[11] = 0x01;
        sol[47] = 9;
        let (fixes, _) = crate::gps::decode_reader(frame(0x01, 0x06, &sol).as_slice()).unwrap();
        assert_eq!(fixes.len(), 1);
        assert_eq!((fixes[0].mode, fixes[0].lat_deg), (Some(FixMode::NoFix), None));
    }
}

/// A receiver sending only UBX messages without a position (raw subframes here) gives no fix, and the
/// decoder says why once, as a notice and first in its summary; the same messages beside NMEA (an F9P
/// logging raw measurements) say nothing, the NMEA giving the fixes.
#[test]
fn messages_without_a_position_say_why_there_is_no_fix() {
    use crate::gps::{GpsEvent, NmeaDecoder};
    let now = std::time::Instant::now();
    let notices = |d: &mut NmeaDecoder| -> Vec<String> {
        std::iter::from_fn(|| d.poll_event())
            .filter_map(|e| if let GpsEvent::Notice(n) = e { Some(n) } else { None })
            .collect()
    };
    let sfrbx: Vec<u8> = (0..10u8).flat_map(|i| frame(0x02, 0x13, &[i; 48])).collect();
    let mut d = NmeaDecoder::default();
    d.handle_bytes(&sfrbx, now);
    d.handle_bytes(&sfrbx, now);
    d.finish(now);
    let advice = WithoutFix::RawSubframes.advice();
    assert_eq!(notices(&mut d), [advice]);
    assert_eq!(d.stats().ubx_without_fix, Some(WithoutFix::RawSubframes));
    assert!(d.stats().to_string().starts_with(advice), "{}", d.stats());
    // Stored-log read-back: LOG-BATCH (0x21 0x11).
    let mut d = NmeaDecoder::default();
    d.handle_bytes(&(0..5).flat_map(|_| frame(0x21, 0x11, &[0; 100])).collect::<Vec<u8>>(), now);
    assert_eq!(notices(&mut d), [WithoutFix::StoredLog.advice()]);
    // RXM-RAWX among NMEA: no notice, no advice.
    let gga = "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n";
    let mut mixed = Vec::new();
    for _ in 0..5 {
        mixed.extend(frame(0x02, 0x15, &[0; 16]));
        mixed.extend_from_slice(gga.as_bytes());
    }
    let mut d = NmeaDecoder::default();
    d.handle_bytes(&mixed, now);
    d.finish(now);
    assert!(notices(&mut d).is_empty());
    assert_eq!(d.stats().ubx_without_fix, Some(WithoutFix::RawMeasurements));
    assert!(!d.stats().to_string().contains(WithoutFix::RawMeasurements.advice()));
}

/// The message identifiers of [`WithoutFix`] against the u-blox 8 / M8 receiver description's tables;
/// the navigation messages that give fixes are not among them.
#[test]
fn messages_without_a_position_are_named_by_their_identifiers() {
    assert_eq!(WithoutFix::of(0x02, 0x13), Some(WithoutFix::RawSubframes));
    assert_eq!(WithoutFix::of(0x02, 0x15), Some(WithoutFix::RawMeasurements));
    assert_eq!(WithoutFix::of(0x02, 0x14), Some(WithoutFix::RawMeasurements));
    for id in [0x08, 0x0B, 0x0D, 0x0F, 0x11] {
        assert_eq!(WithoutFix::of(0x21, id), Some(WithoutFix::StoredLog), "LOG 0x{id:02X}");
    }
    assert_eq!(WithoutFix::of(0x0A, 0x32), Some(WithoutFix::StoredLog));
    // NAV-PVT, NAV-SOL, NAV-POSLLH, HNR-PVT, MON-VER.
    for (class, id) in [(0x01, 0x07), (0x01, 0x06), (0x01, 0x02), (0x28, 0x00), (0x0A, 0x04)] {
        assert_eq!(WithoutFix::of(class, id), None);
    }
}
