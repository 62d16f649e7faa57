//! The recording format: plain NMEA with our timestamps interleaved.
//!
//! A recording is the raw byte stream of sentences as received, with a `$PVNAV,TS,<unix_ms>*hh` sentence
//! (checksummed like NMEA) written before each chunk of received data: the wall-clock time the chunk
//! arrived, in Unix milliseconds. It stays a valid NMEA log (gpsd, gpsdecode and any NMEA tool skip the
//! proprietary sentence), our decoder reads it directly, and the replay source paces by the timestamps.
//! Timestamps are only inserted at line boundaries, so sentences are never split. Operator marks
//! (`$PVNAV,MARK,<n>,<label>*hh`, the cone test's records) are inserted the same way: a mark that arrives
//! while a received sentence is half written waits for the end of that line.
//!
//! [`RecordingTap`] records what a running source delivers: one more consumer of its events (an
//! [`Outbox`] that writes each [`GpsEvent::Raw`] sentence on the source's own thread), started and
//! stopped while the source runs — the console's Record toggle.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use super::nmea_out::{mark_sentence, timestamp_sentence};
use super::{GpsEvent, RawLine};
use crate::outbox::Outbox;

/// Writes received bytes to a recording, inserting timestamps at line boundaries.
#[derive(Debug)]
pub struct Recorder<W: Write> {
    out: W,
    at_line_start: bool,
    last_ts_ms: Option<i64>,
    /// Mark sentences waiting for the end of the line being written.
    pending_marks: Vec<String>,
    marks: u32,
}

impl<W: Write> Recorder<W> {
    /// A recorder writing to `out`.
    pub fn new(out: W) -> Self {
        Self { out, at_line_start: true, last_ts_ms: None, pending_marks: Vec::new(), marks: 0 }
    }

    /// Records `data` received at wall-clock `unix_ms`. A timestamp precedes the first complete line
    /// start in `data` when the time moved on since the last one.
    pub fn write(&mut self, data: &[u8], unix_ms: i64) -> std::io::Result<()> {
        let mut rest = data;
        while !rest.is_empty() {
            if self.at_line_start && self.last_ts_ms != Some(unix_ms) {
                self.out.write_all(timestamp_sentence(unix_ms).as_bytes())?;
                self.last_ts_ms = Some(unix_ms);
            }
            let cut = rest.iter().position(|&b| b == b'\n').map_or(rest.len(), |i| i + 1);
            self.out.write_all(&rest[..cut])?;
            self.at_line_start = rest[cut - 1] == b'\n';
            rest = &rest[cut..];
            if self.at_line_start {
                self.write_pending_marks(unix_ms)?;
            }
        }
        Ok(())
    }

    /// Records an operator mark made at wall-clock `unix_ms`, numbered 1, 2, ... in order; returns its
    /// number. It is written at once when the recording is at a line boundary, else right after the
    /// line being received.
    pub fn mark(&mut self, label: &str, unix_ms: i64) -> std::io::Result<u32> {
        self.marks += 1;
        self.pending_marks.push(mark_sentence(self.marks, label));
        if self.at_line_start {
            self.write_pending_marks(unix_ms)?;
        }
        Ok(self.marks)
    }

    fn write_pending_marks(&mut self, unix_ms: i64) -> std::io::Result<()> {
        if self.pending_marks.is_empty() {
            return Ok(());
        }
        if self.last_ts_ms != Some(unix_ms) {
            self.out.write_all(timestamp_sentence(unix_ms).as_bytes())?;
            self.last_ts_ms = Some(unix_ms);
        }
        for m in self.pending_marks.drain(..) {
            self.out.write_all(m.as_bytes())?;
        }
        Ok(())
    }

    /// Flushes the output.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }

    /// The inner writer.
    pub fn into_inner(self) -> W {
        self.out
    }
}

/// Unix time now, in milliseconds.
pub fn unix_ms_now() -> i64 {
    chrono::Utc::now().timestamp_millis()
}

/// A fresh recording name in `dir`, `vestnav-gps-<YYYYmmdd-HHMMSS>.nmea` at `now` (local time), with
/// `-2`, `-3`, ... appended while that name exists: a new recording never replaces a file.
pub fn new_recording_path(dir: &Path, now: chrono::DateTime<chrono::Local>) -> PathBuf {
    let stem = format!("vestnav-gps-{}", now.format("%Y%m%d-%H%M%S"));
    let mut path = dir.join(format!("{stem}.nmea"));
    let mut n = 2;
    while path.exists() {
        path = dir.join(format!("{stem}-{n}.nmea"));
        n += 1;
    }
    path
}

/// What a [`RecordingTap`] has written (serde: a station's snapshot carries it to a remote view).
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct RecordingStatus {
    /// The file.
    pub path: PathBuf,
    /// Bytes written (sentences, line ends and timestamps).
    pub bytes: u64,
    /// Sentences written.
    pub sentences: u64,
    /// Still recording (false after [`RecordingTap::stop`] or an error).
    pub active: bool,
    /// The error that ended the recording, naming the file.
    pub error: Option<String>,
}

/// How often a running recording is flushed to its file.
const FLUSH_EVERY: Duration = Duration::from_secs(1);

struct Active {
    rec: Recorder<CountingWriter<BufWriter<File>>>,
    last_flush: Instant,
}

#[derive(Default)]
struct TapState {
    active: Option<Active>,
    status: Option<RecordingStatus>,
}

/// Counts the bytes that pass through.
struct CountingWriter<W> {
    inner: W,
    bytes: u64,
}

impl<W: Write> Write for CountingWriter<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.bytes += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// Records the raw sentences of a running source in the [recording format](self), on demand. Clones
/// share one recording. Only NMEA sentences are written (`$`/`!` first): a gpsd source's JSON is not
/// recorded, and the input's own `$PVNAV,TS` stamps are replaced by the recorder's.
#[derive(Clone, Default)]
pub struct RecordingTap {
    state: Arc<Mutex<TapState>>,
}

impl std::fmt::Debug for RecordingTap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RecordingTap").field("status", &self.status()).finish()
    }
}

impl RecordingTap {
    fn lock(&self) -> std::sync::MutexGuard<'_, TapState> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Starts recording into a new file at `path` (stopping a recording in progress first). Refuses an
    /// existing file: a recording never replaces one. The error names the file.
    pub fn start(&self, path: &Path) -> Result<(), String> {
        self.stop();
        let file = File::options()
            .write(true)
            .create_new(true)
            .open(path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        let mut st = self.lock();
        st.active = Some(Active {
            rec: Recorder::new(CountingWriter { inner: BufWriter::new(file), bytes: 0 }),
            last_flush: Instant::now(),
        });
        st.status =
            Some(RecordingStatus { path: path.to_owned(), active: true, ..RecordingStatus::default() });
        Ok(())
    }

    /// Stops recording and flushes the file; returns what was written.
    pub fn stop(&self) -> Option<RecordingStatus> {
        let mut st = self.lock();
        if let Some(mut a) = st.active.take()
            && let Some(status) = st.status.as_mut()
        {
            status.active = false;
            if let Err(e) = a.rec.flush() {
                status.error = Some(format!("{}: {e}", status.path.display()));
            }
            status.bytes = a.rec.into_inner().bytes;
        }
        st.status.clone()
    }

    /// Writes what is buffered to the file (a source that ended leaves nothing half-written for a reader);
    /// a write error ends the recording and is kept in the status.
    pub fn flush(&self) {
        let mut st = self.lock();
        let st = &mut *st;
        let (Some(a), Some(status)) = (st.active.as_mut(), st.status.as_mut()) else { return };
        a.last_flush = Instant::now();
        if let Err(e) = a.rec.flush() {
            status.error = Some(format!("{}: {e}", status.path.display()));
            status.active = false;
            st.active = None;
        }
    }

    /// True while recording.
    pub fn is_recording(&self) -> bool {
        self.lock().active.is_some()
    }

    /// The current or last recording's counts and error.
    pub fn status(&self) -> Option<RecordingStatus> {
        self.lock().status.clone()
    }

    /// Records one sentence received at wall-clock `unix_ms` (nothing when not recording, or when it is
    /// not an NMEA sentence or is a `$PVNAV,TS` stamp). A write error ends the recording and is kept in
    /// the status.
    pub fn record(&self, line: &RawLine, unix_ms: i64) {
        let text = line.text.trim_end();
        if !(text.starts_with('$') || text.starts_with('!')) || text.starts_with("$PVNAV,TS,") {
            return;
        }
        let mut st = self.lock();
        let st = &mut *st;
        let (Some(a), Some(status)) = (st.active.as_mut(), st.status.as_mut()) else { return };
        let mut result = a.rec.write(text.as_bytes(), unix_ms).and_then(|()| a.rec.write(b"\r\n", unix_ms));
        if result.is_ok() && a.last_flush.elapsed() >= FLUSH_EVERY {
            a.last_flush = Instant::now();
            result = a.rec.flush();
        }
        match result {
            Ok(()) => {
                status.sentences += 1;
                status.bytes = a.rec.out.bytes;
            }
            Err(e) => {
                status.error = Some(format!("{}: {e}", status.path.display()));
                status.active = false;
                st.active = None;
            }
        }
    }

    /// A consumer for a source's outputs that records its [`GpsEvent::Raw`] sentences while a recording
    /// runs, stamped with the wall-clock time they are handed over (on the source's thread).
    pub fn outbox(&self) -> Outbox<GpsEvent> {
        let tap = self.clone();
        Outbox::sink(move |ev: GpsEvent| {
            if let GpsEvent::Raw(line) = &ev {
                tap.record(line, unix_ms_now());
            }
            true
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gps::decode_reader;

    #[test]
    fn marks_never_split_a_sentence_and_decode_as_marks() {
        let mut rec = Recorder::new(Vec::new());
        let gga = "$GPGGA,110518.000,5709.8067,N,00207.2822,W,1,08,1.0,59.3,M,48.7,M,,0000*7E\r\n";
        let (head, tail) = gga.split_at(20);
        rec.write(head.as_bytes(), 1000).unwrap();
        assert_eq!(rec.mark("cone 1", 1001).unwrap(), 1);
        rec.write(tail.as_bytes(), 1002).unwrap();
        assert_eq!(rec.mark("cone, 2", 1003).unwrap(), 2);
        let text = String::from_utf8(rec.into_inner()).unwrap();
        assert!(text.contains(gga), "the GGA must stay whole: {text}");
        // After the GGA, and only after it, comes the first mark (behind its timestamp).
        let lines: Vec<&str> = text.lines().filter(|l| !l.starts_with("$PVNAV,TS,")).collect();
        let gga_at = lines.iter().position(|l| l.starts_with("$GPGGA")).unwrap();
        assert!(lines[gga_at + 1].starts_with("$PVNAV,MARK,1,cone 1*"), "{text}");
        let (_, marks, _) = crate::gps::decode_reader_with_marks(text.as_bytes()).unwrap();
        let labels: Vec<_> = marks.iter().map(|m| (m.number, m.label.as_str())).collect();
        assert_eq!(labels, vec![(1, "cone 1"), (2, "cone  2")]);
    }

    #[test]
    fn recording_decodes_like_the_original() {
        let original = std::fs::read(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/gpsd-logs/nd-1005.log"),
        )
        .unwrap();
        let mut rec = Recorder::new(Vec::new());
        for (i, chunk) in original.chunks(37).enumerate() {
            rec.write(chunk, 1_700_000_000_000 + i64::try_from(i).unwrap() * 100).unwrap();
        }
        let recorded = rec.into_inner();
        let (a, sa) = decode_reader(original.as_slice()).unwrap();
        let (b, sb) = decode_reader(recorded.as_slice()).unwrap();
        assert_eq!(
            a,
            b.iter()
                .map(|f| crate::gps::Fix { received_at: a[0].received_at, ..f.clone() })
                .collect::<Vec<_>>()
        );
        assert_eq!(sa.rejected(), sb.rejected());
        assert!(sb.sentences > sa.sentences);
    }
}
