//! Hard/soft-iron calibration by least-squares ellipsoid (3-D) or ellipse (2-D, level turn) fitting.

use nalgebra::{DMatrix, Matrix2, Matrix3, SVD, SymmetricEigen, Vector2, Vector3};
use serde::{Deserialize, Serialize};

use super::calibration::Calibration;
use super::tilt::norm3;

/// Fewest samples for the 3-D fit (the general quadric has 9 degrees of freedom).
pub const MIN_SAMPLES_3D: usize = 9;
/// Fewest samples for the 2-D fit (the general conic has 5 degrees of freedom).
pub const MIN_SAMPLES_2D: usize = 5;
/// Largest magnitude accepted in a sample [µT]: no magnetometer reads more, larger values are garbage.
pub const MAX_SAMPLE_UT: f64 = 1e6;
/// [`fit_calibration`] treats the samples as planar when the smallest eigenvalue of their covariance is
/// below this fraction of the largest (their thinnest spread is under ~30 % of the widest: tilts of less
/// than about ±25° during a turn).
pub const PLANAR_EIGEN_RATIO: f64 = 0.1;
/// A planar sample set is fitted in 2-D only if its plane's normal is within this angle of body `z`
/// (the wearer turned about a roughly vertical axis) [deg].
pub const MAX_PLANE_TILT_DEG: f64 = 20.0;
/// Width of the heading bins of the coverage figure [deg].
pub const COVERAGE_BIN_DEG: f64 = 10.0;
/// Largest accepted ratio of the fitted ellipsoid's longest to shortest axis: a vest's soft iron distorts
/// by tens of percent; a larger ratio comes from samples that cover too little of the sphere.
pub const MAX_AXIS_RATIO: f64 = 4.0;

/// What the fit knows of the true Earth field at the place (World Magnetic Model), for its scale.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct FieldReference {
    /// Total intensity `F` [µT]; `None` scales to the fitted mean radius.
    pub total_ut: Option<f64>,
    /// Inclination (dip) `I` below the horizontal [deg]; only the level (2-D) fit uses it.
    pub dip_deg: Option<f64>,
}

impl FieldReference {
    /// No reference: scale to the samples' mean radius.
    pub const NONE: Self = Self { total_ut: None, dip_deg: None };

    /// Only the total intensity `F` [µT].
    pub const fn total(total_ut: f64) -> Self {
        Self { total_ut: Some(total_ut), dip_deg: None }
    }

    /// Total intensity and dip of a field vector (north, east, down) [µT], e.g. from
    /// [`crate::geo::magnetic_field_ned_ut`].
    pub fn from_ned(field_ned_ut: [f64; 3]) -> Self {
        let [n, e, d] = field_ned_ut;
        Self { total_ut: Some(norm3(field_ned_ut)), dip_deg: Some(d.atan2(n.hypot(e)).to_degrees()) }
    }
}

/// Which model a calibration fit used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum FitKind {
    /// Full ellipsoid: hard iron in x, y, z and a 3x3 soft iron.
    Ellipsoid3d,
    /// Ellipse in the sensor's x-y plane (level turn): hard iron in x, y and a 2x2 soft iron; the z axis is
    /// passed through unscaled (`W_zz = 1`) with an offset from the reference field, if known.
    Ellipse2d,
}

/// The result of a calibration fit with its figures of merit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitReport {
    /// The fitted calibration.
    pub calibration: Calibration,
    /// Which model was fitted.
    pub kind: FitKind,
    /// RMS of `(|h_i| - F) / F` over the corrected samples [%]: ~0.6 % from 0.3 µT noise on 50 µT in 3-D,
    /// ~2 % in 2-D (plus the uncorrected vertical cross terms); well above that the samples were disturbed
    /// (steel, tilt during a level turn) and the fit should be redone.
    pub residual_rms_pct: f64,
    /// Fraction of the 36 ten-degree heading bins that the corrected samples hit, 0–1 (see
    /// [`heading_coverage`]); below ~0.8 the operator should keep turning.
    pub coverage: f64,
    /// Smallest over largest eigenvalue of the raw samples' covariance (1 for a full sphere, ~0 for a
    /// level turn); compared with [`PLANAR_EIGEN_RATIO`].
    pub planarity: f64,
    /// Number of samples used.
    pub samples: usize,
}

/// Errors of the calibration fits.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// Fewer samples than the model's degrees of freedom.
    #[error("too few samples for the {kind} fit: {got}, need at least {needed}")]
    TooFewSamples {
        /// "3-D" or "2-D".
        kind: &'static str,
        /// Samples required.
        needed: usize,
        /// Samples given.
        got: usize,
    },
    /// A sample component is NaN, infinite or beyond [`MAX_SAMPLE_UT`].
    #[error("sample {index} is not finite or beyond ±1e6 µT")]
    NonFinite {
        /// Index of the first bad sample.
        index: usize,
    },
    /// The reference field strength is not positive and finite, or its dip not within ±80°.
    #[error("reference field {total_ut:?} µT / dip {dip_deg:?}° is not usable")]
    BadReference {
        /// The total intensity given [µT].
        total_ut: Option<f64>,
        /// The dip given [deg].
        dip_deg: Option<f64>,
    },
    /// The samples do not determine a unique conic/quadric (all equal, collinear, coplanar for the 3-D
    /// fit, or the solver did not converge): turn the sensor through more orientations.
    #[error("the samples do not determine an ellipsoid (too little spread); keep turning")]
    Degenerate,
    /// The best-fitting quadric is not an ellipsoid/ellipse (not positive definite) or is implausibly
    /// elongated (axis ratio above [`MAX_AXIS_RATIO`]).
    #[error("the samples do not lie on an ellipsoid (fit is not positive definite or too elongated)")]
    NotEllipsoid,
    /// The samples lie in a plane tilted more than [`MAX_PLANE_TILT_DEG`] from the sensor's x-y plane:
    /// neither the 3-D nor the level 2-D fit applies.
    #[error("samples lie in a plane tilted {tilt_deg:.0}° from level; turn level or tumble the sensor")]
    TiltedPlane {
        /// Angle between the plane's normal and body z [deg].
        tilt_deg: f64,
    },
    /// 2-D fit with only `F`: the horizontal radius is at least `F`, so no vertical field fits.
    #[error("horizontal field {horizontal_ut:.1} µT is not below the reference {field_ut:.1} µT")]
    InconsistentVertical {
        /// Fitted horizontal radius [µT].
        horizontal_ut: f64,
        /// Reference field [µT].
        field_ut: f64,
    },
}

/// Fits a calibration to raw samples, choosing the model by the samples' shape.
///
/// **Rule.** Let `l_min <= l_max` be the eigenvalues of the raw samples' covariance and `n` the
/// eigenvector of `l_min`. If `l_min / l_max >= PLANAR_EIGEN_RATIO` the samples span 3-D and the
/// ellipsoid is fitted ([`fit_ellipsoid`]). Otherwise they are nearly planar — a wearer turning in place —
/// where the quadric's out-of-plane terms are poorly determined: if `n` is within `MAX_PLANE_TILT_DEG` of
/// body z the level ellipse is fitted ([`fit_ellipse_level`]), else [`FitError::TiltedPlane`].
///
/// `reference.total_ut` is the strength `F` (WMM total intensity) the corrected field is scaled to; `None`
/// scales to the fitted mean radius. The level fit also uses the dip (see [`fit_ellipse_level`]).
pub fn fit_calibration(samples_ut: &[[f64; 3]], reference: FieldReference) -> Result<FitReport, FitError> {
    check_inputs(samples_ut, reference, MIN_SAMPLES_3D.min(MIN_SAMPLES_2D), "2-D")?;
    let (planarity, normal) = planarity(samples_ut)?;
    if planarity >= PLANAR_EIGEN_RATIO {
        return fit_ellipsoid(samples_ut, reference.total_ut);
    }
    let tilt_deg = normal.z.abs().min(1.0).acos().to_degrees();
    if tilt_deg > MAX_PLANE_TILT_DEG {
        return Err(FitError::TiltedPlane { tilt_deg });
    }
    fit_ellipse_level(samples_ut, reference)
}

/// Fits the hard iron `b` and a symmetric soft iron `W` so that `|W (m_i - b)| ≈ F` (3-D ellipsoid).
///
/// **Maths.** The raw field is `m = A^-1 h + b` with `|h| = F`, so the samples lie on the ellipsoid
/// `(m - b)^T Q (m - b) = 1`, `Q = A^T A / F^2`. After centring and scaling the samples (`x = (m - mu)/s`,
/// for conditioning) the general quadric `x^T M x + 2 u^T x + d = 0` (10 coefficients
/// `a, b, c, 2f, 2g, 2h, 2p, 2q, 2r, d`) is fitted by total least squares: the coefficient vector is the
/// right singular vector of the design matrix with the smallest singular value (Li & Griffiths 2004 without
/// their ellipsoid-specific constraint; Vasconcelos et al. 2011). Then the centre is
/// `c = -M^-1 u`, `k = c^T M c - d`, and `E = M / k` must be positive definite; the correction is the
/// symmetric square root `W = F E^(1/2) / s` (eigen decomposition `E = V L V^T`, `E^(1/2) = V L^(1/2) V^T`)
/// and `b = mu + s c`. The symmetric root is the unique symmetric positive-definite `W`: it recovers a
/// symmetric soft iron exactly and otherwise differs from the truth by a rotation only (which a
/// body-fixed sensor cannot tell from mounting). Without `F` the scale is the geometric mean of the
/// semi-axes (`det W = 1`: the volume-equivalent sphere).
///
/// **Limits.** The algebraic fit is slightly biased by noise (negligible at 0.3 µT on 50 µT) and needs
/// samples spread over the sphere; a wearer turning in place gives a thin band, for which use
/// [`fit_calibration`] or [`fit_ellipse_level`].
pub fn fit_ellipsoid(samples_ut: &[[f64; 3]], field_ut: Option<f64>) -> Result<FitReport, FitError> {
    check_inputs(samples_ut, FieldReference { total_ut: field_ut, dip_deg: None }, MIN_SAMPLES_3D, "3-D")?;
    let (mu, s) = centre_and_scale(samples_ut.iter().map(|m| Vector3::from(*m)))?;
    let rows = samples_ut.len().max(10);
    let mut design = DMatrix::<f64>::zeros(rows, 10);
    for (i, m) in samples_ut.iter().enumerate() {
        let x = (Vector3::from(*m) - mu) / s;
        let r = [
            x.x * x.x,
            x.y * x.y,
            x.z * x.z,
            2.0 * x.y * x.z,
            2.0 * x.x * x.z,
            2.0 * x.x * x.y,
            2.0 * x.x,
            2.0 * x.y,
            2.0 * x.z,
            1.0,
        ];
        for (j, v) in r.into_iter().enumerate() {
            design[(i, j)] = v;
        }
    }
    let v = null_vector(design)?;
    let mut q = Matrix3::new(v[0], v[5], v[4], v[5], v[1], v[3], v[4], v[3], v[2]);
    let mut u = Vector3::new(v[6], v[7], v[8]);
    let mut d = v[9];
    if q.trace() < 0.0 {
        (q, u, d) = (-q, -u, -d);
    }
    let c = q.try_inverse().ok_or(FitError::NotEllipsoid)? * -u;
    let k = c.dot(&(q * c)) - d;
    let root = sqrt_spd3(&(q / k))?;
    // Semi-axes are 1/sqrt(eigenvalues of E); their geometric mean is det(E)^(-1/6) = det(root)^(-1/3).
    let mean_radius_ut = s * root.determinant().powf(-1.0 / 3.0);
    let f = field_ut.unwrap_or(mean_radius_ut);
    let w = root * (f / s);
    let b = mu + c * s;
    let calibration = Calibration {
        hard_iron_ut: [b.x, b.y, b.z],
        soft_iron: [0, 1, 2].map(|i| [w[(i, 0)], w[(i, 1)], w[(i, 2)]]),
        field_ut: f,
    };
    if !is_finite(&calibration) {
        return Err(FitError::Degenerate);
    }
    Ok(report(samples_ut, calibration, FitKind::Ellipsoid3d))
}

/// Fits a level turn: hard iron `(b_x, b_y)` and a symmetric 2x2 soft iron from the ellipse the samples
/// trace in x-y, then the vertical axis from the known field.
///
/// Horizontal: the maths of [`fit_ellipsoid`] on the conic `x^T M x + 2 u^T x + d = 0` (6 coefficients)
/// gives `W2 = H E^(1/2) / s` and the centre. Vertical: `W = diag(W2, 1)` stays symmetric (the brief's 2x2
/// model; a unit checks symmetry), so soft-iron cross terms into z are not corrected. The vertical offset and
/// scale cannot be separated in a level turn; the offset is `b_z = c0 - Z`, where `c0` is the intercept of a
/// least-squares fit `m_z = c0 + c . h_xy` on the corrected horizontal field (the mean z, unbiased by a
/// partial turn), and:
/// - total `F` and dip `I` known (WMM): `H = F cos I`, `Z = F sin I` — the corrected field is the WMM's;
/// - only `F`: `H = r`, the ellipse's geometric-mean radius (horizontal soft iron taken as
///   volume-preserving), `Z = sign(c0) sqrt(F^2 - r^2)` ([`FitError::InconsistentVertical`] if `r >= F`;
///   the sign assumes `|b_z| < |Z|`);
/// - neither: `H = r`, `b_z = 0`, and the calibration's `F = sqrt(r^2 + c0^2)`.
///
/// **Limits.** The samples must be level within a few degrees: a tilt `theta` moves the x-y reading by
/// about `Z sin theta`, which the ellipse absorbs (±5° of wobble costs ~2° of heading, ±10° ~6°; see
/// docs/heading.md); a raised `residual_rms_pct` shows it. The fitted `b_x, b_y` include the soft-iron
/// cross terms times the vertical field (`S_xz Z`), exact at level. The uncorrected `S_zx, S_zy` make the
/// corrected vertical vary with heading (by ~1.5 µT, 3 % of `|h|`, for 5 % cross terms); headings stay
/// right while roughly level.
pub fn fit_ellipse_level(samples_ut: &[[f64; 3]], reference: FieldReference) -> Result<FitReport, FitError> {
    check_inputs(samples_ut, reference, MIN_SAMPLES_2D, "2-D")?;
    let (mu, s) = centre_and_scale(samples_ut.iter().map(|m| Vector2::new(m[0], m[1])))?;
    let rows = samples_ut.len().max(6);
    let mut design = DMatrix::<f64>::zeros(rows, 6);
    for (i, m) in samples_ut.iter().enumerate() {
        let x = (Vector2::new(m[0], m[1]) - mu) / s;
        let r = [x.x * x.x, x.y * x.y, 2.0 * x.x * x.y, 2.0 * x.x, 2.0 * x.y, 1.0];
        for (j, v) in r.into_iter().enumerate() {
            design[(i, j)] = v;
        }
    }
    let v = null_vector(design)?;
    let mut q = Matrix2::new(v[0], v[2], v[2], v[1]);
    let mut u = Vector2::new(v[3], v[4]);
    let mut d = v[5];
    if q.trace() < 0.0 {
        (q, u, d) = (-q, -u, -d);
    }
    let c = q.try_inverse().ok_or(FitError::NotEllipsoid)? * -u;
    let k = c.dot(&(q * c)) - d;
    let root = sqrt_spd2(&(q / k))?;
    let mean_radius_ut = s / root.determinant().sqrt();
    let h = match (reference.total_ut, reference.dip_deg) {
        (Some(f), Some(dip)) => f * dip.to_radians().cos().abs(),
        _ => mean_radius_ut,
    };
    let w2 = root * (h / s);
    let b = mu + c * s;
    // Vertical intercept: least squares m_z = c0 + c1 h_x / H + c2 h_y / H.
    let mut a = DMatrix::<f64>::zeros(samples_ut.len(), 3);
    let mut z = nalgebra::DVector::<f64>::zeros(samples_ut.len());
    for (i, m) in samples_ut.iter().enumerate() {
        let hxy = w2 * (Vector2::new(m[0], m[1]) - b);
        (a[(i, 0)], a[(i, 1)], a[(i, 2)], z[i]) = (1.0, hxy.x / h, hxy.y / h, m[2]);
    }
    let lin = SVD::try_new(a, true, true, f64::EPSILON, 10_000)
        .and_then(|svd| svd.solve(&z, 1e-9).ok())
        .ok_or(FitError::Degenerate)?;
    let c0 = lin[0];
    let (b_z, f) = match (reference.total_ut, reference.dip_deg) {
        (Some(f), Some(dip)) => (c0 - f * dip.to_radians().sin(), f),
        (Some(f), None) if h >= f => {
            return Err(FitError::InconsistentVertical { horizontal_ut: h, field_ut: f });
        }
        (Some(f), None) => (c0 - c0.signum() * (f * f - h * h).sqrt(), f),
        (None, Some(dip)) => (c0 - h * dip.to_radians().tan(), h / dip.to_radians().cos()),
        (None, None) => (0.0, h.hypot(c0)),
    };
    let calibration = Calibration {
        hard_iron_ut: [b.x, b.y, b_z],
        soft_iron: [[w2[(0, 0)], w2[(0, 1)], 0.0], [w2[(1, 0)], w2[(1, 1)], 0.0], [0.0, 0.0, 1.0]],
        field_ut: f,
    };
    if !is_finite(&calibration) {
        return Err(FitError::Degenerate);
    }
    Ok(report(samples_ut, calibration, FitKind::Ellipse2d))
}

/// Fraction (0–1) of the `360 / COVERAGE_BIN_DEG` heading bins hit by corrected samples.
///
/// Each sample's heading is taken in the sensor's x-y plane as if level, `atan2(-h_y, h_x)` (see
/// [`super::tilt_compensated_heading`]); samples with no horizontal component are skipped. For a wearer
/// turning in place this is the part of a full turn done so far.
pub fn heading_coverage(corrected_ut: &[[f64; 3]]) -> f64 {
    let bins = (360.0 / COVERAGE_BIN_DEG).round() as usize;
    let mut hit = vec![false; bins];
    for h in corrected_ut {
        if h[0].hypot(h[1]) > 0.0 && h[0].is_finite() && h[1].is_finite() {
            let deg = crate::geo::normalize_deg((-h[1]).atan2(h[0]).to_degrees());
            let i = ((deg / COVERAGE_BIN_DEG) as usize).min(bins - 1);
            hit[i] = true;
        }
    }
    hit.iter().filter(|&&b| b).count() as f64 / bins as f64
}

fn check_inputs(
    samples_ut: &[[f64; 3]],
    reference: FieldReference,
    needed: usize,
    kind: &'static str,
) -> Result<(), FitError> {
    if samples_ut.len() < needed {
        return Err(FitError::TooFewSamples { kind, needed, got: samples_ut.len() });
    }
    if let Some(index) = samples_ut.iter().position(|m| !m.iter().all(|v| v.abs() <= MAX_SAMPLE_UT)) {
        return Err(FitError::NonFinite { index });
    }
    let bad_total = reference.total_ut.is_some_and(|f| f.is_nan() || f <= 0.0 || f > MAX_SAMPLE_UT);
    let bad_dip = reference.dip_deg.is_some_and(|d| d.is_nan() || d.abs() > 80.0);
    if bad_total || bad_dip {
        return Err(FitError::BadReference { total_ut: reference.total_ut, dip_deg: reference.dip_deg });
    }
    Ok(())
}

/// Smallest/largest covariance eigenvalue ratio and the eigenvector of the smallest.
fn planarity(samples_ut: &[[f64; 3]]) -> Result<(f64, Vector3<f64>), FitError> {
    let (mu, s) = centre_and_scale(samples_ut.iter().map(|m| Vector3::from(*m)))?;
    let mut cov = Matrix3::zeros();
    for m in samples_ut {
        let x = (Vector3::from(*m) - mu) / s;
        cov += x * x.transpose();
    }
    let eig = SymmetricEigen::try_new(cov, f64::EPSILON, 1000).ok_or(FitError::Degenerate)?;
    let (imin, lmin) = eig.eigenvalues.argmin();
    let lmax = eig.eigenvalues.max();
    if lmax.is_nan() || lmax <= 0.0 {
        return Err(FitError::Degenerate);
    }
    Ok(((lmin / lmax).max(0.0), eig.eigenvectors.column(imin).into_owned()))
}

/// Mean and RMS distance from it; `Degenerate` when all samples coincide.
fn centre_and_scale<const D: usize>(
    points: impl Iterator<Item = nalgebra::SVector<f64, D>> + Clone,
) -> Result<(nalgebra::SVector<f64, D>, f64), FitError> {
    let n = points.clone().count().max(1) as f64;
    let mu = points.clone().sum::<nalgebra::SVector<f64, D>>() / n;
    let s = (points.map(|p| (p - mu).norm_squared()).sum::<f64>() / n).sqrt();
    if s > 1e-9 * (1.0 + mu.norm()) && s.is_finite() { Ok((mu, s)) } else { Err(FitError::Degenerate) }
}

/// The unit vector minimising `|D v|`: the right singular vector of the smallest singular value.
/// `Degenerate` when the null space is more than one-dimensional (the fit is not unique).
fn null_vector(design: DMatrix<f64>) -> Result<Vec<f64>, FitError> {
    let cols = design.ncols();
    let svd = SVD::try_new(design, false, true, f64::EPSILON, 10_000).ok_or(FitError::Degenerate)?;
    let v_t = svd.v_t.ok_or(FitError::Degenerate)?;
    let sv = &svd.singular_values;
    // Sorted in descending order; the last is the fit's residual, the one before must be clearly non-zero.
    if sv.len() != cols || sv[cols - 2].is_nan() || sv[cols - 2] <= 1e-9 * sv[0] {
        return Err(FitError::Degenerate);
    }
    Ok(v_t.row(cols - 1).iter().copied().collect())
}

fn sqrt_spd3(e: &Matrix3<f64>) -> Result<Matrix3<f64>, FitError> {
    let eig = SymmetricEigen::try_new(*e, f64::EPSILON, 1000).ok_or(FitError::NotEllipsoid)?;
    check_axes(eig.eigenvalues.as_slice())?;
    let root = eig.eigenvalues.map(f64::sqrt);
    Ok(eig.eigenvectors * Matrix3::from_diagonal(&root) * eig.eigenvectors.transpose())
}

fn sqrt_spd2(e: &Matrix2<f64>) -> Result<Matrix2<f64>, FitError> {
    let eig = SymmetricEigen::try_new(*e, f64::EPSILON, 1000).ok_or(FitError::NotEllipsoid)?;
    check_axes(eig.eigenvalues.as_slice())?;
    let root = eig.eigenvalues.map(f64::sqrt);
    Ok(eig.eigenvectors * Matrix2::from_diagonal(&root) * eig.eigenvectors.transpose())
}

/// Positive definite, finite, and axis ratio `sqrt(l_max / l_min)` within [`MAX_AXIS_RATIO`].
fn check_axes(eigenvalues: &[f64]) -> Result<(), FitError> {
    if !eigenvalues.iter().all(|l| l.is_finite()) {
        return Err(FitError::NotEllipsoid);
    }
    let lmin = eigenvalues.iter().copied().fold(f64::INFINITY, f64::min);
    let lmax = eigenvalues.iter().copied().fold(0.0, f64::max);
    if lmin > 0.0 && lmax.is_finite() && lmax <= MAX_AXIS_RATIO * MAX_AXIS_RATIO * lmin {
        Ok(())
    } else {
        Err(FitError::NotEllipsoid)
    }
}

fn is_finite(c: &Calibration) -> bool {
    c.soft_iron.iter().flatten().chain(&c.hard_iron_ut).all(|v| v.is_finite()) && c.field_ut.is_finite()
}

fn report(samples_ut: &[[f64; 3]], calibration: Calibration, kind: FitKind) -> FitReport {
    let corrected: Vec<[f64; 3]> = samples_ut.iter().map(|m| calibration.apply(*m)).collect();
    let f = calibration.field_ut;
    let ms = corrected.iter().map(|h| ((norm3(*h) - f) / f).powi(2)).sum::<f64>() / corrected.len() as f64;
    FitReport {
        calibration,
        kind,
        residual_rms_pct: 100.0 * ms.sqrt(),
        coverage: heading_coverage(&corrected),
        planarity: planarity(samples_ut).map_or(0.0, |(p, _)| p),
        samples: samples_ut.len(),
    }
}

#[cfg(test)]
#[path = "fit_tests.rs"]
mod tests;
