//! Least-squares curve fits shared by the sweep, the measured-data analysis and the two-point simulation.
//!
//! Goodness of fit is the coefficient of determination computed in the data's own (linear) space,
//! `R^2 = 1 - SSE/SST`, as MATLAB's curve-fitting tool reports it (the thesis's fits come from there).

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{Dyn, Matrix, Owned, U2, Vector2};
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
    let problem = PowerLawProblem { x, y, p: Vector2::new(start.intercept.exp(), start.slope) };
    let (solved, report) = LevenbergMarquardt::new().minimize(problem);
    if !report.termination.was_successful() {
        return Err(FitError::NoConvergence(format!("{:?}", report.termination)));
    }
    let (a, b) = (solved.p[0], solved.p[1]);
    let y_hat: Vec<f64> = x.iter().map(|v| a * v.powf(b)).collect();
    Ok(PowerLawFit { coefficient: a, exponent: b, r2: r_squared(y, &y_hat) })
}

struct PowerLawProblem<'a> {
    x: &'a [f64],
    y: &'a [f64],
    p: Vector2<f64>,
}

impl LeastSquaresProblem<f64, Dyn, U2> for PowerLawProblem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, U2>;
    type ParameterStorage = Owned<f64, U2>;

    fn set_params(&mut self, p: &Vector2<f64>) {
        self.p.copy_from(p);
    }

    fn params(&self) -> Vector2<f64> {
        self.p
    }

    fn residuals(&self) -> Option<Matrix<f64, Dyn, nalgebra::U1, Self::ResidualStorage>> {
        let (a, b) = (self.p[0], self.p[1]);
        Some(nalgebra::DVector::from_iterator(
            self.x.len(),
            self.x.iter().zip(self.y).map(|(x, y)| a * x.powf(b) - y),
        ))
    }

    fn jacobian(&self) -> Option<Matrix<f64, Dyn, U2, Self::JacobianStorage>> {
        let (a, b) = (self.p[0], self.p[1]);
        let mut j = nalgebra::OMatrix::<f64, Dyn, U2>::zeros(self.x.len());
        for (row, x) in self.x.iter().enumerate() {
            let xb = x.powf(b);
            j[(row, 0)] = xb;
            j[(row, 1)] = a * xb * x.ln();
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

    #[test]
    fn bad_inputs_are_errors() {
        assert_eq!(fit_line(&[1.0], &[1.0]), Err(FitError::TooFewPoints { needed: 2, got: 1 }));
        assert_eq!(fit_line(&[1.0, 1.0], &[1.0, 2.0]), Err(FitError::Degenerate));
        assert_eq!(fit_power_law(&[1.0, -1.0], &[1.0, 2.0]), Err(FitError::NonPositive));
    }
}
