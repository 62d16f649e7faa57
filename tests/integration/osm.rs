//! The offline OpenStreetMap through the binary: `route plan` on the Helsinki extract (© OpenStreetMap
//! contributors, `ODbL`; tests/data/osm) writes a GPX (the route and its path) that `nav simulate` walks to
//! the end in every run, guided along the path; `nav simulate --osm` plans the path itself; `map render`
//! draws a PNG; bad input is refused by name.

use std::path::PathBuf;
use std::process::Command;

use approx::assert_relative_eq;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn helsinki() -> String {
    root().join("tests/data/osm/helsinki.osm.pbf").to_str().unwrap().to_owned()
}

fn vestnav(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vestnav")).args(args).output().expect("run vestnav");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("vestnav-osm-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn all_runs_arrive(json: &str) {
    let v: serde_json::Value = serde_json::from_str(json).unwrap();
    for s in v["strategies"].as_array().unwrap() {
        assert_relative_eq!(s["summary"]["finish_rate"].as_f64().unwrap(), 1.0);
    }
}

#[test]
fn a_planned_walk_is_written_as_gpx_and_every_simulated_run_arrives() {
    let dir = temp_dir("plan");
    let gpx = dir.join("walk.gpx");
    let (ok, out, err) = vestnav(&[
        "route",
        "plan",
        "--osm",
        &helsinki(),
        "--from",
        "60.1700,24.9400",
        "--to",
        "60.1660,24.9500",
        "--gpx",
        gpx.to_str().unwrap(),
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let length = v["length_m"].as_f64().unwrap();
    assert!(
        length
            >= v["geodesic_m"].as_f64().unwrap()
                - v["from_snap_m"].as_f64().unwrap()
                - v["to_snap_m"].as_f64().unwrap()
    );
    assert!(v["points"].as_array().unwrap().len() > 10);
    let (ok, out, err) = vestnav(&[
        "nav",
        "simulate",
        "--route",
        gpx.to_str().unwrap(),
        "--strategy",
        "both",
        "--runs",
        "5",
        "--json",
    ]);
    assert!(ok, "{err}");
    all_runs_arrive(&out);
    // The GPX holds the walk's points as its route and the path as a track: guidance follows the path and
    // the cross-track error is measured from it.
    let sim: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(sim["waypoints"].as_u64(), Some(2), "Start and Goal");
    assert_eq!(sim["path_points"].as_u64(), Some(v["points"].as_array().unwrap().len() as u64));
    // The map of the same area with the route over it.
    let png = dir.join("map.png");
    let (ok, _, err) = vestnav(&[
        "map",
        "render",
        "--osm",
        &helsinki(),
        "--zoom",
        "17",
        "--route",
        gpx.to_str().unwrap(),
        "--png",
        png.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn nav_simulate_follows_paths_between_sparse_waypoints() {
    let dir = temp_dir("follow");
    let gpx = dir.join("two.gpx");
    std::fs::write(
        &gpx,
        r#"<?xml version="1.0"?><gpx version="1.1" creator="test" xmlns="http://www.topografix.com/GPX/1/1">
<rte><rtept lat="60.1700" lon="24.9400"><name>A</name></rtept><rtept lat="60.1660" lon="24.9500"><name>B</name></rtept>
<rtept lat="60.1690" lon="24.9520"><name>C</name></rtept></rte></gpx>"#,
    )
    .unwrap();
    let (ok, out, err) = vestnav(&[
        "nav",
        "simulate",
        "--route",
        gpx.to_str().unwrap(),
        "--osm",
        &helsinki(),
        "--profile",
        "prefer-footways",
        "--runs",
        "5",
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["waypoints"].as_u64(), Some(3), "the route's own waypoints A, B, C");
    assert!(v["path_points"].as_u64().unwrap() > 20, "a dense path expected: {}", v["path_points"]);
    all_runs_arrive(&out);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_extracts_and_unreachable_points_are_refused_by_name() {
    let dir = temp_dir("bad");
    let junk = dir.join("junk.osm.pbf");
    std::fs::write(&junk, b"not a pbf").unwrap();
    let (ok, _, err) = vestnav(&[
        "route",
        "plan",
        "--osm",
        junk.to_str().unwrap(),
        "--from",
        "60.17,24.94",
        "--to",
        "60.166,24.95",
    ]);
    assert!(!ok);
    assert!(err.contains("junk.osm.pbf") && err.contains("not a valid .osm.pbf"), "{err}");
    let (ok, _, err) =
        vestnav(&["route", "plan", "--osm", &helsinki(), "--from", "61.0,24.94", "--to", "60.166,24.95"]);
    assert!(!ok);
    assert!(err.contains("no walkable way within 300 m"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `vestnav station --map`: a file that is no extract (or a folder) is refused before the station starts,
/// naming it, with a non-zero exit; the Helsinki extract is read off the command thread and the station
/// says it re-routes on it (and its status says the network is there).
#[test]
fn station_map_refuses_a_bad_extract_and_reroutes_on_a_good_one() {
    let dir = temp_dir("station-map");
    let junk = dir.join("junk.osm.pbf");
    std::fs::write(&junk, b"not a pbf").unwrap();
    let station = |map: &str| {
        vestnav(&[
            "station",
            "--gps",
            "sim",
            "--vest",
            "emulated",
            "--status-every",
            "0",
            "--json",
            "--for",
            "5",
            "--map",
            map,
        ])
    };
    for bad in [junk.to_str().unwrap(), dir.to_str().unwrap()] {
        let (ok, out, err) = station(bad);
        assert!(!ok, "{bad} accepted: {out}");
        assert!(err.contains("--map") && err.contains(bad), "{err}");
        assert!(out.is_empty(), "the station started: {out}");
    }
    let (ok, out, err) = station(&helsinki());
    assert!(ok, "{err}");
    assert!(err.contains(&format!("re-routing on the paths of {}", helsinki())), "{err}");
    let last: serde_json::Value = serde_json::from_str(out.lines().last().unwrap()).unwrap();
    assert_eq!(last["path_network"], serde_json::Value::Bool(true), "{out}");
    let _ = std::fs::remove_dir_all(&dir);
}
