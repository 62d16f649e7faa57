//! Drawing the extract into 256 px Web Mercator tiles with tiny-skia, and a bounded cache of drawn tiles.
//!
//! Order, bottom to top: land, woods, parks, grass, squares, water, buildings, waterways and coastline,
//! barriers, roads and paths by class (casing under fill, minor under major), railways, barrier points, and
//! names (streets at zoom ≥ 16, named water and parks at ≥ 15, buildings at ≥ 17; each drawn only when it
//! fits wholly inside its tile and clear of the names already placed, so no name is ever cut at a tile edge).
//! Widths grow with zoom so the map stays legible from 14 to 19. Below zoom 12 only areas and main roads
//! are drawn.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex};

use tiny_skia::{FillRule, LineCap, LineJoin, Paint, PathBuilder, Pixmap, Stroke, StrokeDash, Transform};
use vestnav_core::geo::DVec2;
use vestnav_plot::Color;

use crate::map::{AreaKind, FeatureRef, LineKind, MapData};
use crate::rules::WayClass;
use crate::tile::{TILE_SIZE, TileId};

/// The version of the drawing: part of the name of the disk cache of drawn tiles, so tiles drawn by
/// another version are never shown. The crate's version, and a counter raised whenever colours, widths,
/// layers or labels change between releases.
pub const RENDER_VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), "+draw1");

/// A hash of the drawing's own source (this file, the way rules and the map model, as compiled), part of
/// the disk cache's name beside [`RENDER_VERSION`]: an edit of them puts the tiles drawn before in another
/// folder even when the counter was not raised (an edit that changes nothing drawn costs one redraw).
pub const RENDER_SOURCE_HASH: u64 =
    fnv1a(&[include_bytes!("render.rs"), include_bytes!("rules.rs"), include_bytes!("map.rs")]);

/// FNV-1a (64 bit) over `parts` in turn, at compile time.
const fn fnv1a(parts: &[&[u8]]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325_u64;
    let mut p = 0;
    while p < parts.len() {
        let bytes = parts[p];
        let mut i = 0;
        while i < bytes.len() {
            h ^= bytes[i] as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
            i += 1;
        }
        p += 1;
    }
    h
}

/// The attribution OpenStreetMap's licence (`ODbL`) requires wherever the map is shown.
pub const ATTRIBUTION: &str = "© OpenStreetMap contributors";

/// Colours of the map (also what the rendering tests look for).
pub mod colors {
    use vestnav_plot::Color;
    /// Land, where nothing else is drawn.
    pub const LAND: Color = Color::rgb(242, 239, 233);
    /// Woods.
    pub const WOOD: Color = Color::rgb(173, 209, 158);
    /// Parks.
    pub const PARK: Color = Color::rgb(200, 250, 204);
    /// Grass.
    pub const GRASS: Color = Color::rgb(205, 235, 176);
    /// Pedestrian squares.
    pub const SQUARE: Color = Color::rgb(221, 221, 232);
    /// Water.
    pub const WATER: Color = Color::rgb(170, 211, 223);
    /// Buildings.
    pub const BUILDING: Color = Color::rgb(217, 208, 201);
    /// Building outlines.
    pub const BUILDING_EDGE: Color = Color::rgb(190, 176, 165);
    /// Footways and paths.
    pub const FOOTWAY: Color = Color::rgb(232, 92, 74);
    /// Steps.
    pub const STEPS: Color = Color::rgb(190, 40, 40);
    /// Cycleways.
    pub const CYCLEWAY: Color = Color::rgb(60, 90, 230);
    /// Tracks.
    pub const TRACK: Color = Color::rgb(150, 110, 40);
    /// Minor streets (fill).
    pub const STREET: Color = Color::rgb(255, 255, 255);
    /// Road casing.
    pub const CASING: Color = Color::rgb(170, 160, 150);
    /// Barriers (walls, fences).
    pub const BARRIER: Color = Color::rgb(110, 110, 110);
    /// A barrier node that stops a pedestrian.
    pub const BLOCKING: Color = Color::rgb(200, 0, 0);
    /// Railways.
    pub const RAIL: Color = Color::rgb(120, 120, 120);
    /// Names.
    pub const LABEL: Color = Color::rgb(45, 45, 45);
}

fn paint(c: Color) -> Paint<'static> {
    let mut p = Paint { anti_alias: true, ..Paint::default() };
    p.set_color_rgba8(c.r, c.g, c.b, c.a);
    p
}

fn with_alpha(c: Color, a: u8) -> Color {
    Color::rgba(c.r, c.g, c.b, a)
}

/// Width scale at zoom `z`: 1 at zoom 16, × 2^0.6 per zoom level.
fn zoom_scale(z: u8) -> f32 {
    2f32.powf((f32::from(z) - 16.0) * 0.6)
}

/// How a road or path class is stroked: fill colour, width at zoom 16 [px], casing, dash, least zoom.
struct PathStyle {
    fill: Color,
    width_px: f32,
    casing: bool,
    dash: Option<[f32; 2]>,
    min_zoom: u8,
    /// Drawing order (higher on top).
    rank: u8,
}

fn path_style(class: WayClass) -> PathStyle {
    let road = |fill, width_px, min_zoom, rank| PathStyle {
        fill,
        width_px,
        casing: true,
        dash: None,
        min_zoom,
        rank,
    };
    match class {
        WayClass::Motorway => road(Color::rgb(232, 146, 162), 9.0, 5, 12),
        WayClass::Trunk => road(Color::rgb(249, 178, 156), 9.0, 5, 11),
        WayClass::Primary => road(Color::rgb(252, 214, 164), 8.0, 8, 10),
        WayClass::Secondary => road(Color::rgb(247, 250, 191), 7.5, 9, 9),
        WayClass::Tertiary => road(colors::STREET, 7.0, 11, 8),
        WayClass::Minor | WayClass::LivingStreet => road(colors::STREET, 5.5, 12, 7),
        WayClass::Service => road(colors::STREET, 3.5, 14, 6),
        WayClass::Pedestrian => road(colors::SQUARE, 5.0, 13, 5),
        WayClass::Track => PathStyle {
            fill: colors::TRACK,
            width_px: 1.6,
            casing: false,
            dash: Some([5.0, 2.0]),
            min_zoom: 13,
            rank: 4,
        },
        WayClass::Cycleway => PathStyle {
            fill: colors::CYCLEWAY,
            width_px: 1.6,
            casing: false,
            dash: None,
            min_zoom: 13,
            rank: 3,
        },
        WayClass::Footway => PathStyle {
            fill: colors::FOOTWAY,
            width_px: 1.6,
            casing: false,
            dash: None,
            min_zoom: 13,
            rank: 2,
        },
        WayClass::Steps => PathStyle {
            fill: colors::STEPS,
            width_px: 3.0,
            casing: false,
            dash: Some([1.2, 1.2]),
            min_zoom: 14,
            rank: 1,
        },
    }
}

fn area_color(kind: AreaKind) -> Color {
    match kind {
        AreaKind::Wood => colors::WOOD,
        AreaKind::Park => colors::PARK,
        AreaKind::Grass => colors::GRASS,
        AreaKind::Pedestrian => colors::SQUARE,
        AreaKind::Water => colors::WATER,
        AreaKind::Building => colors::BUILDING,
    }
}

/// A drawn tile: 256 x 256 RGBA pixels (straight, not premultiplied, alpha; rows top to bottom).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TileImage {
    /// The tile.
    pub id: TileId,
    /// `256 * 256 * 4` bytes.
    pub rgba: Vec<u8>,
}

impl TileImage {
    /// The colour at pixel (`x`, `y`), if inside.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 4]> {
        if x >= TILE_SIZE || y >= TILE_SIZE {
            return None;
        }
        let i = ((y * TILE_SIZE + x) * 4) as usize;
        let p = self.rgba.get(i..i + 4)?;
        Some([p[0], p[1], p[2], p[3]])
    }
}

/// Draws tiles of one extract, keeping the last [`Renderer::CACHE_TILES`] drawn. Shareable between
/// threads: drawing happens outside the cache's lock, so tile loaders render in parallel.
#[derive(Debug)]
pub struct Renderer {
    map: Arc<MapData>,
    cache: Mutex<TileCache>,
}

#[derive(Debug, Default)]
struct TileCache {
    tiles: HashMap<TileId, Arc<TileImage>>,
    order: VecDeque<TileId>,
}

impl Renderer {
    /// How many drawn tiles are kept (256 KiB each: 32 MiB).
    pub const CACHE_TILES: usize = 128;

    /// A renderer of `map`.
    pub fn new(map: Arc<MapData>) -> Self {
        Self { map, cache: Mutex::new(TileCache::default()) }
    }

    /// The map drawn.
    pub fn map(&self) -> &MapData {
        &self.map
    }

    /// The tile, from the cache or drawn now.
    pub fn tile(&self, id: TileId) -> Arc<TileImage> {
        if let Some(t) = self.cache.lock().ok().and_then(|c| c.tiles.get(&id).cloned()) {
            return t;
        }
        let image = Arc::new(render_tile(&self.map, id));
        if let Ok(mut c) = self.cache.lock() {
            if c.tiles.insert(id, Arc::clone(&image)).is_none() {
                c.order.push_back(id);
            }
            while c.order.len() > Self::CACHE_TILES {
                if let Some(old) = c.order.pop_front() {
                    c.tiles.remove(&old);
                }
            }
        }
        image
    }

    /// The tile as PNG bytes (drawn or cached).
    pub fn tile_png(&self, id: TileId) -> Result<Vec<u8>, String> {
        let t = self.tile(id);
        let mut pixmap = Pixmap::new(TILE_SIZE, TILE_SIZE).ok_or("tile pixmap")?;
        for (dst, src) in pixmap.pixels_mut().iter_mut().zip(t.rgba.chunks_exact(4)) {
            *dst = tiny_skia::ColorU8::from_rgba(src[0], src[1], src[2], src[3]).premultiply();
        }
        pixmap.encode_png().map_err(|e| e.to_string())
    }
}

/// Draws one tile of `map` (uncached; see [`Renderer`]).
pub fn render_tile(map: &MapData, id: TileId) -> TileImage {
    let Some(pixmap) = render_pixmap(map, id) else {
        // Only when a 256 x 256 pixmap cannot be allocated: an empty (transparent) tile.
        return TileImage { id, rgba: vec![0; (TILE_SIZE * TILE_SIZE * 4) as usize] };
    };
    let rgba = pixmap
        .pixels()
        .iter()
        .flat_map(|p| {
            let c = p.demultiply();
            [c.red(), c.green(), c.blue(), c.alpha()]
        })
        .collect();
    TileImage { id, rgba }
}

/// Draws one tile of `map` into a tiny-skia pixmap (premultiplied); `None` only when the pixmap cannot be
/// allocated.
pub fn render_pixmap(map: &MapData, id: TileId) -> Option<Pixmap> {
    let mut pm = Pixmap::new(TILE_SIZE, TILE_SIZE)?;
    pm.fill(tiny_skia::Color::from_rgba8(colors::LAND.r, colors::LAND.g, colors::LAND.b, 255));
    let scale = zoom_scale(id.z);
    // Features reach into the tile by at most their half width; labels are placed only when inside.
    let near = map.features_near(id, 24.0);
    let px = |m: DVec2| {
        let p = id.pixel_of_mercator(m);
        (p.x as f32, p.y as f32)
    };

    draw_areas(&mut pm, map, id, &near);

    // Lines: water and barriers first, then paths by rank (casings of all roads under all fills), rails.
    let lines: Vec<u32> =
        near.iter().filter_map(|f| if let FeatureRef::Line(i) = f { Some(*i) } else { None }).collect();
    let polyline = |i: u32| -> Option<tiny_skia::Path> {
        let pts = map.line_merc.get(i as usize)?;
        let mut pb = PathBuilder::new();
        let mut it = pts.iter().map(|m| px(*m));
        let (x, y) = it.next()?;
        pb.move_to(x, y);
        it.for_each(|(x, y)| pb.line_to(x, y));
        pb.finish()
    };
    let stroke = |width: f32, dash: Option<[f32; 2]>| Stroke {
        width: width.max(0.6),
        line_cap: if dash.is_some() { LineCap::Butt } else { LineCap::Round },
        line_join: LineJoin::Round,
        dash: dash
            .and_then(|[on, off]| StrokeDash::new(vec![on * scale.max(1.0), off * scale.max(1.0)], 0.0)),
        ..Stroke::default()
    };
    let kind_of = |i: u32| map.lines.get(i as usize).map(|l| l.kind);
    for &i in &lines {
        let (width, color) = match kind_of(i) {
            Some(LineKind::Waterway | LineKind::Coastline) => (2.5 * scale, colors::WATER),
            Some(LineKind::Barrier) if id.z >= 15 => (1.0, colors::BARRIER),
            _ => continue,
        };
        if let Some(path) = polyline(i) {
            pm.stroke_path(&path, &paint(color), &stroke(width, None), Transform::identity(), None);
        }
    }
    let mut paths: Vec<(u8, u32, WayClass, bool)> = lines
        .iter()
        .filter_map(|&i| match kind_of(i) {
            Some(LineKind::Path { class, tunnel }) => {
                let st = path_style(class);
                (id.z >= st.min_zoom && (id.z >= 12 || st.rank >= 10)).then_some((st.rank, i, class, tunnel))
            }
            _ => None,
        })
        .collect();
    paths.sort_unstable();
    for &(_, i, class, tunnel) in &paths {
        let st = path_style(class);
        if st.casing
            && id.z >= 14
            && !tunnel
            && let Some(path) = polyline(i)
        {
            pm.stroke_path(
                &path,
                &paint(colors::CASING),
                &stroke(st.width_px * scale + 1.6, None),
                Transform::identity(),
                None,
            );
        }
    }
    for &(_, i, class, tunnel) in &paths {
        let st = path_style(class);
        let color = if tunnel { with_alpha(st.fill, 90) } else { st.fill };
        if let Some(path) = polyline(i) {
            pm.stroke_path(
                &path,
                &paint(color),
                &stroke(st.width_px * scale, st.dash),
                Transform::identity(),
                None,
            );
        }
    }
    for &i in &lines {
        if kind_of(i) == Some(LineKind::Rail)
            && let Some(path) = polyline(i)
        {
            pm.stroke_path(
                &path,
                &paint(colors::RAIL),
                &stroke(1.5 * scale.max(0.7), None),
                Transform::identity(),
                None,
            );
        }
    }

    draw_barrier_points(&mut pm, map, id, &near);
    draw_names(&mut pm, map, id, &near);
    Some(pm)
}

/// Fills the areas near the tile, by kind (woods under parks under ... under buildings).
fn draw_areas(pm: &mut Pixmap, map: &MapData, id: TileId, near: &[FeatureRef]) {
    let px = |m: DVec2| {
        let p = id.pixel_of_mercator(m);
        (p.x as f32, p.y as f32)
    };
    let mut areas: Vec<u32> =
        near.iter().filter_map(|f| if let FeatureRef::Area(i) = f { Some(*i) } else { None }).collect();
    areas.sort_by_key(|&i| map.areas.get(i as usize).map(|a| a.kind));
    for &i in &areas {
        let (Some(area), Some(rings)) = (map.areas.get(i as usize), map.area_merc.get(i as usize)) else {
            continue;
        };
        if area.kind == AreaKind::Building && id.z < 14 {
            continue;
        }
        let mut pb = PathBuilder::new();
        for ring in rings {
            let mut pts = ring.iter().map(|m| px(*m));
            if let Some((x, y)) = pts.next() {
                pb.move_to(x, y);
                pts.for_each(|(x, y)| pb.line_to(x, y));
                pb.close();
            }
        }
        if let Some(path) = pb.finish() {
            pm.fill_path(
                &path,
                &paint(area_color(area.kind)),
                FillRule::EvenOdd,
                Transform::identity(),
                None,
            );
            if area.kind == AreaKind::Building && id.z >= 16 {
                let s = Stroke { width: 0.8, ..Stroke::default() };
                pm.stroke_path(&path, &paint(colors::BUILDING_EDGE), &s, Transform::identity(), None);
            }
        }
    }
}

/// Barrier points from zoom 17: red when they stop a pedestrian.
fn draw_barrier_points(pm: &mut Pixmap, map: &MapData, id: TileId, near: &[FeatureRef]) {
    let scale = zoom_scale(id.z);
    let px = |m: DVec2| {
        let p = id.pixel_of_mercator(m);
        (p.x as f32, p.y as f32)
    };
    if id.z >= 17 {
        for f in near {
            if let FeatureRef::Barrier(i) = f
                && let Some(b) = map.barriers.get(*i as usize)
            {
                let (x, y) = px(crate::tile::mercator_from_wgs84(b.pos));
                if let Some(c) = PathBuilder::from_circle(x, y, 1.2 * scale) {
                    let color = if b.blocks { colors::BLOCKING } else { colors::BARRIER };
                    pm.fill_path(&c, &paint(color), FillRule::Winding, Transform::identity(), None);
                }
            }
        }
    }
}

/// A placed label's box [px].
#[derive(Debug, Clone, Copy)]
struct LabelBox {
    x0: f32,
    y0: f32,
    x1: f32,
    y1: f32,
}

impl LabelBox {
    fn overlaps(&self, o: &Self) -> bool {
        self.x0 < o.x1 && o.x0 < self.x1 && self.y0 < o.y1 && o.y0 < self.y1
    }
}

/// The point halfway along a pixel polyline.
fn midpoint(points: &[(f32, f32)]) -> Option<(f32, f32)> {
    let seg = |w: &[(f32, f32)]| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1);
    let total: f32 = points.windows(2).map(seg).sum();
    let mut left = total / 2.0;
    for w in points.windows(2) {
        let l = seg(w);
        if l >= left && l > 0.0 {
            let t = left / l;
            return Some((w[0].0 + t * (w[1].0 - w[0].0), w[0].1 + t * (w[1].1 - w[0].1)));
        }
        left -= l;
    }
    points.first().copied()
}

fn draw_names(pm: &mut Pixmap, map: &MapData, id: TileId, near: &[FeatureRef]) {
    const SIZE_PX: f32 = 11.0;
    const MARGIN_PX: f32 = 2.0;
    let mut placed: Vec<LabelBox> = Vec::new();
    let mut names: std::collections::HashSet<String> = std::collections::HashSet::new();
    let px = |m: &DVec2| {
        let p = id.pixel_of_mercator(*m);
        (p.x as f32, p.y as f32)
    };
    let mut candidates: Vec<(u8, String, (f32, f32), f32)> = Vec::new(); // (priority, text, centre, room)
    for f in near {
        match *f {
            FeatureRef::Area(i) => {
                let (Some(a), Some(rings)) = (map.areas.get(i as usize), map.area_merc.get(i as usize))
                else {
                    continue;
                };
                let Some(name) = &a.name else { continue };
                let min_zoom = if a.kind == AreaKind::Building { 17 } else { 15 };
                if id.z < min_zoom {
                    continue;
                }
                let Some(outer) = rings.first() else { continue };
                let pts: Vec<(f32, f32)> = outer.iter().map(px).collect();
                let (x0, x1) = pts.iter().fold((f32::MAX, f32::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
                let (y0, y1) = pts.iter().fold((f32::MAX, f32::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
                candidates.push((1, name.clone(), (f32::midpoint(x0, x1), f32::midpoint(y0, y1)), x1 - x0));
            }
            FeatureRef::Line(i) => {
                let (Some(l), Some(m)) = (map.lines.get(i as usize), map.line_merc.get(i as usize)) else {
                    continue;
                };
                let Some(name) = &l.name else { continue };
                if id.z < 16 || !matches!(l.kind, LineKind::Path { tunnel: false, .. } | LineKind::Waterway) {
                    continue;
                }
                let pts: Vec<(f32, f32)> = m.iter().map(px).collect();
                // A name goes on a line at least as long as the name (streets are split into many short ways).
                let length: f32 = pts.windows(2).map(|w| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1)).sum();
                if let Some(c) = midpoint(&pts) {
                    candidates.push((0, name.clone(), c, length));
                }
            }
            FeatureRef::Barrier(_) => {}
        }
    }
    candidates.sort_by(|a, b| a.0.cmp(&b.0).then_with(|| a.1.cmp(&b.1)));
    for (_, text, (cx, cy), room) in candidates {
        let w = vestnav_plot::label_width(&text, SIZE_PX);
        if w > room {
            continue;
        }
        let b = LabelBox {
            x0: cx - w / 2.0 - 2.0,
            y0: cy - SIZE_PX * 0.7,
            x1: cx + w / 2.0 + 2.0,
            y1: cy + SIZE_PX * 0.7,
        };
        let inside = b.x0 >= MARGIN_PX
            && b.y0 >= MARGIN_PX
            && b.x1 <= TILE_SIZE as f32 - MARGIN_PX
            && b.y1 <= TILE_SIZE as f32 - MARGIN_PX;
        if !inside || placed.iter().any(|p| p.overlaps(&b)) || names.contains(&text) {
            continue;
        }
        vestnav_plot::draw_label(pm, &text, cx, cy, SIZE_PX, colors::LABEL, 1.5);
        placed.push(b);
        // Once per tile: a street's many ways would repeat its name.
        names.insert(text);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// FNV-1a's published 64-bit test vectors ("a", "foobar", the latter split in two parts), and the
    /// drawing's source hash against the same files read from disk now.
    #[test]
    fn the_source_hash_is_fnv1a_of_the_drawings_files() {
        assert_eq!(fnv1a(&[b""]), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(&[b"a"]), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(&[b"fo", b"obar"]), 0x8594_4171_f739_67e8);
        let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let files: Vec<Vec<u8>> =
            ["render.rs", "rules.rs", "map.rs"].iter().map(|f| std::fs::read(src.join(f)).unwrap()).collect();
        let parts: Vec<&[u8]> = files.iter().map(Vec::as_slice).collect();
        assert_eq!(RENDER_SOURCE_HASH, fnv1a(&parts));
    }
}
