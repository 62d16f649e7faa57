//! Tests of the calibration fits against synthetic data with known hard and soft iron (see `synth.rs`).
//!
//! Tolerances (field 50 µT, noise 0.3 µT per axis): hard iron within 1 µT; corrected magnitudes of
//! noise-free readings within 1 % of F (level turn: the horizontal within 1 % of H, the total within 3.5 %
//! as the 2x2 model leaves the vertical cross terms); headings within 1.5°; 3-D soft iron within 0.01 of
//! the truth `S^-1`.

use super::*;
use crate::compass::synth::{self, F_UT, HARD_IRON, NOISE_UT, field_ned, soft_iron, to_body, z_ut};
use crate::compass::tilt::tilt_compensated_heading;
use crate::geo::wrap_deg_180;
use approx::assert_relative_eq;
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;
use rand::SeedableRng;
use rand::rngs::StdRng;

/// Worst heading error [deg] of a calibration over 24 headings at several tilts (noise-free readings).
fn worst_heading_error_deg(cal: &Calibration, tilts: &[(f64, f64)]) -> f64 {
    let mut rng = StdRng::seed_from_u64(0);
    let mut worst: f64 = 0.0;
    for i in 0..24 {
        let heading = 15.0 * f64::from(i);
        for &(p, r) in tilts {
            let raw = synth::distort(to_body(field_ned(0.0), heading, p, r), 0.0, &mut rng);
            let att = tilt_compensated_heading(cal.apply(raw), synth::accel_at(heading, p, r)).unwrap();
            worst = worst.max(wrap_deg_180(att.heading_deg - heading).abs());
        }
    }
    worst
}

/// Worst relative magnitude error [%] of noise-free readings over `n` directions on a sphere, corrected.
fn worst_magnitude_error_pct(cal: &Calibration, raw_clean: &[[f64; 3]]) -> f64 {
    raw_clean.iter().map(|m| (norm3(cal.apply(*m)) - F_UT).abs() / F_UT * 100.0).fold(0.0, f64::max)
}

fn max_abs_diff(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max)
}

#[test]
fn sphere_fit_recovers_hard_and_soft_iron() {
    let samples = synth::sphere_samples(300, NOISE_UT, 1);
    let fit = fit_calibration(&samples, FieldReference::total(F_UT)).unwrap();
    assert_eq!(fit.kind, FitKind::Ellipsoid3d);
    let cal = fit.calibration;
    let b_err = max_abs_diff(cal.hard_iron_ut, HARD_IRON);
    let w_true = soft_iron().try_inverse().unwrap();
    let w = Matrix3::from_fn(|i, j| cal.soft_iron[i][j]);
    let w_err = (w - w_true).abs().max();
    let mag_err = worst_magnitude_error_pct(&cal, &synth::sphere_samples(500, 0.0, 2));
    let tilts = [(0.0, 0.0), (20.0, -10.0), (-15.0, 25.0), (40.0, 30.0)];
    let hdg_err = worst_heading_error_deg(&cal, &tilts);
    println!(
        "3-D: |b err| {b_err:.3} µT, |W err| {w_err:.4}, |h| err {mag_err:.3} %, heading err {hdg_err:.3}°, \
         residual {:.3} %, coverage {:.2}",
        fit.residual_rms_pct, fit.coverage
    );
    assert!(b_err < 1.0);
    assert!(w_err < 0.01);
    assert!(mag_err < 1.0);
    assert!(hdg_err < 1.5);
    // Noise of 0.3 µT per axis is 0.6 % of 50 µT along the radius.
    assert!(fit.residual_rms_pct > 0.3 && fit.residual_rms_pct < 1.0, "{}", fit.residual_rms_pct);
    assert_relative_eq!(cal.field_ut, F_UT);
    assert!(fit.planarity > 0.3 && fit.coverage > 0.99 && fit.samples == 300);
}

#[test]
fn sphere_fit_without_reference_scales_to_the_volume_equivalent_radius() {
    // The ellipsoid {S h + b : |h| = F} has semi-axes F times the eigenvalues of S (symmetric), whose
    // geometric mean is F det(S)^(1/3).
    let samples = synth::sphere_samples(200, 0.0, 3);
    let fit = fit_ellipsoid(&samples, None).unwrap();
    let r = F_UT * soft_iron().determinant().cbrt();
    assert_relative_eq!(fit.calibration.field_ut, r, max_relative = 1e-6);
    let w = Matrix3::from_fn(|i, j| fit.calibration.soft_iron[i][j]);
    assert_relative_eq!(w.determinant(), 1.0, max_relative = 1e-6);
    assert!(fit.residual_rms_pct < 1e-6);
}

#[test]
fn level_turn_falls_back_to_the_ellipse_and_recovers_heading() {
    // 72 samples over one turn, ±1° wobble (standing), 0.3 µT noise; the reference is the true F and dip.
    let samples = synth::level_turn_samples(72, 1.0, NOISE_UT, 4);
    let reference = FieldReference::from_ned(field_ned(0.0).into());
    let fit = fit_calibration(&samples, reference).unwrap();
    assert_eq!(fit.kind, FitKind::Ellipse2d);
    let cal = fit.calibration;
    // A level turn sees the offset b + S e_z Z - Z e_z: the soft iron's third column times the vertical
    // field shifts the centre, and the vertical scale S_zz cannot be told from the offset.
    let s = soft_iron();
    let z = z_ut();
    let b_eff = Vector3::from(HARD_IRON) + s.column(2) * z - Vector3::new(0.0, 0.0, z);
    let b_err = max_abs_diff(cal.hard_iron_ut, b_eff.into());
    // Magnitudes of noise-free level readings at 36 headings.
    let mut rng = StdRng::seed_from_u64(5);
    let clean: Vec<[f64; 3]> = (0..36)
        .map(|i| synth::distort(to_body(field_ned(0.0), 10.0 * f64::from(i), 0.0, 0.0), 0.0, &mut rng))
        .collect();
    let mag_err = worst_magnitude_error_pct(&cal, &clean);
    let h_err = clean
        .iter()
        .map(|m| {
            let h = cal.apply(*m);
            (h[0].hypot(h[1]) - synth::H_UT).abs() / synth::H_UT * 100.0
        })
        .fold(0.0, f64::max);
    let hdg_level = worst_heading_error_deg(&cal, &[(0.0, 0.0)]);
    let hdg_gait = worst_heading_error_deg(&cal, &[(3.0, -2.0), (-3.0, 2.0)]);
    println!(
        "2-D: |b err| {b_err:.3} µT, |h_xy| err {h_err:.3} %, |h| err {mag_err:.3} %, heading err level {hdg_level:.3}° / ±3° tilt \
         {hdg_gait:.3}°, residual {:.3} %, coverage {:.2}, planarity {:.4}",
        fit.residual_rms_pct, fit.coverage, fit.planarity
    );
    assert!(b_err < 1.0);
    assert!(h_err < 1.0);
    // The 2x2 model leaves S_zx h_x + S_zy h_y (up to 1.56 µT here) in the vertical: up to 2.9 % of |h|.
    assert!(mag_err < 3.5);
    assert!(hdg_level < 1.5);
    assert!(hdg_gait < 1.5);
    // 72 samples 5° apart with noise: a bin or two may be skipped.
    assert!(fit.coverage > 0.9);
    assert!(fit.planarity < PLANAR_EIGEN_RATIO);
}

#[test]
fn level_turn_with_total_field_only_still_gives_headings() {
    let samples = synth::level_turn_samples(72, 0.0, NOISE_UT, 6);
    let fit = fit_ellipse_level(&samples, FieldReference::total(F_UT)).unwrap();
    let hdg = worst_heading_error_deg(&fit.calibration, &[(0.0, 0.0)]);
    println!("2-D (F only): heading err {hdg:.3}°, b {:?}", fit.calibration.hard_iron_ut);
    assert!(hdg < 1.5);
    assert_relative_eq!(fit.calibration.field_ut, F_UT);
    let fit = fit_ellipse_level(&samples, FieldReference::NONE).unwrap();
    assert!(worst_heading_error_deg(&fit.calibration, &[(0.0, 0.0)]) < 1.5);
}

#[test]
fn coverage_counts_ten_degree_bins() {
    // Half a turn (0..180° in 5° steps, 36 samples): bins 0..18 hit, 18 of 36.
    let h: Vec<[f64; 3]> = (0..36)
        .map(|i| {
            let psi = (5.0 * f64::from(i)).to_radians() + 1e-6;
            [20.0 * psi.cos(), -20.0 * psi.sin(), 46.0]
        })
        .collect();
    assert_relative_eq!(heading_coverage(&h), 0.5);
    assert_relative_eq!(heading_coverage(&[]), 0.0);
    assert_relative_eq!(heading_coverage(&[[0.0, 0.0, 50.0]]), 0.0);
}

#[test]
fn degenerate_inputs_are_errors() {
    let few = synth::sphere_samples(8, 0.0, 7);
    assert!(matches!(fit_ellipsoid(&few, None), Err(FitError::TooFewSamples { needed: 9, got: 8, .. })));
    assert!(matches!(
        fit_ellipse_level(&few[..4], FieldReference::NONE),
        Err(FitError::TooFewSamples { needed: 5, got: 4, .. })
    ));
    let mut bad = synth::sphere_samples(50, 0.0, 8);
    bad[17][1] = f64::NAN;
    assert_eq!(fit_calibration(&bad, FieldReference::NONE), Err(FitError::NonFinite { index: 17 }));
    let same = vec![[1.0, 2.0, 3.0]; 20];
    assert_eq!(fit_calibration(&same, FieldReference::NONE), Err(FitError::Degenerate));
    let line: Vec<[f64; 3]> = (0..20).map(|i| [f64::from(i), 2.0 * f64::from(i), -f64::from(i)]).collect();
    assert!(fit_calibration(&line, FieldReference::NONE).is_err());
    // A circle in a plane tilted 45° about x: planar but not level.
    let tilted: Vec<[f64; 3]> = (0..36)
        .map(|i| {
            let a = (10.0 * f64::from(i)).to_radians();
            let s = std::f64::consts::FRAC_1_SQRT_2;
            [50.0 * a.cos(), 50.0 * a.sin() * s, 50.0 * a.sin() * s]
        })
        .collect();
    assert!(matches!(fit_calibration(&tilted, FieldReference::NONE), Err(FitError::TiltedPlane { .. })));
    // The same circle forced through the 3-D fit: many quadrics contain it.
    assert_eq!(fit_ellipsoid(&tilted, None), Err(FitError::Degenerate));
    // A hyperboloid of one sheet x^2 + y^2 - z^2 = 1 (scaled): a quadric, not an ellipsoid.
    let hyper: Vec<[f64; 3]> = (0..60)
        .map(|i| {
            let (t, a) = (-1.0 + f64::from(i % 5) * 0.5, f64::from(i) * 0.7);
            [30.0 * t.cosh() * a.cos(), 30.0 * t.cosh() * a.sin(), 30.0 * t.sinh()]
        })
        .collect();
    assert_eq!(fit_ellipsoid(&hyper, None), Err(FitError::NotEllipsoid));
    let good = synth::sphere_samples(50, 0.0, 9);
    assert!(matches!(
        fit_calibration(&good, FieldReference::total(-5.0)),
        Err(FitError::BadReference { .. })
    ));
    let level = synth::level_turn_samples(36, 0.0, 0.0, 10);
    // F = 10 µT is below the ~20 µT horizontal radius.
    assert!(matches!(
        fit_ellipse_level(&level, FieldReference::total(10.0)),
        Err(FitError::InconsistentVertical { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    #[test]
    fn random_finite_samples_never_panic(
        samples in prop::collection::vec(prop::array::uniform3(-2e6..2e6f64), 0..40),
        small in prop::collection::vec(prop::array::uniform3(-1.0..1.0f64), 0..15),
        f in prop::option::of(-100.0..100.0f64),
        dip in prop::option::of(-95.0..95.0f64),
    ) {
        let reference = FieldReference { total_ut: f, dip_deg: dip };
        for s in [&samples, &small] {
            let fits = [fit_calibration(s, reference), fit_ellipsoid(s, f), fit_ellipse_level(s, reference)];
            for rep in fits.into_iter().flatten() {
                let c = rep.calibration;
                prop_assert!(c.hard_iron_ut.iter().chain(c.soft_iron.iter().flatten()).all(|v| v.is_finite()));
                prop_assert!((0.0..=1.0).contains(&rep.coverage));
            }
        }
    }
}
