//! The recording format: plain NMEA with our timestamps interleaved.
//!
//! A recording is the raw byte stream of sentences as received, with a `$PVNAV,TS,<unix_ms>*hh` sentence
//! (checksummed like NMEA) written before each chunk of received data: the wall-clock time the chunk
//! arrived, in Unix milliseconds. It stays a valid NMEA log (gpsd, gpsdecode and any NMEA tool skip the
//! proprietary sentence), our decoder reads it directly, and the replay source paces by the timestamps.
//! Timestamps are only inserted at line boundaries, so sentences are never split. Operator marks
//! (`$PVNAV,MARK,<n>,<label>*hh`, the cone test's records) are inserted the same way: a mark that arrives
//! while a received sentence is half written waits for the end of that line.

use std::io::Write;

use super::nmea_out::{mark_sentence, timestamp_sentence};

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
