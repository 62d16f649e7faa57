//! "Make this area available offline": downloads every tile of a box over a zoom range from an XYZ
//! source whose terms allow bulk download, into the on-disk cache the map reads or into an MBTiles file
//! ([`super::mbtiles`]). The console's Tiles window and `vestnav tiles prefetch` both start it here.
//!
//! A coordinator thread (`tiles-prefetch`) prepares the list and starts the download workers
//! (`tiles-prefetch-N`, the configured parallelism, default 2), which take tiles from one shared list. A
//! tile already stored is skipped, so a cancelled or killed run resumes where it stopped. Into the cache
//! each tile is written atomically (temporary file, rename); into an MBTiles file the coordinator writes
//! the tiles the workers hand it in batches, one SQLite transaction each, and a worker takes its next tile
//! only once its last one is committed: at any instant at most `parallelism` tiles are downloaded but not
//! stored, which is all a kill can lose. Never runs on the UI thread.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;

use super::mbtiles::{MbTilesMeta, MbTilesWriter};
use super::{BBox, TileError, TileKey, TileSourceConfig, Waker, cache, store};

/// Most tiles one prefetch may download (z18 over a few km² is already ~10 000).
pub const MAX_PREFETCH_TILES: u64 = 50_000;
/// Size assumed per tile for the estimate before a prefetch [bytes] (typical raster street-map tiles are
/// 10–40 kB).
pub const EST_TILE_BYTES: u64 = 25_000;
/// Default parallel downloads.
pub const DEFAULT_PARALLELISM: usize = 2;
/// Most parallel downloads the setting allows.
pub const MAX_PARALLELISM: usize = 8;
/// Most tiles written in one MBTiles transaction.
pub const MAX_BATCH: usize = 64;

/// Where the tiles go.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PrefetchTarget {
    /// The on-disk tile cache under this root (the console's `tile_cache_dir`), in the source's folder.
    Cache(PathBuf),
    /// An MBTiles file, created or resumed; it opens as a tile source (`mbtiles:FILE`).
    MbTiles(PathBuf),
}

impl PrefetchTarget {
    /// `FILE.mbtiles` is an MBTiles file, anything else a cache root folder.
    pub fn from_path(path: PathBuf) -> Self {
        if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("mbtiles")) {
            Self::MbTiles(path)
        } else {
            Self::Cache(path)
        }
    }
}

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
    /// Where the tiles go.
    pub target: PrefetchTarget,
}

impl PrefetchRequest {
    /// Checks the request before anything is downloaded: the source's bulk policy
    /// ([`TileSourceConfig::bulk_download_allowed`]), the zoom range and the tile limit. Returns the
    /// tiles to fetch and the URL template.
    pub fn check(&self) -> Result<(Vec<TileKey>, String), String> {
        self.source.bulk_download_allowed()?;
        let url = self.source.url_template().ok_or("not an HTTP source")?.to_owned();
        if self.z0 > self.z1 || self.z1 > super::MAX_ZOOM {
            return Err(format!("zoom range {}..{} is not valid (0..{})", self.z0, self.z1, super::MAX_ZOOM));
        }
        let tiles = self.bbox.tiles(self.z0, self.z1, MAX_PREFETCH_TILES).ok_or_else(|| {
            format!(
                "{} tiles is over the limit of {MAX_PREFETCH_TILES}: lower the highest zoom or the margin",
                self.bbox.tile_count(self.z0, self.z1)
            )
        })?;
        Ok((tiles, url))
    }
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
    /// 1 while the prefetch runs (its coordinator thread), 0 once it has ended.
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
    coordinator: Option<JoinHandle<()>>,
}

/// A downloaded tile handed to the MBTiles writer, with where to say it is committed.
type ToWrite = (TileKey, Vec<u8>, mpsc::SyncSender<Result<(), String>>);

/// What the workers share.
struct Job {
    progress: Arc<Progress>,
    cancel: Arc<AtomicBool>,
    tiles: Vec<TileKey>,
    next: AtomicUsize,
    url: String,
    client: store::TileClient,
    waker: Option<Waker>,
}

impl Job {
    fn error(&self, e: String) {
        *self.progress.last_error.lock().unwrap_or_else(PoisonError::into_inner) = Some(e);
    }

    fn wake(&self) {
        if let Some(w) = &self.waker {
            w();
        }
    }

    /// One worker: downloads tiles until the list is done or cancelled; `store` writes one tile.
    fn work(
        &self,
        cache_dir: Option<&std::path::Path>,
        store: &dyn Fn(TileKey, Vec<u8>) -> Result<(), String>,
    ) {
        let p = &self.progress;
        while !self.cancel.load(Ordering::SeqCst) {
            let Some(&key) = self.tiles.get(self.next.fetch_add(1, Ordering::SeqCst)) else { break };
            let url = key.url(&self.url);
            let what = super::tile_what(key, &super::redact_url(&url));
            if let Some(dir) = cache_dir
                && store::read_capped(&cache::tile_path(dir, key), &what).is_ok_and(|b| b.is_some())
            {
                p.skipped.fetch_add(1, Ordering::SeqCst);
                continue;
            }
            match self.client.download(&url, &what) {
                Ok(Some(b)) => {
                    let n = b.len() as u64;
                    match store(key, b) {
                        Ok(()) => {
                            p.bytes.fetch_add(n, Ordering::SeqCst);
                            p.fetched.fetch_add(1, Ordering::SeqCst);
                        }
                        Err(e) => {
                            p.failed.fetch_add(1, Ordering::SeqCst);
                            self.error(e);
                        }
                    }
                }
                Ok(None) => {
                    p.missing.fetch_add(1, Ordering::SeqCst);
                }
                Err(e) => {
                    p.failed.fetch_add(1, Ordering::SeqCst);
                    // A server sending us elsewhere does so for every tile: stop at the first instead
                    // of asking it for each of them.
                    if matches!(e, TileError::Redirected { .. }) {
                        self.cancel.store(true, Ordering::SeqCst);
                    }
                    self.error(e.to_string());
                }
            }
            self.wake();
        }
    }
}

impl Prefetch {
    /// Checks the request ([`PrefetchRequest::check`]) and starts the coordinator thread, which opens the
    /// target and starts the workers. `waker` is called as tiles arrive (the console's repaint request).
    /// Downloads follow no redirect to another host ([`store::TileClient`]): the first such redirect
    /// stops the prefetch, and its error says where the server pointed.
    pub fn start(req: &PrefetchRequest, waker: Option<Waker>) -> Result<Self, String> {
        let (tiles, url) = req.check()?;
        let client = store::TileClient::new("prefetch").map_err(|e| e.to_string())?;
        let progress = Arc::new(Progress::default());
        progress.total.store(tiles.len() as u64, Ordering::SeqCst);
        progress.running.store(1, Ordering::SeqCst);
        let cancel = Arc::new(AtomicBool::new(false));
        let job = Job {
            progress: progress.clone(),
            cancel: cancel.clone(),
            tiles,
            next: AtomicUsize::new(0),
            url,
            client,
            waker,
        };
        let req = req.clone();
        let coordinator = std::thread::Builder::new()
            .name("tiles-prefetch".into())
            .spawn(move || {
                let job = Arc::new(job);
                run(&req, &job);
                job.progress.running.store(0, Ordering::SeqCst);
                job.wake();
            })
            .map_err(|e| format!("cannot start the prefetch thread: {e}"))?;
        Ok(Self { progress, cancel, coordinator: Some(coordinator) })
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
        if let Some(t) = self.coordinator.take() {
            let _ = t.join();
        }
        self.snapshot()
    }
}

/// The coordinator: prepares the target, runs the workers, and (MBTiles) writes what they fetch.
fn run(req: &PrefetchRequest, job: &Arc<Job>) {
    let workers = req.parallelism.clamp(1, MAX_PARALLELISM);
    match &req.target {
        PrefetchTarget::Cache(root) => {
            let dir = cache::source_dir(root, &req.source);
            let threads = spawn_workers(job, workers, move |job| {
                job.work(Some(&dir), &|key, b| {
                    let path = cache::tile_path(&dir, key);
                    cache::store(&path, &b).map_err(|e| format!("cannot write {}: {e}", path.display()))
                });
            });
            for t in threads {
                let _ = t.join();
            }
        }
        PrefetchTarget::MbTiles(path) => {
            let meta = MbTilesMeta {
                name: req.source.label(),
                bbox: req.bbox,
                min_zoom: req.z0,
                max_zoom: req.z1,
                attribution: req.source.attribution(),
            };
            let opened = MbTilesWriter::open(path, &meta).and_then(|w| {
                let present = w.present(&job.tiles)?;
                Ok((w, present))
            });
            let (mut writer, present) = match opened {
                Ok(o) => o,
                Err(e) => return job.error(e.to_string()),
            };
            // Tiles already in the file are skipped before any worker starts (indices past them).
            let job = if present.is_empty() {
                job.clone()
            } else {
                job.progress.skipped.store(present.len() as u64, Ordering::SeqCst);
                let tiles = job.tiles.iter().copied().filter(|k| !present.contains(k)).collect();
                Arc::new(Job {
                    progress: job.progress.clone(),
                    cancel: job.cancel.clone(),
                    tiles,
                    next: AtomicUsize::new(0),
                    url: job.url.clone(),
                    client: job.client.clone(),
                    waker: job.waker.clone(),
                })
            };
            let (tx, rx) = mpsc::channel::<ToWrite>();
            let threads = spawn_workers(&job, workers, move |job| {
                let tx = tx.clone();
                job.work(None, &|key, b| {
                    let (ack_tx, ack_rx) = mpsc::sync_channel(1);
                    tx.send((key, b, ack_tx)).map_err(|_| "the MBTiles writer has stopped".to_owned())?;
                    ack_rx.recv().map_err(|_| "the MBTiles writer has stopped".to_owned())?
                });
            });
            // Ends when every worker has ended (their senders dropped).
            while let Ok(first) = rx.recv() {
                let mut batch = vec![first];
                while batch.len() < MAX_BATCH
                    && let Ok(more) = rx.try_recv()
                {
                    batch.push(more);
                }
                let (tiles, acks): (Vec<_>, Vec<_>) = batch.into_iter().map(|(k, b, a)| ((k, b), a)).unzip();
                let res = writer.write_batch(&tiles).map_err(|e| e.to_string());
                for a in acks {
                    let _ = a.send(res.clone());
                }
            }
            for t in threads {
                let _ = t.join();
            }
        }
    }
}

/// Starts `n` workers running `f`; a thread that cannot start is reported, the others carry on.
fn spawn_workers<F>(job: &Arc<Job>, n: usize, f: F) -> Vec<JoinHandle<()>>
where
    F: Fn(&Job) + Send + Clone + 'static,
{
    let mut threads = Vec::new();
    for i in 0..n {
        let (job2, f) = (job.clone(), f.clone());
        match std::thread::Builder::new().name(format!("tiles-prefetch-{i}")).spawn(move || f(&job2)) {
            Ok(h) => threads.push(h),
            Err(e) => job.error(format!("cannot start a prefetch thread: {e}")),
        }
    }
    threads
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
            target: PrefetchTarget::Cache(std::env::temp_dir()),
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
