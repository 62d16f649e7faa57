//! `vestnav tiles prefetch` against a tile server on 127.0.0.1 started here: the tiles of the box over the
//! zooms and no others, into an MBTiles file that survives a SIGKILL mid-run and is resumed, with no more
//! requests in flight than `--parallel`; the bulk-download policy refusals; `--dry-run`; a redirect to
//! another host not followed (issue 21 item 7); a FIFO as the `--tiles` path refused at once.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use vestnav_tiles::{TileKey, TileSourceConfig};

#[path = "../support/tile_server.rs"]
mod tile_server;

use tile_server::{Tile, TileServer, expected_tiles};

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("vestnav-tiles-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Tiles in the MBTiles file, converted from TMS rows back to XYZ (`y = 2^z − 1 − tile_row`), with their
/// bytes' lengths.
fn file_tiles(path: &Path) -> BTreeMap<Tile, usize> {
    let c = rusqlite::Connection::open(path).unwrap();
    c.busy_timeout(Duration::from_secs(5)).unwrap();
    let mut st = c.prepare("SELECT zoom_level, tile_column, tile_row, length(tile_data) FROM tiles").unwrap();
    st.query_map([], |r| {
        let (z, x, row, len): (u8, u32, u32, i64) = (r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?);
        Ok(((z, x, (1u32 << z) - 1 - row), usize::try_from(len).unwrap_or(0)))
    })
    .unwrap()
    .map(Result::unwrap)
    .collect()
}

fn tile_count(path: &Path) -> usize {
    let Ok(c) = rusqlite::Connection::open_with_flags(path, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
    else {
        return 0;
    };
    let _ = c.busy_timeout(Duration::from_millis(200));
    c.query_row("SELECT COUNT(*) FROM tiles", [], |r| r.get::<_, i64>(0)).map_or(0, |n| n as usize)
}

fn integrity(path: &Path) -> String {
    let c = rusqlite::Connection::open(path).unwrap();
    c.query_row("PRAGMA integrity_check", [], |r| r.get(0)).unwrap()
}

// The area: a box at MIT, 100 m margin, zooms 13-18.
const BBOX: &str = "42.3570,-71.1000,42.3610,-71.0930";
const MARGIN_M: f64 = 100.0;
const ZOOM: (u8, u8) = (13, 18);
const PARALLEL: usize = 2;

fn prefetch_args(server: &TileServer, out: &Path) -> Vec<String> {
    [
        "tiles",
        "prefetch",
        "--source",
        &server.url(),
        "--allow-bulk",
        "--bbox",
        BBOX,
        "--margin-m",
        &MARGIN_M.to_string(),
        "--zoom",
        &format!("{}-{}", ZOOM.0, ZOOM.1),
        "--parallel",
        &PARALLEL.to_string(),
        "--out",
        out.to_str().unwrap(),
    ]
    .iter()
    .map(|s| (*s).to_owned())
    .collect()
}

/// The box grown by the margin exactly as the prefetch documents it: 1° of latitude = 111 320 m, 1° of
/// longitude = 111 320 m · cos(latitude) at the box's most poleward edge.
fn expected() -> BTreeSet<Tile> {
    let v: Vec<f64> = BBOX.split(',').map(|s| s.parse().unwrap()).collect();
    let (s, w, n, e) = (v[0], v[1], v[2], v[3]);
    let dlat = MARGIN_M / 111_320.0;
    let dlon = MARGIN_M / (111_320.0 * n.abs().max(s.abs()).to_radians().cos());
    expected_tiles(s - dlat, w - dlon, n + dlat, e + dlon, ZOOM.0, ZOOM.1)
}

#[test]
fn prefetch_into_mbtiles_survives_a_kill_and_resumes() {
    let dir = temp_dir("kill");
    let out = dir.join("area.mbtiles");
    let mut server = TileServer::start(Duration::from_millis(20));
    let expected = expected();
    assert!((80..2000).contains(&expected.len()), "{} tiles", expected.len());

    // First run, killed (SIGKILL) once some tiles are in the file.
    let mut child = Command::new(env!("CARGO_BIN_EXE_vestnav"))
        .args(prefetch_args(&server, &out))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while tile_count(&out) < 10 {
        assert!(t0.elapsed() < Duration::from_secs(30), "no tiles written");
        assert!(child.try_wait().unwrap().is_none(), "the prefetch ended before the kill");
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    // Requests the killed process had in flight have reached the server or never will: the server's count
    // stays the same for 300 ms (its threads may be scheduled late on a loaded machine).
    let mut first_requests = server.requested();
    let mut steady_since = Instant::now();
    while steady_since.elapsed() < Duration::from_millis(300) {
        assert!(t0.elapsed() < Duration::from_mins(1), "the server's requests settle");
        std::thread::sleep(Duration::from_millis(20));
        let now = server.requested();
        if now.len() != first_requests.len() {
            first_requests = now;
            steady_since = Instant::now();
        }
    }
    let after_kill = file_tiles(&out);
    assert_eq!(integrity(&out), "ok", "the killed run left a damaged file");
    assert!(after_kill.len() >= 10 && after_kill.len() < expected.len(), "{} tiles", after_kill.len());
    assert!(after_kill.values().all(|&l| l == server.png.len()), "a partial tile");
    assert!(after_kill.keys().all(|k| expected.contains(k)));

    // Second run: finishes the rest.
    let run =
        Command::new(env!("CARGO_BIN_EXE_vestnav")).args(prefetch_args(&server, &out)).output().unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(stderr.contains(&format!("{} tiles at zooms 13-18", expected.len())), "estimate first: {stderr}");
    assert!(stderr.contains(&format!("{} already there", after_kill.len())), "{stderr}");
    assert!(!stderr.contains("SECRET"), "the API key is never printed: {stderr}");

    // Each tile of the box requested once over both runs, except those in flight at the kill.
    let all = server.requested();
    let mut counts: BTreeMap<Tile, usize> = BTreeMap::new();
    for t in &all {
        *counts.entry(*t).or_default() += 1;
    }
    assert_eq!(counts.keys().copied().collect::<BTreeSet<_>>(), expected, "exactly the box's tiles");
    let twice: Vec<_> = counts.iter().filter(|(_, n)| **n > 1).collect();
    assert!(twice.len() <= PARALLEL && twice.iter().all(|(_, n)| **n == 2), "re-requested: {twice:?}");
    for (t, _) in &twice {
        assert!(first_requests.contains(t) && !after_kill.contains_key(t), "{t:?}");
    }
    let m = server.max_in_flight.load(Ordering::SeqCst);
    assert!((1..=PARALLEL).contains(&m), "max in flight {m}");

    // The file: exactly the expected tiles, in TMS rows, whole; valid SQLite; standard metadata.
    let tiles = file_tiles(&out);
    assert_eq!(tiles.keys().copied().collect::<BTreeSet<_>>(), expected);
    assert!(tiles.values().all(|&l| l == server.png.len()));
    assert_eq!(integrity(&out), "ok");
    let c = rusqlite::Connection::open(&out).unwrap();
    let meta = |n: &str| -> String {
        c.query_row("SELECT value FROM metadata WHERE name = ?1", [n], |r| r.get(0)).unwrap()
    };
    assert_eq!((meta("format"), meta("minzoom"), meta("maxzoom")), ("png".into(), "13".into(), "18".into()));
    assert!(!meta("name").is_empty() && !meta("bounds").is_empty());
    assert!(!meta("attribution").contains("SECRET"));
    drop(c);

    // With the server stopped, the file opens as a tile source.
    server.stop();
    let mut store = vestnav_tiles::store::open(&TileSourceConfig::MbTiles(out.clone()), &dir).unwrap();
    let &(z, x, y) = expected.iter().next_back().unwrap();
    let found = store.get(TileKey::new(z, x, y).unwrap()).unwrap().unwrap();
    assert_eq!(found.bytes, *server.png);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn refusals_and_dry_run_download_nothing() {
    let dir = temp_dir("refuse");
    let out = dir.join("x.mbtiles");
    let server = TileServer::start(Duration::from_millis(1));
    let run = |args: &[String]| Command::new(env!("CARGO_BIN_EXE_vestnav")).args(args).output().unwrap();
    let mut args = prefetch_args(&server, &out);

    // Without --allow-bulk: refused, as the console refuses an XYZ source without the tick.
    let no_ack: Vec<String> = args.iter().filter(|a| *a != "--allow-bulk").cloned().collect();
    let r = run(&no_ack);
    let e = String::from_utf8_lossy(&r.stderr);
    assert!(
        !r.status.success() && e.contains("not marked as allowing bulk") && e.contains("--allow-bulk"),
        "{e}"
    );
    assert!(!e.contains("SECRET"), "{e}");
    // The public OpenStreetMap server, by name or by URL, even with --allow-bulk.
    for osm in ["osm", "https://tile.openstreetmap.org/{z}/{x}/{y}.png"] {
        args[3] = osm.to_owned();
        let r = run(&args);
        let e = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && e.contains("forbids bulk download"), "{osm}: {e}");
    }
    // --dry-run: the estimate on stdout, nothing downloaded or written.
    args[3] = server.url();
    args.push("--dry-run".into());
    let r = run(&args);
    let o = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(o.contains(&format!("{} tiles at zooms 13-18", expected().len())) && o.contains("MB"), "{o}");
    assert!(server.requested().is_empty());
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Issue 21 item 7: a server that redirects every tile to another host (127.0.0.2 — a distinct host on
/// the loopback) makes the prefetch stop with the reason, and the other host is never asked.
#[test]
fn prefetch_follows_no_redirect_to_another_host() {
    let dir = temp_dir("redirect");
    let out = dir.join("area.mbtiles");
    let other = TileServer::start_on("127.0.0.2", Duration::ZERO, None);
    let first = TileServer::redirecting("127.0.0.1", other.base());
    let run = Command::new(env!("CARGO_BIN_EXE_vestnav")).args(prefetch_args(&first, &out)).output().unwrap();
    let e = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{e}");
    assert!(
        e.contains(&format!(
            "redirected to {}: not followed (prefetch only downloads from the host you named)",
            other.base()
        )),
        "{e}"
    );
    assert!(e.contains("not stored") && !e.contains("SECRET"), "{e}");
    assert!(other.requested().is_empty(), "the second host was asked: {:?}", other.requested());
    assert!((1..=PARALLEL).contains(&first.requested().len()), "stops at the first: {:?}", first.requested());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Issue 21 item 7: `--tiles` naming a FIFO is refused while the command line is parsed — the console
/// never starts, nothing opens the FIFO, nothing blocks.
#[cfg(unix)]
#[test]
fn a_fifo_as_the_tiles_path_is_refused_at_once() {
    let dir = temp_dir("fifo");
    for name in ["area.pmtiles", "area.mbtiles"] {
        let fifo = dir.join(name);
        assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        let mut child = Command::new(env!("CARGO_BIN_EXE_vestnav"))
            .arg("--tiles")
            .arg(&fifo)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let t0 = Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if t0.elapsed() > Duration::from_secs(20) {
                child.kill().unwrap();
                panic!("vestnav --tiles {name} (a FIFO) did not exit within 20 s");
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let mut err = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
        assert!(!status.success(), "{err}");
        assert!(err.contains("FIFO (named pipe), not a regular file") && err.contains(name), "{err}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
