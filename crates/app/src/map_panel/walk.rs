//! Routing on foot in the console, over the path network of the OpenStreetMap extract shown on the map
//! (`crate::tiles::MapExtract`): "Route to here" plans from the wearer's last fix to a clicked point, and
//! "Follow paths" plans every leg of the route along the paths. The planner (`vestnav_osm::PathGraph`)
//! runs on a worker thread (`osm-plan`); its result replaces the route through the same path as a GPX
//! import — one undo step, and a question first while guidance is steering the wearer: the waypoints
//! (the clicked goal; the route's own waypoints, moved onto the paths) with the dense path between them,
//! which guidance follows (cross-track from the path) and the station re-plans when the wearer strays
//! ([`share_network`]). "No path" and every other planning error is raised as a notice.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, TryRecvError};

use vestnav_core::geo::LatLon;
use vestnav_core::guidance::RoutePath;
use vestnav_osm::{PathGraph, Profile};
use vestnav_station::route::{RouteModel, Waypoint};
use vestnav_station::{Notices, Severity, Subject};

use super::MapView;
use crate::route_import::ImportChoice;

/// The profiles offered, with their names in the menu.
pub const PROFILES: [(Profile, &str); 3] = [
    (Profile::Shortest, "shortest"),
    (Profile::AvoidSteps, "avoid steps"),
    (Profile::PreferFootways, "prefer footways"),
];

/// A walk to plan, asked from the map's menu.
#[derive(Debug, Clone, PartialEq)]
pub enum WalkRequest {
    /// From the wearer's last fix to a clicked point.
    ToHere {
        /// The wearer's last fix.
        from: LatLon,
        /// The point clicked.
        to: LatLon,
    },
    /// Every leg of the route, through its waypoints in order (they keep their names and radii).
    FollowPaths(Vec<Waypoint>),
}

/// The planner's state in the map: the profile chosen and the plan running.
#[derive(Default)]
pub struct WalkPlanner {
    /// The profile the next plan uses.
    pub profile: Profile,
    job: Option<Receiver<Result<ImportChoice, String>>>,
}

impl WalkPlanner {
    /// A plan is running.
    pub fn busy(&self) -> bool {
        self.job.is_some()
    }
}

/// Plans `req` on `graph` under `profile` into the route to import, or the error to show: for "to here"
/// one waypoint `Here` where the walk ends, for "follow paths" the route's waypoints moved onto the paths;
/// with the planned path between them.
pub fn plan(graph: &PathGraph, req: &WalkRequest, profile: Profile) -> Result<ImportChoice, String> {
    let name = PROFILES.iter().find(|(p, _)| *p == profile).map_or("shortest", |(_, n)| n);
    let (route, what) = match req {
        WalkRequest::ToHere { from, to } => (graph.plan(*from, *to, profile), "walk to here"),
        WalkRequest::FollowPaths(wps) => {
            let points: Vec<LatLon> = wps.iter().map(Waypoint::pos).collect();
            (graph.plan_via(&points, profile), "route along paths")
        }
    };
    let route = route.map_err(|e| format!("{what}: {e}"))?;
    let guided = match req {
        WalkRequest::ToHere { from, to } => route
            .guided(&[Waypoint::at("Start", *from), Waypoint::at("Here", *to)])
            .and_then(|(wps, path)| {
                // The walk starts where the wearer is: only its end is a waypoint.
                let end = path.points().len() - 1;
                Ok((wps[1..].to_vec(), RoutePath::new(path.points().to_vec(), vec![end])?))
            }),
        WalkRequest::FollowPaths(wps) => route.guided(wps),
    };
    let (waypoints, path) = guided.map_err(|e| format!("{what}: {e}"))?;
    RouteModel::check_len(waypoints.len()).map_err(|e| format!("{what}: {e}"))?;
    Ok(ImportChoice {
        label: format!(
            "{what} ({:.0} m along paths, {name}, {} waypoint(s), a path of {} points)",
            route.length_m,
            waypoints.len(),
            path.points().len()
        ),
        name: format!("{what} ({name})"),
        waypoints,
        path: Some(path),
    })
}

/// Hands the loaded extract's path network to the station for re-routing (once per extract; again when
/// the profile changes), so it is read only once.
pub fn share_network(
    map: &MapView,
    station: &mut vestnav_station::Station,
    shared: &mut Option<(usize, Profile)>,
) {
    let Some(loaded) = map.tiles.extract.as_ref().and_then(|e| e.loaded()) else { return };
    let key = (Arc::as_ptr(&loaded.graph) as usize, map.walk.profile);
    if *shared != Some(key) {
        station.set_path_network(Arc::clone(&loaded.graph), map.walk.profile);
        *shared = Some(key);
    }
}

impl MapView {
    /// Starts planning `req` on the loaded extract's network, off the UI thread.
    pub fn start_walk(&mut self, req: WalkRequest, ctx: &egui::Context, notices: &mut Notices) {
        let Some(graph) = self.tiles.extract.as_ref().and_then(|e| e.loaded()).map(|l| Arc::clone(&l.graph))
        else {
            notices.raise(Severity::Warning, Subject::Route, "no OpenStreetMap extract loaded (Tiles…)");
            return;
        };
        let (tx, rx) = std::sync::mpsc::channel();
        let (profile, ctx) = (self.walk.profile, ctx.clone());
        let spawned = std::thread::Builder::new().name("osm-plan".into()).spawn(move || {
            // The receiver is gone when the map was dropped meanwhile: nothing left to tell.
            let _ = tx.send(plan(&graph, &req, profile));
            ctx.request_repaint();
        });
        match spawned {
            Ok(_) => self.walk.job = Some(rx),
            Err(e) => {
                notices.raise(Severity::Alarm, Subject::Route, format!("cannot start the planner: {e}"));
            }
        }
    }

    /// Takes a finished plan: its route replaces the route like an import (asked first while guiding),
    /// its error becomes a notice.
    pub(super) fn poll_walk(&mut self, route: &mut RouteModel, notices: &mut Notices) {
        let Some(rx) = &self.walk.job else { return };
        let outcome = match rx.try_recv() {
            Err(TryRecvError::Empty) => return,
            Err(TryRecvError::Disconnected) => Err("the planner thread ended without an answer".to_owned()),
            Ok(o) => o,
        };
        self.walk.job = None;
        match outcome {
            Ok(choice) => self.import_choice(route, choice, notices),
            Err(e) => notices.raise(Severity::Warning, Subject::Route, e),
        }
    }
}
