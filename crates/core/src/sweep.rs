//! Damping sweep and damping calibration of the tactor model (thesis §3.2.2–3.2.3, Figs 35–41).
//!
//! The viscous damping `b` is the one unmeasured parameter of the tactor; manufacturing spread and
//! temperature move a tactor along a force–frequency curve as `b` varies. [`sweep`] simulates a range of
//! dampings (chosen so that the closed-form steady frequency spans a frequency range), and fits what the
//! thesis fits: `f = A n^B` (n = force amplitude), `f = c0 + c1 i_ss` and the inverse `b(f)`, both as the exact
//! closed form and as the thesis's 4-parameter `b = p1 (f + p2)^p3 + p4`. [`calibrate_damping`] returns the
//! damping that makes the simulated tactor turn at a measured peak frequency (the thesis's 133.2 Hz tactor).
//!
//! "Frequency" of a simulated point is its rotation frequency `f_rot`, the exact location of the acceleration's
//! spectral peak, measured over the whole revolutions inside the window
//! ([`Summary::omega_mean_revs_rad_s`] / 2 pi, independent of the ripple's phase at the window ends); the 1 Hz
//! FFT bin is reported alongside.

use std::f64::consts::TAU;

use serde::{Deserialize, Serialize};

use crate::fit::{Curve, FitError, LineFit, PowerLawFit, fit_line, fit_power_law, least_squares};
use crate::tactor::{SimOptions, Summary, TactorError, TactorParams, simulate_summary};

/// Scale of `b` inside the 4-parameter fit, so the fitted parameters are of order 1..1000.
const DAMPING_SCALE_N_M_S: f64 = 1e-8;
/// Relative frequency agreement at which [`calibrate_damping`] stops.
const CALIBRATION_REL_TOL: f64 = 1e-7;
/// Most refinement simulations [`calibrate_damping`] runs.
const CALIBRATION_MAX_ITER: usize = 12;

/// Why a sweep or calibration could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SweepError {
    /// The tactor parameters or simulation options were rejected.
    #[error(transparent)]
    Tactor(#[from] TactorError),
    /// A least-squares fit failed.
    #[error("fit failed: {0}")]
    Fit(#[from] FitError),
    /// The frequency cannot be reached with a non-negative damping (or is not a positive finite number).
    #[error(
        "frequency {frequency_hz} Hz is outside (0, {max_hz:.2}) Hz, the range reachable with damping >= 0 \
         (the limit is the no-load speed u/Kt)"
    )]
    FrequencyOutOfRange {
        /// The requested frequency.
        frequency_hz: f64,
        /// The no-load frequency `u / (2 pi Kt)`.
        max_hz: f64,
    },
    /// The sweep's frequency range is empty or reversed.
    #[error("sweep range must satisfy 0 < min_hz < max_hz, got {min_hz}..{max_hz}")]
    BadRange {
        /// Lower end.
        min_hz: f64,
        /// Upper end.
        max_hz: f64,
    },
    /// The number of sweep points is outside 4..=10000 (the 4-parameter fit needs 4).
    #[error("a sweep needs 4..=10000 points, got {0}")]
    Points(usize),
    /// The calibration did not reach the frequency (cannot happen inside the reachable range).
    #[error("calibration did not converge: simulated {achieved_hz} Hz for a target of {target_hz} Hz")]
    NoConvergence {
        /// Target frequency.
        target_hz: f64,
        /// Best simulated frequency.
        achieved_hz: f64,
    },
}

/// No-load rotation frequency `u / (2 pi Kt)` \[Hz\]: the limit of the closed-form steady state as `b -> 0`.
pub fn max_frequency_hz(params: &TactorParams) -> f64 {
    params.voltage_v / (TAU * params.torque_constant_n_m_per_a)
}

/// Exact closed-form inverse of the steady state: from `omega = Kt u / (R b + Kt^2)` with `omega = 2 pi f`,
/// `b(f) = (Kt u / (2 pi f) - Kt^2) / R` (thesis §3.2.3 inverts this numerically; here it is exact).
pub fn damping_for_frequency(params: &TactorParams, frequency_hz: f64) -> Result<f64, SweepError> {
    params.validate()?;
    let max_hz = max_frequency_hz(params);
    if !(frequency_hz.is_finite() && frequency_hz > 0.0 && frequency_hz < max_hz) {
        return Err(SweepError::FrequencyOutOfRange { frequency_hz, max_hz });
    }
    let kt = params.torque_constant_n_m_per_a;
    Ok((kt * params.voltage_v / (TAU * frequency_hz) - kt * kt) / params.resistance_ohm)
}

/// Range and resolution of a damping sweep.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SweepOptions {
    /// Lowest closed-form steady frequency \[Hz\] (sets the largest damping).
    pub min_hz: f64,
    /// Highest closed-form steady frequency \[Hz\] (sets the smallest damping).
    pub max_hz: f64,
    /// Number of dampings, evenly spaced in frequency.
    pub points: usize,
    /// Simulation of each point: 2 s at 10 kHz by default (the window is the last second, long after the
    /// ~0.1–0.3 s settling).
    pub sim: SimOptions,
}

impl Default for SweepOptions {
    fn default() -> Self {
        Self {
            min_hz: 80.0,
            max_hz: 200.0,
            points: 40,
            sim: SimOptions { duration_s: 2.0, output_rate_hz: 10_000.0 },
        }
    }
}

/// One simulated tactor of a sweep.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SweepPoint {
    /// Damping simulated [N m s].
    pub damping_n_m_s: f64,
    /// Closed-form steady frequency of that damping [Hz].
    pub closed_form_hz: f64,
    /// Simulated rotation (peak) frequency over whole revolutions of the window [Hz].
    pub f_rot_hz: f64,
    /// FFT peak of the acceleration over the last 1 s \[Hz\] (1 Hz bins).
    pub fft_peak_1s_hz: f64,
    /// Force amplitude `Mt * peak |v'|` [N].
    pub force_amplitude_n: f64,
    /// Peak |v'| [m/s^2].
    pub accel_peak_m_s2: f64,
    /// Mean (steady) current over the window [A].
    pub current_mean_a: f64,
    /// Mean torque over the window [N m].
    pub torque_mean_n_m: f64,
    /// Relative half peak-to-peak speed ripple.
    pub omega_ripple: f64,
}

impl SweepPoint {
    fn from_summary(s: &Summary) -> Self {
        Self {
            damping_n_m_s: s.params.damping_n_m_s,
            closed_form_hz: s.steady_state.f_rot_hz,
            f_rot_hz: f_rot_revs_hz(s),
            fft_peak_1s_hz: s.fft_peak_1s_hz,
            force_amplitude_n: s.force_amplitude_n,
            accel_peak_m_s2: s.accel_peak_m_s2,
            current_mean_a: s.current_mean_a,
            torque_mean_n_m: s.torque_mean_n_m,
            omega_ripple: s.omega_ripple,
        }
    }
}

/// Rotation frequency over whole revolutions, or `delta theta / delta t` if the window holds less than one.
fn f_rot_revs_hz(s: &Summary) -> f64 {
    if s.omega_mean_revs_rad_s.is_finite() { s.omega_mean_revs_rad_s / TAU } else { s.f_rot_hz }
}

/// Simulates one tactor with damping `damping_n_m_s` and keeps the sweep figures (no traces).
pub fn sweep_point(
    params: &TactorParams,
    damping_n_m_s: f64,
    sim: &SimOptions,
) -> Result<SweepPoint, SweepError> {
    let s = simulate_summary(&params.with_damping(damping_n_m_s), sim)?;
    Ok(SweepPoint::from_summary(&s))
}

/// The exact inverse `b(f) = a / f + c` with `a = Kt u / (2 pi R)` and `c = -Kt^2 / R`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ExactInverse {
    /// `Kt u / (2 pi R)` [N m s Hz].
    pub a_n_m_s_hz: f64,
    /// `-Kt^2 / R` [N m s].
    pub c_n_m_s: f64,
}

impl ExactInverse {
    /// The inverse of `params`' closed-form steady state.
    pub fn new(params: &TactorParams) -> Self {
        let kt = params.torque_constant_n_m_per_a;
        Self {
            a_n_m_s_hz: kt * params.voltage_v / (TAU * params.resistance_ohm),
            c_n_m_s: -kt * kt / params.resistance_ohm,
        }
    }

    /// `b(f)` [N m s].
    pub fn eval(&self, frequency_hz: f64) -> f64 {
        self.a_n_m_s_hz / frequency_hz + self.c_n_m_s
    }
}

/// The thesis's 4-parameter inverse `b = p1 (f + p2)^p3 + p4` (f in Hz, b in N m s), least-squares fitted to
/// the simulated `(f_rot, b)` points (Levenberg–Marquardt, started from the exact inverse `p2 = 0, p3 = -1`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct InverseFit {
    /// Factor [N m s Hz^-p3].
    pub p1: f64,
    /// Frequency offset [Hz].
    pub p2: f64,
    /// Exponent.
    pub p3: f64,
    /// Offset [N m s].
    pub p4: f64,
    /// Largest |fit - b| / b over the simulated points.
    pub max_rel_residual: f64,
    /// Largest |fit(f) - exact(f)| / exact(f) over the sweep's frequencies: how far the simulated calibration
    /// curve (speed ripple included) lies from the ripple-free closed form.
    pub max_rel_dev_from_exact: f64,
}

impl InverseFit {
    /// `b(f)` [N m s].
    pub fn eval(&self, frequency_hz: f64) -> f64 {
        self.p1 * (frequency_hz + self.p2).powf(self.p3) + self.p4
    }
}

/// A damping sweep with its fits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepResult {
    /// Parameters of the swept tactor (its damping is replaced point by point).
    pub params: TactorParams,
    /// Range and resolution.
    pub options: SweepOptions,
    /// The simulated points, by increasing frequency (decreasing damping).
    pub points: Vec<SweepPoint>,
    /// `f_rot = A n^B` over (force amplitude, `f_rot`) (thesis Fig 35).
    pub power_law: PowerLawFit,
    /// `f_rot = c0 + c1 i` over (mean current, `f_rot`) (thesis Fig 37); closed form: `c0 = u / (2 pi Kt)`,
    /// `c1 = -R / (2 pi Kt)`.
    pub current_line: LineFit,
    /// Exact closed-form inverse `b(f)`.
    pub exact_inverse: ExactInverse,
    /// The thesis's 4-parameter inverse fitted to the simulated points (Fig 38).
    pub inverse_fit: InverseFit,
}

/// Sweeps the damping so that the closed-form frequency runs evenly over `min_hz..=max_hz`, simulates each
/// tactor (summary only) and fits the power law, the current line and the 4-parameter inverse.
pub fn sweep(params: &TactorParams, options: &SweepOptions) -> Result<SweepResult, SweepError> {
    params.validate()?;
    options.sim.validate()?;
    let (lo, hi) = (options.min_hz, options.max_hz);
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo < hi) {
        return Err(SweepError::BadRange { min_hz: lo, max_hz: hi });
    }
    if !(4..=10_000).contains(&options.points) {
        return Err(SweepError::Points(options.points));
    }
    damping_for_frequency(params, hi)?;
    let step = (hi - lo) / (options.points - 1) as f64;
    let points = (0..options.points)
        .map(|k| {
            let f = lo + step * k as f64;
            sweep_point(params, damping_for_frequency(params, f)?, &options.sim)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let f: Vec<f64> = points.iter().map(|p| p.f_rot_hz).collect();
    let force: Vec<f64> = points.iter().map(|p| p.force_amplitude_n).collect();
    let current: Vec<f64> = points.iter().map(|p| p.current_mean_a).collect();
    let b: Vec<f64> = points.iter().map(|p| p.damping_n_m_s).collect();
    let power_law = fit_power_law(&force, &f)?;
    let current_line = fit_line(&current, &f)?;
    let exact_inverse = ExactInverse::new(params);
    let inverse_fit = fit_inverse(&f, &b, &exact_inverse)?;
    Ok(SweepResult {
        params: *params,
        options: *options,
        points,
        power_law,
        current_line,
        exact_inverse,
        inverse_fit,
    })
}

/// Fits `b = p1 (f + p2)^p3 + p4` to `(f, b)`, started from the exact inverse.
fn fit_inverse(f: &[f64], b: &[f64], exact: &ExactInverse) -> Result<InverseFit, SweepError> {
    let s = DAMPING_SCALE_N_M_S;
    let start = [exact.a_n_m_s_hz / s, 0.0, -1.0, exact.c_n_m_s / s];
    let bs: Vec<f64> = b.iter().map(|v| v / s).collect();
    let p = least_squares(&InverseLaw, f, &bs, start)?.params;
    let mut fit = InverseFit {
        p1: p[0] * s,
        p2: p[1],
        p3: p[2],
        p4: p[3] * s,
        max_rel_residual: 0.0,
        max_rel_dev_from_exact: 0.0,
    };
    for (fk, bk) in f.iter().zip(b) {
        let v = fit.eval(*fk);
        if !v.is_finite() {
            return Err(
                FitError::NoConvergence("the fitted inverse is not finite over the sweep".into()).into()
            );
        }
        fit.max_rel_residual = fit.max_rel_residual.max(((v - bk) / bk).abs());
        let e = exact.eval(*fk);
        fit.max_rel_dev_from_exact = fit.max_rel_dev_from_exact.max(((v - e) / e).abs());
    }
    Ok(fit)
}

/// `p1 (f + p2)^p3 + p4`, defined where `f + p2 > 0`.
struct InverseLaw;

impl Curve<4> for InverseLaw {
    fn value(&self, [p1, p2, p3, p4]: &[f64; 4], f: f64) -> Option<f64> {
        let g = f + p2;
        (g > 0.0).then(|| p1 * g.powf(*p3) + p4)
    }

    fn gradient(&self, [p1, p2, p3, _]: &[f64; 4], f: f64) -> Option<[f64; 4]> {
        let g = f + p2;
        if g <= 0.0 {
            return None;
        }
        let gp = g.powf(*p3);
        Some([gp, p1 * p3 * gp / g, p1 * gp * g.ln(), 1.0])
    }
}

/// The damping that reproduces a measured peak frequency.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// The measured peak frequency [Hz].
    pub frequency_hz: f64,
    /// Exact closed-form damping `b(f)` (speed ripple ignored) [N m s].
    pub damping_closed_form_n_m_s: f64,
    /// Damping whose simulated rotation frequency equals the target [N m s].
    pub damping_n_m_s: f64,
    /// Simulated rotation frequency at that damping, over whole revolutions [Hz].
    pub achieved_f_rot_hz: f64,
    /// Number of refinement simulations.
    pub iterations: usize,
    /// Summary of the last refinement simulation.
    pub summary: Summary,
}

impl Calibration {
    /// The calibrated tactor: the input parameters with the calibrated damping.
    pub fn params(&self) -> TactorParams {
        self.summary.params
    }
}

/// Finds the damping whose simulated rotation frequency is `frequency_hz` (thesis §3.2.3: the tactor with a
/// measured 133.2 Hz peak).
///
/// Starts from the exact closed-form inverse and corrects for the speed ripple by fixed-point iteration on
/// the closed-form target: `f_cf <- f_cf * f / f_sim(b(f_cf))`, `b = b(f_cf)`, until the simulated frequency
/// agrees to 1e-7 (the ripple shifts the mean speed by only ~0.1 %, so two or three simulations suffice).
pub fn calibrate_damping(
    params: &TactorParams,
    frequency_hz: f64,
    sim: &SimOptions,
) -> Result<Calibration, SweepError> {
    let b0 = damping_for_frequency(params, frequency_hz)?;
    let max_hz = max_frequency_hz(params);
    let mut target_cf = frequency_hz;
    let mut b = b0;
    let mut best_hz = f64::NAN;
    for iteration in 1..=CALIBRATION_MAX_ITER {
        let summary = simulate_summary(&params.with_damping(b), sim)?;
        let f_sim = f_rot_revs_hz(&summary);
        if !(f_sim.is_finite() && f_sim > 0.0) {
            break;
        }
        if best_hz.is_nan() || (f_sim - frequency_hz).abs() < (best_hz - frequency_hz).abs() {
            best_hz = f_sim;
        }
        if (f_sim - frequency_hz).abs() <= CALIBRATION_REL_TOL * frequency_hz {
            return Ok(Calibration {
                frequency_hz,
                damping_closed_form_n_m_s: b0,
                damping_n_m_s: b,
                achieved_f_rot_hz: f_sim,
                iterations: iteration,
                summary,
            });
        }
        target_cf = (target_cf * frequency_hz / f_sim).min(max_hz * (1.0 - 1e-9));
        b = damping_for_frequency(params, target_cf)?;
    }
    Err(SweepError::NoConvergence { target_hz: frequency_hz, achieved_hz: best_hz })
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    use super::*;
    use crate::tactor::{BodyMass, Preset};

    fn thesis() -> TactorParams {
        TactorParams::preset(Preset::ThesisSim)
    }

    #[test]
    fn sweep_fits_match_closed_forms_and_thesis() {
        let p = thesis();
        let r = sweep(&p, &SweepOptions::default()).unwrap();
        assert_eq!(r.points.len(), 40);
        // Constant-speed force m l w^2 gives f = n^0.5 / (2 pi sqrt(m l)); the thesis's measured exponent
        // is 0.4839.
        assert!((r.power_law.exponent - 0.5).abs() < 0.01, "{:?}", r.power_law);
        assert!(r.power_law.r2 > 0.999);
        // f = u/(2 pi Kt) - R/(2 pi Kt) i, from i = (u - Kt omega)/R.
        assert_relative_eq!(
            r.current_line.intercept,
            3.3 / (std::f64::consts::TAU * 0.0019),
            max_relative = 1e-4
        );
        assert_relative_eq!(
            r.current_line.slope,
            -62.0 / (std::f64::consts::TAU * 0.0019),
            max_relative = 1e-3
        );
        assert!(r.current_line.r2 > 0.999_99);
        // The 4-parameter inverse reproduces the simulated points and the exact inverse within 1 %.
        assert!(r.inverse_fit.max_rel_residual < 1e-3, "{:?}", r.inverse_fit);
        assert!(r.inverse_fit.max_rel_dev_from_exact < 0.01, "{:?}", r.inverse_fit);
        assert_relative_eq!(r.inverse_fit.p3, -1.0, max_relative = 0.05);
        // Frequency increases as damping decreases along the sweep.
        assert!(
            r.points
                .windows(2)
                .all(|w| w[1].f_rot_hz > w[0].f_rot_hz && w[1].damping_n_m_s < w[0].damping_n_m_s)
        );
    }

    #[test]
    fn encased_sweep_lies_on_nearly_the_same_force_curve() {
        let o = SweepOptions { points: 8, ..SweepOptions::default() };
        let a = sweep(&thesis(), &o).unwrap();
        let b = sweep(&thesis().with_body(BodyMass::Encased), &o).unwrap();
        assert_relative_eq!(a.power_law.exponent, b.power_law.exponent, max_relative = 0.05);
    }

    #[test]
    fn calibration_reproduces_the_measured_peak() {
        let c = calibrate_damping(&thesis(), 133.2, &SweepOptions::default().sim).unwrap();
        assert_relative_eq!(c.achieved_f_rot_hz, 133.2, max_relative = 1e-6);
        assert_relative_eq!(c.damping_n_m_s, c.damping_closed_form_n_m_s, max_relative = 0.01);
        assert_relative_eq!(c.params().damping_n_m_s, c.damping_n_m_s);
        assert!(c.iterations <= CALIBRATION_MAX_ITER);
    }

    #[test]
    fn bad_requests_are_errors() {
        let p = thesis();
        assert!(matches!(damping_for_frequency(&p, 300.0), Err(SweepError::FrequencyOutOfRange { .. })));
        assert!(matches!(damping_for_frequency(&p, f64::NAN), Err(SweepError::FrequencyOutOfRange { .. })));
        assert!(matches!(damping_for_frequency(&p, -5.0), Err(SweepError::FrequencyOutOfRange { .. })));
        let o = SweepOptions::default();
        assert_eq!(sweep(&p, &SweepOptions { points: 3, ..o }), Err(SweepError::Points(3)));
        assert!(matches!(
            sweep(&p, &SweepOptions { min_hz: 150.0, max_hz: 100.0, ..o }),
            Err(SweepError::BadRange { .. })
        ));
        assert!(matches!(
            sweep(&p, &SweepOptions { max_hz: 290.0, ..o }),
            Err(SweepError::FrequencyOutOfRange { .. })
        ));
    }

    proptest! {
        #[test]
        fn exact_inverse_round_trips(f in 1.0..276.0f64, u in 1.0..6.0f64, r in 20.0..100.0f64) {
            let mut p = thesis().with_voltage(u);
            p.resistance_ohm = r;
            prop_assume!(f < max_frequency_hz(&p) * 0.999);
            let b = damping_for_frequency(&p, f).unwrap();
            let back = p.with_damping(b).steady_state().f_rot_hz;
            prop_assert!((back / f - 1.0).abs() < 1e-12);
            prop_assert!((ExactInverse::new(&p).eval(f) / b - 1.0).abs() < 1e-12);
        }
    }
}
