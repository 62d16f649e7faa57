//! `vestnav fieldtest drift | cones`: GPS accuracy field tests (thesis §5) on NMEA logs and console
//! session logs.
//!
//! NMEA logs are decoded by `vestnav_device::gps` (one fix per epoch; operator marks are
//! `$PVNAV,MARK,<n>,<label>` sentences). Fix times come from the receiver's UTC time of day, unwrapped across
//! midnight; a fix without time is placed 1 s after the previous one (the receivers are 1 Hz).
//!
//! Console session logs (JSON Lines written by `vestnav_device::session_log`) give their `fix` and `mark`
//! records; times are the records' `t_s` (seconds since the session started), a mark's position is the one
//! the console recorded at the key press, or the latest fix at or before it when the record has none. The
//! format is chosen by `--format`, by default from the content (first non-blank byte `{` = session log).

use std::io::Read as _;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use chrono::{Datelike as _, NaiveTime, Timelike as _};
use clap::{Args, ValueEnum};
use vestnav_core::accuracy::Sample;
use vestnav_core::fieldtest::{
    ConeConfig, ConeMark, TimedFix, cones, drift, position_at, unwrap_time_of_day,
};
use vestnav_core::geo::{Earth, LatLon, declination_deg, true_from_magnetic_deg};
use vestnav_device::gps::decode_reader_with_marks;
use vestnav_device::session_log::{LogEntry, ReadMode, read_log_with};
use vestnav_report::fieldtest::{ConesReport, DriftReport, Source};
use vestnav_report::to_json;
use vestnav_station::fieldtests::receiver_sample;

/// Earth model on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum EarthArg {
    /// WGS-84 geodesics (default).
    Wgs84,
    /// The thesis's haversine on a 6372.795 km sphere.
    ThesisSphere,
}

impl From<EarthArg> for Earth {
    fn from(e: EarthArg) -> Self {
        match e {
            EarthArg::Wgs84 => Earth::Wgs84,
            EarthArg::ThesisSphere => Earth::ThesisSphere,
        }
    }
}

/// Format of a field-test log on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LogFormat {
    /// From the content: a console session log when the first non-blank byte is `{`, else NMEA.
    Auto,
    /// NMEA 0183, with `$PVNAV,MARK` sentences for the operator's marks.
    Nmea,
    /// The console's session log (JSON Lines with `fix` and `mark` records).
    Session,
}

impl LogFormat {
    fn name(self) -> &'static str {
        match self {
            LogFormat::Auto => "auto",
            LogFormat::Nmea => "nmea",
            LogFormat::Session => "session",
        }
    }
}

/// Arguments of `vestnav fieldtest drift`.
#[derive(Debug, Args)]
pub struct DriftArgs {
    /// Log of a stationary receiver: NMEA, or a console session log.
    pub file: PathBuf,
    /// Log format.
    #[arg(long, value_enum, default_value = "auto")]
    pub format: LogFormat,
    /// Earth model of the distances.
    #[arg(long, value_enum, default_value = "wgs84")]
    pub earth: EarthArg,
    /// Print one JSON object (keys `max_from_first_m`, `cep50_m`, `cep95_m`, `drms_m`, `twodrms_m`, `fixes`, ...).
    #[arg(long)]
    pub json: bool,
    /// Write a figure: scatter with CEP/2DRMS circles, and distance vs time (thesis Fig 65).
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Also measure the fixes against a known point (the accuracy statistics).
    #[command(flatten)]
    pub reference: crate::accuracy::ReferenceArgs,
}

/// Arguments of `vestnav fieldtest cones`.
#[derive(Debug, Args)]
pub struct ConesArgs {
    /// Log of the cone walk with a mark at each cone: NMEA with `$PVNAV,MARK` sentences, or a console session
    /// log with `mark` records (the M key / "Mark cone").
    pub file: PathBuf,
    /// Log format.
    #[arg(long, value_enum, default_value = "auto")]
    pub format: LogFormat,
    /// Nominal distance between consecutive cones [m].
    #[arg(long, default_value_t = 10.0)]
    pub spacing_m: f64,
    /// Expected number of cones (warns when the marks differ).
    #[arg(long)]
    pub count: Option<usize>,
    /// Bearing of the cone line [deg]; default: from the first mark to the last.
    #[arg(long)]
    pub line_bearing_deg: Option<f64>,
    /// The line bearing is magnetic (laid out by compass): convert it with the WMM declination at the first
    /// mark on the log's date (or with --declination-deg).
    #[arg(long)]
    pub magnetic: bool,
    /// Declination to use with --magnetic [deg, east positive] instead of the WMM (thesis: -15.4).
    #[arg(long, allow_negative_numbers = true)]
    pub declination_deg: Option<f64>,
    /// Earth model of the distances.
    #[arg(long, value_enum, default_value = "wgs84")]
    pub earth: EarthArg,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write a figure: track with the marks circled, consecutive distances with the RMSE line (Figs 67–70).
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Also measure each mark against where its cone stands: the reference is the first cone's surveyed
    /// position, the others follow at the spacing along the line bearing.
    #[command(flatten)]
    pub reference: crate::accuracy::ReferenceArgs,
}

/// An operator mark as read from a log.
struct LogMark {
    /// Time on the log's time line [s], if known.
    t_s: Option<f64>,
    /// Label (never empty).
    label: String,
    /// Position recorded with the mark, if any (session logs).
    pos: Option<LatLon>,
}

/// A decoded log: positioned fixes with times, the marks with times, and the first fix's date — the one
/// reading of a log for every `fieldtest` subcommand (`accuracy` and `compare` too).
pub(crate) struct Log {
    /// The format it was read as (never `Auto`).
    pub(crate) format: LogFormat,
    pub(crate) fixes: Vec<TimedFix>,
    /// Each fix's height above mean sea level (GGA altitude; session logs have none).
    heights: Vec<Option<f64>>,
    /// Whether each fix is good enough to average into a reference (`Fix::good_for_reference`; every fix
    /// of a session log, which records no quality).
    good: Vec<bool>,
    marks: Vec<LogMark>,
    date: Option<(i32, u8, u8)>,
    /// Rejected NMEA sentences, or skipped (cut-off) session-log lines.
    rejected: u64,
    /// Notes about the reading, passed on as warnings.
    warnings: Vec<String>,
}

impl Log {
    /// The fixes with their heights, for the accuracy statistics.
    pub(crate) fn samples(&self) -> Vec<Sample> {
        self.fixes
            .iter()
            .zip(&self.heights)
            .map(|(f, h)| Sample { t_s: f.t_s, pos: f.pos, height_m: *h })
            .collect()
    }

    /// The fixes good enough to average into a reference.
    pub(crate) fn good_samples(&self) -> Vec<Sample> {
        self.samples().into_iter().zip(&self.good).filter(|(_, g)| **g).map(|(s, _)| s).collect()
    }
}

fn seconds_of_day(t: NaiveTime) -> f64 {
    f64::from(t.num_seconds_from_midnight()) + f64::from(t.nanosecond()) / 1e9
}

/// Bytes looked at to recognise the format.
const SNIFF_BYTES: u64 = 64 * 1024;

/// Reads the log at `path` in `format` (`Auto`: decided from the first non-blank byte).
pub(crate) fn load(path: &Path, format: LogFormat) -> anyhow::Result<Log> {
    let format = match format {
        LogFormat::Auto => sniff(path)?,
        f => f,
    };
    match format {
        LogFormat::Session => load_session(path),
        _ => load_nmea(path),
    }
}

/// `Session` when the first non-blank byte (after a UTF-8 byte order mark) is `{`, else `Nmea`.
fn sniff(path: &Path) -> anyhow::Result<LogFormat> {
    let file = vestnav_files::open_regular(path).with_context(|| format!("opening {}", path.display()))?;
    let mut head = Vec::new();
    file.take(SNIFF_BYTES).read_to_end(&mut head).with_context(|| format!("reading {}", path.display()))?;
    let head = head.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&head);
    Ok(match head.iter().find(|b| !b.is_ascii_whitespace()) {
        Some(b'{') => LogFormat::Session,
        _ => LogFormat::Nmea,
    })
}

fn load_nmea(path: &Path) -> anyhow::Result<Log> {
    let file = vestnav_files::open_regular(path).with_context(|| format!("opening {}", path.display()))?;
    let (raw, marks, stats) = decode_reader_with_marks(std::io::BufReader::new(file))
        .with_context(|| format!("reading {}", path.display()))?;
    let (mut fixes, mut heights, mut good) = (Vec::new(), Vec::new(), Vec::new());
    let mut prev: Option<f64> = None;
    let mut date = None;
    for f in &raw {
        // The station's receivers side by side take their fixes by the same rule.
        let Some(s) = receiver_sample(f, prev) else { continue };
        prev = Some(s.t_s);
        if date.is_none() {
            date = f.time.map(|d| (d.year(), d.month() as u8, d.day() as u8));
        }
        fixes.push(TimedFix { t_s: s.t_s, pos: s.pos });
        heights.push(s.height_m);
        good.push(f.good_for_reference());
    }
    let first_t = fixes.first().map(|f| f.t_s);
    let marks = marks
        .into_iter()
        .map(|m| LogMark {
            t_s: m.time_of_day.map(|tod| unwrap_time_of_day(seconds_of_day(tod), first_t)),
            label: if m.label.is_empty() { format!("{}", m.number) } else { m.label },
            pos: None,
        })
        .collect();
    Ok(Log {
        format: LogFormat::Nmea,
        fixes,
        heights,
        good,
        marks,
        date,
        rejected: stats.rejected(),
        warnings: Vec::new(),
    })
}

/// `YYYY-MM-DD` at the start of an ISO-8601 time.
fn iso_date(utc: &str) -> Option<(i32, u8, u8)> {
    let d = chrono::NaiveDate::parse_from_str(utc.get(..10)?, "%Y-%m-%d").ok()?;
    Some((d.year(), u8::try_from(d.month()).ok()?, u8::try_from(d.day()).ok()?))
}

/// Reads a console session log with `vestnav_device::session_log`'s strict reader: its `fix` records become
/// the track, its `mark` records the marks (times = `t_s`, seconds since the session started). A malformed
/// line, an overlong line or session time going back is an error naming the line; a last line cut off
/// without its newline (the console stopped mid-write), a fix whose numbers are invalid and records of
/// unknown kinds are skipped, counted in `rejected_sentences` and named in the warnings (one bad fix never
/// poisons a log).
fn load_session(path: &Path) -> anyhow::Result<Log> {
    let (records, stats) = read_log_with(path, ReadMode::Strict)?;
    let mut log = Log {
        format: LogFormat::Session,
        fixes: Vec::new(),
        heights: Vec::new(),
        good: Vec::new(),
        marks: Vec::new(),
        date: None,
        rejected: stats.skipped() as u64,
        warnings: stats.examples.iter().map(|(line, why)| format!("line {line}: {why}")).collect(),
    };
    if stats.skipped() + stats.invalid_mark_positions > stats.examples.len() {
        log.warnings.push(format!(
            "{} lines skipped and {} mark positions removed in all (the first {} named above)",
            stats.skipped(),
            stats.invalid_mark_positions,
            stats.examples.len()
        ));
    }
    for rec in records {
        match rec.entry {
            LogEntry::Fix { lat_deg, lon_deg, .. } => {
                // The reader has checked the position's range (`check_fix`).
                let pos = LatLon::new(lat_deg, lon_deg);
                if log.date.is_none() {
                    log.date = iso_date(&rec.utc);
                }
                log.fixes.push(TimedFix { t_s: rec.t_s, pos });
            }
            LogEntry::Mark { label, lat_deg, lon_deg } => {
                let pos = lat_deg.zip(lon_deg).map(|(la, lo)| LatLon::new(la, lo));
                let label =
                    if label.trim().is_empty() { format!("mark {}", log.marks.len() + 1) } else { label };
                log.marks.push(LogMark { t_s: Some(rec.t_s), label, pos });
            }
            _ => {}
        }
    }
    // Records from different threads can be milliseconds out of order: the analysis wants time order.
    log.fixes.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    // Session logs carry no height or quality: every fix counts as good.
    log.heights = vec![None; log.fixes.len()];
    log.good = vec![true; log.fixes.len()];
    log.marks.sort_by(|a, b| a.t_s.unwrap_or(0.0).total_cmp(&b.t_s.unwrap_or(0.0)));
    Ok(log)
}

/// Runs `vestnav fieldtest drift`.
#[allow(clippy::print_stdout)]
pub fn run_drift(args: &DriftArgs) -> anyhow::Result<()> {
    let log = load(&args.file, args.format)?;
    let earth = Earth::from(args.earth);
    let mut s =
        drift(&log.fixes, earth).with_context(|| format!("{}: no positioned fixes", args.file.display()))?;
    s.warnings.extend(log.warnings.iter().cloned());
    let report = DriftReport::new(source(args.file.as_path(), &log), earth, None, Ok(s.clone()), &log.fixes);
    if args.reference.is_set() {
        let png = args.png.as_deref();
        return crate::accuracy::finish_drift(&args.file, &log, &args.reference, report, args.json, png);
    }
    if args.json {
        print!("{}", to_json(&report)?);
    } else {
        println!("{}: {} fixes over {:.0} s ({:?})", args.file.display(), s.fixes, s.duration_s, args.earth);
        println!("  mean position      {:.7}, {:.7}", s.mean.lat_deg, s.mean.lon_deg);
        println!("  max from first fix {:8.2} m   (thesis Fig 65: 1.17 m over 3 min)", s.max_from_first_m);
        println!("  max from mean      {:8.2} m", s.max_from_mean_m);
        println!(
            "  CEP50 / CEP95      {:8.2} / {:.2} m (nearest-rank percentiles about the mean)",
            s.cep50_m, s.cep95_m
        );
        println!("  DRMS / 2DRMS       {:8.2} / {:.2} m", s.drms_m, s.twodrms_m);
        println!("  sigma east / north {:8.2} / {:.2} m", s.sigma_en_m[0], s.sigma_en_m[1]);
        for w in &s.warnings {
            println!("  warning: {w}");
        }
    }
    if let Some(path) = &args.png {
        report.figure().save_png(path)?;
    }
    Ok(())
}

/// Where a log's fixes came from, for the reports.
pub(crate) fn source(path: &Path, log: &Log) -> Source {
    Source {
        file: Some(path.display().to_string()),
        format: log.format.name().to_string(),
        rejected_sentences: log.rejected,
    }
}

/// The log's marks as cone marks: the position recorded with the mark, else the latest fix at or before
/// its time ([`position_at`]). Also returns how many marks had no time (and were left out).
fn cone_marks(log: &Log) -> (Vec<ConeMark>, usize) {
    let mut marks = Vec::new();
    let mut untimed = 0;
    for m in &log.marks {
        let Some(t) = m.t_s else {
            untimed += 1;
            continue;
        };
        if let Some(pos) = m.pos.or_else(|| position_at(&log.fixes, t)) {
            marks.push(ConeMark { t_s: t, label: m.label.clone(), pos });
        }
    }
    (marks, untimed)
}

/// Runs `vestnav fieldtest cones`.
#[allow(clippy::print_stdout)]
pub fn run_cones(args: &ConesArgs) -> anyhow::Result<()> {
    if !(args.spacing_m.is_finite() && args.spacing_m > 0.0) {
        anyhow::bail!("--spacing-m must be a positive number of metres");
    }
    let log = load(&args.file, args.format)?;
    if log.fixes.is_empty() {
        anyhow::bail!("{}: no positioned fixes", args.file.display());
    }
    let (marks, untimed) = cone_marks(&log);
    let mut line_bearing = args.line_bearing_deg;
    let mut declination_used = None;
    if args.magnetic {
        let Some(b) = args.line_bearing_deg else {
            anyhow::bail!("--magnetic needs --line-bearing-deg");
        };
        let d = match (args.declination_deg, log.date, marks.first()) {
            (Some(d), _, _) => d,
            (None, Some((y, mo, da)), Some(m)) => declination_deg(m.pos, 0.0, y, mo, da)?,
            (None, None, _) => anyhow::bail!("the log has no date for the WMM: give --declination-deg"),
            (None, _, None) => anyhow::bail!("no marks"),
        };
        declination_used = Some(d);
        line_bearing = Some(true_from_magnetic_deg(b, d));
    }
    let config = ConeConfig {
        count: args.count,
        line_bearing_deg: line_bearing,
        earth: args.earth.into(),
        ..ConeConfig::with_spacing(args.spacing_m)
    };
    let mut s = cones(&marks, &log.fixes, &config)
        .with_context(|| format!("{}: {} timed marks", args.file.display(), marks.len()))?;
    if untimed > 0 {
        s.warnings.push(format!("{untimed} marks without a receiver time were ignored"));
    }
    s.warnings.extend(log.warnings.iter().cloned());
    let report = ConesReport::new(
        source(args.file.as_path(), &log),
        config,
        declination_used,
        Some(Ok(s.clone())),
        &marks,
        &log.fixes,
    );
    if args.reference.is_set() {
        return crate::accuracy::finish_cones(&args.reference, report, args.json, args.png.as_deref());
    }
    if args.json {
        print!("{}", to_json(&report)?);
    } else {
        println!(
            "{}: {} marks, nominal spacing {:.2} m, line bearing {:.1}° true",
            args.file.display(),
            s.marks,
            s.spacing_m,
            s.line_bearing_deg
        );
        for (k, d) in s.distances_m.iter().enumerate() {
            println!(
                "  {:>10} -> {:<10} {:7.2} m  (along {:7.2}, cross {:+6.2})",
                s.labels[k],
                s.labels[k + 1],
                d,
                s.along_m[k],
                s.cross_m[k]
            );
        }
        println!("  min / mean / max   {:.2} / {:.2} / {:.2} m", s.min_m, s.mean_m, s.max_m);
        println!(
            "  RMSE vs nominal    {:.2} m (along {:.2}, cross RMS {:.2})",
            s.rmse_m, s.along_rmse_m, s.cross_rms_m
        );
        for w in &s.warnings {
            println!("  warning: {w}");
        }
    }
    if let Some(path) = &args.png {
        report.figure().save_png(path)?;
    }
    Ok(())
}
