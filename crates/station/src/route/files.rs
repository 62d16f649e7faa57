//! The route's files: GPX read and written through `vestnav_device::route_file` (the one home of the
//! format), `GeoJSON` export, and the route autosave.
//!
//! The route autosave ([`Autosave`]): the route being edited (name, waypoints, next waypoint) is written
//! as GPX through `route_file` whenever it changes, atomically (a temp file, then a rename), and read back
//! at start-up ([`read_autosave`]).
//!
//! Exports ([`export_gpx`], [`export_geojson`]) replace an existing file only when told to (`replace`: the
//! operator answered "Replace X?"); otherwise it is refused with a message naming it. GPX has one `<trkseg>` per track segment of the map (a new segment after a GPS source
//! change or an implausible jump); `GeoJSON` (RFC 7946, for QGIS) has the route as a `LineString`, each waypoint
//! as a `Point` and the track as a `MultiLineString` of its segments, positions as `[lon, lat]`.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use vestnav_core::guidance::RoutePath;
use vestnav_device::route_file::{self, RouteFile, Track, TrackPoint};

use super::RouteModel;
use crate::{Notices, RouteStart, Severity, Subject};

pub use vestnav_device::route_file::{DEMO_GPX, Waypoint};

/// What the console takes from a GPX file: the route to guide along (its first route, else its
/// waypoints, else its first track), and every track point for the replayed track.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GpxContent {
    /// Route name, if any.
    pub name: Option<String>,
    /// The route's points.
    pub waypoints: Vec<Waypoint>,
    /// Track points of every track and segment, as `(lat_deg, lon_deg)`.
    pub track: Vec<(f64, f64)>,
    /// The path the route follows between its points (a planner's GPX: a track through them in order).
    pub path: Option<RoutePath>,
}

impl GpxContent {
    fn from_file(file: &RouteFile) -> Self {
        let route = file.default_route();
        Self {
            name: route.as_ref().and_then(|r| r.name.clone()).or_else(|| file.name.clone()),
            path: route.as_ref().and_then(|r| r.path.clone()),
            waypoints: route.map(|r| r.waypoints).unwrap_or_default(),
            track: file.tracks.iter().flat_map(Track::points).map(|p| (p.lat_deg, p.lon_deg)).collect(),
        }
    }
}

/// Parses GPX text (see [`GpxContent`]); errors name the bad point.
pub fn parse_gpx(text: &str) -> Result<GpxContent, String> {
    route_file::parse_gpx(text).map(|f| GpxContent::from_file(&f)).map_err(|e| e.to_string())
}

/// Reads a GPX file (size-limited); errors name the file.
pub fn read_gpx(path: &Path) -> Result<GpxContent, String> {
    route_file::read_gpx(path).map(|f| GpxContent::from_file(&f)).map_err(|e| e.to_string())
}

/// The route and the track (one `<trkseg>` per non-empty segment; each point with the `<ele>` and `<time>`
/// it has) as a GPX file.
pub fn to_route_file(name: &str, waypoints: &[Waypoint], segments: &[&[TrackPoint]]) -> RouteFile {
    let mut file = RouteFile::from_route(name, waypoints.to_vec());
    let segments: Vec<Vec<TrackPoint>> =
        segments.iter().filter(|s| !s.is_empty()).map(|s| s.to_vec()).collect();
    if !segments.is_empty() {
        file.tracks.push(Track { name: Some(format!("{name} track")), segments });
    }
    file
}

/// GPX 1.1 text of the route and the track's segments.
pub fn write_gpx(name: &str, waypoints: &[Waypoint], segments: &[&[TrackPoint]]) -> Result<String, String> {
    Ok(route_file::to_gpx(&to_route_file(name, waypoints, segments)))
}

/// A `GeoJSON` position (RFC 7946 §3.1.1): longitude first.
fn position(lat_deg: f64, lon_deg: f64) -> serde_json::Value {
    serde_json::json!([lon_deg, lat_deg])
}

/// The route and track as a `GeoJSON` `FeatureCollection` (RFC 7946): the route as a `LineString` (when it
/// has two points or more), each waypoint as a `Point` (`name`, 1-based `index`), and the track as one
/// `MultiLineString` with a line per segment (segments of one point are left out: a line needs two). Every
/// feature has a `kind` property: `route`, `waypoint` or `track`. A track point's elevation becomes its
/// position's third value (RFC 7946 §3.1.1) when every point of the track has one; the points' times go in
/// the track's `coordTimes` property (ISO 8601 UTC, `null` where unknown; one array per line, the
/// convention of GPX-to-GeoJSON converters such as Mapbox's `togeojson`), present when any point has one.
pub fn geojson(name: &str, waypoints: &[Waypoint], segments: &[&[TrackPoint]]) -> serde_json::Value {
    let mut features = Vec::new();
    if waypoints.len() >= 2 {
        features.push(serde_json::json!({
            "type": "Feature",
            "properties": { "kind": "route", "name": name },
            "geometry": {
                "type": "LineString",
                "coordinates": waypoints.iter().map(|w| position(w.lat_deg, w.lon_deg)).collect::<Vec<_>>(),
            },
        }));
    }
    for (k, w) in waypoints.iter().enumerate() {
        features.push(serde_json::json!({
            "type": "Feature",
            "properties": { "kind": "waypoint", "name": w.name, "index": k + 1 },
            "geometry": { "type": "Point", "coordinates": position(w.lat_deg, w.lon_deg) },
        }));
    }
    let drawn: Vec<&[TrackPoint]> = segments.iter().copied().filter(|s| s.len() >= 2).collect();
    let with_ele = drawn.iter().flat_map(|s| s.iter()).all(|p| p.ele_m.is_some());
    let lines: Vec<Vec<serde_json::Value>> = drawn
        .iter()
        .map(|s| {
            s.iter()
                .map(|p| match p.ele_m {
                    Some(ele) if with_ele => serde_json::json!([p.lon_deg, p.lat_deg, ele]),
                    _ => position(p.lat_deg, p.lon_deg),
                })
                .collect()
        })
        .collect();
    if !lines.is_empty() {
        let mut properties = serde_json::json!({ "kind": "track", "name": format!("{name} track") });
        if drawn.iter().flat_map(|s| s.iter()).any(|p| p.time.is_some()) {
            let times: Vec<Vec<Option<String>>> = drawn
                .iter()
                .map(|s| {
                    s.iter()
                        .map(|p| p.time.map(|t| t.to_rfc3339_opts(chrono::SecondsFormat::AutoSi, true)))
                        .collect()
                })
                .collect();
            properties["coordTimes"] = serde_json::json!(times);
        }
        features.push(serde_json::json!({
            "type": "Feature",
            "properties": properties,
            "geometry": { "type": "MultiLineString", "coordinates": lines },
        }));
    }
    serde_json::json!({ "type": "FeatureCollection", "name": name, "features": features })
}

/// `GeoJSON` text of the route and track (see [`geojson`]).
pub fn to_geojson(name: &str, waypoints: &[Waypoint], segments: &[&[TrackPoint]]) -> Result<String, String> {
    serde_json::to_string_pretty(&geojson(name, waypoints, segments))
        .map_err(|e| format!("cannot encode GeoJSON: {e}"))
}

/// Writes `text` to a new file at `path` ([`vestnav_files::write_new`]: all of it or nothing): an existing
/// file is never replaced (the error names it), even one that appears while it is written.
pub fn write_new(path: &Path, text: &str) -> Result<(), String> {
    vestnav_files::write_new(path, text.as_bytes()).map_err(|e| {
        if e.kind() == std::io::ErrorKind::AlreadyExists {
            format!(
                "{} already exists: not overwritten (type another name, or delete the file first)",
                path.display()
            )
        } else {
            format!("cannot write {}: {e}", path.display())
        }
    })
}

/// Writes `text` to `path`: atomically over an existing file when `replace`, else only as a new file
/// ([`write_new`]).
pub fn write_export(path: &Path, text: &str, replace: bool) -> Result<(), String> {
    if replace { write_atomically(path, text) } else { write_new(path, text) }
}

/// Exports the route and track as GPX to `path` (an existing file only when `replace`); returns what was
/// written.
pub fn export_gpx(
    path: &Path,
    name: &str,
    waypoints: &[Waypoint],
    segments: &[&[TrackPoint]],
    replace: bool,
) -> Result<String, String> {
    if path.as_os_str().is_empty() {
        return Err("type a file path first".to_owned());
    }
    write_export(path, &write_gpx(name, waypoints, segments)?, replace)?;
    Ok(format!(
        "wrote {} waypoints and {} track points in {} segments to {}",
        waypoints.len(),
        segments.iter().map(|s| s.len()).sum::<usize>(),
        segments.iter().filter(|s| !s.is_empty()).count(),
        path.display()
    ))
}

/// The `GeoJSON` file for a typed path: its extension replaced by `.geojson`.
pub fn geojson_path(path: &Path) -> PathBuf {
    path.with_extension("geojson")
}

/// Exports the route and track as `GeoJSON` to [`geojson_path`] of `path` (an existing file only when
/// `replace`); returns what was written.
pub fn export_geojson(
    path: &Path,
    name: &str,
    waypoints: &[Waypoint],
    segments: &[&[TrackPoint]],
    replace: bool,
) -> Result<String, String> {
    if path.as_os_str().is_empty() {
        return Err("type a file path first".to_owned());
    }
    let path = geojson_path(path);
    write_export(&path, &to_geojson(name, waypoints, segments)?, replace)?;
    Ok(format!("wrote {} waypoints and the track as GeoJSON to {}", waypoints.len(), path.display()))
}

/// The route as the operator edits it: what the autosave keeps and an undo step restores.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RouteState {
    /// Route name.
    pub name: String,
    /// The waypoints, in order.
    pub waypoints: Vec<Waypoint>,
    /// Index of the next waypoint (`waypoints.len()`: the route is finished).
    pub next: usize,
    /// The path between the waypoints, when the route was planned along paths (one vertex per waypoint).
    pub path: Option<RoutePath>,
}

impl RouteState {
    /// Whether this is the route `name`, `waypoints`, `next`, `path` (compared without cloning them).
    pub fn is(&self, name: &str, waypoints: &[Waypoint], next: usize, path: Option<&RoutePath>) -> bool {
        self.next == next && self.name == name && self.waypoints == waypoints && self.path.as_ref() == path
    }
}

/// File name of the route autosave in the data directory.
pub const AUTOSAVE_FILE: &str = "route-autosave.gpx";

/// What the autosave's file-level `<metadata><name>` starts with; the next waypoint's index follows.
const AUTOSAVE_NEXT_PREFIX: &str = "vestnav route autosave; next=";

/// The autosave's GPX text: the route as the file's one `<rte>` (its path, if any, as a `<trk>`:
/// `RouteFile::with_path`), the next waypoint's index in the file's `<metadata><name>` (GPX has no element
/// for it, and `route_file` is the one home of the format).
pub fn autosave_gpx(state: &RouteState) -> String {
    let mut file = RouteFile::with_path(&state.name, state.waypoints.clone(), state.path.as_ref());
    file.name = Some(format!("{AUTOSAVE_NEXT_PREFIX}{}", state.next));
    route_file::to_gpx(&file)
}

/// The route kept in autosave GPX text (see [`autosave_gpx`]); a plain GPX file is taken as well (its
/// default route, next = 0).
pub fn parse_autosave(text: &str) -> Result<RouteState, String> {
    route_file::parse_gpx(text).map(|f| autosave_state(&f)).map_err(|e| e.to_string())
}

fn autosave_state(file: &RouteFile) -> RouteState {
    let (name, waypoints) = match file.routes.first() {
        Some(r) => (r.name.clone(), r.points.clone()),
        None => file.default_route().map_or((None, Vec::new()), |r| (r.name, r.waypoints)),
    };
    let next = file
        .name
        .as_deref()
        .and_then(|n| n.strip_prefix(AUTOSAVE_NEXT_PREFIX))
        .and_then(|n| n.trim().parse::<usize>().ok())
        .unwrap_or(0)
        .min(waypoints.len());
    let path = file.route_path(&waypoints);
    RouteState { name: name.unwrap_or_else(|| "route".to_owned()), waypoints, next, path }
}

/// Reads the autosave at `path`: `Ok(None)` when there is none, an error naming the file when it cannot
/// be read or is not GPX.
pub fn read_autosave(path: &Path) -> Result<Option<RouteState>, String> {
    match route_file::read_gpx(path) {
        Ok(f) => Ok(Some(autosave_state(&f))),
        Err(route_file::RouteFileError::Io { source, .. })
            if source.kind() == std::io::ErrorKind::NotFound =>
        {
            Ok(None)
        }
        Err(e) => Err(e.to_string()),
    }
}

/// Writes `text` to `path` atomically (`vestnav_files::write_atomic`: a unique temp file beside it,
/// flushed to disk, renamed over it), so a crash leaves the old file or the new one, never half of one.
/// Errors name the file.
pub fn write_atomically(path: &Path, text: &str) -> Result<(), String> {
    vestnav_files::write_atomic(path, text.as_bytes())
        .map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// Shortest time between two autosave writes: a waypoint dragged across the map changes the route every
/// frame, and one write per frame is wasted work (the last change is written at most this much later,
/// and at once on exit).
pub const AUTOSAVE_MIN_INTERVAL: Duration = Duration::from_millis(500);

/// The route autosave: remembers what is on disk and writes the route when it differs.
#[derive(Debug)]
pub struct Autosave {
    path: PathBuf,
    saved: RouteState,
    last_attempt: Option<Instant>,
    last_error: Option<String>,
}

impl Autosave {
    /// An autosave to `path` whose file holds (or stands for) `saved`: nothing is written until the
    /// route differs from it.
    pub fn new(path: PathBuf, saved: RouteState) -> Self {
        Self { path, saved, last_attempt: None, last_error: None }
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes the route when it differs from the file, at most once per [`AUTOSAVE_MIN_INTERVAL`] unless
    /// `now_or_never` (exit). Returns a new error (each distinct failure once, for the operator).
    pub fn poll(&mut self, route: &super::RouteModel, now: Instant, now_or_never: bool) -> Option<String> {
        if route.is(&self.saved) {
            return None;
        }
        if !now_or_never && self.last_attempt.is_some_and(|t| now.duration_since(t) < AUTOSAVE_MIN_INTERVAL) {
            return None;
        }
        self.last_attempt = Some(now);
        let state = route.state();
        let written = vestnav_files::ensure_parent(&self.path)
            .map_err(|e| format!("cannot create the folder of {}: {e}", self.path.display()))
            .and_then(|()| write_atomically(&self.path, &autosave_gpx(&state)));
        match written {
            Ok(()) => {
                self.saved = state;
                self.last_error = None;
                None
            }
            Err(e) if self.last_error.as_ref() == Some(&e) => None,
            Err(e) => {
                self.last_error = Some(e.clone());
                Some(format!("route autosave failed: {e}"))
            }
        }
    }
}

/// Loads the route the station starts with: the file named, else the autosave, else the demo route. An
/// unreadable autosave is kept aside (`….corrupt-<time>`, so the next autosave does not overwrite what may be
/// worth rescuing) and a notice names it.
pub(crate) fn load_start(start: &RouteStart, notices: &mut Notices) -> (RouteModel, Option<Autosave>) {
    let mut restored = None;
    if start.file.is_none()
        && let Some(path) = &start.autosave
    {
        match read_autosave(path) {
            Ok(state) => restored = state,
            Err(e) => {
                let kept = match vestnav_files::keep_aside(path) {
                    Ok(p) => format!("it was kept as {}", p.display()),
                    Err(_) => {
                        "it could not be moved aside and will be overwritten by the next autosave".to_owned()
                    }
                };
                notices.raise(
                    Severity::Alarm,
                    Subject::Route,
                    format!(
                        "Route autosave {} is unreadable ({e}); started with the default route, {kept}.",
                        path.display()
                    ),
                );
            }
        }
    }
    let state = restored.unwrap_or_else(|| {
        let content = match &start.file {
            Some(path) => read_gpx(path),
            None => parse_gpx(DEMO_GPX).map_err(|e| format!("demo route: {e}")),
        };
        match content {
            Ok(c) => RouteState {
                name: c.name.unwrap_or_else(|| "route".into()),
                waypoints: c.waypoints,
                next: 0,
                path: c.path,
            },
            Err(e) => {
                notices.raise(Severity::Alarm, Subject::Route, format!("route unreadable: {e}"));
                RouteState { name: "route".into(), ..RouteState::default() }
            }
        }
    });
    if let Err(e) = RouteModel::check_len(state.waypoints.len()) {
        notices.raise(Severity::Alarm, Subject::Route, format!("route not loaded: {e}"));
    }
    let ok = RouteModel::check_len(state.waypoints.len()).is_ok();
    let model = if ok { RouteModel::new(state) } else { RouteModel::default() };
    let autosave = start.autosave.clone().map(|p| Autosave::new(p, model.state()));
    (model, autosave)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demo_route_loads_and_round_trips() {
        let c = parse_gpx(DEMO_GPX).unwrap();
        assert_eq!(c.waypoints.len(), 7);
        assert_eq!(c.waypoints[0].name, "Start (SE gate)");
        let text = write_gpx("demo", &c.waypoints, &[&pts(&[(42.0, -71.0), (42.1, -71.1)])]).unwrap();
        let back = parse_gpx(&text).unwrap();
        assert_eq!(back.waypoints, c.waypoints);
        assert_eq!(back.track, vec![(42.0, -71.0), (42.1, -71.1)]);
        assert!(parse_gpx("<gpx><rte><rtept lat=\"99\" lon=\"0\"/></rte></gpx>").is_err());
        assert!(parse_gpx("garbage").is_err());
        let missing = read_gpx(Path::new("/nonexistent/route.gpx")).unwrap_err();
        assert!(missing.contains("/nonexistent/route.gpx"), "{missing}");
    }

    #[test]
    fn the_autosave_round_trips_with_the_next_waypoint() {
        let dir = std::env::temp_dir().join(format!("vestnav-autosave-{}", std::process::id()));
        let path = dir.join(AUTOSAVE_FILE);
        assert_eq!(read_autosave(&path), Ok(None));
        let state = RouteState {
            name: "Loop & back".into(),
            waypoints: vec![
                Waypoint { name: "A".into(), lat_deg: 42.1, lon_deg: -71.2, arrival_radius_m: None },
                Waypoint {
                    name: "B <2>".into(),
                    lat_deg: -0.000_001,
                    lon_deg: 179.9,
                    arrival_radius_m: None,
                },
            ],
            next: 1,
            path: None,
        };
        let model = |s: &RouteState| super::super::RouteModel::new(s.clone());
        let mut a = Autosave::new(path.clone(), RouteState::default());
        let t0 = Instant::now();
        assert_eq!(a.poll(&model(&state), t0, false), None);
        assert_eq!(read_autosave(&path), Ok(Some(state.clone())));
        // A change right after a write waits for the interval, unless it is the exit's.
        let first = RouteState { next: 0, ..state.clone() };
        a.poll(&model(&first), t0, false);
        assert_eq!(read_autosave(&path).unwrap().unwrap().next, 1);
        a.poll(&model(&first), t0, true);
        assert_eq!(read_autosave(&path).unwrap().unwrap().next, 0);
        // An empty route stays empty, with its name.
        a.poll(&model(&RouteState { name: "empty".into(), ..RouteState::default() }), t0, true);
        assert_eq!(
            read_autosave(&path),
            Ok(Some(RouteState { name: "empty".into(), ..RouteState::default() }))
        );
        std::fs::write(&path, "<gpx><rte><rtept lat=\"1\"").unwrap();
        let e = read_autosave(&path).unwrap_err();
        assert!(e.contains(&path.display().to_string()), "{e}");
        // A plain GPX file is a route too.
        assert_eq!(parse_autosave(DEMO_GPX).unwrap().waypoints.len(), 7);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    type Line = Vec<(f64, f64)>;

    /// Track points without time or elevation.
    fn pts(line: &[(f64, f64)]) -> Vec<TrackPoint> {
        line.iter()
            .map(|&(lat_deg, lon_deg)| TrackPoint { lat_deg, lon_deg, ele_m: None, time: None })
            .collect()
    }

    fn segs() -> (Line, Line) {
        (
            vec![(42.3571, -71.1012), (42.35712, -71.10118), (42.35715, -71.10114)],
            vec![(-33.868_82, 151.209_29), (-33.868_9, 151.2094)],
        )
    }

    /// Issue 15: GPX export has one `<trkseg>` per map segment, read back by `route_file`'s reader.
    #[test]
    fn gpx_export_keeps_the_segments_and_refuses_to_overwrite() {
        let dir = std::env::temp_dir().join(format!("vestnav-route-export-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("walk.gpx");
        let wps = vec![Waypoint { name: "A".into(), lat_deg: 42.1, lon_deg: -71.2, arrival_radius_m: None }];
        let (a, b) = segs();
        // The first segment's points carry the fix's time and altitude: GPX 1.1 writes them as <ele>, then
        // <time> (wptType's sequence).
        let t0 = chrono::DateTime::parse_from_rfc3339("2026-05-01T14:03:07.2Z").unwrap().to_utc();
        let mut timed = pts(&a);
        for (k, p) in (0i32..).zip(timed.iter_mut()) {
            p.time = Some(t0 + chrono::Duration::seconds(i64::from(k)));
            p.ele_m = Some(12.5 + f64::from(k));
        }
        let msg = export_gpx(&path, "walk", &wps, &[&timed, &pts(&b)], false).unwrap();
        assert!(msg.contains("2 segments"), "{msg}");
        let back = route_file::read_gpx(&path).unwrap();
        let got: Vec<Vec<(f64, f64)>> = back.tracks[0]
            .segments
            .iter()
            .map(|s| s.iter().map(|p| (p.lat_deg, p.lon_deg)).collect())
            .collect();
        assert_eq!(got, vec![a.clone(), b.clone()]);
        assert_eq!(back.tracks[0].segments[0], timed, "time and elevation come back");
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("<ele>12.5</ele><time>2026-05-01T14:03:07.200Z</time>"), "{text}");
        assert!(text.find("<rte>").unwrap() < text.find("<trk>").unwrap(), "GPX 1.1 order: wpt, rte, trk");
        assert_eq!(back.routes[0].points, wps);
        let before = std::fs::read(&path).unwrap();
        let e = export_gpx(&path, "other", &[], &[&pts(&b)], false).unwrap_err();
        assert!(e.contains(&path.display().to_string()) && e.contains("not overwritten"), "{e}");
        assert_eq!(std::fs::read(&path).unwrap(), before, "the file is untouched");
        // Replacing, once the operator said so.
        export_gpx(&path, "other", &[], &[&pts(&b)], true).unwrap();
        assert_eq!(route_file::read_gpx(&path).unwrap().tracks[0].segments.len(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Issue 15: `GeoJSON` (RFC 7946) positions are `[lon, lat]` of the points given.
    #[test]
    fn geojson_has_lon_lat_route_points_and_track_segments() {
        let wps = vec![
            Waypoint { name: "A".into(), lat_deg: 42.1, lon_deg: -71.2, arrival_radius_m: None },
            Waypoint { name: "B".into(), lat_deg: 42.3, lon_deg: -71.4, arrival_radius_m: None },
        ];
        let (a, b) = segs();
        let text = to_geojson("walk", &wps, &[&pts(&a), &pts(&[(1.0, 2.0)]), &pts(&b)]).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["type"], "FeatureCollection");
        let features = v["features"].as_array().unwrap();
        let of = |kind: &str| features.iter().filter(|f| f["properties"]["kind"] == kind).collect::<Vec<_>>();
        let pair = |c: &serde_json::Value| (c[0].as_f64().unwrap(), c[1].as_f64().unwrap());
        let route = of("route");
        assert_eq!(route[0]["geometry"]["type"], "LineString");
        let line: Vec<(f64, f64)> =
            route[0]["geometry"]["coordinates"].as_array().unwrap().iter().map(pair).collect();
        assert_eq!(line, wps.iter().map(|w| (w.lon_deg, w.lat_deg)).collect::<Vec<_>>());
        let points = of("waypoint");
        assert_eq!(points.len(), 2);
        assert_eq!(points[1]["geometry"]["type"], "Point");
        assert_eq!(pair(&points[1]["geometry"]["coordinates"]), (-71.4, 42.3));
        assert_eq!(points[1]["properties"]["name"], "B");
        let track = of("track");
        assert_eq!(track[0]["geometry"]["type"], "MultiLineString");
        let lines: Vec<Vec<(f64, f64)>> = track[0]["geometry"]["coordinates"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l.as_array().unwrap().iter().map(pair).collect())
            .collect();
        let swap = |s: &[(f64, f64)]| s.iter().map(|&(lat, lon)| (lon, lat)).collect::<Vec<_>>();
        assert_eq!(lines, vec![swap(&a), swap(&b)], "one line per segment of two points or more");
        assert!(track[0]["properties"].get("coordTimes").is_none(), "no times, no coordTimes");
        // With elevation on every point: [lon, lat, ele]; times per line in coordTimes.
        let t0 = chrono::DateTime::parse_from_rfc3339("2026-05-01T14:03:07Z").unwrap().to_utc();
        let mut timed = pts(&a);
        for p in &mut timed {
            p.ele_m = Some(7.25);
        }
        timed[1].time = Some(t0);
        let v = geojson("walk", &[], &[&timed]);
        let track = &v["features"][0];
        assert_eq!(track["geometry"]["coordinates"][0][0], serde_json::json!([a[0].1, a[0].0, 7.25]));
        assert_eq!(
            track["properties"]["coordTimes"],
            serde_json::json!([[null, "2026-05-01T14:03:07Z", null]])
        );
        assert_eq!(geojson_path(Path::new("out/walk.gpx")), PathBuf::from("out/walk.geojson"));
    }
}
