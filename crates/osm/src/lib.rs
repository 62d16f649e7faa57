//! Offline OpenStreetMap for vestnav: one `.osm.pbf` extract (Geofabrik, `BBBike`, `osmium extract`) read
//! into a map drawn as Web Mercator tiles and a path network a pedestrian walks, with a planner over it.
//! Headless — no UI, no threads of its own — so the console, the CLI and the tests share it.
//!
//! - [`Extract::read`]: the extract (size-limited; every error names the file) into [`MapData`] and a
//!   [`PathGraph`];
//! - [`rules`]: who may walk where (access, barriers, motorways and trunks without sidewalk), one home for
//!   the tag rules;
//! - [`PathGraph::plan`] / [`PathGraph::plan_via`]: a dense route along the network, under a [`Profile`];
//! - [`Renderer::tile`]: a 256 px tile drawn on demand and cached; [`ATTRIBUTION`] must be shown with it.
//!
//! ```
//! use vestnav_core::geo::LatLon;
//! use vestnav_osm::{Extract, Profile, RawNode, RawWay};
//!
//! let tags = |pairs: &[(&str, &str)]| pairs.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
//! let node = |id, lat, lon| RawNode { id, pos: LatLon::new(lat, lon), tags: vec![] };
//! let nodes = vec![node(1, 60.1700, 24.9400), node(2, 60.1700, 24.9420), node(3, 60.1710, 24.9420)];
//! let ways = vec![RawWay { id: 10, nodes: vec![1, 2, 3], tags: tags(&[("highway", "footway")]) }];
//! let extract = Extract::from_elements(&nodes, ways, vec![]);
//! let route = extract.graph.plan(LatLon::new(60.1700, 24.9400), LatLon::new(60.1710, 24.9420), Profile::Shortest)?;
//! assert_eq!(route.points.len(), 3);
//! assert!((route.length_m - 222.2).abs() < 1.0); // 111.5 m east + 111.3 m north
//! # Ok::<(), vestnav_osm::PlanError>(())
//! ```

mod extract;
mod graph;
mod map;
mod render;
pub mod rules;
pub mod tile;

pub use extract::{
    Builder, Extract, ExtractStats, MAX_EXTRACT_BYTES, OsmError, RawMember, RawNode, RawRelation, RawWay,
};
pub use graph::{MAX_SNAP_M, PathGraph, PlanError, Profile, Route, WalkWay};
pub use map::{Area, AreaKind, BarrierNode, Line, LineKind, MapData};
pub use render::{
    ATTRIBUTION, RENDER_SOURCE_HASH, RENDER_VERSION, Renderer, TileImage, colors, render_pixmap, render_tile,
};
pub use tile::TileId;
