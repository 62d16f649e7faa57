//! The reference of the live tests: set (typed, a waypoint) or averaged from good fixes, and the accuracy
//! test against it; the drift and cone tests' statistics "against the reference". The statistics are
//! [`crate::accuracy`]'s, on the same recordings and clocks as the other tests.

use super::{FieldTests, LiveFix, Phase, Recording};
use crate::accuracy::{self, AccuracyStats, Reference};
use crate::geo::LatLon;

/// Default averaging window of a reference [s] (5 min).
pub const DEFAULT_AVERAGING_S: f64 = 300.0;
/// Longest averaging window [s] (1 h).
pub const MAX_AVERAGING_S: f64 = 3600.0;
/// Default duration of the accuracy test [s] (10 min).
pub const DEFAULT_ACCURACY_TARGET_S: f64 = 600.0;
/// Longest accuracy test [s] (1 h: the statistics are recomputed on every fix, and memory stays bounded).
pub const MAX_ACCURACY_TARGET_S: f64 = 3600.0;

/// A reference being averaged from the good fixes of a window.
#[derive(Debug, Clone)]
pub struct AveragingRun {
    /// Where it is (`Done` once the reference is set from it).
    pub phase: Phase,
    /// The window [s].
    pub target_s: f64,
    rec: Recording,
    /// Fixes passed over as not good enough (no 3-D or corrected fix).
    pub skipped: usize,
    /// Why no reference came of it.
    pub error: Option<String>,
}

impl AveragingRun {
    pub(super) fn new() -> Self {
        Self {
            phase: Phase::Idle,
            target_s: DEFAULT_AVERAGING_S,
            rec: Recording::default(),
            skipped: 0,
            error: None,
        }
    }

    /// Good fixes averaged so far.
    pub fn fixes(&self) -> usize {
        self.rec.fixes().len()
    }

    /// Time averaged so far [s].
    pub fn elapsed_s(&self) -> f64 {
        self.rec.elapsed_s()
    }
}

/// The accuracy test: every fix against the reference, live.
#[derive(Debug, Clone)]
pub struct AccuracyRun {
    /// Where it is.
    pub phase: Phase,
    /// Duration target [s]; reaching it ends the test.
    pub target_s: f64,
    rec: Recording,
    /// The statistics of the fixes so far against the reference.
    pub stats: Option<AccuracyStats>,
    /// Why there are no statistics.
    pub error: Option<String>,
    /// Bumped whenever the data changes.
    pub revision: u64,
}

impl AccuracyRun {
    pub(super) fn new() -> Self {
        Self {
            phase: Phase::Idle,
            target_s: DEFAULT_ACCURACY_TARGET_S,
            rec: Recording::default(),
            stats: None,
            error: None,
            revision: 0,
        }
    }

    /// The recorded fixes.
    pub fn recording(&self) -> &Recording {
        &self.rec
    }

    /// Time recorded [s].
    pub fn elapsed_s(&self) -> f64 {
        self.rec.elapsed_s()
    }
}

impl FieldTests {
    /// The reference the tests are measured against, if set.
    pub fn reference(&self) -> Option<&Reference> {
        self.reference.as_ref()
    }

    /// Sets (or clears) the reference: every statistic against it is recomputed, a running test goes on.
    /// A reference at an invalid position is refused.
    pub fn set_reference(&mut self, reference: Option<Reference>) -> Result<(), String> {
        if let Some(r) = &reference {
            LatLon::new(r.pos.lat_deg, r.pos.lon_deg).validated().map_err(|e| format!("reference: {e}"))?;
            if !(r.uncertainty_m.is_finite() && r.uncertainty_m >= 0.0) {
                return Err("reference: the uncertainty must be a non-negative number of metres".into());
            }
        }
        self.reference = reference;
        if self.accuracy.phase == Phase::Running && self.reference.is_none() {
            self.accuracy.phase = Phase::Ended("reference cleared");
        }
        self.recompute();
        Ok(())
    }

    /// Starts averaging a reference over the next [`AveragingRun::target_s`] of good fixes (discarding a
    /// previous averaging). The reference is set when the window is full or at [`Self::finish_averaging`].
    pub fn start_averaging(&mut self) {
        self.averaging.target_s = self.averaging.target_s.clamp(1.0, MAX_AVERAGING_S);
        self.averaging.phase = Phase::Running;
        self.averaging.rec.clear();
        self.averaging.skipped = 0;
        self.averaging.error = None;
    }

    /// Ends the averaging now and sets the reference from the fixes so far.
    pub fn finish_averaging(&mut self) {
        if self.averaging.phase != Phase::Running {
            return;
        }
        let samples = self.averaging.rec.accuracy_samples();
        let from_s = samples.first().map_or(0.0, |s| s.t_s);
        // A microsecond of slack: the last fix is inside the window whatever the rounding of `from + span`.
        let window_s = self.averaging.rec.elapsed_s() + 1e-6;
        self.averaging.phase = Phase::Done;
        match accuracy::average_reference(&samples, from_s, window_s, self.earth) {
            Ok(r) => {
                // The mean of valid positions is valid: this cannot be refused.
                let _ = self.set_reference(Some(r));
            }
            Err(e) => self.averaging.error = Some(e.to_string()),
        }
    }

    /// Abandons the averaging (no reference is set).
    pub fn cancel_averaging(&mut self) {
        if self.averaging.phase == Phase::Running {
            self.averaging.phase = Phase::Idle;
            self.averaging.rec.clear();
        }
    }

    /// Starts a new accuracy test (needs a reference; discards the previous test).
    pub fn start_accuracy(&mut self) -> Result<(), String> {
        if self.reference.is_none() {
            return Err("set a reference first".into());
        }
        let a = &mut self.accuracy;
        a.target_s = a.target_s.clamp(1.0, MAX_ACCURACY_TARGET_S);
        a.phase = Phase::Running;
        a.rec.clear();
        a.stats = None;
        a.error = None;
        a.revision += 1;
        Ok(())
    }

    /// Stops the accuracy test; its results stay.
    pub fn stop_accuracy(&mut self) {
        if self.accuracy.phase == Phase::Running {
            self.accuracy.phase = Phase::Done;
        }
    }

    /// Feeds the averaging and the accuracy test; false when a running one refused the fix (time going
    /// backwards on its clock).
    pub(super) fn push_reference_runs(&mut self, fix: &LiveFix, pos: LatLon) -> bool {
        let mut taken = true;
        if self.averaging.phase == Phase::Running {
            if !fix.good {
                self.averaging.skipped += 1;
            } else if !self.averaging.rec.push(fix, pos) {
                taken = false;
            } else if self.averaging.rec.elapsed_s() >= self.averaging.target_s {
                self.finish_averaging();
            }
        }
        if self.accuracy.phase == Phase::Running {
            if self.accuracy.rec.push(fix, pos) {
                self.accuracy.revision += 1;
                self.update_accuracy_stats();
                if self.accuracy.rec.elapsed_s() >= self.accuracy.target_s {
                    self.accuracy.phase = Phase::Done;
                }
            } else {
                taken = false;
            }
        }
        taken
    }

    /// The source ended, changed or jumped: an averaging is abandoned (its window no longer continues) and
    /// a running accuracy test ends, its results kept.
    pub(super) fn end_reference_runs(&mut self, why: &'static str) {
        if self.averaging.phase == Phase::Running {
            self.averaging.phase = Phase::Ended(why);
            self.averaging.error = Some(format!("averaging abandoned: {why}"));
        }
        if self.accuracy.phase == Phase::Running {
            self.accuracy.phase = Phase::Ended(why);
            self.accuracy.revision += 1;
        }
    }

    pub(super) fn update_accuracy_stats(&mut self) {
        let a = &mut self.accuracy;
        match (&self.reference, a.rec.is_empty()) {
            (Some(r), false) => match accuracy::accuracy(&a.rec.accuracy_samples(), r, self.earth) {
                Ok(s) => {
                    a.stats = Some(s);
                    a.error = None;
                }
                Err(e) => {
                    a.stats = None;
                    a.error = Some(e.to_string());
                }
            },
            _ => a.stats = None,
        }
    }

    /// A recording against the reference (`None` without reference or fixes).
    pub(super) fn against_reference(&self, rec: &Recording) -> Option<Result<AccuracyStats, String>> {
        let r = self.reference.as_ref()?;
        if rec.is_empty() {
            return None;
        }
        Some(accuracy::accuracy(&rec.accuracy_samples(), r, self.earth).map_err(|e| e.to_string()))
    }

    /// The cone marks against where the cones stand (the reference is the first cone; the line bearing and
    /// spacing are the cone statistics').
    pub(super) fn cones_against_reference(&self) -> Option<Result<AccuracyStats, String>> {
        let r = self.reference.as_ref()?;
        let s = self.cones.stats.as_ref()?;
        Some(
            accuracy::cones_against_reference(
                &self.cones.marks,
                r,
                s.line_bearing_deg,
                s.spacing_m,
                self.earth,
            )
            .map_err(|e| e.to_string()),
        )
    }
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;

    use super::*;
    use crate::geo::Earth;

    const C: LatLon = LatLon::new(42.3575, -71.1010);

    fn fix(t_s: f64, p: LatLon, height_m: Option<f64>, good: bool) -> LiveFix {
        LiveFix {
            arrival_s: t_s,
            tod_s: Some(36_000.0 + t_s),
            lat_deg: p.lat_deg,
            lon_deg: p.lon_deg,
            speed_m_s: Some(0.0),
            height_m,
            good,
        }
    }

    /// An averaged reference: the mean of the good fixes only (a circle's centre, closed form), its
    /// uncertainty their DRMS about it (the radius), its height their mean; bad fixes are passed over.
    #[test]
    fn averaging_sets_the_mean_of_the_good_fixes() {
        let mut t = FieldTests::new();
        t.averaging.target_s = 34.0; // ends on the 35th good fix: whole turns of the circle
        t.start_averaging();
        for k in 0..40 {
            let good = k % 4 != 3;
            // The bad fixes are 50 m off: they must not pull the mean.
            let p = if good {
                Earth::Wgs84.direct(C, 120.0 * f64::from(k % 4), 2.0)
            } else {
                Earth::Wgs84.direct(C, 0.0, 50.0)
            };
            t.push_fix(&fix(f64::from(k), p, Some(10.0 + f64::from(k % 4)), good));
        }
        assert_eq!(t.averaging.phase, Phase::Done);
        let r = t.reference().expect("reference set").clone();
        assert!(Earth::Wgs84.distance_m(r.pos, C) < 1e-3, "{:?}", r.pos);
        assert_relative_eq!(r.uncertainty_m, 2.0, max_relative = 1e-3);
        assert_relative_eq!(r.height_m.unwrap(), 11.0, max_relative = 1e-9);
        assert!(t.averaging.skipped >= 8);
    }

    /// The accuracy test against a typed reference: fixes east of it at known distances give the bias,
    /// the shares within each radius and the vertical error in closed form.
    #[test]
    fn accuracy_test_against_a_typed_reference() {
        let mut t = FieldTests::new();
        assert!(t.start_accuracy().is_err(), "no reference yet");
        let reference = Reference { height_m: Some(100.0), ..Reference::typed(C, 0.01) };
        t.set_reference(Some(reference)).unwrap();
        t.start_accuracy().unwrap();
        let east = [0.05, 0.3, 0.8, 1.5, 3.0, 6.0];
        for (k, d) in east.iter().enumerate() {
            let p = Earth::Wgs84.direct(C, 90.0, *d);
            t.push_fix(&fix(k as f64, p, Some(100.5), true));
        }
        let s = t.accuracy.stats.as_ref().expect("statistics");
        assert_eq!(s.fixes, 6);
        let mean_east = east.iter().sum::<f64>() / 6.0;
        assert_relative_eq!(s.bias_en_m[0], mean_east, max_relative = 1e-6);
        assert!(s.bias_en_m[1].abs() < 1e-6);
        for (k, r) in [0.1, 0.5, 1.0, 2.0, 5.0].iter().enumerate() {
            assert_relative_eq!(s.share_within(*r).unwrap(), (k + 1) as f64 / 6.0);
        }
        let v = s.vertical.as_ref().expect("vertical");
        assert_relative_eq!(v.bias_m, 0.5, max_relative = 1e-9);
        // The drift test runs on with it: its fixes against the reference too.
        t.start_drift();
        t.push_fix(&fix(10.0, Earth::Wgs84.direct(C, 0.0, 1.0), None, true));
        let d = t.drift.against.as_ref().expect("against").as_ref().unwrap();
        assert_relative_eq!(d.bias_en_m[1], 1.0, max_relative = 1e-6);
        t.source_changed();
        assert_eq!(t.accuracy.phase, Phase::Ended(super::super::SOURCE_CHANGED));
    }

    /// Cone marks against the cones: the reference is the first cone, the others every spacing along the
    /// line; a mark 1 m to the side of its cone is 1 m off.
    #[test]
    fn cone_marks_against_their_cones() {
        let mut t = FieldTests::new();
        t.set_reference(Some(Reference::typed(C, 0.0))).unwrap();
        t.cones.use_bearing = true;
        t.cones.bearing_deg = 0.0;
        t.push_fix(&fix(0.0, C, None, true));
        t.start_cones();
        for k in 0..3 {
            let cone = Earth::Wgs84.direct(C, 0.0, 10.0 * f64::from(k));
            let p = if k == 1 { Earth::Wgs84.direct(cone, 90.0, 1.0) } else { cone };
            t.push_fix(&fix(1.0 + 10.0 * f64::from(k), p, None, true));
            t.mark_cone().unwrap();
        }
        let s = t.cones.against.as_ref().expect("against").as_ref().unwrap();
        assert_eq!(s.fixes, 3);
        assert_relative_eq!(s.max_m, 1.0, max_relative = 1e-6);
        assert!(s.error_m[0] < 1e-6 && s.error_m[2] < 1e-6, "{:?}", s.error_m);
    }
}
