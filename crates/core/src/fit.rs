//! Least-squares curve fits shared by the sweep, the measured-data analysis and the two-point simulation,
//! and the one nonlinear least-squares path they all use ([`least_squares`] over a [`Curve`]).
//!
//! Goodness of fit is the coefficient of determination computed in the data's own (linear) space,
//! `R^2 = 1 - SSE/SST`, as MATLAB's curve-fitting tool reports it (the thesis's fits come from there).

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use serde::{Deserialize, Serialize};

/// Why a fit could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// Fewer usable points than the model has parameters (or x and y differ in length).
    #[error("need at least {needed} paired points, got {got}")]
    TooFewPoints {
        /// Points the model needs.
        needed: usize,
        /// Points given.
        got: usize,
    },
    /// The x values do not vary, so no slope (or exponent) is defined.
    #[error("x values are all equal; the fit is undefined")]
    Degenerate,
    /// A power law needs strictly positive x and y.
    #[error("a power-law fit needs x > 0 and y > 0")]
    NonPositive,
    /// The optimiser did not converge.
    #[error("least-squares solver did not converge: {0}")]
    NoConvergence(String),
}

/// A straight line `y = intercept + slope * x` fitted by ordinary least squares.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LineFit {
    /// Value at x = 0.
    pub intercept: f64,
    /// dy/dx.
    pub slope: f64,
    /// Coefficient of determination.
    pub r2: f64,
}

impl LineFit {
    /// Evaluates the line at `x`.
    pub fn eval(&self, x: f64) -> f64 {
        self.intercept + self.slope * x
    }
}

/// A power law `y = coefficient * x^exponent` (MATLAB `power1`), fitted by nonlinear least squares in linear space.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PowerLawFit {
    /// The factor A in `A x^B`.
    pub coefficient: f64,
    /// The exponent B in `A x^B`.
    pub exponent: f64,
    /// Coefficient of determination, in linear space.
    pub r2: f64,
}

impl PowerLawFit {
    /// Evaluates `A x^B`.
    pub fn eval(&self, x: f64) -> f64 {
        self.coefficient * x.powf(self.exponent)
    }
}

/// `R^2 = 1 - SSE/SST` of predictions `y_hat` against data `y`; 1 for a perfect fit of constant data.
pub fn r_squared(y: &[f64], y_hat: &[f64]) -> f64 {
    let n = y.len().min(y_hat.len());
    if n == 0 {
        return f64::NAN;
    }
    let mean = y[..n].iter().sum::<f64>() / n as f64;
    let sst: f64 = y[..n].iter().map(|v| (v - mean).powi(2)).sum();
    let sse: f64 = y[..n].iter().zip(&y_hat[..n]).map(|(a, b)| (a - b).powi(2)).sum();
    if sst == 0.0 {
        return if sse == 0.0 { 1.0 } else { f64::NEG_INFINITY };
    }
    1.0 - sse / sst
}

/// Ordinary least-squares line through `(x, y)`:
/// `slope = Sxy / Sxx`, `intercept = mean(y) - slope * mean(x)`.
pub fn fit_line(x: &[f64], y: &[f64]) -> Result<LineFit, FitError> {
    if x.len() != y.len() || x.len() < 2 {
        return Err(FitError::TooFewPoints { needed: 2, got: x.len().min(y.len()) });
    }
    let n = x.len() as f64;
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    let sxx: f64 = x.iter().map(|v| (v - mx).powi(2)).sum();
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    if sxx == 0.0 {
        return Err(FitError::Degenerate);
    }
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let y_hat: Vec<f64> = x.iter().map(|v| intercept + slope * v).collect();
    Ok(LineFit { intercept, slope, r2: r_squared(y, &y_hat) })
}

/// Fits `y = A x^B` by Levenberg–Marquardt on the residuals `A x^B - y` (linear space, as MATLAB's `power1`),
/// started from the log–log line `ln y = ln A + B ln x`.
pub fn fit_power_law(x: &[f64], y: &[f64]) -> Result<PowerLawFit, FitError> {
    if x.len() != y.len() || x.len() < 2 {
        return Err(FitError::TooFewPoints { needed: 2, got: x.len().min(y.len()) });
    }
    if x.iter().chain(y).any(|v| v.is_nan() || *v <= 0.0 || !v.is_finite()) {
        return Err(FitError::NonPositive);
    }
    let lx: Vec<f64> = x.iter().map(|v| v.ln()).collect();
    let ly: Vec<f64> = y.iter().map(|v| v.ln()).collect();
    let start = fit_line(&lx, &ly)?;
    let [a, b] = least_squares(&PowerLaw, x, y, [start.intercept.exp(), start.slope])?.params;
    let y_hat: Vec<f64> = x.iter().map(|v| a * v.powf(b)).collect();
    Ok(PowerLawFit { coefficient: a, exponent: b, r2: r_squared(y, &y_hat) })
}

/// `A x^B` with parameters `[A, B]`.
struct PowerLaw;

impl Curve<2> for PowerLaw {
    fn value(&self, [a, b]: &[f64; 2], x: f64) -> Option<f64> {
        Some(a * x.powf(*b))
    }

    fn gradient(&self, [a, b]: &[f64; 2], x: f64) -> Option<[f64; 2]> {
        let xb = x.powf(*b);
        Some([xb, a * xb * x.ln()])
    }
}

// -----------------------------------------------------------------------------------------------------------
// The one nonlinear least-squares path.

/// A curve `y = f(x; p)` with `N` parameters, fitted by [`least_squares`].
///
/// Both methods return `None` where `p` is outside the model's domain (for example a negative base under a
/// fractional power); the solver then treats the step as failed and shrinks its trust region.
pub trait Curve<const N: usize> {
    /// `f(x; p)`.
    fn value(&self, p: &[f64; N], x: f64) -> Option<f64>;
    /// The partial derivatives `df/dp_k` at `x`.
    fn gradient(&self, p: &[f64; N], x: f64) -> Option<[f64; N]>;
}

/// The minimiser [`least_squares`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solved<const N: usize> {
    /// The parameters.
    pub params: [f64; N],
    /// Sum of squared residuals `sum (f(x_i; p) - y_i)^2` at `params`.
    pub sse: f64,
}

/// Minimises `sum (f(x_i; p) - y_i)^2` over `p` by Levenberg–Marquardt (the `levenberg-marquardt` crate, MINPACK's
/// algorithm), starting from `start`, with the analytic Jacobian of `curve`. Every nonlinear fit in this crate
/// (power law, inverse damping law, skin attenuation, two-point Gaussian) goes through here.
pub fn least_squares<C: Curve<N>, const N: usize>(
    curve: &C,
    x: &[f64],
    y: &[f64],
    start: [f64; N],
) -> Result<Solved<N>, FitError> {
    if x.len() != y.len() || x.len() < N {
        return Err(FitError::TooFewPoints { needed: N, got: x.len().min(y.len()) });
    }
    let problem = CurveProblem { curve, x, y, p: DVector::from_column_slice(&start) };
    let (solved, report) = LevenbergMarquardt::new().minimize(problem);
    if !report.termination.was_successful() {
        return Err(FitError::NoConvergence(format!("{:?}", report.termination)));
    }
    let mut params = [0.0; N];
    params.copy_from_slice(solved.p.as_slice());
    let sse = x
        .iter()
        .zip(y)
        .map(|(x, y)| curve.value(&params, *x).map_or(f64::INFINITY, |v| (v - y).powi(2)))
        .sum();
    Ok(Solved { params, sse })
}

/// Adapts a [`Curve`] and its data to the solver's problem trait.
struct CurveProblem<'a, C, const N: usize> {
    curve: &'a C,
    x: &'a [f64],
    y: &'a [f64],
    p: DVector<f64>,
}

impl<C: Curve<N>, const N: usize> CurveProblem<'_, C, N> {
    fn params_array(&self) -> [f64; N] {
        let mut p = [0.0; N];
        p.copy_from_slice(self.p.as_slice());
        p
    }
}

impl<C: Curve<N>, const N: usize> LeastSquaresProblem<f64, Dyn, Dyn> for CurveProblem<'_, C, N> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, p: &DVector<f64>) {
        self.p.copy_from(p);
    }

    fn params(&self) -> DVector<f64> {
        self.p.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let p = self.params_array();
        let mut r = DVector::zeros(self.x.len());
        for (k, (x, y)) in self.x.iter().zip(self.y).enumerate() {
            r[k] = self.curve.value(&p, *x)? - y;
        }
        Some(r)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let p = self.params_array();
        let mut j = DMatrix::zeros(self.x.len(), N);
        for (row, x) in self.x.iter().enumerate() {
            for (col, d) in self.curve.gradient(&p, *x)?.into_iter().enumerate() {
                j[(row, col)] = d;
            }
        }
        Some(j)
    }
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;

    use super::*;

    #[test]
    fn line_recovers_exact_line() {
        let x = [0.0, 1.0, 2.0, 5.0];
        let y: Vec<f64> = x.iter().map(|v| 3.0 - 0.5 * v).collect();
        let f = fit_line(&x, &y).unwrap();
        assert_relative_eq!(f.slope, -0.5, epsilon = 1e-12);
        assert_relative_eq!(f.intercept, 3.0, epsilon = 1e-12);
        assert_relative_eq!(f.r2, 1.0, epsilon = 1e-12);
    }

    #[test]
    fn line_textbook_example() {
        // x = 1..5, y = [2, 4, 5, 4, 5]: slope 0.6, intercept 2.2, R^2 = 0.6 (by hand: SSE 2.4, SST 6).
        let f = fit_line(&[1.0, 2.0, 3.0, 4.0, 5.0], &[2.0, 4.0, 5.0, 4.0, 5.0]).unwrap();
        assert_relative_eq!(f.slope, 0.6, epsilon = 1e-12);
        assert_relative_eq!(f.intercept, 2.2, epsilon = 1e-12);
        assert_relative_eq!(f.r2, 0.6, epsilon = 1e-12);
    }

    #[test]
    fn power_law_recovers_thesis_fit() {
        // Points on the thesis's measured fit f = 124.7 n^0.4839 (physics.md §1).
        let n: Vec<f64> = (1..=20).map(|k| 0.5 + 0.06 * f64::from(k)).collect();
        let f: Vec<f64> = n.iter().map(|v| 124.7 * v.powf(0.4839)).collect();
        let fit = fit_power_law(&n, &f).unwrap();
        assert_relative_eq!(fit.coefficient, 124.7, max_relative = 1e-9);
        assert_relative_eq!(fit.exponent, 0.4839, max_relative = 1e-9);
        assert_relative_eq!(fit.r2, 1.0, epsilon = 1e-12);
    }

    /// `y = c0 + c1 x` through the generic solver lands on the closed-form OLS line.
    struct Line;

    impl Curve<2> for Line {
        fn value(&self, [c0, c1]: &[f64; 2], x: f64) -> Option<f64> {
            Some(c0 + c1 * x)
        }

        fn gradient(&self, _: &[f64; 2], x: f64) -> Option<[f64; 2]> {
            Some([1.0, x])
        }
    }

    #[test]
    fn generic_solver_matches_the_closed_form_line() {
        let x = [1.0, 2.0, 3.0, 4.0, 5.0];
        let y = [2.0, 4.0, 5.0, 4.0, 5.0];
        let s = least_squares(&Line, &x, &y, [0.0, 0.0]).unwrap();
        // By hand: slope 0.6, intercept 2.2, SSE 2.4.
        assert_relative_eq!(s.params[0], 2.2, epsilon = 1e-9);
        assert_relative_eq!(s.params[1], 0.6, epsilon = 1e-9);
        assert_relative_eq!(s.sse, 2.4, epsilon = 1e-9);
    }

    /// `exp(-k x)`, defined for `k >= 0` only, to exercise the solver's domain handling.
    struct Decay;

    impl Curve<1> for Decay {
        fn value(&self, [k]: &[f64; 1], x: f64) -> Option<f64> {
            (*k >= 0.0).then(|| (-k * x).exp())
        }

        fn gradient(&self, [k]: &[f64; 1], x: f64) -> Option<[f64; 1]> {
            (*k >= 0.0).then(|| [-x * (-k * x).exp()])
        }
    }

    #[test]
    fn generic_solver_recovers_a_decay_rate_and_refuses_too_few_points() {
        let x: Vec<f64> = (0..20).map(|k| f64::from(k) * 0.1).collect();
        let y: Vec<f64> = x.iter().map(|x| (-1.7 * x).exp()).collect();
        let s = least_squares(&Decay, &x, &y, [0.2]).unwrap();
        assert_relative_eq!(s.params[0], 1.7, max_relative = 1e-9);
        assert!(s.sse < 1e-20);
        assert_eq!(
            least_squares(&Line, &[1.0], &[1.0], [0.0, 0.0]),
            Err(FitError::TooFewPoints { needed: 2, got: 1 })
        );
    }

    #[test]
    fn bad_inputs_are_errors() {
        assert_eq!(fit_line(&[1.0], &[1.0]), Err(FitError::TooFewPoints { needed: 2, got: 1 }));
        assert_eq!(fit_line(&[1.0, 1.0], &[1.0, 2.0]), Err(FitError::Degenerate));
        assert_eq!(fit_power_law(&[1.0, -1.0], &[1.0, 2.0]), Err(FitError::NonPositive));
    }
}
