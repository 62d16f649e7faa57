//! The simulated wearer's heading sensors: the vest's compass (through [`crate::compass`]'s sensor model,
//! calibration and tilt compensation) and the receiver's course over ground.

use glam::DVec2;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use crate::compass::{
    Calibration, FieldReference, MagnetometerModel, MagnetometerSim, SensorPose, SteelObject, body_from_ned,
    fit_calibration, tilt_compensated_heading,
};
use crate::geo::{GeoError, LatLon, normalize_deg};
use crate::guidance::{CompassReading, HeadingMode};

/// A steel object placed relative to the route: at a fraction of its length, beside it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SteelPlacement {
    /// Where along the route, as a fraction of its length (0 = start, 1 = end).
    pub along_route: f64,
    /// Distance beside the route, right of the direction of travel positive [m].
    pub offset_m: f64,
    /// Dipole strength [µT m^3] ([`SteelObject::moment_ut_m3`]: a parked car ~30, a lamp post ~5).
    pub moment_ut_m3: f64,
}

/// The heading part of a simulation: which source guidance uses, the compass's sensor model, and how the
/// wearer stands, turns on the spot and starts walking.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HeadingSim {
    /// Heading source selector given to guidance. With [`HeadingMode::Cog`] the vest has no compass at all
    /// (today's vest): guidance gets COG or nothing.
    pub mode: HeadingMode,
    /// White noise per magnetometer axis [µT] (default 0.3, a LIS3MDL-class part).
    pub mag_noise_ut: f64,
    /// White noise per accelerometer axis [m/s^2] (default 0.05).
    pub accel_noise_m_s2: f64,
    /// Torso pitch amplitude while walking [deg] (default 3).
    pub gait_pitch_deg: f64,
    /// Torso roll amplitude while walking [deg] (default 2).
    pub gait_roll_deg: f64,
    /// Steel objects near the route (default: two parked cars, 2 m beside the route at 30 % and 62 % of
    /// its length).
    pub steel: [SteelPlacement; 2],
    /// Turning rate on the spot [deg/s] (default 60: a few small steps round).
    pub rotate_rate_deg_s: f64,
    /// A wearer standing and told nothing directional for this long walks off the way they face [s]
    /// (default 8 s: with COG only, walking is the only way to get a heading).
    pub idle_walk_s: f64,
    /// Speed noise of the receiver [m/s] (default 0.1): COG scatters by `atan(sigma_v / v)` on top of
    /// [`super::SimConfig::cog_noise_deg`], so it is noise at a slow walk and random standing.
    pub speed_noise_m_s: f64,
}

impl HeadingSim {
    /// Defaults with the given heading mode.
    pub fn new(mode: HeadingMode) -> Self {
        let vest = MagnetometerModel::typical_vest();
        let car = |along_route| SteelPlacement { along_route, offset_m: 2.0, moment_ut_m3: 30.0 };
        Self {
            mode,
            mag_noise_ut: vest.mag_noise_ut,
            accel_noise_m_s2: vest.accel_noise_m_s2,
            gait_pitch_deg: vest.gait_pitch_deg,
            gait_roll_deg: vest.gait_roll_deg,
            steel: [car(0.30), car(0.62)],
            rotate_rate_deg_s: 60.0,
            idle_walk_s: 8.0,
            speed_noise_m_s: 0.1,
        }
    }
}

/// Date of the World Magnetic Model field and declination used by the simulation.
pub const SIM_DATE: (i32, u8, u8) = (2025, 6, 1);

/// The point at `along` (fraction of the length) on the polyline `pts`, `offset_m` to the right of it.
fn beside_route(pts: &[DVec2], along: f64, offset_m: f64) -> DVec2 {
    // Right of travel in east/north: (north, -east) of the direction.
    let right = |u: DVec2| DVec2::new(u.y, -u.x);
    let length: f64 = pts.windows(2).map(|w| (w[1] - w[0]).length()).sum();
    let mut left = if along.is_finite() { along.clamp(0.0, 1.0) * length } else { 0.0 };
    let mut last = None;
    for w in pts.windows(2) {
        let seg = w[1] - w[0];
        let l = seg.length();
        if l.is_nan() || l <= 0.0 {
            continue;
        }
        let u = seg / l;
        if left <= l {
            return w[0] + u * left + right(u) * offset_m;
        }
        left -= l;
        last = Some((w[1], u));
    }
    last.map_or_else(|| pts.first().copied().unwrap_or(DVec2::ZERO), |(end, u)| end + right(u) * offset_m)
}

/// The vest's compass as the simulated wearer carries it: the sensor model, a calibration fitted once before
/// the walk (a figure-8 away from steel), tilt compensation and the quality figure.
#[derive(Debug)]
pub(super) struct CompassSensor {
    sim: MagnetometerSim,
    calibration: Calibration,
    /// Steel positions, east/north of the route start [m] (for reports).
    pub steel_en_m: Vec<DVec2>,
}

impl CompassSensor {
    /// A compass at the route start `origin` with the steel of `h` placed along `route_en_m`; seeded.
    pub fn new(h: &HeadingSim, origin: LatLon, route_en_m: &[DVec2], seed: u64) -> Result<Self, GeoError> {
        let steel_en_m: Vec<DVec2> =
            h.steel.iter().map(|s| beside_route(route_en_m, s.along_route, s.offset_m)).collect();
        let model = MagnetometerModel {
            mag_noise_ut: h.mag_noise_ut,
            accel_noise_m_s2: h.accel_noise_m_s2,
            gait_pitch_deg: h.gait_pitch_deg,
            gait_roll_deg: h.gait_roll_deg,
            steel: h
                .steel
                .iter()
                .zip(&steel_en_m)
                .filter(|(s, _)| s.moment_ut_m3.is_finite() && s.moment_ut_m3 != 0.0)
                .map(|(s, p)| SteelObject { east_m: p.x, north_m: p.y, moment_ut_m3: s.moment_ut_m3 })
                .collect(),
            ..MagnetometerModel::typical_vest()
        };
        let sim = MagnetometerSim::new(model, origin, 0.0, SIM_DATE, seed)?;
        let calibration = figure_eight_calibration(&sim, seed ^ 0x5EED);
        Ok(Self { sim, calibration, steel_en_m })
    }

    /// Declination of the undisturbed field at the start [deg, east +] (what the console sets from WMM).
    pub fn declination_deg(&self) -> f64 {
        self.sim.declination_deg()
    }

    /// The compass reading for a body at `pos_en_m` with true heading `heading_true_deg`, walking at
    /// `pace_m_s` (0 standing) at time `t_s`: sensor sample → calibration → tilt compensation → magnetic
    /// heading and quality. `None` when tilt compensation has no answer. The one place the wearer's compass
    /// comes from.
    pub fn read(
        &mut self,
        t_s: f64,
        pos_en_m: DVec2,
        heading_true_deg: f64,
        pace_m_s: f64,
    ) -> Option<CompassReading> {
        let pose = SensorPose { t_s, heading_true_deg, east_m: pos_en_m.x, north_m: pos_en_m.y, pace_m_s };
        let s = self.sim.sample(&pose);
        let h = self.calibration.apply(s.raw_mag_body_ut);
        let att = tilt_compensated_heading(h, s.accel_body_m_s2)?;
        Some(CompassReading {
            magnetic_deg: att.heading_deg,
            age_s: 0.0,
            quality_pct: Some(self.calibration.quality_pct(h)),
        })
    }
}

/// The calibration the console's wizard would produce: 200 readings at random attitudes (heading 0–360°,
/// pitch and roll ±60°, a figure-8) in the undisturbed field, fitted by [`fit_calibration`]. Falls back to
/// the identity (an uncalibrated unit) if the fit fails.
fn figure_eight_calibration(sim: &MagnetometerSim, seed: u64) -> Calibration {
    let mut rng = StdRng::seed_from_u64(seed);
    let m = sim.model();
    let field = sim.field_ned_ut();
    let samples: Vec<[f64; 3]> = (0..200)
        .map(|_| {
            let (psi, theta, phi) =
                (rng.random_range(0.0..360.0), rng.random_range(-60.0..60.0), rng.random_range(-60.0..60.0));
            let h = body_from_ned(psi, theta, phi, field);
            std::array::from_fn(|i| {
                let noise: f64 = StandardNormal.sample(&mut rng);
                m.soft_iron[i][0] * h[0]
                    + m.soft_iron[i][1] * h[1]
                    + m.soft_iron[i][2] * h[2]
                    + m.hard_iron_ut[i]
                    + m.mag_noise_ut * noise
            })
        })
        .collect();
    let reference = FieldReference::from_ned(field);
    fit_calibration(&samples, reference)
        .map_or(Calibration::identity(reference.total_ut.unwrap_or(0.0)), |f| f.calibration)
}

/// Course over ground the receiver reports for a walker going `heading_deg` at `speed_m_s`:
/// `heading + N(0, sigma^2)` with `sigma = sqrt(cog_noise^2 + atan(sigma_v / v)^2)` (velocity noise
/// `sigma_v` turns into direction noise inversely with speed); uniform at a standstill.
pub(super) fn cog_deg(
    rng: &mut StdRng,
    heading_deg: f64,
    speed_m_s: f64,
    cog_noise_deg: f64,
    sigma_v: f64,
) -> f64 {
    if speed_m_s.is_nan() || speed_m_s <= 1e-3 {
        return rng.random_range(0.0..360.0);
    }
    let from_speed = (sigma_v.max(0.0) / speed_m_s).atan().to_degrees();
    let sigma = cog_noise_deg.hypot(from_speed);
    let n: f64 = StandardNormal.sample(rng);
    normalize_deg(heading_deg + sigma * n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::wrap_deg_180;
    use approx::assert_relative_eq;

    #[test]
    fn steel_is_placed_beside_the_route() {
        // An L: 100 m north then 100 m east; 25 % along = 50 m north, right of travel = east.
        let pts = [DVec2::ZERO, DVec2::new(0.0, 100.0), DVec2::new(100.0, 100.0)];
        let p = beside_route(&pts, 0.25, 2.0);
        assert_relative_eq!(p.x, 2.0, epsilon = 1e-9);
        assert_relative_eq!(p.y, 50.0, epsilon = 1e-9);
        // 75 % = 50 m along the east leg; right of eastward travel = south.
        let p = beside_route(&pts, 0.75, 2.0);
        assert_relative_eq!(p.x, 50.0, epsilon = 1e-9);
        assert_relative_eq!(p.y, 98.0, epsilon = 1e-9);
        assert_relative_eq!(beside_route(&pts, 1.0, 0.0).x, 100.0, epsilon = 1e-9);
    }

    #[test]
    fn calibrated_compass_far_from_steel_reads_true_minus_declination() {
        let origin = LatLon::new(42.3562, -71.1000);
        let route = [DVec2::ZERO, DVec2::new(0.0, 1000.0)];
        let mut h = HeadingSim::new(HeadingMode::Compass);
        // Steel far away (900 m along, out of reach of the start).
        h.steel = [SteelPlacement { along_route: 0.9, offset_m: 2.0, moment_ut_m3: 30.0 }; 2];
        let mut c = CompassSensor::new(&h, origin, &route, 3).unwrap();
        let decl = c.declination_deg();
        // Boston, 2025: about 14° W.
        assert!((-16.0..-12.0).contains(&decl), "{decl}");
        for truth in [0.0, 45.0, 170.0, 300.0] {
            for (t, pace) in [(0.0, 0.0), (0.37, 1.4), (1.1, 0.5)] {
                let r = c.read(t, DVec2::ZERO, truth, pace).unwrap();
                let err = wrap_deg_180(r.magnetic_deg + decl - truth);
                assert!(err.abs() < 3.0, "truth {truth} pace {pace}: error {err}");
                assert!(r.quality_pct.unwrap() >= 90, "{r:?}");
            }
        }
        // Next to the steel (1 m off it) the heading is off by more and the quality drops.
        let near = c.steel_en_m[0] + DVec2::new(-1.0, 0.0);
        let worst = (0..36)
            .map(|i| {
                let truth = f64::from(i) * 10.0;
                let r = c.read(0.0, near, truth, 0.0).unwrap();
                (wrap_deg_180(r.magnetic_deg + decl - truth).abs(), r.quality_pct.unwrap())
            })
            .fold((0.0f64, 100u8), |(e, q), (e1, q1)| (e.max(e1), q.min(q1)));
        assert!(worst.0 > 20.0 && worst.1 < 60, "{worst:?}");
    }

    #[test]
    fn cog_is_noise_at_a_standstill_and_sharp_at_a_walk() {
        let mut rng = StdRng::seed_from_u64(1);
        let spread = |rng: &mut StdRng, v: f64| {
            let errs: Vec<f64> =
                (0..2000).map(|_| wrap_deg_180(cog_deg(rng, 90.0, v, 5.0, 0.1) - 90.0)).collect();
            (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt()
        };
        // Closed form: sqrt(5^2 + atan(0.1/1.4)^2) = 6.4°; at 0.5 m/s sqrt(25 + 11.3^2) = 12.4°.
        assert_relative_eq!(
            spread(&mut rng, 1.4),
            5.0f64.hypot((0.1f64 / 1.4).atan().to_degrees()),
            max_relative = 0.08
        );
        assert_relative_eq!(
            spread(&mut rng, 0.5),
            5.0f64.hypot((0.2f64).atan().to_degrees()),
            max_relative = 0.08
        );
        // Uniform on the circle: RMS of a uniform (-180, 180] is 180/sqrt(3) = 103.9°.
        assert_relative_eq!(spread(&mut rng, 0.0), 180.0 / 3.0f64.sqrt(), max_relative = 0.05);
    }
}
