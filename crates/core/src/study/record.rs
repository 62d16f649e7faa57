//! Study results: one [`TrialRecord`] per trial, written as a tidy CSV (one row per trial, the columns of
//! [`CSV_COLUMNS`] in that order, RFC 4180 quoting) and as JSON, and the CSV read back with every value
//! checked (a results file may come from anywhere: bounded size, errors name the line).

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use super::protocol::Task;

/// Largest results CSV [`read_csv`] accepts [bytes] (a million trials of ~200 bytes).
pub const MAX_CSV_BYTES: usize = 256 << 20;
/// Longest field read back [bytes] (notes included).
pub const MAX_FIELD_BYTES: usize = 64 << 10;

/// How a trial ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Outcome {
    /// The wearer answered (the operator entered the response).
    Answered,
    /// No response was entered (e.g. skipped, timed out).
    NoResponse,
    /// The operator aborted the session during the trial.
    Aborted,
    /// STOP ALL (from any source) during the trial.
    Stopped,
    /// A navigation trial reached its end.
    Completed,
    /// The unit refused the stimulus (outside its limits).
    Refused,
    /// A navigation trial ended before its last waypoint: by the operator (End trial) or its time limit.
    Ended,
}

impl Outcome {
    /// Every outcome.
    pub const ALL: [Self; 7] = [
        Self::Answered,
        Self::NoResponse,
        Self::Aborted,
        Self::Stopped,
        Self::Completed,
        Self::Refused,
        Self::Ended,
    ];

    /// The name in the CSV's `outcome` column and the LSL markers.
    pub fn name(self) -> &'static str {
        match self {
            Self::Answered => "answered",
            Self::NoResponse => "no-response",
            Self::Aborted => "aborted",
            Self::Stopped => "stopped",
            Self::Completed => "completed",
            Self::Refused => "refused",
            Self::Ended => "ended",
        }
    }

    /// Parses [`Self::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|o| o.name() == name)
    }
}

/// One trial's result: one row of the results CSV.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrialRecord {
    /// Participant id.
    pub participant: String,
    /// Session id.
    pub session: String,
    /// Protocol name.
    pub protocol: String,
    /// Task kind.
    pub task: Task,
    /// 0-based block index.
    pub block: usize,
    /// Block name.
    pub block_name: String,
    /// 0-based trial index in the session.
    pub trial: usize,
    /// A training trial.
    pub training: bool,
    /// Feedback was given.
    pub feedback: bool,
    /// The stimulus's label.
    pub stimulus: String,
    /// The correct answer.
    pub answer: String,
    /// The response entered; `None` when there was none.
    pub response: Option<String>,
    /// Whether the response was the answer; `None` without a response.
    pub correct: Option<bool>,
    /// Stimulus onset on the session clock [s].
    pub stimulus_on_s: Option<f64>,
    /// Response time on the session clock [s].
    pub response_s: Option<f64>,
    /// Response time from stimulus onset [ms].
    pub rt_ms: Option<f64>,
    /// How the trial ended.
    pub outcome: Outcome,
    /// Navigation: time from start to the last waypoint [s].
    pub completion_s: Option<f64>,
    /// Navigation: distance walked [m].
    pub path_m: Option<f64>,
    /// Navigation: length of the route [m].
    pub route_m: Option<f64>,
    /// Navigation: RMS of the cross-track error [m].
    pub cross_track_rms_m: Option<f64>,
    /// Navigation: cues played.
    pub cues: Option<u32>,
    /// Navigation: stops (STOP ALL or stop cues) during the walk.
    pub stops: Option<u32>,
    /// Navigation: waypoints not reached.
    pub missed_waypoints: Option<u32>,
    /// The pause after this trial [ms]: its block's `iti_ms`, else the protocol's, else the station's.
    /// `None` in files from before the timing columns.
    #[serde(default)]
    pub iti_ms: Option<u32>,
    /// Feedback trials: how long feedback lasted at least [ms] (block > protocol > station).
    #[serde(default)]
    pub feedback_ms: Option<u32>,
    /// Localization and pattern trials: the response timeout the trial ran under [s]; `None`: the runner
    /// waited for the operator (or a file from before the timing columns).
    #[serde(default)]
    pub response_timeout_s: Option<f64>,
    /// Navigation: the trial's time limit [s].
    #[serde(default)]
    pub time_limit_s: Option<f64>,
    /// Free text from the operator or the runner.
    pub notes: String,
}

impl TrialRecord {
    /// A record with the trial's identity and everything else empty (outcome [`Outcome::NoResponse`]).
    pub fn new(participant: &str, session: &str, protocol: &str, task: Task) -> Self {
        Self {
            participant: participant.to_owned(),
            session: session.to_owned(),
            protocol: protocol.to_owned(),
            task,
            block: 0,
            block_name: String::new(),
            trial: 0,
            training: false,
            feedback: false,
            stimulus: String::new(),
            answer: String::new(),
            response: None,
            correct: None,
            stimulus_on_s: None,
            response_s: None,
            rt_ms: None,
            outcome: Outcome::NoResponse,
            completion_s: None,
            path_m: None,
            route_m: None,
            cross_track_rms_m: None,
            cues: None,
            stops: None,
            missed_waypoints: None,
            iti_ms: None,
            feedback_ms: None,
            response_timeout_s: None,
            time_limit_s: None,
            notes: String::new(),
        }
    }

    /// The path length over the route length (navigation), when both are known and the route is not empty.
    pub fn path_ratio(&self) -> Option<f64> {
        match (self.path_m, self.route_m) {
            (Some(p), Some(r)) if r > 0.0 => Some(p / r),
            _ => None,
        }
    }
}

/// How many columns [`CSV_COLUMNS`] has.
const COLUMNS: usize = 29;

/// The columns a results file may lack: the timing columns, added after the first results files were
/// written (read as empty then).
pub const OPTIONAL_COLUMNS: [&str; 4] = ["iti_ms", "feedback_ms", "response_timeout_s", "time_limit_s"];

/// The results CSV's columns, in order, each with its meaning (the same text as `docs/study.md`).
/// Empty cells mean "none / not applicable".
pub const CSV_COLUMNS: [(&str, &str); COLUMNS] = [
    ("participant", "participant id"),
    ("session", "session id"),
    ("protocol", "protocol name"),
    ("task", "localization, pattern-id or navigation"),
    ("block", "0-based block index in the protocol"),
    ("block_name", "the block's name"),
    ("trial", "0-based trial index in the session"),
    ("training", "1 for a training trial, 0 for a test trial"),
    ("feedback", "1 when the wearer was told the answer after responding"),
    ("stimulus", "what was presented: T0..T15, a set such as T0+T3, a pattern name, or ROUTE/CONDITION"),
    ("answer", "the correct answer (the stimulus's label)"),
    ("response", "the response entered; empty when none"),
    ("correct", "1 when response equals answer, 0 when not, empty without a response"),
    (
        "stimulus_on_s",
        "stimulus onset on the session clock (LSL clock when LSL is on, else seconds since the session started) [s]",
    ),
    ("response_s", "time the response was entered, same clock [s]"),
    ("rt_ms", "response time: response_s - stimulus_on_s [ms]"),
    (
        "outcome",
        "answered, no-response, aborted, stopped (STOP ALL during the trial), completed (navigation: the last waypoint reached), refused (the unit refused the stimulus), ended (navigation: ended by the operator or the time limit first)",
    ),
    ("completion_s", "navigation: time from start to the end of the route [s]"),
    ("path_m", "navigation: distance walked [m]"),
    (
        "route_m",
        "navigation: the route's length up to the last waypoint's arrival radius, the shortest walk that completes it [m]",
    ),
    ("cross_track_rms_m", "navigation: root mean square of the cross-track error [m]"),
    ("cues", "navigation: cues played"),
    ("stops", "navigation: stops during the walk"),
    ("missed_waypoints", "navigation: waypoints not reached"),
    (
        "iti_ms",
        "the pause after this trial: its block's iti_ms, else the protocol's, else the station's [ms]",
    ),
    (
        "feedback_ms",
        "feedback trials: how long feedback lasted at least (block, else protocol, else station) [ms]",
    ),
    (
        "response_timeout_s",
        "localization and pattern trials: the response timeout the trial ran under; empty: waited for the response [s]",
    ),
    ("time_limit_s", "navigation: the trial's time limit (block, else protocol, else station) [s]"),
    ("notes", "free text"),
];

/// Quotes a CSV field when it holds a comma, quote or line break (RFC 4180).
fn field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_owned() }
}

fn opt_f64(v: Option<f64>) -> String {
    v.filter(|x| x.is_finite()).map(|x| format!("{x}")).unwrap_or_default()
}

fn opt_u32(v: Option<u32>) -> String {
    v.map(|x| x.to_string()).unwrap_or_default()
}

fn flag(b: bool) -> &'static str {
    if b { "1" } else { "0" }
}

/// The CSV header line (with its line break).
pub fn csv_header() -> String {
    let mut s = CSV_COLUMNS.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(",");
    s.push('\n');
    s
}

/// One record as a CSV line (with its line break), columns as [`CSV_COLUMNS`]. Numbers are written in
/// Rust's shortest round-trip form, so [`read_csv`] gives back the same `f64`.
pub fn csv_row(r: &TrialRecord) -> String {
    let cells: [String; COLUMNS] = [
        field(&r.participant),
        field(&r.session),
        field(&r.protocol),
        r.task.name().to_owned(),
        r.block.to_string(),
        field(&r.block_name),
        r.trial.to_string(),
        flag(r.training).to_owned(),
        flag(r.feedback).to_owned(),
        field(&r.stimulus),
        field(&r.answer),
        r.response.as_deref().map(field).unwrap_or_default(),
        r.correct.map(|c| flag(c).to_owned()).unwrap_or_default(),
        opt_f64(r.stimulus_on_s),
        opt_f64(r.response_s),
        opt_f64(r.rt_ms),
        r.outcome.name().to_owned(),
        opt_f64(r.completion_s),
        opt_f64(r.path_m),
        opt_f64(r.route_m),
        opt_f64(r.cross_track_rms_m),
        opt_u32(r.cues),
        opt_u32(r.stops),
        opt_u32(r.missed_waypoints),
        opt_u32(r.iti_ms),
        opt_u32(r.feedback_ms),
        opt_f64(r.response_timeout_s),
        opt_f64(r.time_limit_s),
        field(&r.notes),
    ];
    let mut line = cells.join(",");
    line.push('\n');
    line
}

/// The whole results CSV: header and one row per record.
pub fn write_csv(rows: &[TrialRecord]) -> String {
    let mut out = csv_header();
    for r in rows {
        let _ = write!(out, "{}", csv_row(r));
    }
    out
}

/// The records as pretty-printed JSON (an array of objects with the CSV's fields).
pub fn write_json(rows: &[TrialRecord]) -> String {
    // Serializing plain strings, numbers and enums cannot fail.
    serde_json::to_string_pretty(rows).unwrap_or_default()
}

/// Why a results CSV was refused: the 1-based line and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("line {line}: {message}")]
pub struct CsvError {
    /// 1-based line of the file (a quoted field may span lines: the line it starts on).
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

/// Splits CSV text into records of fields (RFC 4180: quoted fields may hold commas, doubled quotes and
/// line breaks), each with the line it starts on. Blank lines are skipped.
fn split_records(text: &str) -> Result<Vec<(usize, Vec<String>)>, CsvError> {
    let mut out = Vec::new();
    let mut fields: Vec<String> = Vec::new();
    let mut cur = String::new();
    let (mut line, mut start_line) = (1usize, 1usize);
    let mut chars = text.chars().peekable();
    let mut in_quotes = false;
    let mut quoted_field = false;
    let too_long = |line| CsvError { line, message: format!("a field longer than {MAX_FIELD_BYTES} bytes") };
    while let Some(ch) = chars.next() {
        if in_quotes {
            match ch {
                '"' if chars.peek() == Some(&'"') => {
                    chars.next();
                    cur.push('"');
                }
                '"' => in_quotes = false,
                _ => {
                    if ch == '\n' {
                        line += 1;
                    }
                    cur.push(ch);
                }
            }
            if cur.len() > MAX_FIELD_BYTES {
                return Err(too_long(start_line));
            }
            continue;
        }
        match ch {
            '"' if cur.is_empty() && !quoted_field => {
                in_quotes = true;
                quoted_field = true;
            }
            '"' => return Err(CsvError { line, message: "a quote inside an unquoted field".to_owned() }),
            ',' => {
                fields.push(std::mem::take(&mut cur));
                quoted_field = false;
            }
            '\r' if chars.peek() == Some(&'\n') => {}
            '\n' | '\r' => {
                if !(fields.is_empty() && cur.is_empty() && !quoted_field) {
                    fields.push(std::mem::take(&mut cur));
                    out.push((start_line, std::mem::take(&mut fields)));
                }
                quoted_field = false;
                line += 1;
                start_line = line;
            }
            _ if quoted_field => {
                return Err(CsvError { line, message: "text after a closing quote".to_owned() });
            }
            _ => {
                cur.push(ch);
                if cur.len() > MAX_FIELD_BYTES {
                    return Err(too_long(line));
                }
            }
        }
    }
    if in_quotes {
        return Err(CsvError { line: start_line, message: "a quoted field is never closed".to_owned() });
    }
    if !(fields.is_empty() && cur.is_empty() && !quoted_field) {
        fields.push(cur);
        out.push((start_line, fields));
    }
    Ok(out)
}

/// Reads a results CSV written by [`write_csv`] (or edited in a spreadsheet): the header must name every
/// column of [`CSV_COLUMNS`] but the [`OPTIONAL_COLUMNS`] (in any order; extra columns are ignored), every
/// value is checked. At most [`MAX_CSV_BYTES`]; errors name the line.
pub fn read_csv(text: &str) -> Result<Vec<TrialRecord>, CsvError> {
    if text.len() > MAX_CSV_BYTES {
        return Err(CsvError { line: 1, message: format!("larger than {MAX_CSV_BYTES} bytes") });
    }
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let records = split_records(text)?;
    let Some((_, header)) = records.first() else {
        return Err(CsvError { line: 1, message: "empty file: no header".to_owned() });
    };
    // A column the file lacks reads as empty cells (index past every row).
    let mut col = [usize::MAX; COLUMNS];
    for (i, (name, _)) in CSV_COLUMNS.iter().enumerate() {
        match header.iter().position(|h| h.trim() == *name) {
            Some(at) => col[i] = at,
            None if OPTIONAL_COLUMNS.contains(name) => {}
            None => {
                return Err(CsvError {
                    line: 1,
                    message: format!(
                        "no column {name:?} in the header (is this a vestnav study results file?)"
                    ),
                });
            }
        }
    }
    records[1..].iter().map(|(line, cells)| parse_row(*line, cells, &col, header.len())).collect()
}

fn parse_row(
    line: usize,
    cells: &[String],
    col: &[usize; COLUMNS],
    width: usize,
) -> Result<TrialRecord, CsvError> {
    let err = |message: String| CsvError { line, message };
    if cells.len() != width {
        return Err(err(format!("{} fields, the header has {width}", cells.len())));
    }
    let get = |i: usize| cells.get(col[i]).map_or("", String::as_str);
    let name = |i: usize| CSV_COLUMNS[i].0;
    let text = |i: usize| get(i).to_owned();
    let opt_text = |i: usize| Some(get(i).to_owned()).filter(|s| !s.is_empty());
    let int = |i: usize| -> Result<usize, CsvError> {
        get(i).trim().parse::<usize>().map_err(|_| err(format!("{}: {:?} is not a count", name(i), get(i))))
    };
    let boolean = |i: usize| -> Result<Option<bool>, CsvError> {
        match get(i).trim() {
            "" => Ok(None),
            "1" | "true" | "TRUE" | "True" => Ok(Some(true)),
            "0" | "false" | "FALSE" | "False" => Ok(Some(false)),
            other => Err(err(format!("{}: {other:?} is not 0 or 1", name(i)))),
        }
    };
    let real = |i: usize| -> Result<Option<f64>, CsvError> {
        let s = get(i).trim();
        if s.is_empty() {
            return Ok(None);
        }
        s.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .map(Some)
            .ok_or_else(|| err(format!("{}: {s:?} is not a finite number", name(i))))
    };
    let count = |i: usize| -> Result<Option<u32>, CsvError> {
        let s = get(i).trim();
        if s.is_empty() {
            return Ok(None);
        }
        s.parse::<u32>().map(Some).map_err(|_| err(format!("{}: {s:?} is not a count", name(i))))
    };
    let task = Task::from_name(get(3).trim())
        .ok_or_else(|| err(format!("task: {:?} is not localization, pattern-id or navigation", get(3))))?;
    let outcome = Outcome::from_name(get(16).trim()).ok_or_else(|| {
        let all: Vec<&str> = Outcome::ALL.iter().map(|o| o.name()).collect();
        err(format!("outcome: {:?} is not one of {}", get(16), all.join(", ")))
    })?;
    Ok(TrialRecord {
        participant: text(0),
        session: text(1),
        protocol: text(2),
        task,
        block: int(4)?,
        block_name: text(5),
        trial: int(6)?,
        training: boolean(7)?.unwrap_or(false),
        feedback: boolean(8)?.unwrap_or(false),
        stimulus: text(9),
        answer: text(10),
        response: opt_text(11),
        correct: boolean(12)?,
        stimulus_on_s: real(13)?,
        response_s: real(14)?,
        rt_ms: real(15)?,
        outcome,
        completion_s: real(17)?,
        path_m: real(18)?,
        route_m: real(19)?,
        cross_track_rms_m: real(20)?,
        cues: count(21)?,
        stops: count(22)?,
        missed_waypoints: count(23)?,
        iti_ms: count(24)?,
        feedback_ms: count(25)?,
        response_timeout_s: real(26)?,
        time_limit_s: real(27)?,
        notes: text(28),
    })
}

/// Reads a results CSV file, at most [`MAX_CSV_BYTES`]; errors name the path and the line.
pub fn read_csv_file(path: &std::path::Path) -> Result<Vec<TrialRecord>, String> {
    use std::io::Read as _;
    let fail = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let meta = std::fs::metadata(path).map_err(|e| fail(&e))?;
    if !meta.is_file() {
        return Err(fail(&"not a regular file"));
    }
    let file = std::fs::File::open(path).map_err(|e| fail(&e))?;
    let mut bytes = Vec::new();
    file.take(MAX_CSV_BYTES as u64 + 1).read_to_end(&mut bytes).map_err(|e| fail(&e))?;
    if bytes.len() > MAX_CSV_BYTES {
        return Err(fail(&format!("larger than {MAX_CSV_BYTES} bytes")));
    }
    let text = String::from_utf8(bytes).map_err(|_| fail(&"not UTF-8 text"))?;
    read_csv(&text).map_err(|e| fail(&e))
}

#[cfg(test)]
#[path = "record_tests.rs"]
mod tests;
