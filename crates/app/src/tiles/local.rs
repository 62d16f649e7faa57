//! [`SourceTiles`]: the one `walkers::Tiles` implementation behind every tile source. The loader threads
//! of `vestnav_tiles::loader` own the store (a file or the HTTP cache), read and decode tiles off the UI
//! thread and hand the decoded images back (or why a tile is absent, refused or failed); the UI thread turns them into textures, keeps a bounded number of them, magnifies the
//! store's deepest zoom beyond it, and shows a coarser tile while a finer one loads.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use egui::{ColorImage, Rect, TextureHandle, pos2};
use vestnav_tiles::loader::{Loaded, TileLoader};
use vestnav_tiles::store::{Origin, StoreInfo};
use vestnav_tiles::{MAX_ZOOM, TileImage, TileKey, TileSourceConfig};
use walkers::sources::Attribution;
use walkers::{Tile, TileId, TilePiece, Tiles};

/// Textures kept at most (256 px tiles: 256 kB each, so 64 MB).
pub const MAX_TEXTURES: usize = 256;
/// A failed or refused tile is tried again after this long.
pub const RETRY_FAILED_AFTER: Duration = Duration::from_secs(30);
/// Coarser zooms searched for a stand-in while a tile loads.
const FALLBACK_LEVELS: u8 = 6;

/// How many tiles of the last frame were in each state, for the indicator.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FrameCounts {
    /// Drawn from a local file.
    pub local: u32,
    /// Drawn from the disk cache (fresh).
    pub cached: u32,
    /// Drawn from the disk cache, stale (the server did not answer).
    pub stale: u32,
    /// Drawn from a download this session.
    pub downloaded: u32,
    /// Not held by the source.
    pub missing: u32,
    /// Held by the source but refused (not a regular file, too large, declaring too many pixels, not
    /// an image, redirected elsewhere): the loader's last error says why.
    pub refused: u32,
    /// Could not be read or fetched.
    pub failed: u32,
    /// Still loading.
    pub loading: u32,
}

impl FrameCounts {
    /// Tiles drawn (exact or magnified).
    pub fn shown(&self) -> u32 {
        self.local + self.cached + self.stale + self.downloaded
    }
}

enum Slot {
    Ready { tex: TextureHandle, origin: Origin, used: u64 },
    Missing { used: u64 },
    Failed { at: Instant, used: u64, refused: bool },
}

impl Slot {
    fn used(&self) -> u64 {
        match self {
            Self::Ready { used, .. } | Self::Missing { used } | Self::Failed { used, .. } => *used,
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Tiles of one source, loaded off the UI thread by a [`TileLoader`].
pub struct SourceTiles {
    /// The configured raster source (`None` for the OpenStreetMap extract drawn on demand).
    source: Option<TileSourceConfig>,
    label: String,
    loader: TileLoader,
    slots: HashMap<TileKey, Slot>,
    ctx: egui::Context,
    frame: u64,
    counts: FrameCounts,
    last_counts: FrameCounts,
    attribution: &'static str,
}

/// The egui image of a decoded tile.
fn color_image(img: &TileImage) -> ColorImage {
    ColorImage::from_rgba_unmultiplied([img.width as usize, img.height as usize], &img.rgba)
}

/// Attribution strings handed to walkers, which wants `&'static str`: each distinct text is leaked once.
fn intern(text: &str) -> &'static str {
    static TEXTS: Mutex<Vec<&'static str>> = Mutex::new(Vec::new());
    let mut texts = lock(&TEXTS);
    if let Some(t) = texts.iter().find(|t| **t == text) {
        return t;
    }
    let t: &'static str = Box::leak(text.to_owned().into_boxed_str());
    texts.push(t);
    t
}

impl SourceTiles {
    /// Starts the loader threads of `source` (two for HTTP sources, the OpenStreetMap policy's limit of
    /// parallel connections; one for local files); `cache_dir` holds downloaded tiles.
    pub fn new(source: TileSourceConfig, cache_dir: &std::path::Path, ctx: egui::Context) -> Self {
        let repaint = ctx.clone();
        let waker: vestnav_tiles::Waker = Arc::new(move || repaint.request_repaint());
        let loader = TileLoader::start(&source, cache_dir, &waker);
        Self::with_loader(source.label(), Some(source), loader, ctx)
    }

    /// The tiles a started `loader` hands over; `label` names them in the indicator, `source` is the
    /// configured source they come from (`None` for a store made by the console, the OSM extract).
    pub fn with_loader(
        label: String,
        source: Option<TileSourceConfig>,
        loader: TileLoader,
        ctx: egui::Context,
    ) -> Self {
        let attribution = intern(&source.as_ref().map(TileSourceConfig::attribution).unwrap_or_default());
        Self {
            source,
            label,
            loader,
            slots: HashMap::new(),
            ctx,
            frame: 0,
            counts: FrameCounts::default(),
            last_counts: FrameCounts::default(),
            attribution,
        }
    }

    /// The configured source shown (`None` for the OSM extract).
    pub fn source(&self) -> Option<&TileSourceConfig> {
        self.source.as_ref()
    }

    /// The source's name for the indicator.
    pub fn label(&self) -> &str {
        &self.label
    }

    /// Starts a new frame's counts (call before the map draws).
    pub fn begin_frame(&mut self) {
        self.last_counts = self.counts;
        self.counts = FrameCounts::default();
        self.frame += 1;
    }

    /// Counts of the last complete frame.
    pub fn counts(&self) -> FrameCounts {
        if self.counts == FrameCounts::default() { self.last_counts } else { self.counts }
    }

    /// `Some(Err)` when the source could not be opened (the file is missing or not a tile file).
    pub fn open_state(&self) -> Option<Result<StoreInfo, String>> {
        self.loader.open_state()
    }

    /// The latest tile refusal or failure (names the tile and its file or URL).
    pub fn last_error(&self) -> Option<String> {
        self.loader.last_error()
    }

    /// The attribution to show: the source's own, else the file's metadata.
    pub fn attribution_text(&self) -> String {
        if !self.attribution.is_empty() {
            return self.attribution.to_owned();
        }
        match self.open_state() {
            Some(Ok(StoreInfo { attribution: Some(a), .. })) => a,
            _ => String::new(),
        }
    }

    fn drain(&mut self) {
        for (key, loaded) in self.loader.take_done() {
            let used = self.frame;
            let slot = match loaded {
                Loaded::Image(img, origin) => Slot::Ready {
                    tex: self.ctx.load_texture(
                        format!("tile-{}-{}-{}", key.z, key.x, key.y),
                        color_image(&img),
                        egui::TextureOptions::LINEAR,
                    ),
                    origin,
                    used,
                },
                Loaded::Absent => Slot::Missing { used },
                Loaded::Refused(_) => Slot::Failed { at: Instant::now(), used, refused: true },
                Loaded::Failed(_) => Slot::Failed { at: Instant::now(), used, refused: false },
            };
            self.slots.insert(key, slot);
        }
        if self.slots.len() > MAX_TEXTURES {
            let mut by_age: Vec<(u64, TileKey)> = self.slots.iter().map(|(k, s)| (s.used(), *k)).collect();
            by_age.sort_unstable();
            for (_, k) in by_age.into_iter().take(self.slots.len() - MAX_TEXTURES) {
                self.slots.remove(&k);
            }
        }
    }

    fn zoom_range(&self) -> Option<(u8, u8)> {
        match self.open_state() {
            Some(Ok(i)) => Some((i.min_zoom, i.max_zoom)),
            Some(Err(_)) => None,
            None => Some((0, MAX_ZOOM)),
        }
    }

    /// The tile or a part of a coarser one, and how it counts.
    fn lookup(&mut self, want: TileKey) -> Option<TilePiece> {
        let (min_zoom, max_zoom) = self.zoom_range()?;
        let fetch_z = want.z.min(max_zoom);
        if fetch_z < min_zoom {
            self.counts.missing += 1;
            return None;
        }
        let (fetch, _) = want.ancestor(fetch_z);
        let frame = self.frame;
        let mut need_request = false;
        match self.slots.get_mut(&fetch) {
            None => need_request = true,
            Some(Slot::Failed { at, .. }) if at.elapsed() > RETRY_FAILED_AFTER => {
                self.slots.remove(&fetch);
                need_request = true;
            }
            Some(Slot::Missing { used }) => {
                *used = frame;
                self.counts.missing += 1;
                return None;
            }
            Some(Slot::Failed { used, refused, .. }) => {
                *used = frame;
                if *refused {
                    self.counts.refused += 1;
                } else {
                    self.counts.failed += 1;
                }
                return None;
            }
            Some(Slot::Ready { .. }) => {}
        }
        if need_request {
            self.loader.request(fetch);
        }
        let lowest = fetch_z.saturating_sub(FALLBACK_LEVELS).max(min_zoom);
        for z in (lowest..=fetch_z).rev() {
            let (k, uv) = want.ancestor(z);
            if let Some(Slot::Ready { tex, origin, used }) = self.slots.get_mut(&k) {
                *used = frame;
                if z == fetch_z {
                    let c = &mut self.counts;
                    match origin {
                        Origin::Local => c.local += 1,
                        Origin::Cache => c.cached += 1,
                        Origin::Stale => c.stale += 1,
                        Origin::Downloaded => c.downloaded += 1,
                    }
                } else {
                    self.counts.loading += 1;
                }
                let uv = Rect::from_min_max(pos2(uv[0], uv[1]), pos2(uv[2], uv[3]));
                return Some(TilePiece::new(Tile::Raster(tex.clone()), uv));
            }
        }
        self.counts.loading += 1;
        None
    }
}

impl Tiles for SourceTiles {
    fn at(&mut self, tile_id: TileId) -> Option<TilePiece> {
        self.drain();
        let key = TileKey::new(tile_id.zoom, tile_id.x, tile_id.y)?;
        self.lookup(key)
    }

    fn attribution(&self) -> Attribution {
        Attribution { text: self.attribution, url: "", logo_light: None, logo_dark: None }
    }

    fn tile_size(&self) -> u32 {
        256
    }
}
