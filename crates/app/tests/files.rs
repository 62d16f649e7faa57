//! Issue 15, files and alarms: typed paths resolve against a sensible base and show the absolute path,
//! saves ask "Replace X?" before writing over a file, recent files follow exports and show missing files,
//! and the audible alarm rings once per loss.
#![allow(clippy::unwrap_used)]

mod common;

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use egui_kittest::kittest::Queryable as _;
use vestnav_app::file_dialog::RecentKind;
use vestnav_device::gps::{GpsEvent, SourceState};

fn test_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("vestnav-files-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A relative typed path is taken in the console's files folder (`~/Documents/vestnav`), not in the folder
/// of the last file used (a replayed log's) nor the working directory; the field shows the absolute path it
/// will use, and the export writes exactly there.
#[test]
fn a_typed_relative_path_resolves_in_the_files_folder_and_is_shown_absolute() {
    let elsewhere = test_dir("relative");
    let devices = common::Devices::default();
    let mut h = common::console(&devices);
    h.state_mut().cfg.recent.last_dir = Some(elsewhere.clone());
    let name = format!("walk-test-{}.gpx", std::process::id());
    h.state_mut().map.gpx_path = name.clone();
    h.run_steps(2);
    let home = directories::UserDirs::new().unwrap();
    let folder = home.document_dir().unwrap_or_else(|| home.home_dir()).join("vestnav");
    let abs = folder.join(&name);
    assert!(h.query_by_label(&format!("Uses: {}", abs.display())).is_some(), "the absolute path is shown");
    h.get_by_label("Export GPX").click();
    h.run_steps(2);
    assert!(abs.exists(), "{}", h.state().latest_notice().map(|n| n.text.clone()).unwrap_or_default());
    assert!(!elsewhere.join(&name).exists(), "nothing in the last file's folder");
    assert!(!PathBuf::from(&name).exists(), "nothing in the working directory");
    std::fs::remove_file(&abs).unwrap();
    std::fs::remove_dir_all(&elsewhere).unwrap();
}

/// Saving over an existing file asks "Replace X?"; Cancel leaves it, Replace writes it.
#[test]
fn saving_over_a_file_asks_and_writes_only_after_replace() {
    let dir = test_dir("replace");
    let path = dir.join("route.gpx");
    std::fs::write(&path, "keep me").unwrap();
    let devices = common::Devices::default();
    let mut h = common::console(&devices);
    h.state_mut().map.gpx_path = path.display().to_string();
    h.run_steps(2);
    let question = format!("Replace {}?", path.display());
    h.get_by_label("Export GPX").click();
    h.run_steps(2);
    assert!(h.query_by_label(&question).is_some(), "asked");
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "keep me");
    h.get_by_label("Cancel").click();
    h.run_steps(2);
    assert!(h.query_by_label(&question).is_none(), "the question closed");
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "keep me", "Cancel keeps the file");
    h.get_by_label("Export GPX").click();
    h.run_steps(2);
    h.get_by_label("Replace").click();
    h.run_steps(2);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("<gpx"), "replaced: {text}");
    assert!(h.query_by_label(&question).is_none());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An export joins the recent route files; a file deleted since is listed as missing, not opened.
#[test]
fn recent_files_follow_an_export_and_mark_a_deleted_file_missing() {
    let dir = test_dir("recent");
    let path = dir.join("loop.gpx");
    let devices = common::Devices::default();
    let mut h = common::console(&devices);
    assert!(h.state().cfg.recent.list(RecentKind::Routes).is_empty());
    h.state_mut().map.gpx_path = path.display().to_string();
    h.run_steps(2);
    h.get_by_label("Export GPX").click();
    h.run_steps(2);
    assert_eq!(h.state().cfg.recent.list(RecentKind::Routes), std::slice::from_ref(&path));
    assert_eq!(h.state().cfg.recent.last_dir.as_deref(), Some(dir.as_path()));

    h.get_by_label("Recent").click();
    h.run_steps(2);
    assert!(h.query_by_label(&path.display().to_string()).is_some(), "listed");
    assert!(h.query_by_label_contains("(missing)").is_none());
    h.key_press(egui::Key::Escape);
    h.run_steps(2);

    std::fs::remove_file(&path).unwrap();
    h.state_mut().map.gpx_path.clear();
    h.run_steps(1);
    let routes_before = h.state().station.route().waypoints().to_vec();
    h.get_by_label("Recent").click();
    h.run_steps(2);
    let missing = format!("{} (missing)", path.display());
    assert!(h.query_by_label(&missing).is_some(), "shown as missing");
    h.get_by_label(&missing).click();
    h.run_steps(2);
    assert_eq!(h.state().station.route().waypoints(), routes_before, "a missing file is not opened");
    assert!(h.state().map.gpx_path.is_empty());
    std::fs::remove_dir_all(&dir).unwrap();
}

fn state(s: SourceState) -> GpsEvent {
    GpsEvent::State(s)
}

/// The bell rings once on the transition to fix loss (not on every frame while lost), again on a new loss
/// after recovery, and never when the operator turned it off.
#[test]
fn the_alarm_rings_once_per_fix_loss() {
    let devices = common::Devices::default();
    let mut h = common::console(&devices);
    let rings = Arc::new(AtomicUsize::new(0));
    let counter = Arc::clone(&rings);
    h.state_mut().set_bell(move || {
        counter.fetch_add(1, Ordering::SeqCst);
    });
    h.run_steps(3);
    assert_eq!(rings.load(Ordering::SeqCst), 0, "no ring without a loss");

    let lose = |h: &mut egui_kittest::Harness<'static, vestnav_app::console::Console>| {
        devices.gps(&state(SourceState::Lost { reason: "receiver gone".into() }));
        assert!(common::settle(h, |c| matches!(c.station.gps.state, Some(SourceState::Lost { .. }))));
        h.run_steps(5);
    };
    let recover = |h: &mut egui_kittest::Harness<'static, vestnav_app::console::Console>| {
        devices.gps(&state(SourceState::Live { detail: "back".into() }));
        assert!(common::settle(h, |c| matches!(c.station.gps.state, Some(SourceState::Live { .. }))));
        h.run_steps(2);
    };
    lose(&mut h);
    assert!(h.query_by_label_contains("GPS FIX LOST").is_some(), "the banner shows it too");
    assert_eq!(rings.load(Ordering::SeqCst), 1, "once on the transition");
    recover(&mut h);
    assert_eq!(rings.load(Ordering::SeqCst), 1);
    lose(&mut h);
    assert_eq!(rings.load(Ordering::SeqCst), 2, "again on a new loss");

    recover(&mut h);
    h.state_mut().cfg.audible_alarm = false;
    lose(&mut h);
    assert_eq!(rings.load(Ordering::SeqCst), 2, "off means silent");
}
