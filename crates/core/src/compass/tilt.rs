//! Frames, attitude and tilt-compensated heading.
//!
//! Frames (aerospace convention): body `x` forward, `y` right, `z` down; earth frame NED (north, east,
//! down). The body attitude is the Z-Y-X Euler sequence heading `psi`, pitch `theta`, roll `phi`:
//! `C_ned_from_body = Rz(psi) Ry(theta) Rx(phi)`, so a vector measured in the body is
//! `v_body = C_ned_from_body^T v_ned` ([`body_from_ned`]).

use serde::{Deserialize, Serialize};

use crate::geo::normalize_deg;

/// Standard gravity [m/s^2] (CGPM 1901), the magnitude a resting accelerometer reads.
pub const STANDARD_GRAVITY_M_S2: f64 = 9.806_65;

/// Below this specific-force magnitude the accelerometer no longer shows where "down" is (free fall, the
/// top of a jump, a fall of the control unit) and [`tilt_compensated_heading`] returns `None` [m/s^2].
pub const MIN_ACCEL_M_S2: f64 = 0.3 * STANDARD_GRAVITY_M_S2;

/// Below this magnetic field magnitude there is no field to steer by [µT] (the Earth's is 22–67 µT).
pub const MIN_FIELD_UT: f64 = 0.1;

/// Below this ratio of horizontal to total field the heading is undefined (at a magnetic pole, or a
/// magnetometer axis saturated along gravity) and [`tilt_compensated_heading`] returns `None`.
pub const MIN_HORIZONTAL_FRACTION: f64 = 1e-3;

/// Attitude of the body from one magnetometer and one accelerometer reading.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Attitude {
    /// Magnetic heading of the body's `x` axis, clockwise from magnetic north, in [0, 360) [deg].
    pub heading_deg: f64,
    /// Pitch [deg], nose (body `x`) up positive, in [-90, 90].
    pub pitch_deg: f64,
    /// Roll [deg], right side (body `y`) down positive, in (-180, 180].
    pub roll_deg: f64,
    /// Inclination (dip) of the measured field below the horizontal [deg], in [-90, 90]. A value far from
    /// the World Magnetic Model's is a sign of a local disturbance.
    pub dip_deg: f64,
}

/// Magnetic heading, pitch and roll from a (calibrated) magnetometer and an accelerometer reading.
///
/// **Accelerometer sign convention.** The accelerometer measures specific force `f = a - g` (what a
/// real MEMS part reports): at rest it reads the *reaction* to gravity, pointing **up**, so a level sensor at
/// rest reads `[0, 0, -9.81]` m/s^2 in this z-down frame. The gravity direction in the body is
/// `g_b = -f_b = g [-sin theta, sin phi cos theta, cos phi cos theta]`, hence the closed forms
/// (e.g. ST AN3192, Freescale AN4248 eqs. 13 and 14, written here for `g_b`):
///
/// - roll `phi = atan2(g_y, g_z)`, pitch `theta = atan2(-g_x, sqrt(g_y^2 + g_z^2))`;
/// - de-rotating the field into the horizontal plane, `m_h = Ry(theta) Rx(phi) m_b`:
///   `X_h = m_x cos theta + (m_y sin phi + m_z cos phi) sin theta`, `Y_h = m_y cos phi - m_z sin phi`,
///   `Z_h = -m_x sin theta + (m_y sin phi + m_z cos phi) cos theta`;
/// - heading `psi = atan2(-Y_h, X_h)` (AN4248 eq. 22), dip `= atan2(Z_h, sqrt(X_h^2 + Y_h^2))`.
///
/// Linear accelerations (walking bounce, turning) tilt the apparent gravity and so bias pitch/roll; the
/// caller filters the accelerometer if needed. Returns `None` when any input is not finite, when
/// `|f| < MIN_ACCEL_M_S2` (free fall), when `|m| < MIN_FIELD_UT`, or when the horizontal field is below
/// `MIN_HORIZONTAL_FRACTION` of the total (heading undefined).
pub fn tilt_compensated_heading(mag_body_ut: [f64; 3], accel_body_m_s2: [f64; 3]) -> Option<Attitude> {
    if !mag_body_ut.iter().chain(&accel_body_m_s2).all(|v| v.is_finite()) {
        return None;
    }
    let [gx, gy, gz] = accel_body_m_s2.map(|f| -f);
    let accel_norm = norm3([gx, gy, gz]);
    let field_norm = norm3(mag_body_ut);
    // Non-finite norms (overflow of huge inputs) fail these comparisons too.
    if !(accel_norm >= MIN_ACCEL_M_S2 && accel_norm.is_finite()) {
        return None;
    }
    if !(field_norm >= MIN_FIELD_UT && field_norm.is_finite()) {
        return None;
    }
    let roll = gy.atan2(gz);
    let pitch = (-gx).atan2(gy.hypot(gz));
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let [mx, my, mz] = mag_body_ut;
    let y_rolled = my * sr + mz * cr;
    let xh = mx * cp + y_rolled * sp;
    let yh = my * cr - mz * sr;
    let zh = -mx * sp + y_rolled * cp;
    let horizontal = xh.hypot(yh);
    if horizontal < MIN_HORIZONTAL_FRACTION * field_norm {
        return None;
    }
    Some(Attitude {
        heading_deg: normalize_deg((-yh).atan2(xh).to_degrees()),
        pitch_deg: pitch.to_degrees(),
        roll_deg: roll.to_degrees(),
        dip_deg: zh.atan2(horizontal).to_degrees(),
    })
}

/// A vector given in NED expressed in the body frame of attitude (`heading_deg`, `pitch_deg`,
/// `roll_deg`): `v_body = Rx(phi)^T Ry(theta)^T Rz(psi)^T v_ned` (Z-Y-X Euler angles, see the module doc).
///
/// Written out: with `(n', e') = (n cos psi + e sin psi, -n sin psi + e cos psi)` (heading removed) and
/// `(x, d') = (n' cos theta - d sin theta, n' sin theta + d cos theta)` (pitch removed),
/// `v_body = [x, e' cos phi + d' sin phi, -e' sin phi + d' cos phi]`.
pub fn body_from_ned(heading_deg: f64, pitch_deg: f64, roll_deg: f64, v_ned: [f64; 3]) -> [f64; 3] {
    let (sy, cy) = heading_deg.to_radians().sin_cos();
    let (sp, cp) = pitch_deg.to_radians().sin_cos();
    let (sr, cr) = roll_deg.to_radians().sin_cos();
    let [n, e, d] = v_ned;
    let n1 = n * cy + e * sy;
    let e1 = -n * sy + e * cy;
    let x = n1 * cp - d * sp;
    let d1 = n1 * sp + d * cp;
    [x, e1 * cr + d1 * sr, -e1 * sr + d1 * cr]
}

/// Euclidean norm of a 3-vector.
pub(crate) fn norm3(v: [f64; 3]) -> f64 {
    v[0].hypot(v[1]).hypot(v[2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::wrap_deg_180;
    use approx::assert_relative_eq;
    use nalgebra::{Rotation3, Vector3};
    use proptest::prelude::*;

    /// Earth field of a mid-latitude place in NED [µT]: H = 20, Z = 46 (dip 66.5°), no declination
    /// (the frame is magnetic north here).
    const FIELD_NED: [f64; 3] = [20.0, 0.0, 46.0];

    /// Body-frame readings for an attitude, built with nalgebra's own Euler rotation (independent of
    /// [`body_from_ned`]): `R = Rz(yaw) Ry(pitch) Rx(roll)` maps body to NED, so `v_b = R^T v_n`.
    fn readings(heading_deg: f64, pitch_deg: f64, roll_deg: f64) -> ([f64; 3], [f64; 3]) {
        let r = Rotation3::from_euler_angles(
            roll_deg.to_radians(),
            pitch_deg.to_radians(),
            heading_deg.to_radians(),
        );
        let m = r.inverse() * Vector3::from(FIELD_NED);
        // At rest the accelerometer reads the reaction to gravity: up, i.e. -g along NED down.
        let f = r.inverse() * Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_M_S2);
        ([m.x, m.y, m.z], [f.x, f.y, f.z])
    }

    #[test]
    fn level_cardinal_headings() {
        for (want, mag) in [
            (0.0, [20.0, 0.0, 46.0]),   // x along the field: north
            (90.0, [0.0, -20.0, 46.0]), // facing east the field (north) is on the left: -y
            (180.0, [-20.0, 0.0, 46.0]),
            (270.0, [0.0, 20.0, 46.0]),
        ] {
            let a = tilt_compensated_heading(mag, [0.0, 0.0, -STANDARD_GRAVITY_M_S2]).unwrap();
            assert!(wrap_deg_180(a.heading_deg - want).abs() < 1e-9, "{want}: {a:?}");
            assert!(a.pitch_deg.abs() < 1e-12 && a.roll_deg.abs() < 1e-12);
            // Dip = atan(46/20) = 66.50°.
            assert_relative_eq!(a.dip_deg, 46.0_f64.atan2(20.0).to_degrees(), max_relative = 1e-12);
        }
    }

    #[test]
    fn tilted_sensor_keeps_heading_and_recovers_pitch_and_roll() {
        for heading in [0.0, 37.0, 90.0, 181.0, 270.0, 333.0] {
            for (pitch, roll) in [(10.0, 0.0), (0.0, -15.0), (25.0, 30.0), (-40.0, 12.0), (5.0, -60.0)] {
                let (m, f) = readings(heading, pitch, roll);
                let a = tilt_compensated_heading(m, f).unwrap();
                assert!(
                    wrap_deg_180(a.heading_deg - heading).abs() < 1e-9,
                    "{heading} {pitch} {roll}: {a:?}"
                );
                assert_relative_eq!(a.pitch_deg, pitch, epsilon = 1e-9);
                assert_relative_eq!(a.roll_deg, roll, epsilon = 1e-9);
                assert_relative_eq!(a.dip_deg, 46.0_f64.atan2(20.0).to_degrees(), epsilon = 1e-9);
            }
        }
    }

    #[test]
    fn body_from_ned_matches_nalgebra_euler_rotation() {
        let v = [3.0, -7.0, 11.0];
        for (h, p, r) in [(0.0, 0.0, 0.0), (123.0, -21.0, 44.0), (271.0, 80.0, -170.0)] {
            let rot =
                Rotation3::from_euler_angles(f64::to_radians(r), f64::to_radians(p), f64::to_radians(h));
            let want = rot.inverse() * Vector3::from(v);
            let got = body_from_ned(h, p, r, v);
            for i in 0..3 {
                assert_relative_eq!(got[i], want[i], epsilon = 1e-12);
            }
        }
    }

    #[test]
    fn degenerate_inputs_give_none() {
        let g = [0.0, 0.0, -STANDARD_GRAVITY_M_S2];
        assert!(tilt_compensated_heading([0.0; 3], g).is_none());
        assert!(tilt_compensated_heading([20.0, 0.0, 46.0], [0.0; 3]).is_none());
        // Free fall: |f| = 0.5 m/s^2.
        assert!(tilt_compensated_heading([20.0, 0.0, 46.0], [0.3, 0.0, -0.4]).is_none());
        // Field straight down (magnetic pole): no horizontal component.
        assert!(tilt_compensated_heading([0.0, 0.0, 60.0], g).is_none());
        assert!(tilt_compensated_heading([f64::NAN, 0.0, 46.0], g).is_none());
        assert!(tilt_compensated_heading([20.0, 0.0, 46.0], [0.0, f64::INFINITY, -9.8]).is_none());
    }

    proptest! {
        #[test]
        fn any_finite_input_is_safe(m in prop::array::uniform3(-1e300..1e300f64),
                                    f in prop::array::uniform3(-1e300..1e300f64)) {
            if let Some(a) = tilt_compensated_heading(m, f) {
                prop_assert!((0.0..360.0).contains(&a.heading_deg));
                prop_assert!(a.pitch_deg.abs() <= 90.0 && a.roll_deg.abs() <= 180.0);
            }
        }
    }
}
