//! "Make this area available offline": downloads every tile of a box over a zoom range from an XYZ
//! source whose terms allow bulk download, into the on-disk cache the map reads. Worker threads (the
//! configured parallelism, default 2) take tiles from one shared list; a tile already on disk is skipped,
//! so a cancelled or killed run resumes where it stopped. Never runs on the UI thread.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;

use super::{BBox, TileSourceConfig, cache, store};

/// Most tiles one prefetch may download (z18 over a few km² is already ~10 000).
pub const MAX_PREFETCH_TILES: u64 = 50_000;
/// Size assumed per tile for the estimate before a prefetch [bytes] (typical raster street-map tiles are
/// 10–40 kB).
pub const EST_TILE_BYTES: u64 = 25_000;
/// Default parallel downloads.
pub const DEFAULT_PARALLELISM: usize = 2;
/// Most parallel downloads the setting allows.
pub const MAX_PARALLELISM: usize = 8;

/// What the operator asked to download.
#[derive(Debug, Clone, PartialEq)]
pub struct PrefetchRequest {
    /// The source (must allow bulk download).
    pub source: TileSourceConfig,
    /// The area.
    pub bbox: BBox,
    /// Lowest zoom.
    pub z0: u8,
    /// Highest zoom.
    pub z1: u8,
    /// Parallel downloads (1..=[`MAX_PARALLELISM`]).
    pub parallelism: usize,
    /// Root of the tile cache.
    pub cache_root: PathBuf,
}

/// Tile count and size estimate of a request, shown before it starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Estimate {
    /// Tiles in the box over the zooms.
    pub tiles: u64,
    /// Their size at [`EST_TILE_BYTES`] each [bytes].
    pub bytes: u64,
}

/// The estimate for `bbox` over zooms `z0..=z1`.
pub fn estimate(bbox: &BBox, z0: u8, z1: u8) -> Estimate {
    let tiles = bbox.tile_count(z0, z1);
    Estimate { tiles, bytes: tiles.saturating_mul(EST_TILE_BYTES) }
}

/// Counters of a running prefetch.
#[derive(Debug, Default)]
pub struct Progress {
    /// Tiles to handle.
    pub total: AtomicU64,
    /// Downloaded and stored.
    pub fetched: AtomicU64,
    /// Already on disk, skipped.
    pub skipped: AtomicU64,
    /// The server has no such tile (404).
    pub missing: AtomicU64,
    /// Failed (network, server error, not an image).
    pub failed: AtomicU64,
    /// Bytes downloaded.
    pub bytes: AtomicU64,
    /// Worker threads still running.
    pub running: AtomicUsize,
    /// The latest error (names the redacted URL).
    pub last_error: Mutex<Option<String>>,
}

/// A copy of the counters.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Snapshot {
    /// Tiles to handle.
    pub total: u64,
    /// Downloaded.
    pub fetched: u64,
    /// Skipped (already on disk).
    pub skipped: u64,
    /// Absent on the server.
    pub missing: u64,
    /// Failed.
    pub failed: u64,
    /// Bytes downloaded.
    pub bytes: u64,
    /// All workers have ended.
    pub finished: bool,
    /// The latest error.
    pub last_error: Option<String>,
}

impl Snapshot {
    /// Tiles handled so far.
    pub fn done(&self) -> u64 {
        self.fetched + self.skipped + self.missing + self.failed
    }
}

/// A running (or finished) prefetch.
pub struct Prefetch {
    progress: Arc<Progress>,
    cancel: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl Prefetch {
    /// Checks the request (the source's bulk policy, the tile limit) and starts the workers. `waker` is
    /// asked to repaint as tiles arrive.
    pub fn start(req: &PrefetchRequest, waker: Option<&egui::Context>) -> Result<Self, String> {
        req.source.bulk_download_allowed()?;
        let url = req.source.url_template().ok_or("not an HTTP source")?.to_owned();
        if req.z0 > req.z1 || req.z1 > super::MAX_ZOOM {
            return Err(format!("zoom range {}..{} is not valid (0..{})", req.z0, req.z1, super::MAX_ZOOM));
        }
        let tiles = req.bbox.tiles(req.z0, req.z1, MAX_PREFETCH_TILES).ok_or_else(|| {
            format!(
                "{} tiles is over the limit of {MAX_PREFETCH_TILES}: lower the highest zoom or the margin",
                req.bbox.tile_count(req.z0, req.z1)
            )
        })?;
        let client = store::http_client().map_err(|e| e.to_string())?;
        let dir = cache::source_dir(&req.cache_root, &req.source);
        let progress = Arc::new(Progress::default());
        progress.total.store(tiles.len() as u64, Ordering::SeqCst);
        let cancel = Arc::new(AtomicBool::new(false));
        let tiles = Arc::new(tiles);
        let next = Arc::new(AtomicUsize::new(0));
        let workers = req.parallelism.clamp(1, MAX_PARALLELISM);
        progress.running.store(workers, Ordering::SeqCst);
        let mut threads = Vec::new();
        for i in 0..workers {
            let (p, c, t, n) = (progress.clone(), cancel.clone(), tiles.clone(), next.clone());
            let (client, dir, url, waker) = (client.clone(), dir.clone(), url.clone(), waker.cloned());
            let spawned = std::thread::Builder::new().name(format!("tiles-prefetch-{i}")).spawn(move || {
                while !c.load(Ordering::SeqCst) {
                    let Some(&key) = t.get(n.fetch_add(1, Ordering::SeqCst)) else { break };
                    let path = cache::tile_path(&dir, key);
                    if store::read_capped(&path).is_ok_and(|b| b.is_some()) {
                        p.skipped.fetch_add(1, Ordering::SeqCst);
                        continue;
                    }
                    match store::download(&client, &key.url(&url)) {
                        Ok(Some(b)) => match cache::store(&path, &b) {
                            Ok(()) => {
                                p.bytes.fetch_add(b.len() as u64, Ordering::SeqCst);
                                p.fetched.fetch_add(1, Ordering::SeqCst);
                            }
                            Err(e) => {
                                p.failed.fetch_add(1, Ordering::SeqCst);
                                *p.last_error.lock().unwrap_or_else(PoisonError::into_inner) =
                                    Some(format!("cannot write {}: {e}", path.display()));
                            }
                        },
                        Ok(None) => {
                            p.missing.fetch_add(1, Ordering::SeqCst);
                        }
                        Err(e) => {
                            p.failed.fetch_add(1, Ordering::SeqCst);
                            *p.last_error.lock().unwrap_or_else(PoisonError::into_inner) =
                                Some(e.to_string());
                        }
                    }
                    if let Some(w) = &waker {
                        w.request_repaint();
                    }
                }
                p.running.fetch_sub(1, Ordering::SeqCst);
                if let Some(w) = &waker {
                    w.request_repaint();
                }
            });
            match spawned {
                Ok(h) => threads.push(h),
                Err(e) => {
                    progress.running.fetch_sub(1, Ordering::SeqCst);
                    *progress.last_error.lock().unwrap_or_else(PoisonError::into_inner) =
                        Some(format!("cannot start a prefetch thread: {e}"));
                }
            }
        }
        Ok(Self { progress, cancel, threads })
    }

    /// Asks the workers to stop after the tile each is on (what is on disk stays; a re-run resumes).
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::SeqCst);
    }

    /// Whether cancel was asked.
    pub fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::SeqCst)
    }

    /// The counters now.
    pub fn snapshot(&self) -> Snapshot {
        let p = &self.progress;
        let g = |a: &AtomicU64| a.load(Ordering::SeqCst);
        Snapshot {
            total: g(&p.total),
            fetched: g(&p.fetched),
            skipped: g(&p.skipped),
            missing: g(&p.missing),
            failed: g(&p.failed),
            bytes: g(&p.bytes),
            finished: p.running.load(Ordering::SeqCst) == 0,
            last_error: p.last_error.lock().unwrap_or_else(PoisonError::into_inner).clone(),
        }
    }

    /// Waits for the workers to end and returns the final counters.
    pub fn join(mut self) -> Snapshot {
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        self.snapshot()
    }
}

impl Drop for Prefetch {
    fn drop(&mut self) {
        // Dropping the job (the console closing) stops it; workers end after their current tile.
        self.cancel();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_before_any_download() {
        let bbox = BBox { min_lat: 42.35, min_lon: -71.11, max_lat: 42.36, max_lon: -71.09 };
        let req = PrefetchRequest {
            source: TileSourceConfig::Osm,
            bbox,
            z0: 10,
            z1: 14,
            parallelism: 2,
            cache_root: std::env::temp_dir(),
        };
        assert!(Prefetch::start(&req, None).err().unwrap().contains("forbids bulk download"));
        let xyz = TileSourceConfig::Xyz {
            url: "http://127.0.0.1:9/{z}/{x}/{y}.png".into(),
            attribution: String::new(),
            allows_bulk: true,
        };
        let too_many = PrefetchRequest { source: xyz.clone(), z1: 24, ..req.clone() };
        assert!(Prefetch::start(&too_many, None).err().unwrap().contains("over the limit"));
        let upside_down = PrefetchRequest { source: xyz, z0: 15, z1: 12, ..req };
        assert!(Prefetch::start(&upside_down, None).is_err());
        let e = estimate(&bbox, 10, 14);
        assert_eq!(e.bytes, e.tiles * EST_TILE_BYTES);
        assert!(e.tiles >= 5);
    }
}
