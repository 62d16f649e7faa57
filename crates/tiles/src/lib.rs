//! vestnav's map tiles, with no GUI: where raster tiles come from (the OpenStreetMap server, any XYZ URL
//! template, a PMTiles or MBTiles file, a folder of `{z}/{x}/{y}.png`), the on-disk cache of downloaded
//! tiles and its pruning, the loader threads that read and decode tiles off the UI thread into a plain
//! RGBA [`TileImage`], and the offline prefetch of an area (into the cache or an MBTiles file). The
//! console draws what [`loader::TileLoader`] hands it; `vestnav tiles prefetch` runs [`prefetch`]
//! headless; neither needs egui here.
//!
//! Every byte read from a tile file or a server is treated as hostile: a tile file is opened only when it
//! is a regular file (a FIFO or device never blocks a loader), a tile is at most [`MAX_TILE_BYTES`], must
//! start with a PNG, JPEG or WebP signature, must declare at most [`MAX_TILE_PX`] pixels a side in its
//! header before it is decoded ([`check_tile_bytes`]), and its z/x/y must lie on the tile grid
//! ([`TileKey::new`]). A tile refused is reported with the reason ([`TileError::is_refusal`]), never as
//! absent. Downloads follow no redirect to another host.
//!
//! The maths is the OpenStreetMap "slippy map" convention (<https://wiki.openstreetmap.org/wiki/Slippy_map_tilenames>):
//! at zoom `z` the Web-Mercator world is `2^z × 2^z` tiles, x eastwards from 180° W, y southwards from
//! 85.0511° N.
//!
//! ```
//! use vestnav_tiles::{TileKey, TileSourceConfig, parse_tiles_spec, tile_x, tile_y};
//!
//! // MIT's Great Dome at zoom 17.
//! let key = TileKey::new(17, tile_x(-71.0921, 17), tile_y(42.3597, 17)).unwrap();
//! assert_eq!(key.url("https://t.example/{z}/{x}/{y}.png"), "https://t.example/17/39652/48479.png");
//! // The map's --tiles option; the API key stays out of messages.
//! let src = parse_tiles_spec("https://t.example/{z}/{x}/{y}.png?key=S3CRET").unwrap();
//! assert!(matches!(src, TileSourceConfig::Xyz { .. }));
//! assert!(!src.label().contains("S3CRET"));
//! // A tile that is not an image is refused, naming where it came from.
//! let e = vestnav_tiles::decode_tile(b"<html>", "tile 17/39652/48479 of t.example").unwrap_err();
//! assert!(e.is_refusal() && e.to_string().contains("not a PNG, JPEG or WebP"));
//! ```

pub mod cache;
pub mod decode;
pub mod loader;
pub mod mbtiles;
pub mod pmtiles;
pub mod prefetch;
pub mod store;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use decode::{TileFormat, TileImage, check_tile_bytes, decode_tile, sniff};

/// Called by a loader or prefetch thread when it has something new for the UI: core's one waker type.
pub use vestnav_core::Waker;

/// Largest tile accepted from a file or a server [bytes]: real 256/512 px raster tiles are 5–100 kB.
pub const MAX_TILE_BYTES: usize = 1 << 20;
/// Largest decoded tile side accepted [px] (real tiles are 256 or 512).
pub const MAX_TILE_PX: u32 = 1024;
/// Highest zoom level accepted anywhere (tile numbers must fit the grid; servers stop at 19–22).
pub const MAX_ZOOM: u8 = 24;
/// Latitude limit of the Web-Mercator tile grid [deg]: `atan(sinh(π))`.
pub const MERCATOR_MAX_LAT_DEG: f64 = 85.051_128_779_806_59;

/// The public OpenStreetMap tile server's URL template.
pub const OSM_URL: &str = "https://tile.openstreetmap.org/{z}/{x}/{y}.png";
/// Attribution the OpenStreetMap tiles require.
pub const OSM_ATTRIBUTION: &str = "© OpenStreetMap contributors";

/// Where the map's tiles come from (remembered in the console config; `vestnav --tiles SOURCE`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum TileSourceConfig {
    /// The public OpenStreetMap tile server (cached on disk; its policy forbids bulk download).
    #[default]
    Osm,
    /// Any XYZ tile server: `url` with `{z}`, `{x}`, `{y}` (an API key may sit in the query string).
    Xyz {
        /// URL template, e.g. `https://tiles.example.com/{z}/{x}/{y}.png?key=…`.
        url: String,
        /// Attribution text the provider requires, shown on the map.
        attribution: String,
        /// The provider's terms allow bulk/offline download (enables the prefetch).
        allows_bulk: bool,
    },
    /// A local raster PMTiles v3 file.
    PmTiles(PathBuf),
    /// A local raster MBTiles (SQLite) file.
    MbTiles(PathBuf),
    /// A folder of `{z}/{x}/{y}.png` (or `.jpg`, `.webp`) tiles.
    Folder(PathBuf),
}

/// The forms `--tiles` takes, for messages.
pub const TILES_SPEC_FORMS: &str = "osm | xyz:URL-with-{z}{x}{y} | URL-with-{z}{x}{y} | pmtiles:FILE | mbtiles:FILE | folder:DIR | FILE.pmtiles | FILE.mbtiles | DIR";

impl TileSourceConfig {
    /// Short name for the indicator: "OSM", "XYZ tiles.example.com", "PMTiles area.pmtiles".
    pub fn label(&self) -> String {
        let file = |p: &PathBuf| {
            p.file_name().map_or_else(|| p.display().to_string(), |f| f.to_string_lossy().into())
        };
        match self {
            Self::Osm => "OpenStreetMap".into(),
            Self::Xyz { url, .. } => format!("XYZ {}", url_host(url)),
            Self::PmTiles(p) => format!("PMTiles {}", file(p)),
            Self::MbTiles(p) => format!("MBTiles {}", file(p)),
            Self::Folder(p) => format!("folder {}", file(p)),
        }
    }

    /// The attribution to show on the map (a local file's own attribution, when it has one, comes from
    /// the file instead).
    pub fn attribution(&self) -> String {
        match self {
            Self::Osm => OSM_ATTRIBUTION.into(),
            Self::Xyz { attribution, .. } => attribution.clone(),
            Self::PmTiles(_) | Self::MbTiles(_) | Self::Folder(_) => String::new(),
        }
    }

    /// The URL template, for the sources downloaded over HTTP.
    pub fn url_template(&self) -> Option<&str> {
        match self {
            Self::Osm => Some(OSM_URL),
            Self::Xyz { url, .. } => Some(url),
            _ => None,
        }
    }

    /// Whether the area of a route may be downloaded in bulk from this source; `Err` says why not and
    /// where to go instead.
    pub fn bulk_download_allowed(&self) -> Result<(), String> {
        match self {
            Self::Osm => Err("The public OpenStreetMap tile server's usage policy forbids bulk download \
                 (https://operations.osmfoundation.org/policies/tiles/). Use an XYZ source whose terms allow \
                 offline use (a self-hosted tile server, or a provider that permits bulk download), or open a \
                 raster source made offline (see the Tiles window)."
                .into()),
            Self::Xyz { allows_bulk: false, .. } => Err("This XYZ source is not marked as allowing bulk \
                 download. Tick \"terms allow bulk download\" only if the provider's terms permit offline \
                 use (a self-hosted server does)."
                .into()),
            Self::Xyz { url, .. } if is_osm_host(url) => Self::Osm.bulk_download_allowed(),
            Self::Xyz { allows_bulk: true, .. } => Ok(()),
            Self::PmTiles(_) | Self::MbTiles(_) | Self::Folder(_) => {
                Err("This source is a local file: it is already available offline.".into())
            }
        }
    }
}

/// Where raster tiles that work offline come from, for the Tiles window and the CLI's help: every source
/// named here is one the console draws (PNG, JPEG or WebP tiles).
pub const OFFLINE_RASTER_SOURCES: &str = "Raster sources that work offline:\n\
     • an MBTiles file of PNG/JPEG tiles: QGIS \"Generate XYZ tiles (MBTiles)\" from any layer, or \
     `gdal_translate -of MBTILES` then `gdaladdo` from an orthophoto or a scanned map, or this window's \
     prefetch from an XYZ source whose terms allow it;\n\
     • a PMTiles file of raster tiles: `pmtiles convert` of such an MBTiles file;\n\
     • a folder of {z}/{x}/{y}.png tiles: QGIS \"Generate XYZ tiles (Directory)\", or `gdal2tiles.py --xyz`.\n\
     Vector tiles (tilemaker, planetiler, OpenMapTiles: .pbf/MVT) are refused: they hold map data, not \
     pictures, and drawing them needs a style and a renderer the console does not have.";

/// Why vector tiles are refused, said wherever one is met (an MBTiles `format` of `pbf`, a PMTiles of MVT).
pub const VECTOR_TILES_REFUSED: &str = "vector tiles hold map data, not pictures: drawing them needs a \
     style and a renderer the console does not have; use a raster archive (PNG, JPEG or WebP tiles)";

/// Whether `url` points at the public OpenStreetMap tile server (`tile.openstreetmap.org` or one of its
/// `a.`/`b.`/`c.` aliases), whatever the source is called: its policy forbids bulk download.
pub fn is_osm_host(url: &str) -> bool {
    let host = url_host(url).rsplit_once('@').map_or(url_host(url), |(_, h)| h);
    let host = host.split(':').next().unwrap_or(host).trim_end_matches('.').to_ascii_lowercase();
    host == "tile.openstreetmap.org" || host.ends_with(".tile.openstreetmap.org")
}

/// Host part of a URL (no scheme, path, or query: the query may hold an API key).
pub fn url_host(url: &str) -> &str {
    let rest = url.split_once("://").map_or(url, |(_, r)| r);
    rest.split(['/', '?', '#']).next().unwrap_or(rest)
}

/// A URL fit for messages: the query string (where API keys live) replaced by `?…`.
pub fn redact_url(url: &str) -> String {
    match url.split_once('?') {
        Some((base, _)) => format!("{base}?…"),
        None => url.to_owned(),
    }
}

/// Parses a `--tiles` value (see [`TILES_SPEC_FORMS`]). A bare path is a PMTiles or MBTiles file by its
/// extension, or a folder.
pub fn parse_tiles_spec(spec: &str) -> Result<TileSourceConfig, String> {
    let bad = |why: &str| format!("--tiles {spec:?}: {why} (expected {TILES_SPEC_FORMS})");
    let spec_t = spec.trim();
    if spec_t.eq_ignore_ascii_case("osm") {
        return Ok(TileSourceConfig::Osm);
    }
    let xyz = spec_t
        .strip_prefix("xyz:")
        .or_else(|| (spec_t.starts_with("http://") || spec_t.starts_with("https://")).then_some(spec_t));
    if let Some(url) = xyz {
        check_url_template(url).map_err(|e| bad(&e))?;
        return Ok(TileSourceConfig::Xyz {
            url: url.to_owned(),
            attribution: format!("tiles: {}", url_host(url)),
            allows_bulk: false,
        });
    }
    let path_of = |p: &str| if p.is_empty() { Err(bad("missing path")) } else { Ok(PathBuf::from(p)) };
    // A PMTiles/MBTiles path that exists must be a regular file: a FIFO or device is refused here, before
    // anything tries to open it (a missing file is reported when the map opens it).
    let file_of = |p: &str| {
        let p = path_of(p)?;
        refuse_non_regular(&p).map_err(|e| bad(&e.to_string()))?;
        Ok(p)
    };
    if let Some(p) = spec_t.strip_prefix("pmtiles:") {
        return file_of(p).map(TileSourceConfig::PmTiles);
    }
    if let Some(p) = spec_t.strip_prefix("mbtiles:") {
        return file_of(p).map(TileSourceConfig::MbTiles);
    }
    if let Some(p) = spec_t.strip_prefix("folder:") {
        return path_of(p).map(TileSourceConfig::Folder);
    }
    let p = path_of(spec_t)?;
    match p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("pmtiles") => file_of(spec_t).map(TileSourceConfig::PmTiles),
        Some("mbtiles") => file_of(spec_t).map(TileSourceConfig::MbTiles),
        _ if p.is_dir() => Ok(TileSourceConfig::Folder(p)),
        _ => Err(bad("not a known source, a .pmtiles/.mbtiles file or a folder")),
    }
}

/// Checks an XYZ URL template: http(s), and `{z}`, `{x}`, `{y}` each present.
pub fn check_url_template(url: &str) -> Result<(), String> {
    if !(url.starts_with("http://") || url.starts_with("https://")) {
        return Err(format!("{}: the URL must start with http:// or https://", redact_url(url)));
    }
    for p in ["{z}", "{x}", "{y}"] {
        if !url.contains(p) {
            return Err(format!("{}: the URL template lacks {p}", redact_url(url)));
        }
    }
    Ok(())
}

/// One tile of the slippy-map grid, checked to lie on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TileKey {
    /// Zoom level, 0..=[`MAX_ZOOM`].
    pub z: u8,
    /// Column, 0..2^z, eastwards.
    pub x: u32,
    /// Row, 0..2^z, southwards (XYZ order, not TMS).
    pub y: u32,
}

impl TileKey {
    /// The tile, if `z <= MAX_ZOOM` and `x, y < 2^z`.
    pub fn new(z: u8, x: u32, y: u32) -> Option<Self> {
        (z <= MAX_ZOOM && u64::from(x) < (1u64 << z) && u64::from(y) < (1u64 << z)).then_some(Self {
            z,
            x,
            y,
        })
    }

    /// The MBTiles (TMS) row of this tile: `tile_row = 2^z − 1 − y` (MBTiles 1.3 spec: rows count
    /// northwards from the south edge).
    pub fn tms_row(self) -> u32 {
        ((1u64 << self.z) - 1 - u64::from(self.y)) as u32
    }

    /// The ancestor of this tile at `z` (`z <= self.z`), and the part of it this tile covers, in the
    /// ancestor's texture coordinates `[u0, v0, u1, v1]`.
    pub fn ancestor(self, z: u8) -> (Self, [f32; 4]) {
        let dz = self.z.saturating_sub(z);
        let n = 1u32 << dz;
        let parent = Self { z: self.z - dz, x: self.x >> dz, y: self.y >> dz };
        let s = 1.0 / n as f32;
        let (u, v) = ((self.x % n) as f32 * s, (self.y % n) as f32 * s);
        (parent, [u, v, u + s, v + s])
    }

    /// The URL of this tile from an XYZ template (`{z}`, `{x}`, `{y}` replaced; everything else, such as
    /// an API key, kept).
    pub fn url(self, template: &str) -> String {
        template
            .replace("{z}", &self.z.to_string())
            .replace("{x}", &self.x.to_string())
            .replace("{y}", &self.y.to_string())
    }
}

/// The tile column containing longitude `lon_deg` at zoom `z`: `x = ⌊(lon + 180)/360 · 2^z⌋`, clamped to
/// the grid (slippy-map formula).
pub fn tile_x(lon_deg: f64, z: u8) -> u32 {
    let n = f64::from(1u32 << z);
    let x = ((lon_deg + 180.0) / 360.0 * n).floor();
    x.clamp(0.0, n - 1.0) as u32
}

/// The tile row containing latitude `lat_deg` at zoom `z`:
/// `y = ⌊(1 − ln(tan φ + sec φ)/π)/2 · 2^z⌋`, clamped to the grid (slippy-map formula).
pub fn tile_y(lat_deg: f64, z: u8) -> u32 {
    let n = f64::from(1u32 << z);
    let phi = lat_deg.clamp(-MERCATOR_MAX_LAT_DEG, MERCATOR_MAX_LAT_DEG).to_radians();
    let y = ((1.0 - (phi.tan() + 1.0 / phi.cos()).ln() / std::f64::consts::PI) / 2.0 * n).floor();
    y.clamp(0.0, n - 1.0) as u32
}

/// A latitude/longitude box [deg].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BBox {
    /// Southern edge.
    pub min_lat: f64,
    /// Western edge.
    pub min_lon: f64,
    /// Northern edge.
    pub max_lat: f64,
    /// Eastern edge.
    pub max_lon: f64,
}

impl BBox {
    /// The box around `points` (`(lat, lon)`), grown by `margin_m` on every side (1° of latitude taken as
    /// 111 320 m, 1° of longitude as 111 320 m · cos φ at the box's widest latitude), clamped to the
    /// Mercator grid. `None` without points.
    pub fn around(points: impl IntoIterator<Item = (f64, f64)>, margin_m: f64) -> Option<Self> {
        let mut it = points.into_iter().filter(|(a, o)| a.is_finite() && o.is_finite());
        let (a, o) = it.next()?;
        let mut b = Self { min_lat: a, min_lon: o, max_lat: a, max_lon: o };
        for (a, o) in it {
            b.min_lat = b.min_lat.min(a);
            b.max_lat = b.max_lat.max(a);
            b.min_lon = b.min_lon.min(o);
            b.max_lon = b.max_lon.max(o);
        }
        let m = margin_m.max(0.0);
        let dlat = m / 111_320.0;
        let widest = b.min_lat.abs().max(b.max_lat.abs()).min(89.0).to_radians();
        let dlon = m / (111_320.0 * widest.cos());
        Some(Self {
            min_lat: (b.min_lat - dlat).max(-MERCATOR_MAX_LAT_DEG),
            max_lat: (b.max_lat + dlat).min(MERCATOR_MAX_LAT_DEG),
            min_lon: (b.min_lon - dlon).max(-180.0),
            max_lon: (b.max_lon + dlon).min(180.0),
        })
    }

    /// The tiles covering the box at zoom `z`: columns `x0..=x1`, rows `y0..=y1` (north to south).
    pub fn tile_range(&self, z: u8) -> (u32, u32, u32, u32) {
        (tile_x(self.min_lon, z), tile_x(self.max_lon, z), tile_y(self.max_lat, z), tile_y(self.min_lat, z))
    }

    /// How many tiles cover the box over zooms `z0..=z1`.
    pub fn tile_count(&self, z0: u8, z1: u8) -> u64 {
        (z0..=z1.min(MAX_ZOOM))
            .map(|z| {
                let (x0, x1, y0, y1) = self.tile_range(z);
                u64::from(x1 - x0 + 1) * u64::from(y1 - y0 + 1)
            })
            .sum()
    }

    /// The tiles covering the box over zooms `z0..=z1`, at most `limit` of them (`None` when more).
    pub fn tiles(&self, z0: u8, z1: u8, limit: u64) -> Option<Vec<TileKey>> {
        if self.tile_count(z0, z1) > limit {
            return None;
        }
        let mut out = Vec::new();
        for z in z0..=z1.min(MAX_ZOOM) {
            let (x0, x1, y0, y1) = self.tile_range(z);
            for x in x0..=x1 {
                for y in y0..=y1 {
                    out.push(TileKey { z, x, y });
                }
            }
        }
        Some(out)
    }
}

/// Why a tile could not be used. Each names the tile and the file or the (redacted) URL it came from.
/// The variants for which [`TileError::is_refusal`] holds say the tile *exists* but was refused; none
/// of them means "the source has no such tile" (that is `Ok(None)`).
#[derive(Debug, thiserror::Error)]
pub enum TileError {
    /// Reading a file failed.
    #[error("{what}: {source}")]
    Io {
        /// The file.
        what: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A FIFO, device, socket or folder where a tile file (or a PMTiles/MBTiles file) was expected, or
    /// anything but a folder where a tile folder was: never opened, so it never blocks.
    #[error("{what} refused: {why}")]
    NotRegular {
        /// The path.
        what: String,
        /// What it is instead ("a FIFO (named pipe), not a regular file").
        why: String,
    },
    /// The tile is larger than [`MAX_TILE_BYTES`].
    #[error("{what} refused: {bytes} bytes, over the {MAX_TILE_BYTES}-byte limit")]
    TooLarge {
        /// The file or URL.
        what: String,
        /// Its size.
        bytes: u64,
    },
    /// Not a PNG, JPEG or WebP image.
    #[error("{what} refused: not a PNG, JPEG or WebP image")]
    NotAnImage {
        /// The file or URL.
        what: String,
    },
    /// The image's header declares a side over [`MAX_TILE_PX`] (or of 0 px): refused before decoding.
    #[error("{what} refused: {format} declares {width}x{height} px, more than {MAX_TILE_PX} px a side")]
    Oversize {
        /// The file or URL.
        what: String,
        /// "PNG", "JPEG" or "WebP".
        format: &'static str,
        /// Declared width [px].
        width: u32,
        /// Declared height [px].
        height: u32,
    },
    /// The image is broken.
    #[error("{what}: cannot decode the image: {why}")]
    Decode {
        /// The file or URL.
        what: String,
        /// The decoder's reason.
        why: String,
    },
    /// The file is not what it claims to be (bad header, directory, table).
    #[error("{what}: {why}")]
    Corrupt {
        /// The file.
        what: String,
        /// What is wrong.
        why: String,
    },
    /// The server answered with an error or could not be reached.
    #[error("{what}: {why}")]
    Http {
        /// The redacted URL.
        what: String,
        /// What went wrong.
        why: String,
    },
    /// The server could not be reached at all: no answer was had, so nothing is known of the tile.
    #[error("{what}: {cause}")]
    Network {
        /// The redacted URL.
        what: String,
        /// Why the server was not reached.
        cause: NetworkCause,
    },
    /// The server redirected to another host, or from https to http: not followed.
    #[error("{what}: redirected to {to}: not followed ({who} only downloads from the host you named)")]
    Redirected {
        /// The redacted URL asked for.
        what: String,
        /// Where the server pointed (scheme and host; no path or query).
        to: String,
        /// Who refused to follow: "prefetch" or "the map".
        who: &'static str,
    },
}

/// Why a tile server was not reached, told apart so the operator reads the true reason ("offline" only
/// when the name could not even be resolved, never "the server has no tile here").
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NetworkCause {
    /// The server's name did not resolve: this machine is offline or has no DNS.
    #[error("offline: {host} cannot be resolved (no network or no DNS)")]
    Offline {
        /// The server's host name.
        host: String,
    },
    /// The host answered that nothing listens there.
    #[error("{host} refused the connection")]
    Refused {
        /// The server's host (and port).
        host: String,
    },
    /// No route to the host, or no answer in time.
    #[error("{host} is unreachable ({why})")]
    Unreachable {
        /// The server's host (and port).
        host: String,
        /// "no answer within 15 s", "no route to the network", …
        why: String,
    },
    /// Any other transport failure (TLS, a reset connection): the client's words.
    #[error("{host} could not be reached: {why}")]
    Other {
        /// The server's host (and port).
        host: String,
        /// The client's reason.
        why: String,
    },
}

impl TileError {
    /// Whether the tile (or file) exists but was refused as hostile or broken — not a missing tile and
    /// not a failure to reach it.
    pub fn is_refusal(&self) -> bool {
        matches!(
            self,
            Self::NotRegular { .. }
                | Self::TooLarge { .. }
                | Self::NotAnImage { .. }
                | Self::Oversize { .. }
                | Self::Decode { .. }
                | Self::Redirected { .. }
        )
    }
}

/// How a tile is named in messages: `tile z/x/y of SOURCE` (a file, or a redacted URL).
pub fn tile_what(key: TileKey, source: &str) -> String {
    format!("tile {}/{}/{} of {source}", key.z, key.x, key.y)
}

/// Refuses `path` when it exists but is not a regular file (FIFO, device, socket, folder), without
/// opening anything that could block; `Ok` when it is a regular file or does not exist.
pub fn refuse_non_regular(path: &Path) -> Result<(), TileError> {
    match vestnav_files::open_regular(path) {
        Ok(_) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(TileError::from_open(path.display().to_string(), e)),
    }
}

impl TileError {
    /// The error of opening a file with [`vestnav_files::open_regular`] (or reading it with
    /// [`vestnav_files::read_limited`]): "not a regular file" becomes [`TileError::NotRegular`], anything
    /// else [`TileError::Io`].
    pub fn from_open(what: String, e: std::io::Error) -> Self {
        // open_regular says InvalidInput for "not a regular file" and nothing else does.
        if e.kind() == std::io::ErrorKind::InvalidInput {
            Self::NotRegular { what, why: e.to_string() }
        } else {
            Self::Io { what, source: e }
        }
    }
}

/// FNV-1a 64-bit hash of `s`, in hex: a stable cache folder name for a URL template.
pub fn stable_hash(s: &str) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in s.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slippy_map_formulas() {
        // Known tiles: the whole world at z0; Boston's MIT at z17 (lat 42.3601, lon -71.0942).
        assert_eq!((tile_x(0.0, 0), tile_y(0.0, 0)), (0, 0));
        assert_eq!((tile_x(-180.0, 1), tile_x(179.999, 1)), (0, 1));
        assert_eq!((tile_y(85.0, 1), tile_y(-85.0, 1)), (0, 1));
        assert_eq!(tile_x(-71.0942, 17), 39651);
        assert_eq!(tile_y(42.3601, 17), 48479);
        // Out of range latitudes and longitudes clamp to the grid.
        assert_eq!(tile_y(90.0, 3), 0);
        assert_eq!(tile_y(-90.0, 3), 7);
        assert_eq!(tile_x(200.0, 3), 7);
    }

    #[test]
    fn bbox_counts_and_lists_agree() {
        let b = BBox::around([(42.3573, -71.1010), (42.3601, -71.0942)], 100.0).unwrap();
        assert!(b.min_lat < 42.3573 && b.max_lon > -71.0942);
        let tiles = b.tiles(10, 16, 10_000).unwrap();
        assert_eq!(tiles.len() as u64, b.tile_count(10, 16));
        assert!(b.tiles(10, 16, 3).is_none());
        let (x0, x1, y0, y1) = b.tile_range(16);
        assert!(x0 <= x1 && y0 <= y1);
        assert!(BBox::around(std::iter::empty(), 1.0).is_none());
    }

    #[test]
    fn keys_rows_and_urls() {
        assert!(TileKey::new(1, 2, 0).is_none());
        assert!(TileKey::new(25, 0, 0).is_none());
        let k = TileKey::new(3, 5, 1).unwrap();
        assert_eq!(k.tms_row(), 6);
        assert_eq!(TileKey::new(0, 0, 0).unwrap().tms_row(), 0);
        assert_eq!(
            k.url("https://t.example/{z}/{x}/{y}.png?key=S3CRET"),
            "https://t.example/3/5/1.png?key=S3CRET"
        );
        let (p, uv) = k.ancestor(1);
        assert_eq!(p, TileKey { z: 1, x: 1, y: 0 });
        for (a, b) in uv.iter().zip([0.25, 0.25, 0.5, 0.5]) {
            assert!((a - b).abs() < 1e-6);
        }
        assert_eq!(redact_url("https://t.example/{z}?key=S3CRET"), "https://t.example/{z}?…");
        assert_eq!(url_host("https://t.example:8080/{z}/{x}/{y}.png"), "t.example:8080");
    }

    #[test]
    fn tiles_specs() {
        assert_eq!(parse_tiles_spec("osm").unwrap(), TileSourceConfig::Osm);
        let x = parse_tiles_spec("https://t.example/{z}/{x}/{y}.png?k=1").unwrap();
        assert!(
            matches!(x, TileSourceConfig::Xyz { ref url, allows_bulk: false, .. } if url.ends_with("k=1"))
        );
        assert_eq!(parse_tiles_spec("a.pmtiles").unwrap(), TileSourceConfig::PmTiles("a.pmtiles".into()));
        assert_eq!(parse_tiles_spec("mbtiles:b").unwrap(), TileSourceConfig::MbTiles("b".into()));
        assert_eq!(parse_tiles_spec("folder:/t").unwrap(), TileSourceConfig::Folder("/t".into()));
        for bad in ["xyz:https://t.example/{z}/{x}.png", "xyz:ftp://a/{z}/{x}/{y}", "nothing.txt", "pmtiles:"]
        {
            assert!(parse_tiles_spec(bad).unwrap_err().contains("expected"), "{bad}");
        }
    }

    #[test]
    fn bulk_policy() {
        assert!(TileSourceConfig::Osm.bulk_download_allowed().unwrap_err().contains("forbids bulk download"));
        let x = |b| TileSourceConfig::Xyz {
            url: "https://a/{z}/{x}/{y}".into(),
            attribution: String::new(),
            allows_bulk: b,
        };
        assert!(x(false).bulk_download_allowed().is_err());
        assert!(x(true).bulk_download_allowed().is_ok());
        // The OpenStreetMap server under an XYZ name is still the OpenStreetMap server.
        for url in [
            "https://tile.openstreetmap.org/{z}/{x}/{y}.png",
            "https://b.Tile.OpenStreetMap.org:443/{z}/{x}/{y}.png",
        ] {
            let osm =
                TileSourceConfig::Xyz { url: url.into(), attribution: String::new(), allows_bulk: true };
            assert!(osm.bulk_download_allowed().unwrap_err().contains("forbids bulk download"), "{url}");
        }
        assert!(!is_osm_host("https://tile.openstreetmap.org.example.com/{z}/{x}/{y}.png"));
    }
}
