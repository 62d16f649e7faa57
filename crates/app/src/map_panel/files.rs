//! The map's route file row: the typed path, Recent, Import (with the choice dialog when a file holds
//! more than one route) and the GPX / `GeoJSON` exports.

use std::path::{Path, PathBuf};

use egui::RichText;

use crate::config::Config;
use crate::route_import::{ImportChoice, ImportDialog};
use vestnav_device::route_file::TrackPoint;
use vestnav_station::route::{RouteModel, Track};
use vestnav_station::{Notices, Severity, Subject};

use super::{MapView, RouteExport};

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

impl MapView {
    /// The route file: the typed path with Browse… and the path it uses, Recent, Import, the exports (each
    /// asking "Replace X?" before writing over a file).
    pub(super) fn file_row(
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

    /// Replaces the route with an imported choice (one undo step); a route beyond the limit is refused and
    /// said. While guidance is steering the wearer the operator is asked first (guidance restarts at the
    /// new route's first waypoint).
    pub fn import_choice(&mut self, route: &mut RouteModel, c: ImportChoice, notices: &mut Notices) {
        self.import = None;
        if self.guiding {
            self.pending_import = Some(c);
            return;
        }
        Self::replace_route(route, c, notices);
    }

    fn replace_route(route: &mut RouteModel, c: ImportChoice, notices: &mut Notices) {
        match route.replace_with_path(c.name, c.waypoints, c.path) {
            Ok(()) => notices.raise(Severity::Info, Subject::Route, format!("imported {}", c.label)),
            Err(e) => notices.raise(Severity::Alarm, Subject::Route, format!("not imported: {e}")),
        }
    }

    /// "Replace the route being guided?" for an import that waits for the answer.
    pub(super) fn confirm_import(&mut self, ui: &egui::Ui, route: &mut RouteModel, notices: &mut Notices) {
        let Some(c) = &self.pending_import else { return };
        let next = route.waypoints().get(route.next()).map_or_else(String::new, |w| w.name.clone());
        let mut answer = None;
        let modal = egui::Modal::new(egui::Id::unique("vestnav-confirm-import")).show(ui.ctx(), |ui| {
            ui.label(RichText::new("Replace the route being guided?").strong());
            ui.label(format!(
                "Guidance heads for {next} now. Importing {} replaces the route and restarts guidance at its \
                 first waypoint (Undo brings the old route back).",
                c.label
            ));
            ui.horizontal(|ui| {
                if ui.button("Replace route").clicked() {
                    answer = Some(true);
                }
                if ui.button("Keep the current route").clicked() {
                    answer = Some(false);
                }
            });
        });
        if answer.is_none() && modal.should_close() {
            answer = Some(false);
        }
        match answer {
            Some(true) => {
                if let Some(c) = self.pending_import.take() {
                    Self::replace_route(route, c, notices);
                }
            }
            Some(false) => {
                if let Some(c) = self.pending_import.take() {
                    notices.raise(Severity::Info, Subject::Route, format!("{} not imported", c.label));
                }
            }
            None => {}
        }
    }

    /// The import dialog (when open): one button per thing the file holds; returns whether the route
    /// changed.
    pub(super) fn import_dialog(&mut self, ui: &mut egui::Ui, route: &mut RouteModel, notices: &mut Notices) {
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
}
