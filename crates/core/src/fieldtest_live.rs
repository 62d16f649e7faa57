//! The field tests run live on a stream of fixes (thesis §5): the drift and cone procedures, their time
//! base, walking detection and the live pinning warning — headless, fed fix by fix (the station feeds it
//! every fix of whatever source runs; a view only draws it). The statistics are [`crate::fieldtest`]'s.
//!
//! **Time base.** A test runs on the receiver's clock: the UTC time of day of each fix, placed on a running
//! time line by [`unwrap_time_of_day`] (the one rule across midnight), so a log replayed at x10 still
//! reports "201 fixes over 200 s". Only when the receiver sends no time are the fixes' arrival instants
//! used instead (a test falls back to them for good as soon as one of its fixes has no receiver time).
//!
//! **Sources.** Every source feeds the same runs. When the source changes ([`FieldTests::source_changed`])
//! the latest fix and the time line are forgotten (a new receiver's clock is not the old one's) and a
//! running test ends "source changed"; when the source ends ([`FieldTests::source_ended`]: a replay at the
//! end of its file) a running test ends "source ended" instead of waiting for fixes that cannot come; when
//! it jumps ([`FieldTests::source_jumped`]: a replay sought or looped) a running test ends too.
//!
//! **Against a reference.** With a reference set ([`FieldTests::set_reference`]: typed, a GPX waypoint,
//! or averaged over a window of good fixes with [`FieldTests::start_averaging`]), the accuracy test
//! ([`FieldTests::accuracy`]) measures every fix against it with [`crate::accuracy::accuracy`], the drift
//! test's fixes gain the same statistics, and the cone marks are measured against where their cones stand
//! (the reference being the first cone): all live, on the tests' own clocks.
//!
//! **Moving during a drift test.** The receiver moves like a walker when either the reported speed over
//! ground is at least [`WALKING_SPEED_M_S`] on every fix of the last [`WALK_SUSTAIN_S`] s, or the
//! straight-line displacement over the last [`WALK_WINDOW_S`] s is at least that speed times the window (a
//! walker's progress, well above the noise of a still receiver, which wanders a few decimetres in a few
//! seconds).

use crate::accuracy::{AccuracyStats, Reference};
use crate::fieldtest::{
    self, ConeConfig, ConeMark, ConeStats, DAY_S, DriftStats, TimedFix, unwrap_time_of_day,
};
use crate::geo::{Earth, LatLon};

mod reference;

pub use reference::{
    AccuracyRun, AveragingRun, DEFAULT_ACCURACY_TARGET_S, DEFAULT_AVERAGING_S, MAX_ACCURACY_TARGET_S,
    MAX_AVERAGING_S,
};

/// One fix as the station hands it to the tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveFix {
    /// Arrival time [s] (any origin, increasing).
    pub arrival_s: f64,
    /// The receiver's UTC time of day [s], when sent.
    pub tod_s: Option<f64>,
    /// WGS-84 latitude [deg].
    pub lat_deg: f64,
    /// WGS-84 longitude [deg].
    pub lon_deg: f64,
    /// Speed over ground [m/s], when sent.
    pub speed_m_s: Option<f64>,
    /// Height above mean sea level [m] (GGA altitude), when sent.
    pub height_m: Option<f64>,
    /// Good enough to average into a reference (a position-bearing quality, 3-D when the mode is known).
    pub good: bool,
}

/// Speed below which `SiRF` Star III static navigation may pin the position [m/s] (physics.md §5).
pub const STATIC_NAV_SPEED_M_S: f64 = 1.2;
/// Default drift-test duration [s] (thesis: 3 min).
pub const DEFAULT_DRIFT_TARGET_S: f64 = 180.0;
/// Default nominal cone spacing [m] (thesis: 10 m).
pub const DEFAULT_CONE_SPACING_M: f64 = 10.0;
/// Default number of cones (thesis: 10).
pub const DEFAULT_CONE_COUNT: usize = 10;
/// Identical consecutive fixes for this long raise the live pinning warning [s].
pub const LIVE_PINNED_RUN_S: f64 = 5.0;
/// Speed at or above which a "stationary" receiver is taken to be carried at walking pace [m/s] (a slow
/// walk is about 1 m/s; a still receiver's reported speed stays below ~0.2 m/s).
pub const WALKING_SPEED_M_S: f64 = 0.5;
/// The reported speed must stay at or above [`WALKING_SPEED_M_S`] this long to warn [s].
pub const WALK_SUSTAIN_S: f64 = 3.0;
/// Window of the displacement check [s]: moving `WALKING_SPEED_M_S * WALK_WINDOW_S` (2.5 m) in it warns.
pub const WALK_WINDOW_S: f64 = 5.0;

/// The clock a test's times are on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Clock {
    /// The receiver's UTC time of each fix.
    Receiver,
    /// The instant each fix arrived (the receiver sends no time).
    Arrival,
}

impl Clock {
    /// How a view names it.
    pub fn describe(self) -> &'static str {
        match self {
            Clock::Receiver => "receiver UTC time of each fix",
            Clock::Arrival => {
                "arrival time at the console (the receiver sends no time: a faster-than-real-time replay \
                 shortens durations)"
            }
        }
    }

    /// Short name, as written in a JSON report's `clock`.
    pub fn key(self) -> &'static str {
        match self {
            Clock::Receiver => "receiver",
            Clock::Arrival => "arrival",
        }
    }
}

/// One fix as a test received it: both clocks, position and speed.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sample {
    arrival_s: f64,
    /// Receiver time on the test's time line [s], when the receiver sent one.
    receiver_s: Option<f64>,
    pos: LatLon,
    speed_m_s: Option<f64>,
    /// Height above mean sea level [m], when sent.
    height_m: Option<f64>,
}

impl Sample {
    fn time_on(&self, clock: Clock) -> Option<f64> {
        match clock {
            Clock::Receiver => self.receiver_s,
            Clock::Arrival => Some(self.arrival_s),
        }
    }
}

/// The fixes of one test, with the times on the test's clock.
#[derive(Debug, Clone, Default)]
pub struct Recording {
    samples: Vec<Sample>,
    clock: Option<Clock>,
    fixes: Vec<TimedFix>,
    /// The last receiver time on the time line [s].
    last_receiver_s: Option<f64>,
}

impl Recording {
    fn clear(&mut self) {
        *self = Self::default();
    }

    /// Records a fix (receiver time of day `tod_s` [s], if any). Returns `false`, recording nothing, when the
    /// fix's time on the test's clock is earlier than the previous fix's.
    fn push(&mut self, f: &LiveFix, pos: LatLon) -> bool {
        let LiveFix { arrival_s, tod_s, speed_m_s, height_m, .. } = *f;
        let receiver_s = tod_s.map(|tod| unwrap_time_of_day(tod, self.last_receiver_s));
        let sample = Sample { arrival_s, receiver_s, pos, speed_m_s, height_m };
        let clock = match (self.clock, receiver_s) {
            (None | Some(Clock::Receiver), Some(_)) => Clock::Receiver,
            _ => Clock::Arrival,
        };
        let Some(t_s) = sample.time_on(clock) else { return false };
        if self.clock != Some(clock) {
            self.clock = Some(clock);
            self.fixes = self
                .samples
                .iter()
                .filter_map(|s| s.time_on(clock).map(|t_s| TimedFix { t_s, pos: s.pos }))
                .collect();
        }
        if self.fixes.last().is_some_and(|l| t_s < l.t_s) {
            return false;
        }
        if receiver_s.is_some() {
            self.last_receiver_s = receiver_s;
        }
        self.samples.push(sample);
        self.fixes.push(TimedFix { t_s, pos });
        true
    }

    /// The recorded fixes on the test's clock.
    pub fn fixes(&self) -> &[TimedFix] {
        &self.fixes
    }

    /// The clock of the test (`None` before its first fix).
    pub fn clock(&self) -> Option<Clock> {
        self.clock
    }

    /// Time from the first fix to the last [s].
    pub fn elapsed_s(&self) -> f64 {
        match (self.fixes.first(), self.fixes.last()) {
            (Some(a), Some(b)) => b.t_s - a.t_s,
            _ => 0.0,
        }
    }

    /// No fix recorded.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The recorded fixes with their heights, for the accuracy statistics (times on the test's clock).
    pub fn accuracy_samples(&self) -> Vec<crate::accuracy::Sample> {
        // One fix per sample: a test's clock is the receiver's only while every sample has its time.
        self.fixes
            .iter()
            .zip(&self.samples)
            .map(|(f, s)| crate::accuracy::Sample { t_s: f.t_s, pos: f.pos, height_m: s.height_m })
            .collect()
    }

    /// The speed [m/s] at which the receiver moves like a walker at the latest fix, if it does (see the
    /// module doc).
    fn walking_speed_m_s(&self, earth: Earth) -> Option<f64> {
        let last = self.fixes.last()?;
        let mut slowest = f64::INFINITY;
        for (f, s) in self.fixes.iter().zip(&self.samples).rev() {
            match s.speed_m_s {
                Some(v) if v >= WALKING_SPEED_M_S => slowest = slowest.min(v),
                _ => break,
            }
            if last.t_s - f.t_s >= WALK_SUSTAIN_S {
                return Some(slowest);
            }
        }
        let before = self.fixes.iter().rev().find(|f| last.t_s - f.t_s >= WALK_WINDOW_S)?;
        let dt_s = last.t_s - before.t_s;
        let v = earth.distance_m(before.pos, last.pos) / dt_s;
        (v >= WALKING_SPEED_M_S).then_some(v)
    }
}

/// Where a test is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Phase {
    /// Not started (or reset).
    Idle,
    /// Recording fixes.
    Running,
    /// Stopped; results frozen until a new run starts.
    Done,
    /// Ended because its source ended or changed (the reason, e.g. "source ended"); results frozen.
    Ended(&'static str),
}

/// Why a test ended without the operator: the source reached its end (a replay's file).
pub const SOURCE_ENDED: &str = "source ended";
/// Why a test ended without the operator: the operator picked another source.
pub const SOURCE_CHANGED: &str = "source changed";

/// Why a test ended without the operator: the source jumped in time (a replay sought or looped).
pub const SOURCE_JUMPED: &str = "source jumped (replay sought or looped)";

/// The stationary drift test.
#[derive(Debug, Clone)]
pub struct DriftRun {
    /// Where it is.
    pub phase: Phase,
    /// Duration target [s]; reaching it ends the test.
    pub target_s: f64,
    rec: Recording,
    /// The walking speed [m/s] at the latest fix, when the receiver moves like a walker.
    pub walking_now_m_s: Option<f64>,
    /// When (test time [s] from the first fix) and how fast the receiver first moved like a walker.
    pub walked: Option<(f64, f64)>,
    /// The statistics of the fixes so far.
    pub stats: Option<DriftStats>,
    /// Why there are no statistics.
    pub error: Option<String>,
    /// The fixes against the reference, when one is set (or why there are no such statistics).
    pub against: Option<Result<AccuracyStats, String>>,
    /// Bumped whenever the data changes (views cache derived plots per revision).
    pub revision: u64,
}

impl DriftRun {
    fn new() -> Self {
        Self {
            phase: Phase::Idle,
            target_s: DEFAULT_DRIFT_TARGET_S,
            rec: Recording::default(),
            walking_now_m_s: None,
            walked: None,
            stats: None,
            error: None,
            against: None,
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

/// The cone test.
#[derive(Debug, Clone)]
pub struct ConeRun {
    /// Where it is.
    pub phase: Phase,
    /// Nominal cone spacing [m].
    pub spacing_m: f64,
    /// Cones laid.
    pub count: usize,
    /// Use a typed true bearing for the line instead of the first-to-last mark direction.
    pub use_bearing: bool,
    /// The typed line bearing [deg].
    pub bearing_deg: f64,
    rec: Recording,
    /// The marks so far.
    pub marks: Vec<ConeMark>,
    /// The statistics (from the second mark).
    pub stats: Option<ConeStats>,
    /// Why there are no statistics.
    pub error: Option<String>,
    /// Each mark against where its cone stands, the reference being the first cone (from the second
    /// mark, when a reference is set).
    pub against: Option<Result<AccuracyStats, String>>,
    /// Bumped whenever the data changes.
    pub revision: u64,
}

impl ConeRun {
    fn new() -> Self {
        Self {
            phase: Phase::Idle,
            spacing_m: DEFAULT_CONE_SPACING_M,
            count: DEFAULT_CONE_COUNT,
            use_bearing: false,
            bearing_deg: 0.0,
            rec: Recording::default(),
            marks: Vec::new(),
            stats: None,
            error: None,
            against: None,
            revision: 0,
        }
    }

    /// The recorded fixes.
    pub fn recording(&self) -> &Recording {
        &self.rec
    }

    /// The settings; the expected count is left out while the test runs (a missing mark is only a mistake
    /// once the operator has finished).
    pub fn config(&self, earth: Earth) -> ConeConfig {
        ConeConfig {
            count: (self.phase != Phase::Running).then_some(self.count),
            line_bearing_deg: self.use_bearing.then_some(self.bearing_deg),
            earth,
            ..ConeConfig::with_spacing(self.spacing_m)
        }
    }
}

/// The latest fix the tests were given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Latest {
    /// Arrival time [s] and position.
    pub fix: TimedFix,
    /// Receiver UTC time of day [s], when sent.
    pub tod_s: Option<f64>,
    /// Speed over ground [m/s], when sent.
    pub speed_m_s: Option<f64>,
}

/// Which test the live pinning warning is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Procedure {
    /// The drift test.
    Drift,
    /// The cone test.
    Cones,
    /// The accuracy test against the reference.
    Accuracy,
}

/// The drift and cone tests fed with every fix.
#[derive(Debug, Clone)]
pub struct FieldTests {
    /// Distances on this Earth model.
    pub earth: Earth,
    latest: Option<Latest>,
    /// Fixes refused: non-finite or out-of-range coordinates, or time going backwards.
    pub rejected: usize,
    /// The drift test.
    pub drift: DriftRun,
    /// The cone test.
    pub cones: ConeRun,
    /// The truth the tests are measured against, when set ([`Self::set_reference`]).
    reference: Option<Reference>,
    /// A reference being averaged from good fixes.
    pub averaging: AveragingRun,
    /// The accuracy test: fixes against the reference.
    pub accuracy: AccuracyRun,
}

impl Default for FieldTests {
    fn default() -> Self {
        Self::new()
    }
}

impl FieldTests {
    /// Idle tests: WGS-84 distances, thesis defaults (3 min; 10 cones, 10 m).
    pub fn new() -> Self {
        Self {
            earth: Earth::Wgs84,
            latest: None,
            rejected: 0,
            drift: DriftRun::new(),
            cones: ConeRun::new(),
            reference: None,
            averaging: AveragingRun::new(),
            accuracy: AccuracyRun::new(),
        }
    }

    /// The latest fix given.
    pub fn latest(&self) -> Option<Latest> {
        self.latest
    }

    /// Feeds one fix: arrival time [s] (any origin, increasing), receiver UTC time of day [s] if sent,
    /// WGS-84 latitude/longitude [deg], speed over ground [m/s] if known. Fixes with non-finite or
    /// out-of-range coordinates, an arrival time earlier than the previous fix's, or a time earlier than the
    /// previous fix's on a running test's clock, are counted in [`Self::rejected`] and ignored.
    pub fn push(
        &mut self,
        arrival_s: f64,
        tod_s: Option<f64>,
        lat_deg: f64,
        lon_deg: f64,
        speed: Option<f64>,
    ) {
        self.push_fix(&LiveFix {
            arrival_s,
            tod_s,
            lat_deg,
            lon_deg,
            speed_m_s: speed,
            height_m: None,
            good: true,
        });
    }

    /// Feeds one fix with its height and whether it is good enough to average into a reference (see
    /// [`Self::push`] for what is refused). The accuracy test and an averaging reference take it too.
    pub fn push_fix(&mut self, fix: &LiveFix) {
        let Ok(pos) = LatLon::new(fix.lat_deg, fix.lon_deg).validated() else {
            self.rejected += 1;
            return;
        };
        let arrival_s = fix.arrival_s;
        if !arrival_s.is_finite() || self.latest.is_some_and(|l| arrival_s < l.fix.t_s) {
            self.rejected += 1;
            return;
        }
        let tod_s = fix.tod_s.filter(|t| t.is_finite() && (0.0..DAY_S + 1.0).contains(t));
        let speed_m_s = fix.speed_m_s.filter(|s| s.is_finite() && *s >= 0.0);
        let height_m = fix.height_m.filter(|h| h.is_finite() && h.abs() < 100_000.0);
        let fix = LiveFix { tod_s, speed_m_s, height_m, ..*fix };
        self.latest = Some(Latest { fix: TimedFix { t_s: arrival_s, pos }, tod_s, speed_m_s });
        let mut refused = false;
        if self.drift.phase == Phase::Running {
            if self.drift.rec.push(&fix, pos) {
                self.drift.revision += 1;
                self.update_drift_stats();
                self.drift.walking_now_m_s = self.drift.rec.walking_speed_m_s(self.earth);
                if let Some(v) = self.drift.walking_now_m_s
                    && self.drift.walked.is_none()
                {
                    self.drift.walked = Some((self.drift.elapsed_s(), v));
                }
                if self.drift.elapsed_s() >= self.drift.target_s {
                    self.drift.phase = Phase::Done;
                }
            } else {
                refused = true;
            }
        }
        if self.cones.phase == Phase::Running {
            if self.cones.rec.push(&fix, pos) {
                self.cones.revision += 1;
                self.update_cone_stats();
            } else {
                refused = true;
            }
        }
        refused |= !self.push_reference_runs(&fix, pos);
        if refused {
            self.rejected += 1;
        }
    }

    /// The operator picked another source: the latest fix and the refusal count are forgotten (the new
    /// source's arrival times and receiver clock start afresh) and a running test ends [`SOURCE_CHANGED`].
    pub fn source_changed(&mut self) {
        self.latest = None;
        self.rejected = 0;
        self.end_running(SOURCE_CHANGED);
    }

    /// The source reached its end (a replay's file, the simulator's route): a running test ends
    /// [`SOURCE_ENDED`], its results kept.
    pub fn source_ended(&mut self) {
        self.end_running(SOURCE_ENDED);
    }

    /// The source jumped in time (a replay sought or started again): the receiver's clock no longer
    /// continues, so a running test ends [`SOURCE_JUMPED`], its results kept.
    pub fn source_jumped(&mut self) {
        self.end_running(SOURCE_JUMPED);
    }

    fn end_running(&mut self, why: &'static str) {
        self.end_reference_runs(why);
        if self.drift.phase == Phase::Running {
            self.drift.phase = Phase::Ended(why);
            self.drift.walking_now_m_s = None;
            self.drift.revision += 1;
        }
        if self.cones.phase == Phase::Running {
            self.cones.phase = Phase::Ended(why);
            self.update_cone_stats();
            self.cones.revision += 1;
        }
    }

    /// Recomputes every statistic (after a change of [`Self::earth`] or of the cone settings).
    pub fn recompute(&mut self) {
        if !self.drift.rec.is_empty() {
            self.update_drift_stats();
        }
        self.update_cone_stats();
        self.update_accuracy_stats();
        self.drift.revision += 1;
        self.cones.revision += 1;
        self.accuracy.revision += 1;
    }

    fn update_drift_stats(&mut self) {
        self.drift.against = self.against_reference(&self.drift.rec);
        match fieldtest::drift(&self.drift.rec.fixes, self.earth) {
            Ok(s) => {
                self.drift.stats = Some(s);
                self.drift.error = None;
            }
            Err(e) => {
                self.drift.stats = None;
                self.drift.error = Some(e.to_string());
            }
        }
    }

    /// Recomputes the cone statistics.
    pub fn update_cone_stats(&mut self) {
        if self.cones.marks.len() < 2 {
            self.cones.stats = None;
            self.cones.error = None;
            self.cones.against = None;
            return;
        }
        match fieldtest::cones(&self.cones.marks, &self.cones.rec.fixes, &self.cones.config(self.earth)) {
            Ok(s) => {
                self.cones.stats = Some(s);
                self.cones.error = None;
            }
            Err(e) => {
                self.cones.stats = None;
                self.cones.error = Some(e.to_string());
            }
        }
        self.cones.against = self.cones_against_reference();
    }

    /// Starts a new drift test (discarding the previous one).
    pub fn start_drift(&mut self) {
        self.drift.phase = Phase::Running;
        self.drift.rec.clear();
        self.drift.walking_now_m_s = None;
        self.drift.walked = None;
        self.drift.stats = None;
        self.drift.error = None;
        self.drift.against = None;
        self.drift.revision += 1;
    }

    /// Stops the drift test; its results stay.
    pub fn stop_drift(&mut self) {
        if self.drift.phase == Phase::Running {
            self.drift.phase = Phase::Done;
            self.drift.walking_now_m_s = None;
        }
    }

    /// Starts a new cone test (discarding the previous one).
    pub fn start_cones(&mut self) {
        self.cones.phase = Phase::Running;
        self.cones.rec.clear();
        self.cones.marks.clear();
        self.cones.stats = None;
        self.cones.error = None;
        self.cones.against = None;
        self.cones.revision += 1;
    }

    /// Ends the cone test; its results stay, and the mark count is now judged against the cones laid.
    pub fn finish_cones(&mut self) {
        if self.cones.phase == Phase::Running {
            self.cones.phase = Phase::Done;
            self.update_cone_stats();
            self.cones.revision += 1;
        }
    }

    /// Marks the next cone at the test's latest fix; returns its label (`"cone N"`, N from 1). `None` when
    /// no cone test runs or no fix has arrived yet.
    pub fn mark_cone(&mut self) -> Option<String> {
        if self.cones.phase != Phase::Running {
            return None;
        }
        let at = self.cones.rec.fixes.last().copied().or_else(|| self.latest.map(|l| l.fix))?;
        let label = format!("cone {}", self.cones.marks.len() + 1);
        let pos = fieldtest::position_at(&self.cones.rec.fixes, at.t_s).unwrap_or(at.pos);
        self.cones.marks.push(ConeMark { t_s: at.t_s, label: label.clone(), pos });
        self.cones.revision += 1;
        self.update_cone_stats();
        Some(label)
    }

    /// The live pinning hint for `procedure`: a run of identical fixes over the last seconds, or a speed
    /// below the `SiRF` static-navigation threshold while a cone test runs.
    pub fn live_pinning_warning(&self, procedure: Procedure) -> Option<String> {
        let (track, what) = match procedure {
            Procedure::Drift => (&self.drift.rec.fixes, "drift test"),
            Procedure::Cones => (&self.cones.rec.fixes, "cone test"),
            Procedure::Accuracy => (&self.accuracy.recording().fixes, "accuracy test"),
        };
        let last = track.last()?;
        let start = track.iter().rposition(|f| last.t_s - f.t_s > 30.0).map_or(0, |i| i + 1);
        let pin = fieldtest::pinning(&track[start..]);
        let ongoing = (pin.longest_run_start_s + pin.longest_run_s - last.t_s).abs() < 1e-6;
        if ongoing && pin.longest_run_s >= LIVE_PINNED_RUN_S {
            return Some(format!(
                "{what}: the receiver has repeated one position for {:.0} s — it looks pinned (SiRF static \
                 navigation)",
                pin.longest_run_s
            ));
        }
        if procedure == Procedure::Cones
            && self.cones.phase == Phase::Running
            && let Some(speed) = self.latest.and_then(|l| l.speed_m_s)
            && speed < STATIC_NAV_SPEED_M_S
        {
            return Some(format!(
                "speed {speed:.2} m/s is below ~{STATIC_NAV_SPEED_M_S} m/s: SiRF static navigation may pin the \
                 position — walk briskly between cones"
            ));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    const C: LatLon = LatLon::new(42.3575, -71.1010);

    fn at(along_m: f64, east_m: f64) -> LatLon {
        let p = Earth::Wgs84.direct(C, 0.0, along_m);
        Earth::Wgs84.direct(p, 90.0, east_m)
    }

    /// Issue 15 fault 7: the drift test's time base is the receiver's UTC, not the arrival instants (a x10
    /// replay), across midnight too; a fix without receiver time puts the test on the arrival clock.
    #[test]
    fn drift_runs_on_the_receiver_clock_across_midnight() {
        let mut t = FieldTests::new();
        t.drift.target_s = 300.0;
        let tod0 = DAY_S - 100.0; // midnight falls 100 s into the test
        t.push(0.0, Some(tod0), C.lat_deg, C.lon_deg, Some(0.0));
        t.start_drift();
        for k in 0..=200 {
            let k = f64::from(k);
            t.push(0.1 * k, Some((tod0 + k) % DAY_S), C.lat_deg, C.lon_deg, Some(0.0));
        }
        assert_eq!(t.drift.recording().clock(), Some(Clock::Receiver));
        assert_eq!(t.rejected, 0);
        let s = t.drift.stats.as_ref().unwrap();
        assert_eq!(s.fixes, 201);
        assert_relative_eq!(s.duration_s, 200.0, max_relative = 1e-9);
        assert_eq!(t.drift.phase, Phase::Running, "200 s of a 300 s target");
        // The receiver stops sending time: the whole test is re-timed on arrival (0 .. 20.1 s).
        t.push(20.1, None, C.lat_deg, C.lon_deg, Some(0.0));
        assert_eq!(t.drift.recording().clock(), Some(Clock::Arrival));
        assert_relative_eq!(t.drift.elapsed_s(), 20.1, max_relative = 1e-9);
    }

    /// Issue 23 item 2: a drift test after a change of source records the new source's fixes, whatever
    /// the old source's arrival times and clock were (a replay of a morning log after the simulator's
    /// afternoon).
    #[test]
    fn a_new_source_starts_a_fresh_time_line() {
        let mut t = FieldTests::new();
        for k in 0..20 {
            t.push(3600.0 + f64::from(k), Some(50_000.0 + f64::from(k)), C.lat_deg, C.lon_deg, None);
        }
        t.start_drift();
        t.push(3620.0, Some(50_020.0), C.lat_deg, C.lon_deg, None);
        t.source_changed();
        assert_eq!(t.drift.phase, Phase::Ended(SOURCE_CHANGED));
        // The replay: earlier arrival origin, earlier time of day.
        t.push(10.0, Some(30_000.0), C.lat_deg, C.lon_deg, None);
        t.start_drift();
        for k in 1..=10 {
            t.push(10.0 + 0.1 * f64::from(k), Some(30_000.0 + f64::from(k)), C.lat_deg, C.lon_deg, None);
        }
        assert_eq!(t.rejected, 0);
        assert_eq!(t.drift.stats.as_ref().unwrap().fixes, 10);
        assert_relative_eq!(t.drift.elapsed_s(), 9.0, max_relative = 1e-9);
    }

    /// Issue 23 item 6: a test running when its source ends says so and keeps its results.
    #[test]
    fn source_end_ends_a_running_test() {
        let mut t = FieldTests::new();
        t.push(0.0, Some(10.0), C.lat_deg, C.lon_deg, None);
        t.start_drift();
        for k in 1..=5 {
            t.push(f64::from(k), Some(10.0 + f64::from(k)), C.lat_deg, C.lon_deg, None);
        }
        t.source_ended();
        assert_eq!(t.drift.phase, Phase::Ended(SOURCE_ENDED));
        assert_eq!(t.drift.stats.as_ref().unwrap().fixes, 5);
        // Nothing more is recorded.
        t.push(9.0, Some(19.0), C.lat_deg, C.lon_deg, None);
        assert_eq!(t.drift.stats.as_ref().unwrap().fixes, 5);
    }

    /// Issue 15 fault 7: a receiver carried at walking pace during a drift test raises the warning, from
    /// the reported speed or, without one, from its displacement; a still receiver does not.
    #[test]
    fn a_walking_receiver_warns_during_a_drift_test() {
        for reports_speed in [true, false] {
            let mut t = FieldTests::new();
            let speed = |v: f64| reports_speed.then_some(v);
            t.push(0.0, Some(0.0), C.lat_deg, C.lon_deg, speed(0.0));
            t.start_drift();
            for k in 0..10 {
                let p = at(0.03 * f64::from(k % 3), 0.0);
                t.push(f64::from(k), Some(f64::from(k)), p.lat_deg, p.lon_deg, speed(0.05));
            }
            assert_eq!(t.drift.walking_now_m_s, None, "a still receiver");
            for k in 1..=8 {
                let p = at(1.2 * f64::from(k), 0.0);
                let s = 9.0 + f64::from(k);
                t.push(s, Some(s), p.lat_deg, p.lon_deg, speed(1.2));
            }
            let v = t.drift.walking_now_m_s.expect("walking warning");
            assert_relative_eq!(v, 1.2, max_relative = 0.01);
            for k in 1..=8 {
                let p = at(9.6, 0.0);
                let s = 17.0 + f64::from(k);
                t.push(s, Some(s), p.lat_deg, p.lon_deg, speed(0.0));
            }
            assert_eq!(t.drift.walking_now_m_s, None);
            assert!(t.drift.walked.is_some_and(|(at_s, _)| at_s > 10.0 && at_s < 17.0));
        }
    }

    #[test]
    fn pinned_receiver_raises_the_live_warning() {
        let mut t = FieldTests::new();
        t.push(0.0, None, C.lat_deg, C.lon_deg, Some(1.5));
        t.start_cones();
        for k in 1..=4 {
            let p = at(1.5 * f64::from(k), 0.0);
            t.push(f64::from(k), None, p.lat_deg, p.lon_deg, Some(1.5));
        }
        assert_eq!(t.live_pinning_warning(Procedure::Cones), None);
        for k in 5..=12 {
            let p = at(6.0, 0.0);
            t.push(f64::from(k), None, p.lat_deg, p.lon_deg, Some(1.5));
        }
        assert!(t.live_pinning_warning(Procedure::Cones).is_some_and(|w| w.contains("pinned")));
        let p = at(8.0, 0.0);
        t.push(13.0, None, p.lat_deg, p.lon_deg, Some(0.6));
        assert!(t.live_pinning_warning(Procedure::Cones).is_some_and(|w| w.contains("static navigation")));
    }

    #[test]
    fn hostile_fixes_are_ignored() {
        let mut t = FieldTests::new();
        t.push(f64::NAN, None, 42.0, -71.0, None);
        t.push(1.0, None, f64::NAN, -71.0, None);
        t.push(1.0, None, 95.0, -71.0, None);
        t.push(1.0, None, 42.0, f64::INFINITY, None);
        assert!(t.latest().is_none());
        t.push(5.0, Some(f64::NAN), 42.0, -71.0, Some(f64::NAN));
        t.push(4.0, None, 42.0, -71.0, None);
        assert_eq!(t.rejected, 5);
        assert_eq!(t.latest().unwrap().speed_m_s, None);
        assert_eq!(t.latest().unwrap().tod_s, None, "a NaN receiver time is no time");
    }
}
