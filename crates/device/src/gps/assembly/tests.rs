//! Tests of `assembly`.

use super::*;
use proptest::prelude::*;

fn all_events(d: &mut NmeaDecoder) -> Vec<GpsEvent> {
    std::iter::from_fn(|| d.poll_event()).collect()
}

proptest! {
    /// No byte sequence makes the decoder panic, in any chunking.
    #[test]
    fn arbitrary_bytes_never_panic(data in proptest::collection::vec(any::<u8>(), 0..4000), cut in 1usize..600) {
        let now = Instant::now();
        for config in [DecoderConfig::file(), DecoderConfig::live()] {
            let mut d = NmeaDecoder::new(config);
            for chunk in data.chunks(cut) {
                d.handle_bytes(chunk, now);
                d.handle_timeout(now + Duration::from_secs(1));
            }
            d.finish(now);
            let _ = all_events(&mut d);
        }
    }

    /// Valid-looking sentences with random field contents (correct checksums) never panic either.
    #[test]
    fn checksummed_garbage_never_panics(
        tag in prop::sample::select(vec!["GPGGA", "GNRMC", "GPGSA", "GLGSV", "GNGNS", "GPVTG", "GPZDA",
                                         "GPGST", "GNTHS", "GPHDT", "HCHDG", "GPGLL", "PVNAV", "PGRME"]),
        fields in proptest::collection::vec("[0-9A-Z.,+-]{0,12}", 0..22),
    ) {
        let body = format!("{tag},{}", fields.join(","));
        let text = crate::gps::framing::with_checksum(&body).repeat(3);
        let (_fixes, stats) = crate::gps::decode_reader(text.as_bytes()).unwrap();
        prop_assert_eq!(stats.sentences + stats.overlong, 3);
    }
}

#[test]
fn live_mode_learns_the_cycle_end_and_emits_without_waiting() {
    let log = std::fs::read(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/gpsd-logs/nd-1005.log"),
    )
    .unwrap();
    let mut d = NmeaDecoder::new(DecoderConfig::live());
    let now = Instant::now();
    // Feed line by line; after learning (3 epochs) a fix must come out at the cycle's last sentence,
    // i.e. before the next epoch's first GGA is fed.
    let mut fixes_before_next_gga = 0;
    for line in log.split_inclusive(|&b| b == b'\n') {
        if line.starts_with(b"$GPGGA") {
            fixes_before_next_gga = 0;
        }
        d.handle_bytes(line, now);
        fixes_before_next_gga += all_events(&mut d).iter().filter(|e| matches!(e, GpsEvent::Fix(_))).count();
    }
    assert_eq!(d.ender, Some(Kind::Vtg));
    assert_eq!(fixes_before_next_gga, 1, "the last epoch was emitted at its VTG");
}

#[test]
fn constellation_table_is_in_discriminant_order() {
    for (i, c) in ALL_CONSTELLATIONS.into_iter().enumerate() {
        assert_eq!(c as usize, i, "{c:?}");
    }
}

#[test]
fn midnight_rolls_the_date_over() {
    use crate::gps::framing::with_checksum;
    let text = [
        "GPRMC,235959.00,A,4221.0,N,07106.0,W,0.0,0.0,311226,,,A",
        "GPGGA,000000.00,4221.0,N,07106.0,W,1,05,1.0,10.0,M,0.0,M,,",
        "GPGGA,000001.00,4221.0,N,07106.0,W,1,05,1.0,10.0,M,0.0,M,,",
    ]
    .map(with_checksum)
    .concat();
    let (fixes, _) = crate::gps::decode_reader(text.as_bytes()).unwrap();
    let times: Vec<String> = fixes.iter().map(|f| f.time.unwrap().to_rfc3339()).collect();
    assert_eq!(
        times,
        ["2026-12-31T23:59:59+00:00", "2027-01-01T00:00:00+00:00", "2027-01-01T00:00:01+00:00"]
    );
}

#[test]
fn fix_loss_and_recovery() {
    let (fixes, _) = crate::gps::decode_file(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/gpsd-logs/tomtom-mkII.log"),
    )
    .unwrap();
    let modes: Vec<_> = fixes.iter().map(|f| f.mode).collect();
    assert!(modes.contains(&Some(FixMode::Fix3D)));
    assert!(modes.contains(&Some(FixMode::Fix2D)));
    let lost = fixes.iter().filter(|f| f.mode == Some(FixMode::NoFix)).count();
    assert!(lost >= 20, "{lost}");
    assert!(
        fixes
            .iter()
            .filter(|f| f.mode == Some(FixMode::NoFix))
            .all(|f| f.lat_deg.is_none() && f.error.is_none())
    );
}

/// Implausible values with correct checksums: removed or corrected by `Fix::validate` and counted,
/// the position (which is fine) kept.
#[test]
fn implausible_nmea_values_are_removed_and_counted() {
    use crate::gps::framing::with_checksum;
    let text = [
        // 10 100 satellites used and a negative HDOP.
        "GPGGA,110518.000,5709.8067,N,00207.2822,W,1,10100,-1.0,59.3,M,48.2,M,,0000",
        // Speed -5 kn and course 400 deg.
        "GPRMC,110518.000,A,5709.8067,N,00207.2822,W,-5.0,400.0,140311,,,A",
    ]
    .map(with_checksum)
    .concat();
    let (fixes, stats) = crate::gps::decode_reader(text.as_bytes()).unwrap();
    assert_eq!(stats.rejected(), 0, "{stats}");
    assert_eq!(fixes.len(), 1);
    let f = &fixes[0];
    assert!(f.has_position());
    assert!((f.lat_deg.unwrap() - 57.163_445).abs() < 1e-9);
    assert_eq!((f.sats_used, f.hdop, f.speed_m_s), (None, None, None));
    assert!((f.course_deg.unwrap() - 40.0).abs() < 1e-9, "{f:?}");
    // The DOP model made a negative error estimate (-1.0 x UERE) from the negative HDOP: removed too.
    assert_eq!(f.error, None);
    // sats, HDOP, speed, course (normalised), error estimate.
    assert_eq!(stats.implausible_values, 5, "{stats}");
    assert_eq!(stats.invalid_positions, 0);
    assert!(stats.to_string().contains("5 implausible values"), "{stats}");
}

/// The same through VTG and GSA, which carry course, speed and DOPs on their own.
#[test]
fn implausible_vtg_and_gsa_values_are_removed_and_counted() {
    use crate::gps::framing::with_checksum;
    let text = [
        "GPGGA,110518.000,5709.8067,N,00207.2822,W,1,08,,59.3,M,48.2,M,,0000",
        "GPGSA,A,3,02,05,07,12,13,15,18,20,,,,,1.8,-1.0,-1.5",
        "GPVTG,400.0,T,,M,-5.0,N,-9.3,K,A",
    ]
    .map(with_checksum)
    .concat();
    let (fixes, stats) = crate::gps::decode_reader(text.as_bytes()).unwrap();
    assert_eq!(stats.rejected(), 0, "{stats}");
    let f = &fixes[0];
    assert!(f.has_position());
    assert_eq!((f.hdop, f.vdop, f.pdop), (None, None, Some(1.8)));
    assert_eq!(f.speed_m_s, None);
    assert!((f.course_deg.unwrap() - 40.0).abs() < 1e-9, "{f:?}");
    assert_eq!(f.sats_used, Some(8));
    // HDOP, VDOP, speed, course, and the DOP model's negative error estimate.
    assert_eq!(stats.implausible_values, 5, "{stats}");
}
