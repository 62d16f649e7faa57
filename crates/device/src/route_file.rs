//! Routes in GPX 1.1 files: waypoints (`<wpt>`), routes (`<rte>`) and tracks (`<trk>`), read and written.
//!
//! This is the one place vestnav reads and writes GPX (the console, `nav simulate` and the GPS simulator
//! all use it). [`parse_gpx`] keeps everything the file held in a [`RouteFile`] and says which kinds it
//! had; [`RouteFile::default_route`] picks what to walk: the first route, else the waypoints, else the first
//! track; a route with a track through its points in order follows that track as its path
//! ([`RouteFile::route_path`]: how a planner's dense footway route travels, [`RouteFile::with_path`]). Every coordinate is checked at this boundary: a non-finite or out-of-range position (latitude in
//! [-90, 90], longitude in [-180, 180) as the GPX 1.1 schema says) is an error naming the point (its element,
//! its number and its line). [`read_gpx`] refuses files over [`MAX_GPX_BYTES`] before reading them.
//!
//! [`to_gpx`] writes GPX 1.1 in the schema's element order (metadata, `wpt`, `rte`, `trk`), with `<ele>` and
//! `<time>` on track points when known; coordinates are written in Rust's shortest round-trip form, so
//! writing then reading gives the same numbers.
//!
//! ```
//! use vestnav_device::route_file::{DEMO_GPX, RouteSource, parse_gpx};
//! let file = parse_gpx(DEMO_GPX).unwrap();
//! let route = file.default_route().unwrap();
//! assert_eq!(route.source, RouteSource::Route(0));
//! assert_eq!(route.waypoints.len(), 7);
//! ```

use std::fmt::Write as _;
use std::io::Read as _;
use std::path::{Path, PathBuf};

use chrono::{DateTime, Utc};
use serde::{Deserialize, Serialize};
use vestnav_core::geo::{Earth, LatLon};
use vestnav_core::guidance::{MAX_PATH_POINTS, RoutePath};

/// The demo route shipped with vestnav (Briggs Field loop, MIT), loaded when nothing else is.
pub const DEMO_GPX: &str = include_str!("../../../assets/routes/demo.gpx");

/// Files larger than this are refused (a 100 000-point track is about 10 MB).
pub const MAX_GPX_BYTES: u64 = 50 * 1024 * 1024;
/// Most route points (`<wpt>` plus `<rtept>`) a GPX file may hold: the bound of a route the console and
/// the station accept, so that every route that reads can be drawn, listed and guided within a frame's
/// budget. Counted before the file is parsed, so a larger file is refused at once.
pub const MAX_ROUTE_POINTS: usize = 10_000;
/// Most track points (`<trkpt>`) a GPX file may hold (a day's walk at 1 Hz is ~36,000).
pub const MAX_TRACK_POINTS: usize = 500_000;

/// A named point the wearer should reach: guidance's own waypoint type (one type from the file to the
/// guidance engine), its arrival radius kept in GPX as a vestnav extension (see [`VESTNAV_GPX_NS`]).
pub use vestnav_core::guidance::Waypoint;

/// The XML namespace of vestnav's GPX extensions: `<extensions><vestnav:arrival_radius_m>` on a `wpt` or
/// `rtept` holds that waypoint's arrival radius in metres. Other readers skip it, as GPX 1.1 intends.
pub const VESTNAV_GPX_NS: &str = "urn:vestnav:gpx:1";

/// A point of a recorded track.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrackPoint {
    /// Latitude [deg].
    pub lat_deg: f64,
    /// Longitude [deg].
    pub lon_deg: f64,
    /// Elevation [m], if known.
    pub ele_m: Option<f64>,
    /// Time of the fix, if known.
    pub time: Option<DateTime<Utc>>,
}

/// A `<rte>`: an ordered list of points to walk.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Route {
    /// Its name, if any.
    pub name: Option<String>,
    /// Its points.
    pub points: Vec<Waypoint>,
}

/// A `<trk>`: a recording, in segments (a new segment after each loss of fix).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Track {
    /// Its name, if any.
    pub name: Option<String>,
    /// Its segments, each a list of points.
    pub segments: Vec<Vec<TrackPoint>>,
}

impl Track {
    /// Every point of every segment, in order.
    pub fn points(&self) -> impl Iterator<Item = &TrackPoint> {
        self.segments.iter().flatten()
    }
}

/// What a GPX file held.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RouteFile {
    /// The file's name (`<metadata><name>`), if any.
    pub name: Option<String>,
    /// Standalone waypoints (`<wpt>`).
    pub waypoints: Vec<Waypoint>,
    /// Routes (`<rte>`).
    pub routes: Vec<Route>,
    /// Tracks (`<trk>`).
    pub tracks: Vec<Track>,
}

/// Where [`RouteFile::default_route`] took its points from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RouteSource {
    /// The route of this index.
    Route(usize),
    /// The standalone waypoints.
    Waypoints,
    /// The track of this index (all segments joined).
    Track(usize),
}

/// The points to walk, chosen by [`RouteFile::default_route`].
#[derive(Debug, Clone, PartialEq)]
pub struct DefaultRoute {
    /// Where they came from.
    pub source: RouteSource,
    /// A name: the route's or track's, else the file's.
    pub name: Option<String>,
    /// The points (track points are named `T1`, `T2`, ...).
    pub waypoints: Vec<Waypoint>,
    /// The path the route follows between its points, when the file has one (see
    /// [`RouteFile::route_path`]).
    pub path: Option<RoutePath>,
}

/// How far a route point may be from the track that is its path [m] (a planner puts them on it; 25 m lets
/// another tool's points sit beside the way they name).
pub const PATH_MATCH_M: f64 = 25.0;

/// Name of the track [`RouteFile::with_path`] writes.
pub const PATH_TRACK_NAME: &str = "path";

impl RouteFile {
    /// A file holding one route that follows `path` (a planner's dense route): the route's points as the
    /// `<rte>`, the path as a `<trk>` named [`PATH_TRACK_NAME`] with one segment, which
    /// [`RouteFile::route_path`] reads back as the route's path.
    pub fn with_path(name: &str, points: Vec<Waypoint>, path: Option<&RoutePath>) -> Self {
        let mut file = Self::from_route(name, points);
        if let Some(p) = path {
            let segment = p
                .points()
                .iter()
                .map(|q| TrackPoint { lat_deg: q.lat_deg, lon_deg: q.lon_deg, ele_m: None, time: None })
                .collect();
            file.tracks.push(Track { name: Some(PATH_TRACK_NAME.to_owned()), segments: vec![segment] });
        }
        file
    }

    /// The path a route of `waypoints` follows: the file's first track with points, when it passes every
    /// route point in order within [`PATH_MATCH_M`] of one of its vertices (a planner's GPX: the route and
    /// the footway path drawn through it; [`RoutePath::along`] finds the vertices). `None` otherwise, and
    /// for a track over [`MAX_PATH_POINTS`] points.
    pub fn route_path(&self, waypoints: &[Waypoint]) -> Option<RoutePath> {
        let track = self.tracks.iter().find(|t| t.points().next().is_some())?;
        if waypoints.is_empty() || track.points().count() > MAX_PATH_POINTS {
            return None;
        }
        let points = track.points().map(|p| LatLon::new(p.lat_deg, p.lon_deg)).collect();
        RoutePath::along(points, waypoints, Earth::Wgs84, PATH_MATCH_M)
    }

    /// A file holding one route.
    pub fn from_route(name: &str, points: Vec<Waypoint>) -> Self {
        Self {
            name: Some(name.to_owned()),
            routes: vec![Route { name: Some(name.to_owned()), points }],
            ..Self::default()
        }
    }

    /// Whether the file held no point at all.
    pub fn is_empty(&self) -> bool {
        self.waypoints.is_empty()
            && self.routes.iter().all(|r| r.points.is_empty())
            && self.tracks.iter().all(|t| t.points().next().is_none())
    }

    /// The points to walk: the first route with points, else the standalone waypoints, else the first
    /// track with points. `None` when the file has no point.
    pub fn default_route(&self) -> Option<DefaultRoute> {
        if let Some((i, r)) = self.routes.iter().enumerate().find(|(_, r)| !r.points.is_empty()) {
            return Some(DefaultRoute {
                source: RouteSource::Route(i),
                name: r.name.clone().or_else(|| self.name.clone()),
                waypoints: r.points.clone(),
                path: self.route_path(&r.points),
            });
        }
        if !self.waypoints.is_empty() {
            return Some(DefaultRoute {
                source: RouteSource::Waypoints,
                name: self.name.clone(),
                waypoints: self.waypoints.clone(),
                path: self.route_path(&self.waypoints),
            });
        }
        let (i, t) = self.tracks.iter().enumerate().find(|(_, t)| t.points().next().is_some())?;
        Some(DefaultRoute {
            source: RouteSource::Track(i),
            name: t.name.clone().or_else(|| self.name.clone()),
            waypoints: t
                .points()
                .enumerate()
                .map(|(k, p)| Waypoint::new(format!("T{}", k + 1), p.lat_deg, p.lon_deg))
                .collect(),
            path: None,
        })
    }
}

/// Errors of GPX text.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GpxError {
    /// The text is not GPX the parser understands.
    #[error("not a readable GPX file: {0}")]
    Syntax(String),
    /// A point with an invalid position (or elevation).
    #[error("{element} #{number}{} {problem}", line.map_or_else(String::new, |l| format!(" (line {l})")))]
    BadPoint {
        /// The element: `wpt`, `rtept` or `trkpt`.
        element: &'static str,
        /// Its number among the file's elements of that name (1-based).
        number: usize,
        /// Its line in the file, when known.
        line: Option<usize>,
        /// What is wrong, e.g. "latitude 99 is outside [-90, 90]".
        problem: String,
    },
    /// More points than a route or a track may have: refused before parsing.
    #[error("{count} {what}: at most {limit} are accepted (split the file, or thin the route out)")]
    TooManyPoints {
        /// Which points.
        what: &'static str,
        /// How many the file holds.
        count: usize,
        /// The limit.
        limit: usize,
    },
}

/// Errors of GPX files: the file's path and what went wrong.
#[derive(Debug, thiserror::Error)]
pub enum RouteFileError {
    /// The file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file is larger than [`MAX_GPX_BYTES`].
    #[error("{}: {bytes} bytes is more than the {limit} bytes a route file may have", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size (at least).
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// The content is not valid GPX.
    #[error("{}: {source}", path.display())]
    Gpx {
        /// The file.
        path: PathBuf,
        /// Why.
        source: GpxError,
    },
}

/// Reads a GPX file of at most [`MAX_GPX_BYTES`].
pub fn read_gpx(path: &Path) -> Result<RouteFile, RouteFileError> {
    read_gpx_limited(path, MAX_GPX_BYTES)
}

/// Reads a GPX file of at most `limit` bytes (checked before reading, and while reading in case the file
/// grows or is not a regular file).
pub fn read_gpx_limited(path: &Path, limit: u64) -> Result<RouteFile, RouteFileError> {
    let io_err = |source| RouteFileError::Io { path: path.to_path_buf(), source };
    let too_large = |bytes| RouteFileError::TooLarge { path: path.to_path_buf(), bytes, limit };
    // A FIFO or device is refused without being opened: reading a hostile path never blocks (the console
    // reads a reference waypoint on its view's thread).
    let file = vestnav_files::open_regular(path).map_err(io_err)?;
    let size = file.metadata().map_err(io_err)?.len();
    if size > limit {
        return Err(too_large(size));
    }
    let mut bytes = Vec::with_capacity(usize::try_from(size).unwrap_or(0));
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes).map_err(io_err)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64));
    }
    parse_gpx_bytes(&bytes).map_err(|source| RouteFileError::Gpx { path: path.to_path_buf(), source })
}

/// Parses GPX text (see the module doc).
pub fn parse_gpx(text: &str) -> Result<RouteFile, GpxError> {
    parse_gpx_bytes(text.as_bytes())
}

/// Deepest element nesting accepted. GPX 1.1 itself nests six levels (`gpx/trk/trkseg/trkpt/extensions/…`);
/// extensions add a few more. The XML parser behind `gpx` takes time quadratic in the depth, so a small
/// file of deeply nested junk would stall the reader: such files are refused before parsing.
pub const MAX_GPX_DEPTH: usize = 64;

/// The deepest element nesting of `bytes`, stopping as soon as it exceeds `limit`: a linear scan of the
/// tags (`<a>` opens, `</a>` closes, `<a/>`, `<?…?>` and `<!…>` do neither).
fn nesting_depth(bytes: &[u8], limit: usize) -> usize {
    let (mut depth, mut deepest) = (0usize, 0usize);
    let mut i = 0;
    while let Some(off) = bytes.get(i..).and_then(|b| b.iter().position(|&c| c == b'<')) {
        let start = i + off;
        let end = bytes.get(start..).and_then(|b| b.iter().position(|&c| c == b'>')).map(|e| start + e);
        let next = bytes.get(start + 1).copied();
        match next {
            Some(b'/') => depth = depth.saturating_sub(1),
            Some(b'?' | b'!') => {}
            _ => {
                let self_closing = end.is_some_and(|e| e > start + 1 && bytes.get(e - 1) == Some(&b'/'));
                if !self_closing {
                    depth += 1;
                    deepest = deepest.max(depth);
                    if deepest > limit {
                        return deepest;
                    }
                }
            }
        }
        let Some(e) = end else { break };
        i = e + 1;
    }
    deepest
}

/// Counts the `<wpt`/`<rtept` and the `<trkpt` start tags of `bytes`: a linear scan, no parse.
fn count_points(bytes: &[u8]) -> (usize, usize) {
    let (mut route, mut track) = (0, 0);
    let mut i = 0;
    while let Some(k) = bytes.get(i..).and_then(|rest| rest.iter().position(|b| *b == b'<')) {
        let tag = bytes.get(i + k + 1..).unwrap_or(&[]);
        let named = |name: &[u8]| {
            tag.starts_with(name)
                && tag.get(name.len()).is_some_and(|c| c.is_ascii_whitespace() || *c == b'>' || *c == b'/')
        };
        if named(b"wpt") || named(b"rtept") {
            route += 1;
        } else if named(b"trkpt") {
            track += 1;
        }
        i += k + 1;
    }
    (route, track)
}

/// Parses GPX bytes (see the module doc).
pub fn parse_gpx_bytes(bytes: &[u8]) -> Result<RouteFile, GpxError> {
    let depth = nesting_depth(bytes, MAX_GPX_DEPTH);
    if depth > MAX_GPX_DEPTH {
        return Err(GpxError::Syntax(format!(
            "elements nested more than {MAX_GPX_DEPTH} deep: not a GPX file this console reads"
        )));
    }
    let (route_points, track_points) = count_points(bytes);
    if route_points > MAX_ROUTE_POINTS {
        return Err(GpxError::TooManyPoints {
            what: "route points (wpt and rtept)",
            count: route_points,
            limit: MAX_ROUTE_POINTS,
        });
    }
    if track_points > MAX_TRACK_POINTS {
        return Err(GpxError::TooManyPoints {
            what: "track points (trkpt)",
            count: track_points,
            limit: MAX_TRACK_POINTS,
        });
    }
    let g = match gpx::read(bytes) {
        Ok(g) => g,
        // The parser refuses out-of-range coordinates without saying which point: find it ourselves.
        Err(e) => {
            return Err(
                find_bad_point(&String::from_utf8_lossy(bytes)).unwrap_or(GpxError::Syntax(e.to_string()))
            );
        }
    };
    let mut counters = [0usize; 3];
    let mut check = |element: usize, w: &gpx::Waypoint| -> Result<(f64, f64), GpxError> {
        counters[element] += 1;
        let p = w.point();
        let (lat, lon) = (p.y(), p.x());
        let problem = coordinate_problem(lat, lon).or_else(|| {
            w.elevation.filter(|e| !e.is_finite()).map(|e| format!("elevation {e} is not a finite number"))
        });
        match problem {
            Some(problem) => Err(GpxError::BadPoint {
                element: ELEMENTS[element],
                number: counters[element],
                line: None,
                problem,
            }),
            None => Ok((lat, lon)),
        }
    };
    let mut to_waypoint = |element: usize, w: &gpx::Waypoint, k: usize| -> Result<Waypoint, GpxError> {
        let (lat_deg, lon_deg) = check(element, w)?;
        let name = w.name.clone().unwrap_or_else(|| format!("WP{}", k + 1));
        Ok(Waypoint::new(name, lat_deg, lon_deg))
    };
    let [wpt_radii, rtept_radii] = arrival_radii(bytes)?;
    let mut waypoints =
        g.waypoints.iter().enumerate().map(|(k, w)| to_waypoint(0, w, k)).collect::<Result<Vec<_>, _>>()?;
    for (w, r) in waypoints.iter_mut().zip(&wpt_radii) {
        w.arrival_radius_m = *r;
    }
    let mut routes = Vec::with_capacity(g.routes.len());
    let mut rtept_radii = rtept_radii.into_iter();
    for r in &g.routes {
        let mut points =
            r.points.iter().enumerate().map(|(k, w)| to_waypoint(1, w, k)).collect::<Result<Vec<_>, _>>()?;
        for p in &mut points {
            p.arrival_radius_m = rtept_radii.next().flatten();
        }
        routes.push(Route { name: r.name.clone(), points });
    }
    let mut tracks = Vec::with_capacity(g.tracks.len());
    for t in &g.tracks {
        let mut segments = Vec::with_capacity(t.segments.len());
        for s in &t.segments {
            let mut points = Vec::with_capacity(s.points.len());
            for w in &s.points {
                let (lat_deg, lon_deg) = check(2, w)?;
                let time = w
                    .time
                    .and_then(|t| t.format().ok())
                    .and_then(|s| DateTime::parse_from_rfc3339(&s).ok())
                    .map(|t| t.with_timezone(&Utc));
                points.push(TrackPoint { lat_deg, lon_deg, ele_m: w.elevation, time });
            }
            segments.push(points);
        }
        tracks.push(Track { name: t.name.clone(), segments });
    }
    Ok(RouteFile { name: g.metadata.and_then(|m| m.name), waypoints, routes, tracks })
}

const ELEMENTS: [&str; 3] = ["wpt", "rtept", "trkpt"];

/// The vestnav arrival radius of every `wpt` and every `rtept` (all routes, in file order), read from
/// their `<extensions>` (the `gpx` crate skips extensions). A file without vestnav's namespace costs no
/// second pass. A radius that is not a positive finite number is an error naming the point.
fn arrival_radii(bytes: &[u8]) -> Result<[Vec<Option<f64>>; 2], GpxError> {
    let mut radii = [Vec::new(), Vec::new()];
    let ns = VESTNAV_GPX_NS.as_bytes();
    if !bytes.windows(ns.len()).any(|w| w == ns) {
        return Ok(radii);
    }
    let mut path: Vec<String> = Vec::new();
    // Which list the innermost open wpt/rtept belongs to, while inside one.
    let mut point: Option<usize> = None;
    let mut text = String::new();
    for event in xml::reader::EventReader::new(bytes) {
        match event.map_err(|e| GpxError::Syntax(e.to_string()))? {
            xml::reader::XmlEvent::StartElement { name, .. } => {
                if let Some(k) = ["wpt", "rtept"].iter().position(|n| *n == name.local_name) {
                    radii[k].push(None);
                    point = Some(k);
                }
                text.clear();
                path.push(if name.namespace.as_deref() == Some(VESTNAV_GPX_NS) {
                    format!("vestnav:{}", name.local_name)
                } else {
                    name.local_name
                });
            }
            xml::reader::XmlEvent::Characters(t) => text.push_str(&t),
            xml::reader::XmlEvent::EndElement { .. } => {
                let closed = path.pop().unwrap_or_default();
                let in_extensions = path.last().is_some_and(|p| p == "extensions");
                if closed == "vestnav:arrival_radius_m"
                    && in_extensions
                    && let Some(k) = point
                {
                    let number = radii[k].len();
                    let r = text.trim().parse::<f64>().ok().filter(|r| r.is_finite() && *r > 0.0);
                    let Some(r) = r else {
                        let shown: String = text.trim().chars().take(40).collect();
                        return Err(GpxError::BadPoint {
                            element: ELEMENTS[k],
                            number,
                            line: None,
                            problem: format!("arrival radius '{shown}' is not a positive number of metres"),
                        });
                    };
                    if let Some(slot) = radii[k].last_mut() {
                        *slot = Some(r);
                    }
                }
                if closed == "wpt" || closed == "rtept" {
                    point = None;
                }
            }
            _ => {}
        }
    }
    Ok(radii)
}

/// What is wrong with a position, by the GPX 1.1 schema: latitude in [-90, 90], longitude in [-180, 180).
fn coordinate_problem(lat: f64, lon: f64) -> Option<String> {
    if !(lat.is_finite() && (-90.0..=90.0).contains(&lat)) {
        return Some(format!("latitude {lat} is outside [-90, 90]"));
    }
    if !(lon.is_finite() && (-180.0..180.0).contains(&lon)) {
        return Some(format!("longitude {lon} is outside [-180, 180)"));
    }
    None
}

/// Scans the text for the first `wpt`/`rtept`/`trkpt` element whose `lat`/`lon` attribute is missing, not
/// a number or out of range. A plain scan of start tags: enough to name the point the XML parser refused.
fn find_bad_point(text: &str) -> Option<GpxError> {
    let mut counters = [0usize; 3];
    let mut line = 1;
    let mut rest = text;
    while let Some(i) = rest.find('<') {
        line += rest[..i].matches('\n').count();
        rest = &rest[i + 1..];
        let Some(element) = ELEMENTS.iter().position(|name| {
            rest.strip_prefix(name)
                .is_some_and(|after| after.starts_with(|c: char| c.is_whitespace() || c == '/' || c == '>'))
        }) else {
            continue;
        };
        counters[element] += 1;
        let tag = &rest[..rest.find('>').unwrap_or(rest.len())];
        let bad = |problem: String| GpxError::BadPoint {
            element: ELEMENTS[element],
            number: counters[element],
            line: Some(line),
            problem,
        };
        let number = |attr: &str| -> Result<f64, GpxError> {
            let v = attribute(tag, attr).ok_or_else(|| bad(format!("has no {attr} attribute")))?;
            v.trim().parse::<f64>().map_err(|_| {
                // Quote at most a few dozen characters: the value itself may be megabytes long.
                let shown: String = v.chars().take(40).collect();
                let more = if v.chars().count() > 40 { "..." } else { "" };
                bad(format!("{attr} '{shown}{more}' is not a number"))
            })
        };
        let problem = match (number("lat"), number("lon")) {
            (Err(e), _) | (_, Err(e)) => return Some(e),
            (Ok(lat), Ok(lon)) => coordinate_problem(lat, lon),
        };
        if let Some(p) = problem {
            return Some(bad(p));
        }
    }
    None
}

/// The value of attribute `name` in a start tag's text (`name="v"` or `name='v'`).
fn attribute<'a>(tag: &'a str, name: &str) -> Option<&'a str> {
    let mut from = 0;
    while let Some(i) = tag[from..].find(name) {
        let at = from + i;
        from = at + name.len();
        let before_ok = tag[..at].ends_with(char::is_whitespace);
        let after = tag[from..].trim_start();
        if !before_ok || !after.starts_with('=') {
            continue;
        }
        let after = after[1..].trim_start();
        let quote = after.chars().next().filter(|c| *c == '"' || *c == '\'')?;
        let value = &after[1..];
        return value.find(quote).map(|end| &value[..end]);
    }
    None
}

/// Writes `file` as GPX 1.1 (see the module doc).
pub fn to_gpx(file: &RouteFile) -> String {
    let mut out = String::with_capacity(
        256 + 96 * (file.waypoints.len() + file.routes.iter().map(|r| r.points.len()).sum::<usize>())
            + 128 * file.tracks.iter().map(|t| t.points().count()).sum::<usize>(),
    );
    out.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    out.push_str(
        "<gpx version=\"1.1\" creator=\"vestnav\" xmlns=\"http://www.topografix.com/GPX/1/1\" \
         xmlns:vestnav=\"urn:vestnav:gpx:1\" \
         xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" \
         xsi:schemaLocation=\"http://www.topografix.com/GPX/1/1 http://www.topografix.com/GPX/1/1/gpx.xsd\">\n",
    );
    if let Some(name) = &file.name {
        let _ = writeln!(out, "  <metadata>\n    <name>{}</name>\n  </metadata>", escape(name));
    }
    let point = |out: &mut String, indent: &str, element: &str, w: &Waypoint| {
        let _ = write!(
            out,
            "{indent}<{element} lat=\"{}\" lon=\"{}\"><name>{}</name>",
            w.lat_deg,
            w.lon_deg,
            escape(&w.name)
        );
        // wptType: extensions come last.
        if let Some(r) = w.arrival_radius_m.filter(|r| r.is_finite() && *r > 0.0) {
            let _ = write!(
                out,
                "<extensions><vestnav:arrival_radius_m>{r}</vestnav:arrival_radius_m></extensions>"
            );
        }
        let _ = writeln!(out, "</{element}>");
    };
    for w in &file.waypoints {
        point(&mut out, "  ", "wpt", w);
    }
    for r in &file.routes {
        out.push_str("  <rte>\n");
        if let Some(name) = &r.name {
            let _ = writeln!(out, "    <name>{}</name>", escape(name));
        }
        for w in &r.points {
            point(&mut out, "    ", "rtept", w);
        }
        out.push_str("  </rte>\n");
    }
    for t in &file.tracks {
        out.push_str("  <trk>\n");
        if let Some(name) = &t.name {
            let _ = writeln!(out, "    <name>{}</name>", escape(name));
        }
        for s in &t.segments {
            out.push_str("    <trkseg>\n");
            for p in s {
                let _ = write!(out, "      <trkpt lat=\"{}\" lon=\"{}\">", p.lat_deg, p.lon_deg);
                // wptType order: ele, then time.
                if let Some(e) = p.ele_m.filter(|e| e.is_finite()) {
                    let _ = write!(out, "<ele>{e}</ele>");
                }
                if let Some(t) = p.time {
                    let _ = write!(
                        out,
                        "<time>{}</time>",
                        t.to_rfc3339_opts(chrono::SecondsFormat::AutoSi, true)
                    );
                }
                out.push_str("</trkpt>\n");
            }
            out.push_str("    </trkseg>\n");
        }
        out.push_str("  </trk>\n");
    }
    out.push_str("</gpx>\n");
    out
}

/// Writes `file` as GPX 1.1 to `path`.
pub fn write_gpx(path: &Path, file: &RouteFile) -> Result<(), RouteFileError> {
    std::fs::write(path, to_gpx(file))
        .map_err(|source| RouteFileError::Io { path: path.to_path_buf(), source })
}

/// XML text/attribute escaping of the five special characters.
fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wp(name: &str, lat_deg: f64, lon_deg: f64) -> Waypoint {
        Waypoint::new(name, lat_deg, lon_deg)
    }

    #[test]
    fn demo_route_loads() {
        let f = parse_gpx(DEMO_GPX).unwrap();
        assert_eq!(f.name.as_deref(), Some("Briggs Field loop"));
        assert!(f.waypoints.is_empty() && f.tracks.is_empty());
        assert_eq!(f.routes.len(), 1);
        let d = f.default_route().unwrap();
        assert_eq!(d.source, RouteSource::Route(0));
        assert_eq!(d.name.as_deref(), Some("Briggs Field loop"));
        assert_eq!(d.waypoints.len(), 7);
        // The values as typed in assets/routes/demo.gpx.
        assert_eq!(d.waypoints[0], wp("Start (SE gate)", 42.35620, -71.10000));
        assert_eq!(d.waypoints[6], wp("Finish (south bench)", 42.35630, -71.10140));
        // And from the file on disk.
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/routes/demo.gpx");
        assert_eq!(read_gpx(&path).unwrap(), f);
    }

    #[test]
    fn everything_round_trips_in_schema_order() {
        let t0 = DateTime::parse_from_rfc3339("2026-11-22T18:00:12.250Z").unwrap().with_timezone(&Utc);
        let file = RouteFile {
            name: Some("A & B <test>".into()),
            waypoints: vec![wp("bench \"north\"", 42.358_4, -71.100_8), wp("gate's", -33.868_82, 151.209_29)],
            routes: vec![
                Route {
                    name: Some("loop".into()),
                    points: vec![wp("a", 0.1 + 0.2, -179.999_999_9), wp("b", 90.0, 0.0)],
                },
                Route { name: None, points: vec![wp("c", -90.0, 1e-7)] },
            ],
            tracks: vec![Track {
                name: Some("walk".into()),
                segments: vec![
                    vec![
                        TrackPoint { lat_deg: 42.1, lon_deg: -71.2, ele_m: Some(12.5), time: Some(t0) },
                        TrackPoint { lat_deg: 42.100_01, lon_deg: -71.200_01, ele_m: None, time: None },
                    ],
                    vec![TrackPoint { lat_deg: 42.2, lon_deg: -71.3, ele_m: Some(-3.25), time: None }],
                ],
            }],
        };
        let text = to_gpx(&file);
        let (w, r, t) = (text.find("<wpt").unwrap(), text.find("<rte").unwrap(), text.find("<trk").unwrap());
        assert!(w < r && r < t, "element order wpt, rte, trk");
        assert!(text.contains("<ele>12.5</ele><time>2026-11-22T18:00:12.250Z</time>"), "{text}");
        assert_eq!(parse_gpx(&text).unwrap(), file);
        // Through a file too.
        let path = std::env::temp_dir().join(format!("vestnav-route-rt-{}.gpx", std::process::id()));
        write_gpx(&path, &file).unwrap();
        assert_eq!(read_gpx(&path).unwrap(), file);
        std::fs::remove_file(&path).unwrap();
    }

    /// vestnav's extension carries each waypoint's arrival radius through a write and a read; a GPX file
    /// from another program with its own extensions reads as before, and a bad radius names the point.
    #[test]
    fn arrival_radii_round_trip_as_a_gpx_extension() {
        let mut file = RouteFile::from_route("r", vec![wp("a", 1.0, 2.0), wp("b", 3.0, 4.0)]);
        file.routes[0].points[1].arrival_radius_m = Some(12.5);
        file.waypoints = vec![Waypoint { arrival_radius_m: Some(3.0), ..wp("w", 5.0, 6.0) }];
        let text = to_gpx(&file);
        assert!(text.contains("<vestnav:arrival_radius_m>12.5</vestnav:arrival_radius_m>"), "{text}");
        assert_eq!(parse_gpx(&text).unwrap(), file);
        let foreign = "<?xml version=\"1.0\"?><gpx version=\"1.1\" creator=\"x\" xmlns:o=\"urn:other\">\
            <rte><rtept lat=\"1\" lon=\"2\"><extensions><o:arrival_radius_m>9</o:arrival_radius_m></extensions>\
            </rtept></rte></gpx>";
        assert_eq!(parse_gpx(foreign).unwrap().routes[0].points[0].arrival_radius_m, None);
        let bad = text.replace(">12.5<", ">-4<");
        let e = parse_gpx(&bad).unwrap_err();
        assert!(e.to_string().contains("rtept #2") && e.to_string().contains("arrival radius"), "{e}");
    }

    #[test]
    fn default_route_prefers_routes_then_waypoints_then_the_first_track() {
        let track = Track {
            name: Some("rec".into()),
            segments: vec![
                vec![TrackPoint { lat_deg: 1.0, lon_deg: 2.0, ele_m: None, time: None }],
                vec![TrackPoint { lat_deg: 3.0, lon_deg: 4.0, ele_m: None, time: None }],
            ],
        };
        let mut f = RouteFile {
            name: Some("file".into()),
            waypoints: vec![wp("w", 5.0, 6.0)],
            routes: vec![Route::default(), Route { name: None, points: vec![wp("r", 7.0, 8.0)] }],
            tracks: vec![Track::default(), track],
        };
        let d = f.default_route().unwrap();
        assert_eq!(
            (d.source, d.name.as_deref(), d.waypoints.len()),
            (RouteSource::Route(1), Some("file"), 1)
        );
        f.routes.clear();
        assert_eq!(f.default_route().unwrap().source, RouteSource::Waypoints);
        f.waypoints.clear();
        let d = f.default_route().unwrap();
        assert_eq!(d.source, RouteSource::Track(1));
        assert_eq!(d.name.as_deref(), Some("rec"));
        assert_eq!(d.waypoints, vec![wp("T1", 1.0, 2.0), wp("T2", 3.0, 4.0)]);
        f.tracks.clear();
        assert!(f.is_empty() && f.default_route().is_none());
    }

    #[test]
    fn invalid_points_are_errors_naming_the_point() {
        let doc = |body: &str| {
            format!("<?xml version=\"1.0\"?>\n<gpx version=\"1.1\" creator=\"t\">\n{body}\n</gpx>")
        };
        let e = parse_gpx(&doc("<rte>\n<rtept lat=\"42\" lon=\"-71\"/>\n<rtept lat=\"42\" lon=\"-71\"/>\n<rtept lat=\"99\" lon=\"0\"/></rte>"))
            .unwrap_err();
        assert!(matches!(&e, GpxError::BadPoint { element: "rtept", number: 3, line: Some(6), .. }), "{e:?}");
        assert!(e.to_string().contains("latitude 99"), "{e}");
        let e = parse_gpx(&doc("<wpt lat='1' lon='NaN'/>")).unwrap_err();
        assert!(matches!(&e, GpxError::BadPoint { element: "wpt", number: 1, .. }), "{e:?}");
        let e = parse_gpx(&doc("<trk><trkseg><trkpt lat=\"1\" lon=\"200\"/></trkseg></trk>")).unwrap_err();
        assert!(e.to_string().contains("trkpt #1 (line 3) longitude 200"), "{e}");
        let e = parse_gpx(&doc("<wpt lat=\"inf\" lon=\"0\"/>")).unwrap_err();
        assert!(matches!(&e, GpxError::BadPoint { element: "wpt", .. }), "{e:?}");
        assert!(matches!(parse_gpx("garbage"), Err(GpxError::Syntax(_))));
        assert!(matches!(parse_gpx(""), Err(GpxError::Syntax(_))));
    }

    #[test]
    fn routes_over_the_point_limit_are_refused_before_parsing() {
        let mut text = String::from("<gpx version=\"1.1\" creator=\"t\"><rte>");
        for k in 0..=MAX_ROUTE_POINTS {
            text.push_str("<rtept lat=\"42.");
            text.push_str(&k.to_string());
            text.push_str("\" lon=\"-71\"/>");
        }
        text.push_str("</rte></gpx>");
        let e = parse_gpx(&text).unwrap_err();
        assert!(
            matches!(e, GpxError::TooManyPoints { count, limit: MAX_ROUTE_POINTS, .. } if count == MAX_ROUTE_POINTS + 1),
            "{e}"
        );
        // Names that only start like a point's are not counted.
        assert_eq!(count_points(b"<wpt lat='1' lon='1'/><rteptx/><trkpt a='1'><trkpt>"), (1, 2));
    }

    #[test]
    fn files_over_the_limit_are_refused_before_parsing() {
        let path = std::env::temp_dir().join(format!("vestnav-route-big-{}.gpx", std::process::id()));
        std::fs::write(&path, DEMO_GPX).unwrap();
        let e = read_gpx_limited(&path, 100).unwrap_err();
        assert!(
            matches!(e, RouteFileError::TooLarge { bytes, limit: 100, .. } if bytes == DEMO_GPX.len() as u64)
        );
        assert!(e.to_string().contains("vestnav-route-big"), "{e}");
        assert!(read_gpx_limited(&path, DEMO_GPX.len() as u64).is_ok());
        std::fs::remove_file(&path).unwrap();
        let e = read_gpx(&path).unwrap_err();
        assert!(matches!(e, RouteFileError::Io { .. }) && e.to_string().contains("vestnav-route-big"));
    }

    #[test]
    fn a_route_with_its_path_round_trips_and_a_track_elsewhere_is_no_path() {
        // A path of 11 vertices 50 m apart eastward; the route's points on vertices 0, 4 and 10.
        let e = Earth::Wgs84;
        let o = LatLon::new(60.17, 24.94);
        let pts: Vec<LatLon> = (0..=10).map(|i| e.direct(o, 90.0, 50.0 * f64::from(i))).collect();
        let wps: Vec<Waypoint> = [0, 4, 10].iter().map(|&i| Waypoint::at(format!("V{i}"), pts[i])).collect();
        let path = RoutePath::new(pts.clone(), vec![0, 4, 10]).unwrap();
        let text = to_gpx(&RouteFile::with_path("walk", wps.clone(), Some(&path)));
        let back = parse_gpx(&text).unwrap().default_route().unwrap();
        assert_eq!(back.waypoints, wps);
        assert_eq!(back.path.as_ref(), Some(&path));
        // A recorded track that does not pass the route's points is not its path.
        let far: Vec<Waypoint> =
            wps.iter().map(|w| Waypoint::at(&w.name, e.direct(w.pos(), 0.0, 60.0))).collect();
        let text = to_gpx(&RouteFile::with_path("walk", far, Some(&path)));
        assert_eq!(parse_gpx(&text).unwrap().default_route().unwrap().path, None);
    }
}
