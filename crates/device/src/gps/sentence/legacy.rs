//! Own GLL, RMC and GGA parsers for the shapes the `nmea` crate refuses but NMEA 0183 (or gpsd) accepts.
//!
//! They run only after the crate has declined a sentence, so the crate stays the reference for every
//! canonical one:
//! - GLL before NMEA 0183 v2.3 has no mode indicator (`lat,N,lon,E,time,status`: Garmin 48, Humminbird
//!   GR16); v2.3 added the 7th field (FAA mode, `N` = not valid). gpsd's `processGLL` uses the position
//!   when the status is `A` and the mode, if present, is not `N`.
//! - RMC's magnetic variation direction is `E` or `W` (NMEA 0183 v2.x). A `SiRF` III handset (Motorola
//!   T805) sends `0,N` there; gpsd's `processRMC` reads the variation only to report it and treats any
//!   letter other than `W` as east, so the rest of the sentence stays good. We do not use the variation.
//!   The status is `A` (valid) or `V` (navigation receiver warning); NMEA 4.1 receivers also send `D`
//!   (differential). The mode (v2.3+) `N` also means no fix.
//! - GGA with an empty fix-quality field: the Typhoon Myguide 3100 sends one during acquisition
//!   (`...,W,,2,60.000,...`, with RMC `V` and GSA mode 1 in the same second). gpsd accepts the sentence and
//!   takes the fix status from the others; so do we: the quality is unknown, which is not a fix.

use chrono::NaiveDate;

use super::{MS_PER_KNOT, Parsed, Unused, num, parse_coord, parse_time, uint, valid_pos};

/// GLL with or without the v2.3 mode field: `lat,N,lon,E[,time,status[,mode]]`.
pub(super) fn parse_gll(f: &[&str]) -> Result<Parsed, Unused> {
    if f.len() < 4 {
        return Err(Unused::Malformed);
    }
    let pos = position(f.get(..4).unwrap_or(&[]))?;
    let time = time_field(f.get(4).copied())?;
    // NMEA 0183 v1.5 GLL had neither time nor status: a position alone is taken as valid, as gpsd does.
    let status_ok = match f.get(5).copied() {
        None | Some("A" | "D") => true,
        Some("V" | "") => false,
        Some(_) => return Err(Unused::Malformed),
    };
    let mode_ok = f.get(6).is_none_or(|m| *m != "N");
    Ok(Parsed::Gll { time, pos, valid: status_ok && mode_ok && pos.is_some() })
}

/// RMC: `time,status,lat,N,lon,E,knots,course,ddmmyy,magvar,E|W[,mode[,navstatus]]`, the variation
/// ignored (see the module doc).
pub(super) fn parse_rmc(f: &[&str]) -> Result<Parsed, Unused> {
    if f.len() < 9 {
        return Err(Unused::Malformed);
    }
    let time = time_field(f.first().copied())?;
    let status_ok = match f.get(1).copied() {
        Some("A" | "D") => true,
        Some("V") => false,
        _ => return Err(Unused::Malformed),
    };
    let pos = position(f.get(2..6).unwrap_or(&[]))?;
    let date = match f.get(8).copied() {
        None | Some("") => None,
        Some(d) if d.len() == 6 && d.bytes().all(|b| b.is_ascii_digit()) => {
            let (day, month, yy) = (d[0..2].parse().ok(), d[2..4].parse().ok(), d[4..6].parse::<i32>().ok());
            let year = yy.map(super::nmea_year);
            Some(
                year.zip(month)
                    .zip(day)
                    .and_then(|((y, m), d)| NaiveDate::from_ymd_opt(y, m, d))
                    .ok_or(Unused::Malformed)?,
            )
        }
        Some(_) => return Err(Unused::Malformed),
    };
    let mode_ok = f.get(11).is_none_or(|m| *m != "N");
    Ok(Parsed::Rmc {
        time,
        date,
        valid: status_ok && mode_ok,
        pos,
        speed_m_s: num(f.get(6)).filter(|k| *k >= 0.0).map(|k| k * MS_PER_KNOT),
        course_deg: num(f.get(7)),
    })
}

/// GGA whose fix-quality field is empty (every other shape is the crate's):
/// `time,lat,N,lon,E,,sats,hdop,alt,M,sep,M,...`. Numeric fields that are present must be readable.
pub(super) fn parse_gga(f: &[&str]) -> Result<Parsed, Unused> {
    if f.len() < 11 || !f[5].is_empty() {
        return Err(Unused::Malformed);
    }
    let time = time_field(f.first().copied())?;
    let pos = position(f.get(1..5).unwrap_or(&[]))?;
    let opt = |i: usize| -> Result<Option<f64>, Unused> {
        match f.get(i) {
            None | Some(&"") => Ok(None),
            s => num(s).map(Some).ok_or(Unused::Malformed),
        }
    };
    let sats = match f.get(6) {
        None | Some(&"") => None,
        s => Some(uint(s).ok_or(Unused::Malformed)?),
    };
    Ok(Parsed::Gga { time, pos, quality: None, sats, hdop: opt(7)?, alt_m: opt(8)?, geoid_sep_m: opt(10)? })
}

/// An optional `hhmmss[.sss]` field: empty is no time, anything unreadable is malformed.
fn time_field(s: Option<&str>) -> Result<Option<chrono::NaiveTime>, Unused> {
    match s {
        None | Some("") => Ok(None),
        Some(t) => parse_time(t).map(Some).ok_or(Unused::Malformed),
    }
}

/// `lat,N,lon,E`: all empty is no position; a partly filled or unreadable one is malformed.
fn position(f: &[&str]) -> Result<Option<(f64, f64)>, Unused> {
    if f.iter().all(|s| s.is_empty()) {
        return Ok(None);
    }
    let lat = parse_coord(f.first(), f.get(1)).filter(|l| l.abs() <= 90.0);
    let lon = parse_coord(f.get(2), f.get(3)).filter(|l| l.abs() <= 180.0);
    lat.zip(lon).filter(|p| valid_pos(*p)).map(Some).ok_or(Unused::Malformed)
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;

    use super::super::parse;
    use super::*;

    /// Typhoon Myguide 3100 (gpsd's myguide-3100.log): a GGA with an empty fix quality is a sentence with
    /// its time and an unknown quality (no fix); an unreadable field is still malformed.
    #[test]
    fn gga_without_quality() {
        let Ok(Parsed::Gga {
            time: Some(t),
            pos: Some((lat, _)),
            quality: None,
            sats: Some(3),
            hdop,
            alt_m,
            ..
        }) = parse("$GPGGA,105027.80,5612.9956,N,00306.6983,W,,3,2.506,160.002,M,,M,,*6D")
        else {
            panic!()
        };
        assert_eq!(t, chrono::NaiveTime::from_hms_milli_opt(10, 50, 27, 800).unwrap());
        assert_relative_eq!(lat, 56.0 + 12.9956 / 60.0, max_relative = 1e-12);
        assert_eq!((hdop, alt_m), (Some(2.506), Some(160.002)));
        assert!(matches!(
            parse("$GPGGA,105027.80,5612.9956,N,00306.6983,W,,x,2.506,160.002,M,,M,,*26"),
            Err(Unused::Malformed)
        ));
    }

    /// Garmin 48 (gpsd's garmin48.log): a v2.0 GLL without the mode field is a valid position.
    #[test]
    fn gll_without_mode_field() {
        let Ok(Parsed::Gll { time: Some(t), pos: Some((lat, lon)), valid: true }) =
            parse("$GPGLL,4527.458,S,16709.165,E,225309,A*3E")
        else {
            panic!()
        };
        assert_eq!(t, chrono::NaiveTime::from_hms_opt(22, 53, 9).unwrap());
        assert_relative_eq!(lat, -(45.0 + 27.458 / 60.0), max_relative = 1e-12);
        assert_relative_eq!(lon, 167.0 + 9.165 / 60.0, max_relative = 1e-12);
        assert!(matches!(
            parse("$GPGLL,4527.458,S,16709.165,E,225309,V*00"),
            Ok(Parsed::Gll { valid: false, .. })
        ));
    }

    /// Motorola T805 (gpsd's motorola-t805.log): no fix, millisecond time, variation letter `N`.
    #[test]
    fn rmc_no_fix_with_odd_variation_letter() {
        let p = parse("$GPRMC,212607.891,V,,,,,,,181207,0,N*5C");
        let Ok(Parsed::Rmc { time: Some(t), date: Some(d), valid: false, pos: None, .. }) = p else {
            panic!("{p:?}")
        };
        assert_eq!(t, chrono::NaiveTime::from_hms_milli_opt(21, 26, 7, 891).unwrap());
        assert_eq!(d, NaiveDate::from_ymd_opt(2007, 12, 18).unwrap());
        for s in ["$GPRMC,212607.891,X,,,,,,,181207,0,N*00", "$GPRMC,2126xx,A,,,,,,,181207,0,N*00"] {
            assert_eq!(parse(s), Err(Unused::Malformed), "{s}");
        }
    }
}
