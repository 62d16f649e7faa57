//! The console's layout driven by label with `egui_kittest`, devices injected: the View menu, the field-test
//! tab, every tab in a small window.
#![allow(clippy::unwrap_used)]

mod common;

use common::console::*;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use std::time::{Duration, Instant};
use vestnav_app::config::Config;
use vestnav_app::console::{Console, ConsoleOptions};

/// The View menu switches the light high-contrast theme and large text: the context's visuals and text
/// sizes change, and the choice is written to the config file.
#[test]
fn view_menu_switches_theme_and_text_size_and_remembers_them() {
    let dir = std::env::temp_dir().join(format!("vestnav-ui-theme-{}", std::process::id()));
    let path = dir.join("console.json");
    let fake = Fake::default();
    let cfg = Config { map_tiles: false, guidance_auto: false, ..Config::default() };
    let console = Console::new(
        Box::new(fake.clone()),
        ConsoleOptions { cfg, cfg_path: Some(path.clone()), ..ConsoleOptions::default() },
    );
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    h.run_steps(2);
    let body = |h: &Harness<'static, Console>| h.ctx.global_style().text_styles[&egui::TextStyle::Body].size;
    assert!(h.ctx.global_style().visuals.dark_mode);
    let body_before = body(&h);

    for option in ["Light high-contrast theme", "Large text"] {
        if h.query_by_label(option).is_none() {
            h.get_by_label("View").click();
            h.run_steps(2);
        }
        h.get_by_label(option).click();
        h.run_steps(3);
    }
    assert!(h.state().cfg.light_theme && h.state().cfg.large_text);
    let style = h.ctx.global_style();
    assert!(!style.visuals.dark_mode, "the light theme is active");
    assert_eq!(style.visuals.panel_fill, egui::Color32::WHITE);
    assert!(body(&h) >= 18.0 && body(&h) > body_before, "{} pt", body(&h));
    let (saved, err) = Config::load(&path);
    assert!(err.is_none(), "{err:?}");
    assert!(saved.light_theme && saved.large_text, "remembered in the config file");
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Fault 7 of issue 15: a drift test fed fixes whose receiver times span 200 s, arriving within a few
/// seconds (a fast replay), reports 200 s and says it is on the receiver's clock. Truth: the receiver
/// times the test set, and the wall clock measured around the feed.
#[test]
fn the_drift_test_runs_on_the_receiver_clock() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Field tests").click();
    h.run_steps(2);
    h.get_by_label("duration target").set_value_accesskit(5.0);
    h.run_steps(2);
    let (lat, lon) = (42.3575, -71.1010);
    let tod0 = 12.0 * 3600.0;
    send_fix(&mut h, &fake, timed_fix(lat, lon, tod0 - 1.0, Some(0.0)), 1);
    h.run_steps(1);
    h.get_by_label("Start drift test").click();
    h.run_steps(2);
    let started = Instant::now();
    let (n, span_s) = (201_u64, 200.0);
    for k in 0..n {
        #[allow(clippy::cast_precision_loss, reason = "k < 201")]
        let tod = tod0 + span_s * k as f64 / (n - 1) as f64;
        send_fix(&mut h, &fake, timed_fix(lat, lon, tod, Some(0.0)), k + 2);
    }
    let wall_s = started.elapsed().as_secs_f64();
    assert!(wall_s < 20.0, "the fixes arrived within {wall_s:.1} s");
    h.run_steps(2);
    let want = format!("{n} fixes over {span_s:.0} s");
    assert!(h.query_by_label(&want).is_some(), "{want:?} shown");
    assert!(h.query_by_label_contains("time base: receiver UTC").is_some());
    assert!(h.query_by_label_contains("walking speed").is_none(), "a still receiver");
}

/// Fault 7 of issue 15: a receiver carried at walking speed during a stationary drift test raises the
/// warning. Truth: the 1.3 m/s walk the test feeds.
#[test]
fn a_walking_receiver_warns_during_the_drift_test() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Field tests").click();
    h.run_steps(2);
    let (lat, lon) = (42.3575, -71.1010);
    send_fix(&mut h, &fake, timed_fix(lat, lon, 100.0, Some(0.0)), 1);
    h.run_steps(1);
    h.get_by_label("Start drift test").click();
    h.run_steps(2);
    let mut n = 1;
    for k in 0..5 {
        n += 1;
        send_fix(&mut h, &fake, timed_fix(lat, lon, 101.0 + f64::from(k), Some(0.0)), n);
    }
    h.run_steps(1);
    assert!(h.query_by_label_contains("walking speed").is_none(), "still so far");
    for k in 1..=8 {
        n += 1;
        let (la, lo) = north_of(lat, lon, 1.3 * f64::from(k));
        send_fix(&mut h, &fake, timed_fix(la, lo, 105.0 + f64::from(k), Some(1.3)), n);
    }
    h.run_steps(2);
    assert!(
        h.query_by_label_contains("moving at 1.3 m/s (walking speed)").is_some(),
        "the walk's speed shown"
    );
}

/// Fault 7 of issue 15: while a cone test runs the mark count is a live count, not a "missed or marked
/// twice" alarm; finishing with fewer marks than cones gives the verdict. Truth: 2 marks for 10 cones.
#[test]
fn the_cone_test_does_not_cry_missed_while_running() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Field tests").click();
    h.run_steps(2);
    h.get_by_label("Cone test").click();
    h.run_steps(2);
    let (lat, lon) = (42.3575, -71.1010);
    send_fix(&mut h, &fake, timed_fix(lat, lon, 200.0, Some(1.5)), 1);
    h.run_steps(1);
    h.get_by_label("Start cone test").click();
    h.run_steps(2);
    for (k, north_m) in [0.0, 10.0].into_iter().enumerate() {
        let (la, lo) = north_of(lat, lon, north_m);
        #[allow(clippy::cast_precision_loss, reason = "k < 2")]
        send_fix(&mut h, &fake, timed_fix(la, lo, 201.0 + 7.0 * k as f64, Some(1.5)), k as u64 + 2);
        h.run_steps(1);
        h.get_by_label_contains(&format!("Mark cone {}", k + 1)).click();
        h.run_steps(2);
    }
    assert!(h.query_by_label("2 of 10 cones marked").is_some(), "the live count");
    assert!(h.query_by_label_contains("missed").is_none(), "no alarm while running");
    h.get_by_label("Finish").click();
    h.run_steps(2);
    assert!(h.query_by_label_contains("2 marks for 10 cones").is_some(), "the verdict once finished");
}

/// Issue 15 fault 5: at 1024x680 (a small laptop) nothing of any tab lies beyond the window's right edge,
/// STOP ALL is on screen, and the Two-point view fits the width.
#[test]
fn every_tab_fits_a_1024_by_680_window() {
    use egui_kittest::kittest::{NodeT as _, by};
    let fake = Fake::default();
    let cfg = Config { map_tiles: false, guidance_auto: false, ..Config::default() };
    let mut h = harness_sized(&fake, cfg, egui::vec2(1024.0, 680.0));
    let mut offenders = Vec::new();
    let mut check = |h: &mut Harness<'static, Console>, what: &str| {
        for _ in 0..30 {
            h.step();
            std::thread::sleep(Duration::from_millis(20));
        }
        for node in h.query_all(by().predicate(|n| n.label().is_some_and(|l| !l.is_empty()))) {
            let r = node.rect();
            if r.right() > 1024.5 && r.width() > 0.0 {
                offenders.push(format!(
                    "{what}: {:?} {:?} ends at x = {}",
                    node.accesskit_node().role(),
                    node.accesskit_node().label(),
                    r.right()
                ));
            }
        }
        if std::env::var("VESTNAV_DEBUG_LAYOUT").is_ok() {
            for node in h.query_all(by().predicate(|n| n.label().is_some_and(|l| !l.is_empty()))) {
                eprintln!(
                    "{what}: {:?} {:?} {:?}",
                    node.accesskit_node().role(),
                    node.accesskit_node().label(),
                    node.rect()
                );
            }
        }
        // The side panel has a fixed width: its collapse button sits at its right edge.
        let side = h.get_by_label("<< Hide").rect();
        assert!(side.right() <= 320.0, "{what}: the side panel takes {} of 1024 points", side.right());
        let stop = h.get_by_label_contains("STOP ALL").rect();
        assert!(stop.bottom() <= 680.0 && stop.right() <= 1024.0, "{what}: STOP ALL at {stop:?}");
    };
    check(&mut h, "Map");
    // Issue 23 item 5: a route with long names leaves the map the larger share (its list stays within 30 %
    // of the width beside the side panel; rows whose buttons do not fit wrap them to a second line).
    let route: Vec<vestnav_station::route::Waypoint> = (0..7)
        .map(|k| {
            let p = vestnav_core::geo::LatLon::new(42.3573 + 1e-4 * f64::from(k), -71.101);
            vestnav_station::route::Waypoint::at(format!("Waypoint with a long name {k}"), p)
        })
        .collect();
    h.state_mut().station.route_mut().replace("long names".into(), route).unwrap();
    h.run_steps(3);
    check(&mut h, "Map with a route");
    let side = h.get_by_label("<< Hide").rect().right();
    let list = h.get_by_label_contains("Waypoint with a long name 6").rect().left();
    assert!(list - side >= 450.0, "the map keeps {} of 1024 points beside the waypoint list", list - side);
    h.get_by_label("Simulation").click();
    h.run_steps(2);
    for view in ["Tactor model", "Damping sweep", "Skin waves", "Two-point"] {
        h.get_by_label(view).click();
        check(&mut h, view);
    }
    h.get_by_label("Field tests").click();
    h.run_steps(2);
    check(&mut h, "Field tests");
    assert!(offenders.is_empty(), "{}", offenders.join("\n"));
}
