//! The damping sweep (thesis §3.2.2–3.2.3): Figs 35–38 and the JSON schema of `sim sweep`.

use serde::{Deserialize, Serialize};
use vestnav_core::fit::PowerLawFit;
use vestnav_core::sweep::{
    ExactInverse, InverseFit, SweepError, SweepOptions, SweepPoint, SweepResult, sweep,
};
use vestnav_core::tactor::{BodyMass, Preset, RADIUS_CAD_M, RADIUS_FITTED_M, TactorParams};
use vestnav_plot::{Chart, Color, Figure, Marker, Series};

use crate::series::linspace;
use crate::tactor::other_body;

/// The power law of the thesis's 207 measured trials, `f = 124.7 n^0.4839` (R^2 0.97; thesis §3.2.3, Fig 36).
pub const MEASURED_POWER_LAW: (f64, f64) = (124.7, 0.4839);
/// Force range over which the measured fit is drawn [N] (physics.md §4: 0.52–2.01 N over all mountings).
const MEASURED_FORCE_RANGE_N: (f64, f64) = (0.5, 2.0);
/// Points of each fitted curve.
const CURVE_POINTS: usize = 101;

const BLUE: Color = Color::rgb(0, 114, 178);
const RED: Color = Color::rgb(213, 94, 0);
const GREEN: Color = Color::rgb(0, 158, 115);
const BLACK: Color = Color::rgb(20, 20, 20);

/// The radius compared with in Fig 36: the other of the CAD (2.57 mm) and fitted (3.2 mm) radii.
pub fn other_radius_m(radius_m: f64) -> f64 {
    if (radius_m - RADIUS_CAD_M).abs() < 1e-9 { RADIUS_FITTED_M } else { RADIUS_CAD_M }
}

/// The sweeps behind Figs 35–38: the selected tactor, the other body mass (Fig 35), the other radius
/// (Fig 36) and the measured preset R = 67 ohm (Fig 37).
#[derive(Debug, Clone, PartialEq)]
pub struct SweepSet {
    /// The tactor asked for (its JSON is `sim sweep --json`).
    pub main: SweepResult,
    /// The other body mass.
    pub other_body: SweepResult,
    /// The other eccentric radius.
    pub other_radius: SweepResult,
    /// The measured preset.
    pub measured: SweepResult,
}

impl SweepSet {
    /// Runs the four sweeps of `params` (its damping is swept) over `options`.
    pub fn compute(params: &TactorParams, options: &SweepOptions) -> Result<Self, SweepError> {
        let main = sweep(params, options)?;
        let other_body = sweep(&params.with_body(other_body(params.body)), options)?;
        let other_radius = sweep(&params.with_radius(other_radius_m(params.radius_m)), options)?;
        let measured = if params.preset == Preset::Measured {
            main.clone()
        } else {
            let mut p = *params;
            p.preset = Preset::Measured;
            p.resistance_ohm = Preset::Measured.resistance_ohm();
            sweep(&p, options)?
        };
        Ok(Self { main, other_body, other_radius, measured })
    }
}

/// `f_rot = c0 + c1 i` with its units in the key names.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CurrentLine {
    /// `c0 = u / (2 pi Kt)` in the closed form [Hz].
    pub intercept_hz: f64,
    /// `c1 = -R / (2 pi Kt)` in the closed form [Hz/A].
    pub slope_hz_per_a: f64,
    /// Coefficient of determination.
    pub r2: f64,
}

/// JSON of one damping sweep (`vestnav sim sweep --json` and the console's sweep export).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepReport {
    /// Parameter preset.
    pub preset: Preset,
    /// Body mass.
    pub body: BodyMass,
    /// Parameters of the swept tactor.
    pub params: TactorParams,
    /// Range and resolution.
    pub options: SweepOptions,
    /// What the frequencies are.
    pub frequency: String,
    /// `f_rot = A n^B` over (force amplitude, `f_rot`) (Fig 35).
    pub power_law: PowerLawFit,
    /// `f_rot` against the mean current (Fig 37).
    pub current_line: CurrentLine,
    /// Exact closed-form inverse `b(f)`.
    pub exact_inverse: ExactInverse,
    /// The thesis's 4-parameter inverse fitted to the points (Fig 38).
    pub inverse_fit: InverseFit,
    /// The simulated points.
    pub points: Vec<SweepPoint>,
}

impl SweepReport {
    /// The report of one sweep.
    pub fn new(r: &SweepResult) -> Self {
        Self {
            preset: r.params.preset,
            body: r.params.body,
            params: r.params,
            options: r.options,
            frequency: "f_rot: simulated mean speed / 2 pi over the last half of each run".to_string(),
            power_law: r.power_law,
            current_line: CurrentLine {
                intercept_hz: r.current_line.intercept,
                slope_hz_per_a: r.current_line.slope,
                r2: r.current_line.r2,
            },
            exact_inverse: r.exact_inverse,
            inverse_fit: r.inverse_fit,
            points: r.points.clone(),
        }
    }
}

/// The fits of each sweep, one line each (the CSV header).
pub fn header(set: &SweepSet) -> Vec<String> {
    [&set.main, &set.other_body, &set.other_radius, &set.measured]
        .into_iter()
        .map(|r| {
            let inv = &r.inverse_fit;
            format!(
                "{} ({} preset, u = {} V, {} points {}..{} Hz): f = {:.3} n^{:.5} (R^2 {:.5}); f = {:.3} {:+.3} i \
                 (R^2 {:.6}); b = {:.4e} (f {:+.4})^{:.5} {:+.4e} (max rel. residual {:.2e})",
                name(r),
                r.params.preset.name(),
                r.params.voltage_v,
                r.points.len(),
                r.options.min_hz,
                r.options.max_hz,
                r.power_law.coefficient,
                r.power_law.exponent,
                r.power_law.r2,
                r.current_line.intercept,
                r.current_line.slope,
                r.current_line.r2,
                inv.p1,
                inv.p2,
                inv.p3,
                inv.p4,
                inv.max_rel_residual
            )
        })
        .collect()
}

fn name(r: &SweepResult) -> String {
    format!("{}, l = {} mm", r.params.body.name(), crate::sig(r.params.radius_m * 1e3, 4))
}

fn xy(r: &SweepResult, fx: fn(&SweepPoint) -> f64) -> (Vec<f64>, Vec<f64>) {
    r.points.iter().map(|p| (fx(p), p.f_rot_hz)).unzip()
}

/// The sweep's power law over its force range.
fn fit_curve(r: &SweepResult) -> (Vec<f64>, Vec<f64>) {
    let lo = r.points.iter().map(|p| p.force_amplitude_n).fold(f64::INFINITY, f64::min);
    let hi = r.points.iter().map(|p| p.force_amplitude_n).fold(0.0, f64::max);
    let x = linspace(lo, hi, CURVE_POINTS);
    let y = x.iter().map(|n| r.power_law.eval(*n)).collect();
    (x, y)
}

/// Fig 38: simulated (f, b) points, the exact inverse `b = (Kt u/(2 pi f) - Kt^2)/R` and the fitted
/// 4-parameter inverse, in units of 1e-8 N m s.
fn calibration_chart(base: &SweepResult) -> Chart {
    let (f, b): (Vec<f64>, Vec<f64>) =
        base.points.iter().map(|p| (p.f_rot_hz, p.damping_n_m_s * 1e8)).unzip();
    let grid = linspace(base.options.min_hz, base.options.max_hz, CURVE_POINTS);
    let inv = base.inverse_fit;
    Chart::new("Fig 38: damping vs peak frequency (calibration curve)")
        .x_label("f_rot [Hz]")
        .y_label("b [1e-8 N m s]")
        .series(Series::scatter("simulated", f, b).color(BLUE))
        .series(
            Series::line(
                "exact b = (Kt u/(2 pi f) - Kt^2)/R",
                grid.clone(),
                grid.iter().map(|f| base.exact_inverse.eval(*f) * 1e8).collect(),
            )
            .color(GREEN),
        )
        .series(
            Series::line(
                format!(
                    "fit p1 (f{:+.3})^{:.4} + p4, max err {:.3}%",
                    inv.p2,
                    inv.p3,
                    inv.max_rel_residual * 100.0
                ),
                grid.clone(),
                grid.iter().map(|f| inv.eval(*f) * 1e8).collect(),
            )
            .color(RED)
            .dashed(),
        )
}

/// The thesis's Figs 35–38: what `vestnav sim sweep --png` writes and the console's sweep view shows and
/// exports.
///
/// Fig 35 frequency against force for both body masses with their power laws; Fig 36 the model curves of both
/// radii over the measured trials' fit `f = 124.7 n^0.4839`; Fig 37 frequency against the steady current for
/// the measured preset with the line `f = c0 + c1 i`; Fig 38 the calibration curve.
pub fn sweep_figure(set: &SweepSet) -> Figure {
    let law = |r: &SweepResult| {
        format!(
            "fit f = {:.1} n^{:.4} (R2 {:.5})",
            r.power_law.coefficient, r.power_law.exponent, r.power_law.r2
        )
    };
    let (base, other) = (&set.main, &set.other_body);
    let (xa, ya) = xy(base, |p| p.force_amplitude_n);
    let (xb, yb) = xy(other, |p| p.force_amplitude_n);
    let (fa, fya) = fit_curve(base);
    let (fb, fyb) = fit_curve(other);
    let fig35 = Chart::new("Fig 35: peak frequency vs force as b varies")
        .x_label("force amplitude n [N]")
        .y_label("f_rot [Hz]")
        .series(Series::scatter(name(base), xa.clone(), ya.clone()).color(BLUE))
        .series(Series::line(law(base), fa, fya).color(BLUE))
        .series(Series::scatter(name(other), xb, yb).color(RED).marker(Marker::Square))
        .series(Series::line(law(other), fb, fyb).color(RED).dashed());
    let (xc, yc) = xy(&set.other_radius, |p| p.force_amplitude_n);
    let (a, b) = MEASURED_POWER_LAW;
    let mx = linspace(MEASURED_FORCE_RANGE_N.0, MEASURED_FORCE_RANGE_N.1, CURVE_POINTS);
    let my = mx.iter().map(|n| a * n.powf(b)).collect();
    let fig36 = Chart::new("Fig 36: model vs measured fit (207 trials; cloud not available)")
        .x_label("force amplitude n [N]")
        .y_label("frequency [Hz]")
        .series(Series::line(format!("model, {}", name(base)), xa, ya).color(BLUE))
        .series(Series::line(format!("model, {}", name(&set.other_radius)), xc, yc).color(GREEN))
        .series(
            Series::line(format!("measured fit f = {a} n^{b} (R2 0.97)"), mx, my)
                .color(BLACK)
                .dashed()
                .width(2.0),
        );
    let measured = &set.measured;
    let (ic, fc) = xy(measured, |p| p.current_mean_a * 1e3);
    let line = measured.current_line;
    let lx = linspace(
        ic.iter().copied().fold(f64::INFINITY, f64::min),
        ic.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        CURVE_POINTS,
    );
    let ly = lx.iter().map(|i| line.eval(i * 1e-3)).collect();
    let fig37 = Chart::new(format!(
        "Fig 37: frequency vs steady current, preset {} (R = {} ohm)",
        measured.params.preset.name(),
        measured.params.resistance_ohm
    ))
    .x_label("mean current [mA]")
    .y_label("f_rot [Hz]")
    .series(Series::scatter("model (measured points not available)", ic, fc).color(BLUE))
    .series(
        Series::line(
            format!("f = {:.2} {:+.1} i[A] (R2 {:.6})", line.intercept, line.slope, line.r2),
            lx,
            ly,
        )
        .color(RED)
        .dashed(),
    );
    let fig38 = calibration_chart(base);
    Figure::new()
        .title(format!(
            "Damping sweep (thesis Figs 35-38): b over {}-{} Hz, {} points, {} s each; preset {}",
            base.options.min_hz,
            base.options.max_hz,
            base.points.len(),
            base.options.sim.duration_s,
            base.params.preset.name()
        ))
        .columns(2)
        .panel_size(640, 420)
        .push(fig35)
        .push(fig36)
        .push(fig37)
        .push(fig38)
}
