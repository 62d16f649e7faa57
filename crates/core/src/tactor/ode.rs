//! The ODE solver: exponential integrator for the current, Runge–Kutta 4 for the mechanics, sample output.

use super::{SimOptions, TactorError, TactorParams};

/// Largest integrator step away from the start transient [s].
const MAX_STEP_S: f64 = 400e-6;
/// The start transient (current rise) is resolved with steps of `L/R / FINE_STEPS_PER_TAU`...
const FINE_STEPS_PER_TAU: f64 = 16.0;
/// ...for the first `FINE_TAUS` electrical time constants.
const FINE_TAUS: f64 = 20.0;

/// Per-evaluation constants.
#[derive(Debug, Clone, Copy)]
pub(super) struct Consts {
    ml: f64,
    m: f64,
    inv_l: f64,
    mt: f64,
    mt_over_ml2: f64,
    kt: f64,
    b: f64,
    mgl: f64,
    u_over_l: f64,
    kt_over_l: f64,
    pub(super) decay: f64,
}

impl Consts {
    pub(super) fn new(p: &TactorParams) -> Self {
        let m = p.eccentric_mass_kg;
        let l = p.radius_m;
        Self {
            ml: m * l,
            m,
            inv_l: 1.0 / l,
            mt: p.body_mass_kg,
            mt_over_ml2: p.body_mass_kg / (m * l * l),
            kt: p.torque_constant_n_m_per_a,
            b: p.damping_n_m_s,
            mgl: m * p.gravity_m_s2 * l,
            u_over_l: p.voltage_v / p.inductance_h,
            kt_over_l: p.torque_constant_n_m_per_a / p.inductance_h,
            decay: p.resistance_ohm / p.inductance_h,
        }
    }

    /// `(v', omega')` from the mass-matrix solve documented on [`TactorParams::derivatives`].
    #[inline]
    pub(super) fn accelerations(&self, theta: Angle, omega: f64, current: f64) -> (f64, f64) {
        let (s, c) = (theta.sin, theta.cos);
        let f1 = self.ml * omega * omega * s;
        let f2 = self.kt * current - self.b * omega + self.mgl * s;
        let inv_det = 1.0 / (self.mt - self.m * c * c);
        let v_dot = (f1 - c * f2 * self.inv_l) * inv_det;
        let omega_dot = (self.mt_over_ml2 * f2 - c * f1 * self.inv_l) * inv_det;
        (v_dot, omega_dot)
    }

    /// `omega'` alone (the integrator's stages do not need `v'`). Same solve, rearranged for speed: the
    /// reciprocal determinant depends on the angle only, so it is computed while the speed and current of a
    /// stage are still being formed: `omega' = (Mt F2 / (m l^2) - m c s omega^2) / (Mt - m c^2)`.
    #[inline]
    fn omega_dot(&self, theta: Angle, omega: f64, current: f64) -> f64 {
        let (s, c) = (theta.sin, theta.cos);
        let inv_det = 1.0 / (self.mt - self.m * c * c);
        let mcs = self.m * c * s;
        let f2 = self.kt * current - self.b * omega + self.mgl * s;
        (self.mt_over_ml2 * f2 - mcs * (omega * omega)) * inv_det
    }

    /// Non-stiff part of `i'`: `(u - Kt omega)/L`.
    #[inline]
    pub(super) fn current_forcing(&self, omega: f64) -> f64 {
        self.u_over_l - self.kt_over_l * omega
    }
}

/// `phi_1(z) = (e^z - 1)/z`, `phi_2 = (e^z - 1 - z)/z^2`, `phi_3 = (e^z - 1 - z - z^2/2)/z^3`, by Taylor
/// series for small |z| (where the closed forms cancel) and the closed forms elsewhere.
fn phi123(z: f64) -> (f64, f64, f64) {
    if z.abs() < 0.5 {
        // phi_k(z) = sum_j z^j / (j + k)!
        let (mut p1, mut p2, mut p3) = (0.0, 0.0, 0.0);
        let mut zj = 1.0;
        let mut fact = 1.0; // j!
        for j in 0..24 {
            let jf = f64::from(j);
            let f1 = fact * (jf + 1.0);
            let f2 = f1 * (jf + 2.0);
            let f3 = f2 * (jf + 3.0);
            p1 += zj / f1;
            p2 += zj / f2;
            p3 += zj / f3;
            zj *= z;
            fact *= jf + 1.0;
        }
        (p1, p2, p3)
    } else {
        let ez = z.exp();
        let p1 = (ez - 1.0) / z;
        let p2 = (ez - 1.0 - z) / (z * z);
        let p3 = (ez - 1.0 - z - 0.5 * z * z) / (z * z * z);
        (p1, p2, p3)
    }
}

/// Exponential-integrator coefficients of the current equation for one step size `h`, with `z = -h R/L`.
#[derive(Debug, Clone, Copy)]
struct EtdCoeffs {
    h: f64,
    h6: f64,
    /// `e^{z/2}`, `h/2 phi1(z/2)`, `(h/2)^2 phi2(z/2)`.
    e_half: f64,
    a1: f64,
    a2: f64,
    /// `e^{z}`, `h phi1(z)`, `h^2 phi2(z)`.
    e: f64,
    c1: f64,
    c2: f64,
    /// `2 h phi3(z)` = `c3 / h^2`.
    c3_over_h2: f64,
}

impl EtdCoeffs {
    fn new(h: f64, decay: f64) -> Self {
        let z = -h * decay;
        let (p1, p2, p3) = phi123(z);
        let (q1, q2, _) = phi123(0.5 * z);
        let hh = 0.5 * h;
        Self {
            h,
            h6: h / 6.0,
            e_half: (0.5 * z).exp(),
            a1: hh * q1,
            a2: hh * hh * q2,
            e: z.exp(),
            c1: h * p1,
            c2: h * h * p2,
            c3_over_h2: 2.0 * h * p3,
        }
    }
}

/// `(sin d, cos d)` for |d| <= 0.5 by their Taylor polynomials to `d^13` and `d^14` (Horner form; the
/// truncation error is below 3e-17 there).
#[inline]
fn sin_cos_small(d: f64) -> (f64, f64) {
    const S: [f64; 6] =
        [-1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362_880.0, -1.0 / 39_916_800.0, 1.0 / 6_227_020_800.0];
    const C: [f64; 7] = [
        -1.0 / 2.0,
        1.0 / 24.0,
        -1.0 / 720.0,
        1.0 / 40_320.0,
        -1.0 / 3_628_800.0,
        1.0 / 479_001_600.0,
        -1.0 / 87_178_291_200.0,
    ];
    // Estrin's scheme: independent pairs, so the latency is ~4 multiply-adds instead of 7 (Horner).
    let d2 = d * d;
    let d4 = d2 * d2;
    let d8 = d4 * d4;
    let ps = (S[0] + d2 * S[1]) + d4 * (S[2] + d2 * S[3]) + d8 * (S[4] + d2 * S[5]);
    let pc = (C[0] + d2 * C[1]) + d4 * (C[2] + d2 * C[3]) + d8 * ((C[4] + d2 * C[5]) + d4 * C[6]);
    (d + (d * d2) * ps, 1.0 + d2 * pc)
}

/// Angle with its sine and cosine carried along.
#[derive(Debug, Clone, Copy)]
pub(super) struct Angle {
    rad: f64,
    sin: f64,
    cos: f64,
}

impl Angle {
    pub(super) fn new(rad: f64) -> Self {
        let (sin, cos) = rad.sin_cos();
        Self { rad, sin, cos }
    }

    /// `self + d` by the addition theorem (one short polynomial instead of two libm calls per stage).
    #[inline]
    fn plus(self, d: f64) -> Self {
        if d.abs() > 0.5 {
            return Self::new(self.rad + d);
        }
        let (sd, cd) = sin_cos_small(d);
        self.rotate(d, sd, cd)
    }

    /// `self + d` for the small corrections of the Runge–Kutta stages (|d| ~ 1e-3 rad): for
    /// |d| <= 1/32 the Taylor polynomials to `d^7` and `d^6` are exact to 1e-17.
    #[inline]
    fn plus_tiny(self, d: f64) -> Self {
        if d.abs() > 1.0 / 32.0 {
            return self.plus(d);
        }
        let d2 = d * d;
        let sd = d + (d * d2) * (-1.0 / 6.0 + d2 * (1.0 / 120.0 - d2 * (1.0 / 5040.0)));
        let cd = 1.0 + d2 * (-0.5 + d2 * (1.0 / 24.0 - d2 * (1.0 / 720.0)));
        self.rotate(d, sd, cd)
    }

    #[inline]
    fn rotate(self, d: f64, sd: f64, cd: f64) -> Self {
        Self { rad: self.rad + d, sin: self.sin * cd + self.cos * sd, cos: self.cos * cd - self.sin * sd }
    }
}

/// Reduced integration state. The body coordinates are not integrated: with no external force along x,
/// the total x-momentum `Mt v + m l omega cos(theta)` and the centre of mass `Mt x + m l sin(theta)` are
/// conserved (the first equation of motion is exactly their time derivative), both zero from rest at
/// theta0 = 0, hence `v = -(m l/Mt) omega cos(theta)` and `x = -(m l/Mt) sin(theta)`. Integrating x and v
/// with an explicit method instead lets the x-momentum drift by ~1e-6 of its amplitude per 5 s, which
/// shows as a 0.2 % x "drift".
#[derive(Debug, Clone, Copy)]
struct MechState {
    theta: Angle,
    omega: f64,
    current: f64,
}

/// One step of `(theta, omega, i)`: classical Runge–Kutta 4 for the mechanics, the exact variation-of-
/// constants formula for the current.
///
/// The current obeys `i' = -i/tau + g(t)` with `tau = L/R` and forcing `g = (u - Kt omega)/L`, so exactly
/// `i(t + s) = e^{-s/tau} i + integral_0^s e^{-(s-r)/tau} g(t + r) dr`. With `g` a polynomial
/// `g0 + g1 r + g2 r^2` this is `e^{z} i + s phi1(z) g0 + s^2 phi2(z) g1 + 2 s^3 phi3(z) g2` (`z = -s/tau`;
/// exponential integrators, Hochbruck & Ostermann 2010, §2). Each Runge–Kutta stage gets the current at its
/// own time from this formula with `g` linear along that stage's slope (`g' = -Kt omega'/L`), and the end of
/// the step from the quadratic through `g(omega_n)`, `g'(omega_n)` and `g(omega_{n+1})`. Unlike the
/// Cox–Matthews ETDRK4 stages (constant forcing in the first stage), this keeps the quasi-static current
/// `(u - Kt omega)/R - tau Kt omega'/R` consistent with each stage's speed when `h >> L/R`, so the spin-up
/// torque carries no step-size-dependent lag error. For the constant back-emf of the first microseconds the
/// current is exact for any step. `d0` is `omega'` at the step start, already known.
// Inlined into both step loops so that the next step's angle work can overlap this step's tail.
#[allow(clippy::inline_always)]
#[inline(always)]
fn etd_step(k: &Consts, c: &EtdCoeffs, y: &mut MechState, d0: f64) {
    let MechState { theta, omega: om, current: i } = *y;
    let h = c.h;
    let hh = 0.5 * h;
    let g0 = k.current_forcing(om);
    let gd0 = -k.kt_over_l * d0;
    let exp_half_i = c.e_half * i + c.a1 * g0;
    // Stage angles relative to the predictor `theta + h om` (sin/cos once per step): with
    // `oma = om + h/2 d0`, `omb = om + h/2 da`, `omc = om + h db`,
    // `theta + h omb = (theta + h om) + h^2/2 da` and the RK4 update
    // `theta + h/6 (om + 2 oma + 2 omb + omc) = (theta + h om) + h^2/6 (d0 + da + db)`:
    // the corrections are ~1e-3 rad and need only short polynomials.
    let tha = theta.plus(hh * om);
    let thp = theta.plus(h * om);
    let oma = om + hh * d0;
    let thb = tha.plus_tiny(hh * hh * d0);
    let ia = exp_half_i + c.a2 * gd0;
    let da = k.omega_dot(tha, oma, ia);
    let thc = thp.plus_tiny(hh * h * da);
    let omb = om + hh * da;
    let ib = exp_half_i - c.a2 * k.kt_over_l * da;
    let db = k.omega_dot(thb, omb, ib);
    let theta1 = thp.plus_tiny(c.h6 * h * (d0 + da + db));
    let omc = om + h * db;
    let exp_i = c.e * i + c.c1 * g0;
    let ic = exp_i - c.c2 * k.kt_over_l * db;
    // End-of-step current: `exp_i + c2 gd0 + c3 g2` with `g2 = (g(om1) - g0 - gd0 h)/h^2` and
    // `g(om1) = u/L - Kt/L om1`, split so that only one multiply-add waits for `om1`.
    let i_pre = exp_i + c.c2 * gd0 + c.c3_over_h2 * (k.u_over_l - g0 - gd0 * h);
    let dc = k.omega_dot(thc, omc, ic);
    let om1 = om + c.h6 * (d0 + 2.0 * (da + db) + dc);
    *y = MechState { theta: theta1, omega: om1, current: i_pre - c.c3_over_h2 * k.kt_over_l * om1 };
}

/// Receiver of the output samples, in time order. Samples before [`SampleSink::full_from`] are handed over
/// without the body coordinates and `v'` (their sin/cos and mass-matrix solve are skipped); from that index
/// on, every sample is complete.
pub(super) trait SampleSink {
    /// First sample index that needs `x`, `v` and `v'`.
    fn full_from(&self) -> usize;
    /// Sample `n` at `t = n dt` with angle, speed and current only.
    fn partial(&mut self, n: usize, t_s: f64, theta_rad: f64, omega_rad_s: f64, current_a: f64);
    /// Sample `n` with the whole state `[x, v, theta, omega, i]` and the body acceleration `v'`.
    fn full(&mut self, n: usize, t_s: f64, state: &[f64; 5], accel_m_s2: f64);
}

/// Steps between two re-evaluations of sin/cos by libm (the addition theorem accumulates rounding of
/// ~1e-16 per step otherwise).
const RESYNC_STEPS: usize = 64;

/// Integrates from rest and hands every output sample to `sink`, in time order.
pub(super) fn integrate(
    params: &TactorParams,
    options: &SimOptions,
    step_angle_rad: f64,
    sink: &mut impl SampleSink,
) -> Result<(), TactorError> {
    let h_max = (step_angle_rad / params.steady_state().omega_rad_s).min(MAX_STEP_S);
    integrate_with_step(params, options, h_max, sink)
}

/// Cubic Hermite interpolation at fraction `s` of a step of length `h` between `(y0, y0')` and `(y1, y1')`.
#[inline]
fn hermite(s: f64, h: f64, y0: f64, d0: f64, y1: f64, d1: f64) -> f64 {
    let s2 = s * s;
    let s3 = s2 * s;
    (2.0 * s3 - 3.0 * s2 + 1.0) * y0
        + (s3 - 2.0 * s2 + s) * h * d0
        + (3.0 * s2 - 2.0 * s3) * y1
        + (s3 - s2) * h * d1
}

/// [`integrate`] with a chosen largest step `h_max_s`.
///
/// Output samples are at `t_n = n / rate`. While the output interval is longer than the step (or during the
/// start transient, the first `FINE_TAUS` electrical time constants, stepped at `L/R / FINE_STEPS_PER_TAU`),
/// each interval is split into equal sub-steps. Otherwise one step spans `q = floor(h_max / dt_out)` output
/// intervals, and the samples inside it come from cubic Hermite interpolation of `theta`, `omega` and `i`
/// (values and derivatives at both ends, error O(h^4)), with `v'` evaluated at the interpolated state.
fn integrate_with_step(
    params: &TactorParams,
    options: &SimOptions,
    h_max_s: f64,
    sink: &mut impl SampleSink,
) -> Result<(), TactorError> {
    let k = Consts::new(params);
    let n_samples = options.sample_count();
    let dt_out = 1.0 / options.output_rate_hz;
    let tau = params.electrical_time_constant_s();
    let fine_end_s = FINE_TAUS * tau;
    let h_fine = tau / FINE_STEPS_PER_TAU;
    let x_per_sin = -k.ml / k.mt;
    let full_from = sink.full_from();
    // Step ends: the state and `v'` are known anyway.
    let emit = |sink: &mut _, n: usize, y: &MechState, v_dot: f64| -> Result<(), TactorError> {
        let t = n as f64 * dt_out;
        // One test for all four: a sum is finite only if every term is (barring overflow, a divergence too).
        if !(y.theta.rad + y.omega + y.current + v_dot).is_finite() {
            return Err(TactorError::Diverged { t_s: t });
        }
        if n < full_from {
            SampleSink::partial(sink, n, t, y.theta.rad, y.omega, y.current);
        } else {
            let state =
                [x_per_sin * y.theta.sin, x_per_sin * y.omega * y.theta.cos, y.theta.rad, y.omega, y.current];
            SampleSink::full(sink, n, t, &state, v_dot);
        }
        Ok(())
    };
    let mut y = MechState { theta: Angle::new(0.0), omega: 0.0, current: 0.0 };
    let mut cache: Option<(u64, EtdCoeffs)> = None;
    let mut coeffs_for = |h: f64| match cache {
        Some((bits, c)) if bits == h.to_bits() => c,
        _ => {
            let c = EtdCoeffs::new(h, k.decay);
            cache = Some((h.to_bits(), c));
            c
        }
    };
    let (mut v_dot, mut omega_dot) = k.accelerations(y.theta, y.omega, y.current);
    emit(sink, 0, &y, v_dot)?;
    let mut n = 0usize;
    let mut steps = 0usize;
    while n + 1 < n_samples {
        let t = n as f64 * dt_out;
        let h_max = if t < fine_end_s { h_fine.min(h_max_s) } else { h_max_s };
        if dt_out >= h_max {
            let sub = (dt_out / h_max - 1e-9).ceil().max(1.0) as usize;
            let coeffs = coeffs_for(dt_out / sub as f64);
            for _ in 0..sub {
                steps += 1;
                if steps.is_multiple_of(RESYNC_STEPS) {
                    y.theta = Angle::new(y.theta.rad);
                }
                etd_step(&k, &coeffs, &mut y, omega_dot);
                omega_dot = k.omega_dot(y.theta, y.omega, y.current);
            }
            n += 1;
            (v_dot, omega_dot) = k.accelerations(y.theta, y.omega, y.current);
            emit(sink, n, &y, v_dot)?;
        } else {
            let q = ((h_max / dt_out + 1e-9).floor() as usize).clamp(1, n_samples - 1 - n);
            let h = q as f64 * dt_out;
            let coeffs = coeffs_for(h);
            steps += 1;
            if steps.is_multiple_of(RESYNC_STEPS) {
                y.theta = Angle::new(y.theta.rad);
            }
            let y0 = y;
            let d0 = omega_dot;
            etd_step(&k, &coeffs, &mut y, omega_dot);
            (v_dot, omega_dot) = k.accelerations(y.theta, y.omega, y.current);
            let di0 = k.current_forcing(y0.omega) - k.decay * y0.current;
            let di1 = k.current_forcing(y.omega) - k.decay * y.current;
            let inv_q = 1.0 / q as f64;
            for j in 1..q {
                let s = j as f64 * inv_q;
                let th = hermite(s, h, y0.theta.rad, y0.omega, y.theta.rad, y.omega);
                let om = hermite(s, h, y0.omega, d0, y.omega, omega_dot);
                let cur = hermite(s, h, y0.current, di0, y.current, di1);
                let m = n + j;
                if m < full_from {
                    // Finite if both ends are (checked when they were emitted).
                    sink.partial(m, m as f64 * dt_out, th, om, cur);
                } else {
                    let yj = MechState { theta: y0.theta.plus(th - y0.theta.rad), omega: om, current: cur };
                    let (vj, _) = k.accelerations(yj.theta, yj.omega, yj.current);
                    emit(sink, m, &yj, vj)?;
                }
            }
            n += q;
            emit(sink, n, &y, v_dot)?;
        }
    }
    Ok(())
}
