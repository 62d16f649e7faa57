//! The path network a pedestrian walks, and the planner over it.
//!
//! Nodes are the OSM nodes of walkable ways (see [`crate::rules`]); a blocking barrier node is left out,
//! which cuts every way through it. Edges join consecutive nodes of a way in both directions (no `oneway`
//! on foot) and carry their WGS-84 geodesic length. A start or goal anywhere is snapped to the nearest point
//! of the nearest edge (within [`MAX_SNAP_M`]), so a route begins where the wearer stands rather than at the
//! nearest junction.
//!
//! The planner is A* (Hart, Nilsson & Raphael 1968) over a binary heap, with the cost of an edge its
//! length times the profile's factor for the way's class (every factor ≥ 1) and, as heuristic, 0.99 times
//! the haversine distance to the goal on the mean-radius sphere. The haversine distance differs from the
//! WGS-84 geodesic by less than 0.6 %, so the heuristic never overestimates and is consistent: the first
//! time the goal leaves the heap its cost is the least.

use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap, HashSet};

use vestnav_core::geo::{Earth, LatLon, haversine_m};
use vestnav_core::guidance::{RouteError, RoutePath, Waypoint};

use crate::rules::WayClass;
use crate::tile::mercator_from_wgs84;

/// How far from any walkable way a start or goal may be [m].
pub const MAX_SNAP_M: f64 = 300.0;

/// Mean Earth radius (IUGG, R1 = (2a + b) / 3 of WGS-84) [m], for the heuristic.
const MEAN_RADIUS_M: f64 = 6_371_008.8;
/// Shrinks the haversine heuristic below the ellipsoidal distance everywhere.
const HEURISTIC_FACTOR: f64 = 0.99;
/// Zoom of the Web Mercator cells of the snapping grid (≈ 600 m at the equator, less toward the poles).
const GRID_ZOOM: u8 = 16;

/// A walkable way as the builder hands it over.
#[derive(Debug, Clone, PartialEq)]
pub struct WalkWay {
    /// OSM id.
    pub id: i64,
    /// Its class.
    pub class: WayClass,
    /// Its node ids, in order.
    pub nodes: Vec<i64>,
}

/// How the planner weighs ways.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Profile {
    /// The shortest walk.
    #[default]
    Shortest,
    /// Steps count 20 times their length: taken only to save a detour 20 times as long.
    AvoidSteps,
    /// Ways built for walking count their length; streets 1.5 times, main roads 2 times.
    PreferFootways,
}

impl Profile {
    /// The factor a way of `class` multiplies its length by (always ≥ 1).
    pub fn factor(self, class: WayClass) -> f64 {
        match self {
            Self::Shortest => 1.0,
            Self::AvoidSteps => {
                if class == WayClass::Steps {
                    20.0
                } else {
                    1.0
                }
            }
            Self::PreferFootways => match class {
                c if c.is_footway() => 1.0,
                WayClass::Minor | WayClass::Service => 1.5,
                _ => 2.0,
            },
        }
    }
}

/// Why no route was planned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// A point is not a valid position.
    #[error("{which}: {source}")]
    BadPoint {
        /// Which point ("from", "to", "via 2").
        which: String,
        /// What is wrong with it.
        source: vestnav_core::geo::GeoError,
    },
    /// No walkable way within [`MAX_SNAP_M`] of a point.
    #[error("{which} ({lat:.6}, {lon:.6}): no walkable way within {MAX_SNAP_M} m in this extract")]
    NoPathNear {
        /// Which point.
        which: String,
        /// Its latitude [deg].
        lat: f64,
        /// Its longitude [deg].
        lon: f64,
    },
    /// The two points are on parts of the network that do not connect.
    #[error("no walkable connection from {from} to {to} in this extract")]
    NoRoute {
        /// Name of the start.
        from: String,
        /// Name of the goal.
        to: String,
    },
    /// Fewer than two points to route through.
    #[error("a route needs at least two points")]
    TooFewPoints,
}

/// A planned walk.
#[derive(Debug, Clone, PartialEq)]
pub struct Route {
    /// The polyline to walk: the start snapped onto the network, every node passed, the goal snapped.
    pub points: Vec<LatLon>,
    /// Its length along the ways [m].
    pub length_m: f64,
    /// Its cost under the profile (length weighted by class) [m].
    pub cost: f64,
    /// OSM ids of the ways walked, in order, each run once.
    pub ways: Vec<i64>,
    /// How far the start was from the network [m].
    pub from_snap_m: f64,
    /// How far the goal was from the network [m].
    pub to_snap_m: f64,
    /// For each point planned through (start, vias, goal), the index in `points` where the route passes
    /// it (its snapped position): where a guided route puts its waypoints ([`Route::guided`]).
    pub stops: Vec<usize>,
}

impl Route {
    /// The route for guidance: `waypoints` (one per point planned through, in order) moved onto the path
    /// where the route passes them, keeping their names and radii, and the path itself with each on its
    /// vertex. Refused when the counts differ.
    pub fn guided(&self, waypoints: &[Waypoint]) -> Result<(Vec<Waypoint>, RoutePath), RouteError> {
        if waypoints.len() != self.stops.len() {
            return Err(RouteError::BadConfig("one waypoint per point planned through"));
        }
        let moved = waypoints
            .iter()
            .zip(&self.stops)
            .map(|(w, &i)| {
                let p = self.points.get(i).copied().unwrap_or_else(|| w.pos());
                Waypoint { lat_deg: p.lat_deg, lon_deg: p.lon_deg, ..w.clone() }
            })
            .collect();
        Ok((moved, RoutePath::new(self.points.clone(), self.stops.clone())?))
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Edge {
    to: u32,
    way: u32,
    length_m: f64,
}

/// A segment of a way, once (not per direction), for snapping.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Segment {
    a: u32,
    b: u32,
    way: u32,
    length_m: f64,
}

/// The walkable network of an extract.
#[derive(Debug, Clone, Default)]
pub struct PathGraph {
    pos: Vec<LatLon>,
    osm_ids: Vec<i64>,
    first_edge: Vec<u32>,
    edges: Vec<Edge>,
    ways: Vec<(i64, WayClass)>,
    segments: Vec<Segment>,
    grid: HashMap<(u32, u32), Vec<u32>>,
}

/// Where a point meets the network.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Snap {
    segment: u32,
    /// Fraction of the segment from `a` to `b`.
    t: f64,
    pos: LatLon,
    distance_m: f64,
}

/// A heap entry: smallest `f` first.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Open {
    f: f64,
    g: f64,
    node: u32,
}

impl Eq for Open {}
impl Ord for Open {
    fn cmp(&self, other: &Self) -> Ordering {
        other.f.total_cmp(&self.f).then_with(|| other.g.total_cmp(&self.g))
    }
}
impl PartialOrd for Open {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

const NONE: u32 = u32::MAX;

fn grid_cell(p: LatLon) -> (u32, u32) {
    let m = mercator_from_wgs84(p);
    let n = f64::from(1u32 << GRID_ZOOM);
    let max = (1u32 << GRID_ZOOM) - 1;
    let c = |v: f64| ((v * n).floor().max(0.0) as u32).min(max);
    (c(m.x), c(m.y))
}

/// East/north offset of `p` from `origin` on a local tangent plane [m] (equirectangular; for the few
/// hundred metres of a snap its error is far below a GPS fix's).
fn local_m(origin: LatLon, p: LatLon) -> (f64, f64) {
    let k = MEAN_RADIUS_M.to_radians();
    ((p.lon_deg - origin.lon_deg) * k * origin.lat_deg.to_radians().cos(), (p.lat_deg - origin.lat_deg) * k)
}

impl PathGraph {
    /// Builds the graph from walkable ways, the positions of their nodes and the blocking barrier nodes.
    /// Nodes missing from `coords` (cut by the extract's edge) and blocked nodes cut their ways.
    pub fn build(ways: &[WalkWay], coords: &HashMap<i64, LatLon>, blocked: &HashSet<i64>) -> Self {
        let mut g = Self::default();
        let mut index: HashMap<i64, u32> = HashMap::new();
        let mut pairs: Vec<(u32, Edge)> = Vec::new();
        for w in ways {
            let way = g.ways.len() as u32;
            g.ways.push((w.id, w.class));
            let mut prev: Option<u32> = None;
            for id in &w.nodes {
                let node = match coords.get(id) {
                    Some(p) if !blocked.contains(id) => Some(*index.entry(*id).or_insert_with(|| {
                        g.pos.push(*p);
                        g.osm_ids.push(*id);
                        (g.pos.len() - 1) as u32
                    })),
                    _ => None,
                };
                if let (Some(a), Some(b)) = (prev, node)
                    && a != b
                {
                    let length_m = Earth::Wgs84.distance_m(g.pos[a as usize], g.pos[b as usize]);
                    pairs.push((a, Edge { to: b, way, length_m }));
                    pairs.push((b, Edge { to: a, way, length_m }));
                    g.segments.push(Segment { a, b, way, length_m });
                }
                prev = node;
            }
        }
        pairs.sort_by_key(|(from, e)| (*from, e.to));
        g.first_edge = vec![0; g.pos.len() + 1];
        for (from, _) in &pairs {
            g.first_edge[*from as usize + 1] += 1;
        }
        for i in 0..g.pos.len() {
            g.first_edge[i + 1] += g.first_edge[i];
        }
        g.edges = pairs.into_iter().map(|(_, e)| e).collect();
        for (i, s) in g.segments.iter().enumerate() {
            let (ax, ay) = grid_cell(g.pos[s.a as usize]);
            let (bx, by) = grid_cell(g.pos[s.b as usize]);
            for x in ax.min(bx)..=ax.max(bx) {
                for y in ay.min(by)..=ay.max(by) {
                    g.grid.entry((x, y)).or_default().push(i as u32);
                }
            }
        }
        g
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.pos.len()
    }

    /// Number of directed edges (two per walkable segment).
    pub fn edge_count(&self) -> usize {
        self.edges.len()
    }

    /// Every node: OSM id and position.
    pub fn nodes(&self) -> impl Iterator<Item = (i64, LatLon)> + '_ {
        self.osm_ids.iter().copied().zip(self.pos.iter().copied())
    }

    fn edges_of(&self, node: u32) -> &[Edge] {
        let lo = self.first_edge.get(node as usize).copied().unwrap_or(0) as usize;
        let hi = self.first_edge.get(node as usize + 1).copied().unwrap_or(0) as usize;
        self.edges.get(lo..hi).unwrap_or(&[])
    }

    /// The nearest point of the network to `p`, within [`MAX_SNAP_M`].
    fn snap(&self, p: LatLon) -> Option<Snap> {
        let (cx, cy) = grid_cell(p);
        // Cells at GRID_ZOOM are ≥ 600 m · cos(lat) wide: one ring of neighbours covers MAX_SNAP_M up to
        // latitude 60°; further poleward, widen the ring.
        let cell_m = 40_075_016.686 * p.lat_deg.to_radians().cos() / f64::from(1u32 << GRID_ZOOM);
        let reach = ((MAX_SNAP_M / cell_m.max(1.0)).ceil() as u32).clamp(1, 64);
        let mut best: Option<Snap> = None;
        for x in cx.saturating_sub(reach)..=cx.saturating_add(reach) {
            for y in cy.saturating_sub(reach)..=cy.saturating_add(reach) {
                for &si in self.grid.get(&(x, y)).map_or(&[][..], Vec::as_slice) {
                    let s = self.segments[si as usize];
                    let (a, b) = (self.pos[s.a as usize], self.pos[s.b as usize]);
                    let (bx, by) = local_m(a, b);
                    let (px, py) = local_m(a, p);
                    let len2 = bx * bx + by * by;
                    let t = if len2 > 0.0 { ((px * bx + py * by) / len2).clamp(0.0, 1.0) } else { 0.0 };
                    let (dx, dy) = (px - t * bx, py - t * by);
                    let d = dx.hypot(dy);
                    if d <= MAX_SNAP_M && best.is_none_or(|b| d < b.distance_m) {
                        let pos = LatLon::new(
                            a.lat_deg + t * (b.lat_deg - a.lat_deg),
                            a.lon_deg + t * (b.lon_deg - a.lon_deg),
                        );
                        best = Some(Snap { segment: si, t, pos, distance_m: d });
                    }
                }
            }
        }
        best
    }

    /// Plans a walk from `from` to `to` under `profile`.
    pub fn plan(&self, from: LatLon, to: LatLon, profile: Profile) -> Result<Route, PlanError> {
        self.plan_via(&[from, to], profile)
    }

    /// Plans a walk through every point in order ("follow paths": each leg along the network), joined into
    /// one route.
    pub fn plan_via(&self, points: &[LatLon], profile: Profile) -> Result<Route, PlanError> {
        if points.len() < 2 {
            return Err(PlanError::TooFewPoints);
        }
        let name = |i: usize| match i {
            0 => "from".to_owned(),
            i if i + 1 == points.len() => "to".to_owned(),
            i => format!("via {i}"),
        };
        let mut snaps = Vec::with_capacity(points.len());
        for (i, p) in points.iter().enumerate() {
            let p = p.validated().map_err(|source| PlanError::BadPoint { which: name(i), source })?;
            let snap = self.snap(p).ok_or(PlanError::NoPathNear {
                which: name(i),
                lat: p.lat_deg,
                lon: p.lon_deg,
            })?;
            snaps.push(snap);
        }
        let mut route = Route {
            points: Vec::new(),
            length_m: 0.0,
            cost: 0.0,
            ways: Vec::new(),
            from_snap_m: snaps.first().map_or(0.0, |s| s.distance_m),
            to_snap_m: snaps.last().map_or(0.0, |s| s.distance_m),
            stops: vec![0],
        };
        for (i, pair) in snaps.windows(2).enumerate() {
            let [a, b] = pair else { continue };
            let leg = self
                .leg(*a, *b, profile)
                .ok_or_else(|| PlanError::NoRoute { from: name(i), to: name(i + 1) })?;
            let skip = usize::from(!route.points.is_empty());
            route.points.extend(leg.points.into_iter().skip(skip));
            route.stops.push(route.points.len() - 1);
            route.length_m += leg.length_m;
            route.cost += leg.cost;
            for w in leg.ways {
                if route.ways.last() != Some(&w) {
                    route.ways.push(w);
                }
            }
        }
        Ok(route)
    }

    /// Plans between two OSM nodes of the graph (the comparison with an independent router routes node to
    /// node so that both start from the same place). `None` when a node is not in the graph or unreachable.
    pub fn plan_nodes(&self, from_osm: i64, to_osm: i64, profile: Profile) -> Option<Route> {
        let find = |id: i64| self.osm_ids.iter().position(|&o| o == id);
        let (a, b) = (find(from_osm)?, find(to_osm)?);
        let snap_at = |n: usize| {
            let seg = self.segments.iter().position(|s| s.a as usize == n || s.b as usize == n)?;
            let s = self.segments[seg];
            Some(Snap {
                segment: seg as u32,
                t: if s.a as usize == n { 0.0 } else { 1.0 },
                pos: self.pos[n],
                distance_m: 0.0,
            })
        };
        self.leg(snap_at(a)?, snap_at(b)?, profile)
    }

    /// One leg between two snapped points: A* from the start segment's two ends to the goal segment's.
    fn leg(&self, from: Snap, to: Snap, profile: Profile) -> Option<Route> {
        let n = self.pos.len();
        let start = n as u32; // virtual node at `from`
        let goal = n as u32 + 1; // virtual node at `to`
        let fs = self.segments[from.segment as usize];
        let ts = self.segments[to.segment as usize];
        let fw = profile.factor(self.ways[fs.way as usize].1);
        let tw = profile.factor(self.ways[ts.way as usize].1);
        let h = |node: u32| -> f64 {
            let p = if node == goal {
                to.pos
            } else if node == start {
                from.pos
            } else {
                self.pos[node as usize]
            };
            HEURISTIC_FACTOR * haversine_m(p, to.pos, MEAN_RADIUS_M)
        };
        let mut g = vec![f64::INFINITY; n + 2];
        let mut prev: Vec<(u32, u32)> = vec![(NONE, NONE); n + 2];
        let mut closed = vec![false; n + 2];
        let mut heap = BinaryHeap::new();
        let mut relax = |heap: &mut BinaryHeap<Open>,
                         g: &mut Vec<f64>,
                         node: u32,
                         cost: f64,
                         from_node: u32,
                         way: u32| {
            if cost < g[node as usize] {
                g[node as usize] = cost;
                prev[node as usize] = (from_node, way);
                heap.push(Open { f: cost + h(node), g: cost, node });
            }
        };
        g[start as usize] = 0.0;
        relax(&mut heap, &mut g, fs.a, from.t * fs.length_m * fw, start, fs.way);
        relax(&mut heap, &mut g, fs.b, (1.0 - from.t) * fs.length_m * fw, start, fs.way);
        if from.segment == to.segment {
            relax(&mut heap, &mut g, goal, (from.t - to.t).abs() * fs.length_m * fw, start, fs.way);
        }
        while let Some(Open { g: cost, node, .. }) = heap.pop() {
            if closed[node as usize] || cost > g[node as usize] {
                continue;
            }
            closed[node as usize] = true;
            if node == goal {
                break;
            }
            if node == ts.a {
                relax(&mut heap, &mut g, goal, cost + to.t * ts.length_m * tw, node, ts.way);
            }
            if node == ts.b {
                relax(&mut heap, &mut g, goal, cost + (1.0 - to.t) * ts.length_m * tw, node, ts.way);
            }
            for e in self.edges_of(node) {
                if !closed[e.to as usize] {
                    let f = profile.factor(self.ways[e.way as usize].1);
                    relax(&mut heap, &mut g, e.to, cost + e.length_m * f, node, e.way);
                }
            }
        }
        if !g[goal as usize].is_finite() {
            return None;
        }
        // Walk back from the goal.
        let mut chain: Vec<(u32, u32)> = Vec::new(); // (node, way used to reach it)
        let mut at = goal;
        while at != start {
            let (p, way) = prev[at as usize];
            chain.push((at, way));
            if p == NONE || chain.len() > n + 2 {
                return None;
            }
            at = p;
        }
        chain.reverse();
        let steps = step_lengths(self, from, to, &chain, start, goal);
        let mut points = vec![from.pos];
        let mut ways: Vec<i64> = Vec::new();
        for (&(node, way), &step_m) in chain.iter().zip(&steps) {
            let p = if node == goal { to.pos } else { self.pos[node as usize] };
            if points.last() != Some(&p) {
                points.push(p);
            }
            // A start or goal snapped exactly onto a node walks none of the segment it was snapped to.
            let id = self.ways[way as usize].0;
            if step_m > 0.0 && ways.last() != Some(&id) {
                ways.push(id);
            }
        }
        if points.len() < 2 {
            points.push(to.pos);
        }
        let length_m = steps.iter().sum();
        Some(Route {
            stops: vec![0, points.len() - 1],
            points,
            length_m,
            cost: g[goal as usize],
            ways,
            from_snap_m: from.distance_m,
            to_snap_m: to.distance_m,
        })
    }
}

/// Length of each step of a chain of nodes from a snapped start to a snapped goal: whole edges by their
/// geodesic length, the partial first and last segments by their fraction.
fn step_lengths(
    g: &PathGraph,
    from: Snap,
    to: Snap,
    chain: &[(u32, u32)],
    start: u32,
    goal: u32,
) -> Vec<f64> {
    let fs = g.segments[from.segment as usize];
    let ts = g.segments[to.segment as usize];
    let mut steps = Vec::with_capacity(chain.len());
    let mut at = start;
    for &(node, way) in chain {
        steps.push(if at == start && node == goal {
            (from.t - to.t).abs() * fs.length_m
        } else if at == start {
            if node == fs.a { from.t * fs.length_m } else { (1.0 - from.t) * fs.length_m }
        } else if node == goal {
            if at == ts.a { to.t * ts.length_m } else { (1.0 - to.t) * ts.length_m }
        } else {
            g.edges_of(at)
                .iter()
                .filter(|e| e.to == node && e.way == way)
                .map(|e| e.length_m)
                .fold(f64::INFINITY, f64::min)
        });
        at = node;
    }
    steps
}
