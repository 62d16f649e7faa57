//! Cue selection: bearing-error thresholds with hysteresis, from an error angle to a directional cue.

use serde::{Deserialize, Serialize};

use crate::vest::Cue;

/// Bearing-error thresholds of the cues [deg] (|error| measured from the heading to the aim point).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CueThresholds {
    /// Up to this: `Forward` (default 15°, about the walking heading wobble).
    pub forward_deg: f64,
    /// Up to this: `SlightLeft/Right` (default 45°).
    pub slight_deg: f64,
    /// Up to this: `TurnLeft/Right` (default 135°); beyond: `TurnAround`.
    pub turn_deg: f64,
    /// Hysteresis at each boundary (default 5°): the previous class is kept while the error is within this of
    /// the boundary, so a bearing error hovering at 15° does not alternate Forward/Slight.
    pub hysteresis_deg: f64,
}

impl Default for CueThresholds {
    fn default() -> Self {
        Self { forward_deg: 15.0, slight_deg: 45.0, turn_deg: 135.0, hysteresis_deg: 5.0 }
    }
}

impl CueThresholds {
    /// The cue for a bearing error `e` (deg, positive = target to the right), given the previous directional
    /// cue for hysteresis.
    ///
    /// Class by |e|: `<= forward` Forward, `<= slight` Slight, `<= turn` Turn, else `TurnAround`; the side is the
    /// sign of `e`. With a previous class, a boundary between it and a neighbour moves by `hysteresis` away
    /// from the previous class (so leaving it takes `hysteresis` more error).
    pub fn classify(&self, error_deg: f64, previous: Option<Cue>) -> Cue {
        let mag = error_deg.abs();
        let bounds = [self.forward_deg, self.slight_deg, self.turn_deg];
        let prev_level = previous.and_then(level_of);
        let level = |m: f64| -> usize {
            bounds
                .iter()
                .enumerate()
                .map(|(i, &b)| {
                    // Boundary i separates level i and i+1.
                    match prev_level {
                        Some(p) if p <= i => b + self.hysteresis_deg,
                        Some(_) => b - self.hysteresis_deg,
                        None => b,
                    }
                })
                .filter(|&b| m > b)
                .count()
        };
        let right = error_deg > 0.0;
        match level(mag) {
            0 => Cue::Forward,
            1 if right => Cue::SlightRight,
            1 => Cue::SlightLeft,
            2 if right => Cue::TurnRight,
            2 => Cue::TurnLeft,
            _ => Cue::TurnAround,
        }
    }
}

impl CueThresholds {
    /// Half-width of the forward cone of a wearer standing still: `forward + hysteresis` (default 20°) [deg].
    ///
    /// Wider than the walking `forward` threshold on purpose: the smallest turn-in-place grade is 30°, so
    /// a wearer turned by it from just outside a 15° cone would land just outside the other side and be
    /// turned back; from outside 20° a 30° turn lands within 10° of the aim, within the cone despite the
    /// turn's scatter.
    pub fn in_place_cone_deg(&self) -> f64 {
        self.forward_deg + self.hysteresis_deg
    }

    /// The cue for a wearer standing still: `Forward` within [`Self::in_place_cone_deg`], else the
    /// turn-in-place cue toward the aim graded by [`crate::vest::TurnStep::for_error_deg`].
    pub fn classify_in_place(&self, error_deg: f64) -> Cue {
        if error_deg.abs() <= self.in_place_cone_deg() { Cue::Forward } else { Cue::rotate_toward(error_deg) }
    }
}

fn level_of(cue: Cue) -> Option<usize> {
    match cue {
        Cue::Forward => Some(0),
        Cue::SlightLeft | Cue::SlightRight => Some(1),
        Cue::TurnLeft | Cue::TurnRight | Cue::RotateLeft(_) | Cue::RotateRight(_) => Some(2),
        Cue::TurnAround => Some(3),
        _ => None,
    }
}
