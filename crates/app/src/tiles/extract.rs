//! [`MapExtract`]: an OpenStreetMap extract (`.osm.pbf`, `vestnav --map`) on the console's map. The file is
//! read on a worker thread (`osm-read`, the size limit and checks of `vestnav_osm::Extract::read`), then its
//! map is drawn into tiles on demand by `vestnav_osm::Renderer` on the tile loader threads — the same
//! `TileLoader` and [`SourceTiles`] every raster source uses, through an [`OsmStore`] — and its path
//! network is kept for routing on foot. Nothing here reads or draws on the UI thread.
//!
//! Drawn tiles go to the disk tile cache (the raster sources' cache, pruned with it) in a folder named by
//! the extract's identity and the renderer's version ([`extract_cache_dir`]), and are read back from there
//! before drawing; a cache that cannot be written is said once in the extract's status and never stops
//! the drawing.

use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, TryRecvError};
use std::sync::{Arc, OnceLock};

use vestnav_osm::{
    ATTRIBUTION, Extract, ExtractStats, PathGraph, RENDER_SOURCE_HASH, RENDER_VERSION, Renderer,
};
use vestnav_tiles::cache::{self, DiskCachedStore};
use vestnav_tiles::loader::{OpenStore, TileLoader};
use vestnav_tiles::store::{FoundTile, Origin, StoreInfo, TileStore};
use vestnav_tiles::{TileError, TileKey, tile_what};

use super::SourceTiles;

/// Lowest zoom the extract is drawn at (below it a city's worth of features would make a tile slow).
pub const EXTRACT_MIN_ZOOM: u8 = 14;
/// Highest zoom drawn; the map magnifies zoom 19 beyond it.
pub const EXTRACT_MAX_ZOOM: u8 = 19;
/// Loader threads drawing the extract's tiles (each tile takes milliseconds to tens of them).
const RENDER_THREADS: usize = 2;

/// A tile store that draws tiles of an extract (PNG, checked and decoded like any other tile).
pub struct OsmStore {
    renderer: Arc<Renderer>,
    path: PathBuf,
}

impl TileStore for OsmStore {
    fn info(&self) -> StoreInfo {
        StoreInfo {
            min_zoom: EXTRACT_MIN_ZOOM,
            max_zoom: EXTRACT_MAX_ZOOM,
            attribution: Some(ATTRIBUTION.to_owned()),
        }
    }

    /// The tile drawn now (or from the renderer's cache); `None` outside the extract's area, so a raster
    /// source or the grid shows there instead of blank land.
    fn get(&mut self, key: TileKey) -> Result<Option<FoundTile>, TileError> {
        let Some(id) = vestnav_osm::TileId::new(key.z, key.x, key.y) else { return Ok(None) };
        let Some((sw, ne)) = self.renderer.map().bounds() else { return Ok(None) };
        // Tile rows run southwards: the north-east corner's tile has the highest column, the lowest row.
        let (sw, ne) =
            (vestnav_osm::TileId::containing(sw, key.z), vestnav_osm::TileId::containing(ne, key.z));
        let (Some(sw), Some(ne)) = (sw, ne) else { return Ok(None) };
        if !(sw.x..=ne.x).contains(&key.x) || !(ne.y..=sw.y).contains(&key.y) {
            return Ok(None);
        }
        let what = tile_what(key, &self.path.display().to_string());
        let bytes =
            self.renderer.tile_png(id).map_err(|why| TileError::Corrupt { what: what.clone(), why })?;
        Ok(Some(FoundTile { bytes, origin: Origin::Local, what }))
    }
}

/// The disk cache folder for tiles drawn from the extract at `path` under the tile cache `root`: named by
/// the file's identity (size, modification time, a hash of its first blocks), [`RENDER_VERSION`] and
/// [`RENDER_SOURCE_HASH`].
pub fn extract_cache_dir(root: &Path, path: &Path) -> std::io::Result<PathBuf> {
    let id = cache::file_identity(path)?;
    Ok(cache::rendered_dir(root, &format!("osm-extract {id} {RENDER_VERSION} {RENDER_SOURCE_HASH:016x}")))
}

/// Reads the extract at `path` and names its tile cache folder under `cache_root`: the file's identity
/// taken before and after the read, so a file replaced while being read is not cached under either.
/// `Err` names the file; the folder is `Err` (why) when the drawing cannot be cached.
pub fn read_extract(path: &Path, cache_root: &Path) -> Result<(Extract, Result<PathBuf, String>), String> {
    let before = extract_cache_dir(cache_root, path);
    let extract = Extract::read(path).map_err(|e| e.to_string())?;
    let dir = match (before, extract_cache_dir(cache_root, path)) {
        (Ok(a), Ok(b)) if a == b => Ok(a),
        (Ok(_), Ok(_)) => Err(format!("{}: changed while being read; tiles not cached", path.display())),
        (Err(e), _) | (_, Err(e)) => Err(format!("{}: tiles not cached: {e}", path.display())),
    };
    Ok((extract, dir))
}

/// A loaded extract: what the map draws and what the planner walks.
pub struct LoadedExtract {
    /// The file.
    pub path: PathBuf,
    /// Draws the tiles (shared by the loader threads).
    pub renderer: Arc<Renderer>,
    /// The footway network.
    pub graph: Arc<PathGraph>,
    /// What was in the file.
    pub stats: ExtractStats,
    /// The disk cache folder of its drawn tiles, or why they are not cached.
    pub cache_dir: Result<PathBuf, String>,
    /// The first failure to write a tile into that folder (the map is drawn all the same).
    pub cache_error: Arc<OnceLock<String>>,
}

impl LoadedExtract {
    /// Splits an extract read from its file into the shared renderer and graph; its tiles are cached in
    /// `cache_dir` (from [`read_extract`]).
    pub fn new(e: Extract, cache_dir: Result<PathBuf, String>) -> Self {
        let Extract { path, map, graph, stats } = e;
        Self {
            path,
            renderer: Arc::new(Renderer::new(Arc::new(map))),
            graph: Arc::new(graph),
            stats,
            cache_dir,
            cache_error: Arc::default(),
        }
    }

    /// How each loader thread opens its store: the shared renderer behind the disk cache (the renderer
    /// alone when the tiles cannot be cached).
    pub fn store_opener(&self) -> OpenStore {
        let (renderer, path) = (self.renderer.clone(), self.path.clone());
        let (cache_dir, cache_error) = (self.cache_dir.clone(), self.cache_error.clone());
        Arc::new(move || -> Result<Box<dyn TileStore>, TileError> {
            let drawn = Box::new(OsmStore { renderer: renderer.clone(), path: path.clone() });
            Ok(match &cache_dir {
                Ok(dir) => Box::new(DiskCachedStore::new(drawn, dir.clone(), cache_error.clone())),
                Err(_) => drawn,
            })
        })
    }

    /// Why its tiles are not (all) in the disk cache, if they are not.
    pub fn cache_problem(&self) -> Option<&str> {
        match &self.cache_dir {
            Err(e) => Some(e),
            Ok(_) => self.cache_error.get().map(String::as_str),
        }
    }
}

type ReadOutcome = Result<(Extract, Result<PathBuf, String>), String>;

enum State {
    Reading(Receiver<ReadOutcome>),
    Ready(Box<(LoadedExtract, SourceTiles)>),
    Failed(String),
}

/// The extract named by the settings: being read, shown, or why it could not be read.
pub struct MapExtract {
    path: PathBuf,
    state: State,
}

/// The file's name for the indicator.
fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(|| p.display().to_string(), |f| f.to_string_lossy().into_owned())
}

impl MapExtract {
    /// Starts reading `path` on a worker thread; `ctx` is woken when it is done. Its drawn tiles are
    /// cached under the tile cache folder `cache_root`.
    pub fn open(path: &Path, cache_root: &Path, ctx: &egui::Context) -> Self {
        let (tx, rx) = std::sync::mpsc::channel();
        let (p, root, ctx2) = (path.to_path_buf(), cache_root.to_path_buf(), ctx.clone());
        let spawned = std::thread::Builder::new().name("osm-read".into()).spawn(move || {
            // The receiver is gone when the setting changed meanwhile: nothing left to tell.
            let _ = tx.send(read_extract(&p, &root));
            ctx2.request_repaint();
        });
        let state = match spawned {
            Ok(_) => State::Reading(rx),
            Err(e) => State::Failed(format!("{}: cannot start the reading thread: {e}", path.display())),
        };
        Self { path: path.to_path_buf(), state }
    }

    /// The file named.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Takes the read's outcome when it has arrived, starting the tile loader of a loaded extract.
    pub fn poll(&mut self, ctx: &egui::Context) {
        let State::Reading(rx) = &self.state else { return };
        self.state = match rx.try_recv() {
            Err(TryRecvError::Empty) => return,
            Err(TryRecvError::Disconnected) => {
                State::Failed(format!("{}: the reading thread ended without an answer", self.path.display()))
            }
            Ok(Err(e)) => State::Failed(e),
            Ok(Ok((e, cache_dir))) => {
                let loaded = LoadedExtract::new(e, cache_dir);
                let tiles = extract_tiles(&loaded, ctx);
                State::Ready(Box::new((loaded, tiles)))
            }
        };
    }

    /// The extract once read.
    pub fn loaded(&self) -> Option<&LoadedExtract> {
        match &self.state {
            State::Ready(r) => Some(&r.0),
            _ => None,
        }
    }

    /// Its tiles once read.
    pub fn tiles(&mut self) -> Option<&mut SourceTiles> {
        match &mut self.state {
            State::Ready(r) => Some(&mut r.1),
            _ => None,
        }
    }

    /// Why it could not be read (names the file).
    pub fn error(&self) -> Option<&str> {
        match &self.state {
            State::Failed(e) => Some(e),
            _ => None,
        }
    }

    /// The indicator's text: reading, what was read, or the error.
    pub fn status(&self) -> String {
        let name = file_name(&self.path);
        match &self.state {
            State::Reading(_) => format!("map {name}: reading…"),
            State::Failed(e) => format!("map: {e}"),
            State::Ready(r) => {
                let mut s = format!(
                    "map {name}: {:.1} MB, {} path nodes",
                    r.0.stats.bytes as f64 / 1e6,
                    r.0.graph.node_count()
                );
                if let Some(why) = r.0.cache_problem() {
                    s.push_str(" · ");
                    s.push_str(why);
                }
                s
            }
        }
    }
}

/// The tiles of a loaded extract: the loader threads draw them with the shared renderer.
pub fn extract_tiles(loaded: &LoadedExtract, ctx: &egui::Context) -> SourceTiles {
    let repaint = ctx.clone();
    let waker: vestnav_tiles::Waker = Arc::new(move || repaint.request_repaint());
    let loader = TileLoader::start_with(RENDER_THREADS, &loaded.store_opener(), &waker);
    SourceTiles::with_loader(format!("OSM extract {}", file_name(&loaded.path)), None, loader, ctx.clone())
}
