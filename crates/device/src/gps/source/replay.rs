//! The replay source: an NMEA log or recording handed out in time (by `$PVNAV,TS` stamps or UTC times).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::{SourceState, Worker};
use crate::gps::sentence;
use crate::gps::{DecoderConfig, NmeaDecoder};

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

pub(super) fn run_replay(w: &Worker, path: &std::path::Path, speed: Option<f64>) {
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
