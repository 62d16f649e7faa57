//! GPS time: the GPS epoch and week, GPS − UTC now and in the past (the leap seconds), and UTC of a GPS week
//! and time of week, for the binary decoders whose messages carry GPS time (`SiRF`, `SkyTraq`, UBX).

use chrono::{DateTime, Utc};

/// GPS time minus UTC [s] since 2017-01-01 (IERS Bulletin C 52; no leap second announced since).
///
/// A `SiRF` receiver learns the current value from the almanac's UTC page (subframe 4, page 18, broadcast
/// every 12.5 min) and uses a firmware default until then: the `SiRF` II of gpsd's `sirf2.log` still said
/// 13 s (the value of 1999–2005) after 13 minutes of navigating in 2021. GPS minus UTC has only ever grown,
/// so a receiver's smaller value is such a stale default; the decoder takes the larger of this constant and
/// what MID 41 implies.
pub(crate) const GPS_UTC_OFFSET_S: i64 = 18;
/// Unix time of the GPS epoch, 1980-01-06T00:00:00Z [s].
pub(crate) const GPS_EPOCH_UNIX_S: i64 = 315_964_800;
/// GPS time minus UTC [s] from each leap second on: (Unix time of the UTC midnight it took effect, the new
/// difference). The leap seconds of 1981–2016 (IERS Bulletin C; the last one before 2017-01-01 00:00 UTC
/// made it [`GPS_UTC_OFFSET_S`]).
pub(crate) const GPS_UTC_HISTORY: [(i64, i64); 18] = [
    (362_793_600, 1),                  // 1981-07-01
    (394_329_600, 2),                  // 1982-07-01
    (425_865_600, 3),                  // 1983-07-01
    (489_024_000, 4),                  // 1985-07-01
    (567_993_600, 5),                  // 1988-01-01
    (631_152_000, 6),                  // 1990-01-01
    (662_688_000, 7),                  // 1991-01-01
    (709_948_800, 8),                  // 1992-07-01
    (741_484_800, 9),                  // 1993-07-01
    (773_020_800, 10),                 // 1994-07-01
    (820_454_400, 11),                 // 1996-01-01
    (867_715_200, 12),                 // 1997-07-01
    (915_148_800, 13),                 // 1999-01-01
    (1_136_073_600, 14),               // 2006-01-01
    (1_230_768_000, 15),               // 2009-01-01
    (1_341_100_800, 16),               // 2012-07-01
    (1_435_708_800, 17),               // 2015-07-01
    (1_483_228_800, GPS_UTC_OFFSET_S), // 2017-01-01
];
/// Seconds in a GPS week.
pub(crate) const WEEK_S: i64 = 604_800;
/// Milliseconds in a GPS week (the time-of-week range).
pub(crate) const WEEK_MS: i64 = WEEK_S * 1000;

/// UTC of a GPS week and time of week [ms] for a receiver that does not say GPS − UTC (`SkyTraq` binary):
/// the difference in force at that time by [`GPS_UTC_HISTORY`] (0 before the first leap second of
/// 1981-07-01). The inserted second itself (23:59:60 UTC) is labelled as the midnight after it.
pub(crate) fn utc_from_gps_by_history(week: u32, tow_ms: i64) -> Option<DateTime<Utc>> {
    let gps_unix_s = GPS_EPOCH_UNIX_S + i64::from(week) * WEEK_S + tow_ms.div_euclid(1000);
    let leap_s = GPS_UTC_HISTORY
        .iter()
        .rev()
        .find(|&&(from_unix_s, leap)| gps_unix_s - leap >= from_unix_s)
        .map_or(0, |&(_, leap)| leap);
    utc_from_gps(week, tow_ms, leap_s)
}

/// UTC of a GPS week and time of week [ms], `leap_s` = GPS − UTC; `None` for a time of week outside the
/// week.
pub(crate) fn utc_from_gps(week: u32, tow_ms: i64, leap_s: i64) -> Option<DateTime<Utc>> {
    if !(0..WEEK_MS).contains(&tow_ms) {
        return None;
    }
    let s = GPS_EPOCH_UNIX_S + i64::from(week) * WEEK_S + tow_ms.div_euclid(1000) - leap_s;
    DateTime::from_timestamp(s, (tow_ms.rem_euclid(1000) * 1_000_000) as u32)
}

/// UTC of a GPS week and a time of week in nanoseconds that may run a little past either end of the week
/// (UBX's iTOW + fTOW), rounded to the millisecond, `leap_s` = GPS − UTC; `None` before the GPS epoch.
pub(crate) fn utc_from_gps_ns(week: i64, tow_ns: i64, leap_s: i64) -> Option<DateTime<Utc>> {
    let ms = tow_ns.checked_add(500_000)?.div_euclid(1_000_000);
    let week = week.checked_add(ms.div_euclid(WEEK_MS))?;
    utc_from_gps(u32::try_from(week).ok()?, ms.rem_euclid(WEEK_MS), leap_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn utc(s: &str) -> DateTime<Utc> {
        DateTime::parse_from_rfc3339(s).unwrap().with_timezone(&Utc)
    }

    /// GPS week 2000 began 2018-05-06 00:00:00 GPS time (IS-GPS-200 week count from 1980-01-06, 2000 weeks
    /// = 14,000 days), which was 2018-05-05 23:59:42 UTC with GPS − UTC = 18 s.
    #[test]
    fn a_week_and_time_of_week_give_utc() {
        assert_eq!(utc_from_gps(2000, 0, 18), Some(utc("2018-05-05T23:59:42Z")));
        assert_eq!(utc_from_gps(2000, 1_500, 18), Some(utc("2018-05-05T23:59:43.5Z")));
        assert_eq!(utc_from_gps(2000, WEEK_MS, 18), None, "the time of week ends before the week's length");
        assert_eq!(utc_from_gps_by_history(2000, 0), Some(utc("2018-05-05T23:59:42Z")));
        // 1990-01-01 00:00:06 GPS, just past the leap second of that midnight (GPS − UTC 5 -> 6 s).
        let week = (631_152_000 - GPS_EPOCH_UNIX_S) / WEEK_S;
        let tow_ms = (631_152_000 - GPS_EPOCH_UNIX_S - week * WEEK_S + 6) * 1000;
        assert_eq!(utc_from_gps_by_history(week as u32, tow_ms), Some(utc("1990-01-01T00:00:00Z")));
        assert_eq!(utc_from_gps_by_history(week as u32, tow_ms - 1000), Some(utc("1990-01-01T00:00:00Z")));
    }

    /// UBX's iTOW + fTOW in nanoseconds runs a little past either end of the week: it rounds to the
    /// millisecond and carries into the neighbouring week.
    #[test]
    fn nanoseconds_round_and_carry_across_the_week() {
        assert_eq!(utc_from_gps_ns(2000, -400, 18), Some(utc("2018-05-05T23:59:42Z")));
        assert_eq!(utc_from_gps_ns(2000, -600_000, 18), Some(utc("2018-05-05T23:59:41.999Z")));
        assert_eq!(utc_from_gps_ns(1999, WEEK_MS * 1_000_000 - 100, 18), Some(utc("2018-05-05T23:59:42Z")));
        assert_eq!(utc_from_gps_ns(-1, 0, 18), None);
        assert_eq!(utc_from_gps_ns(0, -1_000_000, 0), None, "before the GPS epoch");
        assert_eq!(utc_from_gps_ns(0, i64::MAX, 0), None, "no overflow");
    }
}
