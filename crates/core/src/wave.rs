//! Skin travelling waves of vibrating tactors and their linear superposition (thesis §4.1.3).
//!
//! A tactor pressed on the skin (or on the Skinsim substitute) launches a wave whose amplitude falls off as a
//! Gaussian of the distance `r` from the tactor and whose phase lags by `r / c`:
//!
//! ```text
//! a(r, t) = a0 exp(-(r/b)^2) sin(2 pi / lambda (r - c t) + phi),   lambda = c / f
//! ```
//!
//! Measured on Skinsim (thesis §4.1.3): `a0 = 26.02 m/s^2`, `b = 28.18 mm`, `lambda = 42.94 mm`, `c = 3023
//! mm/s` at 70.4 Hz. Several tactors superpose linearly; the thesis notes the measured superposition is not
//! fully linear (R^2 0.42 predicted against 0.91 fitted), so the field here is the linear model.
//!
//! Everything is in SI units: positions and widths in metres, accelerations in m/s^2, times in seconds.
//! Positions live on a plane ([`DVec2`]); a 1-D problem is the x axis of that plane.
//!
//! ```
//! use glam::DVec2;
//! use vestnav_core::wave::{Skin, WaveSource};
//! let skin = Skin::MEASURED;
//! let tactor = WaveSource::measured(DVec2::ZERO);
//! // One wavelength away the envelope has fallen to exp(-(42.94/28.18)^2) = 9.8 % of a0.
//! let amp = tactor.envelope_m_s2(DVec2::new(skin.wavelength_m(tactor.frequency_hz), 0.0));
//! assert!((amp / tactor.amplitude_m_s2 - 0.0981).abs() < 1e-3);
//! ```

use std::f64::consts::{PI, TAU};

/// The plane vector type of positions, re-exported so callers need no direct `glam` dependency.
pub use glam::DVec2;
use serde::{Deserialize, Serialize};

use crate::fit::{Curve, FitError, LineFit, fit_line, least_squares, r_squared};
use crate::vest::{GRID, TACTOR_COUNT, TactorMask};

/// Measured source amplitude on Skinsim, `a0` [m/s^2] (thesis §4.1.3).
pub const MEASURED_A0_M_S2: f64 = 26.02;
/// Measured Gaussian width `b` of the travelling-wave tactor \[m\] (thesis §4.1.3).
pub const MEASURED_WIDTH_M: f64 = 0.028_18;
/// Measured wavelength on Skinsim \[m\] (thesis §4.1.3).
pub const MEASURED_WAVELENGTH_M: f64 = 0.042_94;
/// Measured wave speed on Skinsim [m/s] (thesis §4.1.3).
pub const MEASURED_SPEED_M_S: f64 = 3.023;
/// Frequency of the measured travelling wave \[Hz\]: `c / lambda` = 3023 / 42.94 = 70.4 Hz.
pub const MEASURED_FREQUENCY_HZ: f64 = MEASURED_SPEED_M_S / MEASURED_WAVELENGTH_M;
/// Gaussian widths of the three tactors of Fig 52 \[m\]; their mean 36.2 mm is the two-point simulation's
/// width.
pub const FIG52_WIDTHS_M: [f64; 3] = [0.028_18, 0.038_4, 0.042_13];
/// Source amplitudes of the three tactors of Fig 52 [m/s^2] (read off the figure: about 25.7, 9 and 9).
pub const FIG52_A0_M_S2: [f64; 3] = [25.7, 9.0, 9.0];
/// The design rule's fraction: a neighbour's wave should have fallen below 10 % of its source (thesis
/// §4.1.3).
pub const SPACING_RULE_FRACTION: f64 = 0.1;

/// Why a wave computation could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WaveError {
    /// A parameter is outside its physical range.
    #[error("{name} must be {expected}, got {value}")]
    OutOfRange {
        /// Which parameter.
        name: &'static str,
        /// What it must be.
        expected: &'static str,
        /// The value given.
        value: f64,
    },
    /// A least-squares fit failed.
    #[error(transparent)]
    Fit(#[from] FitError),
    /// No crest of the wave was found at a distance within the simulated time.
    #[error("no wave crest found at {distance_m} m within the simulated time")]
    NoCrest {
        /// The distance where no crest was found \[m\].
        distance_m: f64,
    },
}

/// The Gaussian fall-off of a tactor's vibration with distance: `a(d) = a0 exp(-(d/b)^2)` (thesis §4.1.3, Fig
/// 52).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GaussianAttenuation {
    /// Amplitude at the tactor, `a0` [m/s^2].
    pub a0_m_s2: f64,
    /// Width `b` \[m\]: at `d = b` the amplitude has fallen to `1/e`.
    pub width_m: f64,
}

impl GaussianAttenuation {
    /// `a0 exp(-(d/b)^2)` at distance `distance_m` (sign ignored) [m/s^2] (thesis §4.1.3).
    pub fn amplitude_m_s2(&self, distance_m: f64) -> f64 {
        self.a0_m_s2 * (-(distance_m / self.width_m).powi(2)).exp()
    }

    /// Distance where the amplitude has fallen to `fraction` of `a0`; see [`spacing_for_fraction_m`].
    pub fn distance_for_fraction_m(&self, fraction: f64) -> Result<f64, WaveError> {
        spacing_for_fraction_m(self.width_m, fraction)
    }
}

/// The spacing rule (thesis §4.1.3): the distance at which a Gaussian of width `b` has fallen to `fraction`
/// of its source. From `exp(-(d/b)^2) = fraction`: `d = b sqrt(ln(1/fraction))`. With the design fraction 10
/// % this is `1.517 b` (42.8 mm for b = 28.18 mm, 54.9 mm for the mean b = 36.2 mm).
pub fn spacing_for_fraction_m(width_m: f64, fraction: f64) -> Result<f64, WaveError> {
    if !(fraction > 0.0 && fraction < 1.0) {
        return Err(WaveError::OutOfRange { name: "fraction", expected: "in (0, 1)", value: fraction });
    }
    if !(width_m > 0.0 && width_m.is_finite()) {
        return Err(WaveError::OutOfRange {
            name: "width_m",
            expected: "positive and finite",
            value: width_m,
        });
    }
    Ok(width_m * (1.0 / fraction).ln().sqrt())
}

/// Fits `a0 exp(-(d/b)^2)` to measured (distance, amplitude) points, as the thesis did for Fig 52 (MATLAB's
/// `gauss1` with the centre held at the tactor). Start: the line `ln a = ln a0 - d^2/b^2` through the
/// positive points, then Levenberg–Marquardt on the linear-space residuals. `r2` is computed in linear space.
pub fn fit_attenuation(distance_m: &[f64], amplitude_m_s2: &[f64]) -> Result<AttenuationFit, WaveError> {
    if distance_m.len() != amplitude_m_s2.len() || distance_m.len() < 2 {
        return Err(
            FitError::TooFewPoints { needed: 2, got: distance_m.len().min(amplitude_m_s2.len()) }.into()
        );
    }
    if distance_m.iter().chain(amplitude_m_s2).any(|v| !v.is_finite()) {
        return Err(WaveError::OutOfRange { name: "data", expected: "finite", value: f64::NAN });
    }
    let (d2, ln_a): (Vec<f64>, Vec<f64>) = distance_m
        .iter()
        .zip(amplitude_m_s2)
        .filter(|(_, a)| **a > 0.0)
        .map(|(d, a)| (d * d, a.ln()))
        .unzip();
    let start = fit_line(&d2, &ln_a)?;
    if start.slope >= 0.0 {
        return Err(WaveError::OutOfRange {
            name: "amplitude trend",
            expected: "falling with distance",
            value: start.slope,
        });
    }
    let start = [start.intercept.exp(), (-1.0 / start.slope).sqrt()];
    let [a0, width] = least_squares(&CentredGaussian, distance_m, amplitude_m_s2, start)?.params;
    let model = GaussianAttenuation { a0_m_s2: a0, width_m: width.abs() };
    let predicted: Vec<f64> = distance_m.iter().map(|d| model.amplitude_m_s2(*d)).collect();
    Ok(AttenuationFit { model, r2: r_squared(amplitude_m_s2, &predicted) })
}

/// A fitted attenuation curve with its goodness of fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AttenuationFit {
    /// The fitted Gaussian.
    pub model: GaussianAttenuation,
    /// Coefficient of determination, linear space.
    pub r2: f64,
}

/// `a0 exp(-(d/b)^2)` with parameters `[a0, b]` (the centre held at the tactor).
struct CentredGaussian;

impl Curve<2> for CentredGaussian {
    fn value(&self, [a0, b]: &[f64; 2], d: f64) -> Option<f64> {
        Some(a0 * (-(d / b).powi(2)).exp())
    }

    fn gradient(&self, [a0, b]: &[f64; 2], d: f64) -> Option<[f64; 2]> {
        let e = (-(d / b).powi(2)).exp();
        Some([e, a0 * e * 2.0 * d * d / (b * b * b)])
    }
}

/// The medium the waves travel in. The wave speed is a property of the skin; amplitude, width and frequency
/// belong to each source.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Skin {
    /// Phase speed `c` [m/s].
    pub speed_m_s: f64,
}

impl Skin {
    /// Skinsim as measured in the thesis: `c = 3.023 m/s` (§4.1.3).
    pub const MEASURED: Self = Self { speed_m_s: MEASURED_SPEED_M_S };

    /// Wavelength `lambda = c / f` \[m\].
    pub fn wavelength_m(&self, frequency_hz: f64) -> f64 {
        self.speed_m_s / frequency_hz
    }

    /// Acceleration of one source's wave at `point_m` and time `t_s` [m/s^2] (thesis §4.1.3):
    /// `a0 exp(-(r/b)^2) sin(k r - w t + phi)` with `r = |point - source|`, `k = 2 pi f / c`, `w = 2 pi f`
    /// (the thesis's `sin(2 pi/lambda (x - c t))` with `x` replaced by the radial distance, so the wave runs
    /// outward on every side).
    pub fn wave_m_s2(&self, source: &WaveSource, point_m: DVec2, t_s: f64) -> f64 {
        let r = point_m.distance(source.position_m);
        let omega = TAU * source.frequency_hz;
        let k = omega / self.speed_m_s;
        source.envelope_m_s2(point_m) * (k * r - omega * t_s + source.phase_rad).sin()
    }

    /// Linear superposition of every source's wave at `point_m` and `t_s` [m/s^2]:
    /// `a(p, t) = sum_i a_i(p, t)` (thesis §4.1.3).
    pub fn field_m_s2(&self, sources: &[WaveSource], point_m: DVec2, t_s: f64) -> f64 {
        sources.iter().map(|s| self.wave_m_s2(s, point_m, t_s)).sum()
    }

    /// The signal at `point_m` as a sum of sinusoids, one per distinct source frequency:
    /// `a(t) = sum_f A_f sin(w_f t + c_f)`. Sources of equal frequency are added as phasors: each contributes
    /// `a_i exp(-(r_i/b_i)^2) sin(k r_i - w t + phi_i) = A_i sin(w t + pi - k r_i - phi_i)`, so
    /// `A_f exp(i c_f) = sum_i A_i exp(i (pi - k r_i - phi_i))`. Sorted by frequency.
    pub fn components(&self, sources: &[WaveSource], point_m: DVec2) -> Vec<Sinusoid> {
        let mut groups: Vec<(f64, f64, f64)> = Vec::new(); // (frequency, re, im)
        for s in sources {
            let amp = s.envelope_m_s2(point_m);
            let k = TAU * s.frequency_hz / self.speed_m_s;
            let phase = PI - k * point_m.distance(s.position_m) - s.phase_rad;
            let (im, re) = phase.sin_cos();
            let tol = 1e-9 * s.frequency_hz.abs().max(1.0);
            if let Some(g) = groups.iter_mut().find(|g| (g.0 - s.frequency_hz).abs() <= tol) {
                g.1 += amp * re;
                g.2 += amp * im;
            } else {
                groups.push((s.frequency_hz, amp * re, amp * im));
            }
        }
        groups.sort_by(|a, b| a.0.total_cmp(&b.0));
        groups
            .into_iter()
            .map(|(f, re, im)| Sinusoid {
                amplitude_m_s2: re.hypot(im),
                omega_rad_s: TAU * f,
                phase_rad: im.atan2(re),
            })
            .collect()
    }

    /// Peak vibration amplitude at `point_m` over all time [m/s^2]: the sum of the component amplitudes of
    /// [`Skin::components`]. Exact when all sources share one frequency (then it is one phasor's length);
    /// with several incommensurate frequencies it is the supremum the signal approaches over a long time.
    pub fn peak_amplitude_m_s2(&self, sources: &[WaveSource], point_m: DVec2) -> f64 {
        self.components(sources, point_m).iter().map(|c| c.amplitude_m_s2).sum()
    }

    /// Time of the first crest (local maximum) of one source's wave at distance `distance_m` after the crest
    /// found at `after_s`, by sampling at `sample_rate_hz` and refining the sampled maximum with a parabola
    /// through it and its neighbours (vertex offset `(y[-1] - y[1]) / (2 (y[-1] - 2 y[0] + y[1]))` samples).
    fn next_crest_s(
        self,
        source: &WaveSource,
        distance_m: f64,
        after_s: f64,
        sample_rate_hz: f64,
    ) -> Option<f64> {
        let dt = 1.0 / sample_rate_hz;
        let point = source.position_m + DVec2::new(distance_m, 0.0);
        let sample = |t: f64| self.wave_m_s2(source, point, t);
        // Search two periods; the crest after any instant lies within one.
        let steps = (2.0 * sample_rate_hz / source.frequency_hz).ceil() as usize + 2;
        let t0 = after_s + 0.5 * dt;
        let (mut prev, mut cur) = (sample(t0 - dt), sample(t0));
        for i in 0..steps {
            let t = t0 + (i as f64) * dt;
            let next = sample(t + dt);
            if cur > prev && cur >= next && cur > 0.0 {
                let denom = prev - 2.0 * cur + next;
                let offset = if denom.abs() > 0.0 { 0.5 * (prev - next) / denom } else { 0.0 };
                return Some(t + offset * dt);
            }
            prev = cur;
            cur = next;
        }
        None
    }

    /// Arrival times of one crest of `source`'s wave at increasing `distances_m` (thesis Fig 59): the first
    /// crest after `t = 0` at the first distance, then at each next distance the first crest after the
    /// previous one. The crest is tracked correctly while consecutive distances are less than one wavelength
    /// apart, which is checked. The times come from traces sampled at `sample_rate_hz` (the thesis's 10 kHz),
    /// with parabolic refinement, so fitting distance against time ([`fit_wave_speed`]) is an independent
    /// check of `c`.
    pub fn arrival_times_s(
        &self,
        source: &WaveSource,
        distances_m: &[f64],
        sample_rate_hz: f64,
    ) -> Result<Vec<f64>, WaveError> {
        if sample_rate_hz.is_nan() || sample_rate_hz <= 4.0 * source.frequency_hz {
            return Err(WaveError::OutOfRange {
                name: "sample_rate_hz",
                expected: "more than 4x the source frequency",
                value: sample_rate_hz,
            });
        }
        let lambda = self.wavelength_m(source.frequency_hz);
        let mut times = Vec::with_capacity(distances_m.len());
        let mut after = 0.0;
        let mut last_d: Option<f64> = None;
        for &d in distances_m {
            if let Some(prev) = last_d
                && !(d > prev && d - prev < lambda)
            {
                return Err(WaveError::OutOfRange {
                    name: "distance step",
                    expected: "increasing by less than one wavelength",
                    value: d - prev,
                });
            }
            let t = self
                .next_crest_s(source, d, after, sample_rate_hz)
                .ok_or(WaveError::NoCrest { distance_m: d })?;
            times.push(t);
            after = t;
            last_d = Some(d);
        }
        Ok(times)
    }
}

/// Wave speed from arrival times (thesis Fig 59): least-squares line `distance = d0 + c * t`, slope = speed.
pub fn fit_wave_speed(arrival_s: &[f64], distance_m: &[f64]) -> Result<LineFit, WaveError> {
    Ok(fit_line(arrival_s, distance_m)?)
}

/// One sinusoid `A sin(w t + c)` of a signal.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sinusoid {
    /// Amplitude `A` [m/s^2].
    pub amplitude_m_s2: f64,
    /// Angular frequency `w` [rad/s].
    pub omega_rad_s: f64,
    /// Phase `c` \[rad\], in (-pi, pi].
    pub phase_rad: f64,
}

impl Sinusoid {
    /// Value at time `t_s`.
    pub fn at(&self, t_s: f64) -> f64 {
        self.amplitude_m_s2 * (self.omega_rad_s * t_s + self.phase_rad).sin()
    }
}

/// A vibrating tactor on the skin.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WaveSource {
    /// Position on the skin plane \[m\].
    pub position_m: DVec2,
    /// Amplitude at the tactor, `a0` [m/s^2].
    pub amplitude_m_s2: f64,
    /// Gaussian width `b` of the fall-off \[m\].
    pub width_m: f64,
    /// Vibration frequency \[Hz\].
    pub frequency_hz: f64,
    /// Phase `phi` \[rad\] added to the wave's argument.
    pub phase_rad: f64,
}

impl WaveSource {
    /// The thesis's measured travelling-wave tactor (a0 = 26.02 m/s^2, b = 28.18 mm, 70.4 Hz, phase 0) at
    /// `position_m`.
    pub fn measured(position_m: DVec2) -> Self {
        Self {
            position_m,
            amplitude_m_s2: MEASURED_A0_M_S2,
            width_m: MEASURED_WIDTH_M,
            frequency_hz: MEASURED_FREQUENCY_HZ,
            phase_rad: 0.0,
        }
    }

    /// A source on the x axis (for 1-D problems).
    pub fn on_line(x_m: f64, amplitude_m_s2: f64, width_m: f64, frequency_hz: f64, phase_rad: f64) -> Self {
        Self { position_m: DVec2::new(x_m, 0.0), amplitude_m_s2, width_m, frequency_hz, phase_rad }
    }

    /// The same source with its amplitude multiplied by `factor`.
    #[must_use]
    pub fn scaled(self, factor: f64) -> Self {
        Self { amplitude_m_s2: self.amplitude_m_s2 * factor, ..self }
    }

    /// The Gaussian envelope `a0 exp(-(r/b)^2)` of this source at `point_m` [m/s^2].
    pub fn envelope_m_s2(&self, point_m: DVec2) -> f64 {
        GaussianAttenuation { a0_m_s2: self.amplitude_m_s2, width_m: self.width_m }
            .amplitude_m_s2(point_m.distance(self.position_m))
    }
}

/// Position of tactor `index` on the vest plane \[m\], grid spacing `spacing_m` centre to centre.
///
/// Numbering as in [`crate::vest`] (seen from behind, row-major from the top-left). The plane's origin is the
/// grid centre, x points to the wearer's right (column 0 at `x = -1.5 s`), y points up (row 0 at `y = +1.5
/// s`). `None` for an index outside the grid.
pub fn tactor_position_m(index: usize, spacing_m: f64) -> Option<DVec2> {
    if index >= TACTOR_COUNT {
        return None;
    }
    let half = (GRID as f64 - 1.0) / 2.0;
    let (row, col) = ((index / GRID) as f64, (index % GRID) as f64);
    Some(DVec2::new((col - half) * spacing_m, (half - row) * spacing_m))
}

/// One source per tactor in `mask`, each a copy of `template` moved to its grid position.
pub fn vest_sources(mask: TactorMask, spacing_m: f64, template: &WaveSource) -> Vec<WaveSource> {
    mask.indices()
        .filter_map(|i| tactor_position_m(i, spacing_m))
        .map(|position_m| WaveSource { position_m, ..*template })
        .collect()
}

/// The two-tactor midpoint experiment (thesis §4.1.3): two tactors `separation_m` apart, the signal halfway.
///
/// The thesis predicted `3.02 sin(334.3 t + c1) + 3.45 sin(444.8 t + c2)` (fitted: 2.43 and 2.76). The two
/// tactors ran at different frequencies, 334.3 rad/s = 53.2 Hz and 444.8 rad/s = 70.8 Hz, so the midpoint
/// signal has one component per tactor, each of amplitude `a0 exp(-(s/2 / b)^2)`. At 40 mm: `a0 = 26.02`, `b
/// = 28.18 mm` gives 3.47 (the 70.8 Hz term, 3.45), `a0 = 9`, `b = 38.4 mm` gives 3.04 (the 53.2 Hz term,
/// 3.02); exactly 3.45 and 3.02 need a0 = 25.87 and 8.94 with those widths, i.e. the Fig 52 tactors' own
/// amplitudes.
pub fn midpoint_components(skin: &Skin, left: &WaveSource, right: &WaveSource) -> Vec<Sinusoid> {
    let mid = (left.position_m + right.position_m) / 2.0;
    skin.components(&[*left, *right], mid)
}

/// The thesis's midpoint pair: tactor 1 (a0 = 9 m/s^2, b = 38.4 mm, 53.2 Hz) at x = 0 and tactor 2
/// (a0 = 26.02 m/s^2, b = 28.18 mm, 70.8 Hz) at `x = separation_m`; see [`midpoint_components`].
pub fn thesis_midpoint_pair(separation_m: f64) -> (WaveSource, WaveSource) {
    (
        WaveSource::on_line(0.0, FIG52_A0_M_S2[1], FIG52_WIDTHS_M[1], 334.3 / TAU, 0.0),
        WaveSource::on_line(separation_m, MEASURED_A0_M_S2, MEASURED_WIDTH_M, 444.8 / TAU, 0.0),
    )
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    use super::*;

    #[test]
    fn measured_constants_agree() {
        // lambda = c / f: 3.023 / 42.94 mm = 70.4 Hz (thesis).
        assert_relative_eq!(MEASURED_FREQUENCY_HZ, 70.4, max_relative = 1e-3);
        assert_relative_eq!(Skin::MEASURED.wavelength_m(MEASURED_FREQUENCY_HZ), MEASURED_WAVELENGTH_M);
    }

    #[test]
    fn spacing_rule_closed_form() {
        // exp(-(d/b)^2) = 0.1 at d = b sqrt(ln 10) = 1.517427 b.
        let d = spacing_for_fraction_m(0.0362, 0.1).unwrap();
        assert_relative_eq!(d, 0.0362 * 10f64.ln().sqrt(), max_relative = 1e-12);
        let g = GaussianAttenuation { a0_m_s2: 10.0, width_m: 0.0362 };
        assert_relative_eq!(g.amplitude_m_s2(d), 1.0, max_relative = 1e-12);
        assert!(spacing_for_fraction_m(0.0362, 0.0).is_err());
        assert!(spacing_for_fraction_m(0.0362, 1.0).is_err());
        assert!(spacing_for_fraction_m(-1.0, 0.5).is_err());
    }

    #[test]
    fn travelling_wave_matches_thesis_formula() {
        // a = a0 exp(-(x/b)^2) sin(2 pi / lambda (x - c t)) for x >= 0 on the x axis.
        let skin = Skin::MEASURED;
        let s = WaveSource::measured(DVec2::ZERO);
        for (x, t) in [(0.0, 0.001), (0.02, 0.0037), (0.037, 0.011), (0.052, 0.02)] {
            let expected = MEASURED_A0_M_S2
                * (-(x / MEASURED_WIDTH_M).powi(2)).exp()
                * (TAU / MEASURED_WAVELENGTH_M * (x - MEASURED_SPEED_M_S * t)).sin();
            let got = skin.wave_m_s2(&s, DVec2::new(x, 0.0), t);
            assert_relative_eq!(got, expected, epsilon = 1e-9, max_relative = 1e-9);
        }
    }

    #[test]
    fn midpoint_amplitudes_reproduce_thesis_prediction() {
        let (left, right) = thesis_midpoint_pair(0.080);
        let c = midpoint_components(&Skin::MEASURED, &left, &right);
        assert_eq!(c.len(), 2);
        assert_relative_eq!(c[0].omega_rad_s, 334.3, max_relative = 1e-12);
        assert_relative_eq!(c[1].omega_rad_s, 444.8, max_relative = 1e-12);
        // 9 exp(-(40/38.4)^2) = 3.0409 and 26.02 exp(-(40/28.18)^2) = 3.4696 (thesis 3.02 and 3.45).
        assert_relative_eq!(c[0].amplitude_m_s2, 3.02, max_relative = 0.01);
        assert_relative_eq!(c[1].amplitude_m_s2, 3.45, max_relative = 0.01);
        // The components reproduce the summed field at any time.
        let mid = DVec2::new(0.04, 0.0);
        for t in [0.0, 0.0013, 0.0271] {
            let sum: f64 = c.iter().map(|s| s.at(t)).sum();
            assert_relative_eq!(sum, Skin::MEASURED.field_m_s2(&[left, right], mid, t), epsilon = 1e-12);
        }
    }

    #[test]
    fn equal_frequency_phasors_add() {
        // Two in-phase equal sources at the same distance double; half a wavelength apart in path they
        // cancel.
        let skin = Skin::MEASURED;
        let f = MEASURED_FREQUENCY_HZ;
        let lambda = skin.wavelength_m(f);
        let a = WaveSource::on_line(-0.01, 5.0, 0.03, f, 0.0);
        let b = WaveSource::on_line(0.01, 5.0, 0.03, f, 0.0);
        let p = DVec2::ZERO;
        assert_relative_eq!(
            skin.peak_amplitude_m_s2(&[a, b], p),
            2.0 * a.envelope_m_s2(p),
            max_relative = 1e-12
        );
        let b_opposite = WaveSource { phase_rad: PI, ..b };
        assert!(skin.peak_amplitude_m_s2(&[a, b_opposite], p) < 1e-12);
        // Same source a whole wavelength further away: the phases agree again (same sign, smaller envelope).
        let shifted = WaveSource::on_line(-0.01 - lambda, 5.0, 0.03, f, 0.0);
        let t = 0.0042;
        let ratio = skin.wave_m_s2(&shifted, p, t) / skin.wave_m_s2(&a, p, t);
        assert_relative_eq!(ratio, shifted.envelope_m_s2(p) / a.envelope_m_s2(p), max_relative = 1e-9);
    }

    #[test]
    fn vest_positions_follow_numbering() {
        let s = 0.06;
        assert_eq!(tactor_position_m(0, s), Some(DVec2::new(-0.09, 0.09)));
        assert_eq!(tactor_position_m(3, s), Some(DVec2::new(0.09, 0.09)));
        assert_eq!(tactor_position_m(12, s), Some(DVec2::new(-0.09, -0.09)));
        assert_eq!(tactor_position_m(16, s), None);
        let src = vest_sources(TactorMask::CORNERS, s, &WaveSource::measured(DVec2::ZERO));
        assert_eq!(src.len(), 4);
    }

    #[test]
    fn arrival_times_give_wave_speed() {
        let skin = Skin::MEASURED;
        let s = WaveSource::measured(DVec2::ZERO);
        let d = [0.0, 0.02, 0.037, 0.052];
        let t = skin.arrival_times_s(&s, &d, 10_000.0).unwrap();
        let fit = fit_wave_speed(&t, &d).unwrap();
        assert_relative_eq!(fit.slope, MEASURED_SPEED_M_S, max_relative = 1e-3);
        // Steps of a wavelength or more are refused: the crest could not be tracked.
        assert!(skin.arrival_times_s(&s, &[0.0, 0.05], 10_000.0).is_err());
    }

    #[test]
    fn attenuation_fit_recovers_parameters() {
        for (a0, b) in FIG52_A0_M_S2.iter().zip(FIG52_WIDTHS_M) {
            let g = GaussianAttenuation { a0_m_s2: *a0, width_m: b };
            let d: Vec<f64> = (0..12).map(|k| f64::from(k) * 0.008).collect();
            let a: Vec<f64> = d.iter().map(|x| g.amplitude_m_s2(*x)).collect();
            let fit = fit_attenuation(&d, &a).unwrap();
            assert_relative_eq!(fit.model.a0_m_s2, *a0, max_relative = 1e-8);
            assert_relative_eq!(fit.model.width_m, b, max_relative = 1e-8);
            assert_relative_eq!(fit.r2, 1.0, epsilon = 1e-12);
        }
        assert!(fit_attenuation(&[0.0], &[1.0]).is_err());
    }

    fn arb_source() -> impl Strategy<Value = WaveSource> {
        (-0.1..0.1f64, -0.1..0.1f64, 0.1..30.0f64, 0.01..0.05f64, 40.0..200.0f64, -3.0..3.0f64).prop_map(
            |(x, y, a, b, f, phi)| WaveSource {
                position_m: DVec2::new(x, y),
                amplitude_m_s2: a,
                width_m: b,
                frequency_hz: f,
                phase_rad: phi,
            },
        )
    }

    proptest! {
        #[test]
        fn superposition_is_linear(
            s1 in prop::collection::vec(arb_source(), 1..5),
            s2 in prop::collection::vec(arb_source(), 1..5),
            k in -3.0..3.0f64,
            px in -0.1..0.1f64, py in -0.1..0.1f64, t in 0.0..0.1f64,
        ) {
            let skin = Skin::MEASURED;
            let p = DVec2::new(px, py);
            let mut combined: Vec<WaveSource> = s1.iter().map(|s| s.scaled(k)).collect();
            combined.extend(&s2);
            let lhs = skin.field_m_s2(&combined, p, t);
            let rhs = k * skin.field_m_s2(&s1, p, t) + skin.field_m_s2(&s2, p, t);
            prop_assert!((lhs - rhs).abs() <= 1e-9 * (1.0 + lhs.abs()));
        }

        #[test]
        fn attenuation_is_monotone(a0 in 0.1..50.0f64, b in 0.005..0.1f64, d1 in 0.0..0.3f64, step in 1e-6..0.1f64) {
            let g = GaussianAttenuation { a0_m_s2: a0, width_m: b };
            prop_assert!(g.amplitude_m_s2(d1 + step) <= g.amplitude_m_s2(d1));
            prop_assert!(g.amplitude_m_s2(d1) <= a0);
        }

        #[test]
        fn peak_amplitude_bounds_the_field(s in prop::collection::vec(arb_source(), 1..5),
                                           px in -0.1..0.1f64, t in 0.0..0.1f64) {
            let skin = Skin::MEASURED;
            let p = DVec2::new(px, 0.0);
            prop_assert!(skin.field_m_s2(&s, p, t).abs() <= skin.peak_amplitude_m_s2(&s, p) * (1.0 + 1e-12) + 1e-12);
        }
    }
}
