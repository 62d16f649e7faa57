//! `vestnav sim tactor | sweep | damping-for`: the tactor model from the command line.
//!
//! Thin layer over `vestnav_core::tactor` and `vestnav_core::sweep`: parse, validate, run, then print a
//! table or one JSON object, and optionally write CSV traces and report figures (thesis Figs 28–41).

use std::f64::consts::TAU;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use serde_json::{Value, json};
use vestnav_core::sweep::{
    Calibration, SweepOptions, SweepResult, calibrate_damping, max_frequency_hz, sweep,
};
use vestnav_core::tactor::{
    BodyMass, Preset, RADIUS_FITTED_M, SimOptions, Summary, TactorParams, TactorRun, Traces,
    amplitude_spectrum, simulate, simulate_with_step_angle,
};
use vestnav_plot::{Chart, Color, Figure, Marker, Scale, Series};

/// Parameter preset of the tactor model.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum PresetArg {
    /// R = 62 ohm, the value the thesis's simulations used.
    ThesisSim,
    /// R = 67 ohm, as measured.
    Measured,
}

/// Mass of the tactor body.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum MassArg {
    /// 3.7 g, bare motor with screw.
    Unencased,
    /// 4.95 g, in its case.
    Encased,
}

/// Options shared by the tactor-model commands.
#[derive(Debug, Clone, Args)]
pub struct ModelArgs {
    /// Parameter preset.
    #[arg(long, value_enum, default_value = "thesis-sim")]
    pub preset: PresetArg,
    /// Tactor body mass.
    #[arg(long, value_enum, default_value = "unencased")]
    pub mass: MassArg,
    /// Viscous damping b [N m s] (default: the thesis's 6.3e-8).
    #[arg(long, allow_negative_numbers = true)]
    pub damping: Option<f64>,
    /// Drive voltage [V] (default 3.3).
    #[arg(long, allow_negative_numbers = true)]
    pub voltage: Option<f64>,
    /// Radius of the eccentric's centre of mass [mm] (2.57 CAD, 3.2 fitted).
    #[arg(long, allow_negative_numbers = true)]
    pub radius_mm: Option<f64>,
}

impl ModelArgs {
    /// The validated model parameters.
    fn params(&self) -> anyhow::Result<TactorParams> {
        let preset = match self.preset {
            PresetArg::ThesisSim => Preset::ThesisSim,
            PresetArg::Measured => Preset::Measured,
        };
        let body = match self.mass {
            MassArg::Unencased => BodyMass::Unencased,
            MassArg::Encased => BodyMass::Encased,
        };
        let mut p = TactorParams::preset(preset).with_body(body);
        if let Some(b) = self.damping {
            p = p.with_damping(b);
        }
        if let Some(u) = self.voltage {
            p = p.with_voltage(u);
        }
        if let Some(l) = self.radius_mm {
            p = p.with_radius(l * 1e-3);
        }
        p.validate().context("invalid tactor parameters")?;
        Ok(p)
    }
}

/// `vestnav sim tactor`
#[derive(Debug, Args)]
pub struct TactorArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Simulated time from rest [s]; the last half is the analysis window.
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
    pub duration_s: f64,
    /// Output sampling rate of the traces [Hz] (the thesis's 10 kHz).
    #[arg(long, default_value_t = 10_000.0, allow_negative_numbers = true)]
    pub output_rate_hz: f64,
    /// Accuracy: largest eccentric rotation per integrator step [rad] (errors scale with its 4th power).
    #[arg(long, default_value_t = 0.26, allow_negative_numbers = true)]
    pub step_angle_rad: f64,
    /// Print the summary as one JSON object (SI units).
    #[arg(long)]
    pub json: bool,
    /// Write the traces (t, theta, omega, x, v, a, force, torque, current) as CSV.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write a figure: the thesis's Figs 28–34 as one sheet (also simulates the other body mass).
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// `vestnav sim sweep`
#[derive(Debug, Args)]
pub struct SweepArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Number of damping values.
    #[arg(long, default_value_t = 40)]
    pub points: usize,
    /// Lowest steady rotation frequency of the sweep [Hz].
    #[arg(long, default_value_t = 80.0, allow_negative_numbers = true)]
    pub min_hz: f64,
    /// Highest steady rotation frequency of the sweep [Hz].
    #[arg(long, default_value_t = 200.0, allow_negative_numbers = true)]
    pub max_hz: f64,
    /// Simulated time of each point [s]; the last half is analysed.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    pub duration_s: f64,
    /// Print the sweep and its fits as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write a figure sheet (Figs 35–38; also sweeps encased, l = 3.2 mm and the measured preset).
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// `vestnav sim damping-for`
#[derive(Debug, Args)]
pub struct DampingForArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// The tactor's measured peak frequency [Hz].
    #[arg(long, allow_negative_numbers = true)]
    pub frequency_hz: f64,
    /// Print as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write a figure of the calibrated tactor's force (Figs 39–41 model side; simulates 10 s).
    #[arg(long)]
    pub png: Option<PathBuf>,
}

fn summary_json(s: &Summary) -> Value {
    json!({
        "preset": s.params.preset.name(),
        "body": s.params.body.name(),
        "params": s.params,
        "duration_s": s.options.duration_s,
        "output_rate_hz": s.options.output_rate_hz,
        "window_start_s": s.window_start_s,
        "window_end_s": s.window_end_s,
        "omega_mean_rad_s": s.omega_mean_rad_s,
        "f_rot_hz": s.f_rot_hz,
        "omega_mean_revs_rad_s": s.omega_mean_revs_rad_s,
        "omega_min_rad_s": s.omega_min_rad_s,
        "omega_max_rad_s": s.omega_max_rad_s,
        "omega_ripple": s.omega_ripple,
        "fft_peak_1s_hz": s.fft_peak_1s_hz,
        "fft_window_s": s.fft_window_s,
        "accel_peak_m_s2": s.accel_peak_m_s2,
        "force_amplitude_n": s.force_amplitude_n,
        "x_amplitude_m": s.x_amplitude_m,
        "current_peak_a": s.current_peak_a,
        "current_mean_a": s.current_mean_a,
        "torque_peak_n_m": s.torque_peak_n_m,
        "torque_mean_n_m": s.torque_mean_n_m,
        "settling_time_s": s.settling_time_s,
        "steady_state": s.steady_state,
    })
}

#[allow(clippy::print_stdout)]
fn print_summary_table(s: &Summary) {
    let ss = &s.steady_state;
    let p = &s.params;
    println!(
        "tactor model: preset {} (R = {} ohm), {} (Mt = {} g), l = {} mm, u = {} V, b = {:e} N m s",
        p.preset.name(),
        p.resistance_ohm,
        p.body.name(),
        p.body_mass_kg * 1e3,
        p.radius_m * 1e3,
        p.voltage_v,
        p.damping_n_m_s
    );
    println!(
        "simulated {} s from rest at {} Hz; window {}..{} s",
        s.options.duration_s, s.options.output_rate_hz, s.window_start_s, s.window_end_s
    );
    println!("{:<34} {:>14} {:>14}", "quantity", "simulated", "closed form");
    let row = |name: &str, sim: f64, cf: Option<f64>| {
        let cf = cf.map_or_else(|| "-".to_string(), |v| format!("{v:.6}"));
        println!("{name:<34} {sim:>14.6} {cf:>14}");
    };
    row("mean omega [rad/s]", s.omega_mean_rad_s, Some(ss.omega_rad_s));
    row("f_rot [Hz]", s.f_rot_hz, Some(ss.f_rot_hz));
    row("omega min [rad/s]", s.omega_min_rad_s, None);
    row("omega max [rad/s]", s.omega_max_rad_s, None);
    row("FFT peak, last 1 s [Hz]", s.fft_peak_1s_hz, None);
    row("peak acceleration [m/s^2]", s.accel_peak_m_s2, Some(ss.accel_amplitude_m_s2));
    row("force amplitude [N]", s.force_amplitude_n, Some(ss.force_amplitude_n));
    row("x amplitude [mm]", s.x_amplitude_m * 1e3, Some(ss.x_amplitude_m * 1e3));
    row("peak current (start) [mA]", s.current_peak_a * 1e3, Some(ss.start_current_a * 1e3));
    row("mean current [mA]", s.current_mean_a * 1e3, Some(ss.current_a * 1e3));
    row("peak torque (start) [uN m]", s.torque_peak_n_m * 1e6, Some(ss.start_torque_n_m * 1e6));
    row("mean torque [uN m]", s.torque_mean_n_m * 1e6, Some(ss.torque_n_m * 1e6));
    match s.settling_time_s {
        Some(t) => row("2 % settling time [s]", t, None),
        None => println!("{:<34} {:>14}", "2 % settling time [s]", "not settled"),
    }
    println!("(closed forms ignore the speed ripple; force/acceleration closed forms assume constant speed)");
}

fn write_csv(path: &Path, tr: &Traces) -> anyhow::Result<()> {
    let file = std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut w = BufWriter::new(file);
    let io = |e| anyhow::anyhow!("cannot write {}: {e}", path.display());
    writeln!(w, "t_s,theta_rad,omega_rad_s,x_m,v_m_s,accel_m_s2,force_n,torque_n_m,current_a").map_err(io)?;
    for k in 0..tr.len() {
        writeln!(
            w,
            "{},{},{},{},{},{},{},{},{}",
            tr.t_s[k],
            tr.theta_rad[k],
            tr.omega_rad_s[k],
            tr.x_m[k],
            tr.v_m_s[k],
            tr.accel_m_s2[k],
            tr.force_n[k],
            tr.torque_n_m[k],
            tr.current_a[k]
        )
        .map_err(io)?;
    }
    w.flush().map_err(io)
}

/// Samples with `t0 <= t <= t1` of `(t, y)`, thinned to at most `max_points` (keeping each chunk's extreme
/// so that oscillations stay visible).
fn slice_xy(t: &[f64], y: &[f64], t0: f64, t1: f64, max_points: usize) -> (Vec<f64>, Vec<f64>) {
    let idx: Vec<usize> = (0..t.len()).filter(|&k| t[k] >= t0 && t[k] <= t1).collect();
    let stride = idx.len().div_ceil(max_points.max(1)).max(1);
    if stride == 1 {
        return (idx.iter().map(|&k| t[k]).collect(), idx.iter().map(|&k| y[k]).collect());
    }
    let mut xs = Vec::new();
    let mut ys = Vec::new();
    for chunk in idx.chunks(stride) {
        // min and max of each chunk, in time order
        let (mut kmin, mut kmax) = (chunk[0], chunk[0]);
        for &k in chunk {
            if y[k] < y[kmin] {
                kmin = k;
            }
            if y[k] > y[kmax] {
                kmax = k;
            }
        }
        for k in if kmin <= kmax { [kmin, kmax] } else { [kmax, kmin] } {
            xs.push(t[k]);
            ys.push(y[k]);
        }
    }
    (xs, ys)
}

/// Envelope: the largest |y| over each revolution of the eccentric (theta from 2 pi k to 2 pi (k+1)), at the
/// revolution's mid time. Before the first full revolution, nothing.
fn envelope(tr: &Traces, y: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut ts = Vec::new();
    let mut env = Vec::new();
    let mut start = 0usize;
    let mut rev = 1.0;
    for k in 1..tr.len() {
        if tr.theta_rad[k] >= TAU * rev {
            let peak = y[start..=k].iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            ts.push(0.5 * (tr.t_s[start] + tr.t_s[k]));
            env.push(peak);
            start = k;
            rev = (tr.theta_rad[k] / TAU).floor() + 1.0;
        }
    }
    (ts, env)
}

fn save(fig: &Figure, path: &Path) -> anyhow::Result<()> {
    fig.save_png(path).with_context(|| format!("cannot write figure {}", path.display()))
}

fn tactor_sheet(main: &TactorRun, other: &TactorRun) -> Figure {
    let label = |r: &TactorRun| {
        format!("{} (Mt = {} g)", r.summary.params.body.name(), r.summary.params.body_mass_kg * 1e3)
    };
    let (la, lb) = (label(main), label(other));
    let (a, b) = (&main.traces, &other.traces);
    let s = &main.summary;
    let t_end = s.options.duration_s;
    let t_short = t_end.min(0.5);
    let col_a = Color::rgb(31, 119, 180);
    let col_b = Color::rgb(214, 39, 40);
    let pair = |title: &str, ylab: &str, ya: &[f64], yb: &[f64], t1: f64, scale: f64| {
        let (xa, va) = slice_xy(&a.t_s, ya, 0.0, t1, 3000);
        let (xb, vb) = slice_xy(&b.t_s, yb, 0.0, t1, 3000);
        Chart::new(title)
            .x_label("time [s]")
            .y_label(ylab)
            .series(Series::line(la.clone(), xa, va.iter().map(|v| v * scale).collect()).color(col_a))
            .series(
                Series::line(lb.clone(), xb, vb.iter().map(|v| v * scale).collect()).color(col_b).dashed(),
            )
    };
    let fig28 = pair("Fig 28: eccentric angle", "theta [rad]", &a.theta_rad, &b.theta_rad, t_short, 1.0);
    let fig29 = pair("Fig 29: body position", "x [mm]", &a.x_m, &b.x_m, t_end.min(0.1), 1e3);
    let env_pair = |title: &str, ylab: &str, ya: &[f64], yb: &[f64]| {
        let (ta, ea) = envelope(a, ya);
        let (tb, eb) = envelope(b, yb);
        let keep = |t: Vec<f64>, e: Vec<f64>| -> (Vec<f64>, Vec<f64>) {
            t.into_iter().zip(e).filter(|(t, _)| *t <= t_end.min(1.0)).unzip()
        };
        let (ta, ea) = keep(ta, ea);
        let (tb, eb) = keep(tb, eb);
        Chart::new(title)
            .x_label("time [s]")
            .y_label(ylab)
            .series(Series::line(la.clone(), ta, ea).color(col_a))
            .series(Series::line(lb.clone(), tb, eb).color(col_b).dashed())
    };
    let fig30 = env_pair(
        "Fig 30: acceleration amplitude (per revolution)",
        "|a| [m/s^2]",
        &a.accel_m_s2,
        &b.accel_m_s2,
    );
    let fig31 = env_pair("Fig 31: force amplitude (a x Mt)", "|F| [N]", &a.force_n, &b.force_n);
    let ss = &s.steady_state;
    let (tt, torque) = slice_xy(&a.t_s, &a.torque_n_m, 0.0, t_short, 3000);
    let fig32 = Chart::new("Fig 32: motor torque")
        .x_label("time [s]")
        .y_label("T [uN m]")
        .series(Series::line(la.clone(), tt, torque.iter().map(|v| v * 1e6).collect()).color(col_a))
        .hline(ss.torque_n_m * 1e6, "steady Kt i (closed form)")
        .hline(ss.start_torque_n_m * 1e6, "start Kt u/R");
    let (tc, current) = slice_xy(&a.t_s, &a.current_a, 0.0, t_short, 3000);
    let fig33 = Chart::new("Fig 33: motor current")
        .x_label("time [s]")
        .y_label("i [mA]")
        .series(Series::line(la.clone(), tc, current.iter().map(|v| v * 1e3).collect()).color(col_a))
        .hline(ss.current_a * 1e3, "steady (u - Kt w)/R")
        .hline(ss.start_current_a * 1e3, "start u/R");
    let rate = s.options.output_rate_hz;
    let w0 = (s.window_start_s * rate).round() as usize;
    let (f, amp) = amplitude_spectrum(&a.accel_m_s2[w0.min(a.len())..], rate);
    let (f, amp): (Vec<f64>, Vec<f64>) =
        f.into_iter().zip(amp).filter(|(f, v)| *f > 0.0 && *f <= 1000.0 && *v > 0.0).unzip();
    let fig34 = Chart::new(format!(
        "Fig 34: spectrum of a, window {}-{} s (1 s FFT peak {:.0} Hz)",
        s.window_start_s, s.window_end_s, s.fft_peak_1s_hz
    ))
    .x_label("frequency [Hz]")
    .y_label("amplitude [m/s^2]")
    .y_scale(Scale::Log10)
    .series(Series::line(la, f, amp).color(col_a))
    .vline(s.f_rot_hz, format!("f_rot {:.2} Hz", s.f_rot_hz));
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
}

/// Runs `sim tactor`.
#[allow(clippy::print_stdout)]
pub fn run_tactor(args: &TactorArgs) -> anyhow::Result<()> {
    let params = args.model.params()?;
    let options = SimOptions { duration_s: args.duration_s, output_rate_hz: args.output_rate_hz };
    options.validate().context("invalid simulation options")?;
    let run = simulate_with_step_angle(&params, &options, args.step_angle_rad)
        .context("tactor simulation failed")?;
    if let Some(path) = &args.csv {
        write_csv(path, &run.traces)?;
    }
    if let Some(path) = &args.png {
        let other_body = match params.body {
            BodyMass::Unencased => BodyMass::Encased,
            BodyMass::Encased => BodyMass::Unencased,
        };
        let other = simulate_with_step_angle(&params.with_body(other_body), &options, args.step_angle_rad)
            .context("tactor simulation failed")?;
        save(&tactor_sheet(&run, &other), path)?;
    }
    if args.json {
        println!("{}", summary_json(&run.summary));
    } else {
        print_summary_table(&run.summary);
    }
    Ok(())
}

fn sweep_json(r: &SweepResult) -> Value {
    json!({
        "preset": r.params.preset.name(),
        "body": r.params.body.name(),
        "params": r.params,
        "options": r.options,
        "frequency": "f_rot: simulated mean speed / 2 pi over the last half of each run",
        "power_law": {
            "coefficient": r.power_law.coefficient,
            "exponent": r.power_law.exponent,
            "r2": r.power_law.r2,
        },
        "current_line": {
            "intercept_hz": r.current_line.intercept,
            "slope_hz_per_a": r.current_line.slope,
            "r2": r.current_line.r2,
        },
        "exact_inverse": r.exact_inverse,
        "inverse_fit": r.inverse_fit,
        "points": r.points,
    })
}

/// Fig 38: simulated (f, b) points, the exact inverse and the fitted 4-parameter inverse.
fn calibration_chart(base: &SweepResult) -> Chart {
    let blue = Color::rgb(31, 119, 180);
    let red = Color::rgb(214, 39, 40);
    let green = Color::rgb(44, 160, 44);
    let (fb_x, bb): (Vec<f64>, Vec<f64>) =
        base.points.iter().map(|p| (p.f_rot_hz, p.damping_n_m_s * 1e8)).unzip();
    let lo = base.options.min_hz;
    let hi = base.options.max_hz;
    let grid: Vec<f64> = (0..=100).map(|k| lo + (hi - lo) * f64::from(k) / 100.0).collect();
    let inv = base.inverse_fit;
    Chart::new("Fig 38: damping vs peak frequency (calibration curve)")
        .x_label("f_rot [Hz]")
        .y_label("b [1e-8 N m s]")
        .series(Series::scatter("simulated", fb_x, bb).color(blue))
        .series(
            Series::line(
                "exact b = (Kt u/(2 pi f) - Kt^2)/R",
                grid.clone(),
                grid.iter().map(|f| base.exact_inverse.eval(*f) * 1e8).collect(),
            )
            .color(green),
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
            .color(red)
            .dashed(),
        )
}

fn sweep_sheet(
    base: &SweepResult,
    encased: &SweepResult,
    fitted_l: &SweepResult,
    measured: &SweepResult,
) -> Figure {
    let xy = |r: &SweepResult, fx: fn(&vestnav_core::sweep::SweepPoint) -> f64| -> (Vec<f64>, Vec<f64>) {
        r.points.iter().map(|p| (fx(p), p.f_rot_hz)).unzip()
    };
    let fit_curve = |r: &SweepResult| -> (Vec<f64>, Vec<f64>) {
        let lo = r.points.iter().map(|p| p.force_amplitude_n).fold(f64::INFINITY, f64::min);
        let hi = r.points.iter().map(|p| p.force_amplitude_n).fold(0.0, f64::max);
        (0..=100).map(|k| lo + (hi - lo) * f64::from(k) / 100.0).map(|n| (n, r.power_law.eval(n))).unzip()
    };
    let name = |r: &SweepResult| format!("{}, l = {} mm", r.params.body.name(), r.params.radius_m * 1e3);
    let law = |r: &SweepResult| {
        format!(
            "fit f = {:.1} n^{:.4} (R2 {:.5})",
            r.power_law.coefficient, r.power_law.exponent, r.power_law.r2
        )
    };
    let blue = Color::rgb(31, 119, 180);
    let red = Color::rgb(214, 39, 40);
    let green = Color::rgb(44, 160, 44);
    let (xa, ya) = xy(base, |p| p.force_amplitude_n);
    let (xb, yb) = xy(encased, |p| p.force_amplitude_n);
    let (fa, fya) = fit_curve(base);
    let (fb, fyb) = fit_curve(encased);
    let fig35 = Chart::new("Fig 35: peak frequency vs force as b varies")
        .x_label("force amplitude n [N]")
        .y_label("f_rot [Hz]")
        .series(Series::scatter(name(base), xa, ya).color(blue))
        .series(Series::line(law(base), fa, fya).color(blue))
        .series(Series::scatter(name(encased), xb, yb).color(red).marker(Marker::Square))
        .series(Series::line(law(encased), fb, fyb).color(red).dashed());
    let (xc, yc) = xy(fitted_l, |p| p.force_amplitude_n);
    let (xa, ya) = xy(base, |p| p.force_amplitude_n);
    let (mx, my): (Vec<f64>, Vec<f64>) =
        (0..=100).map(|k| 0.5 + 1.2 * f64::from(k) / 100.0).map(|n| (n, 124.7 * n.powf(0.4839))).unzip();
    let fig36 = Chart::new("Fig 36: model vs measured fit (207 trials; cloud not available)")
        .x_label("force amplitude n [N]")
        .y_label("frequency [Hz]")
        .series(Series::line(format!("model, {}", name(base)), xa, ya).color(blue))
        .series(Series::line(format!("model, {}", name(fitted_l)), xc, yc).color(green))
        .series(
            Series::line("measured fit f = 124.7 n^0.4839 (R2 0.97)", mx, my).color(red).dashed().width(2.0),
        );
    let (ic, fc) = xy(measured, |p| p.current_mean_a * 1e3);
    let line = measured.current_line;
    let fig37 = Chart::new(format!(
        "Fig 37: frequency vs steady current, preset {} (R = {} ohm)",
        measured.params.preset.name(),
        measured.params.resistance_ohm
    ))
    .x_label("mean current [mA]")
    .y_label("f_rot [Hz]")
    .series(Series::scatter("model (measured points not available)", ic.clone(), fc).color(blue))
    .series(
        Series::line(
            format!("f = {:.2} {:+.1} i[A] (R2 {:.6})", line.intercept, line.slope, line.r2),
            ic.clone(),
            ic.iter().map(|i| line.eval(i * 1e-3)).collect(),
        )
        .color(red)
        .dashed(),
    );
    let fig38 = calibration_chart(base);
    let (lo, hi) = (base.options.min_hz, base.options.max_hz);
    Figure::new()
        .title(format!(
            "Damping sweep (thesis Figs 35-38): b over {}-{} Hz, {} points, {} s each; preset {}",
            lo,
            hi,
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

/// Runs `sim sweep`.
#[allow(clippy::print_stdout)]
pub fn run_sweep(args: &SweepArgs) -> anyhow::Result<()> {
    let params = args.model.params()?;
    let options = SweepOptions {
        min_hz: args.min_hz,
        max_hz: args.max_hz,
        points: args.points,
        sim: SimOptions { duration_s: args.duration_s, output_rate_hz: 10_000.0 },
    };
    let result = sweep(&params, &options).context("damping sweep failed")?;
    if let Some(path) = &args.png {
        let other_body = match params.body {
            BodyMass::Unencased => BodyMass::Encased,
            BodyMass::Encased => BodyMass::Unencased,
        };
        let encased = sweep(&params.with_body(other_body), &options).context("damping sweep failed")?;
        let fitted_l =
            sweep(&params.with_radius(RADIUS_FITTED_M), &options).context("damping sweep failed")?;
        let mut measured_params = params;
        measured_params.preset = Preset::Measured;
        measured_params.resistance_ohm = Preset::Measured.resistance_ohm();
        let measured = sweep(&measured_params, &options).context("damping sweep failed")?;
        save(&sweep_sheet(&result, &encased, &fitted_l, &measured), path)?;
    }
    if args.json {
        println!("{}", sweep_json(&result));
        return Ok(());
    }
    let p = &result.params;
    println!(
        "damping sweep: preset {} (R = {} ohm), {}, l = {} mm, u = {} V; {} points over {}-{} Hz",
        p.preset.name(),
        p.resistance_ohm,
        p.body.name(),
        p.radius_m * 1e3,
        p.voltage_v,
        result.points.len(),
        args.min_hz,
        args.max_hz
    );
    println!(
        "{:>14} {:>12} {:>10} {:>12} {:>12}",
        "b [N m s]", "f_rot [Hz]", "FFT [Hz]", "force [N]", "i_mean [mA]"
    );
    for q in &result.points {
        println!(
            "{:>14.4e} {:>12.4} {:>10.1} {:>12.5} {:>12.4}",
            q.damping_n_m_s,
            q.f_rot_hz,
            q.fft_peak_1s_hz,
            q.force_amplitude_n,
            q.current_mean_a * 1e3
        );
    }
    let pl = result.power_law;
    let cl = result.current_line;
    let inv = result.inverse_fit;
    println!("power law   f = {:.3} n^{:.5}   (R2 = {:.6})", pl.coefficient, pl.exponent, pl.r2);
    println!("current     f = {:.3} + ({:.2}) i [A]   (R2 = {:.8})", cl.intercept, cl.slope, cl.r2);
    println!(
        "exact inverse  b = {:.6e} / f + ({:.6e})",
        result.exact_inverse.a_n_m_s_hz, result.exact_inverse.c_n_m_s
    );
    println!(
        "fitted inverse b = {:.6e} (f + {:.5})^{:.6} + ({:.6e}); max error {:.3} % vs points, {:.3} % vs exact",
        inv.p1,
        inv.p2,
        inv.p3,
        inv.p4,
        inv.max_rel_residual * 100.0,
        inv.max_rel_dev_from_exact * 100.0
    );
    Ok(())
}

fn calibrated_sheet(cal: &Calibration, run: &TactorRun) -> Figure {
    let tr = &run.traces;
    let s = &run.summary;
    let (te, fe) = envelope(tr, &tr.force_n);
    let blue = Color::rgb(31, 119, 180);
    let red = Color::rgb(214, 39, 40);
    let t_end = s.options.duration_s;
    let fig39 = Chart::new(format!("Fig 39: force amplitude over {t_end} s"))
        .x_label("time [s]")
        .y_label("|F| [N]")
        .series(Series::line("model envelope (per revolution)", te.clone(), fe.clone()).color(blue))
        .hline(s.force_amplitude_n, format!("window peak {:.3} N", s.force_amplitude_n));
    let (t1, f1) = slice_xy(&tr.t_s, &tr.force_n, 0.0, t_end.min(1.0), 6000);
    let (te1, fe1): (Vec<f64>, Vec<f64>) = te.into_iter().zip(fe).filter(|(t, _)| *t <= 1.0).unzip();
    let mut fig40 = Chart::new("Fig 40: force, first 1 s")
        .x_label("time [s]")
        .y_label("F [N]")
        .series(Series::line("model force", t1, f1).color(Color::rgb(150, 170, 200)))
        .series(Series::line("model envelope", te1, fe1).color(blue).width(2.0));
    if let Some(ts) = s.settling_time_s {
        fig40 = fig40.vline(ts, format!("2% settling {ts:.3} s"));
    }
    let t0 = s.window_start_s;
    let (t2, f2) = slice_xy(&tr.t_s, &tr.force_n, t0, t0 + 0.03, 2000);
    let fig41 =
        Chart::new(format!("Fig 41: steady force waveform ({:.2} Hz)", s.omega_mean_revs_rad_s / TAU))
            .x_label("time [s]")
            .y_label("F [N]")
            .series(Series::line("model force", t2, f2).color(red));
    Figure::new()
        .title(format!(
            "Calibrated tactor (thesis Figs 39-41, model side; measured traces not available): \
             peak {} Hz -> b = {:.4e} N m s (closed form {:.4e})",
            cal.frequency_hz, cal.damping_n_m_s, cal.damping_closed_form_n_m_s
        ))
        .columns(3)
        .panel_size(560, 400)
        .push(fig39)
        .push(fig40)
        .push(fig41)
}

/// Runs `sim damping-for`.
#[allow(clippy::print_stdout)]
pub fn run_damping_for(args: &DampingForArgs) -> anyhow::Result<()> {
    let params = args.model.params()?;
    let f = args.frequency_hz;
    let max_hz = max_frequency_hz(&params);
    if !(f.is_finite() && f > 0.0 && f < max_hz) {
        bail!(
            "--frequency-hz must be a number in (0, {max_hz:.2}) Hz for this tactor (no-load limit u/(2 pi Kt)), got {f}"
        );
    }
    let cal =
        calibrate_damping(&params, f, &SweepOptions::default().sim).context("damping calibration failed")?;
    let run = if args.png.is_some() {
        Some(simulate(&cal.params(), &SimOptions::default()).context("tactor simulation failed")?)
    } else {
        None
    };
    if let (Some(path), Some(run)) = (&args.png, &run) {
        save(&calibrated_sheet(&cal, run), path)?;
    }
    let s = run.as_ref().map_or(&cal.summary, |r| &r.summary);
    if args.json {
        println!(
            "{}",
            json!({
                "preset": params.preset.name(),
                "frequency_hz": cal.frequency_hz,
                "damping_n_m_s": cal.damping_n_m_s,
                "damping_closed_form_n_m_s": cal.damping_closed_form_n_m_s,
                "achieved_f_rot_hz": cal.achieved_f_rot_hz,
                "iterations": cal.iterations,
                "summary": summary_json(s),
            })
        );
        return Ok(());
    }
    println!("{:e}", cal.damping_n_m_s);
    eprintln!(
        "b = {:.6e} N m s makes the simulated tactor turn at {:.4} Hz (preset {}, {}, l = {} mm, u = {} V); \
         ripple-free closed form: {:.6e} N m s; force amplitude {:.4} N",
        cal.damping_n_m_s,
        cal.achieved_f_rot_hz,
        params.preset.name(),
        params.body.name(),
        params.radius_m * 1e3,
        params.voltage_v,
        cal.damping_closed_form_n_m_s,
        s.force_amplitude_n
    );
    Ok(())
}
