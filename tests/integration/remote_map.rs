//! A remote station's route path on the console's map (issue 26): a route with a footway path sent to a
//! station over a real Mosquitto comes back on its route topic and the console's map draws it along the
//! path — the part passed, the section ahead, in the station's colour — and the largest path the broker
//! accepts is drawn thinned to the map's budget, its ends kept.
//!
//! Truth: the path's geometry in metres as the test laid it out. Web Mercator is conformal, so over a
//! kilometre the painted polyline keeps the path's angles and length ratios (to well under 1 %) whatever
//! the zoom and pan.

use std::time::{Duration, Instant};

use egui::epaint::{ColorMode, Shape};
use egui::{Pos2, Stroke};
use vestnav_app::map_panel::remote::colour_of;
use vestnav_app::map_panel::route_line::{PATH_DRAWN_MAX, PathStyle};
use vestnav_core::geo::{Earth, LatLon};
use vestnav_core::guidance::RoutePath;
use vestnav_remote::wire::MAX_WIRE_PATH_POINTS;
use vestnav_station::command::Command as StationCommand;
use vestnav_station::route::Waypoint;

use crate::remote::{Broker, StationProc, in_contact, temp_dir, wait_for};

/// Every shape of the last frame, those inside groups included.
fn shapes(h: &egui_kittest::Harness<'_, vestnav_app::console::Console>) -> Vec<Shape> {
    fn flatten(s: &Shape, out: &mut Vec<Shape>) {
        match s {
            Shape::Vec(v) => v.iter().for_each(|s| flatten(s, out)),
            s => out.push(s.clone()),
        }
    }
    let mut out = Vec::new();
    h.output().shapes.iter().for_each(|c| flatten(&c.shape, &mut out));
    out
}

/// Every polyline the last frame painted with `stroke`.
fn lines_in(h: &egui_kittest::Harness<'_, vestnav_app::console::Console>, stroke: Stroke) -> Vec<Vec<Pos2>> {
    shapes(h)
        .into_iter()
        .filter_map(|s| match s {
            Shape::Path(p)
                if !p.closed
                    && (p.stroke.width - stroke.width).abs() < 1e-3
                    && matches!(p.stroke.color, ColorMode::Solid(c) if c == stroke.color) =>
            {
                Some(p.points)
            }
            _ => None,
        })
        .collect()
}

/// Turns the console until the map draws alpha's route of `n` path points (or fails after 10 s).
fn run_until_drawn(h: &mut egui_kittest::Harness<'_, vestnav_app::console::Console>, n: usize) {
    let until = Instant::now() + Duration::from_secs(10);
    loop {
        h.run_steps(1);
        let w = h.state().map.remote_wearers.iter().find(|w| w.name == "alpha").cloned();
        if w.is_some_and(|w| w.path().is_some_and(|p| p.points().len() == n)) {
            h.run_steps(1);
            return;
        }
        assert!(Instant::now() < until, "alpha's route with its path of {n} points never reached the map");
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn length(a: Pos2, b: Pos2) -> f32 {
    (b - a).length()
}

#[test]
fn a_remote_stations_route_is_drawn_along_its_path_with_the_part_passed() {
    let dir = temp_dir("map-path");
    let broker = Broker::start(&dir);
    let alpha = StationProc::spawn(&broker, "alpha");
    let cfg = vestnav_app::config::Config { map_tiles: false, ..vestnav_app::config::Config::default() };
    let mut console = vestnav_app::console::Console::new(
        Box::new(vestnav_station::hardware::Hardware::default()),
        vestnav_app::console::ConsoleOptions { cfg, ..vestnav_app::console::ConsoleOptions::default() },
    );
    console.tab = vestnav_app::console::Tab::Map;
    let panel = vestnav_app::remote_panel::RemotePanel::connect(
        &broker.client("operator"),
        "operator",
        vestnav_station::stop::StopPath::default(),
    )
    .unwrap();
    wait_for("alpha in contact", Duration::from_secs(30), || in_contact(panel.fleet().unwrap(), "alpha"));
    let fix = || {
        let f = panel.fleet()?.station("alpha")?.state?.station.fix?;
        Some(LatLon::new(f.lat_deg?, f.lon_deg?))
    };
    wait_for("alpha's position", Duration::from_secs(10), || fix().is_some());
    // Around the wearer W, far from it (so no waypoint is reached or passed during the test): A 500 m
    // north, 500 m east to C, 1000 m south to D, 1000 m west to B. Waypoints A, C and B; C is passed (next
    // is B): the part passed is A→C, the section ahead C→D→B.
    let e = Earth::Wgs84;
    let w = fix().unwrap();
    let a = e.direct(w, 0.0, 500.0);
    let c = e.direct(a, 90.0, 500.0);
    let d = e.direct(c, 180.0, 1000.0);
    let b = e.direct(d, 270.0, 1000.0);
    let path = RoutePath::new(vec![a, c, d, b], vec![0, 1, 3]).unwrap();
    let waypoints = vec![Waypoint::at("A", a), Waypoint::at("C", c), Waypoint::at("B", b)];
    let route = |path: RoutePath, waypoints: Vec<Waypoint>, next| StationCommand::SetRoute {
        name: "around".into(),
        waypoints,
        next,
        path: Some(path),
    };
    panel.stations().send("alpha", route(path, waypoints.clone(), 2)).unwrap();
    console.remote = Some(panel);
    let mut h = egui_kittest::Harness::builder()
        .with_size(egui::vec2(1024.0, 680.0))
        .build_ui_state(|ui, c: &mut vestnav_app::console::Console| c.ui(ui), console);
    run_until_drawn(&mut h, 4);
    let wearer = h.state().map.remote_wearers.iter().find(|w| w.name == "alpha").cloned().unwrap();
    assert_eq!(wearer.next, 2, "the station still has B next");

    let style = PathStyle::remote(colour_of("alpha"));
    let ahead = lines_in(&h, style.ahead);
    let passed = lines_in(&h, style.passed);
    let [ahead] = ahead.as_slice() else { panic!("one section ahead drawn: {ahead:?}") };
    let [passed] = passed.as_slice() else { panic!("one part passed drawn: {passed:?}") };
    // Ahead: C→D→B, a right angle, south then west, the second leg as long as the first.
    let [pc, pd, pb] = ahead.as_slice() else { panic!("the section ahead is C, D, B: {ahead:?}") };
    let (cd, db) = (*pd - *pc, *pb - *pd);
    assert!(cd.y > 0.0 && cd.x.abs() < 0.01 * cd.y, "C→D runs south on screen: {cd:?}");
    assert!(db.x < 0.0 && db.y.abs() < 0.01 * -db.x, "D→B runs west on screen: {db:?}");
    let ratio = length(*pd, *pb) / length(*pc, *pd);
    assert!((ratio - 1.0).abs() < 0.01, "D→B / C→D = {ratio}, laid out 1000 m / 1000 m");
    // Passed: A→C, east, half as long as C→D, ending where the section ahead starts.
    let [pa, pc2] = passed.as_slice() else { panic!("the part passed is A, C: {passed:?}") };
    let ac = *pc2 - *pa;
    assert!(ac.x > 0.0 && ac.y.abs() < 0.01 * ac.x, "A→C runs east on screen: {ac:?}");
    let ratio = length(*pa, *pc2) / length(*pc, *pd);
    assert!((ratio - 0.5).abs() < 0.005, "A→C / C→D = {ratio}, laid out 500 m / 1000 m");
    assert!(length(*pc2, *pc) < 0.01, "the part passed ends at C, where the section ahead starts");
    // Nothing is drawn straight from waypoint to waypoint (the dashed legs of a route without a path).
    let dashes = colour_of("alpha").gamma_multiply(0.7);
    let faint_dashes =
        shapes(&h).iter().any(|s| matches!(s, Shape::LineSegment { stroke, .. } if stroke.color == dashes));
    assert!(!faint_dashes, "the straight legs are drawn over the path");

    // The largest path the broker accepts: 40 000 points from A to B, 2 km south. Drawn thinned to the
    // map's budget, from A to B.
    let long: Vec<LatLon> = (0..MAX_WIRE_PATH_POINTS)
        .map(|i| e.direct(a, 180.0, 2000.0 * i as f64 / (MAX_WIRE_PATH_POINTS - 1) as f64))
        .collect();
    let (last, end) = (MAX_WIRE_PATH_POINTS - 1, *long.last().unwrap());
    let long = RoutePath::new(long, vec![0, last]).unwrap();
    let two = vec![Waypoint::at("A", a), Waypoint::at("B", end)];
    h.state().remote.as_ref().unwrap().stations().send("alpha", route(long, two, 1)).unwrap();
    run_until_drawn(&mut h, MAX_WIRE_PATH_POINTS);
    let ahead = lines_in(&h, style.ahead);
    let [line] = ahead.as_slice() else { panic!("one section ahead drawn") };
    assert!(
        line.len() <= PATH_DRAWN_MAX + 2 && line.len() >= PATH_DRAWN_MAX / 2,
        "{} of {MAX_WIRE_PATH_POINTS} points drawn, the budget {PATH_DRAWN_MAX}",
        line.len()
    );
    let (first, last) = (line[0], line[line.len() - 1]);
    let south = last - first;
    assert!(south.y > 0.0 && south.x.abs() < 0.01 * south.y, "drawn from A down to B: {south:?}");
    // 2000 m drawn as 4 times the 500 m of A→C (the zoom has not changed).
    let ratio = south.y / ac.x;
    assert!((ratio - 4.0).abs() < 0.04, "A→B / A→C = {ratio}, laid out 2000 m / 500 m");

    h.state_mut().shutdown();
    drop(h);
    alpha.quit();
    drop(broker);
    let _ = std::fs::remove_dir_all(&dir);
}
