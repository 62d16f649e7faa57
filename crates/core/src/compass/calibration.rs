//! The hard/soft-iron calibration, its quality figure and its fixed-point wire form.

use serde::{Deserialize, Serialize};

use super::tilt::norm3;

/// Scale of the hard iron and field strength on the wire: units of 0.1 µT.
pub const WIRE_UT_PER_LSB: f64 = 0.1;
/// Scale of the soft-iron matrix on the wire: Q12, `value * 4096`.
pub const WIRE_Q12_ONE: f64 = 4096.0;

/// A magnetometer calibration: `h = W (m - b)`, hard iron `b`, soft iron `W` (symmetric positive definite
/// when it comes from [`super::fit_calibration`]), scaled so an undisturbed Earth field has magnitude
/// `field_ut`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Hard-iron offset `b` in raw sensor units [µT], subtracted first.
    pub hard_iron_ut: [f64; 3],
    /// Soft-iron correction `W`, row-major, applied after the offset (dimensionless).
    pub soft_iron: [[f64; 3]; 3],
    /// Reference field strength `F` the corrected field should have [µT] (WMM total intensity at the place,
    /// or the fitted mean radius); 0 means unknown.
    pub field_ut: f64,
}

impl Default for Calibration {
    /// The identity calibration (`b = 0`, `W = I`) with an unknown reference field (`field_ut = 0`).
    fn default() -> Self {
        Self::identity(0.0)
    }
}

impl Calibration {
    /// The identity calibration with reference field `field_ut` [µT]: raw readings pass through unchanged.
    pub const fn identity(field_ut: f64) -> Self {
        Self {
            hard_iron_ut: [0.0; 3],
            soft_iron: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            field_ut,
        }
    }

    /// Corrects a raw reading: `h = W (m - b)` [µT].
    pub fn apply(&self, raw_ut: [f64; 3]) -> [f64; 3] {
        let d = [0, 1, 2].map(|i| raw_ut[i] - self.hard_iron_ut[i]);
        self.soft_iron.map(|row| row[0] * d[0] + row[1] * d[1] + row[2] * d[2])
    }

    /// Quality of one corrected reading, 0–100 %: `round(100 max(0, 1 - 2 | |h| - F | / F))`.
    ///
    /// An undisturbed, well-calibrated field has `|h| = F` and scores 100; every 1 % of magnitude error
    /// costs 2 points, so 10 % off scores 80 and 50 % off scores 0. A field magnitude error of `e F` from a
    /// disturbance perpendicular to the horizontal field turns the heading by up to `atan(e F / H)`, so at a
    /// dip of 66° (`F/H = 2.5`) a score of 90 can hide a heading error of ~7°: a high score is necessary,
    /// not sufficient. Returns 0 when `field_ut` is not positive and finite (no reference: the caller shows
    /// "uncalibrated") or the reading is not finite.
    pub fn quality_pct(&self, corrected_ut: [f64; 3]) -> u8 {
        let f = self.field_ut;
        let m = norm3(corrected_ut);
        if !(f > 0.0 && f.is_finite() && m.is_finite()) {
            return 0;
        }
        let q = (1.0 - 2.0 * (m - f).abs() / f).max(0.0);
        (100.0 * q).round() as u8
    }

    /// The fixed-point wire form (see [`CalibrationWire`]); rounds to the nearest step and rejects values
    /// that do not fit rather than wrapping them.
    pub fn to_wire(&self) -> Result<CalibrationWire, WireError> {
        let mut hard_iron_dut = [0_i16; 3];
        for (out, &v) in hard_iron_dut.iter_mut().zip(&self.hard_iron_ut) {
            *out = to_i16("hard iron [µT]", v, 1.0 / WIRE_UT_PER_LSB)?;
        }
        let mut soft_iron_q12 = [0_i16; 9];
        for (out, &v) in soft_iron_q12.iter_mut().zip(self.soft_iron.iter().flatten()) {
            *out = to_i16("soft iron", v, WIRE_Q12_ONE)?;
        }
        let scaled = (self.field_ut / WIRE_UT_PER_LSB).round();
        if !(0.0..=f64::from(u16::MAX)).contains(&scaled) {
            return Err(WireError::OutOfRange {
                quantity: "field [µT]",
                value: self.field_ut,
                min: 0.0,
                max: f64::from(u16::MAX) * WIRE_UT_PER_LSB,
            });
        }
        Ok(CalibrationWire { hard_iron_dut, soft_iron_q12, field_dut: scaled as u16 })
    }

    /// Checks that the calibration can be used: finite numbers, a symmetric positive definite soft-iron
    /// matrix (within 1e-3, the wire's Q12 rounding), and a positive reference field. A unit refuses a
    /// calibration that fails (NAK), keeping its previous one.
    pub fn check(&self) -> Result<(), CalibrationError> {
        let w = &self.soft_iron;
        let finite = self.hard_iron_ut.iter().chain(w.iter().flatten()).all(|v| v.is_finite());
        let field_ok = self.field_ut.is_finite() && self.field_ut > 0.0;
        if !(finite && field_ok) {
            return Err(CalibrationError::NotFinite);
        }
        let symmetric = (0..3).all(|i| (0..3).all(|j| (w[i][j] - w[j][i]).abs() <= 1e-3));
        // Sylvester's criterion: every leading principal minor positive.
        let m1 = w[0][0];
        let m2 = w[0][0] * w[1][1] - w[0][1] * w[1][0];
        let m3 = w[0][0] * (w[1][1] * w[2][2] - w[1][2] * w[2][1])
            - w[0][1] * (w[1][0] * w[2][2] - w[1][2] * w[2][0])
            + w[0][2] * (w[1][0] * w[2][1] - w[1][1] * w[2][0]);
        if !(symmetric && m1 > 0.0 && m2 > 0.0 && m3 > 0.0) {
            return Err(CalibrationError::NotPositiveDefinite);
        }
        Ok(())
    }

    /// The calibration a wire form stands for (every wire value is representable, so this cannot fail).
    pub fn from_wire(wire: &CalibrationWire) -> Self {
        let mut soft_iron = [[0.0; 3]; 3];
        for (i, &q) in wire.soft_iron_q12.iter().enumerate() {
            soft_iron[i / 3][i % 3] = f64::from(q) / WIRE_Q12_ONE;
        }
        Self {
            hard_iron_ut: wire.hard_iron_dut.map(|v| f64::from(v) * WIRE_UT_PER_LSB),
            soft_iron,
            field_ut: f64::from(wire.field_dut) * WIRE_UT_PER_LSB,
        }
    }
}

/// A calibration as the vest protocol carries it, in fixed point.
///
/// Resolution and range: hard iron 0.1 µT, ±3276.7 µT; soft iron 1/4096 ≈ 0.000244, [-8, 7.99976];
/// field 0.1 µT, 0–6553.5 µT. The rounding error (half a step) moves a heading by well under 0.1°.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct CalibrationWire {
    /// Hard iron `b` (x, y, z) in units of 0.1 µT.
    pub hard_iron_dut: [i16; 3],
    /// Soft iron `W` row-major in Q12 (`value * 4096`).
    pub soft_iron_q12: [i16; 9],
    /// Reference field strength `F` in units of 0.1 µT.
    pub field_dut: u16,
}

/// Why a calibration cannot be used ([`Calibration::check`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum CalibrationError {
    /// A number is not finite, or the reference field is not positive.
    #[error("calibration has a non-finite value or no positive reference field")]
    NotFinite,
    /// The soft-iron matrix is not symmetric positive definite.
    #[error("soft-iron matrix is not symmetric positive definite")]
    NotPositiveDefinite,
}

/// Errors converting a calibration to its wire form.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WireError {
    /// A value that is not finite or does not fit its fixed-point field.
    #[error("{quantity} {value} does not fit the wire format (range {min} to {max})")]
    OutOfRange {
        /// Which quantity ("hard iron [µT]", "soft iron", "field [µT]").
        quantity: &'static str,
        /// The offending value.
        value: f64,
        /// Smallest representable value.
        min: f64,
        /// Largest representable value.
        max: f64,
    },
}

fn to_i16(quantity: &'static str, value: f64, scale: f64) -> Result<i16, WireError> {
    let scaled = (value * scale).round();
    if (f64::from(i16::MIN)..=f64::from(i16::MAX)).contains(&scaled) {
        Ok(scaled as i16)
    } else {
        Err(WireError::OutOfRange {
            quantity,
            value,
            min: f64::from(i16::MIN) / scale,
            max: f64::from(i16::MAX) / scale,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    fn example() -> Calibration {
        Calibration {
            hard_iron_ut: [12.0, -30.0, 25.0],
            soft_iron: [[0.9, 0.07, -0.04], [0.07, 1.12, 0.05], [-0.04, 0.05, 0.95]],
            field_ut: 51.6,
        }
    }

    #[test]
    fn apply_is_w_times_m_minus_b() {
        let c = example();
        // m - b = [1, 2, 3]; W row sums by hand: 0.9 + 0.14 - 0.12 = 0.92, 0.07 + 2.24 + 0.15 = 2.46,
        // -0.04 + 0.10 + 2.85 = 2.91.
        let h = c.apply([13.0, -28.0, 28.0]);
        for (got, want) in h.iter().zip([0.92, 2.46, 2.91]) {
            assert_relative_eq!(*got, want, max_relative = 1e-12);
        }
        let id = Calibration::default();
        assert_eq!(id.apply([1.5, -2.5, 3.5]).map(f64::to_bits), [1.5, -2.5, 3.5].map(f64::to_bits));
        assert_eq!(id.field_ut.to_bits(), 0.0_f64.to_bits());
    }

    #[test]
    fn quality_follows_its_definition() {
        let c = Calibration::identity(50.0);
        assert_eq!(c.quality_pct([0.0, 0.0, 50.0]), 100);
        assert_eq!(c.quality_pct([30.0, 0.0, 40.0]), 100); // |h| = 50
        assert_eq!(c.quality_pct([0.0, 55.0, 0.0]), 80); // 10 % off
        assert_eq!(c.quality_pct([0.0, 0.0, 45.0]), 80);
        assert_eq!(c.quality_pct([0.0, 0.0, 51.0]), 96); // 2 % off
        assert_eq!(c.quality_pct([0.0, 0.0, 75.0]), 0); // 50 % off
        assert_eq!(c.quality_pct([0.0, 0.0, 200.0]), 0);
        assert_eq!(c.quality_pct([f64::NAN, 0.0, 50.0]), 0);
        assert_eq!(Calibration::default().quality_pct([0.0, 0.0, 50.0]), 0);
    }

    #[test]
    fn wire_round_trip_within_half_a_step() {
        let c = example();
        let w = c.to_wire().unwrap();
        assert_eq!(w.hard_iron_dut, [120, -300, 250]);
        assert_eq!(w.field_dut, 516);
        // 0.9 * 4096 = 3686.4 -> 3686; 1.12 * 4096 = 4587.52 -> 4588; -0.04 * 4096 = -163.84 -> -164.
        assert_eq!(w.soft_iron_q12[0], 3686);
        assert_eq!(w.soft_iron_q12[4], 4588);
        assert_eq!(w.soft_iron_q12[2], -164);
        assert_eq!(w.soft_iron_q12[6], -164);
        let back = Calibration::from_wire(&w);
        for i in 0..3 {
            assert!((back.hard_iron_ut[i] - c.hard_iron_ut[i]).abs() <= 0.05 + 1e-12);
            for j in 0..3 {
                assert!((back.soft_iron[i][j] - c.soft_iron[i][j]).abs() <= 0.5 / 4096.0 + 1e-12);
            }
        }
        assert_relative_eq!(back.field_ut, 51.6, max_relative = 1e-12);
        assert_eq!(back.to_wire().unwrap(), w);
        let zero = Calibration::from_wire(&CalibrationWire::default()).apply([1.0, 2.0, 3.0]);
        assert!(zero.iter().all(|v| v.abs() < 1e-300));
    }

    #[test]
    fn wire_rejects_out_of_range_instead_of_wrapping() {
        let mut c = example();
        c.hard_iron_ut[1] = 3276.8; // 32768 > i16::MAX
        assert!(matches!(c.to_wire(), Err(WireError::OutOfRange { quantity: "hard iron [µT]", .. })));
        c.hard_iron_ut[1] = -3276.8; // -32768 = i16::MIN fits
        assert_eq!(c.to_wire().unwrap().hard_iron_dut[1], i16::MIN);
        let mut c = example();
        c.soft_iron[2][1] = 8.0; // 32768
        assert!(matches!(c.to_wire(), Err(WireError::OutOfRange { quantity: "soft iron", .. })));
        c.soft_iron[2][1] = f64::NAN;
        assert!(c.to_wire().is_err());
        let mut c = example();
        c.field_ut = -0.1;
        assert!(c.to_wire().is_err());
        c.field_ut = 6553.6;
        assert!(c.to_wire().is_err());
        c.field_ut = 6553.5;
        assert_eq!(c.to_wire().unwrap().field_dut, u16::MAX);
    }

    proptest! {
        #[test]
        fn wire_decode_encode_is_exact(b in prop::array::uniform3(any::<i16>()),
                                       w in prop::array::uniform9(any::<i16>()), f in any::<u16>()) {
            let wire = CalibrationWire { hard_iron_dut: b, soft_iron_q12: w, field_dut: f };
            prop_assert_eq!(Calibration::from_wire(&wire).to_wire().unwrap(), wire);
        }

        #[test]
        fn wire_encode_never_panics(b in prop::array::uniform3(any::<f64>()),
                                    f in any::<f64>(), w in any::<f64>()) {
            let c = Calibration { hard_iron_ut: b, soft_iron: [[w; 3]; 3], field_ut: f };
            let _ = c.to_wire();
        }
    }
}
