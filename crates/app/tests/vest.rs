//! The console's Vest panel driven by label with `egui_kittest`, devices injected: the grid, STOP ALL, the
//! compass, the vest's banner lines and the pattern editor.
#![allow(clippy::unwrap_used)]

mod common;

use common::console::*;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};
use vestnav_app::config::Config;
use vestnav_app::console::Severity;
use vestnav_app::console::{Console, ConsoleOptions};
use vestnav_core::guidance::HeadingSource;
use vestnav_core::vest::TactorMask;
use vestnav_device::gps::GpsEvent;
use vestnav_device::session_log::LogEntry;
use vestnav_device::sim::{CompassSetup, SimulatedCompass, WearerMotion};
use vestnav_device::wtcu::engine::HeadingSensor as _;
use vestnav_device::wtcu::{LinkState, Request, VestCommand};

#[test]
fn clicking_a_tactor_fires_it_and_shows_it_on() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("T5").click();
    settle(&mut h, |c| !on(c).is_empty());
    assert_eq!(fake.sent(), vec![Request::Fire { mask: TactorMask::from_indices([5]), duration_ms: 500 }]);
    assert_eq!(on(h.state()), TactorMask::from_indices([5]));
}

#[test]
fn stop_all_button_and_key() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("STOP ALL").click();
    settle(&mut h, |_| fake.sent().len() == 1);
    h.key_press(egui::Key::Space);
    settle(&mut h, |_| fake.sent().len() == 2);
    // The clicked button keeps the keyboard focus; Space must not press it as well.
    h.run_steps(3);
    std::thread::sleep(Duration::from_millis(50));
    h.run_steps(2);
    assert_eq!(fake.sent(), vec![Request::StopAll, Request::StopAll]);
    assert!(!h.state().cfg.guidance_auto);
}

#[test]
fn space_stops_the_vest_without_pressing_the_focused_button() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Multi-select").focus();
    h.run_steps(2);
    let multi = h.state().vest_ui.select_mode;
    h.key_press(egui::Key::Space);
    settle(&mut h, |_| !fake.sent().is_empty());
    h.run_steps(3);
    assert_eq!(fake.sent(), vec![Request::StopAll]);
    assert_eq!(h.state().vest_ui.select_mode, multi, "the focused checkbox was not toggled");
}

#[test]
fn escape_closes_a_menu_without_stopping_the_vest() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.state_mut().cfg.guidance_auto = true;
    h.run_steps(2);
    h.get_by_label("GPS source").click();
    h.run_steps(2);
    assert!(h.query_by_label("NMEA file replay").is_some(), "the combo box is open");
    h.key_press(egui::Key::Escape);
    h.run_steps(3);
    assert!(h.query_by_label("NMEA file replay").is_none(), "Esc closed it");
    std::thread::sleep(Duration::from_millis(50));
    assert!(fake.sent().is_empty(), "{:?}", fake.sent());
    assert!(h.state().cfg.guidance_auto, "automatic guidance untouched");
}

#[test]
fn the_grid_is_disabled_while_the_vest_is_not_live() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Disconnect vest").click();
    settle(&mut h, |c| !c.station.vest.is_live());
    h.run_steps(1);
    assert!(h.query_by_label_contains("tactors cannot be fired").is_some());
    h.get_by_label("T5").click();
    h.run_steps(2);
    assert!(fake.sent().iter().all(|r| *r == Request::StopAll), "{:?}", fake.sent());
}

#[test]
fn multi_select_fires_several() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("Multi-select").click();
    h.run_steps(1);
    for t in ["T0", "T3", "T12"] {
        h.get_by_label(t).click();
        h.run_steps(2);
    }
    assert!(h.state().vest_ui.select_mode);
    assert_eq!(h.state().vest_ui.selected, TactorMask::from_indices([0, 3, 12]));
    h.get_by_label("Fire selected (3)").click();
    settle(&mut h, |_| !fake.sent().is_empty());
    assert_eq!(
        fake.sent(),
        vec![Request::Fire { mask: TactorMask::from_indices([0, 3, 12]), duration_ms: 500 }]
    );
}

#[test]
fn emulated_vest_reports_the_clicked_tactor_on_then_stop_all_clears_it() {
    let dir = std::env::temp_dir().join(format!("vestnav-ui-{}", std::process::id()));
    let mut h = real_harness(Some(dir.clone()));
    settle(&mut h, |c| c.station.vest.state == Some(LinkState::Ready));
    assert_eq!(h.state().station.vest.state, Some(LinkState::Ready), "emulated vest did not come up");
    // Above the fold of the 1400x900 window (the status bar takes the last ~25 points).
    let t15 = h.get_by_label("T15").rect();
    assert!(t15.bottom() <= 875.0, "the vest grid ends at y = {}", t15.bottom());
    h.get_by_label("T9").click();
    // The orange state comes from the unit's acks/status, not from what we sent.
    settle(&mut h, |c| on(c).contains(9));
    assert_eq!(on(h.state()), TactorMask::from_indices([9]));
    h.get_by_label("STOP ALL").click();
    settle(&mut h, |c| on(c).is_empty());
    assert!(on(h.state()).is_empty());
    // The simulator walks the demo route: a fix arrives within about a second.
    settle(&mut h, |c| c.station.gps.fix.is_some());
    assert!(h.state().station.gps.fix.as_ref().unwrap().has_position());
    let log_path = h.state().log_path().unwrap().to_path_buf();
    drop(h);
    std::thread::sleep(std::time::Duration::from_millis(300));
    let (records, _) = vestnav_device::session_log::read_log(&log_path).unwrap();
    assert!(
        records
            .iter()
            .any(|r| matches!(&r.entry, LogEntry::Command { command: VestCommand::Fire { .. }, .. }))
    );
    assert!(
        records.iter().any(|r| matches!(&r.entry, LogEntry::Command { command: VestCommand::StopAll, .. }))
    );
    assert!(records.iter().any(|r| matches!(&r.entry, LogEntry::Ack { .. })));
    assert!(records.iter().any(|r| matches!(&r.entry, LogEntry::Fix { .. })));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The vest's compass steers guidance through the console's own threads: the unit (protocol v2, an ideal
/// sensor, the wearer standing facing 90° true) streams its magnetic heading, the console loads the
/// calibration kept for the unit, and guidance, adding the WMM declination at the wearer's position, steers
/// by 90° true. Truth: the emulated wearer's body heading.
#[test]
fn the_vest_compass_reaches_guidance_and_steers_by_true_heading() {
    let setup = CompassSetup {
        motion: WearerMotion::Still { heading_deg: 90.0 },
        steel_east_m: None,
        ideal: true,
        seed: 5,
    };
    let (raw, _) = SimulatedCompass::new(&setup).sample(Instant::now());
    let field = raw.iter().map(|v| v * v).sum::<f64>().sqrt();
    let fake = Fake { compass: Some(setup), ..Fake::default() };
    let mut cfg = Config {
        map_tiles: false,
        guidance_auto: false,
        heading_mode: vestnav_core::guidance::HeadingMode::Compass,
        ..Config::default()
    };
    cfg.compass_calibrations.insert("emulated".into(), vestnav_core::compass::Calibration::identity(field));
    let mut h = harness_with(&fake, cfg);
    // The console asked for the stream and loaded the unit's calibration when it identified itself.
    settle(&mut h, |_| fake.sent().iter().any(|r| matches!(r, Request::SetCalibration(_))));
    let sent = fake.sent();
    assert!(sent.contains(&Request::HeadingStart { rate_hz: 5 }), "{sent:?}");
    assert!(sent.iter().any(|r| matches!(r, Request::SetCalibration(_))), "{sent:?}");
    settle(&mut h, |c| c.station.vest.heading.is_some_and(|a| a.quality_pct == Some(100)));
    let a = h.state().station.vest.heading.unwrap();
    assert_eq!(a.quality_pct, Some(100), "{a:?}");
    // A standing wearer near the emulated place (same WMM declination): guidance steers by the compass.
    for _ in 0..40 {
        fake.gps(&GpsEvent::Fix(Box::new(fix(42.3562, -71.1000, Duration::ZERO))));
        h.step();
        if h.state().station.guidance.as_ref().is_some_and(|g| g.heading_source == HeadingSource::Compass) {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let g = h.state().station.guidance.clone().unwrap();
    assert_eq!(g.heading_source, HeadingSource::Compass, "{g:?}");
    let heading = g.heading_deg.unwrap();
    assert!((heading - 90.0).abs() < 0.5, "guidance steers by {heading:.2}° true, the wearer faces 90°");
    assert!(g.declination_deg.is_some());
    // The Vest tab shows the reading as the unit reports it, with its true heading.
    h.get_by_label("Vest").click();
    h.run_steps(2);
    h.get_by_label_contains("quality 100 %");
}

/// Issue 15, "one unmistakable state": the vest's transport dies while guiding. The banner strip says VEST
/// LOST with what to do (derived from the vest worker's link state), guidance is on hold in the banner and
/// in its panel, and the grid is disabled; when the unit comes back the vest and guidance lines go.
#[test]
fn a_killed_vest_shows_in_the_banner_and_guidance_holds() {
    let fake = Fake::default();
    let dead = Arc::new(AtomicBool::new(false));
    let factory = Killable { fake: fake.clone(), dead: dead.clone() };
    let cfg = Config { map_tiles: false, guidance_auto: true, ..Config::default() };
    let console = Console::new(Box::new(factory), ConsoleOptions { cfg, ..ConsoleOptions::default() });
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    settle(&mut h, |c| c.station.vest.is_live());
    walk_until(&mut h, &fake, Duration::from_secs(3), |c| {
        c.station
            .guidance
            .as_ref()
            .is_some_and(|g| g.hold.is_none() && g.heading_source != HeadingSource::None)
    });
    h.run_steps(1);
    let c = h.state();
    assert!(banner_of(c, BannerSubject::Vest).is_none(), "{:?}", c.banners(Instant::now()));
    assert!(banner_of(c, BannerSubject::Guidance).is_none(), "{:?}", c.station.guidance);
    assert!(h.query_by_label_contains("VEST LOST").is_none());

    dead.store(true, std::sync::atomic::Ordering::SeqCst);
    walk_until(&mut h, &fake, Duration::from_secs(3), |c| {
        !c.station.vest.is_live() && c.station.guidance.as_ref().is_some_and(|g| g.hold.is_some())
    });
    h.run_steps(1);
    let vest = banner_of(h.state(), BannerSubject::Vest).expect("a vest line");
    assert_eq!(vest.severity, Severity::Alarm);
    assert!(vest.text.starts_with("VEST LOST: ") && vest.text.contains("Check the unit's power"), "{vest:?}");
    assert!(h.query_by_label_contains("VEST LOST: ").is_some());
    let guidance = banner_of(h.state(), BannerSubject::Guidance).expect("a guidance line");
    assert!(guidance.text.starts_with("GUIDANCE ON HOLD: no vest"), "{guidance:?}");
    assert!(h.query_by_label_contains("GUIDANCE ON HOLD: no vest").is_some());
    assert!(h.query_by_label_contains("On hold: vest").is_some(), "the Guidance panel says hold");
    assert!(h.query_by_label_contains("tactors cannot be fired").is_some());

    dead.store(false, std::sync::atomic::Ordering::SeqCst);
    walk_until(&mut h, &fake, Duration::from_secs(5), |c| {
        c.station.vest.is_live() && c.station.guidance.as_ref().is_some_and(|g| g.hold.is_none())
    });
    h.run_steps(1);
    assert!(h.state().station.vest.is_live());
    assert!(banner_of(h.state(), BannerSubject::Vest).is_none());
    assert!(banner_of(h.state(), BannerSubject::Guidance).is_none(), "{:?}", h.state().station.guidance);
    assert!(h.query_by_label_contains("VEST LOST").is_none());
    assert!(h.query_by_label_contains("GUIDANCE ON HOLD").is_none());
}

/// Disconnecting the vest by hand: the banner says so, and automatic guidance is on hold.
#[test]
fn a_disconnected_vest_shows_in_the_banner() {
    let fake = Fake::default();
    let cfg = Config { map_tiles: false, guidance_auto: true, ..Config::default() };
    let mut h = harness_with(&fake, cfg);
    h.get_by_label("Disconnect vest").click();
    settle(&mut h, |c| !c.station.vest.is_live());
    h.run_steps(1);
    assert!(h.query_by_label_contains("VEST DISCONNECTED: ").is_some());
    assert!(h.query_by_label_contains("GUIDANCE ON HOLD: no vest").is_some());
}

/// Issue 15, pattern editor: what is painted on two frames is exactly what the unit is told to play.
/// Truth: the tactors and durations the test painted and typed.
#[test]
fn the_pattern_editor_previews_exactly_the_painted_frames() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    open_pattern_editor(&mut h);
    paint(&mut h, &[0, 5]);
    set_frame_duration(&mut h, 1, 300);
    h.get_by_label("Add frame").click();
    h.run_steps(2);
    paint(&mut h, &[10, 15]);
    set_frame_duration(&mut h, 2, 700);
    h.get_by_label("Preview").click();
    settle(&mut h, |_| !plays(&fake).is_empty());
    let frame = |tactors: [usize; 2], duration_ms| vestnav_core::vest::Frame {
        mask: TactorMask::from_indices(tactors),
        duration_ms,
    };
    assert_eq!(
        plays(&fake),
        vec![Request::Play { frames: vec![frame([0, 5], 300), frame([10, 15], 700)], repeats: 1 }]
    );
}

/// Issue 15: an open pattern editor stays open and usable when the Vest section is collapsed (the window is
/// the frame's, not the section's).
#[test]
fn the_pattern_editor_survives_collapsing_the_vest_section() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    open_pattern_editor(&mut h);
    h.get_by_label("Vest").click();
    h.run_steps(2);
    assert!(h.query_by_label("Pattern editor...").is_none(), "the Vest section is collapsed");
    paint(&mut h, &[3]);
    h.get_by_label("Preview").click();
    settle(&mut h, |_| !plays(&fake).is_empty());
    assert_eq!(
        plays(&fake),
        vec![Request::Play {
            frames: vec![vestnav_core::vest::Frame {
                mask: TactorMask::from_indices([3]),
                duration_ms: h.state().pattern_editor.pattern.frames[0].duration_ms,
            }],
            repeats: 1
        }]
    );
}

/// Issue 15, pattern editor: a pattern outside the limits says why and cannot be previewed. Truth: the
/// limits of `vestnav_device::wtcu::limits` (8 tactors at once, 2000 ms continuous).
#[test]
fn an_invalid_pattern_shows_the_reason_and_preview_is_disabled() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    open_pattern_editor(&mut h);
    paint(&mut h, &[0, 1, 2, 3, 4, 5, 6, 7, 8]);
    h.run_steps(1);
    assert!(h.query_by_label_contains("9 tactors at once").is_some());
    assert!(disabled(&h, "Preview"));
    assert!(disabled(&h, "Save to file"));
    paint(&mut h, &[8]);
    h.run_steps(1);
    assert!(h.query_by_label_contains("Refused").is_none());
    assert!(!disabled(&h, "Preview"));
    set_frame_duration(&mut h, 1, 2500);
    assert!(h.query_by_label_contains("2500 ms exceeds the limit of 2000 ms").is_some());
    assert!(disabled(&h, "Preview"));
    h.get_by_label("Preview").click();
    h.run_steps(2);
    std::thread::sleep(Duration::from_millis(50));
    h.run_steps(1);
    assert!(plays(&fake).is_empty(), "{:?}", fake.sent());
}

/// Issue 15, pattern editor: a pattern saved to a file loads back equal, and saving again does not replace
/// the file without asking. Truth: the pattern the test built.
#[test]
fn a_saved_pattern_loads_back_equal_and_is_not_overwritten_unasked() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    open_pattern_editor(&mut h);
    paint(&mut h, &[3, 6]);
    h.get_by_label("Duplicate frame").click();
    h.run_steps(2);
    paint(&mut h, &[6, 9]);
    let path = test_dir("pattern-editor").join("sweep.json");
    {
        let ed = &mut h.state_mut().pattern_editor;
        ed.pattern.name = "diagonal".into();
        ed.pattern.repeats = 2;
        ed.path = path.display().to_string();
    }
    h.run_steps(1);
    let saved = h.state().pattern_editor.pattern.clone();
    assert_eq!(saved.frames.len(), 2);
    assert_eq!(saved.frames[1].mask, TactorMask::from_indices([3, 9]));
    h.get_by_label("Save to file").click();
    h.run_steps(2);
    assert!(path.exists(), "{:?}", h.state().pattern_editor.message);
    let on_disk = std::fs::read_to_string(&path).unwrap();

    // Change it, save again: the file stays as it was until replacing is confirmed.
    h.state_mut().pattern_editor.pattern.repeats = 1;
    h.get_by_label("Save to file").click();
    h.run_steps(2);
    assert!(h.query_by_label("Replace file").is_some());
    assert_eq!(std::fs::read_to_string(&path).unwrap(), on_disk);
    h.get_by_label("Cancel").click();
    h.run_steps(2);
    assert_eq!(std::fs::read_to_string(&path).unwrap(), on_disk);

    h.get_by_label("Load file").click();
    h.run_steps(2);
    assert_eq!(h.state().pattern_editor.pattern, saved);

    // Confirmed, the file is replaced.
    h.state_mut().pattern_editor.pattern.repeats = 1;
    h.get_by_label("Save to file").click();
    h.run_steps(2);
    h.get_by_label("Replace file").click();
    h.run_steps(2);
    h.get_by_label("Load file").click();
    h.run_steps(2);
    assert_eq!(h.state().pattern_editor.pattern, vestnav_core::vest::Pattern { repeats: 1, ..saved });
    let _ = std::fs::remove_dir_all(path.parent().unwrap());
}

/// Issue 15, pattern editor: per-tactor intensity goes to the unit as `SET_INTENSITY` before the PLAY.
/// Truth: the levels the test set.
#[test]
fn intensity_is_sent_before_the_play() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    open_pattern_editor(&mut h);
    paint(&mut h, &[1, 2]);
    h.state_mut().pattern_editor.levels[2] = 80;
    h.run_steps(1);
    h.get_by_label("Preview").click();
    settle(&mut h, |_| !plays(&fake).is_empty());
    assert_eq!(
        fake.sent(),
        vec![
            Request::SetIntensity { mask: TactorMask::from_indices([1]), level: 255 },
            Request::SetIntensity { mask: TactorMask::from_indices([2]), level: 80 },
            Request::Play {
                frames: vec![vestnav_core::vest::Frame {
                    mask: TactorMask::from_indices([1, 2]),
                    duration_ms: 500
                }],
                repeats: 1
            },
        ]
    );
}

#[test]
fn space_on_a_focused_tactor_button_stops_and_does_not_fire_it() {
    let fake = Fake::default();
    let mut h = harness(&fake);
    h.get_by_label("T5").focus();
    h.run_steps(2);
    h.key_press(egui::Key::Space);
    settle(&mut h, |_| !fake.sent().is_empty());
    h.run_steps(3);
    std::thread::sleep(Duration::from_millis(50));
    h.run_steps(2);
    assert_eq!(fake.sent(), vec![Request::StopAll]);
    assert_eq!(on(h.state()), TactorMask::NONE);
}
