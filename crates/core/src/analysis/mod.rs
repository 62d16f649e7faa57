//! Measured tactor traces (thesis §3.1): peak frequency, amplitude envelope, overshoot, settling time,
//! statistics across trials and tactors, and the 5th-order zero-phase Butterworth low-pass the thesis
//! filtered with.
//!
//! A trace is a force \[N\] or acceleration [m/s^2] series sampled uniformly (the thesis: 10 kHz on an
//! impedance head); amplitudes come out in the trace's own unit. Input comes as CSV text ([`parse_csv`]):
//! parsing is pure, reading the file is the caller's job, and every malformed byte is an error with its line
//! number.
//!
//! ```
//! use vestnav_core::analysis::{analyze_trace, Butterworth}; let fs = 10_000.0; let x: Vec<f64> =
//! (0..20_000).map(|i| (2.0 * std::f64::consts::PI * 133.0 * i as f64 / fs).sin()).collect(); let summary =
//! analyze_trace(&x, fs).unwrap(); assert!((summary.peak_frequency_hz - 133.0).abs() < 0.05);
//! assert!((summary.steady_amplitude - 1.0).abs() < 1e-3); let lp = Butterworth::lowpass(5, 400.0,
//! fs).unwrap(); assert!((lp.magnitude(0.0) - 1.0).abs() < 1e-12);
//! ```

use std::f64::consts::{PI, TAU};
use std::ops::Range;

use rustfft::FftPlanner;
use rustfft::num_complex::Complex;
use serde::{Deserialize, Serialize};
use statrs::distribution::{ContinuousCDF, StudentsT};

use crate::fit::{FitError, PowerLawFit, fit_power_law};

/// Why a trace or a set of trials could not be analysed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnalysisError {
    /// The trace is too short for the computation.
    #[error("trace too short: {got} samples, need at least {needed}")]
    TooShort {
        /// Samples needed.
        needed: usize,
        /// Samples given.
        got: usize,
    },
    /// A parameter is outside its valid range.
    #[error("{name} must be {expected}, got {value}")]
    OutOfRange {
        /// Which parameter.
        name: &'static str,
        /// What it must be.
        expected: &'static str,
        /// The value given.
        value: f64,
    },
    /// A sample is NaN or infinite.
    #[error("sample {index} is not a finite number")]
    NonFinite {
        /// Index of the sample.
        index: usize,
    },
    /// The trace has no oscillation (constant after removing its mean).
    #[error("the trace does not oscillate")]
    NoOscillation,
    /// Both groups of a t-test have zero variance, so t is undefined.
    #[error("both groups have zero variance; the t statistic is undefined")]
    ZeroVariance,
    /// A curve fit failed.
    #[error(transparent)]
    Fit(#[from] FitError),
}

fn check_finite(x: &[f64]) -> Result<(), AnalysisError> {
    match x.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(AnalysisError::NonFinite { index }),
        None => Ok(()),
    }
}

fn check_rate(sample_rate_hz: f64) -> Result<(), AnalysisError> {
    if sample_rate_hz > 0.0 && sample_rate_hz.is_finite() {
        Ok(())
    } else {
        Err(AnalysisError::OutOfRange { name: "sample_rate_hz", expected: "positive", value: sample_rate_hz })
    }
}

// -----------------------------------------------------------------------------------------------------------
// Spectrum

/// The strongest spectral line of a trace.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpectralPeak {
    /// Refined peak frequency \[Hz\].
    pub frequency_hz: f64,
    /// Frequency of the strongest FFT bin \[Hz\].
    pub bin_frequency_hz: f64,
    /// Bin width `fs / N` \[Hz\].
    pub bin_width_hz: f64,
}

/// The forward FFT of `buf`, in place: the one FFT of vestnav (rustfft). A planner per call, no state kept
/// between calls (planning costs about as much as one transform; both are microseconds at our lengths).
fn fft_in_place(buf: &mut [Complex<f64>]) {
    if !buf.is_empty() {
        FftPlanner::new().plan_fft_forward(buf.len()).process(buf);
    }
}

/// Single-sided amplitude spectrum of `signal` sampled at `rate_hz`, rectangular window:
/// `A_k = |X_k| * 2/N` for `k = 0..=N/2` (DC not doubled), at frequencies `k * rate / N`.
/// Returns `(frequencies_hz, amplitudes)`; empty for an empty signal. For a sine on a bin, `A_k` is its
/// amplitude exactly.
pub fn amplitude_spectrum(signal: &[f64], rate_hz: f64) -> (Vec<f64>, Vec<f64>) {
    let n = signal.len();
    if n == 0 {
        return (Vec::new(), Vec::new());
    }
    let mut buf: Vec<Complex<f64>> = signal.iter().map(|&v| Complex::new(v, 0.0)).collect();
    fft_in_place(&mut buf);
    let half = n / 2;
    let scale = 2.0 / n as f64;
    let freqs = (0..=half).map(|k| k as f64 * rate_hz / n as f64).collect();
    let amps = buf[..=half]
        .iter()
        .enumerate()
        .map(|(k, c)| if k == 0 { c.norm() / n as f64 } else { c.norm() * scale })
        .collect();
    (freqs, amps)
}

/// Frequency of the largest non-DC bin of [`amplitude_spectrum`] (no interpolation: the simulation's
/// traces are long and clean; measured traces use [`peak_frequency`]); `None` for fewer than 4 samples.
pub fn spectrum_peak_hz(signal: &[f64], rate_hz: f64) -> Option<f64> {
    if signal.len() < 4 {
        return None;
    }
    let (f, a) = amplitude_spectrum(signal, rate_hz);
    let (k, _) = a.iter().enumerate().skip(1).max_by(|x, y| x.1.total_cmp(y.1))?;
    Some(f[k])
}

/// Peak frequency of `x` (thesis §3.1) by FFT with sub-bin refinement.
///
/// The mean is removed and a Hann window `w[n] = 0.5 - 0.5 cos(2 pi n / N)` applied (it keeps leakage of the
/// start transient and of noise away from the peak). The strongest bin `k` (DC excluded) is refined by
/// fitting a parabola to the log magnitudes of bins `k-1, k, k+1` (Gaussian interpolation): `delta = (ln
/// m[k-1] - ln m[k+1]) / (2 (ln m[k-1] - 2 ln m[k] + ln m[k+1]))`, `f = (k + delta) fs / N`. For a
/// Hann-windowed sinusoid the bias of this estimator is below 2 % of a bin.
pub fn peak_frequency(x: &[f64], sample_rate_hz: f64) -> Result<SpectralPeak, AnalysisError> {
    check_rate(sample_rate_hz)?;
    check_finite(x)?;
    let n = x.len();
    if n < 8 {
        return Err(AnalysisError::TooShort { needed: 8, got: n });
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let mut buf: Vec<Complex<f64>> = x
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let w = 0.5 - 0.5 * (2.0 * PI * i as f64 / n as f64).cos();
            Complex::new((v - mean) * w, 0.0)
        })
        .collect();
    fft_in_place(&mut buf);
    let mag: Vec<f64> = buf[..=n / 2].iter().map(|c| c.norm()).collect();
    let (k, peak) = mag
        .iter()
        .enumerate()
        .skip(1)
        .fold((0, 0.0), |best, (i, m)| if *m > best.1 { (i, *m) } else { best });
    if k == 0 || peak.is_nan() || peak <= 0.0 {
        return Err(AnalysisError::NoOscillation);
    }
    let bin = sample_rate_hz / n as f64;
    let delta = match (mag.get(k - 1), mag.get(k + 1)) {
        (Some(&l), Some(&r)) if l > 0.0 && r > 0.0 => {
            let (ll, lc, lr) = (l.ln(), peak.ln(), r.ln());
            let denom = ll - 2.0 * lc + lr;
            if denom < 0.0 { (0.5 * (ll - lr) / denom).clamp(-0.5, 0.5) } else { 0.0 }
        }
        _ => 0.0,
    };
    Ok(SpectralPeak {
        frequency_hz: (k as f64 + delta) * bin,
        bin_frequency_hz: k as f64 * bin,
        bin_width_hz: bin,
    })
}

// -----------------------------------------------------------------------------------------------------------
// Envelope, overshoot, settling

/// Oscillation amplitude envelope sampled once per oscillation period.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Envelope {
    /// Centre time of each window \[s\], from the first sample.
    pub time_s: Vec<f64>,
    /// Half the peak-to-peak value in each window (trace unit).
    pub amplitude: Vec<f64>,
    /// Window length \[s\] (one period of the peak frequency, rounded to whole samples).
    pub window_s: f64,
}

/// Amplitude envelope of `x` at oscillation frequency `frequency_hz`: the trace is cut into consecutive
/// windows of one period `P = round(fs / f)` samples and each window's amplitude is `(max - min) / 2`. A
/// window of one whole period holds one crest and one trough whatever the phase, and half the peak-to-peak
/// ignores any sensor offset. The resolution is one period (7.5 ms at 133 Hz); sampling at 10 kHz misses a
/// crest by at most `1 - cos(pi f / fs)` (0.09 % at 133 Hz). Unlike a Hilbert envelope it has no end effects.
pub fn cycle_envelope(x: &[f64], sample_rate_hz: f64, frequency_hz: f64) -> Result<Envelope, AnalysisError> {
    check_rate(sample_rate_hz)?;
    check_finite(x)?;
    if !(frequency_hz > 0.0 && frequency_hz < sample_rate_hz / 2.0) {
        return Err(AnalysisError::OutOfRange {
            name: "frequency_hz",
            expected: "between 0 and the Nyquist frequency",
            value: frequency_hz,
        });
    }
    let period = ((sample_rate_hz / frequency_hz).round() as usize).max(2);
    if x.len() < period {
        return Err(AnalysisError::TooShort { needed: period, got: x.len() });
    }
    let windows = (0..x.len() / period).map(|w| {
        let start = w * period;
        (start..start + period, (start as f64 + (period as f64 - 1.0) / 2.0) / sample_rate_hz)
    });
    let (time_s, amplitude) = window_envelope(x, windows);
    Ok(Envelope { time_s, amplitude, window_s: period as f64 / sample_rate_hz })
}

/// Amplitude envelope of a simulated tactor trace per revolution of the eccentric: the windows run from the
/// sample where `theta` reaches `2 pi k` to the one where it reaches `2 pi (k + 1)` (both included), placed
/// at the revolution's mid time; the amplitude is the same half peak-to-peak as [`cycle_envelope`]'s (thesis
/// Figs 30, 31 and 39 plot this envelope). Unlike a fixed-length window it follows the speed as the motor
/// spins up. Nothing is returned before the first full revolution; `t`, `theta` and `y` are samples at the
/// same times. `window_s` is the mean revolution time (0 when there is none).
pub fn revolution_envelope(t: &[f64], theta: &[f64], y: &[f64]) -> Envelope {
    let n = t.len().min(theta.len()).min(y.len());
    let mut windows = Vec::new();
    let mut start = 0usize;
    let mut next = TAU;
    for k in 1..n {
        if theta[k] >= next {
            windows.push((start..k + 1, 0.5 * (t[start] + t[k])));
            start = k;
            next = ((theta[k] / TAU).floor() + 1.0) * TAU;
        }
    }
    let window_s = match (windows.first(), windows.last()) {
        (Some((first, _)), Some((last, _))) => (t[last.end - 1] - t[first.start]) / windows.len() as f64,
        _ => 0.0,
    };
    let (time_s, amplitude) = window_envelope(y, windows);
    Envelope { time_s, amplitude, window_s }
}

/// The one envelope definition: for each `(window, time)`, half the peak-to-peak of `x[window]` (one crest
/// and one trough per window whatever the phase, and any offset cancels).
fn window_envelope(
    x: &[f64],
    windows: impl IntoIterator<Item = (Range<usize>, f64)>,
) -> (Vec<f64>, Vec<f64>) {
    windows
        .into_iter()
        .map(|(w, t)| {
            let (lo, hi) =
                x[w].iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
            (t, (hi - lo) / 2.0)
        })
        .unzip()
}

/// The settling band used by [`analyze_trace`]: 2 % of the steady amplitude.
pub const SETTLING_BAND: f64 = 0.02;

/// What one trial shows (thesis §3.1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TraceSummary {
    /// Peak frequency of the trace's second half \[Hz\] ([`peak_frequency`]).
    pub peak_frequency_hz: f64,
    /// Steady oscillation amplitude: median envelope over the last quarter of the trace (trace unit).
    pub steady_amplitude: f64,
    /// Largest envelope value (trace unit).
    pub peak_amplitude: f64,
    /// Time of the largest envelope value \[s\].
    pub peak_time_s: f64,
    /// Overshoot `100 (peak - steady) / steady` [%].
    pub overshoot_pct: f64,
    /// 2 % settling time \[s\]: end of the last envelope window outside `steady (1 +- 0.02)`; 0 if none is.
    pub settling_time_s: f64,
    /// Number of samples.
    pub samples: usize,
    /// Trace length \[s\].
    pub duration_s: f64,
}

/// Analyses one trial: peak frequency ([`peak_frequency`] of the second half, where the tactor runs
/// steadily), envelope ([`cycle_envelope`] at that frequency), steady amplitude (median of the envelope
/// windows in the last quarter), overshoot `100 (max env - steady) / steady` %, and the 2 % settling time of
/// the envelope (the end time of the last window whose amplitude is outside `steady (1 +- 0.02)`; resolution
/// one period).
pub fn analyze_trace(x: &[f64], sample_rate_hz: f64) -> Result<TraceSummary, AnalysisError> {
    check_rate(sample_rate_hz)?;
    check_finite(x)?;
    if x.len() < 16 {
        return Err(AnalysisError::TooShort { needed: 16, got: x.len() });
    }
    let peak = peak_frequency(&x[x.len() / 2..], sample_rate_hz)?;
    let env = cycle_envelope(x, sample_rate_hz, peak.frequency_hz)?;
    let m = env.amplitude.len();
    let mut tail: Vec<f64> = env.amplitude[m - (m / 4).max(1)..].to_vec();
    tail.sort_by(f64::total_cmp);
    let steady = if tail.len() % 2 == 1 {
        tail[tail.len() / 2]
    } else {
        0.5 * (tail[tail.len() / 2 - 1] + tail[tail.len() / 2])
    };
    if steady.is_nan() || steady <= 0.0 {
        return Err(AnalysisError::NoOscillation);
    }
    let (i_max, max) = env
        .amplitude
        .iter()
        .enumerate()
        .fold((0, f64::NEG_INFINITY), |best, (i, v)| if *v > best.1 { (i, *v) } else { best });
    let band = SETTLING_BAND * steady;
    let settling = env
        .amplitude
        .iter()
        .rposition(|a| (a - steady).abs() > band)
        .map_or(0.0, |i| env.time_s[i] + env.window_s / 2.0);
    Ok(TraceSummary {
        peak_frequency_hz: peak.frequency_hz,
        steady_amplitude: steady,
        peak_amplitude: max,
        peak_time_s: env.time_s[i_max],
        overshoot_pct: 100.0 * (max - steady) / steady,
        settling_time_s: settling,
        samples: x.len(),
        duration_s: x.len() as f64 / sample_rate_hz,
    })
}

// -----------------------------------------------------------------------------------------------------------
// Statistics

/// Descriptive statistics of a sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Stats {
    /// Sample size.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (n - 1 in the denominator); 0 for one value.
    pub sd: f64,
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
    /// `max - min`.
    pub range: f64,
}

impl Stats {
    /// Statistics of `x`; `None` if it is empty or holds a non-finite value.
    pub fn of(x: &[f64]) -> Option<Self> {
        if x.is_empty() || x.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let n = x.len();
        let mean = x.iter().sum::<f64>() / n as f64;
        let var =
            if n > 1 { x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64 } else { 0.0 };
        let min = x.iter().copied().fold(f64::INFINITY, f64::min);
        let max = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Some(Self { n, mean, sd: var.sqrt(), min, max, range: max - min })
    }
}

/// Which two-sample t-test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TTestKind {
    /// Welch's test (unequal variances; scipy `ttest_ind(equal_var=False)`). The default: tactors differ.
    Welch,
    /// Student's test with pooled variance (scipy `ttest_ind(equal_var=True)`, MATLAB `ttest2` default).
    Pooled,
}

/// Result of a two-sample t-test.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TTest {
    /// Which test.
    pub kind: TTestKind,
    /// The t statistic (positive when the first group's mean is larger).
    pub t: f64,
    /// Degrees of freedom (fractional for Welch).
    pub df: f64,
    /// Two-sided p-value `2 P(T > |t|)`.
    pub p_value: f64,
    /// Mean of the first group minus mean of the second.
    pub mean_difference: f64,
}

/// Two-sample t-test of `a` against `b`, two-sided.
///
/// Welch: `t = (ma - mb) / sqrt(va/na + vb/nb)`,
/// `df = (va/na + vb/nb)^2 / ((va/na)^2/(na-1) + (vb/nb)^2/(nb-1))`.
/// Pooled: `sp^2 = ((na-1) va + (nb-1) vb) / (na + nb - 2)`, `t = (ma - mb) / (sp sqrt(1/na + 1/nb))`,
/// `df = na + nb - 2`. `p = 2 sf_T(|t|; df)` with Student's t distribution (statrs).
pub fn t_test(a: &[f64], b: &[f64], kind: TTestKind) -> Result<TTest, AnalysisError> {
    let sa = Stats::of(a).ok_or(AnalysisError::TooShort { needed: 2, got: a.len() })?;
    let sb = Stats::of(b).ok_or(AnalysisError::TooShort { needed: 2, got: b.len() })?;
    if sa.n < 2 || sb.n < 2 {
        return Err(AnalysisError::TooShort { needed: 2, got: sa.n.min(sb.n) });
    }
    let (na, nb) = (sa.n as f64, sb.n as f64);
    let (va, vb) = (sa.sd * sa.sd, sb.sd * sb.sd);
    let diff = sa.mean - sb.mean;
    let (se, df) = match kind {
        TTestKind::Welch => {
            let (qa, qb) = (va / na, vb / nb);
            let df = (qa + qb).powi(2) / (qa * qa / (na - 1.0) + qb * qb / (nb - 1.0));
            ((qa + qb).sqrt(), df)
        }
        TTestKind::Pooled => {
            let sp2 = ((na - 1.0) * va + (nb - 1.0) * vb) / (na + nb - 2.0);
            ((sp2 * (1.0 / na + 1.0 / nb)).sqrt(), na + nb - 2.0)
        }
    };
    if se.is_nan() || se <= 0.0 || !df.is_finite() {
        return Err(AnalysisError::ZeroVariance);
    }
    let t = diff / se;
    let dist = StudentsT::new(0.0, 1.0, df).map_err(|_| AnalysisError::OutOfRange {
        name: "degrees of freedom",
        expected: "positive",
        value: df,
    })?;
    let p_value = (2.0 * dist.sf(t.abs())).min(1.0);
    Ok(TTest { kind, t, df, p_value, mean_difference: diff })
}

/// The thesis's power law across trials (§3.1, physics.md §1): `f = A n^B` with `n` the steady amplitude
/// (force) and `f` the peak frequency of each trial, fitted in linear space with R^2 ([`fit_power_law`]).
pub fn frequency_power_law(trials: &[TraceSummary]) -> Result<PowerLawFit, AnalysisError> {
    let n: Vec<f64> = trials.iter().map(|t| t.steady_amplitude).collect();
    let f: Vec<f64> = trials.iter().map(|t| t.peak_frequency_hz).collect();
    Ok(fit_power_law(&n, &f)?)
}

// -----------------------------------------------------------------------------------------------------------
// Butterworth low-pass

/// One second-order section `(b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)`, run in transposed direct
/// form II.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Biquad {
    /// Numerator `[b0, b1, b2]`.
    pub b: [f64; 3],
    /// Denominator `[a1, a2]` (`a0 = 1`).
    pub a: [f64; 2],
}

impl Biquad {
    fn response(&self, z_inv: Complex<f64>) -> Complex<f64> {
        let z2 = z_inv * z_inv;
        (self.b[0] + z_inv * self.b[1] + z2 * self.b[2]) / (1.0 + z_inv * self.a[0] + z2 * self.a[1])
    }

    /// DF-II-T state that makes the section sit in steady state under a constant input `u`
    /// (`y = H(1) u`, `z2 = b2 u - a2 y`, `z1 = b1 u - a1 y + z2`), as `lfilter_zi` does.
    fn steady_state(&self, u: f64) -> [f64; 2] {
        let gain = (self.b[0] + self.b[1] + self.b[2]) / (1.0 + self.a[0] + self.a[1]);
        let y = gain * u;
        let z2 = self.b[2] * u - self.a[1] * y;
        [self.b[1] * u - self.a[0] * y + z2, z2]
    }

    fn run(&self, x: &mut [f64], mut z: [f64; 2]) {
        for v in x.iter_mut() {
            let input = *v;
            let y = self.b[0] * input + z[0];
            z[0] = self.b[1] * input - self.a[0] * y + z[1];
            z[1] = self.b[2] * input - self.a[1] * y;
            *v = y;
        }
    }
}

/// A digital Butterworth low-pass as a cascade of second-order sections (a first-order one for odd orders).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Butterworth {
    /// The sections, each with unit gain at DC.
    pub sections: Vec<Biquad>,
    /// Filter order.
    pub order: usize,
    /// -3 dB cutoff of one pass \[Hz\].
    pub cutoff_hz: f64,
    /// Sample rate \[Hz\].
    pub sample_rate_hz: f64,
}

impl Butterworth {
    /// Designs an order-`order` low-pass with cutoff `cutoff_hz` by the bilinear transform of the analog
    /// prototype.
    ///
    /// Analog poles on a circle of radius `Wc = 2 fs tan(pi fc / fs)` (pre-warped so the digital filter has
    /// `|H|^2 = 1/2` exactly at `fc`): `s_k = Wc exp(i pi (2k + N + 1) / (2N))`, `k = 0..N-1`; all zeros at
    /// infinity. Bilinear transform `z = (1 + s/(2 fs)) / (1 - s/(2 fs))` maps each pole and sends the zeros
    /// to `z = -1`. A conjugate pole pair `p, p*` becomes `g (1 + z^-1)^2 / (1 - 2 Re(p) z^-1 + |p|^2 z^-2)`
    /// with `g = (1 - 2 Re(p) + |p|^2) / 4`; the real pole of an odd order `g (1 + z^-1) / (1 - p z^-1)`, `g
    /// = (1 - p)/2`; so every section has unit gain at DC. The thesis used a 5th-order filter run forward and
    /// backward.
    pub fn lowpass(order: usize, cutoff_hz: f64, sample_rate_hz: f64) -> Result<Self, AnalysisError> {
        check_rate(sample_rate_hz)?;
        if !(1..=20).contains(&order) {
            return Err(AnalysisError::OutOfRange { name: "order", expected: "1..=20", value: order as f64 });
        }
        if !(cutoff_hz > 0.0 && cutoff_hz < sample_rate_hz / 2.0) {
            return Err(AnalysisError::OutOfRange {
                name: "cutoff_hz",
                expected: "between 0 and the Nyquist frequency",
                value: cutoff_hz,
            });
        }
        let fs2 = 2.0 * sample_rate_hz;
        let wc = fs2 * (PI * cutoff_hz / sample_rate_hz).tan();
        let n = order as f64;
        let bilinear = |s: Complex<f64>| (1.0 + s / fs2) / (1.0 - s / fs2);
        let mut sections = Vec::with_capacity(order.div_ceil(2));
        for k in 0..order / 2 {
            let angle = PI * (2.0 * k as f64 + n + 1.0) / (2.0 * n);
            let p = bilinear(Complex::from_polar(wc, angle));
            let (a1, a2) = (-2.0 * p.re, p.norm_sqr());
            let g = (1.0 + a1 + a2) / 4.0;
            sections.push(Biquad { b: [g, 2.0 * g, g], a: [a1, a2] });
        }
        if order % 2 == 1 {
            let p = bilinear(Complex::new(-wc, 0.0)).re;
            let g = (1.0 - p) / 2.0;
            sections.push(Biquad { b: [g, g, 0.0], a: [-p, 0.0] });
        }
        Ok(Self { sections, order, cutoff_hz, sample_rate_hz })
    }

    /// Complex response of one pass at `frequency_hz`: the product of the sections' `H(e^{i w})`,
    /// `w = 2 pi f / fs`.
    pub fn response(&self, frequency_hz: f64) -> Complex<f64> {
        let z_inv = Complex::from_polar(1.0, -2.0 * PI * frequency_hz / self.sample_rate_hz);
        self.sections.iter().map(|s| s.response(z_inv)).product()
    }

    /// `|H(f)|` of one pass; the zero-phase (forward-backward) filter's magnitude is its square.
    pub fn magnitude(&self, frequency_hz: f64) -> f64 {
        self.response(frequency_hz).norm()
    }

    /// The transfer function as polynomials in `z^-1`, `(b, a)` with `a[0] = 1`, by multiplying out the
    /// sections (MATLAB/scipy `butter`'s `[b, a]` form).
    pub fn transfer_function(&self) -> (Vec<f64>, Vec<f64>) {
        let mul = |p: &[f64], q: &[f64]| {
            let mut r = vec![0.0; p.len() + q.len() - 1];
            for (i, x) in p.iter().enumerate() {
                for (j, y) in q.iter().enumerate() {
                    r[i + j] += x * y;
                }
            }
            r
        };
        let (mut b, mut a) = (vec![1.0], vec![1.0]);
        for s in &self.sections {
            b = mul(&b, &s.b);
            a = mul(&a, &[1.0, s.a[0], s.a[1]]);
        }
        b.truncate(self.order + 1);
        a.truncate(self.order + 1);
        (b, a)
    }

    /// One causal pass from a zero state.
    pub fn filter(&self, x: &[f64]) -> Vec<f64> {
        let mut y = x.to_vec();
        for s in &self.sections {
            s.run(&mut y, [0.0, 0.0]);
        }
        y
    }

    /// Zero-phase filtering, forward then backward (MATLAB `filtfilt`, scipy `sosfiltfilt`): response
    /// `|H|^2`, no delay. As scipy does, the trace is first extended at both ends by its odd reflection (`2
    /// x[0] - x[k]`, `2 x[n-1] - x[n-1-k]`) of `3 (2 sections + 1 - zero-order terms)` samples (fewer for
    /// short traces), and each pass starts every section in the steady state of its first input, so a trace
    /// that starts or ends away from zero does not ring. Non-finite input is an error.
    pub fn filtfilt(&self, x: &[f64]) -> Result<Vec<f64>, AnalysisError> {
        check_finite(x)?;
        let n = x.len();
        if n < 2 {
            return Err(AnalysisError::TooShort { needed: 2, got: n });
        }
        let trailing_zero = usize::from(self.order % 2 == 1);
        let taps = 2 * self.sections.len() + 1 - trailing_zero;
        let pad = (3 * taps).min(n - 1);
        let mut ext = Vec::with_capacity(n + 2 * pad);
        ext.extend((1..=pad).rev().map(|k| 2.0 * x[0] - x[k]));
        ext.extend_from_slice(x);
        ext.extend((1..=pad).map(|k| 2.0 * x[n - 1] - x[n - 1 - k]));
        self.pass_from_steady_state(&mut ext);
        ext.reverse();
        self.pass_from_steady_state(&mut ext);
        ext.reverse();
        Ok(ext[pad..pad + n].to_vec())
    }

    fn pass_from_steady_state(&self, x: &mut [f64]) {
        let first = x.first().copied().unwrap_or(0.0);
        for s in &self.sections {
            // Every section has unit DC gain, so every section's first input is `first`.
            s.run(x, s.steady_state(first));
        }
    }
}

// -----------------------------------------------------------------------------------------------------------
// CSV input

/// Whether the first column of a CSV is time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeColumn {
    /// Time if the header names it (`t`, `time`, `time_s`, `t_s`, `time_ms`, `t_ms`, `seconds`, `ms`), or,
    /// with no header, if it has at least two columns and the first one increases in uniform steps.
    #[default]
    Auto,
    /// The first column is time.
    Present,
    /// Every column is a trial.
    Absent,
}

/// Why a CSV could not be read; lines are 1-based.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CsvError {
    /// The text holds no data row.
    #[error("no data rows")]
    Empty,
    /// A blank line inside the data.
    #[error("line {line}: blank line inside the data")]
    BlankLine {
        /// Line number.
        line: usize,
    },
    /// A field is not a finite number.
    #[error("line {line}, column {column}: {text:?} is not a finite number")]
    BadNumber {
        /// Line number.
        line: usize,
        /// Column number (1-based).
        column: usize,
        /// The offending field (cut to 40 characters).
        text: String,
    },
    /// A row has a different number of fields than the first.
    #[error("line {line}: {got} fields, expected {expected}")]
    ColumnCount {
        /// Line number.
        line: usize,
        /// Fields of the first row.
        expected: usize,
        /// Fields of this row.
        got: usize,
    },
    /// The time column does not increase uniformly.
    #[error(
        "line {line}: time column is not increasing in uniform steps (step {step_s} s, expected {expected_s} s)"
    )]
    NonUniformTime {
        /// Line number.
        line: usize,
        /// The step found \[s\].
        step_s: f64,
        /// The first step \[s\].
        expected_s: f64,
    },
    /// Only a time column, no trial.
    #[error("no trial column besides the time column")]
    NoTrials,
    /// The sample rate (given for a file without time, or from its time column) is not usable.
    #[error("sample rate must be positive and finite, got {0} Hz")]
    BadSampleRate(f64),
}

/// Trials read from one CSV.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TraceSet {
    /// One name per trial (from the header, or `trial1`, `trial2`, ...).
    pub names: Vec<String>,
    /// One series per trial, all of equal length.
    pub traces: Vec<Vec<f64>>,
    /// Sample rate \[Hz\], from the time column or as given.
    pub sample_rate_hz: f64,
    /// Whether the sample rate came from a time column in the file.
    pub time_from_file: bool,
}

fn split_fields(line: &str, sep: char) -> Vec<&str> {
    if sep == ' ' { line.split_whitespace().collect() } else { line.split(sep).map(str::trim).collect() }
}

fn is_time_name(name: &str) -> bool {
    let n = name.trim().trim_matches('"').to_ascii_lowercase();
    matches!(
        n.as_str(),
        "t" | "time" | "time_s" | "t_s" | "time_ms" | "t_ms" | "seconds" | "ms" | "time [s]" | "time [ms]"
    )
}

fn parse_number(text: &str, line: usize, column: usize) -> Result<f64, CsvError> {
    match text.trim_matches('"').parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(CsvError::BadNumber { line, column, text: text.chars().take(40).collect() }),
    }
}

/// Parses trial traces from CSV text.
///
/// Format: fields separated by `,` (or `;`, tab or spaces, chosen from the first line); an optional header (a
/// first line with any non-numeric field); lines starting with `#` are comments; an optional time column
/// first (see [`TimeColumn`]; a header name containing `ms` means milliseconds, otherwise seconds), then one
/// column per trial. Trailing blank lines are allowed; a blank line between data rows, a non-numeric or
/// non-finite field, a row with a different number of fields, or a time column that does not increase in
/// uniform steps (within 1 % of the first step) is an error naming the line.
pub fn parse_csv(text: &str, time: TimeColumn, sample_rate_hz: f64) -> Result<TraceSet, CsvError> {
    let mut pending_blank = None;
    let mut header: Option<Vec<String>> = None;
    let mut sep = ',';
    let mut rows: Vec<Vec<f64>> = Vec::new();
    let mut data_lines: Vec<usize> = Vec::new();
    let mut width = 0;
    for (i, raw) in text.lines().enumerate() {
        let no = i + 1;
        let line = raw.trim();
        if line.starts_with('#') {
            continue;
        }
        if line.is_empty() {
            if !rows.is_empty() || header.is_some() {
                pending_blank.get_or_insert(no);
            }
            continue;
        }
        if let Some(line) = pending_blank {
            return Err(CsvError::BlankLine { line });
        }
        if rows.is_empty() && header.is_none() {
            sep = [',', ';', '\t'].into_iter().find(|c| line.contains(*c)).unwrap_or(' ');
            let fields = split_fields(line, sep);
            width = fields.len();
            if fields.iter().any(|f| f.trim_matches('"').parse::<f64>().is_err()) {
                header = Some(fields.iter().map(|f| f.trim_matches('"').to_string()).collect());
                continue;
            }
        }
        let fields = split_fields(line, sep);
        if fields.len() != width {
            return Err(CsvError::ColumnCount { line: no, expected: width, got: fields.len() });
        }
        let row = fields
            .iter()
            .enumerate()
            .map(|(c, f)| parse_number(f, no, c + 1))
            .collect::<Result<Vec<_>, _>>()?;
        rows.push(row);
        data_lines.push(no);
    }
    if rows.is_empty() {
        return Err(CsvError::Empty);
    }
    let has_time = match time {
        TimeColumn::Present => true,
        TimeColumn::Absent => false,
        TimeColumn::Auto => match &header {
            Some(h) => h.first().is_some_and(|n| is_time_name(n)),
            None => width >= 2 && rows.len() >= 3 && uniform_steps(&rows, &data_lines, 1.0).is_ok(),
        },
    };
    let rate = if has_time {
        if width < 2 {
            return Err(CsvError::NoTrials);
        }
        let unit = match &header {
            Some(h) if h.first().is_some_and(|n| n.to_ascii_lowercase().contains("ms")) => 1e-3,
            _ => 1.0,
        };
        let step = uniform_steps(&rows, &data_lines, unit)?;
        // A subnormal step passes as uniform but has no usable reciprocal.
        let rate = 1.0 / step;
        if !rate.is_finite() {
            return Err(CsvError::BadSampleRate(rate));
        }
        rate
    } else {
        if !(sample_rate_hz > 0.0 && sample_rate_hz.is_finite()) {
            return Err(CsvError::BadSampleRate(sample_rate_hz));
        }
        sample_rate_hz
    };
    let first = usize::from(has_time);
    let names = (first..width)
        .map(|c| {
            header
                .as_ref()
                .and_then(|h| h.get(c))
                .filter(|s| !s.is_empty())
                .cloned()
                .unwrap_or_else(|| format!("trial{}", c + 1 - first))
        })
        .collect();
    let traces = (first..width).map(|c| rows.iter().map(|r| r[c]).collect()).collect();
    Ok(TraceSet { names, traces, sample_rate_hz: rate, time_from_file: has_time })
}

/// The common step of the first column [s] if it increases uniformly (within 1 % of the first step).
fn uniform_steps(rows: &[Vec<f64>], lines: &[usize], unit: f64) -> Result<f64, CsvError> {
    let line_of = |i: usize| lines.get(i).copied().unwrap_or(0);
    if rows.len() < 2 {
        return Err(CsvError::NonUniformTime { line: line_of(1), step_s: f64::NAN, expected_s: f64::NAN });
    }
    let step = (rows[1][0] - rows[0][0]) * unit;
    for (i, pair) in rows.windows(2).enumerate() {
        let s = (pair[1][0] - pair[0][0]) * unit;
        if step.is_nan() || step <= 0.0 || s.is_nan() || (s - step).abs() > 0.01 * step {
            return Err(CsvError::NonUniformTime { line: line_of(i + 1), step_s: s, expected_s: step });
        }
    }
    Ok(step)
}

#[cfg(test)]
mod tests;
