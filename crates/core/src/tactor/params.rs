//! Tactor parameters and presets, why they are refused, the closed-form steady state and the run options.

use serde::{Deserialize, Serialize};

use super::GRAVITY_M_S2;
use super::ode::{Angle, Consts};

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

pub(super) fn check_positive(name: &'static str, value: f64) -> Result<(), TactorError> {
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

    pub(super) fn sample_count(&self) -> usize {
        // Samples at t = k/rate for k = 0..=n; the tiny slack absorbs rounding of e.g. 10 s x 10 kHz.
        (self.duration_s * self.output_rate_hz + 1e-9).floor() as usize + 1
    }
}
