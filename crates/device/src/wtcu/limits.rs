//! Safety limits of the vest, checked by the console before sending and by the unit before running.
//!
//! Defaults and why (physics.md §4, §6: 16 tactors, ~70 mA each at 200 Hz, 1.12 A all together, 500 ms
//! normal on-time):
//! - **on-time**: no tactor is ever on continuously for more than 2000 ms (4x the normal 500 ms), whatever
//!   the commands: a FIRE's duration, a pattern's longest run over all its repeats
//!   ([`Pattern::longest_on_ms`]), and a command that keeps a tactor on which is already on (its run
//!   continues, [`RunTracker`]) are all held to it;
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
    /// A tactor would stay on longer than allowed in one go (one FIRE, or one run of a pattern over all its
    /// repeats).
    #[error("on-time {requested_ms} ms exceeds the limit of {max_ms} ms")]
    OnTooLong {
        /// Requested continuous on-time (ms).
        requested_ms: u32,
        /// Limit (ms).
        max_ms: u16,
    },
    /// A command would keep a tactor that is already on running past the continuous limit, counted from the
    /// start of its current run.
    #[error(
        "tactor {tactor} has been on for {on_for_ms} ms; {requested_ms} ms more without a break exceeds the \
         continuous limit of {max_ms} ms"
    )]
    RunTooLong {
        /// The tactor.
        tactor: usize,
        /// How long its current run has lasted so far (ms, rounded up).
        on_for_ms: u32,
        /// Continuous on-time the command adds from now (ms).
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
            Self::ZeroDuration | Self::OnTooLong { .. } | Self::RunTooLong { .. } => NakReason::DurationLimit,
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
    /// tactor on longer than `max_on_ms` in one go over the whole played pattern, all repeats and the wraps
    /// between them included ([`Pattern::longest_on_ms`], in closed form). Whether the pattern continues a
    /// run already under way is [`RunTracker::check`]'s business.
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

/// Continuous on-time each tactor gets from the start of a pattern (ms), [`Pattern::leading_on_ms`]: what
/// it adds to a run already under way when the pattern starts.
pub fn leading_pattern_ms(frames: &[Frame], repeats: u8) -> [u32; TACTOR_COUNT] {
    let pattern = Pattern { name: String::new(), frames: frames.to_vec(), repeats };
    std::array::from_fn(|t| pattern.leading_on_ms(t))
}

/// Per-tactor continuous runs on a timeline (sans-IO: times are parameters).
///
/// A *run* of a tactor is a maximal stretch of time during which it is driven without a break. An off time
/// of zero length (a command switching it on at the very instant another switched it off, consecutive
/// frames, the wrap between repeats) is no break. The limit is: no run lasts longer than `max_on_ms`.
/// Feed it every change of the driven set, in time order, with [`Self::set`].
#[derive(Debug, Clone, Default)]
pub struct RunTracker {
    /// Start of the current run of each tactor that is on.
    on_since: [Option<Instant>; TACTOR_COUNT],
    /// The last finished run of each tactor that is off: (start, end).
    last_run: [Option<(Instant, Instant)>; TACTOR_COUNT],
}

impl RunTracker {
    /// No tactor on, no history.
    pub fn new() -> Self {
        Self::default()
    }

    /// The driven set becomes `mask` at `at` (not earlier than the previous call).
    pub fn set(&mut self, mask: TactorMask, at: Instant) {
        for (t, (on_since, last_run)) in self.on_since.iter_mut().zip(&mut self.last_run).enumerate() {
            match (*on_since, mask.contains(t)) {
                (None, true) => {
                    // Switched off and on again at the same instant: the same run goes on.
                    let start = match *last_run {
                        Some((start, end)) if end >= at => start,
                        _ => at,
                    };
                    *on_since = Some(start);
                }
                (Some(start), false) => {
                    *on_since = None;
                    *last_run = Some((start, at));
                }
                _ => {}
            }
        }
    }

    /// When the run began that a command switching `tactor` on at `at` would continue: the start of its
    /// current run if it is on, or of the run that ended exactly at `at`; `None` when it would start afresh.
    pub fn run_start(&self, tactor: usize, at: Instant) -> Option<Instant> {
        let on = self.on_since.get(tactor).copied().flatten();
        on.or_else(|| {
            self.last_run.get(tactor).copied().flatten().filter(|&(_, end)| end >= at).map(|(start, _)| start)
        })
    }

    /// Checks a command at `at` that keeps each tactor `t` on without a break for `leading_ms[t]` from `at`
    /// ([`planned_fire_ms`], [`leading_pattern_ms`]): for every tactor whose run it continues,
    /// `(at - run_start) + leading_ms <= max_on_ms`. Runs the command starts afresh are
    /// [`Limits::check_fire`]'s and [`Limits::check_pattern`]'s business.
    pub fn check(
        &self,
        leading_ms: &[u32; TACTOR_COUNT],
        at: Instant,
        limits: &Limits,
    ) -> Result<(), LimitError> {
        let max = Duration::from_millis(u64::from(limits.max_on_ms));
        for (tactor, &requested_ms) in leading_ms.iter().enumerate() {
            if requested_ms == 0 {
                continue;
            }
            let Some(start) = self.run_start(tactor, at) else { continue };
            let on_for = at.saturating_duration_since(start);
            if on_for + Duration::from_millis(u64::from(requested_ms)) > max {
                let on_for_ms = on_for.as_micros().div_ceil(1000);
                return Err(LimitError::RunTooLong {
                    tactor,
                    on_for_ms: u32::try_from(on_for_ms).unwrap_or(u32::MAX),
                    requested_ms,
                    max_ms: limits.max_on_ms,
                });
            }
        }
        Ok(())
    }
}

/// What a unit drives, as planned by the last FIRE or PLAY it accepted.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum Schedule {
    /// Nothing.
    #[default]
    Idle,
    /// `mask` on until `until`.
    Fire {
        /// The tactors.
        mask: TactorMask,
        /// When they go off.
        until: Instant,
    },
    /// `frames` stepped through `repeats` times from `start`.
    Pattern {
        /// The frames.
        frames: Vec<Frame>,
        /// Passes over the frames.
        repeats: u8,
        /// When the first frame began.
        start: Instant,
    },
}

impl Schedule {
    /// A FIRE of `mask` for `duration_ms` starting at `start`.
    pub fn fire(mask: TactorMask, duration_ms: u16, start: Instant) -> Self {
        Self::Fire { mask, until: start + Duration::from_millis(u64::from(duration_ms)) }
    }

    /// The tactors driven at `at`, and when that changes next (`None`: never again, the schedule is over).
    /// The next change is always later than `at`.
    pub fn at(&self, at: Instant) -> (TactorMask, Option<Instant>) {
        match self {
            Self::Idle => (TactorMask::NONE, None),
            Self::Fire { mask, until } => {
                if at < *until {
                    (*mask, Some(*until))
                } else {
                    (TactorMask::NONE, None)
                }
            }
            Self::Pattern { frames, repeats, start } => {
                let cycle_ms: u64 = frames.iter().map(|f| u64::from(f.duration_ms)).sum();
                let total_ms = cycle_ms * u64::from(*repeats);
                let elapsed_ms =
                    u64::try_from(at.saturating_duration_since(*start).as_millis()).unwrap_or(u64::MAX);
                if cycle_ms == 0 || elapsed_ms >= total_ms {
                    return (TactorMask::NONE, None);
                }
                let mut end = elapsed_ms - elapsed_ms % cycle_ms;
                for f in frames {
                    end += u64::from(f.duration_ms);
                    if elapsed_ms < end {
                        return (f.mask, Some(*start + Duration::from_millis(end)));
                    }
                }
                (TactorMask::NONE, None)
            }
        }
    }
}

/// A [`Schedule`] played on a clock, with the [`RunTracker`] of what it drove: the unit's timeline, or the
/// console's model of it. Sans-IO: the clock only moves through [`Self::step`] and [`Self::advance_to`].
#[derive(Debug, Clone, Default)]
pub struct Timeline {
    schedule: Schedule,
    on: TactorMask,
    now: Option<Instant>,
    runs: RunTracker,
}

impl Timeline {
    /// Nothing scheduled, nothing on.
    pub fn new() -> Self {
        Self::default()
    }

    /// The tactors driven as of the last step.
    pub fn on(&self) -> TactorMask {
        self.on
    }

    /// The runs of what was driven.
    pub fn runs(&self) -> &RunTracker {
        &self.runs
    }

    /// The schedule in force.
    pub fn schedule(&self) -> &Schedule {
        &self.schedule
    }

    /// When the driven set changes next by itself (a pattern step, a fire's end), after the last step.
    pub fn next_change(&self) -> Option<Instant> {
        self.schedule.at(self.now?).1
    }

    /// Moves the clock to `at` (an earlier time counts as the last one) and returns the new driven set if it
    /// changed. Changes between the last step and `at` are not looked at: step at every
    /// [`Self::next_change`] in turn (or use [`Self::advance_to`]) to see each one at its own instant.
    pub fn step(&mut self, at: Instant) -> Option<TactorMask> {
        let at = self.now.map_or(at, |now| now.max(at));
        self.now = Some(at);
        let (mask, next) = self.schedule.at(at);
        if next.is_none() && mask.is_empty() {
            self.schedule = Schedule::Idle;
        }
        if mask == self.on {
            return None;
        }
        self.on = mask;
        self.runs.set(mask, at);
        Some(mask)
    }

    /// Plays the schedule up to `to`, every change at its own instant.
    pub fn advance_to(&mut self, to: Instant) {
        while let Some(t) = self.next_change().filter(|&t| t <= to) {
            self.step(t);
        }
        self.step(to);
    }

    /// Replaces the schedule at `at` (advance to `at` first) and returns the new driven set if it changed.
    pub fn replace(&mut self, schedule: Schedule, at: Instant) -> Option<TactorMask> {
        self.schedule = schedule;
        self.step(at)
    }
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
