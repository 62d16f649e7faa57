//! [`SourceTiles`]: the one `walkers::Tiles` implementation behind every tile source. Loader threads own
//! the store (a file or the HTTP cache), read and decode tiles off the UI thread and hand the decoded
//! images back; the UI thread turns them into textures, keeps a bounded number of them, magnifies the
//! store's deepest zoom beyond it, and shows a coarser tile while a finer one loads.

use std::collections::{HashMap, HashSet, VecDeque};

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::time::{Duration, Instant};

use egui::{ColorImage, Rect, TextureHandle, pos2};
use walkers::sources::Attribution;
use walkers::{Tile, TileId, TilePiece, Tiles};

use super::store::{Origin, StoreInfo, TileStore};
use super::{TileKey, TileSourceConfig, decode_tile};

/// Textures kept at most (256 px tiles: 256 kB each, so 64 MB).
pub const MAX_TEXTURES: usize = 256;
/// Requests waiting at most; older ones are dropped (the map has moved on).
pub const MAX_QUEUE: usize = 256;
/// A failed tile is tried again after this long.
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
    /// Not held by the source, or failed.
    pub missing: u32,
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
    Failed { at: Instant, used: u64 },
}

impl Slot {
    fn used(&self) -> u64 {
        match self {
            Self::Ready { used, .. } | Self::Missing { used } | Self::Failed { used, .. } => *used,
        }
    }
}

type Outcome = Result<Option<(ColorImage, Origin)>, String>;

#[derive(Default)]
struct Queue {
    waiting: VecDeque<TileKey>,
    pending: HashSet<TileKey>,
}

struct Shared {
    queue: Mutex<Queue>,
    wake: Condvar,
    done: Mutex<Vec<(TileKey, Outcome)>>,
    stop: AtomicBool,
    /// The store's description once open, or why it could not be opened.
    opened: Mutex<Option<Result<StoreInfo, String>>>,
    /// The latest tile error, for the indicator.
    last_error: Mutex<Option<String>>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Tiles of one source, loaded off the UI thread.
pub struct SourceTiles {
    source: TileSourceConfig,
    shared: Arc<Shared>,
    slots: HashMap<TileKey, Slot>,
    ctx: egui::Context,
    frame: u64,
    counts: FrameCounts,
    last_counts: FrameCounts,
    attribution: &'static str,
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
        let shared = Arc::new(Shared {
            queue: Mutex::default(),
            wake: Condvar::new(),
            done: Mutex::default(),
            stop: AtomicBool::new(false),
            opened: Mutex::new(None),
            last_error: Mutex::new(None),
        });
        let threads = if source.url_template().is_some() { 2 } else { 1 };
        for i in 0..threads {
            let (sh, source, cache_dir, ctx) =
                (shared.clone(), source.clone(), cache_dir.to_path_buf(), ctx.clone());
            let spawned = std::thread::Builder::new()
                .name(format!("tiles-{i}"))
                .spawn(move || loader(&sh, &source, &cache_dir, &ctx));
            if let Err(e) = spawned {
                *lock(&shared.opened) = Some(Err(format!("cannot start the tile loader thread: {e}")));
            }
        }
        let attribution = intern(&source.attribution());
        Self {
            source,
            shared,
            slots: HashMap::new(),
            ctx,
            frame: 0,
            counts: FrameCounts::default(),
            last_counts: FrameCounts::default(),
            attribution,
        }
    }

    /// The source shown.
    pub fn source(&self) -> &TileSourceConfig {
        &self.source
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
        lock(&self.shared.opened).clone()
    }

    /// The latest tile error (names the file or URL).
    pub fn last_error(&self) -> Option<String> {
        lock(&self.shared.last_error).clone()
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
        let done = std::mem::take(&mut *lock(&self.shared.done));
        for (key, outcome) in done {
            let slot = match outcome {
                Ok(Some((img, origin))) => Slot::Ready {
                    tex: self.ctx.load_texture(
                        format!("tile-{}-{}-{}", key.z, key.x, key.y),
                        img,
                        egui::TextureOptions::LINEAR,
                    ),
                    origin,
                    used: self.frame,
                },
                Ok(None) => Slot::Missing { used: self.frame },
                Err(e) => {
                    *lock(&self.shared.last_error) = Some(e);
                    Slot::Failed { at: Instant::now(), used: self.frame }
                }
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

    fn request(&self, key: TileKey) {
        let mut q = lock(&self.shared.queue);
        if q.pending.insert(key) {
            q.waiting.push_back(key);
            while q.waiting.len() > MAX_QUEUE {
                if let Some(old) = q.waiting.pop_front() {
                    q.pending.remove(&old);
                }
            }
            self.shared.wake.notify_one();
        }
    }

    fn zoom_range(&self) -> Option<(u8, u8)> {
        match self.open_state() {
            Some(Ok(i)) => Some((i.min_zoom, i.max_zoom)),
            Some(Err(_)) => None,
            None => Some((0, super::MAX_ZOOM)),
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
            Some(Slot::Missing { used } | Slot::Failed { used, .. }) => {
                *used = frame;
                self.counts.missing += 1;
                return None;
            }
            Some(Slot::Ready { .. }) => {}
        }
        if need_request {
            self.request(fetch);
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

impl Drop for SourceTiles {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        self.shared.wake.notify_all();
    }
}

/// One loader thread: opens its own store, then serves the newest request first until stopped.
fn loader(shared: &Shared, source: &TileSourceConfig, cache_dir: &std::path::Path, ctx: &egui::Context) {
    let mut store: Box<dyn TileStore> = match super::store::open(source, cache_dir) {
        Ok(s) => {
            lock(&shared.opened).get_or_insert(Ok(s.info()));
            s
        }
        Err(e) => {
            *lock(&shared.opened) = Some(Err(e.to_string()));
            ctx.request_repaint();
            return;
        }
    };
    ctx.request_repaint();
    loop {
        let key = {
            let mut q = lock(&shared.queue);
            loop {
                if shared.stop.load(Ordering::SeqCst) {
                    return;
                }
                if let Some(k) = q.waiting.pop_back() {
                    break k;
                }
                q = shared
                    .wake
                    .wait_timeout(q, Duration::from_millis(500))
                    .unwrap_or_else(PoisonError::into_inner)
                    .0;
            }
        };
        let what = format!("tile {}/{}/{}", key.z, key.x, key.y);
        let outcome: Outcome = match store.get(key) {
            Ok(Some((bytes, origin))) => {
                decode_tile(&bytes, &what).map(|img| Some((img, origin))).map_err(|e| e.to_string())
            }
            Ok(None) => Ok(None),
            Err(e) => Err(e.to_string()),
        };
        lock(&shared.done).push((key, outcome));
        lock(&shared.queue).pending.remove(&key);
        ctx.request_repaint();
    }
}
