//! The map: tiles of the configured source (`crate::tiles`; OpenStreetMap by default) or a local metric
//! grid, the wearer with an accuracy circle, the track, waypoints and route, and the mouse editing of
//! waypoints.
//!
//! Mouse: drag the map to pan (leaves follow mode), Ctrl+wheel or pinch to zoom; drag a waypoint to move
//! it; right-click a waypoint for delete / move earlier / move later / make next; right-click the map to add
//! a waypoint there (with an OpenStreetMap extract loaded, also *Route to here along paths* and *Follow
//! paths*: `walk`); with "Add waypoints" on, a left click adds one at the end of the route.
//!
//! Every edit of the route (add, move, drag, delete, reorder, rename, typed coordinates, clear, import)
//! is one step of a bounded undo history ([`UNDO_STEPS`]); Ctrl+Z undoes, Ctrl+Shift+Z and Ctrl+Y redo
//! (outside text fields). A delete is not confirmed: it is undoable at once, and says so ("Deleted WP3"
//! with an **Undo delete** button).

use std::cell::Cell;
use std::path::PathBuf;
use std::rc::Rc;
use std::time::Instant;

use egui::{Key, KeyboardShortcut, Modifiers, RichText};
use walkers::{MapMemory, Position, lat_lon};

use crate::config::Config;
use crate::map_tools::{self, MapTools};
use crate::route_import::ImportDialog;
use vestnav_device::gps::Fix;
use vestnav_device::route_file::TrackPoint;
use vestnav_station::guidance::GuidanceStatus;
use vestnav_station::route::{RouteModel, Track};
use vestnav_station::{Notices, Severity, Subject};

pub use vestnav_station::route::{Coordinate, UNDO_STEPS, parse_coordinate, plausible_step};

mod files;
mod paint;
pub mod remote;
pub mod route_line;
pub mod walk;

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
    /// Remote stations' wearers to draw (handed in each frame from the Stations window's fleet).
    pub remote_wearers: Vec<remote::RemoteWearer>,
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
    /// An import waiting for the operator's answer to "Replace the route being guided?".
    pub pending_import: Option<crate::route_import::ImportChoice>,
    /// Whether guidance is steering the wearer along the route (an import then asks first).
    guiding: bool,
    /// Routing on foot over the OSM extract's paths: the profile and the plan running.
    pub walk: walk::WalkPlanner,
    /// The waypoint picked in the list (a click selects; "Guide to" makes it the next one).
    pub selected: Option<usize>,
}

/// What a route export writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RouteExport {
    /// GPX at the typed path.
    Gpx,
    /// `GeoJSON` at the typed path with `.geojson`.
    GeoJson,
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
            remote_wearers: Vec::new(),
            replay: None,
            add_mode: false,
            marks: 0,
            gpx_path: String::new(),
            gpx_browse: crate::file_dialog::Browse::default(),
            export_browse: crate::file_dialog::Browse::default(),
            pending_replace: None,
            pending_import: None,
            guiding: false,
            walk: walk::WalkPlanner::default(),
            selected: None,
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
            lat: coordinate_text(w.lat_deg),
            lon: coordinate_text(w.lon_deg),
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
        self.guiding = cfg.guidance_auto && !route.waypoints().is_empty();
        self.toolbar(ui, route, track, cfg, notices);
        self.file_row(ui, route, track, cfg, notices);
        self.import_dialog(ui, route, notices);
        self.poll_walk(route, notices);
        self.confirm_import(ui, route, notices);
        if let Some(e) = &self.tools.goto_error {
            ui.label(RichText::new(format!("Go to: {e}")).color(ui.visuals().error_fg_color));
        }
        self.tools_line(ui);
        let speed_m_s = fix.and_then(|f| f.speed_m_s);
        Self::next_info(ui, route, fix, guidance, speed_m_s, walking_m_s);
        // A narrow window leaves the map the larger share: the list never grows past its share of the width
        // (at 1024 px the map keeps about 500 px; its rows put their buttons on a second line).
        let list_w = (ui.available_width() * 0.3).clamp(200.0, 340.0);
        egui::Panel::right("waypoint-list").default_size(list_w).max_size(list_w).show(ui, |ui| {
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
                .filter(|st| st.next == route.next() && st.route_revision == route.revision())
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
        // Below the list, so neither an undo notice nor the editor moves the rows under the cursor.
        let mut action: Option<(usize, WaypointAction)> = None;
        egui::Panel::bottom("waypoint-actions").resizable(false).show(ui, |ui| {
            self.selection_ui(ui, route, &mut action);
            if let Some(n) = route.undo_notice().map(str::to_owned) {
                ui.horizontal_wrapped(|ui| {
                    ui.label(RichText::new(n).strong());
                    if ui.small_button("Undo delete").clicked() {
                        route.undo();
                    }
                });
            }
            self.editor_ui(ui, route);
        });
        let next = route.next();
        let waypoints = route.waypoints();
        // Two lines a row: the name (cut with "…" when long), then its buttons, so no name widens the list
        // past its share of the window or pushes the buttons out of it.
        egui::ScrollArea::vertical().show_rows(ui, 44.0, waypoints.len(), |ui, range| {
            for i in range {
                let Some(w) = waypoints.get(i) else { continue };
                let marker = if i == next { "> " } else { "" };
                let label = format!("{marker}{} {}", i + 1, w.name);
                let name = ui
                    .add(egui::Button::selectable(self.selected == Some(i), label).truncate())
                    .on_hover_text(if i == next {
                        "the next waypoint guidance heads for"
                    } else {
                        "select (Guide to below makes it the next waypoint)"
                    });
                if name.clicked() {
                    self.selected = Some(i);
                }
                ui.horizontal(|ui| {
                    ui.add_space(12.0);
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

    /// The selected waypoint and the deliberate step of guiding to it (a click on a name only selects).
    fn selection_ui(
        &mut self,
        ui: &mut egui::Ui,
        route: &RouteModel,
        action: &mut Option<(usize, WaypointAction)>,
    ) {
        let Some(i) = self.selected.filter(|&i| i < route.waypoints().len()) else {
            self.selected = None;
            return;
        };
        let name = &route.waypoints()[i].name;
        ui.horizontal_wrapped(|ui| {
            ui.label(RichText::new(format!("Selected: {} {name}", i + 1)).strong());
            if i == route.next() {
                ui.label("(the next waypoint)");
            } else if ui
                .button(format!("Guide to {name}"))
                .on_hover_text("Make it the next waypoint: guidance re-targets at once")
                .clicked()
            {
                *action = Some((i, WaypointAction::Select));
            }
        });
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
}

/// A latitude or longitude for the waypoint editor: 7 decimals (1e-7° is 1.1 cm of latitude, finer than any
/// GPS fix), trailing zeros dropped but one decimal kept, so 42.3581 shows as `42.3581`, never as
/// `42.358100000000004`.
pub fn coordinate_text(deg: f64) -> String {
    let s = format!("{deg:.7}");
    let s = s.trim_end_matches('0');
    if s.ends_with('.') { format!("{s}0") } else { s.to_owned() }
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

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn coordinates_show_seven_decimals_at_most() {
        assert_eq!(coordinate_text(42.3581 + 4e-15), "42.3581");
        assert_eq!(coordinate_text(-71.093_612_345_678), "-71.0936123");
        assert_eq!(coordinate_text(10.0), "10.0");
        // 1e-7 degree of latitude is 6.4e6 m x 1e-7 x pi / 180 = 1.1 cm.
        assert_eq!(coordinate_text(0.000_000_1), "0.0000001");
    }

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
