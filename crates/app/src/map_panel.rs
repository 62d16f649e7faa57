//! The map: tiles of the configured source (`crate::tiles`; OpenStreetMap by default) or a local metric
//! grid, the wearer with an accuracy circle, the track, waypoints and route, and the mouse editing of
//! waypoints.
//!
//! Mouse: drag the map to pan (leaves follow mode), Ctrl+wheel or pinch to zoom; drag a waypoint to move
//! it; right-click a waypoint for delete / move earlier / move later / make next; right-click the map to add
//! a waypoint there; with "Add waypoints" on, a left click adds one at the end of the route.
//!
//! Every edit of the route (add, move, drag, delete, reorder, rename, typed coordinates, clear, import)
//! is one step of a bounded undo history ([`UNDO_STEPS`]); Ctrl+Z undoes, Ctrl+Shift+Z and Ctrl+Y redo
//! (outside text fields). A delete is not confirmed: it is undoable at once, and says so ("Deleted WP3"
//! with an **Undo delete** button).

use std::cell::Cell;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::time::Instant;

use egui::{Color32, Key, KeyboardShortcut, Modifiers, Pos2, RichText, Stroke, vec2};
use walkers::{MapMemory, Position, Projector, TileId, TilePiece, Tiles, lat_lon};

use crate::config::Config;
use crate::map_tools::{self, MapTools};
use crate::route::{RouteState, Waypoint, decimation_stride};
use crate::route_import::{ImportChoice, ImportDialog};
use vestnav_core::geo::{DVec2, Earth, LatLon, LocalFrame};
use vestnav_device::gps::Fix;
use vestnav_device::route_file::TrackPoint;

use crate::guidance::GuidanceStatus;

/// Undo steps kept; the oldest is forgotten beyond this.
pub const UNDO_STEPS: usize = 100;

/// Track points drawn at most per frame (older points are strided, the newest [`TRACK_TAIL`] drawn in full).
pub const TRACK_DRAW_MAX: usize = 2500;
/// Newest track points always drawn at full resolution.
pub const TRACK_TAIL: usize = 500;
/// With tiles on, the map falls back to the local grid when no tile has arrived for this long [s].
pub const TILES_OFFLINE_AFTER_S: f64 = 2.0;

/// Fastest the wearer can plausibly move between two fixes [m/s]: a run (walking is ~1.4 m/s), so that a
/// hurried wearer never splits the track but a teleport does.
pub const TRACK_MAX_SPEED_M_S: f64 = 5.0;
/// Jump every step is allowed on top of [`TRACK_MAX_SPEED_M_S`] [m]: GPS error (a `SiRF` receiver's multipath
/// hop is tens of metres), and the step between two fixes whose timestamps are missing or equal.
pub const TRACK_JUMP_SLACK_M: f64 = 50.0;

/// Beyond this distance the next waypoint is not a walk but a wrong route or a wrong position [m]. A day's
/// walk is 30-40 km; 100 km is beyond any single leg of a guided walk, so the console warns instead of
/// printing a distance and a time to go.
pub const FAR_WAYPOINT_M: f64 = 100_000.0;
/// Longest time to go shown as a number [s]; beyond it the line says "more than 12 h to go".
pub const TIME_TO_GO_MAX_S: f64 = 12.0 * 3600.0;

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

/// The time between two fixes for the walking rule [s]: from the receiver's UTC when both carry it (true
/// time also in a fast replay), else from the instants their bytes arrived, else 0.
fn fix_dt_s(prev: &TrackStamp, f: &Fix) -> f64 {
    match ((prev.time, f.time), (prev.received_at, f.received_at)) {
        ((Some(a), Some(b)), _) => (b - a).num_milliseconds() as f64 / 1000.0,
        (_, (Some(a), Some(b))) => b.saturating_duration_since(a).as_secs_f64(),
        _ => 0.0,
    }
}

/// When and where the newest track point was taken.
#[derive(Debug, Clone, Copy)]
struct TrackStamp {
    at: (f64, f64),
    time: Option<chrono::DateTime<chrono::Utc>>,
    received_at: Option<Instant>,
}

/// How the wearer's dot is drawn: live (blue) or last known (grey, with its age).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WearerMarker {
    /// The position is current: its bytes arrived at most `stale_after_s` ago.
    pub live: bool,
    /// Age of the position [s] (`None`: the arrival time is unknown, which counts as not live).
    pub age_s: Option<f64>,
}

/// The wearer's marker for `fix` at `now`: live only while the fix's bytes arrived at most `stale_after_s`
/// ago (the limit the GPS alarm calls a fix stale at).
pub fn wearer_marker(fix: &Fix, now: Instant, stale_after_s: f64) -> WearerMarker {
    let age_s = fix.age(now).map(|a| a.as_secs_f64());
    WearerMarker { live: age_s.is_some_and(|a| a <= stale_after_s), age_s }
}

/// The distance and time-to-go part of the next-waypoint line, and a warning when the numbers make no
/// sense for a walk.
#[derive(Debug, Clone, PartialEq)]
pub struct LegSummary {
    /// "312 m · aim bearing 45° · 4 min 00 s to go", or only the distance when it is absurd.
    pub text: String,
    /// Set when the waypoint is beyond [`FAR_WAYPOINT_M`].
    pub warning: Option<String>,
}

/// Distance in metres, in units a reader takes in at once: "850 m", "4.2 km", "15196 km".
pub fn distance_text(distance_m: f64) -> String {
    if distance_m < 1000.0 {
        format!("{distance_m:.0} m")
    } else if distance_m < 100_000.0 {
        format!("{:.1} km", distance_m / 1000.0)
    } else {
        format!("{:.0} km", distance_m / 1000.0)
    }
}

/// A time to go: "4 min 05 s", "2 h 10 min", or "more than 12 h" past [`TIME_TO_GO_MAX_S`].
pub fn time_to_go_text(ttg_s: f64) -> String {
    if !ttg_s.is_finite() || ttg_s > TIME_TO_GO_MAX_S {
        return format!("more than {:.0} h", TIME_TO_GO_MAX_S / 3600.0);
    }
    // Whole seconds first, so that 59.6 s reads "1 min 00 s", never "0 min 60 s".
    let s = ttg_s.max(0.0).round() as u64;
    if s >= 3600 {
        format!("{} h {:02} min", s / 3600, (s % 3600) / 60)
    } else {
        format!("{} min {:02} s", s / 60, s % 60)
    }
}

/// The leg to the next waypoint in words: `distance_m` and `bearing_deg` from guidance, `speed_m_s` the pace
/// the time to go assumes (time to go = distance / speed).
pub fn leg_summary(distance_m: f64, bearing_deg: Option<f64>, speed_m_s: f64) -> LegSummary {
    let d = distance_text(distance_m);
    if distance_m > FAR_WAYPOINT_M {
        return LegSummary {
            text: format!("{d} away"),
            warning: Some(format!(
                "Next waypoint {d} away: too far to walk (over {:.0} km). Check the route and the GPS source.",
                FAR_WAYPOINT_M / 1000.0
            )),
        };
    }
    let b = bearing_deg.filter(|b| b.is_finite()).map_or_else(|| "—".to_owned(), |b| format!("{b:.0}°"));
    let ttg = time_to_go_text(distance_m / speed_m_s.max(0.1));
    LegSummary { text: format!("{d} · aim bearing {b} · {ttg} to go"), warning: None }
}

/// Map state kept between frames.
pub struct MapView {
    /// walkers' view state (centre, zoom).
    pub memory: MapMemory,
    /// The tile source, its indicator, the Tiles window and the offline prefetch.
    pub tiles: crate::tiles::MapTiles,
    tile_hits: Rc<Cell<u32>>,
    tile_misses: Rc<Cell<u32>>,
    /// UI time since which no tile has been available although tiles are on [s].
    pub no_tiles_since_s: Option<f64>,
    /// Name of the route.
    pub route_name: String,
    /// The waypoints, in order.
    pub waypoints: Vec<Waypoint>,
    /// Index of the next waypoint.
    pub next: usize,
    /// The wearer's track, all segments one after the other: position, the fix's UTC time and altitude
    /// (what a GPX export writes as `<time>` and `<ele>`).
    pub track: Vec<TrackPoint>,
    /// Indices into `track` where a new segment starts (after a GPS source change or an implausible jump,
    /// see [`plausible_step`]); segments are drawn as separate lines.
    pub track_breaks: Vec<usize>,
    track_last: Option<TrackStamp>,
    /// How the wearer was drawn in the latest frame (`None`: no position), for tests and the status line.
    pub wearer_shown: Option<WearerMarker>,
    /// A track shown from a session log being replayed, and the replay cursor.
    pub replay: Option<(Vec<TrackPoint>, usize)>,
    /// Left click adds a waypoint.
    pub add_mode: bool,
    /// Operator marks made with the M key.
    pub marks: u32,
    /// GPX file path for import/export, as typed (relative: in `cfg.recent.base()`).
    pub gpx_path: String,
    /// The "Browse…" dialog of the route file field.
    pub gpx_browse: crate::file_dialog::Browse,
    /// The "Export as…" dialog.
    pub export_browse: crate::file_dialog::Browse,
    /// An export waiting for the operator's "Replace X?" answer: the typed file and what to write.
    pub pending_replace: Option<(PathBuf, RouteExport)>,
    right_click_at: Option<Position>,
    menu_wp: Option<usize>,
    /// Undo steps, oldest first (at most [`UNDO_STEPS`]).
    undo: VecDeque<UndoStep>,
    /// Redo steps, the most recently undone last.
    redo: Vec<UndoStep>,
    /// "Deleted WP3": shown with an **Undo delete** button after a delete or a clear, until the next edit.
    pub undo_notice: Option<String>,
    /// A problem the operator must read (e.g. an unreadable route autosave), shown until dismissed.
    pub notice: Option<String>,
    /// The waypoint editor (name and typed coordinates), when open.
    pub editor: Option<WaypointEditor>,
    /// The waypoint being dragged and the route before the drag began (one drag is one undo step).
    drag_before: Option<(usize, RouteState)>,
    /// The map tools: coordinates under the mouse, go-to, measuring, field-test overlay.
    pub tools: MapTools,
    /// The import dialog, when a GPX file offered more than one thing to import.
    pub import: Option<ImportDialog>,
}

/// What a route export writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RouteExport {
    /// GPX at the typed path.
    Gpx,
    /// `GeoJSON` at the typed path with `.geojson`.
    GeoJson,
}

/// The route file field's dialogs.
const ROUTE_OPEN: crate::file_dialog::DialogSpec = crate::file_dialog::DialogSpec {
    mode: crate::file_dialog::Mode::Open,
    title: "Route file (GPX)",
    filter: ("GPX", &["gpx"]),
};
const ROUTE_SAVE: crate::file_dialog::DialogSpec = crate::file_dialog::DialogSpec {
    mode: crate::file_dialog::Mode::Save,
    title: "Export the route as GPX",
    filter: ("GPX", &["gpx"]),
};

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

/// The waypoint editor's fields, as typed.
#[derive(Debug, Clone, PartialEq)]
pub struct WaypointEditor {
    /// Index of the waypoint edited.
    pub index: usize,
    /// Its name.
    pub name: String,
    /// Latitude in decimal degrees, as typed.
    pub lat: String,
    /// Longitude in decimal degrees, as typed.
    pub lon: String,
    /// The waypoint's own arrival radius in metres, as typed (empty: guidance's global radius).
    pub radius: String,
    /// Why the last Apply was refused (names the field).
    pub error: Option<String>,
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

/// A map position as waypoint coordinates within GPX's ranges: latitude clamped to [-90, 90], longitude
/// wrapped into [-180, 180) (the map can be panned past the antimeridian), so the route can always be
/// saved and read back.
fn waypoint_coords(p: Position) -> (f64, f64) {
    let lat_deg = if p.y().is_finite() { p.y().clamp(-90.0, 90.0) } else { 0.0 };
    let mut lon_deg = if p.x().is_finite() { (p.x() + 180.0).rem_euclid(360.0) - 180.0 } else { 0.0 };
    if lon_deg >= 180.0 {
        lon_deg -= 360.0;
    }
    (lat_deg, lon_deg)
}

/// A [`Tiles`] wrapper that counts tiles found and missing, to tell "offline" from "loading".
struct CountingTiles<'a> {
    inner: &'a mut crate::tiles::SourceTiles,
    hits: Rc<Cell<u32>>,
    misses: Rc<Cell<u32>>,
}

impl Tiles for CountingTiles<'_> {
    fn at(&mut self, tile_id: TileId) -> Option<TilePiece> {
        let t = self.inner.at(tile_id);
        let c = if t.is_some() { &self.hits } else { &self.misses };
        c.set(c.get() + 1);
        t
    }
    fn attribution(&self) -> walkers::sources::Attribution {
        self.inner.attribution()
    }
    fn tile_size(&self) -> u32 {
        self.inner.tile_size()
    }
}

/// A "nice" length (1, 2 or 5 × 10^k metres) of at least `min_m`.
pub fn nice_length_m(min_m: f64) -> f64 {
    let min_m = min_m.max(1e-3);
    let p = 10f64.powf(min_m.log10().floor());
    [1.0, 2.0, 5.0, 10.0].into_iter().map(|k| k * p).find(|&v| v >= min_m).unwrap_or(10.0 * p)
}

/// What the operator asked for on one waypoint, from the list or from the map's context menu.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum WaypointAction {
    /// Make it the next waypoint.
    Select,
    /// One place earlier in the route.
    MoveUp,
    /// One place later in the route.
    MoveDown,
    /// Remove it.
    Delete,
    /// Open the editor on it.
    Edit,
}

fn to_pos2(v: egui::Vec2) -> Pos2 {
    Pos2::new(v.x, v.y)
}

impl MapView {
    /// An empty map view.
    pub fn new(follow: bool) -> Self {
        let mut memory = MapMemory::default();
        let _ = memory.set_zoom(17.0);
        if !follow {
            memory.center_at(lat_lon(42.3573, -71.1010));
        }
        Self {
            memory,
            tiles: crate::tiles::MapTiles::default(),
            tile_hits: Rc::default(),
            tile_misses: Rc::default(),
            no_tiles_since_s: None,
            route_name: "route".into(),
            waypoints: Vec::new(),
            next: 0,
            track: Vec::new(),
            track_breaks: Vec::new(),
            track_last: None,
            wearer_shown: None,
            replay: None,
            add_mode: false,
            marks: 0,
            gpx_path: String::new(),
            gpx_browse: crate::file_dialog::Browse::default(),
            export_browse: crate::file_dialog::Browse::default(),
            pending_replace: None,
            right_click_at: None,
            menu_wp: None,
            undo: VecDeque::new(),
            redo: Vec::new(),
            undo_notice: None,
            notice: None,
            editor: None,
            drag_before: None,
            tools: MapTools::default(),
            import: None,
        }
    }

    /// The route as it stands (name, waypoints, next).
    pub fn route_state(&self) -> RouteState {
        RouteState { name: self.route_name.clone(), waypoints: self.waypoints.clone(), next: self.next }
    }

    /// Records the edit just made (the route was `before`) as one undo step; clears the redo steps, the
    /// delete notice and the editor. Nothing is recorded when the route did not change.
    fn commit(&mut self, what: String, before: RouteState) {
        if before.is(&self.route_name, &self.waypoints, self.next) {
            return;
        }
        if self.undo.len() >= UNDO_STEPS {
            self.undo.pop_front();
        }
        self.undo.push_back(UndoStep { what, state: before, left_next: self.next });
        self.redo.clear();
        self.undo_notice = None;
        self.editor = None;
    }

    /// Puts `step`'s route in place and returns the step that goes back to the route it replaced.
    fn swap_in(&mut self, step: UndoStep) -> UndoStep {
        let current = RouteState {
            name: std::mem::take(&mut self.route_name),
            waypoints: std::mem::take(&mut self.waypoints),
            next: self.next,
        };
        let UndoStep { what, state, left_next } = step;
        self.route_name = state.name;
        self.waypoints = state.waypoints;
        let next = if current.next == left_next { state.next } else { current.next };
        self.next = next.min(self.waypoints.len());
        self.undo_notice = None;
        self.editor = None;
        self.drag_before = None;
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
    pub fn clear_route(&mut self) {
        if self.waypoints.is_empty() {
            return;
        }
        let before = self.route_state();
        let n = before.waypoints.len();
        self.waypoints.clear();
        self.next = 0;
        self.commit("clear route".to_owned(), before);
        self.undo_notice = Some(format!("Cleared the route ({n} waypoints)"));
    }

    /// Replaces the route with an imported one (one undo step).
    pub fn replace_route(&mut self, name: String, waypoints: Vec<Waypoint>) {
        let before = self.route_state();
        let what = format!("import {name}");
        self.route_name = name;
        self.waypoints = waypoints;
        self.next = 0;
        self.commit(what, before);
    }

    /// Renames waypoint `i` and sets its position from typed text (decimal degrees): one undo step.
    /// Errors name the field (`Name`, `Latitude`, `Longitude`) and change nothing.
    pub fn edit_waypoint(&mut self, i: usize, name: &str, lat: &str, lon: &str) -> Result<(), String> {
        let radius = self.waypoints.get(i).and_then(|w| w.arrival_radius_m);
        self.edit_waypoint_with_radius(i, name, lat, lon, radius)
    }

    /// Like [`Self::edit_waypoint`], also setting the waypoint's own arrival radius [m] (`None`: guidance's
    /// global radius). A radius that is not a positive finite number is refused, naming the field.
    pub fn edit_waypoint_with_radius(
        &mut self,
        i: usize,
        name: &str,
        lat: &str,
        lon: &str,
        radius_m: Option<f64>,
    ) -> Result<(), String> {
        if radius_m.is_some_and(|r| !(r.is_finite() && r > 0.0)) {
            return Err(
                "Arrival radius: must be a positive number of metres (empty: the global radius)".into()
            );
        }
        let name = name.trim();
        if name.is_empty() {
            return Err("Name: must not be empty".to_owned());
        }
        let lat_deg = parse_coordinate(lat, Coordinate::Latitude)?;
        let lon_deg = parse_coordinate(lon, Coordinate::Longitude)?;
        let Some(old) = self.waypoints.get(i).cloned() else {
            return Err(format!("waypoint {} no longer exists", i + 1));
        };
        let moved = old.lat_deg.to_bits() != lat_deg.to_bits() || old.lon_deg.to_bits() != lon_deg.to_bits();
        let radius_changed = old.arrival_radius_m != radius_m;
        let what = match (old.name != name, moved, radius_changed) {
            (true, false, false) => format!("rename {} to {name}", old.name),
            (false, true, false) => format!("move {} to typed coordinates", old.name),
            (false, false, true) => format!("arrival radius of {}", old.name),
            _ => format!("edit {}", old.name),
        };
        let before = self.route_state();
        if let Some(w) = self.waypoints.get_mut(i) {
            *w = Waypoint { name: name.to_owned(), lat_deg, lon_deg, arrival_radius_m: radius_m };
        }
        self.commit(what, before);
        Ok(())
    }

    /// Opens the editor on waypoint `i` with its current values.
    pub fn open_editor(&mut self, i: usize) {
        self.editor = self.waypoints.get(i).map(|w| WaypointEditor {
            index: i,
            name: w.name.clone(),
            lat: w.lat_deg.to_string(),
            lon: w.lon_deg.to_string(),
            radius: w.arrival_radius_m.map_or_else(String::new, |r| r.to_string()),
            error: None,
        });
    }

    /// Appends the position of `fix` to the wearer's track, starting a new segment when the step from the
    /// previous point is not one a walker can make in the time between them ([`plausible_step`]).
    pub fn push_track(&mut self, fix: &Fix) {
        let (Some(lat_deg), Some(lon_deg)) = (fix.lat_deg, fix.lon_deg) else { return };
        if !(lat_deg.is_finite() && lon_deg.is_finite()) {
            return;
        }
        let at = (lat_deg, lon_deg);
        if let Some(prev) = &self.track_last
            && !plausible_step(prev.at, at, fix_dt_s(prev, fix))
        {
            self.break_track();
        }
        self.track.push(TrackPoint {
            lat_deg,
            lon_deg,
            ele_m: fix.alt_m.filter(|a| a.is_finite()),
            time: fix.time,
        });
        self.track_last = Some(TrackStamp { at, time: fix.time, received_at: fix.received_at });
    }

    /// Ends the current track segment: the next point starts a new one (the GPS source changed).
    pub fn break_track(&mut self) {
        let n = self.track.len();
        if n > 0 && self.track_breaks.last() != Some(&n) {
            self.track_breaks.push(n);
        }
        self.track_last = None;
    }

    /// The track's segments, oldest first, none empty.
    pub fn track_segments(&self) -> Vec<&[TrackPoint]> {
        segments(&self.track, &self.track_breaks).map(|r| &self.track[r]).collect()
    }

    fn anchor(&self) -> (f64, f64) {
        self.waypoints
            .first()
            .map(|w| (w.lat_deg, w.lon_deg))
            .or_else(|| self.track.first().map(|p| (p.lat_deg, p.lon_deg)))
            .unwrap_or((42.3573, -71.1010))
    }

    /// Draws the map tab; returns whether the route changed (the guidance worker must hear of it).
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        fix: Option<&Fix>,
        guidance: Option<&GuidanceStatus>,
        walking_m_s: f64,
        cfg: &mut Config,
        status: &mut String,
    ) -> bool {
        let mut changed = false;
        if !ui.ctx().text_edit_focused() {
            // The more specific shortcut first: Ctrl+Z alone also matches Ctrl+Shift+Z.
            let (redo, undo) = ui.input_mut(|i| {
                let redo = i
                    .consume_shortcut(&KeyboardShortcut::new(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z))
                    || i.consume_shortcut(&KeyboardShortcut::new(Modifiers::COMMAND, Key::Y));
                (redo, !redo && i.consume_shortcut(&KeyboardShortcut::new(Modifiers::COMMAND, Key::Z)))
            });
            changed |= (redo && self.redo()) || (undo && self.undo());
        }
        if let Some(n) = self.notice.clone() {
            ui.horizontal_wrapped(|ui| {
                ui.label(RichText::new(n).strong().color(ui.visuals().warn_fg_color));
                if ui.small_button("Dismiss").clicked() {
                    self.notice = None;
                }
            });
        }
        self.toolbar(ui, cfg, status);
        changed |= self.file_row(ui, cfg, status);
        changed |= self.import_dialog(ui, status);
        if let Some(e) = &self.tools.goto_error {
            ui.label(RichText::new(format!("Go to: {e}")).color(ui.visuals().error_fg_color));
        }
        self.tools_line(ui);
        let speed_m_s = fix.and_then(|f| f.speed_m_s);
        self.next_info(ui, fix, guidance, speed_m_s, walking_m_s);
        egui::Panel::right("waypoint-list").default_size(290.0).show(ui, |ui| {
            changed |= self.waypoint_list(ui);
        });
        changed |= self.map_ui(ui, fix, guidance.and_then(|g| g.heading_deg), cfg);
        self.next = self.next.min(self.waypoints.len());
        changed
    }

    fn toolbar(&mut self, ui: &mut egui::Ui, cfg: &mut Config, status: &mut String) {
        ui.horizontal_wrapped(|ui| {
            if ui.toggle_value(&mut cfg.follow, "Follow wearer").changed() && cfg.follow {
                self.memory.follow_my_position();
            }
            ui.toggle_value(&mut self.add_mode, "Add waypoints");
            if ui.button(" + ").on_hover_text("Zoom in").clicked() {
                let _ = self.memory.zoom_in();
            }
            if ui.button(" - ").on_hover_text("Zoom out").clicked() {
                let _ = self.memory.zoom_out();
            }
            self.tiles.toolbar(ui, cfg, &self.waypoints);
            ui.separator();
            if ui
                .toggle_value(&mut self.tools.measuring, "Measure")
                .on_hover_text("Click two points on the map: geodesic distance and bearing")
                .changed()
            {
                self.tools.measure_points.clear();
            }
            let goto = ui.add(
                egui::TextEdit::singleline(&mut self.tools.goto_text)
                    .hint_text("42.3573, -71.1010 / DMS / UTM / MGRS")
                    .desired_width(200.0),
            );
            let enter = goto.lost_focus() && ui.input(|i| i.key_pressed(Key::Enter));
            if ui.button("Go to").on_hover_text("Centre the map on the typed position").clicked() || enter {
                match map_tools::parse_position(&self.tools.goto_text) {
                    Ok(p) => {
                        self.memory.center_at(lat_lon(p.lat_deg, p.lon_deg));
                        cfg.follow = false;
                        self.tools.goto_error = None;
                        *status = format!("map centred on {}", map_tools::format_decimal(p));
                    }
                    Err(e) => self.tools.goto_error = Some(e),
                }
            }
            ui.separator();
            if ui.button("Clear track").clicked() {
                self.track.clear();
                self.track_breaks.clear();
                self.track_last = None;
                self.replay = None;
            }
        });
    }

    /// The route file: the typed path with Browse… and the path it uses, Recent, Import, the exports (each
    /// asking "Replace X?" before writing over a file). Returns whether the route changed.
    fn file_row(&mut self, ui: &mut egui::Ui, cfg: &mut Config, status: &mut String) -> bool {
        use crate::file_dialog::{self as fd, RecentKind};
        let mut changed = false;
        let base = cfg.recent.base();
        ui.horizontal(|ui| {
            ui.label("Route file:");
            ui.vertical(|ui| {
                fd::path_field(ui, &mut self.gpx_path, &mut self.gpx_browse, ROUTE_OPEN, &base, "file.gpx");
            });
        });
        if let Some(fd::Picked::File(p)) = self.export_browse.poll() {
            self.gpx_path = p.display().to_string();
            self.export(RouteExport::Gpx, p, false, cfg, status);
        }
        ui.horizontal_wrapped(|ui| {
            if let Some(p) = fd::recent_menu(ui, &cfg.recent, RecentKind::Routes) {
                self.gpx_path = p.display().to_string();
                changed |= self.import_gpx(&p, cfg, status);
            }
            if ui.button("Import GPX").clicked() {
                match fd::resolve(&self.gpx_path, &base) {
                    Some(p) => changed |= self.import_gpx(&p, cfg, status),
                    None => "GPX import: type a file path or Browse… first".clone_into(status),
                }
            }
            for (label, kind) in [("Export GPX", RouteExport::Gpx), ("Export GeoJSON", RouteExport::GeoJson)]
            {
                let button = ui.button(label);
                let button = if kind == RouteExport::GeoJson {
                    button.on_hover_text("the path with .geojson, for QGIS")
                } else {
                    button
                };
                if button.clicked() {
                    match fd::resolve(&self.gpx_path, &base) {
                        Some(p) => self.export(kind, p, false, cfg, status),
                        None => *status = format!("{label}: type a file path or Browse… first"),
                    }
                }
            }
            if ui
                .add_enabled(!self.export_browse.is_open(), egui::Button::new("Export GPX as…"))
                .on_hover_text("Name the GPX file in the desktop's file dialog")
                .clicked()
            {
                let current = fd::resolve(&self.gpx_path, &base);
                let dir = current.as_deref().and_then(Path::parent).filter(|d| d.is_dir()).unwrap_or(&base);
                let name = current
                    .as_deref()
                    .and_then(Path::file_name)
                    .map_or_else(|| format!("{}.gpx", self.route_name), |n| n.to_string_lossy().into_owned());
                self.export_browse.start(ui.ctx(), ROUTE_SAVE, dir, Some(&name));
            }
        });
        if let Some(note) = &self.export_browse.note {
            ui.label(RichText::new(note).small().color(ui.visuals().warn_fg_color));
        }
        if let Some((path, kind)) = self.pending_replace.clone() {
            let target = Self::export_target(kind, &path);
            match fd::confirm_replace(ui.ctx(), &target) {
                Some(fd::Answer::Replace) => {
                    self.pending_replace = None;
                    self.export(kind, path, true, cfg, status);
                }
                Some(fd::Answer::Cancel) => {
                    self.pending_replace = None;
                    *status = format!("{} left as it was", target.display());
                }
                None => {}
            }
        }
        changed
    }

    fn export_target(kind: RouteExport, path: &Path) -> PathBuf {
        match kind {
            RouteExport::Gpx => path.to_path_buf(),
            RouteExport::GeoJson => crate::route::geojson_path(path),
        }
    }

    /// Exports the route and track to `path` (absolute); an existing file is replaced only when `replace`,
    /// else the operator is asked first. A GPX export joins the recent route files.
    fn export(
        &mut self,
        kind: RouteExport,
        path: PathBuf,
        replace: bool,
        cfg: &mut Config,
        status: &mut String,
    ) {
        let target = Self::export_target(kind, &path);
        if !replace && target.exists() {
            self.pending_replace = Some((path, kind));
            return;
        }
        let segments = self.track_segments();
        let result = match kind {
            RouteExport::Gpx => {
                crate::route::export_gpx(&path, &self.route_name, &self.waypoints, &segments, replace)
            }
            RouteExport::GeoJson => {
                crate::route::export_geojson(&path, &self.route_name, &self.waypoints, &segments, replace)
            }
        };
        *status = match result {
            Ok(msg) => {
                match kind {
                    RouteExport::Gpx => cfg.recent.push(crate::file_dialog::RecentKind::Routes, &target),
                    RouteExport::GeoJson => cfg.recent.used(&target),
                }
                msg
            }
            Err(e) if kind == RouteExport::Gpx => format!("GPX export failed: {e}"),
            Err(e) => format!("GeoJSON export failed: {e}"),
        };
    }

    /// Imports the GPX file at `path`: straight away when it holds one thing, else through the import
    /// dialog. The file joins the recent route files once read. Returns whether the route changed.
    fn import_gpx(&mut self, path: &Path, cfg: &mut Config, status: &mut String) -> bool {
        let file = match vestnav_device::route_file::read_gpx(path) {
            Ok(file) => file,
            Err(e) => {
                *status = format!("GPX import failed: {e}");
                return false;
            }
        };
        cfg.recent.push(crate::file_dialog::RecentKind::Routes, path);
        let track: Vec<TrackPoint> =
            file.tracks.iter().flat_map(vestnav_device::route_file::Track::points).cloned().collect();
        if !track.is_empty() {
            self.replay = Some((track, usize::MAX));
        }
        let shown = path.display().to_string();
        let mut choices = crate::route_import::choices(&file);
        match choices.len() {
            0 => *status = format!("{shown} holds no waypoint, route or track"),
            1 => {
                let c = choices.remove(0);
                *status = format!("imported {}", c.label);
                self.import_choice(c);
                return true;
            }
            _ => {
                *status = format!("{shown} holds {} things: choose one", choices.len());
                self.import = Some(ImportDialog { path: shown, choices });
            }
        }
        false
    }

    /// The measuring tool's result and the coordinates under the mouse, in one line each.
    fn tools_line(&self, ui: &mut egui::Ui) {
        if self.tools.measuring {
            let text = match (self.tools.measurement(), self.tools.measure_points.len()) {
                (Some(m), _) => format!("Measured: {}", map_tools::measurement_text(&m)),
                (None, 1) => "Measure: click the second point".to_owned(),
                _ => "Measure: click the first point".to_owned(),
            };
            ui.label(RichText::new(text).strong());
        }
        // Always one line, so the map below does not move when the mouse enters or leaves it.
        let text = self.tools.pointer.map_or_else(
            || "Mouse: move over the map for its coordinates".to_owned(),
            |p| map_tools::coordinate_lines(p).join("   "),
        );
        ui.label(RichText::new(text).small().monospace());
    }

    /// Replaces the route with an imported choice (one undo step).
    pub fn import_choice(&mut self, c: ImportChoice) {
        self.replace_route(c.name, c.waypoints);
        self.import = None;
    }

    /// The import dialog (when open): one button per thing the file holds; returns whether the route
    /// changed.
    fn import_dialog(&mut self, ui: &mut egui::Ui, status: &mut String) -> bool {
        let Some(dialog) = &self.import else { return false };
        let mut picked = None;
        let mut close = false;
        egui::Window::new("Import from GPX").collapsible(false).resizable(false).show(ui.ctx(), |ui| {
            ui.label(format!("{} holds:", dialog.path));
            for (k, c) in dialog.choices.iter().enumerate() {
                if ui.button(&c.label).clicked() {
                    picked = Some(k);
                }
            }
            close = ui.button("Cancel").clicked();
        });
        if close {
            self.import = None;
        }
        let Some(c) = picked.and_then(|k| self.import.as_mut().map(|d| d.choices.swap_remove(k))) else {
            return false;
        };
        *status = format!("imported {}", c.label);
        self.import_choice(c);
        true
    }

    /// The line about the next waypoint. Distance and bearing are core guidance's (the one home of the
    /// navigation logic), from its latest status for this waypoint; the map only turns them into words.
    fn next_info(
        &self,
        ui: &mut egui::Ui,
        fix: Option<&Fix>,
        guidance: Option<&GuidanceStatus>,
        speed_m_s: Option<f64>,
        walking_m_s: f64,
    ) {
        let mut warning = None;
        let text = match (fix, self.waypoints.get(self.next)) {
            (_, None) if self.waypoints.is_empty() => {
                "no waypoints: right-click the map to add one".to_owned()
            }
            (_, None) => "route finished".to_owned(),
            (None, Some(w)) => {
                format!("next: {} ({}/{}) · waiting for a fix", w.name, self.next + 1, self.waypoints.len())
            }
            (Some(_), Some(w)) => match guidance
                .filter(|st| st.next == self.next)
                .and_then(|st| st.distance_m.filter(|d| d.is_finite()).map(|d| (d, st.bearing_deg)))
            {
                None => format!(
                    "next: {} ({}/{}) · waiting for guidance",
                    w.name,
                    self.next + 1,
                    self.waypoints.len()
                ),
                Some((d, bearing)) => {
                    let v = speed_m_s.filter(|v| *v >= 0.3).unwrap_or(walking_m_s).max(0.1);
                    let leg = leg_summary(d, bearing, v);
                    warning = leg.warning;
                    format!("next: {} ({}/{}) · {}", w.name, self.next + 1, self.waypoints.len(), leg.text)
                }
            },
        };
        ui.label(RichText::new(text).strong());
        if let Some(w) = warning {
            ui.label(RichText::new(w).strong().color(ui.visuals().warn_fg_color));
        }
    }

    fn waypoint_list(&mut self, ui: &mut egui::Ui) -> bool {
        let mut changed = false;
        ui.label(RichText::new(format!("{} ({} waypoints)", self.route_name, self.waypoints.len())).strong());
        ui.horizontal(|ui| {
            let undo = ui
                .add_enabled(!self.undo.is_empty(), egui::Button::new("Undo"))
                .on_hover_text(format!("Undo {} (Ctrl+Z)", self.undo_label().unwrap_or("")))
                .on_disabled_hover_text("Nothing to undo");
            if undo.clicked() {
                changed |= self.undo();
            }
            let redo = ui
                .add_enabled(!self.redo.is_empty(), egui::Button::new("Redo"))
                .on_hover_text(format!("Redo {} (Ctrl+Shift+Z or Ctrl+Y)", self.redo_label().unwrap_or("")))
                .on_disabled_hover_text("Nothing to redo");
            if redo.clicked() {
                changed |= self.redo();
            }
            let clear = ui
                .add_enabled(!self.waypoints.is_empty(), egui::Button::new("Clear route"))
                .on_hover_text("Remove every waypoint (Undo brings them back)");
            if clear.clicked() {
                self.clear_route();
                changed = true;
            }
        });
        if let Some(n) = self.undo_notice.clone() {
            ui.horizontal_wrapped(|ui| {
                ui.label(RichText::new(n).strong());
                if ui.small_button("Undo delete").clicked() {
                    changed |= self.undo();
                }
            });
        }
        changed |= self.editor_ui(ui);
        let mut action: Option<(usize, WaypointAction)> = None;
        egui::ScrollArea::vertical().show_rows(ui, 22.0, self.waypoints.len(), |ui, range| {
            for i in range {
                let w = &self.waypoints[i];
                ui.horizontal(|ui| {
                    let marker = if i == self.next { "> " } else { "" };
                    if ui.selectable_label(i == self.next, format!("{marker}{} {}", i + 1, w.name)).clicked()
                    {
                        action = Some((i, WaypointAction::Select));
                    }
                    if ui.small_button("Edit").on_hover_text("Rename, type coordinates").clicked() {
                        action = Some((i, WaypointAction::Edit));
                    }
                    if ui.small_button("Up").on_hover_text("Move earlier").clicked() {
                        action = Some((i, WaypointAction::MoveUp));
                    }
                    if ui.small_button("Down").on_hover_text("Move later").clicked() {
                        action = Some((i, WaypointAction::MoveDown));
                    }
                    if ui.small_button("Del").on_hover_text("Delete (Undo brings it back)").clicked() {
                        action = Some((i, WaypointAction::Delete));
                    }
                });
            }
        });
        if let Some((i, a)) = action {
            changed |= a != WaypointAction::Edit;
            self.apply_waypoint_action(i, a);
        }
        changed
    }

    /// The waypoint editor (when open): name, latitude and longitude; Apply (or Enter) checks and applies
    /// them as one undo step.
    fn editor_ui(&mut self, ui: &mut egui::Ui) -> bool {
        let Some(ed) = &mut self.editor else { return false };
        let (mut apply, mut cancel) = (false, false);
        ui.group(|ui| {
            ui.label(RichText::new(format!("Edit waypoint {}", ed.index + 1)).strong());
            egui::Grid::new("waypoint-editor").num_columns(2).show(ui, |ui| {
                for (label, text) in [
                    ("Name", &mut ed.name),
                    ("Latitude (deg)", &mut ed.lat),
                    ("Longitude (deg)", &mut ed.lon),
                    ("Arrival radius (m)", &mut ed.radius),
                ] {
                    let l = ui.label(label);
                    let r = ui.add(egui::TextEdit::singleline(text).desired_width(150.0)).labelled_by(l.id);
                    apply |= r.lost_focus() && ui.input(|i| i.key_pressed(Key::Enter));
                    ui.end_row();
                }
            });
            if let Some(e) = &ed.error {
                ui.label(RichText::new(e).strong().color(ui.visuals().error_fg_color));
            }
            ui.horizontal(|ui| {
                apply |= ui.button("Apply").clicked();
                cancel = ui.button("Cancel").clicked();
            });
        });
        if cancel {
            self.editor = None;
            return false;
        }
        if !apply {
            return false;
        }
        let ed = ed.clone();
        let radius = match ed.radius.trim() {
            "" => Ok(None),
            t => t.replace(',', ".").parse::<f64>().map(Some).map_err(|_| {
                format!("Arrival radius: '{t}' is not a number of metres (empty: the global radius)")
            }),
        };
        let result =
            radius.and_then(|r| self.edit_waypoint_with_radius(ed.index, &ed.name, &ed.lat, &ed.lon, r));
        match result {
            Ok(()) => {
                self.editor = None;
                true
            }
            Err(e) => {
                if let Some(open) = &mut self.editor {
                    open.error = Some(e);
                }
                false
            }
        }
    }

    fn apply_waypoint_action(&mut self, i: usize, action: WaypointAction) {
        match action {
            WaypointAction::Select => self.next = i,
            WaypointAction::MoveUp => self.move_waypoint(i, -1),
            WaypointAction::MoveDown => self.move_waypoint(i, 1),
            WaypointAction::Delete => self.delete_waypoint(i),
            WaypointAction::Edit => self.open_editor(i),
        }
    }

    /// Moves waypoint `i` one place earlier (`-1`) or later (`1`).
    pub fn move_waypoint(&mut self, i: usize, dir: i32) {
        let j = if dir < 0 { i.checked_sub(1) } else { Some(i + 1) };
        if let Some(j) = j.filter(|&j| j < self.waypoints.len()) {
            let before = self.route_state();
            self.waypoints.swap(i, j);
            let way = if dir < 0 { "earlier" } else { "later" };
            self.commit(format!("move {} {way}", self.waypoints[j].name), before);
        }
    }

    /// Deletes waypoint `i`, keeping the next waypoint the same where possible; undoable at once (the
    /// delete notice says so).
    pub fn delete_waypoint(&mut self, i: usize) {
        if i < self.waypoints.len() {
            let before = self.route_state();
            let w = self.waypoints.remove(i);
            if i < self.next {
                self.next -= 1;
            }
            self.commit(format!("delete {}", w.name), before);
            self.undo_notice = Some(format!("Deleted {}", w.name));
        }
    }

    /// Adds a waypoint at `pos`: at the end, or right before the next one when `as_next`.
    pub fn add_waypoint(&mut self, pos: Position, as_next: bool) {
        let before = self.route_state();
        let n = self.waypoints.len() + 1;
        let (lat_deg, lon_deg) = waypoint_coords(pos);
        let w = Waypoint::new(format!("WP{n}"), lat_deg, lon_deg);
        let what = format!("add {}", w.name);
        if as_next && self.next <= self.waypoints.len() {
            self.waypoints.insert(self.next, w);
        } else {
            self.waypoints.push(w);
        }
        self.commit(what, before);
    }

    #[allow(clippy::too_many_lines)] // one paint pass over every layer of the map, in order
    fn map_ui(
        &mut self,
        ui: &mut egui::Ui,
        fix: Option<&Fix>,
        heading_deg: Option<f64>,
        cfg: &mut Config,
    ) -> bool {
        let mut changed = false;
        let wearer = fix.and_then(|f| f.lat_deg.zip(f.lon_deg)).map(|(la, lo)| lat_lon(la, lo));
        let marker =
            fix.filter(|_| wearer.is_some()).map(|f| wearer_marker(f, Instant::now(), cfg.stale_after_s));
        self.wearer_shown = marker;
        let anchor = self.anchor();
        let my_position = wearer.unwrap_or_else(|| lat_lon(anchor.0, anchor.1));
        self.tile_hits.set(0);
        self.tile_misses.set(0);
        let tile_notes = (self.tiles.note(cfg, false), self.tiles.note(cfg, true));
        let mut counting = self.tiles.active(cfg, ui.ctx()).map(|t| CountingTiles {
            inner: t,
            hits: self.tile_hits.clone(),
            misses: self.tile_misses.clone(),
        });
        let tiles_dyn = counting.as_mut().map(|t| t as &mut dyn Tiles);
        let now_s = ui.input(|i| i.time);
        let tiles_missing_s = self.no_tiles_since_s.map_or(0.0, |t| now_s - t);
        let tiles_on = cfg.map_tiles;
        // Borrow the fields the closure needs separately from walkers' memory.
        let waypoints = &mut self.waypoints;
        let next = &mut self.next;
        let track = &self.track;
        let track_breaks = &self.track_breaks;
        let replay = &self.replay;
        let add_mode = self.add_mode && !self.tools.measuring;
        let measuring = self.tools.measuring;
        let measure_points = self.tools.measure_points.clone();
        let field = &self.tools.field;
        let right_click_at = &mut self.right_click_at;
        let menu_wp = &mut self.menu_wp;
        let route_name = &self.route_name;
        let drag_before = &mut self.drag_before;
        let mut dragging = false;
        let map = walkers::Map::new(tiles_dyn, &mut self.memory, my_position)
            .double_click_to_zoom(true)
            .zoom_with_ctrl(false);
        let resp = map.show(ui, |ui, response, projector, _memory| {
            let rect = response.rect;
            let painter = ui.painter_at(rect);
            let offline = !tiles_on || tiles_missing_s > TILES_OFFLINE_AFTER_S;
            if offline {
                painter.rect_filled(rect, 0.0, ui.visuals().extreme_bg_color);
            }
            let px_per_m =
                f64::from(projector.scale_pixel_per_meter(projector.unproject(rect.center().to_vec2())));
            draw_grid(&painter, projector, rect, anchor, px_per_m, offline, ui.visuals().dark_mode);

            // Route line, the leg to the next waypoint highlighted.
            let pts: Vec<Pos2> =
                waypoints.iter().map(|w| to_pos2(projector.project(lat_lon(w.lat_deg, w.lon_deg)))).collect();
            if pts.len() >= 2 {
                painter.line(pts.clone(), Stroke::new(2.0, Color32::from_rgb(60, 120, 220)));
            }
            if let (Some(w), Some(p)) = (wearer, pts.get(*next)) {
                painter.line_segment(
                    [to_pos2(projector.project(w)), *p],
                    Stroke::new(2.5, Color32::from_rgb(240, 140, 0)),
                );
            }

            // Replay track from a session log / GPX import.
            if let Some((rt, cursor)) = replay {
                draw_track(
                    &painter,
                    projector,
                    &rt[..(*cursor).min(rt.len())],
                    &[],
                    Color32::from_rgb(150, 60, 200),
                );
                if let Some(p) = rt.get((*cursor).min(rt.len()).saturating_sub(1)) {
                    painter.circle_filled(
                        to_pos2(projector.project(lat_lon(p.lat_deg, p.lon_deg))),
                        6.0,
                        Color32::from_rgb(150, 60, 200),
                    );
                }
            }
            // The wearer's own track.
            draw_track(&painter, projector, track, track_breaks, Color32::from_rgb(220, 50, 50));

            // Waypoints, draggable, with a context menu.
            let mut action: Option<(usize, WaypointAction)> = None;
            let font = egui::FontId::proportional(12.0);
            let visible: Vec<usize> =
                (0..pts.len()).filter(|&i| rect.expand(20.0).contains(pts[i])).collect();
            let crowded = visible.len() > 200;
            let pointer = ui.ctx().pointer_hover_pos();
            for i in visible {
                let p = &pts[i];
                let fill = match i.cmp(&*next) {
                    std::cmp::Ordering::Equal => Color32::from_rgb(240, 140, 0),
                    std::cmp::Ordering::Less => Color32::from_rgb(120, 160, 120),
                    std::cmp::Ordering::Greater => Color32::from_rgb(60, 120, 220),
                };
                let id = egui::Id::unique(("vestnav-waypoint", i));
                // Only waypoints under the pointer, being dragged or with their menu open need a widget:
                // a thousand idle interaction rects would cost milliseconds per frame.
                let near = pointer.is_some_and(|q| q.distance(*p) < 24.0);
                if !(near || ui.ctx().is_being_dragged(id) || *menu_wp == Some(i)) {
                    if crowded {
                        painter.circle_filled(*p, 5.0, fill);
                    } else {
                        painter.circle(*p, 8.0, fill, Stroke::new(1.5, Color32::WHITE));
                        painter.text(
                            *p,
                            egui::Align2::CENTER_CENTER,
                            (i + 1).to_string(),
                            font.clone(),
                            Color32::WHITE,
                        );
                        painter.text(
                            *p + vec2(12.0, -12.0),
                            egui::Align2::LEFT_BOTTOM,
                            &waypoints[i].name,
                            font.clone(),
                            ui.visuals().strong_text_color(),
                        );
                    }
                    continue;
                }
                let r = ui.interact(
                    egui::Rect::from_center_size(*p, vec2(18.0, 18.0)),
                    id,
                    egui::Sense::click_and_drag(),
                );
                if r.dragged()
                    && let Some(pos) = r.interact_pointer_pos()
                {
                    if drag_before.is_none() {
                        let before = RouteState {
                            name: route_name.clone(),
                            waypoints: waypoints.clone(),
                            next: *next,
                        };
                        *drag_before = Some((i, before));
                    }
                    dragging = true;
                    (waypoints[i].lat_deg, waypoints[i].lon_deg) =
                        waypoint_coords(projector.unproject(pos.to_vec2()));
                    changed = true;
                }
                painter.circle(
                    *p,
                    if r.hovered() || r.dragged() { 10.0 } else { 8.0 },
                    fill,
                    Stroke::new(1.5, Color32::WHITE),
                );
                painter.text(
                    *p,
                    egui::Align2::CENTER_CENTER,
                    (i + 1).to_string(),
                    font.clone(),
                    Color32::WHITE,
                );
                if r.secondary_clicked() {
                    *menu_wp = Some(i);
                }
                {
                    painter.text(
                        *p + vec2(12.0, -12.0),
                        egui::Align2::LEFT_BOTTOM,
                        &waypoints[i].name,
                        font.clone(),
                        ui.visuals().strong_text_color(),
                    );
                }
                let open = r.context_menu(|ui| {
                    ui.label(RichText::new(&waypoints[i].name).strong());
                    if ui.button("Make next").clicked() {
                        action = Some((i, WaypointAction::Select));
                    }
                    if ui.button("Move earlier").clicked() {
                        action = Some((i, WaypointAction::MoveUp));
                    }
                    if ui.button("Move later").clicked() {
                        action = Some((i, WaypointAction::MoveDown));
                    }
                    if ui.button("Delete waypoint").clicked() {
                        action = Some((i, WaypointAction::Delete));
                    }
                });
                if open.is_none() && *menu_wp == Some(i) && !r.secondary_clicked() {
                    *menu_wp = None;
                }
            }

            // The wearer: accuracy circle, dot, course arrow (blue, COG) and the heading guidance steers by
            // (orange: the compass, or whatever the heading rule chose; true north up). A position that is
            // no longer current is drawn grey with its age, without the course it had.
            if let (Some(w), Some(f), Some(m)) = (wearer, fix, marker) {
                let c = to_pos2(projector.project(w));
                let (dot, ring) = if m.live {
                    (Color32::from_rgb(20, 90, 200), Color32::from_rgb(40, 140, 255))
                } else {
                    (Color32::from_gray(120), Color32::from_gray(150))
                };
                if let Some(e) = f.error.map(|e| e.horizontal_m).filter(|e| e.is_finite() && *e > 0.0) {
                    let r = (e * px_per_m) as f32;
                    painter.circle(c, r.min(4000.0), ring.gamma_multiply(0.16), Stroke::new(1.0, ring));
                }
                if m.live
                    && let (Some(course), Some(v)) = (f.course_deg, f.speed_m_s)
                    && v >= 0.3
                    && course.is_finite()
                {
                    let a = (course as f32).to_radians();
                    let tip = c + vec2(a.sin(), -a.cos()) * 22.0;
                    painter.arrow(c, tip - c, Stroke::new(3.0, Color32::from_rgb(20, 90, 200)));
                }
                if let Some(h) = heading_deg.filter(|h| h.is_finite()) {
                    let a = (h as f32).to_radians();
                    let tip = c + vec2(a.sin(), -a.cos()) * 34.0;
                    painter.arrow(c, tip - c, Stroke::new(2.5, Color32::from_rgb(240, 140, 20)));
                }
                painter.circle(c, 7.0, dot, Stroke::new(2.0, Color32::WHITE));
                if !m.live {
                    painter.text(
                        c + vec2(12.0, 12.0),
                        egui::Align2::LEFT_TOP,
                        format!("last known, {}", age_text(m.age_s)),
                        font.clone(),
                        ui.visuals().strong_text_color(),
                    );
                }
            }

            // The measuring tool's line, its ends and its result at the second point.
            let accent = Color32::from_rgb(230, 30, 140);
            let ends: Vec<Pos2> = measure_points
                .iter()
                .map(|p| to_pos2(projector.project(lat_lon(p.lat_deg, p.lon_deg))))
                .collect();
            if let [a, b] = ends.as_slice() {
                painter.line_segment([*a, *b], Stroke::new(2.5, accent));
            }
            for e in &ends {
                painter.circle(*e, 4.5, accent, Stroke::new(1.5, Color32::WHITE));
            }
            if let ([a, b], [_, pb]) = (measure_points.as_slice(), ends.as_slice()) {
                let m = map_tools::measure(*a, *b);
                painter.text(
                    *pb + vec2(10.0, 10.0),
                    egui::Align2::LEFT_TOP,
                    map_tools::measurement_text(&m),
                    font.clone(),
                    ui.visuals().strong_text_color(),
                );
            }

            // Field tests running: drift fixes (small dots) and cone marks (labelled triangles).
            let cone_color = Color32::from_rgb(255, 120, 0);
            let drift_color = Color32::from_rgb(0, 150, 140);
            for p in &field.drift {
                painter.circle_filled(
                    to_pos2(projector.project(lat_lon(p.lat_deg, p.lon_deg))),
                    2.5,
                    drift_color,
                );
            }
            for (label, p) in &field.cones {
                let c = to_pos2(projector.project(lat_lon(p.lat_deg, p.lon_deg)));
                let tri = vec![c + vec2(0.0, -8.0), c + vec2(6.0, 5.0), c + vec2(-6.0, 5.0)];
                painter.add(egui::Shape::convex_polygon(tri, cone_color, Stroke::new(1.0, Color32::WHITE)));
                painter.text(
                    c + vec2(8.0, 4.0),
                    egui::Align2::LEFT_TOP,
                    label,
                    font.clone(),
                    ui.visuals().strong_text_color(),
                );
            }

            // North arrow (the map is always north up) and the legend of what is drawn.
            let panel = ui.visuals().panel_fill.gamma_multiply(0.85);
            let ink = ui.visuals().strong_text_color();
            map_tools::draw_north_arrow(&painter, rect, ink, panel);
            let mut legend: Vec<map_tools::LegendItem> = vec![
                (Color32::from_rgb(240, 140, 0), "next waypoint"),
                (Color32::from_rgb(60, 120, 220), "route"),
                (Color32::from_rgb(220, 50, 50), "track"),
                (Color32::from_rgb(20, 90, 200), "wearer (ring: 1-sigma accuracy)"),
            ];
            if replay.is_some() {
                legend.push((Color32::from_rgb(150, 60, 200), "replayed track"));
            }
            if !field.cones.is_empty() {
                legend.push((cone_color, "cone marks"));
            }
            if !field.drift.is_empty() {
                legend.push((drift_color, "drift-test fixes"));
            }
            if !measure_points.is_empty() {
                legend.push((accent, "measured line"));
            }
            map_tools::draw_legend(&painter, rect, &legend, ink, panel);

            // The position under the mouse.
            let pointer_at = response
                .hover_pos()
                .map(|p| projector.unproject(p.to_vec2()))
                .map(|p| LatLon::new(p.y(), p.x()));

            // Measuring clicks.
            let mut measure_click = None;
            if measuring
                && response.clicked()
                && let Some(pos) = response.interact_pointer_pos()
            {
                let p = projector.unproject(pos.to_vec2());
                measure_click = Some(LatLon::new(p.y(), p.x()));
            }

            // Adding waypoints.
            let mut add_click = None;
            if add_mode
                && response.clicked()
                && let Some(pos) = response.interact_pointer_pos()
            {
                add_click = Some(projector.unproject(pos.to_vec2()));
            }
            if response.secondary_clicked() {
                *right_click_at = response.interact_pointer_pos().map(|p| projector.unproject(p.to_vec2()));
            }
            let mut add_here: Option<bool> = None;
            response.context_menu(|ui| {
                if ui.button("Add waypoint here (end of route)").clicked() {
                    add_here = Some(false);
                }
                if ui.button("Insert as next waypoint").clicked() {
                    add_here = Some(true);
                }
            });

            // Scale bar and attribution / offline note.
            let bar_m = nice_length_m(80.0 / px_per_m.max(1e-9));
            let bar_px = (bar_m * px_per_m) as f32;
            let y = rect.bottom() - 16.0;
            let x0 = rect.left() + 14.0;
            let ink = ui.visuals().strong_text_color();
            painter.rect_filled(
                egui::Rect::from_min_max(
                    egui::pos2(x0 - 6.0, y - 18.0),
                    egui::pos2(x0 + bar_px + 40.0, y + 6.0),
                ),
                3.0,
                ui.visuals().panel_fill.gamma_multiply(0.85),
            );
            painter.line_segment([egui::pos2(x0, y), egui::pos2(x0 + bar_px, y)], Stroke::new(3.0, ink));
            painter.line_segment([egui::pos2(x0, y - 5.0), egui::pos2(x0, y + 3.0)], Stroke::new(2.0, ink));
            painter.line_segment(
                [egui::pos2(x0 + bar_px, y - 5.0), egui::pos2(x0 + bar_px, y + 3.0)],
                Stroke::new(2.0, ink),
            );
            let label = if bar_m >= 1000.0 { format!("{} km", bar_m / 1000.0) } else { format!("{bar_m} m") };
            painter.text(
                egui::pos2(x0 + bar_px / 2.0, y - 4.0),
                egui::Align2::CENTER_BOTTOM,
                label,
                font.clone(),
                ink,
            );
            let note = if offline { &tile_notes.1 } else { &tile_notes.0 };
            painter.text(
                rect.right_bottom() - vec2(6.0, 4.0),
                egui::Align2::RIGHT_BOTTOM,
                note,
                egui::FontId::proportional(11.0),
                ink,
            );

            (action, add_here, add_click, dragging, measure_click, pointer_at, rect)
        });
        let (action, add_here, add_click, dragging, measure_click, pointer_at, map_rect) = resp.inner;
        self.tools.pointer = pointer_at;
        self.tools.map_rect = Some(map_rect);
        if let Some(p) = measure_click {
            self.tools.measure_click(p);
        }
        // A drag is one undo step, recorded when it ends.
        if !dragging && let Some((i, before)) = self.drag_before.take() {
            let name = self.waypoints.get(i).map_or_else(|| format!("WP{}", i + 1), |w| w.name.clone());
            self.commit(format!("drag {name}"), before);
        }
        if let Some(pos) = add_click {
            self.add_waypoint(pos, false);
            changed = true;
        }
        if let Some((i, a)) = action {
            changed = true;
            self.apply_waypoint_action(i, a);
        }
        if let (Some(as_next), Some(pos)) = (add_here, self.right_click_at) {
            self.add_waypoint(pos, as_next);
            changed = true;
        }
        if cfg.map_tiles && self.tile_hits.get() == 0 && self.tile_misses.get() > 0 {
            self.no_tiles_since_s.get_or_insert(now_s);
        } else {
            self.no_tiles_since_s = None;
        }
        if self.memory.detached().is_some() {
            cfg.follow = false;
        }
        changed
    }
}

/// An age in words: "12 s ago", "5 min ago", or "age unknown".
pub fn age_text(age_s: Option<f64>) -> String {
    match age_s.filter(|a| a.is_finite()) {
        None => "age unknown".to_owned(),
        Some(a) if a < 120.0 => format!("{a:.0} s ago"),
        Some(a) if a < 7200.0 => format!("{:.0} min ago", a / 60.0),
        Some(a) => format!("{:.1} h ago", a / 3600.0),
    }
}

/// The index ranges of the segments of a track of `n` points split at `breaks` (ascending), none empty.
fn segments<T>(track: &[T], breaks: &[usize]) -> impl Iterator<Item = std::ops::Range<usize>> {
    let n = track.len();
    let starts = std::iter::once(0).chain(breaks.iter().copied().filter(move |&b| b < n));
    let ends = breaks.iter().copied().filter(move |&b| b < n).chain(std::iter::once(n));
    starts.zip(ends).filter(|(a, b)| a < b).map(|(a, b)| a..b)
}

/// Draws a track as one line per segment, strided for old points and full for the newest [`TRACK_TAIL`]
/// (the stride is the whole track's, so many segments cost no more than one).
fn draw_track(
    painter: &egui::Painter,
    projector: &Projector,
    track: &[TrackPoint],
    breaks: &[usize],
    color: Color32,
) {
    let tail_start = track.len().saturating_sub(TRACK_TAIL);
    let stride = decimation_stride(tail_start, TRACK_DRAW_MAX - TRACK_TAIL);
    let project = |p: &TrackPoint| to_pos2(projector.project(lat_lon(p.lat_deg, p.lon_deg)));
    for seg in segments(track, breaks) {
        let last = seg.end - 1;
        let pts: Vec<Pos2> = seg
            .clone()
            .filter(|&i| i >= tail_start || i % stride == 0 || i == seg.start || i == last)
            .map(|i| project(&track[i]))
            .collect();
        if pts.len() >= 2 {
            painter.line(pts, Stroke::new(2.0, color));
        } else if let Some(p) = pts.first() {
            painter.circle_filled(*p, 2.0, color);
        }
    }
}

/// A metric grid anchored at the route's first point, with lines every "nice" distance.
fn draw_grid(
    painter: &egui::Painter,
    projector: &Projector,
    rect: egui::Rect,
    anchor: (f64, f64),
    px_per_m: f64,
    strong: bool,
    dark: bool,
) {
    if !(px_per_m.is_finite() && px_per_m > 0.0) {
        return;
    }
    let step_m = nice_length_m(70.0 / px_per_m);
    let frame = LocalFrame::new(LatLon::new(anchor.0, anchor.1), Earth::Wgs84);
    let corners = [rect.left_top(), rect.right_bottom()].map(|p| {
        let ll = projector.unproject(p.to_vec2());
        frame.enu_from_wgs84(LatLon::new(ll.y(), ll.x()))
    });
    let (e0, e1) = (corners[0].x.min(corners[1].x), corners[0].x.max(corners[1].x));
    let (n0, n1) = (corners[0].y.min(corners[1].y), corners[0].y.max(corners[1].y));
    if ((e1 - e0) / step_m) > 400.0 || ((n1 - n0) / step_m) > 400.0 {
        return;
    }
    let alpha = if strong { 90 } else { 40 };
    let base = if dark { 200 } else { 60 };
    let minor = Stroke::new(1.0, Color32::from_rgba_unmultiplied(base, base, base, alpha));
    let axis = Stroke::new(1.5, Color32::from_rgba_unmultiplied(base, base, base, alpha * 2));
    let to_screen = |e: f64, n: f64| {
        let p = frame.wgs84_from_enu(DVec2::new(e, n));
        to_pos2(projector.project(lat_lon(p.lat_deg, p.lon_deg)))
    };
    let mut e = (e0 / step_m).floor() * step_m;
    while e <= e1 {
        let s = if e.abs() < step_m / 2.0 { axis } else { minor };
        painter.line_segment([to_screen(e, n0), to_screen(e, n1)], s);
        e += step_m;
    }
    let mut n = (n0 / step_m).floor() * step_m;
    while n <= n1 {
        let s = if n.abs() < step_m / 2.0 { axis } else { minor };
        painter.line_segment([to_screen(e0, n), to_screen(e1, n)], s);
        n += step_m;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn nice_lengths() {
        assert_relative_eq!(nice_length_m(3.0), 5.0);
        assert_relative_eq!(nice_length_m(70.0), 100.0);
        assert_relative_eq!(nice_length_m(120.0), 200.0);
        assert_relative_eq!(nice_length_m(1.0), 1.0);
    }

    fn fix_at(lat: f64, lon: f64, t_s: i64) -> Fix {
        let t0 = "2026-01-01T12:00:00Z".parse::<chrono::DateTime<chrono::Utc>>().unwrap();
        Fix {
            lat_deg: Some(lat),
            lon_deg: Some(lon),
            time: Some(t0 + chrono::TimeDelta::seconds(t_s)),
            ..Fix::default()
        }
    }

    /// 1e-4° of latitude is ~11.1 m: a walker's step per second stays in one segment; 0.01° (1.1 km) in 10 s
    /// (111 m/s) does not; a source change always splits.
    #[test]
    fn the_track_splits_at_jumps_and_source_changes() {
        let mut m = MapView::new(true);
        for k in 0..5 {
            m.push_track(&fix_at(42.0 + f64::from(k) * 1e-5, -71.0, i64::from(k)));
        }
        m.push_track(&fix_at(42.01, -71.0, 14));
        m.push_track(&fix_at(42.01001, -71.0, 15));
        m.break_track();
        m.push_track(&fix_at(42.01002, -71.0, 16));
        let lens: Vec<usize> = m.track_segments().iter().map(|s| s.len()).collect();
        assert_eq!(lens, vec![5, 2, 1]);
        // 1.1 km over 10 minutes of receiver time is a walk (1.9 m/s), whatever the arrival instants say.
        let mut m = MapView::new(true);
        m.push_track(&fix_at(42.0, -71.0, 0));
        m.push_track(&fix_at(42.01, -71.0, 600));
        assert_eq!(m.track_segments().len(), 1);
    }

    #[test]
    fn legs_beyond_a_walk_warn_and_times_to_go_are_bounded() {
        let near = leg_summary(312.0, Some(45.2), 1.3);
        assert_eq!(near.text, "312 m · aim bearing 45° · 4 min 00 s to go");
        assert!(near.warning.is_none());
        let far = leg_summary(15_195_988.0, Some(10.0), 1.3);
        assert_eq!(far.text, "15196 km away");
        assert!(far.warning.unwrap().contains("too far to walk"));
        assert_eq!(time_to_go_text(59.6), "1 min 00 s");
        assert_eq!(time_to_go_text(7800.0), "2 h 10 min");
        assert_eq!(time_to_go_text(90_000.0), "more than 12 h");
        assert_eq!(distance_text(4_249.0), "4.2 km");
    }

    #[test]
    fn waypoint_editing_keeps_the_next_one() {
        let mut m = MapView::new(true);
        for k in 0..4 {
            m.add_waypoint(lat_lon(42.0 + f64::from(k) * 1e-3, -71.0), false);
        }
        m.next = 2;
        m.delete_waypoint(0);
        assert_eq!(m.next, 1);
        assert_eq!(m.waypoints[m.next].name, "WP3");
        m.move_waypoint(1, -1);
        assert_eq!(m.waypoints[0].name, "WP3");
        m.move_waypoint(0, -1);
        assert_eq!(m.waypoints[0].name, "WP3");
        m.add_waypoint(lat_lon(1.0, 2.0), true);
        assert_relative_eq!(m.waypoints[1].lat_deg, 1.0);
    }

    #[test]
    fn the_undo_history_is_bounded_and_keeps_guidances_next_waypoint() {
        let mut m = MapView::new(true);
        for k in 0..(UNDO_STEPS + 5) {
            m.add_waypoint(lat_lon(42.0, -71.0 + k as f64 * 1e-4), false);
        }
        let mut undone = 0;
        while m.undo() {
            undone += 1;
        }
        assert_eq!(undone, UNDO_STEPS);
        assert_eq!(m.waypoints.len(), 5);
        while m.redo() {}
        assert_eq!(m.waypoints.len(), UNDO_STEPS + 5);
        // Deleting the next waypoint and undoing makes it next again, unless guidance moved on meanwhile.
        m.next = 3;
        m.delete_waypoint(3);
        assert_eq!(m.undo_notice.as_deref(), Some("Deleted WP4"));
        m.undo();
        assert_eq!((m.next, m.waypoints[3].name.as_str()), (3, "WP4"));
        m.redo();
        m.next = 7;
        m.undo();
        assert_eq!(m.next, 7, "guidance's arrival is kept");
        // A new edit forgets the redo steps.
        m.undo();
        m.move_waypoint(0, 1);
        assert!(!m.redo());
    }

    #[test]
    fn typed_coordinates_are_checked_and_name_the_field() {
        assert_relative_eq!(parse_coordinate(" 42.3573 ", Coordinate::Latitude).unwrap(), 42.3573);
        assert_relative_eq!(parse_coordinate("-71,1°", Coordinate::Longitude).unwrap(), -71.1);
        let e = parse_coordinate("91", Coordinate::Latitude).unwrap_err();
        assert!(e.starts_with("Latitude: 91 is outside"), "{e}");
        assert!(parse_coordinate("180", Coordinate::Longitude).unwrap_err().starts_with("Longitude"));
        assert!(parse_coordinate("north", Coordinate::Latitude).unwrap_err().contains("not a number"));
        assert!(parse_coordinate("NaN", Coordinate::Latitude).is_err());
        let mut m = MapView::new(true);
        m.add_waypoint(lat_lon(1.0, 2.0), false);
        assert_eq!(m.edit_waypoint(0, "  ", "1", "2").unwrap_err(), "Name: must not be empty");
        m.edit_waypoint(0, "Gate", "1.5", "2").unwrap();
        assert_eq!(m.undo_label(), Some("edit WP1"));
        m.edit_waypoint(0, "Gate 2", "1.5", "2").unwrap();
        assert_eq!(m.undo_label(), Some("rename Gate to Gate 2"));
        // Positions off the map's edge are wrapped into GPX's ranges.
        assert_eq!(waypoint_coords(lat_lon(95.0, 190.0)), (90.0, -170.0));
    }
}
