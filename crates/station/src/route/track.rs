//! The wearer's track: every position, in segments split where the wearer cannot have walked the step
//! (a GPS source change, a replay seek, a teleport), bounded in memory.

use std::time::Instant;

use vestnav_core::geo::{Earth, LatLon};
use vestnav_device::gps::Fix;
use vestnav_device::route_file::TrackPoint;

/// Fastest the wearer can plausibly move between two fixes [m/s]: a run (walking is ~1.4 m/s), so that a
/// hurried wearer never splits the track but a teleport does.
pub const TRACK_MAX_SPEED_M_S: f64 = 5.0;
/// Jump every step is allowed on top of [`TRACK_MAX_SPEED_M_S`] [m]: GPS error (a `SiRF` receiver's multipath
/// hop is tens of metres), and the step between two fixes whose timestamps are missing or equal.
pub const TRACK_JUMP_SLACK_M: f64 = 50.0;
/// Track points kept (55 h at 1 Hz, 5.5 h at 10 Hz); beyond it the oldest tenth is let go (and counted).
/// The session log keeps every fix; this is what the map draws and exports.
pub const TRACK_MAX_POINTS: usize = 200_000;

/// Whether the step from `a` to `b` is one the wearer can have walked in `dt_s` seconds: the rule that splits
/// the track into segments.
///
/// Plausible when `distance_m(a, b) <= TRACK_JUMP_SLACK_M + TRACK_MAX_SPEED_M_S * dt_s` (negative or unknown
/// `dt_s` counts as 0: only the slack is allowed). Distances on the WGS84 ellipsoid.
pub fn plausible_step(a: (f64, f64), b: (f64, f64), dt_s: f64) -> bool {
    let d = Earth::Wgs84.distance_m(LatLon::new(a.0, a.1), LatLon::new(b.0, b.1));
    let dt_s = if dt_s.is_finite() { dt_s.max(0.0) } else { 0.0 };
    d <= TRACK_JUMP_SLACK_M + TRACK_MAX_SPEED_M_S * dt_s
}

/// When and where the newest track point was taken.
#[derive(Debug, Clone, Copy)]
struct TrackStamp {
    at: (f64, f64),
    time: Option<chrono::DateTime<chrono::Utc>>,
    received_at: Option<Instant>,
}

/// The time between two fixes for the walking rule [s]: from the receiver's UTC when both carry it (true
/// time also in a fast replay), else from the instants their bytes arrived, else 0.
fn fix_dt_s(prev: &TrackStamp, f: &Fix) -> f64 {
    match ((prev.time, f.time), (prev.received_at, f.received_at)) {
        ((Some(a), Some(b)), _) => (b - a).num_milliseconds() as f64 / 1000.0,
        (_, (Some(a), Some(b))) => b.saturating_duration_since(a).as_secs_f64(),
        _ => 0.0,
    }
}

/// The wearer's track (see the module doc).
#[derive(Debug, Clone, Default)]
pub struct Track {
    points: Vec<TrackPoint>,
    /// Indices into `points` where a new segment starts.
    breaks: Vec<usize>,
    last: Option<TrackStamp>,
    /// Points let go beyond [`TRACK_MAX_POINTS`].
    dropped: u64,
}

impl Track {
    /// Appends the position of `fix`, starting a new segment when the step from the previous point is not
    /// one a walker can make in the time between them ([`plausible_step`]). A fix without a finite
    /// position is ignored.
    pub fn push(&mut self, fix: &Fix) {
        let (Some(lat_deg), Some(lon_deg)) = (fix.lat_deg, fix.lon_deg) else { return };
        if !(lat_deg.is_finite() && lon_deg.is_finite()) {
            return;
        }
        let at = (lat_deg, lon_deg);
        if let Some(prev) = &self.last
            && !plausible_step(prev.at, at, fix_dt_s(prev, fix))
        {
            self.break_segment();
        }
        if self.points.len() >= TRACK_MAX_POINTS {
            self.let_go(TRACK_MAX_POINTS / 10);
        }
        self.points.push(TrackPoint {
            lat_deg,
            lon_deg,
            ele_m: fix.alt_m.filter(|a| a.is_finite()),
            time: fix.time,
        });
        self.last = Some(TrackStamp { at, time: fix.time, received_at: fix.received_at });
    }

    /// Ends the current segment: the next point starts a new one (the GPS source changed).
    pub fn break_segment(&mut self) {
        let n = self.points.len();
        if n > 0 && self.breaks.last() != Some(&n) {
            self.breaks.push(n);
        }
        self.last = None;
    }

    /// Lets the oldest `n` points go.
    fn let_go(&mut self, n: usize) {
        let n = n.min(self.points.len());
        self.points.drain(..n);
        self.breaks.retain(|b| *b > n);
        for b in &mut self.breaks {
            *b -= n;
        }
        self.dropped += n as u64;
    }

    /// Every point, all segments one after the other.
    pub fn points(&self) -> &[TrackPoint] {
        &self.points
    }

    /// Where segments start (indices into [`Self::points`]).
    pub fn breaks(&self) -> &[usize] {
        &self.breaks
    }

    /// The segments, oldest first, none empty.
    pub fn segments(&self) -> Vec<&[TrackPoint]> {
        segments(&self.points, &self.breaks).filter_map(|r| self.points.get(r)).collect()
    }

    /// Points let go beyond [`TRACK_MAX_POINTS`] this session.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }
}

/// The index ranges of the segments of a track of `n` points split at `breaks` (ascending), none empty.
pub fn segments<T>(track: &[T], breaks: &[usize]) -> impl Iterator<Item = std::ops::Range<usize>> + use<T> {
    let n = track.len();
    let breaks = breaks.to_vec();
    let starts: Vec<usize> = std::iter::once(0).chain(breaks.iter().copied().filter(|&b| b < n)).collect();
    let ends: Vec<usize> = breaks.iter().copied().filter(|&b| b < n).chain(std::iter::once(n)).collect();
    starts.into_iter().zip(ends).filter(|(a, b)| a < b).map(|(a, b)| a..b)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fix_at(lat: f64, lon: f64, t_s: i64) -> Fix {
        Fix {
            lat_deg: Some(lat),
            lon_deg: Some(lon),
            time: chrono::DateTime::from_timestamp(1_700_000_000 + t_s, 0),
            ..Fix::default()
        }
    }

    #[test]
    fn the_track_splits_at_jumps_and_source_changes() {
        let mut t = Track::default();
        t.push(&fix_at(42.0, -71.0, 0));
        t.push(&fix_at(42.00001, -71.0, 1));
        // 11 km in one second: a new segment.
        t.push(&fix_at(42.1, -71.0, 2));
        t.break_segment();
        t.push(&fix_at(42.1, -71.0, 3));
        let segs = t.segments();
        assert_eq!(segs.iter().map(|s| s.len()).collect::<Vec<_>>(), vec![2, 1, 1]);
    }

    #[test]
    fn the_track_is_bounded_and_keeps_its_segments_right() {
        let mut t = Track::default();
        for k in 0..(TRACK_MAX_POINTS + 5) {
            if k == TRACK_MAX_POINTS - 3 {
                t.break_segment();
            }
            t.push(&fix_at(42.0, -71.0, i64::try_from(k).unwrap()));
        }
        assert!(t.points().len() <= TRACK_MAX_POINTS);
        assert_eq!(t.dropped() as usize + t.points().len(), TRACK_MAX_POINTS + 5);
        let lens: Vec<usize> = t.segments().iter().map(|s| s.len()).collect();
        assert_eq!(*lens.last().unwrap(), 8, "{lens:?}");
    }
}
