//! Waypoints and the wearer's track on the map: geometry for drawing, and the console's use of the GPX
//! files read and written by `vestnav_device::route_file` (the one home of the format).
//!
//! Distances and bearings to waypoints are core guidance's (WGS-84 geodesics, `vestnav_core::geo`); the map's
//! metric grid uses core's `geo::LocalFrame`.
//!
//! The route autosave ([`Autosave`]): the route being edited (name, waypoints, next waypoint) is written
//! as GPX through `route_file` whenever it changes, atomically (a temp file, then a rename), and read back
//! at start-up ([`read_autosave`]).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use vestnav_device::route_file::{self, RouteFile, Track, TrackPoint};

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
}

impl GpxContent {
    fn from_file(file: &RouteFile) -> Self {
        let route = file.default_route();
        Self {
            name: route.as_ref().and_then(|r| r.name.clone()).or_else(|| file.name.clone()),
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

/// The route (and the track, when there is one) as a GPX file.
pub fn to_route_file(name: &str, waypoints: &[Waypoint], track: &[(f64, f64)]) -> RouteFile {
    let mut file = RouteFile::from_route(name, waypoints.to_vec());
    if !track.is_empty() {
        file.tracks.push(Track {
            name: Some(format!("{name} track")),
            segments: vec![
                track
                    .iter()
                    .map(|&(lat_deg, lon_deg)| TrackPoint { lat_deg, lon_deg, ele_m: None, time: None })
                    .collect(),
            ],
        });
    }
    file
}

/// GPX 1.1 text of the route and track.
pub fn write_gpx(name: &str, waypoints: &[Waypoint], track: &[(f64, f64)]) -> Result<String, String> {
    Ok(route_file::to_gpx(&to_route_file(name, waypoints, track)))
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
}

impl RouteState {
    /// Whether this is the route `name`, `waypoints`, `next` (compared without cloning them).
    pub fn is(&self, name: &str, waypoints: &[Waypoint], next: usize) -> bool {
        self.next == next && self.name == name && self.waypoints == waypoints
    }
}

/// File name of the route autosave in the data directory.
pub const AUTOSAVE_FILE: &str = "route-autosave.gpx";

/// What the autosave's file-level `<metadata><name>` starts with; the next waypoint's index follows.
const AUTOSAVE_NEXT_PREFIX: &str = "vestnav route autosave; next=";

/// The autosave's GPX text: the route as the file's one `<rte>`, the next waypoint's index in the file's
/// `<metadata><name>` (GPX has no element for it, and `route_file` is the one home of the format).
pub fn autosave_gpx(state: &RouteState) -> String {
    let mut file = RouteFile::from_route(&state.name, state.waypoints.clone());
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
    RouteState { name: name.unwrap_or_else(|| "route".to_owned()), waypoints, next }
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

/// Writes `text` to `path` atomically: into a temp file next to it, flushed to disk, then renamed over
/// it, so a crash leaves the old file or the new one, never half of one. Errors name the file.
pub fn write_atomically(path: &Path, text: &str) -> Result<(), String> {
    use std::io::Write as _;
    let fail = |p: &Path, e: std::io::Error| format!("cannot write {}: {e}", p.display());
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| fail(dir, e))?;
    }
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    let mut f = std::fs::File::create(&tmp).map_err(|e| fail(&tmp, e))?;
    f.write_all(text.as_bytes()).and_then(|()| f.sync_all()).map_err(|e| fail(&tmp, e))?;
    drop(f);
    std::fs::rename(&tmp, path).map_err(|e| fail(path, e))
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
    pub fn poll(
        &mut self,
        name: &str,
        waypoints: &[Waypoint],
        next: usize,
        now: Instant,
        now_or_never: bool,
    ) -> Option<String> {
        if self.saved.is(name, waypoints, next) {
            return None;
        }
        if !now_or_never && self.last_attempt.is_some_and(|t| now.duration_since(t) < AUTOSAVE_MIN_INTERVAL) {
            return None;
        }
        self.last_attempt = Some(now);
        let state = RouteState { name: name.to_owned(), waypoints: waypoints.to_vec(), next };
        match write_atomically(&self.path, &autosave_gpx(&state)) {
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

/// Picks at most about `max_points` of `n` points for drawing: a fixed stride, always keeping the last.
///
/// A 100k-point track drawn at full resolution costs tens of milliseconds per frame; the stride keeps the
/// frame time bounded while the most recent points (drawn separately in full) stay exact.
pub fn decimation_stride(n: usize, max_points: usize) -> usize {
    n.div_ceil(max_points.max(1)).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demo_route_loads_and_round_trips() {
        let c = parse_gpx(DEMO_GPX).unwrap();
        assert_eq!(c.waypoints.len(), 7);
        assert_eq!(c.waypoints[0].name, "Start (SE gate)");
        let text = write_gpx("demo", &c.waypoints, &[(42.0, -71.0), (42.1, -71.1)]).unwrap();
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
                Waypoint { name: "A".into(), lat_deg: 42.1, lon_deg: -71.2 },
                Waypoint { name: "B <2>".into(), lat_deg: -0.000_001, lon_deg: 179.9 },
            ],
            next: 1,
        };
        let mut a = Autosave::new(path.clone(), RouteState::default());
        let t0 = Instant::now();
        assert_eq!(a.poll(&state.name, &state.waypoints, state.next, t0, false), None);
        assert_eq!(read_autosave(&path), Ok(Some(state.clone())));
        // A change right after a write waits for the interval, unless it is the exit's.
        a.poll(&state.name, &state.waypoints, 0, t0, false);
        assert_eq!(read_autosave(&path).unwrap().unwrap().next, 1);
        a.poll(&state.name, &state.waypoints, 0, t0, true);
        assert_eq!(read_autosave(&path).unwrap().unwrap().next, 0);
        // An empty route stays empty, with its name.
        a.poll("empty", &[], 0, t0, true);
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

    #[test]
    fn stride_bounds_points() {
        assert_eq!(decimation_stride(10, 5000), 1);
        assert!(100_000 / decimation_stride(100_000, 5000) <= 5000);
    }
}
