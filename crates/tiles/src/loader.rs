//! [`TileLoader`]: the threads that read and decode a source's tiles off the UI thread. The UI asks for
//! tiles ([`TileLoader::request`]), the loader threads (`tiles-N`: one for a file, two for a server, the
//! OpenStreetMap policy's limit of parallel connections) each own a store, serve the newest request
//! first, and hand back one [`Loaded`] per tile ([`TileLoader::take_done`]), calling the waker. Old
//! requests are dropped when more than [`MAX_QUEUE`] wait: the map has moved on.
//!
//! Nothing a store does can block the UI: the UI only takes a mutex held for a push or a swap. Every
//! file a store opens is opened only if it is a regular file, so a FIFO in a tile folder is refused
//! (and said so), never waited on.

use std::collections::{HashSet, VecDeque};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::time::Duration;

use super::store::{self, Origin, StoreInfo, TileStore};
use super::{TileError, TileImage, TileKey, TileSourceConfig, Waker, decode_tile};

/// How a loader thread opens its store (called once on each loader thread).
pub type OpenStore = Arc<dyn Fn() -> Result<Box<dyn TileStore>, TileError> + Send + Sync>;

/// Requests waiting at most; older ones are dropped (the map has moved on).
pub const MAX_QUEUE: usize = 256;

/// What became of one requested tile.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Loaded {
    /// Decoded, and where its bytes came from.
    Image(TileImage, Origin),
    /// The source has no such tile.
    Absent,
    /// The tile is there but was refused: the reason (not a regular file, over a size limit, an image
    /// declaring too many pixels, not an image, undecodable, a redirect to another host), naming the
    /// tile and its file or URL.
    Refused(String),
    /// The tile could not be read or fetched (a read error, the server unreachable or failing).
    Failed(String),
}

/// Reads and decodes one tile from `store`.
pub fn load(store: &mut dyn TileStore, key: TileKey) -> Loaded {
    let outcome = store.get(key).and_then(|found| match found {
        Some(t) => decode_tile(&t.bytes, &t.what).map(|img| Some((img, t.origin))),
        None => Ok(None),
    });
    match outcome {
        Ok(Some((img, origin))) => Loaded::Image(img, origin),
        Ok(None) => Loaded::Absent,
        Err(e) if e.is_refusal() => Loaded::Refused(e.to_string()),
        Err(e) => Loaded::Failed(e.to_string()),
    }
}

#[derive(Default)]
struct Queue {
    waiting: VecDeque<TileKey>,
    pending: HashSet<TileKey>,
}

struct Shared {
    queue: Mutex<Queue>,
    wake: Condvar,
    done: Mutex<Vec<(TileKey, Loaded)>>,
    stop: AtomicBool,
    /// The store's description once open, or why it could not be opened.
    opened: Mutex<Option<Result<StoreInfo, String>>>,
    /// The latest refusal or failure, for the indicator.
    last_error: Mutex<Option<String>>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The loader threads of one source. Dropping it stops them (each ends after the tile it is on).
pub struct TileLoader {
    shared: Arc<Shared>,
}

impl TileLoader {
    /// Starts the loader threads of `source`; `cache_dir` holds downloaded tiles; `waker` is called
    /// whenever a tile is done or the store has opened (or failed to).
    pub fn start(source: &TileSourceConfig, cache_dir: &Path, waker: &Waker) -> Self {
        let threads = if source.url_template().is_some() { 2 } else { 1 };
        let (source, cache_dir) = (source.clone(), cache_dir.to_path_buf());
        Self::start_with(threads, &(Arc::new(move || store::open(&source, &cache_dir)) as OpenStore), waker)
    }

    /// Starts `threads` loader threads, each serving requests from the store `open` gives it (called
    /// once per thread, on that thread): the one path for every kind of store, including ones made
    /// outside this crate (the console's OpenStreetMap extract, drawn on demand).
    pub fn start_with(threads: usize, open: &OpenStore, waker: &Waker) -> Self {
        let shared = Arc::new(Shared {
            queue: Mutex::default(),
            wake: Condvar::new(),
            done: Mutex::default(),
            stop: AtomicBool::new(false),
            opened: Mutex::new(None),
            last_error: Mutex::new(None),
        });
        for i in 0..threads.max(1) {
            let (sh, open, waker) = (shared.clone(), open.clone(), waker.clone());
            let spawned = std::thread::Builder::new()
                .name(format!("tiles-{i}"))
                .spawn(move || run(&sh, &*open, &waker));
            if let Err(e) = spawned {
                *lock(&shared.opened) = Some(Err(format!("cannot start the tile loader thread: {e}")));
            }
        }
        Self { shared }
    }

    /// Asks for `key` (once: a tile already waiting or loading is not asked again).
    pub fn request(&self, key: TileKey) {
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

    /// The tiles done since the last call.
    pub fn take_done(&self) -> Vec<(TileKey, Loaded)> {
        std::mem::take(&mut *lock(&self.shared.done))
    }

    /// `None` while the store opens, then what it holds or why it could not be opened.
    pub fn open_state(&self) -> Option<Result<StoreInfo, String>> {
        lock(&self.shared.opened).clone()
    }

    /// The latest refusal or failure (names the tile and its file or URL).
    pub fn last_error(&self) -> Option<String> {
        lock(&self.shared.last_error).clone()
    }
}

impl Drop for TileLoader {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        self.shared.wake.notify_all();
    }
}

/// One loader thread: opens its own store, then serves the newest request first until stopped.
fn run(
    shared: &Shared,
    open: &(dyn Fn() -> Result<Box<dyn TileStore>, TileError> + Send + Sync),
    waker: &Waker,
) {
    let mut store: Box<dyn TileStore> = match open() {
        Ok(s) => {
            lock(&shared.opened).get_or_insert(Ok(s.info()));
            s
        }
        Err(e) => {
            *lock(&shared.opened) = Some(Err(e.to_string()));
            waker();
            return;
        }
    };
    waker();
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
        let loaded = load(store.as_mut(), key);
        if let Loaded::Refused(e) | Loaded::Failed(e) = &loaded {
            *lock(&shared.last_error) = Some(e.clone());
        }
        lock(&shared.done).push((key, loaded));
        lock(&shared.queue).pending.remove(&key);
        waker();
    }
}
