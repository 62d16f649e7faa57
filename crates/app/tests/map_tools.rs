//! Issue 11, map tools, driven by label with `egui_kittest`: measuring, go-to, the GPX import dialog,
//! and a per-waypoint arrival radius reaching guidance.
#![allow(clippy::unwrap_used)]

mod common;

use std::time::{Duration, Instant};

use egui_kittest::kittest::Queryable as _;
use vestnav_device::gps::{Fix, FixMode, GpsEvent};
use vestnav_station::route::Waypoint;
use walkers::lat_lon;

/// WGS-84 semi-major axis [m] and first eccentricity squared (NIMA TR8350.2).
const A_M: f64 = 6_378_137.0;
const E2: f64 = 6.694_379_990_14e-3;

/// Two clicks 200 px apart vertically on a map centred on the equator at zoom 17. Truth, in closed form:
/// walkers draws Web Mercator with a world of `256 * 2^zoom` px, so 200 px north of the equator is the
/// latitude `gd(2 pi 200 / (256 2^17))` (the Gudermannian); the geodesic along the meridian from the
/// equator is `a (1 - e^2) phi` to first order (the next term, `e^2 phi^3 / 2`, is ~1e-15 m here), due north.
#[test]
fn measuring_by_two_clicks_shows_the_geodesic_distance() {
    let devices = common::Devices::default();
    let mut h = common::console(&devices);
    h.get_by_label("Measure").click();
    h.run_steps(2);
    {
        let c = h.state_mut();
        c.map.memory.center_at(lat_lon(0.5, 10.0));
        c.map.memory.set_zoom(17.0).unwrap();
    }
    h.run_steps(3);
    let rect = h.state().map.tools.map_rect.unwrap();
    let a = rect.center();
    let b = a - egui::vec2(0.0, 200.0);
    common::click_at(&mut h, a);
    common::click_at(&mut h, b);
    let y = 2.0 * std::f64::consts::PI * 200.0 / (256.0 * 2f64.powi(17));
    let phi = y.sinh().atan();
    let want_m = A_M * (1.0 - E2) * phi;
    let m = h.state().map.tools.measurement().expect("two points measured");
    assert!((m.distance_m - want_m).abs() < 0.05, "{} vs {want_m}", m.distance_m);
    assert!(m.initial_bearing_deg < 1e-6 || m.initial_bearing_deg > 360.0 - 1e-6, "{m:?}");
    let shown = [want_m - 0.05, want_m, want_m + 0.05].map(|d| format!("Measured: {d:.1} m · bearing"));
    assert!(shown.iter().any(|s| h.query_by_label_contains(s).is_some()), "none of {shown:?} shown");
}

/// Go to an MGRS reference: the map centres on it. Truth: `GeographicLib`'s `GeoConvert` manual, `echo
/// 38SMB4488 | GeoConvert` gives `33.33424 44.40363`.
#[test]
fn go_to_centres_the_map_on_a_typed_mgrs_reference() {
    let devices = common::Devices::default();
    let mut h = common::console(&devices);
    h.state_mut().map.tools.goto_text = "38SMB4488".into();
    h.run_steps(1);
    h.get_by_label("Go to").click();
    h.run_steps(3);
    let c = h.state().map.memory.detached().expect("the map left follow mode");
    assert!((c.y() - 33.33424).abs() < 1e-5 && (c.x() - 44.40363).abs() < 1e-5, "{c:?}");
    // A typo says what was expected and moves nothing.
    h.state_mut().map.tools.goto_text = "33.3 north".into();
    h.run_steps(1);
    h.get_by_label("Go to").click();
    h.run_steps(2);
    assert!(h.query_by_label_contains("Go to: '33.3 north' is not a position").is_some());
    assert_eq!(h.state().map.memory.detached(), Some(c));
}

#[test]
fn the_import_dialog_offers_what_the_file_holds() {
    let dir = std::env::temp_dir().join(format!("vestnav-map-tools-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("several.gpx");
    std::fs::write(
        &path,
        r#"<?xml version="1.0"?><gpx version="1.1" creator="t">
        <wpt lat="42.0" lon="-71.0"><name>a</name></wpt>
        <wpt lat="42.001" lon="-71.0"><name>b</name></wpt>
        <wpt lat="42.002" lon="-71.0"><name>c</name></wpt>
        <rte><name>Loop</name><rtept lat="42" lon="-71"/><rtept lat="42.1" lon="-71"/></rte>
        <trk><name>Walk</name><trkseg>
          <trkpt lat="42.0" lon="-71.0"/><trkpt lat="42.0001" lon="-71.0"/><trkpt lat="42.0002" lon="-71.0"/>
          <trkpt lat="42.0002" lon="-71.001"/>
        </trkseg></trk></gpx>"#,
    )
    .unwrap();
    let devices = common::Devices::default();
    let mut h = common::console(&devices);
    h.state_mut().map.gpx_path = path.display().to_string();
    h.run_steps(1);
    h.get_by_label("Import GPX").click();
    h.run_steps(3);
    // The straight run of three track points keeps its ends, plus the corner: 3 of 4.
    for label in ["route 'Loop' (2 points)", "3 waypoints", "track 'Walk' (4 points, simplified to 3)"] {
        assert!(h.query_by_label(label).is_some(), "{label} offered");
    }
    h.get_by_label("3 waypoints").click();
    h.run_steps(3);
    let names: Vec<&str> = h.state().station.route().waypoints().iter().map(|w| w.name.as_str()).collect();
    assert_eq!(names, vec!["a", "b", "c"]);
    assert!(h.state().map.import.is_none(), "the dialog closed");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A fix `d_m` metres due north of (42, -71), fresh. One degree of latitude at 42° N is 111 034 m
/// (WGS-84 meridian arc), so 20 m is 1.8012e-4 degrees.
fn fix_north_of_a(d_m: f64) -> Fix {
    Fix {
        lat_deg: Some(42.0 + d_m / 111_034.0),
        lon_deg: Some(-71.0),
        mode: Some(FixMode::Fix3D),
        received_at: Some(Instant::now()),
        ..Fix::default()
    }
}

/// The radius typed in the waypoint editor is the one guidance arrives by: 20 m from a waypoint is no
/// arrival with the global 8 m, and is one with the waypoint's own 30 m.
#[test]
fn an_arrival_radius_edited_per_waypoint_decides_guidances_arrival() {
    use egui::accesskit::Role;
    let devices = common::Devices::default();
    let mut h = common::console(&devices);
    {
        let c = h.state_mut();
        c.station
            .route_mut()
            .replace(
                "radius".into(),
                vec![Waypoint::new("A", 42.0, -71.0), Waypoint::new("B", 42.003, -71.0)],
            )
            .unwrap();
    }
    h.run_steps(2);
    let guided = |h: &mut egui_kittest::Harness<'static, _>| {
        for _ in 0..3 {
            devices.gps(&GpsEvent::Fix(Box::new(fix_north_of_a(20.0))));
            std::thread::sleep(Duration::from_millis(30));
            h.run_steps(2);
        }
    };
    guided(&mut h);
    assert!(
        common::settle(&mut h, |c| c.station.guidance.as_ref().is_some_and(|g| g.distance_m.is_some())),
        "guidance saw the fixes"
    );
    assert_eq!(
        h.state().station.guidance.as_ref().map(|g| g.next),
        Some(0),
        "20 m is outside the global 8 m"
    );
    h.get_all_by_label("Edit").next().unwrap().click();
    h.run_steps(2);
    h.get_by_role_and_label(Role::TextInput, "Arrival radius (m)").set_text_value_accesskit("30");
    h.run_steps(2);
    h.get_by_label("Apply").click();
    h.run_steps(2);
    assert_eq!(h.state().station.route().waypoints()[0].arrival_radius_m, Some(30.0));
    guided(&mut h);
    assert!(
        common::settle(&mut h, |c| c.station.guidance.as_ref().is_some_and(|g| g.next == 1)),
        "guidance arrived at A within its own 30 m: {:?}",
        h.state().station.guidance
    );
}
