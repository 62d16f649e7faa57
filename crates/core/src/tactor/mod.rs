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

mod ode;
mod params;
mod summary;
#[cfg(test)]
mod tests;

pub use params::{
    BodyMass, DAMPING_THESIS_N_M_S, Preset, RADIUS_CAD_M, RADIUS_FITTED_M, SimOptions, SteadyState,
    TactorError, TactorParams,
};
pub use summary::{Summary, TactorRun, Traces, settling_time_s};

use ode::{SampleSink, integrate};
use params::check_positive;
use summary::SummaryBuilder;

/// Standard gravity used by the thesis [m/s^2].
pub const GRAVITY_M_S2: f64 = 9.81;

/// Default accuracy of [`simulate`]: away from the start, the step is also limited to this eccentric rotation at the closed-form steady speed
/// \[rad\] (0.26 rad = 300 us at 834 rad/s: RK4 errors ~5e-5 relative there, a tenth of the reference
/// tolerances; halving it costs 30 % more time for 16x smaller errors).
pub const DEFAULT_STEP_ANGLE_RAD: f64 = 0.26;
/// Most output samples a traced simulation may store (9 traces of f64: 5 M samples = 360 MB).
const MAX_TRACE_SAMPLES: f64 = 5.0e6;

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
