//! Typed positions: decimal degrees, degrees-minutes-seconds, UTM/UPS and MGRS, read and written.
//!
//! UTM/UPS and MGRS come from the `geoconvert` crate (a port of `GeographicLib`'s `UTMUPS` and `MGRS`, with
//! the Norway and Svalbard zone exceptions). Nothing here projects by hand. The one home of this parsing:
//! the console's go-to box and coordinate readout and the CLI's `--reference` both use it.
//!
//! Typed forms [`parse_position`] reads:
//! - decimal: `42.3573, -71.1010` or `42.3573 -71.1010` (latitude first);
//! - DMS: `42°21'26.3"N 71°06'03.6"W`, `42 21 26.3 N 71 6 3.6 W`, `N42 21 26.3 W71 6 3.6` (`d`, `°`, `'`,
//!   `"` as separators, hemisphere letter before or after);
//! - UTM: `19T 327588 4691263` (zone and MGRS latitude band, upper case) or `19n 327588 4691263` (zone and
//!   hemisphere in lower case, as `GeographicLib`'s `GeoConvert` writes it); UPS as `UPS N 2000000 2000000`;
//! - MGRS: `19TCG2758891263` (spaces allowed: `19T CG 27588 91263`); a short MGRS names the centre of its
//!   square.
//!
//! ```
//! use vestnav_core::coords::parse_position;
//! let p = parse_position("42°21'26.28\"N 71°06'03.60\"W").unwrap();
//! assert!((p.lat_deg - 42.3573).abs() < 1e-6 && (p.lon_deg + 71.101).abs() < 1e-6);
//! ```

use crate::geo::LatLon;

/// Digits per MGRS coordinate shown for the mouse: 5 is 1 m.
pub const MGRS_DIGITS: i32 = 5;

/// The position in decimal degrees: `42.357300, -71.101000` (6 decimals: 0.1 m).
pub fn format_decimal(p: LatLon) -> String {
    format!("{:.6}, {:.6}", p.lat_deg, p.lon_deg)
}

/// One angle in degrees, minutes and seconds with its hemisphere letter: `42°21'26.28"N`.
///
/// Seconds are rounded to `decimals` first and carried into minutes and degrees, so 59.996" never reads 60".
pub fn format_dms_angle(value_deg: f64, latitude: bool, decimals: usize) -> String {
    let hemisphere = match (latitude, value_deg < 0.0) {
        (true, false) => 'N',
        (true, true) => 'S',
        (false, false) => 'E',
        (false, true) => 'W',
    };
    let scale = 10f64.powi(i32::try_from(decimals).unwrap_or(i32::MAX));
    let total = (value_deg.abs() * 3600.0 * scale).round() as u64;
    let per_min = 60 * scale as u64;
    let (deg, rest) = (total / (60 * per_min), total % (60 * per_min));
    let (min, sec) = (rest / per_min, rest % per_min);
    let sec = sec as f64 / scale;
    let width = if decimals == 0 { 2 } else { decimals + 3 };
    let deg_width = if latitude { 2 } else { 3 };
    format!("{deg:0deg_width$}°{min:02}'{sec:0width$.decimals$}\"{hemisphere}")
}

/// The position in DMS: `42°21'26.28"N 071°06'03.60"W` (seconds to 0.01", about 0.3 m).
pub fn format_dms(p: LatLon) -> String {
    format!("{} {}", format_dms_angle(p.lat_deg, true, 2), format_dms_angle(p.lon_deg, false, 2))
}

/// Latitudes closer to the equator than this are taken as the equator (1e-9° is 0.1 mm): `geoconvert`
/// 1.0.2 panics formatting the MGRS of a point a hair south of the equator.
const EQUATOR_SNAP_DEG: f64 = 1e-9;

fn geoconvert_latlon(p: LatLon) -> Result<geoconvert::LatLon, String> {
    let lon = crate::geo::wrap_deg_180(p.lon_deg);
    let lon = if lon >= 180.0 { lon - 360.0 } else { lon };
    let lat = if p.lat_deg.abs() < EQUATOR_SNAP_DEG { 0.0 } else { p.lat_deg };
    geoconvert::LatLon::create(lat, lon).map_err(|e| e.to_string())
}

/// Runs a `geoconvert` formatting step, turning a panic inside the crate (it asserts on cases its port
/// of `GeographicLib` gets wrong) into an error: the mouse readout must never take the console down.
fn guarded(f: impl FnOnce() -> String + std::panic::UnwindSafe) -> Result<String, String> {
    std::panic::catch_unwind(f).map_err(|_| "not available at this position".to_owned())
}

/// The MGRS latitude band letter of an MGRS string (`None` for UPS, whose strings start with a letter).
fn mgrs_band(mgrs: &str) -> Option<char> {
    let digits = mgrs.chars().take_while(char::is_ascii_digit).count();
    (digits > 0).then(|| mgrs.chars().nth(digits)).flatten()
}

/// The position in UTM, with the MGRS latitude band: `19T 327588 4691263` (metres, rounded); UPS near
/// the poles as `UPS N 2000000 2000000`.
pub fn format_utm(p: LatLon) -> Result<String, String> {
    let ll = geoconvert_latlon(p)?;
    let utm = ll.to_utmups();
    if utm.zone() == 0 {
        let h = if utm.is_north() { 'N' } else { 'S' };
        return Ok(format!("UPS {h} {:.0} {:.0}", utm.easting(), utm.northing()));
    }
    let band = guarded(move || ll.to_mgrs(1).to_string())
        .ok()
        .and_then(|m| mgrs_band(&m))
        .unwrap_or(if utm.is_north() { 'N' } else { 'M' });
    Ok(format!("{}{band} {:.0} {:.0}", utm.zone(), utm.easting().floor(), utm.northing().floor()))
}

/// The position in MGRS with `digits` digits per coordinate (5: 1 m): `19TCG2758891263`.
pub fn format_mgrs(p: LatLon, digits: i32) -> Result<String, String> {
    let ll = geoconvert_latlon(p)?;
    guarded(move || ll.to_mgrs(digits.clamp(1, 5)).to_string())
}

/// Reads one DMS angle (`42°21'26.3"N`, `42 21 26.3 N`, `N42 21 26.3`, `-42 21 26.3`): degrees, optional
/// minutes and seconds, and a hemisphere letter (`N`/`S` for latitude, `E`/`W` for longitude) or a sign.
fn parse_dms_angle(text: &str, latitude: bool) -> Result<f64, String> {
    let t = text.trim();
    let (pos, neg) = if latitude { ('N', 'S') } else { ('E', 'W') };
    let mut sign = 1.0;
    let mut body = t.to_uppercase();
    if let Some(c) = body.chars().next().filter(|c| *c == pos || *c == neg) {
        sign = if c == neg { -1.0 } else { 1.0 };
        body = body[c.len_utf8()..].to_owned();
    } else if let Some(c) = body.chars().last().filter(|c| *c == pos || *c == neg) {
        sign = if c == neg { -1.0 } else { 1.0 };
        body.truncate(body.len() - c.len_utf8());
    }
    let body = body.trim();
    let (body, minus) = match body.strip_prefix('-') {
        Some(b) => (b, true),
        None => (body, false),
    };
    let numbers: Vec<&str> = body
        .split(|c: char| c.is_whitespace() || matches!(c, '°' | '\'' | '"' | 'D' | '′' | '″' | ':'))
        .filter(|s| !s.is_empty())
        .collect();
    if numbers.is_empty() || numbers.len() > 3 {
        return Err(format!("'{t}' is not degrees, minutes and seconds"));
    }
    let mut value = 0.0;
    for (k, n) in numbers.iter().enumerate() {
        let v: f64 = n.replace(',', ".").parse().map_err(|_| format!("'{n}' in '{t}' is not a number"))?;
        if !v.is_finite() || v < 0.0 || (k > 0 && v >= 60.0) {
            return Err(format!("'{n}' in '{t}' is out of range"));
        }
        value += v / 60f64.powi(i32::try_from(k).unwrap_or(i32::MAX));
    }
    if minus {
        sign = -sign;
    }
    let value = sign * value;
    let limit = if latitude { 90.0 } else { 180.0 };
    if value.abs() > limit {
        return Err(format!("'{t}' is beyond {limit}°"));
    }
    Ok(value)
}

/// Splits a DMS pair after the latitude's hemisphere letter (`42°21'N 71°6'W`), or before the
/// longitude's when the letters lead (`N42 21 W71 6`).
fn split_dms_pair(t: &str) -> Option<(&str, &str)> {
    let upper = t.to_uppercase();
    let lon_at = upper.find(['E', 'W'])?;
    let lat_at = upper.find(['N', 'S'])?;
    if lat_at < lon_at {
        // Letters trail ("... N ... W") or lead ("N... W..."): split right after N/S when it trails.
        // Trailing when digits come before the latitude's letter.
        let trailing = upper[..lat_at].chars().any(|c| c.is_ascii_digit());
        let cut = if trailing { lat_at + 1 } else { lon_at };
        return Some((t[..cut].trim(), t[cut..].trim()));
    }
    None
}

/// A UTM/UPS position typed as `19T 327588 4691263`, `19n 327588 4691263` or `UPS N e n`.
fn parse_utm(t: &str) -> Option<Result<LatLon, String>> {
    let parts: Vec<&str> = t.split_whitespace().collect();
    let (zone, northp, e, n) = match parts.as_slice() {
        [ups, h, e, n] if ups.eq_ignore_ascii_case("UPS") => {
            (0, h.eq_ignore_ascii_case("N") || h.eq_ignore_ascii_case("north"), *e, *n)
        }
        [zb, e, n] => {
            let digits = zb.chars().take_while(char::is_ascii_digit).count();
            let (z, letter) = zb.split_at(digits);
            let zone: i32 = z.parse().ok()?;
            let mut chars = letter.chars();
            let (Some(c), None) = (chars.next(), chars.next()) else { return None };
            let northp = match c {
                'n' => true,
                's' => false,
                'C'..='M' if c != 'I' => false,
                'N'..='X' if c != 'O' => true,
                _ => return Some(Err(format!("'{c}' is not a latitude band (C to X) nor n/s"))),
            };
            (zone, northp, *e, *n)
        }
        _ => return None,
    };
    let (Ok(e), Ok(n)) = (e.parse::<f64>(), n.parse::<f64>()) else { return None };
    Some(
        geoconvert::UtmUps::create(zone, northp, e, n)
            .map(|u| u.to_latlon())
            .map(|ll| LatLon::new(ll.latitude(), ll.longitude()))
            .map_err(|err| format!("UTM: {err}")),
    )
}

/// A typed MGRS reference (`19TCG2758891263`, spaces allowed), if the text looks like one.
fn parse_mgrs(t: &str) -> Option<Result<LatLon, String>> {
    let compact: String = t.chars().filter(|c| !c.is_whitespace()).collect::<String>().to_uppercase();
    let digits = compact.chars().take_while(char::is_ascii_digit).count();
    let letters = compact[digits..].chars().take_while(char::is_ascii_alphabetic).count();
    let rest = &compact[digits + letters..];
    // A UTM zone (1-2 digits) or none (UPS), band and 100 km square letters, then easting and northing digits.
    let looks = digits <= 2
        && letters == 3
        && rest.chars().all(|c| c.is_ascii_digit())
        && rest.len().is_multiple_of(2);
    if !looks {
        return None;
    }
    Some(
        geoconvert::Mgrs::parse_str(&compact)
            .map(|m| m.to_latlon())
            .map(|ll| LatLon::new(ll.latitude(), ll.longitude()))
            .map_err(|e| format!("MGRS: {e}")),
    )
}

/// Reads a typed position in decimal degrees, DMS, UTM/UPS or MGRS (see the module doc). Errors say what
/// was expected.
pub fn parse_position(text: &str) -> Result<LatLon, String> {
    let t = text.trim();
    if t.is_empty() {
        return Err("type a position: decimal, DMS, UTM or MGRS".to_owned());
    }
    if let Some(r) = parse_mgrs(t).or_else(|| parse_utm(t)) {
        return r.and_then(|p| p.validated().map_err(|e| e.to_string()));
    }
    // Decimal: two numbers separated by a comma and/or spaces.
    let nums: Vec<&str> =
        t.split(|c: char| c == ',' || c.is_whitespace()).filter(|s| !s.is_empty()).collect();
    if let [a, b] = nums.as_slice()
        && let (Ok(lat), Ok(lon)) =
            (a.trim_end_matches('°').parse::<f64>(), b.trim_end_matches('°').parse::<f64>())
    {
        if !(lat.is_finite() && (-90.0..=90.0).contains(&lat)) {
            return Err(format!("latitude {lat} is outside [-90, 90]"));
        }
        if !(lon.is_finite() && (-180.0..=180.0).contains(&lon)) {
            return Err(format!("longitude {lon} is outside [-180, 180]"));
        }
        return Ok(LatLon::new(lat, lon));
    }
    if let Some((lat, lon)) = split_dms_pair(t) {
        return Ok(LatLon::new(parse_dms_angle(lat, true)?, parse_dms_angle(lon, false)?));
    }
    Err(format!(
        "'{t}' is not a position: type decimal (42.3573, -71.1010), DMS (42°21'26\"N 71°06'04\"W), \
         UTM (19T 327588 4691263) or MGRS (19TCG2758891263)"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use geographiclib_rs::{Geodesic, InverseGeodesic};

    fn utm_numbers(s: &str) -> (String, f64, f64) {
        let p: Vec<&str> = s.split_whitespace().collect();
        (p[0].to_owned(), p[1].parse().unwrap(), p[2].parse().unwrap())
    }

    /// Published examples. The CN Tower, Toronto, 43°38'33.24"N 79°23'13.7"W, "is in UTM zone 17, and the
    /// grid position is 630084 m east, 4833438 m north" (Wikipedia, "Universal Transverse Mercator coordinate
    /// system", section "Locating a position using UTM coordinates"). MGRS from `GeographicLib`'s `GeoConvert`
    /// manual (EXAMPLES): `echo 38SMB4488 | GeoConvert` gives `33.33424 44.40363`, and with `-u` gives
    /// `38n 444500 3688500` (the centre of the 1 km square).
    #[test]
    fn utm_and_mgrs_match_published_examples() {
        let cn = LatLon::new(43.0 + 38.0 / 60.0 + 33.24 / 3600.0, -(79.0 + 23.0 / 60.0 + 13.7 / 3600.0));
        let (zone, e, n) = utm_numbers(&format_utm(cn).unwrap());
        assert_eq!(zone, "17T");
        assert!((e - 630_084.0).abs() <= 1.0, "{e}");
        assert!((n - 4_833_438.0).abs() <= 1.0, "{n}");
        // The MGRS letters of that square by the lettering rules (zone 17 is set 5: columns J-R, rows
        // from A): column 6 -> P, row 48 mod 20 = 8 -> J; 10 m digits truncate 30084 / 33438.
        assert_eq!(format_mgrs(cn, 4).unwrap(), "17TPJ30083343");

        let p = parse_position("38SMB4488").unwrap();
        assert!((p.lat_deg - 33.33424).abs() < 1e-5 && (p.lon_deg - 44.40363).abs() < 1e-5, "{p:?}");
        let q = parse_position("38n 444500 3688500").unwrap();
        assert!((q.lat_deg - 33.33424).abs() < 1e-5 && (q.lon_deg - 44.40363).abs() < 1e-5, "{q:?}");
        assert_eq!(format_mgrs(q, 2).unwrap(), "38SMB4488");
    }

    /// Closed form on the central meridian: easting is exactly 500 000 m and northing is `k0 = 0.9996`
    /// times the meridian arc from the equator (plus 10 000 000 m false northing in the south). The arc is
    /// the geodesic along the meridian, from geographiclib (a different algorithm from the crate's
    /// transverse Mercator). Several zones, both hemispheres.
    #[test]
    fn utm_on_central_meridians_is_k0_times_the_meridian_arc() {
        for (lat, zone) in [(42.0, 19), (-33.9, 56), (10.5, 33), (-70.0, 2), (0.5, 31)] {
            let lon = f64::from(6 * zone - 183);
            let (s12, _, _, _): (f64, f64, f64, f64) = Geodesic::wgs84().inverse(0.0, lon, lat, lon);
            let north = if lat >= 0.0 { 0.9996 * s12 } else { 10_000_000.0 - 0.9996 * s12 };
            let utm = geoconvert_latlon(LatLon::new(lat, lon)).unwrap().to_utmups();
            assert_eq!(utm.zone(), zone);
            assert!((utm.easting() - 500_000.0).abs() < 1e-3, "{lat}: {}", utm.easting());
            assert!((utm.northing() - north).abs() < 1e-3, "{lat}: {} vs {north}", utm.northing());
            // And typed back.
            let text = format!("{}{} 500000 {north}", zone, if lat >= 0.0 { 'n' } else { 's' });
            let back = parse_position(&text).unwrap();
            assert!((back.lat_deg - lat).abs() < 1e-8 && (back.lon_deg - lon).abs() < 1e-8, "{text}");
        }
    }

    /// The zone exceptions of the UTM/MGRS definition (NGA, DMA TM 8358.1): zone 32V is widened west to
    /// 3°E (Norway), and above 72°N zones 31X, 33X, 35X, 37X replace 32X, 34X, 36X (Svalbard: 33X spans
    /// 9°E to 21°E).
    #[test]
    fn norway_and_svalbard_zone_exceptions() {
        assert!(format_utm(LatLon::new(60.0, 4.0)).unwrap().starts_with("32V "));
        assert!(format_utm(LatLon::new(50.0, 4.0)).unwrap().starts_with("31U "));
        assert!(format_utm(LatLon::new(78.0, 10.0)).unwrap().starts_with("33X "));
        assert!(format_utm(LatLon::new(78.0, 8.0)).unwrap().starts_with("31X "));
        assert!(format_utm(LatLon::new(-78.0, 10.0)).unwrap().starts_with("32C "));
        assert!(format_utm(LatLon::new(86.0, 0.0)).unwrap().starts_with("UPS N "));
    }

    /// A hair either side of the equator: band N north, band M south (zone 32 at 10°E), no panic.
    #[test]
    fn the_equator_formats_without_panicking() {
        // geoconvert 1.0.2 asserts on the equator itself: the readout says so instead of panicking.
        for lat in [1e-13, 0.0, -1e-13] {
            let _ = format_mgrs(LatLon::new(lat, 10.0), 5);
            assert!(format_utm(LatLon::new(lat, 10.0)).unwrap().starts_with("32N "));
        }
        assert!(format_mgrs(LatLon::new(-1e-3, 10.0), 5).unwrap().starts_with("32M"));
        assert!(format_utm(LatLon::new(-1e-3, 10.0)).unwrap().starts_with("32M "));
    }

    #[test]
    fn dms_formats_and_round_trips() {
        assert_eq!(format_dms_angle(42.357_3, true, 2), "42°21'26.28\"N");
        assert_eq!(format_dms_angle(-71.101, false, 2), "071°06'03.60\"W");
        // 0.999999° is 59'59.9964": rounds up to 1°00'00.00", never 60".
        assert_eq!(format_dms_angle(0.999_999_9, true, 2), "01°00'00.00\"N");
        for p in [
            LatLon::new(42.357_3, -71.101),
            LatLon::new(-33.868_82, 151.209_29),
            LatLon::new(0.000_1, -0.000_1),
            LatLon::new(-89.999, 179.5),
        ] {
            let back = parse_position(&format_dms(p)).unwrap();
            // 0.01" is 2.8e-6 degrees; rounding is half of that.
            assert!((back.lat_deg - p.lat_deg).abs() < 1.5e-6, "{p:?} -> {back:?}");
            assert!((back.lon_deg - p.lon_deg).abs() < 1.5e-6, "{p:?} -> {back:?}");
        }
        let p = parse_position("N42 21 26.28 W71 6 3.6").unwrap();
        assert_relative_eq!(p.lat_deg, 42.0 + 21.0 / 60.0 + 26.28 / 3600.0, max_relative = 1e-12);
        assert_relative_eq!(p.lon_deg, -(71.0 + 6.0 / 60.0 + 3.6 / 3600.0), max_relative = 1e-12);
        assert!(parse_position("42 61 0 N 71 0 0 W").is_err());
        assert!(parse_position("hello").is_err());
        let d = parse_position("42.3573, -71.1010").unwrap();
        assert_eq!((d.lat_deg, d.lon_deg), (42.3573, -71.1010));
        assert!(parse_position("95, 0").unwrap_err().contains("latitude"));
    }
}
