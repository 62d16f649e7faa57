//! Skin waves (thesis §4.1.3): Fig 52 (attenuation), Fig 57 (travelling wave), Fig 59 (arrival times), the
//! superposed field on the vest, and the midpoint of two tactors; each a result type serialised as the JSON
//! of `vestnav sim wave --view ... --json`, with its figure.

use std::f64::consts::TAU;

use serde::{Deserialize, Serialize};
use vestnav_core::vest::{TACTOR_COUNT, TactorMask};
use vestnav_core::wave::{
    self, DVec2, FIG52_A0_M_S2, FIG52_WIDTHS_M, GaussianAttenuation, Sinusoid, Skin, WaveError, WaveSource,
};
use vestnav_plot::{Chart, Color, Figure, Heatmap, Marker, Series};

use crate::series::linspace;

/// Centre-to-centre spacing of the vest's tactors in the figures and the console [mm]. The spacing rule
/// (a neighbour below 10 % of its source, physics.md §2) asks `b sqrt(ln 10)`: 55.0 mm for the mean measured
/// width b = 36.2 mm, 42.8 mm for the travelling wave's 28.18 mm; 60 mm satisfies both.
pub const DEFAULT_VEST_SPACING_MM: f64 = 60.0;
/// Distances from the tactor of Figs 57 and 59 [mm].
pub const THESIS_DISTANCES_MM: [f64; 4] = [0.0, 20.0, 37.0, 52.0];
/// Default window of the travelling-wave figure [s].
pub const DEFAULT_TRAVELLING_S: f64 = 0.05;
/// Default window of the midpoint figure [s].
pub const DEFAULT_MIDPOINT_S: f64 = 0.1;
/// Default separation of the midpoint pair [mm] (the thesis's 80 mm).
pub const DEFAULT_SEPARATION_MM: f64 = 80.0;
/// Sampling rate of the time traces [Hz] (the thesis's 10 kHz).
const TRACE_RATE_HZ: f64 = 10_000.0;
/// Grid nodes per side of the vest field.
pub const FIELD_NODES: usize = 121;

/// Samples of `0..=duration_s` from `t0_s` at the trace rate (at least 2, at most 100 001).
fn trace_times(t0_s: f64, duration_s: f64) -> Vec<f64> {
    let n = ((duration_s * TRACE_RATE_HZ).round() as usize + 1).clamp(2, 100_001);
    linspace(t0_s, t0_s + duration_s, n)
}

// ------------------------------------------------------------------------------------------------------------
// Fig 52

/// One measured tactor's attenuation curve.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AttenuationCurve {
    /// Amplitude at the tactor [m/s^2].
    pub a0_m_s2: f64,
    /// Gaussian width b [mm].
    pub width_mm: f64,
    /// Distance where the amplitude falls to the fraction [mm].
    pub spacing_mm: f64,
    /// `a0 exp(-(d/b)^2)` at each of the report's distances [m/s^2].
    pub amplitude_m_s2: Vec<f64>,
}

/// Fig 52: amplitude against distance for the three measured tactors, and the spacing rule.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Attenuation {
    /// The rule's fraction of the source amplitude.
    pub fraction: f64,
    /// Distances from the tactor [mm].
    pub distance_mm: Vec<f64>,
    /// The three tactors.
    pub tactors: Vec<AttenuationCurve>,
    /// Mean width [mm].
    pub mean_width_mm: f64,
    /// The rule's spacing for the mean width, `b sqrt(ln(1/fraction))` [mm].
    pub mean_spacing_mm: f64,
}

impl Attenuation {
    /// The three tactors of Fig 52 over 0..120 mm and the spacing rule at `fraction`.
    pub fn compute(fraction: f64) -> Result<Self, WaveError> {
        let distance_mm = linspace(0.0, 120.0, 241);
        let tactors = FIG52_A0_M_S2
            .iter()
            .zip(FIG52_WIDTHS_M)
            .map(|(a0, b)| {
                let g = GaussianAttenuation { a0_m_s2: *a0, width_m: b };
                Ok(AttenuationCurve {
                    a0_m_s2: *a0,
                    width_mm: b * 1e3,
                    spacing_mm: g.distance_for_fraction_m(fraction)? * 1e3,
                    amplitude_m_s2: distance_mm.iter().map(|d| g.amplitude_m_s2(d * 1e-3)).collect(),
                })
            })
            .collect::<Result<Vec<_>, WaveError>>()?;
        let mean_b = FIG52_WIDTHS_M.iter().sum::<f64>() / FIG52_WIDTHS_M.len() as f64;
        let mean_spacing = wave::spacing_for_fraction_m(mean_b, fraction)?;
        Ok(Self {
            fraction,
            distance_mm,
            tactors,
            mean_width_mm: mean_b * 1e3,
            mean_spacing_mm: mean_spacing * 1e3,
        })
    }

    /// Fig 52 with each tactor's rule distance marked and the mean width's spacing as a vertical line.
    pub fn figure(&self) -> Figure {
        let mut chart = Chart::new(format!(
            "Fig 52: amplitude versus distance (dashed: {:.0} % spacing rule for the mean b = {:.1} mm: {:.1} mm)",
            self.fraction * 100.0,
            self.mean_width_mm,
            self.mean_spacing_mm
        ))
        .x_label("distance from the tactor d [mm]")
        .y_label("acceleration amplitude [m/s^2]");
        for (i, t) in self.tactors.iter().enumerate() {
            let label = format!(
                "a0 = {} m/s^2, b = {:.2} mm ({:.0} % at {:.1} mm)",
                t.a0_m_s2,
                t.width_mm,
                self.fraction * 100.0,
                t.spacing_mm
            );
            chart = chart
                .series(
                    Series::line(label, self.distance_mm.clone(), t.amplitude_m_s2.clone())
                        .width(2.0)
                        .color(Color::palette(i)),
                )
                .series(
                    Series::scatter("", vec![t.spacing_mm], vec![t.a0_m_s2 * self.fraction])
                        .marker(Marker::Circle)
                        .color(Color::palette(i)),
                );
        }
        Figure::single(chart.vline(self.mean_spacing_mm, ""))
    }
}

// ------------------------------------------------------------------------------------------------------------
// Fig 57

/// Fig 57: one source's travelling wave `a0 exp(-(x/b)^2) sin(2 pi/lambda (x - c t))` at several distances.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Travelling {
    /// Frequency [Hz].
    pub frequency_hz: f64,
    /// Wave speed [m/s].
    pub speed_m_s: f64,
    /// `lambda = c / f` [mm].
    pub wavelength_mm: f64,
    /// Distances [mm].
    pub distance_mm: Vec<f64>,
    /// Envelope `a0 exp(-(x/b)^2)` at each distance [m/s^2].
    pub envelope_m_s2: Vec<f64>,
    /// Phase lag `2 pi x / lambda` [rad].
    pub phase_lag_rad: Vec<f64>,
    /// Delay `x / c` [s].
    pub delay_s: Vec<f64>,
    /// Sample times [s].
    pub time_s: Vec<f64>,
    /// The wave at each distance (one row per distance) [m/s^2].
    pub acceleration_m_s2: Vec<Vec<f64>>,
}

impl Travelling {
    /// The wave of `source` (at the origin) on `skin` at `distances_mm` over `t0_s..t0_s + duration_s`.
    pub fn compute(
        skin: &Skin,
        source: &WaveSource,
        distances_mm: &[f64],
        t0_s: f64,
        duration_s: f64,
    ) -> Self {
        let time_s = trace_times(t0_s, duration_s);
        let at = |d_mm: f64| source.position_m + DVec2::new(d_mm * 1e-3, 0.0);
        let k = TAU * source.frequency_hz / skin.speed_m_s;
        Self {
            frequency_hz: source.frequency_hz,
            speed_m_s: skin.speed_m_s,
            wavelength_mm: skin.wavelength_m(source.frequency_hz) * 1e3,
            distance_mm: distances_mm.to_vec(),
            envelope_m_s2: distances_mm.iter().map(|d| source.envelope_m_s2(at(*d))).collect(),
            phase_lag_rad: distances_mm.iter().map(|d| k * d * 1e-3).collect(),
            delay_s: distances_mm.iter().map(|d| d * 1e-3 / skin.speed_m_s).collect(),
            acceleration_m_s2: distances_mm
                .iter()
                .map(|d| time_s.iter().map(|t| skin.wave_m_s2(source, at(*d), *t)).collect())
                .collect(),
            time_s,
        }
    }

    /// The chart of Fig 57 (time in ms).
    pub fn chart(&self) -> Chart {
        let t_ms: Vec<f64> = self.time_s.iter().map(|v| v * 1e3).collect();
        let mut chart = Chart::new("Fig 57: acceleration at several distances from the tactor (phase lag)")
            .x_label("time [ms]")
            .y_label("acceleration [m/s^2]");
        for (d, trace) in self.distance_mm.iter().zip(&self.acceleration_m_s2) {
            chart =
                chart.series(Series::line(format!("x = {d:.0} mm"), t_ms.clone(), trace.clone()).width(1.8));
        }
        chart
    }

    /// Fig 57 alone.
    pub fn figure(&self) -> Figure {
        Figure::single(self.chart())
    }
}

// ------------------------------------------------------------------------------------------------------------
// Fig 59

/// Fig 59: arrival time of a crest against distance; the slope of distance against time is the wave speed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Arrival {
    /// Distances [mm].
    pub distance_mm: Vec<f64>,
    /// Crest arrival time at each distance (10 kHz traces) [s].
    pub arrival_s: Vec<f64>,
    /// Fitted speed, the slope of distance against time [m/s].
    pub speed_m_s: f64,
    /// Intercept of the line [mm].
    pub intercept_mm: f64,
    /// Coefficient of determination.
    pub r2: f64,
    /// The model's speed [m/s].
    pub model_speed_m_s: f64,
}

impl Arrival {
    /// Arrival times of `source`'s crests on `skin` at `distances_mm` and the fitted speed.
    pub fn compute(skin: &Skin, source: &WaveSource, distances_mm: &[f64]) -> Result<Self, WaveError> {
        let distances_m: Vec<f64> = distances_mm.iter().map(|d| d * 1e-3).collect();
        let arrival_s = skin.arrival_times_s(source, &distances_m, TRACE_RATE_HZ)?;
        let fit = wave::fit_wave_speed(&arrival_s, &distances_m)?;
        Ok(Self {
            distance_mm: distances_mm.to_vec(),
            arrival_s,
            speed_m_s: fit.slope,
            intercept_mm: fit.intercept * 1e3,
            r2: fit.r2,
            model_speed_m_s: skin.speed_m_s,
        })
    }

    /// Fig 59 with the fitted line.
    pub fn figure(&self) -> Figure {
        let t_ms: Vec<f64> = self.arrival_s.iter().map(|v| v * 1e3).collect();
        let (lo, hi) = (t_ms.first().copied().unwrap_or(0.0), t_ms.last().copied().unwrap_or(1.0));
        let line_t = vec![lo, hi];
        let line_d: Vec<f64> = line_t.iter().map(|t| self.intercept_mm + self.speed_m_s * t).collect();
        let chart =
            Chart::new(format!("Fig 59: distance versus arrival time, slope c = {:.3} m/s", self.speed_m_s))
                .x_label("arrival time of the crest [ms]")
                .y_label("distance from the tactor [mm]")
                .series(
                    Series::scatter("crest arrival (10 kHz traces)", t_ms, self.distance_mm.clone())
                        .marker(Marker::Circle),
                )
                .series(
                    Series::line(
                        format!("fit: c = {:.3} m/s, R^2 = {:.4}", self.speed_m_s, self.r2),
                        line_t,
                        line_d,
                    )
                    .dashed(),
                );
        Figure::single(chart)
    }
}

// ------------------------------------------------------------------------------------------------------------
// The vest field

/// What the vest field is computed for.
#[derive(Debug, Clone, PartialEq)]
pub struct VestFieldInputs {
    /// Firing tactors (vest numbering, row-major from the wearer's upper left, seen from behind).
    pub tactors: Vec<usize>,
    /// Centre-to-centre spacing [mm].
    pub spacing_mm: f64,
    /// Every tactor's wave (amplitude, width, frequency; its position is replaced per tactor).
    pub source: WaveSource,
    /// The skin.
    pub skin: Skin,
    /// Time of the snapshot [s].
    pub time_s: f64,
}

impl Default for VestFieldInputs {
    /// Tactor 5 at 60 mm spacing with the measured travelling wave, snapshot at 0 s.
    fn default() -> Self {
        Self {
            tactors: vec![5],
            spacing_mm: DEFAULT_VEST_SPACING_MM,
            source: WaveSource::measured(DVec2::ZERO),
            skin: Skin::MEASURED,
            time_s: 0.0,
        }
    }
}

/// The field at one tactor's position.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TactorPoint {
    /// Tactor index.
    pub tactor: usize,
    /// Whether it fires.
    pub firing: bool,
    /// Position, to the wearer's right [mm].
    pub x_mm: f64,
    /// Position, up [mm].
    pub y_mm: f64,
    /// Peak amplitude of the superposed waves there [m/s^2].
    pub peak_m_s2: f64,
}

/// The field on a square grid of nodes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FieldGrid {
    /// Node coordinates along both axes [mm].
    pub axis_mm: Vec<f64>,
    /// Peak amplitude over time, row-major (row = y) [m/s^2].
    pub peak_m_s2: Vec<f64>,
    /// Acceleration at the snapshot time, row-major [m/s^2].
    pub snapshot_m_s2: Vec<f64>,
}

/// The superposed travelling waves of the firing tactors on the vest plane.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VestField {
    /// Firing tactors.
    pub tactors: Vec<usize>,
    /// Spacing [mm].
    pub spacing_mm: f64,
    /// Frequency [Hz].
    pub frequency_hz: f64,
    /// Amplitude of each source [m/s^2].
    pub amplitude_m_s2: f64,
    /// Gaussian width of each source [mm].
    pub width_mm: f64,
    /// Wave speed [m/s].
    pub speed_m_s: f64,
    /// Snapshot time [s].
    pub time_s: f64,
    /// The spacing rule for this width (neighbour below 10 %) [mm].
    pub spacing_rule_mm: f64,
    /// The field at every tactor.
    pub at_tactors: Vec<TactorPoint>,
    /// The field over the grid plus one spacing of margin.
    pub grid: FieldGrid,
}

impl VestField {
    /// Superposes the sources (linearly, physics.md §2) on a grid of [`FIELD_NODES`] nodes per side over the
    /// 4x4 grid plus one spacing of margin.
    pub fn compute(i: &VestFieldInputs) -> Result<Self, WaveError> {
        if let Some(bad) = i.tactors.iter().find(|t| **t >= TACTOR_COUNT) {
            return Err(WaveError::OutOfRange {
                name: "tactor",
                expected: "an index 0..16",
                value: *bad as f64,
            });
        }
        let mask = TactorMask::from_indices(i.tactors.iter().copied());
        let spacing_m = i.spacing_mm * 1e-3;
        let sources = wave::vest_sources(mask, spacing_m, &i.source);
        let half = 2.5 * spacing_m;
        let axis = linspace(-half, half, FIELD_NODES);
        let mut peak = Vec::with_capacity(FIELD_NODES * FIELD_NODES);
        let mut snap = Vec::with_capacity(FIELD_NODES * FIELD_NODES);
        for y in &axis {
            for x in &axis {
                let p = DVec2::new(*x, *y);
                peak.push(i.skin.peak_amplitude_m_s2(&sources, p));
                snap.push(i.skin.field_m_s2(&sources, p, i.time_s));
            }
        }
        let at_tactors = (0..TACTOR_COUNT)
            .filter_map(|k| wave::tactor_position_m(k, spacing_m).map(|p| (k, p)))
            .map(|(k, p)| TactorPoint {
                tactor: k,
                firing: mask.contains(k),
                x_mm: p.x * 1e3,
                y_mm: p.y * 1e3,
                peak_m_s2: i.skin.peak_amplitude_m_s2(&sources, p),
            })
            .collect();
        let rule = wave::spacing_for_fraction_m(i.source.width_m, wave::SPACING_RULE_FRACTION)?;
        Ok(Self {
            tactors: i.tactors.clone(),
            spacing_mm: i.spacing_mm,
            frequency_hz: i.source.frequency_hz,
            amplitude_m_s2: i.source.amplitude_m_s2,
            width_mm: i.source.width_m * 1e3,
            speed_m_s: i.skin.speed_m_s,
            time_s: i.time_s,
            spacing_rule_mm: rule * 1e3,
            at_tactors,
            grid: FieldGrid {
                axis_mm: axis.iter().map(|v| v * 1e3).collect(),
                peak_m_s2: peak,
                snapshot_m_s2: snap,
            },
        })
    }

    /// One line each: the sources, the spacing rule, and the share a neighbour receives.
    pub fn header(&self) -> Vec<String> {
        let neighbour = (-(self.spacing_mm / self.width_mm).powi(2)).exp();
        vec![
            format!(
                "firing tactors {:?}; spacing {} mm; a0 = {} m/s^2, b = {:.2} mm, f = {:.2} Hz, c = {} m/s",
                self.tactors,
                crate::sig(self.spacing_mm, 4),
                crate::sig(self.amplitude_m_s2, 4),
                self.width_mm,
                self.frequency_hz,
                crate::sig(self.speed_m_s, 4)
            ),
            format!("spacing rule (neighbour below 10 %): {:.2} mm", self.spacing_rule_mm),
            format!(
                "a neighbour at {} mm receives {:.1} % of its source",
                self.spacing_mm,
                neighbour * 100.0
            ),
        ]
    }

    /// Peak amplitude and the snapshot as two heat maps seen from behind, tactors marked (`*` = firing).
    pub fn figure(&self) -> Figure {
        let n = self.grid.axis_mm.len();
        let (lo, hi) = (
            self.grid.axis_mm.first().copied().unwrap_or(0.0),
            self.grid.axis_mm.last().copied().unwrap_or(0.0),
        );
        let cell = (hi - lo) / (n.max(2) - 1) as f64;
        let extent = (lo - cell / 2.0, hi + cell / 2.0);
        let points: Vec<(f64, f64, String)> = self
            .at_tactors
            .iter()
            .map(|t| (t.x_mm, t.y_mm, if t.firing { format!("{}*", t.tactor) } else { t.tactor.to_string() }))
            .collect();
        let map = |title: String, values: &[f64], unit: &str| {
            Heatmap::new(title, extent, extent, n, n, values.to_vec())
                .x_label("x, wearer's right [mm]")
                .y_label("y, up [mm]")
                .colorbar_label(unit)
                .equal_aspect()
                .points(points.clone())
        };
        Figure::new()
            .title(format!(
                "Vest field seen from behind: tactors {:?}, {:.0} mm spacing, {:.1} Hz",
                self.tactors, self.spacing_mm, self.frequency_hz
            ))
            .columns(2)
            .panel_size(560, 480)
            .push(map(
                "Peak amplitude of the superposed waves (* = firing)".to_string(),
                &self.grid.peak_m_s2,
                "peak |a| [m/s^2]",
            ))
            .push(map(
                format!("Snapshot of a(x, y) at t = {} s", self.time_s),
                &self.grid.snapshot_m_s2,
                "a [m/s^2]",
            ))
    }
}

// ------------------------------------------------------------------------------------------------------------
// Midpoint

/// One sinusoid `A sin(omega t + c)` as the thesis wrote it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ThesisComponent {
    /// Amplitude [m/s^2].
    pub amplitude_m_s2: f64,
    /// Angular frequency [rad/s].
    pub omega_rad_s: f64,
}

/// The signal halfway between two tactors running at different frequencies (thesis §4.1.3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Midpoint {
    /// Distance between the tactors [mm].
    pub separation_mm: f64,
    /// The two sources.
    pub sources: [WaveSource; 2],
    /// The sinusoids arriving at the midpoint.
    pub components: Vec<Sinusoid>,
    /// The thesis's prediction at 80 mm: `3.02 sin(334.3 t + c1) + 3.45 sin(444.8 t + c2)`.
    pub thesis_predicted: [ThesisComponent; 2],
    /// The amplitudes the thesis fitted to the measured midpoint signal [m/s^2].
    pub thesis_fitted_amplitudes_m_s2: [f64; 2],
}

impl Midpoint {
    /// The thesis's pair of sources `separation_mm` apart and their components at the midpoint.
    pub fn compute(skin: &Skin, separation_mm: f64) -> Self {
        let (left, right) = wave::thesis_midpoint_pair(separation_mm * 1e-3);
        Self {
            separation_mm,
            components: wave::midpoint_components(skin, &left, &right),
            sources: [left, right],
            thesis_predicted: [
                ThesisComponent { amplitude_m_s2: 3.02, omega_rad_s: 334.3 },
                ThesisComponent { amplitude_m_s2: 3.45, omega_rad_s: 444.8 },
            ],
            thesis_fitted_amplitudes_m_s2: [2.43, 2.76],
        }
    }

    /// Each component and their sum at the midpoint over `0..duration_s`.
    pub fn figure(&self, skin: &Skin, duration_s: f64) -> Figure {
        let t = trace_times(0.0, duration_s);
        let t_ms: Vec<f64> = t.iter().map(|v| v * 1e3).collect();
        let mid = (self.sources[0].position_m + self.sources[1].position_m) / 2.0;
        let total: Vec<f64> = t.iter().map(|ti| skin.field_m_s2(&self.sources, mid, *ti)).collect();
        let bound: f64 = self.components.iter().map(|c| c.amplitude_m_s2).sum::<f64>().max(1e-9);
        let mut chart =
            Chart::new(format!("Signal halfway between two tactors {:.0} mm apart", self.separation_mm))
                .x_label("time [ms]")
                .y_label("acceleration [m/s^2]")
                .y_range(-1.15 * bound, 1.8 * bound);
        for c in &self.components {
            let y: Vec<f64> = t.iter().map(|ti| c.at(*ti)).collect();
            chart = chart.series(
                Series::line(
                    format!("{:.2} sin({:.1} t + c)", c.amplitude_m_s2, c.omega_rad_s),
                    t_ms.clone(),
                    y,
                )
                .dashed(),
            );
        }
        Figure::single(chart.series(Series::line("sum at the midpoint", t_ms, total).width(2.0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn spacing_rule_is_b_sqrt_ln_ten() {
        let a = Attenuation::compute(0.1).unwrap();
        for t in &a.tactors {
            assert_relative_eq!(t.spacing_mm, t.width_mm * 10f64.ln().sqrt(), max_relative = 1e-12);
        }
        assert_relative_eq!(a.mean_width_mm, (28.18 + 38.4 + 42.13) / 3.0, max_relative = 1e-12);
        // The default vest spacing satisfies the rule for the mean width (55.0 mm).
        assert!(DEFAULT_VEST_SPACING_MM > a.mean_spacing_mm);
    }

    #[test]
    fn arrival_recovers_the_wave_speed_and_travelling_lags_by_x_over_c() {
        let skin = Skin::MEASURED;
        let source = WaveSource::measured(DVec2::ZERO);
        let a = Arrival::compute(&skin, &source, &THESIS_DISTANCES_MM).unwrap();
        assert_relative_eq!(a.speed_m_s, 3.023, max_relative = 1e-3);
        let t = Travelling::compute(&skin, &source, &THESIS_DISTANCES_MM, 0.0, 0.01);
        assert_relative_eq!(t.delay_s[3], 0.052 / 3.023, max_relative = 1e-12);
        assert_relative_eq!(t.wavelength_mm, 42.94, max_relative = 1e-9);
    }

    #[test]
    fn vest_field_json_round_trips_and_one_tactor_is_its_gaussian() {
        let f = VestField::compute(&VestFieldInputs::default()).unwrap();
        assert_eq!(f.grid.peak_m_s2.len(), FIELD_NODES * FIELD_NODES);
        let centre = &f.at_tactors[5];
        assert!(centre.firing);
        assert_relative_eq!(centre.peak_m_s2, 26.02, max_relative = 1e-12);
        let back: VestField = serde_json::from_str(&crate::to_json(&f).unwrap()).unwrap();
        assert_eq!(back.tactors, f.tactors);
        assert_relative_eq!(back.spacing_rule_mm, 28.18 * 10f64.ln().sqrt(), max_relative = 1e-9);
        assert!(
            VestField::compute(&VestFieldInputs { tactors: vec![16], ..VestFieldInputs::default() }).is_err()
        );
    }

    #[test]
    fn midpoint_matches_the_thesis_prediction() {
        let m = Midpoint::compute(&Skin::MEASURED, DEFAULT_SEPARATION_MM);
        assert_relative_eq!(m.components[0].amplitude_m_s2, 3.02, max_relative = 0.01);
        assert_relative_eq!(m.components[1].amplitude_m_s2, 3.45, max_relative = 0.01);
    }
}
