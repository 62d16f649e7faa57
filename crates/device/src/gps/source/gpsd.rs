//! The gpsd source: the TCP session with a gpsd daemon and its bounded read loop.

use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use super::{GPSD_READ_TIMEOUT, LOST_AFTER, STALE_AFTER, SourceState, Worker};
use crate::gps::GpsEvent;
use crate::gps::gpsd::{GpsdClient, LineFramer, MAX_LINE_LEN, WATCH};

pub(super) fn run_gpsd(w: &Worker, host: &str, port: u16) {
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
        tracing::warn!(host, port, "gpsd at {host}:{port}: {reason}");
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
    tracing::info!(host, port, "connected to gpsd at {addr}");
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
    let mut events = Vec::new();
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
                    if let Some(ev) = client.handle_report(&String::from_utf8_lossy(line), now) {
                        events.push(ev);
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
                for ev in events.drain(..) {
                    if !w.send(ev) {
                        return None;
                    }
                }
            }
            Err(e) if crate::serial::is_timeout(&e) => {}
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
