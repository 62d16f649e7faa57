//! A pinned receiver: one that repeats the same position while the wearer walks (`SiRF` static
//! navigation below ~1.2 m/s, u-blox static hold), which guidance would otherwise read as "the wearer
//! stands still".
//!
//! **Rule.** The receiver is pinned at the latest fix when every fix of the last [`PINNED_AFTER_S`] seconds
//! (at least [`MIN_REPEATS`] of them) has the same latitude and longitude to 1e-9° (~0.1 mm: a
//! receiver's own noise never repeats a position that exactly, a holding filter always does) and none
//! reports a speed of [`MOVING_SPEED_M_S`] or more. Independent evidence that the wearer moves makes the
//! diagnosis firm: [`PinnedReport::wearer_moves`] says what said so (the simulator's own walker, the vest
//! compass's gait sway). Without it the repeated position is still reported (a receiver on a table
//! also repeats a held position), and the view says so.
//!
//! The gait evidence: a walker's torso pitches and rolls a few degrees once per step (docs/heading.md,
//! "Sensor model"); a standing wearer's compass pitch varies by well under a degree. Pitch readings whose
//! standard deviation over the last [`GAIT_WINDOW_S`] s is at least [`GAIT_PITCH_SD_DEG`] say the wearer
//! walks.

use std::collections::VecDeque;

use crate::geo::LatLon;

/// How long the position must repeat before the receiver is reported pinned [s].
pub const PINNED_AFTER_S: f64 = 5.0;
/// Fewest fixes in that span (a 1 Hz receiver gives 6).
pub const MIN_REPEATS: usize = 4;
/// A reported speed at or above this [m/s] is movement, not a held position.
pub const MOVING_SPEED_M_S: f64 = 0.2;
/// Window of the compass gait check [s].
pub const GAIT_WINDOW_S: f64 = 3.0;
/// Standard deviation of the compass pitch over [`GAIT_WINDOW_S`] that says the wearer walks [deg] (the
/// gait's ±3° sway gives ~2°; a standing wearer well under 0.5°).
pub const GAIT_PITCH_SD_DEG: f64 = 1.0;

/// What says the wearer moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionEvidence {
    /// The simulator's own walker moves (its truth).
    Simulator,
    /// The vest compass's pitch sways like a walker's.
    CompassGait,
}

impl MotionEvidence {
    /// In words, for the operator.
    pub fn describe(self) -> &'static str {
        match self {
            Self::Simulator => "the simulator's walker is moving",
            Self::CompassGait => "the vest compass sways like a walking wearer",
        }
    }
}

/// The diagnosis at the latest fix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinnedReport {
    /// How long the position has repeated [s].
    pub held_s: f64,
    /// The held position.
    pub position: LatLon,
    /// Independent evidence that the wearer moves meanwhile, if any.
    pub wearer_moves: Option<MotionEvidence>,
}

/// Watches fixes (and motion evidence) for a held position; times are seconds on any one increasing clock.
#[derive(Debug, Clone, Default)]
pub struct PinDetector {
    /// The current run of one position without a moving speed: first and last time, position, fixes.
    run: Option<(f64, f64, LatLon, usize)>,
    /// Recent compass pitch readings: time, pitch [deg].
    pitch: VecDeque<(f64, f64)>,
    /// When the simulator last said its walker moves [s].
    sim_moving_at: Option<f64>,
}

fn same(a: LatLon, b: LatLon) -> bool {
    (a.lat_deg - b.lat_deg).abs() < 1e-9 && (a.lon_deg - b.lon_deg).abs() < 1e-9
}

impl PinDetector {
    /// Forgets everything (a new source).
    pub fn clear(&mut self) {
        *self = Self::default();
    }

    /// A fix with a position at `t_s`; non-finite input and time going backwards are ignored.
    pub fn push_fix(&mut self, t_s: f64, pos: LatLon, speed_m_s: Option<f64>) {
        if !t_s.is_finite() || pos.validated().is_err() || self.run.is_some_and(|r| t_s < r.1) {
            return;
        }
        let moving = speed_m_s.is_some_and(|v| v.is_finite() && v >= MOVING_SPEED_M_S);
        self.run = match self.run {
            _ if moving => None,
            Some((start, _, p, n)) if same(p, pos) => Some((start, t_s, p, n + 1)),
            _ => Some((t_s, t_s, pos, 1)),
        };
    }

    /// A compass pitch reading [deg] at `t_s`.
    pub fn push_pitch(&mut self, t_s: f64, pitch_deg: f64) {
        if !t_s.is_finite() || !pitch_deg.is_finite() {
            return;
        }
        self.pitch.push_back((t_s, pitch_deg));
        while self.pitch.front().is_some_and(|p| p.0 < t_s - GAIT_WINDOW_S) || self.pitch.len() > 200 {
            self.pitch.pop_front();
        }
    }

    /// The simulator says its walker moves (pace above standing) at `t_s`.
    pub fn simulator_moving(&mut self, t_s: f64) {
        if t_s.is_finite() {
            self.sim_moving_at = Some(t_s);
        }
    }

    /// The diagnosis at `now_s`: `Some` while the latest fixes hold one position (see the module doc).
    pub fn report(&self, now_s: f64) -> Option<PinnedReport> {
        let (start, last, position, n) = self.run?;
        let held_s = last - start;
        if held_s < PINNED_AFTER_S || n < MIN_REPEATS {
            return None;
        }
        let wearer_moves = if self.sim_moving_at.is_some_and(|t| now_s - t <= GAIT_WINDOW_S) {
            Some(MotionEvidence::Simulator)
        } else if self.gait(now_s) {
            Some(MotionEvidence::CompassGait)
        } else {
            None
        };
        Some(PinnedReport { held_s, position, wearer_moves })
    }

    /// Whether the compass pitch over the last window sways like a walker's.
    fn gait(&self, now_s: f64) -> bool {
        let recent: Vec<f64> =
            self.pitch.iter().filter(|p| p.0 >= now_s - GAIT_WINDOW_S).map(|p| p.1).collect();
        if recent.len() < 5 {
            return false;
        }
        let n = recent.len() as f64;
        let mean = recent.iter().sum::<f64>() / n;
        let var = recent.iter().map(|p| (p - mean).powi(2)).sum::<f64>() / n;
        var.sqrt() >= GAIT_PITCH_SD_DEG
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::Earth;

    const C: LatLon = LatLon::new(42.3575, -71.1010);

    #[test]
    fn a_held_position_is_reported_after_five_seconds() {
        let mut d = PinDetector::default();
        // Walking north at 1 m/s, then held at the 10 m point with speed 0.
        for k in 0..10 {
            d.push_fix(f64::from(k), Earth::Wgs84.direct(C, 0.0, f64::from(k)), Some(1.0));
        }
        assert_eq!(d.report(9.0), None);
        let held = Earth::Wgs84.direct(C, 0.0, 10.0);
        for k in 10..=14 {
            d.push_fix(f64::from(k), held, Some(0.0));
        }
        assert_eq!(d.report(14.0), None, "4 s held");
        d.push_fix(15.0, held, Some(0.0));
        let r = d.report(15.0).expect("5 s held");
        assert!((r.held_s - 5.0).abs() < 1e-9);
        assert_eq!(r.wearer_moves, None);
        // The walker's gait in the compass (±3° at 1.8 Hz, sampled at 5 Hz) makes it firm.
        for k in 0..15 {
            let t = 12.0 + 0.2 * f64::from(k);
            d.push_pitch(t, 3.0 * (2.0 * std::f64::consts::PI * 1.8 * t).sin());
        }
        assert_eq!(d.report(15.0).unwrap().wearer_moves, Some(MotionEvidence::CompassGait));
        // A still receiver's noise never repeats a position exactly.
        d.push_fix(16.0, Earth::Wgs84.direct(held, 45.0, 0.02), Some(0.0));
        assert_eq!(d.report(16.0), None);
    }

    #[test]
    fn a_standing_compass_is_no_evidence_and_speed_is_movement() {
        let mut d = PinDetector::default();
        for k in 0..8 {
            d.push_fix(f64::from(k), C, Some(0.0));
            d.push_pitch(f64::from(k), 0.2 * f64::from(k % 2));
        }
        assert_eq!(d.report(7.0).unwrap().wearer_moves, None);
        d.simulator_moving(7.0);
        assert_eq!(d.report(7.0).unwrap().wearer_moves, Some(MotionEvidence::Simulator));
        // A repeated position with a walking speed is a receiver reporting movement, not holding.
        let mut d = PinDetector::default();
        for k in 0..8 {
            d.push_fix(f64::from(k), C, Some(1.0));
        }
        assert_eq!(d.report(7.0), None);
    }
}
