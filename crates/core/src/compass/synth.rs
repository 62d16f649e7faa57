//! Synthetic magnetometer data with known parameters, for the tests (independent of the code under test:
//! rotations come from nalgebra's Euler angles, the distortion is applied with nalgebra matrices).

use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};

/// Field strength of the synthetic tests [µT].
pub const F_UT: f64 = 50.0;
/// Horizontal intensity of the synthetic field [µT] (dip = acos(20/50) = 66.4°).
pub const H_UT: f64 = 20.0;
/// Hard iron of the synthetic sensor [µT].
pub const HARD_IRON: [f64; 3] = [12.0, -30.0, 25.0];
/// Magnetometer noise per axis [µT].
pub const NOISE_UT: f64 = 0.3;

/// Vertical component of the synthetic field [µT]: `sqrt(F^2 - H^2)`.
pub fn z_ut() -> f64 {
    (F_UT * F_UT - H_UT * H_UT).sqrt()
}

/// Synthetic field in NED with declination `decl_deg` [µT].
pub fn field_ned(decl_deg: f64) -> Vector3<f64> {
    let d = decl_deg.to_radians();
    Vector3::new(H_UT * d.cos(), H_UT * d.sin(), z_ut())
}

/// The soft-iron distortion `S` (raw = S h + b): symmetric, axis scalings 0.88–1.15, cross terms.
pub fn soft_iron() -> Matrix3<f64> {
    Matrix3::new(1.15, 0.08, -0.05, 0.08, 0.88, 0.06, -0.05, 0.06, 1.02)
}

/// Raw reading of the field `h_body` through `S` and the hard iron, plus noise.
pub fn distort(h_body: Vector3<f64>, noise_ut: f64, rng: &mut StdRng) -> [f64; 3] {
    let n = Vector3::from_fn(|_, _| {
        let z: f64 = StandardNormal.sample(rng);
        z * noise_ut
    });
    let m = soft_iron() * h_body + Vector3::from(HARD_IRON) + n;
    [m.x, m.y, m.z]
}

/// Body-frame vector of a NED vector at an attitude, via nalgebra (`R = Rz Ry Rx` body to NED).
pub fn to_body(v_ned: Vector3<f64>, heading_deg: f64, pitch_deg: f64, roll_deg: f64) -> Vector3<f64> {
    let r =
        Rotation3::from_euler_angles(roll_deg.to_radians(), pitch_deg.to_radians(), heading_deg.to_radians());
    r.inverse() * v_ned
}

/// Raw samples over the whole sphere of orientations: `n` field directions on a Fibonacci sphere.
pub fn sphere_samples(n: usize, noise_ut: f64, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = StdRng::seed_from_u64(seed);
    let golden = std::f64::consts::PI * (3.0 - 5.0_f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            distort(Vector3::new(r * phi.cos(), r * phi.sin(), z) * F_UT, noise_ut, &mut rng)
        })
        .collect()
}

/// Raw samples from a level turn through 360° in `n` steps, with a small gait wobble of pitch/roll
/// amplitude `wobble_deg`.
pub fn level_turn_samples(n: usize, wobble_deg: f64, noise_ut: f64, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = StdRng::seed_from_u64(seed);
    (0..n)
        .map(|i| {
            let heading = 360.0 * i as f64 / n as f64;
            let (p, r) = (wobble_deg * (0.7 * i as f64).sin(), wobble_deg * (1.3 * i as f64).cos());
            distort(to_body(field_ned(0.0), heading, p, r), noise_ut, &mut rng)
        })
        .collect()
}

/// Accelerometer reading at rest at an attitude (reaction to gravity, up).
pub fn accel_at(heading_deg: f64, pitch_deg: f64, roll_deg: f64) -> [f64; 3] {
    let f = to_body(Vector3::new(0.0, 0.0, -9.806_65), heading_deg, pitch_deg, roll_deg);
    [f.x, f.y, f.z]
}
