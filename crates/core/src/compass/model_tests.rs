//! Tests of the sensor model: through tilt compensation and calibration back to the true heading.

use super::*;
use crate::compass::{Calibration, FieldReference, FitKind, fit_calibration, tilt_compensated_heading};
use crate::geo::{declination_deg, normalize_deg, wrap_deg_180};
use approx::assert_relative_eq;

const CAMBRIDGE: LatLon = LatLon::new(42.3601, -71.0942);
const DATE: (i32, u8, u8) = (2025, 6, 1);

fn pose(t_s: f64, heading_true_deg: f64, pace_m_s: f64) -> SensorPose {
    SensorPose { t_s, heading_true_deg, east_m: 0.0, north_m: 0.0, pace_m_s }
}

#[test]
fn wmm_field_vector_is_consistent_with_declination_and_plausible() {
    let f = magnetic_field_ned_ut(CAMBRIDGE, 0.0, 2025, 6, 1).unwrap();
    let d = declination_deg(CAMBRIDGE, 0.0, 2025, 6, 1).unwrap();
    assert_relative_eq!(f[1].atan2(f[0]).to_degrees(), d, epsilon = 1e-3);
    // NOAA's calculator for Boston, 2025: total ~51.5 µT, dip ~66°, vertical down (northern hemisphere).
    let total = norm3(f);
    let dip = f[2].atan2(f[0].hypot(f[1])).to_degrees();
    assert!((49.0..54.0).contains(&total), "{total}");
    assert!((64.0..69.0).contains(&dip), "{dip}");
    assert!(magnetic_field_ned_ut(CAMBRIDGE, 0.0, 2025, 2, 30).is_err());
}

#[test]
fn ideal_sensor_through_tilt_compensation_gives_true_minus_declination() {
    let d = declination_deg(CAMBRIDGE, 0.0, 2025, 6, 1).unwrap();
    // Standing (level) and walking with a 6° / 4° gait wobble: the accelerometer reads pure gravity, so
    // tilt compensation is exact either way.
    let walking = MagnetometerModel { gait_pitch_deg: 6.0, gait_roll_deg: 4.0, ..MagnetometerModel::ideal() };
    for (model, pace) in [(MagnetometerModel::ideal(), 0.0), (walking, 1.4)] {
        let mut sim = MagnetometerSim::new(model, CAMBRIDGE, 0.0, DATE, 1).unwrap();
        assert_relative_eq!(sim.declination_deg(), d, epsilon = 1e-3);
        for i in 0..72 {
            let t = 0.05 * f64::from(i);
            let heading = 5.0 * f64::from(i);
            let s = sim.sample(&pose(t, heading, pace));
            let att = tilt_compensated_heading(s.raw_mag_body_ut, s.accel_body_m_s2).unwrap();
            let want = normalize_deg(heading - d);
            assert!(wrap_deg_180(att.heading_deg - want).abs() < 0.01, "{heading}: {att:?} vs {want}");
            assert_relative_eq!(att.pitch_deg, s.pitch_deg, epsilon = 1e-9);
            assert_relative_eq!(att.roll_deg, s.roll_deg, epsilon = 1e-9);
        }
    }
}

#[test]
fn gait_tilt_follows_step_frequency() {
    let m = MagnetometerModel::typical_vest();
    // A quarter step period after t = 0 the pitch peaks; the roll (once per stride) is at sin(pi/4).
    let t = 0.25 / m.step_frequency_hz;
    let (p, r) = m.gait_tilt_deg(t, 1.4);
    assert_relative_eq!(p, m.gait_pitch_deg, max_relative = 1e-12);
    assert_relative_eq!(r, m.gait_roll_deg * std::f64::consts::FRAC_1_SQRT_2, max_relative = 1e-12);
    assert_eq!(m.gait_tilt_deg(t, 0.0), (0.0, 0.0));
    assert_eq!(m.gait_tilt_deg(f64::NAN, 1.4), (0.0, 0.0));
}

#[test]
fn calibrating_a_turn_in_place_recovers_the_heading() {
    let model = MagnetometerModel::typical_vest();
    let mut sim = MagnetometerSim::new(model.clone(), CAMBRIDGE, 0.0, DATE, 2).unwrap();
    let d = sim.declination_deg();
    // The wearer turns once in place, slowly (10 s, standing): 100 samples at 10 Hz.
    let samples: Vec<[f64; 3]> = (0..100)
        .map(|i| sim.sample(&pose(0.1 * f64::from(i), 3.6 * f64::from(i), 0.0)).raw_mag_body_ut)
        .collect();
    let reference = FieldReference::from_ned(sim.field_ned_ut());
    let fit = fit_calibration(&samples, reference).unwrap();
    assert_eq!(fit.kind, FitKind::Ellipse2d);
    let cal = fit.calibration;
    // Now walk (gait tilt ±3°/±2°) on a noise-free copy of the same sensor, and standing with noise.
    let quiet = MagnetometerModel { mag_noise_ut: 0.0, accel_noise_m_s2: 0.0, ..model };
    let mut walk = MagnetometerSim::with_field(quiet, sim.field_ned_ut(), 3);
    let (mut worst_walk, mut sq_noisy): (f64, f64) = (0.0, 0.0);
    for i in 0..360 {
        let heading = f64::from(i);
        let want = normalize_deg(heading - d);
        let s = walk.sample(&pose(0.037 * f64::from(i), heading, 1.4));
        let att = tilt_compensated_heading(cal.apply(s.raw_mag_body_ut), s.accel_body_m_s2).unwrap();
        worst_walk = worst_walk.max(wrap_deg_180(att.heading_deg - want).abs());
        let s = sim.sample(&pose(0.0, heading, 0.0));
        let att = tilt_compensated_heading(cal.apply(s.raw_mag_body_ut), s.accel_body_m_s2).unwrap();
        sq_noisy += wrap_deg_180(att.heading_deg - want).powi(2);
    }
    let rms_noisy = (sq_noisy / 360.0).sqrt();
    println!(
        "model turn-in-place fit: residual {:.2} %, coverage {:.2}; heading err walking (noise-free) max \
         {worst_walk:.3}°, standing with noise rms {rms_noisy:.3}°",
        fit.residual_rms_pct, fit.coverage
    );
    assert!(worst_walk < 1.5);
    assert!(rms_noisy < 1.5);
    // Uncalibrated, the same readings are tens of degrees off.
    let s = walk.sample(&pose(0.0, 90.0, 0.0));
    let raw_att = tilt_compensated_heading(s.raw_mag_body_ut, s.accel_body_m_s2).unwrap();
    assert!(wrap_deg_180(raw_att.heading_deg - (90.0 - d)).abs() > 10.0);
}

/// Steel object south-west of the wearer, so the unit vector from it to the sensor is north-east.
/// In a field with no declination (`H` north, `Z` down, `u = (H, 0, Z)/F`) and `a = k / (F d^3)`, the
/// dipole formula gives `u . r = H / (F sqrt 2)` and the disturbance `a (0.5 H, 1.5 H, -Z)` (N, E, D): the
/// horizontal field turns east by `atan2(1.5 a, 1 + 0.5 a)` and the magnitude becomes
/// `sqrt(H^2 ((1 + a/2)^2 + (3a/2)^2) + Z^2 (1 - a)^2)`.
#[test]
fn steel_nearby_turns_the_heading_and_drops_the_quality() {
    let (h, z) = (20.0, 46.0);
    let f = f64::hypot(h, z);
    let k = 30.0; // a parked car
    let cal = Calibration::identity(f);
    for d in [1.0, 1.5, 2.0, 3.0, 10.0, 20.0] {
        let s = std::f64::consts::FRAC_1_SQRT_2 * d;
        let car = SteelObject { east_m: -s, north_m: -s, moment_ut_m3: k };
        let model = MagnetometerModel { steel: vec![car], ..MagnetometerModel::ideal() };
        let mut sim = MagnetometerSim::with_field(model, [h, 0.0, z], 4);
        let sample = sim.sample(&pose(0.0, 0.0, 0.0));
        let att = tilt_compensated_heading(sample.raw_mag_body_ut, sample.accel_body_m_s2).unwrap();
        let a = k / (f * d * d * d);
        let turn_deg = (1.5 * a).atan2(1.0 + 0.5 * a).to_degrees();
        // The field turned east: facing true north, the compass reads west of north.
        assert_relative_eq!(wrap_deg_180(att.heading_deg), -turn_deg, epsilon = 1e-9);
        let mag = (h * h * ((1.0 + 0.5 * a).powi(2) + (1.5 * a).powi(2)) + z * z * (1.0 - a).powi(2)).sqrt();
        let want_q = (100.0 * (1.0 - 2.0 * (mag - f).abs() / f).max(0.0)).round() as u8;
        let q = cal.quality_pct(sample.raw_mag_body_ut);
        println!("steel at {d} m: heading error {turn_deg:.2}°, |B| {mag:.2} µT, quality {q} %");
        assert_eq!(q, want_q);
        if d <= 1.5 {
            assert!(turn_deg > 10.0 && q < 90, "{d} m: {turn_deg}° {q} %");
        }
        if d >= 10.0 {
            assert!(turn_deg < 0.2 && q >= 99, "{d} m: {turn_deg}° {q} %");
        }
    }
}

#[test]
fn samples_are_seeded_and_noisy() {
    let model = MagnetometerModel::typical_vest();
    let mut a = MagnetometerSim::with_field(model.clone(), [20.0, -5.0, 46.0], 9);
    let mut b = MagnetometerSim::with_field(model, [20.0, -5.0, 46.0], 9);
    let p = pose(1.0, 45.0, 1.4);
    let (sa, sb) = (a.sample(&p), b.sample(&p));
    // Same seed, same draw: bit-identical readings.
    assert_eq!(sa.raw_mag_body_ut.map(f64::to_bits), sb.raw_mag_body_ut.map(f64::to_bits));
    assert_ne!(a.sample(&p).raw_mag_body_ut.map(f64::to_bits), sa.raw_mag_body_ut.map(f64::to_bits));
    assert_relative_eq!(norm3(sa.accel_body_m_s2), STANDARD_GRAVITY_M_S2, max_relative = 0.05);
}
