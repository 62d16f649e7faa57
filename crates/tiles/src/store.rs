//! Where one tile's bytes come from: a folder, an MBTiles or PMTiles file, or an XYZ server through the
//! on-disk cache. Each store is owned by one loader thread ([`super::local`]), so none needs to be `Sync`.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use super::pmtiles::PmTilesReader;
use super::{MAX_TILE_BYTES, TileError, TileKey, TileSourceConfig, check_tile_bytes, redact_url, tile_what};

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

/// One tile's bytes as a store found them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FoundTile {
    /// The bytes, checked with [`check_tile_bytes`] (signature, size, declared dimensions).
    pub bytes: Vec<u8>,
    /// Where they came from.
    pub origin: Origin,
    /// How the tile is named in messages: `tile z/x/y of FILE-or-URL` ([`tile_what`]).
    pub what: String,
}

/// A source of tile bytes.
pub trait TileStore: Send {
    /// What the store holds.
    fn info(&self) -> StoreInfo;
    /// The tile: `Ok(Some)` with its checked bytes, `Ok(None)` when the store does not have it, `Err`
    /// when it could not be read or was refused ([`TileError::is_refusal`]) — a refused tile is never
    /// reported as absent.
    fn get(&mut self, key: TileKey) -> Result<Option<FoundTile>, TileError>;
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

/// Reads a tile file of at most [`MAX_TILE_BYTES`] and checks it ([`check_tile_bytes`]); `Ok(None)` when
/// there is no such file. Opens regular files only ([`vestnav_files::read_limited`]): a FIFO, device or
/// folder in its place is refused without being opened, so a loader never blocks on it. `what` names
/// the tile in messages.
pub fn read_capped(path: &Path, what: &str) -> Result<Option<Vec<u8>>, TileError> {
    match vestnav_files::read_limited(path, MAX_TILE_BYTES as u64) {
        Ok(buf) => {
            check_tile_bytes(&buf, what)?;
            Ok(Some(buf))
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        // read_limited says InvalidData for "over the limit" (and only for that).
        Err(e) if e.kind() == std::io::ErrorKind::InvalidData => {
            let bytes = std::fs::metadata(path).map_or(MAX_TILE_BYTES as u64 + 1, |m| m.len());
            Err(TileError::TooLarge { what: what.to_owned(), bytes })
        }
        Err(e) => Err(TileError::from_open(what.to_owned(), e)),
    }
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
        // Only a folder is listed: a FIFO or device given as the folder is refused from its metadata.
        match std::fs::metadata(root) {
            Ok(m) if !m.is_dir() => {
                return Err(TileError::NotRegular { what, why: "not a folder".into() });
            }
            _ => {}
        }
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
    fn get(&mut self, key: TileKey) -> Result<Option<FoundTile>, TileError> {
        let dir = self.root.join(key.z.to_string()).join(key.x.to_string());
        for ext in EXTENSIONS {
            let path = dir.join(format!("{}.{ext}", key.y));
            let what = tile_what(key, &path.display().to_string());
            if let Some(bytes) = read_capped(&path, &what)? {
                return Ok(Some(FoundTile { bytes, origin: Origin::Local, what }));
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
    fn get(&mut self, key: TileKey) -> Result<Option<FoundTile>, TileError> {
        let Some(bytes) = self.0.tile(key)? else { return Ok(None) };
        let what = tile_what(key, &self.0.path().display().to_string());
        check_tile_bytes(&bytes, &what)?;
        Ok(Some(FoundTile { bytes, origin: Origin::Local, what }))
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
    /// Opens `path` read-only and reads its metadata (zoom range, attribution, format). The path must
    /// be a regular file: a FIFO or device is refused before SQLite could open (and block on) it.
    pub fn open(path: &Path) -> Result<Self, TileError> {
        let what = path.display().to_string();
        let sql = |e: rusqlite::Error| TileError::Corrupt {
            what: what.clone(),
            why: format!("not a readable MBTiles file: {e}"),
        };
        vestnav_files::open_regular(path).map_err(|e| TileError::from_open(what.clone(), e))?;
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
            if ["pbf", "mvt"].contains(&f.as_str()) {
                return Err(TileError::Corrupt {
                    what,
                    why: format!("tile format '{f}': {}", super::VECTOR_TILES_REFUSED),
                });
            }
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
    fn get(&mut self, key: TileKey) -> Result<Option<FoundTile>, TileError> {
        let what = tile_what(key, &self.path.display().to_string());
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
        Ok(Some(FoundTile { bytes: b, origin: Origin::Local, what }))
    }
}

/// Most same-host redirects followed for one tile.
pub const MAX_REDIRECTS: usize = 5;

/// A blocking HTTP client for tiles: identifying User-Agent, [`HTTP_TIMEOUT`], and a redirect policy that
/// follows at most [`MAX_REDIRECTS`] redirects and only to the host (and port) the URL named, never from
/// https to http; any other redirect is handed back unfollowed and reported as
/// [`TileError::Redirected`].
#[derive(Clone)]
pub struct TileClient {
    client: reqwest::blocking::Client,
    who: &'static str,
}

/// Whether a redirect from `from` to `to` stays where the user pointed: same host and port, and no
/// step down from https to http.
fn same_origin(from: &reqwest::Url, to: &reqwest::Url) -> bool {
    let downgrade = from.scheme() == "https" && to.scheme() != "https";
    !downgrade
        && matches!(to.scheme(), "http" | "https")
        && from.host_str().map(str::to_ascii_lowercase) == to.host_str().map(str::to_ascii_lowercase)
        && from.port_or_known_default() == to.port_or_known_default()
}

/// `scheme://host[:port]` of a URL, for messages (no path, no query: they may hold a key).
fn origin_text(u: &reqwest::Url) -> String {
    let host = u.host_str().unwrap_or("?");
    match u.port() {
        Some(p) => format!("{}://{host}:{p}", u.scheme()),
        None => format!("{}://{host}", u.scheme()),
    }
}

/// Why `err` (a request that got no response) did not reach `host`: the OS error kinds in its source chain
/// first (refused, no route), then a timeout, then a failed name resolution (reported by the resolver as
/// "dns error" / "failed to lookup address"), else the client's own words.
pub fn network_cause(err: &reqwest::Error, host: &str) -> crate::NetworkCause {
    use crate::NetworkCause;
    use std::error::Error as _;
    let host = host.to_owned();
    let mut texts = Vec::new();
    let mut source: Option<&(dyn std::error::Error + 'static)> = err.source();
    while let Some(e) = source {
        if let Some(io) = e.downcast_ref::<std::io::Error>() {
            match io.kind() {
                std::io::ErrorKind::ConnectionRefused => return NetworkCause::Refused { host },
                std::io::ErrorKind::NetworkUnreachable | std::io::ErrorKind::HostUnreachable => {
                    return NetworkCause::Unreachable { host, why: "no route to it".into() };
                }
                std::io::ErrorKind::TimedOut => {
                    return NetworkCause::Unreachable { host, why: "no answer in time".into() };
                }
                _ => {}
            }
        }
        texts.push(e.to_string().to_ascii_lowercase());
        source = e.source();
    }
    if err.is_timeout() {
        return NetworkCause::Unreachable {
            host,
            why: format!("no answer within {} s", HTTP_TIMEOUT.as_secs()),
        };
    }
    let all = texts.join(": ");
    if all.contains("dns error") || all.contains("lookup address") || all.contains("name resolution") {
        return NetworkCause::Offline { host };
    }
    // The source chain's words, not the error's own text: that names the URL, which may hold a key.
    let why = if all.is_empty() { "transport error".to_owned() } else { all };
    NetworkCause::Other { host, why }
}

impl TileClient {
    /// A client; `who` names the caller in a refused redirect's message ("prefetch", "the map").
    pub fn new(who: &'static str) -> Result<Self, TileError> {
        let policy = reqwest::redirect::Policy::custom(|attempt| {
            let Some(first) = attempt.previous().first() else { return attempt.stop() };
            if !same_origin(first, attempt.url()) {
                // Handed back as the 3xx response: `download` names where it pointed.
                attempt.stop()
            } else if attempt.previous().len() > MAX_REDIRECTS {
                attempt.error(format!("more than {MAX_REDIRECTS} redirects"))
            } else {
                attempt.follow()
            }
        });
        let client = reqwest::blocking::Client::builder()
            .user_agent(USER_AGENT)
            .timeout(HTTP_TIMEOUT)
            .redirect(policy)
            .build()
            .map_err(|e| TileError::Http { what: "HTTP client".into(), why: e.to_string() })?;
        Ok(Self { client, who })
    }

    /// Downloads one tile: `Ok(None)` for 404/204 (the server has no such tile), the checked bytes for
    /// 200. A redirect this client does not follow is [`TileError::Redirected`]; the body is read only up
    /// to [`MAX_TILE_BYTES`].
    pub fn download(&self, url: &str, what: &str) -> Result<Option<Vec<u8>>, TileError> {
        let http = |why: String| TileError::Http { what: what.to_owned(), why };
        let resp = self.client.get(url).send().map_err(|e| {
            let host = reqwest::Url::parse(url).ok().and_then(|u| {
                let host = u.host_str()?.to_owned();
                Some(u.port().map_or_else(|| host.clone(), |p| format!("{host}:{p}")))
            });
            let host = host.unwrap_or_else(|| "the server".to_owned());
            TileError::Network { what: what.to_owned(), cause: network_cause(&e, &host) }
        })?;
        let status = resp.status();
        if status == reqwest::StatusCode::NOT_FOUND || status == reqwest::StatusCode::NO_CONTENT {
            return Ok(None);
        }
        if status.is_redirection() {
            let to = resp
                .headers()
                .get(reqwest::header::LOCATION)
                .and_then(|l| l.to_str().ok())
                .and_then(|l| resp.url().join(l).ok());
            return Err(match to {
                Some(to) => {
                    TileError::Redirected { what: what.to_owned(), to: origin_text(&to), who: self.who }
                }
                None => http(format!("server answered {status} without a usable Location")),
            });
        }
        if !status.is_success() {
            return Err(http(format!("server answered {status}")));
        }
        if let Some(bytes) = resp.content_length().filter(|l| *l > MAX_TILE_BYTES as u64) {
            return Err(TileError::TooLarge { what: what.to_owned(), bytes });
        }
        let mut buf = Vec::new();
        resp.take(MAX_TILE_BYTES as u64 + 1)
            .read_to_end(&mut buf)
            .map_err(|e| http(format!("reading the body failed: {e}")))?;
        check_tile_bytes(&buf, what)?;
        Ok(Some(buf))
    }
}

/// An XYZ server seen through the on-disk cache: a fresh cached tile is served from disk; a missing or
/// stale one is downloaded and cached; when the download fails a stale tile is still served (a refused
/// download is reported, never replaced by a stale tile silently: the operator sees why).
pub struct HttpStore {
    url: String,
    dir: PathBuf,
    client: TileClient,
}

impl HttpStore {
    /// A store for `url` (an XYZ template) caching into `dir`.
    pub fn new(url: String, dir: PathBuf) -> Result<Self, TileError> {
        Ok(Self { url, dir, client: TileClient::new("the map")? })
    }
}

impl TileStore for HttpStore {
    fn info(&self) -> StoreInfo {
        StoreInfo { min_zoom: 0, max_zoom: 19, attribution: None }
    }
    fn get(&mut self, key: TileKey) -> Result<Option<FoundTile>, TileError> {
        let path = super::cache::tile_path(&self.dir, key);
        let url = key.url(&self.url);
        let what = tile_what(key, &redact_url(&url));
        // A cached file that is not a usable tile (or not a regular file) is as good as none: it is
        // downloaded again and replaced.
        let cached = read_capped(&path, &what).ok().flatten();
        let age = std::fs::metadata(&path)
            .and_then(|m| m.modified())
            .ok()
            .and_then(|t| SystemTime::now().duration_since(t).ok());
        if let Some(b) = &cached
            && age.is_some_and(|a| a < STALE_AFTER)
        {
            super::cache::touch(&path);
            return Ok(Some(FoundTile { bytes: b.clone(), origin: Origin::Cache, what }));
        }
        match self.client.download(&url, &what) {
            Ok(Some(bytes)) => {
                // A cache that cannot be written is not worth losing the tile over.
                let _ = super::cache::store(&path, &bytes);
                Ok(Some(FoundTile { bytes, origin: Origin::Downloaded, what }))
            }
            Ok(None) => Ok(None),
            Err(e) => match cached {
                Some(bytes) if !e.is_refusal() => Ok(Some(FoundTile { bytes, origin: Origin::Stale, what })),
                _ => Err(e),
            },
        }
    }
}
