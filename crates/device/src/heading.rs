//! One heading reading, whatever produced it: the vest's magnetometer (WTCU protocol v2 HEADING reports),
//! an external NMEA compass (HDG), or gpsd's ATT messages.
//!
//! True heading from a dual-antenna receiver (HDT, THS) stays part of its epoch
//! ([`crate::gps::Fix::true_heading_deg`]); an [`Attitude`] is a reading that stands on its own, timed by
//! when its bytes arrived like a fix, so its age is computed the same way everywhere.

use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

/// What north a heading is measured from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HeadingReference {
    /// Magnetic north: add the declination (WMM, `vestnav_core::geo::declination_deg`) for true north.
    Magnetic,
    /// True (geographic) north.
    True,
}

/// Which device a heading came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HeadingOrigin {
    /// The WTCU's tilt-compensated magnetometer (protocol v2).
    Vest,
    /// An NMEA sentence from the GPS input (HDG from an external compass).
    Nmea,
    /// A gpsd ATT message.
    Gpsd,
}

/// One heading (and, when the source gives them, attitude) reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Attitude {
    /// Heading of the body's forward axis in [0, 360) \[deg\], clockwise from `reference` north.
    pub heading_deg: f64,
    /// What north `heading_deg` is measured from.
    pub reference: HeadingReference,
    /// Pitch, nose up positive \[deg\], if known.
    pub pitch_deg: Option<f64>,
    /// Roll, right side down positive \[deg\], if known.
    pub roll_deg: Option<f64>,
    /// Calibration/field quality 0..=100 (100 = the measured field matches the calibrated field exactly;
    /// 0 = uncalibrated or badly disturbed), if the source gives one.
    pub quality_pct: Option<u8>,
    /// Strength of the measured magnetic field \[µT\], if known (a disturbed field differs from the
    /// WMM's at the place).
    pub field_ut: Option<f64>,
    /// The raw (uncalibrated) magnetometer reading, body frame x forward, y right, z down \[µT\], when
    /// the source gives it (the vest): what the console's calibration fit works on.
    pub raw_mag_ut: Option<[f64; 3]>,
    /// The device that produced it.
    pub origin: HeadingOrigin,
    /// When its bytes arrived (the one clock for ages, as for fixes).
    pub received_at: Instant,
}

impl Attitude {
    /// How old the reading is at `now`.
    pub fn age(&self, now: Instant) -> Duration {
        now.saturating_duration_since(self.received_at)
    }

    /// Checks the numbers at the boundary: a finite heading in [0, 360], pitch within ±90°, roll within
    /// ±180°, quality at most 100, a finite non-negative field. `Err` names the first bad value.
    pub fn validate(&self) -> Result<(), &'static str> {
        if !(self.heading_deg.is_finite() && (0.0..=360.0).contains(&self.heading_deg)) {
            return Err("heading outside 0..360°");
        }
        if self.pitch_deg.is_some_and(|p| !(p.is_finite() && p.abs() <= 90.0)) {
            return Err("pitch outside ±90°");
        }
        if self.roll_deg.is_some_and(|r| !(r.is_finite() && r.abs() <= 180.0)) {
            return Err("roll outside ±180°");
        }
        if self.quality_pct.is_some_and(|q| q > 100) {
            return Err("quality above 100");
        }
        if self.field_ut.is_some_and(|f| !(f.is_finite() && f >= 0.0)) {
            return Err("negative or non-finite field strength");
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reading(heading_deg: f64) -> Attitude {
        Attitude {
            heading_deg,
            reference: HeadingReference::Magnetic,
            pitch_deg: Some(3.0),
            roll_deg: Some(-2.0),
            quality_pct: Some(90),
            field_ut: Some(51.0),
            raw_mag_ut: None,
            origin: HeadingOrigin::Vest,
            received_at: Instant::now(),
        }
    }

    #[test]
    fn validation_names_the_bad_value() {
        assert_eq!(reading(359.9).validate(), Ok(()));
        assert!(reading(f64::NAN).validate().unwrap_err().contains("heading"));
        assert!(reading(400.0).validate().is_err());
        let mut r = reading(10.0);
        r.pitch_deg = Some(95.0);
        assert!(r.validate().unwrap_err().contains("pitch"));
        let mut r = reading(10.0);
        r.quality_pct = Some(101);
        assert!(r.validate().unwrap_err().contains("quality"));
    }
}
