//! The recording format: plain NMEA with our timestamps interleaved.
//!
//! A recording is the raw byte stream of sentences as received, with a `$PVNAV,TS,<unix_ms>*hh` sentence
//! (checksummed like NMEA) written before each chunk of received data: the wall-clock time the chunk
//! arrived, in Unix milliseconds. It stays a valid NMEA log (gpsd, gpsdecode and any NMEA tool skip the
//! proprietary sentence), our decoder reads it directly, and the replay source paces by the timestamps.
//! Timestamps are only inserted at line boundaries, so sentences are never split.

use std::io::Write;

use super::nmea_out::timestamp_sentence;

/// Writes received bytes to a recording, inserting timestamps at line boundaries.
#[derive(Debug)]
pub struct Recorder<W: Write> {
    out: W,
    at_line_start: bool,
    last_ts_ms: Option<i64>,
}

impl<W: Write> Recorder<W> {
    /// A recorder writing to `out`.
    pub fn new(out: W) -> Self {
        Self { out, at_line_start: true, last_ts_ms: None }
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
