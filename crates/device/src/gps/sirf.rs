//! `SiRF` binary protocol: frames (`A0 A2 len16be payload ck16be B0 B3`).
//!
//! The layout and checksum are those of the "`SiRF` Binary Protocol Reference Manual" (`SiRF` Technology,
//! rev. 2.4, 2008), chapter 1 "Protocol Layers": the payload length has 15 bits, the checksum is the sum of
//! the payload bytes modulo 2^15, both big-endian; the payload starts with the message id (MID).
//!
//! `SirfDecoder` turns checksum-verified payloads into [`Fix`]es by the field tables of the manual's
//! chapter 2 "Output Messages" (MID 2 Measured Navigation Data Out, MID 4 Measured Tracker Data Out,
//! MID 41 Geodetic Navigation Data; see its doc for how a second's messages make one epoch), MID 67 SID 1
//! GNSS Navigation Solution of the `SiRFstarV` ("`SiRFstarV` OSP Extensions", CS-303979-SP-9) and MID 98
//! Extended Measured Navigation Data of u-blox receivers with `SiRF`-derived firmware (u-blox TIM,
//! "Firmware Release 2.1 UBX 1.0"). The framer (`framing`) finds the frames and checks their checksums.

use std::time::Instant;

use chrono::{DateTime, NaiveDate, Utc};

use super::gps_time::{GPS_EPOCH_UNIX_S, GPS_UTC_OFFSET_S, WEEK_MS, WEEK_S, utc_from_gps};
use super::{Constellation, ErrorEstimate, ErrorSource, Fix, FixMode, FixQuality, Satellite};

/// Start sequence.
pub const START: [u8; 2] = [0xA0, 0xA2];
/// End sequence.
pub const END: [u8; 2] = [0xB0, 0xB3];
/// Bytes of a frame around its payload: start (2), length (2), checksum (2), end (2).
pub const OVERHEAD: usize = 8;
/// Longest payload the 15-bit length field can carry.
pub const MAX_PAYLOAD: usize = 0x7FFF;

/// The 15-bit checksum of a payload.
pub fn checksum(payload: &[u8]) -> u16 {
    payload.iter().fold(0u16, |sum, &b| sum.wrapping_add(u16::from(b)) & 0x7FFF)
}

/// One whole frame around `payload` (MID first).
///
/// # Panics
/// If the payload is longer than [`MAX_PAYLOAD`]; every message we build is far shorter.
pub fn frame(payload: &[u8]) -> Vec<u8> {
    assert!(payload.len() <= MAX_PAYLOAD, "SiRF payload longer than 32,767 bytes");
    let len = u16::try_from(payload.len()).expect("checked above");
    let mut out = Vec::with_capacity(payload.len() + OVERHEAD);
    out.extend_from_slice(&START);
    out.extend_from_slice(&len.to_be_bytes());
    out.extend_from_slice(payload);
    out.extend_from_slice(&checksum(payload).to_be_bytes());
    out.extend_from_slice(&END);
    out
}

// ---------------------------------------------------------------------------------------------------------
// Decoding
// ---------------------------------------------------------------------------------------------------------

/// The week a 10-bit GPS week number (MID 2, MID 4) is counted from when no extended week has been seen:
/// the rollover of 2019-04-07 (week 2048), so the window is 2019-04-07 .. 2039-11-20.
const PIVOT_WEEK: u32 = 2048;
/// Two solution messages whose times of week differ by less than this [ms] belong to one navigation
/// solution. MID 2 truncates its time to 10 ms, MID 41 sends milliseconds; `SiRF` receivers compute at most
/// 5 solutions a second, 200 ms apart.
const SAME_EPOCH_MS: i64 = 50;

/// Why a checksum-verified payload produced nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SirfUnused {
    /// A message id this decoder does not know.
    Unsupported,
    /// A known message id whose payload is too short for its layout (or has no message id at all).
    Malformed,
}

/// Decodes `SiRF` binary payloads into one [`Fix`] per navigation solution (sans-IO).
///
/// # Epochs
/// The manual's output cycle (chapter 2, "Output Messages"; MID 166 sets each message's rate) sends, once
/// per navigation solution, MID 2 (Measured Navigation Data) and, from firmware 2.3.2 on, MID 41
/// (Geodetic Navigation Data), both stamped with the solution's GPS time of week, plus MID 4 (Measured
/// Tracker Data, the satellites) and status messages. The decoder groups MID 2 and MID 41 by time of week
/// (within [`SAME_EPOCH_MS`]): an epoch closes when a solution message of another time arrives (or a
/// second one of the same type), or — once one epoch has shown which solution messages this receiver
/// sends — as soon as all of them are in, so a live fix is not held back until the next second. MID 4 is
/// receiver state like NMEA's GSV: the latest one goes with every fix.
///
/// # Which message says what (and how this follows gpsd)
/// gpsd's `sirf` driver builds its fixes from MID 2 alone and ignores MID 41 (firmware before 2.3.2 filled
/// it badly, its comment says). The decoder does the same for what both carry, so its fixes match gpsd's:
/// - position: MID 2's ECEF metres, converted by [`wgs84_from_ecef`] (MID 41's latitude/longitude only
///   when an epoch has no MID 2);
/// - time: MID 2's GPS week and time of week (10 ms) minus GPS−UTC ([`GPS_UTC_OFFSET_S`] or the
///   receiver's own value if larger); MID 41's extended week resolves MID 2's 10-bit week;
/// - mode and quality: MID 2's mode 1 (the same bits as the low byte of MID 41's nav type);
/// - from MID 41 only: altitude above MSL and the geoid separation, speed and course (MID 2's ECEF velocity
///   without it), EHPE/EVPE as the error estimate (the DOP model without it).
///
/// # `SiRFstarV`: MID 67 SID 1
/// The `SiRFstarV` replaces MID 41 by MID 67 SID 1 (GNSS Navigation Solution), stamped with the same
/// time of week as MID 2 (milliseconds plus nanoseconds). When an epoch has a valid one (its solution
/// validity word is 0), it gives the position (latitude/longitude ×10^7, where MID 2 has whole ECEF
/// metres), the mode (solution info bits 0–2, MID 2's mode-1 values), altitudes, speed and course (unless
/// solution info bit 12 says the velocity is invalid), EHPE/EVPE, HDOP/PDOP/VDOP and the satellites in
/// the solution; MID 2 still gives the time when the epoch has one (10 ms resolution, where MID 67 has
/// nanoseconds: gpsd's last report of each second carries MID 2's time with MID 67's position).
/// A `SiRFstarV` also sends MID 41, which carries the *next* solution's time and position ahead of its
/// MID 2 (gpsd's `sirfstarv.log`): grouped by time of week, it joins the epoch it describes.
///
/// # u-blox with `SiRF` firmware: MID 98
/// A u-blox receiver running `SiRF`-derived firmware sends MID 98 (Extended Measured Navigation Data) after
/// each MID 2: latitude, longitude and course in radians ×10^8, HAE altitude, speed and climb in
/// millimetres, the MID 2 nav-type bits, the receiver's UTC date and time (valid when nav type bit 6 is
/// set) and GDOP/PDOP/HDOP/VDOP/TDOP ×5. From the first MID 98 on, each MID 98 is a whole epoch and MID 2
/// only supplies the satellites used (as gpsd, which skips MID 2 once it has seen MID 98). MID 98 has no
/// altitude above MSL and no geoid separation, so its fixes carry no altitude.
///
/// Before the receiver's first fix its clock is a firmware default (2004 in gpsd's `sirf2.log`): no-fix
/// epochs before the first fix carry no time.
#[derive(Debug, Default)]
pub(crate) struct SirfDecoder {
    /// The solution being assembled.
    pending: Option<Epoch>,
    /// Which solution messages this receiver sends (what "complete" means), once an epoch has closed.
    expected: Option<Expected>,
    /// The latest satellite view (MID 4).
    sky: Vec<Satellite>,
    /// The latest extended GPS week the receiver sent (MID 41 of a fix, MID 7).
    extended_week: Option<u32>,
    /// GPS − UTC [s] implied by the last MID 41 of a fix.
    receiver_gps_utc_s: Option<i64>,
    /// True once the receiver has navigated: from then on its clock is set.
    clock_set: bool,
    /// A u-blox MID 98 has been seen: MID 98 makes the epochs, MID 2 only the satellites used.
    ublox: bool,
    /// The satellites of the last MID 2 (count and channel PRNs): a MID 98 epoch's satellites used.
    ublox_used: Option<(u8, [u8; 12])>,
}

/// Which solution messages an epoch has.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Kinds {
    nav: bool,
    geodetic: bool,
    gnss: bool,
}

impl Kinds {
    fn covers(self, other: Self) -> bool {
        (self.nav || !other.nav) && (self.geodetic || !other.geodetic) && (self.gnss || !other.gnss)
    }
}

/// Epochs a solution message may be missing before the decoder stops waiting for it: one lost frame must
/// not teach it that the receiver stopped sending that message.
const MISSES_TO_FORGET: u8 = 3;

/// The solution messages the receiver has been sending: a message is expected from the first epoch that
/// had it until [`MISSES_TO_FORGET`] epochs in a row lacked it. Per message: `None` = not expected, else
/// the epochs in a row that lacked it.
#[derive(Debug, Clone, Copy, Default)]
struct Expected {
    nav: Option<u8>,
    geodetic: Option<u8>,
    gnss: Option<u8>,
}

impl Expected {
    fn learn(&mut self, seen: Kinds) {
        for (misses, present) in
            [(&mut self.nav, seen.nav), (&mut self.geodetic, seen.geodetic), (&mut self.gnss, seen.gnss)]
        {
            *misses = if present {
                Some(0)
            } else {
                misses.map(|m| m.saturating_add(1)).filter(|&m| m < MISSES_TO_FORGET)
            };
        }
    }

    fn kinds(self) -> Kinds {
        Kinds { nav: self.nav.is_some(), geodetic: self.geodetic.is_some(), gnss: self.gnss.is_some() }
    }
}

/// One navigation solution's messages.
#[derive(Debug, Clone)]
struct Epoch {
    /// GPS time of week of the first message [ms].
    tow_ms: i64,
    nav: Option<NavSolution>,
    geodetic: Option<Geodetic>,
    gnss: Option<GnssNav>,
    /// A u-blox MID 98: the whole epoch.
    ublox: Option<UbloxNav>,
}

impl Epoch {
    fn new(tow_ms: i64) -> Self {
        Self { tow_ms, nav: None, geodetic: None, gnss: None, ublox: None }
    }
    fn kinds(&self) -> Kinds {
        Kinds { nav: self.nav.is_some(), geodetic: self.geodetic.is_some(), gnss: self.gnss.is_some() }
    }
}

/// One solution message of an epoch.
enum Part {
    Nav(NavSolution),
    Geodetic(Geodetic),
    Gnss(GnssNav),
}

/// A decoded message.
enum Message {
    Nav(NavSolution),
    Geodetic(Geodetic),
    Gnss(GnssNav),
    Ublox(UbloxNav),
    Tracker(Vec<Satellite>),
    ClockStatus { extended_week: u16 },
    Unused,
}

impl SirfDecoder {
    /// A decoder with no epoch under way.
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// One checksum-verified payload (MID first). `Ok(Some(fix))` when this message completes an epoch.
    ///
    /// A payload that is not used changes nothing. At most one fix comes out per call; when a message both
    /// closes one epoch and completes the next, the second fix comes with the next payload (or `finish`).
    pub(crate) fn handle(&mut self, payload: &[u8], now: Instant) -> Result<Option<Fix>, SirfUnused> {
        let message = decode(payload)?;
        // An epoch completed during the previous call but held back (see above) goes out first.
        let mut out = match &self.pending {
            Some(p) if self.complete(p) => self.close(now),
            _ => None,
        };
        match message {
            Message::Nav(n) => {
                self.ublox_used = Some((n.sats_used, n.prns));
                if !self.ublox {
                    out = out.or(self.add(n.tow_ms(), Part::Nav(n), now));
                }
            }
            Message::Geodetic(g) => out = out.or(self.add(i64::from(g.tow_ms), Part::Geodetic(g), now)),
            Message::Gnss(g) => out = out.or(self.add(g.tow_ms, Part::Gnss(g), now)),
            Message::Ublox(u) => {
                self.ublox = true;
                // A MID 2 epoch still open (the one before the first MID 98) goes out first.
                if self.pending.is_some() {
                    self.expected.get_or_insert_with(Expected::default);
                    out = out.or(self.close(now));
                }
                self.pending = Some(Epoch { ublox: Some(u), ..Epoch::new(0) });
                if out.is_none() {
                    out = self.close(now);
                }
            }
            Message::Tracker(sky) => self.sky = sky,
            Message::ClockStatus { extended_week } => {
                if extended_week > 0 {
                    self.extended_week = Some(u32::from(extended_week));
                }
            }
            Message::Unused => {}
        }
        Ok(out)
    }

    /// End of stream: an epoch still being assembled, if any.
    pub(crate) fn finish(&mut self, now: Instant) -> Option<Fix> {
        self.close(now)
    }

    /// Whether an epoch has every solution message it will get.
    fn complete(&self, p: &Epoch) -> bool {
        p.ublox.is_some() || self.expected.is_some_and(|e| p.kinds().covers(e.kinds()))
    }

    /// Adds one solution message; returns a fix when it closes the pending epoch or completes the new one.
    fn add(&mut self, tow_ms: i64, part: Part, now: Instant) -> Option<Fix> {
        let mut out = None;
        if let Some(p) = &self.pending {
            let repeat = match &part {
                Part::Nav(_) => p.nav.is_some(),
                Part::Geodetic(_) => p.geodetic.is_some(),
                Part::Gnss(_) => p.gnss.is_some(),
            };
            if repeat || p.ublox.is_some() || tow_distance_ms(p.tow_ms, tow_ms) >= SAME_EPOCH_MS {
                // The first epoch closed by the next one shows which solution messages to expect.
                self.expected.get_or_insert_with(Expected::default);
                out = self.close(now);
            }
        }
        let p = self.pending.get_or_insert_with(|| Epoch::new(tow_ms));
        match part {
            Part::Nav(n) => p.nav = Some(n),
            Part::Geodetic(g) => p.geodetic = Some(g),
            Part::Gnss(g) => p.gnss = Some(g),
        }
        let complete = self.pending.as_ref().is_some_and(|p| self.complete(p));
        if complete && out.is_none() { self.close(now) } else { out }
    }

    /// Turns the pending epoch into a fix.
    fn close(&mut self, now: Instant) -> Option<Fix> {
        let epoch = self.pending.take()?;
        if let Some(u) = &epoch.ublox {
            return Some(self.build_ublox(u, now));
        }
        if let Some(e) = &mut self.expected {
            e.learn(epoch.kinds());
        }
        Some(self.build(&epoch, now))
    }

    fn build(&mut self, epoch: &Epoch, now: Instant) -> Fix {
        let nav = epoch.nav.as_ref();
        let geo = epoch.geodetic.as_ref();
        let gnss = epoch.gnss.as_ref();
        let nav_type = match gnss {
            // An invalid GNSS solution says "no fix" whatever the older messages say.
            Some(g) => {
                if g.valid {
                    (g.solution_info & 0x07) as u8
                } else {
                    0
                }
            }
            None => nav.map_or_else(|| geo.map_or(0, |g| g.nav_type as u8), |n| n.mode1),
        };
        let (mode, quality) = mode_and_quality(nav_type);
        let has_fix = mode != FixMode::NoFix;
        if has_fix {
            self.clock_set = true;
            if let Some(offset) = geo.and_then(Geodetic::gps_minus_utc_s) {
                self.receiver_gps_utc_s = Some(offset);
            }
            if let Some(g) = gnss {
                self.receiver_gps_utc_s = Some(i64::from(g.leap_s));
                if g.week > 0 {
                    self.extended_week = Some(u32::from(g.week));
                }
            }
            // Before a fix MID 41's week is the firmware's default; with one it is the real week.
            if let Some(g) = geo.filter(|g| g.extended_week > 0) {
                self.extended_week = Some(u32::from(g.extended_week));
            }
        }
        let mut fix =
            Fix { mode: Some(mode), quality: Some(quality), received_at: Some(now), ..Fix::default() };

        if self.clock_set {
            let gps = match (nav, gnss, geo) {
                (Some(n), _, _) => Some((self.full_week(n.week, geo), i64::from(n.tow_cs) * 10)),
                (None, Some(g), _) if g.week > 0 => Some((u32::from(g.week), g.tow_ms)),
                (None, _, Some(g)) => Some((u32::from(g.extended_week), i64::from(g.tow_ms))),
                _ => None,
            };
            let leap_s = self.receiver_gps_utc_s.map_or(GPS_UTC_OFFSET_S, |r| r.max(GPS_UTC_OFFSET_S));
            fix.time = gps.and_then(|(week, tow_ms)| utc_from_gps(week, tow_ms, leap_s));
            fix.time_of_day = fix.time.map(|t| t.time());
        }

        // Satellites used: MID 2's channel list, else MID 41's bitmap (bit 0 = PRN 1).
        let used: Vec<u16> = match (nav, geo) {
            (Some(n), _) => n.prns.iter().filter(|&&p| p != 0).map(|&p| u16::from(p)).collect(),
            (None, Some(g)) => (0..32u16).filter(|b| g.sv_bitmap & (1 << b) != 0).map(|b| b + 1).collect(),
            (None, None) => Vec::new(),
        };
        fix.satellites.clone_from(&self.sky);
        for s in &mut fix.satellites {
            s.used = used.contains(&s.prn);
            *fix.sats_visible_by.entry(s.constellation).or_insert(0) += 1;
        }
        fix.sats_visible = Some(fix.satellites.len() as u32);

        if has_fix {
            for &prn in &used {
                *fix.sats_used_by.entry(Constellation::from_nmea_id(prn)).or_insert(0) += 1;
            }
            fix.sats_used = gnss
                .map(|g| g.sats_used)
                .or(nav.map(|n| n.sats_used))
                .or(geo.map(|g| g.sats_used))
                .map(u32::from);
            fix.hdop = gnss
                .map(|g| g.dop_x5[2])
                .or(nav.map(|n| n.hdop_x5))
                .or(geo.map(|g| g.hdop_x5))
                .map(|h| f64::from(h) / 5.0);
            if let Some(g) = gnss {
                fix.pdop = Some(f64::from(g.dop_x5[1]) / 5.0);
                fix.vdop = Some(f64::from(g.dop_x5[3]) / 5.0);
                Self::fill_from_gnss(&mut fix, g);
            } else {
                Self::fill_position(&mut fix, nav, geo);
            }
        }
        fix
    }

    /// Position, altitude, velocity and error estimate from a valid MID 67 SID 1.
    fn fill_from_gnss(fix: &mut Fix, g: &GnssNav) {
        let (lat, lon) = g.solution.lat_lon_deg();
        (fix.lat_deg, fix.lon_deg) = (Some(lat), Some(lon));
        g.solution.fill(fix, g.solution_info & GNSS_VELOCITY_INVALID == 0);
        Self::dop_model_error(fix);
    }

    /// The fix of a u-blox MID 98 epoch.
    fn build_ublox(&mut self, u: &UbloxNav, now: Instant) -> Fix {
        let (mode, quality) = mode_and_quality(u.nav_type);
        let mut fix =
            Fix { mode: Some(mode), quality: Some(quality), received_at: Some(now), ..Fix::default() };
        // Nav type bit 6: the time is UTC (the receiver knows GPS - UTC).
        if u.nav_type & 0x40 != 0 {
            fix.time = u.utc;
            fix.time_of_day = u.utc.map(|t| t.time());
        }
        let used: Vec<u16> = self
            .ublox_used
            .map(|(_, prns)| prns.iter().filter(|&&p| p != 0).map(|&p| u16::from(p)).collect())
            .unwrap_or_default();
        fix.satellites.clone_from(&self.sky);
        for s in &mut fix.satellites {
            s.used = used.contains(&s.prn);
            *fix.sats_visible_by.entry(s.constellation).or_insert(0) += 1;
        }
        fix.sats_visible = Some(fix.satellites.len() as u32);
        if mode != FixMode::NoFix {
            for &prn in &used {
                *fix.sats_used_by.entry(Constellation::from_nmea_id(prn)).or_insert(0) += 1;
            }
            fix.sats_used = self.ublox_used.map(|(n, _)| u32::from(n));
            let [_gdop, pdop, hdop, vdop, _tdop] = u.dop_x5.map(|d| f64::from(d) / 5.0);
            (fix.pdop, fix.hdop, fix.vdop) = (Some(pdop), Some(hdop), Some(vdop));
            fix.lat_deg = Some((f64::from(u.lat_rad_e8) * 1e-8).to_degrees());
            fix.lon_deg = Some((f64::from(u.lon_rad_e8) * 1e-8).to_degrees());
            fix.speed_m_s = Some(f64::from(u.speed_mm_s) / 1000.0);
            fix.course_deg = Some((f64::from(u.course_rad_e8) * 1e-8).to_degrees().rem_euclid(360.0));
            Self::dop_model_error(&mut fix);
        }
        fix
    }

    /// Position, altitude, velocity and error estimate of an epoch with a fix.
    fn fill_position(fix: &mut Fix, nav: Option<&NavSolution>, geo: Option<&Geodetic>) {
        let mut ecef_geodetic = None;
        if let Some(n) = nav {
            ecef_geodetic = wgs84_from_ecef(n.ecef_m);
            if let Some((lat, lon, _)) = ecef_geodetic {
                fix.lat_deg = Some(lat.to_degrees());
                fix.lon_deg = Some(lon.to_degrees());
            }
        } else if let Some(g) = geo {
            let (lat, lon) = g.solution.lat_lon_deg();
            (fix.lat_deg, fix.lon_deg) = (Some(lat), Some(lon));
        }
        if fix.lat_deg.is_none() {
            // The receiver claimed a fix at a position that is not one: say so rather than guess.
            fix.mode = Some(FixMode::NoFix);
            fix.quality = Some(FixQuality::Invalid);
            return;
        }

        if let Some(g) = geo {
            g.solution.fill(fix, g.nav_type & NAV_TYPE_VELOCITY_INVALID == 0);
        } else if let (Some(n), Some((lat, lon, _))) = (nav, ecef_geodetic)
            && n.mode2 & MODE2_VELOCITY_INVALID == 0
        {
            let [east, north, _up] = enu_from_ecef_velocity(n.velocity_m_s, lat, lon);
            fix.speed_m_s = Some(east.hypot(north));
            fix.course_deg = Some(east.atan2(north).to_degrees().rem_euclid(360.0));
        }
        Self::dop_model_error(fix);
    }

    /// Without the receiver's own error estimate: HDOP times the UERE.
    fn dop_model_error(fix: &mut Fix) {
        if fix.error.is_none() {
            let differential = fix.quality.is_some_and(FixQuality::is_differential);
            let uere_m = if differential { super::UERE_DGPS_M } else { super::UERE_M };
            fix.error = fix.hdop.map(|h| ErrorEstimate {
                horizontal_m: h * uere_m,
                vertical_m: None,
                source: ErrorSource::DopModel { uere_m },
            });
        }
    }

    /// The full GPS week of a 10-bit MID 2 week: next to the epoch's MID 41 extended week, else the latest
    /// extended week seen, else in the 1024 weeks from [`PIVOT_WEEK`]. Weeks above 1023 are taken as they
    /// are (later firmware sends the extended week).
    fn full_week(&self, week: u16, geo: Option<&Geodetic>) -> u32 {
        let week = u32::from(week);
        if week >= 1024 {
            return week;
        }
        let reference = geo.map(|g| u32::from(g.extended_week)).filter(|&w| w > 0).or(self.extended_week);
        let Some(reference) = reference else {
            return PIVOT_WEEK + (week + 1024 - PIVOT_WEEK % 1024) % 1024;
        };
        let candidate = reference - reference % 1024 + week;
        if candidate + 512 < reference {
            candidate + 1024
        } else if candidate > reference + 512 && candidate >= 1024 {
            candidate - 1024
        } else {
            candidate
        }
    }
}

/// Distance between two times of week [ms], across the week's end.
fn tow_distance_ms(a: i64, b: i64) -> i64 {
    let d = (a - b).rem_euclid(WEEK_MS);
    d.min(WEEK_MS - d)
}

/// Fix mode and quality from the "position mode" bits shared by MID 2's mode 1 and the low byte of MID 41's
/// nav type (manual: "Mode 1" table under MID 2).
///
/// Bits 0–2: 0 no solution, 1–3 Kalman filter solution from 1–3 satellites, 4 from more than 3, 5 2-D
/// least squares, 6 3-D least squares, 7 dead reckoning; bit 7: DGPS corrections applied. 4 and 6 are 3D;
/// fewer than four satellites, or a held altitude, make 2D (as gpsd maps them); dead reckoning is a 2D
/// position of quality "estimated" (gpsd: 2D, status DR).
fn mode_and_quality(bits: u8) -> (FixMode, FixQuality) {
    let mode = match bits & 0x07 {
        0 => return (FixMode::NoFix, FixQuality::Invalid),
        7 => return (FixMode::Fix2D, FixQuality::Estimated),
        4 | 6 => FixMode::Fix3D,
        _ => FixMode::Fix2D,
    };
    (mode, if bits & 0x80 != 0 { FixQuality::Dgps } else { FixQuality::Gps })
}

/// MID 2 mode 2 bit 4: the velocity is invalid.
const MODE2_VELOCITY_INVALID: u8 = 0x10;
/// MID 41 nav type bit 12: the velocity is invalid (MID 2's mode 2 is the high byte of nav type).
const NAV_TYPE_VELOCITY_INVALID: u16 = 0x1000;

/// MID 2, Measured Navigation Data Out (41 bytes; later firmware appends bytes, which are ignored).
#[derive(Debug, Clone)]
struct NavSolution {
    /// WGS-84 ECEF X, Y, Z [m] (I4 each, bytes 1–12).
    ecef_m: [f64; 3],
    /// ECEF velocity [m/s] (I2 each, ×8, bytes 13–18).
    velocity_m_s: [f64; 3],
    /// Mode 1 (byte 19), see [`mode_and_quality`].
    mode1: u8,
    /// HDOP ×5 (byte 20).
    hdop_x5: u8,
    /// Mode 2 (byte 21).
    mode2: u8,
    /// GPS week (byte 22–23, 10 bits on `SiRF` II).
    week: u16,
    /// GPS time of week ×100 [s] (bytes 24–27).
    tow_cs: u32,
    /// Satellites in the solution (byte 28).
    sats_used: u8,
    /// PRNs of channels 1–12 used in the solution, 0 for none (bytes 29–40).
    prns: [u8; 12],
}

impl NavSolution {
    fn tow_ms(&self) -> i64 {
        i64::from(self.tow_cs) * 10
    }
}

/// The fields MID 41 and MID 67 SID 1 share, with the same scales at different offsets.
#[derive(Debug, Clone)]
struct Solution {
    /// Latitude, longitude ×10^7 [deg].
    lat_e7: i32,
    lon_e7: i32,
    /// Altitude above the ellipsoid and above MSL ×100 [m].
    alt_hae_cm: i32,
    alt_msl_cm: i32,
    /// Speed over ground ×100 [m/s], course over ground ×100 [deg].
    speed_cm_s: u16,
    course_cdeg: u16,
    /// Estimated horizontal and vertical position error ×100 [m].
    ehpe_cm: u32,
    evpe_cm: u32,
}

impl Solution {
    /// Reads the position (latitude at `position`, then longitude, altitude above the ellipsoid and above
    /// MSL, 4 bytes each), the velocity (speed at `velocity`, then course) and the error estimate
    /// (horizontal at `error`, then vertical).
    fn read(f: &Fields<'_>, position: usize, velocity: usize, error: usize) -> Result<Self, SirfUnused> {
        Ok(Self {
            lat_e7: f.i32(position)?,
            lon_e7: f.i32(position + 4)?,
            alt_hae_cm: f.i32(position + 8)?,
            alt_msl_cm: f.i32(position + 12)?,
            speed_cm_s: f.u16(velocity)?,
            course_cdeg: f.u16(velocity + 2)?,
            ehpe_cm: f.u32(error)?,
            evpe_cm: f.u32(error + 4)?,
        })
    }

    /// Latitude and longitude [deg].
    fn lat_lon_deg(&self) -> (f64, f64) {
        (f64::from(self.lat_e7) * 1e-7, f64::from(self.lon_e7) * 1e-7)
    }

    /// Altitude, geoid separation, speed and course (unless the receiver says the velocity is invalid)
    /// and the receiver's error estimate (when it gives one) into `fix`.
    fn fill(&self, fix: &mut Fix, velocity_valid: bool) {
        fix.alt_m = Some(f64::from(self.alt_msl_cm) / 100.0);
        fix.geoid_sep_m = Some((f64::from(self.alt_hae_cm) - f64::from(self.alt_msl_cm)) / 100.0);
        if velocity_valid {
            fix.speed_m_s = Some(f64::from(self.speed_cm_s) / 100.0);
            fix.course_deg = Some(f64::from(self.course_cdeg) / 100.0);
        }
        if self.ehpe_cm > 0 {
            fix.error = Some(ErrorEstimate {
                horizontal_m: f64::from(self.ehpe_cm) / 100.0,
                vertical_m: (self.evpe_cm > 0).then(|| f64::from(self.evpe_cm) / 100.0),
                source: ErrorSource::Sirf,
            });
        }
    }
}

/// MID 41, Geodetic Navigation Data (91 bytes).
#[derive(Debug, Clone)]
struct Geodetic {
    /// Nav type (bytes 3–4): low byte as MID 2's mode 1, high byte as its mode 2.
    nav_type: u16,
    /// Extended (not 10-bit) GPS week (bytes 5–6).
    extended_week: u16,
    /// GPS time of week [ms] (bytes 7–10).
    tow_ms: u32,
    /// UTC date and time as the receiver computes it (bytes 11–18), when it is a date.
    utc: Option<DateTime<Utc>>,
    /// Satellites used, bit 0 = PRN 1 (bytes 19–22).
    sv_bitmap: u32,
    /// Position (bytes 23–38), velocity (40–43) and error estimate (50–57).
    solution: Solution,
    /// Satellites in the fix (byte 88), HDOP ×5 (byte 89).
    sats_used: u8,
    hdop_x5: u8,
}

impl Geodetic {
    /// GPS − UTC [s] as the receiver applies it: its GPS time minus its UTC, rounded to whole seconds;
    /// `None` unless both are valid and the difference is a plausible leap-second count (0–255 s).
    fn gps_minus_utc_s(&self) -> Option<i64> {
        let utc = self.utc?;
        let tow_ms = i64::from(self.tow_ms);
        if !(0..WEEK_MS).contains(&tow_ms) {
            return None;
        }
        let gps_ms = (GPS_EPOCH_UNIX_S + i64::from(self.extended_week) * WEEK_S) * 1000 + tow_ms;
        let offset = (gps_ms - utc.timestamp_millis() + 500).div_euclid(1000);
        (0..=255).contains(&offset).then_some(offset)
    }
}

/// MID 67 SID 1 solution info bit 12: the velocity is invalid.
const GNSS_VELOCITY_INVALID: u32 = 0x1000;

/// MID 67 SID 1, GNSS Navigation Solution (`SiRFstarV`, 126 bytes; byte 1 is the SID).
#[derive(Debug, Clone)]
struct GnssNav {
    /// Solution validity (bytes 2–5) is 0: the solution is valid.
    valid: bool,
    /// Solution info (bytes 6–9): bits 0–2 as MID 2's mode 1, bit 12 velocity invalid.
    solution_info: u32,
    /// Extended GPS week (bytes 10–11).
    week: u16,
    /// GPS time of week [ms] (bytes 12–15 in ms plus 16–19 in ns, rounded to the millisecond).
    tow_ms: i64,
    /// GPS − UTC [s] (byte 32).
    leap_s: u8,
    /// Position (bytes 54–69), velocity (70–73) and error estimate (86–93).
    solution: Solution,
    /// GDOP, PDOP, HDOP, VDOP, TDOP ×5 (bytes 96–100).
    dop_x5: [u8; 5],
    /// Satellites in the solution (byte 101).
    sats_used: u8,
}

/// MID 98, u-blox Extended Measured Navigation Data (39 bytes).
#[derive(Debug, Clone)]
struct UbloxNav {
    /// Latitude, longitude [rad ×10^8] (bytes 1–8).
    lat_rad_e8: i32,
    lon_rad_e8: i32,
    /// Speed over ground [mm/s] (bytes 13–16).
    speed_mm_s: i32,
    /// Course over ground [rad ×10^8] (bytes 21–24).
    course_rad_e8: i32,
    /// Nav type (byte 25): MID 2's mode 1 bits, bit 6 = the time is UTC.
    nav_type: u8,
    /// UTC date and time (bytes 26–33), when it is a date.
    utc: Option<DateTime<Utc>>,
    /// GDOP, PDOP, HDOP, VDOP, TDOP ×5 (bytes 34–38).
    dop_x5: [u8; 5],
}

/// A UTC date and time from year (2 bytes), month, day, hour, minute (1 byte each) and milliseconds of
/// the minute (2 bytes) at `at`, the layout of MID 41, 67 and 98; `None` when it is not a date.
fn utc_fields(f: &Fields<'_>, at: usize) -> Result<Option<DateTime<Utc>>, SirfUnused> {
    let (year, month, day) = (f.u16(at)?, f.u8(at + 2)?, f.u8(at + 3)?);
    let (hour, minute, ms) = (f.u8(at + 4)?, f.u8(at + 5)?, f.u16(at + 6)?);
    Ok(NaiveDate::from_ymd_opt(i32::from(year), u32::from(month), u32::from(day))
        .and_then(|d| d.and_hms_milli_opt(u32::from(hour), u32::from(minute), 0, 0))
        .filter(|_| ms < 60_000)
        .map(|t| t.and_utc() + chrono::TimeDelta::milliseconds(i64::from(ms))))
}

/// Big-endian fields of a payload at byte offsets of the manual's tables (byte 0 = MID).
struct Fields<'a>(&'a [u8]);

impl Fields<'_> {
    fn bytes<const N: usize>(&self, at: usize) -> Result<[u8; N], SirfUnused> {
        let end = at.checked_add(N).ok_or(SirfUnused::Malformed)?;
        let slice = self.0.get(at..end).ok_or(SirfUnused::Malformed)?;
        slice.try_into().map_err(|_| SirfUnused::Malformed)
    }
    fn u8(&self, at: usize) -> Result<u8, SirfUnused> {
        self.0.get(at).copied().ok_or(SirfUnused::Malformed)
    }
    fn u16(&self, at: usize) -> Result<u16, SirfUnused> {
        self.bytes(at).map(u16::from_be_bytes)
    }
    fn i16(&self, at: usize) -> Result<i16, SirfUnused> {
        self.bytes(at).map(i16::from_be_bytes)
    }
    fn u32(&self, at: usize) -> Result<u32, SirfUnused> {
        self.bytes(at).map(u32::from_be_bytes)
    }
    fn i32(&self, at: usize) -> Result<i32, SirfUnused> {
        self.bytes(at).map(i32::from_be_bytes)
    }
}

/// Message ids that are known and carry nothing a fix needs (manual chapter 2, "Output Messages"):
/// 5 raw tracker data, 6 software version, 8 50 bps subframe data, 9 CPU throughput, 10 error ID,
/// 11 command acknowledgment, 12 command negative acknowledgment, 13 visible list, 14 almanac, 15 ephemeris,
/// 17 differential corrections, 18 OK to send, 19 navigation parameters, 27 DGPS status, 28–31 navigation
/// library data, 50 SBAS parameters, 51 navigation notification, 52 1 PPS time, 56 extended ephemeris,
/// 64 navigation library, 71 hardware configuration request, 92 CW interference report, 93 TCXO learning,
/// 225 statistics, 255 development data (51–93: `SiRFstarIV`/V One Socket Protocol).
const KNOWN_UNUSED: [u8; 28] = [
    5, 6, 8, 9, 10, 11, 12, 13, 14, 15, 17, 18, 19, 27, 28, 29, 30, 31, 50, 51, 52, 56, 64, 71, 92, 93, 225,
    255,
];

/// Decodes one payload by its message id.
fn decode(payload: &[u8]) -> Result<Message, SirfUnused> {
    let f = Fields(payload);
    let mid = f.u8(0)?;
    Ok(match mid {
        2 => Message::Nav(decode_nav(&f)?),
        4 => Message::Tracker(decode_tracker(&f)?),
        7 => {
            // MID 7 Clock Status (20 bytes): extended week (1–2), TOW, SVs, drift, bias, GPS time.
            if payload.len() < 20 {
                return Err(SirfUnused::Malformed);
            }
            Message::ClockStatus { extended_week: f.u16(1)? }
        }
        41 => Message::Geodetic(decode_geodetic(&f)?),
        // MID 67: SID 1 is the navigation solution; the others (16 satellites, 17 ...) repeat MID 4.
        67 if f.u8(1)? == 1 => Message::Gnss(decode_gnss(&f)?),
        67 => Message::Unused,
        98 => Message::Ublox(decode_ublox(&f)?),
        m if KNOWN_UNUSED.contains(&m) => Message::Unused,
        _ => return Err(SirfUnused::Unsupported),
    })
}

fn decode_nav(f: &Fields<'_>) -> Result<NavSolution, SirfUnused> {
    if f.0.len() < 41 {
        return Err(SirfUnused::Malformed);
    }
    let mut prns = [0u8; 12];
    for (i, p) in prns.iter_mut().enumerate() {
        *p = f.u8(29 + i)?;
    }
    Ok(NavSolution {
        ecef_m: [f64::from(f.i32(1)?), f64::from(f.i32(5)?), f64::from(f.i32(9)?)],
        velocity_m_s: [f64::from(f.i16(13)?) / 8.0, f64::from(f.i16(15)?) / 8.0, f64::from(f.i16(17)?) / 8.0],
        mode1: f.u8(19)?,
        hdop_x5: f.u8(20)?,
        mode2: f.u8(21)?,
        week: f.u16(22)?,
        tow_cs: f.u32(24)?,
        sats_used: f.u8(28)?,
        prns,
    })
}

fn decode_geodetic(f: &Fields<'_>) -> Result<Geodetic, SirfUnused> {
    if f.0.len() < 91 {
        return Err(SirfUnused::Malformed);
    }
    let utc = utc_fields(f, 11)?;
    Ok(Geodetic {
        nav_type: f.u16(3)?,
        extended_week: f.u16(5)?,
        tow_ms: f.u32(7)?,
        utc,
        sv_bitmap: f.u32(19)?,
        solution: Solution::read(f, 23, 40, 50)?,
        sats_used: f.u8(88)?,
        hdop_x5: f.u8(89)?,
    })
}

fn decode_gnss(f: &Fields<'_>) -> Result<GnssNav, SirfUnused> {
    if f.0.len() < 126 {
        return Err(SirfUnused::Malformed);
    }
    let sub_ms = i64::from(f.u32(16)?.min(999_999));
    Ok(GnssNav {
        valid: f.u32(2)? == 0,
        solution_info: f.u32(6)?,
        week: f.u16(10)?,
        tow_ms: i64::from(f.u32(12)?) + (sub_ms + 500_000) / 1_000_000,
        leap_s: f.u8(32)?,
        solution: Solution::read(f, 54, 70, 86)?,
        dop_x5: f.bytes(96)?,
        sats_used: f.u8(101)?,
    })
}

fn decode_ublox(f: &Fields<'_>) -> Result<UbloxNav, SirfUnused> {
    if f.0.len() < 39 {
        return Err(SirfUnused::Malformed);
    }
    Ok(UbloxNav {
        lat_rad_e8: f.i32(1)?,
        lon_rad_e8: f.i32(5)?,
        speed_mm_s: f.i32(13)?,
        course_rad_e8: f.i32(21)?,
        nav_type: f.u8(25)?,
        utc: utc_fields(f, 26)?,
        dop_x5: f.bytes(34)?,
    })
}

/// MID 4, Measured Tracker Data Out: GPS week (1–2), TOW ×100 (3–6), channel count (7), then 15 bytes a
/// channel: PRN, azimuth ×2/3 [deg] (so degrees = value × 1.5), elevation ×2 [deg] (degrees = value / 2),
/// state (2 bytes), ten C/N0 values [dB-Hz], one per 100 ms of the last second.
///
/// Listed: channels with a PRN that have a direction or a signal; the SNR is the mean of the ten C/N0
/// values (as gpsd), `None` when all are zero; azimuth and elevation are `None` when both are zero (a
/// satellite tracked before the almanac says where it is). A PRN on two channels is listed once.
fn decode_tracker(f: &Fields<'_>) -> Result<Vec<Satellite>, SirfUnused> {
    let channels = usize::from(f.u8(7)?);
    if f.0.len() < 8 + 15 * channels {
        return Err(SirfUnused::Malformed);
    }
    let mut sats: Vec<Satellite> = Vec::with_capacity(channels);
    for ch in 0..channels {
        let at = 8 + 15 * ch;
        let prn = u16::from(f.u8(at)?);
        let (az, el) = (f.u8(at + 1)?, f.u8(at + 2)?);
        let cn0 = f.bytes::<10>(at + 5)?;
        let sum: u32 = cn0.iter().map(|&c| u32::from(c)).sum();
        let placed = az != 0 || el != 0;
        if prn == 0 || (!placed && sum == 0) || sats.iter().any(|s| s.prn == prn) {
            continue;
        }
        sats.push(Satellite {
            prn,
            constellation: Constellation::from_nmea_id(prn),
            elevation_deg: placed.then(|| f64::from(el) / 2.0),
            azimuth_deg: placed.then(|| f64::from(az) * 1.5),
            snr_dbhz: (sum > 0).then(|| f64::from(sum) / 10.0),
            used: false,
        });
    }
    Ok(sats)
}

/// WGS-84 semi-major axis [m].
const WGS84_A_M: f64 = 6_378_137.0;
/// WGS-84 flattening.
const WGS84_F: f64 = 1.0 / 298.257_223_563;

/// Geodetic latitude, longitude [rad] and height above the ellipsoid [m] of a WGS-84 ECEF point [m];
/// `None` within 100 km of the earth's centre, where the closed form below has no solution.
///
/// Heikkinen's exact closed form (M. Heikkinen, "Geschlossene Formeln zur Berechnung räumlicher
/// geodätischer Koordinaten aus rechtwinkligen Koordinaten", Z. Vermess. 107 (1982); as given by J. Zhu,
/// "Conversion of Earth-centered Earth-fixed coordinates to geodetic coordinates", IEEE Trans. AES 30
/// (1994), eqs. 1–12), with `b = a(1 − f)`, `e² = f(2 − f)`, `e'² = e²/(1 − e²)`, `p = √(x² + y²)`:
/// `F = 54 b² z²`, `G = p² + (1 − e²) z² − e²(a² − b²)`, `c = e⁴ F p² / G³`, `s = ∛(1 + c + √(c² + 2c))`,
/// `k = s + 1 + 1/s`, `P = F / (3 k² G²)`, `Q = √(1 + 2 e⁴ P)`,
/// `r₀ = −P e² p / (1 + Q) + √(a²/2 (1 + 1/Q) − P (1 − e²) z² / (Q (1 + Q)) − P p² / 2)`,
/// `U = √((p − e² r₀)² + z²)`, `V = √((p − e² r₀)² + (1 − e²) z²)`, `z₀ = b² z / (a V)`;
/// then `h = U (1 − b² / (a V))`, `φ = atan2(z + e'² z₀, p)`, `λ = atan2(y, x)`.
/// Exact to far below a millimetre for any point near the earth's surface — no iteration.
pub(crate) fn wgs84_from_ecef([x, y, z]: [f64; 3]) -> Option<(f64, f64, f64)> {
    let a = WGS84_A_M;
    let b = a * (1.0 - WGS84_F);
    let e2 = WGS84_F * (2.0 - WGS84_F);
    let ep2 = e2 / (1.0 - e2);
    let p = x.hypot(y);
    if p.hypot(z) < 100_000.0 {
        return None;
    }
    let big_f = 54.0 * b * b * z * z;
    let g = p * p + (1.0 - e2) * z * z - e2 * (a * a - b * b);
    let c = e2 * e2 * big_f * p * p / (g * g * g);
    let s = (1.0 + c + (c * c + 2.0 * c).sqrt()).cbrt();
    let k = s + 1.0 + 1.0 / s;
    let big_p = big_f / (3.0 * k * k * g * g);
    let q = (1.0 + 2.0 * e2 * e2 * big_p).sqrt();
    let r0 = -big_p * e2 * p / (1.0 + q)
        + (a * a / 2.0 * (1.0 + 1.0 / q)
            - big_p * (1.0 - e2) * z * z / (q * (1.0 + q))
            - big_p * p * p / 2.0)
            .max(0.0)
            .sqrt();
    let u = (p - e2 * r0).hypot(z);
    let v = ((p - e2 * r0).powi(2) + (1.0 - e2) * z * z).sqrt();
    let z0 = b * b * z / (a * v);
    let h = u * (1.0 - b * b / (a * v));
    let lat = (z + ep2 * z0).atan2(p);
    let lon = y.atan2(x);
    (lat.is_finite() && lon.is_finite() && h.is_finite()).then_some((lat, lon, h))
}

/// East, north, up velocity [m/s] of an ECEF velocity at geodetic latitude/longitude [rad]: the rows of
/// the rotation ECEF → ENU, `e = (−sin λ, cos λ, 0)`, `n = (−sin φ cos λ, −sin φ sin λ, cos φ)`,
/// `u = (cos φ cos λ, cos φ sin λ, sin φ)` (e.g. Misra & Enge, *Global Positioning System*, §4.2).
pub(crate) fn enu_from_ecef_velocity([vx, vy, vz]: [f64; 3], lat: f64, lon: f64) -> [f64; 3] {
    let (sp, cp) = lat.sin_cos();
    let (sl, cl) = lon.sin_cos();
    [-sl * vx + cl * vy, -sp * cl * vx - sp * sl * vy + cp * vz, cp * cl * vx + cp * sl * vy + sp * vz]
}

#[cfg(test)]
mod tests {
    use super::*;

    use std::collections::BTreeMap;
    use std::path::PathBuf;
    use std::time::Instant;

    use proptest::prelude::*;

    fn data(name: &str) -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/gpsd-logs-more").join(name)
    }

    /// The checksum-verified payloads of a byte stream: a frame scanner of its own, independent of the
    /// framer, which skips anything that is not a whole frame with a correct checksum.
    fn payloads(bytes: &[u8]) -> Vec<&[u8]> {
        let mut out = Vec::new();
        let mut i = 0;
        while let Some(off) = bytes.get(i..).and_then(|rest| rest.windows(2).position(|w| w == START)) {
            let at = i + off;
            let frame = bytes.get(at + 2..at + 4).and_then(|len| {
                let n = usize::from(u16::from_be_bytes([len[0], len[1]]) & 0x7FFF);
                let payload = bytes.get(at + 4..at + 4 + n)?;
                let ck = bytes.get(at + 4 + n..at + 6 + n)?;
                let ok = u16::from_be_bytes([ck[0], ck[1]]) == checksum(payload)
                    && bytes.get(at + 6 + n..at + 8 + n) == Some(&END[..]);
                ok.then_some((payload, at + 8 + n))
            });
            match frame {
                Some((payload, next)) => {
                    out.push(payload);
                    i = next;
                }
                None => i = at + 1,
            }
        }
        out
    }

    /// The payloads of gpsd's `sirf2.log` (read once per test binary).
    fn sirf2_payloads() -> &'static [Vec<u8>] {
        static PAYLOADS: std::sync::OnceLock<Vec<Vec<u8>>> = std::sync::OnceLock::new();
        PAYLOADS.get_or_init(|| {
            let bytes = std::fs::read(data("sirf2.log")).unwrap();
            payloads(&bytes).into_iter().map(<[u8]>::to_vec).collect()
        })
    }

    fn decode_all(payloads: impl IntoIterator<Item = impl AsRef<[u8]>>) -> Vec<Fix> {
        let now = Instant::now();
        let mut d = SirfDecoder::new();
        let mut fixes = Vec::new();
        for p in payloads {
            if let Ok(Some(f)) = d.handle(p.as_ref(), now) {
                fixes.push(f);
            }
        }
        fixes.extend(d.finish(now));
        // Decoders run at different instants; what they decoded is what is compared.
        for f in &mut fixes {
            f.received_at = None;
        }
        fixes
    }

    fn time_key(t: DateTime<Utc>) -> String {
        t.format("%Y-%m-%dT%H:%M:%S%.3fZ").to_string()
    }

    /// One gpsd TPV report.
    struct Tpv {
        time: String,
        mode: u8,
        lat: Option<f64>,
        lon: Option<f64>,
        speed: Option<f64>,
        track: Option<f64>,
    }

    /// gpsd's TPV reports of a `.chk` file, in order.
    fn gpsd_tpv(name: &str) -> Vec<Tpv> {
        let text = std::fs::read_to_string(data(name)).unwrap();
        text.lines()
            .filter(|l| l.starts_with('{'))
            .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
            .filter(|v| v["class"] == "TPV")
            .map(|v| Tpv {
                time: v["time"].as_str().unwrap_or_default().to_string(),
                mode: v["mode"].as_u64().unwrap_or(0) as u8,
                lat: v["lat"].as_f64(),
                lon: v["lon"].as_f64(),
                speed: v["speed"].as_f64(),
                track: v["track"].as_f64(),
            })
            .collect()
    }

    /// Compares fixes with gpsd's TPV reports that have a position, keyed by the TPV time: the same UTC
    /// time to the millisecond, the same mode, latitude and longitude within 1e-7 deg. Returns the matched
    /// TPVs and the times of the others.
    fn match_gpsd<'a>(fixes: &[Fix], tpv: &'a [Tpv]) -> (Vec<(&'a Tpv, Fix)>, Vec<String>) {
        let ours: BTreeMap<String, &Fix> =
            fixes.iter().filter_map(|f| Some((time_key(f.time?), f))).collect();
        let mut matched = Vec::new();
        let mut misses = Vec::new();
        for t in tpv.iter().filter(|t| t.mode >= 2) {
            let close = |a: Option<f64>, b: Option<f64>| a.zip(b).is_some_and(|(a, b)| (a - b).abs() < 1e-7);
            match ours.get(&t.time) {
                Some(f)
                    if f.mode.map(FixMode::gpsd_number) == Some(t.mode)
                        && close(f.lat_deg, t.lat)
                        && close(f.lon_deg, t.lon) =>
                {
                    matched.push((t, (*f).clone()));
                }
                _ => misses.push(t.time.clone()),
            }
        }
        (matched, misses)
    }

    #[test]
    fn sirf2_log_matches_gpsd_for_every_epoch_with_a_position() {
        let fixes = decode_all(sirf2_payloads());
        // One fix per navigation solution: the log has 775 MID 2 and 775 MID 41, one of each a second.
        assert_eq!(fixes.len(), 775);
        let tpv = gpsd_tpv("sirf2.log.chk");
        let (matched, misses) = match_gpsd(&fixes, &tpv);
        let total = matched.len() + misses.len();
        let worst = matched
            .iter()
            .map(|(t, f)| {
                let dlat = (f.lat_deg.unwrap() - t.lat.unwrap()).abs();
                dlat.max((f.lon_deg.unwrap() - t.lon.unwrap()).abs())
            })
            .fold(0.0, f64::max);
        eprintln!(
            "sirf2.log: {} of gpsd's {total} epochs with a position matched; worst {worst:e} deg",
            matched.len()
        );
        assert_eq!(total, 615);
        assert!(matched.len() * 100 >= total * 99, "misses: {misses:?}");

        // Deliberate difference from gpsd: before the receiver's first fix its clock is a firmware default
        // (week 1268 = 2004 in MID 41; gpsd resolved MID 2's 10-bit week to 2023-12), so our 160 no-fix
        // epochs before the first fix carry no time, where gpsd reports 160 mode-1 TPVs with times.
        let first_fix = fixes.iter().position(Fix::has_position).unwrap();
        assert_eq!(first_fix, 160);
        assert!(fixes[..first_fix].iter().all(|f| f.time.is_none() && f.mode == Some(FixMode::NoFix)));
        assert_eq!(tpv.iter().take_while(|t| t.mode == 1).count(), 160);
    }

    #[test]
    fn mid_2_alone_matches_gpsd_including_speed_and_track() {
        // Without MID 41 the 10-bit week is resolved from the 2019 rollover, and speed and course come from
        // MID 2's ECEF velocity — as gpsd computes them.
        let fixes = decode_all(sirf2_payloads().iter().filter(|p| p[0] != 41));
        let tpv = gpsd_tpv("sirf2.log.chk");
        let (matched, misses) = match_gpsd(&fixes, &tpv);
        assert!(misses.is_empty(), "{misses:?}");
        let mut with_velocity = 0;
        for (t, f) in &matched {
            // Deliberate difference: where MID 2's mode 2 flags the velocity invalid (the 60 2D epochs),
            // we give no speed or course; gpsd reports speed 0 and track 0.
            let (Some(speed), Some(course)) = (f.speed_m_s, f.course_deg) else {
                assert_eq!((t.speed, t.track), (Some(0.0), Some(0.0)), "{}", t.time);
                continue;
            };
            approx::assert_abs_diff_eq!(speed, t.speed.unwrap(), epsilon = 1e-3);
            if speed > 0.0 {
                let d = (course - t.track.unwrap() + 540.0).rem_euclid(360.0) - 180.0;
                assert!(d.abs() < 1e-3, "{}: {course} {:?}", t.time, t.track);
            }
            with_velocity += 1;
        }
        assert_eq!(with_velocity, 555);
    }

    /// The forward transform, geodetic [rad, m] to ECEF [m]: `N = a / √(1 − e² sin² φ)`,
    /// `x = (N + h) cos φ cos λ`, `y = (N + h) cos φ sin λ`, `z = (N (1 − e²) + h) sin φ`.
    fn ecef_from_wgs84(lat: f64, lon: f64, h: f64) -> [f64; 3] {
        let e2 = WGS84_F * (2.0 - WGS84_F);
        let n = WGS84_A_M / (1.0 - e2 * lat.sin().powi(2)).sqrt();
        [(n + h) * lat.cos() * lon.cos(), (n + h) * lat.cos() * lon.sin(), (n * (1.0 - e2) + h) * lat.sin()]
    }

    #[test]
    fn ecef_to_wgs84_inverts_the_forward_transform() {
        for lat_deg in [-90.0, -89.999, -57.3, -1e-9, 0.0, 12.5, 37.293_859_454, 45.0, 89.99, 90.0] {
            for lon_deg in [-180.0, -121.918_694_932, -0.001, 0.0, 2.1, 90.0, 179.999] {
                for h in [-430.0, 0.0, 31.6, 8_848.0, 18_000.0] {
                    let (lat, lon) = (f64::to_radians(lat_deg), f64::to_radians(lon_deg));
                    let (la, lo, hh) = wgs84_from_ecef(ecef_from_wgs84(lat, lon, h)).unwrap();
                    assert!((la.to_degrees() - lat_deg).abs() < 1e-10, "{lat_deg} {lon_deg} {h}");
                    if lat_deg.abs() < 90.0 {
                        let dlon = (lo.to_degrees() - lon_deg + 540.0).rem_euclid(360.0) - 180.0;
                        assert!(dlon.abs() < 1e-10, "{lat_deg} {lon_deg} {h}");
                    }
                    assert!((hh - h).abs() < 1e-5, "{lat_deg} {lon_deg} {h}: {hh}");
                }
            }
        }
        assert_eq!(wgs84_from_ecef([0.0, 0.0, 0.0]), None);
        assert_eq!(wgs84_from_ecef([f64::NAN, 0.0, 0.0]), None);
    }

    #[test]
    fn the_geodetic_message_alone_gives_the_same_fixes_within_the_ecef_resolution() {
        let all = sirf2_payloads();
        let full = decode_all(all);
        let geodetic_only = decode_all(all.iter().filter(|p| p[0] != 2));
        assert_eq!(geodetic_only.len(), full.len());
        let mut compared = 0;
        for (g, f) in geodetic_only.iter().zip(&full) {
            assert_eq!(g.mode, f.mode);
            let (Some(gt), Some(ft)) = (g.time, f.time) else { continue };
            // MID 41 keeps milliseconds (…36.825), MID 2 truncates to 10 ms (…36.820); both minus 18 s.
            assert!((gt - ft).num_milliseconds().abs() < 10, "{gt} {ft}");
            if let (Some(glat), Some(flat), Some(glon), Some(flon)) =
                (g.lat_deg, f.lat_deg, g.lon_deg, f.lon_deg)
            {
                // MID 2's whole ECEF metres against MID 41's 1e-7 deg (1 cm): within 1.5 m.
                let north_m = (glat - flat).to_radians() * 6.371e6;
                let east_m = (glon - flon).to_radians() * 6.371e6 * flat.to_radians().cos();
                assert!(north_m.hypot(east_m) < 1.5, "{gt}: {north_m} {east_m}");
                compared += 1;
            }
        }
        assert_eq!(compared, 615);
    }

    #[test]
    fn fields_of_a_3d_dgps_epoch() {
        let fixes = decode_all(sirf2_payloads());
        let f = fixes.last().unwrap();
        assert_eq!(f.time.map(time_key).as_deref(), Some("2021-12-09T20:47:45.780Z"));
        assert_eq!((f.mode, f.quality), (Some(FixMode::Fix3D), Some(FixQuality::Dgps)));
        assert!(f.alt_m.is_some() && f.geoid_sep_m.is_some() && f.speed_m_s.is_some());
        assert_eq!(f.error.map(|e| e.source), Some(ErrorSource::Sirf));
        approx::assert_relative_eq!(f.hdop.unwrap(), 1.8);
        // gpsd's last SKY: the same directions and mean C/N0 (gpsd lists only satellites with a non-zero
        // azimuth and elevation); gpsd marks by tracker state bit 0 and SBAS, we by MID 2's channel list.
        let expect = [
            (9, 312.0, 47.5, Some(45.3)),
            (16, 88.5, 50.5, Some(45.9)),
            (3, 174.0, 48.5, Some(45.0)),
            (26, 48.0, 25.5, None),
            (7, 249.0, 31.5, Some(41.1)),
            (6, 283.5, 15.0, None),
            (18, 318.0, 13.5, None),
            (4, 24.0, 70.0, Some(43.5)),
            (131, 171.0, 46.0, Some(40.9)),
        ];
        for (prn, az, el, ss) in expect {
            let s = f.satellites.iter().find(|s| s.prn == prn).unwrap();
            assert_eq!((s.azimuth_deg, s.elevation_deg), (Some(az), Some(el)), "{prn}");
            assert_eq!(s.snr_dbhz.map(|x| (x * 10.0).round() / 10.0), ss, "{prn}");
        }
        let used: Vec<u16> = f.satellites.iter().filter(|s| s.used).map(|s| s.prn).collect();
        assert_eq!(f.sats_used, Some(used.len() as u32));
        for prn in [9, 16, 3, 7, 4] {
            assert!(used.contains(&prn), "{prn} {used:?}");
        }
        let mut checked = f.clone();
        assert!(checked.validate().is_clean());
    }

    #[test]
    fn epochs_complete_on_their_last_solution_message_in_either_order() {
        let all = sirf2_payloads();
        let now = Instant::now();
        // In the log's order (41, 4, 2, ...) the fix comes with MID 2, once one second has shown the cycle.
        let mut d = SirfDecoder::new();
        let mut emitted_by = Vec::new();
        for p in all {
            if d.handle(p, now).unwrap().is_some() {
                emitted_by.push(p[0]);
            }
        }
        assert!(d.finish(now).is_none());
        assert_eq!(emitted_by.len(), 775);
        assert!(emitted_by[2..].iter().all(|&m| m == 2), "{emitted_by:?}");
        // A receiver that sends MID 2 first: the same fixes, each with its MID 41.
        let mut swapped = all.to_vec();
        for i in 1..swapped.len() {
            if swapped[i][0] == 2 && swapped[i - 1][0] == 4 && i >= 2 && swapped[i - 2][0] == 41 {
                swapped.swap(i, i - 2);
            }
        }
        assert_eq!(decode_all(&swapped), decode_all(all));
        // A lost MID 2 leaves an epoch of MID 41 alone, closed by the next solution; nothing is lost.
        let mut n2 = 0;
        let lossy: Vec<_> = all
            .iter()
            .filter(|p| {
                n2 += usize::from(p[0] == 2);
                !(p[0] == 2 && n2 % 50 == 0)
            })
            .collect();
        let fixes = decode_all(lossy);
        assert_eq!(fixes.len(), 775);
        assert_eq!(fixes.iter().filter(|f| f.has_position()).count(), 615);
        assert!(fixes.windows(2).all(|w| w[0].time.is_none() || w[0].time < w[1].time));
    }

    #[test]
    fn unknown_short_and_unused_payloads() {
        let now = Instant::now();
        let mut d = SirfDecoder::new();
        assert_eq!(d.handle(&[], now), Err(SirfUnused::Malformed));
        assert_eq!(d.handle(&[0xC8, 1, 2], now), Err(SirfUnused::Unsupported));
        assert_eq!(d.handle(&[2; 40], now), Err(SirfUnused::Malformed));
        assert_eq!(d.handle(&[41; 90], now), Err(SirfUnused::Malformed));
        assert_eq!(d.handle(&[4, 0, 0, 0, 0, 0, 0, 1], now), Err(SirfUnused::Malformed));
        assert_eq!(d.handle(&[7; 19], now), Err(SirfUnused::Malformed));
        for mid in [9, 27, 50, 52, 13, 10, 255] {
            assert_eq!(d.handle(&[mid, 0, 0], now), Ok(None), "{mid}");
        }
        assert_eq!(d.finish(now), None);
    }

    /// A few real payloads of every message id in `sirf2.log`, with and without a fix.
    fn sample_payloads() -> Vec<Vec<u8>> {
        let all = sirf2_payloads();
        all.iter().skip(700).step_by(7).take(40).chain(all.iter().rev().take(14)).cloned().collect()
    }

    fn mutated() -> impl Strategy<Value = Vec<u8>> {
        let samples = sample_payloads();
        (0..samples.len(), any::<prop::sample::Index>(), any::<u8>()).prop_map(move |(i, at, b)| {
            let mut p = samples[i].clone();
            let at = at.index(p.len());
            p[at] = b;
            p
        })
    }

    fn arbitrary_payload() -> impl Strategy<Value = Vec<u8>> {
        prop_oneof![
            prop::collection::vec(any::<u8>(), 0..300),
            (prop::sample::select(vec![2u8, 4, 7, 41]), prop::collection::vec(any::<u8>(), 0..200)).prop_map(
                |(mid, mut body)| {
                    body.insert(0, mid);
                    body
                }
            ),
        ]
    }

    proptest! {
        #[test]
        fn arbitrary_payloads_never_panic(payloads in prop::collection::vec(arbitrary_payload(), 1..40)) {
            let now = Instant::now();
            let mut d = SirfDecoder::new();
            for p in &payloads {
                if let Ok(Some(mut f)) = d.handle(p, now) {
                    f.validate();
                }
            }
            if let Some(mut f) = d.finish(now) {
                f.validate();
            }
        }

        #[test]
        fn a_real_payload_with_one_byte_changed_never_panics(bad in mutated(), before in 0usize..54) {
            let now = Instant::now();
            let mut d = SirfDecoder::new();
            let samples = sample_payloads();
            prop_assert_eq!(samples.len(), 54);
            for p in samples.iter().take(before) {
                let _ = d.handle(p, now);
            }
            if let Ok(Some(mut f)) = d.handle(&bad, now) {
                f.validate();
            }
            for p in samples.iter().skip(before) {
                if let Ok(Some(mut f)) = d.handle(p, now) {
                    f.validate();
                }
            }
            let _ = d.finish(now);
        }
    }

    #[test]
    fn a_frame_of_a_real_sirf_ii_receiver_round_trips() {
        // The first frame of gpsd's `sirf2.log` (MID 41, Geodetic Navigation Data, 91 bytes): the receiver
        // computed its checksum (0x079A), so building the frame from its payload must give its bytes back.
        let hex = "a0a2005b290001100004f4000003e807d40418173bbb8000000000000000000000000000000000000000001500000000\
                   00000000000000000000000000000000000000000000000000000000001bdff000000000000000000000000000fa0007\
                   9ab0b3";
        let bytes: Vec<u8> =
            (0..hex.len()).step_by(2).map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap()).collect();
        let payload = &bytes[4..bytes.len() - 4];
        assert_eq!(payload.len(), 91);
        assert_eq!(checksum(payload), 0x079A);
        assert_eq!(frame(payload), bytes);
    }

    fn unhex(s: &str) -> Vec<u8> {
        let s: String = s.split_whitespace().collect();
        (0..s.len()).step_by(2).map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap()).collect()
    }

    /// gpsd's `sirfstarv.log` (a `SiRFstarV`, 5xp 5.5.25), the payloads of its first solution: MID 2 and
    /// MID 67 SID 1 of 02:17:14, then the MID 41 that already describes 02:17:15.
    const SIRFSTARV_MID2: &str =
        "02ffdb976fffc426e100435b9c000000000000040902000201981970060c191d050253000000000000000000000000";
    const SIRFSTARV_MID67_1: &str = "4301000000000000000408020ff0fe5f000f420c0000020107e30418021136b0121574c0000041d53a7300000000001bfb\
        38000000001a445c1cb7b0ee5b0001b5f80001bda300003122000000000000009b00000000000006cf000005e90001241c091b\
        1606110008120000000000000008000000000000000000000318";
    const SIRFSTARV_MID41: &str = "290000020408020ff1024807e3041802113a98110008121a445c0db7b0ee590001b5ef0001bd9a150007312200000000\
        000000000694000005f100000000001d5505c9b200000000001bfb38000000000000009b00000000060918";

    #[test]
    fn sirfstarv_mid67_gives_the_position_gpsd_reports() {
        let payloads = [unhex(SIRFSTARV_MID2), unhex(SIRFSTARV_MID67_1), unhex(SIRFSTARV_MID41)];
        assert_eq!(payloads.iter().map(Vec::len).collect::<Vec<_>>(), [47, 126, 91]);
        let fixes = decode_all(&payloads);
        // gpsd's last TPV of 02:17:14 (sirfstarv.log.chk): lat 44.068764400, lon -121.314141300, mode 3,
        // altMSL 1140.83; MID 2's whole ECEF metres alone would give 44.068762281, -121.314137599.
        let f = &fixes[0];
        assert_eq!(f.time.map(time_key).as_deref(), Some("2019-04-24T02:17:14.000Z"));
        assert_eq!(f.mode, Some(FixMode::Fix3D));
        assert!((f.lat_deg.unwrap() - 44.068_764_4).abs() < 1e-9);
        assert!((f.lon_deg.unwrap() + 121.314_141_3).abs() < 1e-9);
        assert!((f.alt_m.unwrap() - 1140.83).abs() < 1e-9);
        assert_eq!(f.sats_used, Some(6));
        // The MID 41 of 02:17:15 opens the next epoch instead of joining this one.
        assert_eq!(fixes[1].time.map(time_key).as_deref(), Some("2019-04-24T02:17:15.000Z"));
        assert!((fixes[1].lat_deg.unwrap() - 44.068_762_9).abs() < 1e-9);
    }

    #[test]
    fn an_invalid_mid67_solution_is_no_fix() {
        let mut mid2 = unhex(SIRFSTARV_MID2);
        let mut mid67 = unhex(SIRFSTARV_MID67_1);
        mid67[5] = 1; // solution validity: not 0
        mid2[19] = 0; // MID 2 mode 1: no solution
        let fixes = decode_all([mid2, mid67]);
        assert_eq!(fixes.len(), 1);
        assert_eq!(fixes[0].mode, Some(FixMode::NoFix));
        assert_eq!(fixes[0].lat_deg, None);
    }

    /// gpsd's `ublox-sirf1.log` (a u-blox TIM with `SiRF`-derived firmware): MID 2 of the first second,
    /// then two MID 98 (a MID 2 between them is left out).
    const UBLOX_MID2: &str =
        "02003bb7f700055ecc004c6735000000000000040902012e03490b6b080b171407010e191800000000";
    const UBLOX_MID98_A: &str =
        "62056a834e0088d97c00013d2d000000170000001805a9df426407d5060b090636af0a04090508";
    const UBLOX_MID98_B: &str =
        "62056a834d0088d97c00013d3d0000001b0000001b05bee42f6407d5060b09063a970a04090508";

    #[test]
    fn ublox_mid98_makes_the_epochs_gpsd_reports() {
        let fixes =
            decode_all([unhex(UBLOX_MID2), unhex(UBLOX_MID98_A), unhex(UBLOX_MID2), unhex(UBLOX_MID98_B)]);
        // gpsd's TPVs (ublox-sirf1.log.chk): 09:06:08.990 from the first MID 2 (lat 52.062675883,
        // lon 5.138600900), then 09:06:13.999 (52.062675221, 5.138613239) and 09:06:14.999 (52.062674648,
        // 5.138613239) from MID 98; the second MID 2 makes no epoch of its own.
        let got: Vec<(String, f64, f64)> = fixes
            .iter()
            .map(|f| (f.time.map(time_key).unwrap_or_default(), f.lat_deg.unwrap(), f.lon_deg.unwrap()))
            .collect();
        let want = [
            ("09:06:08.990Z", 52.062_675_883, 5.138_600_900),
            ("09:06:13.999Z", 52.062_675_221, 5.138_613_239),
            ("09:06:14.999Z", 52.062_674_648, 5.138_613_239),
        ];
        assert_eq!(got.len(), want.len(), "{got:?}");
        for ((t, lat, lon), (wt, wlat, wlon)) in got.iter().zip(want) {
            assert!(t.ends_with(wt), "{t} vs {wt}");
            assert!((lat - wlat).abs() < 1e-7 && (lon - wlon).abs() < 1e-7, "{t}: {lat},{lon}");
        }
        // MID 98's date is the receiver's UTC (2005-06-11); HDOP 9/5, satellites from the MID 2.
        assert!(got[1].0.starts_with("2005-06-11"));
        assert_eq!(fixes[1].hdop, Some(1.8));
        assert_eq!(fixes[1].sats_used, Some(8));
        assert_eq!(fixes[1].mode, Some(FixMode::Fix3D));
    }
}
