//! The session log: every position, vest command, ack and operator mark, written as it happens.
//!
//! Format: JSON Lines, one [`LogRecord`] per line, UTF-8, appended and flushed by a dedicated writer thread
//! (the UI and the workers only hand records over a bounded channel, they never touch the disk). A line
//! looks like `{"t_s":12.03,"utc":"2026-11-22T18:00:12.030Z","kind":"fix","lat_deg":42.3562,...}`;
//! `t_s` is seconds since the session started, `utc` the wall clock. Files are named
//! `session-YYYYmmdd-HHMMSS.jsonl` in the log directory. [`read_log`] reads a log back, skipping and counting
//! lines it cannot parse (a log cut off by a crash still loads).

use std::io::{BufRead, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, sync_channel};
use std::thread::JoinHandle;
use std::time::Instant;

use serde::{Deserialize, Serialize};
use vestnav_core::vest::TactorMask;

use crate::model::{CommandOrigin, Outbox, VestCommand};

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
        /// The command.
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
}

/// One line of the log.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LogRecord {
    /// Seconds since the session started.
    pub t_s: f64,
    /// Wall-clock UTC time.
    pub utc: String,
    /// The entry.
    #[serde(flatten)]
    pub entry: LogEntry,
}

/// The UI's handle on the writer thread; dropping it flushes and closes the file.
#[derive(Debug)]
pub struct SessionLog {
    outbox: Option<Outbox<LogRecord>>,
    start: Instant,
    path: PathBuf,
    thread: Option<JoinHandle<std::io::Result<u64>>>,
}

/// A cheap clonable handle the workers use to add records.
#[derive(Debug, Clone)]
pub struct LogSender {
    outbox: Outbox<LogRecord>,
    start: Instant,
}

impl LogSender {
    /// Stamps `entry` with the session time and the wall clock and queues it.
    pub fn log(&self, entry: LogEntry) {
        let utc = chrono::Utc::now().to_rfc3339_opts(chrono::SecondsFormat::Millis, true);
        self.outbox.send(LogRecord { t_s: self.start.elapsed().as_secs_f64(), utc, entry });
    }
}

impl SessionLog {
    /// Creates `dir/session-<now>.jsonl` and starts the writer thread.
    pub fn create(dir: &Path) -> std::io::Result<Self> {
        std::fs::create_dir_all(dir)?;
        let name = chrono::Utc::now().format("session-%Y%m%d-%H%M%S.jsonl").to_string();
        Self::create_at(&dir.join(name))
    }

    /// Creates (or appends to) the log at `path` and starts the writer thread.
    pub fn create_at(path: &Path) -> std::io::Result<Self> {
        let file = std::fs::OpenOptions::new().create(true).append(true).open(path)?;
        let (tx, rx) = sync_channel::<LogRecord>(8192);
        let thread = std::thread::Builder::new()
            .name("vestnav-session-log".into())
            .spawn(move || write_loop(&rx, BufWriter::new(file)))?;
        Ok(Self {
            outbox: Some(Outbox::new(tx, None)),
            start: Instant::now(),
            path: path.to_path_buf(),
            thread: Some(thread),
        })
    }

    /// A handle for other threads.
    pub fn sender(&self) -> Option<LogSender> {
        self.outbox.as_ref().map(|o| LogSender { outbox: o.clone(), start: self.start })
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Records dropped because the writer could not keep up.
    pub fn dropped(&self) -> u64 {
        self.outbox.as_ref().map_or(0, Outbox::dropped)
    }

    /// Stops the writer after it has written everything queued; returns how many records it wrote.
    pub fn close(mut self) -> std::io::Result<u64> {
        self.finish()
    }

    fn finish(&mut self) -> std::io::Result<u64> {
        self.outbox = None;
        match self.thread.take() {
            Some(t) => t.join().unwrap_or_else(|_| Err(std::io::Error::other("log writer panicked"))),
            None => Ok(0),
        }
    }
}

impl Drop for SessionLog {
    fn drop(&mut self) {
        // Workers may still hold senders; the thread ends when the last one goes. Do not wait for them here.
        self.outbox = None;
        if let Some(t) = self.thread.take()
            && t.is_finished()
        {
            let _ = t.join();
        }
    }
}

/// Writes records until every sender is gone, flushing whenever the queue runs empty.
fn write_loop(rx: &Receiver<LogRecord>, mut out: BufWriter<std::fs::File>) -> std::io::Result<u64> {
    let mut n = 0u64;
    while let Ok(first) = rx.recv() {
        let mut next = Some(first);
        while let Some(rec) = next {
            serde_json::to_writer(&mut out, &rec).map_err(std::io::Error::other)?;
            out.write_all(b"\n")?;
            n += 1;
            next = rx.try_recv().ok();
        }
        out.flush()?;
    }
    out.flush()?;
    Ok(n)
}

/// A log read back from disk.
#[derive(Debug, Clone, Default)]
pub struct LoadedLog {
    /// The records, in file order.
    pub records: Vec<LogRecord>,
    /// Lines that were not valid records (cut off, edited, foreign).
    pub bad_lines: usize,
}

impl LoadedLog {
    /// The positions, as `(t_s, lat_deg, lon_deg)`.
    pub fn track(&self) -> Vec<(f64, f64, f64)> {
        self.records
            .iter()
            .filter_map(|r| match r.entry {
                LogEntry::Fix { lat_deg, lon_deg, .. } => Some((r.t_s, lat_deg, lon_deg)),
                _ => None,
            })
            .collect()
    }

    /// Session length [s].
    pub fn duration_s(&self) -> f64 {
        self.records.last().map_or(0.0, |r| r.t_s)
    }
}

/// Reads a session log; bad lines are skipped and counted, an unreadable file is an error.
pub fn read_log(path: &Path) -> std::io::Result<LoadedLog> {
    let file = std::fs::File::open(path)?;
    let mut log = LoadedLog::default();
    for line in std::io::BufReader::new(file).split(b'\n') {
        let line = line?;
        if line.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        match serde_json::from_slice::<LogRecord>(&line) {
            Ok(r) if r.t_s.is_finite() => log.records.push(r),
            _ => log.bad_lines += 1,
        }
    }
    Ok(log)
}

/// Session logs in `dir`, newest first.
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_records_read_back_and_junk_is_skipped() {
        let dir = std::env::temp_dir().join(format!("vestnav-log-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s.jsonl");
        let _ = std::fs::remove_file(&path);
        let log = SessionLog::create_at(&path).unwrap();
        let tx = log.sender().unwrap();
        tx.log(LogEntry::Fix {
            lat_deg: 42.5,
            lon_deg: -71.25,
            error_m: Some(3.0),
            speed_m_s: None,
            course_deg: None,
            gps_utc: None,
        });
        tx.log(LogEntry::Command {
            origin: CommandOrigin::Manual,
            command: VestCommand::Fire { mask: TactorMask(0b101), on_ms: 500 },
            reason: "operator".into(),
        });
        tx.log(LogEntry::Mark { label: "cone 1".into(), lat_deg: None, lon_deg: None });
        drop(tx);
        assert_eq!(log.close().unwrap(), 3);
        // A crash mid-line leaves a partial record: it must not hide the rest.
        let mut f = std::fs::OpenOptions::new().append(true).open(&path).unwrap();
        f.write_all(b"{\"t_s\":9,\"utc\":\"x\",\"kind\":\"fi").unwrap();
        let back = read_log(&path).unwrap();
        assert_eq!(back.records.len(), 3);
        assert_eq!(back.bad_lines, 1);
        assert_eq!(back.track().len(), 1);
        assert!(matches!(
            &back.records[1].entry,
            LogEntry::Command { command: VestCommand::Fire { mask: TactorMask(5), on_ms: 500 }, .. }
        ));
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("{\"t_s\":"));
        assert!(text.contains("\"kind\":\"mark\""));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
