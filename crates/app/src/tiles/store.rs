//! Where one tile's bytes come from: a folder, an MBTiles or PMTiles file, or an XYZ server through the
//! on-disk cache. Each store is owned by one loader thread ([`super::local`]), so none needs to be `Sync`.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use super::pmtiles::PmTilesReader;
use super::{MAX_TILE_BYTES, TileError, TileKey, TileSourceConfig, check_tile_bytes, redact_url};

/// A cached tile older than this is stale: shown, and fetched again when the server answers.
pub const STALE_AFTER: Duration = Duration::from_hours(30 * 24);
/// Timeout of one tile request.
pub const HTTP_TIMEOUT: Duration = Duration::from_secs(15);
/// The User-Agent sent to tile servers (the OSM policy asks for an identifying one).
pub const USER_AGENT: &str = concat!("vestnav-console/", env!("CARGO_PKG_VERSION"));

/// Where the bytes of a tile came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Origin {
    /// A local file (PMTiles, MBTiles, folder).
    Local,
    /// The on-disk cache, fresh.
    Cache,
    /// The on-disk cache, older than [`STALE_AFTER`] and the server did not answer.
    Stale,
    /// Downloaded just now (and cached).
    Downloaded,
}

/// What a store knows about itself once open.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoreInfo {
    /// Lowest zoom the store holds.
    pub min_zoom: u8,
    /// Highest zoom it holds; the map magnifies this zoom's tiles beyond it.
    pub max_zoom: u8,
    /// Attribution found in the file (MBTiles metadata), if any.
    pub attribution: Option<String>,
}

/// A source of tile bytes.
pub trait TileStore: Send {
    /// What the store holds.
    fn info(&self) -> StoreInfo;
    /// The tile's bytes (checked with [`check_tile_bytes`]) and their origin; `None` when the store does
    /// not have this tile.
    fn get(&mut self, key: TileKey) -> Result<Option<(Vec<u8>, Origin)>, TileError>;
}

/// Opens the store of `source`; `cache_dir` holds downloaded tiles of the HTTP sources.
pub fn open(source: &TileSourceConfig, cache_dir: &Path) -> Result<Box<dyn TileStore>, TileError> {
    Ok(match source {
        TileSourceConfig::Osm | TileSourceConfig::Xyz { .. } => {
            let url = source.url_template().unwrap_or_default().to_owned();
            Box::new(HttpStore::new(url, super::cache::source_dir(cache_dir, source))?)
        }
        TileSourceConfig::PmTiles(p) => Box::new(PmStore(PmTilesReader::open(p)?)),
        TileSourceConfig::MbTiles(p) => Box::new(MbTilesStore::open(p)?),
        TileSourceConfig::Folder(p) => Box::new(FolderStore::open(p)?),
    })
}

/// Reads a file of at most [`MAX_TILE_BYTES`] (checking the size before reading), `None` if absent.
pub fn read_capped(path: &Path) -> Result<Option<Vec<u8>>, TileError> {
    let what = || path.display().to_string();
    let file = match std::fs::File::open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(source) => return Err(TileError::Io { what: what(), source }),
    };
    let mut buf = Vec::new();
    file.take(MAX_TILE_BYTES as u64 + 1)
        .read_to_end(&mut buf)
        .map_err(|source| TileError::Io { what: what(), source })?;
    if buf.len() > MAX_TILE_BYTES {
        let bytes = std::fs::metadata(path).map_or(buf.len() as u64, |m| m.len());
        return Err(TileError::TooLarge { what: what(), bytes });
    }
    check_tile_bytes(&buf, &what())?;
    Ok(Some(buf))
}

/// A folder of `{z}/{x}/{y}.png` tiles (also `.jpg`, `.jpeg`, `.webp`; the content decides the format).
pub struct FolderStore {
    root: PathBuf,
    info: StoreInfo,
}

/// File extensions tried in a tile folder, in order.
const EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "webp"];

impl FolderStore {
    /// Opens `root`; its zoom range is read from the numeric folder names directly inside it.
    pub fn open(root: &Path) -> Result<Self, TileError> {
        let what = root.display().to_string();
        let rd = std::fs::read_dir(root).map_err(|source| TileError::Io { what: what.clone(), source })?;
        let zooms: Vec<u8> = rd
            .filter_map(Result::ok)
            .filter(|e| e.path().is_dir())
            .filter_map(|e| e.file_name().to_str()?.parse::<u8>().ok())
            .filter(|z| *z <= super::MAX_ZOOM)
            .collect();
        let (Some(&min_zoom), Some(&max_zoom)) = (zooms.iter().min(), zooms.iter().max()) else {
            return Err(TileError::Corrupt {
                what,
                why: "no {z} folders (0-24) inside: not a {z}/{x}/{y}.png tile folder".into(),
            });
        };
        Ok(Self { root: root.to_owned(), info: StoreInfo { min_zoom, max_zoom, attribution: None } })
    }
}

impl TileStore for FolderStore {
    fn info(&self) -> StoreInfo {
        self.info.clone()
    }
    fn get(&mut self, key: TileKey) -> Result<Option<(Vec<u8>, Origin)>, TileError> {
        let dir = self.root.join(key.z.to_string()).join(key.x.to_string());
        for ext in EXTENSIONS {
            if let Some(b) = read_capped(&dir.join(format!("{}.{ext}", key.y)))? {
                return Ok(Some((b, Origin::Local)));
            }
        }
        Ok(None)
    }
}

/// A raster PMTiles archive.
pub struct PmStore(PmTilesReader);

impl TileStore for PmStore {
    fn info(&self) -> StoreInfo {
        StoreInfo { min_zoom: self.0.header.min_zoom, max_zoom: self.0.header.max_zoom, attribution: None }
    }
    fn get(&mut self, key: TileKey) -> Result<Option<(Vec<u8>, Origin)>, TileError> {
        let Some(b) = self.0.tile(key)? else { return Ok(None) };
        check_tile_bytes(&b, &format!("{} tile {}/{}/{}", self.0.path().display(), key.z, key.x, key.y))?;
        Ok(Some((b, Origin::Local)))
    }
}

/// An MBTiles file (SQLite, <https://github.com/mapbox/mbtiles-spec/blob/master/1.3/spec.md>): table
/// `tiles(zoom_level, tile_column, tile_row, tile_data)` with TMS rows ([`TileKey::tms_row`]).
pub struct MbTilesStore {
    conn: rusqlite::Connection,
    path: PathBuf,
    info: StoreInfo,
}

impl MbTilesStore {
    /// Opens `path` read-only and reads its metadata (zoom range, attribution, format).
    pub fn open(path: &Path) -> Result<Self, TileError> {
        let what = path.display().to_string();
        let sql = |e: rusqlite::Error| TileError::Corrupt {
            what: what.clone(),
            why: format!("not a readable MBTiles file: {e}"),
        };
        if !path.is_file() {
            return Err(TileError::Io { what, source: std::io::Error::from(std::io::ErrorKind::NotFound) });
        }
        let conn = rusqlite::Connection::open_with_flags(
            path,
            rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY | rusqlite::OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(sql)?;
        let meta = |name: &str| -> Option<String> {
            conn.query_row("SELECT value FROM metadata WHERE name = ?1", [name], |r| r.get::<_, String>(0))
                .ok()
        };
        if let Some(f) = meta("format") {
            let f = f.to_ascii_lowercase();
            if !["png", "jpg", "jpeg", "webp"].contains(&f.as_str()) {
                return Err(TileError::Corrupt {
                    what,
                    why: format!("tile format '{f}': the console draws PNG, JPEG or WebP tiles only"),
                });
            }
        }
        let zoom =
            |s: Option<String>| s.and_then(|v| v.trim().parse::<u8>().ok()).filter(|z| *z <= super::MAX_ZOOM);
        let (mut min_zoom, mut max_zoom) = (zoom(meta("minzoom")), zoom(meta("maxzoom")));
        if min_zoom.is_none() || max_zoom.is_none() {
            let (lo, hi): (Option<i64>, Option<i64>) = conn
                .query_row("SELECT MIN(zoom_level), MAX(zoom_level) FROM tiles", [], |r| {
                    Ok((r.get(0)?, r.get(1)?))
                })
                .map_err(sql)?;
            let z = |v: Option<i64>| v.and_then(|v| u8::try_from(v).ok()).filter(|z| *z <= super::MAX_ZOOM);
            min_zoom = min_zoom.or(z(lo));
            max_zoom = max_zoom.or(z(hi));
        }
        // Prove the tiles table is there with the right columns.
        conn.prepare("SELECT tile_data FROM tiles WHERE zoom_level = 0 AND tile_column = 0 AND tile_row = 0")
            .map_err(sql)?;
        let (Some(min_zoom), Some(max_zoom)) = (min_zoom, max_zoom) else {
            return Err(TileError::Corrupt { what, why: "no tiles and no minzoom/maxzoom metadata".into() });
        };
        let attribution =
            meta("attribution").filter(|a| !a.trim().is_empty()).map(|a| a.chars().take(200).collect());
        Ok(Self { conn, path: path.to_owned(), info: StoreInfo { min_zoom, max_zoom, attribution } })
    }
}

impl TileStore for MbTilesStore {
    fn info(&self) -> StoreInfo {
        self.info.clone()
    }
    fn get(&mut self, key: TileKey) -> Result<Option<(Vec<u8>, Origin)>, TileError> {
        let what = format!("{} tile {}/{}/{}", self.path.display(), key.z, key.x, key.y);
        let sql = |e: rusqlite::Error| TileError::Corrupt { what: what.clone(), why: e.to_string() };
        let params = rusqlite::params![key.z, key.x, key.tms_row()];
        // The length first, so that a huge blob is refused without being read.
        let len: Option<i64> = match self.conn.query_row(
            "SELECT length(tile_data) FROM tiles WHERE zoom_level = ?1 AND tile_column = ?2 AND tile_row = ?3",
            params,
            |r| r.get(0),
        ) {
            Ok(l) => l,
            Err(rusqlite::Error::QueryReturnedNoRows) => return Ok(None),
            Err(e) => return Err(sql(e)),
        };
        let len = len.unwrap_or(0);
        if u64::try_from(len).unwrap_or(0) > MAX_TILE_BYTES as u64 {
            return Err(TileError::TooLarge { what, bytes: len as u64 });
        }
        let b: Vec<u8> = self
            .conn
            .query_row(
                "SELECT tile_data FROM tiles WHERE zoom_level = ?1 AND tile_column = ?2 AND tile_row = ?3",
                params,
                |r| r.get(0),
            )
            .map_err(sql)?;
        check_tile_bytes(&b, &what)?;
        Ok(Some((b, Origin::Local)))
    }
}

/// Downloads one tile: `Ok(None)` for 404/204 (the server has no such tile), the checked bytes for 200.
pub fn download(client: &reqwest::blocking::Client, url: &str) -> Result<Option<Vec<u8>>, TileError> {
    let what = redact_url(url);
    let http = |why: String| TileError::Http { what: what.clone(), why };
    let resp = client.get(url).send().map_err(|e| http(format!("request failed: {}", e.without_url())))?;
    let status = resp.status();
    if status == reqwest::StatusCode::NOT_FOUND || status == reqwest::StatusCode::NO_CONTENT {
        return Ok(None);
    }
    if !status.is_success() {
        return Err(http(format!("server answered {status}")));
    }
    if resp.content_length().is_some_and(|l| l > MAX_TILE_BYTES as u64) {
        return Err(TileError::TooLarge { what, bytes: resp.content_length().unwrap_or(0) });
    }
    let mut buf = Vec::new();
    resp.take(MAX_TILE_BYTES as u64 + 1)
        .read_to_end(&mut buf)
        .map_err(|e| http(format!("reading the body failed: {e}")))?;
    check_tile_bytes(&buf, &what)?;
    Ok(Some(buf))
}

/// A blocking HTTP client for tiles: identifying User-Agent, [`HTTP_TIMEOUT`], no redirects to other
/// schemes beyond reqwest's default policy.
pub fn http_client() -> Result<reqwest::blocking::Client, TileError> {
    reqwest::blocking::Client::builder()
        .user_agent(USER_AGENT)
        .timeout(HTTP_TIMEOUT)
        .build()
        .map_err(|e| TileError::Http { what: "HTTP client".into(), why: e.to_string() })
}

/// An XYZ server seen through the on-disk cache: a fresh cached tile is served from disk; a missing or
/// stale one is downloaded and cached; when the download fails a stale tile is still served.
pub struct HttpStore {
    url: String,
    dir: PathBuf,
    client: reqwest::blocking::Client,
}

impl HttpStore {
    /// A store for `url` (an XYZ template) caching into `dir`.
    pub fn new(url: String, dir: PathBuf) -> Result<Self, TileError> {
        Ok(Self { url, dir, client: http_client()? })
    }
}

impl TileStore for HttpStore {
    fn info(&self) -> StoreInfo {
        StoreInfo { min_zoom: 0, max_zoom: 19, attribution: None }
    }
    fn get(&mut self, key: TileKey) -> Result<Option<(Vec<u8>, Origin)>, TileError> {
        let path = super::cache::tile_path(&self.dir, key);
        let cached = read_capped(&path).ok().flatten();
        let age = std::fs::metadata(&path)
            .and_then(|m| m.modified())
            .ok()
            .and_then(|t| SystemTime::now().duration_since(t).ok());
        if let Some(b) = &cached
            && age.is_some_and(|a| a < STALE_AFTER)
        {
            super::cache::touch(&path);
            return Ok(Some((b.clone(), Origin::Cache)));
        }
        match download(&self.client, &key.url(&self.url)) {
            Ok(Some(b)) => {
                // A cache that cannot be written is not worth losing the tile over.
                let _ = super::cache::store(&path, &b);
                Ok(Some((b, Origin::Downloaded)))
            }
            Ok(None) => Ok(None),
            Err(e) => match cached {
                Some(b) => Ok(Some((b, Origin::Stale))),
                None => Err(e),
            },
        }
    }
}
