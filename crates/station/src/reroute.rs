//! Re-routing off the path: when guidance reports the wearer off a planned route's path for the set time
//! ([`crate::guidance::GuidanceStatus::reroute_from`]), the station plans again from where the wearer is
//! through the waypoints still ahead, along the OpenStreetMap extract's path network, and replaces the rest
//! of the path ([`crate::route::RouteModel::reroute`]), saying so (a notice, the session log,
//! [`crate::Station::reroute_line`]). When planning fails it says so and guidance keeps the old path.
//!
//! The network comes from the extract once: read on its own thread (`osm-graph`,
//! [`crate::Station::load_path_network`]) or handed over by a view that has read it already
//! ([`crate::Station::set_path_network`]). Each plan runs on a short-lived thread (`osm-reroute`); the
//! station only polls channels in its turn, so neither guidance nor the stop path ever waits for them.
//! One re-route is asked per excursion off the path and route revision.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, TryRecvError, channel};

use vestnav_core::geo::LatLon;
use vestnav_core::guidance::RoutePath;
use vestnav_device::session_log::LogEntry;
use vestnav_osm::{Extract, PathGraph, Profile};

use crate::{Severity, Station, Subject};

/// The path network, as far as it is known.
#[derive(Default)]
enum Network {
    /// None was given.
    #[default]
    None,
    /// The extract is being read.
    Loading(PathBuf, Receiver<Result<PathGraph, String>>),
    /// Ready to plan on.
    Ready(Arc<PathGraph>),
}

/// A plan running: the route revision it re-routes, where it started and its answer.
struct Job {
    revision: u64,
    from: LatLon,
    rx: Receiver<Result<(RoutePath, f64), String>>,
}

/// The station's re-routing state.
#[derive(Default)]
pub(crate) struct Rerouter {
    network: Network,
    /// The profile re-routes are planned under (the one the view planned the route with).
    profile: Profile,
    job: Option<Job>,
    /// The route revision a re-route was asked for in the current excursion off the path.
    asked: Option<u64>,
    /// The last re-route, in words, for the view.
    line: Option<String>,
}

impl Station {
    /// Reads the OpenStreetMap extract at `path` on its own thread (`osm-graph`) for re-routing; a failure
    /// is raised as a notice naming the file.
    pub fn load_path_network(&mut self, path: PathBuf) {
        let (tx, rx) = channel();
        let p = path.clone();
        let spawned = std::thread::Builder::new().name("osm-graph".into()).spawn(move || {
            // The station is gone when the receiver is: nothing left to tell.
            let _ = tx.send(Extract::read(&p).map(|e| e.graph).map_err(|e| e.to_string()));
        });
        match spawned {
            Ok(_) => self.rerouter.network = Network::Loading(path, rx),
            Err(e) => self.notices.raise(
                Severity::Warning,
                Subject::Route,
                format!("cannot read the path network for re-routing: {e}"),
            ),
        }
    }

    /// Re-routes on `graph` (already read by the view), planning under `profile`.
    pub fn set_path_network(&mut self, graph: Arc<PathGraph>, profile: Profile) {
        self.rerouter.network = Network::Ready(graph);
        self.rerouter.profile = profile;
    }

    /// Whether a path network for re-routing is ready.
    pub fn has_path_network(&self) -> bool {
        matches!(self.rerouter.network, Network::Ready(_))
    }

    /// The last re-route (or why it failed), in words.
    pub fn reroute_line(&self) -> Option<&str> {
        self.rerouter.line.as_deref()
    }

    /// The re-routing turn of [`Station::pump`]: takes the network once read, a finished plan, and asks
    /// for a new one when guidance says the wearer has been off the path long enough.
    pub(crate) fn reroute_turn(&mut self) {
        self.take_network();
        self.take_plan();
        let Some(st) = &self.guidance else { return };
        if st.route_revision != self.route.revision() {
            return;
        }
        let Some(from) = st.reroute_from else {
            if st.off_path_s.is_none() {
                // Back on the path: the next excursion may ask again.
                self.rerouter.asked = None;
            }
            return;
        };
        let off_s = st.off_path_s.unwrap_or(0.0);
        if self.rerouter.asked == Some(self.route.revision()) || self.rerouter.job.is_some() {
            return;
        }
        self.rerouter.asked = Some(self.route.revision());
        self.start_plan(from, off_s);
    }

    fn take_network(&mut self) {
        let Network::Loading(path, rx) = &self.rerouter.network else { return };
        let got = match rx.try_recv() {
            Err(TryRecvError::Empty) => return,
            Err(TryRecvError::Disconnected) => Err("the reader ended without an answer".to_owned()),
            Ok(r) => r,
        };
        let path = path.clone();
        match got {
            Ok(graph) => self.rerouter.network = Network::Ready(Arc::new(graph)),
            Err(e) => {
                self.rerouter.network = Network::None;
                self.notices.raise(
                    Severity::Warning,
                    Subject::Route,
                    format!("no re-routing: {} unreadable: {e}", path.display()),
                );
            }
        }
    }

    /// Plans from `from` through the waypoints still ahead on a thread of its own.
    fn start_plan(&mut self, from: LatLon, off_s: f64) {
        let next = self.route.next();
        let (Some(path), Network::Ready(graph)) = (self.route.path().cloned(), &self.rerouter.network) else {
            let why = if self.route.path().is_none() {
                "the route has no path"
            } else {
                "no path network loaded (open an OpenStreetMap extract)"
            };
            self.reroute_failed(&format!("off the path for {off_s:.0} s; cannot re-route: {why}"));
            return;
        };
        let mut points = vec![from];
        points.extend(self.route.waypoints().iter().skip(next).map(vestnav_core::guidance::Waypoint::pos));
        let (graph, profile) = (Arc::clone(graph), self.rerouter.profile);
        let (tx, rx) = channel();
        let spawned = std::thread::Builder::new().name("osm-reroute".into()).spawn(move || {
            let planned = graph.plan_via(&points, profile).map_err(|e| e.to_string()).and_then(|r| {
                // The new path starts where the wearer stands, then joins the network where the planner
                // snapped them onto it: on it at once, however far off they strayed.
                let mut new_points = vec![from];
                new_points.extend_from_slice(&r.points);
                let stops: Vec<usize> = r.stops.iter().skip(1).map(|i| i + 1).collect();
                let length_m = r.length_m + r.from_snap_m;
                path.replaced_from(next, &new_points, &stops)
                    .map(|p| (p, length_m))
                    .map_err(|e| e.to_string())
            });
            let _ = tx.send(planned);
        });
        match spawned {
            Ok(_) => self.rerouter.job = Some(Job { revision: self.route.revision(), from, rx }),
            Err(e) => self.reroute_failed(&format!("cannot start the planner: {e}")),
        }
    }

    fn take_plan(&mut self) {
        let Some(job) = &self.rerouter.job else { return };
        let got = match job.rx.try_recv() {
            Err(TryRecvError::Empty) => return,
            Err(TryRecvError::Disconnected) => Err("the planner ended without an answer".to_owned()),
            Ok(r) => r,
        };
        let (revision, from) = (job.revision, job.from);
        self.rerouter.job = None;
        if revision != self.route.revision() {
            // The operator changed the route meanwhile: theirs wins.
            return;
        }
        let applied = got.and_then(|(path, length_m)| {
            self.route.reroute(path).map(|()| length_m).map_err(|e| e.to_string())
        });
        match applied {
            Ok(length_m) => {
                let text = format!(
                    "off the path: re-routed from the wearer at {:.6}, {:.6} ({length_m:.0} m along paths \
                     to the end)",
                    from.lat_deg, from.lon_deg
                );
                self.notices.raise(Severity::Info, Subject::Route, text.clone());
                self.log(LogEntry::Note { text: text.clone() });
                self.rerouter.line = Some(text);
            }
            Err(e) => self.reroute_failed(&format!("re-route failed: {e}")),
        }
    }

    fn reroute_failed(&mut self, why: &str) {
        let text = format!("{why}; guiding along the old path");
        self.notices.raise(Severity::Warning, Subject::Route, text.clone());
        self.log(LogEntry::Note { text: text.clone() });
        self.rerouter.line = Some(text);
    }
}
