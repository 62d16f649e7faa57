//! Safety limits of the vest, checked by the console before sending and by the unit before running.
//!
//! Defaults and why (physics.md §4, §6: 16 tactors, ~70 mA each at 200 Hz, 1.12 A all together, 500 ms
//! normal on-time):
//! - **on-time**: at most 2000 ms per command or per continuous run in a pattern (4x the normal 500 ms), so
//!   no single message can leave a tactor on for long;
//! - **current budget**: at most 8 tactors at once, 8 x 70 mA = 560 mA, half the 1.12 A of the full vest.
//!   A small Li-ion pack and the motor drivers of a belt-worn unit are sized for such a peak, and every cue of
//!   vestnav's vocabulary (`vestnav_core::vest::Cue`) needs at most 8;
//! - **duty cycle**: per tactor at most 5000 ms on in any 10 s window (50 %), against overheating the pancake
//!   motor and numbing the skin;
//! - **patterns**: at most 32 frames and 10 s in total.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use vestnav_core::vest::{Frame, Pattern, TACTOR_COUNT, TactorMask};

use super::message::NakReason;

/// The limits a unit enforces (and reports in its IDENTIFY), also applied by the console.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Limits {
    /// Longest on-time of one command, and of one continuous run of a tactor in a pattern (ms).
    pub max_on_ms: u16,
    /// Most tactors on at once (the current budget divided by 70 mA).
    pub max_simultaneous: u8,
    /// Length of the sliding duty-cycle window (ms).
    pub duty_window_ms: u16,
    /// Most on-time of one tactor within any duty-cycle window (ms).
    pub max_duty_on_ms: u16,
    /// Most frames in one pattern.
    pub max_pattern_frames: u8,
    /// Longest pattern, all repeats included (ms).
    pub max_pattern_ms: u16,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_on_ms: 2000,
            max_simultaneous: 8,
            duty_window_ms: 10_000,
            max_duty_on_ms: 5000,
            max_pattern_frames: 32,
            max_pattern_ms: 10_000,
        }
    }
}

/// A command outside the limits.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LimitError {
    /// An on-time of zero (a fire must end, a frame must last).
    #[error("on-time of 0 ms")]
    ZeroDuration,
    /// A tactor would stay on longer than allowed in one go.
    #[error("on-time {requested_ms} ms exceeds the limit of {max_ms} ms")]
    OnTooLong {
        /// Requested continuous on-time (ms).
        requested_ms: u32,
        /// Limit (ms).
        max_ms: u16,
    },
    /// More tactors at once than the current budget allows.
    #[error("{requested} tactors at once exceeds the current budget of {max} (70 mA each)")]
    TooManyTactors {
        /// Tactors requested at once.
        requested: u32,
        /// Limit.
        max: u8,
    },
    /// A tactor would exceed its on-time budget in the duty-cycle window.
    #[error(
        "tactor {tactor}: {spent_ms} ms already on plus {requested_ms} ms requested exceeds {max_ms} ms per \
         {window_ms} ms"
    )]
    DutyCycle {
        /// The tactor.
        tactor: usize,
        /// On-time already spent in the window (ms).
        spent_ms: u32,
        /// On-time the command asks for (ms).
        requested_ms: u32,
        /// Budget (ms).
        max_ms: u16,
        /// Window (ms).
        window_ms: u16,
    },
    /// A pattern has no frames, zero repeats, too many frames or lasts too long.
    #[error("pattern: {0}")]
    Pattern(String),
}

impl LimitError {
    /// The NAK reason a unit sends for this violation.
    pub fn nak_reason(&self) -> NakReason {
        match self {
            Self::ZeroDuration | Self::OnTooLong { .. } => NakReason::DurationLimit,
            Self::TooManyTactors { .. } => NakReason::TooManyTactors,
            Self::DutyCycle { .. } => NakReason::DutyCycle,
            Self::Pattern(_) => NakReason::PatternLimit,
        }
    }
}

impl Limits {
    /// The stricter of two sets of limits, field by field (console limits against the unit's).
    #[must_use]
    pub fn tighter(&self, other: &Self) -> Self {
        Self {
            max_on_ms: self.max_on_ms.min(other.max_on_ms),
            max_simultaneous: self.max_simultaneous.min(other.max_simultaneous),
            duty_window_ms: self.duty_window_ms.max(other.duty_window_ms),
            max_duty_on_ms: self.max_duty_on_ms.min(other.max_duty_on_ms),
            max_pattern_frames: self.max_pattern_frames.min(other.max_pattern_frames),
            max_pattern_ms: self.max_pattern_ms.min(other.max_pattern_ms),
        }
    }

    /// Checks a FIRE of `mask` for `duration_ms` (without the duty cycle, see [`DutyLedger::check`]).
    pub fn check_fire(&self, mask: TactorMask, duration_ms: u16) -> Result<(), LimitError> {
        if mask.is_empty() {
            return Ok(());
        }
        if duration_ms == 0 {
            return Err(LimitError::ZeroDuration);
        }
        if duration_ms > self.max_on_ms {
            return Err(LimitError::OnTooLong {
                requested_ms: u32::from(duration_ms),
                max_ms: self.max_on_ms,
            });
        }
        if mask.count() > u32::from(self.max_simultaneous) {
            return Err(LimitError::TooManyTactors { requested: mask.count(), max: self.max_simultaneous });
        }
        Ok(())
    }

    /// Checks a pattern: 1..=`max_pattern_frames` frames, every frame longer than 0 ms, at least one repeat,
    /// total time (frames x repeats) within `max_pattern_ms`, every frame within the current budget, and no
    /// tactor on longer than `max_on_ms` in one go ([`Pattern::longest_on_ms`], across repeats).
    pub fn check_pattern(&self, frames: &[Frame], repeats: u8) -> Result<(), LimitError> {
        if frames.is_empty() {
            return Err(LimitError::Pattern("no frames".to_owned()));
        }
        if repeats == 0 {
            return Err(LimitError::Pattern("0 repeats".to_owned()));
        }
        if frames.len() > usize::from(self.max_pattern_frames) {
            return Err(LimitError::Pattern(format!(
                "{} frames exceeds the limit of {}",
                frames.len(),
                self.max_pattern_frames
            )));
        }
        if frames.iter().any(|f| f.duration_ms == 0) {
            return Err(LimitError::ZeroDuration);
        }
        let pattern = Pattern { name: String::new(), frames: frames.to_vec(), repeats };
        if pattern.total_ms() > u32::from(self.max_pattern_ms) {
            return Err(LimitError::Pattern(format!(
                "{} ms exceeds the limit of {} ms",
                pattern.total_ms(),
                self.max_pattern_ms
            )));
        }
        let most = pattern.max_simultaneous();
        if most > u32::from(self.max_simultaneous) {
            return Err(LimitError::TooManyTactors { requested: most, max: self.max_simultaneous });
        }
        let longest = pattern.longest_on_ms();
        if longest > u32::from(self.max_on_ms) {
            return Err(LimitError::OnTooLong { requested_ms: longest, max_ms: self.max_on_ms });
        }
        Ok(())
    }
}

/// On-time each tactor would get from a FIRE (ms).
pub fn planned_fire_ms(mask: TactorMask, duration_ms: u16) -> [u32; TACTOR_COUNT] {
    let mut planned = [0u32; TACTOR_COUNT];
    for t in mask.indices() {
        planned[t] = u32::from(duration_ms);
    }
    planned
}

/// On-time each tactor would get from a pattern (ms): the sum of its frames' durations times `repeats`.
pub fn planned_pattern_ms(frames: &[Frame], repeats: u8) -> [u32; TACTOR_COUNT] {
    let mut planned = [0u32; TACTOR_COUNT];
    for f in frames {
        for t in f.mask.indices() {
            planned[t] += u32::from(f.duration_ms);
        }
    }
    for p in &mut planned {
        *p *= u32::from(repeats.max(1));
    }
    planned
}

/// Per-tactor history of on-intervals, for the duty-cycle limit (sans-IO: times are parameters).
///
/// The check is conservative: the on-time spent in the last window plus everything the new command asks
/// for must fit the budget, `spent(now - window, now) + planned <= max_duty_on_ms`, as if the whole command
/// ran inside the same window.
#[derive(Debug, Clone, Default)]
pub struct DutyLedger {
    intervals: [VecDeque<(Instant, Instant)>; TACTOR_COUNT],
}

impl DutyLedger {
    /// An empty history.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records that `mask` was (or is planned to be) on from `from` to `to`.
    pub fn record(&mut self, mask: TactorMask, from: Instant, to: Instant) {
        if to <= from {
            return;
        }
        for t in mask.indices() {
            if let Some(q) = self.intervals.get_mut(t) {
                q.push_back((from, to));
            }
        }
    }

    /// Cuts every interval at `at`: what was planned after it will not happen (a command replaced it).
    pub fn truncate_after(&mut self, at: Instant) {
        for q in &mut self.intervals {
            q.retain(|&(from, _)| from < at);
            for iv in q.iter_mut() {
                iv.1 = iv.1.min(at);
            }
        }
    }

    /// Forgets intervals that ended before `now - window`.
    pub fn prune(&mut self, now: Instant, window: Duration) {
        let Some(start) = now.checked_sub(window) else { return };
        for q in &mut self.intervals {
            while q.front().is_some_and(|&(_, to)| to < start) {
                q.pop_front();
            }
        }
    }

    /// On-time of `tactor` between `now - window` and `now` (ms).
    pub fn spent_ms(&self, tactor: usize, now: Instant, window: Duration) -> u32 {
        let start = now.checked_sub(window);
        let Some(q) = self.intervals.get(tactor) else { return 0 };
        let total: Duration = q
            .iter()
            .map(|&(from, to)| {
                let from = start.map_or(from, |s| from.max(s));
                let to = to.min(now);
                to.saturating_duration_since(from)
            })
            .sum();
        total.as_millis().try_into().unwrap_or(u32::MAX)
    }

    /// Checks the duty-cycle budget for `planned_ms` more on-time per tactor, starting at `now`.
    pub fn check(
        &self,
        planned_ms: &[u32; TACTOR_COUNT],
        now: Instant,
        limits: &Limits,
    ) -> Result<(), LimitError> {
        let window = Duration::from_millis(u64::from(limits.duty_window_ms));
        for (tactor, &requested_ms) in planned_ms.iter().enumerate() {
            if requested_ms == 0 {
                continue;
            }
            let spent_ms = self.spent_ms(tactor, now, window);
            if spent_ms + requested_ms > u32::from(limits.max_duty_on_ms) {
                return Err(LimitError::DutyCycle {
                    tactor,
                    spent_ms,
                    requested_ms,
                    max_ms: limits.max_duty_on_ms,
                    window_ms: limits.duty_window_ms,
                });
            }
        }
        Ok(())
    }

    /// Records a pattern starting at `start` frame by frame.
    pub fn record_pattern(&mut self, frames: &[Frame], repeats: u8, start: Instant) {
        let mut t = start;
        for _ in 0..repeats.max(1) {
            for f in frames {
                let end = t + Duration::from_millis(u64::from(f.duration_ms));
                self.record(f.mask, t, end);
                t = end;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vestnav_core::vest::{Cue, DEFAULT_ON_MS};

    #[test]
    fn every_cue_passes_the_default_limits() {
        let limits = Limits::default();
        for cue in Cue::ALL {
            let p = cue.pattern(DEFAULT_ON_MS);
            assert_eq!(limits.check_pattern(&p.frames, p.repeats), Ok(()), "{cue:?}");
        }
    }

    #[test]
    fn fire_limits() {
        let l = Limits::default();
        assert_eq!(l.check_fire(TactorMask::CORNERS, 500), Ok(()));
        assert_eq!(l.check_fire(TactorMask::CORNERS, 0), Err(LimitError::ZeroDuration));
        assert!(matches!(l.check_fire(TactorMask(1), 2001), Err(LimitError::OnTooLong { .. })));
        assert!(matches!(l.check_fire(TactorMask(0x01FF), 100), Err(LimitError::TooManyTactors { .. })));
        assert_eq!(l.check_fire(TactorMask(0x00FF), 100), Ok(()));
    }

    #[test]
    fn a_pattern_holding_a_tactor_too_long_is_refused() {
        let f = |mask, duration_ms| Frame { mask: TactorMask(mask), duration_ms };
        let l = Limits::default();
        // tactor 0 on through three consecutive 800 ms frames = 2400 ms continuous.
        let frames = [f(1, 800), f(3, 800), f(1, 800)];
        assert_eq!(
            l.check_pattern(&frames, 1),
            Err(LimitError::OnTooLong { requested_ms: 2400, max_ms: 2000 })
        );
    }

    #[test]
    fn duty_ledger_counts_the_window() {
        let t0 = Instant::now();
        let ms = |m: u64| Duration::from_millis(m);
        let l = Limits::default();
        let mut ledger = DutyLedger::new();
        ledger.record(TactorMask(1), t0, t0 + ms(2000));
        ledger.record(TactorMask(1), t0 + ms(3000), t0 + ms(5000));
        let now = t0 + ms(6000);
        assert_eq!(ledger.spent_ms(0, now, ms(10_000)), 4000);
        assert_eq!(ledger.check(&planned_fire_ms(TactorMask(1), 1000), now, &l), Ok(()));
        assert!(ledger.check(&planned_fire_ms(TactorMask(1), 1001), now, &l).is_err());
        // At 11 s the window is [1 s, 11 s]: 1000 ms of the first interval and all 2000 of the second.
        assert_eq!(ledger.spent_ms(0, t0 + ms(11_000), ms(10_000)), 3000);
        assert_eq!(ledger.spent_ms(0, t0 + ms(12_000), ms(10_000)), 2000);
        ledger.truncate_after(t0 + ms(4000));
        assert_eq!(ledger.spent_ms(0, now, ms(10_000)), 3000);
    }
}
