//! `SkyTraq` Venus binary protocol (Venus 6 / Venus 8 receivers, e.g. the Venus838): frames
//! (`A0 A1 len16be payload cs 0D 0A`) and the sans-IO decoder of its navigation messages into [`Fix`]es.
//!
//! The layouts are those of `SkyTraq`'s binary message application notes (AN0003 for the Venus 6 GPS
//! receiver; AN0028 and AN0037 "Binary Messages of `SkyTraq` Venus 8 GNSS Receiver"; the 0xDC–0xDF
//! raw-measurement output as the Venus 8 notes give it), checked against gpsd's two captures of them
//! (`tests/data/gpsd-logs-more/skytraq-*.log`, whose every position decodes to gpsd's reading):
//! - frame: start `A0 A1`, the payload length (big-endian, counting the payload only), the payload whose
//!   first byte is the message id, the checksum (XOR of every payload byte), end `0D 0A`. All fields are
//!   big-endian; offsets below count from the message id (offset 0);
//! - 0xA8 Navigation Data Message (59 bytes): fix mode U1 1 (0 no fix, 1 2D, 2 3D, 3 3D + DGNSS), SVs in
//!   the fix U1 2, GNSS week U2 3, time of week U4 5 (0.01 s), latitude I4 9 and longitude I4 13 (1e-7
//!   deg), ellipsoid altitude I4 17 and mean-sea-level altitude I4 21 (cm), GDOP, PDOP, HDOP, VDOP, TDOP U2
//!   25–33 (0.01), ECEF X/Y/Z I4 35–43 (cm), ECEF velocity I4 47–55 (cm/s);
//! - 0xDF Navigation Data of the raw-measurement output (81 bytes): issue of data U1 1, navigation state U1
//!   2 (0 no fix, 1 fix prediction, 2 2D, 3 3D, 4 3D + DGNSS), GNSS week U2 3, time of week R8 5 (s), ECEF
//!   X/Y/Z R8 13/21/29 (m), ECEF velocity R4 37/41/45 (m/s), clock bias R8 49, clock drift R4 57, GDOP,
//!   PDOP, HDOP, VDOP, TDOP R4 61–77;
//! - 0xDE SV and channel status (3 + 10 n bytes): issue of data U1 1, number of SVs U1 2, then per SV from
//!   3: channel U1 0, PRN U1 1, SV status U1 2, URA U1 3, C/N0 U1 4 (dB-Hz), elevation I2 5, azimuth I2 7
//!   (deg), channel status U1 9 (0x10 used in the normal fix, 0x20 used in the differential fix).
//!
//! Each 0xA8 and each 0xDF is a whole solution, so it gives its fix at once (no epoch is held open). A
//! 0xDF takes the satellites of the 0xDE with its issue of data (the receiver sends it just before). A
//! "fix prediction" is no fix (the receiver propagating its last solution, not a measurement; gpsd reads
//! it so too). Neither message says GPS − UTC: UTC is the GPS time less the leap seconds in force at that
//! time (`gps_time::utc_from_gps_by_history`). Other messages (0xDC measurement time, 0xDD raw
//! measurements, 0xE0–0xE3 subframes, replies to commands) carry no position: counted, not used.

use std::time::Instant;

use super::fix::{Constellation, Fix, FixMode, FixQuality, Satellite};
use super::gps_time::utc_from_gps_by_history;
use super::sirf::{enu_from_ecef_velocity, wgs84_from_ecef};
use super::ubx::{UbxUnused, nmea_id};

/// Start sequence.
pub const START: [u8; 2] = [0xA0, 0xA1];
/// End sequence.
pub const END: [u8; 2] = [0x0D, 0x0A];
/// Bytes of a frame around its payload: start (2), length (2), checksum (1), end (2).
pub const OVERHEAD: usize = 7;

/// Navigation Data Message (Venus 6 and 8).
const NAV_DATA: u8 = 0xA8;
/// SV and channel status (Venus 8 raw-measurement output).
const SV_STATUS: u8 = 0xDE;
/// Navigation data (Venus 8 raw-measurement output).
const NAV_RAW: u8 = 0xDF;

/// The frame checksum: XOR of every payload byte.
pub fn checksum(payload: &[u8]) -> u8 {
    payload.iter().fold(0, |acc, &b| acc ^ b)
}

/// One whole frame around `payload` (message id first).
///
/// # Panics
/// If the payload is longer than 65,535 bytes; every message we build is far shorter.
pub fn frame(payload: &[u8]) -> Vec<u8> {
    let len = u16::try_from(payload.len()).expect("SkyTraq payload longer than 65,535 bytes");
    let mut out = Vec::with_capacity(payload.len() + OVERHEAD);
    out.extend_from_slice(&START);
    out.extend_from_slice(&len.to_be_bytes());
    out.extend_from_slice(payload);
    out.push(checksum(payload));
    out.extend_from_slice(&END);
    out
}

/// Big-endian field readers: `None` past the end of the payload.
fn be<const N: usize>(p: &[u8], at: usize) -> Option<[u8; N]> {
    p.get(at..at + N)?.try_into().ok()
}
fn u1(p: &[u8], at: usize) -> Option<u8> {
    p.get(at).copied()
}
fn u2(p: &[u8], at: usize) -> Option<u16> {
    be(p, at).map(u16::from_be_bytes)
}
fn i2(p: &[u8], at: usize) -> Option<i16> {
    be(p, at).map(i16::from_be_bytes)
}
fn u4(p: &[u8], at: usize) -> Option<u32> {
    be(p, at).map(u32::from_be_bytes)
}
fn i4(p: &[u8], at: usize) -> Option<i32> {
    be(p, at).map(i32::from_be_bytes)
}
fn r4(p: &[u8], at: usize) -> Option<f64> {
    be(p, at).map(|b| f64::from(f32::from_be_bytes(b)))
}
fn r8(p: &[u8], at: usize) -> Option<f64> {
    be(p, at).map(f64::from_be_bytes)
}

/// The sans-IO `SkyTraq` decoder: one verified frame's payload at a time in, fixes out.
#[derive(Debug, Clone, Default)]
pub(crate) struct SkyTraqDecoder {
    /// The last 0xDE not yet taken by its 0xDF: its issue of data and satellites.
    sky: Option<(u8, Vec<Satellite>)>,
}

impl SkyTraqDecoder {
    /// A decoder with no state.
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// One checksum-verified payload (message id first). `Ok(Some(fix))` for a navigation message; the fix
    /// is not yet validated.
    pub(crate) fn handle(&mut self, payload: &[u8], now: Instant) -> Result<Option<Fix>, UbxUnused> {
        let (id, need) = match payload.first() {
            Some(&NAV_DATA) => (NAV_DATA, 59),
            Some(&NAV_RAW) => (NAV_RAW, 81),
            Some(&SV_STATUS) => (SV_STATUS, 3),
            _ => return Err(UbxUnused::Unsupported),
        };
        if payload.len() < need {
            return Err(UbxUnused::Malformed);
        }
        let fix = match id {
            NAV_DATA => nav_data(payload),
            NAV_RAW => self.nav_raw(payload),
            _ => {
                self.sky = Some(sv_status(payload).ok_or(UbxUnused::Malformed)?);
                return Ok(None);
            }
        };
        let mut fix = fix.ok_or(UbxUnused::Malformed)?;
        fix.received_at = Some(now);
        Ok(Some(fix))
    }

    /// 0xDF: the ECEF solution, with the satellites of the 0xDE of the same issue of data (each 0xDE is
    /// taken once: a stream that stops sending it gives no stale sky 256 solutions later).
    fn nav_raw(&mut self, p: &[u8]) -> Option<Fix> {
        let (mode, quality) = match u1(p, 2)? {
            2 => (FixMode::Fix2D, FixQuality::Gps),
            3 => (FixMode::Fix3D, FixQuality::Gps),
            4 => (FixMode::Fix3D, FixQuality::Dgps),
            _ => (FixMode::NoFix, FixQuality::Invalid),
        };
        let tow_s = r8(p, 5)?;
        let mut fix = solution(mode, quality, u2(p, 3)?, tow_s * 1000.0);
        fix.pdop = r4(p, 65);
        fix.hdop = r4(p, 69);
        fix.vdop = r4(p, 73);
        if let Some((iod, sats)) = self.sky.take()
            && Some(iod) == u1(p, 1)
        {
            fix.sats_used = u32::try_from(sats.iter().filter(|s| s.used).count()).ok();
            fix.set_sky(sats);
        }
        if mode != FixMode::NoFix {
            let ecef = [r8(p, 13)?, r8(p, 21)?, r8(p, 29)?];
            let velocity = [r4(p, 37)?, r4(p, 41)?, r4(p, 45)?];
            // No altitude: the fix's is above mean sea level, the message gives only the ECEF point (as
            // UBX NAV-SOL alone).
            set_position(&mut fix, ecef, velocity);
        }
        Some(fix)
    }
}

/// A fix with the mode, quality and time of a solution at GPS `week` and time of week `tow_ms`.
fn solution(mode: FixMode, quality: FixQuality, week: u16, tow_ms: f64) -> Fix {
    // Milliseconds: the receivers send the time of week in 0.01 s (0xA8) or as a double whose last
    // digits are the receiver's clock offset (0xDF: 444956.999088...); the fix keeps the millisecond.
    let time = tow_ms
        .is_finite()
        .then(|| tow_ms.round())
        .filter(|ms| (0.0..7.0 * 86_400_000.0).contains(ms))
        .and_then(|ms| utc_from_gps_by_history(u32::from(week), ms as i64));
    Fix {
        time,
        time_of_day: time.map(|t| t.time()),
        mode: Some(mode),
        quality: Some(quality),
        ..Fix::default()
    }
}

/// The geodetic position of an ECEF point [m] and the speed and course of an ECEF velocity [m/s]; an ECEF
/// point that is no place on earth makes the fix a no fix.
fn set_position(fix: &mut Fix, ecef_m: [f64; 3], velocity_m_s: [f64; 3]) {
    let Some((lat, lon, _hae)) = wgs84_from_ecef(ecef_m) else {
        fix.mode = Some(FixMode::NoFix);
        fix.quality = Some(FixQuality::Invalid);
        return;
    };
    fix.lat_deg = Some(lat.to_degrees());
    fix.lon_deg = Some(lon.to_degrees());
    set_velocity(fix, velocity_m_s, lat, lon);
}

/// Speed over ground and course from an ECEF velocity at latitude/longitude [rad].
fn set_velocity(fix: &mut Fix, velocity_m_s: [f64; 3], lat: f64, lon: f64) {
    let [east, north, _up] = enu_from_ecef_velocity(velocity_m_s, lat, lon);
    fix.speed_m_s = Some(east.hypot(north));
    fix.course_deg = Some(east.atan2(north).to_degrees().rem_euclid(360.0));
}

/// 0xA8: the solution in geodetic and ECEF form. The position is the message's latitude/longitude (1e-7
/// deg, exact); the ECEF velocity gives speed and course; the altitudes only in a 3D fix (a 2D fix's is
/// held, not measured).
fn nav_data(p: &[u8]) -> Option<Fix> {
    let (mode, quality) = match u1(p, 1)? {
        1 => (FixMode::Fix2D, FixQuality::Gps),
        2 => (FixMode::Fix3D, FixQuality::Gps),
        3 => (FixMode::Fix3D, FixQuality::Dgps),
        _ => (FixMode::NoFix, FixQuality::Invalid),
    };
    let mut fix = solution(mode, quality, u2(p, 3)?, f64::from(u4(p, 5)?) * 10.0);
    fix.sats_used = Some(u32::from(u1(p, 2)?));
    let dop = |at| u2(p, at).map(|d| f64::from(d) / 100.0);
    fix.pdop = dop(27);
    fix.hdop = dop(29);
    fix.vdop = dop(31);
    if mode != FixMode::NoFix {
        let lat = f64::from(i4(p, 9)?) / 1e7;
        let lon = f64::from(i4(p, 13)?) / 1e7;
        fix.lat_deg = Some(lat);
        fix.lon_deg = Some(lon);
        let cm = |at| i4(p, at).map(|v| f64::from(v) / 100.0);
        set_velocity(&mut fix, [cm(47)?, cm(51)?, cm(55)?], lat.to_radians(), lon.to_radians());
        if mode == FixMode::Fix3D {
            let (hae, msl) = (cm(17)?, cm(21)?);
            fix.alt_m = Some(msl);
            fix.geoid_sep_m = Some(hae - msl);
        }
    }
    Some(fix)
}

/// 0xDE: (issue of data, satellites). PRNs become gpsd's NMEA-style ids: GPS 1–32, SBAS 33–64 and
/// 120–158 (as u-blox's), GLONASS 65–96, QZSS 193–199, `BeiDou` 201–255 as 401–455 (the Venus 8's `BeiDou`
/// numbering); PRN 0 (an idle channel) and other numbers are left out.
fn sv_status(p: &[u8]) -> Option<(u8, Vec<Satellite>)> {
    let iod = u1(p, 1)?;
    let n = usize::from(u1(p, 2)?);
    let blocks = p.get(3..).filter(|b| b.len() >= 10 * n)?;
    let sats = blocks
        .chunks_exact(10)
        .take(n)
        .filter_map(|b| {
            let prn = u1(b, 1)?;
            let (constellation, id) = match prn {
                1..=32 => (Constellation::Gps, u16::from(prn)),
                33..=64 => (Constellation::Sbas, u16::from(prn)),
                65..=96 => (Constellation::Glonass, u16::from(prn)),
                120..=158 => nmea_id(1, prn)?,
                193..=199 => nmea_id(5, prn - 192)?,
                201..=255 => (Constellation::Beidou, 200 + u16::from(prn)),
                _ => return None,
            };
            let (cno, elev, azim) = (u1(b, 4)?, i2(b, 5)?, i2(b, 7)?);
            Some(Satellite::from_binary((constellation, id), elev, azim, cno, u1(b, 9)? & 0x30 != 0))
        })
        .collect();
    Some((iod, sats))
}

#[cfg(test)]
mod tests;
