//! Hostile tile inputs (issue 21, item 7), each with real parts: a FIFO made with `mkfifo` in a tile
//! folder and as the PMTiles/MBTiles path, a real PNG whose header declares 20000x20000 px stored in an
//! MBTiles file and a tile folder, and tile servers on 127.0.0.1 and 127.0.0.2 (two hosts) that redirect.
//! Every wait is bounded: a loader that blocked would fail the test instead of hanging it.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use vestnav_tiles::loader::{Loaded, TileLoader};
use vestnav_tiles::mbtiles::{MbTilesMeta, MbTilesWriter};
use vestnav_tiles::prefetch::{Prefetch, PrefetchRequest, PrefetchTarget};
use vestnav_tiles::{BBox, MAX_TILE_PX, TileKey, TileSourceConfig, parse_tiles_spec};

#[path = "../../../tests/support/tile_server.rs"]
mod tile_server;

use tile_server::{TileServer, png_declaring, solid_png};

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("vestnav-tiles-hostile-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn mkfifo(path: &Path) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let ok = std::process::Command::new("mkfifo").arg(path).status().unwrap().success();
    assert!(ok, "mkfifo {}", path.display());
}

/// Runs `f` on its own thread and waits at most `limit` for it: a call that blocks (on a FIFO) fails
/// the test instead of hanging it.
fn bounded<T: Send + 'static>(limit: Duration, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(limit).expect("blocked: no answer within the time limit")
}

/// Asks the loader for `key` and waits (at most 10 s) for what became of it.
fn load_one(loader: &TileLoader, key: TileKey) -> Loaded {
    loader.request(key);
    let t0 = Instant::now();
    loop {
        if let Some((_, l)) = loader.take_done().into_iter().find(|(k, _)| *k == key) {
            return l;
        }
        assert!(t0.elapsed() < Duration::from_secs(10), "tile {key:?} still loading after 10 s");
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn no_waker() -> vestnav_tiles::Waker {
    Arc::new(|| {})
}

fn refused(l: &Loaded) -> &str {
    match l {
        Loaded::Refused(why) => why,
        other => panic!("expected a refusal, got {other:?}"),
    }
}

#[test]
fn a_fifo_in_a_tile_folder_is_refused_and_never_blocks() {
    let dir = temp_dir("fifo-folder");
    let png = solid_png([1, 2, 3]);
    for (x, y) in [(0, 0), (1, 0), (0, 1)] {
        let p = dir.join(format!("1/{x}/{y}.png"));
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, &png).unwrap();
    }
    let fifo = dir.join("1/1/1.png");
    mkfifo(&fifo);
    let loader = TileLoader::start(&TileSourceConfig::Folder(dir.clone()), &dir, &no_waker());
    let why = load_one(&loader, TileKey::new(1, 1, 1).unwrap());
    let why = refused(&why);
    assert!(why.contains("tile 1/1/1 of") && why.contains("1/1/1.png"), "{why}");
    assert!(why.contains("FIFO (named pipe), not a regular file"), "{why}");
    // The loader is not stuck: the next tile still comes.
    assert!(matches!(load_one(&loader, TileKey::new(1, 0, 1).unwrap()), Loaded::Image(..)));
    assert!(loader.last_error().unwrap().contains("FIFO"));
    // A tile absent from the folder is absent, not refused.
    assert_eq!(load_one(&loader, TileKey::new(0, 0, 0).unwrap()), Loaded::Absent);
    drop(loader);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_fifo_as_the_pmtiles_or_mbtiles_file_is_refused_and_never_blocks() {
    let dir = temp_dir("fifo-file");
    for name in ["area.pmtiles", "area.mbtiles"] {
        let fifo = dir.join(name);
        mkfifo(&fifo);
        // `--tiles FILE` refuses it while parsing the command line.
        let spec = fifo.display().to_string();
        let e = bounded(Duration::from_secs(5), move || parse_tiles_spec(&spec)).unwrap_err();
        assert!(e.contains("FIFO (named pipe), not a regular file") && e.contains(name), "{e}");
        // A remembered source that has become a FIFO: the loader reports it, promptly.
        let source = if name.ends_with("pmtiles") {
            TileSourceConfig::PmTiles(fifo.clone())
        } else {
            TileSourceConfig::MbTiles(fifo.clone())
        };
        let loader = TileLoader::start(&source, &dir, &no_waker());
        let t0 = Instant::now();
        let state = loop {
            if let Some(s) = loader.open_state() {
                break s;
            }
            assert!(t0.elapsed() < Duration::from_secs(10), "{name}: the loader is stuck opening");
            std::thread::sleep(Duration::from_millis(5));
        };
        let e = state.unwrap_err();
        assert!(e.contains(name) && e.contains("refused: a FIFO"), "{e}");
    }
    // The prefetch's MBTiles writer refuses it too (SQLite never opens it).
    let fifo = dir.join("area.mbtiles");
    let meta = MbTilesMeta {
        name: "t".into(),
        bbox: BBox { min_lat: 0.0, min_lon: 0.0, max_lat: 1.0, max_lon: 1.0 },
        min_zoom: 0,
        max_zoom: 1,
        attribution: String::new(),
    };
    let e =
        bounded(Duration::from_secs(5), move || MbTilesWriter::open(&fifo, &meta).err().unwrap().to_string());
    assert!(e.contains("FIFO"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_png_declaring_20000_px_is_refused_with_the_reason_in_mbtiles_and_folders() {
    let dir = temp_dir("bomb");
    let bomb = png_declaring(20_000);
    // The image crate (an independent reader) agrees the header says 20000x20000.
    let dims = image::ImageReader::with_format(std::io::Cursor::new(&bomb), image::ImageFormat::Png)
        .into_dimensions()
        .unwrap();
    assert_eq!(dims, (20_000, 20_000));
    let want = format!("PNG declares 20000x20000 px, more than {MAX_TILE_PX} px a side");

    // An MBTiles file: tile 1/1/0 (TMS row 1) is the bomb, 1/0/0 a real tile.
    let mb = dir.join("area.mbtiles");
    let c = rusqlite::Connection::open(&mb).unwrap();
    c.execute_batch(
        "CREATE TABLE metadata (name TEXT, value TEXT);
         CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER, tile_data BLOB);
         INSERT INTO metadata VALUES ('format', 'png'), ('minzoom', '0'), ('maxzoom', '1');",
    )
    .unwrap();
    c.execute("INSERT INTO tiles VALUES (1, 1, 1, ?1)", [&bomb]).unwrap();
    c.execute("INSERT INTO tiles VALUES (1, 0, 1, ?1)", [&solid_png([9, 9, 9])]).unwrap();
    drop(c);
    let loader = TileLoader::start(&TileSourceConfig::MbTiles(mb.clone()), &dir, &no_waker());
    let l = load_one(&loader, TileKey::new(1, 1, 0).unwrap());
    let why = refused(&l);
    assert_eq!(why, format!("tile 1/1/0 of {} refused: {want}", mb.display()));
    assert!(matches!(load_one(&loader, TileKey::new(1, 0, 0).unwrap()), Loaded::Image(..)));
    assert_eq!(load_one(&loader, TileKey::new(1, 1, 1).unwrap()), Loaded::Absent);
    drop(loader);

    // A tile folder.
    let folder = dir.join("tiles");
    let p = folder.join("2/3/1.png");
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    std::fs::write(&p, &bomb).unwrap();
    let loader = TileLoader::start(&TileSourceConfig::Folder(folder), &dir, &no_waker());
    let l = load_one(&loader, TileKey::new(2, 3, 1).unwrap());
    assert_eq!(refused(&l), format!("tile 2/3/1 of {} refused: {want}", p.display()));
    drop(loader);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The console's fetch path (the loader's HTTP store): a redirect to another host is not followed — the
/// second host is never asked — and the refusal says where it pointed; a same-host redirect is followed.
#[test]
fn the_map_follows_no_redirect_to_another_host() {
    let dir = temp_dir("redirect-map");
    let other = TileServer::start_on("127.0.0.2", Duration::ZERO, None);
    let first = TileServer::redirecting("127.0.0.1", other.base());
    let source = TileSourceConfig::Xyz { url: first.url(), attribution: String::new(), allows_bulk: false };
    let loader = TileLoader::start(&source, &dir, &no_waker());
    let l = load_one(&loader, TileKey::new(3, 2, 1).unwrap());
    let why = refused(&l);
    assert!(
        why.contains(&format!(
            "redirected to {}: not followed (the map only downloads from the host you named)",
            other.base()
        )),
        "{why}"
    );
    assert!(why.starts_with("tile 3/2/1 of http://127.0.0.1:") && !why.contains("SECRET"), "{why}");
    assert_eq!(first.requested(), vec![(3, 2, 1)]);
    assert!(other.requested().is_empty(), "the second host was asked: {:?}", other.requested());
    drop(loader);

    // Same host, other path: followed.
    let same = TileServer::start(Duration::ZERO);
    let url = format!("{}/r/{{z}}/{{x}}/{{y}}.png", same.base());
    let source = TileSourceConfig::Xyz { url, attribution: String::new(), allows_bulk: false };
    let loader = TileLoader::start(&source, &dir.join("same"), &no_waker());
    match load_one(&loader, TileKey::new(3, 2, 1).unwrap()) {
        Loaded::Image(img, _) => assert_eq!((img.width, img.height), (256, 256)),
        other => panic!("{other:?}"),
    }
    assert_eq!(same.requested(), vec![(3, 2, 1), (3, 2, 1)], "the redirect and its target");
    drop(loader);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The prefetch: the first cross-host redirect stops it; nothing reaches the second host.
#[test]
fn prefetch_follows_no_redirect_to_another_host() {
    let dir = temp_dir("redirect-prefetch");
    let other = TileServer::start_on("127.0.0.2", Duration::ZERO, None);
    let first = TileServer::redirecting("127.0.0.1", other.base());
    let req = PrefetchRequest {
        source: TileSourceConfig::Xyz { url: first.url(), attribution: String::new(), allows_bulk: true },
        bbox: BBox { min_lat: 42.35, min_lon: -71.11, max_lat: 42.37, max_lon: -71.08 },
        z0: 12,
        z1: 15,
        parallelism: 2,
        target: PrefetchTarget::Cache(dir.clone()),
    };
    let s = bounded(Duration::from_secs(30), move || Prefetch::start(&req, None).unwrap().join());
    assert!(s.total > 18, "{s:?}");
    assert_eq!(s.fetched, 0);
    assert!((1..=2).contains(&s.failed), "stopped at the first redirect (one per worker): {s:?}");
    let e = s.last_error.unwrap();
    assert!(
        e.contains(&format!(
            "redirected to {}: not followed (prefetch only downloads from the host you named)",
            other.base()
        )),
        "{e}"
    );
    assert!(other.requested().is_empty(), "the second host was asked: {:?}", other.requested());
    assert!(first.requested().len() <= 2);
    std::fs::remove_dir_all(&dir).unwrap();
}
