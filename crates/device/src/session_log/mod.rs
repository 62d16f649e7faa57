//! The console's session log: every position, vest command, ack and operator mark, written as it happens.
//!
//! Format: JSON Lines, one [`LogRecord`] per line, UTF-8, appended and flushed by a dedicated writer thread
//! that owns the file (the UI and the workers only hand records over a bounded channel and never touch the
//! disk). A line looks like `{"t_s":12.03,"utc":"2026-11-22T18:00:12.030Z","kind":"fix","lat_deg":42.3562,...}`;
//! `t_s` is seconds since the session started, `utc` the wall clock. Files are named
//! `session-YYYYmmdd-HHMMSS.jsonl` in the log directory. This module is the only reader and writer of the
//! format: the console, the CLI (`fieldtest`) and the simulator all use it.
//!
//! **Bounded.** [`LogSender::log`] never blocks: when the queue is full the record is dropped and counted.
//! Commands and marks have a reserved share of the queue, so a flood of fixes cannot crowd them out. The
//! writer coalesces floods per entry kind ([`RateLimits`]: by default at most 20 fixes, 50 acks, 50
//! tactor reports and 50 notes per second of session time; commands and marks are never rate-limited) and
//! writes a note `"N fix events dropped (flood)"` once per second while a flood lasts and when it ends, so
//! a gpsd or unit flood produces a file of bounded size while every command and mark is kept.
//!
//! **Storage failures are shown, not silent.** A full disk, a read-only or failing medium does not stop
//! the writer: it holds records in memory (bounded), counts what it must drop, retries every second, and
//! resumes with a note saying how many records were lost and when. [`SessionLog::health`] tells the
//! console ([`LogHealth`], with [`LogHealth::banner`] as the words to show); `tracing::error!` tells
//! stderr once per failure episode. Details in the `write` module.
//!
//! **Compatibility.** Logs written by the console before this module (commands as the app's own
//! `VestCommand`, whose `Fire` had an `on_ms` field) still read: the `Fire` on-time is accepted under both
//! `duration_ms` (written now) and `on_ms` (read only).
//!
//! **Reading.** [`read_log`] reads a log back with bounded memory per line (a line over [`MAX_LINE_BYTES`]
//! is skipped and counted without being held in memory), skips and counts lines it cannot parse (a log cut
//! off by a crash still loads), and validates fixes: a non-finite or out-of-range position, a negative error
//! or speed is skipped and counted by reason in [`ReadStats`]. Errors name the file.
//!
//! ```
//! use vestnav_device::session_log::{LogEntry, SessionLog, read_log};
//! let dir = std::env::temp_dir().join(format!("vestnav-doc-log-{}", std::process::id()));
//! let log = SessionLog::create(&dir).unwrap();
//! let tx = log.sender().unwrap();
//! tx.log(LogEntry::Note { text: "hello".into() });
//! drop(tx);
//! let path = log.path().to_path_buf();
//! assert_eq!(log.close().unwrap().written, 1);
//! let (records, stats) = read_log(&path).unwrap();
//! assert_eq!((records.len(), stats.bad_lines), (1, 0));
//! std::fs::remove_dir_all(&dir).unwrap();
//! ```

use std::fmt;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use vestnav_core::vest::{Pattern, TactorMask};

use crate::heading::{Attitude, HeadingOrigin, HeadingReference};
use crate::wtcu::message::CalibrationWire;
use crate::wtcu::{CommandOrigin, VestCommand};

/// Lines longer than this are skipped by [`read_log`] (a record is a few hundred bytes; a pattern with
/// many frames a few KiB).
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// Records of rate-limited kinds (fixes, acks, tactor reports, notes) that may wait in the queue.
const QUEUE_LIMITED: usize = 4096;
/// Further queue room reserved for commands and marks.
const QUEUE_RESERVED: usize = 4096;

/// What happened.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum LogEntry {
    /// A GPS position.
    Fix {
        /// Latitude [deg].
        lat_deg: f64,
        /// Longitude [deg].
        lon_deg: f64,
        /// Estimated horizontal error [m].
        error_m: Option<f64>,
        /// Speed over ground [m/s].
        speed_m_s: Option<f64>,
        /// Course over ground [deg].
        course_deg: Option<f64>,
        /// Receiver UTC time, if sent.
        gps_utc: Option<String>,
    },
    /// A command sent to the vest.
    Command {
        /// Who asked.
        origin: CommandOrigin,
        /// The command (the `Fire` on-time is read as `duration_ms` or, from older logs, `on_ms`).
        #[serde(with = "LoggedCommand")]
        command: VestCommand,
        /// Why (the guidance reason, or "operator").
        reason: String,
    },
    /// The unit acknowledged something.
    Ack {
        /// What.
        what: String,
    },
    /// The tactors the unit reports on.
    TactorsOn {
        /// The set.
        mask: TactorMask,
    },
    /// An operator mark (a cone in the cone test, or a free note).
    Mark {
        /// Label.
        label: String,
        /// Where the wearer was, if known.
        lat_deg: Option<f64>,
        /// Where the wearer was, if known.
        lon_deg: Option<f64>,
    },
    /// A link state change or other notice.
    Note {
        /// Text.
        text: String,
    },
    /// A heading reading (the vest's magnetometer, an NMEA compass, gpsd's ATT), as received.
    Heading {
        /// Heading \[deg\], from `reference` north.
        heading_deg: f64,
        /// Magnetic or true.
        reference: HeadingReference,
        /// Which device.
        origin: HeadingOrigin,
        /// Pitch \[deg\], if known.
        pitch_deg: Option<f64>,
        /// Roll \[deg\], if known.
        roll_deg: Option<f64>,
        /// Quality 0..=100, if given.
        quality_pct: Option<u8>,
    },
}

impl LogEntry {
    /// The record of a heading reading.
    pub fn heading(a: &Attitude) -> Self {
        Self::Heading {
            heading_deg: a.heading_deg,
            reference: a.reference,
            origin: a.origin,
            pitch_deg: a.pitch_deg,
            roll_deg: a.roll_deg,
            quality_pct: a.quality_pct,
        }
    }
}

/// The serialised shape of [`VestCommand`] in the log: serde's default shape of the device type, with the
/// `Fire` on-time also accepted under its older name `on_ms` (the app's own command type before the
/// session log moved to the device crate).
#[derive(Serialize, Deserialize)]
#[serde(remote = "VestCommand")]
enum LoggedCommand {
    Fire {
        mask: TactorMask,
        #[serde(alias = "on_ms")]
        duration_ms: u16,
    },
    Play(Pattern),
    SetIntensity {
        mask: TactorMask,
        level: u8,
    },
    StopAll,
    RequestStatus,
    HeadingStart {
        rate_hz: u8,
    },
    HeadingStop,
    SetCalibration(CalibrationWire),
}

/// The kind of a [`LogEntry`] (its `kind` tag), for rate limits and statistics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EntryKind {
    /// [`LogEntry::Fix`].
    Fix,
    /// [`LogEntry::Command`].
    Command,
    /// [`LogEntry::Ack`].
    Ack,
    /// [`LogEntry::TactorsOn`].
    TactorsOn,
    /// [`LogEntry::Mark`].
    Mark,
    /// [`LogEntry::Note`].
    Note,
    /// [`LogEntry::Heading`].
    Heading,
}

impl EntryKind {
    /// Every kind, in tag order.
    pub const ALL: [Self; 7] =
        [Self::Fix, Self::Command, Self::Ack, Self::TactorsOn, Self::Mark, Self::Note, Self::Heading];

    /// The `kind` tag in the file.
    pub fn tag(self) -> &'static str {
        match self {
            Self::Fix => "fix",
            Self::Command => "command",
            Self::Ack => "ack",
            Self::TactorsOn => "tactors_on",
            Self::Mark => "mark",
            Self::Note => "note",
            Self::Heading => "heading",
        }
    }

    /// Commands and marks are never rate-limited and have reserved queue room.
    pub fn is_essential(self) -> bool {
        matches!(self, Self::Command | Self::Mark)
    }

    fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for EntryKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.tag())
    }
}

impl LogEntry {
    /// Its kind.
    pub fn kind(&self) -> EntryKind {
        match self {
            Self::Fix { .. } => EntryKind::Fix,
            Self::Command { .. } => EntryKind::Command,
            Self::Ack { .. } => EntryKind::Ack,
            Self::TactorsOn { .. } => EntryKind::TactorsOn,
            Self::Mark { .. } => EntryKind::Mark,
            Self::Note { .. } => EntryKind::Note,
            Self::Heading { .. } => EntryKind::Heading,
        }
    }
}

/// One line of the log.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LogRecord {
    /// Seconds since the session started.
    pub t_s: f64,
    /// Wall-clock UTC time (RFC 3339, milliseconds).
    pub utc: String,
    /// The entry.
    #[serde(flatten)]
    pub entry: LogEntry,
}

/// The wall clock as written in [`LogRecord::utc`].
pub fn utc_stamp(t: chrono::DateTime<chrono::Utc>) -> String {
    t.to_rfc3339_opts(chrono::SecondsFormat::Millis, true)
}

// ---------------------------------------------------------------------------------------------------------
// Flood coalescing (pure: time is the records' session time).

/// Per-kind rate limits of the writer [records per second of session time]; `None` = not limited.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RateLimits {
    /// Limit per kind, indexed like [`EntryKind::ALL`].
    per_kind: [Option<u32>; EntryKind::ALL.len()],
}

impl Default for RateLimits {
    /// 20 fixes/s (a 1–10 Hz receiver never reaches it), 20 headings/s (the vest streams at most 10),
    /// 50 acks, tactor reports and notes per second; commands and marks unlimited.
    fn default() -> Self {
        let mut l = Self::unlimited();
        l.set(EntryKind::Fix, Some(20));
        l.set(EntryKind::Ack, Some(50));
        l.set(EntryKind::TactorsOn, Some(50));
        l.set(EntryKind::Note, Some(50));
        l.set(EntryKind::Heading, Some(20));
        l
    }
}

impl RateLimits {
    /// No limit on any kind.
    pub fn unlimited() -> Self {
        Self { per_kind: [None; EntryKind::ALL.len()] }
    }

    /// Sets the limit of `kind` [records/s]. Commands and marks stay unlimited whatever is asked.
    pub fn set(&mut self, kind: EntryKind, per_s: Option<u32>) {
        self.per_kind[kind.index()] = if kind.is_essential() { None } else { per_s };
    }

    /// The limit of `kind` [records/s].
    pub fn get(&self, kind: EntryKind) -> Option<u32> {
        self.per_kind[kind.index()]
    }
}

/// The writer's flood filter: counts records per kind in whole seconds of session time (`floor(t_s)`),
/// passes at most the limit of each kind per second and counts the rest; [`Coalescer::summaries`] turns
/// the counts into notes.
///
/// A flood of `r` records/s of a kind limited to `L`/s over `T` s yields `L T` records plus at most
/// `T + 1` notes, whatever `r` is.
#[derive(Debug, Clone)]
pub struct Coalescer {
    limits: RateLimits,
    window: Option<i64>,
    passed: [u32; EntryKind::ALL.len()],
    suppressed: [u64; EntryKind::ALL.len()],
    total_suppressed: u64,
}

impl Coalescer {
    /// A filter with these limits.
    pub fn new(limits: RateLimits) -> Self {
        Self {
            limits,
            window: None,
            passed: [0; EntryKind::ALL.len()],
            suppressed: [0; EntryKind::ALL.len()],
            total_suppressed: 0,
        }
    }

    /// Records suppressed so far, all kinds.
    pub fn total_suppressed(&self) -> u64 {
        self.total_suppressed
    }

    /// Feeds one record: the notes summarising the previous second's floods (when `rec` starts a new
    /// second) and whether `rec` itself is to be written.
    pub fn admit(&mut self, rec: &LogRecord) -> (Vec<LogRecord>, bool) {
        let t_s = if rec.t_s.is_finite() { rec.t_s } else { 0.0 };
        let second = t_s.floor() as i64;
        let mut notes = Vec::new();
        // Time going backwards (clock quirks, appended sessions) also starts a new window.
        if self.window != Some(second) {
            notes = self.summaries(t_s, &rec.utc);
            self.window = Some(second);
            self.passed = [0; EntryKind::ALL.len()];
        }
        let k = rec.entry.kind().index();
        let keep = match self.limits.per_kind[k] {
            Some(limit) if self.passed[k] >= limit => {
                self.suppressed[k] += 1;
                self.total_suppressed += 1;
                false
            }
            _ => {
                self.passed[k] = self.passed[k].saturating_add(1);
                true
            }
        };
        (notes, keep)
    }

    /// Notes `"N <kind> events dropped (flood)"` for every kind suppressed since the last summary, stamped
    /// `t_s`/`utc`; resets the counts. Call at each new second, when idle and at the end.
    pub fn summaries(&mut self, t_s: f64, utc: &str) -> Vec<LogRecord> {
        let mut notes = Vec::new();
        for kind in EntryKind::ALL {
            let n = std::mem::take(&mut self.suppressed[kind.index()]);
            if n > 0 {
                notes.push(LogRecord {
                    t_s,
                    utc: utc.to_owned(),
                    entry: LogEntry::Note { text: format!("{n} {kind} events dropped (flood)") },
                });
            }
        }
        notes
    }
}

// ---------------------------------------------------------------------------------------------------------
// Writer.

/// Counters shared by the senders and the writer.
#[derive(Debug, Default)]
struct Shared {
    /// Rate-limited records waiting in the queue.
    queued_limited: AtomicUsize,
    /// Records dropped because the queue was full.
    queue_dropped: AtomicU64,
}

/// What the writer did, returned by [`SessionLog::close`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WriteStats {
    /// Lines written (flood and storage notes included).
    pub written: u64,
    /// Records suppressed by the flood filter.
    pub coalesced: u64,
    /// Records dropped because the queue was full.
    pub queue_dropped: u64,
    /// Records lost to storage failures (a full disk, a read-only or failing medium): see
    /// [`LogHealth`].
    pub storage_lost: u64,
}

/// The console's handle on the writer thread. Dropping it lets the thread finish once every
/// [`LogSender`] is gone; [`SessionLog::close`] waits for that.
#[derive(Debug)]
pub struct SessionLog {
    tx: Option<SyncSender<LogRecord>>,
    shared: Arc<Shared>,
    health: SharedHealth,
    start: Instant,
    path: PathBuf,
    thread: Option<JoinHandle<io::Result<WriteStats>>>,
}

/// A cheap clonable handle the workers use to add records; never blocks.
#[derive(Debug, Clone)]
pub struct LogSender {
    tx: SyncSender<LogRecord>,
    shared: Arc<Shared>,
    start: Instant,
}

impl LogSender {
    /// Stamps `entry` with the session time (since the log's start instant) and the wall clock, and
    /// queues it; when the queue is full it is dropped and counted. Never waits, whatever the disk does
    /// (a storage failure is the writer's business: [`SessionLog::health`]). Returns `false` once the
    /// writer is gone (the log was closed).
    pub fn log(&self, entry: LogEntry) -> bool {
        let t_s = self.start.elapsed().as_secs_f64();
        self.send(LogRecord { t_s, utc: utc_stamp(chrono::Utc::now()), entry })
    }

    /// Queues a record stamped by the caller (replay, tests); same rules as [`LogSender::log`].
    pub fn send(&self, record: LogRecord) -> bool {
        let limited = !record.entry.kind().is_essential();
        if limited {
            // Rate-limited kinds may fill only their share of the queue; the rest is for commands and marks.
            let q = &self.shared.queued_limited;
            if q.fetch_add(1, Ordering::AcqRel) >= QUEUE_LIMITED {
                q.fetch_sub(1, Ordering::AcqRel);
                self.shared.queue_dropped.fetch_add(1, Ordering::Relaxed);
                return true;
            }
        }
        match self.tx.try_send(record) {
            Ok(()) => true,
            Err(e) => {
                if limited {
                    self.shared.queued_limited.fetch_sub(1, Ordering::AcqRel);
                }
                match e {
                    TrySendError::Full(_) => {
                        self.shared.queue_dropped.fetch_add(1, Ordering::Relaxed);
                        true
                    }
                    TrySendError::Disconnected(_) => false,
                }
            }
        }
    }

    /// The instant session time counts from.
    pub fn start(&self) -> Instant {
        self.start
    }
}

impl SessionLog {
    /// Creates `dir/session-<UTC now>.jsonl` (with `-1`, `-2`, ... when that name exists) and starts the
    /// writer thread; session time counts from now. Fails when the file cannot be created (see
    /// [`SessionLog::create_resilient`] for a log that waits for its folder instead).
    pub fn create(dir: &Path) -> io::Result<Self> {
        let (path, file) = create_session_file(dir)?;
        Self::with_sink(
            Box::new(SessionFile::open(path.clone(), file)),
            path,
            Instant::now(),
            RateLimits::default(),
        )
    }

    /// As [`SessionLog::create`], but a folder that cannot be written (read-only HOME, full disk) does not
    /// stop the log: it starts in [`LogHealth::Failing`] (logged, shown by the console) and creates the
    /// file as soon as a retry succeeds. Fails only when the writer thread cannot start.
    pub fn create_resilient(dir: &Path) -> io::Result<Self> {
        match create_session_file(dir) {
            Ok((path, file)) => Self::with_sink(
                Box::new(SessionFile::open(path.clone(), file)),
                path,
                Instant::now(),
                RateLimits::default(),
            ),
            Err(e) => {
                let path = dir.join(chrono::Utc::now().format("session-%Y%m%d-%H%M%S.jsonl").to_string());
                Self::start_writer(
                    Box::new(SessionFile::later(path.clone())),
                    path,
                    Instant::now(),
                    RateLimits::default(),
                    WriterOptions::default(),
                    Some(&e),
                )
            }
        }
    }

    /// Creates (or appends to) the log at `path`, session time counting from now, default rate limits.
    pub fn create_at(path: &Path) -> io::Result<Self> {
        Self::create_with(path, Instant::now(), RateLimits::default())
    }

    /// Creates (or appends to) the log at `path`; session time counts from `start`; `limits` coalesce floods.
    pub fn create_with(path: &Path, start: Instant, limits: RateLimits) -> io::Result<Self> {
        let file = std::fs::OpenOptions::new().create(true).append(true).open(path)?;
        Self::with_sink(
            Box::new(SessionFile::open(path.to_path_buf(), file)),
            path.to_path_buf(),
            start,
            limits,
        )
    }

    /// A log writing into `sink` (named `path` in messages): for tests that inject storage failures.
    pub fn with_sink(
        sink: Box<dyn LogSink>,
        path: PathBuf,
        start: Instant,
        limits: RateLimits,
    ) -> io::Result<Self> {
        Self::start_writer(sink, path, start, limits, WriterOptions::default(), None)
    }

    fn start_writer(
        sink: Box<dyn LogSink>,
        path: PathBuf,
        start: Instant,
        limits: RateLimits,
        opts: WriterOptions,
        initial_error: Option<&io::Error>,
    ) -> io::Result<Self> {
        let (tx, rx) = sync_channel::<LogRecord>(QUEUE_LIMITED + QUEUE_RESERVED);
        let shared = Arc::new(Shared::default());
        let health = SharedHealth::default();
        let journal = Journal::new(sink, path.clone(), start, opts, health.clone(), initial_error);
        let writer_shared = shared.clone();
        let tick = opts.retry.min(Duration::from_secs(1));
        let thread = std::thread::Builder::new()
            .name("vestnav-session-log".into())
            .spawn(move || write_loop(&rx, journal, &writer_shared, limits, start, tick))?;
        Ok(Self { tx: Some(tx), shared, health, start, path, thread: Some(thread) })
    }

    /// A handle for other threads (`None` after the log was stopped).
    pub fn sender(&self) -> Option<LogSender> {
        self.tx.as_ref().map(|tx| LogSender {
            tx: tx.clone(),
            shared: self.shared.clone(),
            start: self.start,
        })
    }

    /// The file being written (for [`SessionLog::create_resilient`], the file to be created).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The instant session time counts from.
    pub fn start(&self) -> Instant {
        self.start
    }

    /// Records dropped so far because the queue was full (the flood filter's own count is in
    /// [`WriteStats::coalesced`]).
    pub fn dropped(&self) -> u64 {
        self.shared.queue_dropped.load(Ordering::Relaxed)
    }

    /// Whether records reach the file, for the console to read each frame (a mutex held for a clone; the
    /// writer updates it at most once per batch of records). [`LogHealth::banner`] words it.
    pub fn health(&self) -> LogHealth {
        self.health.lock().unwrap_or_else(std::sync::PoisonError::into_inner).clone()
    }

    /// Waits until every sender is gone and the writer has written everything queued; what it did. An
    /// error when records could not be written by then (storage failure still going on; the count is in
    /// the message) or the writer thread panicked.
    pub fn close(mut self) -> io::Result<WriteStats> {
        self.tx = None;
        match self.thread.take() {
            Some(t) => t.join().unwrap_or_else(|_| Err(io::Error::other("session log writer panicked"))),
            None => Ok(WriteStats::default()),
        }
    }
}

impl Drop for SessionLog {
    fn drop(&mut self) {
        // Workers may still hold senders; the thread ends when the last one goes. Do not wait for them here.
        self.tx = None;
        if let Some(t) = self.thread.take()
            && t.is_finished()
        {
            let _ = t.join();
        }
    }
}

/// Creates a new `dir/session-<UTC now>[-N].jsonl`, never an existing one.
fn create_session_file(dir: &Path) -> io::Result<(PathBuf, std::fs::File)> {
    std::fs::create_dir_all(dir)?;
    let stem = chrono::Utc::now().format("session-%Y%m%d-%H%M%S").to_string();
    let mut n = 0u32;
    loop {
        let name = if n == 0 { format!("{stem}.jsonl") } else { format!("{stem}-{n}.jsonl") };
        let path = dir.join(name);
        match std::fs::OpenOptions::new().write(true).create_new(true).open(&path) {
            Ok(file) => return Ok((path, file)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists && n < 1000 => n += 1,
            Err(e) => return Err(e),
        }
    }
}

/// Writes records until every sender is gone: the flood filter, a note per second for queue drops, the
/// journal handed to the file whenever the queue runs empty (retried every `tick` while it fails), and the
/// pending flood notes after a quiet `tick` and at the end.
fn write_loop(
    rx: &Receiver<LogRecord>,
    mut out: Journal,
    shared: &Shared,
    limits: RateLimits,
    start: Instant,
    tick: Duration,
) -> io::Result<WriteStats> {
    let mut filter = Coalescer::new(limits);
    let mut queue_notes = QueueDropNotes::default();
    let now = || (start.elapsed().as_secs_f64(), utc_stamp(chrono::Utc::now()));
    loop {
        let first = match rx.recv_timeout(tick) {
            Ok(rec) => rec,
            Err(RecvTimeoutError::Timeout) => {
                // Quiet for a while: the flood (if any) has ended.
                let (t_s, utc) = now();
                for note in filter.summaries(t_s, &utc) {
                    out.push(&note, Instant::now());
                }
                queue_notes.write(&mut out, shared, t_s, &utc, true);
                out.drain(Instant::now(), false);
                out.publish();
                continue;
            }
            Err(RecvTimeoutError::Disconnected) => break,
        };
        let mut next = Some(first);
        while let Some(rec) = next {
            if !rec.entry.kind().is_essential() {
                shared.queued_limited.fetch_sub(1, Ordering::AcqRel);
            }
            let (notes, keep) = filter.admit(&rec);
            let t = Instant::now();
            for note in &notes {
                out.push(note, t);
            }
            if keep {
                out.push(&rec, t);
            }
            next = rx.try_recv().ok();
        }
        let (t_s, utc) = now();
        queue_notes.write(&mut out, shared, t_s, &utc, false);
        out.drain(Instant::now(), false);
        out.publish();
    }
    let (t_s, utc) = now();
    for note in filter.summaries(t_s, &utc) {
        out.push(&note, Instant::now());
    }
    queue_notes.write(&mut out, shared, t_s, &utc, true);
    out.stats.coalesced = filter.total_suppressed();
    out.stats.queue_dropped = shared.queue_dropped.load(Ordering::Relaxed);
    out.finish()
}

/// Notes of records dropped on a full queue: at most one per second of writer time.
#[derive(Debug, Default)]
struct QueueDropNotes {
    reported: u64,
    last_t_s: Option<f64>,
}

impl QueueDropNotes {
    fn write(&mut self, out: &mut Journal, shared: &Shared, t_s: f64, utc: &str, force: bool) {
        if !force && self.last_t_s.is_some_and(|last| t_s - last < 1.0) {
            return;
        }
        let dropped = shared.queue_dropped.load(Ordering::Relaxed);
        if dropped > self.reported {
            let text = format!("{} events dropped (writer queue full)", dropped - self.reported);
            out.push(&LogRecord { t_s, utc: utc.to_owned(), entry: LogEntry::Note { text } }, Instant::now());
            self.reported = dropped;
            self.last_t_s = Some(t_s);
        }
    }
}

mod write;
use write::{Journal, SessionFile, SharedHealth, WriterOptions};
pub use write::{LogHealth, LogSink, PENDING_LIMIT_BYTES, RETRY_INTERVAL, SYNC_INTERVAL, StorageError};

mod read;
pub use read::*;

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write as _;

    fn temp_dir(tag: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("vestnav-session-log-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn fix(lat_deg: f64, lon_deg: f64) -> LogEntry {
        LogEntry::Fix {
            lat_deg,
            lon_deg,
            error_m: Some(3.0),
            speed_m_s: None,
            course_deg: None,
            gps_utc: None,
        }
    }

    fn rec(t_s: f64, entry: LogEntry) -> LogRecord {
        LogRecord { t_s, utc: "2026-11-22T18:00:00.000Z".into(), entry }
    }

    fn fire(mask: u16, duration_ms: u16) -> LogEntry {
        LogEntry::Command {
            origin: CommandOrigin::Manual,
            command: VestCommand::Fire { mask: TactorMask(mask), duration_ms },
            reason: "operator".into(),
        }
    }

    fn read_str(text: &str) -> (Vec<LogRecord>, ReadStats) {
        read_log_from(io::Cursor::new(text.as_bytes().to_vec()), ReadMode::Lenient).unwrap()
    }

    #[test]
    fn written_records_read_back_and_junk_is_skipped() {
        let dir = temp_dir("rt");
        let path = dir.join("s.jsonl");
        let log = SessionLog::create_at(&path).unwrap();
        let tx = log.sender().unwrap();
        let entries = vec![
            fix(42.5, -71.25),
            fire(0b101, 500),
            LogEntry::Command {
                origin: CommandOrigin::Guidance,
                command: VestCommand::Play(vestnav_core::vest::Cue::TurnLeft.pattern(500)),
                reason: "turn left: bearing error -80°".into(),
            },
            LogEntry::Command {
                origin: CommandOrigin::Manual,
                command: VestCommand::SetIntensity { mask: TactorMask(3), level: 200 },
                reason: "operator".into(),
            },
            LogEntry::Ack { what: "fire".into() },
            LogEntry::TactorsOn { mask: TactorMask(0xF00F) },
            LogEntry::Mark { label: "cone 1".into(), lat_deg: Some(42.5), lon_deg: Some(-71.25) },
            LogEntry::Note { text: "link up".into() },
        ];
        for e in &entries {
            assert!(tx.log(e.clone()));
        }
        drop(tx);
        let stats = log.close().unwrap();
        assert_eq!(stats, WriteStats { written: entries.len() as u64, ..WriteStats::default() });
        // A crash mid-line leaves a partial record: it must not hide the rest.
        let mut f = std::fs::OpenOptions::new().append(true).open(&path).unwrap();
        f.write_all(b"{\"t_s\":9,\"utc\":\"x\",\"kind\":\"fi").unwrap();
        drop(f);
        let (back, stats) = read_log(&path).unwrap();
        assert_eq!(back.iter().map(|r| r.entry.clone()).collect::<Vec<_>>(), entries);
        assert_eq!(stats.bad_lines, 1);
        assert_eq!(stats.records, entries.len());
        assert!(back.windows(2).all(|w| w[0].t_s <= w[1].t_s));
        assert_eq!(track(&back), vec![(back[0].t_s, 42.5, -71.25)]);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("{\"t_s\":"));
        assert!(text.contains("\"kind\":\"mark\""));
        assert!(text.contains("\"duration_ms\":500"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn old_app_logs_still_read() {
        // Lines as the console wrote them before the log moved here (app VestCommand, `on_ms`).
        let text = concat!(
            r#"{"t_s":0.5,"utc":"2026-11-22T18:00:00.500Z","kind":"fix","lat_deg":42.3562,"lon_deg":-71.1,"error_m":2.5,"speed_m_s":1.3,"course_deg":45.0,"gps_utc":"18:00:00"}"#,
            "\n",
            r#"{"t_s":1.0,"utc":"2026-11-22T18:00:01.000Z","kind":"command","origin":"Manual","command":{"Fire":{"mask":5,"on_ms":500}},"reason":"operator"}"#,
            "\n",
            r#"{"t_s":1.5,"utc":"2026-11-22T18:00:01.500Z","kind":"command","origin":"Guidance","command":"StopAll","reason":"stop"}"#,
            "\n",
            r#"{"t_s":2.0,"utc":"2026-11-22T18:00:02.000Z","kind":"tactors_on","mask":5}"#,
            "\n"
        );
        let (r, stats) = read_str(text);
        assert_eq!(stats.skipped(), 0, "{stats:?}");
        assert_eq!(r.len(), 4);
        assert_eq!(r[1].entry, fire(5, 500));
        assert!(matches!(
            r[2].entry,
            LogEntry::Command { origin: CommandOrigin::Guidance, command: VestCommand::StopAll, .. }
        ));
        assert_eq!(r[3].entry, LogEntry::TactorsOn { mask: TactorMask(5) });
        // Written back, the command uses today's name, and reads again to the same record.
        let line = serde_json::to_string(&r[1]).unwrap();
        assert!(line.contains(r#""command":{"Fire":{"mask":5,"duration_ms":500}}"#), "{line}");
        assert_eq!(serde_json::from_str::<LogRecord>(&line).unwrap(), r[1]);
    }

    #[test]
    fn invalid_fixes_are_skipped_and_counted_by_reason() {
        let text = [
            r#"{"t_s":0,"utc":"u","kind":"fix","lat_deg":42.0,"lon_deg":-71.0,"error_m":null,"speed_m_s":null,"course_deg":null,"gps_utc":null}"#,
            r#"{"t_s":1,"utc":"u","kind":"fix","lat_deg":95.0,"lon_deg":-71.0,"error_m":null,"speed_m_s":null,"course_deg":null,"gps_utc":null}"#,
            r#"{"t_s":2,"utc":"u","kind":"fix","lat_deg":42.0,"lon_deg":-181.0,"error_m":null,"speed_m_s":null,"course_deg":null,"gps_utc":null}"#,
            r#"{"t_s":3,"utc":"u","kind":"fix","lat_deg":42.0,"lon_deg":-71.0,"error_m":-1.0,"speed_m_s":null,"course_deg":null,"gps_utc":null}"#,
            r#"{"t_s":4,"utc":"u","kind":"fix","lat_deg":42.0,"lon_deg":-71.0,"error_m":null,"speed_m_s":-0.5,"course_deg":null,"gps_utc":null}"#,
            // JSON has no NaN or infinity: serde_json refuses 1e400 (and writes a NaN as null): a bad line.
            r#"{"t_s":5,"utc":"u","kind":"fix","lat_deg":1e400,"lon_deg":-71.0,"error_m":null,"speed_m_s":null,"course_deg":null,"gps_utc":null}"#,
            r#"{"t_s":6,"utc":"u","kind":"mark","label":"cone 2","lat_deg":420.0,"lon_deg":-71.0}"#,
            r#"{"t_s":1e400,"utc":"u","kind":"note","text":"x"}"#,
            "",
            r#"{"t_s":7,"utc":"u","kind":"fix","lat_deg":-90.0,"lon_deg":180.0,"error_m":0.0,"speed_m_s":0.0,"course_deg":null,"gps_utc":null}"#,
        ]
        .join("\n");
        let (r, s) = read_str(&text);
        assert_eq!(r.len(), 3);
        assert_eq!(s.lines, 10);
        assert_eq!(s.invalid_fixes.get(&FixProblem::OutOfRangePosition), Some(&2));
        assert_eq!(s.invalid_fixes.get(&FixProblem::BadError), Some(&1));
        assert_eq!(s.invalid_fixes.get(&FixProblem::BadSpeed), Some(&1));
        assert_eq!(s.invalid_fix_count(), 4);
        assert_eq!(s.bad_lines, 2);
        assert_eq!(s.invalid_mark_positions, 1);
        assert_eq!(r[1].entry, LogEntry::Mark { label: "cone 2".into(), lat_deg: None, lon_deg: None });
        assert_eq!(s.examples.first().map(|e| e.0), Some(2));
    }

    #[test]
    fn fix_checks_by_reason() {
        assert_eq!(check_fix(f64::NAN, 0.0, None, None), Err(FixProblem::NonFinitePosition));
        assert_eq!(check_fix(0.0, f64::INFINITY, None, None), Err(FixProblem::NonFinitePosition));
        assert_eq!(check_fix(90.000_001, 0.0, None, None), Err(FixProblem::OutOfRangePosition));
        assert_eq!(check_fix(0.0, 180.000_001, None, None), Err(FixProblem::OutOfRangePosition));
        assert_eq!(check_fix(0.0, 0.0, Some(f64::NAN), None), Err(FixProblem::BadError));
        assert_eq!(check_fix(0.0, 0.0, None, Some(-1e-9)), Err(FixProblem::BadSpeed));
        assert_eq!(check_fix(-90.0, -180.0, Some(0.0), Some(0.0)), Ok(()));
    }

    #[test]
    fn an_overlong_line_is_skipped_without_hiding_the_next() {
        let good = r#"{"t_s":1,"utc":"u","kind":"note","text":"ok"}"#;
        let huge =
            format!(r#"{{"t_s":0,"utc":"u","kind":"note","text":"{}"}}"#, "x".repeat(3 * MAX_LINE_BYTES));
        let head = r#"{"t_s":2,"utc":"u","kind":"note","text":""}"#.len();
        let exact =
            format!(r#"{{"t_s":2,"utc":"u","kind":"note","text":"{}"}}"#, "y".repeat(MAX_LINE_BYTES - head));
        assert_eq!(exact.len(), MAX_LINE_BYTES);
        // A reader with a tiny buffer exercises the line being assembled across many fills.
        let text = format!("{huge}\n{good}\n{exact}\n{huge}");
        let reader = io::BufReader::with_capacity(7, io::Cursor::new(text.into_bytes()));
        let (r, s) = read_log_from(reader, ReadMode::Lenient).unwrap();
        assert_eq!(s.long_lines, 2);
        assert_eq!(s.lines, 4);
        assert_eq!(r.len(), 2);
        assert_eq!(r[0].entry, LogEntry::Note { text: "ok".into() });
        assert!(matches!(&r[1].entry, LogEntry::Note { text } if text.len() == MAX_LINE_BYTES - head));
    }

    fn read_strict(text: &str) -> Result<(Vec<LogRecord>, ReadStats), LineError> {
        read_log_from(io::Cursor::new(text.as_bytes().to_vec()), ReadMode::Strict)
    }

    #[test]
    fn strict_reading_refuses_what_would_lose_data_and_skips_what_would_not() {
        let note = |t: f64| format!("{{\"t_s\":{t},\"utc\":\"u\",\"kind\":\"note\",\"text\":\"n\"}}\n");
        // A byte-order mark on line 1 and a record of a kind from a newer console are fine.
        let text = format!(
            "\u{feff}{}{{\"t_s\":2,\"utc\":\"u\",\"kind\":\"wind\",\"speed_m_s\":3}}\n{}",
            note(1.0),
            note(3.0)
        );
        let (r, s) = read_strict(&text).unwrap();
        assert_eq!((r.len(), s.other_kinds, s.bad_lines), (2, 1, 0), "{s:?}");
        // A malformed line in the middle is refused with its number and what is wrong.
        for (bad, what) in [
            ("not json\n", "not JSON"),
            ("{\"t_s\":2}\n", "kind"),
            ("{\"t_s\":2,\"utc\":\"u\",\"kind\":\"fix\",\"lat_deg\":\"n\"}\n", "bad fix record"),
        ] {
            let Err(LineError::Refused(line, why)) = read_strict(&format!("{}{bad}{}", note(1.0), note(2.0)))
            else {
                panic!("{bad} was not refused");
            };
            assert_eq!(line, 2);
            assert!(why.contains(what), "{why}");
        }
        // The same line cut off at the end of the file (no newline) is skipped and named.
        let (r, s) = read_strict(&format!("{}{}{{\"t_s\":3,\"ki", note(1.0), note(2.0))).unwrap();
        assert_eq!((r.len(), s.bad_lines), (2, 1));
        assert!(s.examples[0].1.contains("cut off"), "{s:?}");
        // Time going back by more than a second: two sessions in one file.
        let Err(LineError::Refused(line, why)) =
            read_strict(&format!("{}{}{}", note(10.0), note(9.5), note(2.0)))
        else {
            panic!("time going back was not refused");
        };
        assert_eq!(line, 3);
        assert!(why.contains("goes back from 10.000 s to 2.000 s"), "{why}");
        // An overlong line is refused (lenient reading skips it: see above).
        let huge = format!(
            "{{\"t_s\":0,\"utc\":\"u\",\"kind\":\"note\",\"text\":\"{}\"}}\n",
            "x".repeat(MAX_LINE_BYTES)
        );
        assert!(matches!(read_strict(&format!("{}{huge}", note(1.0))), Err(LineError::Refused(2, _))));
    }

    #[test]
    fn a_missing_file_is_an_error_naming_it() {
        let path = std::env::temp_dir().join("vestnav-no-such-dir-xyz/session.jsonl");
        let e = read_log(&path).unwrap_err();
        assert!(e.to_string().contains("vestnav-no-such-dir-xyz/session.jsonl"), "{e}");
    }

    #[test]
    fn coalescer_bounds_a_flood_and_keeps_every_command() {
        // 10 s of a 1000 Hz fix flood with a command every 0.1 s.
        let mut c = Coalescer::new(RateLimits::default());
        let (mut fixes, mut commands, mut notes) = (0usize, 0usize, Vec::new());
        for i in 0..10_000u32 {
            let t = f64::from(i) / 1000.0;
            let mut batch = vec![rec(t, fix(42.0, -71.0))];
            if i % 100 == 0 {
                batch.push(rec(t, fire(1, 100)));
            }
            for r in batch {
                let (n, keep) = c.admit(&r);
                notes.extend(n);
                if keep {
                    match r.entry.kind() {
                        EntryKind::Fix => fixes += 1,
                        EntryKind::Command => commands += 1,
                        _ => unreachable!(),
                    }
                }
            }
        }
        notes.extend(c.summaries(10.0, "u"));
        assert_eq!(fixes, 10 * 20);
        assert_eq!(commands, 100);
        // One note per second of flood, counting exactly what was dropped.
        assert_eq!(notes.len(), 10);
        for n in &notes {
            assert_eq!(n.entry, LogEntry::Note { text: "980 fix events dropped (flood)".into() });
        }
        assert_eq!(c.total_suppressed(), 10 * 980);
        // Below the limit nothing is dropped and no note is written.
        let mut c = Coalescer::new(RateLimits::default());
        for i in 0..100u32 {
            let (n, keep) = c.admit(&rec(f64::from(i) * 0.1, fix(42.0, -71.0)));
            assert!(keep && n.is_empty());
        }
        assert!(c.summaries(10.0, "u").is_empty());
    }

    #[test]
    fn a_flood_through_the_writer_gives_a_bounded_file_with_every_command_and_mark() {
        let dir = temp_dir("flood");
        let path = dir.join("flood.jsonl");
        // Session time is stamped by the caller here, so the flood spans a known 3 s whatever the machine.
        let log = SessionLog::create_with(&path, Instant::now(), RateLimits::default()).unwrap();
        let tx = log.sender().unwrap();
        let n_fix = 60_000u32;
        let mut sent_essential = 0;
        for i in 0..n_fix {
            let t = 3.0 * f64::from(i) / f64::from(n_fix);
            tx.send(rec(t, fix(42.0, -71.0)));
            tx.send(rec(t, LogEntry::Ack { what: "status".into() }));
            if i % 600 == 0 {
                tx.send(rec(t, fire(2, 200)));
                tx.send(rec(t, LogEntry::Mark { label: format!("m{i}"), lat_deg: None, lon_deg: None }));
                sent_essential += 2;
            }
        }
        drop(tx);
        let queue_dropped = log.dropped();
        let stats = log.close().unwrap();
        let (r, rs) = read_log(&path).unwrap();
        assert_eq!(rs.skipped(), 0);
        let count = |k: EntryKind| r.iter().filter(|x| x.entry.kind() == k).count();
        assert_eq!(count(EntryKind::Command) + count(EntryKind::Mark), sent_essential);
        assert!(count(EntryKind::Fix) <= 3 * 20, "{}", count(EntryKind::Fix));
        assert!(count(EntryKind::Ack) <= 3 * 50);
        let dropped_in_notes: u64 = r
            .iter()
            .filter_map(|x| match &x.entry {
                LogEntry::Note { text } => text.split(' ').next().and_then(|n| n.parse::<u64>().ok()),
                _ => None,
            })
            .sum();
        // Everything sent is either in the file or counted in a note.
        let kept = (count(EntryKind::Fix) + count(EntryKind::Ack)) as u64;
        assert_eq!(kept + dropped_in_notes, 2 * u64::from(n_fix));
        assert_eq!(stats.coalesced + stats.queue_dropped, dropped_in_notes);
        assert_eq!(stats.queue_dropped, queue_dropped);
        assert!(std::fs::metadata(&path).unwrap().len() < 200_000);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn create_never_overwrites_and_stamps_session_time() {
        let dir = temp_dir("create");
        let a = SessionLog::create(&dir).unwrap();
        let b = SessionLog::create(&dir).unwrap();
        assert_ne!(a.path(), b.path());
        let start = Instant::now().checked_sub(Duration::from_secs(5)).unwrap();
        let c = SessionLog::create_with(&dir.join("c.jsonl"), start, RateLimits::default()).unwrap();
        c.sender().unwrap().log(LogEntry::Note { text: "late".into() });
        let path = c.path().to_path_buf();
        c.close().unwrap();
        let (r, _) = read_log(&path).unwrap();
        assert!(r[0].t_s >= 5.0 && r[0].t_s < 60.0, "{}", r[0].t_s);
        assert!(chrono::DateTime::parse_from_rfc3339(&r[0].utc).is_ok());
        drop((a, b));
        assert_eq!(list_logs(&dir).len(), 3);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
