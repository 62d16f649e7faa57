//! The map's "Tiles" controls: the on/off switch, the indicator of where tiles come from (and how many
//! are cached, stale, missing), and the Tiles window: the source picker, the cache's size limit, and the
//! prefetch of the route's area.

use std::path::PathBuf;

use egui::{Color32, RichText};

use vestnav_tiles::prefetch::{self, Prefetch, PrefetchRequest, PrefetchTarget};
use vestnav_tiles::{BBox, MAX_ZOOM, TileSourceConfig, cache, check_url_template, url_host};

use super::{MapExtract, SourceTiles};
use crate::config::Config;
use crate::file_dialog::{Browse, DialogSpec, Mode, path_field};
use vestnav_station::route::Waypoint;

/// The source picker's choice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Osm,
    Xyz,
    PmTiles,
    MbTiles,
    Folder,
}

/// The prefetch's target choice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum PrefetchInto {
    Cache,
    MbTiles,
}

/// What the cache thread reports: a message (after a prune) and the cache's size [bytes] and file count.
type CacheReport = (Option<String>, (u64, usize));

/// Tile state of the map: the active source's tiles, the Tiles window and a prefetch job.
pub struct MapTiles {
    active: Option<SourceTiles>,
    /// The OpenStreetMap extract the settings name (`vestnav --map`), read, drawn under the raster source.
    pub extract: Option<MapExtract>,
    /// The extract path field of the Tiles window.
    map_path: String,
    /// Its Browse… dialog.
    browse_map: Browse,
    /// The Tiles window is open.
    pub window_open: bool,
    kind: Kind,
    url: String,
    attribution: String,
    allows_bulk: bool,
    path: String,
    /// Why the last Apply was refused.
    pub source_error: Option<String>,
    /// Margin around the route for the prefetch [m].
    pub margin_m: f64,
    /// Lowest prefetch zoom.
    pub z0: u8,
    /// Highest prefetch zoom.
    pub z1: u8,
    /// Where the prefetch writes.
    prefetch_into: PrefetchInto,
    /// The MBTiles file a prefetch writes (created, or resumed when it exists).
    pub prefetch_mbtiles_path: String,
    /// The running or last prefetch.
    pub prefetch: Option<Prefetch>,
    /// The source path field's Browse… dialog.
    browse_source: Browse,
    /// The prefetch MBTiles field's Browse… dialog.
    browse_prefetch: Browse,
    /// The MBTiles file the last prefetch wrote, offered as the source once it has ended.
    prefetch_file: Option<PathBuf>,
    /// A message about the last prefetch or prune.
    pub message: Option<String>,
    pruned: bool,
    usage: Option<(u64, usize)>,
    /// What a "Prune now" or "Measure" on the worker thread found: (message, usage).
    cache_job: Option<std::sync::mpsc::Receiver<CacheReport>>,
}

impl Default for MapTiles {
    fn default() -> Self {
        Self {
            active: None,
            extract: None,
            map_path: String::new(),
            browse_map: Browse::default(),
            window_open: false,
            kind: Kind::Osm,
            url: String::new(),
            attribution: String::new(),
            allows_bulk: false,
            path: String::new(),
            source_error: None,
            margin_m: 300.0,
            z0: 12,
            z1: 17,
            prefetch_into: PrefetchInto::Cache,
            prefetch_mbtiles_path: String::new(),
            prefetch: None,
            browse_source: Browse::default(),
            browse_prefetch: Browse::default(),
            prefetch_file: None,
            message: None,
            pruned: false,
            usage: None,
            cache_job: None,
        }
    }
}

/// The cache root the config names, or the platform's.
pub fn cache_root(cfg: &Config) -> PathBuf {
    cfg.tile_cache_dir.clone().unwrap_or_else(cache::default_root)
}

const PMTILES_FILE: DialogSpec =
    DialogSpec { mode: Mode::Open, title: "Raster PMTiles file", filter: ("PMTiles", &["pmtiles"]) };
const MBTILES_FILE: DialogSpec =
    DialogSpec { mode: Mode::Open, title: "Raster MBTiles file", filter: ("MBTiles", &["mbtiles"]) };
const MBTILES_WRITE: DialogSpec =
    DialogSpec { mode: Mode::Save, title: "MBTiles file to write", filter: ("MBTiles", &["mbtiles"]) };
const OSM_EXTRACT: DialogSpec = DialogSpec {
    mode: Mode::Open,
    title: "OpenStreetMap extract (.osm.pbf)",
    filter: ("OSM extract", &["pbf"]),
};
const TILE_FOLDER: DialogSpec =
    DialogSpec { mode: Mode::Folder, title: "Folder of {z}/{x}/{y} tiles", filter: ("", &[]) };

/// Why the map shows no tiles, true to the cause: the source that could not be opened, the latest
/// refusal or failure while tiles are refused or failed (a network failure says offline, refused or
/// unreachable — from the fetch error), "loading" while tiles load, and "SOURCE has none here" only when
/// the source answered that it has no such tile.
fn no_tiles_note(
    open: Option<Result<vestnav_tiles::store::StoreInfo, String>>,
    last_error: Option<String>,
    c: super::local::FrameCounts,
    source: &str,
) -> String {
    match (open, last_error) {
        (Some(Err(e)), _) => format!("no tiles: metric grid ({e})"),
        (_, Some(e)) if c.refused + c.failed > 0 => format!("no tiles: metric grid ({e})"),
        _ if c.loading > 0 => "no tiles yet: metric grid (loading…)".into(),
        _ if c.missing > 0 => format!("no tiles: metric grid ({source} has none here)"),
        _ => "no tiles: metric grid".into(),
    }
}

fn mb(bytes: u64) -> String {
    format!("{:.1} MB", bytes as f64 / 1e6)
}

impl MapTiles {
    /// The tiles to draw this frame (`None` with tiles off): (re)starts the source when the setting
    /// changed, and prunes the cache once per run, on a worker thread.
    pub fn active(&mut self, cfg: &Config, ctx: &egui::Context) -> Option<&mut SourceTiles> {
        if !cfg.map_tiles {
            self.active = None;
            return None;
        }
        if self.active.as_ref().is_none_or(|t| t.source() != Some(&cfg.tiles)) {
            self.active = Some(SourceTiles::new(cfg.tiles.clone(), &cache_root(cfg), ctx.clone()));
        }
        self.prune_once(cfg);
        let t = self.active.as_mut()?;
        t.begin_frame();
        Some(t)
    }

    /// Prunes the disk cache (raster tiles and the extract's drawn ones) to its limit, once per run, on a
    /// worker thread.
    fn prune_once(&mut self, cfg: &Config) {
        if !self.pruned {
            self.pruned = true;
            let (root, limit) = (cache_root(cfg), cfg.tile_cache_mb.saturating_mul(1_000_000));
            // Pruning walks the whole cache: never on the UI thread. It reports nothing back; the cache
            // usage shown in the Tiles window is measured when asked.
            let _ = std::thread::Builder::new()
                .name("tiles-prune".into())
                .spawn(move || cache::prune(&root, limit));
        }
    }

    /// The extract the settings name, opened (read on its thread) when the setting changed; its outcome
    /// taken when it has arrived.
    pub fn sync_extract(&mut self, cfg: &Config, ctx: &egui::Context) {
        match &cfg.osm_map {
            None => self.extract = None,
            Some(p) if self.extract.as_ref().is_none_or(|e| e.path() != p) => {
                self.extract = Some(MapExtract::open(p, &cache_root(cfg), ctx));
                // Its drawn tiles go to the disk cache: bounded with the raster tiles' even with tiles off.
                self.prune_once(cfg);
            }
            Some(_) => {}
        }
        if let Some(e) = &mut self.extract {
            e.poll(ctx);
        }
    }

    /// The layers to draw this frame, bottom first: the extract's tiles (once read) and the raster
    /// source's (with tiles on). The extract shows wherever the raster source has no tile.
    pub fn layers(
        &mut self,
        cfg: &Config,
        ctx: &egui::Context,
    ) -> (Option<&mut SourceTiles>, Option<&mut SourceTiles>) {
        self.sync_extract(cfg, ctx);
        // `active` borrows all of self: take the raster layer through it, the extract's beside it.
        let raster = self.active(cfg, ctx).is_some();
        let mut extract = self.extract.as_mut().and_then(MapExtract::tiles);
        if let Some(t) = extract.as_deref_mut() {
            t.begin_frame();
        }
        (extract, if raster { self.active.as_mut() } else { None })
    }

    /// The note at the map's bottom right: the attribution with tiles, "no tiles: metric grid" (and why)
    /// without: the source that could not be opened, the tiles refused or failed (the latest reason, naming
    /// the tile and its file or server: offline, refused, unreachable, an HTTP error), tiles still loading,
    /// or — only when the source itself said it has no such tile (a 404, a file without it) — that the
    /// source has none here.
    pub fn note(&self, cfg: &Config, no_tiles_shown: bool) -> String {
        if self.extract.as_ref().is_some_and(|e| e.loaded().is_some()) {
            // The extract's own attribution, required wherever its map shows; the raster's beside it.
            let raster = self.active.as_ref().filter(|_| cfg.map_tiles).map(SourceTiles::attribution_text);
            return match raster {
                Some(a) if !a.is_empty() && a != vestnav_osm::ATTRIBUTION => {
                    format!("{} · {a}", vestnav_osm::ATTRIBUTION)
                }
                _ => vestnav_osm::ATTRIBUTION.to_owned(),
            };
        }
        if !cfg.map_tiles {
            return "no tiles: metric grid (tiles off)".into();
        }
        let Some(t) = &self.active else { return "no tiles: metric grid".into() };
        if no_tiles_shown {
            return no_tiles_note(t.open_state(), t.last_error(), t.counts(), t.label());
        }
        let a = t.attribution_text();
        if a.is_empty() { t.label().to_owned() } else { a }
    }

    /// The indicator's text and colour: the source and the tiles of the last frame by state.
    pub fn indicator(&self, cfg: &Config) -> (String, Color32) {
        if !cfg.map_tiles {
            return ("no tiles: metric grid".into(), Color32::GRAY);
        }
        let Some(t) = &self.active else { return (cfg.tiles.label(), Color32::GRAY) };
        if let Some(Err(e)) = t.open_state() {
            return (format!("{}: {e}", t.label()), Color32::from_rgb(220, 80, 60));
        }
        let c = t.counts();
        let mut parts = Vec::new();
        for (n, what) in [
            (c.local, "local"),
            (c.cached, "cached"),
            (c.downloaded, "downloaded"),
            (c.stale, "stale"),
            (c.loading, "loading"),
            (c.missing, "missing"),
            (c.refused, "refused"),
            (c.failed, "failed"),
        ] {
            if n > 0 {
                parts.push(format!("{n} {what}"));
            }
        }
        let not_shown = c.missing + c.refused + c.failed;
        let colour = if not_shown > 0 && c.shown() == 0 {
            Color32::from_rgb(220, 80, 60)
        } else if not_shown > 0 || c.stale > 0 || c.loading > 0 {
            Color32::from_rgb(220, 170, 40)
        } else {
            Color32::from_rgb(70, 170, 90)
        };
        (format!("{}: {}", t.label(), if parts.is_empty() { "—".into() } else { parts.join(" · ") }), colour)
    }

    /// The map toolbar's tile controls and, when open, the Tiles window.
    pub fn toolbar(&mut self, ui: &mut egui::Ui, cfg: &mut Config, waypoints: &[Waypoint]) {
        ui.checkbox(&mut cfg.map_tiles, "Tiles");
        let (text, colour) = self.indicator(cfg);
        let hover = self
            .active
            .as_ref()
            .and_then(SourceTiles::last_error)
            .unwrap_or_else(|| "where the map's tiles come from".into());
        ui.label(RichText::new(text).color(colour).small()).on_hover_text(hover);
        if let Some(e) = &self.extract {
            let cache_problem = e.loaded().and_then(|l| l.cache_problem()).is_some();
            let colour = if e.error().is_some() {
                Color32::from_rgb(220, 80, 60)
            } else if e.loaded().is_some() && !cache_problem {
                Color32::from_rgb(70, 170, 90)
            } else {
                Color32::from_rgb(220, 170, 40)
            };
            ui.label(RichText::new(e.status()).color(colour).small())
                .on_hover_text("the OpenStreetMap extract drawn offline under the tiles (Tiles… to change)");
        }
        if ui.button("Tiles…").on_hover_text("Tile source, cache and offline prefetch").clicked() {
            self.window_open = !self.window_open;
            if self.window_open {
                self.load_fields(&cfg.tiles);
                self.map_path = cfg.osm_map.as_ref().map(|p| p.display().to_string()).unwrap_or_default();
            }
        }
        if let Some(p) = &self.prefetch
            && !p.snapshot().finished
        {
            ui.ctx().request_repaint_after(std::time::Duration::from_millis(200));
        }
        let mut open = self.window_open;
        egui::Window::new("Tiles").open(&mut open).resizable(true).default_width(460.0).show(
            ui.ctx(),
            |ui| {
                self.window(ui, cfg, waypoints);
            },
        );
        self.window_open &= open;
    }

    fn load_fields(&mut self, source: &TileSourceConfig) {
        self.source_error = None;
        match source {
            TileSourceConfig::Osm => self.kind = Kind::Osm,
            TileSourceConfig::Xyz { url, attribution, allows_bulk } => {
                self.kind = Kind::Xyz;
                self.url.clone_from(url);
                self.attribution.clone_from(attribution);
                self.allows_bulk = *allows_bulk;
            }
            TileSourceConfig::PmTiles(p) | TileSourceConfig::MbTiles(p) | TileSourceConfig::Folder(p) => {
                self.kind = match source {
                    TileSourceConfig::PmTiles(_) => Kind::PmTiles,
                    TileSourceConfig::MbTiles(_) => Kind::MbTiles,
                    _ => Kind::Folder,
                };
                self.path = p.display().to_string();
            }
        }
    }

    /// The source the picker's fields describe, or why they do not describe one.
    fn picked(&self) -> Result<TileSourceConfig, String> {
        // The path the field's "Uses: …" line shows: a relative one is taken in the documents folder.
        let path = || {
            crate::file_dialog::resolve(&self.path, &crate::file_dialog::documents_dir())
                .ok_or_else(|| "enter the file or folder path".to_owned())
        };
        Ok(match self.kind {
            Kind::Osm => TileSourceConfig::Osm,
            Kind::Xyz => {
                let url = self.url.trim().to_owned();
                check_url_template(&url)?;
                let attribution = if self.attribution.trim().is_empty() {
                    format!("tiles: {}", url_host(&url))
                } else {
                    self.attribution.trim().to_owned()
                };
                TileSourceConfig::Xyz { url, attribution, allows_bulk: self.allows_bulk }
            }
            Kind::PmTiles => TileSourceConfig::PmTiles(path()?),
            Kind::MbTiles => TileSourceConfig::MbTiles(path()?),
            Kind::Folder => TileSourceConfig::Folder(path()?),
        })
    }

    fn window(&mut self, ui: &mut egui::Ui, cfg: &mut Config, waypoints: &[Waypoint]) {
        self.source_ui(ui, cfg);
        self.extract_ui(ui, cfg);
        self.cache_and_prefetch_ui(ui, cfg, waypoints);
    }

    /// The source picker: kind, URL or path (with Browse…), where offline raster tiles come from, Use.
    fn source_ui(&mut self, ui: &mut egui::Ui, cfg: &mut Config) {
        ui.heading("Source");
        ui.horizontal_wrapped(|ui| {
            ui.radio_value(&mut self.kind, Kind::Osm, "OpenStreetMap");
            ui.radio_value(&mut self.kind, Kind::Xyz, "XYZ URL");
            ui.radio_value(&mut self.kind, Kind::PmTiles, "PMTiles file");
            ui.radio_value(&mut self.kind, Kind::MbTiles, "MBTiles file");
            ui.radio_value(&mut self.kind, Kind::Folder, "Tile folder");
        });
        match self.kind {
            Kind::Osm => {
                ui.label(
                    "The public OpenStreetMap server, cached on disk. Its policy forbids bulk download.",
                );
            }
            Kind::Xyz => {
                ui.add(
                    egui::TextEdit::singleline(&mut self.url)
                        .hint_text("https://…/{z}/{x}/{y}.png?key=…")
                        .desired_width(420.0),
                );
                ui.add(
                    egui::TextEdit::singleline(&mut self.attribution)
                        .hint_text("attribution text")
                        .desired_width(420.0),
                );
                ui.checkbox(&mut self.allows_bulk, "The provider's terms allow bulk/offline download");
            }
            Kind::PmTiles | Kind::MbTiles | Kind::Folder => {
                let (hint, spec) = match self.kind {
                    Kind::PmTiles => ("/path/area.pmtiles", PMTILES_FILE),
                    Kind::MbTiles => ("/path/area.mbtiles", MBTILES_FILE),
                    _ => ("/path/tiles (holding {z}/{x}/{y}.png)", TILE_FOLDER),
                };
                let base = crate::file_dialog::documents_dir();
                path_field(ui, &mut self.path, &mut self.browse_source, spec, &base, hint);
                ui.label(RichText::new(vestnav_tiles::OFFLINE_RASTER_SOURCES).small());
            }
        }
        ui.horizontal(|ui| {
            if ui.button("Use this source").clicked() {
                match self.picked() {
                    Ok(s) => {
                        cfg.tiles = s;
                        self.source_error = None;
                    }
                    Err(e) => self.source_error = Some(e),
                }
            }
            ui.label(format!("now: {}", cfg.tiles.label()));
        });
        if let Some(e) = &self.source_error {
            ui.colored_label(ui.visuals().error_fg_color, e);
        }
    }

    /// The OpenStreetMap extract: path (with Browse…), Use, Remove, and its state.
    fn extract_ui(&mut self, ui: &mut egui::Ui, cfg: &mut Config) {
        ui.separator();
        ui.heading("Offline map from an OpenStreetMap extract");
        ui.label(
            "An .osm.pbf extract (Geofabrik, BBBike, osmium extract) drawn offline at zooms 14–19 under \
             the tile source, where it has no tile; its footways route the wearer (right-click the map).",
        );
        let base = crate::file_dialog::documents_dir();
        path_field(ui, &mut self.map_path, &mut self.browse_map, OSM_EXTRACT, &base, "/path/area.osm.pbf");
        ui.horizontal(|ui| {
            if ui.button("Use this extract").clicked() {
                match crate::file_dialog::resolve(&self.map_path, &base) {
                    Some(p) => cfg.osm_map = Some(p),
                    None => self.source_error = Some("enter the extract's path".into()),
                }
            }
            if cfg.osm_map.is_some() && ui.button("Remove").clicked() {
                cfg.osm_map = None;
            }
        });
        if let Some(e) = &self.extract {
            match e.error() {
                Some(err) => ui.colored_label(ui.visuals().error_fg_color, err),
                None => ui.label(e.status()),
            };
        }
    }

    /// The cache's folder, limit and prune, and the prefetch of the route's area.
    fn cache_and_prefetch_ui(&mut self, ui: &mut egui::Ui, cfg: &mut Config, waypoints: &[Waypoint]) {
        ui.separator();
        ui.heading("Cache");
        let root = cache_root(cfg);
        ui.label(format!("Downloaded tiles are kept in {}", root.display()));
        if let Some(rx) = &self.cache_job
            && let Ok((message, usage)) = rx.try_recv()
        {
            self.message = message.or(self.message.take());
            self.usage = Some(usage);
            self.cache_job = None;
        }
        ui.horizontal(|ui| {
            ui.label("Size limit");
            ui.add(egui::DragValue::new(&mut cfg.tile_cache_mb).range(10..=100_000).suffix(" MB"));
            let idle = self.cache_job.is_none();
            let prune = ui
                .add_enabled(idle, egui::Button::new("Prune now"))
                .on_hover_text("Remove the least recently used tiles above the limit")
                .clicked();
            let measure = ui.add_enabled(idle, egui::Button::new("Measure")).clicked();
            if prune || measure {
                // Walking the cache takes a while when it is large: never on the UI thread.
                let (tx, rx) = std::sync::mpsc::channel();
                let (root, limit, ctx) =
                    (root.clone(), cfg.tile_cache_mb.saturating_mul(1_000_000), ui.ctx().clone());
                let spawned = std::thread::Builder::new().name("tiles-prune".into()).spawn(move || {
                    let message = prune.then(|| {
                        let r = cache::prune(&root, limit);
                        format!("pruned {} tiles: {} → {}", r.removed, mb(r.before_bytes), mb(r.after_bytes))
                    });
                    // The window may have been closed and the receiver dropped: nothing left to tell.
                    let _ = tx.send((message, cache::usage(&root)));
                    ctx.request_repaint();
                });
                match spawned {
                    Ok(_) => self.cache_job = Some(rx),
                    Err(e) => self.message = Some(format!("cannot start the cache thread: {e}")),
                }
            }
            if self.cache_job.is_some() {
                ui.spinner();
            } else if let Some((b, n)) = self.usage {
                ui.label(format!("{n} tiles, {}", mb(b)));
            }
        });

        ui.separator();
        ui.heading("Make this area available offline");
        self.prefetch_ui(ui, cfg, waypoints);
        if let Some(m) = &self.message {
            ui.label(m);
        }
    }

    fn prefetch_ui(&mut self, ui: &mut egui::Ui, cfg: &mut Config, waypoints: &[Waypoint]) {
        if let Err(why) = cfg.tiles.bulk_download_allowed() {
            ui.label(RichText::new(why).color(ui.visuals().warn_fg_color));
            if cfg.tiles.url_template().is_some() {
                ui.label(RichText::new(vestnav_tiles::OFFLINE_RASTER_SOURCES).small());
            }
            return;
        }
        let running = self.prefetch.as_ref().is_some_and(|p| !p.snapshot().finished);
        ui.add_enabled_ui(!running, |ui| {
            ui.horizontal(|ui| {
                ui.label("Margin around the route");
                ui.add(egui::DragValue::new(&mut self.margin_m).range(0.0..=20_000.0).suffix(" m"));
            });
            ui.horizontal(|ui| {
                ui.label("Zooms");
                ui.add(egui::DragValue::new(&mut self.z0).range(0..=MAX_ZOOM));
                ui.label("to");
                ui.add(egui::DragValue::new(&mut self.z1).range(0..=MAX_ZOOM));
                ui.label("Parallel downloads");
                ui.add(
                    egui::DragValue::new(&mut cfg.prefetch_parallelism).range(1..=prefetch::MAX_PARALLELISM),
                );
            });
            ui.horizontal(|ui| {
                ui.label("Into");
                ui.radio_value(&mut self.prefetch_into, PrefetchInto::Cache, "cache folder");
                ui.radio_value(&mut self.prefetch_into, PrefetchInto::MbTiles, "MBTiles file");
            });
            if self.prefetch_into == PrefetchInto::MbTiles {
                let base = crate::file_dialog::documents_dir();
                path_field(
                    ui,
                    &mut self.prefetch_mbtiles_path,
                    &mut self.browse_prefetch,
                    MBTILES_WRITE,
                    &base,
                    "/path/area.mbtiles",
                );
            }
        });
        let bbox = BBox::around(waypoints.iter().map(|w| (w.lat_deg, w.lon_deg)), self.margin_m);
        let Some(bbox) = bbox else {
            ui.label("Add waypoints first: the area is the route's box plus the margin.");
            return;
        };
        let (z0, z1) = (self.z0.min(self.z1), self.z0.max(self.z1));
        let est = prefetch::estimate(&bbox, z0, z1);
        ui.label(format!(
            "{} tiles at zooms {z0}–{z1}, about {} (estimated at {} kB a tile); tiles already on disk are skipped.",
            est.tiles,
            mb(est.bytes),
            prefetch::EST_TILE_BYTES / 1000
        ));
        self.prefetch_progress(ui, cfg);
        ui.horizontal(|ui| {
            if running {
                if ui.button("Cancel").clicked()
                    && let Some(p) = &self.prefetch
                {
                    p.cancel();
                }
            } else if ui
                .add_enabled(est.tiles <= prefetch::MAX_PREFETCH_TILES, egui::Button::new("Download"))
                .clicked()
            {
                self.start_prefetch(ui.ctx(), cfg, bbox, (z0, z1));
            }
            if est.tiles > prefetch::MAX_PREFETCH_TILES {
                ui.colored_label(
                    ui.visuals().warn_fg_color,
                    format!(
                        "over the limit of {} tiles: lower the highest zoom",
                        prefetch::MAX_PREFETCH_TILES
                    ),
                );
            }
        });
    }

    /// The running or last prefetch: progress, counts, the last error, and its file offered as the source.
    fn prefetch_progress(&self, ui: &mut egui::Ui, cfg: &mut Config) {
        if let Some(p) = &self.prefetch {
            let s = p.snapshot();
            let frac = if s.total == 0 { 1.0 } else { s.done() as f32 / s.total as f32 };
            ui.add(egui::ProgressBar::new(frac).show_percentage().text(format!(
                "{}/{} tiles",
                s.done(),
                s.total
            )));
            ui.label(format!(
                "{} downloaded ({}), {} already on disk, {} absent on the server, {} failed{}",
                s.fetched,
                mb(s.bytes),
                s.skipped,
                s.missing,
                s.failed,
                if s.finished { if p.cancelled() { " — cancelled" } else { " — done" } } else { "" }
            ));
            if let Some(e) = &s.last_error {
                ui.colored_label(ui.visuals().warn_fg_color, format!("last error: {e}"));
            }
            if s.finished
                && let Some(file) = &self.prefetch_file
                && cfg.tiles != TileSourceConfig::MbTiles(file.clone())
                && ui.button("Use this MBTiles file as the source").clicked()
            {
                cfg.tiles = TileSourceConfig::MbTiles(file.clone());
            }
        }
    }

    /// Starts the prefetch the window's fields describe (the Download button).
    fn start_prefetch(&mut self, ctx: &egui::Context, cfg: &Config, bbox: BBox, (z0, z1): (u8, u8)) {
        let target = if self.prefetch_into == PrefetchInto::MbTiles {
            crate::file_dialog::resolve(&self.prefetch_mbtiles_path, &crate::file_dialog::documents_dir())
                .map(PrefetchTarget::MbTiles)
        } else {
            Some(PrefetchTarget::Cache(cache_root(cfg)))
        };
        if let Some(target) = target {
            let file = match &target {
                PrefetchTarget::MbTiles(p) => Some(p.clone()),
                PrefetchTarget::Cache(_) => None,
            };
            let req = PrefetchRequest {
                source: cfg.tiles.clone(),
                bbox,
                z0,
                z1,
                parallelism: cfg.prefetch_parallelism,
                target,
            };
            let repaint = ctx.clone();
            match Prefetch::start(&req, Some(std::sync::Arc::new(move || repaint.request_repaint()))) {
                Ok(p) => {
                    self.prefetch = Some(p);
                    self.prefetch_file = file;
                    self.message = None;
                }
                Err(e) => self.message = Some(e),
            }
        } else {
            self.message = Some("enter the MBTiles file to write".into());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::local::FrameCounts;
    use super::*;

    /// "has none here" only when the source said so; a network failure is shown with its cause.
    #[test]
    fn the_note_says_the_true_cause() {
        let missing = FrameCounts { missing: 6, ..FrameCounts::default() };
        assert_eq!(
            no_tiles_note(None, None, missing, "OpenStreetMap"),
            "no tiles: metric grid (OpenStreetMap has none here)"
        );
        let offline = vestnav_tiles::TileError::Network {
            what: "tile 15/1/2 of https://tile.openstreetmap.org/15/1/2.png".into(),
            cause: vestnav_tiles::NetworkCause::Offline { host: "tile.openstreetmap.org".into() },
        };
        let failed = FrameCounts { failed: 6, ..FrameCounts::default() };
        let note = no_tiles_note(None, Some(offline.to_string()), failed, "OpenStreetMap");
        assert!(note.contains("offline: tile.openstreetmap.org cannot be resolved"), "{note}");
        assert!(!note.contains("has none here"), "{note}");
        let loading = FrameCounts { loading: 6, ..FrameCounts::default() };
        assert_eq!(
            no_tiles_note(None, None, loading, "OpenStreetMap"),
            "no tiles yet: metric grid (loading…)"
        );
        let broken = no_tiles_note(Some(Err("x.mbtiles: vector".into())), None, missing, "x");
        assert_eq!(broken, "no tiles: metric grid (x.mbtiles: vector)");
    }
}
