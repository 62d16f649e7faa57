//! Guidance strategies: where to aim on the active leg (bearing-only, cross-track-corrected pursuit).

use glam::DVec2;
use serde::{Deserialize, Serialize};

use super::GuidanceConfig;

/// The geometry a strategy sees, in a local east/north frame centred on the wearer (wearer at the origin).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegGeometry {
    /// The active waypoint [m].
    pub target_en_m: DVec2,
    /// The start of the active leg (previous waypoint), if any [m].
    pub from_en_m: Option<DVec2>,
}

/// A guidance strategy: where to aim, given the leg. Implementations are pure.
pub trait Strategy: std::fmt::Debug + Send {
    /// Short name (`bearing`, `pursuit`).
    fn name(&self) -> &'static str;
    /// The point to aim at, in the wearer-centred frame of `leg` [m].
    fn aim_en_m(&self, leg: &LegGeometry) -> DVec2;
}

/// Bearing-only: aim straight at the active waypoint.
#[derive(Debug, Clone, Copy, Default)]
pub struct BearingOnly;

impl Strategy for BearingOnly {
    fn name(&self) -> &'static str {
        "bearing"
    }
    fn aim_en_m(&self, leg: &LegGeometry) -> DVec2 {
        leg.target_en_m
    }
}

/// Cross-track-corrected pursuit ("carrot chasing"): aim at the point `lookahead_m` further along the leg
/// than the wearer's foot point on it; once that passes the waypoint, aim at the waypoint.
///
/// With leg start `a`, end `b`, unit `u = (b - a)/|b - a|` and the wearer at the origin `p = 0`: the foot point
/// is at `s = (p - a)·u`, the aim point `a + min(s + L, |b - a|) u`. A cross-track error `x` thus turns into a
/// bearing error of `atan(x / L)` toward the leg: the wearer converges on the line instead of cutting
/// corners, like pure pursuit in path following (Coulter 1992, CMU-RI-TR-92-01).
#[derive(Debug, Clone, Copy)]
pub struct Pursuit {
    /// Look-ahead distance L [m].
    pub lookahead_m: f64,
}

impl Strategy for Pursuit {
    fn name(&self) -> &'static str {
        "pursuit"
    }
    fn aim_en_m(&self, leg: &LegGeometry) -> DVec2 {
        let Some(a) = leg.from_en_m else { return leg.target_en_m };
        let ab = leg.target_en_m - a;
        let len = ab.length();
        if len < 1e-9 {
            return leg.target_en_m;
        }
        let u = ab / len;
        let s = (-a).dot(u);
        let t = (s + self.lookahead_m.max(0.0)).clamp(0.0, len);
        a + u * t
    }
}

/// The built-in strategies, by name (for the CLI and the app).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum StrategyKind {
    /// [`BearingOnly`].
    BearingOnly,
    /// [`Pursuit`] with [`GuidanceConfig::lookahead_m`].
    Pursuit,
}

impl StrategyKind {
    /// Every strategy.
    pub const ALL: [Self; 2] = [Self::BearingOnly, Self::Pursuit];

    /// CLI name.
    pub fn name(self) -> &'static str {
        match self {
            Self::BearingOnly => "bearing",
            Self::Pursuit => "pursuit",
        }
    }

    /// Parses a CLI name (`bearing` or `pursuit`).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    pub(super) fn build(self, config: &GuidanceConfig) -> Box<dyn Strategy> {
        match self {
            Self::BearingOnly => Box::new(BearingOnly),
            Self::Pursuit => Box::new(Pursuit { lookahead_m: config.lookahead_m }),
        }
    }
}
