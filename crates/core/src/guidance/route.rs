//! Routes: waypoints, the active one, and arrival or passing with confirmation and re-arming.

use serde::{Deserialize, Serialize};

use super::RoutePath;
use crate::geo::{Earth, LatLon, leg_offset};

/// Errors building a route.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RouteError {
    /// A route needs at least one waypoint.
    #[error("the route has no waypoints")]
    Empty,
    /// A waypoint with a bad latitude/longitude.
    #[error("waypoint {index} ({name}): {source}")]
    BadWaypoint {
        /// Index of the waypoint.
        index: usize,
        /// Its name.
        name: String,
        /// What is wrong.
        source: crate::geo::GeoError,
    },
    /// Arrival radius not positive and finite, or confirm count zero.
    #[error("invalid route setting: {0}")]
    BadConfig(&'static str),
}

/// A named waypoint: the one waypoint type from a GPX file through the route model and the remote
/// protocol to guidance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Waypoint {
    /// Name shown to the operator.
    pub name: String,
    /// Latitude [deg].
    pub lat_deg: f64,
    /// Longitude [deg].
    pub lon_deg: f64,
    /// This waypoint's own arrival radius [m]; `None` uses the route's [`RouteConfig::arrival_radius_m`].
    /// Files keep it (vestnav's GPX extension); guidance honours it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arrival_radius_m: Option<f64>,
}

impl Waypoint {
    /// A waypoint named `name` at `lat_deg`, `lon_deg`, arrived at within the route's radius.
    pub fn new(name: impl Into<String>, lat_deg: f64, lon_deg: f64) -> Self {
        Self { name: name.into(), lat_deg, lon_deg, arrival_radius_m: None }
    }

    /// A waypoint named `name` at `pos`, arrived at within the route's radius.
    pub fn at(name: impl Into<String>, pos: LatLon) -> Self {
        Self::new(name, pos.lat_deg, pos.lon_deg)
    }

    /// Its position.
    pub fn pos(&self) -> LatLon {
        LatLon::new(self.lat_deg, self.lon_deg)
    }

    /// The same waypoint with its own arrival radius [m] (`None`: the route's).
    #[must_use]
    pub fn with_arrival_radius_m(mut self, radius_m: Option<f64>) -> Self {
        self.arrival_radius_m = radius_m;
        self
    }
}

/// Settings of a route: arrival and its hysteresis, looping.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RouteConfig {
    /// A waypoint is reached within this distance [m]. Default 8 m: about 2.5x the `SiRF` III's open-sky
    /// horizontal RMS (~3 m), so a noisy fix rarely misses it.
    pub arrival_radius_m: f64,
    /// Consecutive fixes inside the radius needed to count an arrival (default 2): one noisy fix does not
    /// arrive.
    pub confirm_fixes: u32,
    /// After [`Route::back`] the waypoint only arms again once the wearer is farther than this [m] (default
    /// 1.5x the arrival radius), so stepping back while standing on it does not re-arrive at once.
    pub rearm_radius_m: f64,
    /// A waypoint passed abeam within this distance [m] counts as *passed* (advance, logged as missed)
    /// instead of making the wearer turn around (default 2x the arrival radius).
    pub pass_radius_m: f64,
    /// After the last waypoint, start again at the first.
    pub looped: bool,
}

impl Default for RouteConfig {
    fn default() -> Self {
        Self {
            arrival_radius_m: 8.0,
            confirm_fixes: 2,
            rearm_radius_m: 12.0,
            pass_radius_m: 16.0,
            looped: false,
        }
    }
}

/// What happened to the route in one update.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RouteEvent {
    /// The active waypoint was reached (index); the next one is active.
    Arrived(usize),
    /// The active waypoint was passed close by without reaching the arrival radius (index).
    Passed(usize),
    /// The last waypoint was reached (or passed): the route is finished.
    Finished,
}

/// A route of waypoints with the index of the active one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Route {
    waypoints: Vec<Waypoint>,
    config: RouteConfig,
    active: usize,
    finished: bool,
    inside_count: u32,
    armed: bool,
    laps: u32,
    /// The path between the waypoints, when the route was planned along paths.
    #[serde(default)]
    path: Option<RoutePath>,
}

impl Route {
    /// A route; the first waypoint is active.
    pub fn new(waypoints: Vec<Waypoint>, config: RouteConfig) -> Result<Self, RouteError> {
        if waypoints.is_empty() {
            return Err(RouteError::Empty);
        }
        for (index, w) in waypoints.iter().enumerate() {
            w.pos().validated().map_err(|source| RouteError::BadWaypoint {
                index,
                name: w.name.clone(),
                source,
            })?;
            if w.arrival_radius_m.is_some_and(|r| !(r.is_finite() && r > 0.0)) {
                return Err(RouteError::BadConfig("a waypoint's arrival radius must be positive"));
            }
        }
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if !positive(config.arrival_radius_m)
            || !positive(config.rearm_radius_m)
            || !positive(config.pass_radius_m)
        {
            return Err(RouteError::BadConfig("radii must be positive"));
        }
        if config.confirm_fixes == 0 {
            return Err(RouteError::BadConfig("confirm_fixes must be at least 1"));
        }
        Ok(Self {
            waypoints,
            config,
            active: 0,
            finished: false,
            inside_count: 0,
            armed: true,
            laps: 0,
            path: None,
        })
    }

    /// The same route following `path` between its waypoints (a planner's dense route): guidance measures
    /// the cross-track error from the path's section toward the active waypoint and aims along it. Refused
    /// unless the path has one vertex per waypoint.
    pub fn with_path(mut self, path: Option<RoutePath>) -> Result<Self, RouteError> {
        if path.as_ref().is_some_and(|p| p.waypoint_vertices().len() != self.waypoints.len()) {
            return Err(RouteError::BadConfig("the path must carry one vertex per waypoint"));
        }
        self.path = path;
        Ok(self)
    }

    /// The path between the waypoints, if the route has one.
    pub fn path(&self) -> Option<&RoutePath> {
        self.path.as_ref()
    }

    /// The section of the path toward the active waypoint (at least two points), if the route has a path.
    /// After the first lap of a looped route the leg into waypoint 0 has none (straight leg).
    pub fn active_path(&self) -> Option<&[LatLon]> {
        if self.active == 0 && self.laps > 0 {
            return None;
        }
        self.path.as_ref().map(|p| p.leg(self.active)).filter(|l| l.len() >= 2)
    }

    /// The waypoints.
    pub fn waypoints(&self) -> &[Waypoint] {
        &self.waypoints
    }

    /// The settings.
    pub fn config(&self) -> &RouteConfig {
        &self.config
    }

    /// Index of the active waypoint.
    pub fn active_index(&self) -> usize {
        self.active
    }

    /// The active waypoint.
    pub fn active(&self) -> &Waypoint {
        // `active` is always < len (kept by every mutator) and the route is never empty.
        &self.waypoints[self.active.min(self.waypoints.len() - 1)]
    }

    /// The waypoint before the active one (start of the active leg), if any.
    pub fn previous(&self) -> Option<&Waypoint> {
        if self.active > 0 {
            self.waypoints.get(self.active - 1)
        } else if self.config.looped && self.waypoints.len() > 1 && self.laps > 0 {
            // In a loop, the leg into waypoint 0 comes from the last waypoint after the first lap.
            self.waypoints.last()
        } else {
            None
        }
    }

    /// Completed laps of a looped route.
    pub fn laps(&self) -> u32 {
        self.laps
    }

    /// The radii that apply at the active waypoint [m]: `(arrival, rearm, pass)`.
    ///
    /// A waypoint with its own arrival radius `r_w` scales the route's re-arm and pass radii by
    /// `r_w / arrival_radius_m`, keeping the hysteresis in the proportions the route set (1.5x and 2x by
    /// default); a waypoint without one uses the route's three radii.
    pub fn active_radii_m(&self) -> (f64, f64, f64) {
        let c = &self.config;
        match self.active().arrival_radius_m {
            Some(r) => {
                let k = r / c.arrival_radius_m;
                (r, c.rearm_radius_m * k, c.pass_radius_m * k)
            }
            None => (c.arrival_radius_m, c.rearm_radius_m, c.pass_radius_m),
        }
    }

    /// Whether the active waypoint is armed: arrival at it is being watched for (false after [`Route::back`]
    /// until the wearer has been farther than [`RouteConfig::rearm_radius_m`] from it).
    pub fn is_armed(&self) -> bool {
        self.armed
    }

    /// Whether the route is finished (never for a looped route).
    pub fn is_finished(&self) -> bool {
        self.finished
    }

    /// Skips the active waypoint (operator command): the next one becomes active. At the last waypoint of an
    /// open route this finishes the route.
    pub fn skip(&mut self) -> Option<RouteEvent> {
        self.advance()
    }

    /// Goes back to the previous waypoint (operator command). It arms only after the wearer is farther than
    /// [`RouteConfig::rearm_radius_m`] from it. Un-finishes a finished route.
    pub fn back(&mut self) {
        if self.finished {
            self.finished = false;
        } else if self.active > 0 {
            self.active -= 1;
        } else if self.config.looped && self.laps > 0 {
            self.active = self.waypoints.len() - 1;
            self.laps -= 1;
        }
        self.inside_count = 0;
        self.armed = false;
    }

    fn advance(&mut self) -> Option<RouteEvent> {
        if self.finished {
            return None;
        }
        self.inside_count = 0;
        self.armed = true;
        if self.active + 1 < self.waypoints.len() {
            self.active += 1;
            None
        } else if self.config.looped {
            self.active = 0;
            self.laps += 1;
            None
        } else {
            self.finished = true;
            Some(RouteEvent::Finished)
        }
    }

    /// Feeds one fix: arrival with confirmation and re-arming, or passing abeam. Returns what happened.
    ///
    /// Arrival: `d <= arrival_radius` for `confirm_fixes` consecutive fixes while armed. Passing: the fix is
    /// within `pass_radius` and past the waypoint — along the route's path where it has one
    /// ([`RoutePath::passed`]), else along the straight active leg (`along > leg length`). Re-arming:
    /// `d > rearm_radius`. The radii are the active waypoint's ([`Route::active_radii_m`]).
    pub fn observe(&mut self, earth: Earth, pos: LatLon) -> Option<RouteEvent> {
        if self.finished {
            return None;
        }
        let index = self.active;
        let target = self.active().pos();
        let d = earth.distance_m(pos, target);
        let (arrival_m, rearm_m, pass_m) = self.active_radii_m();
        if !self.armed {
            if d > rearm_m {
                self.armed = true;
            }
            return None;
        }
        if d <= arrival_m {
            self.inside_count += 1;
            if self.inside_count >= self.config.confirm_fixes {
                return Some(self.advance().unwrap_or(RouteEvent::Arrived(index)));
            }
            return None;
        }
        self.inside_count = 0;
        let along_path = if self.active_path().is_some() {
            self.path.as_ref().and_then(|p| p.passed(earth, index, pos))
        } else {
            None
        };
        let past = along_path.or_else(|| {
            let prev = self.previous()?.pos();
            let off = leg_offset(earth, prev, target, pos);
            Some(off.leg_length_m > 0.0 && off.along_track_m > off.leg_length_m)
        });
        if past == Some(true) && d <= pass_m {
            return Some(self.advance().map_or(RouteEvent::Passed(index), |_| RouteEvent::Finished));
        }
        None
    }
}
