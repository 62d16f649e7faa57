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

/// Where the error estimate of a fix comes from.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum ErrorSource {
    /// The receiver's own GST pseudorange error statistics (1-sigma latitude/longitude/altitude).
    Gst,
    /// Garmin's `$PGRME` estimated position error.
    Pgrme,
    /// gpsd's `eph`/`epv` (its own DOP model unless the receiver sent GST/PGRME; confidence unspecified).
    Gpsd,
    /// Our DOP model: `sigma_h = HDOP * UERE`, `sigma_v = VDOP * UERE` (see [`crate::gps::UERE_M`]).
    DopModel {
        /// The user equivalent range error used [m, 1 sigma].
        uere_m: f64,
    },
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
    /// True when the fix carries a position (mode 2D/3D and lat/lon present).
    pub fn has_position(&self) -> bool {
        matches!(self.mode, Some(FixMode::Fix2D | FixMode::Fix3D))
            && self.lat_deg.is_some()
            && self.lon_deg.is_some()
    }

    /// Age of the fix at `now` (time since its epoch was completed), when the receive time is known.
    pub fn age(&self, now: Instant) -> Option<Duration> {
        self.received_at.map(|t| now.saturating_duration_since(t))
    }
}
