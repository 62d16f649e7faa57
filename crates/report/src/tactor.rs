//! The simulated tactor (thesis §3.2): Figs 28–34, the calibrated tactor of Figs 39–41, and the JSON
//! schemas of `sim tactor` and `sim damping-for`.

use serde::{Deserialize, Serialize};
use vestnav_core::analysis::{amplitude_spectrum, revolution_envelope};
use vestnav_core::sweep::Calibration;
use vestnav_core::tactor::{
    BodyMass, Preset, SimOptions, Summary, TactorError, TactorParams, TactorRun, simulate_with_step_angle,
};
use vestnav_plot::{Chart, Color, Figure, Scale, Series, decimate_minmax};

use crate::series::time_window;

/// Traces are drawn from rest up to this time by default [s] (the thesis's Figs 28–33 show about 0.5 s).
pub const DEFAULT_SPAN_S: f64 = 0.5;
/// Most points per trace in a figure (min/max decimation keeps the oscillation's envelope).
pub const MAX_TRACE_POINTS: usize = 4000;
/// Highest frequency drawn in the spectrum (Fig 34) [Hz].
const SPECTRUM_MAX_HZ: f64 = 1000.0;

/// Colour of the selected tactor's traces.
const MAIN: Color = Color::rgb(0, 114, 178);
/// Colour of the other body mass's traces.
const OTHER: Color = Color::rgb(213, 94, 0);

/// The other body mass: Figs 28–31 compare the unencased and the encased tactor.
pub fn other_body(body: BodyMass) -> BodyMass {
    match body {
        BodyMass::Unencased => BodyMass::Encased,
        BodyMass::Encased => BodyMass::Unencased,
    }
}

/// The simulations behind the tactor figure: the selected tactor, and the same tactor with the other body
/// mass when the figure compares them.
#[derive(Debug, Clone, PartialEq)]
pub struct TactorRuns {
    /// The tactor asked for.
    pub main: TactorRun,
    /// The same tactor with the other body mass ([`other_body`]), if compared.
    pub other: Option<TactorRun>,
}

impl TactorRuns {
    /// Simulates `params` from rest (and the other body mass when `compare_bodies`), with the integrator's
    /// largest rotation per step `step_angle_rad` (`vestnav_core::tactor::DEFAULT_STEP_ANGLE_RAD` by
    /// default).
    pub fn simulate(
        params: &TactorParams,
        options: &SimOptions,
        step_angle_rad: f64,
        compare_bodies: bool,
    ) -> Result<Self, TactorError> {
        let main = simulate_with_step_angle(params, options, step_angle_rad)?;
        let other = if compare_bodies {
            Some(simulate_with_step_angle(
                &params.with_body(other_body(params.body)),
                options,
                step_angle_rad,
            )?)
        } else {
            None
        };
        Ok(Self { main, other })
    }

    /// The runs, selected tactor first.
    pub fn all(&self) -> impl Iterator<Item = &TactorRun> {
        std::iter::once(&self.main).chain(self.other.as_ref())
    }
}

/// JSON of one simulated tactor (`vestnav sim tactor --json` and the console's tactor export): the
/// [`Summary`] with the preset and body names and the run's duration and rate at the top level.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TactorReport {
    /// Parameter preset (`thesis-sim` or `measured`).
    pub preset: Preset,
    /// Body mass (`unencased` or `encased`).
    pub body: BodyMass,
    /// Simulated time from rest [s].
    pub duration_s: f64,
    /// Output sampling rate of the traces [Hz].
    pub output_rate_hz: f64,
    /// The figures of merit (keys `params`, `options`, `window_start_s`, ..., `steady_state`).
    #[serde(flatten)]
    pub summary: Summary,
}

impl TactorReport {
    /// The report of one run's summary.
    pub fn new(summary: &Summary) -> Self {
        Self {
            preset: summary.params.preset,
            body: summary.params.body,
            duration_s: summary.options.duration_s,
            output_rate_hz: summary.options.output_rate_hz,
            summary: summary.clone(),
        }
    }
}

/// JSON of `vestnav sim damping-for --json`: the [`Calibration`] (keys `frequency_hz`, `damping_n_m_s`,
/// `damping_closed_form_n_m_s`, `achieved_f_rot_hz`, `iterations`, `summary`) and the preset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationReport {
    /// Parameter preset.
    pub preset: Preset,
    /// The calibration.
    #[serde(flatten)]
    pub calibration: Calibration,
}

/// Named summary values with units, for tables and the CSV header.
pub fn summary_rows(s: &Summary) -> Vec<(&'static str, String)> {
    let ss = &s.steady_state;
    vec![
        ("mean omega [rad/s]", format!("{:.4}", s.omega_mean_rad_s)),
        ("closed-form omega [rad/s]", format!("{:.4}", ss.omega_rad_s)),
        ("f_rot [Hz]", format!("{:.4}", s.f_rot_hz)),
        ("omega min / max [rad/s]", format!("{:.3} / {:.3}", s.omega_min_rad_s, s.omega_max_rad_s)),
        ("omega ripple", format!("{:.4}", s.omega_ripple)),
        ("FFT peak [Hz]", format!("{:.1} ({} s window)", s.fft_peak_1s_hz, s.fft_window_s)),
        ("peak acceleration [m/s^2]", format!("{:.3}", s.accel_peak_m_s2)),
        ("force amplitude [N]", format!("{:.5}", s.force_amplitude_n)),
        ("x amplitude [mm]", format!("{:.6}", s.x_amplitude_m * 1e3)),
        (
            "current peak / mean [mA]",
            format!("{:.3} / {:.3}", s.current_peak_a * 1e3, s.current_mean_a * 1e3),
        ),
        (
            "torque peak / mean [uN m]",
            format!("{:.4} / {:.4}", s.torque_peak_n_m * 1e6, s.torque_mean_n_m * 1e6),
        ),
        (
            "2 % settling time [s]",
            s.settling_time_s.map_or_else(|| "not settled".to_string(), |t| format!("{t:.4}")),
        ),
        ("start current u/R [mA]", format!("{:.3}", ss.start_current_a * 1e3)),
        ("L/R [us]", format!("{:.2}", ss.electrical_time_constant_s * 1e6)),
    ]
}

/// One line naming the simulated tactor.
pub fn describe(s: &Summary) -> String {
    let p = &s.params;
    format!(
        "{} preset ({} ohm), {}, u = {} V, b = {:.4e} N m s, l = {} mm, T = {} s, window {}..{} s",
        p.preset.name(),
        p.resistance_ohm,
        p.body.name(),
        p.voltage_v,
        p.damping_n_m_s,
        p.radius_m * 1e3,
        s.options.duration_s,
        s.window_start_s,
        s.window_end_s
    )
}

/// The summary of each run, one line each (the CSV header).
pub fn header(runs: &TactorRuns) -> Vec<String> {
    let mut lines = Vec::new();
    for run in runs.all() {
        let s = &run.summary;
        lines.push(describe(s));
        for (name, value) in summary_rows(s) {
            lines.push(format!("{}: {name} = {value}", s.params.body.name()));
        }
    }
    lines
}

fn body_label(run: &TactorRun) -> String {
    let p = &run.summary.params;
    format!("{} (Mt = {} g)", p.body.name(), p.body_mass_kg * 1e3)
}

/// A trace of every run over `0..=span_s`, scaled and thinned for drawing.
fn traces(
    runs: &TactorRuns,
    title: &str,
    y_label: &str,
    span_s: f64,
    scale: f64,
    pick: fn(&TactorRun) -> &[f64],
) -> Chart {
    let mut chart = Chart::new(title).x_label("time [s]").y_label(y_label);
    for (k, run) in runs.all().enumerate() {
        let (t, y) = time_window(&run.traces.t_s, pick(run), 0.0, span_s, scale);
        let (t, y) = decimate_minmax(&t, &y, MAX_TRACE_POINTS);
        let series = Series::line(body_label(run), t, y);
        chart = chart.series(if k == 0 { series.color(MAIN) } else { series.color(OTHER).dashed() });
    }
    chart
}

/// The per-revolution envelope of every run over `0..=span_s`.
fn envelopes(
    runs: &TactorRuns,
    title: &str,
    y_label: &str,
    span_s: f64,
    pick: fn(&TactorRun) -> &[f64],
) -> Chart {
    let mut chart = Chart::new(title).x_label("time [s]").y_label(y_label);
    for (k, run) in runs.all().enumerate() {
        let tr = &run.traces;
        let env = revolution_envelope(&tr.t_s, &tr.theta_rad, pick(run));
        let (t, e) = (env.time_s, env.amplitude);
        let (t, e): (Vec<f64>, Vec<f64>) = t.into_iter().zip(e).filter(|(t, _)| *t <= span_s).unzip();
        let series = Series::line(body_label(run), t, e);
        chart = chart.series(if k == 0 { series.color(MAIN) } else { series.color(OTHER).dashed() });
    }
    chart
}

/// The thesis's Figs 28–34 for the runs, traces from rest to `span_s` (default [`DEFAULT_SPAN_S`]), and the
/// rotor speed against its closed-form steady state: what `vestnav sim tactor --png` writes and the console's
/// tactor view shows and exports.
///
/// Fig 28 eccentric angle theta, Fig 29 body position x, Figs 30/31 the per-revolution amplitude of the
/// acceleration and of the force `Mt a`, Fig 32 torque `Kt i`, Fig 33 current, Fig 34 the spectrum of the
/// acceleration over the analysis window (physics.md §7). Reference lines are the closed forms of the selected
/// tactor: steady current `(u - Kt omega)/R`, start current `u/R`, torques `Kt i`, steady speed
/// `omega = Kt u / (R b + Kt^2)`, force `m l omega^2`.
pub fn tactor_figure(runs: &TactorRuns, span_s: f64) -> Figure {
    let s = &runs.main.summary;
    let ss = &s.steady_state;
    let span_s = if span_s.is_finite() && span_s > 0.0 { span_s } else { DEFAULT_SPAN_S };
    let fig28 = traces(runs, "Fig 28: eccentric angle", "theta [rad]", span_s, 1.0, |r| &r.traces.theta_rad);
    let fig29 = traces(runs, "Fig 29: body position", "x [mm]", span_s, 1e3, |r| &r.traces.x_m);
    let fig30 =
        envelopes(runs, "Fig 30: acceleration amplitude (per revolution)", "|a| [m/s^2]", span_s, |r| {
            &r.traces.accel_m_s2
        })
        .hline(ss.accel_amplitude_m_s2, "closed form m l omega^2 / Mt");
    let fig31 = envelopes(runs, "Fig 31: force amplitude (a x Mt)", "|F| [N]", span_s, |r| &r.traces.force_n)
        .hline(ss.force_amplitude_n, "closed form m l omega^2");
    let only_main = TactorRuns { main: runs.main.clone(), other: None };
    let fig32 = traces(&only_main, "Fig 32: motor torque", "T [uN m]", span_s, 1e6, |r| &r.traces.torque_n_m)
        .hline(ss.torque_n_m * 1e6, "steady Kt i (closed form)")
        .hline(ss.start_torque_n_m * 1e6, "start Kt u/R");
    let fig33 = traces(&only_main, "Fig 33: motor current", "i [mA]", span_s, 1e3, |r| &r.traces.current_a)
        .hline(ss.current_a * 1e3, "steady (u - Kt w)/R")
        .hline(ss.start_current_a * 1e3, "start u/R");
    let tr = &runs.main.traces;
    let rate = s.options.output_rate_hz;
    let w0 = ((s.window_start_s * rate).round() as usize).min(tr.len());
    let (f, amp) = amplitude_spectrum(&tr.accel_m_s2[w0..], rate);
    let (f, amp): (Vec<f64>, Vec<f64>) =
        f.into_iter().zip(amp).filter(|(f, v)| *f > 0.0 && *f <= SPECTRUM_MAX_HZ && *v > 0.0).unzip();
    let fig34 = Chart::new(format!(
        "Fig 34: spectrum of a, window {}-{} s (1 s FFT peak {:.0} Hz)",
        s.window_start_s, s.window_end_s, s.fft_peak_1s_hz
    ))
    .x_label("frequency [Hz]")
    .y_label("amplitude [m/s^2]")
    .y_scale(Scale::Log10)
    .series(Series::line(body_label(&runs.main), f, amp).color(MAIN))
    .vline(s.f_rot_hz, format!("f_rot {:.2} Hz", s.f_rot_hz));
    let mut speed = traces(runs, "Rotor speed (the slope of Fig 28)", "omega [rad/s]", span_s, 1.0, |r| {
        &r.traces.omega_rad_s
    })
    .hline(ss.omega_rad_s, "closed-form steady speed");
    if let Some(ts) = s.settling_time_s {
        speed = speed.vline(ts, format!("2 % settled {ts:.3} s"));
    }
    let p = &s.params;
    Figure::new()
        .title(format!(
            "Simulated tactor (thesis Figs 28-34): preset {} (R = {} ohm), l = {} mm, u = {} V, b = {:.3e} N m s",
            p.preset.name(),
            p.resistance_ohm,
            p.radius_m * 1e3,
            p.voltage_v,
            p.damping_n_m_s
        ))
        .columns(2)
        .panel_size(640, 400)
        .push(fig28)
        .push(fig29)
        .push(fig30)
        .push(fig31)
        .push(fig32)
        .push(fig33)
        .push(fig34)
        .push(speed)
}

/// The calibrated tactor, model side of the thesis's Figs 39–41: the force envelope over the run, the force
/// over the first second with its envelope and the 2 % settling time, and the steady force waveform.
pub fn calibrated_figure(cal: &Calibration, run: &TactorRun) -> Figure {
    let tr = &run.traces;
    let s = &run.summary;
    let env = revolution_envelope(&tr.t_s, &tr.theta_rad, &tr.force_n);
    let (te, fe) = (env.time_s, env.amplitude);
    let t_end = s.options.duration_s;
    let fig39 = Chart::new(format!("Fig 39: force amplitude over {t_end} s"))
        .x_label("time [s]")
        .y_label("|F| [N]")
        .series(Series::line("model envelope (per revolution)", te.clone(), fe.clone()).color(MAIN))
        .hline(s.force_amplitude_n, format!("window peak {:.3} N", s.force_amplitude_n));
    let (t1, f1) = time_window(&tr.t_s, &tr.force_n, 0.0, t_end.min(1.0), 1.0);
    let (t1, f1) = decimate_minmax(&t1, &f1, MAX_TRACE_POINTS);
    let (te1, fe1): (Vec<f64>, Vec<f64>) = te.into_iter().zip(fe).filter(|(t, _)| *t <= 1.0).unzip();
    let mut fig40 = Chart::new("Fig 40: force, first 1 s")
        .x_label("time [s]")
        .y_label("F [N]")
        .series(Series::line("model force", t1, f1).color(Color::rgb(150, 170, 200)))
        .series(Series::line("model envelope", te1, fe1).color(MAIN).width(2.0));
    if let Some(ts) = s.settling_time_s {
        fig40 = fig40.vline(ts, format!("2% settling {ts:.3} s"));
    }
    let t0 = s.window_start_s;
    let (t2, f2) = time_window(&tr.t_s, &tr.force_n, t0, t0 + 0.03, 1.0);
    let fig41 = Chart::new(format!(
        "Fig 41: steady force waveform ({:.2} Hz)",
        s.omega_mean_revs_rad_s / std::f64::consts::TAU
    ))
    .x_label("time [s]")
    .y_label("F [N]")
    .series(Series::line("model force", t2, f2).color(OTHER));
    Figure::new()
        .title(format!(
            "Calibrated tactor (thesis Figs 39-41, model side; measured traces not available): \
             peak {:.2} Hz -> b = {:.4e} N m s (closed form {:.4e})",
            cal.frequency_hz, cal.damping_n_m_s, cal.damping_closed_form_n_m_s
        ))
        .columns(3)
        .panel_size(560, 400)
        .push(fig39)
        .push(fig40)
        .push(fig41)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use vestnav_core::tactor::DEFAULT_STEP_ANGLE_RAD;
    use vestnav_plot::Panel;

    fn runs() -> TactorRuns {
        let params = TactorParams::preset(Preset::ThesisSim);
        let options = SimOptions { duration_s: 1.0, output_rate_hz: 10_000.0 };
        TactorRuns::simulate(&params, &options, DEFAULT_STEP_ANGLE_RAD, true).unwrap()
    }

    #[test]
    fn figure_has_the_thesis_panels_and_closed_forms() {
        let runs = runs();
        let fig = tactor_figure(&runs, DEFAULT_SPAN_S);
        let titles: Vec<&str> = fig
            .panels
            .iter()
            .map(|p| match p {
                Panel::Chart(c) => c.title.as_str(),
                Panel::Heatmap(h) => h.title.as_str(),
            })
            .collect();
        for (k, fig_no) in (28..=34).enumerate() {
            assert!(titles[k].starts_with(&format!("Fig {fig_no}:")), "{titles:?}");
        }
        assert!(titles[0].contains("eccentric angle"), "physics.md §7: Fig 28 is theta");
        // Fig 31: the force envelope settles on the reference force amplitude (physics.md §1: 0.90945 N);
        // the reference line is the constant-speed closed form m l omega^2.
        let Panel::Chart(fig31) = &fig.panels[3] else { panic!("chart expected") };
        let (m, l) = (0.55e-3, 2.57e-3);
        let kt = 0.0019;
        let omega = kt * 3.3 / (62.0 * 6.3e-8 + kt * kt);
        assert_relative_eq!(fig31.hlines[0].value, m * l * omega * omega, max_relative = 1e-9);
        let last = *fig31.series[0].y.last().unwrap();
        assert_relative_eq!(last, 0.90945, max_relative = 5e-3);
        // Fig 33: the start current is u/R and the steady one (u - Kt omega)/R.
        let Panel::Chart(fig33) = &fig.panels[5] else { panic!("chart expected") };
        assert_relative_eq!(fig33.hlines[1].value, 3.3 / 62.0 * 1e3, max_relative = 1e-9);
        assert_relative_eq!(fig33.hlines[0].value, (3.3 - kt * omega) / 62.0 * 1e3, max_relative = 1e-9);
        // Traces are thinned but keep their extremes, within the span.
        let Panel::Chart(fig28) = &fig.panels[0] else { panic!("chart expected") };
        assert!(fig28.series.iter().all(|s| s.x.len() <= MAX_TRACE_POINTS + 2));
        assert!(fig28.series[0].x.iter().all(|t| *t <= DEFAULT_SPAN_S));
    }

    #[test]
    fn json_has_the_cli_keys_and_round_trips() {
        let runs = runs();
        let report = TactorReport::new(&runs.main.summary);
        let text = crate::to_json(&report).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        for key in [
            "preset",
            "body",
            "params",
            "duration_s",
            "output_rate_hz",
            "omega_mean_rad_s",
            "f_rot_hz",
            "steady_state",
        ] {
            assert!(v.get(key).is_some(), "missing {key}");
        }
        assert_eq!(v["preset"], "thesis-sim");
        assert_eq!(v["body"], "unencased");
        let back: TactorReport = serde_json::from_str(&text).unwrap();
        assert_relative_eq!(
            back.summary.omega_mean_rad_s,
            report.summary.omega_mean_rad_s,
            max_relative = 1e-15
        );
        assert_eq!(back.preset, report.preset);
    }
}
