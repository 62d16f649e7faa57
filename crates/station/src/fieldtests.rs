//! The field tests' feed: every fix with a position of whatever source runs goes to core's
//! [`FieldTests`] with its arrival time (from the fix's `received_at`) and the receiver's time of day; the
//! station tells them when the source changes, jumps or ends. A view only draws them.

use std::time::Instant;

use chrono::Timelike as _;
use vestnav_core::fieldtest_live::FieldTests;
use vestnav_device::gps::Fix;

/// Feeds `fix` to `tests`: its arrival [s] after `epoch`, its UTC time of day (`time_of_day`, else the
/// time of `time`) in seconds, position and speed over ground. A fix without a position is not fed.
pub fn feed(tests: &mut FieldTests, epoch: Instant, fix: &Fix) {
    let (Some(lat), Some(lon)) = (fix.lat_deg, fix.lon_deg) else { return };
    let arrival_s = fix.received_at.map_or(0.0, |t| t.saturating_duration_since(epoch).as_secs_f64());
    let tod = fix.time_of_day.or_else(|| fix.time.map(|t| t.time()));
    let tod_s = tod.map(|t| f64::from(t.num_seconds_from_midnight()) + f64::from(t.nanosecond()) * 1e-9);
    tests.push(arrival_s, tod_s, lat, lon, fix.speed_m_s);
}
