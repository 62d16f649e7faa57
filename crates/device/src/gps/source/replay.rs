//! The replay source: an NMEA log or recording handed out in time (by `$PVNAV,TS` stamps or UTC times),
//! with pause, seek and progress through a [`ReplayControl`].

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use vestnav_core::fieldtest::unwrap_time_of_day;

use super::{ReplaySpeed, SourceState, Worker};
use crate::gps::sentence;
use crate::gps::{DecoderConfig, GpsEvent, NmeaDecoder};

/// No seek requested (the bits of a fraction are never this value).
const NO_SEEK: u64 = u64::MAX;

/// The controls of a running replay, shared between its worker and whoever steers it (the console's GPS
/// panel): pause/resume, seek, and the position reached. All atomics: setting them never waits on the
/// worker, which looks at them before every line and at least every 20 ms while waiting.
#[derive(Debug)]
pub struct ReplayControl {
    paused: AtomicBool,
    /// At the end of the file, start again from its beginning.
    looped: AtomicBool,
    /// A pending seek: the bits of a fraction of the time span in `[0, 1]`, or [`NO_SEEK`].
    seek: AtomicU64,
    position_bytes: AtomicU64,
    total_bytes: AtomicU64,
    position_ms: AtomicU64,
    span_ms: AtomicU64,
}

impl Default for ReplayControl {
    fn default() -> Self {
        Self {
            paused: AtomicBool::new(false),
            looped: AtomicBool::new(false),
            seek: AtomicU64::new(NO_SEEK),
            position_bytes: AtomicU64::new(0),
            total_bytes: AtomicU64::new(0),
            position_ms: AtomicU64::new(0),
            span_ms: AtomicU64::new(0),
        }
    }
}

/// Where a replay is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReplayProgress {
    /// Bytes of the file handed out so far (the end of the last line).
    pub position_bytes: u64,
    /// The file's size.
    pub total_bytes: u64,
    /// Time of the last paced line, from the file's first stamp [ms].
    pub position_ms: u64,
    /// Time from the file's first stamp to its last (splices closed to 1 s) [ms]; 0 when unstamped.
    pub span_ms: u64,
}

impl ReplayProgress {
    /// The position as a fraction in `[0, 1]`: of the time span, or of the bytes when the file has no
    /// stamps.
    pub fn fraction(&self) -> f64 {
        if self.span_ms > 0 {
            (self.position_ms as f64 / self.span_ms as f64).clamp(0.0, 1.0)
        } else if self.total_bytes > 0 {
            (self.position_bytes as f64 / self.total_bytes as f64).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }
}

impl ReplayControl {
    /// Pauses (`true`) or resumes the replay.
    pub fn set_paused(&self, paused: bool) {
        self.paused.store(paused, Ordering::Relaxed);
    }

    /// Loops (`true`: at the end of the file the replay starts again from its beginning, with a
    /// [`GpsEvent::Discontinuity`]) or stops at the end ([`SourceState::Finished`]).
    pub fn set_looped(&self, looped: bool) {
        self.looped.store(looped, Ordering::Relaxed);
    }

    /// True while looping.
    pub fn is_looped(&self) -> bool {
        self.looped.load(Ordering::Relaxed)
    }

    /// True while paused.
    pub fn is_paused(&self) -> bool {
        self.paused.load(Ordering::Relaxed)
    }

    /// Asks the replay to continue from `fraction` (clamped to `[0, 1]`) of the file's time span (of its
    /// lines when it has no stamps): from the first line stamped at or after that time. The worker
    /// restarts its decoder there and sends a [`GpsEvent::Discontinuity`].
    pub fn seek_fraction(&self, fraction: f64) {
        let f = if fraction.is_finite() { fraction.clamp(0.0, 1.0) } else { 0.0 };
        self.seek.store(f.to_bits(), Ordering::Relaxed);
    }

    /// Asks the replay to continue from `ms` after the file's first stamp (see [`Self::seek_fraction`]).
    pub fn seek_ms(&self, ms: u64) {
        let span = self.span_ms.load(Ordering::Relaxed);
        self.seek_fraction(if span == 0 { 0.0 } else { ms as f64 / span as f64 });
    }

    /// The position reached.
    pub fn progress(&self) -> ReplayProgress {
        ReplayProgress {
            position_bytes: self.position_bytes.load(Ordering::Relaxed),
            total_bytes: self.total_bytes.load(Ordering::Relaxed),
            position_ms: self.position_ms.load(Ordering::Relaxed),
            span_ms: self.span_ms.load(Ordering::Relaxed),
        }
    }

    fn take_seek(&self) -> Option<f64> {
        let bits = self.seek.swap(NO_SEEK, Ordering::Relaxed);
        (bits != NO_SEEK).then(|| f64::from_bits(bits))
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

/// The lines of a log (byte ranges) and the time of each paced line from the first one [ms]: by the
/// `$PVNAV,TS` stamps when the log has them, else by the sentences' UTC times of day (midnight wrap
/// handled; a splice — a jump back, or forward by more than a minute — continues one second later).
fn timeline(data: &[u8]) -> Vec<(std::ops::Range<usize>, Option<u64>)> {
    let has_ts = data.windows(10).any(|x| x == b"$PVNAV,TS,");
    let mut out = Vec::new();
    let mut first: Option<i64> = None;
    let mut shift_ms: i64 = 0;
    let mut last: Option<i64> = None;
    let mut start = 0;
    for line in data.split_inclusive(|&b| b == b'\n') {
        let range = start..start + line.len();
        start = range.end;
        let stamp = match line_stamp(line) {
            Some((is_ts, mut ms)) if is_ts == has_ts => {
                if !has_ts {
                    // A time of day: onto the running line, across midnight (core's one rule).
                    let tod_s = ms as f64 / 1000.0;
                    let t_s = unwrap_time_of_day(tod_s, last.map(|p| p as f64 / 1000.0));
                    ms = (t_s * 1000.0).round() as i64;
                }
                if let Some(prev) = last
                    && (ms < prev || ms - prev > 60_000)
                {
                    shift_ms += (ms - prev) - 1000;
                }
                last = Some(ms);
                let f = *first.get_or_insert(ms);
                Some(u64::try_from(ms - f - shift_ms).unwrap_or(0))
            }
            _ => None,
        };
        out.push((range, stamp));
    }
    out
}

/// What [`replay_controlled`] hands out.
pub(crate) enum ReplayItem<'a> {
    /// The next line of the file.
    Line(&'a [u8]),
    /// A seek was done: the next line is at `to_ms`, the last one handed out was at `from_ms`.
    Seek {
        /// Time of the last line handed out [ms from the first stamp].
        from_ms: u64,
        /// Time of the next line [ms from the first stamp].
        to_ms: u64,
    },
}

/// Hands out the lines of a log in time: by its `$PVNAV,TS` stamps when it has them, else by the
/// sentences' UTC times of day (midnight wrap handled; a splice — a jump back, or forward by more than a
/// minute — continues one second later), at `speed`. Returns false
/// when stopped or when `emit` returns false.
pub fn replay_lines(
    data: &[u8],
    speed: ReplaySpeed,
    stop: &AtomicBool,
    mut emit: impl FnMut(&[u8]) -> bool,
) -> bool {
    replay_controlled(data, speed, stop, &ReplayControl::default(), |item| match item {
        ReplayItem::Line(l) => emit(l),
        ReplayItem::Seek { .. } => true,
    })
}

/// [`replay_lines`] steered by `ctl`: paused while it says so (the clock restarts on resume), seeking
/// when asked, publishing the position after every line.
pub(crate) fn replay_controlled(
    data: &[u8],
    speed: ReplaySpeed,
    stop: &AtomicBool,
    ctl: &ReplayControl,
    mut emit: impl FnMut(ReplayItem<'_>) -> bool,
) -> bool {
    let speed = speed.pace();
    let lines = timeline(data);
    let span_ms = lines.iter().filter_map(|(_, s)| *s).max().unwrap_or(0);
    ctl.total_bytes.store(data.len() as u64, Ordering::Relaxed);
    ctl.span_ms.store(span_ms, Ordering::Relaxed);
    // The pacing clock: this instant corresponds to this file time (reset by pause and seek).
    let mut clock: Option<(Instant, u64)> = None;
    let mut i = 0;
    while i < lines.len() {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        if let Some(f) = ctl.take_seek() {
            let j = if span_ms > 0 {
                let target = (f * span_ms as f64).round() as u64;
                lines.iter().position(|(_, s)| s.is_some_and(|s| s >= target)).unwrap_or(lines.len())
            } else {
                ((f * lines.len() as f64) as usize).min(lines.len())
            };
            let from_ms = ctl.position_ms.load(Ordering::Relaxed);
            let to_ms = lines.get(j).and_then(|(_, s)| *s).unwrap_or(span_ms);
            i = j;
            clock = None;
            let at = lines.get(j).map_or(data.len(), |(r, _)| r.start);
            ctl.position_bytes.store(at as u64, Ordering::Relaxed);
            ctl.position_ms.store(to_ms, Ordering::Relaxed);
            if !emit(ReplayItem::Seek { from_ms, to_ms }) {
                return false;
            }
            continue;
        }
        if ctl.is_paused() {
            clock = None;
            std::thread::sleep(Duration::from_millis(20));
            continue;
        }
        let Some((range, stamp)) = lines.get(i).cloned() else { break };
        if let (Some(speed), Some(ms)) = (speed, stamp) {
            let (t0, ms0) = *clock.get_or_insert((Instant::now(), ms));
            let due = t0 + Duration::from_secs_f64((ms.saturating_sub(ms0) as f64 / 1000.0) / speed);
            let now = Instant::now();
            if now < due {
                std::thread::sleep((due - now).min(Duration::from_millis(20)));
                continue;
            }
        }
        let Some(line) = data.get(range.clone()) else { break };
        if !emit(ReplayItem::Line(line)) {
            return false;
        }
        ctl.position_bytes.store(range.end as u64, Ordering::Relaxed);
        if let Some(ms) = stamp {
            ctl.position_ms.store(ms, Ordering::Relaxed);
        }
        i += 1;
    }
    !stop.load(Ordering::Relaxed)
}

/// `ms` as `m:ss.s`.
fn clock_text(ms: u64) -> String {
    format!("{}:{:04.1}", ms / 60_000, (ms % 60_000) as f64 / 1000.0)
}

pub(super) fn run_replay(w: &Worker, path: &std::path::Path, speed: ReplaySpeed, ctl: &ReplayControl) {
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
    let new_decoder = || NmeaDecoder::new(DecoderConfig::live()).with_raw_lines();
    loop {
        let mut d = new_decoder();
        let completed = replay_controlled(&data, speed, &w.stop, ctl, |item| match item {
            ReplayItem::Line(line) => {
                d.handle_bytes(line, Instant::now());
                w.drain(&mut d)
            }
            ReplayItem::Seek { from_ms, to_ms } => {
                // The half-assembled epoch belongs to the old place in the file: drop it with the decoder.
                d = new_decoder();
                let dir = if to_ms < from_ms { "back" } else { "forward" };
                w.send(GpsEvent::Discontinuity(format!(
                    "replay sought {dir} from {} to {}: the track restarts here",
                    clock_text(from_ms),
                    clock_text(to_ms)
                )))
            }
        });
        if !completed {
            return;
        }
        d.finish(Instant::now());
        if !w.drain(&mut d) {
            return;
        }
        if !ctl.is_looped() {
            w.state(SourceState::Finished);
            return;
        }
        if !w.send(GpsEvent::Discontinuity(format!(
            "replay looped: {} starts again from the beginning",
            path.display()
        ))) {
            return;
        }
    }
}
