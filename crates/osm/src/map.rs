//! What the map draws: lines, areas and barrier points in Web Mercator, with a grid index so a tile
//! touches only the features near it.

use std::collections::HashMap;

use vestnav_core::geo::{DVec2, LatLon};

use crate::rules::WayClass;
use crate::tile::{TileId, mercator_from_wgs84};

/// What a line is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LineKind {
    /// A road or path of any class (also ones a pedestrian may not use: they are drawn, not walked).
    Path {
        /// Its class.
        class: WayClass,
        /// Underground (`tunnel=*` or a negative `layer`): drawn faint.
        tunnel: bool,
    },
    /// A railway or tram line above ground.
    Rail,
    /// A river, stream, canal or ditch.
    Waterway,
    /// The coastline (`natural=coastline`), drawn as a line: building the sea's polygon from a cut
    /// extract is not done.
    Coastline,
    /// A wall, fence, hedge or rail as a line.
    Barrier,
}

/// What an area is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum AreaKind {
    /// Woods and scrub.
    Wood,
    /// Parks, gardens, playgrounds, cemeteries.
    Park,
    /// Grass, meadows, pitches.
    Grass,
    /// Pedestrian squares.
    Pedestrian,
    /// Water: lakes, ponds, docks, riverbanks.
    Water,
    /// Buildings.
    Building,
}

/// A line feature.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    /// What it is.
    pub kind: LineKind,
    /// Its `name`, if any.
    pub name: Option<String>,
    /// Its points (at least two).
    pub points: Vec<LatLon>,
}

/// An area feature.
#[derive(Debug, Clone, PartialEq)]
pub struct Area {
    /// What it is.
    pub kind: AreaKind,
    /// Its `name`, if any.
    pub name: Option<String>,
    /// Its closed rings (first point repeated last); holes are filled even-odd.
    pub rings: Vec<Vec<LatLon>>,
}

/// A barrier on a node (gate, bollard, ...).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BarrierNode {
    /// Where it is.
    pub pos: LatLon,
    /// Whether it stops a pedestrian (see [`crate::rules::node_blocks`]).
    pub blocks: bool,
}

/// A feature's place in [`MapData`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum FeatureRef {
    Area(u32),
    Line(u32),
    Barrier(u32),
}

/// Zoom whose tiles are the index's cells.
const INDEX_ZOOM: u8 = 14;
/// A feature spanning more cells than this is kept in one list checked by every tile instead.
const MAX_CELLS_PER_FEATURE: u64 = 1024;

/// Everything the renderer draws, in unit Web Mercator, with a grid index.
#[derive(Debug, Clone, Default)]
pub struct MapData {
    /// Lines.
    pub lines: Vec<Line>,
    /// Areas.
    pub areas: Vec<Area>,
    /// Barrier nodes.
    pub barriers: Vec<BarrierNode>,
    /// Mercator positions of each line's points.
    pub(crate) line_merc: Vec<Vec<DVec2>>,
    /// Mercator positions of each area's rings.
    pub(crate) area_merc: Vec<Vec<Vec<DVec2>>>,
    /// Index cells at zoom [`INDEX_ZOOM`].
    cells: HashMap<(u32, u32), Vec<FeatureRef>>,
    /// Features too large for the cells.
    big: Vec<FeatureRef>,
    /// Bounds of everything in unit Mercator (top-left, bottom-right).
    bounds: Option<(DVec2, DVec2)>,
}

fn bbox(points: impl Iterator<Item = DVec2>) -> Option<(DVec2, DVec2)> {
    points.fold(None, |acc, p| match acc {
        None => Some((p, p)),
        Some((a, b)) => Some((a.min(p), b.max(p))),
    })
}

impl MapData {
    /// Whether nothing is drawn.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty() && self.areas.is_empty() && self.barriers.is_empty()
    }

    /// The south-west and north-east corners of everything drawn, if anything is.
    pub fn bounds(&self) -> Option<(LatLon, LatLon)> {
        let (a, b) = self.bounds?;
        let nw = crate::tile::wgs84_from_mercator(a);
        let se = crate::tile::wgs84_from_mercator(b);
        Some((LatLon::new(se.lat_deg, nw.lon_deg), LatLon::new(nw.lat_deg, se.lon_deg)))
    }

    /// Projects every feature and builds the index (called once the features are in).
    pub(crate) fn finish_index(&mut self) {
        self.line_merc =
            self.lines.iter().map(|l| l.points.iter().map(|p| mercator_from_wgs84(*p)).collect()).collect();
        self.area_merc = self
            .areas
            .iter()
            .map(|a| a.rings.iter().map(|r| r.iter().map(|p| mercator_from_wgs84(*p)).collect()).collect())
            .collect();
        self.cells.clear();
        self.big.clear();
        let mut all: Option<(DVec2, DVec2)> = None;
        let mut entries: Vec<(FeatureRef, (DVec2, DVec2))> = Vec::new();
        for (i, pts) in self.line_merc.iter().enumerate() {
            if let Some(b) = bbox(pts.iter().copied()) {
                entries.push((FeatureRef::Line(i as u32), b));
            }
        }
        for (i, rings) in self.area_merc.iter().enumerate() {
            if let Some(b) = bbox(rings.iter().flatten().copied()) {
                entries.push((FeatureRef::Area(i as u32), b));
            }
        }
        for (i, b) in self.barriers.iter().enumerate() {
            let m = mercator_from_wgs84(b.pos);
            entries.push((FeatureRef::Barrier(i as u32), (m, m)));
        }
        let n = f64::from(1u32 << INDEX_ZOOM);
        let max = (1u32 << INDEX_ZOOM) - 1;
        let cell = |v: f64| ((v * n).floor().max(0.0) as u32).min(max);
        for (r, (a, b)) in entries {
            all = Some(all.map_or((a, b), |(lo, hi)| (lo.min(a), hi.max(b))));
            let (x0, x1, y0, y1) = (cell(a.x), cell(b.x), cell(a.y), cell(b.y));
            if u64::from(x1 - x0 + 1) * u64::from(y1 - y0 + 1) > MAX_CELLS_PER_FEATURE {
                self.big.push(r);
                continue;
            }
            for x in x0..=x1 {
                for y in y0..=y1 {
                    self.cells.entry((x, y)).or_default().push(r);
                }
            }
        }
        self.bounds = all;
    }

    /// The features whose bounding boxes may touch `tile` grown by `margin_px` on each side, each once,
    /// in a stable order.
    pub(crate) fn features_near(&self, tile: TileId, margin_px: f64) -> Vec<FeatureRef> {
        let (a, b) = tile.mercator_bounds();
        let margin = margin_px / (tile.scale() * f64::from(crate::tile::TILE_SIZE));
        let (a, b) = (a - DVec2::splat(margin), b + DVec2::splat(margin));
        let Some((lo, hi)) = self.bounds else { return Vec::new() };
        if b.x < lo.x || b.y < lo.y || a.x > hi.x || a.y > hi.y {
            return Vec::new();
        }
        let n = f64::from(1u32 << INDEX_ZOOM);
        let max = (1u32 << INDEX_ZOOM) - 1;
        let cell = |v: f64| ((v * n).floor().max(0.0) as u32).min(max);
        // Clip the query to the data's own extent so a low-zoom tile scans only occupied cells.
        let (a, b) = (a.max(lo), b.min(hi));
        let (x0, x1, y0, y1) = (cell(a.x), cell(b.x), cell(a.y), cell(b.y));
        let mut out: Vec<FeatureRef> = self.big.clone();
        if u64::from(x1 - x0 + 1) * u64::from(y1 - y0 + 1) > self.cells.len() as u64 {
            out.extend(
                self.cells
                    .iter()
                    .filter(|((x, y), _)| (x0..=x1).contains(x) && (y0..=y1).contains(y))
                    .flat_map(|(_, v)| v.iter().copied()),
            );
        } else {
            for x in x0..=x1 {
                for y in y0..=y1 {
                    if let Some(v) = self.cells.get(&(x, y)) {
                        out.extend(v.iter().copied());
                    }
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }
}
