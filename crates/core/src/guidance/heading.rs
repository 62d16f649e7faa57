//! Heading source selection (auto / compass / COG) and the compass-versus-COG disagreement monitor.
//!
//! Declination is applied here and nowhere else: a compass reading is magnetic, and
//! [`true_compass_deg`] adds [`GuidanceConfig::declination_deg`] once to make it true. Every other heading
//! (COG, HDT/THS) is already true.

use serde::{Deserialize, Serialize};

use crate::geo::{normalize_deg, true_from_magnetic_deg, wrap_deg_180};

use super::{GuidanceConfig, HeadingSource, NavInput};

/// Which heading guidance steers by ([`GuidanceConfig::heading_mode`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum HeadingMode {
    /// Compass when it is fresh and its quality adequate (and not disturbed), else true heading, else COG
    /// when moving fast enough.
    Auto,
    /// The compass only; no usable compass reading holds with the reason.
    Compass,
    /// The rule from before the compass: COG when moving fast enough, else true heading, else compass.
    #[default]
    Cog,
}

impl HeadingMode {
    /// Every mode.
    pub const ALL: [Self; 3] = [Self::Auto, Self::Compass, Self::Cog];

    /// Short name (`auto`, `compass`, `cog`), as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Compass => "compass",
            Self::Cog => "cog",
        }
    }

    /// Parses [`Self::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }
}

/// One compass reading with what guidance needs to trust it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CompassReading {
    /// Magnetic heading of the wearer's body [deg] (tilt-compensated; declination is added by guidance).
    pub magnetic_deg: f64,
    /// Age of the reading at `now_s` [s].
    pub age_s: f64,
    /// Calibration quality 0–100 % (e.g. `compass::Calibration::quality_pct`); `None` when the source
    /// reports none (an external NMEA HDG compass), which is accepted.
    pub quality_pct: Option<u8>,
}

impl CompassReading {
    /// A reading taken now with no quality figure (what [`NavInput::compass_deg`] alone gives).
    pub fn fresh(magnetic_deg: f64) -> Self {
        Self { magnetic_deg, age_s: 0.0, quality_pct: None }
    }
}

/// The heading chosen for one update.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct HeadingChoice {
    pub source: HeadingSource,
    pub heading_deg: Option<f64>,
    /// The rule in words, e.g. "compass (auto: compass fresh, quality 92 %)".
    pub rule: String,
}

/// The compass corrected to true: `magnetic + declination` ([`true_from_magnetic_deg`]); `None` without a
/// declination (the compass is then unusable) or with a non-finite reading.
pub(super) fn true_compass_deg(config: &GuidanceConfig, compass: Option<&CompassReading>) -> Option<f64> {
    let c = compass.filter(|c| c.magnetic_deg.is_finite())?;
    let decl = config.declination_deg.filter(|d| d.is_finite())?;
    Some(true_from_magnetic_deg(c.magnetic_deg, decl))
}

/// Why a compass reading is not usable in auto or compass mode, if it is not.
fn compass_problem(config: &GuidanceConfig, compass: Option<&CompassReading>) -> Option<String> {
    let Some(c) = compass.filter(|c| c.magnetic_deg.is_finite()) else {
        return Some("no compass".to_owned());
    };
    if config.declination_deg.is_none_or(|d| !d.is_finite()) {
        return Some("no declination set".to_owned());
    }
    if !(c.age_s.is_finite() && c.age_s <= config.compass_max_age_s) {
        return Some(format!("compass stale ({:.1} s)", c.age_s));
    }
    match c.quality_pct {
        Some(q) if q < config.compass_min_quality_pct => {
            Some(format!("compass quality {q} % < {} %", config.compass_min_quality_pct))
        }
        _ => None,
    }
}

fn quality_words(c: Option<&CompassReading>) -> String {
    match c.and_then(|c| c.quality_pct) {
        Some(q) => format!("quality {q} %"),
        None => "quality not reported".to_owned(),
    }
}

/// Picks the heading by `config.heading_mode` (rules in `docs/guidance.md`, heading source).
///
/// `disturbed` is the disagreement monitor's verdict: in auto mode it makes COG (when moving fast
/// enough) win over the compass while it lasts.
pub(super) fn choose(
    config: &GuidanceConfig,
    input: &NavInput,
    compass: Option<&CompassReading>,
    disturbed: bool,
) -> HeadingChoice {
    let finite = |x: Option<f64>| x.filter(|v| v.is_finite());
    let moving = finite(input.speed_m_s).is_some_and(|s| s >= config.cog_min_speed_m_s);
    let cog = finite(input.cog_deg).filter(|_| moving).map(normalize_deg);
    let true_heading = finite(input.true_heading_deg).map(normalize_deg);
    let compass_true = true_compass_deg(config, compass);
    let pick =
        |source, heading_deg, rule: String| HeadingChoice { source, heading_deg: Some(heading_deg), rule };
    let none = |rule: String| HeadingChoice { source: HeadingSource::None, heading_deg: None, rule };
    match config.heading_mode {
        HeadingMode::Cog => {
            if let Some(h) = cog {
                return pick(HeadingSource::Cog, h, "COG (cog: moving)".to_owned());
            }
            if let Some(h) = true_heading {
                return pick(
                    HeadingSource::TrueHeading,
                    h,
                    "true heading (cog: too slow for COG)".to_owned(),
                );
            }
            // The old rule: a compass with a declination, whatever its age or quality.
            if let Some(h) = compass_true {
                return pick(HeadingSource::Compass, h, "compass (cog: too slow for COG)".to_owned());
            }
            none("none (cog: too slow for COG, no true heading or compass)".to_owned())
        }
        HeadingMode::Compass => match (compass_problem(config, compass), compass_true) {
            (None, Some(h)) => {
                let warn = if disturbed { ", disturbed?" } else { "" };
                pick(
                    HeadingSource::Compass,
                    h,
                    format!("compass (compass: {}{warn})", quality_words(compass)),
                )
            }
            (problem, _) => none(format!("none (compass: {})", problem.unwrap_or_default())),
        },
        HeadingMode::Auto => {
            let problem = compass_problem(config, compass);
            if disturbed && let Some(h) = cog {
                return pick(
                    HeadingSource::Cog,
                    h,
                    "COG (auto: compass disagrees with COG, disturbed?)".to_owned(),
                );
            }
            if let (None, Some(h)) = (&problem, compass_true) {
                let why = if disturbed {
                    format!("compass disturbed? but too slow for COG, {}", quality_words(compass))
                } else {
                    format!("compass fresh, {}", quality_words(compass))
                };
                return pick(HeadingSource::Compass, h, format!("compass (auto: {why})"));
            }
            let problem = problem.unwrap_or_default();
            if let Some(h) = true_heading {
                return pick(HeadingSource::TrueHeading, h, format!("true heading (auto: {problem})"));
            }
            if let Some(h) = cog {
                return pick(HeadingSource::Cog, h, format!("COG (auto: {problem}, moving)"));
            }
            none(format!("none (auto: {problem}, no true heading, too slow for COG)"))
        }
    }
}

/// Watches compass (true-corrected) against COG while walking fast and raises "compass disturbed?".
///
/// Evidence is only taken while the speed is at least [`GuidanceConfig::disagree_min_speed_m_s`] (and at
/// least the COG threshold) with both a usable compass and COG: below that COG is noise. The warning rises
/// once `|wrap(compass - COG)| > disagree_deg` has held for `disagree_s` without a break, and clears once
/// they agree within `disagree_deg` for `disagree_s` — an agreeing instant alone does not clear it, so a
/// noisy compass near steel does not flicker the warning. Without evidence (slow, standing, no COG) the
/// state is kept as it is.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Disagreement {
    /// Since when the current run of disagreeing (or, while disturbed, agreeing) evidence lasts [s].
    since_s: Option<f64>,
    disturbed: bool,
    /// Last measured difference compass − COG [deg].
    pub last_diff_deg: Option<f64>,
}

impl Disagreement {
    pub fn disturbed(&self) -> bool {
        self.disturbed
    }

    /// Takes the evidence of one update at `now_s` and returns whether the compass is now suspect.
    pub fn observe(
        &mut self,
        config: &GuidanceConfig,
        input: &NavInput,
        compass: Option<&CompassReading>,
        now_s: f64,
    ) -> bool {
        let speed = input.speed_m_s.filter(|s| s.is_finite());
        let fast = speed.is_some_and(|s| s >= config.disagree_min_speed_m_s.max(config.cog_min_speed_m_s));
        let fresh = compass_problem(config, compass).is_none();
        let (Some(cog), Some(c), true, true) =
            (input.cog_deg.filter(|v| v.is_finite()), true_compass_deg(config, compass), fast, fresh)
        else {
            return self.disturbed;
        };
        let diff = wrap_deg_180(c - cog);
        self.last_diff_deg = Some(diff);
        let disagrees = diff.abs() > config.disagree_deg;
        // Evidence against the current verdict starts (or continues) a run; evidence for it ends the run.
        if disagrees == self.disturbed {
            self.since_s = None;
        } else {
            let since = *self.since_s.get_or_insert(now_s);
            if now_s - since >= config.disagree_s {
                self.disturbed = disagrees;
                self.since_s = None;
            }
        }
        self.disturbed
    }
}
