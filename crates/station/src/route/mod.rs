//! The route: the one owner of the waypoints, the next waypoint, the edit history and the autosave
//! ([`RouteModel`]), and the wearer's track ([`Track`]).
//!
//! A route planned along paths also holds its path ([`RouteModel::path`]); an edit that moves, adds,
//! removes or reorders waypoints drops it (straight legs again), a re-route replaces it.
//!
//! Every edit (add, move, drag, delete, reorder, rename, typed coordinates, clear, import) is one step of
//! a bounded undo history ([`UNDO_STEPS`]). A route never holds more than [`MAX_WAYPOINTS`] waypoints:
//! an edit or an import beyond it is refused with a message, never slowly accepted, so that everything
//! drawn or searched per frame stays bounded. Each change bumps [`RouteModel::revision`]; the station
//! hands the new route to guidance and the autosave once per revision.

use std::collections::VecDeque;

use vestnav_core::guidance::RoutePath;

mod files;
mod track;

pub use files::*;
pub use track::{TRACK_JUMP_SLACK_M, TRACK_MAX_POINTS, TRACK_MAX_SPEED_M_S, Track, plausible_step, segments};

/// Undo steps kept; the oldest is forgotten beyond this.
pub const UNDO_STEPS: usize = 100;

/// Most waypoints a route may have: the same bound as a GPX file's route points
/// ([`vestnav_device::route_file::MAX_ROUTE_POINTS`]), so every file that reads can be guided, and every
/// route can be drawn and listed within a frame's budget.
pub const MAX_WAYPOINTS: usize = vestnav_device::route_file::MAX_ROUTE_POINTS;

/// One step of the undo (or redo) history: the route to go back to.
#[derive(Debug, Clone)]
struct UndoStep {
    /// The edit, in words ("delete WP3").
    what: String,
    /// The route to restore.
    state: RouteState,
    /// The next waypoint's index the history left: when guidance has moved on since (an arrival), the
    /// restore keeps guidance's next waypoint instead of the stored one.
    left_next: usize,
}

/// Why a route edit was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RouteError {
    /// The route would exceed [`MAX_WAYPOINTS`].
    #[error("a route holds at most {limit} waypoints; this one would have {count}")]
    TooManyWaypoints {
        /// How many it would have.
        count: usize,
        /// The limit.
        limit: usize,
    },
    /// A typed value is not acceptable (the message names the field).
    #[error("{0}")]
    Field(String),
    /// The waypoint no longer exists.
    #[error("waypoint {0} no longer exists")]
    Gone(usize),
}

/// Longest waypoint name accepted from outside (a typed edit, a network command) [characters].
pub const MAX_WAYPOINT_NAME: usize = 200;

/// Checks one waypoint's fields as the operator typed or sent them: a non-empty name of at most
/// [`MAX_WAYPOINT_NAME`] characters, a position inside GPX's ranges, an arrival radius that is a positive
/// finite number of metres when given. The message names the field.
pub fn check_waypoint(
    name: &str,
    lat_deg: f64,
    lon_deg: f64,
    radius_m: Option<f64>,
) -> Result<(), RouteError> {
    if radius_m.is_some_and(|r| !(r.is_finite() && r > 0.0)) {
        return Err(RouteError::Field(
            "Arrival radius: must be a positive number of metres (empty: the global radius)".into(),
        ));
    }
    let name = name.trim();
    if name.is_empty() {
        return Err(RouteError::Field("Name: must not be empty".to_owned()));
    }
    if name.chars().count() > MAX_WAYPOINT_NAME {
        return Err(RouteError::Field(format!("Name: longer than {MAX_WAYPOINT_NAME} characters")));
    }
    if !(-90.0..=90.0).contains(&lat_deg) {
        return Err(RouteError::Field(format!("Latitude: {lat_deg} is outside [-90, 90] degrees")));
    }
    if !(-180.0..180.0).contains(&lon_deg) {
        return Err(RouteError::Field(format!("Longitude: {lon_deg} is outside [-180, 180) degrees")));
    }
    Ok(())
}

/// The route the operator edits and guidance follows (see the module doc).
#[derive(Debug, Clone)]
pub struct RouteModel {
    name: String,
    waypoints: Vec<Waypoint>,
    next: usize,
    /// The path between the waypoints (a planned walk); dropped by an edit that moves, adds, removes or
    /// reorders waypoints (its vertices would no longer be theirs).
    path: Option<RoutePath>,
    undo: VecDeque<UndoStep>,
    redo: Vec<UndoStep>,
    /// "Deleted WP3": shown with an **Undo delete** button after a delete or a clear, until the next edit.
    undo_notice: Option<String>,
    /// The route before an edit in progress (a drag), recorded as one step when it ends.
    pending: Option<(String, RouteState)>,
    revision: u64,
}

impl Default for RouteModel {
    fn default() -> Self {
        Self::new(RouteState { name: "route".to_owned(), waypoints: Vec::new(), next: 0, path: None })
    }
}

impl RouteModel {
    /// A model holding `state` (its next index clamped, its waypoints cut to [`MAX_WAYPOINTS`]: use
    /// [`Self::check_len`] first to refuse a longer one).
    pub fn new(state: RouteState) -> Self {
        let RouteState { name, mut waypoints, next, path } = state;
        waypoints.truncate(MAX_WAYPOINTS);
        let next = next.min(waypoints.len());
        let path = path.filter(|p| p.waypoint_vertices().len() == waypoints.len());
        Self {
            name,
            waypoints,
            next,
            path,
            undo: VecDeque::new(),
            redo: Vec::new(),
            undo_notice: None,
            pending: None,
            revision: 0,
        }
    }

    /// Refuses a route of `count` waypoints when it is over [`MAX_WAYPOINTS`].
    pub fn check_len(count: usize) -> Result<(), RouteError> {
        if count > MAX_WAYPOINTS {
            Err(RouteError::TooManyWaypoints { count, limit: MAX_WAYPOINTS })
        } else {
            Ok(())
        }
    }

    /// The route's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The waypoints, in order.
    pub fn waypoints(&self) -> &[Waypoint] {
        &self.waypoints
    }

    /// Index of the next waypoint (`waypoints().len()`: the route is finished).
    pub fn next(&self) -> usize {
        self.next
    }

    /// The path the route follows between its waypoints, when it was planned along paths.
    pub fn path(&self) -> Option<&RoutePath> {
        self.path.as_ref()
    }

    /// The points a wearer walks along the route (what the GPS simulator walks): the path's when it has
    /// one, else the waypoints.
    pub fn walked(&self) -> Vec<Waypoint> {
        match &self.path {
            Some(p) => p.points().iter().map(|q| Waypoint::at("path", *q)).collect(),
            None => self.waypoints.clone(),
        }
    }

    /// Bumped by every change (edits, undo, redo, a new next waypoint).
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// "Deleted WP3" after a delete or clear, until the next edit.
    pub fn undo_notice(&self) -> Option<&str> {
        self.undo_notice.as_deref()
    }

    /// Forgets the delete notice (the operator dismissed it).
    pub fn dismiss_undo_notice(&mut self) {
        self.undo_notice = None;
    }

    /// The route as it stands (name, waypoints, next).
    pub fn state(&self) -> RouteState {
        RouteState {
            name: self.name.clone(),
            waypoints: self.waypoints.clone(),
            next: self.next,
            path: self.path.clone(),
        }
    }

    /// Whether the route is `state` (compared without cloning).
    pub fn is(&self, state: &RouteState) -> bool {
        state.is(&self.name, &self.waypoints, self.next, self.path.as_ref())
    }

    /// Sets the next waypoint (deliberate re-targeting, or guidance's arrival); not an undo step.
    pub fn set_next(&mut self, next: usize) {
        let next = next.min(self.waypoints.len());
        if next != self.next {
            self.next = next;
            self.revision += 1;
        }
    }

    /// Records the edit just made (the route was `before`) as one undo step; clears the redo steps and the
    /// delete notice. Nothing is recorded when the route did not change.
    fn commit(&mut self, what: String, before: RouteState) {
        if self.is(&before) {
            return;
        }
        if self.undo.len() >= UNDO_STEPS {
            self.undo.pop_front();
        }
        self.undo.push_back(UndoStep { what, state: before, left_next: self.next });
        self.redo.clear();
        self.undo_notice = None;
        self.revision += 1;
    }

    /// Puts `step`'s route in place and returns the step that goes back to the route it replaced.
    fn swap_in(&mut self, step: UndoStep) -> UndoStep {
        let current = RouteState {
            name: std::mem::take(&mut self.name),
            waypoints: std::mem::take(&mut self.waypoints),
            next: self.next,
            path: self.path.take(),
        };
        let UndoStep { what, state, left_next } = step;
        self.name = state.name;
        self.waypoints = state.waypoints;
        self.path = state.path;
        let next = if current.next == left_next { state.next } else { current.next };
        self.next = next.min(self.waypoints.len());
        self.undo_notice = None;
        self.pending = None;
        self.revision += 1;
        UndoStep { what, state: current, left_next: self.next }
    }

    /// Undoes the latest edit; returns whether there was one.
    pub fn undo(&mut self) -> bool {
        let Some(step) = self.undo.pop_back() else { return false };
        let back = self.swap_in(step);
        self.redo.push(back);
        true
    }

    /// Redoes the latest undone edit; returns whether there was one.
    pub fn redo(&mut self) -> bool {
        let Some(step) = self.redo.pop() else { return false };
        let back = self.swap_in(step);
        self.undo.push_back(back);
        true
    }

    /// The edit Undo would take back, in words.
    pub fn undo_label(&self) -> Option<&str> {
        self.undo.back().map(|s| s.what.as_str())
    }

    /// The edit Redo would make again, in words.
    pub fn redo_label(&self) -> Option<&str> {
        self.redo.last().map(|s| s.what.as_str())
    }

    /// Removes every waypoint (one undo step, with the delete notice).
    pub fn clear(&mut self) {
        if self.waypoints.is_empty() {
            return;
        }
        let before = self.state();
        let n = before.waypoints.len();
        self.waypoints.clear();
        self.path = None;
        self.next = 0;
        self.commit("clear route".to_owned(), before);
        self.undo_notice = Some(format!("Cleared the route ({n} waypoints)"));
    }

    /// Replaces the route with an imported one (one undo step), heading for its first waypoint.
    pub fn replace(&mut self, name: String, waypoints: Vec<Waypoint>) -> Result<(), RouteError> {
        self.replace_with_path(name, waypoints, None)
    }

    /// [`Self::replace`] with the path the route follows between its waypoints (a planned walk, a
    /// planner's GPX); refused unless the path has one vertex per waypoint.
    pub fn replace_with_path(
        &mut self,
        name: String,
        waypoints: Vec<Waypoint>,
        path: Option<RoutePath>,
    ) -> Result<(), RouteError> {
        Self::check_len(waypoints.len())?;
        if path.as_ref().is_some_and(|p| p.waypoint_vertices().len() != waypoints.len()) {
            return Err(RouteError::Field("the path does not pass every waypoint".to_owned()));
        }
        let before = self.state();
        let what = format!("import {name}");
        self.name = name;
        self.waypoints = waypoints;
        self.path = path;
        self.next = 0;
        self.commit(what, before);
        Ok(())
    }

    /// Replaces the path from the next waypoint on with `path` (a re-route from where the wearer is: its
    /// vertices must be the same waypoints'): one undo step, the waypoints unchanged.
    pub fn reroute(&mut self, path: RoutePath) -> Result<(), RouteError> {
        if path.waypoint_vertices().len() != self.waypoints.len() {
            return Err(RouteError::Field("the new path does not pass every waypoint".to_owned()));
        }
        let before = self.state();
        self.path = Some(path);
        self.commit("re-route from the wearer".to_owned(), before);
        Ok(())
    }

    /// Renames waypoint `i`, sets its position and its own arrival radius [m] (`None`: guidance's global
    /// radius): one undo step. A radius that is not a positive finite number, an empty name or a position
    /// outside GPX's ranges is refused, naming the field, and changes nothing.
    pub fn edit(
        &mut self,
        i: usize,
        name: &str,
        lat_deg: f64,
        lon_deg: f64,
        radius_m: Option<f64>,
    ) -> Result<(), RouteError> {
        check_waypoint(name, lat_deg, lon_deg, radius_m)?;
        let name = name.trim();
        let Some(old) = self.waypoints.get(i).cloned() else {
            return Err(RouteError::Gone(i + 1));
        };
        let moved = old.lat_deg.to_bits() != lat_deg.to_bits() || old.lon_deg.to_bits() != lon_deg.to_bits();
        let radius_changed = old.arrival_radius_m != radius_m;
        let what = match (old.name != name, moved, radius_changed) {
            (true, false, false) => format!("rename {} to {name}", old.name),
            (false, true, false) => format!("move {} to typed coordinates", old.name),
            (false, false, true) => format!("arrival radius of {}", old.name),
            _ => format!("edit {}", old.name),
        };
        let before = self.state();
        if let Some(w) = self.waypoints.get_mut(i) {
            *w = Waypoint { name: name.to_owned(), lat_deg, lon_deg, arrival_radius_m: radius_m };
        }
        if moved {
            self.path = None;
        }
        self.commit(what, before);
        Ok(())
    }

    /// Moves waypoint `i` one place earlier (`-1`) or later (`1`).
    pub fn move_by(&mut self, i: usize, dir: i32) {
        let j = if dir < 0 { i.checked_sub(1) } else { Some(i + 1) };
        if let Some(j) = j.filter(|&j| j < self.waypoints.len()) {
            let before = self.state();
            self.waypoints.swap(i, j);
            self.path = None;
            let way = if dir < 0 { "earlier" } else { "later" };
            let name = self.waypoints.get(j).map_or_else(String::new, |w| w.name.clone());
            self.commit(format!("move {name} {way}"), before);
        }
    }

    /// Deletes waypoint `i`, keeping the next waypoint the same where possible; undoable at once (the
    /// delete notice says so).
    pub fn delete(&mut self, i: usize) {
        if i < self.waypoints.len() {
            let before = self.state();
            let w = self.waypoints.remove(i);
            self.path = None;
            if i < self.next {
                self.next -= 1;
            }
            self.commit(format!("delete {}", w.name), before);
            self.undo_notice = Some(format!("Deleted {}", w.name));
        }
    }

    /// Adds a waypoint at (`lat_deg`, `lon_deg`) (clamped/wrapped into GPX's ranges): at the end, or right
    /// before the next one when `as_next`. Refused beyond [`MAX_WAYPOINTS`].
    pub fn add(&mut self, lat_deg: f64, lon_deg: f64, as_next: bool) -> Result<(), RouteError> {
        Self::check_len(self.waypoints.len() + 1)?;
        let before = self.state();
        let n = self.waypoints.len() + 1;
        let (lat_deg, lon_deg) = gpx_coords(lat_deg, lon_deg);
        let w = Waypoint::new(format!("WP{n}"), lat_deg, lon_deg);
        let what = format!("add {}", w.name);
        if as_next && self.next <= self.waypoints.len() {
            self.waypoints.insert(self.next, w);
        } else {
            self.waypoints.push(w);
        }
        self.path = None;
        self.commit(what, before);
        Ok(())
    }

    /// Moves waypoint `i` to (`lat_deg`, `lon_deg`) while it is dragged: the drag, however many frames it
    /// takes, becomes one undo step when [`Self::end_drag`] is called.
    pub fn drag(&mut self, i: usize, lat_deg: f64, lon_deg: f64) {
        if i >= self.waypoints.len() {
            return;
        }
        if self.pending.is_none() {
            let name = self.waypoints.get(i).map_or_else(|| format!("WP{}", i + 1), |w| w.name.clone());
            self.pending = Some((format!("drag {name}"), self.state()));
        }
        let (lat_deg, lon_deg) = gpx_coords(lat_deg, lon_deg);
        if let Some(w) = self.waypoints.get_mut(i) {
            w.lat_deg = lat_deg;
            w.lon_deg = lon_deg;
            self.path = None;
            self.revision += 1;
        }
    }

    /// Ends a drag: one undo step for the whole of it.
    pub fn end_drag(&mut self) {
        if let Some((what, before)) = self.pending.take() {
            // The revision already moved with each drag step; record the step without bumping it twice.
            let revision = self.revision;
            self.commit(what, before);
            self.revision = revision.max(self.revision);
        }
    }

    /// Whether a drag is in progress.
    pub fn dragging(&self) -> bool {
        self.pending.is_some()
    }
}

/// A position as waypoint coordinates within GPX's ranges: latitude clamped to [-90, 90], longitude
/// wrapped into [-180, 180) (the map can be panned past the antimeridian), non-finite values as 0, so the
/// route can always be saved and read back.
pub fn gpx_coords(lat_deg: f64, lon_deg: f64) -> (f64, f64) {
    let lat = if lat_deg.is_finite() { lat_deg.clamp(-90.0, 90.0) } else { 0.0 };
    let mut lon = if lon_deg.is_finite() { (lon_deg + 180.0).rem_euclid(360.0) - 180.0 } else { 0.0 };
    if lon >= 180.0 {
        lon -= 360.0;
    }
    (lat, lon)
}

/// Parses a coordinate typed in decimal degrees (`42.3573`, `-71.1`; a decimal comma and a trailing `°`
/// are accepted) and checks it against GPX's range for `field`: latitude in [-90, 90], longitude in
/// [-180, 180). Errors name the field.
pub fn parse_coordinate(text: &str, field: Coordinate) -> Result<f64, String> {
    let t = text.trim().trim_end_matches('°').trim();
    let t = if t.contains(',') && !t.contains('.') { t.replace(',', ".") } else { t.to_owned() };
    let name = field.name();
    if t.is_empty() {
        return Err(format!("{name}: enter a value in decimal degrees"));
    }
    let v: f64 =
        t.parse().map_err(|_| format!("{name}: '{}' is not a number in decimal degrees", text.trim()))?;
    let ok = match field {
        Coordinate::Latitude => (-90.0..=90.0).contains(&v),
        Coordinate::Longitude => (-180.0..180.0).contains(&v),
    };
    if ok { Ok(v) } else { Err(format!("{name}: {v} is outside {}", field.range())) }
}

/// Which coordinate [`parse_coordinate`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coordinate {
    /// Latitude, [-90, 90] degrees.
    Latitude,
    /// Longitude, [-180, 180) degrees.
    Longitude,
}

impl Coordinate {
    fn name(self) -> &'static str {
        match self {
            Self::Latitude => "Latitude",
            Self::Longitude => "Longitude",
        }
    }
    fn range(self) -> &'static str {
        match self {
            Self::Latitude => "[-90, 90] degrees",
            Self::Longitude => "[-180, 180) degrees",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(n: usize) -> RouteModel {
        let wps =
            (0..n).map(|i| Waypoint::new(format!("WP{}", i + 1), 42.0 + i as f64 * 1e-3, -71.0)).collect();
        RouteModel::new(RouteState { name: "r".into(), waypoints: wps, next: 0, path: None })
    }

    #[test]
    fn a_path_survives_renames_and_undo_but_not_moves() {
        use vestnav_core::geo::LatLon;
        let mut m = model(0);
        let pts: Vec<LatLon> = (0..5).map(|i| LatLon::new(42.0 + f64::from(i) * 1e-3, -71.0)).collect();
        let wps = vec![Waypoint::at("A", pts[0]), Waypoint::at("B", pts[4])];
        let path = RoutePath::new(pts.clone(), vec![0, 4]).unwrap();
        assert!(
            m.replace_with_path(
                "walk".into(),
                wps.clone(),
                Some(RoutePath::new(pts.clone(), vec![0]).unwrap())
            )
            .is_err()
        );
        m.replace_with_path("walk".into(), wps, Some(path.clone())).unwrap();
        assert_eq!(m.path(), Some(&path));
        assert_eq!(m.walked().len(), 5, "the simulator walks the path");
        m.edit(0, "Start", pts[0].lat_deg, pts[0].lon_deg, None).unwrap();
        assert_eq!(m.path(), Some(&path), "a rename keeps it");
        m.drag(1, 42.01, -71.0);
        m.end_drag();
        assert_eq!(m.path(), None, "a moved waypoint drops it");
        assert!(m.undo());
        assert_eq!(m.path(), Some(&path), "undo brings it back");
        // A re-route replaces it as one undo step.
        let detour = path.replaced_from(1, &[LatLon::new(42.002, -70.999), pts[4]], &[1]).unwrap();
        m.reroute(detour.clone()).unwrap();
        assert_eq!(m.path(), Some(&detour));
        assert_eq!(m.undo_label(), Some("re-route from the wearer"));
        // The autosave keeps it.
        assert_eq!(parse_autosave(&autosave_gpx(&m.state())).unwrap().path, Some(detour));
    }

    #[test]
    fn editing_keeps_the_next_waypoint() {
        let mut m = model(4);
        m.set_next(2);
        m.delete(0);
        assert_eq!(m.next(), 1, "the same waypoint stays next");
        assert_eq!(m.waypoints()[m.next()].name, "WP3");
        assert_eq!(m.undo_notice(), Some("Deleted WP1"));
        m.add(42.5, -71.5, true).unwrap();
        assert_eq!(m.waypoints()[1].name, "WP4", "inserted before the next one");
        assert!(m.undo());
        assert!(m.undo());
        assert_eq!(m.waypoints().len(), 4);
    }

    #[test]
    fn the_undo_history_is_bounded_and_keeps_guidances_next_waypoint() {
        let mut m = model(2);
        for k in 0..(UNDO_STEPS + 20) {
            m.edit(0, &format!("name {k}"), 42.0, -71.0, None).unwrap();
        }
        let mut undone = 0;
        while m.undo() {
            undone += 1;
        }
        assert_eq!(undone, UNDO_STEPS);
        // Guidance moved on (arrival) after an edit: undo keeps its next waypoint.
        let mut m = model(3);
        m.delete(2);
        m.set_next(1);
        assert!(m.undo());
        assert_eq!(m.next(), 1);
    }

    #[test]
    fn a_route_beyond_the_limit_is_refused_and_unchanged() {
        let mut m = model(3);
        let big: Vec<Waypoint> =
            (0..=MAX_WAYPOINTS).map(|i| Waypoint::new(format!("P{i}"), 0.0, 0.0)).collect();
        let e = m.replace("big".into(), big).unwrap_err();
        assert_eq!(e, RouteError::TooManyWaypoints { count: MAX_WAYPOINTS + 1, limit: MAX_WAYPOINTS });
        assert_eq!(m.waypoints().len(), 3);
        let full: Vec<Waypoint> =
            (0..MAX_WAYPOINTS).map(|i| Waypoint::new(format!("P{i}"), 0.0, 0.0)).collect();
        m.replace("full".into(), full).unwrap();
        assert!(m.add(1.0, 1.0, false).is_err());
        assert_eq!(m.waypoints().len(), MAX_WAYPOINTS);
    }

    #[test]
    fn a_drag_is_one_undo_step_and_typed_values_are_checked() {
        let mut m = model(2);
        let r0 = m.revision();
        for k in 0..10 {
            m.drag(1, 42.0 + f64::from(k) * 1e-4, -71.0);
        }
        m.end_drag();
        assert!(m.revision() > r0);
        assert_eq!(m.undo_label(), Some("drag WP2"));
        assert!(m.undo());
        assert!((m.waypoints()[1].lat_deg - 42.001).abs() < 1e-12);
        assert!(matches!(m.edit(0, " ", 1.0, 1.0, None), Err(RouteError::Field(e)) if e.starts_with("Name")));
        assert!(
            matches!(m.edit(0, "a", 91.0, 1.0, None), Err(RouteError::Field(e)) if e.starts_with("Latitude"))
        );
        assert!(
            matches!(m.edit(0, "a", 1.0, 1.0, Some(-1.0)), Err(RouteError::Field(e)) if e.starts_with("Arrival"))
        );
        assert_eq!(gpx_coords(0.0, 190.0), (0.0, -170.0));
        assert_eq!(gpx_coords(f64::NAN, 180.0), (0.0, -180.0));
        assert!(parse_coordinate("42,5°", Coordinate::Latitude).is_ok_and(|v| (v - 42.5).abs() < 1e-12));
        assert!(parse_coordinate("x", Coordinate::Longitude).unwrap_err().starts_with("Longitude"));
    }
}
