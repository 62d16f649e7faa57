//! A magnetometer + accelerometer sensor model for the emulated vest and the simulated wearer.

use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use super::tilt::{STANDARD_GRAVITY_M_S2, body_from_ned, norm3};
use crate::geo::{GeoError, LatLon, magnetic_field_ned_ut};

/// Below this pace the wearer is standing: no gait tilt [m/s].
pub const WALKING_PACE_M_S: f64 = 0.2;
/// Closest distance to a steel object the dipole formula is evaluated at [m] (it diverges at 0).
pub const MIN_STEEL_DISTANCE_M: f64 = 0.3;

/// A steel object near the route (a parked car, a lamp post, a railing), modelled as the dipole its
/// magnetisation by the Earth's field induces.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SteelObject {
    /// Position east of the local origin [m].
    pub east_m: f64,
    /// Position north of the local origin [m].
    pub north_m: f64,
    /// Dipole strength `k` [µT m^3]: the disturbance is `k / r^3` to `2 k / r^3` (see
    /// [`MagnetometerModel::disturbance_ned_ut`]). A parked car is roughly 30 (9–18 µT at 1.5 m, tens of
    /// degrees of heading error; 1 µT at 3 m, 0.03 µT at 10 m); a lamp post roughly 5.
    pub moment_ut_m3: f64,
}

/// Parameters of the simulated magnetometer and accelerometer on the wearer's vest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MagnetometerModel {
    /// Hard-iron offset `b` added to the reading [µT].
    pub hard_iron_ut: [f64; 3],
    /// Soft-iron distortion `S` (row-major): the reading is `S h + b`. A calibration's `W` estimates
    /// `S^-1`.
    pub soft_iron: [[f64; 3]; 3],
    /// White noise per magnetometer axis, standard deviation [µT].
    pub mag_noise_ut: f64,
    /// White noise per accelerometer axis, standard deviation [m/s^2].
    pub accel_noise_m_s2: f64,
    /// Amplitude of the pitch oscillation while walking [deg].
    pub gait_pitch_deg: f64,
    /// Amplitude of the roll (lateral sway) oscillation while walking [deg].
    pub gait_roll_deg: f64,
    /// Step frequency while walking [Hz] (~1.8 for a normal walk).
    pub step_frequency_hz: f64,
    /// Steel objects disturbing the field.
    pub steel: Vec<SteelObject>,
}

impl MagnetometerModel {
    /// A perfect sensor: no iron, no noise, no gait tilt, no steel.
    pub fn ideal() -> Self {
        Self {
            hard_iron_ut: [0.0; 3],
            soft_iron: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            mag_noise_ut: 0.0,
            accel_noise_m_s2: 0.0,
            gait_pitch_deg: 0.0,
            gait_roll_deg: 0.0,
            step_frequency_hz: 1.8,
            steel: Vec::new(),
        }
    }

    /// A typical uncalibrated vest control unit: hard iron (12, -30, 25) µT from the battery and motor
    /// magnets, soft iron of 10–15 % with cross terms, 0.3 µT noise (a LIS3MDL-class part), 0.05 m/s^2
    /// accelerometer noise, ±3° pitch and ±2° roll at 1.8 Hz while walking, no steel.
    pub fn typical_vest() -> Self {
        Self {
            hard_iron_ut: [12.0, -30.0, 25.0],
            soft_iron: [[1.12, 0.06, -0.04], [0.06, 0.90, 0.05], [-0.04, 0.05, 1.03]],
            mag_noise_ut: 0.3,
            accel_noise_m_s2: 0.05,
            gait_pitch_deg: 3.0,
            gait_roll_deg: 2.0,
            ..Self::ideal()
        }
    }

    /// Pitch and roll of the torso at time `t_s` [deg]: zero standing; walking
    /// `pitch = A_p sin(2 pi f t)` (once per step) and `roll = A_r sin(pi f t)` (lateral sway, once per
    /// stride of two steps).
    pub fn gait_tilt_deg(&self, t_s: f64, pace_m_s: f64) -> (f64, f64) {
        if pace_m_s.is_nan() || pace_m_s <= WALKING_PACE_M_S || !t_s.is_finite() {
            return (0.0, 0.0);
        }
        let phase = std::f64::consts::PI * self.step_frequency_hz * t_s;
        (self.gait_pitch_deg * (2.0 * phase).sin(), self.gait_roll_deg * phase.sin())
    }

    /// Disturbance of the steel objects at `(east_m, north_m)`, NED [µT], in the Earth field `field_ned_ut`.
    ///
    /// Each object is an induced dipole along the Earth field's direction `u`, at the sensor's height:
    /// `B = k (3 (u . e) e - u) / d^3` with `e` the unit vector from the object to the sensor and `d` the
    /// distance (not below [`MIN_STEEL_DISTANCE_M`]). This is the field of a magnetic dipole `m`,
    /// `mu0 / (4 pi) (3 (m . e) e - m) / d^3`, with `k = mu0 |m| / (4 pi)`; its size lies between `k / d^3`
    /// and `2 k / d^3`.
    pub fn disturbance_ned_ut(&self, field_ned_ut: [f64; 3], east_m: f64, north_m: f64) -> [f64; 3] {
        let f = norm3(field_ned_ut);
        let mut sum = [0.0; 3];
        if f.is_nan() || f <= 0.0 {
            return sum;
        }
        let u = field_ned_ut.map(|c| c / f);
        for obj in &self.steel {
            let (dn, de) = (north_m - obj.north_m, east_m - obj.east_m);
            let dist = dn.hypot(de);
            let (rn, re) = if dist > 0.0 { (dn / dist, de / dist) } else { (1.0, 0.0) };
            let r = [rn, re, 0.0];
            let d = dist.max(MIN_STEEL_DISTANCE_M);
            let ur = u[0] * rn + u[1] * re;
            let scale = obj.moment_ut_m3 / (d * d * d);
            for i in 0..3 {
                sum[i] += scale * (3.0 * ur * r[i] - u[i]);
            }
        }
        sum
    }
}

impl Default for MagnetometerModel {
    fn default() -> Self {
        Self::typical_vest()
    }
}

/// Where the wearer is and how they move at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SensorPose {
    /// Time [s] (drives the gait phase).
    pub t_s: f64,
    /// True heading of the body's forward axis, clockwise from true north [deg].
    pub heading_true_deg: f64,
    /// Position east of the local origin [m] (for the steel objects).
    pub east_m: f64,
    /// Position north of the local origin [m].
    pub north_m: f64,
    /// Walking pace [m/s]; at or below [`WALKING_PACE_M_S`] the wearer stands still.
    pub pace_m_s: f64,
}

/// One simulated reading and the true attitude it was taken at.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SensorSample {
    /// Raw magnetometer reading in the body frame [µT].
    pub raw_mag_body_ut: [f64; 3],
    /// Accelerometer reading (specific force, reads -g along down at rest) in the body frame [m/s^2].
    pub accel_body_m_s2: [f64; 3],
    /// True pitch [deg].
    pub pitch_deg: f64,
    /// True roll [deg].
    pub roll_deg: f64,
}

/// A seeded simulated sensor at one place and date.
///
/// The World Magnetic Model is evaluated once, at construction (or [`MagnetometerSim::set_place`]): the
/// field changes by a few nT and the declination by ~0.01° per km, far below the sensor's noise over a
/// walk.
#[derive(Debug)]
pub struct MagnetometerSim {
    model: MagnetometerModel,
    field_ned_ut: [f64; 3],
    rng: StdRng,
}

impl MagnetometerSim {
    /// A sensor at `place` (`height_m` above the ellipsoid) on the date, seeded with `seed`.
    pub fn new(
        model: MagnetometerModel,
        place: LatLon,
        height_m: f64,
        (year, month, day): (i32, u8, u8),
        seed: u64,
    ) -> Result<Self, GeoError> {
        let field = magnetic_field_ned_ut(place, height_m, year, month, day)?;
        Ok(Self::with_field(model, field, seed))
    }

    /// A sensor in a given Earth field, north/east/down [µT] (true-north frame).
    pub fn with_field(model: MagnetometerModel, field_ned_ut: [f64; 3], seed: u64) -> Self {
        Self { model, field_ned_ut, rng: StdRng::seed_from_u64(seed) }
    }

    /// Re-evaluates the World Magnetic Model at a new place/date (a long journey).
    pub fn set_place(
        &mut self,
        place: LatLon,
        height_m: f64,
        (year, month, day): (i32, u8, u8),
    ) -> Result<(), GeoError> {
        self.field_ned_ut = magnetic_field_ned_ut(place, height_m, year, month, day)?;
        Ok(())
    }

    /// The model.
    pub fn model(&self) -> &MagnetometerModel {
        &self.model
    }

    /// The undisturbed Earth field, north/east/down [µT].
    pub fn field_ned_ut(&self) -> [f64; 3] {
        self.field_ned_ut
    }

    /// Declination of the undisturbed field, east positive [deg]: `atan2(east, north)`. The magnetic
    /// heading a perfect compass shows is `true heading - declination`.
    pub fn declination_deg(&self) -> f64 {
        self.field_ned_ut[1].atan2(self.field_ned_ut[0]).to_degrees()
    }

    /// Draws one reading.
    ///
    /// The body attitude is (`heading_true_deg`, gait pitch, gait roll) ([`MagnetometerModel::gait_tilt_deg`]);
    /// the field is the Earth's plus the steel objects' at the position, rotated into the body
    /// ([`body_from_ned`]), then distorted `S h + b` and noised. The accelerometer reads the specific force
    /// of a body at rest, `body_from_ned(0, 0, -g)`, plus noise (the gait's linear accelerations are not
    /// modelled).
    pub fn sample(&mut self, pose: &SensorPose) -> SensorSample {
        let (pitch_deg, roll_deg) = self.model.gait_tilt_deg(pose.t_s, pose.pace_m_s);
        let dist = self.model.disturbance_ned_ut(self.field_ned_ut, pose.east_m, pose.north_m);
        let field = [0, 1, 2].map(|i| self.field_ned_ut[i] + dist[i]);
        let h = body_from_ned(pose.heading_true_deg, pitch_deg, roll_deg, field);
        let s = &self.model.soft_iron;
        let mut raw = [0.0; 3];
        for (i, out) in raw.iter_mut().enumerate() {
            let noise: f64 = StandardNormal.sample(&mut self.rng);
            *out = s[i][0] * h[0]
                + s[i][1] * h[1]
                + s[i][2] * h[2]
                + self.model.hard_iron_ut[i]
                + self.model.mag_noise_ut * noise;
        }
        let mut accel =
            body_from_ned(pose.heading_true_deg, pitch_deg, roll_deg, [0.0, 0.0, -STANDARD_GRAVITY_M_S2]);
        for a in &mut accel {
            let noise: f64 = StandardNormal.sample(&mut self.rng);
            *a += self.model.accel_noise_m_s2 * noise;
        }
        SensorSample { raw_mag_body_ut: raw, accel_body_m_s2: accel, pitch_deg, roll_deg }
    }
}

#[cfg(test)]
#[path = "model_tests.rs"]
mod tests;
