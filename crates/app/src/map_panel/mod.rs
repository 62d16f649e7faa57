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
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::time::Instant;

use egui::{Color32, Key, KeyboardShortcut, Modifiers, Pos2, RichText, Stroke, vec2};
use walkers::{MapMemory, Position, Projector, TileId, TilePiece, Tiles, lat_lon};

use crate::config::Config;
use crate::map_tools::{self, MapTools};
use crate::route_import::{ImportChoice, ImportDialog};
use vestnav_core::geo::{DVec2, Earth, LatLon, LocalFrame};
use vestnav_device::gps::Fix;
use vestnav_device::route_file::TrackPoint;
use vestnav_station::guidance::GuidanceStatus;
use vestnav_station::route::{RouteModel, Track, segments};
use vestnav_station::{Notices, Severity, Subject};

pub use vestnav_station::route::{Coordinate, UNDO_STEPS, parse_coordinate, plausible_step};

/// Waypoints drawn as markers at most per frame: beyond it (a long route zoomed out) only the route line,
/// the next waypoint and the waypoint under the pointer are drawn, so the frame stays cheap at
/// [`vestnav_station::route::MAX_WAYPOINTS`].
pub const WAYPOINT_MARKERS_MAX: usize = 1000;

/// Track points drawn at most per frame (older points are strided, the newest [`TRACK_TAIL`] drawn in full).
pub const TRACK_DRAW_MAX: usize = 2500;
/// Newest track points always drawn at full resolution.
pub const TRACK_TAIL: usize = 500;
/// With tiles on, the map falls back to the local grid when no tile has arrived for this long [s].
pub const TILES_OFFLINE_AFTER_S: f64 = 2.0;

/// Beyond this distance the next waypoint is not a walk but a wrong route or a wrong position [m]. A day's
/// walk is 30-40 km; 100 km is beyond any single leg of a guided walk, so the console warns instead of
/// printing a distance and a time to go.
pub const FAR_WAYPOINT_M: f64 = 100_000.0;
/// Longest time to go shown as a number [s]; beyond it the line says "more than 12 h to go".
pub const TIME_TO_GO_MAX_S: f64 = 12.0 * 3600.0;

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
    /// The waypoint editor (name and typed coordinates), when open.
    pub editor: Option<WaypointEditor>,
    /// The track was cleared from the view at this many points (only later points are drawn).
    track_from: usize,
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
            editor: None,
            track_from: 0,
            tools: MapTools::default(),
            import: None,
        }
    }

    /// Opens the editor on waypoint `i` with its current values.
    pub fn open_editor(&mut self, route: &RouteModel, i: usize) {
        self.editor = route.waypoints().get(i).map(|w| WaypointEditor {
            index: i,
            name: w.name.clone(),
            lat: w.lat_deg.to_string(),
            lon: w.lon_deg.to_string(),
            radius: w.arrival_radius_m.map_or_else(String::new, |r| r.to_string()),
            error: None,
        });
    }

    fn anchor(route: &RouteModel, track: &Track) -> (f64, f64) {
        route
            .waypoints()
            .first()
            .map(|w| (w.lat_deg, w.lon_deg))
            .or_else(|| track.points().first().map(|p| (p.lat_deg, p.lon_deg)))
            .unwrap_or((42.3573, -71.1010))
    }

    /// Draws the map tab over the station's route and track; route edits go to `route` (the station
    /// hands each change to guidance and the autosave), messages to `notices`.
    #[allow(clippy::too_many_arguments)] // the map shows the route, the track, the fix and guidance at once
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        route: &mut RouteModel,
        track: &Track,
        fix: Option<&Fix>,
        guidance: Option<&GuidanceStatus>,
        walking_m_s: f64,
        cfg: &mut Config,
        notices: &mut Notices,
    ) {
        if !ui.ctx().text_edit_focused() {
            // The more specific shortcut first: Ctrl+Z alone also matches Ctrl+Shift+Z.
            let (redo, undo) = ui.input_mut(|i| {
                let redo = i
                    .consume_shortcut(&KeyboardShortcut::new(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z))
                    || i.consume_shortcut(&KeyboardShortcut::new(Modifiers::COMMAND, Key::Y));
                (redo, !redo && i.consume_shortcut(&KeyboardShortcut::new(Modifiers::COMMAND, Key::Z)))
            });
            if redo {
                route.redo();
            } else if undo {
                route.undo();
            }
        }
        self.toolbar(ui, route, track, cfg, notices);
        self.file_row(ui, route, track, cfg, notices);
        self.import_dialog(ui, route, notices);
        if let Some(e) = &self.tools.goto_error {
            ui.label(RichText::new(format!("Go to: {e}")).color(ui.visuals().error_fg_color));
        }
        self.tools_line(ui);
        let speed_m_s = fix.and_then(|f| f.speed_m_s);
        Self::next_info(ui, route, fix, guidance, speed_m_s, walking_m_s);
        egui::Panel::right("waypoint-list").default_size(290.0).show(ui, |ui| {
            self.waypoint_list(ui, route, notices);
        });
        self.map_ui(ui, route, track, fix, guidance.and_then(|g| g.heading_deg), cfg, notices);
    }

    fn toolbar(
        &mut self,
        ui: &mut egui::Ui,
        route: &RouteModel,
        track: &Track,
        cfg: &mut Config,
        notices: &mut Notices,
    ) {
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
            self.tiles.toolbar(ui, cfg, route.waypoints());
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
                        notices.raise(
                            Severity::Info,
                            Subject::Route,
                            format!("map centred on {}", map_tools::format_decimal(p)),
                        );
                    }
                    Err(e) => self.tools.goto_error = Some(e),
                }
            }
            ui.separator();
            if ui
                .button("Clear track")
                .on_hover_text("Draw the track from now on (the session log keeps it)")
                .clicked()
            {
                self.track_from = track.points().len();
                self.replay = None;
            }
        });
    }

    /// The route file: the typed path with Browse… and the path it uses, Recent, Import, the exports (each
    /// asking "Replace X?" before writing over a file).
    fn file_row(
        &mut self,
        ui: &mut egui::Ui,
        route: &mut RouteModel,
        track: &Track,
        cfg: &mut Config,
        notices: &mut Notices,
    ) {
        use crate::file_dialog::{self as fd, RecentKind};
        let base = cfg.recent.base();
        ui.horizontal(|ui| {
            ui.label("Route file:");
            ui.vertical(|ui| {
                fd::path_field(ui, &mut self.gpx_path, &mut self.gpx_browse, ROUTE_OPEN, &base, "file.gpx");
            });
        });
        if let Some(fd::Picked::File(p)) = self.export_browse.poll() {
            self.gpx_path = p.display().to_string();
            self.export(RouteExport::Gpx, p, false, (route, track), cfg, notices);
        }
        ui.horizontal_wrapped(|ui| {
            if let Some(p) = fd::recent_menu(ui, &cfg.recent, RecentKind::Routes) {
                self.gpx_path = p.display().to_string();
                self.import_gpx(&p, route, cfg, notices);
            }
            if ui.button("Import GPX").clicked() {
                match fd::resolve(&self.gpx_path, &base) {
                    Some(p) => self.import_gpx(&p, route, cfg, notices),
                    None => notices.raise(
                        Severity::Warning,
                        Subject::Route,
                        "GPX import: type a file path or Browse… first",
                    ),
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
                        Some(p) => self.export(kind, p, false, (route, track), cfg, notices),
                        None => notices.raise(
                            Severity::Warning,
                            Subject::Route,
                            format!("{label}: type a file path or Browse… first"),
                        ),
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
                    .map_or_else(|| format!("{}.gpx", route.name()), |n| n.to_string_lossy().into_owned());
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
                    self.export(kind, path, true, (route, track), cfg, notices);
                }
                Some(fd::Answer::Cancel) => {
                    self.pending_replace = None;
                    notices.raise(
                        Severity::Info,
                        Subject::Route,
                        format!("{} left as it was", target.display()),
                    );
                }
                None => {}
            }
        }
    }

    fn export_target(kind: RouteExport, path: &Path) -> PathBuf {
        match kind {
            RouteExport::Gpx => path.to_path_buf(),
            RouteExport::GeoJson => vestnav_station::route::geojson_path(path),
        }
    }

    /// Exports the route and track to `path` (absolute); an existing file is replaced only when `replace`,
    /// else the operator is asked first. A GPX export joins the recent route files.
    fn export(
        &mut self,
        kind: RouteExport,
        path: PathBuf,
        replace: bool,
        (route, track): (&RouteModel, &Track),
        cfg: &mut Config,
        notices: &mut Notices,
    ) {
        let target = Self::export_target(kind, &path);
        if !replace && target.exists() {
            self.pending_replace = Some((path, kind));
            return;
        }
        let segments = track.segments();
        let (name, waypoints) = (route.name(), route.waypoints());
        let result = match kind {
            RouteExport::Gpx => {
                vestnav_station::route::export_gpx(&path, name, waypoints, &segments, replace)
            }
            RouteExport::GeoJson => {
                vestnav_station::route::export_geojson(&path, name, waypoints, &segments, replace)
            }
        };
        match result {
            Ok(msg) => {
                match kind {
                    RouteExport::Gpx => cfg.recent.push(crate::file_dialog::RecentKind::Routes, &target),
                    RouteExport::GeoJson => cfg.recent.used(&target),
                }
                notices.raise(Severity::Info, Subject::Route, msg);
            }
            Err(e) => {
                let what = if kind == RouteExport::Gpx { "GPX" } else { "GeoJSON" };
                notices.raise(Severity::Alarm, Subject::Route, format!("{what} export failed: {e}"));
            }
        }
    }

    /// Imports the GPX file at `path`: straight away when it holds one thing, else through the import
    /// dialog. The file joins the recent route files once read.
    fn import_gpx(&mut self, path: &Path, route: &mut RouteModel, cfg: &mut Config, notices: &mut Notices) {
        let file = match vestnav_device::route_file::read_gpx(path) {
            Ok(file) => file,
            Err(e) => {
                notices.raise(Severity::Alarm, Subject::Route, format!("GPX import failed: {e}"));
                return;
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
            0 => notices.raise(
                Severity::Warning,
                Subject::Route,
                format!("{shown} holds no waypoint, route or track"),
            ),
            1 => {
                let c = choices.remove(0);
                self.import_choice(route, c, notices);
            }
            _ => {
                notices.raise(
                    Severity::Info,
                    Subject::Route,
                    format!("{shown} holds {} things: choose one", choices.len()),
                );
                self.import = Some(ImportDialog { path: shown, choices });
            }
        }
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

    /// Replaces the route with an imported choice (one undo step); a route beyond the limit is refused and
    /// said.
    pub fn import_choice(&mut self, route: &mut RouteModel, c: ImportChoice, notices: &mut Notices) {
        match route.replace(c.name, c.waypoints) {
            Ok(()) => notices.raise(Severity::Info, Subject::Route, format!("imported {}", c.label)),
            Err(e) => notices.raise(Severity::Alarm, Subject::Route, format!("not imported: {e}")),
        }
        self.import = None;
    }

    /// The import dialog (when open): one button per thing the file holds; returns whether the route
    /// changed.
    fn import_dialog(&mut self, ui: &mut egui::Ui, route: &mut RouteModel, notices: &mut Notices) {
        let Some(dialog) = &self.import else { return };
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
            return;
        };
        self.import_choice(route, c, notices);
    }

    /// The line about the next waypoint. Distance and bearing are core guidance's (the one home of the
    /// navigation logic), from its latest status for this waypoint; the map only turns them into words.
    fn next_info(
        ui: &mut egui::Ui,
        route: &RouteModel,
        fix: Option<&Fix>,
        guidance: Option<&GuidanceStatus>,
        speed_m_s: Option<f64>,
        walking_m_s: f64,
    ) {
        let mut warning = None;
        let text = match (fix, route.waypoints().get(route.next())) {
            (_, None) if route.waypoints().is_empty() => {
                "no waypoints: right-click the map to add one".to_owned()
            }
            (_, None) => "route finished".to_owned(),
            (None, Some(w)) => {
                format!(
                    "next: {} ({}/{}) · waiting for a fix",
                    w.name,
                    route.next() + 1,
                    route.waypoints().len()
                )
            }
            (Some(_), Some(w)) => match guidance
                .filter(|st| st.next == route.next())
                .and_then(|st| st.distance_m.filter(|d| d.is_finite()).map(|d| (d, st.bearing_deg)))
            {
                None => format!(
                    "next: {} ({}/{}) · waiting for guidance",
                    w.name,
                    route.next() + 1,
                    route.waypoints().len()
                ),
                Some((d, bearing)) => {
                    let v = speed_m_s.filter(|v| *v >= 0.3).unwrap_or(walking_m_s).max(0.1);
                    let leg = leg_summary(d, bearing, v);
                    warning = leg.warning;
                    format!(
                        "next: {} ({}/{}) · {}",
                        w.name,
                        route.next() + 1,
                        route.waypoints().len(),
                        leg.text
                    )
                }
            },
        };
        ui.label(RichText::new(text).strong());
        if let Some(w) = warning {
            ui.label(RichText::new(w).strong().color(ui.visuals().warn_fg_color));
        }
    }

    fn waypoint_list(&mut self, ui: &mut egui::Ui, route: &mut RouteModel, notices: &mut Notices) {
        ui.label(RichText::new(format!("{} ({} waypoints)", route.name(), route.waypoints().len())).strong());
        ui.horizontal(|ui| {
            let undo_label = route.undo_label().map(str::to_owned);
            let undo = ui
                .add_enabled(undo_label.is_some(), egui::Button::new("Undo"))
                .on_hover_text(format!("Undo {} (Ctrl+Z)", undo_label.unwrap_or_default()))
                .on_disabled_hover_text("Nothing to undo");
            if undo.clicked() {
                route.undo();
            }
            let redo_label = route.redo_label().map(str::to_owned);
            let redo = ui
                .add_enabled(redo_label.is_some(), egui::Button::new("Redo"))
                .on_hover_text(format!("Redo {} (Ctrl+Shift+Z or Ctrl+Y)", redo_label.unwrap_or_default()))
                .on_disabled_hover_text("Nothing to redo");
            if redo.clicked() {
                route.redo();
            }
            let clear = ui
                .add_enabled(!route.waypoints().is_empty(), egui::Button::new("Clear route"))
                .on_hover_text("Remove every waypoint (Undo brings them back)");
            if clear.clicked() {
                route.clear();
            }
        });
        if let Some(n) = route.undo_notice().map(str::to_owned) {
            ui.horizontal_wrapped(|ui| {
                ui.label(RichText::new(n).strong());
                if ui.small_button("Undo delete").clicked() {
                    route.undo();
                }
            });
        }
        self.editor_ui(ui, route);
        let mut action: Option<(usize, WaypointAction)> = None;
        let next = route.next();
        let waypoints = route.waypoints();
        egui::ScrollArea::vertical().show_rows(ui, 22.0, waypoints.len(), |ui, range| {
            for i in range {
                let Some(w) = waypoints.get(i) else { continue };
                ui.horizontal(|ui| {
                    let marker = if i == next { "> " } else { "" };
                    if ui.selectable_label(i == next, format!("{marker}{} {}", i + 1, w.name)).clicked() {
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
            self.apply_waypoint_action(route, i, a, notices);
        }
    }

    /// The waypoint editor (when open): name, latitude and longitude; Apply (or Enter) checks and applies
    /// them as one undo step.
    fn editor_ui(&mut self, ui: &mut egui::Ui, route: &mut RouteModel) {
        let Some(ed) = &mut self.editor else { return };
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
            return;
        }
        if !apply {
            return;
        }
        let ed = ed.clone();
        let radius = match ed.radius.trim() {
            "" => Ok(None),
            t => t.replace(',', ".").parse::<f64>().map(Some).map_err(|_| {
                format!("Arrival radius: '{t}' is not a number of metres (empty: the global radius)")
            }),
        };
        let result = radius.and_then(|r| {
            let lat = parse_coordinate(&ed.lat, Coordinate::Latitude)?;
            let lon = parse_coordinate(&ed.lon, Coordinate::Longitude)?;
            route.edit(ed.index, &ed.name, lat, lon, r).map_err(|e| e.to_string())
        });
        match result {
            Ok(()) => self.editor = None,
            Err(e) => {
                if let Some(open) = &mut self.editor {
                    open.error = Some(e);
                }
            }
        }
    }

    fn apply_waypoint_action(
        &mut self,
        route: &mut RouteModel,
        i: usize,
        action: WaypointAction,
        notices: &mut Notices,
    ) {
        match action {
            WaypointAction::Select => {
                route.set_next(i);
                let name = route.waypoints().get(i).map_or_else(String::new, |w| w.name.clone());
                notices.raise(Severity::Info, Subject::Guidance, format!("guidance now heads for {name}"));
            }
            WaypointAction::MoveUp => route.move_by(i, -1),
            WaypointAction::MoveDown => route.move_by(i, 1),
            WaypointAction::Delete => route.delete(i),
            WaypointAction::Edit => self.open_editor(route, i),
        }
    }

    #[allow(clippy::too_many_lines)] // one paint pass over every layer of the map, in order
    #[allow(clippy::too_many_arguments)]
    fn map_ui(
        &mut self,
        ui: &mut egui::Ui,
        route: &mut RouteModel,
        track: &Track,
        fix: Option<&Fix>,
        heading_deg: Option<f64>,
        cfg: &mut Config,
        notices: &mut Notices,
    ) {
        let wearer = fix.and_then(|f| f.lat_deg.zip(f.lon_deg)).map(|(la, lo)| lat_lon(la, lo));
        let marker =
            fix.filter(|_| wearer.is_some()).map(|f| wearer_marker(f, Instant::now(), cfg.stale_after_s));
        self.wearer_shown = marker;
        let anchor = Self::anchor(route, track);
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
        // Borrow the fields the closure needs separately from walkers' memory. The closure only reads the
        // route; what it asks for (drag, add, menu actions) is applied to the route after it.
        let waypoints = route.waypoints();
        let next = &route.next();
        let track_from = self.track_from.min(track.points().len());
        let drawn_track = track.points().get(track_from..).unwrap_or(&[]);
        let drawn_breaks: Vec<usize> =
            track.breaks().iter().filter(|b| **b > track_from).map(|b| b - track_from).collect();
        let replay = &self.replay;
        let add_mode = self.add_mode && !self.tools.measuring;
        let measuring = self.tools.measuring;
        let measure_points = self.tools.measure_points.clone();
        let field = &self.tools.field;
        let right_click_at = &mut self.right_click_at;
        let menu_wp = &mut self.menu_wp;
        let mut dragging = false;
        let mut dragged_to = None;
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
            draw_track(&painter, projector, drawn_track, &drawn_breaks, Color32::from_rgb(220, 50, 50));

            // Waypoints, draggable, with a context menu.
            let mut action: Option<(usize, WaypointAction)> = None;
            let font = egui::FontId::proportional(12.0);
            let visible: Vec<usize> =
                (0..pts.len()).filter(|&i| rect.expand(20.0).contains(pts[i])).collect();
            let crowded = visible.len() > 200;
            // Beyond the marker budget only the next waypoint and the one under the pointer get a marker.
            let too_many = visible.len() > WAYPOINT_MARKERS_MAX;
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
                    if too_many && i != *next {
                        continue;
                    }
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
                    dragging = true;
                    dragged_to = Some((i, projector.unproject(pos.to_vec2())));
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

            (action, add_here, add_click, (dragging, dragged_to), measure_click, pointer_at, rect)
        });
        let (action, add_here, add_click, (dragging, dragged_to), measure_click, pointer_at, map_rect) =
            resp.inner;
        self.tools.pointer = pointer_at;
        self.tools.map_rect = Some(map_rect);
        if let Some(p) = measure_click {
            self.tools.measure_click(p);
        }
        // A drag, however many frames it takes, is one undo step, recorded when it ends.
        if let Some((i, pos)) = dragged_to {
            route.drag(i, pos.y(), pos.x());
        }
        if !dragging && route.dragging() {
            route.end_drag();
        }
        let mut add = |pos: Position, as_next: bool| {
            if let Err(e) = route.add(pos.y(), pos.x(), as_next) {
                notices.raise(Severity::Warning, Subject::Route, format!("waypoint not added: {e}"));
            }
        };
        if let Some(pos) = add_click {
            add(pos, false);
        }
        if let (Some(as_next), Some(pos)) = (add_here, self.right_click_at) {
            add(pos, as_next);
        }
        if let Some((i, a)) = action {
            self.apply_waypoint_action(route, i, a, notices);
        }
        if cfg.map_tiles && self.tile_hits.get() == 0 && self.tile_misses.get() > 0 {
            self.no_tiles_since_s.get_or_insert(now_s);
        } else {
            self.no_tiles_since_s = None;
        }
        if self.memory.detached().is_some() {
            cfg.follow = false;
        }
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

/// Picks at most about `max_points` of `n` points for drawing: a fixed stride, always keeping the last.
///
/// A 100k-point track drawn at full resolution costs tens of milliseconds per frame; the stride keeps the
/// frame time bounded while the most recent points (drawn separately in full) stay exact.
pub fn decimation_stride(n: usize, max_points: usize) -> usize {
    n.div_ceil(max_points.max(1)).max(1)
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
    fn stride_bounds_points() {
        assert_eq!(decimation_stride(10, 5000), 1);
        assert!(100_000 / decimation_stride(100_000, 5000) <= 5000);
    }
}
