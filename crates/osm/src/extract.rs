//! Reading an `.osm.pbf` extract into what the map draws and the graph a pedestrian walks.
//!
//! The file is read in three passes over its blocks (relations, then ways, then nodes), so only the
//! coordinates of nodes that some kept way uses are held in memory — a city extract of tens of MB has
//! millions of nodes that belong to nothing drawn or walked. The size of the file is limited
//! ([`MAX_EXTRACT_BYTES`] by default) and refused with the reason before any block is decoded; every error
//! names the file.

use std::collections::{HashMap, HashSet};
use std::io::{BufReader, Read as _};
use std::path::{Path, PathBuf};

use vestnav_core::geo::LatLon;

use crate::graph::{PathGraph, WalkWay};
use crate::map::{Area, AreaKind, BarrierNode, Line, LineKind, MapData};
use crate::rules::{self, Tags, tag};

/// Extracts larger than this are refused by [`Extract::read`] (a city is tens of MB; a country is GBs and
/// would not fit a laptop's memory as a walking graph).
pub const MAX_EXTRACT_BYTES: u64 = 512 * 1024 * 1024;

/// Ways with more nodes than this are cut (OSM's own API limit is 2000 nodes per way).
const MAX_WAY_NODES: usize = 100_000;

/// Why an extract could not be read.
#[derive(Debug, thiserror::Error)]
pub enum OsmError {
    /// The file could not be opened or read (missing, not a regular file, unreadable).
    #[error("{path}: {source}")]
    Io {
        /// The extract.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// The file is larger than the limit.
    #[error("{path}: {bytes} bytes, more than the {limit} bytes accepted for an extract")]
    TooLarge {
        /// The extract.
        path: PathBuf,
        /// Its size.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// The bytes are not a valid OSM PBF file.
    #[error("{path}: not a valid .osm.pbf extract: {reason}")]
    Format {
        /// The extract.
        path: PathBuf,
        /// What the PBF reader found wrong.
        reason: String,
    },
    /// The file is valid but holds nothing to draw or walk.
    #[error("{path}: the extract holds no ways to draw or walk")]
    Empty {
        /// The extract.
        path: PathBuf,
    },
}

/// A node as the reader hands it to the [`Builder`].
#[derive(Debug, Clone, PartialEq)]
pub struct RawNode {
    /// OSM id.
    pub id: i64,
    /// Position.
    pub pos: LatLon,
    /// Tags (only needed when the node is a barrier).
    pub tags: Vec<(String, String)>,
}

/// A way as the reader hands it to the [`Builder`].
#[derive(Debug, Clone, PartialEq)]
pub struct RawWay {
    /// OSM id.
    pub id: i64,
    /// Its node ids, in order.
    pub nodes: Vec<i64>,
    /// Tags.
    pub tags: Vec<(String, String)>,
}

/// A multipolygon relation's way member.
#[derive(Debug, Clone, PartialEq)]
pub struct RawMember {
    /// The way's OSM id.
    pub way: i64,
    /// Whether it is an inner ring (`role=inner`); anything else is outer.
    pub inner: bool,
}

/// A relation as the reader hands it to the [`Builder`] (only way members matter).
#[derive(Debug, Clone, PartialEq)]
pub struct RawRelation {
    /// OSM id.
    pub id: i64,
    /// Way members.
    pub members: Vec<RawMember>,
    /// Tags.
    pub tags: Vec<(String, String)>,
}

/// Counts of what an extract held and what was kept.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ExtractStats {
    /// Size of the file [bytes].
    pub bytes: u64,
    /// Nodes read.
    pub nodes_read: u64,
    /// Ways read.
    pub ways_read: u64,
    /// Relations read.
    pub relations_read: u64,
    /// Nodes with an invalid position, skipped.
    pub bad_nodes: u64,
    /// Way node references to nodes the extract does not hold (ways cut at the extract's edge).
    pub missing_nodes: u64,
}

/// Collects elements — relations first, then ways, then nodes, as the three passes hand them — and
/// builds the map and the graph. Tests feed it hand-made elements; [`Extract::read`] feeds it a file.
#[derive(Debug, Default)]
pub struct Builder {
    /// Multipolygon relations that draw something: kind, name, members.
    multipolygons: Vec<(AreaKind, Option<String>, Vec<RawMember>)>,
    /// Way ids that some kept multipolygon needs.
    member_ways: HashSet<i64>,
    /// Ways kept to be drawn as lines: kind, name, node ids.
    lines: Vec<(LineKind, Option<String>, Vec<i64>)>,
    /// Closed ways kept to be drawn as areas.
    areas: Vec<(AreaKind, Option<String>, Vec<i64>)>,
    /// Walkable ways: id, class, node ids.
    walk: Vec<(i64, rules::WayClass, Vec<i64>)>,
    /// Node lists of multipolygon member ways.
    member_nodes: HashMap<i64, Vec<i64>>,
    /// Node ids some kept way uses.
    needed: HashSet<i64>,
    /// Positions of the needed nodes.
    coords: HashMap<i64, LatLon>,
    /// Barrier nodes (drawn; the blocking ones cut the graph).
    barriers: Vec<(i64, BarrierNode)>,
    stats: ExtractStats,
}

/// What an area-drawing tag set draws, if anything.
fn area_kind(tags: &Tags) -> Option<AreaKind> {
    if tag(tags, "building").is_some_and(|v| v != "no") {
        return Some(AreaKind::Building);
    }
    if tag(tags, "natural") == Some("water")
        || matches!(tag(tags, "waterway"), Some("riverbank" | "dock"))
        || matches!(tag(tags, "landuse"), Some("reservoir" | "basin"))
    {
        return Some(AreaKind::Water);
    }
    if matches!(tag(tags, "leisure"), Some("park" | "garden" | "playground" | "dog_park"))
        || matches!(tag(tags, "landuse"), Some("recreation_ground" | "cemetery"))
    {
        return Some(AreaKind::Park);
    }
    if matches!(tag(tags, "landuse"), Some("grass" | "meadow" | "village_green" | "flowerbed"))
        || matches!(tag(tags, "natural"), Some("grassland" | "heath"))
        || matches!(tag(tags, "leisure"), Some("pitch"))
    {
        return Some(AreaKind::Grass);
    }
    if tag(tags, "landuse") == Some("forest") || matches!(tag(tags, "natural"), Some("wood" | "scrub")) {
        return Some(AreaKind::Wood);
    }
    if (tag(tags, "highway") == Some("pedestrian") && tag(tags, "area") == Some("yes"))
        || tag(tags, "place") == Some("square")
    {
        return Some(AreaKind::Pedestrian);
    }
    None
}

/// What a way draws as a line, if anything.
fn line_kind(tags: &Tags) -> Option<LineKind> {
    if let Some(class) = rules::WayClass::of(tags) {
        if tag(tags, "area") == Some("yes") {
            return None;
        }
        let tunnel = tag(tags, "tunnel").is_some_and(|v| v != "no")
            || tag(tags, "layer").is_some_and(|l| l.starts_with('-'));
        return Some(LineKind::Path { class, tunnel });
    }
    if matches!(tag(tags, "railway"), Some("rail" | "tram" | "light_rail" | "narrow_gauge" | "subway"))
        && tag(tags, "tunnel").is_none_or(|v| v == "no")
    {
        return Some(LineKind::Rail);
    }
    if matches!(tag(tags, "waterway"), Some("river" | "stream" | "canal" | "drain" | "ditch")) {
        return Some(LineKind::Waterway);
    }
    if tag(tags, "natural") == Some("coastline") {
        return Some(LineKind::Coastline);
    }
    if matches!(
        tag(tags, "barrier"),
        Some("wall" | "fence" | "hedge" | "retaining_wall" | "city_wall" | "guard_rail" | "handrail")
    ) {
        return Some(LineKind::Barrier);
    }
    None
}

fn name_of(tags: &Tags) -> Option<String> {
    tag(tags, "name").filter(|n| !n.trim().is_empty()).map(|n| n.chars().take(80).collect())
}

impl Builder {
    /// A builder with nothing in it.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes a relation (first pass).
    pub fn relation(&mut self, r: RawRelation) {
        self.stats.relations_read += 1;
        if tag(&r.tags, "type") != Some("multipolygon") {
            return;
        }
        let Some(kind) = area_kind(&r.tags) else { return };
        self.member_ways.extend(r.members.iter().map(|m| m.way));
        self.multipolygons.push((kind, name_of(&r.tags), r.members));
    }

    /// Takes a way (second pass).
    pub fn way(&mut self, mut w: RawWay) {
        self.stats.ways_read += 1;
        w.nodes.truncate(MAX_WAY_NODES);
        if w.nodes.len() < 2 {
            return;
        }
        let mut keep = false;
        if let Some(class) = rules::walkable(&w.tags) {
            self.walk.push((w.id, class, w.nodes.clone()));
            keep = true;
        }
        let closed = w.nodes.len() >= 4 && w.nodes.first() == w.nodes.last();
        if let Some(kind) = area_kind(&w.tags).filter(|_| closed) {
            self.areas.push((kind, name_of(&w.tags), w.nodes.clone()));
            keep = true;
        }
        if let Some(kind) = line_kind(&w.tags) {
            self.lines.push((kind, name_of(&w.tags), w.nodes.clone()));
            keep = true;
        }
        if self.member_ways.contains(&w.id) {
            self.member_nodes.insert(w.id, w.nodes.clone());
            keep = true;
        }
        if keep {
            self.needed.extend(w.nodes.iter().copied());
        }
    }

    /// Takes a node (third pass).
    pub fn node(&mut self, n: &RawNode) {
        self.stats.nodes_read += 1;
        let Ok(pos) = n.pos.validated() else {
            self.stats.bad_nodes += 1;
            return;
        };
        if pos.lat_deg.abs() > crate::tile::MAX_MERCATOR_LAT_DEG {
            self.stats.bad_nodes += 1;
            return;
        }
        if tag(&n.tags, "barrier").is_some() {
            self.barriers.push((n.id, BarrierNode { pos, blocks: rules::node_blocks(&n.tags) }));
        }
        if self.needed.contains(&n.id) {
            self.coords.insert(n.id, pos);
        }
    }

    /// Whether a node with these tags needs its tags kept (the reader skips copying the others').
    pub fn wants_node_tags(key: &str) -> bool {
        key == "barrier"
    }

    /// Positions of `ids`, split into runs wherever a node is missing from the extract.
    fn runs(&mut self, ids: &[i64]) -> Vec<Vec<LatLon>> {
        let mut runs = Vec::new();
        let mut run = Vec::new();
        for id in ids {
            if let Some(p) = self.coords.get(id) {
                run.push(*p);
            } else {
                self.stats.missing_nodes += 1;
                if run.len() >= 2 {
                    runs.push(std::mem::take(&mut run));
                }
                run.clear();
            }
        }
        if run.len() >= 2 {
            runs.push(run);
        }
        runs
    }

    /// Builds the map and the path graph.
    pub fn finish(mut self) -> (MapData, PathGraph, ExtractStats) {
        let mut map = MapData::default();
        for (kind, name, ids) in std::mem::take(&mut self.lines) {
            for points in self.runs(&ids) {
                map.lines.push(Line { kind, name: name.clone(), points });
            }
        }
        for (kind, name, ids) in std::mem::take(&mut self.areas) {
            // A closed way cut by the extract's edge is no longer an area: drop it rather than draw a wrong one.
            let ring: Option<Vec<LatLon>> = ids.iter().map(|id| self.coords.get(id).copied()).collect();
            if let Some(ring) = ring {
                map.areas.push(Area { kind, name, rings: vec![ring] });
            }
        }
        for (kind, name, members) in std::mem::take(&mut self.multipolygons) {
            let lists: Vec<&Vec<i64>> =
                members.iter().filter_map(|m| self.member_nodes.get(&m.way)).collect();
            let rings: Vec<Vec<LatLon>> = assemble_rings(&lists)
                .into_iter()
                .filter_map(|ids| ids.iter().map(|id| self.coords.get(id).copied()).collect())
                .collect();
            if !rings.is_empty() {
                map.areas.push(Area { kind, name, rings });
            }
        }
        map.barriers = self.barriers.iter().map(|(_, b)| *b).collect();
        map.finish_index();
        let blocked: HashSet<i64> =
            self.barriers.iter().filter(|(_, b)| b.blocks).map(|(id, _)| *id).collect();
        let walk: Vec<WalkWay> = std::mem::take(&mut self.walk)
            .into_iter()
            .map(|(id, class, nodes)| WalkWay { id, class, nodes })
            .collect();
        let graph = PathGraph::build(&walk, &self.coords, &blocked);
        (map, graph, self.stats)
    }
}

/// Joins way node lists end to end into closed rings (multipolygon members are often split into several
/// ways). Lists that do not close are dropped. Pure ids: bounded by the members' total length.
fn assemble_rings(lists: &[&Vec<i64>]) -> Vec<Vec<i64>> {
    let mut used = vec![false; lists.len()];
    let mut rings = Vec::new();
    for start in 0..lists.len() {
        if used[start] {
            continue;
        }
        used[start] = true;
        let mut ring: Vec<i64> = lists[start].clone();
        // Each pass either closes the ring, appends one unused list, or gives up: at most lists.len() passes.
        while ring.len() >= 2 && ring.first() != ring.last() {
            let Some(&end) = ring.last() else { break };
            let next = (0..lists.len())
                .find(|&i| !used[i] && (lists[i].first() == Some(&end) || lists[i].last() == Some(&end)));
            let Some(i) = next else { break };
            used[i] = true;
            if lists[i].first() == Some(&end) {
                ring.extend(lists[i].iter().skip(1));
            } else {
                ring.extend(lists[i].iter().rev().skip(1));
            }
        }
        if ring.len() >= 4 && ring.first() == ring.last() {
            rings.push(ring);
        }
    }
    rings
}

/// An extract read from a file: the map to draw, the graph to walk, and what was in it.
#[derive(Debug)]
pub struct Extract {
    /// The file it came from.
    pub path: PathBuf,
    /// What the renderer draws.
    pub map: MapData,
    /// What the planner walks.
    pub graph: PathGraph,
    /// Counts.
    pub stats: ExtractStats,
}

impl Extract {
    /// Reads an `.osm.pbf` extract of at most [`MAX_EXTRACT_BYTES`].
    pub fn read(path: &Path) -> Result<Self, OsmError> {
        Self::read_limited(path, MAX_EXTRACT_BYTES)
    }

    /// Reads an `.osm.pbf` extract of at most `limit` bytes.
    pub fn read_limited(path: &Path, limit: u64) -> Result<Self, OsmError> {
        let io = |source| OsmError::Io { path: path.to_owned(), source };
        let bytes = vestnav_files::open_regular(path).and_then(|f| f.metadata()).map_err(io)?.len();
        if bytes > limit {
            return Err(OsmError::TooLarge { path: path.to_owned(), bytes, limit });
        }
        let mut b = Builder::new();
        for pass in [Pass::Relations, Pass::Ways, Pass::Nodes] {
            read_pass(path, limit, pass, &mut b)?;
        }
        let (map, graph, mut stats) = b.finish();
        stats.bytes = bytes;
        if map.is_empty() && graph.node_count() == 0 {
            return Err(OsmError::Empty { path: path.to_owned() });
        }
        Ok(Self { path: path.to_owned(), map, graph, stats })
    }

    /// What can be said of an extract before reading it: a regular file within [`MAX_EXTRACT_BYTES`]
    /// whose first block is the `OSMHeader` the PBF format puts first (a 4-byte big-endian length, then a
    /// `BlobHeader` message whose field 1, the block type, is that string). Cheap: reads at most 64 KiB.
    pub fn check_file(path: &Path) -> Result<(), OsmError> {
        use std::io::Read;
        let io = |source| OsmError::Io { path: path.to_owned(), source };
        let format = |reason: &str| OsmError::Format { path: path.to_owned(), reason: reason.to_owned() };
        let mut file = vestnav_files::open_regular(path).map_err(io)?;
        let bytes = file.metadata().map_err(io)?.len();
        if bytes > MAX_EXTRACT_BYTES {
            return Err(OsmError::TooLarge { path: path.to_owned(), bytes, limit: MAX_EXTRACT_BYTES });
        }
        let mut len = [0u8; 4];
        file.read_exact(&mut len).map_err(|_| format("shorter than a block header"))?;
        let len = u32::from_be_bytes(len) as usize;
        // The format caps a BlobHeader at 64 KiB.
        if len == 0 || len > 64 * 1024 {
            return Err(format("the first block header's length is out of range"));
        }
        let mut header = vec![0u8; len];
        file.read_exact(&mut header).map_err(|_| format("the first block header is cut short"))?;
        // Field 1, wire type 2 (length-delimited): tag byte 0x0A, a one-byte varint length, the type.
        let kind = match header.as_slice() {
            [0x0A, n, rest @ ..] if usize::from(*n) <= rest.len() && *n < 0x80 => &rest[..usize::from(*n)],
            _ => return Err(format("the first block header has no block type")),
        };
        if kind != b"OSMHeader" {
            return Err(format("the first block is not an OSMHeader"));
        }
        Ok(())
    }

    /// Builds an extract from elements in memory (tests, tools): relations, then ways, then nodes.
    pub fn from_elements(nodes: &[RawNode], ways: Vec<RawWay>, relations: Vec<RawRelation>) -> Self {
        let mut b = Builder::new();
        for r in relations {
            b.relation(r);
        }
        for w in ways {
            b.way(w);
        }
        for n in nodes {
            b.node(n);
        }
        let (map, graph, stats) = b.finish();
        Self { path: PathBuf::from("(in memory)"), map, graph, stats }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pass {
    Relations,
    Ways,
    Nodes,
}

fn owned_tags<'a>(tags: impl Iterator<Item = (&'a str, &'a str)>) -> Vec<(String, String)> {
    tags.map(|(k, v)| (k.to_owned(), v.to_owned())).collect()
}

/// One pass over the file's blocks, handing the elements of one type to the builder.
///
/// The PBF reader (osmpbf) validates blob sizes (64 KiB headers, 32 MiB blobs) but a few of its accessors
/// panic on values no valid file holds (an unknown relation member type, say); so a pass runs under
/// `catch_unwind` and such a file is refused as malformed instead of taking the program down.
fn read_pass(path: &Path, limit: u64, pass: Pass, b: &mut Builder) -> Result<(), OsmError> {
    let format = |reason: String| OsmError::Format { path: path.to_owned(), reason };
    let file =
        vestnav_files::open_regular(path).map_err(|source| OsmError::Io { path: path.to_owned(), source })?;
    // The file may grow after the size check: never read past the limit.
    let reader = osmpbf::ElementReader::new(BufReader::new(file.take(limit)));
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        reader.for_each(|element| match (pass, element) {
            (Pass::Relations, osmpbf::Element::Relation(r)) => {
                let members = r
                    .members()
                    .filter(|m| m.member_type == osmpbf::RelMemberType::Way)
                    .map(|m| RawMember {
                        way: m.member_id,
                        inner: m.role().is_ok_and(|role| role == "inner"),
                    })
                    .collect();
                b.relation(RawRelation { id: r.id(), members, tags: owned_tags(r.tags()) });
            }
            (Pass::Ways, osmpbf::Element::Way(w)) => {
                b.way(RawWay {
                    id: w.id(),
                    nodes: w.refs().take(MAX_WAY_NODES).collect(),
                    tags: owned_tags(w.tags()),
                });
            }
            (Pass::Nodes, osmpbf::Element::Node(n)) => {
                let keep_tags = n.tags().any(|(k, _)| Builder::wants_node_tags(k));
                let tags = if keep_tags { owned_tags(n.tags()) } else { Vec::new() };
                b.node(&RawNode { id: n.id(), pos: LatLon::new(n.lat(), n.lon()), tags });
            }
            (Pass::Nodes, osmpbf::Element::DenseNode(n)) => {
                let keep_tags = n.tags().any(|(k, _)| Builder::wants_node_tags(k));
                let tags = if keep_tags { owned_tags(n.tags()) } else { Vec::new() };
                b.node(&RawNode { id: n.id(), pos: LatLon::new(n.lat(), n.lon()), tags });
            }
            _ => {}
        })
    }));
    match outcome {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => Err(format(e.to_string())),
        Err(_) => Err(format("the PBF reader failed on malformed data".to_owned())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rings_join_split_members_in_either_direction() {
        let a = vec![1, 2, 3];
        let b = vec![5, 4, 3]; // reversed
        let c = vec![5, 6, 1];
        let open = vec![10, 11, 12];
        let rings = assemble_rings(&[&a, &b, &c, &open]);
        assert_eq!(rings, vec![vec![1, 2, 3, 4, 5, 6, 1]]);
    }
}
