//! GPS accuracy field tests (thesis §5): stationary drift and the cone test, as pure statistics over fixes.
//!
//! **Drift** (thesis Fig 65): a receiver lies still; each fix's distance from the first fix (the thesis's
//! figure, max 1.17 m over 3 min) and from the mean position; CEP50/CEP95, DRMS and 2DRMS of the scatter
//! about the mean. **Cone test** (Figs 67–70): cones every `spacing` metres on a line; the operator marks each
//! cone; the distances between consecutive marks are compared with the spacing (mean, RMSE), split into
//! along-line and cross-line components. Both warn when the receiver looks *pinned* (`SiRF` "static
//! navigation": the same position repeated while standing or walking slowly), which flatters a drift test
//! and distorts cone marks.
//!
//! Percentiles are **nearest-rank**: the p-th percentile of n sorted values `x_1 <= ... <= x_n` is
//! `x_k` with `k = ceil(p/100 * n)` (k >= 1) — always a measured value, never interpolated.
//!
//! ```
//! use vestnav_core::fieldtest::{drift, TimedFix};
//! use vestnav_core::geo::{Earth, LatLon};
//! let c = LatLon::new(42.3575, -71.1010);
//! // Eight fixes on a 2 m circle around c: CEP50 = DRMS = 2 m.
//! let fixes: Vec<_> = (0..8)
//!     .map(|i| TimedFix { t_s: f64::from(i), pos: Earth::Wgs84.direct(c, 45.0 * f64::from(i), 2.0) })
//!     .collect();
//! let s = drift(&fixes, Earth::Wgs84).unwrap();
//! assert!((s.cep50_m - 2.0).abs() < 1e-6 && (s.drms_m - 2.0).abs() < 1e-6);
//! ```

use glam::DVec2;
use serde::{Deserialize, Serialize};

use crate::geo::{Earth, LatLon, LocalFrame, bearing_of_enu_deg};

/// Errors of the field-test statistics.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FieldTestError {
    /// Fewer data than the statistic needs.
    #[error("not enough data: {what} (have {have}, need {need})")]
    TooFew {
        /// What is counted.
        what: &'static str,
        /// How many there are.
        have: usize,
        /// How many are needed.
        need: usize,
    },
    /// A setting that is not a positive finite number.
    #[error("invalid setting: {0}")]
    BadSetting(&'static str),
}

/// One fix with its time [s] (any origin; only differences are used).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TimedFix {
    /// Time [s].
    pub t_s: f64,
    /// Position.
    pub pos: LatLon,
}

impl TimedFix {
    /// Whether the fix can be used: finite time, finite latitude in [-90, 90] and longitude in [-180, 180].
    /// The statistics skip (and count) the others, so one absurd fix never poisons a session.
    pub fn is_valid(&self) -> bool {
        let (lat, lon) = (self.pos.lat_deg, self.pos.lon_deg);
        self.t_s.is_finite() && lat.is_finite() && lon.is_finite() && lat.abs() <= 90.0 && lon.abs() <= 180.0
    }
}

/// Runs of identical consecutive positions (static-navigation pinning).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PinningReport {
    /// Fixes equal to the previous fix (same latitude and longitude to 1e-9 deg, ~0.1 mm).
    pub repeated_fixes: usize,
    /// `repeated_fixes / (fixes - 1)`.
    pub repeated_fraction: f64,
    /// Longest run of identical consecutive fixes (fixes in the run).
    pub longest_run: usize,
    /// Time span of that run [s].
    pub longest_run_s: f64,
    /// Start time of that run [s].
    pub longest_run_start_s: f64,
}

/// Finds runs of identical consecutive positions in `fixes`.
pub fn pinning(fixes: &[TimedFix]) -> PinningReport {
    let same =
        |a: LatLon, b: LatLon| (a.lat_deg - b.lat_deg).abs() < 1e-9 && (a.lon_deg - b.lon_deg).abs() < 1e-9;
    let mut repeated = 0;
    let (mut best_len, mut best_start, mut best_end) = (usize::from(!fixes.is_empty()), 0usize, 0usize);
    let mut run_start = 0;
    for i in 1..fixes.len() {
        if same(fixes[i].pos, fixes[i - 1].pos) {
            repeated += 1;
            let len = i - run_start + 1;
            if len > best_len {
                (best_len, best_start, best_end) = (len, run_start, i);
            }
        } else {
            run_start = i;
        }
    }
    let span = |a: usize, b: usize| fixes.get(b).zip(fixes.get(a)).map_or(0.0, |(y, x)| y.t_s - x.t_s);
    PinningReport {
        repeated_fixes: repeated,
        repeated_fraction: if fixes.len() > 1 { repeated as f64 / (fixes.len() - 1) as f64 } else { 0.0 },
        longest_run: best_len,
        longest_run_s: span(best_start, best_end),
        longest_run_start_s: fixes.get(best_start).map_or(0.0, |f| f.t_s),
    }
}

/// Nearest-rank percentile of `values` (`p` in 0..=100): `x_k`, `k = max(1, ceil(p n / 100))` of the sorted
/// values. `None` when empty.
pub fn percentile_nearest_rank(values: &[f64], p: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    // A tiny tolerance keeps exact products like 0.5 * 8 = 4 from rounding up to 5.
    let k = ((p.clamp(0.0, 100.0) / 100.0 * n as f64) - 1e-9).ceil().max(1.0) as usize;
    v.get(k.min(n) - 1).copied()
}

/// Results of a stationary drift test.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DriftStats {
    /// Number of fixes used.
    pub fixes: usize,
    /// Fixes skipped as invalid (non-finite time or position, position out of range).
    pub skipped_invalid: usize,
    /// Time from the first to the last fix [s].
    pub duration_s: f64,
    /// The first fix.
    pub first: LatLon,
    /// The mean position (mean of east/north about the first fix, mapped back).
    pub mean: LatLon,
    /// Largest distance of a fix from the first fix [m] (thesis Fig 65: 1.17 m).
    pub max_from_first_m: f64,
    /// Largest distance from the mean [m].
    pub max_from_mean_m: f64,
    /// Median (nearest-rank P50) distance from the mean [m].
    pub cep50_m: f64,
    /// P95 (nearest-rank) distance from the mean [m].
    pub cep95_m: f64,
    /// DRMS = sqrt(mean of squared distances from the mean) [m].
    pub drms_m: f64,
    /// 2DRMS = 2 DRMS [m].
    pub twodrms_m: f64,
    /// Standard deviation of east and north about the mean [m] (population, 1/n).
    pub sigma_en_m: [f64; 2],
    /// Time of each fix relative to the first [s].
    pub t_s: Vec<f64>,
    /// Distance of each fix from the first [m].
    pub from_first_m: Vec<f64>,
    /// Distance of each fix from the mean [m].
    pub from_mean_m: Vec<f64>,
    /// East/north of each fix about the mean [m] (for the scatter plot).
    pub en_about_mean_m: Vec<DVec2>,
    /// Pinning (static navigation) report.
    pub pinning: PinningReport,
    /// Warnings for the operator (e.g. the receiver looks pinned).
    pub warnings: Vec<String>,
}

/// Drift statistics of a stationary session (thesis §5, Fig 65).
///
/// With `e_i` the east/north of fix i in a local frame ([`LocalFrame`]) about the first fix, the mean is
/// `m = (1/n) sum e_i`; `r_i = |p_i - mean|` is the geodesic distance from the mean (frame re-centred on it);
/// `DRMS = sqrt((1/n) sum r_i^2)`, `2DRMS = 2 DRMS`, `CEP50 = P50(r)`, `CEP95 = P95(r)` (measured, nearest-rank,
/// see the module doc); distances from the first fix are geodesic on `earth`. Invalid fixes (see
/// [`TimedFix::is_valid`]) are skipped and counted in [`DriftStats::skipped_invalid`].
pub fn drift(fixes: &[TimedFix], earth: Earth) -> Result<DriftStats, FieldTestError> {
    let all = fixes.len();
    let fixes: Vec<TimedFix> = fixes.iter().copied().filter(TimedFix::is_valid).collect();
    let skipped_invalid = all - fixes.len();
    let [first, ..] = fixes.as_slice() else {
        return Err(FieldTestError::TooFew { what: "fixes", have: 0, need: 1 });
    };
    let n = fixes.len() as f64;
    let frame0 = LocalFrame::new(first.pos, earth);
    let mean_en = fixes.iter().map(|f| frame0.enu_from_wgs84(f.pos)).sum::<DVec2>() / n;
    let mean = frame0.wgs84_from_enu(mean_en);
    let frame = LocalFrame::new(mean, earth);
    let en: Vec<DVec2> = fixes.iter().map(|f| frame.enu_from_wgs84(f.pos)).collect();
    let from_mean: Vec<f64> = en.iter().map(|v| v.length()).collect();
    let from_first: Vec<f64> = fixes.iter().map(|f| earth.distance_m(first.pos, f.pos)).collect();
    let drms = (from_mean.iter().map(|r| r * r).sum::<f64>() / n).sqrt();
    let centre = en.iter().sum::<DVec2>() / n;
    let var = en.iter().map(|v| (*v - centre) * (*v - centre)).sum::<DVec2>() / n;
    let pin = pinning(&fixes);
    let mut warnings = Vec::new();
    if skipped_invalid > 0 {
        warnings
            .push(format!("{skipped_invalid} invalid fixes skipped (non-finite or out-of-range position)"));
    }
    if fixes.len() > 2 && pin.repeated_fraction > 0.5 {
        warnings.push(format!(
            "receiver looks pinned: {:.0} % of fixes repeat the previous position exactly (longest run {} fixes, \
             {:.0} s): SiRF static navigation (or a coarse output resolution) flatters a drift test",
            100.0 * pin.repeated_fraction,
            pin.longest_run,
            pin.longest_run_s
        ));
    }
    Ok(DriftStats {
        fixes: fixes.len(),
        skipped_invalid,
        duration_s: fixes.last().map_or(0.0, |l| l.t_s - first.t_s),
        first: first.pos,
        mean,
        max_from_first_m: from_first.iter().copied().fold(0.0, f64::max),
        max_from_mean_m: from_mean.iter().copied().fold(0.0, f64::max),
        cep50_m: percentile_nearest_rank(&from_mean, 50.0).unwrap_or(0.0),
        cep95_m: percentile_nearest_rank(&from_mean, 95.0).unwrap_or(0.0),
        drms_m: drms,
        twodrms_m: 2.0 * drms,
        sigma_en_m: [var.x.sqrt(), var.y.sqrt()],
        t_s: fixes.iter().map(|f| f.t_s - first.t_s).collect(),
        from_first_m: from_first,
        from_mean_m: from_mean,
        en_about_mean_m: en,
        pinning: pin,
        warnings,
    })
}

/// An operator's mark (a cone reached), with the position recorded for it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConeMark {
    /// Time of the mark [s].
    pub t_s: f64,
    /// Label (e.g. "cone 3").
    pub label: String,
    /// Position recorded for the mark.
    pub pos: LatLon,
}

/// The receiver's position at a mark time: the latest fix at or before `t_s` (what a live console records
/// when the key is pressed); the first fix after it if none precedes. Invalid fixes
/// ([`TimedFix::is_valid`]) are passed over. `None` when the track has no valid fix.
pub fn position_at(track: &[TimedFix], t_s: f64) -> Option<LatLon> {
    let mut valid = track.iter().filter(|f| f.is_valid());
    valid.clone().rev().find(|f| f.t_s <= t_s).or_else(|| valid.find(|f| f.t_s > t_s)).map(|f| f.pos)
}

/// Settings of a cone test.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ConeConfig {
    /// Nominal distance between consecutive cones [m] (thesis: 10 m).
    pub spacing_m: f64,
    /// Expected number of cones (thesis: 10); a different mark count is reported as a warning.
    pub count: Option<usize>,
    /// True bearing of the cone line [deg]; `None` = from the first mark to the last.
    pub line_bearing_deg: Option<f64>,
    /// Earth model of the distances.
    pub earth: Earth,
    /// A track run of identical fixes at least this long [s] while marks advance warns of pinning (default
    /// 5 s).
    pub pinned_run_s: f64,
}

impl ConeConfig {
    /// Thesis defaults: 10 m spacing, WGS-84, line from the marks, no expected count.
    pub fn with_spacing(spacing_m: f64) -> Self {
        Self { spacing_m, count: None, line_bearing_deg: None, earth: Earth::Wgs84, pinned_run_s: 5.0 }
    }
}

/// Results of a cone test.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConeStats {
    /// Number of marks used.
    pub marks: usize,
    /// Marks skipped as invalid (non-finite time or position, position out of range).
    pub skipped_invalid_marks: usize,
    /// Track fixes skipped as invalid (see [`TimedFix::is_valid`]).
    pub skipped_invalid: usize,
    /// Nominal spacing [m].
    pub spacing_m: f64,
    /// Expected cone count, if given.
    pub expected_count: Option<usize>,
    /// Bearing of the line used for the components [deg, true].
    pub line_bearing_deg: f64,
    /// Distances between consecutive marks [m] (marks - 1 values).
    pub distances_m: Vec<f64>,
    /// Smallest consecutive distance [m].
    pub min_m: f64,
    /// Largest consecutive distance [m].
    pub max_m: f64,
    /// Mean consecutive distance [m].
    pub mean_m: f64,
    /// RMSE of the consecutive distances against the spacing [m].
    pub rmse_m: f64,
    /// Along-line component of each consecutive displacement [m].
    pub along_m: Vec<f64>,
    /// Cross-line component (right of the line positive) of each consecutive displacement [m].
    pub cross_m: Vec<f64>,
    /// RMSE of the along-line components against the spacing [m].
    pub along_rmse_m: f64,
    /// RMS of the cross-line components [m] (nominally 0).
    pub cross_rms_m: f64,
    /// The first mark's position: origin of `marks_en_m`.
    pub origin: LatLon,
    /// Time of the first mark [s] (origin of `marks_t_s`).
    pub marks_t0_s: f64,
    /// East/north of each mark about the first mark [m].
    pub marks_en_m: Vec<DVec2>,
    /// Time of each mark relative to the first [s].
    pub marks_t_s: Vec<f64>,
    /// Labels of the marks.
    pub labels: Vec<String>,
    /// Warnings (pinned receiver, missing cones).
    pub warnings: Vec<String>,
}

/// Cone-test statistics (thesis §5, Figs 67–70) from the marks and (optionally) the whole track.
///
/// With mark positions `p_k` mapped to east/north about the first mark and `delta_k = p_k+1 - p_k`:
/// `d_k = |p_k+1 - p_k|` (geodesic on `earth`), `mean = (1/m) sum d_k`, `RMSE = sqrt((1/m) sum (d_k - s)^2)`
/// with `s` the spacing (the thesis's Figs 69/70 line); with `u` the unit vector of the line bearing
/// `theta` (`u = (sin theta, cos theta)`), `along_k = delta_k·u`, `cross_k = delta_k x u` (right positive).
/// Pinning warnings: two consecutive marks at the same position, or a run of identical track fixes longer
/// than `pinned_run_s` between the first and the last mark. Invalid marks and track fixes (see
/// [`TimedFix::is_valid`]) are skipped and counted.
pub fn cones(
    marks: &[ConeMark],
    track: &[TimedFix],
    config: &ConeConfig,
) -> Result<ConeStats, FieldTestError> {
    let all_marks = marks.len();
    if !(config.spacing_m.is_finite() && config.spacing_m > 0.0) {
        return Err(FieldTestError::BadSetting("spacing must be a positive number of metres"));
    }
    let marks: Vec<&ConeMark> =
        marks.iter().filter(|m| TimedFix { t_s: m.t_s, pos: m.pos }.is_valid()).collect();
    let skipped_invalid_marks = all_marks - marks.len();
    if marks.len() < 2 {
        return Err(FieldTestError::TooFew { what: "cone marks", have: marks.len(), need: 2 });
    }
    let earth = config.earth;
    let frame = LocalFrame::new(marks[0].pos, earth);
    let en: Vec<DVec2> = marks.iter().map(|m| frame.enu_from_wgs84(m.pos)).collect();
    let last_en = en[en.len() - 1];
    let line_bearing_deg = config
        .line_bearing_deg
        .filter(|b| b.is_finite())
        .map_or_else(|| bearing_of_enu_deg(last_en), crate::geo::normalize_deg);
    let th = line_bearing_deg.to_radians();
    let u = DVec2::new(th.sin(), th.cos());
    let distances: Vec<f64> = marks.windows(2).map(|w| earth.distance_m(w[0].pos, w[1].pos)).collect();
    let deltas: Vec<DVec2> = en.windows(2).map(|w| w[1] - w[0]).collect();
    let along: Vec<f64> = deltas.iter().map(|d| d.dot(u)).collect();
    let cross: Vec<f64> = deltas.iter().map(|d| d.perp_dot(u)).collect();
    let m = distances.len() as f64;
    let s = config.spacing_m;
    let rms = |it: &mut dyn Iterator<Item = f64>| (it.map(|x| x * x).sum::<f64>() / m).sqrt();

    let skipped_invalid = track.iter().filter(|f| !f.is_valid()).count();
    let mut warnings = Vec::new();
    if skipped_invalid_marks + skipped_invalid > 0 {
        warnings.push(format!(
            "skipped as invalid (non-finite or out-of-range position): {skipped_invalid_marks} marks, \
             {skipped_invalid} track fixes"
        ));
    }
    if let Some(c) = config.count.filter(|&c| c != marks.len()) {
        warnings.push(format!("{} marks for {c} cones: a cone was missed or marked twice", marks.len()));
    }
    for (k, d) in distances.iter().enumerate() {
        if *d < 1e-3 {
            warnings.push(format!(
                "marks {} and {} have the same position: the receiver looks pinned (static navigation)",
                marks[k].label,
                marks[k + 1].label
            ));
        }
    }
    let (t0, t1) = (marks[0].t_s, marks[marks.len() - 1].t_s);
    let during: Vec<TimedFix> =
        track.iter().copied().filter(|f| f.is_valid() && f.t_s >= t0 && f.t_s <= t1).collect();
    let pin = pinning(&during);
    if pin.longest_run_s >= config.pinned_run_s {
        warnings.push(format!(
            "the receiver repeated one position for {:.0} s from t = {:.0} s: static navigation pinning \
             distorts the marks (walk faster than ~1.2 m/s between cones)",
            pin.longest_run_s,
            pin.longest_run_start_s - t0
        ));
    }
    Ok(ConeStats {
        marks: marks.len(),
        skipped_invalid_marks,
        skipped_invalid,
        spacing_m: s,
        expected_count: config.count,
        line_bearing_deg,
        min_m: distances.iter().copied().fold(f64::INFINITY, f64::min),
        max_m: distances.iter().copied().fold(0.0, f64::max),
        mean_m: distances.iter().sum::<f64>() / m,
        rmse_m: rms(&mut distances.iter().map(|d| d - s)),
        along_rmse_m: rms(&mut along.iter().map(|a| a - s)),
        cross_rms_m: rms(&mut cross.iter().copied()),
        distances_m: distances,
        along_m: along,
        cross_m: cross,
        origin: marks[0].pos,
        marks_t0_s: t0,
        marks_en_m: en,
        marks_t_s: marks.iter().map(|m| m.t_s - t0).collect(),
        labels: marks.iter().map(|m| m.label.clone()).collect(),
        warnings,
    })
}

/// Seconds in a UTC day (receivers report no leap second in their time of day that matters here).
pub const DAY_S: f64 = 86_400.0;

/// Places a receiver's UTC time of day `tod_s` (seconds since midnight, in [0, 86 400]) on a running time
/// line whose previous value was `prev_s` (seconds, on the same line; `None` for the first): the one rule for
/// logs, replays and live tests that cross midnight.
///
/// Rule: the result is `tod_s + 86 400 k` with the integer `k` that puts it within half a day of `prev_s`,
/// i.e. in `[prev_s - 43 200, prev_s + 43 200)`. A receiver reports at least every few seconds, so the nearest
/// day is the right one: 23:59:59 then 00:00:00 is one second later, not 86 399 s earlier, and the day
/// count goes on growing across any number of midnights. A step back of less than half a day stays a step
/// back (a spliced log), for the caller to see. The first value is `tod_s` itself.
///
/// ```
/// use vestnav_core::fieldtest::unwrap_time_of_day;
/// let t = unwrap_time_of_day(0.5, Some(86_399.5)); // half a second past midnight
/// assert!((t - 86_400.5).abs() < 1e-9);
/// ```
pub fn unwrap_time_of_day(tod_s: f64, prev_s: Option<f64>) -> f64 {
    let Some(prev) = prev_s.filter(|p| p.is_finite()) else { return tod_s };
    let k = ((prev - DAY_S / 2.0 - tod_s) / DAY_S).ceil();
    tod_s + DAY_S * k
}

/// The receiver-time line of a stream of positioned fixes, the one rule of `fieldtest compare` on logs and
/// of the console's receivers side by side: a fix with a UTC time of day `tod_s` is placed by
/// [`unwrap_time_of_day`] after the previous fix's time `prev_s`; a fix without one counts one second after
/// the previous (0 for the first), the rate of the receivers that omit it.
///
/// ```
/// use vestnav_core::fieldtest::receiver_time_s;
/// assert!((receiver_time_s(Some(0.5), Some(86_399.5)) - 86_400.5).abs() < 1e-9);
/// assert!((receiver_time_s(None, Some(10.0)) - 11.0).abs() < 1e-9);
/// ```
pub fn receiver_time_s(tod_s: Option<f64>, prev_s: Option<f64>) -> f64 {
    match tod_s {
        Some(tod) => unwrap_time_of_day(tod, prev_s),
        None => prev_s.map_or(0.0, |p| p + 1.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    const C: LatLon = LatLon::new(42.3575, -71.1010);

    #[test]
    fn time_of_day_unwraps_at_midnight() {
        assert_relative_eq!(unwrap_time_of_day(100.0, None), 100.0);
        // Across midnight, forwards: 23:59:59 -> 00:00:01 is 2 s later.
        assert_relative_eq!(unwrap_time_of_day(1.0, Some(86_399.0)), 86_401.0);
        // Exactly at midnight.
        assert_relative_eq!(unwrap_time_of_day(0.0, Some(86_399.0)), 86_400.0);
        assert_relative_eq!(unwrap_time_of_day(86_399.0, Some(86_400.0)), 86_399.0);
        // Same day, normal steps and a short step back (a splice) stay as they are.
        assert_relative_eq!(unwrap_time_of_day(43_000.0, Some(42_999.0)), 43_000.0);
        assert_relative_eq!(unwrap_time_of_day(40_000.0, Some(42_999.0)), 40_000.0);
        // Half a day is the boundary: exactly 12 h back is still the same day, more is the next.
        assert_relative_eq!(unwrap_time_of_day(0.0, Some(43_200.0)), 0.0);
        assert_relative_eq!(unwrap_time_of_day(0.0, Some(43_200.5)), 86_400.0);
    }

    #[test]
    fn time_of_day_unwraps_across_several_days() {
        // A 1 Hz receiver logging for three and a half days from 22:00 UTC: the unwrapped time line is the
        // elapsed time, whatever the day.
        let start = 22.0 * 3600.0;
        let mut prev = None;
        for k in 0..(3 * 86_400 + 43_200) {
            let elapsed = f64::from(k);
            let tod = (start + elapsed).rem_euclid(DAY_S);
            let t = unwrap_time_of_day(tod, prev);
            assert_relative_eq!(t, start + elapsed, epsilon = 1e-6);
            prev = Some(t);
        }
        // Gaps of up to almost half a day across midnight too, in steps of 11 h.
        let mut prev = Some(20.0 * 3600.0);
        for k in 1..10 {
            let truth = 20.0 * 3600.0 + 11.0 * 3600.0 * f64::from(k);
            let t = unwrap_time_of_day(truth.rem_euclid(DAY_S), prev);
            assert_relative_eq!(t, truth, epsilon = 1e-6);
            prev = Some(t);
        }
    }

    #[test]
    fn nearest_rank_percentiles() {
        let v = [5.0, 1.0, 4.0, 2.0, 3.0];
        assert_eq!(percentile_nearest_rank(&v, 50.0), Some(3.0));
        assert_eq!(percentile_nearest_rank(&v, 95.0), Some(5.0));
        assert_eq!(percentile_nearest_rank(&v, 0.0), Some(1.0));
        assert_eq!(percentile_nearest_rank(&v, 20.0), Some(1.0));
        assert_eq!(percentile_nearest_rank(&v, 21.0), Some(2.0));
        let ten: Vec<f64> = (1..=10).map(f64::from).collect();
        assert_eq!(percentile_nearest_rank(&ten, 50.0), Some(5.0));
        assert_eq!(percentile_nearest_rank(&ten, 95.0), Some(10.0));
        assert_eq!(percentile_nearest_rank(&[], 50.0), None);
    }

    #[test]
    fn circle_about_the_mean_gives_cep_and_drms_equal_to_the_radius() {
        for earth in [Earth::Wgs84, Earth::ThesisSphere] {
            let r = 3.0;
            let fixes: Vec<TimedFix> = (0..36)
                .map(|i| TimedFix { t_s: f64::from(i), pos: earth.direct(C, 10.0 * f64::from(i), r) })
                .collect();
            let s = drift(&fixes, earth).unwrap();
            assert_relative_eq!(s.cep50_m, r, max_relative = 1e-6);
            assert_relative_eq!(s.cep95_m, r, max_relative = 1e-6);
            assert_relative_eq!(s.drms_m, r, max_relative = 1e-6);
            assert_relative_eq!(s.twodrms_m, 2.0 * r, max_relative = 1e-6);
            // Farthest from the first point (on the circle) is the opposite point: 2 r.
            assert_relative_eq!(s.max_from_first_m, 2.0 * r, max_relative = 1e-6);
            assert!(earth.distance_m(s.mean, C) < 1e-6);
            // sigma per axis of a uniform circle = r / sqrt 2.
            assert_relative_eq!(s.sigma_en_m[0], r / 2f64.sqrt(), max_relative = 1e-6);
            assert!(s.warnings.is_empty());
        }
    }

    #[test]
    fn known_radii_give_known_percentiles_and_drms() {
        // Symmetric pairs at radii 1..=10 m about C (each radius in two opposite directions): the mean is C,
        // the 20 distances are 1,1,2,2,...,10,10. P50 = 5, P95 = 10, DRMS = sqrt(mean k^2) = sqrt(38.5).
        let mut fixes = Vec::new();
        for k in 1..=10 {
            let brg = 17.0 * f64::from(k);
            fixes.push(TimedFix { t_s: 0.0, pos: Earth::Wgs84.direct(C, brg, f64::from(k)) });
            fixes.push(TimedFix { t_s: 0.0, pos: Earth::Wgs84.direct(C, brg + 180.0, f64::from(k)) });
        }
        let s = drift(&fixes, Earth::Wgs84).unwrap();
        assert_relative_eq!(s.cep50_m, 5.0, max_relative = 1e-6);
        assert_relative_eq!(s.cep95_m, 10.0, max_relative = 1e-6);
        assert_relative_eq!(s.drms_m, 38.5f64.sqrt(), max_relative = 1e-6);
    }

    #[test]
    fn pinned_drift_warns() {
        let fixes: Vec<TimedFix> = (0..10).map(|i| TimedFix { t_s: f64::from(i), pos: C }).collect();
        let s = drift(&fixes, Earth::Wgs84).unwrap();
        assert_eq!(s.pinning.longest_run, 10);
        assert_relative_eq!(s.pinning.longest_run_s, 9.0);
        assert_eq!(s.warnings.len(), 1);
        assert!(s.max_from_first_m.abs() < 1e-9);
        assert!(drift(&[], Earth::Wgs84).is_err());
    }

    fn line_marks(dists: &[f64], cross_offsets: &[f64], bearing_deg: f64) -> Vec<ConeMark> {
        let mut along = 0.0;
        let mut out = Vec::new();
        for (k, off) in cross_offsets.iter().enumerate() {
            if k > 0 {
                along += dists[k - 1];
            }
            let on_line = Earth::Wgs84.direct(C, bearing_deg, along);
            let pos = Earth::Wgs84.direct(on_line, bearing_deg + 90.0, *off);
            out.push(ConeMark { t_s: 10.0 * k as f64, label: format!("cone {}", k + 1), pos });
        }
        out
    }

    #[test]
    fn exact_cones_have_zero_error() {
        let marks = line_marks(&[10.0; 9], &[0.0; 10], 15.4);
        let cfg =
            ConeConfig { count: Some(10), line_bearing_deg: Some(15.4), ..ConeConfig::with_spacing(10.0) };
        let s = cones(&marks, &[], &cfg).unwrap();
        assert_eq!(s.distances_m.len(), 9);
        assert!(s.rmse_m < 1e-6 && s.cross_rms_m < 1e-6 && s.along_rmse_m < 1e-6, "{s:?}");
        assert_relative_eq!(s.mean_m, 10.0, max_relative = 1e-9);
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    }

    #[test]
    fn alternating_errors_give_closed_form_stats() {
        // Along: 8, 12, 8, 12 -> mean 10, RMSE 2. Cross offsets alternate -1/+1 m (+ = right of the line)
        // -> cross components +2, -2, +2, -2 m.
        // The marks are built along a geodesic through C, the frame is centred on the first mark 1 m off it:
        // the planar components are good to ~1e-5 relative (see LocalFrame), hence the tolerance.
        let marks = line_marks(&[8.0, 12.0, 8.0, 12.0], &[-1.0, 1.0, -1.0, 1.0, -1.0], 90.0);
        let cfg =
            ConeConfig { line_bearing_deg: Some(90.0), count: Some(10), ..ConeConfig::with_spacing(10.0) };
        let s = cones(&marks, &[], &cfg).unwrap();
        for (a, want) in s.along_m.iter().zip([8.0, 12.0, 8.0, 12.0]) {
            assert_relative_eq!(*a, want, max_relative = 1e-4);
        }
        for (c, want) in s.cross_m.iter().zip([2.0, -2.0, 2.0, -2.0]) {
            assert_relative_eq!(*c, want, max_relative = 1e-4);
        }
        assert_relative_eq!(s.along_rmse_m, 2.0, max_relative = 1e-4);
        assert_relative_eq!(s.cross_rms_m, 2.0, max_relative = 1e-4);
        // Full distances: sqrt(8^2 + 2^2), sqrt(12^2 + 2^2), ...
        let d1 = 68f64.sqrt();
        let d2 = 148f64.sqrt();
        assert_relative_eq!(s.mean_m, f64::midpoint(d1, d2), max_relative = 1e-4);
        let rmse = f64::midpoint((d1 - 10.0).powi(2), (d2 - 10.0).powi(2)).sqrt();
        assert_relative_eq!(s.rmse_m, rmse, max_relative = 1e-4);
        assert_eq!(s.warnings.len(), 1, "5 marks for 10 cones");
    }

    #[test]
    fn pinned_marks_and_tracks_warn() {
        let mut marks = line_marks(&[10.0; 3], &[0.0; 4], 0.0);
        marks[2].pos = marks[1].pos;
        let track: Vec<TimedFix> = (0..=30)
            .map(|i| TimedFix { t_s: f64::from(i), pos: if i < 20 { C } else { marks[3].pos } })
            .collect();
        let s = cones(&marks, &track, &ConeConfig::with_spacing(10.0)).unwrap();
        assert!(s.warnings.iter().any(|w| w.contains("same position")), "{:?}", s.warnings);
        assert!(s.warnings.iter().any(|w| w.contains("19 s")), "{:?}", s.warnings);
        assert!(cones(&marks[..1], &[], &ConeConfig::with_spacing(10.0)).is_err());
        assert!(cones(&marks, &[], &ConeConfig::with_spacing(f64::NAN)).is_err());
    }

    #[test]
    fn one_absurd_fix_is_skipped_and_counted_in_drift() {
        // The circle of radius 2 m (CEP50 = DRMS = 2 m) plus absurd fixes anywhere in the log.
        let mut fixes: Vec<TimedFix> = (0..8)
            .map(|i| TimedFix { t_s: f64::from(i), pos: Earth::Wgs84.direct(C, 45.0 * f64::from(i), 2.0) })
            .collect();
        fixes.insert(3, TimedFix { t_s: 2.5, pos: LatLon::new(42.3575, 500.0) });
        fixes.insert(0, TimedFix { t_s: -1.0, pos: LatLon::new(f64::NAN, -71.1) });
        fixes.push(TimedFix { t_s: f64::INFINITY, pos: C });
        fixes.push(TimedFix { t_s: 9.0, pos: LatLon::new(-91.0, 0.0) });
        let s = drift(&fixes, Earth::Wgs84).unwrap();
        assert_eq!(s.fixes, 8);
        assert_eq!(s.skipped_invalid, 4);
        assert_relative_eq!(s.cep50_m, 2.0, max_relative = 1e-6);
        assert_relative_eq!(s.drms_m, 2.0, max_relative = 1e-6);
        assert_relative_eq!(s.duration_s, 7.0);
        assert!(s.warnings.iter().any(|w| w.starts_with("4 invalid fixes skipped")), "{:?}", s.warnings);
        // Only invalid fixes: not enough data, not a panic.
        assert!(matches!(drift(&fixes[..1], Earth::Wgs84), Err(FieldTestError::TooFew { have: 0, .. })));
    }

    #[test]
    fn one_absurd_fix_or_mark_is_skipped_and_counted_in_cones() {
        let mut marks = line_marks(&[10.0; 9], &[0.0; 10], 15.4);
        marks.insert(4, ConeMark { t_s: 35.0, label: "bad".into(), pos: LatLon::new(1e300, -71.0) });
        let mut track: Vec<TimedFix> = marks.iter().map(|m| TimedFix { t_s: m.t_s, pos: m.pos }).collect();
        track.push(TimedFix { t_s: 36.0, pos: LatLon::new(42.0, -200.0) });
        let cfg =
            ConeConfig { count: Some(10), line_bearing_deg: Some(15.4), ..ConeConfig::with_spacing(10.0) };
        let s = cones(&marks, &track, &cfg).unwrap();
        assert_eq!((s.marks, s.skipped_invalid_marks, s.skipped_invalid), (10, 1, 2));
        assert!(s.rmse_m < 1e-6, "{s:?}");
        assert_relative_eq!(s.mean_m, 10.0, max_relative = 1e-9);
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        // A mark taken just after the absurd fixes (35 s, 36 s) gets the latest valid one: cone 4 at 30 s.
        assert_eq!(position_at(&track, 36.5), Some(marks[3].pos));
    }

    #[test]
    fn mark_positions_come_from_the_latest_fix() {
        let track = [
            TimedFix { t_s: 1.0, pos: LatLon::new(1.0, 0.0) },
            TimedFix { t_s: 2.0, pos: LatLon::new(2.0, 0.0) },
        ];
        assert_eq!(position_at(&track, 1.5), Some(LatLon::new(1.0, 0.0)));
        assert_eq!(position_at(&track, 0.5), Some(LatLon::new(1.0, 0.0)));
        assert_eq!(position_at(&track, 9.0), Some(LatLon::new(2.0, 0.0)));
        assert_eq!(position_at(&[], 9.0), None);
    }
}
