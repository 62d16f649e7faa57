//! `vestnav analyze tactor-data`: measured tactor traces (thesis §3.1).
//!
//! Each file is one tactor (or one group of trials): an optional time column and one column per trial. Per
//! trial: peak frequency, steady amplitude, overshoot, 2 % settling time. Per file: mean, SD and range.
//! Across all files: the power law `f = A n^B` (frequency against amplitude) with R^2. With exactly two
//! files: two-sample t-tests (Welch and pooled) of peak frequency and amplitude between them.

#![allow(clippy::print_stdout)] // Printing the results is this module's job.
#![allow(rustdoc::broken_intra_doc_links)] // Units in brackets in the clap help texts ([mm]) are not links.

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use vestnav_core::analysis::{self, Butterworth, Stats, TTestKind, TimeColumn, TraceSummary};
use vestnav_report::analysis::{AnalysisReport, GroupTests as GroupReport, TTestPair, TrialReport};

/// Largest input file read [bytes]: 512 MiB of CSV is far beyond any 10 kHz trial set.
const MAX_FILE_BYTES: u64 = 512 * 1024 * 1024;

/// Whether the files' first column is time.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum TimeColumnArg {
    /// Time if the header names it (`t`, `time`, `time_s`, `time_ms`, ...) or, without a header, if the first
    /// column increases in uniform steps.
    Auto,
    /// The first column is time.
    Yes,
    /// Every column is a trial.
    No,
}

/// `vestnav analyze tactor-data`
#[derive(Debug, Args)]
pub struct TactorDataArgs {
    /// CSV files, one per tactor: an optional time column and one column per trial.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Sample rate [Hz] when the files have no time column.
    #[arg(long, default_value_t = 10_000.0)]
    pub sample_rate_hz: f64,
    /// Whether the first column is time.
    #[arg(long, value_enum, default_value = "auto")]
    pub time_column: TimeColumnArg,
    /// Low-pass the traces first (5th-order Butterworth, zero phase) at this cutoff [Hz].
    #[arg(long)]
    pub lowpass_hz: Option<f64>,
    /// Print as JSON.
    #[arg(long)]
    pub json: bool,
}

struct Trial {
    name: String,
    result: Result<TraceSummary, String>,
}

struct FileReport {
    path: PathBuf,
    sample_rate_hz: f64,
    time_from_file: bool,
    trials: Vec<Trial>,
}

impl FileReport {
    fn ok(&self) -> impl Iterator<Item = &TraceSummary> {
        self.trials.iter().filter_map(|t| t.result.as_ref().ok())
    }

    fn stat(&self, f: impl Fn(&TraceSummary) -> f64) -> Option<Stats> {
        Stats::of(&self.ok().map(f).collect::<Vec<_>>())
    }
}

fn read_file(path: &PathBuf, args: &TactorDataArgs) -> anyhow::Result<FileReport> {
    let size = std::fs::metadata(path).with_context(|| format!("reading {}", path.display()))?.len();
    if size > MAX_FILE_BYTES {
        bail!("{}: {size} bytes is larger than the {MAX_FILE_BYTES}-byte limit", path.display());
    }
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        anyhow::anyhow!(
            "{}: not UTF-8 text (invalid byte at offset {})",
            path.display(),
            e.utf8_error().valid_up_to()
        )
    })?;
    let time = match args.time_column {
        TimeColumnArg::Auto => TimeColumn::Auto,
        TimeColumnArg::Yes => TimeColumn::Present,
        TimeColumnArg::No => TimeColumn::Absent,
    };
    let set =
        analysis::parse_csv(&text, time, args.sample_rate_hz).with_context(|| path.display().to_string())?;
    let filter = match args.lowpass_hz {
        Some(fc) => Some(
            Butterworth::lowpass(5, fc, set.sample_rate_hz)
                .with_context(|| format!("{}: low-pass at {fc} Hz", path.display()))?,
        ),
        None => None,
    };
    let trials = set
        .names
        .iter()
        .zip(&set.traces)
        .map(|(name, trace)| {
            let result = match &filter {
                Some(f) => f.filtfilt(trace).and_then(|y| analysis::analyze_trace(&y, set.sample_rate_hz)),
                None => analysis::analyze_trace(trace, set.sample_rate_hz),
            };
            Trial { name: name.clone(), result: result.map_err(|e| e.to_string()) }
        })
        .collect();
    Ok(FileReport {
        path: path.clone(),
        sample_rate_hz: set.sample_rate_hz,
        time_from_file: set.time_from_file,
        trials,
    })
}

/// Runs `analyze tactor-data`.
pub fn run_tactor_data(args: &TactorDataArgs) -> anyhow::Result<()> {
    if let Some(fc) = args.lowpass_hz
        && !(fc > 0.0 && fc.is_finite())
    {
        bail!("--lowpass-hz must be positive");
    }
    let files = args.files.iter().map(|p| read_file(p, args)).collect::<anyhow::Result<Vec<_>>>()?;
    let all: Vec<TraceSummary> = files.iter().flat_map(FileReport::ok).copied().collect();
    let power_law = analysis::frequency_power_law(&all).map_err(|e| e.to_string());
    let tests = match files.as_slice() {
        [a, b] => Some(two_group_tests(a, b)),
        _ => None,
    };
    let failed = files.iter().flat_map(|f| &f.trials).filter(|t| t.result.is_err()).count();
    if args.json {
        print_json(args, &files, &power_law, tests.as_ref())?;
    } else {
        print_text(args, &files, &power_law, tests.as_ref());
    }
    if failed > 0 {
        bail!("{failed} trial(s) could not be analysed (see above)");
    }
    Ok(())
}

struct GroupTests {
    frequency: [Result<analysis::TTest, String>; 2],
    amplitude: [Result<analysis::TTest, String>; 2],
}

fn two_group_tests(a: &FileReport, b: &FileReport) -> GroupTests {
    let vals = |f: &FileReport, g: fn(&TraceSummary) -> f64| f.ok().map(g).collect::<Vec<_>>();
    let run = |g: fn(&TraceSummary) -> f64| {
        let (x, y) = (vals(a, g), vals(b, g));
        [TTestKind::Welch, TTestKind::Pooled].map(|k| analysis::t_test(&x, &y, k).map_err(|e| e.to_string()))
    };
    GroupTests { frequency: run(|t| t.peak_frequency_hz), amplitude: run(|t| t.steady_amplitude) }
}

fn print_json(
    args: &TactorDataArgs,
    files: &[FileReport],
    power_law: &Result<vestnav_core::fit::PowerLawFit, String>,
    tests: Option<&GroupTests>,
) -> anyhow::Result<()> {
    let pair = |r: &[Result<analysis::TTest, String>; 2]| TTestPair {
        welch: r[0].clone().into(),
        pooled: r[1].clone().into(),
    };
    let report = AnalysisReport {
        files: files
            .iter()
            .map(|f| vestnav_report::analysis::FileReport {
                path: f.path.display().to_string(),
                sample_rate_hz: f.sample_rate_hz,
                time_from_file: f.time_from_file,
                lowpass_hz: args.lowpass_hz,
                trials: f
                    .trials
                    .iter()
                    .map(|t| TrialReport { name: t.name.clone(), outcome: t.result.clone().into() })
                    .collect(),
                peak_frequency_hz: f.stat(|t| t.peak_frequency_hz),
                steady_amplitude: f.stat(|t| t.steady_amplitude),
                overshoot_pct: f.stat(|t| t.overshoot_pct),
                settling_time_s: f.stat(|t| t.settling_time_s),
            })
            .collect(),
        power_law: power_law.clone().into(),
        t_test: tests.map(|g| GroupReport {
            peak_frequency_hz: pair(&g.frequency),
            steady_amplitude: pair(&g.amplitude),
        }),
    };
    print!("{}", vestnav_report::to_json(&report)?);
    Ok(())
}

fn print_stat(name: &str, s: Option<Stats>) {
    match s {
        Some(s) => println!(
            "  {name:<22} mean {:>10.4}  sd {:>9.4}  range {:>10.4} .. {:>10.4} (n = {})",
            s.mean, s.sd, s.min, s.max, s.n
        ),
        None => println!("  {name:<22} no analysable trial"),
    }
}

fn print_test(label: &str, r: &Result<analysis::TTest, String>) {
    match r {
        Ok(t) => println!(
            "  {label:<34} t = {:>8.4}, df = {:>7.2}, p = {:.4e} (mean difference {:.4})",
            t.t, t.df, t.p_value, t.mean_difference
        ),
        Err(e) => println!("  {label:<34} not available: {e}"),
    }
}

fn print_text(
    args: &TactorDataArgs,
    files: &[FileReport],
    power_law: &Result<vestnav_core::fit::PowerLawFit, String>,
    tests: Option<&GroupTests>,
) {
    for f in files {
        println!(
            "{}: {} trial(s), {} Hz ({}){}",
            f.path.display(),
            f.trials.len(),
            f.sample_rate_hz,
            if f.time_from_file { "from the time column" } else { "as given" },
            args.lowpass_hz
                .map(|fc| format!(", low-passed at {fc} Hz (5th order, zero phase)"))
                .unwrap_or_default()
        );
        println!(
            "  {:<16} {:>11} {:>11} {:>11} {:>11}",
            "trial", "f_peak[Hz]", "amplitude", "overshoot%", "settling[s]"
        );
        for t in &f.trials {
            match &t.result {
                Ok(s) => println!(
                    "  {:<16} {:>11.3} {:>11.4} {:>11.2} {:>11.4}",
                    t.name, s.peak_frequency_hz, s.steady_amplitude, s.overshoot_pct, s.settling_time_s
                ),
                Err(e) => println!("  {:<16} error: {e}", t.name),
            }
        }
        print_stat("peak frequency [Hz]", f.stat(|t| t.peak_frequency_hz));
        print_stat("amplitude", f.stat(|t| t.steady_amplitude));
        print_stat("overshoot [%]", f.stat(|t| t.overshoot_pct));
        print_stat("settling time [s]", f.stat(|t| t.settling_time_s));
    }
    match power_law {
        Ok(p) => println!(
            "power law over all trials: f = {:.4} n^{:.4}, R^2 = {:.4} (n = amplitude)",
            p.coefficient, p.exponent, p.r2
        ),
        Err(e) => println!("power law over all trials: not available: {e}"),
    }
    if let (Some(g), [a, b]) = (tests, files) {
        println!("two-sample t-tests, {} vs {} (two-sided):", a.path.display(), b.path.display());
        print_test("peak frequency, Welch", &g.frequency[0]);
        print_test("peak frequency, pooled variance", &g.frequency[1]);
        print_test("amplitude, Welch", &g.amplitude[0]);
        print_test("amplitude, pooled variance", &g.amplitude[1]);
    }
}
