//! The source of a receiver forwarded by the vest unit ([`crate::gps::through_vest`]): bytes from the
//! pipe go through the same NMEA decoder as a serial receiver's; the forwarding's state becomes the
//! source's state, and bytes lost on the way are announced.

use std::time::{Duration, Instant};

use super::{LOST_AFTER, STALE_AFTER, SourceState, Worker};
use crate::gps::through_vest::{ForwardingState, VestGpsReader};
use crate::gps::{DecoderConfig, GpsEvent, NmeaDecoder};

/// How long one pipe read waits: the stop flag and the timers are checked at least this often.
const READ_WAIT: Duration = Duration::from_millis(50);

pub(super) fn run_through_vest(w: &Worker, reader: &VestGpsReader, baud: u32) {
    reader.set_wanted(Some(baud));
    run(w, reader);
    reader.set_wanted(None);
}

fn state_of(f: &ForwardingState) -> SourceState {
    match f {
        ForwardingState::NoLink => {
            SourceState::Connecting { detail: "through the vest unit: waiting for the vest link".into() }
        }
        ForwardingState::Unsupported(why) => {
            SourceState::Lost { reason: format!("through the vest unit: {why}") }
        }
        ForwardingState::Requested { baud } => SourceState::Connecting {
            detail: format!("through the vest unit: asking it to forward its receiver at {baud} baud"),
        },
        ForwardingState::Forwarding { baud } => {
            SourceState::Live { detail: format!("through the vest unit at {baud} baud") }
        }
    }
}

fn run(w: &Worker, reader: &VestGpsReader) {
    let mut d = NmeaDecoder::new(DecoderConfig::live()).with_raw_lines();
    let mut buf = [0u8; 4096];
    let mut seen_state = None;
    let mut forwarding = false;
    let mut last_data = Instant::now();
    let mut stale = false;
    let mut last_stats = Instant::now();
    loop {
        if w.stopped() {
            return;
        }
        let got = reader.read(&mut buf, READ_WAIT);
        let now = Instant::now();
        let (state, changes) = got.state;
        if seen_state != Some(changes) {
            seen_state = Some(changes);
            forwarding = matches!(state, ForwardingState::Forwarding { .. });
            last_data = now;
            stale = false;
            if !w.state(state_of(&state)) {
                return;
            }
        }
        if got.lost > 0 {
            tracing::warn!(lost = got.lost, "GPS through the vest: {} receiver bytes lost", got.lost);
            let notice = format!(
                "{} GPS bytes lost between the receiver and the console (vest unit or link overloaded)",
                got.lost
            );
            if !w.send(GpsEvent::Notice(notice)) {
                return;
            }
        }
        if got.len > 0 {
            d.handle_bytes(&buf[..got.len], now);
            last_data = now;
            if stale {
                stale = false;
                if !w.state(SourceState::Live { detail: "data again".into() }) {
                    return;
                }
            }
        }
        d.handle_timeout(now);
        if !w.drain(&mut d) {
            return;
        }
        let idle = now.saturating_duration_since(last_data);
        if forwarding && !stale && idle >= STALE_AFTER {
            stale = true;
            if !w.state(SourceState::Stale) {
                return;
            }
        }
        if forwarding && idle >= LOST_AFTER && stale {
            // The unit forwards nothing: its receiver is unplugged or silent. Say so once per period.
            last_data = now;
            let reason = format!("through the vest unit: no receiver bytes for {} s", LOST_AFTER.as_secs());
            if !w.state(SourceState::Lost { reason }) {
                return;
            }
        }
        if last_stats.elapsed() >= Duration::from_secs(1) {
            last_stats = Instant::now();
            if !w.send(GpsEvent::Stats(d.stats())) {
                return;
            }
        }
    }
}
