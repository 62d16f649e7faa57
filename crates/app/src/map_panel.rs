//! The map: OpenStreetMap tiles (walkers, cached on disk) or a local metric grid, the wearer with an
//! accuracy circle, the track, waypoints and route, and the mouse editing of waypoints.
//!
//! Mouse: drag the map to pan (leaves follow mode), Ctrl+wheel or pinch to zoom; drag a waypoint to move
//! it; right-click a waypoint for delete / move earlier / move later / make next; right-click the map to add
//! a waypoint there; with "Add waypoints" on, a left click adds one at the end of the route.

use std::cell::Cell;
use std::rc::Rc;

use egui::{Color32, Pos2, RichText, Stroke, vec2};
use walkers::{HttpOptions, HttpTiles, MapMemory, Position, Projector, TileId, TilePiece, Tiles, lat_lon};

use crate::config::Config;
use crate::route::{Waypoint, decimation_stride};
use vestnav_core::geo::{DVec2, Earth, LatLon, LocalFrame};
use vestnav_device::gps::Fix;

use crate::guidance::GuidanceStatus;

/// Track points drawn at most per frame (older points are strided, the newest [`TRACK_TAIL`] drawn in full).
pub const TRACK_DRAW_MAX: usize = 2500;
/// Newest track points always drawn at full resolution.
pub const TRACK_TAIL: usize = 500;
/// With tiles on, the map falls back to the local grid when no tile has arrived for this long [s].
pub const TILES_OFFLINE_AFTER_S: f64 = 2.0;

/// Map state kept between frames.
pub struct MapView {
    /// walkers' view state (centre, zoom).
    pub memory: MapMemory,
    tiles: Option<HttpTiles>,
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
    /// The wearer's track, `(lat_deg, lon_deg)`.
    pub track: Vec<(f64, f64)>,
    /// A track shown from a session log being replayed, and the replay cursor.
    pub replay: Option<(Vec<(f64, f64)>, usize)>,
    /// Left click adds a waypoint.
    pub add_mode: bool,
    /// Operator marks made with the M key.
    pub marks: u32,
    /// GPX file path for import/export.
    pub gpx_path: String,
    right_click_at: Option<Position>,
    menu_wp: Option<usize>,
}

/// A [`Tiles`] wrapper that counts tiles found and missing, to tell "offline" from "loading".
struct CountingTiles<'a> {
    inner: &'a mut HttpTiles,
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
            tiles: None,
            tile_hits: Rc::default(),
            tile_misses: Rc::default(),
            no_tiles_since_s: None,
            route_name: "route".into(),
            waypoints: Vec::new(),
            next: 0,
            track: Vec::new(),
            replay: None,
            add_mode: false,
            marks: 0,
            gpx_path: String::new(),
            right_click_at: None,
            menu_wp: None,
        }
    }

    /// Appends a position to the wearer's track.
    pub fn push_track(&mut self, lat_deg: f64, lon_deg: f64) {
        if lat_deg.is_finite() && lon_deg.is_finite() {
            self.track.push((lat_deg, lon_deg));
        }
    }

    fn anchor(&self) -> (f64, f64) {
        self.waypoints
            .first()
            .map(|w| (w.lat_deg, w.lon_deg))
            .or_else(|| self.track.first().copied())
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
        changed |= self.toolbar(ui, cfg, status);
        let speed_m_s = fix.and_then(|f| f.speed_m_s);
        self.next_info(ui, fix, guidance, speed_m_s, walking_m_s);
        egui::Panel::right("waypoint-list").default_size(210.0).show(ui, |ui| {
            changed |= self.waypoint_list(ui);
        });
        changed |= self.map_ui(ui, fix, guidance.and_then(|g| g.heading_deg), cfg);
        self.next = self.next.min(self.waypoints.len());
        changed
    }

    fn toolbar(&mut self, ui: &mut egui::Ui, cfg: &mut Config, status: &mut String) -> bool {
        let mut changed = false;
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
            ui.checkbox(&mut cfg.map_tiles, "OSM tiles");
            ui.separator();
            ui.add(egui::TextEdit::singleline(&mut self.gpx_path).hint_text("file.gpx").desired_width(160.0));
            if ui.button("Import GPX").clicked() {
                match crate::route::read_gpx(std::path::Path::new(self.gpx_path.trim())) {
                    Ok(c) => {
                        let (nw, nt) = (c.waypoints.len(), c.track.len());
                        if nw > 0 {
                            self.waypoints = c.waypoints;
                            self.next = 0;
                            self.route_name = c.name.unwrap_or_else(|| "imported".into());
                            changed = true;
                        }
                        if nt > 0 {
                            self.replay = Some((c.track, usize::MAX));
                        }
                        *status = format!("imported {nw} waypoints and {nt} track points");
                    }
                    Err(e) => *status = format!("GPX import failed: {e}"),
                }
            }
            if ui.button("Export GPX").clicked() {
                let path = self.gpx_path.trim().to_owned();
                *status = match crate::route::write_gpx(&self.route_name, &self.waypoints, &self.track)
                    .and_then(|t| std::fs::write(&path, t).map_err(|e| e.to_string()))
                {
                    Ok(()) => format!(
                        "wrote {} waypoints and {} track points to {path}",
                        self.waypoints.len(),
                        self.track.len()
                    ),
                    Err(e) => format!("GPX export failed: {e}"),
                };
            }
            if ui.button("Clear track").clicked() {
                self.track.clear();
                self.replay = None;
            }
        });
        changed
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
                    let ttg = d / v;
                    let b = bearing.map_or_else(|| "—".to_owned(), |b| format!("{b:.0}°"));
                    format!(
                        "next: {} ({}/{}) · {d:.0} m · aim bearing {b} · {:.0} min {:02.0} s to go",
                        w.name,
                        self.next + 1,
                        self.waypoints.len(),
                        (ttg / 60.0).floor(),
                        ttg % 60.0
                    )
                }
            },
        };
        ui.label(RichText::new(text).strong());
    }

    fn waypoint_list(&mut self, ui: &mut egui::Ui) -> bool {
        let mut changed = false;
        ui.label(RichText::new(format!("{} ({} waypoints)", self.route_name, self.waypoints.len())).strong());
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
                    if ui.small_button("Up").on_hover_text("Move earlier").clicked() {
                        action = Some((i, WaypointAction::MoveUp));
                    }
                    if ui.small_button("Down").on_hover_text("Move later").clicked() {
                        action = Some((i, WaypointAction::MoveDown));
                    }
                    if ui.small_button("Del").on_hover_text("Delete").clicked() {
                        action = Some((i, WaypointAction::Delete));
                    }
                });
            }
        });
        if let Some((i, a)) = action {
            changed = true;
            self.apply_waypoint_action(i, a);
        }
        changed
    }

    fn apply_waypoint_action(&mut self, i: usize, action: WaypointAction) {
        match action {
            WaypointAction::Select => self.next = i,
            WaypointAction::MoveUp => self.move_waypoint(i, -1),
            WaypointAction::MoveDown => self.move_waypoint(i, 1),
            WaypointAction::Delete => self.delete_waypoint(i),
        }
    }

    /// Moves waypoint `i` one place earlier (`-1`) or later (`1`).
    pub fn move_waypoint(&mut self, i: usize, dir: i32) {
        let j = if dir < 0 { i.checked_sub(1) } else { Some(i + 1) };
        if let Some(j) = j.filter(|&j| j < self.waypoints.len()) {
            self.waypoints.swap(i, j);
        }
    }

    /// Deletes waypoint `i`, keeping the next waypoint the same where possible.
    pub fn delete_waypoint(&mut self, i: usize) {
        if i < self.waypoints.len() {
            self.waypoints.remove(i);
            if i < self.next {
                self.next -= 1;
            }
        }
    }

    /// Adds a waypoint at `pos`: at the end, or right before the next one when `as_next`.
    pub fn add_waypoint(&mut self, pos: Position, as_next: bool) {
        let n = self.waypoints.len() + 1;
        let w = Waypoint { name: format!("WP{n}"), lat_deg: pos.y(), lon_deg: pos.x() };
        if as_next && self.next <= self.waypoints.len() {
            self.waypoints.insert(self.next, w);
        } else {
            self.waypoints.push(w);
        }
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
        if cfg.map_tiles && self.tiles.is_none() {
            let options = HttpOptions {
                cache: Some(crate::config::data_dir().join("tiles")),
                user_agent: Some(walkers::HeaderValue::from_static("vestnav-console/0.1")),
                ..HttpOptions::default()
            };
            self.tiles =
                Some(HttpTiles::with_options(walkers::sources::OpenStreetMap, options, ui.ctx().clone()));
        }
        let wearer = fix.and_then(|f| f.lat_deg.zip(f.lon_deg)).map(|(la, lo)| lat_lon(la, lo));
        let anchor = self.anchor();
        let my_position = wearer.unwrap_or_else(|| lat_lon(anchor.0, anchor.1));
        self.tile_hits.set(0);
        self.tile_misses.set(0);
        let mut counting = match (&mut self.tiles, cfg.map_tiles) {
            (Some(t), true) => Some(CountingTiles {
                inner: t,
                hits: self.tile_hits.clone(),
                misses: self.tile_misses.clone(),
            }),
            _ => None,
        };
        let tiles_dyn = counting.as_mut().map(|t| t as &mut dyn Tiles);
        let now_s = ui.input(|i| i.time);
        let tiles_missing_s = self.no_tiles_since_s.map_or(0.0, |t| now_s - t);
        let tiles_on = cfg.map_tiles;
        // Borrow the fields the closure needs separately from walkers' memory.
        let waypoints = &mut self.waypoints;
        let next = &mut self.next;
        let track = &self.track;
        let replay = &self.replay;
        let add_mode = self.add_mode;
        let right_click_at = &mut self.right_click_at;
        let menu_wp = &mut self.menu_wp;
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
                    Color32::from_rgb(150, 60, 200),
                );
                if let Some(&(la, lo)) = rt.get((*cursor).min(rt.len()).saturating_sub(1)) {
                    painter.circle_filled(
                        to_pos2(projector.project(lat_lon(la, lo))),
                        6.0,
                        Color32::from_rgb(150, 60, 200),
                    );
                }
            }
            // The wearer's own track.
            draw_track(&painter, projector, track, Color32::from_rgb(220, 50, 50));

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
                    let ll = projector.unproject(pos.to_vec2());
                    waypoints[i].lat_deg = ll.y();
                    waypoints[i].lon_deg = ll.x();
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
            // (orange: the compass, or whatever the heading rule chose; true north up).
            if let (Some(w), Some(f)) = (wearer, fix) {
                let c = to_pos2(projector.project(w));
                if let Some(e) = f.error.map(|e| e.horizontal_m).filter(|e| e.is_finite() && *e > 0.0) {
                    let r = (e * px_per_m) as f32;
                    painter.circle(
                        c,
                        r.min(4000.0),
                        Color32::from_rgba_unmultiplied(40, 140, 255, 40),
                        Stroke::new(1.0, Color32::from_rgb(40, 140, 255)),
                    );
                }
                if let (Some(course), Some(v)) = (f.course_deg, f.speed_m_s)
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
                painter.circle(c, 7.0, Color32::from_rgb(20, 90, 200), Stroke::new(2.0, Color32::WHITE));
            }

            // Adding waypoints.
            if add_mode
                && response.clicked()
                && let Some(pos) = response.interact_pointer_pos()
            {
                let ll = projector.unproject(pos.to_vec2());
                waypoints.push(Waypoint {
                    name: format!("WP{}", waypoints.len() + 1),
                    lat_deg: ll.y(),
                    lon_deg: ll.x(),
                });
                changed = true;
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
            let note = if offline {
                if tiles_on {
                    "tiles unavailable (offline?): local grid"
                } else {
                    "local metric grid (tiles off)"
                }
            } else {
                "© OpenStreetMap contributors"
            };
            painter.text(
                rect.right_bottom() - vec2(6.0, 4.0),
                egui::Align2::RIGHT_BOTTOM,
                note,
                egui::FontId::proportional(11.0),
                ink,
            );

            (action, add_here)
        });
        let (action, add_here) = resp.inner;
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

/// Draws a track, strided for old points and full for the newest [`TRACK_TAIL`].
fn draw_track(painter: &egui::Painter, projector: &Projector, track: &[(f64, f64)], color: Color32) {
    if track.len() < 2 {
        return;
    }
    let tail_start = track.len().saturating_sub(TRACK_TAIL);
    let stride = decimation_stride(tail_start, TRACK_DRAW_MAX - TRACK_TAIL);
    let mut pts: Vec<Pos2> = Vec::with_capacity(TRACK_DRAW_MAX + 2);
    pts.extend(
        track[..tail_start]
            .iter()
            .step_by(stride)
            .map(|&(la, lo)| to_pos2(projector.project(lat_lon(la, lo)))),
    );
    pts.extend(track[tail_start..].iter().map(|&(la, lo)| to_pos2(projector.project(lat_lon(la, lo)))));
    painter.line(pts, Stroke::new(2.0, color));
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
}
