//! The two-point simulation (thesis §4.2, Figs 60–63): two tactors' Gaussians summed and fitted by one
//! Gaussian.
//!
//! Two tactors of amplitude `a` (10 m/s^2) and Gaussian width `b` (36.2 mm, the mean of the three measured
//! widths) sit `d` apart on a line:
//!
//! ```text
//! s(x) = a exp(-(x/b)^2) + a exp(-((x-d)/b)^2)
//! ```
//!
//! sampled on `x = -80 ..= 200 mm` in 1 mm steps (281 points) and least-squares fitted by one Gaussian `A
//! exp(-((x-mu)/w)^2)`. `RMSE = sqrt(SSE / (n - 3))` (MATLAB's definition: n points, 3 parameters). While the
//! RMSE stays tiny the two tactors are indistinguishable from one wider tactor; the thesis proposes that the
//! two-point threshold is where the RMSE starts to grow. [`threshold_mm`] makes that a concrete rule.
//!
//! The problem is defined by the thesis on a millimetre grid, so lengths here are in millimetres (named
//! `_mm`).
//!
//! ```
//! use vestnav_core::twopoint::{TwoPointSetup, simulate};
//! let fit = simulate(&TwoPointSetup::THESIS, 11.0).unwrap();
//! // Thesis: A = 19.55, mu = 5.5, w = 37.05, RMSE = 0.001727.
//! assert!((fit.center_mm - 5.5).abs() < 1e-3 && (fit.rmse - 0.001727).abs() < 1e-5);
//! ```

use serde::{Deserialize, Serialize};

use crate::fit::{Curve, FitError, Solved, least_squares};

/// Geometry and amplitudes of the two-point simulation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TwoPointSetup {
    /// Amplitude of each tactor [m/s^2].
    pub amplitude_m_s2: f64,
    /// Gaussian width `b` of each tactor \[mm\].
    pub width_mm: f64,
    /// First grid point \[mm\].
    pub grid_start_mm: f64,
    /// Last grid point \[mm\] (inclusive).
    pub grid_end_mm: f64,
    /// Grid step \[mm\].
    pub grid_step_mm: f64,
}

impl TwoPointSetup {
    /// The thesis's setup (§4.2): 10 m/s^2 each, b = 36.2 mm, x = -80..=200 mm step 1 mm.
    pub const THESIS: Self = Self {
        amplitude_m_s2: 10.0,
        width_mm: 36.2,
        grid_start_mm: -80.0,
        grid_end_mm: 200.0,
        grid_step_mm: 1.0,
    };

    /// The grid positions \[mm\].
    pub fn grid_mm(&self) -> Vec<f64> {
        if !self.grid_step_mm.is_finite()
            || self.grid_step_mm <= 0.0
            || !self.grid_start_mm.is_finite()
            || !self.grid_end_mm.is_finite()
            || self.grid_end_mm < self.grid_start_mm
        {
            return Vec::new();
        }
        let n = ((self.grid_end_mm - self.grid_start_mm) / self.grid_step_mm + 1e-9).floor() as usize + 1;
        (0..n).map(|i| self.grid_start_mm + i as f64 * self.grid_step_mm).collect()
    }

    /// One tactor's Gaussian `a exp(-((x - x0)/b)^2)` at `x_mm` [m/s^2].
    pub fn single_m_s2(&self, x_mm: f64, x0_mm: f64) -> f64 {
        gaussian(self.amplitude_m_s2, x0_mm, self.width_mm, x_mm)
    }

    /// The sum `s(x) = a exp(-(x/b)^2) + a exp(-((x-d)/b)^2)` at `x_mm` (thesis §4.2) [m/s^2].
    pub fn sum_m_s2(&self, x_mm: f64, distance_mm: f64) -> f64 {
        self.single_m_s2(x_mm, 0.0) + self.single_m_s2(x_mm, distance_mm)
    }

    /// The distance at which the summed profile stops having a single peak (Sparrow's criterion): the
    /// centre's curvature `2 G''(d/2)` vanishes at the Gaussian's inflection `d/2 = b / sqrt(2)`, so `d =
    /// sqrt(2) b` (51.2 mm for b = 36.2 mm). Beyond it a dip appears between the tactors.
    pub fn sparrow_limit_mm(&self) -> f64 {
        std::f64::consts::SQRT_2 * self.width_mm
    }
}

/// `A exp(-((x - mu)/w)^2)`.
pub fn gaussian(amplitude: f64, center: f64, width: f64, x: f64) -> f64 {
    amplitude * (-((x - center) / width).powi(2)).exp()
}

/// A single Gaussian `A exp(-((x-mu)/w)^2)` fitted by least squares, with its residuals.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GaussianFit {
    /// Fitted peak `A` [m/s^2].
    #[serde(rename = "amplitude")]
    pub amplitude_m_s2: f64,
    /// Fitted centre `mu` \[mm\].
    pub center_mm: f64,
    /// Fitted width `w` \[mm\] (positive).
    pub width_mm: f64,
    /// `sqrt(SSE / (n - 3))` [m/s^2].
    pub rmse: f64,
    /// Sum of squared residuals [(m/s^2)^2].
    pub sse: f64,
    /// Number of points fitted.
    pub points: usize,
}

impl GaussianFit {
    /// The fitted curve at `x_mm`.
    pub fn eval(&self, x_mm: f64) -> f64 {
        gaussian(self.amplitude_m_s2, self.center_mm, self.width_mm, x_mm)
    }
}

/// Least-squares fit of `A exp(-((x-mu)/w)^2)` to `(x, y)` by Levenberg–Marquardt (analytic Jacobian).
///
/// The sum of squares can have more than one minimum (one broad Gaussian over both peaks, or one narrow
/// Gaussian on one peak), so the solver starts from three points and keeps the smallest SSE: the moments of
/// the positive part of `y` (`mu = sum x y / sum y`, `w = sqrt(2 var)`, since `exp(-(x/w)^2)` has variance
/// `w^2/2`), and the largest sample with `w` from the moments and from the half-maximum width (`w = FWHM / (2
/// sqrt(ln 2))`). `RMSE = sqrt(SSE / (n - 3))` (MATLAB's definition, thesis §4.2).
pub fn fit_gaussian(x: &[f64], y: &[f64]) -> Result<GaussianFit, FitError> {
    if x.len() != y.len() || x.len() < 4 {
        return Err(FitError::TooFewPoints { needed: 4, got: x.len().min(y.len()) });
    }
    if x.iter().chain(y).any(|v| !v.is_finite()) {
        return Err(FitError::NonPositive);
    }
    let (x_min, x_max) =
        x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
    if x_max <= x_min {
        return Err(FitError::Degenerate);
    }
    let weight: f64 = y.iter().map(|v| v.max(0.0)).sum();
    let (i_peak, y_peak) = y
        .iter()
        .enumerate()
        .fold((0, f64::NEG_INFINITY), |best, (i, v)| if *v > best.1 { (i, *v) } else { best });
    if !(weight > 0.0 && y_peak > 0.0) {
        return Err(FitError::NonPositive);
    }
    let mean = x.iter().zip(y).map(|(a, b)| a * b.max(0.0)).sum::<f64>() / weight;
    let var = x.iter().zip(y).map(|(a, b)| (a - mean).powi(2) * b.max(0.0)).sum::<f64>() / weight;
    let w_moments = (2.0 * var).sqrt().max((x_max - x_min) * 1e-3);
    let above_half = x.iter().zip(y).filter(|(_, v)| **v >= y_peak / 2.0).map(|(a, _)| *a);
    let (lo, hi) = above_half.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let w_half = ((hi - lo) / (2.0 * 2f64.ln().sqrt())).max((x_max - x_min) * 1e-3);
    let x_peak = x[i_peak];
    let starts = [[y_peak, mean, w_moments], [y_peak, x_peak, w_half], [y_peak, x_peak, w_moments]];
    let mut best: Option<Solved<3>> = None;
    let mut last_failure = None;
    for p in starts {
        match least_squares(&Gaussian, x, y, p) {
            Ok(solved) if best.is_none_or(|b| solved.sse < b.sse) => best = Some(solved),
            Ok(_) => {}
            Err(e) => last_failure = Some(e),
        }
    }
    let Some(Solved { params: [amplitude, center, width], sse }) = best else {
        return Err(last_failure.unwrap_or(FitError::NoConvergence(String::new())));
    };
    let n = x.len();
    Ok(GaussianFit {
        amplitude_m_s2: amplitude,
        center_mm: center,
        width_mm: width.abs(),
        rmse: (sse / (n - 3) as f64).sqrt(),
        sse,
        points: n,
    })
}

/// [`gaussian`] with parameters `[A, mu, w]`.
struct Gaussian;

impl Curve<3> for Gaussian {
    fn value(&self, [a, mu, w]: &[f64; 3], x: f64) -> Option<f64> {
        Some(gaussian(*a, *mu, *w, x))
    }

    fn gradient(&self, [a, mu, w]: &[f64; 3], x: f64) -> Option<[f64; 3]> {
        let u = (x - mu) / w;
        let e = (-u * u).exp();
        Some([e, a * e * 2.0 * u / w, a * e * 2.0 * u * u / w])
    }
}

/// Result of one two-point simulation: the distance and the single-Gaussian fit of the summed profile.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TwoPointResult {
    /// Distance between the tactors \[mm\].
    pub distance_mm: f64,
    /// The single-Gaussian fit (JSON keys `amplitude, center_mm, width_mm, rmse, sse, points`).
    #[serde(flatten)]
    pub fit: GaussianFit,
}

impl std::ops::Deref for TwoPointResult {
    type Target = GaussianFit;
    fn deref(&self) -> &GaussianFit {
        &self.fit
    }
}

/// Samples the two-tactor sum on the setup's grid and fits one Gaussian to it (thesis §4.2).
pub fn simulate(setup: &TwoPointSetup, distance_mm: f64) -> Result<TwoPointResult, FitError> {
    if !distance_mm.is_finite() {
        return Err(FitError::Degenerate);
    }
    let x = setup.grid_mm();
    let y: Vec<f64> = x.iter().map(|v| setup.sum_m_s2(*v, distance_mm)).collect();
    Ok(TwoPointResult { distance_mm, fit: fit_gaussian(&x, &y)? })
}

/// RMSE (and the whole fit) for each distance in `distances_mm`.
pub fn sweep(setup: &TwoPointSetup, distances_mm: &[f64]) -> Result<Vec<TwoPointResult>, FitError> {
    distances_mm.iter().map(|d| simulate(setup, *d)).collect()
}

/// The default detection level of [`threshold_mm`]: RMSE equal to 1 % of one tactor's amplitude.
pub const DEFAULT_RELATIVE_RMSE: f64 = 0.01;

/// vestnav's concrete version of the thesis's proposal "the two-point threshold is where the RMSE starts to
/// grow" (§4.2). The RMSE grows smoothly from zero (as `d^4` for small `d`: the second-order broadening of
/// the sum is absorbed by a wider fitted Gaussian, only the fourth-order shape difference is left), so
/// "starts to grow" needs a level: the threshold is the smallest distance at which the RMSE of the
/// single-Gaussian fit reaches `relative_rmse` times one tactor's amplitude, i.e. where a single Gaussian
/// misses the measured profile by more than an accelerometer resolving 1 % of the source amplitude could
/// ignore. Found by stepping in 1 mm up to `max_mm` and bisecting the bracketing step to 0.01 mm. With the
/// thesis's setup and 1 % it is about 31 mm, below the Sparrow limit `sqrt(2) b` = 51.2 mm where the profile
/// itself becomes two-peaked. `Ok(None)` if the level is not reached up to `max_mm`.
pub fn threshold_mm(setup: &TwoPointSetup, relative_rmse: f64, max_mm: f64) -> Result<Option<f64>, FitError> {
    if relative_rmse.is_nan() || relative_rmse <= 0.0 || !max_mm.is_finite() {
        return Err(FitError::Degenerate);
    }
    let level = relative_rmse * setup.amplitude_m_s2.abs();
    let above = |d: f64| simulate(setup, d).map(|r| r.rmse >= level);
    let mut lo = 0.0;
    let mut hi = None;
    let mut d = 1.0;
    while d <= max_mm {
        if above(d)? {
            hi = Some(d);
            break;
        }
        lo = d;
        d += 1.0;
    }
    let Some(mut hi) = hi else { return Ok(None) };
    while hi - lo > 0.01 {
        let mid = 0.5 * (lo + hi);
        if above(mid)? {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Ok(Some(hi))
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    use super::*;

    #[test]
    fn grid_has_281_points() {
        let g = TwoPointSetup::THESIS.grid_mm();
        assert_eq!(g.len(), 281);
        assert_relative_eq!(g[0], -80.0);
        assert_relative_eq!(g[280], 200.0);
    }

    #[test]
    fn reference_at_11_mm() {
        // physics.md §3: A = 19.546, mu = 5.500, w = 37.045, RMSE = 0.001727.
        let r = simulate(&TwoPointSetup::THESIS, 11.0).unwrap();
        assert_relative_eq!(r.amplitude_m_s2, 19.546, max_relative = 1e-4);
        assert_relative_eq!(r.center_mm, 5.500, max_relative = 1e-4);
        assert_relative_eq!(r.width_mm, 37.045, max_relative = 1e-4);
        assert_relative_eq!(r.rmse, 0.001_727, max_relative = 1e-3);
        assert_eq!(r.points, 281);
    }

    #[test]
    fn zero_distance_is_one_exact_gaussian() {
        // d = 0: the sum is 20 exp(-(x/b)^2) exactly.
        let r = simulate(&TwoPointSetup::THESIS, 0.0).unwrap();
        assert_relative_eq!(r.amplitude_m_s2, 20.0, max_relative = 1e-9);
        assert_relative_eq!(r.width_mm, 36.2, max_relative = 1e-9);
        assert!(r.center_mm.abs() < 1e-7);
        assert!(r.rmse < 1e-8);
    }

    #[test]
    fn rmse_grows_with_distance_and_threshold_is_bracketed() {
        let setup = TwoPointSetup::THESIS;
        let d: Vec<f64> = (0..=80).map(f64::from).collect();
        let s = sweep(&setup, &d).unwrap();
        for pair in s.windows(2) {
            assert!(pair[1].rmse >= pair[0].rmse);
        }
        let t = threshold_mm(&setup, DEFAULT_RELATIVE_RMSE, 100.0).unwrap().unwrap();
        assert!(simulate(&setup, t).unwrap().rmse >= 0.1);
        assert!(simulate(&setup, t - 0.02).unwrap().rmse < 0.1);
        assert!(t < setup.sparrow_limit_mm());
        assert_eq!(threshold_mm(&setup, 10.0, 20.0).unwrap(), None);
    }

    #[test]
    fn small_distance_rmse_scales_as_fourth_power() {
        // Residual of the best single Gaussian is O(d^4): doubling d multiplies the RMSE by ~16.
        let setup = TwoPointSetup::THESIS;
        let r1 = simulate(&setup, 4.0).unwrap().rmse;
        let r2 = simulate(&setup, 8.0).unwrap().rmse;
        assert_relative_eq!(r2 / r1, 16.0, max_relative = 0.05);
    }

    #[test]
    fn hostile_input_is_an_error() {
        assert!(fit_gaussian(&[1.0, 2.0], &[1.0, 2.0]).is_err());
        assert!(fit_gaussian(&[1.0, 2.0, 3.0, 4.0], &[0.0, 0.0, 0.0, 0.0]).is_err());
        assert!(fit_gaussian(&[1.0, 2.0, f64::NAN, 4.0], &[1.0, 2.0, 1.0, 0.5]).is_err());
        assert!(simulate(&TwoPointSetup::THESIS, f64::INFINITY).is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn fitted_centre_is_the_midpoint(d in 0.0..45.0f64) {
            // By symmetry of the sum about d/2, on a grid wide enough that truncation does not matter.
            let setup = TwoPointSetup { grid_start_mm: -250.0, grid_end_mm: 300.0, ..TwoPointSetup::THESIS };
            let r = simulate(&setup, d).unwrap();
            prop_assert!((r.center_mm - d / 2.0).abs() < 1e-4);
        }

        #[test]
        fn mirrored_pair_mirrors_the_centre(d in 0.0..45.0f64) {
            // The sum for tactors at 0 and -d is the mirror image; its fitted centre is -d/2.
            let setup = TwoPointSetup { grid_start_mm: -300.0, grid_end_mm: 300.0, ..TwoPointSetup::THESIS };
            let a = simulate(&setup, d).unwrap();
            let b = simulate(&setup, -d).unwrap();
            prop_assert!((a.center_mm + b.center_mm).abs() < 1e-4);
            prop_assert!((a.width_mm - b.width_mm).abs() < 1e-6 * a.width_mm);
        }
    }
}
