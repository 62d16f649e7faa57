//! The pancake-motor tactor: an eccentric rotating mass on a free body, driven by a DC motor (thesis §3.2).
//!
//! State `[x, v, theta, omega, i]`: body position and velocity along its one free axis, eccentric angle and
//! rate, motor current. Equations of motion (thesis §3.2, with the coupling term's missing `l` restored, see
//! `physics.md` §1):
//!
//! ```text
//! Mt v'            + m l cos(theta) omega' = m l omega^2 sin(theta)
//! m l cos(theta) v' + m l^2 omega'          = Kt i - b omega + m g l sin(theta)
//! L i'                                      = u - R i - Kt omega
//! x' = v,  theta' = omega
//! ```
//!
//! The electrical time constant `L/R` (17.7 us) is ~400 times shorter than a rotation period (7.5 ms), so the
//! system is stiff. [`simulate`] integrates only `(theta, omega, i)`: the current by the exact
//! variation-of-constants formula with a polynomial forcing (no stability limit, see `etd_step`), the
//! mechanics by classical Runge–Kutta 4 with steps of 0.26 rad of rotation (300 us at full speed) and
//! `L/R / 16` during the first 20 `L/R`; `x` and `v` follow from the conserved momentum and centre of mass.

use crate::analysis::spectrum_peak_hz;
use serde::{Deserialize, Serialize};

/// Standard gravity used by the thesis [m/s^2].
pub const GRAVITY_M_S2: f64 = 9.81;

/// Largest integrator step away from the start transient [s].
const MAX_STEP_S: f64 = 400e-6;
/// Default accuracy of [`simulate`]: away from the start, the step is also limited to this eccentric rotation at the closed-form steady speed
/// \[rad\] (0.26 rad = 300 us at 834 rad/s: RK4 errors ~5e-5 relative there, a tenth of the reference
/// tolerances; halving it costs 30 % more time for 16x smaller errors).
pub const DEFAULT_STEP_ANGLE_RAD: f64 = 0.26;
/// The start transient (current rise) is resolved with steps of `L/R / FINE_STEPS_PER_TAU`...
const FINE_STEPS_PER_TAU: f64 = 16.0;
/// ...for the first `FINE_TAUS` electrical time constants.
const FINE_TAUS: f64 = 20.0;
/// Most output samples a traced simulation may store (9 traces of f64: 5 M samples = 360 MB).
const MAX_TRACE_SAMPLES: f64 = 5.0e6;
/// Longest simulated time accepted \[s\] (the summary path stores theta at every output sample).
const MAX_DURATION_S: f64 = 3600.0;
/// Highest output rate accepted [Hz].
const MAX_OUTPUT_RATE_HZ: f64 = 10.0e6;

/// Parameter preset: the two resistances the thesis uses (physics.md §1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    /// R = 62 ohm: reproduces the thesis's simulation numbers (steady speed 834.2 rad/s).
    ThesisSim,
    /// R = 67 ohm: the measured winding resistance, used by the thesis's current-versus-frequency line.
    Measured,
}

impl Preset {
    /// The preset's name as used on the command line and in JSON (`thesis-sim`, `measured`).
    pub fn name(self) -> &'static str {
        match self {
            Preset::ThesisSim => "thesis-sim",
            Preset::Measured => "measured",
        }
    }

    /// Winding resistance of the preset \[ohm\].
    pub fn resistance_ohm(self) -> f64 {
        match self {
            Preset::ThesisSim => 62.0,
            Preset::Measured => 67.0,
        }
    }
}

/// The tactor body's mass configuration (masses include the mounting screw and the eccentric).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BodyMass {
    /// Bare motor: 3.7 g.
    Unencased,
    /// Motor in its case: 4.95 g.
    Encased,
}

impl BodyMass {
    /// Total moving mass `Mt` \[kg\].
    pub fn kg(self) -> f64 {
        match self {
            BodyMass::Unencased => 3.7e-3,
            BodyMass::Encased => 4.95e-3,
        }
    }

    /// `unencased` or `encased`.
    pub fn name(self) -> &'static str {
        match self {
            BodyMass::Unencased => "unencased",
            BodyMass::Encased => "encased",
        }
    }
}

/// Radius of the eccentric's centre of mass from the CAD model \[m\] (thesis §3.2).
pub const RADIUS_CAD_M: f64 = 2.57e-3;
/// Radius that fits the measured force–frequency cloud better \[m\] (thesis §3.2.3).
pub const RADIUS_FITTED_M: f64 = 3.2e-3;
/// Damping of the thesis's figures [N m s].
pub const DAMPING_THESIS_N_M_S: f64 = 6.3e-8;

/// Why a tactor simulation was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TactorError {
    /// A parameter that must be strictly positive and finite is not.
    #[error("{name} must be a finite number > 0, got {value}")]
    NotPositive {
        /// Parameter name with unit.
        name: &'static str,
        /// The rejected value.
        value: f64,
    },
    /// A parameter that must be finite and non-negative is not.
    #[error("{name} must be a finite number >= 0, got {value}")]
    Negative {
        /// Parameter name with unit.
        name: &'static str,
        /// The rejected value.
        value: f64,
    },
    /// The body mass includes the eccentric, so it must be larger (else the mass matrix is singular).
    #[error("body mass {body_kg} kg must exceed the eccentric mass {eccentric_kg} kg it includes")]
    BodyLighterThanEccentric {
        /// Body mass `Mt`.
        body_kg: f64,
        /// Eccentric mass `m`.
        eccentric_kg: f64,
    },
    /// A value is outside the range this implementation accepts.
    #[error("{name} = {value} is above the limit {limit}")]
    TooLarge {
        /// Parameter name with unit.
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// The largest accepted value.
        limit: f64,
    },
    /// The integration produced a non-finite state (cannot happen for validated parameters; kept as a guard).
    #[error("the simulation diverged at t = {t_s} s")]
    Diverged {
        /// Simulated time of the first non-finite state.
        t_s: f64,
    },
}

fn check_positive(name: &'static str, value: f64) -> Result<(), TactorError> {
    if value.is_finite() && value > 0.0 { Ok(()) } else { Err(TactorError::NotPositive { name, value }) }
}

fn check_non_negative(name: &'static str, value: f64) -> Result<(), TactorError> {
    if value.is_finite() && value >= 0.0 { Ok(()) } else { Err(TactorError::Negative { name, value }) }
}

/// Physical parameters of one tactor (thesis §3.2, physics.md §1). SI units throughout.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TactorParams {
    /// The preset these parameters started from. Overriding mass, radius, voltage or damping keeps it; it
    /// names the resistance choice (62 or 67 ohm).
    pub preset: Preset,
    /// Body mass configuration the preset was built with (informative; `body_mass_kg` is what is simulated).
    pub body: BodyMass,
    /// Eccentric mass `m` \[kg\] (0.55 g).
    pub eccentric_mass_kg: f64,
    /// Radius of the eccentric's centre of mass `l` \[m\] (2.57 mm CAD, 3.2 mm fitted).
    pub radius_m: f64,
    /// Total moving mass `Mt` [kg], eccentric included (3.7 g unencased, 4.95 g encased).
    pub body_mass_kg: f64,
    /// Torque constant `Kt` [N m/A], equal to the back-emf constant \[V s/rad\] (0.0019).
    pub torque_constant_n_m_per_a: f64,
    /// Winding inductance `L` \[H\] (1.1 mH).
    pub inductance_h: f64,
    /// Winding resistance `R` \[ohm\] (62 thesis-sim, 67 measured).
    pub resistance_ohm: f64,
    /// Drive voltage `u` \[V\] (3.3).
    pub voltage_v: f64,
    /// Viscous damping `b` \[N m s\] (6.3e-8 in the thesis's figures).
    pub damping_n_m_s: f64,
    /// Gravity `g` [m/s^2] acting on the eccentric in the angular equation (9.81).
    pub gravity_m_s2: f64,
}

impl TactorParams {
    /// The preset's parameters, unencased, l = 2.57 mm, u = 3.3 V, b = 6.3e-8 N m s (physics.md §1 table).
    pub fn preset(preset: Preset) -> Self {
        Self {
            preset,
            body: BodyMass::Unencased,
            eccentric_mass_kg: 0.55e-3,
            radius_m: RADIUS_CAD_M,
            body_mass_kg: BodyMass::Unencased.kg(),
            torque_constant_n_m_per_a: 0.0019,
            inductance_h: 1.1e-3,
            resistance_ohm: preset.resistance_ohm(),
            voltage_v: 3.3,
            damping_n_m_s: DAMPING_THESIS_N_M_S,
            gravity_m_s2: GRAVITY_M_S2,
        }
    }

    /// The same tactor with another body mass.
    #[must_use]
    pub fn with_body(mut self, body: BodyMass) -> Self {
        self.body = body;
        self.body_mass_kg = body.kg();
        self
    }

    /// The same tactor with another damping `b` [N m s].
    #[must_use]
    pub fn with_damping(mut self, damping_n_m_s: f64) -> Self {
        self.damping_n_m_s = damping_n_m_s;
        self
    }

    /// The same tactor with another drive voltage [V].
    #[must_use]
    pub fn with_voltage(mut self, voltage_v: f64) -> Self {
        self.voltage_v = voltage_v;
        self
    }

    /// The same tactor with another eccentric radius [m].
    #[must_use]
    pub fn with_radius(mut self, radius_m: f64) -> Self {
        self.radius_m = radius_m;
        self
    }

    /// Checks every parameter: masses, radius, `Kt`, `L`, `R`, `u` finite and > 0; `b` and `g` finite and
    /// >= 0; `Mt > m` (the body mass includes the eccentric).
    pub fn validate(&self) -> Result<(), TactorError> {
        check_positive("eccentric mass [kg]", self.eccentric_mass_kg)?;
        check_positive("radius [m]", self.radius_m)?;
        check_positive("body mass [kg]", self.body_mass_kg)?;
        check_positive("torque constant [N m/A]", self.torque_constant_n_m_per_a)?;
        check_positive("inductance [H]", self.inductance_h)?;
        check_positive("resistance [ohm]", self.resistance_ohm)?;
        check_positive("voltage [V]", self.voltage_v)?;
        check_non_negative("damping [N m s]", self.damping_n_m_s)?;
        check_non_negative("gravity [m/s^2]", self.gravity_m_s2)?;
        if self.body_mass_kg <= self.eccentric_mass_kg {
            return Err(TactorError::BodyLighterThanEccentric {
                body_kg: self.body_mass_kg,
                eccentric_kg: self.eccentric_mass_kg,
            });
        }
        Ok(())
    }

    /// Electrical time constant `L/R` \[s\] (17.7 us for the thesis-sim preset).
    pub fn electrical_time_constant_s(&self) -> f64 {
        self.inductance_h / self.resistance_ohm
    }

    /// Closed-form steady state, speed ripple ignored (physics.md §1, thesis §3.2.1):
    ///
    /// - `omega = Kt u / (R b + Kt^2)` (torque balance `Kt i = b omega` with `i = (u - Kt omega)/R`);
    /// - `i = (u - Kt omega)/R`, `T = Kt i`, peak frequency `T/(2 pi b) = omega/(2 pi)`;
    /// - start current `u/R` and start torque `Kt u/R` (the `L = 0` limit at `omega = 0`);
    /// - body: momentum conservation `Mt v + m l omega cos(theta) = 0` gives `x = -(m l/Mt) sin(theta)`, so
    ///   the x amplitude is `m l/Mt`, and at constant `omega` the force amplitude is `m l omega^2` and the
    ///   acceleration amplitude `m l omega^2 / Mt`.
    pub fn steady_state(&self) -> SteadyState {
        let kt = self.torque_constant_n_m_per_a;
        let r = self.resistance_ohm;
        let u = self.voltage_v;
        let omega = kt * u / (r * self.damping_n_m_s + kt * kt);
        let current = (u - kt * omega) / r;
        let ml = self.eccentric_mass_kg * self.radius_m;
        SteadyState {
            omega_rad_s: omega,
            f_rot_hz: omega / std::f64::consts::TAU,
            current_a: current,
            torque_n_m: kt * current,
            start_current_a: u / r,
            start_torque_n_m: kt * u / r,
            force_amplitude_n: ml * omega * omega,
            accel_amplitude_m_s2: ml * omega * omega / self.body_mass_kg,
            x_amplitude_m: ml / self.body_mass_kg,
            electrical_time_constant_s: self.electrical_time_constant_s(),
        }
    }

    /// Right-hand side of the ODE at state `[x, v, theta, omega, i]`, as `[x', v', theta', omega', i']`.
    ///
    /// The 2x2 mass matrix `[[Mt, m l c], [m l c, m l^2]]` (c = cos theta) has determinant
    /// `m l^2 (Mt - m c^2) > 0`; with `F1 = m l omega^2 sin(theta)` and
    /// `F2 = Kt i - b omega + m g l sin(theta)` its solution is
    /// `v' = (F1 - c F2 / l) / (Mt - m c^2)` and `omega' = (Mt F2 / (m l^2) - c F1 / l) / (Mt - m c^2)`;
    /// `i' = (u - R i - Kt omega)/L` (thesis §3.2).
    pub fn derivatives(&self, state: &[f64; 5]) -> [f64; 5] {
        let k = Consts::new(self);
        let (v_dot, omega_dot) = k.accelerations(Angle::new(state[2]), state[3], state[4]);
        [state[1], v_dot, state[3], omega_dot, k.current_forcing(state[3]) - k.decay * state[4]]
    }
}

/// Closed-form steady state of a tactor (see [`TactorParams::steady_state`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SteadyState {
    /// Steady speed `Kt u / (R b + Kt^2)` [rad/s].
    pub omega_rad_s: f64,
    /// Steady rotation (= peak) frequency `omega / 2 pi` [Hz].
    pub f_rot_hz: f64,
    /// Steady current `(u - Kt omega)/R` [A].
    pub current_a: f64,
    /// Steady torque `Kt i` [N m].
    pub torque_n_m: f64,
    /// Start current `u/R` in the `L = 0` limit [A].
    pub start_current_a: f64,
    /// Start torque `Kt u/R` [N m].
    pub start_torque_n_m: f64,
    /// Force amplitude at constant speed `m l omega^2` [N].
    pub force_amplitude_n: f64,
    /// Acceleration amplitude at constant speed `m l omega^2 / Mt` [m/s^2].
    pub accel_amplitude_m_s2: f64,
    /// Body displacement amplitude `m l / Mt` \[m\] (exact, from momentum conservation).
    pub x_amplitude_m: f64,
    /// Electrical time constant `L/R` [s].
    pub electrical_time_constant_s: f64,
}

/// Length and output rate of a simulation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SimOptions {
    /// Simulated time from rest [s]; the analysis window is the last half.
    pub duration_s: f64,
    /// Output sampling rate \[Hz\] (10 kHz as in the thesis).
    pub output_rate_hz: f64,
}

impl Default for SimOptions {
    fn default() -> Self {
        Self { duration_s: 10.0, output_rate_hz: 10_000.0 }
    }
}

impl SimOptions {
    /// Checks duration (0 < T <= 3600 s) and output rate (0 < rate <= 10 MHz, at least 4 samples).
    pub fn validate(&self) -> Result<(), TactorError> {
        check_positive("duration [s]", self.duration_s)?;
        check_positive("output rate [Hz]", self.output_rate_hz)?;
        if self.duration_s > MAX_DURATION_S {
            return Err(TactorError::TooLarge {
                name: "duration [s]",
                value: self.duration_s,
                limit: MAX_DURATION_S,
            });
        }
        if self.output_rate_hz > MAX_OUTPUT_RATE_HZ {
            return Err(TactorError::TooLarge {
                name: "output rate [Hz]",
                value: self.output_rate_hz,
                limit: MAX_OUTPUT_RATE_HZ,
            });
        }
        if self.duration_s * self.output_rate_hz < 4.0 {
            return Err(TactorError::NotPositive {
                name: "output samples (duration x rate) - 4",
                value: self.duration_s * self.output_rate_hz - 4.0,
            });
        }
        Ok(())
    }

    fn sample_count(&self) -> usize {
        // Samples at t = k/rate for k = 0..=n; the tiny slack absorbs rounding of e.g. 10 s x 10 kHz.
        (self.duration_s * self.output_rate_hz + 1e-9).floor() as usize + 1
    }
}

/// Time traces of a simulation at the output rate (thesis Figs 28–34). All vectors have equal length.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Traces {
    /// Time [s].
    pub t_s: Vec<f64>,
    /// Eccentric angle \[rad\] (unwrapped).
    pub theta_rad: Vec<f64>,
    /// Eccentric rate [rad/s].
    pub omega_rad_s: Vec<f64>,
    /// Body position [m].
    pub x_m: Vec<f64>,
    /// Body velocity [m/s].
    pub v_m_s: Vec<f64>,
    /// Body acceleration `v'` [m/s^2].
    pub accel_m_s2: Vec<f64>,
    /// Force `Mt v'` \[N\] (the thesis's "acceleration multiplied by its mass").
    pub force_n: Vec<f64>,
    /// Motor torque `Kt i` [N m].
    pub torque_n_m: Vec<f64>,
    /// Motor current [A].
    pub current_a: Vec<f64>,
}

impl Traces {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when there is no sample.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }
}

/// The figures of merit of one simulation (physics.md §1 "Definitions").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Parameters simulated (their `preset` names the resistance choice).
    pub params: TactorParams,
    /// Duration and output rate.
    pub options: SimOptions,
    /// Start of the analysis window, half the duration [s].
    pub window_start_s: f64,
    /// End of the analysis window, the duration [s].
    pub window_end_s: f64,
    /// Mean speed over the window `delta theta / delta t` [rad/s].
    pub omega_mean_rad_s: f64,
    /// Rotation frequency `omega_mean / 2 pi` [Hz].
    pub f_rot_hz: f64,
    /// Mean speed over the whole revolutions inside the window, `2 pi N / (t_N - t_0)` between the first and
    /// last crossings of a multiple of 2 pi [rad/s]. Unlike `delta theta / delta t` it does not depend on the
    /// ripple's phase at the window ends (which moves the latter by ~0.04 rad / window length), so sweeps
    /// and calibration use it; `NaN` if fewer than one revolution fits in the window.
    pub omega_mean_revs_rad_s: f64,
    /// Smallest sampled speed in the window [rad/s].
    pub omega_min_rad_s: f64,
    /// Largest sampled speed in the window [rad/s].
    pub omega_max_rad_s: f64,
    /// Half the peak-to-peak speed ripple relative to the mean, `(max - min) / (2 mean)`.
    pub omega_ripple: f64,
    /// Peak |v'| in the window [m/s^2].
    pub accel_peak_m_s2: f64,
    /// Force amplitude `Mt * accel_peak` [N].
    pub force_amplitude_n: f64,
    /// Half the peak-to-peak body position in the window [m].
    pub x_amplitude_m: f64,
    /// Peak of the acceleration spectrum over the last 1 s (rectangular window, 1 Hz bins) [Hz].
    pub fft_peak_1s_hz: f64,
    /// Length of the FFT window actually used (1 s, or the whole window if shorter) [s].
    pub fft_window_s: f64,
    /// Largest current of the whole run: the start peak, close to `u/R` [A].
    pub current_peak_a: f64,
    /// Mean current over the window [A].
    pub current_mean_a: f64,
    /// Largest torque of the whole run, `Kt * current_peak` [N m].
    pub torque_peak_n_m: f64,
    /// Mean torque over the window [N m].
    pub torque_mean_n_m: f64,
    /// 2 % settling time of the speed averaged over one revolution (centred), [s]; `None` if it never settles
    /// inside the run (or the rotor does not turn).
    pub settling_time_s: Option<f64>,
    /// Closed-form steady state of the same parameters.
    pub steady_state: SteadyState,
}

/// Traces and summary of one simulation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TactorRun {
    /// Time traces at the output rate.
    pub traces: Traces,
    /// Figures of merit.
    pub summary: Summary,
}

/// Per-evaluation constants.
#[derive(Debug, Clone, Copy)]
struct Consts {
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
    decay: f64,
}

impl Consts {
    fn new(p: &TactorParams) -> Self {
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
    fn accelerations(&self, theta: Angle, omega: f64, current: f64) -> (f64, f64) {
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
    fn current_forcing(&self, omega: f64) -> f64 {
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
struct Angle {
    rad: f64,
    sin: f64,
    cos: f64,
}

impl Angle {
    fn new(rad: f64) -> Self {
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
trait SampleSink {
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
fn integrate(
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

/// First sample index `n` with `n dt + dt/2 >= t_s` (sample times are `n dt`; the half step of slack puts
/// a sample at exactly `t_s` on the inside despite rounding).
fn first_index_at(t_s: f64, dt_s: f64) -> usize {
    let inside = |n: usize| n as f64 * dt_s + 0.5 * dt_s >= t_s;
    let mut n = (t_s / dt_s - 0.5).ceil().max(0.0) as usize;
    while n > 0 && inside(n - 1) {
        n -= 1;
    }
    while !inside(n) {
        n += 1;
    }
    n
}

/// Streaming accumulator of the summary; stores only theta (for the settling time) and the last second of
/// acceleration (for the FFT).
struct SummaryBuilder {
    window_start_s: f64,
    window_start_n: usize,
    fft_start_n: usize,
    dt_out: f64,
    /// Every sample's angle, for the settling time.
    theta: Vec<f64>,
    fft_accel: Vec<f64>,
    theta_window_start: Option<(f64, f64)>,
    theta_last: (f64, f64),
    /// Previous sample `(t, theta)`, the next multiple of 2 pi to cross, the first and latest crossing
    /// `(t, revolution index)` inside the window.
    prev: (f64, f64),
    next_crossing: Option<f64>,
    first_crossing: Option<(f64, f64)>,
    last_crossing: Option<(f64, f64)>,
    omega_min: f64,
    omega_max: f64,
    accel_peak: f64,
    x_min: f64,
    x_max: f64,
    current_peak: f64,
    current_sum: f64,
    window_samples: usize,
}

impl SummaryBuilder {
    fn new(options: &SimOptions) -> Self {
        let duration = options.duration_s;
        let window_start_s = 0.5 * duration;
        let fft_window = (duration - window_start_s).min(1.0);
        let dt_out = 1.0 / options.output_rate_hz;
        Self {
            window_start_s,
            window_start_n: first_index_at(window_start_s, dt_out),
            fft_start_n: first_index_at(duration - fft_window, dt_out),
            dt_out,
            theta: Vec::with_capacity(options.sample_count()),
            fft_accel: Vec::with_capacity((fft_window * options.output_rate_hz) as usize + 2),
            theta_window_start: None,
            theta_last: (0.0, 0.0),
            prev: (0.0, 0.0),
            next_crossing: None,
            first_crossing: None,
            last_crossing: None,
            omega_min: f64::INFINITY,
            omega_max: f64::NEG_INFINITY,
            accel_peak: 0.0,
            x_min: f64::INFINITY,
            x_max: f64::NEG_INFINITY,
            current_peak: f64::NEG_INFINITY,
            current_sum: 0.0,
            window_samples: 0,
        }
    }

    /// What every sample contributes: the settling scan's angle and the whole-run current peak.
    #[inline]
    fn push_any(&mut self, t_s: f64, theta: f64, current: f64) {
        self.theta.push(theta);
        self.current_peak = self.current_peak.max(current);
        self.prev = (t_s, theta);
    }

    #[inline]
    fn push_window(&mut self, t_s: f64, state: &[f64; 5], accel: f64) {
        let [x, _, theta, omega, current] = *state;
        if self.theta_window_start.is_none() {
            self.theta_window_start = Some((t_s, theta));
        }
        self.theta_last = (t_s, theta);
        let next = *self.next_crossing.get_or_insert((theta / std::f64::consts::TAU).ceil());
        let mut next = next;
        let (t_prev, th_prev) = self.prev;
        while theta >= next * std::f64::consts::TAU && theta > th_prev {
            let target = next * std::f64::consts::TAU;
            let t_c = t_prev + (t_s - t_prev) * (target - th_prev) / (theta - th_prev);
            if self.first_crossing.is_none() {
                self.first_crossing = Some((t_c, next));
            }
            self.last_crossing = Some((t_c, next));
            next += 1.0;
        }
        self.next_crossing = Some(next);
        self.omega_min = self.omega_min.min(omega);
        self.omega_max = self.omega_max.max(omega);
        self.accel_peak = self.accel_peak.max(accel.abs());
        self.x_min = self.x_min.min(x);
        self.x_max = self.x_max.max(x);
        self.current_sum += current;
        self.window_samples += 1;
    }
}

impl SampleSink for SummaryBuilder {
    fn full_from(&self) -> usize {
        self.window_start_n.min(self.fft_start_n)
    }

    #[inline]
    fn partial(&mut self, _n: usize, t_s: f64, theta_rad: f64, _omega_rad_s: f64, current_a: f64) {
        self.push_any(t_s, theta_rad, current_a);
    }

    #[inline]
    fn full(&mut self, n: usize, t_s: f64, state: &[f64; 5], accel_m_s2: f64) {
        if n >= self.window_start_n {
            self.push_window(t_s, state, accel_m_s2);
        }
        if n >= self.fft_start_n {
            self.fft_accel.push(accel_m_s2);
        }
        self.push_any(t_s, state[2], state[4]);
    }
}

impl SummaryBuilder {
    fn finish(mut self, params: &TactorParams, options: &SimOptions) -> Summary {
        let (t0, th0) = self.theta_window_start.unwrap_or((0.0, 0.0));
        let (t1, th1) = self.theta_last;
        let omega_mean = if t1 > t0 { (th1 - th0) / (t1 - t0) } else { f64::NAN };
        let current_mean = self.current_sum / self.window_samples.max(1) as f64;
        let kt = params.torque_constant_n_m_per_a;
        // The FFT window holds n samples spanning n * dt seconds (rectangular, bins 1/(n dt) wide).
        if self.fft_accel.len() > 1 {
            self.fft_accel.pop();
        }
        let fft_window_s = self.fft_accel.len() as f64 * self.dt_out;
        let fft_peak = spectrum_peak_hz(&self.fft_accel, options.output_rate_hz).unwrap_or(f64::NAN);
        let settling = settling_time_s(&self.theta, self.dt_out, omega_mean, 0.02);
        Summary {
            params: *params,
            options: *options,
            window_start_s: self.window_start_s,
            window_end_s: options.duration_s,
            omega_mean_rad_s: omega_mean,
            f_rot_hz: omega_mean / std::f64::consts::TAU,
            omega_mean_revs_rad_s: match (self.first_crossing, self.last_crossing) {
                (Some((ta, ka)), Some((tb, kb))) if kb > ka => std::f64::consts::TAU * (kb - ka) / (tb - ta),
                _ => f64::NAN,
            },
            omega_min_rad_s: self.omega_min,
            omega_max_rad_s: self.omega_max,
            omega_ripple: (self.omega_max - self.omega_min) / (2.0 * omega_mean),
            accel_peak_m_s2: self.accel_peak,
            force_amplitude_n: self.accel_peak * params.body_mass_kg,
            x_amplitude_m: 0.5 * (self.x_max - self.x_min),
            fft_peak_1s_hz: fft_peak,
            fft_window_s,
            current_peak_a: self.current_peak,
            current_mean_a: current_mean,
            torque_peak_n_m: kt * self.current_peak,
            torque_mean_n_m: kt * current_mean,
            settling_time_s: settling,
            steady_state: params.steady_state(),
        }
    }
}

/// Simulates the tactor from rest (all states zero, theta0 = 0) and returns the traces at the output rate
/// and the summary. See the module doc for the solver; the step is [`DEFAULT_STEP_ANGLE_RAD`].
pub fn simulate(params: &TactorParams, options: &SimOptions) -> Result<TactorRun, TactorError> {
    simulate_with_step_angle(params, options, DEFAULT_STEP_ANGLE_RAD)
}

fn check_step_angle(step_angle_rad: f64) -> Result<(), TactorError> {
    check_positive("step angle [rad]", step_angle_rad)?;
    if step_angle_rad > 1.0 {
        return Err(TactorError::TooLarge { name: "step angle [rad]", value: step_angle_rad, limit: 1.0 });
    }
    Ok(())
}

/// [`simulate`] with another accuracy: the largest eccentric rotation per integrator step at the closed-form
/// speed, `0 < step_angle_rad <= 1` (RK4 errors scale with its 4th power; steps stay <= 400 us).
pub fn simulate_with_step_angle(
    params: &TactorParams,
    options: &SimOptions,
    step_angle_rad: f64,
) -> Result<TactorRun, TactorError> {
    params.validate()?;
    options.validate()?;
    check_step_angle(step_angle_rad)?;
    let n = options.sample_count();
    if n as f64 > MAX_TRACE_SAMPLES {
        return Err(TactorError::TooLarge {
            name: "output samples (duration x rate)",
            value: n as f64,
            limit: MAX_TRACE_SAMPLES,
        });
    }
    let tr = Traces {
        t_s: Vec::with_capacity(n),
        theta_rad: Vec::with_capacity(n),
        omega_rad_s: Vec::with_capacity(n),
        x_m: Vec::with_capacity(n),
        v_m_s: Vec::with_capacity(n),
        accel_m_s2: Vec::with_capacity(n),
        force_n: Vec::with_capacity(n),
        torque_n_m: Vec::with_capacity(n),
        current_a: Vec::with_capacity(n),
    };
    let mut sink = TraceSink {
        traces: tr,
        builder: SummaryBuilder::new(options),
        mt_kg: params.body_mass_kg,
        kt_n_m_per_a: params.torque_constant_n_m_per_a,
    };
    integrate(params, options, step_angle_rad, &mut sink)?;
    Ok(TactorRun { traces: sink.traces, summary: sink.builder.finish(params, options) })
}

/// Stores every sample as traces and feeds the summary.
struct TraceSink {
    traces: Traces,
    builder: SummaryBuilder,
    mt_kg: f64,
    kt_n_m_per_a: f64,
}

impl SampleSink for TraceSink {
    fn full_from(&self) -> usize {
        0
    }

    fn partial(&mut self, _n: usize, _t_s: f64, _theta_rad: f64, _omega_rad_s: f64, _current_a: f64) {
        unreachable!("traces take every sample complete (full_from = 0)");
    }

    fn full(&mut self, n: usize, t_s: f64, state: &[f64; 5], accel_m_s2: f64) {
        self.builder.full(n, t_s, state, accel_m_s2);
        let [x, v, theta, omega, i] = *state;
        let tr = &mut self.traces;
        tr.t_s.push(t_s);
        tr.theta_rad.push(theta);
        tr.omega_rad_s.push(omega);
        tr.x_m.push(x);
        tr.v_m_s.push(v);
        tr.accel_m_s2.push(accel_m_s2);
        tr.force_n.push(self.mt_kg * accel_m_s2);
        tr.torque_n_m.push(self.kt_n_m_per_a * i);
        tr.current_a.push(i);
    }
}

/// Like [`simulate`] but keeps no traces: the fast path for sweeps and calibration.
pub fn simulate_summary(params: &TactorParams, options: &SimOptions) -> Result<Summary, TactorError> {
    params.validate()?;
    options.validate()?;
    let mut builder = SummaryBuilder::new(options);
    integrate(params, options, DEFAULT_STEP_ANGLE_RAD, &mut builder)?;
    Ok(builder.finish(params, options))
}

/// Time of sample index `n + frac`.
fn time_at(index: usize, frac: f64, dt_s: f64) -> f64 {
    (index as f64 + frac) * dt_s
}

/// First sample time at which `theta` reaches `target` (theta increases, linear interpolation between
/// samples); `None` if it never does.
fn crossing_time(theta: &[f64], start: usize, target: f64, dt_s: f64) -> Option<(usize, f64)> {
    let mut k = start;
    while k + 1 < theta.len() {
        if theta[k + 1] >= target && theta[k] < target {
            let frac = (target - theta[k]) / (theta[k + 1] - theta[k]);
            return Some((k, time_at(k, frac, dt_s)));
        }
        k += 1;
    }
    None
}

/// 2 % settling time of the revolution-averaged speed (physics.md §1).
///
/// At each sample time `t` with angle `theta(t)`, the speed averaged over the revolution centred on it is
/// `2 pi / (t+ - t-)`, where `theta(t+) = theta(t) + pi` and `theta(t-) = theta(t) - pi` (linear
/// interpolation between samples). The settling time is the last sample time at which that average lies
/// outside `final (1 +- tolerance)`, with `final` the window's mean speed; `None` if the average is still
/// outside at the last full revolution or the rotor never turns a full revolution.
pub fn settling_time_s(theta: &[f64], dt_s: f64, final_omega: f64, tolerance: f64) -> Option<f64> {
    use std::f64::consts::PI;
    if !(final_omega.is_finite() && final_omega > 0.0) || theta.len() < 3 {
        return None;
    }
    let lo = final_omega * (1.0 - tolerance);
    let hi = final_omega * (1.0 + tolerance);
    let mut last_outside = 0.0;
    let mut last_inside = false;
    // Cursors into theta for the trailing and leading half revolutions (both advance monotonically).
    let mut back = 0usize;
    let mut front = 0usize;
    for (n, &th) in theta.iter().enumerate() {
        if th - PI < theta[0] {
            continue;
        }
        let Some((bk, t_minus)) = crossing_time(theta, back, th - PI, dt_s) else { continue };
        back = bk;
        let Some((fk, t_plus)) = crossing_time(theta, front.max(n), th + PI, dt_s) else { break };
        front = fk;
        let avg = 2.0 * PI / (t_plus - t_minus);
        last_inside = (lo..=hi).contains(&avg);
        if !last_inside {
            last_outside = time_at(n, 0.0, dt_s);
        }
    }
    last_inside.then_some(last_outside)
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    use super::*;

    fn thesis() -> TactorParams {
        TactorParams::preset(Preset::ThesisSim)
    }

    /// physics.md §1 reference table (scipy DOP853 at rtol 1e-12), thesis-sim, unencased, b = 6.3e-8.
    #[test]
    fn reference_table_within_tolerance() {
        let s = simulate_summary(&thesis(), &SimOptions::default()).unwrap();
        assert_relative_eq!(s.omega_mean_rad_s, 833.5334, max_relative = 1e-4);
        assert_relative_eq!(s.f_rot_hz, 132.6610, max_relative = 1e-4);
        assert_relative_eq!(s.omega_min_rad_s, 801.404, max_relative = 5e-4);
        assert_relative_eq!(s.omega_max_rad_s, 873.969, max_relative = 5e-4);
        assert_relative_eq!(s.fft_peak_1s_hz, 133.0, max_relative = 1e-12);
        assert_relative_eq!(s.fft_window_s, 1.0, max_relative = 1e-12);
        assert_relative_eq!(s.accel_peak_m_s2, 245.798, max_relative = 5e-4);
        assert_relative_eq!(s.force_amplitude_n, 0.90945, max_relative = 5e-4);
        assert_relative_eq!(s.x_amplitude_m, 0.382_027e-3, max_relative = 1e-4);
        let settling = s.settling_time_s.unwrap();
        assert!((settling - 0.1067).abs() <= 3e-3, "settling {settling}");
        // Thesis's own (rounded) numbers.
        assert!((s.steady_state.omega_rad_s - 834.2).abs() < 0.05);
        assert!((s.force_amplitude_n - 0.91).abs() < 0.005);
    }

    #[test]
    fn whole_revolution_speed_does_not_depend_on_the_window() {
        let long = simulate_summary(&thesis(), &SimOptions::default()).unwrap();
        let short =
            simulate_summary(&thesis(), &SimOptions { duration_s: 2.0, output_rate_hz: 10_000.0 }).unwrap();
        assert_relative_eq!(long.omega_mean_revs_rad_s, short.omega_mean_revs_rad_s, max_relative = 5e-6);
        assert_relative_eq!(long.omega_mean_revs_rad_s, 833.5334, max_relative = 5e-5);
    }

    #[test]
    fn smaller_step_angle_converges() {
        // RK4: halving the step divides the error by ~16; the converged value is the reference's.
        let o = SimOptions::default();
        let coarse = simulate_with_step_angle(&thesis(), &o, 0.26).unwrap().summary;
        let fine = simulate_with_step_angle(&thesis(), &o, 0.13).unwrap().summary;
        let err = |s: &Summary| (s.accel_peak_m_s2 / 245.798 - 1.0).abs();
        assert!(err(&fine) < err(&coarse));
        assert_relative_eq!(fine.omega_mean_rad_s, 833.5334, max_relative = 2e-6);
        assert!(simulate_with_step_angle(&thesis(), &o, 0.0).is_err());
        assert!(simulate_with_step_angle(&thesis(), &o, 1.5).is_err());
    }

    #[test]
    fn traced_and_summary_paths_agree() {
        let o = SimOptions { duration_s: 1.0, output_rate_hz: 10_000.0 };
        let run = simulate(&thesis(), &o).unwrap();
        let s = simulate_summary(&thesis(), &o).unwrap();
        assert_eq!(run.summary, s);
        assert_eq!(run.traces.len(), 10_001);
        assert_relative_eq!(run.traces.t_s[10_000], 1.0, max_relative = 1e-12);
        let last = run.traces.len() - 1;
        assert_relative_eq!(
            run.traces.force_n[last],
            run.traces.accel_m_s2[last] * 3.7e-3,
            max_relative = 1e-12
        );
    }

    #[test]
    fn closed_form_steady_state() {
        let p = thesis();
        let ss = p.steady_state();
        // omega = Kt u / (R b + Kt^2) by hand: 0.00627 / (62 * 6.3e-8 + 3.61e-6) = 834.2203 rad/s.
        assert_relative_eq!(ss.omega_rad_s, 0.00627 / (62.0 * 6.3e-8 + 3.61e-6), max_relative = 1e-12);
        assert_relative_eq!(ss.omega_rad_s, 834.2203, max_relative = 1e-7);
        // Torque balance Kt i = b omega.
        assert_relative_eq!(ss.torque_n_m, p.damping_n_m_s * ss.omega_rad_s, max_relative = 1e-12);
        assert_relative_eq!(ss.start_current_a, 3.3 / 62.0, max_relative = 1e-12);
        assert_relative_eq!(ss.x_amplitude_m, 0.55 * 2.57 / 3.7 * 1e-3, max_relative = 1e-12);
        assert_relative_eq!(ss.electrical_time_constant_s, 17.74e-6, max_relative = 1e-3);
    }

    #[test]
    fn window_means_obey_the_averaged_circuit_equation() {
        // Averaging L i' = u - R i - Kt omega over the periodic steady state: u = R <i> + Kt <omega>.
        let s =
            simulate_summary(&thesis(), &SimOptions { duration_s: 2.0, output_rate_hz: 10_000.0 }).unwrap();
        let u = s.params.resistance_ohm * s.current_mean_a + 0.0019 * s.omega_mean_rad_s;
        assert_relative_eq!(u, 3.3, max_relative = 1e-4);
        // The start current peaks just below u/R (back-emf), the start torque at Kt u/R.
        assert_relative_eq!(s.current_peak_a, 3.3 / 62.0, max_relative = 5e-3);
        assert!(s.current_peak_a < 3.3 / 62.0);
        assert_relative_eq!(s.torque_peak_n_m, 0.0019 * s.current_peak_a, max_relative = 1e-12);
    }

    /// Independent truth for the transient: classical RK4 on the full 5-state equations
    /// ([`TactorParams::derivatives`], x and v integrated too) with a step far below L/R.
    fn fine_rk4(p: &TactorParams, h: f64, steps: usize) -> Vec<[f64; 5]> {
        let mut y = [0.0; 5];
        let mut out = vec![y];
        let add =
            |a: &[f64; 5], k: &[f64; 5], s: f64| -> [f64; 5] { std::array::from_fn(|j| a[j] + s * k[j]) };
        for _ in 0..steps {
            let k1 = p.derivatives(&y);
            let k2 = p.derivatives(&add(&y, &k1, h / 2.0));
            let k3 = p.derivatives(&add(&y, &k2, h / 2.0));
            let k4 = p.derivatives(&add(&y, &k3, h));
            y = std::array::from_fn(|j| y[j] + h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]));
            out.push(y);
        }
        out
    }

    #[test]
    fn start_transient_resolves_the_current_rise() {
        let p = thesis();
        let tau = p.electrical_time_constant_s();
        // 1 MHz output over the first 0.5 ms; truth: RK4 at 10 ns steps.
        let run = simulate(&p, &SimOptions { duration_s: 5e-4, output_rate_hz: 1e6 }).unwrap();
        let truth = fine_rk4(&p, 1e-8, 50_000);
        let tr = &run.traces;
        for n in (0..tr.len()).step_by(10) {
            let y = truth[n * 100];
            assert_relative_eq!(tr.current_a[n], y[4], epsilon = 1e-7 * 0.053);
            assert_relative_eq!(tr.omega_rad_s[n], y[3], epsilon = 1e-6 * 15.0);
            assert_relative_eq!(tr.theta_rad[n], y[2], epsilon = 1e-9);
            assert_relative_eq!(tr.v_m_s[n], y[1], max_relative = 1e-6, epsilon = 1e-12);
        }
        // Closed form of the rise with the (still tiny) back-emf ignored: i = u/R (1 - e^{-t/tau}).
        let k = (tau * 1e6).round() as usize;
        assert_relative_eq!(
            tr.current_a[k],
            3.3 / 62.0 * (1.0 - (-(k as f64) * 1e-6 / tau).exp()),
            max_relative = 2e-3
        );
        assert_relative_eq!(tr.current_a[2], 3.3 / 62.0 * (1.0 - (-2e-6 / tau).exp()), max_relative = 1e-3);
    }

    #[test]
    fn spin_up_matches_fine_full_state_integration() {
        // 0.3 s through the whole spin-up (settling ~0.107 s); truth: full 5-state RK4 at 2 us.
        let p = thesis().with_body(BodyMass::Encased);
        let run = simulate(&p, &SimOptions { duration_s: 0.3, output_rate_hz: 1000.0 }).unwrap();
        let truth = fine_rk4(&p, 2e-6, 150_000);
        for n in [10, 50, 100, 200, 300] {
            let y = truth[n * 500];
            let tr = &run.traces;
            assert_relative_eq!(tr.theta_rad[n], y[2], max_relative = 1e-6);
            // The 250 us steps at full speed leave errors of a few 1e-5 (a tenth of the reference tolerances).
            assert_relative_eq!(tr.omega_rad_s[n], y[3], max_relative = 5e-5);
            assert_relative_eq!(tr.current_a[n], y[4], max_relative = 1e-4);
            // x, v are recovered from the conserved momentum and centre of mass: same as integrating them.
            assert_relative_eq!(tr.x_m[n], y[0], epsilon = 1e-4 * 0.3e-3);
            assert_relative_eq!(tr.v_m_s[n], y[1], epsilon = 1e-4 * 0.3);
        }
    }

    #[test]
    fn encased_force_nearly_equals_unencased() {
        // Thesis Fig 31: the force amplitude (acceleration x mass) barely depends on the body mass (~ m l w^2).
        let o = SimOptions { duration_s: 2.0, output_rate_hz: 10_000.0 };
        let a = simulate_summary(&thesis(), &o).unwrap();
        let b = simulate_summary(&thesis().with_body(BodyMass::Encased), &o).unwrap();
        assert_relative_eq!(a.force_amplitude_n, b.force_amplitude_n, max_relative = 0.05);
        assert!(b.accel_peak_m_s2 < a.accel_peak_m_s2);
        assert_relative_eq!(b.x_amplitude_m, 0.55 * 2.57 / 4.95 * 1e-3, max_relative = 1e-4);
    }

    #[test]
    fn settling_of_a_first_order_rise() {
        // omega = w (1 - e^{-t/T}) => theta = w (t - T (1 - e^{-t/T})); 2 % settling at T ln 50.
        let (w, t_c, dt) = (800.0, 0.1, 1e-4);
        let theta: Vec<f64> = (0..10_000)
            .map(|k| f64::from(k) * dt)
            .map(|t| w * (t - t_c * (1.0 - (-t / t_c).exp())))
            .collect();
        let s = settling_time_s(&theta, dt, w, 0.02).unwrap();
        assert!((s - t_c * 50f64.ln()).abs() < 2e-4, "{s}");
        assert_eq!(settling_time_s(&theta[..3000], dt, w, 0.02), None);
        assert_eq!(settling_time_s(&[0.0; 100], dt, w, 0.02), None);
    }

    #[test]
    fn bad_inputs_are_rejected() {
        let o = SimOptions::default();
        assert!(matches!(
            simulate(&thesis().with_damping(f64::NAN), &o),
            Err(TactorError::Negative { name: "damping [N m s]", .. })
        ));
        assert!(matches!(simulate(&thesis().with_voltage(-1.0), &o), Err(TactorError::NotPositive { .. })));
        let mut p = thesis();
        p.body_mass_kg = 0.5e-3;
        assert!(matches!(simulate(&p, &o), Err(TactorError::BodyLighterThanEccentric { .. })));
        for d in [-1.0, 0.0, f64::INFINITY, 1e9] {
            assert!(simulate_summary(&thesis(), &SimOptions { duration_s: d, ..o }).is_err(), "{d}");
        }
        assert!(simulate(&thesis(), &SimOptions { duration_s: 1000.0, output_rate_hz: 1e5 }).is_err());
    }

    #[test]
    fn stalled_rotor_has_no_settling_and_stays_finite() {
        // Below ~0.45 V the start torque Kt u/R cannot lift the eccentric over the top (m g l): a pendulum.
        let s = simulate_summary(
            &thesis().with_voltage(0.2),
            &SimOptions { duration_s: 1.0, output_rate_hz: 1e4 },
        )
        .unwrap();
        assert!(s.omega_mean_rad_s.abs() < 1.0);
        assert_eq!(s.settling_time_s, None);
    }

    proptest! {
        #[test]
        fn steady_speed_falls_with_damping_and_rises_with_voltage(
            b in 1e-9..1e-6f64, db in 1e-10..1e-7f64, u in 0.5..6.0f64, du in 0.01..1.0f64,
        ) {
            let p = thesis().with_damping(b).with_voltage(u);
            let w = p.steady_state().omega_rad_s;
            prop_assert!(p.with_damping(b + db).steady_state().omega_rad_s < w);
            prop_assert!(p.with_voltage(u + du).steady_state().omega_rad_s > w);
            let ss = p.steady_state();
            prop_assert!(ss.current_a > 0.0 && ss.current_a < ss.start_current_a);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(6))]
        #[test]
        fn simulated_speed_is_near_the_closed_form(b in 3e-8..1.5e-7f64, u in 2.5..3.8f64) {
            // The speed ripple shifts the mean by well under 1 %; energy flows in (mean torque > 0).
            let p = thesis().with_damping(b).with_voltage(u);
            let s = simulate_summary(&p, &SimOptions { duration_s: 1.5, output_rate_hz: 10_000.0 }).unwrap();
            prop_assert!((s.omega_mean_rad_s / p.steady_state().omega_rad_s - 1.0).abs() < 0.01);
            prop_assert!(s.torque_mean_n_m > 0.0);
            prop_assert!((s.x_amplitude_m / p.steady_state().x_amplitude_m - 1.0).abs() < 1e-3);
        }
    }
}
