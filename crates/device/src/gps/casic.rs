//! CASIC binary protocol (`ZhongKeWei` AT6558 / AT6558R, Quectel L76K and other low-cost modules): frames
//! (`BA CE len16le class id payload ck32le`) and the sans-IO decoder of its navigation messages into
//! [`Fix`]es.
//!
//! Everything here follows the "CASIC Multimode Satellite Navigation Receiver Protocol Specification"
//! (Hangzhou Zhongke Microelectronics, V4.2.0.3, 2020-01-06), chapter 2:
//! - frame (2.2): the payload length counts the payload only and is a multiple of 4; the checksum is the
//!   32-bit sum `(id << 24) + (class << 16) + len` plus every payload word read little-endian (receivers
//!   put the id in the high byte, as the framing section's formula says; a table elsewhere in some
//!   editions swaps class and id, which no receiver does);
//! - NAV-PV (0x01 0x03, 80 bytes, 2.7.4): `runTime` U4 0, `posValid` U1 4, `velValid` U1 5, `numSV` U1 7,
//!   `pDop` R4 12, `lon` R8 16, `lat` R8 24 (deg), `height` R4 32 (ellipsoidal), `sepGeoid` R4 36,
//!   `hAcc` R4 40 and `vAcc` R4 44 (variances, m²), `speed2D` R4 64 (m/s), `heading` R4 68 (deg);
//! - NAV-DOP (0x01 0x01, 28 bytes, 2.7.2): `pDop` R4 4, `hDop` R4 8, `vDop` R4 12;
//! - NAV-TIMEUTC (0x01 0x10, 24 bytes, 2.7.5): `year` U2 12, `month` 14, `day` 15, `hour` 16, `min` 17,
//!   `sec` 18, `valid` 19 (bit 0 time of week, bit 1 week number, bit 2 leap seconds valid), `dateValid`
//!   21 (0 invalid, 1 external, 2 one satellite, 3 several);
//! - NAV-GPSINFO / BDSINFO / GLNINFO (0x01 0x20 / 0x21 / 0x22, 8 + 12 n bytes, 2.7.7): `numViewSv` U1 4, then
//!   per satellite from 8: `svid` 1, `flags` 2 (bit 0 used in the solution), `cno` 4, `elev` I1 5,
//!   `azim` I2 6.
//!
//! An epoch is everything with one `runTime` (ms since the receiver started, the same in every NAV message
//! of a solution); it closes when a NAV message with another `runTime` arrives, at the end of the stream
//! or after a quiet gap, and gives a fix when it had a NAV-PV. Position flags (`posValid`, 2.7.1 remark 1): 6 is a 2D fix, 7 3D,
//! 8 GNSS + dead reckoning (3D); 4 dead reckoning alone is an estimated 2D fix; 0-3 and 5 (invalid,
//! external input, rough estimate, last position held, quick mode) are no fix. The satellite lists are
//! receiver state per system, kept until the next list of that system, as GSV is for NMEA.

use std::time::Instant;

use chrono::{DateTime, Utc};

use super::fix::{Constellation, ErrorEstimate, ErrorSource, Fix, FixMode, FixQuality, Satellite};
use super::le::{i1, i2, r4, r8, u1, u2, u4};
use super::ubx::{UbxUnused, nmea_id, utc_from_calendar};

/// Sync bytes.
pub const SYNC: [u8; 2] = [0xBA, 0xCE];
/// First sync byte.
pub const SYNC_1: u8 = SYNC[0];
/// Bytes of a frame around its payload: sync (2), length (2), class, id, checksum (4).
pub const OVERHEAD: usize = 10;

const NAV: u8 = 0x01;

/// The frame checksum: `(id << 24) + (class << 16) + len` plus each little-endian payload word, modulo
/// 2^32. A payload that is not whole words has no valid frame (the framer rejects it first); its last
/// partial word is left out here.
pub fn checksum(class: u8, id: u8, payload: &[u8]) -> u32 {
    let len = u32::try_from(payload.len()).unwrap_or(u32::MAX) & 0xFFFF;
    let head = (u32::from(id) << 24).wrapping_add(u32::from(class) << 16).wrapping_add(len);
    payload
        .chunks_exact(4)
        .fold(head, |sum, w| sum.wrapping_add(u32::from_le_bytes([w[0], w[1], w[2], w[3]])))
}

/// One whole frame for `class`/`id` around `payload`.
///
/// # Panics
/// If the payload is longer than 65,535 bytes or not whole 4-byte words; every message we build fits.
pub fn frame(class: u8, id: u8, payload: &[u8]) -> Vec<u8> {
    assert!(payload.len().is_multiple_of(4), "CASIC payloads are whole 4-byte words");
    let len = u16::try_from(payload.len()).expect("CASIC payload longer than 65,535 bytes");
    let mut out = Vec::with_capacity(payload.len() + OVERHEAD);
    out.extend_from_slice(&SYNC);
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(&[class, id]);
    out.extend_from_slice(payload);
    out.extend_from_slice(&checksum(class, id, payload).to_le_bytes());
    out
}

/// What one epoch (one `runTime`) has said so far.
#[derive(Debug, Clone, Default)]
struct Epoch {
    run_ms: u32,
    /// A NAV-PV arrived.
    pv: bool,
    pos_valid: u8,
    num_sv: Option<u8>,
    pos: Option<(f64, f64)>,
    height_m: Option<f64>,
    sep_m: Option<f64>,
    h_var_m2: Option<f64>,
    v_var_m2: Option<f64>,
    speed_m_s: Option<f64>,
    course_deg: Option<f64>,
    pdop: Option<f64>,
    hdop: Option<f64>,
    vdop: Option<f64>,
    time: Option<DateTime<Utc>>,
}

/// The sans-IO CASIC decoder: one verified frame at a time in, fixes out.
#[derive(Debug, Clone, Default)]
pub(crate) struct CasicDecoder {
    epoch: Option<Epoch>,
    /// The last satellite list of each system (GPS, `BeiDou`, GLONASS).
    sky: [Option<Vec<Satellite>>; 3],
}

impl CasicDecoder {
    /// A decoder with no state.
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// True while an epoch with a NAV-PV is open.
    pub(crate) fn has_open_epoch(&self) -> bool {
        self.epoch.as_ref().is_some_and(|e| e.pv)
    }

    /// One checksum-verified frame. `Ok(Some(fix))` when this message starts the next epoch and the
    /// previous one had a NAV-PV; the fix is not yet validated.
    pub(crate) fn handle(
        &mut self,
        class: u8,
        id: u8,
        payload: &[u8],
        now: Instant,
    ) -> Result<Option<Fix>, UbxUnused> {
        let need = match (class, id) {
            (NAV, 0x00 | 0x03) => 80,
            (NAV, 0x01) => 28,
            (NAV, 0x02) => 72,
            (NAV, 0x10) => 24,
            (NAV, 0x11) => 64,
            (NAV, 0x20..=0x22) => 8,
            _ => return Err(UbxUnused::Unsupported),
        };
        let Some(run_ms) = u4(payload, 0).filter(|_| payload.len() >= need) else {
            return Err(UbxUnused::Malformed);
        };
        let sky = if (0x20..=0x22).contains(&id) { Some(sat_info(id, payload)?) } else { None };
        let mut out = None;
        let second_pv = id == 0x03 && self.epoch.as_ref().is_some_and(|e| e.pv);
        if second_pv || self.epoch.as_ref().is_some_and(|e| e.run_ms != run_ms) {
            out = self.close(now);
        }
        if let Some((system, list)) = sky
            && let Some(slot) = self.sky.get_mut(system)
        {
            *slot = Some(list);
        }
        let e = self.epoch.get_or_insert_with(|| Epoch { run_ms, ..Epoch::default() });
        let applied = match id {
            0x03 => apply_pv(e, payload),
            0x01 => {
                apply_dop(e, payload);
                Some(())
            }
            0x10 => apply_timeutc(e, payload),
            _ => Some(()),
        };
        applied.ok_or(UbxUnused::Malformed)?;
        Ok(out)
    }

    /// End of stream (or a quiet gap): the epoch still being assembled.
    pub(crate) fn finish(&mut self, now: Instant) -> Option<Fix> {
        self.close(now)
    }

    fn close(&mut self, now: Instant) -> Option<Fix> {
        let e = self.epoch.take()?;
        e.pv.then(|| self.build(&e, now))
    }

    fn build(&self, e: &Epoch, now: Instant) -> Fix {
        let mode = match e.pos_valid {
            4 | 6 => FixMode::Fix2D,
            7 | 8 => FixMode::Fix3D,
            _ => FixMode::NoFix,
        };
        let mut fix = Fix {
            time: e.time,
            time_of_day: e.time.map(|t| t.time()),
            mode: Some(mode),
            quality: Some(match (mode, e.pos_valid) {
                (FixMode::NoFix, _) => FixQuality::Invalid,
                (_, 4) => FixQuality::Estimated,
                _ => FixQuality::Gps,
            }),
            received_at: Some(now),
            sats_used: e.num_sv.map(u32::from),
            pdop: e.pdop,
            hdop: e.hdop,
            vdop: e.vdop,
            ..Fix::default()
        };
        if mode != FixMode::NoFix
            && let Some((lat, lon)) = e.pos
        {
            fix.lat_deg = Some(lat);
            fix.lon_deg = Some(lon);
            fix.alt_m = e.height_m.zip(e.sep_m).map(|(h, sep)| h - sep);
            fix.geoid_sep_m = e.sep_m;
            fix.speed_m_s = e.speed_m_s;
            fix.course_deg = e.course_deg;
            // The receiver sends variances: the 1-sigma estimate is their square root (a negative or
            // non-finite variance gives NaN, which `Fix::validate` removes and counts).
            fix.error = e.h_var_m2.map(|h| ErrorEstimate {
                horizontal_m: h.sqrt(),
                vertical_m: e.v_var_m2.map(f64::sqrt),
                source: ErrorSource::Casic,
            });
        }
        if self.sky.iter().any(Option::is_some) {
            fix.set_sky(self.sky.iter().flatten().flatten().copied().collect());
        }
        fix
    }
}

fn f(v: Option<f32>) -> Option<f64> {
    v.map(f64::from)
}

/// NAV-PV: the solution.
fn apply_pv(e: &mut Epoch, p: &[u8]) -> Option<()> {
    e.pv = true;
    e.pos_valid = u1(p, 4)?;
    e.num_sv = Some(u1(p, 7)?);
    e.pdop = e.pdop.or(f(r4(p, 12)));
    e.pos = Some((r8(p, 24)?, r8(p, 16)?));
    e.height_m = f(r4(p, 32));
    e.sep_m = f(r4(p, 36));
    e.h_var_m2 = f(r4(p, 40));
    e.v_var_m2 = f(r4(p, 44));
    e.speed_m_s = f(r4(p, 64));
    e.course_deg = f(r4(p, 68));
    Some(())
}

/// NAV-DOP: position, horizontal and vertical DOP (NAV-DOP's PDOP wins over NAV-PV's, they are the same).
fn apply_dop(e: &mut Epoch, p: &[u8]) {
    e.pdop = f(r4(p, 4));
    e.hdop = f(r4(p, 8));
    e.vdop = f(r4(p, 12));
}

/// NAV-TIMEUTC: UTC when time of week, week number and leap seconds are valid and the date is known.
fn apply_timeutc(e: &mut Epoch, p: &[u8]) -> Option<()> {
    if u1(p, 19)? & 0x07 == 0x07 && u1(p, 21)? != 0 {
        e.time =
            utc_from_calendar(u2(p, 12)?, u1(p, 14)?, u1(p, 15)?, (u1(p, 16)?, u1(p, 17)?, u1(p, 18)?), 0);
    }
    Some(())
}

/// NAV-GPSINFO / BDSINFO / GLNINFO: (system index, satellites). Satellite numbers become gpsd's NMEA-style
/// ids: GPS 1-32, SBAS 120-158 as u-blox's, QZSS 193-199; `BeiDou` 1-63 as 401-463; GLONASS 1-32 as
/// 65-96 (65-96 kept).
fn sat_info(id: u8, p: &[u8]) -> Result<(usize, Vec<Satellite>), UbxUnused> {
    let system = usize::from(id - 0x20);
    let n = usize::from(u1(p, 4).ok_or(UbxUnused::Malformed)?);
    let blocks = p.get(8..).filter(|b| b.len() >= 12 * n).ok_or(UbxUnused::Malformed)?;
    let list = blocks
        .chunks_exact(12)
        .take(n)
        .filter_map(|b| {
            let sv = u1(b, 1)?;
            let (constellation, prn) = match (system, sv) {
                (0, 1..=32) => (Constellation::Gps, u16::from(sv)),
                (0, 120..=158) => nmea_id(1, sv)?,
                (0, 193..=199) => nmea_id(5, sv - 192)?,
                (1, 1..=63) => (Constellation::Beidou, 400 + u16::from(sv)),
                (2, 1..=32) => (Constellation::Glonass, 64 + u16::from(sv)),
                (2, 65..=96) => (Constellation::Glonass, u16::from(sv)),
                _ => return None,
            };
            let (elev, azim, cno) = (i1(b, 5)?, i2(b, 6)?, u1(b, 4)?);
            Some(Satellite::from_binary(
                (constellation, prn),
                i16::from(elev),
                azim,
                cno,
                u1(b, 2)? & 0x01 != 0,
            ))
        })
        .collect();
    Ok((system, list))
}

#[cfg(test)]
mod tests;
