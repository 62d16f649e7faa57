//! GPS sources on worker threads, all producing the same [`GpsEvent`] stream.
//!
//! [`GpsSource::spawn`] starts one named worker thread that owns one transport and one decoder; events go
//! out on a bounded channel (`sync_channel`, 1024 events) and the `waker` is called after each batch (the
//! GUI passes `ctx.request_repaint`). When the consumer falls behind, the worker blocks rather than drop
//! fixes. Each source reports its [`SourceState`]; serial and gpsd sources reconnect with exponential
//! backoff (0.5 s doubling to 8 s) until stopped.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use vestnav_core::gnss_sim::GnssErrorModel;

use super::framing::Framer;
use super::gpsd::{GpsdClient, WATCH};
use super::sentence;
use super::sim::SimulatedReceiver;
use super::{DecoderConfig, GpsEvent, NmeaDecoder};

/// Bauds tried by automatic detection, most likely first (`SiRF` III default 4800, u-blox 9600/38400).
pub const DETECT_BAUDS: [u32; 6] = [4800, 9600, 38400, 115_200, 19200, 57600];
/// No data for this long on a live link: the source is stale.
pub const STALE_AFTER: Duration = Duration::from_secs(3);
/// No data for this long: the link is treated as lost and reopened.
pub const LOST_AFTER: Duration = Duration::from_secs(10);

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

/// The consumer's end of a running source.
#[derive(Debug)]
pub struct GpsHandle {
    rx: Receiver<GpsEvent>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl GpsHandle {
    /// The next event, if one is waiting (never blocks).
    pub fn try_recv(&self) -> Option<GpsEvent> {
        self.rx.try_recv().ok()
    }

    /// The next event, waiting up to `timeout`.
    pub fn recv_timeout(&self, timeout: Duration) -> Option<GpsEvent> {
        self.rx.recv_timeout(timeout).ok()
    }

    /// All events waiting now.
    pub fn events(&self) -> impl Iterator<Item = GpsEvent> + '_ {
        self.rx.try_iter()
    }

    /// True while the worker runs.
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Stops the worker and waits for it (at most one read timeout, ~100 ms).
    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Unblock a worker waiting on a full channel.
        while self.rx.try_recv().is_ok() {}
        if let Some(t) = self.thread.take() {
            while !t.is_finished() {
                while self.rx.try_recv().is_ok() {}
                std::thread::sleep(Duration::from_millis(5));
            }
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
    tx: SyncSender<GpsEvent>,
    stop: Arc<AtomicBool>,
    waker: Box<dyn Fn() + Send>,
}

impl Worker {
    fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    /// Sends an event; false when the consumer is gone or a stop was requested.
    fn send(&self, ev: GpsEvent) -> bool {
        if self.stopped() {
            return false;
        }
        let ok = self.tx.send(ev).is_ok();
        (self.waker)();
        ok
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

/// Reconnection delay for attempt `n` (1-based): 0.5 s doubling, capped at 8 s.
pub fn backoff(attempt: u32) -> Duration {
    Duration::from_millis(500u64.saturating_mul(1u64 << attempt.saturating_sub(1).min(4)))
}

impl GpsSource {
    /// Starts a worker thread for `config`; `waker` is called after events are sent.
    pub fn spawn(config: SourceConfig, waker: impl Fn() + Send + 'static) -> std::io::Result<GpsHandle> {
        let (tx, rx) = sync_channel(1024);
        let stop = Arc::new(AtomicBool::new(false));
        let worker = Worker { tx, stop: stop.clone(), waker: Box::new(waker) };
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
                SourceConfig::Simulator { route, pace_m_s, model, seed, period } => {
                    run_sim(&worker, &route, pace_m_s, model, seed, period);
                }
            }
            let _ = worker.tx.send(GpsEvent::State(SourceState::Stopped));
            (worker.waker)();
        })?;
        Ok(GpsHandle { rx, stop, thread: Some(thread) })
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
    let addr = match (host, port).to_socket_addrs().map(|mut a| a.next()) {
        Ok(Some(a)) => a,
        Ok(None) => return Some(format!("{host}: no address")),
        Err(e) => return Some(format!("{host}: {e}")),
    };
    let mut stream = match TcpStream::connect_timeout(&addr, Duration::from_secs(2)) {
        Ok(s) => s,
        Err(e) => return Some(format!("{addr}: {e}")),
    };
    if let Err(e) = stream
        .set_read_timeout(Some(Duration::from_millis(100)))
        .and_then(|()| stream.write_all(WATCH.as_bytes()))
    {
        return Some(e.to_string());
    }
    if !w.state(SourceState::Live { detail: format!("gpsd at {addr}") }) {
        return None;
    }
    *attempt = 1;
    let mut reader = BufReader::new(stream);
    let mut client = GpsdClient::new();
    let mut line = String::new();
    let mut last_data = Instant::now();
    let mut stale = false;
    loop {
        if w.stopped() {
            return None;
        }
        match reader.read_line(&mut line) {
            Ok(0) => return Some("gpsd closed the connection".into()),
            Ok(_) => {
                // A line longer than gpsd ever sends (its SKY is < 10 kB) is not gpsd.
                if line.len() > 1 << 20 {
                    return Some("overlong line from gpsd".into());
                }
                if line.ends_with('\n') {
                    last_data = Instant::now();
                    if stale {
                        stale = false;
                        if !w.state(SourceState::Live { detail: "data again".into() }) {
                            return None;
                        }
                    }
                    if let Some(fix) = client.handle_line(&line)
                        && !w.send(GpsEvent::Fix(Box::new(fix)))
                    {
                        return None;
                    }
                    line.clear();
                }
            }
            Err(e) if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) => {}
            Err(e) => return Some(e.to_string()),
        }
        let idle = last_data.elapsed();
        if !stale && idle >= STALE_AFTER {
            stale = true;
            if !w.state(SourceState::Stale) {
                return None;
            }
        }
        if idle >= LOST_AFTER {
            return Some(format!("no data from gpsd for {} s", LOST_AFTER.as_secs()));
        }
    }
}

fn run_sim(
    w: &Worker,
    route: &[(f64, f64)],
    pace_m_s: f64,
    model: GnssErrorModel,
    seed: u64,
    period: Duration,
) {
    let mut rx = match SimulatedReceiver::new(route, pace_m_s, model, seed, super::sim::whole_second_now()) {
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
    loop {
        let text = rx.next_epoch(period.as_secs_f64());
        d.handle_bytes(text.as_bytes(), Instant::now());
        d.handle_timeout(Instant::now() + Duration::from_hours(1));
        if !w.drain(&mut d) {
            return;
        }
        if rx.finished() {
            w.state(SourceState::Finished);
            return;
        }
        k += 1;
        let due = start + period * k;
        let now = Instant::now();
        if due > now && !w.sleep(due - now) {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn collect(h: &GpsHandle, until: impl Fn(&[GpsEvent]) -> bool, timeout: Duration) -> Vec<GpsEvent> {
        let end = Instant::now() + timeout;
        let mut out = Vec::new();
        while Instant::now() < end && !until(&out) {
            if let Some(e) = h.recv_timeout(Duration::from_millis(50)) {
                out.push(e);
            }
        }
        out
    }

    fn logs() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/gpsd-logs")
    }

    #[test]
    fn replay_as_fast_as_possible_gives_every_epoch() {
        let mut h =
            GpsSource::spawn(SourceConfig::Replay { path: logs().join("nd-1005.log"), speed: None }, || {})
                .unwrap();
        let ev =
            collect(&h, |e| e.contains(&GpsEvent::State(SourceState::Finished)), Duration::from_secs(10));
        let fixes = ev.iter().filter(|e| matches!(e, GpsEvent::Fix(_))).count();
        assert_eq!(fixes, 16);
        h.stop();
    }

    #[test]
    fn replay_paces_by_utc_time() {
        // mr-350p: 14 epochs over 13 s; at 26x that is 0.5 s.
        let t0 = Instant::now();
        let mut h = GpsSource::spawn(
            SourceConfig::Replay { path: logs().join("mr-350p.log"), speed: Some(26.0) },
            || {},
        )
        .unwrap();
        let ev =
            collect(&h, |e| e.contains(&GpsEvent::State(SourceState::Finished)), Duration::from_secs(10));
        let dt = t0.elapsed().as_secs_f64();
        assert!(ev.contains(&GpsEvent::State(SourceState::Finished)));
        assert!((0.45..2.0).contains(&dt), "{dt}");
        h.stop();
    }

    #[test]
    fn simulator_emits_fixes_and_stops() {
        let mut h = GpsSource::spawn(
            SourceConfig::Simulator {
                route: super::super::sim::DEFAULT_ROUTE.to_vec(),
                pace_m_s: 1.4,
                model: GnssErrorModel::sirf3_open_sky(),
                seed: 5,
                period: Duration::from_millis(20),
            },
            || {},
        )
        .unwrap();
        let ev = collect(
            &h,
            |e| e.iter().filter(|x| matches!(x, GpsEvent::Fix(_))).count() >= 5,
            Duration::from_secs(10),
        );
        assert!(ev.iter().filter(|x| matches!(x, GpsEvent::Fix(f) if f.has_position())).count() >= 5);
        h.stop();
    }

    #[test]
    fn gpsd_refused_reports_lost_then_reconnecting() {
        let mut h =
            GpsSource::spawn(SourceConfig::Gpsd { host: "127.0.0.1".into(), port: 1 }, || {}).unwrap();
        let ev = collect(
            &h,
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
        let h =
            GpsSource::spawn(SourceConfig::Serial { port: pty.path().to_owned(), baud: Some(4800) }, || {})
                .unwrap();
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
                h.recv_timeout(Duration::from_millis(50)),
                Some(GpsEvent::State(SourceState::Live { .. }))
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
                if let Some(GpsEvent::Fix(_)) = h.recv_timeout(Duration::from_millis(5)) {
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
}
