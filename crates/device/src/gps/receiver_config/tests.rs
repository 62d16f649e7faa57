//! Frames checked against the documents' field layouts and published frames; the session and the emulated
//! receiver against each other.

use std::time::{Duration, Instant};

use proptest::prelude::*;

use super::emulator::{EmulatedFamily, EmulatedReceiver, Protocol};
use super::*;
use crate::gps::framing::{Frame, Framer};

fn unhex(s: &str) -> Vec<u8> {
    s.split_whitespace().map(|b| u8::from_str_radix(b, 16).unwrap()).collect()
}

/// The UBX frames of `bytes` as (class, id, payload), through the GPS framer.
fn ubx_frames(bytes: &[u8]) -> Vec<(u8, u8, Vec<u8>)> {
    let mut v = Vec::new();
    Framer::new().feed(bytes, |f, _| {
        if let Frame::Ubx { class, id, payload } = f {
            v.push((class, id, payload.to_vec()));
        }
    });
    v
}

fn u16le(p: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([p[at], p[at + 1]])
}

fn u32le(p: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([p[at], p[at + 1], p[at + 2], p[at + 3]])
}

#[test]
fn cfg_rate_1_hz_is_the_published_frame() {
    // The frame u-center sends for 1 Hz, GPS time (measRate 1000 ms, navRate 1, timeRef 1).
    let cfg = ReceiverConfig { rate_hz: Some(1), ..ReceiverConfig::new(Family::Ublox) };
    let cmds = commands(&cfg, 9600).unwrap();
    assert_eq!(cmds.len(), 1);
    assert_eq!(cmds[0].hex(), "B5 62 06 08 06 00 E8 03 01 00 01 00 01 39");
    assert_eq!(cmds[0].expect, Expect::UbxAck { class: 0x06, id: 0x08 });
}

#[test]
fn cfg_rate_fields_follow_the_layout_for_every_rate() {
    // UBX-13003221 §32.10.23: U2 measRate [ms] at 0, U2 navRate at 2, U2 timeRef at 4, little-endian.
    for hz in 1..=10u8 {
        let cfg = ReceiverConfig { rate_hz: Some(hz), ..ReceiverConfig::new(Family::Ublox) };
        let f = &commands(&cfg, 9600).unwrap()[0].bytes;
        assert_eq!(&f[..6], &[0xB5, 0x62, 0x06, 0x08, 6, 0]);
        let p = &f[6..12];
        assert_eq!(u16le(p, 0), (1000.0 / f64::from(hz)).round() as u16);
        assert_eq!(u16le(p, 2), 1);
        assert_eq!(u16le(p, 4), 1);
    }
    // 5 Hz: 200 ms = C8 00.
    let cfg = ReceiverConfig { rate_hz: Some(5), ..ReceiverConfig::new(Family::Ublox) };
    assert_eq!(commands(&cfg, 9600).unwrap()[0].bytes[6..8], [0xC8, 0x00]);
}

#[test]
fn cfg_nav5_encoder_reproduces_the_published_airborne_frame() {
    // The UKHAB "flight mode" frame published for u-blox 6 balloon trackers (CFG-NAV5, all mask bits,
    // dynModel 6, fixMode auto, fixedAltVar 1 m², minElev 5°, pDop/tDop 25.0, pAcc 100 m, tAcc 300 m).
    let published = unhex(
        "B5 62 06 24 24 00 FF FF 06 03 00 00 00 00 10 27 00 00 05 00 FA 00 FA 00 64 00 2C 01 00 00 00 00 \
         00 00 00 00 00 00 00 00 00 00 16 DC",
    );
    let n = Nav5 {
        mask: 0xFFFF,
        dyn_model: 6,
        fix_mode: 3,
        fixed_alt_var: 10_000,
        min_elev_deg: 5,
        p_dop_x10: 250,
        t_dop_x10: 250,
        p_acc_m: 100,
        t_acc_m: 300,
        ..Nav5::default()
    };
    assert_eq!(ubx::frame(UBX_CFG, UBX_CFG_NAV5, &cfg_nav5_payload(&n)), published);
}

#[test]
fn cfg_nav5_pedestrian_with_static_hold_follows_the_layout() {
    let cfg = ReceiverConfig {
        dynamic_model: Some(DynamicModel::Pedestrian),
        static_hold_m_s: Some(0.5),
        static_hold_max_dist_m: Some(10),
        ..ReceiverConfig::new(Family::Ublox)
    };
    let cmds = commands(&cfg, 9600).unwrap();
    assert_eq!(cmds.len(), 1);
    let f = &cmds[0].bytes;
    assert_eq!(&f[..6], &[0xB5, 0x62, 0x06, 0x24, 36, 0]);
    let p = &f[6..42];
    assert_eq!(u16le(p, 0), 0x0041, "mask: bit 0 dyn + bit 6 staticHold");
    assert_eq!(p[2], 3, "dynModel 3 = pedestrian");
    assert_eq!(p[22], 50, "staticHoldThresh in cm/s");
    assert_eq!(u16le(p, 28), 10, "staticHoldMaxDist in m");
    // Every other field is zero (ignored under the mask).
    for (i, b) in p.iter().enumerate() {
        if ![0, 2, 22, 28].contains(&i) {
            assert_eq!(*b, 0, "offset {i}");
        }
    }
    let (a, b) = ubx::checksum(0x06, 0x24, p);
    assert_eq!(&f[42..], &[a, b]);
}

#[test]
fn cfg_gnss_blocks_follow_the_layout_and_the_limits() {
    let c = Constellations::parse("gps,glonass,galileo,qzss,sbas").unwrap();
    let cfg = ReceiverConfig { constellations: Some(c), ..ReceiverConfig::new(Family::Ublox) };
    let f = &commands(&cfg, 9600).unwrap()[0].bytes;
    let len = usize::from(u16le(f, 4));
    assert_eq!(len, 4 + 8 * 6);
    let p = &f[6..6 + len];
    assert_eq!(&p[..4], &[0, 0, 0xFF, 6], "msgVer 0, numTrkChHw 0 (read-only), numTrkChUse all, 6 blocks");
    let mut seen = Vec::new();
    let mut reserved = 0;
    for b in p[4..].chunks_exact(8) {
        let flags = u32le(b, 4);
        assert_eq!((flags >> 16) & 0xFF, 1, "sigCfgMask: L1");
        assert!(b[1] <= b[2], "resTrkCh <= maxTrkCh");
        reserved += usize::from(b[1]);
        seen.push((b[0], flags & 1 == 1));
    }
    assert!(reserved <= 32, "u-blox 8 has 32 channels");
    seen.sort_unstable();
    assert_eq!(seen, [(0, true), (1, true), (2, true), (3, false), (5, true), (6, true)]);
    // Four majors on a u-blox 8, QZSS without GPS, none at all: refused before anything is sent.
    for list in ["gps,glonass,galileo,beidou", "glonass,qzss", "sbas"] {
        let c = Constellations::parse(list).unwrap();
        let cfg = ReceiverConfig { constellations: Some(c), ..ReceiverConfig::new(Family::Ublox) };
        assert!(commands(&cfg, 9600).is_err(), "{list}");
    }
    assert!(Constellations::parse("gps,navic").is_err());
}

#[test]
fn cfg_cfg_save_is_the_published_frame() {
    // "Save configuration" to BBR, flash, EEPROM and SPI flash as published for u-blox 6–8:
    // B5 62 06 09 0D 00 00 00 00 00 FF FF 00 00 00 00 00 00 17 31 BF.
    let cfg = ReceiverConfig { save: true, ..ReceiverConfig::new(Family::Ublox) };
    let cmds = commands(&cfg, 9600).unwrap();
    assert_eq!(cmds[0].hex(), "B5 62 06 09 0D 00 00 00 00 00 FF FF 00 00 00 00 00 00 17 31 BF");
}

#[test]
fn valset_items_follow_the_key_layout() {
    let cfg = ReceiverConfig {
        rate_hz: Some(5),
        dynamic_model: Some(DynamicModel::Pedestrian),
        static_hold_m_s: Some(0.3),
        ..ReceiverConfig::new(Family::Ublox9)
    };
    let cmds = commands(&cfg, 38400).unwrap();
    assert_eq!(cmds.len(), 1);
    let f = &cmds[0].bytes;
    assert_eq!(&f[2..4], &[0x06, 0x8A]);
    let p = &f[6..f.len() - 2];
    assert_eq!(&p[..4], &[0, LAYER_RAM, 0, 0]);
    // CFG-RATE-MEAS 0x30210001 = 01 00 21 30, U2 200 ms.
    assert_eq!(&p[4..10], &[0x01, 0x00, 0x21, 0x30, 0xC8, 0x00]);
    // CFG-RATE-NAV 0x30210002, U2 1; CFG-RATE-TIMEREF 0x20210003, E1 1 (GPS).
    assert_eq!(&p[10..16], &[0x02, 0x00, 0x21, 0x30, 1, 0]);
    assert_eq!(&p[16..21], &[0x03, 0x00, 0x21, 0x20, 1]);
    // CFG-NAVSPG-DYNMODEL 0x20110021, E1 3; CFG-MOTION-GNSSSPEED_THRS 0x20250038, U1 30 cm/s.
    assert_eq!(&p[21..26], &[0x21, 0x00, 0x11, 0x20, 3]);
    assert_eq!(&p[26..31], &[0x38, 0x00, 0x25, 0x20, 30]);
    assert_eq!(p.len(), 31);
    // Saving writes the RAM, BBR and flash layers.
    let saved = commands(&ReceiverConfig { save: true, ..cfg }, 38400).unwrap();
    assert_eq!(saved[0].bytes[7], LAYER_RAM | LAYER_BBR | LAYER_FLASH);
    // The size bits of every key id we write (bits 28–30: 1 bit, 1, 2 bytes).
    assert_eq!(key_value_size(key::SIGNAL_GPS_ENA), Some(1));
    assert_eq!(key_value_size(key::RATE_MEAS), Some(2));
    assert_eq!(key_value_size(key::MOTION_GNSSDIST_THRS), Some(2));
}

#[test]
fn sirf_static_navigation_off_is_psrf100_mid143_mid129() {
    let cfg = ReceiverConfig { sirf_static_nav: Some(false), ..ReceiverConfig::new(Family::Sirf) };
    let cmds = commands(&cfg, 4800).unwrap();
    assert_eq!(cmds.len(), 3);
    // The NMEA Reference Manual's example sentence, checksum as published: $PSRF100,0,4800,8,1,0*0F.
    assert_eq!(cmds[0].bytes, b"$PSRF100,0,4800,8,1,0*0F\r\n");
    assert_eq!(psrf100(0, 9600), "$PSRF100,0,9600,8,1,0*0C\r\n");
    // MID 143, 2-byte payload 8F 00 (disable); checksum 0x008F; A0 A2 ... B0 B3.
    assert_eq!(cmds[1].hex(), "A0 A2 00 02 8F 00 00 8F B0 B3");
    assert_eq!(cmds[1].expect, Expect::SirfAck { mid: 143 });
    // MID 129: 24 bytes, mode 2, ten (rate, checksum) pairs, baud big-endian 4800 = 12 C0.
    let f = &cmds[2].bytes;
    assert_eq!(&f[..4], &[0xA0, 0xA2, 0x00, 0x18]);
    let p = &f[4..28];
    assert_eq!(p[0], 0x81);
    assert_eq!(p[1], 2);
    let pairs: Vec<(u8, u8)> = p[2..22].chunks_exact(2).map(|c| (c[0], c[1])).collect();
    assert_eq!(pairs[0], (1, 1), "GGA every second");
    assert_eq!(pairs[2], (1, 1), "GSA");
    assert_eq!(pairs[3], (5, 1), "GSV every 5 s");
    assert_eq!(pairs[4], (1, 1), "RMC");
    assert_eq!(&p[22..24], &[0x12, 0xC0]);
    assert_eq!(u16::from_be_bytes([f[28], f[29]]), sirf::checksum(p));
    assert_eq!(&f[30..], &[0xB0, 0xB3]);
    // Enabling it again: 8F 01.
    let on = ReceiverConfig { sirf_static_nav: Some(true), ..ReceiverConfig::new(Family::Sirf) };
    assert_eq!(commands(&on, 4800).unwrap()[1].hex(), "A0 A2 00 02 8F 01 00 90 B0 B3");
    assert!(commands(&on, 115_200).is_err(), "MID 129's baud is 16 bits");
}

#[test]
fn settings_a_family_lacks_are_refused() {
    let cfg = ReceiverConfig { rate_hz: Some(5), ..ReceiverConfig::new(Family::Sirf) };
    assert!(commands(&cfg, 4800).is_err());
    let cfg = ReceiverConfig { sirf_static_nav: Some(false), ..ReceiverConfig::new(Family::Ublox) };
    assert!(commands(&cfg, 4800).is_err());
    for hz in [0, 11] {
        let cfg = ReceiverConfig { rate_hz: Some(hz), ..ReceiverConfig::new(Family::Ublox) };
        assert!(commands(&cfg, 4800).is_err());
    }
    assert!(commands(&ReceiverConfig::new(Family::Ublox), 4800).is_err(), "nothing to configure");
}

#[test]
fn published_acks_are_recognised() {
    // ACK-ACK of CFG-RATE and of CFG-PRT as u-center logs them.
    let bytes = unhex("B5 62 05 01 02 00 06 08 16 3F B5 62 05 01 02 00 06 00 0E 37");
    let mut replies = Vec::new();
    Framer::new().feed(&bytes, |f, _| replies.extend(reply::reply(&f)));
    assert_eq!(replies, [reply::Reply::UbxAck { class: 6, id: 8 }, reply::Reply::UbxAck { class: 6, id: 0 }]);
}

fn run(session: &mut ConfigSession, rx: &mut EmulatedReceiver, t0: Instant) -> Vec<CommandOutcome> {
    let mut now = t0;
    let mut out = Vec::new();
    for _ in 0..200 {
        while let Some(bytes) = session.poll_transmit(now) {
            rx.handle_bytes(&bytes);
        }
        session.handle_bytes(&rx.take_output(), now);
        session.handle_timeout(now);
        while let Some(o) = session.poll_outcome() {
            out.push(o);
        }
        if session.is_done() {
            break;
        }
        now += Duration::from_millis(50);
    }
    out
}

#[test]
fn the_emulated_ublox_acks_and_applies_every_command() {
    let mut rx = EmulatedReceiver::new(EmulatedFamily::Ublox8, false);
    let cfg = ReceiverConfig {
        rate_hz: Some(5),
        constellations: Some(Constellations::default()),
        dynamic_model: Some(DynamicModel::Pedestrian),
        static_hold_m_s: Some(0.5),
        save: true,
        ..ReceiverConfig::new(Family::Ublox)
    };
    let out = run(&mut ConfigSession::new(commands(&cfg, 9600).unwrap()), &mut rx, Instant::now());
    let names: Vec<_> = out.iter().map(|o| (o.name.as_str(), o.outcome.clone())).collect();
    assert_eq!(
        names,
        [
            ("CFG-RATE", Outcome::Accepted),
            ("CFG-GNSS", Outcome::Accepted),
            ("CFG-NAV5", Outcome::Accepted),
            ("CFG-CFG (save)", Outcome::Accepted)
        ]
    );
    let s = rx.settings();
    assert_eq!(s.period, Duration::from_millis(200));
    assert_eq!(s.dyn_model, 3);
    assert_eq!(s.static_hold_m_s, Some(0.5));
}

#[test]
fn malformed_and_unsupported_cfg_get_a_nak_and_silence_is_no_reply() {
    let mut rx = EmulatedReceiver::new(EmulatedFamily::Ublox8, false);
    let bad_rate = ConfigCommand::ubx("CFG-RATE", UBX_CFG_RATE, &cfg_rate_payload(10, 1, 1));
    let short = ConfigCommand::ubx("CFG-NAV5", UBX_CFG_NAV5, &[1, 0, 3]);
    let valset =
        ConfigCommand::ubx("CFG-VALSET", UBX_CFG_VALSET, &cfg_valset_payload(1, &[(key::RATE_MEAS, 200)]));
    let out = run(&mut ConfigSession::new(vec![bad_rate, short, valset]), &mut rx, Instant::now());
    assert!(out.iter().all(|o| o.outcome == Outcome::Refused), "{out:?}");
    assert_eq!(rx.settings().period, Duration::from_secs(1));
    // A SiRF receiver does not speak UBX: nothing comes back.
    let mut sirf = EmulatedReceiver::new(EmulatedFamily::Sirf3, true);
    let cfg = ReceiverConfig { rate_hz: Some(2), ..ReceiverConfig::new(Family::Ublox) };
    let t0 = Instant::now();
    let out = run(&mut ConfigSession::new(commands(&cfg, 4800).unwrap()), &mut sirf, t0);
    assert_eq!(out[0].outcome, Outcome::NoReply);
    assert!(out[0].at >= t0 + ACK_TIMEOUT, "decided only after the timeout");
}

#[test]
fn the_emulated_sirf3_turns_static_navigation_off_through_binary() {
    let mut rx = EmulatedReceiver::new(EmulatedFamily::Sirf3, true);
    assert_eq!(rx.settings().static_hold_m_s, Some(SIRF3_STATIC_NAV_M_S));
    let cfg = ReceiverConfig { sirf_static_nav: Some(false), ..ReceiverConfig::new(Family::Sirf) };
    let mut session = ConfigSession::new(commands(&cfg, 4800).unwrap());
    let out = run(&mut session, &mut rx, Instant::now());
    let got: Vec<_> = out.iter().map(|o| o.outcome.clone()).collect();
    assert_eq!(got, [Outcome::Sent, Outcome::Accepted, Outcome::Sent]);
    assert_eq!(rx.settings().static_hold_m_s, None);
    assert_eq!(rx.settings().protocol, Protocol::Nmea);
    // MID 143 before $PSRF100 is ignored (binary to a receiver in NMEA mode).
    let mut rx = EmulatedReceiver::new(EmulatedFamily::Sirf3, true);
    rx.handle_bytes(&sirf::frame(&sirf_static_nav_payload(false)));
    assert_eq!(rx.settings().static_hold_m_s, Some(SIRF3_STATIC_NAV_M_S));
    assert!(rx.take_output().is_empty());
}

#[test]
fn the_emulated_ublox9_applies_valset_all_or_nothing() {
    let mut rx = EmulatedReceiver::new(EmulatedFamily::Ublox9, false);
    let cfg = ReceiverConfig {
        rate_hz: Some(10),
        constellations: Some(Constellations::parse("gps,galileo,beidou,glonass").unwrap()),
        ..ReceiverConfig::new(Family::Ublox9)
    };
    let out = run(&mut ConfigSession::new(commands(&cfg, 38400).unwrap()), &mut rx, Instant::now());
    assert_eq!(out[0].outcome, Outcome::Accepted);
    assert_eq!(rx.settings().period, Duration::from_millis(100));
    let unknown = ConfigCommand::ubx(
        "CFG-VALSET",
        UBX_CFG_VALSET,
        &cfg_valset_payload(1, &[(key::RATE_MEAS, 500), (0x2099_0001, 1)]),
    );
    let out = run(&mut ConfigSession::new(vec![unknown]), &mut rx, Instant::now());
    assert_eq!(out[0].outcome, Outcome::Refused);
    assert_eq!(rx.settings().period, Duration::from_millis(100), "nothing applied");
}

/// A small independent parser of our u-blox 6–8 frames, reading the fields at the documents' offsets.
fn reparse_ublox(bytes: &[u8]) -> ReceiverConfig {
    let mut cfg = ReceiverConfig::new(Family::Ublox);
    for (class, id, p) in ubx_frames(bytes) {
        assert_eq!(class, 0x06, "not a CFG frame: {id:#x} {p:?}");
        match id {
            // measRate is whole ms: 6 Hz is 167 ms, read back as the nearest rate.
            0x08 => cfg.rate_hz = Some((1000.0 / f64::from(u16le(&p, 0))).round() as u8),
            0x24 => {
                let mask = u16le(&p, 0);
                if mask & 1 != 0 {
                    cfg.dynamic_model = DynamicModel::from_code(p[2]);
                }
                if mask & 0x40 != 0 {
                    cfg.static_hold_m_s = Some(f64::from(p[22]) / 100.0);
                    cfg.static_hold_max_dist_m = Some(u16le(&p, 28));
                }
            }
            0x3E => {
                let mut c = Constellations::parse("").unwrap();
                for b in p[4..].chunks_exact(8) {
                    let on = u32le(b, 4) & 1 == 1;
                    match b[0] {
                        0 => c.gps = on,
                        1 => c.sbas = on,
                        2 => c.galileo = on,
                        3 => c.beidou = on,
                        5 => c.qzss = on,
                        6 => c.glonass = on,
                        _ => {}
                    }
                }
                cfg.constellations = Some(c);
            }
            0x09 => cfg.save = u32le(&p, 4) != 0,
            other => panic!("unexpected CFG id {other:#x}"),
        }
    }
    cfg
}

fn constellations() -> impl Strategy<Value = Constellations> {
    proptest::array::uniform6(any::<bool>()).prop_map(|b| Constellations {
        gps: b[0],
        glonass: b[1],
        galileo: b[2],
        beidou: b[3],
        qzss: b[4],
        sbas: b[5],
    })
}

proptest! {
    #[test]
    fn any_valid_ublox_config_reparses_to_itself(
        rate in proptest::option::of(1u8..=10),
        cons in proptest::option::of(constellations()),
        model in proptest::option::of(proptest::sample::select(DynamicModel::ALL.to_vec())),
        hold_cm in proptest::option::of(0u8..=255),
        dist in proptest::option::of(any::<u16>()),
        save in any::<bool>(),
    ) {
        let cfg = ReceiverConfig {
            rate_hz: rate,
            constellations: cons,
            dynamic_model: model,
            static_hold_m_s: hold_cm.map(|c| f64::from(c) / 100.0),
            static_hold_max_dist_m: dist,
            save,
            ..ReceiverConfig::new(Family::Ublox)
        };
        let Ok(cmds) = commands(&cfg, 9600) else {
            prop_assert!(cfg.validate().is_err());
            return Ok(());
        };
        let bytes: Vec<u8> = cmds.iter().flat_map(|c| c.bytes.clone()).collect();
        let back = reparse_ublox(&bytes);
        prop_assert_eq!(back.rate_hz, cfg.rate_hz);
        prop_assert_eq!(back.constellations, cfg.constellations);
        prop_assert_eq!(back.dynamic_model, cfg.dynamic_model);
        prop_assert_eq!(back.save, cfg.save);
        if cfg.static_hold_m_s.is_some() || cfg.static_hold_max_dist_m.is_some() {
            prop_assert_eq!(back.static_hold_m_s, Some(cfg.static_hold_m_s.unwrap_or(0.0)));
            prop_assert_eq!(back.static_hold_max_dist_m, Some(cfg.static_hold_max_dist_m.unwrap_or(0)));
        }
    }

    #[test]
    fn hostile_bytes_never_panic_the_session_or_emulator(
        chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..300), 0..20)
    ) {
        let mut rx = EmulatedReceiver::new(EmulatedFamily::Ublox9, true);
        let mut sirf = EmulatedReceiver::new(EmulatedFamily::Sirf3, true);
        let mut session = ConfigSession::new(
            commands(&ReceiverConfig { rate_hz: Some(2), ..ReceiverConfig::new(Family::Ublox) }, 9600).unwrap(),
        );
        let now = Instant::now();
        let _ = session.poll_transmit(now);
        for c in &chunks {
            rx.handle_bytes(c);
            sirf.handle_bytes(c);
            sirf.handle_bytes(b"$PSRF100,0,4800,8,1,0*0F\r\n");
            session.handle_bytes(c, now);
        }
        prop_assert!(rx.take_output().len() < 64 * 1024);
    }
}
