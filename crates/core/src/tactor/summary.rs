//! Simulation output: time traces, the figures of merit, their streaming builder and the settling time.

use serde::{Deserialize, Serialize};

use crate::analysis::spectrum_peak_hz;

use super::ode::SampleSink;
use super::{SimOptions, SteadyState, TactorParams};

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
pub(super) struct SummaryBuilder {
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
    pub(super) fn new(options: &SimOptions) -> Self {
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
    pub(super) fn finish(mut self, params: &TactorParams, options: &SimOptions) -> Summary {
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
