//! GPS sources on worker threads, all producing the same [`GpsEvent`] stream.
//!
//! [`GpsSource::spawn`] starts one named worker thread that owns one transport and one decoder; every event
//! goes to every consumer's [`Outbox`] (a bounded channel with its own overflow policy and waker: the GUI
//! drops what it cannot draw, a CLI or a file writer waits). A stop request always wins: a worker waiting
//! on a full lossless consumer gives up at once, every blocking read has a short timeout, and
//! [`GpsHandle::stop`] never waits more than [`STOP_WAIT`] for the thread (a thread stuck in DNS or in
//! `connect` is detached and ends by itself). Each source reports its [`SourceState`]; serial and gpsd
//! sources reconnect with exponential backoff (0.5 s doubling to 8 s) until stopped.
//!
//! Input is hostile until checked: the gpsd transport frames lines itself with a bounded buffer
//! ([`super::gpsd::LineFramer`], [`super::gpsd::MAX_LINE_LEN`]) so memory stays bounded whatever a server
//! sends, and every fix is checked by [`super::Fix::validate`] before it is sent.

use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Receiver;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use vestnav_core::gnss_sim::GnssErrorModel;

use super::framing::Framer;
use super::gpsd::{GpsdClient, LineFramer, MAX_LINE_LEN, WATCH};
use super::sentence;
use super::sim::SimulatedReceiver;
use super::{DecoderConfig, GpsEvent, NmeaDecoder};
use crate::outbox::{Outbox, Overflow, Waker};

/// Bauds tried by automatic detection, most likely first (`SiRF` III default 4800, u-blox 9600/38400).
pub const DETECT_BAUDS: [u32; 6] = [4800, 9600, 38400, 115_200, 19200, 57600];
/// No data (for gpsd: no complete line) for this long on a live link: the source is stale.
pub const STALE_AFTER: Duration = Duration::from_secs(3);
/// No data (for gpsd: no complete line) for this long: the link is treated as lost and reopened.
pub const LOST_AFTER: Duration = Duration::from_secs(10);
/// Read timeout of the gpsd socket: the stop flag and the stale/lost timers are checked at least this
/// often, even while a server trickles bytes without a line end.
pub const GPSD_READ_TIMEOUT: Duration = Duration::from_millis(50);
/// The longest [`GpsHandle::stop`] waits for the worker thread before detaching it.
pub const STOP_WAIT: Duration = Duration::from_millis(250);

/// Where fixes come from.
#[derive(Debug, Clone, PartialEq)]
pub enum SourceConfig {
    /// A serial port (USB, Bluetooth SPP `/dev/rfcomm*`, a PTY); `baud: None` detects it.
    Serial {
        /// Port path or name.
        port: String,
        /// Baud rate, or `None` for automatic detection.
        baud: Option<u32>,
    },
    /// An NMEA log or recording replayed in time.
    Replay {
        /// The file.
        path: PathBuf,
        /// Speed factor (1 = recorded speed, 10 = ten times faster); `None` = as fast as possible.
        speed: Option<f64>,
    },
    /// A gpsd daemon's JSON stream.
    Gpsd {
        /// Host name or address (gpsd default 127.0.0.1).
        host: String,
        /// TCP port (gpsd default 2947).
        port: u16,
    },
    /// The built-in simulated receiver walking a route.
    Simulator {
        /// Waypoints (lat, lon) [deg].
        route: Vec<(f64, f64)>,
        /// Walking pace [m/s].
        pace_m_s: f64,
        /// Receiver error model.
        model: GnssErrorModel,
        /// Random seed.
        seed: u64,
        /// Time between epochs (1 s for a 1 Hz receiver); the simulator runs in real time.
        period: Duration,
        /// At the end of the route, start over (with seed `seed + lap`, so each lap has a different error
        /// realisation) and send a [`GpsEvent::Notice`] instead of [`SourceState::Finished`].
        looped: bool,
    },
}

/// A source's connection state.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum SourceState {
    /// Opening the port / connecting / detecting the baud rate.
    Connecting {
        /// What is being tried (e.g. "/dev/rfcomm0 at 4800 baud").
        detail: String,
    },
    /// Data is flowing.
    Live {
        /// E.g. the baud rate found.
        detail: String,
    },
    /// Connected but no data for [`STALE_AFTER`].
    Stale,
    /// The link failed.
    Lost {
        /// Why.
        reason: String,
    },
    /// Waiting before the next connection attempt.
    Reconnecting {
        /// Attempt number (1 = first retry).
        attempt: u32,
        /// Wait before it [ms].
        delay_ms: u64,
    },
    /// A replay reached the end of its file, or the simulator its route.
    Finished,
    /// Stopped on request.
    Stopped,
}

/// The controller of a running source (its events go to the consumers' channels, not through here).
#[derive(Debug)]
pub struct GpsHandle {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl GpsHandle {
    /// True while the worker runs.
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Asks the worker to stop, without waiting.
    pub fn request_stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }

    /// Stops the worker: sets the stop flag and waits for the thread at most [`STOP_WAIT`]. A worker stuck
    /// in a call that cannot be interrupted (DNS resolution, a TCP connect of up to 2 s) is detached and
    /// ends by itself; it sends nothing more once it sees the flag.
    pub fn stop(&mut self) {
        self.request_stop();
        let Some(t) = self.thread.take() else { return };
        let end = Instant::now() + STOP_WAIT;
        while !t.is_finished() && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(2));
        }
        if t.is_finished() {
            let _ = t.join();
        }
    }
}

impl Drop for GpsHandle {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Starts sources.
#[derive(Debug)]
pub struct GpsSource;

struct Worker {
    outputs: Vec<Outbox<GpsEvent>>,
    stop: Arc<AtomicBool>,
}

impl Worker {
    fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    /// Sends an event to every consumer (waiting for a lossless one until stopped); false when a stop was
    /// requested or every consumer is gone.
    fn send(&self, ev: GpsEvent) -> bool {
        if self.stopped() {
            return false;
        }
        let Some((last, rest)) = self.outputs.split_last() else { return false };
        let mut alive = false;
        for o in rest {
            alive |= o.send(ev.clone(), &self.stop);
        }
        alive |= last.send(ev, &self.stop);
        alive && !self.stopped()
    }

    fn state(&self, s: SourceState) -> bool {
        self.send(GpsEvent::State(s))
    }

    fn drain(&self, d: &mut NmeaDecoder) -> bool {
        while let Some(ev) = d.poll_event() {
            if !self.send(ev) {
                return false;
            }
        }
        true
    }

    /// Sleeps up to `d`, waking early on stop; false if stopped.
    fn sleep(&self, d: Duration) -> bool {
        let end = Instant::now() + d;
        while Instant::now() < end {
            if self.stopped() {
                return false;
            }
            std::thread::sleep((end - Instant::now()).min(Duration::from_millis(20)));
        }
        !self.stopped()
    }

    /// Before reconnect attempt `attempt` (0 = the first connection, no wait): reports `Reconnecting` and
    /// sleeps the backoff delay. False when the source was stopped meanwhile.
    fn back_off(&self, attempt: u32) -> bool {
        if attempt == 0 {
            return true;
        }
        let delay = backoff(attempt);
        self.state(SourceState::Reconnecting { attempt, delay_ms: delay.as_millis() as u64 })
            && self.sleep(delay)
    }
}

/// The sources' reconnect backoff: 0.5 s doubling, capped at 8 s (a GPS coming back into Bluetooth range,
/// a restarted gpsd).
pub const RECONNECT: crate::backoff::Backoff =
    crate::backoff::Backoff::new(Duration::from_millis(500), Duration::from_secs(8));

/// Reconnection delay for attempt `n` (1-based): [`RECONNECT`]'s delay before that retry.
pub fn backoff(attempt: u32) -> Duration {
    RECONNECT.delay_for_retry(attempt)
}

impl GpsSource {
    /// Starts a worker thread for `config`; every event goes to every one of `outputs` (each with its own
    /// overflow policy and waker). With no outputs the worker ends at once. The last event is
    /// [`SourceState::Stopped`], handed over only where there is room (it never waits).
    pub fn spawn(config: SourceConfig, outputs: Vec<Outbox<GpsEvent>>) -> std::io::Result<GpsHandle> {
        let stop = Arc::new(AtomicBool::new(false));
        let worker = Worker { outputs, stop: stop.clone() };
        let name = match &config {
            SourceConfig::Serial { .. } => "gps-serial",
            SourceConfig::Replay { .. } => "gps-replay",
            SourceConfig::Gpsd { .. } => "gps-gpsd",
            SourceConfig::Simulator { .. } => "gps-sim",
        };
        let thread = std::thread::Builder::new().name(name.into()).spawn(move || {
            match config {
                SourceConfig::Serial { port, baud } => run_serial(&worker, &port, baud),
                SourceConfig::Replay { path, speed } => run_replay(&worker, &path, speed),
                SourceConfig::Gpsd { host, port } => run_gpsd(&worker, &host, port),
                SourceConfig::Simulator { route, pace_m_s, model, seed, period, looped } => {
                    run_sim(&worker, &SimParams { route: &route, pace_m_s, model, seed, period, looped });
                }
            }
            for o in &worker.outputs {
                o.try_send(GpsEvent::State(SourceState::Stopped));
            }
        })?;
        Ok(GpsHandle { stop, thread: Some(thread) })
    }

    /// Starts a source with one lossless consumer: a channel of `capacity` events with
    /// [`Overflow::Wait`] (the worker waits for the consumer, until stopped). For the CLI and tests.
    pub fn spawn_channel(
        config: SourceConfig,
        capacity: usize,
        waker: Option<Waker>,
    ) -> std::io::Result<(GpsHandle, Receiver<GpsEvent>)> {
        let (out, rx) = Outbox::channel(capacity, Overflow::Wait, waker);
        Ok((Self::spawn(config, vec![out])?, rx))
    }
}

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

fn run_serial(w: &Worker, port: &str, baud: Option<u32>) {
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
                if !w.state(SourceState::Lost { reason: e.to_string() }) {
                    return;
                }
                continue;
            }
        };
        if !w.state(SourceState::Live { detail: format!("{port} at {baud} baud") }) {
            return;
        }
        let mut d = NmeaDecoder::new(DecoderConfig::live());
        d.handle_bytes(&first, Instant::now());
        let reason = read_loop(w, &mut d, |buf| p.read(buf));
        match reason {
            None => return,
            Some(reason) => {
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

/// The pacing stamp of a log line: our `$PVNAV,TS` in ms (`true`), else a sentence's UTC time of day in ms.
fn line_stamp(line: &[u8]) -> Option<(bool, i64)> {
    let s = std::str::from_utf8(line).ok()?.trim_end();
    let s = s.get(s.find('$')?..)?;
    if let Some(rest) = s.strip_prefix("$PVNAV,TS,") {
        return rest.split('*').next()?.parse().ok().map(|ms| (true, ms));
    }
    let mut f = s.split(',');
    let tag = f.next()?;
    let field = match tag.get(3..)? {
        "GGA" | "RMC" | "GNS" | "ZDA" => f.next()?,
        "GLL" => f.nth(4)?,
        _ => return None,
    };
    sentence::parse_time(field).map(|t| (false, i64::from(sentence::tod_ms(t))))
}

/// Hands out the lines of a log in time: by its `$PVNAV,TS` stamps when it has them, else by the
/// sentences' UTC times of day (midnight wrap handled; a splice — a jump back, or forward by more than a
/// minute — continues one second later). `speed`: 1 = recorded speed, `None` = no waiting. Returns false
/// when stopped or when `emit` returns false.
pub fn replay_lines(
    data: &[u8],
    speed: Option<f64>,
    stop: &AtomicBool,
    mut emit: impl FnMut(&[u8]) -> bool,
) -> bool {
    let has_ts = data.windows(10).any(|x| x == b"$PVNAV,TS,");
    let speed = speed.filter(|s| s.is_finite() && *s > 0.0);
    let start = Instant::now();
    let mut base: Option<i64> = None;
    let mut offset_ms: i64 = 0;
    let mut last: Option<i64> = None;
    for line in data.split_inclusive(|&b| b == b'\n') {
        if let (Some(speed), Some((is_ts, mut ms))) = (speed, line_stamp(line))
            && is_ts == has_ts
        {
            {
                if let Some(prev) = last {
                    if !has_ts && ms + offset_ms < prev - 43_200_000 {
                        offset_ms += 86_400_000; // time of day wrapped past midnight
                    }
                    ms += offset_ms;
                    if ms < prev || ms - prev > 60_000 {
                        let b = base.unwrap_or(ms);
                        base = Some(b + (ms - prev) - 1000);
                    }
                } else {
                    ms += offset_ms;
                }
                last = Some(ms);
                let b = *base.get_or_insert(ms);
                let due = start + Duration::from_secs_f64(((ms - b).max(0) as f64 / 1000.0) / speed);
                while Instant::now() < due {
                    if stop.load(Ordering::Relaxed) {
                        return false;
                    }
                    std::thread::sleep((due - Instant::now()).min(Duration::from_millis(20)));
                }
            }
        }
        if stop.load(Ordering::Relaxed) || !emit(line) {
            return false;
        }
    }
    true
}

fn run_replay(w: &Worker, path: &std::path::Path, speed: Option<f64>) {
    if !w.state(SourceState::Connecting { detail: path.display().to_string() }) {
        return;
    }
    let data = match std::fs::read(path) {
        Ok(d) => d,
        Err(e) => {
            w.state(SourceState::Lost { reason: format!("{}: {e}", path.display()) });
            return;
        }
    };
    if !w.state(SourceState::Live { detail: format!("replaying {}", path.display()) }) {
        return;
    }
    let mut d = NmeaDecoder::new(DecoderConfig::live());
    let completed = replay_lines(&data, speed, &w.stop, |line| {
        d.handle_bytes(line, Instant::now());
        w.drain(&mut d)
    });
    if !completed {
        return;
    }
    d.finish(Instant::now());
    if w.drain(&mut d) {
        w.state(SourceState::Finished);
    }
}

fn run_gpsd(w: &Worker, host: &str, port: u16) {
    let mut attempt = 0u32;
    loop {
        if !w.back_off(attempt) {
            return;
        }
        attempt += 1;
        if !w.state(SourceState::Connecting { detail: format!("gpsd at {host}:{port}") }) {
            return;
        }
        let Some(reason) = gpsd_session(w, host, port, &mut attempt) else { return };
        if !w.state(SourceState::Lost { reason }) {
            return;
        }
    }
}

fn gpsd_session(w: &Worker, host: &str, port: u16, attempt: &mut u32) -> Option<String> {
    // Neither DNS nor connect can be interrupted: a stop meanwhile detaches this thread (see `stop`).
    let addr = match (host, port).to_socket_addrs().map(|mut a| a.next()) {
        Ok(Some(a)) => a,
        Ok(None) => return Some(format!("{host}: no address")),
        Err(e) => return Some(format!("{host}: {e}")),
    };
    if w.stopped() {
        return None;
    }
    let mut stream = match TcpStream::connect_timeout(&addr, Duration::from_secs(2)) {
        Ok(s) => s,
        Err(e) => return Some(format!("{addr}: {e}")),
    };
    if let Err(e) = stream
        .set_read_timeout(Some(GPSD_READ_TIMEOUT))
        .and_then(|()| stream.set_write_timeout(Some(Duration::from_secs(1))))
        .and_then(|()| stream.write_all(WATCH.as_bytes()))
    {
        return Some(e.to_string());
    }
    if !w.state(SourceState::Live { detail: format!("gpsd at {addr}") }) {
        return None;
    }
    *attempt = 1;
    gpsd_read_loop(w, |buf| stream.read(buf))
}

/// Reads gpsd reports until error/loss (returns the reason) or stop (returns None). Memory is bounded by
/// the line framer whatever the server sends; the stop flag is checked after every read (each read
/// returns within [`GPSD_READ_TIMEOUT`]); staleness counts time since the last complete line.
fn gpsd_read_loop(w: &Worker, mut read: impl FnMut(&mut [u8]) -> std::io::Result<usize>) -> Option<String> {
    let mut buf = vec![0u8; 64 * 1024];
    let mut framer = LineFramer::new(MAX_LINE_LEN);
    let mut client = GpsdClient::new();
    let mut bytes = 0u64;
    let mut fixes = Vec::new();
    let mut last_line = Instant::now();
    let mut stale = false;
    let mut last_stats = Instant::now();
    let stats = |client: &GpsdClient, framer: &LineFramer, bytes: u64| {
        let mut st = client.stats();
        st.bytes = bytes;
        st.overlong = framer.overlong();
        GpsEvent::Stats(st)
    };
    loop {
        if w.stopped() {
            return None;
        }
        let result = read(&mut buf);
        let now = Instant::now();
        match result {
            Ok(0) => {
                // Final counts before the loss is reported (where there is room: never waits).
                for o in &w.outputs {
                    o.try_send(stats(&client, &framer, bytes));
                }
                return Some("gpsd closed the connection".into());
            }
            Ok(n) => {
                bytes += n as u64;
                let lines = framer.feed(buf.get(..n).unwrap_or_default(), |line| {
                    if let Some(fix) = client.handle_line(&String::from_utf8_lossy(line), now) {
                        fixes.push(fix);
                    }
                });
                if lines > 0 {
                    last_line = now;
                    if stale {
                        stale = false;
                        if !w.state(SourceState::Live { detail: "data again".into() }) {
                            return None;
                        }
                    }
                }
                for fix in fixes.drain(..) {
                    if !w.send(GpsEvent::Fix(Box::new(fix))) {
                        return None;
                    }
                }
            }
            Err(e) if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Some(e.to_string()),
        }
        let idle = now.saturating_duration_since(last_line);
        if !stale && idle >= STALE_AFTER {
            stale = true;
            if !w.state(SourceState::Stale) {
                return None;
            }
        }
        if idle >= LOST_AFTER {
            return Some(format!("no complete line from gpsd for {} s", LOST_AFTER.as_secs()));
        }
        if last_stats.elapsed() >= Duration::from_secs(1) {
            last_stats = Instant::now();
            if !w.send(stats(&client, &framer, bytes)) {
                return None;
            }
        }
    }
}

/// The simulator's settings, as given in [`SourceConfig::Simulator`].
struct SimParams<'a> {
    route: &'a [(f64, f64)],
    pace_m_s: f64,
    model: GnssErrorModel,
    seed: u64,
    period: Duration,
    looped: bool,
}

fn run_sim(w: &Worker, p: &SimParams<'_>) {
    let new_lap = |lap: u64, start| {
        SimulatedReceiver::new(p.route, p.pace_m_s, p.model, p.seed.wrapping_add(lap), start)
    };
    let mut rx = match new_lap(0, super::sim::whole_second_now()) {
        Ok(r) => r,
        Err(e) => {
            w.state(SourceState::Lost { reason: e.to_string() });
            return;
        }
    };
    if !w.state(SourceState::Live { detail: "simulator".into() }) {
        return;
    }
    let mut d = NmeaDecoder::new(DecoderConfig::live());
    let start = Instant::now();
    let mut k: u32 = 0;
    let mut lap: u64 = 0;
    loop {
        let text = rx.next_epoch(p.period.as_secs_f64());
        d.handle_bytes(text.as_bytes(), Instant::now());
        d.handle_timeout(Instant::now() + Duration::from_hours(1));
        if !w.drain(&mut d) {
            return;
        }
        if rx.finished() {
            if !p.looped {
                w.state(SourceState::Finished);
                return;
            }
            lap += 1;
            // The next lap's clock continues from the last epoch, so epoch times keep increasing.
            match new_lap(lap, rx.time()) {
                Ok(r) => rx = r,
                Err(e) => {
                    w.state(SourceState::Lost { reason: e.to_string() });
                    return;
                }
            }
            let seed = p.seed.wrapping_add(lap);
            if !w.send(GpsEvent::Notice(format!(
                "simulator: route finished, starting lap {} (seed {seed})",
                lap + 1
            ))) {
                return;
            }
        }
        k = k.saturating_add(1);
        let due = start + p.period * k;
        let now = Instant::now();
        if due > now && !w.sleep(due - now) {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::Fix;
    use super::*;

    fn collect(
        rx: &Receiver<GpsEvent>,
        until: impl Fn(&[GpsEvent]) -> bool,
        timeout: Duration,
    ) -> Vec<GpsEvent> {
        let end = Instant::now() + timeout;
        let mut out = Vec::new();
        while Instant::now() < end && !until(&out) {
            if let Ok(e) = rx.recv_timeout(Duration::from_millis(50)) {
                out.push(e);
            }
        }
        out
    }

    fn spawn(config: SourceConfig) -> (GpsHandle, Receiver<GpsEvent>) {
        GpsSource::spawn_channel(config, 1024, None).unwrap()
    }

    fn logs() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/gpsd-logs")
    }

    #[test]
    fn replay_as_fast_as_possible_gives_every_epoch() {
        let (mut h, rx) = spawn(SourceConfig::Replay { path: logs().join("nd-1005.log"), speed: None });
        let ev =
            collect(&rx, |e| e.contains(&GpsEvent::State(SourceState::Finished)), Duration::from_secs(10));
        let fixes = ev.iter().filter(|e| matches!(e, GpsEvent::Fix(_))).count();
        assert_eq!(fixes, 16);
        h.stop();
    }

    #[test]
    fn replay_paces_by_utc_time() {
        // mr-350p: 14 epochs over 13 s; at 26x that is 0.5 s.
        let t0 = Instant::now();
        let (mut h, rx) = spawn(SourceConfig::Replay { path: logs().join("mr-350p.log"), speed: Some(26.0) });
        let ev =
            collect(&rx, |e| e.contains(&GpsEvent::State(SourceState::Finished)), Duration::from_secs(10));
        let dt = t0.elapsed().as_secs_f64();
        assert!(ev.contains(&GpsEvent::State(SourceState::Finished)));
        assert!((0.45..2.0).contains(&dt), "{dt}");
        h.stop();
    }

    #[test]
    fn simulator_emits_fixes_and_stops() {
        let (mut h, rx) = spawn(SourceConfig::Simulator {
            route: super::super::sim::DEFAULT_ROUTE.to_vec(),
            pace_m_s: 1.4,
            model: GnssErrorModel::sirf3_open_sky(),
            seed: 5,
            period: Duration::from_millis(20),
            looped: false,
        });
        let ev = collect(
            &rx,
            |e| e.iter().filter(|x| matches!(x, GpsEvent::Fix(_))).count() >= 5,
            Duration::from_secs(10),
        );
        assert!(ev.iter().filter(|x| matches!(x, GpsEvent::Fix(f) if f.has_position())).count() >= 5);
        h.stop();
    }

    #[test]
    fn gpsd_refused_reports_lost_then_reconnecting() {
        let (mut h, rx) = spawn(SourceConfig::Gpsd { host: "127.0.0.1".into(), port: 1 });
        let ev = collect(
            &rx,
            |e| e.iter().any(|x| matches!(x, GpsEvent::State(SourceState::Reconnecting { .. }))),
            Duration::from_secs(5),
        );
        assert!(ev.iter().any(|x| matches!(x, GpsEvent::State(SourceState::Lost { .. }))));
        assert!(
            ev.iter().any(|x| matches!(x, GpsEvent::State(SourceState::Reconnecting { attempt: 1, .. })))
        );
        h.stop();
    }

    /// Fix-in to event-out latency over a real PTY: an epoch's sentences written to the master, the serial
    /// source (fixed baud) reading the slave, until its Fix event is received. Prints p50/p99 (no timing
    /// assertion: speed goals live in benches).
    #[cfg(unix)]
    #[test]
    fn pty_fix_latency_p50_p99() {
        use std::io::Write as _;
        let mut pty = crate::serial::Pty::open().unwrap();
        let (_h, events) = spawn(SourceConfig::Serial { port: pty.path().to_owned(), baud: Some(4800) });
        let mut rx = super::super::sim::SimulatedReceiver::new(
            super::super::sim::DEFAULT_ROUTE,
            1.4,
            GnssErrorModel::perfect(),
            1,
            chrono::DateTime::UNIX_EPOCH,
        )
        .unwrap();
        let mut live = false;
        let end = Instant::now() + Duration::from_secs(5);
        while !live && Instant::now() < end {
            live = matches!(
                events.recv_timeout(Duration::from_millis(50)),
                Ok(GpsEvent::State(SourceState::Live { .. }))
            );
        }
        assert!(live);
        let mut lat_us = Vec::new();
        for k in 0..60 {
            let text = rx.next_epoch(1.0);
            let t0 = Instant::now();
            pty.write_all(text.as_bytes()).unwrap();
            let deadline = t0 + Duration::from_secs(2);
            while Instant::now() < deadline {
                if let Ok(GpsEvent::Fix(_)) = events.recv_timeout(Duration::from_millis(5)) {
                    // The first epochs are closed by the next one (cycle end not yet learned).
                    if k >= 3 {
                        lat_us.push(t0.elapsed().as_micros());
                    }
                    break;
                }
            }
        }
        lat_us.sort_unstable();
        assert!(lat_us.len() >= 50, "{}", lat_us.len());
        let p = |q: f64| lat_us[((lat_us.len() - 1) as f64 * q).round() as usize];
        eprintln!(
            "PTY fix-in to event-out latency: p50 {} us, p99 {} us (n = {})",
            p(0.5),
            p(0.99),
            lat_us.len()
        );
    }

    #[test]
    fn backoff_doubles_and_caps() {
        assert_eq!(backoff(1), Duration::from_millis(500));
        assert_eq!(backoff(2), Duration::from_secs(1));
        assert_eq!(backoff(9), Duration::from_secs(8));
    }

    #[test]
    fn baud_score_counts_valid_sentences() {
        assert_eq!(score_baud(b"\xf0\x0f\x88garbage$GPGGA,1*00\r\n"), 0);
        let good = std::fs::read(logs().join("nd-1005.log")).unwrap();
        assert!(score_baud(&good) > 50);
    }

    // ---- Hostile gpsd servers ("Safety first"): each is a fake gpsd on 127.0.0.1 started by the test,
    // serving a fixed number of connections, with write timeouts so that it always ends by itself.

    use std::net::TcpListener;

    /// Serves `conns` connections on a fresh 127.0.0.1 port with `serve(stream, n)`; stops accepting after
    /// 10 s. Writes time out after 1 s, so a server whose client has gone ends.
    fn fake_gpsd(
        conns: usize,
        serve: impl Fn(TcpStream, usize) + Send + 'static,
    ) -> (u16, std::thread::JoinHandle<()>) {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        listener.set_nonblocking(true).unwrap();
        let t = std::thread::spawn(move || {
            let end = Instant::now() + Duration::from_secs(10);
            let mut n = 0;
            while n < conns && Instant::now() < end {
                match listener.accept() {
                    Ok((stream, _)) => {
                        stream.set_nonblocking(false).unwrap();
                        stream.set_write_timeout(Some(Duration::from_secs(1))).unwrap();
                        stream.set_read_timeout(Some(Duration::from_secs(1))).unwrap();
                        // Read the client's ?WATCH first, as gpsd does: closing a socket with unread
                        // input would reset the connection instead of closing it.
                        let mut watch = Vec::new();
                        let mut byte = [0u8; 1];
                        while watch.last() != Some(&b'\n') && matches!((&stream).read(&mut byte), Ok(1)) {
                            watch.push(byte[0]);
                        }
                        assert_eq!(watch, WATCH.as_bytes());
                        serve(stream, n);
                        n += 1;
                    }
                    Err(_) => std::thread::sleep(Duration::from_millis(5)),
                }
            }
        });
        (port, t)
    }

    fn gpsd_at(port: u16) -> SourceConfig {
        SourceConfig::Gpsd { host: "127.0.0.1".into(), port }
    }

    /// A TPV report as gpsd writes it (`gpsd_json(5)`); `k` makes the time unique.
    fn tpv(k: u32, lat_lon: &str) -> String {
        format!(
            "{{\"class\":\"TPV\",\"device\":\"/dev/ttyUSB0\",\"mode\":3,\"time\":\"2011-03-14T{:02}:{:02}:{:02}.{:03}Z\",\
             {lat_lon},\"altMSL\":59.3,\"speed\":0.0,\"track\":0.0,\"eph\":7.4}}\n",
            k / 3_600_000 % 24,
            k / 60_000 % 60,
            k / 1000 % 60,
            k % 1000
        )
    }

    const GOOD: &str = r#""lat":57.163445,"lon":-2.12137"#;

    fn is_state(e: &GpsEvent, f: impl Fn(&SourceState) -> bool) -> bool {
        matches!(e, GpsEvent::State(s) if f(s))
    }

    fn stats_of(ev: &[GpsEvent]) -> Option<DecodeStatsCopy> {
        ev.iter().rev().find_map(|e| if let GpsEvent::Stats(s) = e { Some(*s) } else { None })
    }
    type DecodeStatsCopy = super::super::DecodeStats;

    /// The issue's values never reach the consumer as positions, and are counted.
    #[test]
    fn gpsd_absurd_positions_never_reach_the_consumer() {
        let (port, server) = fake_gpsd(1, |mut s, _| {
            let bad = [
                r#""lat":57.0,"lon":-1e15"#,
                r#""lat":91.0,"lon":181.0"#,
                r#""lat":9999,"lon":2.0"#,
                r#""lat":1e20,"lon":2.0"#,
                r#""lat":-1e-400e,"lon":NaN"#,
            ];
            let mut text: String = bad.iter().zip(1..).map(|(b, k)| tpv(k * 1000, b)).collect();
            text += &tpv(9000, GOOD);
            let _ = s.write_all(text.as_bytes());
            std::thread::sleep(Duration::from_millis(300));
        });
        let (mut h, rx) = spawn(gpsd_at(port));
        let ev = collect(
            &rx,
            |e| e.iter().any(|e| is_state(e, |s| matches!(s, SourceState::Lost { .. }))),
            Duration::from_secs(5),
        );
        h.stop();
        server.join().unwrap();
        let fixes: Vec<&Fix> =
            ev.iter().filter_map(|e| if let GpsEvent::Fix(f) = e { Some(&**f) } else { None }).collect();
        assert_eq!(fixes.len(), 5, "four absurd TPVs and the good one; the NaN line is not JSON: {ev:?}");
        let positions: Vec<(f64, f64)> = fixes
            .iter()
            .filter(|f| f.has_position())
            .map(|f| (f.lat_deg.unwrap(), f.lon_deg.unwrap()))
            .collect();
        assert_eq!(positions, [(57.163_445, -2.121_37)]);
        assert!(fixes.iter().all(|f| f.has_position() || (f.lat_deg.is_none() && f.lon_deg.is_none())));
        let st = stats_of(&ev).expect("final counts before Lost");
        assert_eq!(st.invalid_positions, 4, "{st:?}");
        assert_eq!(st.malformed, 1, "the NaN line");
    }

    /// One byte per 50 ms and never a newline: the source goes stale (no complete line for 3 s) and a stop
    /// while bytes keep trickling returns within 300 ms.
    #[test]
    fn gpsd_trickle_goes_stale_and_stop_is_prompt() {
        let (port, server) = fake_gpsd(1, |mut s, _| {
            let end = Instant::now() + Duration::from_secs(8);
            let _ = s.write_all(b"{\"class\":\"TPV\"");
            while Instant::now() < end && s.write_all(b"a").is_ok() {
                std::thread::sleep(Duration::from_millis(50));
            }
        });
        let (mut h, rx) = spawn(gpsd_at(port));
        let ev = collect(
            &rx,
            |e| e.iter().any(|e| is_state(e, |s| *s == SourceState::Stale)),
            Duration::from_secs(6),
        );
        assert!(ev.iter().any(|e| is_state(e, |s| *s == SourceState::Stale)), "{ev:?}");
        assert!(!ev.iter().any(|e| is_state(e, |s| matches!(s, SourceState::Lost { .. }))), "{ev:?}");
        let t0 = Instant::now();
        h.stop();
        let dt = t0.elapsed();
        assert!(dt < Duration::from_millis(300), "stop took {dt:?}");
        assert!(!h.is_running());
        server.join().unwrap();
    }

    /// Resident memory of this process [bytes] (Linux), for the unbounded-line test.
    fn rss_bytes() -> Option<u64> {
        let status = std::fs::read_to_string("/proc/self/status").ok()?;
        let kb = status.lines().find_map(|l| l.strip_prefix("VmRSS:"))?.trim().strip_suffix("kB")?;
        kb.trim().parse::<u64>().ok().map(|k| k * 1024)
    }

    /// A 200 MB line without a newline: dropped without being buffered (counted as overlong), the next
    /// line still decodes, memory stays bounded, and a stop during a second endless line is prompt.
    #[test]
    fn gpsd_endless_line_keeps_memory_bounded() {
        let (port, server) = fake_gpsd(1, |mut s, _| {
            let chunk = vec![b'x'; 1 << 20];
            for _ in 0..200 {
                if s.write_all(&chunk).is_err() {
                    return;
                }
            }
            if s.write_all(format!("\n{}", tpv(1000, GOOD)).as_bytes()).is_err() {
                return;
            }
            let end = Instant::now() + Duration::from_secs(8);
            while Instant::now() < end && s.write_all(&chunk).is_ok() {}
        });
        let rss0 = rss_bytes();
        let (mut h, rx) = spawn(gpsd_at(port));
        let mut peak = 0;
        let mut ev = Vec::new();
        let end = Instant::now() + Duration::from_secs(30);
        while Instant::now() < end {
            peak = peak.max(rss_bytes().unwrap_or(0));
            if let Ok(e) = rx.recv_timeout(Duration::from_millis(20)) {
                ev.push(e);
            }
            let fixed = ev.iter().any(|e| matches!(e, GpsEvent::Fix(f) if f.has_position()));
            if fixed && stats_of(&ev).is_some_and(|s| s.overlong >= 1 && s.epochs >= 1) {
                break;
            }
        }
        let fix = ev.iter().find_map(|e| if let GpsEvent::Fix(f) = e { Some(f) } else { None });
        assert!((fix.expect("the line after the endless one").lat_deg.unwrap() - 57.163_445).abs() < 1e-9);
        let st = stats_of(&ev).unwrap();
        assert!(st.overlong >= 1 && st.bytes >= 200 << 20, "{st:?}");
        if let Some(rss0) = rss0 {
            // The line alone is 200 MB; the framer holds at most 2 x 64 KiB of it.
            let grew = peak.saturating_sub(rss0);
            assert!(grew < 64 << 20, "RSS grew by {} MB", grew >> 20);
        }
        let t0 = Instant::now();
        h.stop();
        let dt = t0.elapsed();
        assert!(dt < Duration::from_millis(300), "stop took {dt:?}");
        server.join().unwrap();
    }

    /// A flood of TPVs into a consumer that reads nothing: with `DropNewest` its channel holds at most its
    /// capacity, the rest is counted as dropped, and the worker never waits.
    #[test]
    fn gpsd_flood_into_a_drop_newest_consumer_stays_bounded() {
        const N: u32 = 20_000;
        let (port, server) = fake_gpsd(1, |mut s, _| {
            let text: String = (0..N).map(|k| tpv(k, GOOD)).collect();
            let _ = s.write_all(text.as_bytes());
            std::thread::sleep(Duration::from_millis(200));
        });
        let (out, rx) = Outbox::channel(16, Overflow::DropNewest, None);
        let mut h = GpsSource::spawn(gpsd_at(port), vec![out.clone()]).unwrap();
        let end = Instant::now() + Duration::from_secs(10);
        while out.dropped() < u64::from(N) - 16 && Instant::now() < end {
            std::thread::sleep(Duration::from_millis(20));
        }
        let t0 = Instant::now();
        h.stop();
        assert!(t0.elapsed() < Duration::from_millis(300));
        server.join().unwrap();
        let kept = rx.try_iter().count();
        assert!(kept <= 16, "{kept}");
        // Every TPV (and the Live state before them) was either kept or counted as dropped.
        assert!(out.dropped() + kept as u64 > u64::from(N), "dropped {}, kept {kept}", out.dropped());
    }

    /// gpsd closes the connection in the middle of a line: the source reports the link lost, backs off and
    /// reconnects, and fixes flow again.
    #[test]
    fn gpsd_closing_mid_line_is_lost_then_reconnected() {
        let (port, server) = fake_gpsd(2, |mut s, n| {
            let k = u32::try_from(n).unwrap() * 1000;
            let _ = s.write_all(format!("{}{{\"class\":\"TPV\",\"ti", tpv(k, GOOD)).as_bytes());
            if n == 1 {
                std::thread::sleep(Duration::from_millis(300));
            }
        });
        let (mut h, rx) = spawn(gpsd_at(port));
        let fixes =
            |e: &[GpsEvent]| e.iter().filter(|e| matches!(e, GpsEvent::Fix(f) if f.has_position())).count();
        let ev = collect(&rx, |e| fixes(e) >= 2, Duration::from_secs(8));
        h.stop();
        server.join().unwrap();
        assert_eq!(fixes(&ev), 2, "{ev:?}");
        let lost = ev.iter().position(|e| {
            is_state(e, |s| matches!(s, SourceState::Lost { reason } if reason.contains("closed")))
        });
        let retry = ev
            .iter()
            .position(|e| is_state(e, |s| matches!(s, SourceState::Reconnecting { attempt: 1, .. })));
        let second_fix = ev.iter().rposition(|e| matches!(e, GpsEvent::Fix(_)));
        assert!(lost < retry && retry < second_fix && lost.is_some(), "{ev:?}");
    }

    /// `stop` never waits for a worker stuck in an uninterruptible call: here, a lossless consumer's full
    /// channel is the only thing the worker could wait on, and the stop flag wins.
    #[test]
    fn stop_wins_over_a_stalled_lossless_consumer() {
        let (mut h, rx) = GpsSource::spawn_channel(
            SourceConfig::Replay { path: logs().join("nd-1005.log"), speed: None },
            1,
            None,
        )
        .unwrap();
        std::thread::sleep(Duration::from_millis(100));
        assert!(h.is_running(), "waiting for the consumer");
        let t0 = Instant::now();
        h.stop();
        assert!(t0.elapsed() < Duration::from_millis(300));
        assert!(!h.is_running());
        assert!(rx.try_iter().count() <= 2);
    }

    /// A looped simulator starts over at the end of its route with a new seed, and says so.
    #[test]
    fn looped_simulator_starts_over_with_a_new_seed() {
        // A 50 m route at 50 m/s with 0.1 s epochs: about 10 epochs (1 s) per lap.
        let start = (42.356_2, -71.1);
        let end = (42.356_2 + 50.0 / 111_132.0, -71.1);
        let (mut h, rx) = spawn(SourceConfig::Simulator {
            route: vec![start, end],
            pace_m_s: 50.0,
            model: GnssErrorModel::sirf3_open_sky(),
            seed: 7,
            period: Duration::from_millis(100),
            looped: true,
        });
        let notices = |e: &[GpsEvent]| e.iter().filter(|e| matches!(e, GpsEvent::Notice(_))).count();
        let ev = collect(&rx, |e| notices(e) >= 2, Duration::from_secs(10));
        h.stop();
        assert!(!ev.iter().any(|e| is_state(e, |s| *s == SourceState::Finished)));
        let texts: Vec<&String> =
            ev.iter().filter_map(|e| if let GpsEvent::Notice(t) = e { Some(t) } else { None }).collect();
        assert_eq!(texts.len(), 2, "{ev:?}");
        assert!(texts[0].contains("lap 2") && texts[0].contains("seed 8"), "{texts:?}");
        assert!(texts[1].contains("lap 3") && texts[1].contains("seed 9"), "{texts:?}");
        // Epoch times keep increasing across laps.
        let fixes: Vec<&Fix> =
            ev.iter().filter_map(|e| if let GpsEvent::Fix(f) = e { Some(&**f) } else { None }).collect();
        assert!(fixes.windows(2).all(|w| w[0].time < w[1].time));
        // Laps differ: the same point of the route has a different error realisation.
        let laps: Vec<Vec<f64>> = ev
            .split(|e| matches!(e, GpsEvent::Notice(_)))
            .map(|lap| {
                lap.iter().filter_map(|e| if let GpsEvent::Fix(f) = e { f.lat_deg } else { None }).collect()
            })
            .collect();
        let (a, b) = (&laps[0], &laps[1]);
        assert!(a.len() >= 5 && b.len() >= 5, "{laps:?}");
        assert!(a.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-9), "lap 2 repeats lap 1: {laps:?}");
    }
}
