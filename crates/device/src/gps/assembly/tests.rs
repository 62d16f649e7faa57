//! Tests of `assembly`.

use super::*;
use chrono::{Datelike, Timelike};
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

/// GSA DOPs of 0.00 (the Jackson Labs Micro JLT's "not computed") are not DOPs: no 0 m error estimate.
#[test]
fn zero_dops_are_not_given() {
    use crate::gps::framing::with_checksum;
    let text = [
        "GNGGA,012238.00,3454.4922,S,13835.7617,E,2,12,0.9,53.3,M,-3.5,M,,",
        "GNGSA,A,3,27,9,20,5,4,30,8,7,14,,,,0.00,0.00,0.00",
        "GNGGA,012239.00,3454.4922,S,13835.7617,E,2,12,0.9,53.3,M,-3.5,M,,",
    ]
    .map(with_checksum)
    .concat();
    let (fixes, _) = crate::gps::decode_reader(text.as_bytes()).unwrap();
    let f = &fixes[0];
    assert_eq!((f.hdop, f.pdop, f.vdop), (Some(0.9), None, None));
    let e = f.error.unwrap();
    assert!((e.horizontal_m - 0.9 * super::UERE_DGPS_M).abs() < 1e-9 && e.vertical_m.is_none(), "{e:?}");
}

/// A GSA of the receiver's no-fix time (mode 1, no ids) does not speak for a later epoch with a fix.
#[test]
fn a_no_fix_gsa_does_not_outlive_the_fix() {
    use crate::gps::framing::with_checksum;
    let text = [
        "GPGGA,081433.591,8960.000000,N,00000.000000,E,0,0,,137.000,M,13.000,M,,",
        "GPGSA,A,1,,,,,,,,,,,,,,,",
        "GPGGA,081436.000,5212.982135,N,00653.101394,E,1,3,2.88,102.907,M,47.093,M,,",
        "GPGGA,081437.000,5212.981473,N,00653.102458,E,1,3,2.88,102.907,M,47.093,M,,",
    ]
    .map(with_checksum)
    .concat();
    let (fixes, _) = crate::gps::decode_reader(text.as_bytes()).unwrap();
    assert_eq!(fixes[0].sats_used, Some(0));
    assert_eq!((fixes[1].sats_used, fixes[1].hdop), (Some(3), Some(2.88)));
}

/// Receivers' power-on dates with year 80 (`SiRF` 05/01/80, `MediaTek` 12/01/80) are 1980, not 2080, on
/// every parse path; 1980-01-05 is before GPS time (implausible) and does not hold back the real date.
#[test]
fn year_80_is_1980_and_does_not_block_the_real_date() {
    use crate::gps::framing::with_checksum;
    use crate::gps::sentence::{Parsed, parse};
    for body in [
        "GPRMC,235951.952,V,0000.0000,N,00000.0000,E,,0.00,050180,,,N",
        "GPRMC,081433.591,V,8960.000000,N,00000.000000,E,0.000,0.00,050180,,,N",
        "GPRMC,235951,V,0000.0000,N,00000.0000,E,,,050180,,W",
    ] {
        let s = with_checksum(body);
        let Ok(Parsed::Rmc { date, .. }) = parse(s.trim_end()) else { panic!("{body}") };
        assert_eq!(date, chrono::NaiveDate::from_ymd_opt(1980, 1, 5), "{body}");
    }
    let text = [
        "GPRMC,235951.952,V,0000.0000,N,00000.0000,E,,0.00,050180,,,N",
        "GPRMC,102523.342,A,4815.6883,N,01140.3675,E,0.00,0.00,210808,,,A",
    ]
    .map(with_checksum)
    .concat();
    let (fixes, stats) = crate::gps::decode_reader(text.as_bytes()).unwrap();
    assert_eq!(stats.implausible_dates, 1, "{stats}");
    assert_eq!(fixes.last().unwrap().time.unwrap().to_rfc3339(), "2008-08-21T10:25:23.342+00:00");
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

/// One epoch of a receiver sending GGA and ZDA, at `hh:mm:ss` on `dd/mm/yyyy`.
fn gga_zda(hms: (u32, u32, u32), dmy: (u32, u32, u32)) -> String {
    use crate::gps::framing::with_checksum;
    let t = format!("{:02}{:02}{:02}.00", hms.0, hms.1, hms.2);
    [
        with_checksum(&format!("GPGGA,{t},4221.0,N,07106.0,W,1,05,1.0,10.0,M,0.0,M,,")),
        with_checksum(&format!("GPZDA,{t},{:02},{:02},{:04},00,00", dmy.0, dmy.1, dmy.2)),
    ]
    .concat()
}

/// The issue's case: a ZDA with year 0255 and a valid checksum. Its date never becomes the fix's UTC
/// (first epoch: only the range can judge it; later: the running date stays), the rest of the fix is kept,
/// and the rejection is counted.
#[test]
fn a_zda_of_year_0255_never_becomes_the_fixs_time() {
    let (fixes, stats) = crate::gps::decode_reader(gga_zda((12, 0, 0), (1, 1, 255)).as_bytes()).unwrap();
    assert_eq!(fixes.len(), 1);
    assert_eq!(fixes[0].time, None);
    assert_eq!(fixes[0].time_of_day, NaiveTime::from_hms_opt(12, 0, 0));
    assert!(fixes[0].has_position());
    assert_eq!(stats.implausible_dates, 1);
    assert!(stats.to_string().contains("1 implausible dates"), "{stats}");

    let text = [
        gga_zda((12, 0, 0), (3, 2, 2016)),
        gga_zda((12, 0, 1), (1, 1, 255)),
        gga_zda((12, 0, 2), (3, 2, 2016)),
    ]
    .concat();
    let (fixes, stats) = crate::gps::decode_reader(text.as_bytes()).unwrap();
    let times: Vec<String> = fixes.iter().map(|f| f.time.unwrap().to_rfc3339()).collect();
    assert_eq!(
        times,
        ["2016-02-03T12:00:00+00:00", "2016-02-03T12:00:01+00:00", "2016-02-03T12:00:02+00:00"]
    );
    assert_eq!(stats.implausible_dates, 1);
}

/// A receiver that really changes its date (a spliced log, a corrected week rollover) is followed after
/// [`CONFIRM_EPOCHS`] epochs agree; the epochs before that keep the running date.
#[test]
fn a_confirmed_new_date_is_followed() {
    let text: String = (0..6)
        .map(|i| if i < 2 { gga_zda((8, 0, i), (7, 4, 2019)) } else { gga_zda((8, 0, i), (22, 8, 1999)) })
        .collect();
    let (fixes, stats) = crate::gps::decode_reader(text.as_bytes()).unwrap();
    let dates: Vec<String> = fixes.iter().map(|f| f.time.unwrap().date_naive().to_string()).collect();
    assert_eq!(dates, ["2019-04-07", "2019-04-07", "2019-04-07", "2019-04-07", "1999-08-22", "1999-08-22"]);
    assert_eq!(stats.implausible_dates, u64::from(CONFIRM_EPOCHS) - 1);
}

proptest! {
    /// Mutation fuzzing of the date: one epoch of a consistent stream (crossing midnight) gets any other
    /// date with a correct checksum, by ZDA or by RMC; no fix's UTC ever carries it, every fix keeps the
    /// true date, and the mutation is counted.
    #[test]
    fn mutated_dates_never_reach_the_fix_time(
        at in 1usize..8,
        year in 0u32..10_000,
        month in 1u32..=12,
        day in 1u32..=28,
        by_rmc in any::<bool>(),
    ) {
        use crate::gps::framing::with_checksum;
        // 23:59:56 .. 00:00:03 across the new year 2023/2024.
        let truth: Vec<(NaiveDate, NaiveTime)> = (0..8u32)
            .map(|i| {
                let s = (23 * 3600 + 59 * 60 + 56 + i) % 86_400;
                let date = if s < 3600 { NaiveDate::from_ymd_opt(2024, 1, 1) } else { NaiveDate::from_ymd_opt(2023, 12, 31) };
                (date.unwrap(), NaiveTime::from_num_seconds_from_midnight_opt(s, 0).unwrap())
            })
            .collect();
        let mutated = NaiveDate::from_ymd_opt(i32::try_from(year).unwrap(), month, day).unwrap();
        prop_assume!(mutated != truth[at].0);
        // RMC has two-digit years (83-99 = 19xx, else 20xx): the mutation is the date it reads as.
        let mutated = if by_rmc {
            let yy = year % 100;
            NaiveDate::from_ymd_opt(i32::try_from(if yy >= 83 { 1900 + yy } else { 2000 + yy }).unwrap(), month, day).unwrap()
        } else {
            mutated
        };
        prop_assume!(mutated != truth[at].0);
        let text: String = truth
            .iter()
            .enumerate()
            .map(|(i, (date, tod))| {
                let d = if i == at { mutated } else { *date };
                let t = tod.format("%H%M%S.00");
                if by_rmc {
                    with_checksum(&format!(
                        "GPRMC,{t},A,4221.0,N,07106.0,W,0.0,0.0,{},,,A",
                        d.format("%d%m%y")
                    ))
                } else {
                    gga_zda((tod.hour(), tod.minute(), tod.second()), (d.day(), d.month(), d.year() as u32))
                }
            })
            .collect();
        let (fixes, stats) = crate::gps::decode_reader(text.as_bytes()).unwrap();
        prop_assert_eq!(fixes.len(), truth.len());
        for (f, (date, tod)) in fixes.iter().zip(&truth) {
            prop_assert_eq!(f.time, Some(date.and_time(*tod).and_utc()));
        }
        prop_assert_eq!(stats.implausible_dates, 1);
    }
}

/// The sentences of gpsd's `bundg_zeus_9.log` (a B&G Zeus² multiplexer) from 09:48:15 to 09:48:18, as
/// logged. Up to 09:48:16 its GLL carries GGA's UTC label; from 09:48:17 on it carries RMC's, one second
/// later (GGA(16) and GLL(17) hold the same position).
const ZEUS_LABEL_SWITCH: [&str; 18] = [
    "$GPGGA,094815,5250.9714,N,00518.7347,E,1,12,0.60,-5,M,46.8,M,,*48",
    "$GPGLL,5250.9714,N,00518.7347,E,094815,A,A*44",
    "$GPGSA,A,3,07,08,10,16,20,21,26,27,29,76,75,70,1.10,0.60,0.90*0B",
    "$GPRMC,094816,A,5250.9713,N,00518.7344,E,5.5,237.9,200818,1.4,E,A*16",
    "$GPVTG,237.9,T,236.5,M,5.5,N,10.2,K,A*1D",
    "$GPZDA,094816,20,08,2018,-01,00*67",
    "$GPGGA,094816,5250.9705,N,00518.7323,E,1,12,0.60,-5,M,46.8,M,,*49",
    "$GPGLL,5250.9705,N,00518.7323,E,094817,A,A*44",
    "$GPGSA,A,3,07,08,10,16,20,21,26,27,29,76,75,70,1.10,0.60,0.90*0B",
    "$GPRMC,094817,A,5250.9705,N,00518.7323,E,5.7,238.1,200818,1.4,E,A*14",
    "$GPVTG,238.1,T,236.7,M,5.7,N,10.5,K,A*1D",
    "$GPZDA,094817,20,08,2018,-01,00*66",
    "$GPGGA,094817,5250.9696,N,00518.7305,E,1,12,0.60,-5,M,46.8,M,,*47",
    "$GPGLL,5250.9696,N,00518.7305,E,094818,A,A*44",
    "$GPGSA,A,3,07,08,10,16,20,21,26,27,29,76,75,70,1.10,0.60,0.90*0B",
    "$GPRMC,094818,A,5250.9695,N,00518.7303,E,5.6,229.6,200818,1.4,E,A*17",
    "$GPVTG,229.6,T,228.2,M,5.6,N,10.4,K,A*10",
    "$GPZDA,094818,20,08,2018,-01,00*69",
];

/// One epoch per labelled second, whatever sentence type moves to another label (docs/gps.md, "Epoch rules
/// added for the multiplexers"): the epoch's position is the one most of its position sentences give (a
/// tie, or all within a metre: the latest), its altitude GGA's, its speed RMC/VTG's. Expected values are
/// the sentences' own fields (ddmm.mmmm -> degrees, knots -> m/s). At 09:48:17 GLL(17) and RMC(17) give one
/// position and GGA(17) the next second's: the two win, which is also gpsd's report for 09:48:17 (GLL(17),
/// its `.chk`). gpsd has no report for 09:48:16. Live decoding (cycle end learned, amended fixes) ends every
/// second with the same fix as file decoding.
#[test]
fn a_multiplexer_moving_gll_to_the_next_label_keeps_one_epoch_per_second() {
    let deg = |d: f64, min: f64| d + min / 60.0;
    let kn = |v: f64| v * 1852.0 / 3600.0;
    // (second, lat, lon, altitude, speed): 15 GLL(15) = GGA(15); 16 GGA(16) after RMC(16), 2.8 m apart, a
    // tie; 17 GLL(17) = RMC(17) against GGA(17); 18 RMC(18) after GLL(18), 0.3 m apart (no GGA of 18 in the
    // excerpt).
    let expected = [
        (15, deg(52.0, 50.9714), deg(5.0, 18.7347), Some(-5.0), None),
        (16, deg(52.0, 50.9705), deg(5.0, 18.7323), Some(-5.0), Some(kn(5.5))),
        (17, deg(52.0, 50.9705), deg(5.0, 18.7323), Some(-5.0), Some(kn(5.7))),
        (18, deg(52.0, 50.9695), deg(5.0, 18.7303), None, Some(kn(5.6))),
    ];
    let text = ZEUS_LABEL_SWITCH.join("\r\n") + "\r\n";
    let check = |what: &str, fixes: &[&Fix]| {
        assert_eq!(fixes.len(), expected.len(), "{what}: one fix per labelled second");
        for (f, &(s, lat, lon, alt, speed)) in fixes.iter().zip(&expected) {
            assert_eq!(f.time_of_day, NaiveTime::from_hms_opt(9, 48, s), "{what}");
            assert_eq!(f.mode, Some(FixMode::Fix3D), "{what} {s}");
            assert!(
                (f.lat_deg.unwrap() - lat).abs() < 1e-9 && (f.lon_deg.unwrap() - lon).abs() < 1e-9,
                "{what} {s}"
            );
            assert_eq!(f.alt_m, alt, "{what} {s}");
            match (f.speed_m_s, speed) {
                (Some(a), Some(b)) => assert!((a - b).abs() < 1e-9, "{what} {s}: {a} m/s"),
                (a, b) => assert_eq!(a, b, "{what} {s}"),
            }
        }
    };
    let (file_fixes, stats) = crate::gps::decode_reader(text.as_bytes()).unwrap();
    check("file", &file_fixes.iter().collect::<Vec<_>>());
    // 16 (a tie) and 17 (two against one) disagree; 15 and 18 agree.
    assert_eq!(stats.disagreeing_positions, 2, "{stats}");
    // Live: line by line; the last fix of each second is that second's.
    let mut d = NmeaDecoder::new(DecoderConfig::live());
    let now = Instant::now();
    let mut live: Vec<Fix> = Vec::new();
    let push = |events: Vec<GpsEvent>, live: &mut Vec<Fix>| {
        for e in events {
            if let GpsEvent::Fix(f) = e {
                match live.last_mut() {
                    Some(last) if last.time_of_day == f.time_of_day => *last = *f,
                    _ => live.push(*f),
                }
            }
        }
    };
    for l in ZEUS_LABEL_SWITCH {
        d.handle_bytes(format!("{l}\r\n").as_bytes(), now);
        push(all_events(&mut d), &mut live);
    }
    d.finish(now);
    push(all_events(&mut d), &mut live);
    check("live", &live.iter().collect::<Vec<_>>());
}

/// `bundg_zeus_9.log` at 09:49:45 (gpsd's suite): the multiplexer sends the second's RMC, VTG and ZDA twice
/// and no GGA or GLL. The repeated VTG (no time field) splits the epoch, and the `VTG ZDA` left over carries
/// the same second without a position: it is not a second epoch, so 09:49:45 stays the RMC's 3D fix (gpsd's
/// `.chk`: mode 3, 52.848168333, 5.309098333) instead of turning into "no fix" — in file and live decoding.
#[test]
fn a_second_repeated_without_a_position_is_not_a_no_fix_epoch() {
    let lines = [
        "$GPGGA,094944,5250.8910,N,00518.5482,E,1,12,0.60,-5,M,46.8,M,,*4A",
        "$GPGLL,5250.8909,N,00518.5480,E,094944,A,A*4C",
        "$GPRMC,094944,A,5250.8909,N,00518.5480,E,5.7,233.6,200818,1.4,E,A*10",
        "$GPVTG,227.6,T,226.2,M,5.3,N,9.8,K,A*21",
        "$GPZDA,094944,20,08,2018,-01,00*61",
        "$GPRMC,094945,A,5250.8901,N,00518.5459,E,5.4,240.2,200818,1.4,E,A*1E",
        "$GPVTG,240.0,T,238.6,M,5.7,N,10.5,K,A*1C",
        "$GPZDA,094945,20,08,2018,-01,00*60",
        "$GPRMC,094945,A,5250.8901,N,00518.5459,E,5.4,240.2,200818,1.4,E,A*1E",
        "$GPVTG,240.0,T,238.6,M,5.7,N,10.5,K,A*1C",
        "$GPZDA,094945,20,08,2018,-01,00*60",
        "$GPGGA,094946,5250.8891,N,00518.5441,E,1,12,0.60,-5,M,46.8,M,,*4F",
        "$GPGLL,5250.8890,N,00518.5439,E,094946,A,A*4D",
        "$GPGSA,A,3,07,08,10,16,20,21,26,27,29,76,75,70,1.10,0.60,0.90*0B",
    ];
    let second_45 = |fixes: &[Fix], what: &str| {
        let of_45: Vec<&Fix> =
            fixes.iter().filter(|f| f.time_of_day == NaiveTime::from_hms_opt(9, 49, 45)).collect();
        assert!(!of_45.is_empty(), "{what}");
        for f in of_45 {
            assert_eq!(f.mode, Some(FixMode::Fix3D), "{what}");
            assert!((f.lat_deg.unwrap() - 52.848_168_333).abs() < 1e-9, "{what}");
            assert!((f.lon_deg.unwrap() - 5.309_098_333).abs() < 1e-9, "{what}");
        }
    };
    let text = lines.join("\r\n") + "\r\n";
    let (fixes, _) = crate::gps::decode_reader(text.as_bytes()).unwrap();
    let seconds: Vec<_> = fixes.iter().filter_map(|f| f.time_of_day).map(|t| t.second()).collect();
    assert_eq!(seconds, [44, 45, 46], "one fix per second from a file");
    second_45(&fixes, "file");
    let mut d = NmeaDecoder::new(DecoderConfig::live());
    let now = Instant::now();
    for l in lines {
        d.handle_bytes(format!("{l}\r\n").as_bytes(), now);
    }
    d.finish(now);
    let live: Vec<Fix> = all_events(&mut d)
        .into_iter()
        .filter_map(|e| if let GpsEvent::Fix(f) = e { Some(*f) } else { None })
        .collect();
    second_45(&live, "live");
}

/// [`super::consensus`] against positions laid out at known distances (metres north/east turned into degrees
/// by the same spherical metres-per-degree): within a metre they agree, the majority wins, a tie goes to the
/// kind not out-voted last time, then to the latest, and the antimeridian is no gap.
#[test]
fn an_epochs_position_is_the_one_most_of_its_sentences_give() {
    use super::Kind;
    use super::consensus::{Consensus, M_PER_DEG, consensus};
    let lat0: f64 = 52.85;
    let at = |north_m: f64, east_m: f64| {
        (lat0 + north_m / M_PER_DEG, 5.3 + east_m / (M_PER_DEG * lat0.to_radians().cos()))
    };
    let bit = |k: Kind| 1u16 << k as u16;
    let (gga, rmc, gll) = (Kind::Gga, Kind::Rmc, Kind::Gll);
    assert_eq!(consensus(&[], 0), Consensus { position: None, outvoted: 0 });
    let (a, b, c) = (at(0.0, 0.0), at(0.3, 0.4), at(-0.5, 0.2));
    let all_near = [(gga, a), (gll, b), (rmc, c)];
    assert_eq!(consensus(&all_near, 0), Consensus { position: Some(c), outvoted: 0 }, "all within 1 m");
    // One second of boat motion (2.8 m) apart: two sentences against one, whatever the order.
    let (p, q) = (at(0.0, 0.0), at(-1.5, -2.4));
    for order in
        [[(gll, p), (rmc, p), (gga, q)], [(gll, p), (gga, q), (rmc, p)], [(gga, q), (gll, p), (rmc, p)]]
    {
        let want = Consensus { position: Some(p), outvoted: bit(gga) };
        assert_eq!(consensus(&order, 0), want, "{order:?}");
    }
    // A tie: the latest, unless its kind was out-voted last time.
    let tie = [(gll, p), (gga, q)];
    assert_eq!(consensus(&tie, 0), Consensus { position: Some(q), outvoted: bit(gll) });
    assert_eq!(consensus(&tie, bit(gga)), Consensus { position: Some(p), outvoted: bit(gga) });
    assert_eq!(consensus(&tie, bit(gll)), Consensus { position: Some(q), outvoted: bit(gll) });
    // 1.2 m apart is a disagreement, 0.9 m is not.
    assert_ne!(consensus(&[(gga, at(0.0, 0.0)), (rmc, at(0.0, 1.2))], 0).outvoted, 0);
    assert_eq!(consensus(&[(gga, at(0.0, 0.0)), (rmc, at(0.0, 0.9))], 0).outvoted, 0);
    // 0.67 m across the antimeridian at the equator.
    assert_eq!(consensus(&[(gga, (0.0, 179.999_997)), (rmc, (0.0, -179.999_997))], 0).outvoted, 0);
}

/// A stream repeating one second's position sentences keeps only the epoch's last few positions (memory
/// bounded whatever the input); the majority of those is the fix's.
#[test]
fn an_epoch_keeps_a_bounded_number_of_positions() {
    use std::fmt::Write as _;
    let mut text = String::new();
    for i in 0..1000 {
        // 999 GLLs at one place (0.19 m apart, alternating: no sentence repeats the one before it), then one
        // 100 m away: all labelled 12:00:00.
        let lat = match i {
            999 => "5250.0540",
            i if i % 2 == 0 => "5250.0000",
            _ => "5250.0001",
        };
        let body = format!("GPGLL,{lat},N,00518.0000,E,120000,A,A");
        let sum = body.bytes().fold(0u8, |s, b| s ^ b);
        writeln!(text, "${body}*{sum:02X}\r").unwrap();
    }
    let mut d = NmeaDecoder::new(DecoderConfig::file());
    d.handle_bytes(text.as_bytes(), Instant::now());
    assert!(d.epoch.positions.len() <= super::consensus::MAX_EPOCH_POSITIONS);
    d.finish(Instant::now());
    let fixes: Vec<_> = all_events(&mut d)
        .into_iter()
        .filter_map(|e| if let GpsEvent::Fix(f) = e { Some(f) } else { None })
        .collect();
    assert_eq!(fixes.len(), 1);
    assert!((fixes[0].lat_deg.unwrap() - 52.833_333_333).abs() < 5e-6, "{:?}", fixes[0].lat_deg);
}

/// `bundg_zeus_9.log` at 09:48:04 (gpsd's suite): the multiplexer forwards the second's VTG twice in a row
/// between its RMC and its GGA/GLL. The repeat is the same sentence, not the next epoch: one fix for the
/// second, whose position is the one GGA and GLL agree on against RMC (gpsd's report for 09:48:04, its
/// `.chk`: 52.849703333, 5.312648333). Before, the repeat split off RMC alone as a second fix of 09:48:04.
#[test]
fn a_sentence_forwarded_twice_does_not_split_its_second() {
    let lines = [
        "$GPRMC,094803,A,5250.9840,N,00518.7629,E,5.7,233.2,200818,1.4,E,A*18",
        "$GPGLL,5250.9830,N,00518.7607,E,094803,A,A*4B",
        "$GPRMC,094804,A,5250.9830,N,00518.7607,E,6.4,232.3,200818,1.4,E,A*14",
        "$GPVTG,232.3,T,230.9,M,6.4,N,11.8,K,A*11",
        "$GPVTG,232.3,T,230.9,M,6.4,N,11.8,K,A*11",
        "$GPZDA,094804,20,08,2018,-01,00*64",
        "$GPGGA,094804,5250.9822,N,00518.7589,E,1,12,0.60,-4,M,46.8,M,,*47",
        "$GPGLL,5250.9822,N,00518.7589,E,094804,A,A*4A",
    ];
    let text = lines.join("\r\n") + "\r\n";
    let (fixes, stats) = crate::gps::decode_reader(text.as_bytes()).unwrap();
    let times: Vec<_> = fixes.iter().map(|f| f.time_of_day.unwrap().second()).collect();
    assert_eq!(times, [3, 4], "{stats}");
    assert_eq!(stats.duplicate_sentences, 1);
    let f = &fixes[1];
    assert!(
        (f.lat_deg.unwrap() - 52.849_703_333).abs() < 1e-8
            && (f.lon_deg.unwrap() - 5.312_648_333).abs() < 1e-8
    );
    // Two identical VTGs of two epochs with a time sentence between them are two epochs' VTGs.
    let stationary = [
        "$GPVTG,0.0,T,,M,0.0,N,0.0,K,A*0D",
        "$GPRMC,120000,A,4807.038,N,01131.000,E,0.0,0.0,230394,,,A*7E",
        "$GPVTG,0.0,T,,M,0.0,N,0.0,K,A*0D",
        "$GPRMC,120001,A,4807.038,N,01131.000,E,0.0,0.0,230394,,,A*7F",
    ];
    let text = stationary.join("\r\n") + "\r\n";
    let (fixes, stats) = crate::gps::decode_reader(text.as_bytes()).unwrap();
    assert_eq!(fixes.len(), 2, "{stats}");
    assert!(fixes.iter().all(|f| f.speed_m_s == Some(0.0)), "{fixes:?}");
    assert_eq!(stats.duplicate_sentences, 0);
}

/// gpsd's `telit-pls83-w.log` (a Telit PLS83-W, multi-constellation), 04:35:40-41 as logged: per-system
/// sentences of one epoch (`$GPGGA` and `$GAGGA`, `$GPVTG` and `$GAVTG`, `$GPRMC` and `$GARMC`). The second
/// VTG is another talker's sentence of the same epoch, not a repeat starting the next: one fix a second.
/// Before, `$GAVTG` split off its RMCs as a second fix of the same time.
#[test]
fn another_talkers_sentence_of_the_same_kind_does_not_split_the_epoch() {
    let lines = [
        "$GPGGA,043540.00,4333.190199,N,00127.618384,E,1,05,1.3,250.8,M,50.0,M,,*6D",
        "$GAGGA,043540.00,4333.190199,N,00127.618384,E,1,01,1.3,250.8,M,50.0,M,,*78",
        "$GNGNS,043540.00,4333.190199,N,00127.618384,E,AAAAN,14,1.3,250.8,50.0,,,V*6D",
        "$GPVTG,,T,1.7,M,0.0,N,0.0,K,A*0B",
        "$GAVTG,,T,1.7,M,0.0,N,0.0,K,A*1A",
        "$GPRMC,043540.00,A,4333.190199,N,00127.618384,E,0.0,,040925,1.7,W,A,V*73",
        "$GARMC,043540.00,A,4333.190199,N,00127.618384,E,0.0,,040925,1.7,W,A,V*62",
        "$GNGSA,A,2,02,08,10,23,27,,,,,,,,1.6,1.3,0.9,1*33",
        "$GNGSA,A,2,65,66,73,81,82,,,,,,,,1.6,1.3,0.9,2*3B",
        "$GNGSA,A,2,33,,,,,,,,,,,,1.6,1.3,0.9,3*3E",
        "$GNGSA,A,2,208,211,213,,,,,,,,,,1.6,1.3,0.9,4*01",
        "$GNGSA,A,2,,,,,,,,,,,,,1.6,1.3,0.9,5*38",
        "$GPGGA,043541.00,4333.190190,N,00127.618388,E,1,05,1.3,250.8,M,50.0,M,,*69",
        "$GAGGA,043541.00,4333.190190,N,00127.618388,E,1,01,1.3,250.8,M,50.0,M,,*7C",
        "$GNGNS,043541.00,4333.190190,N,00127.618388,E,AAAAN,14,1.3,250.8,50.0,,,V*69",
        "$GPVTG,,T,1.7,M,0.0,N,0.0,K,A*0B",
        "$GAVTG,,T,1.7,M,0.0,N,0.0,K,A*1A",
        "$GPRMC,043541.00,A,4333.190190,N,00127.618388,E,0.0,,040925,1.7,W,A,V*77",
        "$GARMC,043541.00,A,4333.190190,N,00127.618388,E,0.0,,040925,1.7,W,A,V*66",
    ];
    let text = lines.join("\r\n") + "\r\n";
    let (fixes, stats) = crate::gps::decode_reader(text.as_bytes()).unwrap();
    let times: Vec<_> = fixes.iter().map(|f| f.time_of_day.unwrap().second()).collect();
    assert_eq!(times, [40, 41], "{stats}");
    assert!(fixes.iter().all(|f| f.has_position() && f.speed_m_s == Some(0.0)), "{fixes:?}");
}
