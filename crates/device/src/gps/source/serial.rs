//! The serial source: automatic baud detection and the port's read loop (stale and lost detection).

use std::io::Read;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::{DETECT_BAUDS, LOST_AFTER, STALE_AFTER, SourceState, Worker};
use crate::gps::framing::Framer;
use crate::gps::{DecoderConfig, GpsEvent, NmeaDecoder};

/// Scores bytes read at a candidate baud: the number of sentences with a valid checksum.
pub fn score_baud(bytes: &[u8]) -> u64 {
    let mut f = Framer::new();
    f.feed(bytes, |_, _| {});
    f.stats().sentences
}

/// Tries each baud of [`DETECT_BAUDS`] for up to `per_baud` and returns the first with at least two
/// valid sentences, with the bytes read there (not to be lost).
pub fn detect_baud(port: &str, per_baud: Duration, stop: &AtomicBool) -> Result<(u32, Vec<u8>), String> {
    let mut last_err = String::from("no NMEA at any baud rate");
    for baud in DETECT_BAUDS {
        if stop.load(Ordering::Relaxed) {
            return Err("stopped".into());
        }
        let mut p = match crate::serial::open(port, baud, Duration::from_millis(100)) {
            Ok(p) => p,
            Err(e) => {
                last_err = e.to_string();
                continue;
            }
        };
        let mut got = Vec::new();
        let end = Instant::now() + per_baud;
        let mut buf = [0u8; 1024];
        while Instant::now() < end && !stop.load(Ordering::Relaxed) {
            match p.read(&mut buf) {
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => {
                    last_err = format!("{port}: {e}");
                    break;
                }
            }
            if score_baud(&got) >= 2 {
                return Ok((baud, got));
            }
        }
    }
    Err(last_err)
}

pub(super) fn run_serial(w: &Worker, port: &str, baud: Option<u32>) {
    let mut attempt = 0u32;
    loop {
        if !w.back_off(attempt) {
            return;
        }
        attempt += 1;
        let detail =
            baud.map_or_else(|| format!("{port}, detecting baud"), |b| format!("{port} at {b} baud"));
        if !w.state(SourceState::Connecting { detail }) {
            return;
        }
        let (baud, first) = match baud {
            Some(b) => (b, Vec::new()),
            None => match detect_baud(port, Duration::from_millis(1500), &w.stop) {
                Ok(x) => x,
                Err(reason) => {
                    tracing::warn!(port, "GPS serial port {port}: baud detection failed: {reason}");
                    if !w.state(SourceState::Lost { reason }) {
                        return;
                    }
                    continue;
                }
            },
        };
        let mut p = match crate::serial::open(port, baud, Duration::from_millis(100)) {
            Ok(p) => p,
            Err(e) => {
                tracing::warn!(port, baud, "GPS serial port {port}: cannot open: {e}");
                if !w.state(SourceState::Lost { reason: e.to_string() }) {
                    return;
                }
                continue;
            }
        };
        tracing::info!(port, baud, "GPS serial port {port} open at {baud} baud");
        if !w.state(SourceState::Live { detail: format!("{port} at {baud} baud") }) {
            return;
        }
        let mut d = NmeaDecoder::new(DecoderConfig::live()).with_raw_lines();
        d.handle_bytes(&first, Instant::now());
        let reason = read_loop(w, &mut d, |buf| p.read(buf));
        match reason {
            None => return,
            Some(reason) => {
                tracing::warn!(port, "GPS serial port {port}: link lost: {reason}");
                attempt = 1;
                if !w.state(SourceState::Lost { reason }) {
                    return;
                }
            }
        }
    }
}

/// Reads until error/loss (returns the reason) or stop (returns None).
fn read_loop(
    w: &Worker,
    d: &mut NmeaDecoder,
    mut read: impl FnMut(&mut [u8]) -> std::io::Result<usize>,
) -> Option<String> {
    let mut buf = [0u8; 4096];
    let mut last_data = Instant::now();
    let mut stale = false;
    let mut last_stats = Instant::now();
    loop {
        if w.stopped() {
            return None;
        }
        let now = Instant::now();
        match read(&mut buf) {
            Ok(0) => return Some("end of stream (port closed)".into()),
            Ok(n) => {
                d.handle_bytes(&buf[..n], now);
                last_data = now;
                if stale {
                    stale = false;
                    if !w.state(SourceState::Live { detail: "data again".into() }) {
                        return None;
                    }
                }
            }
            Err(e) if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Some(e.to_string()),
        }
        d.handle_timeout(Instant::now());
        if !w.drain(d) {
            return None;
        }
        let idle = now.saturating_duration_since(last_data);
        if !stale && idle >= STALE_AFTER {
            stale = true;
            if !w.state(SourceState::Stale) {
                return None;
            }
        }
        if idle >= LOST_AFTER {
            return Some(format!("no data for {} s", LOST_AFTER.as_secs()));
        }
        if last_stats.elapsed() >= Duration::from_secs(1) {
            last_stats = Instant::now();
            if !w.send(GpsEvent::Stats(d.stats())) {
                return None;
            }
        }
    }
}
