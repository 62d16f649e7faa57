//! Heading sentences through the decoder: HDG as [`GpsEvent::Attitude`], THS/HDT in the fix.

use super::*;
use crate::heading::Attitude;
use approx::assert_relative_eq;

/// NMEA checksum computed here, independently of the framer: XOR of the bytes between `$` and `*`.
fn xor_checksum(body: &str) -> u8 {
    body.bytes().fold(0, |a, b| a ^ b)
}

/// The literal checksums below were computed with Python; this checks them once more.
fn checked(sentence: &str) -> String {
    let (body, hh) = sentence[1..].split_once('*').unwrap();
    assert_eq!(format!("{:02X}", xor_checksum(body)), hh, "{sentence}");
    format!("{sentence}\r\n")
}

fn events(d: &mut NmeaDecoder) -> Vec<GpsEvent> {
    std::iter::from_fn(|| d.poll_event()).collect()
}

fn attitudes(ev: &[GpsEvent]) -> Vec<Attitude> {
    ev.iter().filter_map(|e| if let GpsEvent::Attitude(a) = e { Some(*a) } else { None }).collect()
}

fn logs() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/gpsd-logs")
}

/// An HDG split over two reads is stamped with the instant of the read that completed it, and is
/// magnetic from the NMEA input; the variation is recorded, not applied.
#[test]
fn hdg_becomes_an_attitude_stamped_on_arrival() {
    let text = checked("$HCHDG,98.3,0.0,E,12.6,W*57");
    let (t0, t1) = (Instant::now(), Instant::now() + Duration::from_millis(70));
    let mut d = NmeaDecoder::new(DecoderConfig::live());
    d.handle_bytes(&text.as_bytes()[..10], t0);
    assert!(events(&mut d).is_empty());
    d.handle_bytes(&text.as_bytes()[10..], t1);
    let a = attitudes(&events(&mut d));
    assert_eq!(a.len(), 1);
    assert_relative_eq!(a[0].heading_deg, 98.3, max_relative = 1e-12);
    assert_eq!(a[0].reference, HeadingReference::Magnetic);
    assert_eq!(a[0].origin, HeadingOrigin::Nmea);
    assert_eq!(a[0].received_at, t1);
    assert_eq!((a[0].pitch_deg, a[0].roll_deg, a[0].quality_pct, a[0].field_ut), (None, None, None, None));
    assert_relative_eq!(d.magnetic_variation_deg().unwrap(), -12.6, max_relative = 1e-12);
    assert_eq!(d.stats().sentences, 1);
    assert_eq!(d.stats().rejected(), 0);
}

/// A 10 Hz compass between every pair of lines of a real log changes none of its fixes (HDG is not an
/// epoch boundary), in file and in live mode; every HDG comes out.
#[test]
fn hdg_between_every_line_changes_no_fix() {
    let log = std::fs::read(logs().join("nd-1005.log")).unwrap();
    let hdg = checked("$HCHDG,359.0,2.5,E,1.3,E*48");
    let mut with_hdg = Vec::new();
    let mut lines = 0;
    for line in log.split_inclusive(|&b| b == b'\n') {
        with_hdg.extend_from_slice(hdg.as_bytes());
        with_hdg.extend_from_slice(line);
        lines += 1;
    }
    let now = Instant::now();
    for config in [DecoderConfig::file(), DecoderConfig::live()] {
        let run = |data: &[u8]| {
            let mut d = NmeaDecoder::new(config);
            let mut ev = Vec::new();
            for line in data.split_inclusive(|&b| b == b'\n') {
                d.handle_bytes(line, now);
                ev.extend(events(&mut d));
            }
            d.finish(now);
            ev.extend(events(&mut d));
            ev
        };
        let plain = run(&log);
        let mixed = run(&with_hdg);
        let fixes = |ev: &[GpsEvent]| -> Vec<Fix> {
            ev.iter()
                .filter_map(|e| if let GpsEvent::Fix(f) = e { Some((**f).clone()) } else { None })
                .collect()
        };
        assert_eq!(fixes(&plain).len(), 16, "{config:?}");
        assert_eq!(fixes(&plain), fixes(&mixed), "{config:?}");
        let a = attitudes(&mixed);
        assert_eq!(a.len(), lines, "{config:?}");
        // 359.0 + 2.5 E = 361.5 -> 1.5 (by hand).
        assert!(a.iter().all(|a| (a.heading_deg - 1.5).abs() < 1e-9));
    }
}

/// Bytes carrying only HDG do not hold an epoch open: the quiet gap after the last GGA still closes it.
#[test]
fn compass_stream_does_not_delay_the_quiet_gap() {
    let t0 = Instant::now();
    let ms = |n| t0 + Duration::from_millis(n);
    let mut d = NmeaDecoder::new(DecoderConfig::live());
    let gga = checked("$GPGGA,110518.000,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.2,M,,0000*77");
    d.handle_bytes(gga.as_bytes(), t0);
    let hdg = checked("$SDHDG,229.8,,,1.3,E*36");
    for n in [100, 200, 300, 400] {
        d.handle_bytes(hdg.as_bytes(), ms(n));
    }
    assert_eq!(d.poll_timeout(), Some(ms(400)), "deadline = last GGA + 400 ms quiet gap");
    d.handle_timeout(ms(450));
    let ev = events(&mut d);
    assert_eq!(attitudes(&ev).len(), 4);
    assert_eq!(ev.iter().filter(|e| matches!(e, GpsEvent::Fix(_))).count(), 1, "{ev:?}");
}

/// Hostile HDG: bad checksum, 999°, NaN, infinity, no heading, a deviation without its letter: no
/// attitude, every one counted as rejected.
#[test]
fn hostile_hdg_is_rejected_and_counted() {
    let mut text = String::from("$HCHDG,98.3,0.0,E,12.6,W*58\r\n"); // wrong checksum (57)
    for s in [
        "$HCHDG,999.0,0.0,E,,*20",
        "$HCHDG,NaN,,,,*0D",
        "$HCHDG,inf,,,,*0D",
        "$HCHDG,,,,,*6C",
        "$HCHDG,10.0,5.0,,,*58",
        "$HCHDG,10.0,200.0,E,,*1A",
    ] {
        text += &checked(s);
    }
    let mut d = NmeaDecoder::new(DecoderConfig::live());
    d.handle_bytes(text.as_bytes(), Instant::now());
    assert!(attitudes(&events(&mut d)).is_empty());
    let st = d.stats();
    assert_eq!((st.bad_checksum, st.malformed), (1, 6), "{st}");
    assert_eq!(st.rejected(), 7);
    assert_eq!(d.magnetic_variation_deg(), None);
}

fn decode(lines: &[&str]) -> Vec<Fix> {
    let text: String = lines.iter().map(|s| checked(s)).collect();
    crate::gps::decode_reader(text.as_bytes()).unwrap().0
}

/// THS mode V: neither its heading nor the same epoch's HDT becomes the fix's true heading; mode A does.
#[test]
fn ths_mode_v_sets_no_true_heading() {
    let gga = "$GPGGA,110518.000,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.2,M,,0000*77";
    let fixes = decode(&[gga, "$GNTHS,244.28,V*06", "$GPHDT,250.0,T*32"]);
    assert_eq!(fixes.len(), 1);
    assert!(fixes[0].has_position());
    assert_eq!(fixes[0].true_heading_deg, None);
    let fixes = decode(&[gga, "$GNTHS,244.28,A*11"]);
    assert_relative_eq!(fixes[0].true_heading_deg.unwrap(), 244.28, max_relative = 1e-12);
    let fixes = decode(&[gga, "$GPHDT,250.0,T*32"]);
    assert_relative_eq!(fixes[0].true_heading_deg.unwrap(), 250.0, max_relative = 1e-12);
}

/// gpsd's own output for the `SkyTraq` PX1172RH (THS and HDT each second, dual antenna): every fix's
/// true heading equals the heading of gpsd's timed ATT report for that second (gpsd prints 3
/// decimals), in file and in live mode.
#[test]
fn skytraq_true_heading_matches_gpsd_att() {
    let chk = std::fs::read_to_string(logs().join("skytraq-PX1172RH_DS.log.chk")).unwrap();
    let mut truth = BTreeMap::new();
    for line in chk.lines().filter(|l| l.contains("\"class\":\"ATT\"")) {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        if let (Some(t), Some(h)) = (v["time"].as_str(), v["heading"].as_f64()) {
            truth.insert(t.to_owned(), h);
        }
    }
    assert!(truth.len() >= 3, "{truth:?}");
    let log = std::fs::read(logs().join("skytraq-PX1172RH_DS.log")).unwrap();
    let now = Instant::now();
    for config in [DecoderConfig::file(), DecoderConfig::live()] {
        let mut d = NmeaDecoder::new(config);
        let mut ev = Vec::new();
        for line in log.split_inclusive(|&b| b == b'\n') {
            d.handle_bytes(line, now);
            ev.extend(events(&mut d));
        }
        d.finish(now);
        ev.extend(events(&mut d));
        let mut matched = 0;
        for f in ev.iter().filter_map(|e| if let GpsEvent::Fix(f) = e { Some(f) } else { None }) {
            let Some(t) = f.time else { continue };
            let key = t.format("%Y-%m-%dT%H:%M:%S%.3fZ").to_string();
            if let Some(h) = truth.get(&key) {
                let got = f.true_heading_deg.unwrap_or_else(|| panic!("{config:?} {key}: no heading"));
                assert!((got - h).abs() <= 5e-4, "{config:?} {key}: {got} vs gpsd {h}");
                matched += 1;
            }
        }
        assert_eq!(matched, truth.len(), "{config:?}");
        assert!(attitudes(&ev).is_empty(), "THS/HDT stay in the fix");
    }
}
