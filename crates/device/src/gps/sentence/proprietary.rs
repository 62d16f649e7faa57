//! Proprietary sentences (`$P` + a three-letter maker code, NMEA 0183 §5.3): the makers' own, outside the
//! standard, so each is handled as its maker and gpsd document it, and any other is ignored (a checksummed
//! sentence of a known form with nothing we use: neither an error nor a position source).
//! - Garmin `$PGRME,hpe,M,vpe,M,spe,M` (estimated position error, metres): used, as gpsd's `processPGRME`
//!   does, as the receiver's own error estimate; 0.00 (`TomTom` Mk II) means "not computed".
//! - Garmin `$PGRMZ` (altitude in feet, fix dimension) and `$PGRMM` (map datum): gpsd reads them for
//!   altitude and datum; the same epoch's GGA/GSA carry position and mode, so they are ignored here.
//! - Ashtech `$PASHR,POS,d1,d2,m3,m4,c5,m6,c7,f8,f9,f10,f11,f12,f13,f14,f15,f16,s17` is a whole fix
//!   (Ashtech/Spectra "POS: Position" reference tables, e.g. the Z-Family Technical Reference Manual
//!   Table 6.106 and the `SP90m` manual): solution type (0 autonomous, 1 code differential/SBAS, 2/12 RTK
//!   float, 3/13 RTK fixed, 5 dead reckoning, 9 SBAS; empty = no fix), satellites used, UTC
//!   `hhmmss.ss`, latitude/longitude `ddmm.mmmmmm`, ellipsoidal altitude (not kept: our altitude is above
//!   mean sea level), correction age, course over ground (true), speed (knots), vertical velocity, PDOP,
//!   HDOP, VDOP, TDOP, firmware or station id. As gpsd's `processPASHR`, a present solution type is a 3D
//!   fix. Ashtech's other `$PASHR` forms (SAT, RID, ...) carry nothing we use.
//! - Magellan `$PMGN*` (e.g. `PMGNST`, a fix status) are ignored: Magellan receivers send GGA/RMC/GSA for
//!   the fix itself.
//! - Our own `$PVNAV,MARK,n,label` (operator marks) and `$PVNAV,TS,unix_ms` (recording timestamps).

use super::{MS_PER_KNOT, Parsed, Unused, num, parse_coord, parse_time, uint};
use crate::gps::fix::FixQuality;

pub(super) fn parse(rest: &str, f: &[&str]) -> Result<Parsed, Unused> {
    match rest {
        // Garmin: $PGRME,hpe,M,vpe,M,spe,M
        // An EPE of 0.00 (`TomTom` Mk II) means "not computed", not a perfect fix.
        "GRME" => Ok(Parsed::Pgrme {
            horizontal_m: num(f.first()).filter(|&v| v > 0.0),
            vertical_m: num(f.get(2)).filter(|&v| v > 0.0),
        }),
        "ASHR" if f.first() == Some(&"POS") => ashtech_pos(f),
        "VNAV" => match f.first().copied() {
            Some("MARK") => {
                let number = uint(f.get(1)).ok_or(Unused::Malformed)?;
                let label = f.get(2..).map(|l| l.join(",")).unwrap_or_default();
                Ok(Parsed::Mark { number, label })
            }
            Some("TS") => {
                let unix_ms = f.get(1).and_then(|s| s.parse::<i64>().ok()).ok_or(Unused::Malformed)?;
                Ok(Parsed::Timestamp { unix_ms })
            }
            _ => Err(Unused::Unsupported),
        },
        _ => Ok(Parsed::Ignored),
    }
}

/// `$PASHR,POS,...` (see the module documentation); `f[0]` is `POS`.
fn ashtech_pos(f: &[&str]) -> Result<Parsed, Unused> {
    let time =
        f.get(3).filter(|t| !t.is_empty()).map(|t| parse_time(t).ok_or(Unused::Malformed)).transpose()?;
    let quality = match f.get(1).map(|s| s.trim()) {
        None | Some("") => None,
        Some("0") => Some(FixQuality::Gps),
        Some("1" | "9" | "10") => Some(FixQuality::Dgps),
        Some("2" | "12" | "22") => Some(FixQuality::FloatRtk),
        Some("3" | "13" | "23") => Some(FixQuality::Rtk),
        Some("5") => Some(FixQuality::Estimated),
        Some(_) => return Err(Unused::Malformed),
    };
    let pos = match (parse_coord(f.get(4), f.get(5)), parse_coord(f.get(6), f.get(7))) {
        (Some(lat), Some(lon)) if lat.abs() <= 90.0 && lon.abs() <= 180.0 => Some((lat, lon)),
        (None, None) => None,
        _ => return Err(Unused::Malformed),
    };
    Ok(Parsed::AshtechPos {
        time,
        pos,
        quality,
        sats: uint(f.get(2)),
        course_deg: num(f.get(10)),
        speed_m_s: num(f.get(11)).map(|kn| kn * MS_PER_KNOT),
        pdop: num(f.get(13)),
        hdop: num(f.get(14)),
        vdop: num(f.get(15)),
    })
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;

    use crate::gps::{FixMode, FixQuality, decode_reader};

    /// Spectra's worked example of `$PASHR,POS` (an RTK-fixed position) with its published checksum (the
    /// framer rejects a wrong one, so a mistyped example cannot pass), and an autonomous fix moving at
    /// 0.7 kn on 331° built field by field from the same table.
    #[test]
    fn ashtech_pos_decodes_to_fixes() {
        let moving = "PASHR,POS,0,06,214619.50,3722.385158,N,12159.833768,W,00043.11,,331.0,000.7,000.0,02.7,01.2,\
                      02.4,01.6,UC00";
        let ck = moving.bytes().fold(0u8, |a, b| a ^ b);
        let log = format!(
            "$PASHR,POS,3,10,151858.00,4717.960848,N,00130.499487,W,82.972,,0.0,0.0,-0.0,2.0,1.1,1.7,1.3,G010*49\r\n\
             ${moving}*{ck:02X}\r\n"
        );
        let (fixes, stats) = decode_reader(log.as_bytes()).unwrap();
        assert_eq!(stats.sentences, 2, "{stats}");
        assert_eq!(fixes.len(), 2);
        let a = &fixes[0];
        assert_eq!(a.time_of_day.unwrap().to_string(), "15:18:58");
        assert_relative_eq!(a.lat_deg.unwrap(), 47.0 + 17.960_848 / 60.0, max_relative = 1e-12);
        assert_relative_eq!(a.lon_deg.unwrap(), -(1.0 + 30.499_487 / 60.0), max_relative = 1e-12);
        assert_eq!((a.mode, a.quality, a.sats_used), (Some(FixMode::Fix3D), Some(FixQuality::Rtk), Some(10)));
        assert_eq!((a.pdop, a.hdop, a.vdop), (Some(2.0), Some(1.1), Some(1.7)));
        let b = &fixes[1];
        assert_eq!(b.time_of_day.unwrap().to_string(), "21:46:19.500");
        assert_relative_eq!(b.lat_deg.unwrap(), 37.0 + 22.385_158 / 60.0, max_relative = 1e-12);
        assert_relative_eq!(b.lon_deg.unwrap(), -(121.0 + 59.833_768 / 60.0), max_relative = 1e-12);
        assert_eq!((b.quality, b.sats_used), (Some(FixQuality::Gps), Some(6)));
        assert_relative_eq!(b.course_deg.unwrap(), 331.0);
        assert_relative_eq!(b.speed_m_s.unwrap(), 0.7 * 1852.0 / 3600.0, max_relative = 1e-12);
    }

    /// An empty solution type is no fix (gpsd's reading); a half position is malformed.
    #[test]
    fn ashtech_pos_without_a_solution_is_no_fix() {
        let body = "PASHR,POS,,00,120000.00,,,,,,,,,,,,,,";
        let ck = body.bytes().fold(0u8, |a, b| a ^ b);
        let (fixes, _) = decode_reader(format!("${body}*{ck:02X}\r\n").as_bytes()).unwrap();
        assert_eq!(fixes[0].mode, Some(FixMode::NoFix));
        assert!(!fixes[0].has_position());
        let body = "PASHR,POS,0,05,120001.00,4717.9,N,,,1.0,,0,0,0,1,1,1,1,X";
        let ck = body.bytes().fold(0u8, |a, b| a ^ b);
        let (_, stats) = decode_reader(format!("${body}*{ck:02X}\r\n").as_bytes()).unwrap();
        assert_eq!(stats.malformed, 1);
    }
}
