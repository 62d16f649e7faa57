//! UBX navigation messages to epochs to [`Fix`]es, sans IO.
//!
//! Field offsets and scales are those of the u-blox interface descriptions: "u-blox 6 Receiver
//! Description" (GPS.G6-SW-10018) for NAV-POSLLH, NAV-SOL, NAV-STATUS, NAV-VELNED, NAV-TIMEGPS,
//! NAV-TIMEUTC and NAV-SVINFO; "u-blox 8 / u-blox M8 Receiver Description" (UBX-13003221) and the ZED-F9P
//! interface description for NAV-PVT, NAV-SAT, NAV-DOP, NAV-EOE and HNR-PVT.
//!
//! An epoch is everything the receiver says about one navigation solution, tied together by its `iTOW`
//! (GPS time of week of the solution, ms). It closes at NAV-EOE (u-blox 8 and later send it as the last
//! message of the epoch; gpsd ends its report cycle there too), or, for receivers without EOE, when a NAV
//! message with a different `iTOW` arrives (or at [`UbxDecoder::finish`]). An epoch gives a fix only when
//! it had a navigation solution (NAV-PVT, NAV-POSLLH, NAV-SOL or NAV-STATUS); NAV-PVT wins over the
//! older messages when both are sent. HNR-PVT (the M8L's high-rate, sensor-fused solution, up to 30 Hz)
//! is a complete fix on its own and does not touch the NAV epoch.
//!
//! The satellite list (NAV-SAT, else NAV-SVINFO) is receiver state, kept until the next one arrives (the
//! NEO-M8N log sends NAV-SAT every fifth epoch), as GSV is for NMEA.
//!
//! Every read is bounds-checked (a message shorter than its documented length is malformed, never read
//! past its end); plausibility is [`Fix::validate`]'s job in the assembler, as for NMEA.

use std::time::Instant;

use chrono::{DateTime, NaiveDate, TimeDelta, Utc};

use crate::gps::fix::{Constellation, ErrorEstimate, ErrorSource, Fix, FixMode, FixQuality, Satellite};
use crate::gps::gps_time::utc_from_gps_ns;
use crate::gps::le::{i1, i2, i4, u1, u2, u4};
use crate::gps::sirf::{enu_from_ecef_velocity, wgs84_from_ecef};

/// Why a verified frame was not used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum UbxUnused {
    /// A class or message we do not decode (counted, not an error).
    Unsupported,
    /// A message we decode, shorter than its documented length or with impossible contents.
    Malformed,
}

const NAV: u8 = 0x01;
const HNR: u8 = 0x28;

/// UTC from the calendar fields of NAV-PVT, NAV-TIMEUTC and HNR-PVT plus their signed nanosecond
/// correction, rounded to the millisecond (gpsd prints milliseconds; the correction is a few µs).
pub(crate) fn utc_from_calendar(
    year: u16,
    month: u8,
    day: u8,
    hms: (u8, u8, u8),
    nano: i32,
) -> Option<DateTime<Utc>> {
    let date = NaiveDate::from_ymd_opt(i32::from(year), u32::from(month), u32::from(day))?;
    // A leap second (sec = 60) has no place in chrono's `and_hms_opt`: counted as the next second.
    let base = date.and_hms_opt(u32::from(hms.0), u32::from(hms.1), 0)?.and_utc();
    let ms = (i64::from(nano) + 500_000).div_euclid(1_000_000);
    base.checked_add_signed(TimeDelta::seconds(i64::from(hms.2)) + TimeDelta::milliseconds(ms))
}

/// The NMEA-style id gpsd gives a satellite (NMEA 4.0 extended numbering, as gpsd's `ubx2_to_prn`) and
/// its constellation, from the u-blox 8+ `gnssId`/`svId` pair (M8 description, appendix "Satellite
/// Numbering"): GPS 1–32; SBAS 120–151 as 33–64, 152–158 as themselves; Galileo 1–36 as 301–336;
/// `BeiDou` 1–37 as 401–437; IMES 1–10 as 173–182; QZSS 1–7 as 193–199; GLONASS 1–32 as 65–96; `NavIC`
/// 1–14 as themselves. `None` for an unknown system or an id outside its range (GLONASS 255: tracked but
/// not identified yet).
pub(crate) fn nmea_id(gnss_id: u8, sv_id: u8) -> Option<(Constellation, u16)> {
    let sv = u16::from(sv_id);
    Some(match (gnss_id, sv_id) {
        (0, 1..=32) => (Constellation::Gps, sv),
        (1, 120..=151) => (Constellation::Sbas, sv - 87),
        (1, 152..=158) => (Constellation::Sbas, sv),
        (2, 1..=36) => (Constellation::Galileo, sv + 300),
        (3, 1..=37) => (Constellation::Beidou, sv + 400),
        (4, 1..=10) => (Constellation::Unknown, sv + 172),
        (5, 1..=7) => (Constellation::Qzss, sv + 192),
        (6, 1..=32) => (Constellation::Glonass, sv + 64),
        (7, 1..=14) => (Constellation::Navic, sv),
        _ => return None,
    })
}

/// The `gnssId`/`svId` pair of a u-blox 6/7 satellite number (NAV-SVINFO's `svid`; u-blox 7 description,
/// "Satellite Numbering": GPS 1–32, `BeiDou` 33–64 and 159–163, GLONASS 65–96, SBAS 120–158, IMES
/// 173–182, QZSS 193–199, Galileo 211–246).
fn legacy_sv(svid: u8) -> Option<(u8, u8)> {
    Some(match svid {
        1..=32 => (0, svid),
        33..=64 => (3, svid - 27),
        65..=96 => (6, svid - 64),
        120..=158 => (1, svid),
        159..=163 => (3, svid - 158),
        173..=182 => (4, svid - 172),
        193..=199 => (5, svid - 192),
        211..=246 => (2, svid - 210),
        _ => return None,
    })
}

/// Fix mode from a u-blox fix type (NAV-PVT `fixType`, NAV-SOL/NAV-STATUS `gpsFix`, HNR-PVT `gpsFix`):
/// 0 no fix; 1 dead reckoning only and 2 2D as 2D; 3 3D, 4 GNSS + dead reckoning and 5 time only
/// (a surveyed-in position) as 3D, as gpsd does.
fn mode_of(fix_type: u8) -> FixMode {
    match fix_type {
        1 | 2 => FixMode::Fix2D,
        3..=5 => FixMode::Fix3D,
        _ => FixMode::NoFix,
    }
}

/// What one epoch has said so far.
#[derive(Debug, Clone, Default)]
struct Epoch {
    itow_ms: u32,
    /// A navigation solution arrived (NAV-PVT, -POSLLH, -SOL, -STATUS).
    nav: bool,
    pvt: bool,
    time: Option<DateTime<Utc>>,
    /// From NAV-TIMEGPS: UTC computed from week, time of week and valid leap seconds.
    gps_time: Option<DateTime<Utc>>,
    /// NAV-TIMEGPS's leap seconds (GPS - UTC) when it says they are valid.
    leap_s: Option<i8>,
    /// NAV-SOL's GPS time when it says week and time of week are valid: (week, time of week in ns).
    sol_gps: Option<(i16, i64)>,
    fix_type: Option<u8>,
    /// `diffSoln`: differential corrections applied.
    diff: bool,
    /// `carrSoln` (NAV-PVT): 1 float, 2 fixed RTK.
    carrier: u8,
    pos: Option<(f64, f64)>,
    height_m: Option<f64>,
    hmsl_m: Option<f64>,
    h_acc_m: Option<f64>,
    v_acc_m: Option<f64>,
    /// NAV-SOL / NAV-POSECEF: WGS-84 ECEF position [m] and its 3D accuracy estimate `pAcc` [m], used when
    /// no geodetic position (NAV-PVT, NAV-POSLLH) came with the epoch.
    ecef_m: Option<[f64; 3]>,
    p_acc_m: Option<f64>,
    /// NAV-SOL / NAV-VELECEF: ECEF velocity [m/s], for speed and course when NAV-VELNED is absent.
    ecef_vel_m_s: Option<[f64; 3]>,
    speed_m_s: Option<f64>,
    course_deg: Option<f64>,
    num_sv: Option<u8>,
    pdop: Option<f64>,
    hdop: Option<f64>,
    vdop: Option<f64>,
}

/// The sans-IO UBX decoder: one verified frame at a time in, fixes out.
#[derive(Debug, Clone, Default)]
pub(crate) struct UbxDecoder {
    epoch: Option<Epoch>,
    /// The last satellite list (NAV-SAT or NAV-SVINFO).
    sky: Option<Vec<Satellite>>,
    /// The receiver's last valid leap seconds (NAV-TIMEGPS): dates an epoch whose NAV-SOL came without
    /// NAV-TIMEGPS or NAV-TIMEUTC.
    leap_s: Option<i8>,
}

impl UbxDecoder {
    /// A decoder with no state.
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// True while an epoch with a navigation solution is open (it closes at NAV-EOE, at the next
    /// epoch's first message, or at [`Self::finish`]).
    pub(crate) fn has_open_epoch(&self) -> bool {
        self.epoch.as_ref().is_some_and(|e| e.nav)
    }

    /// One checksum-verified frame. `Ok(Some(fix))` when this message completes an epoch (NAV-EOE, a
    /// NAV message of the next epoch, or an HNR-PVT); the fix is not yet validated.
    pub(crate) fn handle(
        &mut self,
        class: u8,
        id: u8,
        payload: &[u8],
        now: Instant,
    ) -> Result<Option<Fix>, UbxUnused> {
        match (class, id) {
            (HNR, 0x00) => return hnr_pvt(payload, now).map(Some),
            (
                NAV,
                0x01 | 0x02 | 0x03 | 0x04 | 0x06 | 0x07 | 0x11 | 0x12 | 0x20 | 0x21 | 0x30 | 0x35 | 0x61,
            ) => {}
            _ => return Err(UbxUnused::Unsupported),
        }
        // Every NAV message starts with iTOW; the length of each is checked before the epoch is touched.
        let need = match id {
            0x02 => 28,
            0x03 | 0x20 => 16,
            0x04 => 18,
            0x06 => 52,
            0x07 => 84,
            0x12 => 36,
            0x01 | 0x11 | 0x21 => 20,
            0x30 | 0x35 => 8,
            _ => 4, // 0x61 EOE
        };
        let Some(itow_ms) = u4(payload, 0).filter(|_| payload.len() >= need) else {
            return Err(UbxUnused::Malformed);
        };
        // Satellite lists: their own length rule (8 bytes + 12 per satellite).
        let sky = match id {
            0x35 => Some(nav_sat(payload)?),
            0x30 => Some(nav_svinfo(payload)?),
            _ => None,
        };
        let mut out = None;
        if self.epoch.as_ref().is_some_and(|e| e.itow_ms != itow_ms) {
            out = self.close(now);
        }
        if let Some(sky) = sky {
            self.sky = Some(sky);
        }
        let e = self.epoch.get_or_insert_with(|| Epoch { itow_ms, ..Epoch::default() });
        let p = payload;
        // The lengths were checked above: a `None` below cannot happen, but is never unwrapped.
        let applied = match id {
            0x07 => apply_pvt(e, p),
            0x02 => apply_posllh(e, p),
            0x06 => apply_sol(e, p),
            0x01 => apply_posecef(e, p),
            0x11 => apply_velecef(e, p),
            0x03 => apply_status(e, p),
            0x04 => apply_dop(e, p),
            0x12 => apply_velned(e, p),
            0x20 => apply_timegps(e, p),
            0x21 => apply_timeutc(e, p),
            0x61 => {
                // End of epoch: this one is complete.
                return Ok(out.or_else(|| self.close(now)));
            }
            _ => Some(()),
        };
        if applied.is_none() {
            return Err(UbxUnused::Malformed);
        }
        Ok(out)
    }

    /// End of stream: an epoch still being assembled.
    pub(crate) fn finish(&mut self, now: Instant) -> Option<Fix> {
        self.close(now)
    }

    fn close(&mut self, now: Instant) -> Option<Fix> {
        let e = self.epoch.take()?;
        self.leap_s = e.leap_s.or(self.leap_s);
        e.nav.then(|| self.build(&e, now))
    }

    fn build(&self, e: &Epoch, now: Instant) -> Fix {
        let from_sol = || {
            let (week, tow_ns) = e.sol_gps?;
            utc_from_gps_ns(week.into(), tow_ns, self.leap_s?.into())
        };
        let time = e.time.or(e.gps_time).or_else(from_sol);
        let mode = e.fix_type.map_or(FixMode::NoFix, mode_of);
        let mut fix = Fix {
            time,
            time_of_day: time.map(|t| t.time()),
            mode: Some(mode),
            received_at: Some(now),
            ..Fix::default()
        };
        fix.quality = Some(match (mode, e.fix_type) {
            (FixMode::NoFix, _) => FixQuality::Invalid,
            (_, Some(1)) => FixQuality::Estimated,
            _ if e.carrier == 2 => FixQuality::Rtk,
            _ if e.carrier == 1 => FixQuality::FloatRtk,
            _ if e.diff => FixQuality::Dgps,
            _ => FixQuality::Gps,
        });
        if mode != FixMode::NoFix
            && let Some((lat, lon)) = e.pos
        {
            fix.lat_deg = Some(lat);
            fix.lon_deg = Some(lon);
            fix.alt_m = e.hmsl_m;
            fix.geoid_sep_m = e.height_m.zip(e.hmsl_m).map(|(h, msl)| h - msl);
            fix.speed_m_s = e.speed_m_s;
            fix.course_deg = e.course_deg;
            // hAcc/vAcc: u-blox's "horizontal/vertical accuracy estimate"; docs/gps.md on its confidence.
            fix.error = e.h_acc_m.map(|h| ErrorEstimate {
                horizontal_m: h,
                vertical_m: e.v_acc_m,
                source: ErrorSource::Ubx,
            });
        } else if mode != FixMode::NoFix
            && let Some((lat, lon, _hae)) = e.ecef_m.and_then(wgs84_from_ecef)
        {
            // Only an ECEF solution (ANTARIS, u-blox 6 and timing receivers sending NAV-SOL without
            // NAV-POSLLH): its geodetic position, as gpsd converts it. No altitude: the fix's is above mean
            // sea level and the receiver sent only the ellipsoidal height (no geoid model here).
            fix.lat_deg = Some(lat.to_degrees());
            fix.lon_deg = Some(lon.to_degrees());
            fix.speed_m_s = e.speed_m_s;
            fix.course_deg = e.course_deg;
            if let (None, Some(v)) = (e.speed_m_s, e.ecef_vel_m_s) {
                let [east, north, _up] = enu_from_ecef_velocity(v, lat, lon);
                fix.speed_m_s = Some(east.hypot(north));
                fix.course_deg = Some(east.atan2(north).to_degrees().rem_euclid(360.0));
            }
            // pAcc is the 3D accuracy estimate: an upper bound of the horizontal one.
            fix.error = e.p_acc_m.map(|p| ErrorEstimate {
                horizontal_m: p,
                vertical_m: None,
                source: ErrorSource::Ubx,
            });
        }
        if mode != FixMode::NoFix && fix.lat_deg.is_none() {
            // A fix type with no position to go with it (NAV-PVT's invalidLlh, an ECEF point that is no
            // place on earth, a NAV-SOL whose stream sends no position): no fix, as for SiRF.
            fix.mode = Some(FixMode::NoFix);
            fix.quality = Some(FixQuality::Invalid);
        }
        fix.sats_used = e.num_sv.map(u32::from);
        fix.pdop = e.pdop;
        fix.hdop = e.hdop;
        fix.vdop = e.vdop;
        if let Some(sky) = &self.sky {
            fix.set_sky(sky.clone());
        }
        fix
    }
}

/// NAV-PVT (0x01 0x07; 92 bytes, 84 on u-blox 7): the whole solution in one message.
fn apply_pvt(e: &mut Epoch, p: &[u8]) -> Option<()> {
    let valid = u1(p, 11)?;
    // validDate (bit 0) and validTime (bit 1) both set.
    if valid & 0x03 == 0x03 {
        e.time = utc_from_calendar(
            u2(p, 4)?,
            u1(p, 6)?,
            u1(p, 7)?,
            (u1(p, 8)?, u1(p, 9)?, u1(p, 10)?),
            i4(p, 16)?,
        );
    }
    let flags = u1(p, 21)?;
    e.pvt = true;
    e.nav = true;
    e.fix_type = Some(u1(p, 20)?);
    e.diff = flags & 0x02 != 0;
    e.carrier = flags >> 6;
    e.num_sv = Some(u1(p, 23)?);
    // flags3 bit 0 (protocol 27+, reserved before): longitude, latitude and heights are invalid.
    let invalid_llh = u1(p, 78).is_some_and(|f| f & 0x01 != 0);
    e.pos = (!invalid_llh).then_some((f64::from(i4(p, 28)?) * 1e-7, f64::from(i4(p, 24)?) * 1e-7));
    e.height_m = Some(f64::from(i4(p, 32)?) * 1e-3);
    e.hmsl_m = Some(f64::from(i4(p, 36)?) * 1e-3);
    e.h_acc_m = Some(f64::from(u4(p, 40)?) * 1e-3);
    e.v_acc_m = Some(f64::from(u4(p, 44)?) * 1e-3);
    e.speed_m_s = Some(f64::from(i4(p, 60)?) * 1e-3);
    e.course_deg = Some(f64::from(i4(p, 64)?) * 1e-5);
    e.pdop = Some(f64::from(u2(p, 76)?) * 0.01);
    Some(())
}

/// NAV-POSLLH (0x01 0x02, 28 bytes): position and accuracy; no fix type (NAV-SOL or NAV-STATUS gives it).
fn apply_posllh(e: &mut Epoch, p: &[u8]) -> Option<()> {
    e.nav = true;
    if e.pvt {
        return Some(());
    }
    e.pos = Some((f64::from(i4(p, 8)?) * 1e-7, f64::from(i4(p, 4)?) * 1e-7));
    e.height_m = Some(f64::from(i4(p, 12)?) * 1e-3);
    e.hmsl_m = Some(f64::from(i4(p, 16)?) * 1e-3);
    e.h_acc_m = Some(f64::from(u4(p, 20)?) * 1e-3);
    e.v_acc_m = Some(f64::from(u4(p, 24)?) * 1e-3);
    Some(())
}

/// NAV-SOL (0x01 0x06, 52 bytes): iTOW 0, fTOW 4, week 8, gpsFix 10, flags 11 (bit 1 diffSoln), ecefX/Y/Z
/// 12/16/20 (I4 cm), pAcc 24 (U4 cm), ecefVX/VY/VZ 28/32/36 (I4 cm/s), sAcc 40, pDOP 44 (x 0.01), numSV
/// 47. The ECEF position is the fix's when no NAV-POSLLH comes with it.
fn apply_sol(e: &mut Epoch, p: &[u8]) -> Option<()> {
    e.nav = true;
    if e.pvt {
        return Some(());
    }
    let flags = u1(p, 11)?;
    e.fix_type = Some(u1(p, 10)?);
    e.diff = flags & 0x02 != 0;
    e.num_sv = Some(u1(p, 47)?);
    e.pdop = e.pdop.or(Some(f64::from(u2(p, 44)?) * 0.01));
    // flags bit 2 WKNSET, bit 3 TOWSET: week and time of week valid.
    if flags & 0x0C == 0x0C {
        e.sol_gps = Some((i2(p, 8)?, i64::from(u4(p, 0)?) * 1_000_000 + i64::from(i4(p, 4)?)));
    }
    e.ecef_m = Some(cm3(p, 12)?);
    e.p_acc_m = Some(f64::from(u4(p, 24)?) * 0.01);
    e.ecef_vel_m_s = Some(cm3(p, 28)?);
    Some(())
}

/// Three I4 centimetre values from `o` as metres.
fn cm3(p: &[u8], o: usize) -> Option<[f64; 3]> {
    Some([f64::from(i4(p, o)?) * 0.01, f64::from(i4(p, o + 4)?) * 0.01, f64::from(i4(p, o + 8)?) * 0.01])
}

/// NAV-POSECEF (0x01 0x01, 20 bytes): ecefX/Y/Z 4/8/12 (I4 cm), pAcc 16 (U4 cm).
fn apply_posecef(e: &mut Epoch, p: &[u8]) -> Option<()> {
    e.nav = true;
    if !e.pvt {
        e.ecef_m = Some(cm3(p, 4)?);
        e.p_acc_m = Some(f64::from(u4(p, 16)?) * 0.01);
    }
    Some(())
}

/// NAV-VELECEF (0x01 0x11, 20 bytes): ecefVX/VY/VZ 4/8/12 (I4 cm/s), sAcc 16.
fn apply_velecef(e: &mut Epoch, p: &[u8]) -> Option<()> {
    if !e.pvt {
        e.ecef_vel_m_s = Some(cm3(p, 4)?);
    }
    Some(())
}

/// NAV-STATUS (0x01 0x03, 16 bytes): fix type when neither NAV-PVT nor NAV-SOL said it.
fn apply_status(e: &mut Epoch, p: &[u8]) -> Option<()> {
    e.nav = true;
    if e.fix_type.is_none() {
        e.fix_type = Some(u1(p, 4)?);
        e.diff = u1(p, 5)? & 0x02 != 0;
    }
    Some(())
}

/// NAV-DOP (0x01 0x04, 18 bytes): gDOP 4, pDOP 6, tDOP 8, vDOP 10, hDOP 12, nDOP 14, eDOP 16 (x 0.01).
/// 99.99 is u-blox's "unknown", left for [`Fix::validate`]'s bound.
fn apply_dop(e: &mut Epoch, p: &[u8]) -> Option<()> {
    e.pdop = Some(f64::from(u2(p, 6)?) * 0.01);
    e.vdop = Some(f64::from(u2(p, 10)?) * 0.01);
    e.hdop = Some(f64::from(u2(p, 12)?) * 0.01);
    Some(())
}

/// NAV-VELNED (0x01 0x12, 36 bytes): ground speed (cm/s) and heading of motion (1e-5 deg).
fn apply_velned(e: &mut Epoch, p: &[u8]) -> Option<()> {
    if !e.pvt {
        e.speed_m_s = Some(f64::from(u4(p, 20)?) * 0.01);
        e.course_deg = Some(f64::from(i4(p, 24)?) * 1e-5);
    }
    Some(())
}

/// NAV-TIMEGPS (0x01 0x20, 16 bytes): UTC = GPS epoch + week + iTOW + fTOW - leap seconds, used when
/// towValid, weekValid and leapSValid (bits 0-2) are all set; the leap seconds alone when leapSValid is.
fn apply_timegps(e: &mut Epoch, p: &[u8]) -> Option<()> {
    let (itow, ftow, week, leap, valid) = (u4(p, 0)?, i4(p, 4)?, i2(p, 8)?, i1(p, 10)?, u1(p, 11)?);
    if valid & 0x04 != 0 {
        e.leap_s = Some(leap);
    }
    if valid & 0x07 == 0x07 {
        e.gps_time = utc_from_gps_ns(week.into(), i64::from(itow) * 1_000_000 + i64::from(ftow), leap.into());
    }
    Some(())
}

/// NAV-TIMEUTC (0x01 0x21, 20 bytes): UTC when validUTC (bit 2) is set.
fn apply_timeutc(e: &mut Epoch, p: &[u8]) -> Option<()> {
    if u1(p, 19)? & 0x04 != 0 && e.time.is_none() {
        e.time = utc_from_calendar(
            u2(p, 12)?,
            u1(p, 14)?,
            u1(p, 15)?,
            (u1(p, 16)?, u1(p, 17)?, u1(p, 18)?),
            i4(p, 8)?,
        );
    }
    Some(())
}

/// One satellite: elevation (deg, I1), azimuth (deg, I2), C/N0 (dBHz, U1; 0 = not tracked).
fn satellite(id: (Constellation, u16), elev: i8, azim: i16, cno: u8, used: bool) -> Satellite {
    Satellite::from_binary(id, i16::from(elev), azim, cno, used)
}

/// NAV-SAT (0x01 0x35): `numSvs` at 5, then 12 bytes per satellite from 8: gnssId 0, svId 1, cno 2,
/// elev 3, azim 4, flags 8 (bit 3 svUsed).
fn nav_sat(p: &[u8]) -> Result<Vec<Satellite>, UbxUnused> {
    let n = usize::from(u1(p, 5).ok_or(UbxUnused::Malformed)?);
    let blocks = p.get(8..).filter(|b| b.len() >= 12 * n).ok_or(UbxUnused::Malformed)?;
    Ok(blocks
        .chunks_exact(12)
        .take(n)
        .filter_map(|b| {
            let id = nmea_id(u1(b, 0)?, u1(b, 1)?)?;
            Some(satellite(id, i1(b, 3)?, i2(b, 4)?, u1(b, 2)?, u4(b, 8)? & 0x08 != 0))
        })
        .collect())
}

/// NAV-SVINFO (0x01 0x30): `numCh` at 4, then 12 bytes per channel from 8: svid 1, flags 2 (bit 0
/// svUsed), cno 4, elev 5, azim 6.
fn nav_svinfo(p: &[u8]) -> Result<Vec<Satellite>, UbxUnused> {
    let n = usize::from(u1(p, 4).ok_or(UbxUnused::Malformed)?);
    let blocks = p.get(8..).filter(|b| b.len() >= 12 * n).ok_or(UbxUnused::Malformed)?;
    Ok(blocks
        .chunks_exact(12)
        .take(n)
        .filter_map(|b| {
            let (gnss, sv) = legacy_sv(u1(b, 1)?)?;
            let id = nmea_id(gnss, sv)?;
            Some(satellite(id, i1(b, 5)?, i2(b, 6)?, u1(b, 4)?, u1(b, 2)? & 0x01 != 0))
        })
        .collect())
}

/// HNR-PVT (0x28 0x00, 72 bytes): a complete high-rate fix on its own. iTOW 0, year 4, month 6, day 7,
/// hour 8, min 9, sec 10, valid 11 (validDate, validTime), nano 12, gpsFix 16, flags 17 (bit 0
/// gpsFixOK, bit 1 diffSoln), lon 20, lat 24, height 28, hMSL 32, gSpeed 36, headMot 44, hAcc 52, vAcc 56.
fn hnr_pvt(p: &[u8], now: Instant) -> Result<Fix, UbxUnused> {
    if p.len() < 72 {
        return Err(UbxUnused::Malformed);
    }
    let mut e = Epoch { nav: true, pvt: true, ..Epoch::default() };
    let parsed = (|| {
        if u1(p, 11)? & 0x03 == 0x03 {
            e.time = utc_from_calendar(
                u2(p, 4)?,
                u1(p, 6)?,
                u1(p, 7)?,
                (u1(p, 8)?, u1(p, 9)?, u1(p, 10)?),
                i4(p, 12)?,
            );
        }
        e.fix_type = Some(u1(p, 16)?);
        e.diff = u1(p, 17)? & 0x02 != 0;
        e.pos = Some((f64::from(i4(p, 24)?) * 1e-7, f64::from(i4(p, 20)?) * 1e-7));
        e.height_m = Some(f64::from(i4(p, 28)?) * 1e-3);
        e.hmsl_m = Some(f64::from(i4(p, 32)?) * 1e-3);
        e.speed_m_s = Some(f64::from(i4(p, 36)?) * 1e-3);
        e.course_deg = Some(f64::from(i4(p, 44)?) * 1e-5);
        e.h_acc_m = Some(f64::from(u4(p, 52)?) * 1e-3);
        e.v_acc_m = Some(f64::from(u4(p, 56)?) * 1e-3);
        Some(())
    })();
    parsed.ok_or(UbxUnused::Malformed)?;
    // The high-rate fix carries no satellites or DOPs: those belong to the NAV epoch.
    Ok(UbxDecoder::default().build(&e, now))
}
