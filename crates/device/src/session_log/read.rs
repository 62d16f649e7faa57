//! Reading session logs back: one reader, two policies ([`ReadMode`]), bounded memory per line, fixes
//! validated, errors naming the file and line.

use std::collections::BTreeMap;
use std::fmt;
use std::io::{self, BufRead};
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::{EntryKind, LogEntry, LogRecord, MAX_LINE_BYTES};

/// Why a fix record was rejected by [`read_log`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FixProblem {
    /// Latitude or longitude is NaN or infinite.
    NonFinitePosition,
    /// Latitude outside [-90, 90] or longitude outside [-180, 180].
    OutOfRangePosition,
    /// Negative (or non-finite) horizontal error estimate.
    BadError,
    /// Negative (or non-finite) speed.
    BadSpeed,
}

impl fmt::Display for FixProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::NonFinitePosition => "non-finite position",
            Self::OutOfRangePosition => "position out of range",
            Self::BadError => "negative or non-finite error estimate",
            Self::BadSpeed => "negative or non-finite speed",
        })
    }
}

/// Checks a fix's numbers: finite latitude in [-90, 90], longitude in [-180, 180], error and speed (when
/// present) finite and not negative.
pub fn check_fix(
    lat_deg: f64,
    lon_deg: f64,
    error_m: Option<f64>,
    speed_m_s: Option<f64>,
) -> Result<(), FixProblem> {
    if !(lat_deg.is_finite() && lon_deg.is_finite()) {
        return Err(FixProblem::NonFinitePosition);
    }
    if lat_deg.abs() > 90.0 || lon_deg.abs() > 180.0 {
        return Err(FixProblem::OutOfRangePosition);
    }
    let ok = |v: Option<f64>| v.is_none_or(|v| v.is_finite() && v >= 0.0);
    if !ok(error_m) {
        return Err(FixProblem::BadError);
    }
    if !ok(speed_m_s) {
        return Err(FixProblem::BadSpeed);
    }
    Ok(())
}

/// What [`read_log`] skipped, and why.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct ReadStats {
    /// Lines read (blank ones included).
    pub lines: usize,
    /// Records kept.
    pub records: usize,
    /// Lines that were not valid records (cut off, edited, foreign, non-finite `t_s`).
    pub bad_lines: usize,
    /// Lines longer than [`MAX_LINE_BYTES`], skipped unread.
    pub long_lines: usize,
    /// Well-formed records of a kind this version does not know (a newer console's), skipped.
    pub other_kinds: usize,
    /// Fix records rejected, by reason.
    pub invalid_fixes: BTreeMap<FixProblem, usize>,
    /// Marks whose position was invalid: kept, with the position removed.
    pub invalid_mark_positions: usize,
    /// Line numbers (1-based) of the first few skipped lines, with the reason, for the operator.
    pub examples: Vec<(usize, String)>,
}

impl ReadStats {
    /// Fix records rejected, all reasons.
    pub fn invalid_fix_count(&self) -> usize {
        self.invalid_fixes.values().sum()
    }

    /// Lines skipped for any reason (bad, too long, unknown kind, invalid fix).
    pub fn skipped(&self) -> usize {
        self.bad_lines + self.long_lines + self.other_kinds + self.invalid_fix_count()
    }

    fn note(&mut self, line: usize, why: String) {
        if self.examples.len() < 10 {
            self.examples.push((line, why));
        }
    }
}

/// Errors of [`read_log`]; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum LogReadError {
    /// The file could not be opened.
    #[error("cannot open session log {}: {source}", path.display())]
    Open {
        /// The file.
        path: PathBuf,
        /// Why.
        source: io::Error,
    },
    /// A line the strict reader ([`ReadMode::Strict`]) refuses; `reason` says what is wrong with it.
    #[error("{}:{line}: {reason}", path.display())]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// Reading failed part-way.
    #[error("cannot read session log {} at line {line}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// 1-based line number being read.
        line: usize,
        /// Why.
        source: io::Error,
    },
}

/// How a reader treats a line it cannot use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ReadMode {
    /// Skip and count every unusable line (the console's log viewer: a damaged log still shows).
    #[default]
    Lenient,
    /// Refuse the file at the first malformed line, overlong line or backward step of session time, naming
    /// the line (the field tests: an analysis must not silently lose part of a walk). Still skipped and
    /// counted: a last line cut off without its newline after valid records (the console stopped
    /// mid-write), records of kinds this version does not know, and fixes whose numbers fail
    /// [`check_fix`] (one bad fix never poisons a log).
    Strict,
}

/// In [`ReadMode::Strict`], how far session time may step back between records before the file is taken for
/// several sessions appended together \[s\] (records from different threads are milliseconds out of order).
pub const MAX_TIME_BACKSTEP_S: f64 = 1.0;

/// Reads a session log leniently ([`ReadMode::Lenient`]): the valid records in file order and what was
/// skipped.
pub fn read_log(path: &Path) -> Result<(Vec<LogRecord>, ReadStats), LogReadError> {
    read_log_with(path, ReadMode::Lenient)
}

/// Reads a session log with the given policy: the valid records in file order and what was skipped.
pub fn read_log_with(path: &Path, mode: ReadMode) -> Result<(Vec<LogRecord>, ReadStats), LogReadError> {
    let file = std::fs::File::open(path)
        .map_err(|source| LogReadError::Open { path: path.to_path_buf(), source })?;
    read_log_from(io::BufReader::new(file), mode).map_err(|e| match e {
        LineError::Io(line, source) => LogReadError::Read { path: path.to_path_buf(), line, source },
        LineError::Refused(line, reason) => LogReadError::Line { path: path.to_path_buf(), line, reason },
    })
}

/// Why [`read_log_from`] stopped, with the 1-based line number.
#[derive(Debug)]
pub enum LineError {
    /// Reading failed.
    Io(usize, io::Error),
    /// The strict reader refused the line, for this reason.
    Refused(usize, String),
}

/// Reads session-log lines from any reader with the given policy.
pub fn read_log_from(
    mut reader: impl BufRead,
    mode: ReadMode,
) -> Result<(Vec<LogRecord>, ReadStats), LineError> {
    let strict = mode == ReadMode::Strict;
    let mut records = Vec::new();
    let mut stats = ReadStats::default();
    let mut buf = Vec::new();
    let mut latest_t: Option<f64> = None;
    loop {
        let line_no = stats.lines + 1;
        let Some(line) =
            next_line(&mut reader, &mut buf, MAX_LINE_BYTES).map_err(|e| LineError::Io(line_no, e))?
        else {
            break;
        };
        stats.lines += 1;
        if !line.fits {
            if strict {
                return Err(LineError::Refused(
                    line_no,
                    format!("line longer than {} KiB: not a session log", MAX_LINE_BYTES / 1024),
                ));
            }
            stats.long_lines += 1;
            stats.note(line_no, format!("longer than {MAX_LINE_BYTES} bytes"));
            continue;
        }
        let mut text = buf.trim_ascii();
        if line_no == 1 {
            text = text.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(text);
        }
        if text.is_empty() {
            continue;
        }
        let mut rec = match parse_record(text) {
            Parsed::Record(rec) => rec,
            Parsed::OtherKind(kind) => {
                stats.other_kinds += 1;
                stats.note(line_no, format!("record of unknown kind {kind:?} skipped"));
                continue;
            }
            Parsed::Bad(reason) => {
                if strict && (line.terminated || records.is_empty()) {
                    return Err(LineError::Refused(line_no, reason));
                }
                stats.bad_lines += 1;
                let why = if line.terminated {
                    reason
                } else {
                    format!("line {line_no} is cut off (the console stopped mid-write?): {reason}")
                };
                stats.note(line_no, why);
                continue;
            }
        };
        if strict {
            if let Some(p) = latest_t
                && rec.t_s < p - MAX_TIME_BACKSTEP_S
            {
                return Err(LineError::Refused(
                    line_no,
                    format!(
                        "session time goes back from {p:.3} s to {:.3} s: several sessions appended in one \
                         file? Split it at this line",
                        rec.t_s
                    ),
                ));
            }
            latest_t = Some(latest_t.map_or(rec.t_s, |p| p.max(rec.t_s)));
        }
        match &mut rec.entry {
            LogEntry::Fix { lat_deg, lon_deg, error_m, speed_m_s, .. } => {
                if let Err(p) = check_fix(*lat_deg, *lon_deg, *error_m, *speed_m_s) {
                    *stats.invalid_fixes.entry(p).or_default() += 1;
                    let why = match p {
                        FixProblem::NonFinitePosition | FixProblem::OutOfRangePosition => {
                            format!("fix skipped: position {lat_deg}, {lon_deg}: {p}")
                        }
                        FixProblem::BadError | FixProblem::BadSpeed => format!("fix skipped: {p}"),
                    };
                    stats.note(line_no, why);
                    continue;
                }
            }
            LogEntry::Mark { lat_deg, lon_deg, .. } => {
                let bad = match (*lat_deg, *lon_deg) {
                    (Some(la), Some(lo)) => check_fix(la, lo, None, None).is_err(),
                    (None, None) => false,
                    _ => true,
                };
                if bad {
                    (*lat_deg, *lon_deg) = (None, None);
                    stats.invalid_mark_positions += 1;
                    stats.note(line_no, "mark kept without its invalid position".into());
                }
            }
            _ => {}
        }
        records.push(rec);
    }
    stats.records = records.len();
    Ok((records, stats))
}

/// One line's content, classified.
enum Parsed {
    Record(LogRecord),
    /// Well-formed, with a `kind` this version does not know.
    OtherKind(String),
    /// Not a usable record, and why.
    Bad(String),
}

fn parse_record(text: &[u8]) -> Parsed {
    let err = match serde_json::from_slice::<LogRecord>(text) {
        Ok(r) if r.t_s.is_finite() => return Parsed::Record(r),
        Ok(r) => {
            return Parsed::Bad(format!("bad {} record (t_s is not a finite number)", r.entry.kind().tag()));
        }
        Err(e) => e,
    };
    // Only lines that failed are parsed a second time, to say precisely what is wrong.
    let value: serde_json::Value = match serde_json::from_slice(text) {
        Ok(v) => v,
        Err(e) => return Parsed::Bad(format!("not JSON ({e})")),
    };
    match value.get("kind").and_then(serde_json::Value::as_str) {
        None => Parsed::Bad("no \"kind\" field: not a session-log record".into()),
        Some(kind) if !EntryKind::ALL.iter().any(|k| k.tag() == kind) => Parsed::OtherKind(kind.to_owned()),
        Some(kind) => Parsed::Bad(format!("bad {kind} record ({err})")),
    }
}

/// What [`next_line`] read.
struct Line {
    /// The line fitted in the limit (else it was consumed and `buf` left empty).
    fits: bool,
    /// It ended with `\n` (only the file's last line can lack one).
    terminated: bool,
}

/// Reads the next line (without its `\n`) into `buf`, holding at most `max` bytes; `None` at the end.
fn next_line(reader: &mut impl BufRead, buf: &mut Vec<u8>, max: usize) -> io::Result<Option<Line>> {
    buf.clear();
    let mut fits = true;
    let mut any = false;
    loop {
        let available = match reader.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if available.is_empty() {
            return Ok(any.then_some(Line { fits, terminated: false }));
        }
        any = true;
        let (take, done) = match available.iter().position(|&b| b == b'\n') {
            Some(i) => (i, true),
            None => (available.len(), false),
        };
        if fits {
            if buf.len() + take > max {
                fits = false;
                buf.clear();
            } else {
                buf.extend_from_slice(&available[..take]);
            }
        }
        reader.consume(take + usize::from(done));
        if done {
            return Ok(Some(Line { fits, terminated: true }));
        }
    }
}

/// The positions of a log, as `(t_s, lat_deg, lon_deg)`.
pub fn track(records: &[LogRecord]) -> Vec<(f64, f64, f64)> {
    records
        .iter()
        .filter_map(|r| match r.entry {
            LogEntry::Fix { lat_deg, lon_deg, .. } => Some((r.t_s, lat_deg, lon_deg)),
            _ => None,
        })
        .collect()
}

/// Session logs (`*.jsonl`) in `dir`, newest first (by name, which starts with the UTC time).
pub fn list_logs(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| {
            d.flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|e| e == "jsonl")).collect()
        })
        .unwrap_or_default();
    v.sort();
    v.reverse();
    v
}
