//! The serial source: automatic baud detection and the port's read loop (stale and lost detection).

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use super::corrections::{Filled, PortSlot};
use super::{ConfigRequest, DETECT_BAUDS, LOST_AFTER, STALE_AFTER, SourceState, Worker};
use crate::gps::framing::Framer;
use crate::gps::receiver_config::{ConfigEvent, ConfigReporter, ConfigSession, commands};
use crate::gps::{DecoderConfig, GpsEvent, NmeaDecoder};

/// Scores bytes read at a candidate baud: the number of sentences and binary (UBX, `SiRF`) frames with a
/// valid checksum.
pub fn score_baud(bytes: &[u8]) -> u64 {
    let mut f = Framer::new();
    f.feed(bytes, |_, _| {});
    let s = f.stats();
    s.sentences + s.ubx_frames + s.sirf_frames
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

pub(super) fn run_serial(
    w: &Worker,
    port: &str,
    baud: Option<u32>,
    config: &Receiver<ConfigRequest>,
    slot: &PortSlot,
) {
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
        // RTK corrections write through a second handle on the open port (see `corrections`).
        match p.try_clone() {
            Ok(writer) => slot.set(Some(Box::new(writer))),
            Err(e) => tracing::warn!(port, "GPS serial port {port}: no write handle for corrections: {e}"),
        }
        let _filled = Filled(slot);
        let mut d = NmeaDecoder::new(DecoderConfig::live()).with_raw_lines();
        d.handle_bytes(&first, Instant::now());
        let reason = read_loop(w, &mut d, &mut Port { io: &mut *p, baud }, config);
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

/// The open port and its rate (the `SiRF` protocol switches keep it).
struct Port<'a, T: Read + Write + ?Sized> {
    io: &'a mut T,
    baud: u32,
}

/// A configuration being sent: the session and where its outcomes go.
struct Configuring {
    session: ConfigSession,
    reporter: ConfigReporter,
}

impl Drop for Configuring {
    /// A run cut short (the link lost, the source stopped) says so instead of leaving the operator waiting.
    fn drop(&mut self) {
        if !self.session.is_done() {
            self.reporter
                .report(ConfigEvent::Failed("the link to the receiver ended during configuration".into()));
        }
    }
}

/// Starts a configuration run at the port's baud, or reports why it cannot start.
fn start_config(req: ConfigRequest, baud: u32) -> Option<Configuring> {
    match commands(&req.config, baud) {
        Ok(cmds) => Some(Configuring { session: ConfigSession::new(cmds), reporter: req.reporter }),
        Err(e) => {
            req.reporter.report(ConfigEvent::Failed(e.to_string()));
            None
        }
    }
}

/// Writes what the configuration run has due, and hands its decided outcomes to the reporter and (as a
/// notice) to the consumers. False when the consumers are gone or a stop was requested.
fn step_config(w: &Worker, c: &mut Configuring, io: &mut (impl Write + ?Sized), now: Instant) -> bool {
    c.session.handle_timeout(now);
    while let Some(bytes) = c.session.poll_transmit(now) {
        if let Err(e) = io.write_all(&bytes).and_then(|()| io.flush()) {
            c.session.write_failed(&e.to_string(), now);
        }
    }
    while let Some(o) = c.session.poll_outcome() {
        let text = format!("receiver configuration: {} {}", o.name, o.outcome.label());
        c.reporter.report(ConfigEvent::Outcome(o));
        if !w.send(GpsEvent::Notice(text)) {
            return false;
        }
    }
    true
}

/// Reads until error/loss (returns the reason) or stop (returns None); between reads, writes the commands
/// of a receiver configuration asked for through `config` and feeds the replies to it.
fn read_loop<T: Read + Write + ?Sized>(
    w: &Worker,
    d: &mut NmeaDecoder,
    port: &mut Port<'_, T>,
    config: &Receiver<ConfigRequest>,
) -> Option<String> {
    let mut configuring: Option<Configuring> = None;
    let mut buf = [0u8; 4096];
    let mut last_data = Instant::now();
    let mut stale = false;
    let mut last_stats = Instant::now();
    loop {
        if w.stopped() {
            return None;
        }
        let now = Instant::now();
        if configuring.is_none()
            && let Ok(req) = config.try_recv()
        {
            configuring = start_config(req, port.baud);
        }
        if let Some(c) = &mut configuring {
            if !step_config(w, c, port.io, now) {
                return None;
            }
            if c.session.is_done() {
                c.reporter.report(ConfigEvent::Finished);
                configuring = None;
            }
        }
        match port.io.read(&mut buf) {
            Ok(0) => return Some("end of stream (port closed)".into()),
            Ok(n) => {
                if let Some(c) = &mut configuring {
                    c.session.handle_bytes(&buf[..n], now);
                }
                d.handle_bytes(&buf[..n], now);
                last_data = now;
                if stale {
                    stale = false;
                    if !w.state(SourceState::Live { detail: "data again".into() }) {
                        return None;
                    }
                }
            }
            Err(e) if crate::serial::is_timeout(&e) => {}
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
