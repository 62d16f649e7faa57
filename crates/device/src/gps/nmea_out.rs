//! NMEA sentence generation: GGA, RMC, GSA, GSV, GST with correct checksums.
//!
//! Used by the simulator source and the GPS emulator, so everything they produce goes through the same
//! decoder as a real receiver's output. Latitude/longitude minutes get 6 decimals (1.7e-8 deg), so a
//! generated position decodes back to within 1e-7 deg.

use std::fmt::Write as _;

use chrono::{DateTime, Datelike, Timelike, Utc};

use super::framing::with_checksum;
use super::sentence::MS_PER_KNOT;

/// One satellite for GSV/GSA output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimSatellite {
    /// GPS PRN (1–32).
    pub prn: u16,
    /// Elevation [deg].
    pub elevation_deg: f64,
    /// Azimuth [deg].
    pub azimuth_deg: f64,
    /// C/N0 [dB-Hz].
    pub snr_dbhz: f64,
    /// Used in the fix.
    pub used: bool,
}

/// Everything one generated epoch says.
#[derive(Debug, Clone, PartialEq)]
pub struct EpochOut {
    /// UTC time of the epoch.
    pub time: DateTime<Utc>,
    /// Latitude [deg]; `None` = no fix.
    pub lat_deg: Option<f64>,
    /// Longitude [deg].
    pub lon_deg: Option<f64>,
    /// Altitude above mean sea level [m].
    pub alt_m: f64,
    /// Speed over ground [m/s].
    pub speed_m_s: f64,
    /// Course over ground [deg].
    pub course_deg: f64,
    /// Satellites in view.
    pub satellites: Vec<SimSatellite>,
    /// HDOP.
    pub hdop: f64,
    /// PDOP.
    pub pdop: f64,
    /// VDOP.
    pub vdop: f64,
    /// 1-sigma error per axis for GST [m].
    pub sigma_m: f64,
}

fn hms(t: &DateTime<Utc>) -> String {
    format!("{:02}{:02}{:02}.{:02}", t.hour(), t.minute(), t.second(), t.nanosecond() / 10_000_000)
}

/// Degrees to NMEA `ddmm.mmmmmm,N` (or `dddmm.mmmmmm,E` with `lon`).
fn coord(deg: f64, lon: bool) -> String {
    let hemi = match (lon, deg < 0.0) {
        (false, false) => 'N',
        (false, true) => 'S',
        (true, false) => 'E',
        (true, true) => 'W',
    };
    let a = deg.abs();
    let mut d = a.trunc();
    let mut m = ((a - d) * 60.0 * 1e6).round() / 1e6;
    if m >= 60.0 {
        d += 1.0;
        m -= 60.0;
    }
    if lon {
        format!("{:03}{:09.6},{hemi}", d as u32, m)
    } else {
        format!("{:02}{:09.6},{hemi}", d as u32, m)
    }
}

/// The sentences of one epoch, in a SiRF-like order: GGA, GSA, GSV (every epoch), RMC, GST.
pub fn epoch_sentences(e: &EpochOut) -> String {
    let mut out = String::new();
    let t = hms(&e.time);
    let used: Vec<u16> = e.satellites.iter().filter(|s| s.used).map(|s| s.prn).take(12).collect();
    let fix = e.lat_deg.zip(e.lon_deg);
    match fix {
        Some((lat, lon)) => out.push_str(&with_checksum(&format!(
            "GPGGA,{t},{},{},1,{:02},{:.1},{:.1},M,-33.0,M,,",
            coord(lat, false),
            coord(lon, true),
            used.len(),
            e.hdop,
            e.alt_m
        ))),
        None => out.push_str(&with_checksum(&format!("GPGGA,{t},,,,,0,00,,,M,,M,,"))),
    }
    let mut gsa = format!("GPGSA,A,{}", if fix.is_some() { 3 } else { 1 });
    for i in 0..12 {
        match used.get(i) {
            Some(p) if fix.is_some() => {
                let _ = write!(gsa, ",{p:02}");
            }
            _ => gsa.push(','),
        }
    }
    if fix.is_some() {
        let _ = write!(gsa, ",{:.1},{:.1},{:.1}", e.pdop, e.hdop, e.vdop);
    } else {
        gsa.push_str(",,,");
    }
    out.push_str(&with_checksum(&gsa));
    let n = e.satellites.len();
    let parts = n.div_ceil(4).max(1);
    for part in 0..parts {
        let mut gsv = format!("GPGSV,{parts},{},{n:02}", part + 1);
        for s in e.satellites.iter().skip(part * 4).take(4) {
            let _ = write!(
                gsv,
                ",{:02},{:02},{:03},{:02}",
                s.prn,
                s.elevation_deg.round() as i32,
                s.azimuth_deg.round() as i32,
                s.snr_dbhz.round() as i32
            );
        }
        out.push_str(&with_checksum(&gsv));
    }
    let date = format!("{:02}{:02}{:02}", e.time.day(), e.time.month(), e.time.year().rem_euclid(100));
    match fix {
        Some((lat, lon)) => out.push_str(&with_checksum(&format!(
            "GPRMC,{t},A,{},{},{:.2},{:.1},{date},,,A",
            coord(lat, false),
            coord(lon, true),
            e.speed_m_s / MS_PER_KNOT,
            e.course_deg
        ))),
        None => out.push_str(&with_checksum(&format!("GPRMC,{t},V,,,,,,,{date},,,N"))),
    }
    if fix.is_some() {
        out.push_str(&with_checksum(&format!(
            "GPGST,{t},{:.1},{:.1},{:.1},0.0,{:.1},{:.1},{:.1}",
            e.sigma_m * 1.5,
            e.sigma_m,
            e.sigma_m,
            e.sigma_m,
            e.sigma_m,
            e.sigma_m * 1.7
        )));
    }
    out
}

/// An operator mark sentence: `$PVNAV,MARK,<n>,<label>*hh` (commas and `*`/`$` in the label become blanks).
pub fn mark_sentence(number: u32, label: &str) -> String {
    let clean: String =
        label.chars().map(|c| if c.is_ascii_graphic() && !"*$!,".contains(c) { c } else { ' ' }).collect();
    with_checksum(&format!("PVNAV,MARK,{number},{}", clean.trim()))
}

/// A recording timestamp sentence: `$PVNAV,TS,<unix_ms>*hh`.
pub fn timestamp_sentence(unix_ms: i64) -> String {
    with_checksum(&format!("PVNAV,TS,{unix_ms}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gps::{FixMode, decode_reader};
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    fn epoch(lat: f64, lon: f64) -> EpochOut {
        EpochOut {
            time: DateTime::parse_from_rfc3339("2026-11-22T23:59:59.5Z").unwrap().with_timezone(&Utc),
            lat_deg: Some(lat),
            lon_deg: Some(lon),
            alt_m: 12.5,
            speed_m_s: 1.4,
            course_deg: 271.0,
            satellites: (1..=9)
                .map(|p| SimSatellite {
                    prn: p,
                    elevation_deg: 10.0 * f64::from(p),
                    azimuth_deg: 35.0 * f64::from(p),
                    snr_dbhz: 40.0,
                    used: p <= 7,
                })
                .collect(),
            hdop: 1.1,
            pdop: 1.9,
            vdop: 1.5,
            sigma_m: 2.0,
        }
    }

    proptest! {
        /// Generated sentences decode back to what was generated (position to 1e-7 deg).
        #[test]
        fn generated_epoch_round_trips(lat in -89.9f64..89.9, lon in -179.9f64..179.9) {
            let e = epoch(lat, lon);
            let (fixes, stats) = decode_reader(epoch_sentences(&e).as_bytes()).unwrap();
            prop_assert_eq!(stats.rejected(), 0);
            prop_assert_eq!(fixes.len(), 1);
            let f = &fixes[0];
            prop_assert!((f.lat_deg.unwrap() - lat).abs() <= 1e-7);
            prop_assert!((f.lon_deg.unwrap() - lon).abs() <= 1e-7);
            prop_assert_eq!(f.mode, Some(FixMode::Fix3D));
            prop_assert_eq!(f.sats_used, Some(7));
            prop_assert_eq!(f.sats_visible, Some(9));
            prop_assert_eq!(f.time, Some(e.time));
        }
    }

    #[test]
    fn speed_and_dops_round_trip() {
        let (fixes, _) = decode_reader(epoch_sentences(&epoch(42.0, -71.0)).as_bytes()).unwrap();
        let f = &fixes[0];
        assert_relative_eq!(f.speed_m_s.unwrap(), 1.4, max_relative = 0.01);
        assert_relative_eq!(f.hdop.unwrap(), 1.1, max_relative = 1e-9);
        assert_relative_eq!(f.pdop.unwrap(), 1.9, max_relative = 1e-9);
        assert_eq!(f.error.unwrap().source, crate::gps::ErrorSource::Gst);
        assert_relative_eq!(f.error.unwrap().horizontal_m, 2.0f64.hypot(2.0), max_relative = 1e-9);
    }

    #[test]
    fn marks_decode() {
        let text = format!("{}{}", epoch_sentences(&epoch(42.0, -71.0)), mark_sentence(4, "cone, 4*"));
        let (_, marks, stats) = crate::gps::decode_reader_with_marks(text.as_bytes()).unwrap();
        assert_eq!(stats.rejected(), 0);
        assert_eq!(marks.len(), 1);
        assert_eq!(marks[0].number, 4);
        assert_eq!(marks[0].label, "cone  4");
        assert_eq!(marks[0].time_of_day, Some(epoch(0.0, 0.0).time.time()));
    }
}
