//! Date validation at the decoder boundary (docs/gps.md, "Date validation").
//!
//! A date a receiver sends (RMC, ZDA, a binary time message) becomes the fix's UTC only when it is
//! - within the GPS era, [`FIRST_DATE`] to [`LAST_DATE`]: a GPS receiver cannot know an earlier date, and
//!   a later one is a corrupted field (a ZDA with year 0255 and a valid checksum, found by mutation
//!   fuzzing of real logs); old logs replayed today keep their dates, so "now" is no bound;
//! - and consistent with the running date: the same day, or the next (previous) one when the time of day
//!   wrapped forwards (backwards) past midnight, or any date that puts the epoch after the previous one by
//!   less than a day (a receiver off for hours, two sessions of one log). A different date counts as implausible until
//!   [`CONFIRM_EPOCHS`] epochs in a row agree on it (a receiver that really changed its date — a new
//!   session spliced into a log, a cold start that corrected a week-rollover date — is followed after
//!   that; a single corrupted sentence never is). A jump by whole 1024-week eras gets no exception: one
//!   of the two dates is a receiver's rollover bug, and the confirmation decides which one the stream
//!   keeps.
//!
//! The first date of a stream has nothing to be consistent with: only the range applies to it.

use chrono::{NaiveDate, NaiveTime, TimeDelta};

/// Earliest plausible date: the GPS epoch, 1980-01-06.
pub const FIRST_DATE: NaiveDate = match NaiveDate::from_ymd_opt(1980, 1, 6) {
    Some(d) => d,
    None => NaiveDate::MIN,
};
/// Latest plausible date: 2099-12-31 (NMEA's two-digit years and CASIC's documented range end there).
pub const LAST_DATE: NaiveDate = match NaiveDate::from_ymd_opt(2099, 12, 31) {
    Some(d) => d,
    None => NaiveDate::MAX,
};
/// Epochs in a row that must agree on a new date before it replaces the running one.
pub const CONFIRM_EPOCHS: u32 = 3;

/// True when `d` is within the GPS era ([`FIRST_DATE`]..=[`LAST_DATE`]).
pub fn in_gps_era(d: NaiveDate) -> bool {
    (FIRST_DATE..=LAST_DATE).contains(&d)
}

/// The date that follows `date` at time of day `prev` when the next epoch's time of day is `now`: the
/// next day when the time wrapped forwards past midnight (fell by more than 12 h), the previous day when it
/// wrapped backwards (rose by more than 12 h), else the same day.
pub(crate) fn roll(date: NaiveDate, prev: Option<NaiveTime>, now: Option<NaiveTime>) -> NaiveDate {
    let (Some(prev), Some(now)) = (prev, now) else { return date };
    let half_day = TimeDelta::hours(12);
    if now < prev && prev - now > half_day {
        date.succ_opt().unwrap_or(date)
    } else if now > prev && now - prev > half_day {
        date.pred_opt().unwrap_or(date)
    } else {
        date
    }
}

/// True when the epoch at `date` `tod` follows the previous one at `running` `prev` by more than nothing and
/// less than a day: a receiver that was off for hours (or a log spliced from two sessions) and says so with
/// its date. Any corrupted date of a stream whose epochs are less than a day apart moves its UTC by whole
/// days, so it lands before the previous epoch or a day or more after it: never in this window.
fn steps_forward_within_a_day(
    running: NaiveDate,
    prev: Option<NaiveTime>,
    date: NaiveDate,
    tod: Option<NaiveTime>,
) -> bool {
    let (Some(prev), Some(tod)) = (prev, tod) else { return false };
    let step = date.and_time(tod) - running.and_time(prev);
    step > TimeDelta::zero() && step < TimeDelta::days(1)
}

/// The state of the date check: a new date waiting for confirmation.
#[derive(Debug, Clone, Default)]
pub(crate) struct DateCheck {
    /// (date, its epoch's time of day, epochs in a row that agreed on it).
    candidate: Option<(NaiveDate, Option<NaiveTime>, u32)>,
}

impl DateCheck {
    /// Judges the date `date` an epoch at time of day `tod` says, against the running date `running` of
    /// the epoch at `last_tod`. True: use it. False: implausible (out of range, or a new date not yet
    /// confirmed).
    pub(crate) fn accept(
        &mut self,
        date: NaiveDate,
        tod: Option<NaiveTime>,
        running: Option<NaiveDate>,
        last_tod: Option<NaiveTime>,
    ) -> bool {
        if !in_gps_era(date) {
            return false;
        }
        let Some(running) = running else {
            self.candidate = None;
            return true;
        };
        if roll(running, last_tod, tod) == date || steps_forward_within_a_day(running, last_tod, date, tod) {
            self.candidate = None;
            return true;
        }
        let agreed = match self.candidate {
            Some((d, t, n)) if roll(d, t, tod) == date => n + 1,
            _ => 1,
        };
        if agreed >= CONFIRM_EPOCHS {
            self.candidate = None;
            return true;
        }
        self.candidate = Some((date, tod, agreed));
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn d(y: i32, m: u32, day: u32) -> NaiveDate {
        NaiveDate::from_ymd_opt(y, m, day).unwrap()
    }
    fn t(h: u32, m: u32, s: u32) -> Option<NaiveTime> {
        NaiveTime::from_hms_opt(h, m, s)
    }

    #[test]
    fn range_is_the_gps_era() {
        assert!(!in_gps_era(d(255, 1, 1)));
        assert!(!in_gps_era(d(1980, 1, 5)));
        assert!(in_gps_era(d(1980, 1, 6)));
        assert!(in_gps_era(d(2099, 12, 31)));
        assert!(!in_gps_era(d(2100, 1, 1)));
        // A replay of a 1999 log is as plausible as today's.
        assert!(in_gps_era(d(1999, 8, 22)));
    }

    #[test]
    fn midnight_rolls_the_expected_date_both_ways() {
        assert_eq!(roll(d(2024, 2, 28), t(23, 59, 59), t(0, 0, 0)), d(2024, 2, 29));
        assert_eq!(roll(d(2024, 3, 1), t(0, 0, 1), t(23, 59, 59)), d(2024, 2, 29));
        assert_eq!(roll(d(2024, 3, 1), t(8, 0, 0), t(19, 0, 0)), d(2024, 3, 1));
    }

    #[test]
    fn a_single_jump_is_rejected_a_confirmed_one_followed() {
        let mut c = DateCheck::default();
        let run = Some(d(2015, 3, 18));
        // One corrupted date between good ones.
        assert!(!c.accept(d(2034, 11, 2), t(12, 0, 1), run, t(12, 0, 0)));
        assert!(c.accept(d(2015, 3, 18), t(12, 0, 2), run, t(12, 0, 1)));
        // A real change: rejected twice, accepted the third time in a row.
        assert!(!c.accept(d(2019, 4, 7), t(12, 0, 3), run, t(12, 0, 2)));
        assert!(!c.accept(d(2019, 4, 7), t(12, 0, 4), run, t(12, 0, 3)));
        assert!(c.accept(d(2019, 4, 7), t(12, 0, 5), run, t(12, 0, 4)));
        // A day off by one without midnight is a jump too.
        let run = Some(d(2019, 4, 7));
        assert!(!c.accept(d(2019, 4, 8), t(12, 0, 6), run, t(12, 0, 5)));
        assert!(c.accept(d(2019, 4, 8), t(0, 0, 0), run, t(23, 59, 59)));
    }

    #[test]
    fn a_gap_of_hours_that_the_date_explains_is_followed() {
        let mut c = DateCheck::default();
        // The i.Trek log: a session at 15:16 on the 26th, the next at 04:58 on the 27th (13.7 h later).
        let run = Some(d(2005, 7, 26));
        assert!(c.accept(d(2005, 7, 27), t(4, 58, 49), run, t(15, 16, 6)));
        // A day or more forwards, or any step back, still needs confirmation.
        assert!(!c.accept(d(2005, 7, 27), t(15, 16, 6), run, t(15, 16, 6)));
        assert!(!c.accept(d(2005, 7, 25), t(15, 16, 7), run, t(15, 16, 6)));
    }
}
