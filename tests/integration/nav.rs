//! Integration tests: geodesy + guidance + field tests across the crates, and the `nav` / `fieldtest` CLI.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use approx::assert_relative_eq;
use vestnav_core::fieldtest::{TimedFix, drift};
use vestnav_core::geo::{Earth, LatLon};
use vestnav_core::gnss_sim::{GnssErrorModel, GnssErrorState};

/// A flat east/north frame on WGS-84's radii of curvature at the origin (meridional `M`, prime vertical
/// `N`): `east = dlon N cos(phi0)`, `north = dlat M`. An independent formula, good to ~1e-5 relative over
/// a few hundred metres, to check core's geodesic `LocalFrame` against.
struct SimFrame {
    lat0_deg: f64,
    lon0_deg: f64,
    m_per_rad_north: f64,
    m_per_rad_east: f64,
}

impl SimFrame {
    fn new(lat0_deg: f64, lon0_deg: f64) -> Self {
        let (a_m, e2) = (6_378_137.0, 6.694_379_990_14e-3);
        let phi = f64::to_radians(lat0_deg);
        let w = 1.0 - e2 * phi.sin().powi(2);
        Self {
            lat0_deg,
            lon0_deg,
            m_per_rad_north: a_m * (1.0 - e2) / w.powf(1.5),
            m_per_rad_east: a_m / w.sqrt() * phi.cos(),
        }
    }

    fn en_from_latlon(&self, lat_deg: f64, lon_deg: f64) -> vestnav_core::geo::DVec2 {
        vestnav_core::geo::DVec2::new(
            (lon_deg - self.lon0_deg).to_radians() * self.m_per_rad_east,
            (lat_deg - self.lat0_deg).to_radians() * self.m_per_rad_north,
        )
    }

    fn latlon_from_en(&self, en: vestnav_core::geo::DVec2) -> (f64, f64) {
        (
            self.lat0_deg + (en.y / self.m_per_rad_north).to_degrees(),
            self.lon0_deg + (en.x / self.m_per_rad_east).to_degrees(),
        )
    }
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn logs() -> PathBuf {
    root().join("tests/data/gpsd-logs")
}

fn vestnav(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vestnav")).args(args).output().expect("run vestnav");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn json(args: &[&str]) -> serde_json::Value {
    let (ok, out, err) = vestnav(args);
    assert!(ok, "vestnav {args:?} failed: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("not JSON ({e}): {out}"))
}

fn timed_fixes(path: &Path) -> Vec<TimedFix> {
    let file = std::fs::File::open(path).unwrap();
    let (fixes, _) = vestnav_device::gps::decode_reader(std::io::BufReader::new(file)).unwrap();
    fixes
        .iter()
        .filter(|f| f.has_position())
        .enumerate()
        .map(|(i, f)| TimedFix { t_s: i as f64, pos: LatLon::new(f.lat_deg.unwrap(), f.lon_deg.unwrap()) })
        .collect()
}

/// Drift on gpsd's stationary logs against an independent computation: python geographiclib 2.0 (Karney's
/// own code), positions from the GGA sentences with a valid checksum and quality > 0, mean = arithmetic
/// mean of latitude and longitude (not our local-frame mean), distances from it by `Geodesic.WGS84.Inverse`,
/// nearest-rank percentiles (the script is in docs/field-tests.md). Output, pasted:
/// ```text
/// telit-he910:  n=187 max_first=4.522333 cep50=1.380542 cep95=2.301232 drms=1.482050 2drms=2.964100
/// skytraq-dgps: n=96  max_first=1.615649 cep50=0.407772 cep95=0.972919 drms=0.509834 2drms=1.019668
/// ublox-zed-f9p_hpg1.11: n=655 max_first=2.801796 cep50=1.284013 cep95=2.217637 drms=1.424184
/// ```
#[test]
fn drift_on_gpsd_stationary_logs_matches_geographiclib() {
    let cases = [
        ("telit-he910.log", 187, 4.522_333, 1.380_542, 2.301_232, 1.482_050),
        ("skytraq-dgps.log", 96, 1.615_649, 0.407_772, 0.972_919, 0.509_834),
        ("ublox-zed-f9p_hpg1.11.log", 655, 2.801_796, 1.284_013, 2.217_637, 1.424_184),
    ];
    for (file, n, max_first, cep50, cep95, drms) in cases {
        let s = drift(&timed_fixes(&logs().join(file)), Earth::Wgs84).unwrap();
        assert_eq!(s.fixes, n, "{file}");
        assert_relative_eq!(s.max_from_first_m, max_first, max_relative = 1e-5);
        assert_relative_eq!(s.cep50_m, cep50, max_relative = 1e-5);
        assert_relative_eq!(s.cep95_m, cep95, max_relative = 1e-5);
        assert_relative_eq!(s.drms_m, drms, max_relative = 1e-5);
        assert_relative_eq!(s.twodrms_m, 2.0 * drms, max_relative = 1e-5);
    }
}

#[test]
fn drift_cli_json_keys_and_pinning_warning() {
    let v = json(&["fieldtest", "drift", "--json", logs().join("skytraq-dgps.log").to_str().unwrap()]);
    for key in ["max_from_first_m", "cep50_m", "cep95_m", "drms_m", "twodrms_m", "fixes"] {
        assert!(v.get(key).is_some(), "missing {key}: {v}");
    }
    assert_eq!(v["fixes"], 96);
    assert_relative_eq!(v["cep95_m"].as_f64().unwrap(), 0.972_919, max_relative = 1e-5);
    // nd-1005 (SiRF III): all 16 positions identical -> the pinning warning.
    let v = json(&["fieldtest", "drift", "--json", logs().join("nd-1005.log").to_str().unwrap()]);
    assert_eq!(v["warnings"].as_array().unwrap().len(), 1, "{v}");
    let png = std::env::temp_dir().join(format!("vestnav-drift-{}.png", std::process::id()));
    let (ok, _, err) = vestnav(&[
        "fieldtest",
        "drift",
        logs().join("telit-he910.log").to_str().unwrap(),
        "--png",
        png.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    let _ = std::fs::remove_file(png);
    // A file that is not NMEA at all: a clear error, no panic.
    let (ok, _, err) = vestnav(&["fieldtest", "drift", root().join("Cargo.toml").to_str().unwrap()]);
    assert!(!ok && err.contains("no positioned fixes"), "{err}");
}

fn nmea(body: &str) -> String {
    let ck = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{ck:02X}\r\n")
}

fn ddmm(value: f64, pos: char, neg: char, deg_digits: usize) -> (String, char) {
    let a = value.abs();
    let d = a.trunc();
    let m = (a - d) * 60.0;
    (format!("{:0w$}{:09.6}", d as u32, m, w = deg_digits), if value >= 0.0 { pos } else { neg })
}

/// A synthetic cone walk: cones every `spacing_m` on a line from `start` at `bearing_deg`; the walker
/// walks at `pace_m_s`, stands `dwell_s` at each cone (the operator marks the cone on arrival), and the
/// receiver's output goes through `model`. Returns the NMEA log and the positions the log reports at the
/// marks, as east/north of the GPS simulator's own flat frame (an independent formula).
fn cone_log(model: GnssErrorModel, seed: u64, pace_m_s: f64, dwell_s: u32) -> (String, Vec<(f64, f64)>) {
    let (cones, spacing_m, bearing_deg) = (10, 10.0, 30.0);
    let start = LatLon::new(42.3575, -71.1010);
    let frame = SimFrame::new(start.lat_deg, start.lon_deg);
    let mut err = GnssErrorState::new(model, seed);
    let mut log = String::new();
    let mut marked = Vec::new();
    let mut t = 0u32;
    let walk_s = (spacing_m / pace_m_s).ceil() as u32;
    for k in 0..cones {
        let segment: Vec<(f64, bool)> = if k == 0 {
            (0..=dwell_s).map(|i| (0.0, i == 0)).collect()
        } else {
            let mut v: Vec<(f64, bool)> = (1..=walk_s)
                .map(|i| ((f64::from(k - 1) + f64::from(i) / f64::from(walk_s)) * spacing_m, false))
                .collect();
            v.last_mut().unwrap().1 = true;
            v.extend((0..dwell_s).map(|_| (f64::from(k) * spacing_m, false)));
            v
        };
        for (along_m, mark_now) in segment {
            let truth = Earth::Wgs84.direct(start, bearing_deg, along_m);
            let en = frame.en_from_latlon(truth.lat_deg, truth.lon_deg);
            let moving = !mark_now && along_m < f64::from(k) * spacing_m;
            let reported = err.apply(1.0, en, if moving { pace_m_s } else { 0.0 });
            let (lat, lon) = frame.latlon_from_en(reported);
            let tod = format!("{:02}{:02}{:02}.00", 15 + t / 3600, (t / 60) % 60, t % 60);
            let (la, ns) = ddmm(lat, 'N', 'S', 2);
            let (lo, ew) = ddmm(lon, 'E', 'W', 3);
            log.push_str(&nmea(&format!("GPGGA,{tod},{la},{ns},{lo},{ew},1,08,1.0,10.0,M,-33.0,M,,")));
            log.push_str(&nmea(&format!("GPRMC,{tod},A,{la},{ns},{lo},{ew},0.0,30.0,150625,,,A")));
            if mark_now {
                let _ = write!(log, "{}", nmea(&format!("PVNAV,MARK,{},cone {}", k + 1, k + 1)));
                // What the log says at the mark, re-read through the same 6-decimal rounding.
                let q = frame.en_from_latlon(
                    (lat * 60.0 * 1e6).round() / 60.0 / 1e6,
                    (lon * 60.0 * 1e6).round() / 60.0 / 1e6,
                );
                marked.push((q.x, q.y));
            }
            t += 1;
        }
    }
    (log, marked)
}

fn write_tmp(name: &str, text: &str) -> PathBuf {
    let p = std::env::temp_dir().join(format!("vestnav-{}-{name}", std::process::id()));
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn cone_test_with_a_perfect_receiver_measures_the_spacing() {
    let (log, marked) = cone_log(GnssErrorModel::perfect(), 1, 1.4, 2);
    assert_eq!(marked.len(), 10);
    let path = write_tmp("cones-perfect.nmea", &log);
    let v =
        json(&["fieldtest", "cones", path.to_str().unwrap(), "--spacing-m", "10", "--count", "10", "--json"]);
    assert_eq!(v["marks"], 10);
    for d in v["distances_m"].as_array().unwrap() {
        assert_relative_eq!(d.as_f64().unwrap(), 10.0, max_relative = 1e-3);
    }
    assert!(v["rmse_m"].as_f64().unwrap() < 0.01, "{v}");
    assert!(v["cross_rms_m"].as_f64().unwrap() < 0.01, "{v}");
    assert_relative_eq!(v["line_bearing_deg"].as_f64().unwrap(), 30.0, epsilon = 0.05);
    assert!(v["warnings"].as_array().unwrap().is_empty(), "{v}");
    // Laid out by compass: magnetic 44.2 deg with WMM declination (~-14.2 in Cambridge, June 2025) = 30 true.
    let v = json(&[
        "fieldtest",
        "cones",
        path.to_str().unwrap(),
        "--line-bearing-deg",
        "44.2",
        "--magnetic",
        "--json",
    ]);
    let decl = v["declination_deg"].as_f64().unwrap();
    assert!((-14.8..-13.6).contains(&decl), "{decl}");
    assert_relative_eq!(v["line_bearing_deg"].as_f64().unwrap(), 44.2 + decl, max_relative = 1e-9);
    let png = write_tmp("cones.png", "");
    let (ok, _, err) =
        vestnav(&["fieldtest", "cones", path.to_str().unwrap(), "--png", png.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    let _ = std::fs::remove_file(png);
    let _ = std::fs::remove_file(path);
}

#[test]
fn cone_test_with_gps_error_matches_the_generated_truth() {
    let (log, marked) = cone_log(GnssErrorModel::sirf3_no_static_nav(), 42, 1.4, 2);
    let path = write_tmp("cones-noisy.nmea", &log);
    let v = json(&["fieldtest", "cones", path.to_str().unwrap(), "--spacing-m", "10", "--json"]);
    // Expected from the generator's own flat frame (radii of curvature; not our geodesics).
    let want: Vec<f64> =
        marked.windows(2).map(|w| ((w[1].0 - w[0].0).powi(2) + (w[1].1 - w[0].1).powi(2)).sqrt()).collect();
    let got: Vec<f64> = v["distances_m"].as_array().unwrap().iter().map(|d| d.as_f64().unwrap()).collect();
    assert_eq!(got.len(), 9);
    for (g, w) in got.iter().zip(&want) {
        assert_relative_eq!(*g, *w, max_relative = 2e-3, epsilon = 2e-3);
    }
    let rmse = (want.iter().map(|d| (d - 10.0).powi(2)).sum::<f64>() / want.len() as f64).sqrt();
    assert_relative_eq!(v["rmse_m"].as_f64().unwrap(), rmse, max_relative = 2e-3);
    assert!(rmse > 0.1, "the error model must show: {rmse}");
    let _ = std::fs::remove_file(path);
}

#[test]
fn cone_test_warns_when_static_navigation_pins_the_receiver() {
    // Standing 8 s at each cone with SiRF static navigation: runs of identical fixes.
    let (log, _) = cone_log(GnssErrorModel::sirf3_open_sky(), 7, 1.4, 8);
    let path = write_tmp("cones-pinned.nmea", &log);
    let v = json(&["fieldtest", "cones", path.to_str().unwrap(), "--json"]);
    let warnings = v["warnings"].as_array().unwrap();
    assert!(warnings.iter().any(|w| w.as_str().unwrap().contains("static navigation")), "{v}");
    let _ = std::fs::remove_file(path);
}

#[test]
fn demo_route_loads_and_both_strategies_finish_it() {
    let v = json(&[
        "nav",
        "simulate",
        "--route",
        root().join("assets/routes/demo.gpx").to_str().unwrap(),
        "--strategy",
        "both",
        "--runs",
        "4",
        "--json",
    ]);
    assert_eq!(v["waypoints"], 7);
    let strategies = v["strategies"].as_array().unwrap();
    assert_eq!(strategies.len(), 2);
    for s in strategies {
        let summary = &s["summary"];
        assert_relative_eq!(summary["finish_rate"].as_f64().unwrap(), 1.0);
        assert!(summary["cross_track_rmse_m"]["mean"].as_f64().unwrap() < 10.0, "{summary}");
        for run in s["runs"].as_array().unwrap() {
            // Never faster than walking the route at the pace, minus one arrival radius at each end.
            let t = run["time_s"].as_f64().unwrap();
            let nominal = run["nominal_time_s"].as_f64().unwrap();
            assert!(t > nominal - 2.0 * 8.0 / 1.4 && t < 2.0 * nominal, "{run}");
        }
    }
    let (ok, _, err) = vestnav(&["nav", "simulate", "--route", "/nonexistent.gpx"]);
    assert!(!ok && err.contains("nonexistent"), "{err}");
}

/// `nav simulate` keeps each waypoint's own arrival radius from the GPX (vestnav's extension): with a
/// 150 m radius on the far end of a 400 m leg, every run arrives about 150 m earlier than with the global 8 m.
#[test]
fn nav_simulate_keeps_per_waypoint_arrival_radii() {
    let gpx = |radius: Option<f64>| {
        let ext = radius.map_or_else(String::new, |r| {
            format!("<extensions><vestnav:arrival_radius_m>{r}</vestnav:arrival_radius_m></extensions>")
        });
        format!(
            "<?xml version=\"1.0\"?>\n<gpx version=\"1.1\" creator=\"t\" xmlns=\"http://www.topografix.com/GPX/1/1\" \
             xmlns:vestnav=\"{}\"><rte><rtept lat=\"42.3550\" lon=\"-71.1000\"><name>A</name></rtept>\
             <rtept lat=\"42.3586\" lon=\"-71.1000\"><name>B</name>{ext}</rtept></rte></gpx>",
            vestnav_device::route_file::VESTNAV_GPX_NS
        )
    };
    let mean_time = |radius: Option<f64>| {
        let path = write_tmp(&format!("radii-{radius:?}.gpx"), &gpx(radius));
        let back = vestnav_device::route_file::read_gpx(&path).unwrap().default_route().unwrap();
        assert_eq!(back.waypoints[1].arrival_radius_m, radius, "the file carries the radius");
        let v = json(&["nav", "simulate", "--route", path.to_str().unwrap(), "--runs", "4", "--json"]);
        let runs = v["strategies"][0]["runs"].as_array().unwrap().clone();
        assert!(runs.iter().all(|r| r["finished"].as_bool() == Some(true)), "{v}");
        let _ = std::fs::remove_file(path);
        runs.iter().map(|r| r["time_s"].as_f64().unwrap()).sum::<f64>() / runs.len() as f64
    };
    let (global, own) = (mean_time(None), mean_time(Some(150.0)));
    // 142 m less to walk at 1.4 m/s is about 100 s; allow for the walker's wander.
    assert!(global - own > 60.0, "global radius {global:.0} s, own 150 m radius {own:.0} s");
}

#[test]
fn demo_route_is_a_few_hundred_metres_on_briggs_field() {
    let text = std::fs::read_to_string(root().join("assets/routes/demo.gpx")).unwrap();
    let gpx = vestnav_device::route_file::parse_gpx(&text).unwrap().default_route().unwrap();
    assert!((6..=8).contains(&gpx.waypoints.len()));
    let pts: Vec<LatLon> = gpx.waypoints.iter().map(|w| LatLon::new(w.lat_deg, w.lon_deg)).collect();
    let length: f64 = pts.windows(2).map(|w| Earth::Wgs84.distance_m(w[0], w[1])).sum();
    assert!((300.0..1000.0).contains(&length), "{length}");
    let briggs = LatLon::new(42.3575, -71.1010);
    assert!(pts.iter().all(|p| Earth::Wgs84.distance_m(*p, briggs) < 300.0));
}

/// One console session-log line (the app's own record type and serialisation).
fn session_line(t_s: f64, entry: vestnav_device::session_log::LogEntry) -> String {
    let whole_s = t_s.floor() as u32;
    let utc =
        format!("2026-06-15T15:{:02}:{:02}.{:03}Z", whole_s / 60, whole_s % 60, ((t_s.fract()) * 1e3) as u32);
    let rec = vestnav_device::session_log::LogRecord { t_s, utc, entry };
    let mut line = serde_json::to_string(&rec).unwrap();
    line.push('\n');
    line
}

fn session_fix(t_s: f64, p: LatLon) -> String {
    session_line(
        t_s,
        vestnav_device::session_log::LogEntry::Fix {
            lat_deg: p.lat_deg,
            lon_deg: p.lon_deg,
            error_m: Some(2.5),
            speed_m_s: None,
            course_deg: None,
            gps_utc: None,
        },
    )
}

#[test]
fn cone_test_reads_a_console_session_log() {
    use vestnav_device::session_log::LogEntry;
    // Cones every 10 m on a 75 deg line (geodesic direct from the first cone); 1 Hz fixes that do not fall on
    // whole session seconds; the walker stands 3 s at each cone and the operator marks 0.4 s after the first
    // fix there. Odd marks carry the position the console recorded, and their arrival fix record is missing
    // (dropped by a full log queue), so only the recorded position is right; even marks carry none (the CLI
    // then takes the latest fix at or before the mark). Acks and notes are interleaved, as the console
    // writes them.
    let (start, bearing_deg, spacing_m, pace_m_s) = (LatLon::new(42.3581, -71.0936), 75.0, 10.0, 1.25);
    let cone = |k: u32| Earth::Wgs84.direct(start, bearing_deg, f64::from(k) * spacing_m);
    let mut text = session_line(0.0, LogEntry::Note { text: "GPS connected".into() });
    let mut t_s = 3.2;
    for k in 0..10u32 {
        if k > 0 {
            for i in 1..8u32 {
                let along_m = (f64::from(k - 1) + f64::from(i) * pace_m_s / spacing_m) * spacing_m;
                text.push_str(&session_fix(t_s, Earth::Wgs84.direct(start, bearing_deg, along_m)));
                t_s += 1.0;
            }
        }
        let recorded = (k % 2 == 1).then(|| cone(k));
        if recorded.is_none() {
            text.push_str(&session_fix(t_s, cone(k)));
        }
        text.push_str(&session_line(
            t_s + 0.4,
            LogEntry::Mark {
                label: format!("cone {}", k + 1),
                lat_deg: recorded.map(|p| p.lat_deg),
                lon_deg: recorded.map(|p| p.lon_deg),
            },
        ));
        text.push_str(&session_line(t_s + 0.45, LogEntry::Ack { what: "fire".into() }));
        for _ in 0..3 {
            t_s += 1.0;
            text.push_str(&session_fix(t_s, cone(k)));
        }
    }
    assert!(text.starts_with('{'));
    let path = write_tmp("cones-session.jsonl", &text);
    let v = json(&["fieldtest", "cones", path.to_str().unwrap(), "--spacing-m", "10", "--json"]);
    assert_eq!(v["format"], "session");
    assert_eq!(v["marks"], 10);
    let labels: Vec<String> = (1..=10).map(|k| format!("cone {k}")).collect();
    assert_eq!(v["labels"], serde_json::json!(labels));
    // Truth: the cones are 10 m apart by construction (direct problem), so each distance is 10 m.
    let got: Vec<f64> = v["distances_m"].as_array().unwrap().iter().map(|d| d.as_f64().unwrap()).collect();
    assert_eq!(got.len(), 9);
    for d in &got {
        assert_relative_eq!(*d, spacing_m, max_relative = 1e-6);
    }
    assert!(v["rmse_m"].as_f64().unwrap() < 1e-5, "{v}");
    assert!(v["cross_rms_m"].as_f64().unwrap() < 1e-3, "{v}");
    assert_relative_eq!(v["line_bearing_deg"].as_f64().unwrap(), bearing_deg, epsilon = 0.01);
    // Forcing the wrong format is refused, not misread.
    let (ok, _, err) = vestnav(&["fieldtest", "cones", path.to_str().unwrap(), "--format", "nmea"]);
    assert!(!ok && !err.contains("panicked"), "{err}");
    // A last line cut off mid-write (the console stopped) is skipped with a warning.
    let cut = format!("{text}{{\"t_s\":99.0,\"utc\":\"2026-06-15T15:01:39.000Z\",\"kind\":\"fi");
    let cut_path = write_tmp("cones-session-cut.jsonl", &cut);
    let v = json(&["fieldtest", "cones", cut_path.to_str().unwrap(), "--json"]);
    assert_eq!(v["marks"], 10);
    let warnings = v["warnings"].as_array().unwrap();
    assert!(warnings.iter().any(|w| w.as_str().unwrap().contains("cut off")), "{v}");
    let _ = std::fs::remove_file(cut_path);
    let _ = std::fs::remove_file(path);
}

/// One bad fix never poisons a log: a fix out of range is skipped, counted and named, the rest analysed.
#[test]
fn session_log_with_an_invalid_fix_is_analysed_without_it() {
    let p = LatLon::new(42.3581, -71.0936);
    let bad = "{\"t_s\":2.0,\"utc\":\"x\",\"kind\":\"fix\",\"lat_deg\":9999.0,\"lon_deg\":-71.0,\"error_m\":null,\
               \"speed_m_s\":null,\"course_deg\":null,\"gps_utc\":null}\n";
    let text = format!("{}\n{bad}{}\n{}\n", session_fix(1.0, p), session_fix(3.0, p), session_fix(4.0, p));
    let path = write_tmp("session-one-bad-fix.jsonl", &text);
    let v = json(&["fieldtest", "drift", path.to_str().unwrap(), "--json"]);
    assert_eq!(v["fixes"], 3, "{v}");
    let warnings = v["warnings"].as_array().unwrap();
    assert!(warnings.iter().any(|w| w.as_str().unwrap().contains("fix skipped: position 9999")), "{v}");
    assert_eq!(v["rejected_sentences"], 1, "{v}");
    let _ = std::fs::remove_file(path);
}

#[test]
fn session_log_with_a_malformed_line_is_refused_with_its_line_number() {
    let p = LatLon::new(42.3581, -71.0936);
    let good = session_fix(1.0, p);
    for (bad, what) in [
        ("{\"t_s\":2.0,\"utc\":\"x\",\"kind\":\"fix\",\"lat_deg\":\"north\",\"lon_deg\":-71.0}\n", "bad fix"),
        ("$GPGGA,not json\n", "not JSON"),
        ("{\"t_s\":2.0,\"utc\":\"x\"}\n", "kind"),
    ] {
        let text = format!("{good}\n{bad}{good}");
        let path = write_tmp("session-bad.jsonl", &text);
        for cmd in ["drift", "cones"] {
            let out = Command::new(env!("CARGO_BIN_EXE_vestnav"))
                .args(["fieldtest", cmd, path.to_str().unwrap()])
                .output()
                .unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(1), "{cmd} {bad}: {err}");
            assert!(err.contains("session-bad.jsonl:3:") && err.contains(what), "{cmd} {bad}: {err}");
        }
        let _ = std::fs::remove_file(path);
    }
}

#[test]
fn drift_reads_a_session_log_written_by_the_console_writer() {
    use vestnav_device::session_log::{LogEntry, SessionLog};
    // Fixes on a geodesic circle of radius r about a centre: distance from the mean = r for every fix, so
    // CEP50 = CEP95 = DRMS = r and the largest distance from the first fix is the diameter, 2r.
    let (centre, r_m) = (LatLon::new(42.3581, -71.0936), 2.0);
    let path = std::env::temp_dir().join(format!("vestnav-{}-drift-session.jsonl", std::process::id()));
    let _ = std::fs::remove_file(&path);
    let log = SessionLog::create_at(&path).unwrap();
    let tx = log.sender().unwrap();
    // One fix a second of session time, as a 1 Hz receiver gives them (the writer rate-limits floods by the
    // records' own session time).
    for k in 0..36 {
        let p = Earth::Wgs84.direct(centre, f64::from(k) * 10.0, r_m);
        let utc = vestnav_device::session_log::utc_stamp(chrono::Utc::now());
        tx.send(vestnav_device::session_log::LogRecord {
            t_s: f64::from(k),
            utc,
            entry: LogEntry::Fix {
                lat_deg: p.lat_deg,
                lon_deg: p.lon_deg,
                error_m: None,
                speed_m_s: None,
                course_deg: None,
                gps_utc: None,
            },
        });
    }
    let utc = vestnav_device::session_log::utc_stamp(chrono::Utc::now());
    tx.send(vestnav_device::session_log::LogRecord {
        t_s: 36.0,
        utc,
        entry: LogEntry::Mark { label: "left on the post".into(), lat_deg: None, lon_deg: None },
    });
    drop(tx);
    assert_eq!(log.close().unwrap().written, 37);
    let v = json(&["fieldtest", "drift", path.to_str().unwrap(), "--json"]);
    assert_eq!(v["format"], "session");
    assert_eq!(v["fixes"], 36);
    for key in ["cep50_m", "cep95_m", "drms_m"] {
        assert_relative_eq!(v[key].as_f64().unwrap(), r_m, max_relative = 1e-3);
    }
    assert_relative_eq!(v["max_from_first_m"].as_f64().unwrap(), 2.0 * r_m, max_relative = 1e-3);
    let _ = std::fs::remove_file(path);
}

/// `fieldtest drift|cones --json` are the `vestnav_report` schemas the console's field-test export writes
/// too (`crates/app/src/fieldtest_panel.rs` tests): they read back as `DriftReport` / `ConesReport`, and their
/// statistics are those of the track and marks they carry, recomputed here with the core functions the
/// console calls on live fixes.
#[test]
fn fieldtest_json_is_the_report_schema_of_its_track() {
    use vestnav_core::fieldtest::{ConeConfig, cones};
    use vestnav_report::fieldtest::{ConesReport, DriftReport};
    let (ok, out, err) =
        vestnav(&["fieldtest", "drift", "--json", logs().join("skytraq-dgps.log").to_str().unwrap()]);
    assert!(ok, "{err}");
    let report: DriftReport = serde_json::from_str(&out).unwrap();
    assert_eq!((report.test.as_str(), report.source.format.as_str()), ("drift", "nmea"));
    let stats = report.stats.as_ref().unwrap();
    let again = drift(&report.track, Earth::Wgs84).unwrap();
    assert_eq!(stats.fixes, again.fixes);
    for (a, b) in
        [(stats.cep50_m, again.cep50_m), (stats.cep95_m, again.cep95_m), (stats.drms_m, again.drms_m)]
    {
        assert_relative_eq!(a, b, max_relative = 1e-9);
    }
    let (log, _) = cone_log(GnssErrorModel::perfect(), 3, 1.4, 2);
    let path = write_tmp("cones-schema.nmea", &log);
    let (ok, out, err) = vestnav(&["fieldtest", "cones", path.to_str().unwrap(), "--count", "10", "--json"]);
    assert!(ok, "{err}");
    let report: ConesReport = serde_json::from_str(&out).unwrap();
    assert_eq!(report.cone_marks.len(), 10);
    let config = ConeConfig { count: Some(10), ..ConeConfig::with_spacing(10.0) };
    let again = cones(&report.cone_marks, &report.track, &config).unwrap();
    let stats = report.stats.as_ref().unwrap();
    for (a, b) in stats.distances_m.iter().zip(&again.distances_m) {
        assert_relative_eq!(*a, *b, max_relative = 1e-9);
    }
    let _ = std::fs::remove_file(path);
}

/// The demo route's points, read straight from the GPX text (`lat="…" lon="…"`), independently of the
/// route loader.
fn demo_route_points() -> Vec<LatLon> {
    let text = std::fs::read_to_string(root().join("assets/routes/demo.gpx")).unwrap();
    let attr = |tag: &str, name: &str| -> f64 {
        let start = tag.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
        tag[start..].split('"').next().unwrap().parse().unwrap()
    };
    text.split("<rtept").skip(1).map(|tag| LatLon::new(attr(tag, "lat"), attr(tag, "lon"))).collect()
}

#[test]
fn slow_walker_with_the_compass_finishes_the_demo_route_where_cog_alone_cannot() {
    let route = root().join("assets/routes/demo.gpx");
    let sim = |pace: &str, heading: &str| {
        json(&[
            "nav",
            "simulate",
            "--route",
            route.to_str().unwrap(),
            "--heading",
            heading,
            "--pace-m-s",
            pace,
            "--gnss",
            "sirf3-no-static",
            "--runs",
            "3",
            "--seed",
            "7",
            "--json",
        ])
    };
    let pts = demo_route_points();
    let length_m: f64 = pts.windows(2).map(|w| Earth::Wgs84.distance_m(w[0], w[1])).sum();
    let slow = sim("0.5", "compass,cog");
    assert_relative_eq!(slow["pace_m_s"].as_f64().unwrap(), 0.5);
    let entries = slow["strategies"].as_array().unwrap();
    assert_eq!(entries.len(), 2);
    let (compass, cog) = (&entries[0], &entries[1]);
    assert_eq!(compass["summary"]["heading_mode"], "compass");
    assert_eq!(cog["summary"]["heading_mode"], "cog");
    for run in compass["runs"].as_array().unwrap() {
        assert_eq!(run["finished"], true, "{run}");
        assert_eq!(run["waypoints_missed"], 0, "{run}");
        assert_eq!(run["waypoints_reached"].as_u64().unwrap() as usize, pts.len(), "{run}");
        // No faster than walking the route at 0.5 m/s, less an arrival radius at each end.
        let t = run["time_s"].as_f64().unwrap();
        assert!(t > (length_m - 2.0 * 8.0) / 0.5, "{t} s for {length_m} m: {run}");
        // It came to face the first waypoint, before finishing; COG was never used.
        let face = run["time_to_face_s"].as_f64().unwrap();
        assert!((0.0..t).contains(&face), "{run}");
        let sources = run["heading_source_s"].as_object().unwrap();
        assert!(!sources.contains_key("COG"), "{run}");
        assert!(sources["compass"].as_f64().unwrap() > 0.9 * t, "{run}");
    }
    // COG alone below the 0.8 m/s COG threshold: never a heading, never finished.
    assert_relative_eq!(cog["summary"]["finish_rate"].as_f64().unwrap(), 0.0);
    for run in cog["runs"].as_array().unwrap() {
        let sources = run["heading_source_s"].as_object().unwrap();
        assert_eq!(sources.keys().collect::<Vec<_>>(), vec!["none"], "{run}");
        assert!(run["waypoints_missed"].as_u64().unwrap() > 0, "{run}");
    }
    // The issue's goal: tracking at 0.5 m/s with the compass within 1.5x of a normal 1.4 m/s walk.
    let fast = sim("1.4", "compass");
    let rmse = |v: &serde_json::Value| v["summary"]["cross_track_rmse_m"]["mean"].as_f64().unwrap();
    let (slow_rmse, fast_rmse) = (rmse(compass), rmse(&fast["strategies"][0]));
    assert!(slow_rmse <= 1.5 * fast_rmse, "0.5 m/s: {slow_rmse} m, 1.4 m/s: {fast_rmse} m");
}
