//! `vestnav fieldtest accuracy | compare`, and the `--reference` of `fieldtest drift | cones`: GPS
//! accuracy against a known point, and several receivers side by side (core's `accuracy`, figures and JSON
//! from vestnav-report).
//!
//! Fixes are read by `fieldtest`'s one log reader (NMEA/UBX/SiRF logs through `vestnav_device::gps`, times
//! from the receiver's UTC time of day; console session logs through the strict session-log reader), with
//! their height above mean sea level (GGA altitude) and whether the fix is good enough to average into a
//! reference (`Fix::good_for_reference`). A typed or waypoint reference is made by the station's
//! `fieldtests`, the same as the console's.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use clap::Args;
use vestnav_core::accuracy::{
    Receiver, Reference, accuracy, average_reference, compare, cones_against_reference,
};
use vestnav_core::fieldtest::{ConeStats, DriftStats};
use vestnav_core::geo::Earth;
use vestnav_report::accuracy::{
    AccuracyReport, AgainstReference, CONES_AGAINST_LABEL, CompareReport, DRIFT_AGAINST_LABEL, accuracy_rows,
};
use vestnav_report::fieldtest::{ConesReport, DriftReport};
use vestnav_report::to_json;
use vestnav_station::fieldtests::{typed_reference, waypoint_reference};

use crate::fieldtest::{EarthArg, Log, LogFormat, load, source};

/// Where the truth comes from (one of `--reference`, `--reference-gpx`, `--reference-average-s`).
#[derive(Debug, Args, Default)]
pub struct ReferenceArgs {
    /// The reference position, typed: decimal (`42.3573, -71.1010`), DMS (`42°21'26.3"N 71°06'03.6"W`),
    /// UTM (`19T 327588 4691263`) or MGRS (`19TCG2758891263`).
    #[arg(long, value_name = "POSITION", allow_hyphen_values = true, group = "reference_source")]
    pub reference: Option<String>,
    /// The reference is a waypoint of this GPX file (with --waypoint NAME; default: its only waypoint).
    #[arg(long, value_name = "FILE.gpx", group = "reference_source")]
    pub reference_gpx: Option<PathBuf>,
    /// The waypoint of --reference-gpx to use.
    #[arg(long, value_name = "NAME", requires = "reference_gpx")]
    pub waypoint: Option<String>,
    /// The reference is the mean of the first SECONDS of good fixes (3-D, position-bearing quality) of the
    /// log (of the first log with `compare`). It hides the receiver's bias: accuracy against it is precision.
    #[arg(long, value_name = "SECONDS", group = "reference_source")]
    pub reference_average_s: Option<f64>,
    /// The reference's stated horizontal uncertainty [m] (1 sigma; the survey's figure). An averaged
    /// reference states its own.
    #[arg(long, value_name = "METRES", default_value_t = 0.0)]
    pub reference_uncertainty_m: f64,
    /// The reference's height above mean sea level [m], for the vertical error.
    #[arg(long, value_name = "METRES", allow_negative_numbers = true)]
    pub reference_height_m: Option<f64>,
}

impl ReferenceArgs {
    /// Whether a reference was asked for.
    pub fn is_set(&self) -> bool {
        self.reference.is_some() || self.reference_gpx.is_some() || self.reference_average_s.is_some()
    }
}

/// Arguments of `vestnav fieldtest accuracy`.
#[derive(Debug, Args)]
pub struct AccuracyArgs {
    /// Log of the receiver (still on the marker, or walking a surveyed line): NMEA/UBX, or a console
    /// session log.
    pub file: PathBuf,
    /// The truth.
    #[command(flatten)]
    pub reference: ReferenceArgs,
    /// Log format.
    #[arg(long, value_enum, default_value = "auto")]
    pub format: LogFormat,
    /// Earth model of the distances.
    #[arg(long, value_enum, default_value = "wgs84")]
    pub earth: EarthArg,
    /// Print one JSON object (keys `cep50_m`, `cep95_m`, `drms_m`, `bias_en_m`, `within`, `vertical`, ...).
    #[arg(long)]
    pub json: bool,
    /// Write the accuracy sheet: error against time, scatter about the reference with the CEP circles,
    /// share within each radius.
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// Arguments of `vestnav fieldtest compare`.
#[derive(Debug, Args)]
pub struct CompareArgs {
    /// Logs of two or more receivers recorded at the same time (NMEA/UBX; their UTC times are matched).
    #[arg(required = true, num_args = 2..)]
    pub files: Vec<PathBuf>,
    /// The truth, if known.
    #[command(flatten)]
    pub reference: ReferenceArgs,
    /// Epochs of two receivers match when their times differ by at most this [s].
    #[arg(long, default_value_t = 0.1)]
    pub tolerance_s: f64,
    /// Log format (of every file).
    #[arg(long, value_enum, default_value = "auto")]
    pub format: LogFormat,
    /// Earth model of the distances.
    #[arg(long, value_enum, default_value = "wgs84")]
    pub earth: EarthArg,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write one figure with every receiver.
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// The reference the arguments name; `log` is averaged for `--reference-average-s`.
pub fn resolve_reference(args: &ReferenceArgs, log: Option<&Log>, earth: Earth) -> anyhow::Result<Reference> {
    let u = args.reference_uncertainty_m;
    if !(u.is_finite() && u >= 0.0) {
        anyhow::bail!("--reference-uncertainty-m must be a non-negative number of metres");
    }
    if args.reference_height_m.is_some_and(|h| !h.is_finite()) {
        anyhow::bail!("--reference-height-m must be a number of metres");
    }
    let h = args.reference_height_m;
    let reference = if let Some(text) = &args.reference {
        typed_reference(text, u, h).map_err(|e| anyhow::anyhow!("--reference: {e}"))?
    } else if let Some(gpx) = &args.reference_gpx {
        waypoint_reference(gpx, args.waypoint.as_deref(), u, h)
            .map_err(|e| anyhow::anyhow!("--reference-gpx: {e}"))?
    } else if let Some(window_s) = args.reference_average_s {
        let log = log.context("--reference-average-s needs a log")?;
        let good = log.good_samples();
        let from = good.first().map_or(0.0, |s| s.t_s);
        let mut r = average_reference(&good, from, window_s, earth).context("averaging the reference")?;
        if h.is_some() {
            r.height_m = h;
        }
        r
    } else {
        anyhow::bail!("give a reference: --reference, --reference-gpx or --reference-average-s");
    };
    Ok(reference)
}

/// Runs `vestnav fieldtest accuracy`.
#[allow(clippy::print_stdout)]
pub fn run_accuracy(args: &AccuracyArgs) -> anyhow::Result<()> {
    let earth = Earth::from(args.earth);
    let log = load(&args.file, args.format)?;
    let reference = resolve_reference(&args.reference, Some(&log), earth)?;
    let samples = log.samples();
    let stats = accuracy(&samples, &reference, earth)
        .with_context(|| format!("{}: no positioned fixes", args.file.display()))?;
    let report =
        AccuracyReport::new(source(&args.file, &log), earth, reference.clone(), Ok(stats.clone()), &samples);
    if args.json {
        print!("{}", to_json(&report)?);
    } else {
        println!("{}: against the reference {}", args.file.display(), reference.describe());
        print_rows(&accuracy_rows(&stats));
        for w in &stats.warnings {
            println!("  warning: {w}");
        }
    }
    if let Some(path) = &args.png {
        report.figure().save_png(path)?;
    }
    Ok(())
}

#[allow(clippy::print_stdout)]
fn print_rows(rows: &[(&str, String)]) {
    for (name, value) in rows {
        println!("  {name:<32} {value}");
    }
}

/// Runs `vestnav fieldtest compare`.
#[allow(clippy::print_stdout)]
pub fn run_compare(args: &CompareArgs) -> anyhow::Result<()> {
    let earth = Earth::from(args.earth);
    let logs: Vec<Log> = args.files.iter().map(|f| load(f, args.format)).collect::<anyhow::Result<_>>()?;
    let reference = if args.reference.is_set() {
        Some(resolve_reference(&args.reference, logs.first(), earth)?)
    } else {
        None
    };
    let receivers: Vec<Receiver> = args
        .files
        .iter()
        .zip(&logs)
        .map(|(f, l)| Receiver {
            name: f.file_name().map_or_else(|| f.display().to_string(), |n| n.to_string_lossy().into_owned()),
            samples: l.samples(),
        })
        .collect();
    let comparison = compare(&receivers, reference.as_ref(), args.tolerance_s, earth)?;
    let report = CompareReport {
        test: "compare".into(),
        sources: args.files.iter().zip(&logs).map(|(f, l)| source(f, l)).collect(),
        earth,
        reference_point: reference.clone(),
        comparison: comparison.clone(),
        tracks: logs.iter().map(Log::samples).collect(),
    };
    if args.json {
        print!("{}", to_json(&report)?);
    } else {
        println!(
            "{} receivers, {} epochs matched within {} s",
            comparison.names.len(),
            comparison.matched_epochs,
            comparison.tolerance_s
        );
        if let Some(r) = &reference {
            println!("reference {}", r.describe());
        }
        for d in &comparison.differences {
            println!(
                "  {} - {}: mean east/north {:+.3} / {:+.3} m, RMS {:.3} m, P95 {:.3} m, max {:.3} m",
                d.name,
                comparison.names.first().map_or("", String::as_str),
                d.mean_en_m[0],
                d.mean_en_m[1],
                d.rms_m,
                d.p95_m,
                d.max_m
            );
        }
        for (name, s) in comparison.names.iter().zip(&comparison.against_reference) {
            if let Some(s) = s {
                println!("{name} against the reference:");
                print_rows(&accuracy_rows(s));
            }
        }
        for w in &comparison.warnings {
            println!("  warning: {w}");
        }
    }
    if let Some(path) = &args.png {
        report.figure().save_png(path)?;
    }
    Ok(())
}

/// `fieldtest drift --reference ...`: the drift report with the fixes against the reference; prints it
/// (JSON or text) and writes the figure.
#[allow(clippy::print_stdout)]
pub(crate) fn finish_drift(
    file: &Path,
    log: &Log,
    reference: &ReferenceArgs,
    report: DriftReport,
    json: bool,
    png: Option<&Path>,
) -> anyhow::Result<()> {
    let earth = report.earth;
    let reference = resolve_reference(reference, Some(log), earth)?;
    let stats = accuracy(&log.samples(), &reference, earth).map_err(|e| e.to_string());
    let both = AgainstReference::new(report, reference, stats);
    if json {
        print!("{}", to_json(&both)?);
    } else {
        if let Some(s) = &both.test.stats {
            print_drift(file, s);
        }
        print_against(
            &both.reference_point,
            both.against_reference.as_ref(),
            both.against_reference_error.as_deref(),
        );
    }
    if let Some(path) = png {
        both.figure(DriftReport::figure, DRIFT_AGAINST_LABEL).save_png(path)?;
    }
    Ok(())
}

#[allow(clippy::print_stdout)]
fn print_drift(file: &Path, s: &DriftStats) {
    println!("{}: {} fixes over {:.0} s", file.display(), s.fixes, s.duration_s);
    print_rows(&vestnav_report::fieldtest::drift_rows(s));
    for w in &s.warnings {
        println!("  warning: {w}");
    }
}

#[allow(clippy::print_stdout)]
fn print_against(
    reference: &Reference,
    s: Option<&vestnav_core::accuracy::AccuracyStats>,
    error: Option<&str>,
) {
    println!("against the reference {}:", reference.describe());
    if let Some(s) = s {
        print_rows(&accuracy_rows(s));
        for w in &s.warnings {
            println!("  warning: {w}");
        }
    }
    if let Some(e) = error {
        println!("  no statistics: {e}");
    }
}

/// `fieldtest cones --reference ...`: the cone report with each mark against where its cone stands (the
/// reference is the first cone; the others follow at the spacing along the line bearing).
#[allow(clippy::print_stdout)]
pub fn finish_cones(
    reference: &ReferenceArgs,
    report: ConesReport,
    json: bool,
    png: Option<&Path>,
) -> anyhow::Result<()> {
    let earth = report.earth;
    if reference.reference_average_s.is_some() {
        anyhow::bail!(
            "a cone test's reference is the first cone's surveyed position: use --reference or --reference-gpx"
        );
    }
    let reference = resolve_reference(reference, None, earth)?;
    let stats = match &report.stats {
        Some(s) => {
            cones_against_reference(&report.cone_marks, &reference, s.line_bearing_deg, s.spacing_m, earth)
                .map_err(|e| e.to_string())
        }
        None => Err("no cone statistics".to_string()),
    };
    let both = AgainstReference::new(report, reference, stats);
    if json {
        print!("{}", to_json(&both)?);
    } else {
        if let Some(s) = &both.test.stats {
            print_cones(s);
        }
        print_against(
            &both.reference_point,
            both.against_reference.as_ref(),
            both.against_reference_error.as_deref(),
        );
    }
    if let Some(path) = png {
        both.figure(ConesReport::figure, CONES_AGAINST_LABEL).save_png(path)?;
    }
    Ok(())
}

#[allow(clippy::print_stdout)]
fn print_cones(s: &ConeStats) {
    println!(
        "{} marks, nominal spacing {:.2} m, line bearing {:.1}° true: mean {:.2} m, RMSE {:.2} m",
        s.marks, s.spacing_m, s.line_bearing_deg, s.mean_m, s.rmse_m
    );
    for w in &s.warnings {
        println!("  warning: {w}");
    }
}
