//! Magnetometer heading for the vest's control unit (issue 12): tilt compensation, hard/soft-iron
//! calibration, a quality figure, the calibration's fixed-point wire form, and a sensor model.
//!
//! **Frames.** Body: `x` forward, `y` right, `z` down (aerospace). Earth: NED (north, east, down). The
//! attitude is heading/pitch/roll in the Z-Y-X order, `C_ned_from_body = Rz(psi) Ry(theta) Rx(phi)`; pitch
//! is nose up positive, roll right side down positive, heading clockwise from north. The accelerometer
//! reads specific force: at rest the *reaction* to gravity, `[0, 0, -9.81]` m/s^2 when level. Fields are in
//! µT. A magnetic heading is `true heading - declination` (declination east positive,
//! [`crate::geo::declination_deg`]).
//!
//! **Pipeline.** raw reading `m` → [`Calibration::apply`] `h = W (m - b)` →
//! [`tilt_compensated_heading`]`(h, accel)` → magnetic heading → add the declination for a true heading.
//! [`Calibration::quality_pct`] scores how far `|h|` is from the reference field `F`: a disturbed field
//! (steel nearby) changes its magnitude.
//!
//! **Calibration fit.** The raw field is `m = S h + b` with `|h| = F`: the samples lie on an ellipsoid.
//! A general quadric `x^T M x + 2 u^T x + d = 0` is fitted by total least squares (the smallest right
//! singular vector of the design matrix, nalgebra's SVD); its centre is the hard iron `b = -M^-1 u`, and the
//! symmetric square root of `M / (b^T M b - d)`, scaled by `F`, is the soft-iron correction `W`. A wearer
//! turning in place stays nearly level, so nearly planar samples are fitted as a 2-D ellipse instead
//! ([`fit_calibration`] states the rule). [`FitReport`] carries the RMS magnitude residual and the heading
//! coverage the console uses to ask the operator to keep turning.
//!
//! ```
//! use vestnav_core::compass::{FieldReference, fit_calibration, tilt_compensated_heading};
//! // A level sensor with hard iron (10, -20, 0) µT turned once round in a field of H = 20, Z = 46 µT.
//! let samples: Vec<[f64; 3]> = (0..36)
//!     .map(|i| {
//!         let psi = f64::from(i * 10 + 5).to_radians(); // mid-bin: 5°, 15°, ...
//!         // Facing psi the north field appears at (cos psi, -sin psi) in the body's x-y plane.
//!         [10.0 + 20.0 * psi.cos(), -20.0 - 20.0 * psi.sin(), 46.0]
//!     })
//!     .collect();
//! let fit = fit_calibration(&samples, FieldReference::from_ned([20.0, 0.0, 46.0])).unwrap();
//! assert!((fit.calibration.hard_iron_ut[0] - 10.0).abs() < 1e-6);
//! assert!(fit.coverage > 0.99);
//! // Facing east (90°): the raw reading is the north field on the left (-y) plus the hard iron.
//! let h = fit.calibration.apply([10.0, -40.0, 46.0]);
//! let att = tilt_compensated_heading(h, [0.0, 0.0, -9.81]).unwrap();
//! assert!((att.heading_deg - 90.0).abs() < 1e-6);
//! assert_eq!(fit.calibration.quality_pct(h), 100);
//! ```

mod calibration;
mod fit;
mod model;
#[cfg(test)]
mod synth;
mod tilt;

pub use calibration::{
    Calibration, CalibrationError, CalibrationWire, WIRE_Q12_ONE, WIRE_UT_PER_LSB, WireError,
};
pub use fit::{
    COVERAGE_BIN_DEG, FieldReference, FitError, FitKind, FitReport, MAX_AXIS_RATIO, MAX_PLANE_TILT_DEG,
    MAX_SAMPLE_UT, MIN_SAMPLES_2D, MIN_SAMPLES_3D, PLANAR_EIGEN_RATIO, fit_calibration, fit_ellipse_level,
    fit_ellipsoid, heading_coverage,
};
pub use model::{
    MIN_STEEL_DISTANCE_M, MagnetometerModel, MagnetometerSim, SensorPose, SensorSample, SteelObject,
    WALKING_PACE_M_S,
};
pub use tilt::{
    Attitude, MIN_ACCEL_M_S2, MIN_FIELD_UT, MIN_HORIZONTAL_FRACTION, STANDARD_GRAVITY_M_S2, body_from_ned,
    tilt_compensated_heading,
};
