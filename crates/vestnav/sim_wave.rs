//! `vestnav sim two-point | wave`: skin waves and the two-point simulation from the command line.

#![allow(clippy::print_stdout)] // Printing the results is this module's job.
#![allow(rustdoc::broken_intra_doc_links)] // Units in brackets in the clap help texts ([mm]) are not links.

use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use serde_json::json;
use vestnav_core::twopoint::{self, TwoPointResult, TwoPointSetup};
use vestnav_core::vest::{TACTOR_COUNT, TactorMask};
use vestnav_core::wave::{
    self, DVec2, FIG52_A0_M_S2, FIG52_WIDTHS_M, GaussianAttenuation, MEASURED_FREQUENCY_HZ, Skin, WaveSource,
};
use vestnav_plot::{Chart, Color, Figure, Heatmap, Marker, Scale, Series};

/// `vestnav sim two-point`
#[derive(Debug, Args)]
pub struct TwoPointArgs {
    /// Distance(s) between the two tactors [mm], comma-separated (one pair of panels each in the figure).
    #[arg(long, value_delimiter = ',', default_value = "11")]
    pub distance_mm: Vec<f64>,
    /// Sweep the RMSE over distances 0..=max-mm in 1 mm steps instead (prints a JSON array with --json).
    #[arg(long)]
    pub sweep: bool,
    /// Largest distance of the sweep [mm].
    #[arg(long, default_value_t = 100.0)]
    pub max_mm: f64,
    /// Detection level of the two-point threshold: RMSE as a fraction of one tactor's amplitude.
    #[arg(long, default_value_t = twopoint::DEFAULT_RELATIVE_RMSE)]
    pub relative_rmse: f64,
    /// Print as JSON: keys `amplitude`, `center_mm`, `width_mm`, `rmse` (plus `distance_mm`, `sse`,
    /// `points`).
    #[arg(long)]
    pub json: bool,
    /// Write a figure (Figs 60–63 style; RMSE versus distance with --sweep).
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// Which wave figure to produce.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WaveView {
    /// Amplitude versus distance for the three measured tactors, with the spacing rule (Fig 52).
    Attenuation,
    /// Acceleration versus time at several distances: the phase lag of the travelling wave (Fig 57).
    Travelling,
    /// Arrival time of a crest versus distance, slope = wave speed (Fig 59).
    Arrival,
    /// Superposed field of firing tactors on the 4x4 vest plane.
    Vest,
    /// The signal halfway between two tactors running at 53.2 and 70.8 Hz.
    Midpoint,
}

/// `vestnav sim wave`
#[derive(Debug, Args)]
pub struct WaveArgs {
    /// What to compute.
    #[arg(long, value_enum, default_value = "attenuation")]
    pub view: WaveView,
    /// For `vest`: tactor indices 0..16 that fire (row-major from the wearer's upper left, seen from behind)
    /// [default: 5].
    #[arg(long, value_delimiter = ',')]
    pub tactors: Option<Vec<usize>>,
    /// For `vest`: centre-to-centre tactor spacing [mm] [default: 60].
    #[arg(long)]
    pub spacing_mm: Option<f64>,
    /// For `vest`: every tactor's frequency [Hz] [default: 70.4, the measured travelling wave].
    #[arg(long)]
    pub frequency_hz: Option<f64>,
    /// For `vest`: time of the snapshot panel [s]; for `travelling`: start of the plotted window [s]
    /// [default: 0].
    #[arg(long)]
    pub time_s: Option<f64>,
    /// For `travelling` and `midpoint` (figure only): window length [s] [default: 0.05 / 0.1].
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// For `travelling` and `arrival`: distances from the tactor [mm], increasing [default: 0,20,37,52].
    #[arg(long, value_delimiter = ',')]
    pub distances_mm: Option<Vec<f64>>,
    /// For `midpoint`: distance between the two tactors [mm] [default: 80].
    #[arg(long)]
    pub separation_mm: Option<f64>,
    /// For `attenuation`: the spacing rule's fraction of the source amplitude [default: 0.1].
    #[arg(long)]
    pub fraction: Option<f64>,
    /// Print the numbers as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write a figure.
    #[arg(long)]
    pub png: Option<PathBuf>,
}

fn save(figure: &Figure, path: &Path) -> anyhow::Result<()> {
    figure.save_png(path).with_context(|| format!("writing figure {}", path.display()))
}

fn range(start: f64, end: f64, n: usize) -> Vec<f64> {
    (0..n).map(|i| start + (end - start) * i as f64 / (n - 1).max(1) as f64).collect()
}

// -----------------------------------------------------------------------------------------------------------
// two-point

/// Runs `sim two-point`.
pub fn run_two_point(args: &TwoPointArgs) -> anyhow::Result<()> {
    let setup = TwoPointSetup::THESIS;
    if args.sweep {
        return run_sweep(args, &setup);
    }
    if args.distance_mm.is_empty() || args.distance_mm.iter().any(|d| !d.is_finite() || d.abs() > 1000.0) {
        bail!("--distance-mm must be finite and within ±1000 mm");
    }
    let results = args
        .distance_mm
        .iter()
        .map(|d| twopoint::simulate(&setup, *d).with_context(|| format!("fitting the sum at d = {d} mm")))
        .collect::<anyhow::Result<Vec<_>>>()?;
    if args.json {
        let text = match results.as_slice() {
            [one] => serde_json::to_string_pretty(one)?,
            many => serde_json::to_string_pretty(many)?,
        };
        println!("{text}");
    } else {
        println!(
            "two-point simulation (thesis §4.2): two tactors of {} m/s^2, b = {} mm, grid {}..{} mm ({} points)",
            setup.amplitude_m_s2,
            setup.width_mm,
            setup.grid_start_mm,
            setup.grid_end_mm,
            setup.grid_mm().len()
        );
        for r in &results {
            println!(
                "d = {:>6.2} mm: A = {:.4} m/s^2, mu = {:.4} mm, w = {:.4} mm, RMSE = {:.6} m/s^2",
                r.distance_mm, r.amplitude_m_s2, r.center_mm, r.width_mm, r.rmse
            );
        }
    }
    if let Some(path) = &args.png {
        let mut fig = Figure::new()
            .title("Two-point simulation (thesis Figs 60-63): two Gaussians and the single-Gaussian fit")
            .columns(2)
            .panel_size(640, 400);
        for r in &results {
            let (a, b) = two_point_charts(&setup, r);
            fig = fig.push(a).push(b);
        }
        save(&fig, path)?;
    }
    Ok(())
}

fn two_point_charts(setup: &TwoPointSetup, r: &TwoPointResult) -> (Chart, Chart) {
    let x = setup.grid_mm();
    let d = r.distance_mm;
    let g1: Vec<f64> = x.iter().map(|v| setup.single_m_s2(*v, 0.0)).collect();
    let g2: Vec<f64> = x.iter().map(|v| setup.single_m_s2(*v, d)).collect();
    let sum: Vec<f64> = x.iter().map(|v| setup.sum_m_s2(*v, d)).collect();
    let fit: Vec<f64> = x.iter().map(|v| r.eval(*v)).collect();
    let parts = Chart::new(format!("d = {d} mm: each tactor and the sum"))
        .x_label("position x [mm]")
        .y_label("acceleration amplitude [m/s^2]")
        .series(Series::line("tactor at 0 mm", x.clone(), g1).dashed())
        .series(Series::line(format!("tactor at {d} mm"), x.clone(), g2).dashed())
        .series(Series::line("sum", x.clone(), sum.clone()).width(2.5));
    let step = 6;
    let xs: Vec<f64> = x.iter().step_by(step).copied().collect();
    let ys: Vec<f64> = sum.iter().step_by(step).copied().collect();
    let fitted = Chart::new(format!(
        "d = {d} mm: fit A = {:.3}, mu = {:.2} mm, w = {:.2} mm, RMSE = {:.3e}",
        r.amplitude_m_s2, r.center_mm, r.width_mm, r.rmse
    ))
    .x_label("position x [mm]")
    .y_label("acceleration amplitude [m/s^2]")
    .series(Series::scatter("sum of two tactors", xs, ys).marker(Marker::Circle))
    .series(Series::line("single-Gaussian fit", x, fit).width(2.0))
    .vline(r.center_mm, "mu");
    (parts, fitted)
}

fn run_sweep(args: &TwoPointArgs, setup: &TwoPointSetup) -> anyhow::Result<()> {
    if !(args.max_mm.is_finite() && args.max_mm >= 1.0 && args.max_mm <= 1000.0) {
        bail!("--max-mm must be between 1 and 1000");
    }
    if !(args.relative_rmse > 0.0 && args.relative_rmse.is_finite()) {
        bail!("--relative-rmse must be positive");
    }
    let distances: Vec<f64> = (0..=args.max_mm.floor() as usize).map(|d| d as f64).collect();
    let results = twopoint::sweep(setup, &distances).context("sweeping the two-point fit")?;
    let threshold = twopoint::threshold_mm(setup, args.relative_rmse, args.max_mm)?;
    let sparrow = setup.sparrow_limit_mm();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&results)?);
    } else {
        println!("distance_mm  amplitude  center_mm  width_mm  rmse");
        for r in &results {
            println!(
                "{:>10.1} {:>10.4} {:>10.4} {:>9.4} {:>10.3e}",
                r.distance_mm, r.amplitude_m_s2, r.center_mm, r.width_mm, r.rmse
            );
        }
        match threshold {
            Some(t) => println!(
                "two-point threshold (RMSE >= {} x {} m/s^2 = {:.3} m/s^2): {t:.2} mm",
                args.relative_rmse,
                setup.amplitude_m_s2,
                args.relative_rmse * setup.amplitude_m_s2
            ),
            None => println!("two-point threshold: not reached up to {} mm", args.max_mm),
        }
        println!("profile becomes two-peaked (Sparrow limit sqrt(2) b): {sparrow:.2} mm");
    }
    if let Some(path) = &args.png {
        let d: Vec<f64> = results.iter().map(|r| r.distance_mm).collect();
        let rmse: Vec<f64> = results.iter().map(|r| r.rmse).collect();
        let level = args.relative_rmse * setup.amplitude_m_s2;
        let mut linear = Chart::new("RMSE of the single-Gaussian fit (b = 36.2 mm, 2 x 10 m/s^2)")
            .x_label("distance between tactors d [mm]")
            .y_label("RMSE [m/s^2]")
            .series(Series::line("", d.clone(), rmse.clone()).width(2.0))
            .hline(level, format!("detection level {level:.2} m/s^2"))
            .vline(sparrow, format!("two peaks (sqrt(2) b = {sparrow:.1} mm)"));
        if let Some(t) = threshold {
            linear = linear.vline(t, format!("threshold {t:.1} mm"));
        }
        let (d_log, r_log): (Vec<f64>, Vec<f64>) =
            d.iter().zip(&rmse).filter(|(x, y)| **x > 0.0 && **y > 0.0).map(|(x, y)| (*x, *y)).unzip();
        let c4 = r_log.first().zip(d_log.first()).map_or(0.0, |(r, d)| r / d.powi(4));
        let d4: Vec<f64> = d_log.iter().map(|x| c4 * x.powi(4)).collect();
        let mut log = Chart::new("The same on log-log axes: RMSE grows as d^4 for small d")
            .x_label("distance between tactors d [mm]")
            .y_label("RMSE [m/s^2]")
            .x_scale(Scale::Log10)
            .y_scale(Scale::Log10)
            .series(Series::line("RMSE", d_log.clone(), r_log).width(2.0))
            .series(Series::line("c d^4", d_log, d4).dashed())
            .hline(level, "detection level");
        if let Some(t) = threshold {
            log = log.vline(t, "threshold");
        }
        let fig = Figure::new()
            .title("Two-point threshold from the RMSE sweep (thesis §4.2)")
            .columns(2)
            .push(linear)
            .push(log);
        save(&fig.panel_size(640, 420), path)?;
    }
    Ok(())
}

// -----------------------------------------------------------------------------------------------------------
// wave

/// Runs `sim wave`.
pub fn run_wave(args: &WaveArgs) -> anyhow::Result<()> {
    check_options(args)?;
    match args.view {
        WaveView::Attenuation => attenuation(args),
        WaveView::Travelling => travelling(args),
        WaveView::Arrival => arrival(args),
        WaveView::Vest => vest_field(args),
        WaveView::Midpoint => midpoint(args),
    }
}

/// Refuses options that the chosen view would ignore, so no option silently does nothing.
fn check_options(args: &WaveArgs) -> anyhow::Result<()> {
    use WaveView::{Arrival, Attenuation, Midpoint, Travelling, Vest};
    let given: [(&str, bool, &[WaveView]); 8] = [
        ("--tactors", args.tactors.is_some(), &[Vest]),
        ("--spacing-mm", args.spacing_mm.is_some(), &[Vest]),
        ("--frequency-hz", args.frequency_hz.is_some(), &[Vest]),
        ("--time-s", args.time_s.is_some(), &[Vest, Travelling]),
        ("--duration-s", args.duration_s.is_some(), &[Travelling, Midpoint]),
        ("--distances-mm", args.distances_mm.is_some(), &[Travelling, Arrival]),
        ("--separation-mm", args.separation_mm.is_some(), &[Midpoint]),
        ("--fraction", args.fraction.is_some(), &[Attenuation]),
    ];
    for (name, set, views) in given {
        if set && !views.contains(&args.view) {
            bail!("{name} does not apply to --view {:?}", args.view);
        }
    }
    for v in [args.spacing_mm, args.frequency_hz, args.duration_s, args.separation_mm].into_iter().flatten() {
        if !(v > 0.0 && v.is_finite() && v < 1e6) {
            bail!("lengths, durations and frequencies must be positive and finite, got {v}");
        }
    }
    if args.time_s.is_some_and(|t| !t.is_finite()) {
        bail!("--time-s must be finite");
    }
    if args.duration_s.is_some_and(|d| d > 10.0) {
        bail!("--duration-s is limited to 10 s");
    }
    Ok(())
}

fn distances_m(args: &WaveArgs) -> anyhow::Result<Vec<f64>> {
    let mm = args.distances_mm.clone().unwrap_or_else(|| vec![0.0, 20.0, 37.0, 52.0]);
    if mm.is_empty() || mm.len() > 100 || mm.iter().any(|d| !(d.is_finite() && *d >= 0.0 && *d <= 1000.0)) {
        bail!("--distances-mm takes 1 to 100 distances between 0 and 1000 mm");
    }
    Ok(mm.iter().map(|d| d / 1000.0).collect())
}

fn attenuation(args: &WaveArgs) -> anyhow::Result<()> {
    let fraction = args.fraction.unwrap_or(wave::SPACING_RULE_FRACTION);
    let tactors: Vec<GaussianAttenuation> = FIG52_A0_M_S2
        .iter()
        .zip(FIG52_WIDTHS_M)
        .map(|(a0, b)| GaussianAttenuation { a0_m_s2: *a0, width_m: b })
        .collect();
    let spacing: Vec<f64> =
        tactors.iter().map(|t| t.distance_for_fraction_m(fraction)).collect::<Result<_, _>>()?;
    let mean_b = FIG52_WIDTHS_M.iter().sum::<f64>() / 3.0;
    let mean_spacing = wave::spacing_for_fraction_m(mean_b, fraction)?;
    let d_mm = range(0.0, 120.0, 241);
    if args.json {
        let rows: Vec<_> = tactors
            .iter()
            .zip(&spacing)
            .map(|(t, s)| {
                json!({
                    "a0_m_s2": t.a0_m_s2,
                    "width_mm": t.width_m * 1000.0,
                    "spacing_mm": s * 1000.0,
                    "amplitude_m_s2": d_mm.iter().map(|d| t.amplitude_m_s2(d / 1000.0)).collect::<Vec<_>>(),
                })
            })
            .collect();
        let out = json!({
            "fraction": fraction,
            "distance_mm": d_mm,
            "tactors": rows,
            "mean_width_mm": mean_b * 1000.0,
            "mean_spacing_mm": mean_spacing * 1000.0,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "Gaussian attenuation a = a0 exp(-(d/b)^2) (thesis §4.1.3, Fig 52); spacing rule: below {fraction} of a0"
        );
        for (t, s) in tactors.iter().zip(&spacing) {
            println!(
                "a0 = {:>5.2} m/s^2, b = {:>5.2} mm: falls to {:.0} % at d = {:.1} mm",
                t.a0_m_s2,
                t.width_m * 1000.0,
                fraction * 100.0,
                s * 1000.0
            );
        }
        println!("mean b = {:.1} mm: spacing {:.1} mm", mean_b * 1000.0, mean_spacing * 1000.0);
    }
    if let Some(path) = &args.png {
        let mut chart = Chart::new(format!(
            "Fig 52: amplitude versus distance (dashed: {:.0} % spacing rule for the mean b = {:.1} mm: {:.1} mm)",
            fraction * 100.0,
            mean_b * 1000.0,
            mean_spacing * 1000.0
        ))
            .x_label("distance from the tactor d [mm]")
            .y_label("acceleration amplitude [m/s^2]");
        for (i, (t, s)) in tactors.iter().zip(&spacing).enumerate() {
            let a: Vec<f64> = d_mm.iter().map(|d| t.amplitude_m_s2(d / 1000.0)).collect();
            let label = format!(
                "a0 = {} m/s^2, b = {:.2} mm ({:.0} % at {:.1} mm)",
                t.a0_m_s2,
                t.width_m * 1000.0,
                fraction * 100.0,
                s * 1000.0
            );
            chart = chart.series(Series::line(label, d_mm.clone(), a).width(2.0).color(Color::palette(i)));
            chart = chart.series(
                Series::scatter("", vec![s * 1000.0], vec![t.amplitude_m_s2(*s)])
                    .marker(Marker::Circle)
                    .color(Color::palette(i)),
            );
        }
        let chart = chart.vline(mean_spacing * 1000.0, "");
        save(&Figure::single(chart), path)?;
    }
    Ok(())
}

fn travelling(args: &WaveArgs) -> anyhow::Result<()> {
    let skin = Skin::MEASURED;
    let source = WaveSource::measured(DVec2::ZERO);
    let distances = distances_m(args)?;
    let t0 = args.time_s.unwrap_or(0.0);
    let duration = args.duration_s.unwrap_or(0.05);
    let n = ((duration * 10_000.0).round() as usize + 1).clamp(2, 100_001);
    let t = range(t0, t0 + duration, n);
    let traces: Vec<Vec<f64>> = distances
        .iter()
        .map(|d| t.iter().map(|ti| skin.wave_m_s2(&source, DVec2::new(*d, 0.0), *ti)).collect())
        .collect();
    let k = TAU * source.frequency_hz / skin.speed_m_s;
    if args.json {
        let out = json!({
            "frequency_hz": source.frequency_hz,
            "speed_m_s": skin.speed_m_s,
            "wavelength_mm": skin.wavelength_m(source.frequency_hz) * 1000.0,
            "distance_mm": distances.iter().map(|d| d * 1000.0).collect::<Vec<_>>(),
            "envelope_m_s2": distances
                .iter()
                .map(|d| source.envelope_m_s2(DVec2::new(*d, 0.0)))
                .collect::<Vec<_>>(),
            "phase_lag_rad": distances.iter().map(|d| k * d).collect::<Vec<_>>(),
            "delay_s": distances.iter().map(|d| d / skin.speed_m_s).collect::<Vec<_>>(),
            "time_s": t,
            "acceleration_m_s2": traces,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "travelling wave a0 exp(-(x/b)^2) sin(2 pi/lambda (x - c t)): a0 = {} m/s^2, b = {} mm, f = {:.1} Hz, c = {} m/s",
            source.amplitude_m_s2,
            source.width_m * 1000.0,
            source.frequency_hz,
            skin.speed_m_s
        );
        for d in &distances {
            println!(
                "x = {:>5.1} mm: envelope {:>6.3} m/s^2, phase lag {:>6.3} rad, delay {:>6.3} ms",
                d * 1000.0,
                source.envelope_m_s2(DVec2::new(*d, 0.0)),
                k * d,
                d / skin.speed_m_s * 1000.0
            );
        }
    }
    if let Some(path) = &args.png {
        let t_ms: Vec<f64> = t.iter().map(|v| v * 1000.0).collect();
        let mut chart = Chart::new("Fig 57: acceleration at several distances from the tactor (phase lag)")
            .x_label("time [ms]")
            .y_label("acceleration [m/s^2]");
        for (d, trace) in distances.iter().zip(traces) {
            chart = chart
                .series(Series::line(format!("x = {:.0} mm", d * 1000.0), t_ms.clone(), trace).width(1.8));
        }
        save(&Figure::single(chart), path)?;
    }
    Ok(())
}

fn arrival(args: &WaveArgs) -> anyhow::Result<()> {
    let skin = Skin::MEASURED;
    let source = WaveSource::measured(DVec2::ZERO);
    let distances = distances_m(args)?;
    let times = skin.arrival_times_s(&source, &distances, 10_000.0)?;
    let fit = wave::fit_wave_speed(&times, &distances)?;
    if args.json {
        let out = json!({
            "distance_mm": distances.iter().map(|d| d * 1000.0).collect::<Vec<_>>(),
            "arrival_s": times,
            "speed_m_s": fit.slope,
            "intercept_mm": fit.intercept * 1000.0,
            "r2": fit.r2,
            "model_speed_m_s": skin.speed_m_s,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        for (d, t) in distances.iter().zip(&times) {
            println!("x = {:>6.1} mm: crest arrives at {:>7.3} ms", d * 1000.0, t * 1000.0);
        }
        println!(
            "fitted wave speed (slope of distance vs time): {:.4} m/s (model {} m/s), R^2 = {:.6}",
            fit.slope, skin.speed_m_s, fit.r2
        );
    }
    if let Some(path) = &args.png {
        let t_ms: Vec<f64> = times.iter().map(|v| v * 1000.0).collect();
        let d_mm: Vec<f64> = distances.iter().map(|v| v * 1000.0).collect();
        let (lo, hi) = (t_ms.first().copied().unwrap_or(0.0), t_ms.last().copied().unwrap_or(1.0));
        let line_t = vec![lo, hi];
        let line_d: Vec<f64> = line_t.iter().map(|t| fit.eval(t / 1000.0) * 1000.0).collect();
        let chart =
            Chart::new(format!("Fig 59: distance versus arrival time, slope c = {:.3} m/s", fit.slope))
                .x_label("arrival time of the crest [ms]")
                .y_label("distance from the tactor [mm]")
                .series(Series::scatter("crest arrival (10 kHz traces)", t_ms, d_mm).marker(Marker::Circle))
                .series(
                    Series::line(
                        format!("fit: c = {:.3} m/s, R^2 = {:.4}", fit.slope, fit.r2),
                        line_t,
                        line_d,
                    )
                    .dashed(),
                );
        save(&Figure::single(chart), path)?;
    }
    Ok(())
}

fn vest_field(args: &WaveArgs) -> anyhow::Result<()> {
    let skin = Skin::MEASURED;
    let indices = args.tactors.clone().unwrap_or_else(|| vec![5]);
    if let Some(bad) = indices.iter().find(|i| **i >= TACTOR_COUNT) {
        bail!("tactor {bad} does not exist (0..{TACTOR_COUNT})");
    }
    let mask = TactorMask::from_indices(indices.iter().copied());
    let spacing_m = args.spacing_mm.unwrap_or(60.0) / 1000.0;
    let frequency = args.frequency_hz.unwrap_or(MEASURED_FREQUENCY_HZ);
    let t = args.time_s.unwrap_or(0.0);
    let template = WaveSource { frequency_hz: frequency, ..WaveSource::measured(DVec2::ZERO) };
    let sources = wave::vest_sources(mask, spacing_m, &template);
    let half = 2.5 * spacing_m;
    let n = 121;
    let axis = range(-half, half, n);
    let mut peak = Vec::with_capacity(n * n);
    let mut snap = Vec::with_capacity(n * n);
    for y in &axis {
        for x in &axis {
            let p = DVec2::new(*x, *y);
            peak.push(skin.peak_amplitude_m_s2(&sources, p));
            snap.push(skin.field_m_s2(&sources, p, t));
        }
    }
    let at_tactors: Vec<_> = (0..TACTOR_COUNT)
        .filter_map(|i| wave::tactor_position_m(i, spacing_m).map(|p| (i, p)))
        .map(|(i, p)| {
            json!({
                "tactor": i,
                "firing": mask.contains(i),
                "x_mm": p.x * 1000.0,
                "y_mm": p.y * 1000.0,
                "peak_m_s2": skin.peak_amplitude_m_s2(&sources, p),
            })
        })
        .collect();
    let rule = wave::spacing_for_fraction_m(template.width_m, wave::SPACING_RULE_FRACTION)?;
    if args.json {
        let out = json!({
            "tactors": indices,
            "spacing_mm": spacing_m * 1000.0,
            "frequency_hz": frequency,
            "time_s": t,
            "spacing_rule_mm": rule * 1000.0,
            "at_tactors": at_tactors,
            "grid": { "axis_mm": axis.iter().map(|v| v * 1000.0).collect::<Vec<_>>(),
                      "peak_m_s2": peak, "snapshot_m_s2": snap },
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "vest field: tactors {:?} firing at {frequency:.1} Hz, spacing {:.0} mm (spacing rule for b = {:.2} mm: {:.1} mm)",
            indices,
            spacing_m * 1000.0,
            template.width_m * 1000.0,
            rule * 1000.0
        );
        println!("peak amplitude at each tactor position [m/s^2], as seen from behind:");
        for row in 0..4 {
            let cells: Vec<String> = (0..4)
                .map(|col| {
                    let i = row * 4 + col;
                    let p = wave::tactor_position_m(i, spacing_m).unwrap_or_default();
                    let mark = if mask.contains(i) { '*' } else { ' ' };
                    format!("{i:>2}{mark}{:>7.3}", skin.peak_amplitude_m_s2(&sources, p))
                })
                .collect();
            println!("  {}", cells.join("  "));
        }
    }
    if let Some(path) = &args.png {
        let field =
            VestField { mask, indices: &indices, spacing_m, frequency, t, half_m: half, n, peak, snap };
        save(&vest_figure(field), path)?;
    }
    Ok(())
}

/// The computed vest field, for [`vest_figure`].
struct VestField<'a> {
    mask: TactorMask,
    indices: &'a [usize],
    spacing_m: f64,
    frequency: f64,
    t: f64,
    half_m: f64,
    n: usize,
    peak: Vec<f64>,
    snap: Vec<f64>,
}

fn vest_figure(f: VestField<'_>) -> Figure {
    let VestField { mask, indices, spacing_m, frequency, t, half_m: half, n, peak, snap } = f;
    let ext = (-half * 1000.0, half * 1000.0);
    let cell = 2.0 * half * 1000.0 / (n - 1) as f64;
    let extent = (ext.0 - cell / 2.0, ext.1 + cell / 2.0);
    let points: Vec<(f64, f64, String)> = (0..TACTOR_COUNT)
        .filter_map(|i| wave::tactor_position_m(i, spacing_m).map(|p| (i, p)))
        .map(|(i, p)| {
            (p.x * 1000.0, p.y * 1000.0, if mask.contains(i) { format!("{i}*") } else { i.to_string() })
        })
        .collect();
    let peak_map =
        Heatmap::new("Peak amplitude of the superposed waves (* = firing)", extent, extent, n, n, peak)
            .x_label("x, wearer's right [mm]")
            .y_label("y, up [mm]")
            .colorbar_label("peak |a| [m/s^2]")
            .equal_aspect()
            .points(points.clone());
    let snap_map = Heatmap::new(format!("Snapshot of a(x, y) at t = {t} s"), extent, extent, n, n, snap)
        .x_label("x, wearer's right [mm]")
        .y_label("y, up [mm]")
        .colorbar_label("a [m/s^2]")
        .equal_aspect()
        .points(points);
    Figure::new()
        .title(format!(
            "Vest field seen from behind: tactors {indices:?}, {:.0} mm spacing, {frequency:.1} Hz",
            spacing_m * 1000.0
        ))
        .columns(2)
        .panel_size(560, 480)
        .push(peak_map)
        .push(snap_map)
}

fn midpoint(args: &WaveArgs) -> anyhow::Result<()> {
    let skin = Skin::MEASURED;
    if args.duration_s.is_some() && args.png.is_none() {
        bail!("--duration-s sets the plotted window of --view midpoint: give --png too");
    }
    let separation = args.separation_mm.unwrap_or(80.0) / 1000.0;
    let (left, right) = wave::thesis_midpoint_pair(separation);
    let comps = wave::midpoint_components(&skin, &left, &right);
    let mid = (left.position_m + right.position_m) / 2.0;
    if args.json {
        let out = json!({
            "separation_mm": separation * 1000.0,
            "sources": [left, right],
            "components": comps,
            "thesis_predicted": [
                { "amplitude_m_s2": 3.02, "omega_rad_s": 334.3 },
                { "amplitude_m_s2": 3.45, "omega_rad_s": 444.8 },
            ],
            "thesis_fitted_amplitudes_m_s2": [2.43, 2.76],
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        let terms: Vec<String> = comps
            .iter()
            .map(|c| format!("{:.2} sin({:.1} t {:+.2})", c.amplitude_m_s2, c.omega_rad_s, c.phase_rad))
            .collect();
        println!("midpoint of two tactors {:.0} mm apart: a(t) = {}", separation * 1000.0, terms.join(" + "));
        println!(
            "thesis (80 mm): predicted 3.02 sin(334.3 t + c1) + 3.45 sin(444.8 t + c2), fitted 2.43 and 2.76"
        );
        println!(
            "sources: a0 = {} m/s^2, b = {:.2} mm at {:.1} Hz; a0 = {} m/s^2, b = {:.2} mm at {:.1} Hz",
            left.amplitude_m_s2,
            left.width_m * 1000.0,
            left.frequency_hz,
            right.amplitude_m_s2,
            right.width_m * 1000.0,
            right.frequency_hz
        );
    }
    if let Some(path) = &args.png {
        let duration = args.duration_s.unwrap_or(0.1);
        let n = ((duration * 10_000.0).round() as usize + 1).clamp(2, 100_001);
        let t = range(0.0, duration, n);
        let t_ms: Vec<f64> = t.iter().map(|v| v * 1000.0).collect();
        let total: Vec<f64> = t.iter().map(|ti| skin.field_m_s2(&[left, right], mid, *ti)).collect();
        let bound: f64 = comps.iter().map(|c| c.amplitude_m_s2).sum::<f64>().max(1e-9);

        let mut chart =
            Chart::new(format!("Signal halfway between two tactors {:.0} mm apart", separation * 1000.0))
                .x_label("time [ms]")
                .y_label("acceleration [m/s^2]")
                .y_range(-1.15 * bound, 1.8 * bound);
        for c in &comps {
            let y: Vec<f64> = t.iter().map(|ti| c.at(*ti)).collect();
            let label = format!("{:.2} sin({:.1} t + c)", c.amplitude_m_s2, c.omega_rad_s);
            chart = chart.series(Series::line(label, t_ms.clone(), y).dashed());
        }
        chart = chart.series(Series::line("sum at the midpoint", t_ms, total).width(2.0));
        save(&Figure::single(chart), path)?;
    }
    Ok(())
}
