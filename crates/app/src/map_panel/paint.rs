//! The map's painting, one layer after the other: tiles or the metric grid, route, track, waypoints, the
//! wearer, the tools' overlay and the scale bar, with the mouse editing of waypoints on the map.

use std::cell::Cell;
use std::rc::Rc;
use std::time::Instant;

use egui::{Color32, Pos2, RichText, Stroke, vec2};
use walkers::{Position, Projector, TileId, TilePiece, Tiles, lat_lon};

use crate::config::Config;
use crate::map_tools;
use vestnav_core::geo::{DVec2, Earth, LatLon, LocalFrame};
use vestnav_device::gps::Fix;
use vestnav_device::route_file::TrackPoint;
use vestnav_station::route::{RouteModel, Track, segments};
use vestnav_station::{Notices, Severity, Subject};

use super::route_line::{self, PATH_DRAWN_MAX, PathStyle};
use super::walk::{PROFILES, WalkRequest};
use super::{
    MapView, TILES_OFFLINE_AFTER_S, TRACK_DRAW_MAX, TRACK_TAIL, WAYPOINT_MARKERS_MAX, WaypointAction,
    age_text, decimation_stride, nice_length_m, wearer_marker,
};

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

/// The outline drawn around map text: dark behind light text, light behind dark text, so a label reads on
/// light tiles (streets, fields) and dark ones (forest, satellite) alike.
fn halo_color(text: Color32) -> Color32 {
    // Rec. 601 luma of the text colour, 0..=255.
    let luma = 0.299 * f32::from(text.r()) + 0.587 * f32::from(text.g()) + 0.114 * f32::from(text.b());
    if luma > 127.5 { Color32::from_black_alpha(230) } else { Color32::from_white_alpha(235) }
}

/// Text on the map with a 1.5 px halo of [`halo_color`] (the galley is laid out once and painted nine
/// times: eight offsets of the halo, then the text).
pub(super) fn halo_text(
    painter: &egui::Painter,
    pos: Pos2,
    anchor: egui::Align2,
    text: impl Into<String>,
    font: egui::FontId,
    color: Color32,
) -> egui::Rect {
    let galley = painter.layout_no_wrap(text.into(), font, color);
    let rect = anchor.anchor_size(pos, galley.size());
    let halo = halo_color(color);
    for (dx, dy) in
        [(-1.5, 0.0), (1.5, 0.0), (0.0, -1.5), (0.0, 1.5), (-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)]
    {
        painter.galley_with_override_text_color(rect.min + vec2(dx, dy), galley.clone(), halo);
    }
    painter.galley(rect.min, galley, color);
    rect
}

fn to_pos2(v: egui::Vec2) -> Pos2 {
    Pos2::new(v.x, v.y)
}

impl MapView {
    #[allow(clippy::too_many_lines)] // one paint pass over every layer of the map, in order
    #[allow(clippy::too_many_arguments)]
    pub(super) fn map_ui(
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
        // Bottom first: the OSM extract (once read), then the raster source; one of them alone is the base.
        let (extract, raster) = self.tiles.layers(cfg, ui.ctx());
        let extract_on = extract.is_some();
        let (hits, misses) = (&self.tile_hits, &self.tile_misses);
        let count = |t| CountingTiles { inner: t, hits: hits.clone(), misses: misses.clone() };
        let (mut bottom, mut top) = (extract.map(count), raster.map(count));
        let (base, over): (Option<&mut dyn Tiles>, Option<&mut dyn Tiles>) =
            match (bottom.as_mut(), top.as_mut()) {
                (Some(b), t) => (Some(b), t.map(|t| t as &mut dyn Tiles)),
                (None, t) => (t.map(|t| t as &mut dyn Tiles), None),
            };
        let now_s = ui.input(|i| i.time);
        let tiles_missing_s = self.no_tiles_since_s.map_or(0.0, |t| now_s - t);
        let tiles_on = cfg.map_tiles || extract_on;
        // Borrow the fields the closure needs separately from walkers' memory. The closure only reads the
        // route; what it asks for (drag, add, menu actions) is applied to the route after it.
        let waypoints = route.waypoints();
        let next = &route.next();
        let track_from = self.track_from.min(track.points().len());
        let drawn_track = track.points().get(track_from..).unwrap_or(&[]);
        let drawn_breaks: Vec<usize> =
            track.breaks().iter().filter(|b| **b > track_from).map(|b| b - track_from).collect();
        let replay = &self.replay;
        let remote_wearers = &self.remote_wearers;
        let add_mode = self.add_mode && !self.tools.measuring;
        let measuring = self.tools.measuring;
        let measure_points = self.tools.measure_points.clone();
        let field = &self.tools.field;
        let right_click_at = &mut self.right_click_at;
        let menu_wp = &mut self.menu_wp;
        let mut dragging = false;
        let mut dragged_to = None;
        let has_paths = extract_on;
        let walk_busy = self.walk.busy();
        let walk_profile = &mut self.walk.profile;
        let mut walk_req: Option<WalkRequest> = None;
        let mut map = walkers::Map::new(base, &mut self.memory, my_position)
            .double_click_to_zoom(true)
            .zoom_with_ctrl(false);
        if let Some(over) = over {
            map = map.with_layer(over, 1.0);
        }
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
            // A route planned along paths is drawn along its path (passed, ahead, the rest), at most
            // PATH_DRAWN_MAX points a frame.
            let path = route.path();
            if let Some(path) = path {
                route_line::draw(&painter, projector, path, *next, &PathStyle::LOCAL, PATH_DRAWN_MAX);
            } else if pts.len() >= 2 {
                painter.line(pts.clone(), Stroke::new(2.0, Color32::from_rgb(60, 120, 220)));
            }
            if path.is_none()
                && let (Some(w), Some(p)) = (wearer, pts.get(*next))
            {
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
                        halo_text(
                            &painter,
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
                    halo_text(
                        &painter,
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
                    halo_text(
                        &painter,
                        c + vec2(12.0, 12.0),
                        egui::Align2::LEFT_TOP,
                        format!("last known, {}", age_text(m.age_s)),
                        font.clone(),
                        ui.visuals().strong_text_color(),
                    );
                }
            }

            // Remote stations' wearers (`vestnav --broker`), over the local one.
            super::remote::draw(&painter, projector, remote_wearers, ui);

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
                halo_text(
                    &painter,
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
                halo_text(
                    &painter,
                    c + vec2(8.0, 4.0),
                    egui::Align2::LEFT_TOP,
                    label,
                    font.clone(),
                    ui.visuals().strong_text_color(),
                );
            }

            if let Some(r) = &field.reference {
                let c = to_pos2(projector.project(lat_lon(r.pos.lat_deg, r.pos.lon_deg)));
                r.draw(&painter, c, px_per_m, font.clone(), ui.visuals().strong_text_color());
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
            if field.reference.is_some() {
                legend.push((map_tools::REFERENCE_COLOR, "reference (circle: its uncertainty)"));
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
                if has_paths {
                    ui.separator();
                    let here = right_click_at.map(|p| LatLon::new(p.y(), p.x()));
                    let from = wearer.map(|w| LatLon::new(w.y(), w.x()));
                    let to_here = ui
                        .add_enabled(
                            from.is_some() && !walk_busy,
                            egui::Button::new("Route to here along paths"),
                        )
                        .on_disabled_hover_text("needs a fix of the wearer (and no plan running)");
                    if to_here.clicked()
                        && let (Some(from), Some(to)) = (from, here)
                    {
                        walk_req = Some(WalkRequest::ToHere { from, to });
                    }
                    let follow = ui
                        .add_enabled(
                            waypoints.len() >= 2 && !walk_busy,
                            egui::Button::new("Follow paths (every leg of the route)"),
                        )
                        .on_disabled_hover_text("needs a route of two waypoints or more");
                    if follow.clicked() {
                        walk_req = Some(WalkRequest::FollowPaths(waypoints.to_vec()));
                    }
                    ui.horizontal(|ui| {
                        ui.label("Profile");
                        for (p, name) in PROFILES {
                            ui.radio_value(walk_profile, p, name);
                        }
                    });
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
        if let Some(req) = walk_req {
            self.start_walk(req, ui.ctx(), notices);
        }
        if tiles_on && self.tile_hits.get() == 0 && self.tile_misses.get() > 0 {
            self.no_tiles_since_s.get_or_insert(now_s);
        } else {
            self.no_tiles_since_s = None;
        }
        if self.memory.detached().is_some() {
            cfg.follow = false;
        }
    }
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

    /// WCAG contrast ratio of two opaque colours (relative luminance from sRGB, WCAG 2.x definition).
    fn contrast(a: Color32, b: Color32) -> f32 {
        let lum = |c: Color32| {
            let lin = |v: u8| {
                let v = f32::from(v) / 255.0;
                if v <= 0.039_28 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
            };
            0.2126 * lin(c.r()) + 0.7152 * lin(c.g()) + 0.0722 * lin(c.b())
        };
        let (x, y) = (lum(a), lum(b));
        (x.max(y) + 0.05) / (x.min(y) + 0.05)
    }

    /// Whatever the theme's text colour, its halo contrasts with it by at least 4.5:1 (WCAG AA), so the
    /// label reads on white and on black tiles alike.
    #[test]
    fn labels_have_a_contrasting_halo() {
        for text in [Color32::WHITE, Color32::from_gray(220), Color32::from_gray(40), Color32::BLACK] {
            let halo = halo_color(text);
            let [r, g, b, _] = halo.to_srgba_unmultiplied();
            let opaque = Color32::from_rgb(r, g, b);
            assert!(contrast(text, opaque) >= 4.5, "{text:?} on {opaque:?}");
        }
    }
}
