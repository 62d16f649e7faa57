//! The writer thread's side of the session log: turning records into lines, and surviving the disk.
//!
//! **Storage failures.** A write or `fsync` that fails (a full disk `ENOSPC`, a read-only file system
//! `EROFS`, a failing medium `EIO`, any I/O error) does not stop the writer. It starts a *failure episode*:
//! logged once with `tracing::error!`, published in [`LogHealth::Failing`] for the console to show, and
//! retried every [`RETRY_INTERVAL`] (the file is reopened on each retry, so a medium that comes back is
//! used again). While failing, records are held in memory up to [`PENDING_LIMIT_BYTES`]; records beyond
//! that are counted as lost. When a retry succeeds, the held records are written, then a note
//! `"storage failure: N records lost between … and … (error)"`, and the health becomes
//! [`LogHealth::Recovered`]. The senders never wait for any of this (see [`super::LogSender::log`]).
//!
//! Records written since the last successful `fsync` (every [`SYNC_INTERVAL`]) are counted as lost when
//! an `fsync` fails: the kernel may have dropped them, and nothing tells which.

use std::fmt;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use chrono::{DateTime, Utc};

use super::{LogEntry, LogRecord, WriteStats, utc_stamp};

/// How often a failing log tries to write again.
pub const RETRY_INTERVAL: Duration = Duration::from_secs(1);
/// How often written records are made durable (`fsync`); a failing medium often reports only here.
pub const SYNC_INTERVAL: Duration = Duration::from_secs(2);
/// Memory for records held while writing fails (about 5000 typical records); beyond it they are lost
/// and counted.
pub const PENDING_LIMIT_BYTES: usize = 1 << 20;
/// Lines are handed to the sink in chunks of about this size while writing works.
const CHUNK_BYTES: usize = 64 * 1024;

/// Where the session log's bytes go: the log file, or in tests a sink that fails on demand.
pub trait LogSink: Send {
    /// Writes some of `buf` (as [`std::io::Write::write`]); returns how many bytes were taken.
    fn write(&mut self, buf: &[u8]) -> io::Result<usize>;
    /// Makes everything written so far durable (`fsync`).
    fn sync(&mut self) -> io::Result<()>;
    /// Called before each retry after a failure: a file sink closes its handle so that the next write
    /// reopens the path (a medium that was replaced, a folder that became writable).
    fn reset(&mut self) {}
}

/// The log file, opened when first written to (so a log whose folder cannot be written yet still runs,
/// failing, until it can) and reopened in append mode after a failure.
#[derive(Debug)]
pub(super) struct SessionFile {
    path: PathBuf,
    file: Option<std::fs::File>,
}

impl SessionFile {
    /// A file already open at `path`.
    pub(super) fn open(path: PathBuf, file: std::fs::File) -> Self {
        Self { path, file: Some(file) }
    }

    /// `path`, to be created (with its folder) on the first write.
    pub(super) fn later(path: PathBuf) -> Self {
        Self { path, file: None }
    }
}

impl LogSink for SessionFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        use std::io::Write as _;
        if self.file.is_none() {
            if let Some(dir) = self.path.parent() {
                std::fs::create_dir_all(dir)?;
            }
            self.file = Some(std::fs::OpenOptions::new().create(true).append(true).open(&self.path)?);
        }
        let Some(file) = &mut self.file else { return Err(io::ErrorKind::NotFound.into()) };
        file.write(buf)
    }

    fn sync(&mut self) -> io::Result<()> {
        self.file.as_ref().map_or(Ok(()), std::fs::File::sync_data)
    }

    fn reset(&mut self) {
        self.file = None;
    }
}

/// A storage error as the operator should read it: its kind and the system's message (e.g. "No space
/// left on device (os error 28)").
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StorageError {
    /// The kind (`StorageFull`, `ReadOnlyFilesystem`, ...).
    pub kind: io::ErrorKind,
    /// The operating system's error number, when there is one (28 = ENOSPC, 30 = EROFS, 5 = EIO on Linux).
    pub os_code: Option<i32>,
    /// The message.
    pub message: String,
}

impl From<&io::Error> for StorageError {
    fn from(e: &io::Error) -> Self {
        Self { kind: e.kind(), os_code: e.raw_os_error(), message: e.to_string() }
    }
}

impl fmt::Display for StorageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

/// Whether the session log reaches its file, read each frame by the console ([`super::SessionLog::health`]).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum LogHealth {
    /// Every record so far reached the file (flood coalescing and queue drops aside: those are notes in
    /// the file).
    #[default]
    Ok,
    /// Writing fails now; the writer retries every [`RETRY_INTERVAL`].
    Failing {
        /// The latest error.
        error: StorageError,
        /// When the episode began (wall clock).
        since: DateTime<Utc>,
        /// Records of this episode that will never reach the file.
        lost: u64,
        /// Records held in memory, written if writing resumes before they overflow or the log closes.
        waiting: u64,
    },
    /// Writing failed and works again: what the last episode cost (its note is in the file).
    Recovered {
        /// The episode's error.
        error: StorageError,
        /// When it began.
        since: DateTime<Utc>,
        /// When writing worked again.
        until: DateTime<Utc>,
        /// Records it lost.
        lost: u64,
    },
}

impl LogHealth {
    /// Whether records are not reaching the file now.
    pub fn is_failing(&self) -> bool {
        matches!(self, Self::Failing { .. })
    }

    /// The banner the console shows for this state of the log at `path` (`None` when all is well): what
    /// is not being recorded, where, since when, and what was lost.
    pub fn banner(&self, path: &Path) -> Option<String> {
        let hms = |t: &DateTime<Utc>| t.format("%H:%M:%S UTC");
        match self {
            Self::Ok => None,
            Self::Failing { error, since, lost, waiting } => Some(format!(
                "Session log NOT recording: cannot write {} ({error}) since {}. {lost} records lost, \
                 {waiting} held in memory; retrying every second.",
                path.display(),
                hms(since),
            )),
            Self::Recovered { error, since, until, lost } => Some(format!(
                "Session log recording again to {} since {}. It could not write from {} ({error}): \
                 {lost} records lost.",
                path.display(),
                hms(until),
                hms(since),
            )),
        }
    }
}

/// The health shared between the writer (which sets it) and the console (which reads it).
pub(super) type SharedHealth = Arc<Mutex<LogHealth>>;

/// Tunables of the writer; [`Default`] is what the console uses, tests shrink them.
#[derive(Debug, Clone, Copy)]
pub(super) struct WriterOptions {
    pub(super) pending_limit_bytes: usize,
    pub(super) retry: Duration,
    pub(super) sync_every: Duration,
}

impl Default for WriterOptions {
    fn default() -> Self {
        Self { pending_limit_bytes: PENDING_LIMIT_BYTES, retry: RETRY_INTERVAL, sync_every: SYNC_INTERVAL }
    }
}

/// The current failure episode.
#[derive(Debug)]
struct Failure {
    error: StorageError,
    since: DateTime<Utc>,
    lost: u64,
}

/// Lines on their way to the sink, and the failure bookkeeping.
pub(super) struct Journal {
    sink: Box<dyn LogSink>,
    path: PathBuf,
    opts: WriterOptions,
    /// Serialised lines; `pending[done..]` has not been taken by the sink yet.
    pending: Vec<u8>,
    done: usize,
    failure: Option<Failure>,
    next_retry: Instant,
    last_sync: Instant,
    /// Lines taken by the sink since the last successful `fsync`.
    unsynced: u64,
    health: SharedHealth,
    published: LogHealth,
    pub(super) stats: WriteStats,
    /// Session time of the log's start, for the recovery note.
    start: Instant,
}

impl Journal {
    /// A journal writing to `sink`; `initial` is an error met before the writer started (e.g. the folder
    /// could not be created), which starts the log in a failure episode.
    pub(super) fn new(
        sink: Box<dyn LogSink>,
        path: PathBuf,
        start: Instant,
        opts: WriterOptions,
        health: SharedHealth,
        initial: Option<&io::Error>,
    ) -> Self {
        let now = Instant::now();
        let mut j = Self {
            sink,
            path,
            opts,
            pending: Vec::new(),
            done: 0,
            failure: None,
            next_retry: now,
            last_sync: now,
            unsynced: 0,
            health,
            published: LogHealth::Ok,
            stats: WriteStats::default(),
            start,
        };
        if let Some(e) = initial {
            j.fail(e, now, false);
            j.publish();
        }
        j
    }

    fn waiting_bytes(&self) -> usize {
        self.pending.len() - self.done
    }

    /// Adds one record: serialised into the pending lines, or counted as lost when writing fails and the
    /// held records already fill their memory.
    pub(super) fn push(&mut self, rec: &LogRecord, now: Instant) {
        let line = match serde_json::to_vec(rec) {
            Ok(mut l) => {
                l.push(b'\n');
                l
            }
            Err(e) => {
                // Not reachable with the record types of this module (no maps with non-string keys).
                tracing::error!("session log: a record could not be serialised: {e}");
                self.stats.storage_lost += 1;
                return;
            }
        };
        let full = self.waiting_bytes() + line.len() > self.opts.pending_limit_bytes;
        if let Some(f) = &mut self.failure
            && full
        {
            f.lost += 1;
            self.stats.storage_lost += 1;
            return;
        }
        self.pending.extend_from_slice(&line);
        if self.failure.is_none() && self.waiting_bytes() >= CHUNK_BYTES {
            self.drain(now, false);
        }
    }

    /// Hands the pending lines to the sink (while failing, only once the retry time has come, or when
    /// `force`d at the end), syncs when due, and ends or starts a failure episode accordingly.
    pub(super) fn drain(&mut self, now: Instant, force: bool) {
        if self.failure.is_some() {
            // Nothing to write proves nothing: stay failing until there is something to try with.
            if (now < self.next_retry && !force) || self.waiting_bytes() == 0 {
                return;
            }
            self.sink.reset();
        }
        let sync_due = self.failure.is_some()
            || force
            || (self.unsynced > 0 && now.duration_since(self.last_sync) >= self.opts.sync_every);
        if let Err(e) = self.write_pending() {
            self.fail(&e, now, false);
            return;
        }
        if sync_due && self.unsynced > 0 {
            if let Err(e) = self.sink.sync() {
                self.fail(&e, now, true);
                return;
            }
            self.unsynced = 0;
            self.last_sync = now;
        }
        if let Some(f) = self.failure.take() {
            self.recovered(f, now);
        }
    }

    /// Writes `pending[done..]` as far as the sink takes it, counting the complete lines taken.
    fn write_pending(&mut self) -> io::Result<()> {
        while self.done < self.pending.len() {
            match self.sink.write(&self.pending[self.done..]) {
                Ok(0) => return Err(io::Error::new(io::ErrorKind::WriteZero, "the file took no bytes")),
                Ok(n) => {
                    let n = n.min(self.pending.len() - self.done);
                    let lines = bytecount_newlines(&self.pending[self.done..self.done + n]);
                    self.stats.written += lines;
                    self.unsynced += lines;
                    self.done += n;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => {
                    self.compact();
                    return Err(e);
                }
            }
        }
        self.pending.clear();
        self.done = 0;
        Ok(())
    }

    fn compact(&mut self) {
        self.pending.drain(..self.done);
        self.done = 0;
    }

    /// Starts or continues a failure episode. After a failed `fsync` (`sync_failed`), the lines the kernel
    /// took since the last good one are gone as far as anyone can tell, and counted as lost.
    fn fail(&mut self, e: &io::Error, now: Instant, sync_failed: bool) {
        let error = StorageError::from(e);
        let unconfirmed = if sync_failed { std::mem::take(&mut self.unsynced) } else { 0 };
        self.next_retry = now + self.opts.retry;
        if let Some(f) = &mut self.failure {
            f.lost += unconfirmed;
            f.error = error;
        } else {
            tracing::error!(
                path = %self.path.display(),
                "session log: cannot write {}: {error}; records are held in memory (up to {} KiB), \
                 then lost and counted; retrying every {} ms",
                self.path.display(),
                self.opts.pending_limit_bytes / 1024,
                self.opts.retry.as_millis(),
            );
            self.failure = Some(Failure { error, since: Utc::now(), lost: unconfirmed });
        }
        self.stats.storage_lost += unconfirmed;
    }

    fn recovered(&mut self, f: Failure, now: Instant) {
        let until = Utc::now();
        tracing::warn!(
            path = %self.path.display(),
            "session log: writing {} again; {} records were lost since {} ({})",
            self.path.display(),
            f.lost,
            utc_stamp(f.since),
            f.error,
        );
        let note = LogRecord {
            t_s: now.saturating_duration_since(self.start).as_secs_f64(),
            utc: utc_stamp(until),
            entry: LogEntry::Note {
                text: format!(
                    "storage failure: {} records lost between {} and {} ({})",
                    f.lost,
                    utc_stamp(f.since),
                    utc_stamp(until),
                    f.error
                ),
            },
        };
        self.published = LogHealth::Recovered { error: f.error, since: f.since, until, lost: f.lost };
        self.set_health();
        self.push(&note, now);
        // The note goes out now; should this fail, a new episode starts and is shown.
        self.drain(now, false);
    }

    /// Publishes the health when it changed (once per batch: the console reads it each frame).
    pub(super) fn publish(&mut self) {
        let next = match &self.failure {
            Some(f) => LogHealth::Failing {
                error: f.error.clone(),
                since: f.since,
                lost: f.lost,
                waiting: bytecount_newlines(&self.pending[self.done..]),
            },
            None => return,
        };
        if next != self.published {
            self.published = next;
            self.set_health();
        }
    }

    fn set_health(&self) {
        *self.health.lock().unwrap_or_else(PoisonError::into_inner) = self.published.clone();
    }

    /// The last attempt when the log closes: everything pending is written and synced, or counted as lost
    /// and returned as the error.
    pub(super) fn finish(&mut self) -> io::Result<WriteStats> {
        self.drain(Instant::now(), true);
        let outcome = match &mut self.failure {
            None => Ok(self.stats),
            Some(f) => {
                let waiting = bytecount_newlines(&self.pending[self.done..]);
                f.lost += waiting;
                self.stats.storage_lost += waiting;
                Err(io::Error::new(
                    f.error.kind,
                    format!(
                        "{}: {} records of this session were not written ({})",
                        self.path.display(),
                        f.lost,
                        f.error
                    ),
                ))
            }
        };
        self.publish();
        outcome
    }
}

#[allow(clippy::naive_bytecount)] // a few KiB per batch; not worth a dependency
fn bytecount_newlines(bytes: &[u8]) -> u64 {
    bytes.iter().filter(|b| **b == b'\n').count() as u64
}

#[cfg(test)]
mod tests {
    use std::io::Cursor;
    use std::sync::mpsc;

    use super::super::{RateLimits, ReadMode, SessionLog, read_log, read_log_from};
    use super::*;

    const ENOSPC: i32 = 28;
    const EIO: i32 = 5;

    /// What the injected disk does.
    #[derive(Debug, Default)]
    struct Disk {
        data: Vec<u8>,
        /// Bytes it still takes; `None` = no limit. At 0 a write fails with `full_error`.
        space: Option<usize>,
        full_error: i32,
        /// `fsync` fails with this error number.
        sync_error: Option<i32>,
        /// Writes wait for this to be cleared.
        stalled: Option<mpsc::Receiver<()>>,
    }

    #[derive(Clone, Default)]
    struct TestSink(Arc<Mutex<Disk>>);

    impl LogSink for TestSink {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            let stall = self.0.lock().unwrap().stalled.take();
            if let Some(rx) = stall {
                let _ = rx.recv();
            }
            let mut d = self.0.lock().unwrap();
            let n = d.space.map_or(buf.len(), |s| s.min(buf.len()));
            if n == 0 && !buf.is_empty() {
                return Err(io::Error::from_raw_os_error(d.full_error));
            }
            if let Some(s) = &mut d.space {
                *s -= n;
            }
            d.data.extend_from_slice(&buf[..n]);
            Ok(n)
        }

        fn sync(&mut self) -> io::Result<()> {
            match self.0.lock().unwrap().sync_error {
                Some(code) => Err(io::Error::from_raw_os_error(code)),
                None => Ok(()),
            }
        }
    }

    fn note(i: u32) -> LogRecord {
        LogRecord {
            // Session time 0: the writer's own notes (stamped with real session time) come after.
            t_s: 0.0,
            utc: "2026-11-26T10:00:00.000Z".into(),
            entry: LogEntry::Note { text: format!("n{i:04}") },
        }
    }

    fn line_len() -> usize {
        serde_json::to_vec(&note(0)).unwrap().len() + 1
    }

    fn start(sink: &TestSink, pending_records: usize) -> SessionLog {
        let opts = WriterOptions {
            pending_limit_bytes: pending_records * line_len(),
            retry: Duration::from_millis(20),
            sync_every: Duration::from_millis(20),
        };
        SessionLog::start_writer(
            Box::new(sink.clone()),
            PathBuf::from("/test/session.jsonl"),
            Instant::now(),
            RateLimits::unlimited(),
            opts,
            None,
        )
        .unwrap()
    }

    fn wait_for(what: &str, mut cond: impl FnMut() -> bool) {
        let deadline = Instant::now() + Duration::from_secs(20);
        while !cond() {
            assert!(Instant::now() < deadline, "timed out waiting for {what}");
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// The numbers of the `nNNNN` notes in `bytes`, in file order; the storage notes separately. Every
    /// line must parse (strict reading).
    fn notes_in(bytes: &[u8]) -> (Vec<u32>, Vec<String>) {
        let (records, stats) = read_log_from(Cursor::new(bytes.to_vec()), ReadMode::Strict).unwrap();
        assert_eq!(stats.skipped(), 0, "{stats:?}");
        let mut ours = Vec::new();
        let mut storage = Vec::new();
        for r in records {
            if let LogEntry::Note { text } = r.entry {
                match text.strip_prefix('n').and_then(|n| n.parse().ok()) {
                    Some(i) => ours.push(i),
                    None => storage.push(text),
                }
            }
        }
        (ours, storage)
    }

    #[test]
    fn a_full_disk_is_shown_counted_and_survived() {
        let sink = TestSink::default();
        let log = start(&sink, 10);
        let tx = log.sender().unwrap();
        for i in 0..5 {
            tx.send(note(i));
        }
        wait_for("5 lines", || bytecount_newlines(&sink.0.lock().unwrap().data) == 5);
        assert_eq!(log.health(), LogHealth::Ok);

        // The disk fills in the middle of the next line.
        {
            let mut d = sink.0.lock().unwrap();
            d.space = Some(line_len() / 2);
            d.full_error = ENOSPC;
        }
        tx.send(note(5));
        wait_for("the failure", || log.health().is_failing());
        for i in 6..35 {
            assert!(tx.send(note(i)), "the sender never fails for the disk");
        }
        wait_for(
            "all 30 accounted for",
            || matches!(log.health(), LogHealth::Failing { lost, waiting, .. } if lost + waiting == 30),
        );
        let LogHealth::Failing { error, lost, waiting, since } = log.health() else { unreachable!() };
        assert_eq!((error.kind, error.os_code), (io::ErrorKind::StorageFull, Some(ENOSPC)));
        // Memory for 10 lines: the rest of the half-written line 5 and 9 whole ones; 20 lost.
        assert_eq!((lost, waiting), (20, 10));
        assert!((Utc::now() - since).num_seconds() < 20);
        let banner = log.health().banner(log.path()).unwrap();
        assert!(banner.contains("NOT recording") && banner.contains("/test/session.jsonl"), "{banner}");
        assert!(
            banner.contains("No space left on device") && banner.contains(&format!("{lost} records lost"))
        );

        // Room again: the held records go out first, then the note, then the new records.
        sink.0.lock().unwrap().space = None;
        wait_for("recovery", || matches!(log.health(), LogHealth::Recovered { .. }));
        let LogHealth::Recovered { lost: lost_then, .. } = log.health() else { unreachable!() };
        assert_eq!(lost_then, lost);
        for i in 35..45 {
            tx.send(note(i));
        }
        drop(tx);
        let stats = log.close().unwrap();
        assert_eq!(stats.storage_lost, lost);
        let (ours, storage) = notes_in(&sink.0.lock().unwrap().data);
        assert!(ours.windows(2).all(|w| w[0] < w[1]), "in order, none twice: {ours:?}");
        assert_eq!(ours.len() as u64 + lost, 45, "every record is in the file or counted as lost");
        assert!(ours.starts_with(&[0, 1, 2, 3, 4, 5]) && ours.ends_with(&(35..45).collect::<Vec<_>>()));
        assert_eq!(storage.len(), 1, "{storage:?}");
        assert!(storage[0].starts_with(&format!("storage failure: {lost} records lost between ")));
        assert!(storage[0].ends_with("(No space left on device (os error 28))"), "{}", storage[0]);
        assert_eq!(stats.written, ours.len() as u64 + 1);
    }

    #[test]
    fn a_failing_fsync_counts_what_it_may_have_lost() {
        let sink = TestSink::default();
        sink.0.lock().unwrap().sync_error = Some(EIO);
        let log = start(&sink, 100);
        let tx = log.sender().unwrap();
        for i in 0..3 {
            tx.send(note(i));
        }
        wait_for("the failure", || log.health().is_failing());
        let LogHealth::Failing { error, lost, .. } = log.health() else { unreachable!() };
        assert_eq!(error.os_code, Some(EIO));
        assert!(error.message.contains("Input/output error"), "{error}");
        assert!(lost >= 1, "the unconfirmed lines count as lost");
        sink.0.lock().unwrap().sync_error = None;
        tx.send(note(3));
        wait_for("recovery", || matches!(log.health(), LogHealth::Recovered { .. }));
        drop(tx);
        let stats = log.close().unwrap();
        // Whatever the batching, the three before the failure were written but not confirmed.
        assert_eq!(stats.storage_lost, 3);
        let (_, storage) = notes_in(&sink.0.lock().unwrap().data);
        assert!(storage[0].starts_with("storage failure: 3 records lost"), "{storage:?}");
    }

    #[test]
    fn closing_while_the_disk_is_full_says_what_was_not_written() {
        let sink = TestSink::default();
        {
            let mut d = sink.0.lock().unwrap();
            d.space = Some(0);
            d.full_error = ENOSPC;
        }
        let log = start(&sink, 100);
        let tx = log.sender().unwrap();
        for i in 0..4 {
            tx.send(note(i));
        }
        drop(tx);
        let e = log.close().unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::StorageFull);
        let msg = e.to_string();
        assert!(msg.contains("/test/session.jsonl") && msg.contains("4 records"), "{msg}");
    }

    #[test]
    fn a_stalled_disk_never_blocks_the_senders() {
        let sink = TestSink::default();
        let (release, stalled) = mpsc::channel();
        sink.0.lock().unwrap().stalled = Some(stalled);
        let log = start(&sink, 100);
        let tx = log.sender().unwrap();
        // More than the whole queue: with the writer stuck in a write, the rest must be dropped, not waited
        // for.
        let n = super::super::QUEUE_LIMITED + super::super::QUEUE_RESERVED + 100;
        for i in 0..n {
            assert!(tx.send(note(i as u32)));
        }
        assert!(log.dropped() >= 100, "{}", log.dropped());
        release.send(()).unwrap();
        drop(tx);
        let dropped = log.dropped();
        let stats = log.close().unwrap();
        assert_eq!(stats.queue_dropped, dropped);
        assert_eq!(stats.written, (n as u64 - dropped) + 1, "the rest, and the note counting the drops");
    }

    /// A small tmpfs mounted for one test (the machine allows it when the tests run as root); unmounted
    /// when dropped.
    struct Tmpfs(PathBuf);

    impl Tmpfs {
        fn mount(tag: &str, size: &str) -> Option<Self> {
            let dir = std::env::temp_dir().join(format!("vestnav-tmpfs-{tag}-{}", std::process::id()));
            std::fs::create_dir_all(&dir).ok()?;
            let ok = std::process::Command::new("mount")
                .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
                .arg(&dir)
                .stderr(std::process::Stdio::null())
                .status()
                .is_ok_and(|s| s.success());
            if ok {
                Some(Self(dir))
            } else {
                eprintln!("SKIPPED: cannot mount a tmpfs here (not root, or no mount permission)");
                let _ = std::fs::remove_dir(&dir);
                None
            }
        }

        fn remount(&self, how: &str) {
            let status = std::process::Command::new("mount")
                .args(["-o", &format!("remount,{how}")])
                .arg(&self.0)
                .status()
                .unwrap();
            assert!(status.success(), "remount {how}");
        }
    }

    impl Drop for Tmpfs {
        fn drop(&mut self) {
            let _ = std::process::Command::new("umount").arg("-l").arg(&self.0).status();
            let _ = std::fs::remove_dir(&self.0);
        }
    }

    #[test]
    fn a_real_full_tmpfs_is_shown_and_survived() {
        let Some(fs) = Tmpfs::mount("full", "64k") else { return };
        let log = SessionLog::create_resilient(&fs.0).unwrap();
        assert_eq!(log.health(), LogHealth::Ok);
        let tx = log.sender().unwrap();
        tx.send(note(0));
        // Fill the rest of the file system.
        let filler = fs.0.join("filler");
        let mut f = std::fs::File::create(&filler).unwrap();
        let full = loop {
            if let Err(e) = std::io::Write::write_all(&mut f, &[0u8; 4096]) {
                break e;
            }
        };
        assert_eq!(full.raw_os_error(), Some(ENOSPC));
        drop(f);
        let mut i = 1;
        wait_for("the full disk to show", || {
            tx.send(note(i));
            i += 1;
            std::thread::sleep(Duration::from_millis(20));
            log.health().is_failing()
        });
        let LogHealth::Failing { error, .. } = log.health() else { unreachable!() };
        assert_eq!(error.kind, io::ErrorKind::StorageFull);
        std::fs::remove_file(&filler).unwrap();
        wait_for("recovery", || matches!(log.health(), LogHealth::Recovered { .. }));
        tx.send(note(9999));
        drop(tx);
        let path = log.path().to_path_buf();
        let stats = log.close().unwrap();
        let (records, read) = read_log(&path).unwrap();
        assert_eq!(read.skipped(), 0, "no broken line: {read:?}");
        let texts: Vec<_> = records
            .iter()
            .filter_map(|r| match &r.entry {
                LogEntry::Note { text } => Some(text.as_str()),
                _ => None,
            })
            .collect();
        let ours = texts.iter().filter(|t| t.starts_with('n')).count() as u64;
        assert_eq!(ours + stats.storage_lost, u64::from(i) + 1, "in the file or counted");
        assert!(texts.iter().any(|t| t.starts_with("storage failure: ")), "{texts:?}");
        assert_eq!(texts.last(), Some(&"n9999"));
    }

    #[test]
    fn a_read_only_folder_is_shown_and_the_log_starts_when_it_can() {
        let Some(fs) = Tmpfs::mount("ro", "1m") else { return };
        fs.remount("ro");
        let dir = fs.0.join("sessions");
        let log = SessionLog::create_resilient(&dir).unwrap();
        let LogHealth::Failing { error, .. } = log.health() else { panic!("{:?}", log.health()) };
        assert_eq!((error.kind, error.os_code), (io::ErrorKind::ReadOnlyFilesystem, Some(30)));
        let banner = log.health().banner(log.path()).unwrap();
        assert!(banner.contains(&dir.display().to_string()) && banner.contains("Read-only"), "{banner}");
        let tx = log.sender().unwrap();
        for i in 0..3 {
            tx.send(note(i));
        }
        wait_for("3 held", || matches!(log.health(), LogHealth::Failing { waiting: 3, .. }));
        fs.remount("rw");
        wait_for("recovery", || matches!(log.health(), LogHealth::Recovered { lost: 0, .. }));
        drop(tx);
        let path = log.path().to_path_buf();
        log.close().unwrap();
        assert!(path.starts_with(&dir));
        let (ours, storage) = notes_in(&std::fs::read(&path).unwrap());
        assert_eq!(ours, vec![0, 1, 2]);
        assert!(storage[0].starts_with("storage failure: 0 records lost"), "{storage:?}");
    }
}
