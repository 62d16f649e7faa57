//! The on-disk cache of downloaded tiles: one folder per source under the platform cache folder
//! (`directories::ProjectDirs::cache_dir()/tiles`, on Linux `~/.cache/vestnav/tiles`), laid out as
//! `{source}/{z}/{x}/{y}.png` (the name says `.png` whatever the format: the content is sniffed on read).
//!
//! A tile's modification time is when it was downloaded (it decides staleness); its access time is set
//! explicitly whenever the map uses it, so pruning can drop the least recently used files first when the
//! cache is over its size limit ([`prune`]).
//!
//! Tiles a store draws itself (the console's OpenStreetMap extract) are kept beside them, in a folder named
//! by the drawing's identity ([`rendered_dir`]: the source file's [`file_identity`] and the renderer's
//! version), through [`DiskCachedStore`]; the same pruning bounds them.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use std::time::SystemTime;

use super::store::{FoundTile, Origin, StoreInfo, TileStore};
use super::{TileError, TileKey, TileSourceConfig, stable_hash, tile_what};

/// Default size limit of the tile cache [MB].
pub const DEFAULT_LIMIT_MB: u64 = 500;

/// The platform cache folder for tiles (falls back to the temporary folder without a home directory).
pub fn default_root() -> PathBuf {
    directories::ProjectDirs::from("org", "vestnav", "vestnav")
        .map_or_else(|| std::env::temp_dir().join("vestnav-cache"), |d| d.cache_dir().to_path_buf())
        .join("tiles")
}

/// The cache folder of one HTTP source: `osm` for OpenStreetMap, `xyz-<hash of the URL template>` for
/// others (the template may hold an API key, so it is hashed rather than spelled out).
pub fn source_dir(root: &Path, source: &TileSourceConfig) -> PathBuf {
    match source {
        TileSourceConfig::Xyz { url, .. } => root.join(format!("xyz-{}", stable_hash(url))),
        _ => root.join("osm"),
    }
}

/// Where tile `key` lives in a source's cache folder.
pub fn tile_path(dir: &Path, key: TileKey) -> PathBuf {
    dir.join(key.z.to_string()).join(key.x.to_string()).join(format!("{}.png", key.y))
}

/// Marks a cached tile as just used (its access time), for the least-recently-used pruning. Opens
/// regular files only, and only for reading (setting the times of one's own file needs no write
/// access), so a FIFO put in the cache never blocks the loader.
pub fn touch(path: &Path) {
    if let Ok(f) = vestnav_files::open_regular(path) {
        // Best effort: a cache on a read-only disk still serves tiles, it only prunes by download time.
        let _ = f.set_times(std::fs::FileTimes::new().set_accessed(SystemTime::now()));
    }
}

/// Writes a tile atomically ([`vestnav_files::write_atomic`]: a unique temporary file, synced, then
/// renamed), so a killed prefetch never leaves half a tile and two writers never share a temporary.
pub fn store(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    vestnav_files::ensure_parent(path)?;
    vestnav_files::write_atomic(path, bytes)
}

/// Bytes of a source file hashed into its [`file_identity`] (an extract's header and first blocks).
pub const IDENTITY_HEAD_BYTES: u64 = 64 * 1024;

/// The identity of a file whose drawing is cached: its size, its modification time (ns) and an FNV-1a
/// hash of its first [`IDENTITY_HEAD_BYTES`]. A file rewritten, replaced or touched gets another identity,
/// so tiles drawn from its old content are never shown for the new one. Regular files only.
pub fn file_identity(path: &Path) -> std::io::Result<String> {
    let f = vestnav_files::open_regular(path)?;
    let meta = f.metadata()?;
    let mtime_ns = meta.modified()?.duration_since(SystemTime::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
    let mut head = Vec::new();
    f.take(IDENTITY_HEAD_BYTES).read_to_end(&mut head)?;
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in &head {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    Ok(format!("{}-{mtime_ns}-{h:016x}", meta.len()))
}

/// The cache folder of tiles drawn from one source (`identity`: the file's [`file_identity`] and the
/// renderer's version, so a changed file or a changed drawing never meets old tiles):
/// `rendered-<hash of identity>`.
pub fn rendered_dir(root: &Path, identity: &str) -> PathBuf {
    root.join(format!("rendered-{}", stable_hash(identity)))
}

/// A store whose tiles are kept in the disk cache: a tile is read back from `dir` when there (checked like
/// any tile file; a damaged one is drawn again and replaced), otherwise taken from the inner store and
/// written to `dir`. A write that fails (full disk, read-only folder) never costs the tile: the first
/// failure is kept in `write_error` for the operator (later ones are the same story and not repeated).
pub struct DiskCachedStore {
    inner: Box<dyn TileStore>,
    dir: PathBuf,
    write_error: Arc<OnceLock<String>>,
}

impl DiskCachedStore {
    /// `inner` cached in `dir` (from [`rendered_dir`]); the first write failure goes to `write_error`.
    pub fn new(inner: Box<dyn TileStore>, dir: PathBuf, write_error: Arc<OnceLock<String>>) -> Self {
        Self { inner, dir, write_error }
    }
}

impl TileStore for DiskCachedStore {
    fn info(&self) -> StoreInfo {
        self.inner.info()
    }

    fn get(&mut self, key: TileKey) -> Result<Option<FoundTile>, TileError> {
        let path = tile_path(&self.dir, key);
        let what = tile_what(key, &path.display().to_string());
        if let Ok(Some(bytes)) = super::store::read_capped(&path, &what) {
            touch(&path);
            return Ok(Some(FoundTile { bytes, origin: Origin::Cache, what }));
        }
        let found = self.inner.get(key)?;
        if let Some(t) = &found
            && let Err(e) = store(&path, &t.bytes)
        {
            // Only the first failure is kept: a full disk fails every tile the same way.
            let _ = self.write_error.set(format!("tile cache {} not written: {e}", self.dir.display()));
        }
        Ok(found)
    }
}

/// One cached file.
#[derive(Debug, Clone)]
struct CachedFile {
    path: PathBuf,
    bytes: u64,
    used: SystemTime,
}

fn walk(dir: &Path, out: &mut Vec<CachedFile>, depth: usize) {
    let Ok(rd) = std::fs::read_dir(dir) else { return };
    for e in rd.filter_map(Result::ok) {
        let Ok(m) = e.metadata() else { continue };
        if m.is_dir() && depth < 4 {
            walk(&e.path(), out, depth + 1);
        } else if m.is_file() {
            let used = m.accessed().or_else(|_| m.modified()).unwrap_or(SystemTime::UNIX_EPOCH);
            out.push(CachedFile { path: e.path(), bytes: m.len(), used });
        }
    }
}

/// Size of the cache under `root` [bytes] and its number of files.
pub fn usage(root: &Path) -> (u64, usize) {
    let mut files = Vec::new();
    walk(root, &mut files, 0);
    (files.iter().map(|f| f.bytes).sum(), files.len())
}

/// What [`prune`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PruneReport {
    /// Size before [bytes].
    pub before_bytes: u64,
    /// Size after [bytes].
    pub after_bytes: u64,
    /// Files removed.
    pub removed: usize,
}

/// Removes the least recently used files under `root` until it holds at most `limit_bytes`.
pub fn prune(root: &Path, limit_bytes: u64) -> PruneReport {
    let mut files = Vec::new();
    walk(root, &mut files, 0);
    let before_bytes: u64 = files.iter().map(|f| f.bytes).sum();
    let mut total = before_bytes;
    let mut removed = 0;
    if total > limit_bytes {
        files.sort_by_key(|f| f.used);
        for f in files {
            if total <= limit_bytes {
                break;
            }
            if std::fs::remove_file(&f.path).is_ok() {
                total -= f.bytes;
                removed += 1;
            }
        }
    }
    PruneReport { before_bytes, after_bytes: total, removed }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn prune_drops_least_recently_used_first() {
        let root = std::env::temp_dir().join(format!("vestnav-tilecache-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let dir = source_dir(&root, &TileSourceConfig::Osm);
        let t0 = SystemTime::now() - Duration::from_secs(1000);
        for i in 0..5u32 {
            let p = tile_path(&dir, TileKey::new(3, i, 1).unwrap());
            store(&p, &[0u8; 100]).unwrap();
            let f = std::fs::File::options().write(true).open(&p).unwrap();
            // Tile 0 used most recently, then 1, ... tile 4 least recently.
            f.set_times(std::fs::FileTimes::new().set_accessed(t0 - Duration::from_secs(u64::from(i) * 10)))
                .unwrap();
        }
        assert_eq!(usage(&root), (500, 5));
        let r = prune(&root, 250);
        assert_eq!(r, PruneReport { before_bytes: 500, after_bytes: 200, removed: 3 });
        for i in 0..5u32 {
            let exists = tile_path(&dir, TileKey::new(3, i, 1).unwrap()).exists();
            assert_eq!(exists, i < 2, "tile {i}");
        }
        assert_eq!(prune(&root, 250).removed, 0);
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn source_folders_hide_keys() {
        let root = Path::new("/c");
        let x = TileSourceConfig::Xyz {
            url: "https://a/{z}/{x}/{y}?key=SECRET".into(),
            attribution: String::new(),
            allows_bulk: true,
        };
        let d = source_dir(root, &x);
        assert!(!d.to_string_lossy().contains("SECRET"));
        assert_eq!(source_dir(root, &TileSourceConfig::Osm), Path::new("/c/osm"));
        assert_eq!(
            tile_path(Path::new("/c/osm"), TileKey::new(2, 1, 3).unwrap()),
            Path::new("/c/osm/2/1/3.png")
        );
    }
}
