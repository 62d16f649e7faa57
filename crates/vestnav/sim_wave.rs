//! `vestnav sim two-point | wave`: skin waves and the two-point simulation from the command line.

#![allow(clippy::print_stdout)] // Printing the results is this module's job.
#![allow(rustdoc::broken_intra_doc_links)] // Units in brackets in the clap help texts ([mm]) are not links.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use vestnav_core::twopoint::{self, TwoPointSetup};
use vestnav_core::vest::TACTOR_COUNT;
use vestnav_core::wave::{self, DVec2, Skin, WaveSource};
use vestnav_report::twopoint::{RmseSweep, fits, fits_figure, fits_json};
use vestnav_report::wave::{
    Arrival, Attenuation, DEFAULT_MIDPOINT_S, DEFAULT_SEPARATION_MM, DEFAULT_TRAVELLING_S,
    DEFAULT_VEST_SPACING_MM, Midpoint, THESIS_DISTANCES_MM, Travelling, VestField, VestFieldInputs,
};
use vestnav_report::{Figure, to_json};

/// `vestnav sim two-point`
#[derive(Debug, Args)]
pub struct TwoPointArgs {
    /// Distance(s) between the two tactors [mm], comma-separated (one pair of panels each in the figure).
    #[arg(long, value_delimiter = ',', default_value = "11", allow_negative_numbers = true)]
    pub distance_mm: Vec<f64>,
    /// Sweep the RMSE over distances 0..=max-mm in 1 mm steps instead (prints a JSON array with --json).
    #[arg(long)]
    pub sweep: bool,
    /// Largest distance of the sweep [mm].
    #[arg(long, default_value_t = 100.0, allow_negative_numbers = true)]
    pub max_mm: f64,
    /// Detection level of the two-point threshold: RMSE as a fraction of one tactor's amplitude.
    #[arg(long, default_value_t = twopoint::DEFAULT_RELATIVE_RMSE, allow_negative_numbers = true)]
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

/// Writes the figure; the error names the file (no context added: it would name it twice).
fn save(figure: &Figure, path: &Path) -> anyhow::Result<()> {
    Ok(figure.save_png(path)?)
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
        bail!("--distance-mm must be finite and within ±1000 mm (got {:?})", args.distance_mm);
    }
    let results = fits(&setup, &args.distance_mm).context("fitting the sum of the two tactors")?;
    if args.json {
        print!("{}", fits_json(&results)?);
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
        save(&fits_figure(&setup, &results), path)?;
    }
    Ok(())
}

fn run_sweep(args: &TwoPointArgs, setup: &TwoPointSetup) -> anyhow::Result<()> {
    if !(args.max_mm.is_finite() && args.max_mm >= 1.0 && args.max_mm <= 1000.0) {
        bail!("--max-mm must be between 1 and 1000");
    }
    if !(args.relative_rmse > 0.0 && args.relative_rmse.is_finite()) {
        bail!("--relative-rmse must be positive");
    }
    let sweep =
        RmseSweep::compute(setup, args.max_mm, args.relative_rmse).context("sweeping the two-point fit")?;
    if args.json {
        print!("{}", to_json(&sweep.results)?);
    } else {
        println!("distance_mm  amplitude  center_mm  width_mm  rmse");
        for r in &sweep.results {
            println!(
                "{:>10.1} {:>10.4} {:>10.4} {:>9.4} {:>10.3e}",
                r.distance_mm, r.amplitude_m_s2, r.center_mm, r.width_mm, r.rmse
            );
        }
        match sweep.threshold_mm {
            Some(t) => println!(
                "two-point threshold (RMSE >= {} x {} m/s^2 = {:.3} m/s^2): {t:.2} mm",
                args.relative_rmse,
                setup.amplitude_m_s2,
                args.relative_rmse * setup.amplitude_m_s2
            ),
            None => println!("two-point threshold: not reached up to {} mm", args.max_mm),
        }
        println!("profile becomes two-peaked (Sparrow limit sqrt(2) b): {:.2} mm", setup.sparrow_limit_mm());
    }
    if let Some(path) = &args.png {
        save(&vestnav_report::twopoint::sweep_figure(&sweep), path)?;
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

fn distances_mm(args: &WaveArgs) -> anyhow::Result<Vec<f64>> {
    let mm = args.distances_mm.clone().unwrap_or_else(|| THESIS_DISTANCES_MM.to_vec());
    if mm.is_empty() || mm.len() > 100 || mm.iter().any(|d| !(d.is_finite() && *d >= 0.0 && *d <= 1000.0)) {
        bail!("--distances-mm takes 1 to 100 distances between 0 and 1000 mm");
    }
    Ok(mm)
}

fn attenuation(args: &WaveArgs) -> anyhow::Result<()> {
    let fraction = args.fraction.unwrap_or(wave::SPACING_RULE_FRACTION);
    let a = Attenuation::compute(fraction)?;
    if args.json {
        print!("{}", to_json(&a)?);
    } else {
        println!(
            "Gaussian attenuation a = a0 exp(-(d/b)^2) (thesis §4.1.3, Fig 52); spacing rule: below {fraction} of a0"
        );
        for t in &a.tactors {
            println!(
                "a0 = {:>5.2} m/s^2, b = {:>5.2} mm: falls to {:.0} % at d = {:.1} mm",
                t.a0_m_s2,
                t.width_mm,
                fraction * 100.0,
                t.spacing_mm
            );
        }
        println!("mean b = {:.1} mm: spacing {:.1} mm", a.mean_width_mm, a.mean_spacing_mm);
    }
    if let Some(path) = &args.png {
        save(&a.figure(), path)?;
    }
    Ok(())
}

fn travelling(args: &WaveArgs) -> anyhow::Result<()> {
    let skin = Skin::MEASURED;
    let source = WaveSource::measured(DVec2::ZERO);
    let tr = Travelling::compute(
        &skin,
        &source,
        &distances_mm(args)?,
        args.time_s.unwrap_or(0.0),
        args.duration_s.unwrap_or(DEFAULT_TRAVELLING_S),
    );
    if args.json {
        print!("{}", to_json(&tr)?);
    } else {
        println!(
            "travelling wave a0 exp(-(x/b)^2) sin(2 pi/lambda (x - c t)): a0 = {} m/s^2, b = {} mm, f = {:.1} Hz, c = {} m/s",
            source.amplitude_m_s2,
            source.width_m * 1000.0,
            source.frequency_hz,
            skin.speed_m_s
        );
        for (k, d) in tr.distance_mm.iter().enumerate() {
            println!(
                "x = {:>5.1} mm: envelope {:>6.3} m/s^2, phase lag {:>6.3} rad, delay {:>6.3} ms",
                d,
                tr.envelope_m_s2[k],
                tr.phase_lag_rad[k],
                tr.delay_s[k] * 1000.0
            );
        }
    }
    if let Some(path) = &args.png {
        save(&tr.figure(), path)?;
    }
    Ok(())
}

fn arrival(args: &WaveArgs) -> anyhow::Result<()> {
    let skin = Skin::MEASURED;
    let a = Arrival::compute(&skin, &WaveSource::measured(DVec2::ZERO), &distances_mm(args)?)?;
    if args.json {
        print!("{}", to_json(&a)?);
    } else {
        for (d, t) in a.distance_mm.iter().zip(&a.arrival_s) {
            println!("x = {d:>6.1} mm: crest arrives at {:>7.3} ms", t * 1000.0);
        }
        println!(
            "fitted wave speed (slope of distance vs time): {:.4} m/s (model {} m/s), R^2 = {:.6}",
            a.speed_m_s, a.model_speed_m_s, a.r2
        );
    }
    if let Some(path) = &args.png {
        save(&a.figure(), path)?;
    }
    Ok(())
}

fn vest_field(args: &WaveArgs) -> anyhow::Result<()> {
    let defaults = VestFieldInputs::default();
    let tactors = args.tactors.clone().unwrap_or(defaults.tactors);
    if let Some(bad) = tactors.iter().find(|i| **i >= TACTOR_COUNT) {
        bail!("tactor {bad} does not exist (0..{TACTOR_COUNT})");
    }
    let inputs = VestFieldInputs {
        tactors,
        spacing_mm: args.spacing_mm.unwrap_or(DEFAULT_VEST_SPACING_MM),
        source: WaveSource {
            frequency_hz: args.frequency_hz.unwrap_or(defaults.source.frequency_hz),
            ..defaults.source
        },
        skin: defaults.skin,
        time_s: args.time_s.unwrap_or(0.0),
    };
    let field = VestField::compute(&inputs)?;
    if args.json {
        print!("{}", to_json(&field)?);
    } else {
        println!(
            "vest field: tactors {:?} firing at {:.1} Hz, spacing {:.0} mm (spacing rule for b = {:.2} mm: {:.1} mm)",
            field.tactors, field.frequency_hz, field.spacing_mm, field.width_mm, field.spacing_rule_mm
        );
        println!("peak amplitude at each tactor position [m/s^2], as seen from behind:");
        for row in field.at_tactors.chunks(4) {
            let cells: Vec<String> = row
                .iter()
                .map(|t| format!("{:>2}{}{:>7.3}", t.tactor, if t.firing { '*' } else { ' ' }, t.peak_m_s2))
                .collect();
            println!("  {}", cells.join("  "));
        }
    }
    if let Some(path) = &args.png {
        save(&field.figure(), path)?;
    }
    Ok(())
}

fn midpoint(args: &WaveArgs) -> anyhow::Result<()> {
    let skin = Skin::MEASURED;
    if args.duration_s.is_some() && args.png.is_none() {
        bail!("--duration-s sets the plotted window of --view midpoint: give --png too");
    }
    let m = Midpoint::compute(&skin, args.separation_mm.unwrap_or(DEFAULT_SEPARATION_MM));
    if args.json {
        print!("{}", to_json(&m)?);
    } else {
        let terms: Vec<String> = m
            .components
            .iter()
            .map(|c| format!("{:.2} sin({:.1} t {:+.2})", c.amplitude_m_s2, c.omega_rad_s, c.phase_rad))
            .collect();
        println!("midpoint of two tactors {:.0} mm apart: a(t) = {}", m.separation_mm, terms.join(" + "));
        println!(
            "thesis (80 mm): predicted 3.02 sin(334.3 t + c1) + 3.45 sin(444.8 t + c2), fitted 2.43 and 2.76"
        );
        let [left, right] = &m.sources;
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
        save(&m.figure(&skin, args.duration_s.unwrap_or(DEFAULT_MIDPOINT_S)), path)?;
    }
    Ok(())
}
