//! `vestnav sim tactor | sweep | damping-for`: the tactor model from the command line.
//!
//! Thin layer over `vestnav_core::tactor` and `vestnav_core::sweep`: parse, validate, run, then print a
//! table or one JSON object, and optionally write CSV traces and report figures (thesis Figs 28–41).

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use vestnav_core::sweep::{SweepOptions, calibrate_damping, max_frequency_hz, sweep};
use vestnav_core::tactor::{BodyMass, Preset, SimOptions, Summary, TactorParams, Traces, simulate};
use vestnav_report::sweep::{SweepReport, SweepSet, sweep_figure};
use vestnav_report::tactor::{
    CalibrationReport, DEFAULT_SPAN_S, TactorReport, TactorRuns, calibrated_figure, tactor_figure,
};
use vestnav_report::{Figure, to_json};

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

/// Writes the figure; the error names the file (no context added: it would name it twice).
fn save(fig: &Figure, path: &Path) -> anyhow::Result<()> {
    Ok(fig.save_png(path)?)
}

/// Runs `sim tactor`.
#[allow(clippy::print_stdout)]
pub fn run_tactor(args: &TactorArgs) -> anyhow::Result<()> {
    let params = args.model.params()?;
    let options = SimOptions { duration_s: args.duration_s, output_rate_hz: args.output_rate_hz };
    options.validate().context("invalid simulation options")?;
    // The figure compares the other body mass (Figs 28-31); the JSON and table are the selected tactor's.
    let runs = TactorRuns::simulate(&params, &options, args.step_angle_rad, args.png.is_some())
        .context("tactor simulation failed")?;
    if let Some(path) = &args.csv {
        write_csv(path, &runs.main.traces)?;
    }
    if let Some(path) = &args.png {
        save(&tactor_figure(&runs, DEFAULT_SPAN_S), path)?;
    }
    if args.json {
        print!("{}", to_json(&TactorReport::new(&runs.main.summary))?);
    } else {
        print_summary_table(&runs.main.summary);
    }
    Ok(())
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
    // The figure also sweeps the other body, the other radius and the measured preset.
    let result = if let Some(path) = &args.png {
        let set = SweepSet::compute(&params, &options).context("damping sweep failed")?;
        save(&sweep_figure(&set), path)?;
        set.main
    } else {
        sweep(&params, &options).context("damping sweep failed")?
    };
    if args.json {
        print!("{}", to_json(&SweepReport::new(&result))?);
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
    if let Some(path) = &args.png {
        let run = simulate(&cal.params(), &SimOptions::default()).context("tactor simulation failed")?;
        save(&calibrated_figure(&cal, &run), path)?;
    }
    let s = &cal.summary;
    if args.json {
        print!("{}", to_json(&CalibrationReport { preset: params.preset, calibration: cal.clone() })?);
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
