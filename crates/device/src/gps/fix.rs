//! The position fix: everything one epoch of NMEA (or one gpsd TPV/SKY pair) says about where we are.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use chrono::{DateTime, NaiveTime, Utc};

/// Fix dimension, as the receiver reports it (GSA mode, gpsd TPV `mode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize)]
pub enum FixMode {
    /// No position (receiver searching, or the fix was lost).
    NoFix,
    /// Horizontal position only.
    Fix2D,
    /// Horizontal position and altitude.
    Fix3D,
}

impl FixMode {
    /// gpsd's numbering: 1 = no fix, 2 = 2D, 3 = 3D.
    pub fn gpsd_number(self) -> u8 {
        match self {
            Self::NoFix => 1,
            Self::Fix2D => 2,
            Self::Fix3D => 3,
        }
    }
}

/// GGA fix quality indicator (field 6), NMEA 0183 4.11 numbering.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum FixQuality {
    /// 0: no fix.
    Invalid,
    /// 1: autonomous GPS/GNSS fix.
    Gps,
    /// 2: differential (DGPS, SBAS/WAAS).
    Dgps,
    /// 3: PPS (military precise positioning service).
    Pps,
    /// 4: RTK with fixed integers.
    Rtk,
    /// 5: RTK float.
    FloatRtk,
    /// 6: estimated (dead reckoning).
    Estimated,
    /// 7: manual input.
    Manual,
    /// 8: simulation.
    Simulation,
}

impl FixQuality {
    /// From the GGA quality digit; `None` for digits outside 0..=8.
    pub fn from_digit(d: u8) -> Option<Self> {
        Some(match d {
            0 => Self::Invalid,
            1 => Self::Gps,
            2 => Self::Dgps,
            3 => Self::Pps,
            4 => Self::Rtk,
            5 => Self::FloatRtk,
            6 => Self::Estimated,
            7 => Self::Manual,
            8 => Self::Simulation,
            _ => return None,
        })
    }

    /// The GGA quality digit.
    pub fn digit(self) -> u8 {
        self as u8
    }

    /// True for qualities that carry a usable position (everything except invalid).
    pub fn has_position(self) -> bool {
        self != Self::Invalid
    }

    /// True for corrected fixes (DGPS, RTK), which get the smaller UERE in the DOP error model.
    pub fn is_differential(self) -> bool {
        matches!(self, Self::Dgps | Self::Rtk | Self::FloatRtk)
    }
}

/// A satellite navigation system.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize)]
pub enum Constellation {
    /// US GPS (talker GP; PRN 1–32).
    Gps,
    /// SBAS (WAAS/EGNOS/MSAS; PRN 33–64 or 120–158).
    Sbas,
    /// Russian GLONASS (talker GL; NMEA ids 65–96).
    Glonass,
    /// European Galileo (talker GA).
    Galileo,
    /// Chinese `BeiDou` (talkers GB, BD).
    Beidou,
    /// Japanese QZSS (talker GQ; PRN 193–202).
    Qzss,
    /// Indian NavIC/IRNSS (talker GI).
    Navic,
    /// Not known (a GN sentence with an id outside the known ranges).
    Unknown,
}

impl Constellation {
    /// The constellation a talker id names, `None` for GN (mixed) and non-GNSS talkers.
    pub fn from_talker(talker: &str) -> Option<Self> {
        Some(match talker {
            "GP" => Self::Gps,
            "GL" => Self::Glonass,
            "GA" => Self::Galileo,
            "GB" | "BD" => Self::Beidou,
            "GQ" | "QZ" => Self::Qzss,
            "GI" => Self::Navic,
            _ => return None,
        })
    }

    /// The constellation of an NMEA satellite id in the mixed (GN) numbering (NMEA 0183 4.x; gpsd's
    /// `NMEA.html` table): 1–32 GPS, 33–64 SBAS, 65–96 GLONASS, 120–158 SBAS, 193–202 QZSS,
    /// 201–237 and 401–437 `BeiDou`, 301–336 Galileo.
    pub fn from_nmea_id(id: u16) -> Self {
        match id {
            1..=32 => Self::Gps,
            33..=64 | 120..=158 => Self::Sbas,
            65..=96 => Self::Glonass,
            193..=200 => Self::Qzss,
            201..=237 | 401..=437 => Self::Beidou,
            301..=336 => Self::Galileo,
            _ => Self::Unknown,
        }
    }

    /// From the NMEA 4.11 GSA/GSV system id digit (1 GPS, 2 GLONASS, 3 Galileo, 4 `BeiDou`, 5 QZSS, 6 `NavIC`).
    pub fn from_system_id(id: u8) -> Option<Self> {
        Some(match id {
            1 => Self::Gps,
            2 => Self::Glonass,
            3 => Self::Galileo,
            4 => Self::Beidou,
            5 => Self::Qzss,
            6 => Self::Navic,
            _ => return None,
        })
    }
}

/// One satellite in view.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Satellite {
    /// Satellite id as sent in the GSV sentence.
    pub prn: u16,
    /// Its navigation system.
    pub constellation: Constellation,
    /// Elevation above the horizon [deg], when sent.
    pub elevation_deg: Option<f64>,
    /// Azimuth from true north [deg], when sent.
    pub azimuth_deg: Option<f64>,
    /// Carrier-to-noise ratio [dB-Hz], `None` when not tracked.
    pub snr_dbhz: Option<f64>,
    /// True when a GSA sentence lists it as used in the fix.
    pub used: bool,
}

impl Satellite {
    /// One satellite of a binary receiver message (UBX, CASIC, `SkyTraq`): elevation and azimuth in whole
    /// degrees, C/N0 in dB-Hz. An elevation outside -90..=90 or an azimuth outside 0..=360 is "not known"
    /// (u-blox sends -91), and a C/N0 of 0 means not tracked.
    pub(crate) fn from_binary(id: (Constellation, u16), elev: i16, azim: i16, cno: u8, used: bool) -> Self {
        Self {
            prn: id.1,
            constellation: id.0,
            elevation_deg: (-90..=90).contains(&elev).then_some(f64::from(elev)),
            azimuth_deg: (0..=360).contains(&azim).then_some(f64::from(azim)),
            snr_dbhz: (cno > 0).then_some(f64::from(cno)),
            used,
        }
    }
}

/// Where the error estimate of a fix comes from.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum ErrorSource {
    /// The receiver's own GST pseudorange error statistics (1-sigma latitude/longitude/altitude).
    Gst,
    /// Garmin's `$PGRME` estimated position error.
    Pgrme,
    /// u-blox UBX accuracy estimates (NAV-PVT / NAV-POSLLH `hAcc`, `vAcc`).
    Ubx,
    /// `SiRF` binary estimated horizontal/vertical position error (MID 41 `EHPE`, `EVPE`).
    Sirf,
    /// CASIC NAV-PV `hAcc`/`vAcc` (sent as variances; the square roots).
    Casic,
    /// gpsd's `eph`/`epv` (its own DOP model unless the receiver sent GST/PGRME; confidence unspecified).
    Gpsd,
    /// Our DOP model: `sigma_h = HDOP * UERE`, `sigma_v = VDOP * UERE` (see [`crate::gps::UERE_M`]).
    DopModel {
        /// The user equivalent range error used [m, 1 sigma].
        uere_m: f64,
    },
}

impl ErrorSource {
    /// Where the figure comes from, in a word or two for the operator: the receiver's own estimate
    /// ("UBX hAcc", "GST", "PGRME", "`SiRF` EHPE"), gpsd's ("gpsd eph") or our DOP model ("HDOP x 5 m").
    pub fn describe(&self) -> String {
        match self {
            ErrorSource::Gst => "GST".to_owned(),
            ErrorSource::Pgrme => "PGRME".to_owned(),
            ErrorSource::Ubx => "UBX hAcc".to_owned(),
            ErrorSource::Sirf => "SiRF EHPE".to_owned(),
            ErrorSource::Casic => "CASIC hAcc".to_owned(),
            ErrorSource::Gpsd => "gpsd eph".to_owned(),
            ErrorSource::DopModel { uere_m } => format!("HDOP x {uere_m} m"),
        }
    }
}

/// An estimate of the position error.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ErrorEstimate {
    /// Horizontal 1-sigma error, `sqrt(sigma_lat^2 + sigma_lon^2)` [m] (2D RMS, "DRMS").
    pub horizontal_m: f64,
    /// Vertical 1-sigma error [m], when known.
    pub vertical_m: Option<f64>,
    /// Where the numbers come from.
    pub source: ErrorSource,
}

/// One fix: the receiver's state at the end of one epoch. Everything the receiver did not say is `None`.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Fix {
    /// UTC date and time of the epoch, when both the time and the date are known.
    pub time: Option<DateTime<Utc>>,
    /// UTC time of day of the epoch (known even before the first date arrives).
    pub time_of_day: Option<NaiveTime>,
    /// Latitude [deg], north positive.
    pub lat_deg: Option<f64>,
    /// Longitude [deg], east positive.
    pub lon_deg: Option<f64>,
    /// Altitude above mean sea level [m].
    pub alt_m: Option<f64>,
    /// Geoid separation (WGS-84 ellipsoid minus mean sea level) [m].
    pub geoid_sep_m: Option<f64>,
    /// Fix dimension.
    pub mode: Option<FixMode>,
    /// GGA quality.
    pub quality: Option<FixQuality>,
    /// Speed over ground [m/s].
    pub speed_m_s: Option<f64>,
    /// Course over ground, true [deg].
    pub course_deg: Option<f64>,
    /// True heading from HDT/THS [deg] (dual-antenna or compass receivers).
    pub true_heading_deg: Option<f64>,
    /// Satellites used in the fix (GSA id count, else the GGA/GNS count).
    pub sats_used: Option<u32>,
    /// Satellites in view (GSV total over all constellations).
    pub sats_visible: Option<u32>,
    /// Satellites used, per constellation (from GSA ids).
    pub sats_used_by: BTreeMap<Constellation, u32>,
    /// Satellites in view, per constellation (from GSV).
    pub sats_visible_by: BTreeMap<Constellation, u32>,
    /// The satellites in view.
    pub satellites: Vec<Satellite>,
    /// Horizontal dilution of precision.
    pub hdop: Option<f64>,
    /// Position (3D) dilution of precision.
    pub pdop: Option<f64>,
    /// Vertical dilution of precision.
    pub vdop: Option<f64>,
    /// Error estimate (GST/PGRME when sent, else the DOP model).
    pub error: Option<ErrorEstimate>,
    /// Monotonic time the epoch was completed at (not serialised); see [`Fix::age`].
    #[serde(skip)]
    pub received_at: Option<Instant>,
}

impl Fix {
    /// Takes a binary receiver's (or gpsd's) satellite list as the fix's sky: the list, how many are in
    /// view, and per constellation how many are in view and used. The total used (`sats_used`) is left to
    /// the caller, as receivers state it apart from the list.
    pub fn set_sky(&mut self, satellites: Vec<Satellite>) {
        self.sats_visible = u32::try_from(satellites.len()).ok();
        self.sats_visible_by.clear();
        self.sats_used_by.clear();
        for s in &satellites {
            *self.sats_visible_by.entry(s.constellation).or_default() += 1;
            if s.used {
                *self.sats_used_by.entry(s.constellation).or_default() += 1;
            }
        }
        self.satellites = satellites;
    }

    /// True when the fix carries a position (mode 2D/3D and lat/lon present).
    pub fn has_position(&self) -> bool {
        matches!(self.mode, Some(FixMode::Fix2D | FixMode::Fix3D))
            && self.lat_deg.is_some()
            && self.lon_deg.is_some()
    }

    /// True when the fix is good enough to average into a reference position: a measured quality
    /// (autonomous, differential, PPS, RTK fixed or float; not estimated, manual or simulated) when the
    /// quality is known, and a 3-D fix when the mode is known.
    pub fn good_for_reference(&self) -> bool {
        self.quality.is_none_or(|q| {
            matches!(
                q,
                FixQuality::Gps | FixQuality::Dgps | FixQuality::Pps | FixQuality::Rtk | FixQuality::FloatRtk
            )
        }) && self.mode.is_none_or(|m| m == FixMode::Fix3D)
    }

    /// Age of the fix at `now` (time since its epoch was completed), when the receive time is known.
    pub fn age(&self, now: Instant) -> Option<Duration> {
        self.received_at.map(|t| now.saturating_duration_since(t))
    }
}

/// Largest plausible count of satellites used or in view, and the longest satellite list kept.
///
/// All GNSS constellations together have about 150 satellites in orbit (GPS 31, GLONASS 24, Galileo 28,
/// `BeiDou` 45+, QZSS 7, `NavIC` 7, SBAS ~20), and less than half of them are above one horizon; NMEA GSV
/// cannot number more than 99 sentences x 4. 256 leaves room for every future constellation while a count
/// like 10 100 (a corrupted field) is refused, and caps what a hostile source can make us store per fix.
pub const MAX_SATELLITES: u32 = 256;
/// Lowest plausible altitude above mean sea level [m]: the Dead Sea shore is at -430 m; -1000 m leaves
/// room for mines and a poor geoid model, nothing a navigation receiver on a person goes below.
pub const MIN_ALT_M: f64 = -1000.0;
/// Highest plausible altitude [m]: 100 km is the Kármán line; consumer receivers stop reporting at 18 km
/// (the COCOM export limit), so anything above is corrupted input.
pub const MAX_ALT_M: f64 = 100_000.0;
/// Largest plausible geoid separation magnitude [m]: EGM96 ranges from -107 m to +86 m.
pub const MAX_GEOID_SEP_M: f64 = 200.0;
/// Largest plausible speed over ground [m/s]: civil receivers must stop reporting above 1000 kn
/// (514 m/s, the COCOM limit); the margin covers rounding.
pub const MAX_SPEED_M_S: f64 = 600.0;
/// A negative speed down to this much [m/s] is a printed or rounded zero ("-0.0", "-0.001") and becomes 0.
pub const SPEED_ZERO_TOLERANCE_M_S: f64 = 0.01;
/// Largest plausible dilution of precision: receivers print 99.9 or 99.99 for "unknown"; a larger value is
/// not a satellite geometry, and multiplied by the UERE it would give error circles larger than a city.
pub const MAX_DOP: f64 = 100.0;
/// Largest plausible 1-sigma error estimate [m]: 100 km. Even a dead-reckoning fix with HDOP 99.99 has a
/// DOP-model error of 500 m; a larger "estimate" says nothing and would make the map draw a circle
/// covering the continent (the kind of value that froze the UI in the "Safety first" issue).
pub const MAX_ERROR_M: f64 = 100_000.0;
/// A course or heading in [-360, 720) [deg] is normalised into [0, 360); anything further out is not an
/// angle a receiver meant to send.
pub const COURSE_RANGE_DEG: (f64, f64) = (-360.0, 720.0);
/// Highest plausible carrier-to-noise ratio [dB-Hz]: open-sky signals reach ~55; NMEA GSV allows 0–99.
pub const MAX_SNR_DBHZ: f64 = 99.0;

/// What [`Fix::validate`] removed or corrected.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FixCheck {
    /// The position was not finite or out of range (|lat| > 90°, |lon| > 180°) and was removed; the fix
    /// became [`FixMode::NoFix`].
    pub invalid_position: bool,
    /// Other values that were implausible and were removed (set to `None`) or corrected (a course
    /// normalised, an overlong satellite list cut).
    pub implausible_values: u32,
}

impl FixCheck {
    /// True when nothing was removed or corrected.
    pub fn is_clean(&self) -> bool {
        !self.invalid_position && self.implausible_values == 0
    }

    /// Adds these counts to decoder statistics ([`DecodeStats::invalid_positions`],
    /// [`DecodeStats::implausible_values`]).
    ///
    /// [`DecodeStats::invalid_positions`]: super::DecodeStats::invalid_positions
    /// [`DecodeStats::implausible_values`]: super::DecodeStats::implausible_values
    pub fn count_into(&self, stats: &mut super::DecodeStats) {
        stats.invalid_positions += u64::from(self.invalid_position);
        stats.implausible_values += u64::from(self.implausible_values);
    }
}

/// Keeps `v` if it is finite and within `lo..=hi`; counts a removal.
fn keep_in(v: &mut Option<f64>, lo: f64, hi: f64, removed: &mut u32) {
    if let Some(x) = *v
        && !(x.is_finite() && (lo..=hi).contains(&x))
    {
        *v = None;
        *removed += 1;
    }
}

/// An angle in [0, 360): finite values within [`COURSE_RANGE_DEG`] are normalised (counted), others
/// removed (counted).
fn keep_angle(v: &mut Option<f64>, changed: &mut u32) {
    let Some(x) = *v else { return };
    if (0.0..360.0).contains(&x) {
        return;
    }
    *changed += 1;
    *v = if x.is_finite() && (COURSE_RANGE_DEG.0..COURSE_RANGE_DEG.1).contains(&x) {
        // rem_euclid of a value just below 0 can round up to 360 itself.
        Some(x.rem_euclid(360.0)).filter(|a| *a < 360.0).or(Some(0.0))
    } else {
        None
    };
}

/// Keeps a count if it is at most [`MAX_SATELLITES`]; counts a removal.
fn keep_count(v: &mut Option<u32>, removed: &mut u32) {
    if v.is_some_and(|n| n > MAX_SATELLITES) {
        *v = None;
        *removed += 1;
    }
}

impl Fix {
    /// Checks every value against physical bounds, in place, before the fix leaves the decoder (NMEA and
    /// gpsd alike): input from a device or a network is untrusted.
    ///
    /// - position: latitude and longitude must both be finite with |lat| <= 90° and |lon| <= 180°; else
    ///   both are removed, the error estimate with them, and the mode becomes [`FixMode::NoFix`]
    ///   ([`FixCheck::invalid_position`]);
    /// - altitude within [[`MIN_ALT_M`], [`MAX_ALT_M`]], geoid separation within ±[`MAX_GEOID_SEP_M`];
    /// - DOPs finite and within [0, [`MAX_DOP`]] (a negative DOP would give a negative error estimate);
    /// - speed finite and within [0, [`MAX_SPEED_M_S`]]; a negative speed down to
    ///   -[`SPEED_ZERO_TOLERANCE_M_S`] (a printed "-0.0") becomes 0 without being counted;
    /// - course and true heading finite; outside [0, 360) they are normalised when within
    ///   [`COURSE_RANGE_DEG`], else removed;
    /// - satellite counts (total and per constellation) at most [`MAX_SATELLITES`]; the satellite list is
    ///   cut to [`MAX_SATELLITES`] entries; each satellite's elevation within ±90°, azimuth normalised like a
    ///   course, SNR within [0, [`MAX_SNR_DBHZ`]];
    /// - error estimate: horizontal finite and within [0, [`MAX_ERROR_M`]] (else the estimate is removed),
    ///   vertical likewise (else only it is removed);
    /// - date: the UTC date and time are removed (the time of day kept) when the date is outside the GPS
    ///   era, 1980-01-06 to 2099-12-31 ([`super::assembly::in_gps_era`]; the NMEA decoder also checks each
    ///   date against the previous epochs' and counts its rejections in
    ///   [`DecodeStats::implausible_dates`](super::DecodeStats::implausible_dates)).
    ///
    /// Every removal or correction other than the position is counted in
    /// [`FixCheck::implausible_values`]; values that pass are left bit for bit as they were.
    pub fn validate(&mut self) -> FixCheck {
        let mut check = FixCheck::default();
        let n = &mut check.implausible_values;
        let lat_bad = self.lat_deg.is_some_and(|x| !(x.is_finite() && (-90.0..=90.0).contains(&x)));
        let lon_bad = self.lon_deg.is_some_and(|x| !(x.is_finite() && (-180.0..=180.0).contains(&x)));
        // One coordinate without the other is not a position, whatever the mode claims.
        let half = self.lat_deg.is_some() != self.lon_deg.is_some();
        if lat_bad || lon_bad || half {
            self.lat_deg = None;
            self.lon_deg = None;
            self.error = None;
            self.mode = Some(FixMode::NoFix);
            check.invalid_position = true;
        }
        keep_in(&mut self.alt_m, MIN_ALT_M, MAX_ALT_M, n);
        keep_in(&mut self.geoid_sep_m, -MAX_GEOID_SEP_M, MAX_GEOID_SEP_M, n);
        keep_in(&mut self.hdop, 0.0, MAX_DOP, n);
        keep_in(&mut self.pdop, 0.0, MAX_DOP, n);
        keep_in(&mut self.vdop, 0.0, MAX_DOP, n);
        if let Some(v) = self.speed_m_s
            && (-SPEED_ZERO_TOLERANCE_M_S..=0.0).contains(&v)
        {
            self.speed_m_s = Some(0.0);
        }
        keep_in(&mut self.speed_m_s, 0.0, MAX_SPEED_M_S, n);
        keep_angle(&mut self.course_deg, n);
        keep_angle(&mut self.true_heading_deg, n);
        keep_count(&mut self.sats_used, n);
        keep_count(&mut self.sats_visible, n);
        for map in [&mut self.sats_used_by, &mut self.sats_visible_by] {
            let before = map.len();
            map.retain(|_, c| *c <= MAX_SATELLITES);
            *n += (before - map.len()) as u32;
        }
        if self.satellites.len() > MAX_SATELLITES as usize {
            self.satellites.truncate(MAX_SATELLITES as usize);
            *n += 1;
        }
        for s in &mut self.satellites {
            keep_in(&mut s.elevation_deg, -90.0, 90.0, n);
            keep_angle(&mut s.azimuth_deg, n);
            keep_in(&mut s.snr_dbhz, 0.0, MAX_SNR_DBHZ, n);
        }
        if self.time.is_some_and(|t| !super::assembly::in_gps_era(t.date_naive())) {
            self.time = None;
            *n += 1;
        }
        if let Some(e) = &mut self.error {
            if e.horizontal_m.is_finite() && (0.0..=MAX_ERROR_M).contains(&e.horizontal_m) {
                keep_in(&mut e.vertical_m, 0.0, MAX_ERROR_M, n);
            } else {
                self.error = None;
                *n += 1;
            }
        }
        check
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sky_list_is_counted_per_constellation_and_replaces_the_last() {
        let sat = |prn, constellation, used| Satellite {
            prn,
            constellation,
            elevation_deg: None,
            azimuth_deg: None,
            snr_dbhz: Some(40.0),
            used,
        };
        let mut f = Fix::default();
        f.set_sky(vec![sat(1, Constellation::Beidou, true)]);
        f.set_sky(vec![
            sat(3, Constellation::Gps, true),
            sat(7, Constellation::Gps, false),
            sat(70, Constellation::Glonass, true),
        ]);
        assert_eq!(f.sats_visible, Some(3));
        assert_eq!(f.sats_used, None, "the receiver's own total is the caller's");
        let by = |m: &BTreeMap<Constellation, u32>| m.iter().map(|(c, n)| (*c, *n)).collect::<Vec<_>>();
        assert_eq!(by(&f.sats_visible_by), [(Constellation::Gps, 2), (Constellation::Glonass, 1)]);
        assert_eq!(by(&f.sats_used_by), [(Constellation::Gps, 1), (Constellation::Glonass, 1)]);
        assert_eq!(f.satellites.len(), 3);
    }

    fn good() -> Fix {
        Fix {
            lat_deg: Some(57.163_445),
            lon_deg: Some(-2.121_37),
            alt_m: Some(59.3),
            geoid_sep_m: Some(48.2),
            mode: Some(FixMode::Fix3D),
            speed_m_s: Some(1.2),
            course_deg: Some(359.9),
            sats_used: Some(8),
            sats_visible: Some(12),
            hdop: Some(1.0),
            pdop: Some(1.8),
            vdop: Some(1.5),
            error: Some(ErrorEstimate {
                horizontal_m: 5.0,
                vertical_m: Some(7.5),
                source: ErrorSource::Gpsd,
            }),
            ..Fix::default()
        }
    }

    #[test]
    fn plausible_fixes_pass_unchanged() {
        let mut f = good();
        assert!(f.validate().is_clean());
        assert_eq!(f, good());
        // The edges of every range are inside it.
        for (lat, lon) in [(90.0, 180.0), (-90.0, -180.0), (0.0, 0.0)] {
            let mut f = Fix { lat_deg: Some(lat), lon_deg: Some(lon), ..good() };
            assert!(f.validate().is_clean(), "{lat} {lon}");
            assert!(f.has_position());
        }
        let mut f = Fix { alt_m: Some(-430.0), speed_m_s: Some(0.0), course_deg: Some(0.0), ..good() };
        assert!(f.validate().is_clean());
    }

    #[test]
    fn invalid_positions_become_no_fix() {
        let cases = [
            (Some(57.0), Some(-1e15)),
            (Some(91.0), Some(181.0)),
            (Some(9999.0), Some(2.0)),
            (Some(1e20), Some(2.0)),
            (Some(f64::NAN), Some(2.0)),
            (Some(2.0), Some(f64::INFINITY)),
            (Some(-90.000_001), Some(0.0)),
            (Some(0.0), Some(180.000_001)),
            (None, Some(f64::NEG_INFINITY)),
        ];
        for (lat, lon) in cases {
            let mut f = Fix { lat_deg: lat, lon_deg: lon, ..good() };
            let c = f.validate();
            assert!(c.invalid_position, "{lat:?} {lon:?}");
            assert_eq!(c.implausible_values, 0);
            assert!(!f.has_position());
            assert_eq!((f.lat_deg, f.lon_deg, f.mode, f.error), (None, None, Some(FixMode::NoFix), None));
        }
    }

    #[test]
    fn implausible_values_are_removed_or_normalised() {
        let mut f = Fix {
            alt_m: Some(1e7),
            geoid_sep_m: Some(f64::NAN),
            hdop: Some(-1.0),
            pdop: Some(f64::INFINITY),
            vdop: Some(1e6),
            speed_m_s: Some(-5.0),
            course_deg: Some(400.0),
            true_heading_deg: Some(-90.0),
            sats_used: Some(10_100),
            sats_visible: Some(257),
            error: Some(ErrorEstimate { horizontal_m: -3.0, vertical_m: None, source: ErrorSource::Gpsd }),
            ..good()
        };
        let c = f.validate();
        assert!(!c.invalid_position);
        assert_eq!(c.implausible_values, 11);
        assert!(f.has_position());
        assert_eq!((f.alt_m, f.geoid_sep_m, f.hdop, f.pdop, f.vdop), (None, None, None, None, None));
        assert_eq!((f.speed_m_s, f.sats_used, f.sats_visible, f.error), (None, None, None, None));
        assert!((f.course_deg.unwrap() - 40.0).abs() < 1e-12);
        assert!((f.true_heading_deg.unwrap() - 270.0).abs() < 1e-12);
    }

    #[test]
    fn edge_cases_of_speed_course_and_error() {
        // A printed "-0.0" or a rounding negative is a zero speed, not an error.
        for v in [-0.0, -0.004] {
            let mut f = Fix { speed_m_s: Some(v), ..good() };
            assert!(f.validate().is_clean());
            assert_eq!(f.speed_m_s.map(f64::to_bits), Some(0.0f64.to_bits()));
        }
        // Courses: 360 is north; a tiny negative rounds to 360 in rem_euclid and must become 0; far out is
        // not an angle; NaN is not a course.
        for (c, want) in
            [(360.0, Some(0.0)), (-1e-20, Some(0.0)), (1e6, None), (f64::NAN, None), (-360.0, Some(0.0))]
        {
            let mut f = Fix { course_deg: Some(c), ..good() };
            assert_eq!(f.validate().implausible_values, 1, "{c}");
            assert_eq!(f.course_deg, want, "{c}");
        }
        // A bad vertical error removes only itself; a bad horizontal one the whole estimate.
        let mut f = Fix {
            error: Some(ErrorEstimate {
                horizontal_m: 4.0,
                vertical_m: Some(-1.0),
                source: ErrorSource::Gpsd,
            }),
            ..good()
        };
        assert_eq!(f.validate().implausible_values, 1);
        assert_eq!(f.error.map(|e| (e.horizontal_m, e.vertical_m)), Some((4.0, None)));
    }

    #[test]
    fn satellite_lists_and_counts_are_capped() {
        let sat = Satellite {
            prn: 5,
            constellation: Constellation::Gps,
            elevation_deg: Some(45.0),
            azimuth_deg: Some(90.0),
            snr_dbhz: Some(40.0),
            used: true,
        };
        let mut f = Fix { satellites: vec![sat; 10_100], ..good() };
        f.sats_used_by.insert(Constellation::Gps, 10_100);
        f.sats_visible_by.insert(Constellation::Gps, 12);
        let c = f.validate();
        assert_eq!(f.satellites.len(), MAX_SATELLITES as usize);
        assert_eq!(c.implausible_values, 2, "the list cut, the per-constellation count removed");
        assert!(f.sats_used_by.is_empty());
        assert_eq!(f.sats_visible_by.get(&Constellation::Gps), Some(&12));
        let bad =
            Satellite { elevation_deg: Some(91.0), azimuth_deg: Some(f64::NAN), snr_dbhz: Some(-1.0), ..sat };
        let mut f = Fix { satellites: vec![bad], ..good() };
        assert_eq!(f.validate().implausible_values, 3);
        assert_eq!(f.satellites[0].elevation_deg, None);
    }
}
