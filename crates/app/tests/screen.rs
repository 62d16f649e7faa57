//! The console's frame driven with real pointer events (`egui_kittest`), devices injected: STOP ALL above
//! every window and modal, a layout that holds still as banners come and go, deliberate re-targeting, the
//! "now" display and Resume in view, import while guiding, and when the window turns on its own.
#![allow(clippy::unwrap_used)]

mod common;

use common::console::*;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use std::time::{Duration, Instant};
use vestnav_app::config::Config;
use vestnav_app::console::{Console, LIVENESS_TURN};

fn guiding() -> Config {
    Config { map_tiles: false, guidance_auto: true, ..Config::default() }
}

fn step(h: &mut Harness<'static, Console>, n: usize) {
    for _ in 0..n {
        h.step();
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn stop_rect(h: &Harness<'static, Console>) -> egui::Rect {
    h.get_by_label("STOP ALL").rect()
}

/// With the Receiver, Tiles and pattern-editor windows open and an export's "Replace …?" modal up, STOP
/// ALL is uncovered and one pointer click on it stops: automatic cues halted, the unit told.
#[test]
fn stop_all_acts_on_the_first_click_with_every_window_and_modal_open() {
    let fake = Fake::default();
    let mut h = harness_with(&fake, guiding());
    let dir = test_dir("stop-over-modal");
    let existing = dir.join("route.gpx");
    std::fs::write(&existing, "<gpx/>").unwrap();
    // The pattern editor first: its button is in the side panel, which the other windows may cover.
    open_pattern_editor(&mut h);
    h.get_by_label("Receiver").click();
    step(&mut h, 2);
    h.get_by_label("Tiles…").click();
    step(&mut h, 2);
    // The export's own button may lie under a window now: its question is asked as the button would.
    h.state_mut().map.pending_replace = Some((existing.clone(), vestnav_app::map_panel::RouteExport::Gpx));
    step(&mut h, 3);
    let question = format!("Replace {}?", existing.display());
    assert!(h.query_by_label(&question).is_some(), "the Replace prompt is open");
    let bar_bottom = stop_rect(&h).bottom();
    for title in ["GPS receiver configuration", "Tiles"] {
        let top = h.get_all_by_label(title).map(|n| n.rect().top()).fold(f32::INFINITY, f32::min);
        assert!(
            top >= bar_bottom,
            "window {title} starts at y = {top}, above the top bar's bottom {bar_bottom}"
        );
    }
    assert!(h.state().station.vest.halted.is_none());
    fake.sent.lock().unwrap().clear();
    h.get_by_label("STOP ALL").click();
    step(&mut h, 2);
    settle(&mut h, |c| c.station.vest.halted.is_some());
    assert!(h.state().station.vest.halted.is_some(), "one click on STOP ALL halted guidance");
    assert!(!h.state().cfg.guidance_auto);
    assert!(
        fake.sent().iter().any(|r| matches!(r, vestnav_device::wtcu::Request::StopAll)),
        "the unit was sent STOP ALL: {:?}",
        fake.sent()
    );
}

/// The positions of STOP ALL, the side panel's parts and the map's toolbar are the same with no banner,
/// with several (a halt, a notice, GPS gone) and after they are gone.
#[test]
fn the_layout_holds_still_as_banners_come_and_go() {
    let fake = Fake::default();
    let mut h = harness_with(&fake, guiding());
    fake.gps(&vestnav_device::gps::GpsEvent::Fix(Box::new(walking_fix())));
    step(&mut h, 5);
    let probes = ["STOP ALL", "<< Hide", "Follow wearer", "GPS", "Vest", "T15"];
    let rects = |h: &Harness<'static, Console>| -> Vec<egui::Rect> {
        probes.iter().map(|l| h.get_all_by_label(l).next().unwrap().rect()).collect()
    };
    let calm = rects(&h);
    h.state_mut().stop_all();
    h.state_mut().say(vestnav_station::Severity::Warning, vestnav_station::Subject::Route, "a warning");
    step(&mut h, 4);
    assert!(h.state().banners(Instant::now()).len() >= 2, "{:?}", h.state().banners(Instant::now()));
    assert_eq!(rects(&h), calm, "banners moved {probes:?}");
    // A fix 20 s old: FIX LOST, and the GPS panel's rows say "last known, N s ago" — the side panel keeps
    // its width, the map and the top bar stay.
    fake.gps(&vestnav_device::gps::GpsEvent::Fix(Box::new(fix(42.3562, -71.1, Duration::from_secs(20)))));
    step(&mut h, 4);
    assert!(banner_of(h.state(), BannerSubject::Gps).is_some());
    // (The GPS section itself may grow by a line when the fix is lost, moving the sections below it.)
    assert_eq!(rects(&h)[..4], calm[..4], "a lost fix moved {:?}", &probes[..4]);
    fake.gps(&vestnav_device::gps::GpsEvent::Fix(Box::new(walking_fix())));
    h.state_mut().resume_guidance();
    let k = h.state().station.notices.all().iter().position(|n| n.text == "a warning").unwrap();
    h.state_mut().station.notices.dismiss(k);
    settle(&mut h, |c| c.banners(Instant::now()).is_empty());
    assert!(h.state().banners(Instant::now()).is_empty(), "{:?}", h.state().banners(Instant::now()));
    assert_eq!(rects(&h), calm, "banners going moved {probes:?}");
}

/// A click on a waypoint's name selects it; guidance re-targets only on "Guide to …".
#[test]
fn a_click_on_a_waypoint_selects_it_and_guide_to_re_targets() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    set_route(&mut h, three_waypoints(), 0);
    h.get_by_label("3 Charlie").click();
    step(&mut h, 2);
    assert_eq!(h.state().station.route().next(), 0, "a click on a name does not re-target");
    assert_eq!(h.state().map.selected, Some(2));
    h.get_by_label("Guide to Charlie").click();
    step(&mut h, 2);
    assert_eq!(h.state().station.route().next(), 2);
}

fn write_gpx(path: &std::path::Path) {
    std::fs::write(
        path,
        r#"<?xml version="1.0"?><gpx version="1.1" creator="test" xmlns="http://www.topografix.com/GPX/1/1">
<rte><name>Other</name><rtept lat="42.36" lon="-71.10"><name>X1</name></rtept>
<rtept lat="42.361" lon="-71.101"><name>X2</name></rtept></rte></gpx>"#,
    )
    .unwrap();
}

/// While guiding, Import GPX asks before replacing the route; "Keep" keeps it, "Replace route" replaces.
/// An unreadable file is a banner naming it.
#[test]
fn import_while_guiding_asks_first_and_a_broken_file_is_a_banner() {
    let fake = Fake::default();
    let mut h = harness_with(&fake, guiding());
    set_route(&mut h, three_waypoints(), 1);
    let dir = test_dir("import-guiding");
    let file = dir.join("other.gpx");
    write_gpx(&file);
    h.state_mut().map.gpx_path = file.display().to_string();
    step(&mut h, 1);
    h.get_by_label("Import GPX").click();
    step(&mut h, 3);
    assert_eq!(h.state().station.route().waypoints().len(), 3, "nothing replaced before the answer");
    assert!(h.query_by_label("Replace the route being guided?").is_some());
    h.get_by_label("Keep the current route").click();
    step(&mut h, 3);
    assert_eq!(h.state().station.route().waypoints()[0].name, "Alpha");
    assert_eq!(h.state().station.route().next(), 1);
    h.get_by_label("Import GPX").click();
    step(&mut h, 3);
    h.get_by_label("Replace route").click();
    step(&mut h, 3);
    let names: Vec<String> = h.state().station.route().waypoints().iter().map(|w| w.name.clone()).collect();
    assert_eq!(names, ["X1", "X2"]);

    let broken = dir.join("broken.gpx");
    std::fs::write(&broken, "<gpx><rte><rtept lat=").unwrap();
    h.state_mut().map.gpx_path = broken.display().to_string();
    step(&mut h, 1);
    h.get_by_label("Import GPX").click();
    step(&mut h, 3);
    let banners = h.state().banners(Instant::now());
    assert!(
        banners
            .iter()
            .any(|b| matches!(b.subject, BannerSubject::Notice(_)) && b.text.contains("broken.gpx")),
        "{banners:?}"
    );
}

/// After STOP ALL the HALTED banner has its own Resume; after it, the status line no longer speaks of
/// the stop.
#[test]
fn the_halted_banner_resumes_and_the_status_line_follows() {
    let fake = Fake::default();
    let mut h = harness_with(&fake, guiding());
    h.get_by_label("STOP ALL").click();
    step(&mut h, 2);
    settle(&mut h, |c| c.station.vest.halted.is_some());
    let resumes: Vec<egui::Rect> = h.get_all_by_label("Resume automatic cues").map(|n| n.rect()).collect();
    let in_view = resumes.iter().filter(|r| r.bottom() <= 900.0).count();
    assert!(in_view >= 2, "Resume on the banner and on the now display, in view: {resumes:?}");
    h.get_all_by_label("Resume automatic cues").next().unwrap().click();
    step(&mut h, 2);
    settle(&mut h, |c| c.station.vest.halted.is_none());
    assert!(h.state().station.vest.halted.is_none());
    assert!(h.state().cfg.guidance_auto);
    let status = h.state().latest_notice().map(|n| n.text.clone()).unwrap_or_default();
    assert!(status.contains("resumed"), "status line: {status}");
}

/// The cue guidance sent is on the "now" display, in view without scrolling, at 1400x900 and at
/// 1024x680 (where the side panel also collapses to a strip and back).
#[test]
fn the_current_cue_is_in_view_at_both_sizes() {
    for size in [egui::vec2(1400.0, 900.0), egui::vec2(1024.0, 680.0)] {
        let fake = Fake::default();
        let mut h = harness_sized(&fake, guiding(), size);
        set_route(&mut h, three_waypoints(), 0);
        walk_until(&mut h, &fake, Duration::from_secs(10), |c| {
            c.station.cues.newest_first().next().is_some()
        });
        step(&mut h, 3);
        let (cue, _) = *h.state().station.cues.newest_first().next().expect("guidance sent a cue");
        let words = cue.name().replace('_', " ").to_uppercase();
        let r = h.get_by_label(&words).rect();
        assert!(r.bottom() <= size.y && r.right() <= size.x, "{words} at {r:?} in {size:?}");
        let grid_top = h.get_by_label("Vest").rect().top();
        assert!(r.top() < grid_top, "the cue sits above the Vest section");
        if size.x < 1100.0 {
            h.get_by_label("<< Hide").click();
            step(&mut h, 2);
            assert!(!h.state().side_open);
            h.get_by_label(">>").click();
            step(&mut h, 2);
            assert!(h.state().side_open);
        }
    }
}

/// The window turns on its own only as often as needed: never with nothing connected, and while a vest
/// is connected at least as often as the vest worker's liveness bound of the UI thread demands.
#[test]
fn the_window_turns_on_its_own_only_as_needed() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    let bound = vestnav_app::console::Liveness::default().view.unwrap();
    assert!(LIVENESS_TURN * 3 / 2 <= bound, "a turn every {LIVENESS_TURN:?} within {bound:?} with margin");
    let d = h.state().next_turn(Instant::now()).expect("a vest is connected");
    assert!(d <= LIVENESS_TURN);
    h.state_mut().disconnect_vest();
    h.state_mut().disconnect_gps();
    step(&mut h, 2);
    assert_eq!(h.state().next_turn(Instant::now()), None, "nothing connected, nothing to redraw");
}
