//! Proprietary sentences (`$P` + a three-letter maker code, NMEA 0183 §5.3): the makers' own, outside the
//! standard, so each is handled as its maker and gpsd document it, and any other is ignored (a checksummed
//! sentence of a known form with nothing we use: neither an error nor a position source).
//! - Garmin `$PGRME,hpe,M,vpe,M,spe,M` (estimated position error, metres): used, as gpsd's `processPGRME`
//!   does, as the receiver's own error estimate; 0.00 (`TomTom` Mk II) means "not computed".
//! - Garmin `$PGRMZ` (altitude in feet, fix dimension) and `$PGRMM` (map datum): gpsd reads them for
//!   altitude and datum; the same epoch's GGA/GSA carry position and mode, so they are ignored here.
//! - Ashtech `$PASHR` and Magellan `$PMGN*` are ignored too. gpsd's `processPASHR` reads Ashtech's
//!   `POS` (a position), `SAT` and `RID` and an `OxTS` attitude form, its `processPMGNST` a fix status; none
//!   of the 30 logs needs them (their receivers also send GGA/RMC), so they are left for later (issue 13).
//! - Our own `$PVNAV,MARK,n,label` (operator marks) and `$PVNAV,TS,unix_ms` (recording timestamps).

use super::{Parsed, Unused, num, uint};

pub(super) fn parse(rest: &str, f: &[&str]) -> Result<Parsed, Unused> {
    match rest {
        // Garmin: $PGRME,hpe,M,vpe,M,spe,M
        // An EPE of 0.00 (`TomTom` Mk II) means "not computed", not a perfect fix.
        "GRME" => Ok(Parsed::Pgrme {
            horizontal_m: num(f.first()).filter(|&v| v > 0.0),
            vertical_m: num(f.get(2)).filter(|&v| v > 0.0),
        }),
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
