//! The Lab outputs window: the operator turns OSC on for the console's own station, sees it running with its
//! counts, and turns it off again; the station's status says the same as the window.
#![allow(clippy::unwrap_used)]

use std::time::{Duration, Instant};

use egui_kittest::kittest::Queryable as _;
use vestnav_app::lab_window::LabWindow;
use vestnav_station::Station;

#[test]
fn the_window_starts_and_stops_the_stations_osc_output() {
    let station = Station::new(
        Box::new(vestnav_station::hardware::Hardware::default()),
        vestnav_station::StationOptions::default(),
    );
    let mut window = LabWindow::default();
    window.open = true;
    let mut h = egui_kittest::Harness::builder().with_size(egui::vec2(600.0, 400.0)).build_ui_state(
        |ui, (w, s): &mut (LabWindow, Station)| {
            let _ = w.poll(s);
            w.ui(ui.ctx(), s);
        },
        (window, station),
    );
    h.run_steps(2);
    assert!(h.query_by_label_contains("Lab outputs off").is_some());
    // LSL off (this test needs no liblsl), OSC on to the default 127.0.0.1:9000.
    h.get_by_label("LSL streams (markers, position, heading, vest)").click_accesskit();
    h.run_steps(2);
    h.get_by_label("OSC to").click_accesskit();
    h.run_steps(2);
    h.get_by_label("Start").click_accesskit();
    let until = Instant::now() + Duration::from_secs(10);
    while h.state().1.lab_status().is_none() {
        assert!(
            Instant::now() < until,
            "the outputs started: {:?} starting {} error {}",
            h.state().1.lab_config(),
            h.query_by_label_contains("starting").is_some(),
            h.query_by_label_contains("OSC target").is_some()
        );
        h.run_steps(1);
        std::thread::sleep(Duration::from_millis(10));
    }
    h.state().1.lab().marker("pause", 1.0);
    h.run_steps(2);
    let status = h.state().1.lab_status().unwrap();
    assert_eq!(status.osc.as_ref().unwrap().target, "127.0.0.1:9000");
    assert!(h.query_by_label_contains("OSC to 127.0.0.1:9000").is_some());
    assert!(h.query_by_label_contains("1 markers").is_some());
    assert!(h.query_by_label_contains("LSL off").is_some());
    h.get_by_label("Stop").click_accesskit();
    h.run_steps(2);
    assert!(h.state().1.lab_status().is_none());
    assert!(h.query_by_label_contains("Lab outputs off").is_some());
}

mod common;

use common::console::Fake;
use common::settle;
use egui_kittest::Harness;
use vestnav_app::config::{Config, LabSettings};
use vestnav_app::console::{Console, ConsoleOptions};
use vestnav_station::lab::{LabConfig, LslState};

/// The console with its settings file at `path` (read as the console reads it at start).
fn console_at(fake: &Fake, path: &std::path::Path) -> Harness<'static, Console> {
    let (cfg, problem) = Config::load(path);
    assert!(problem.is_none(), "{problem:?}");
    let cfg = Config { map_tiles: false, guidance_auto: false, ..cfg };
    let console = Console::new(
        Box::new(fake.clone()),
        ConsoleOptions { cfg, cfg_path: Some(path.to_path_buf()), ..ConsoleOptions::default() },
    );
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    h.run_steps(2);
    h
}

fn notices(c: &Console) -> String {
    c.station.notices.all().iter().map(|n| n.text.as_str()).collect::<Vec<_>>().join(" | ")
}

/// Issue 25: the Lab outputs chosen in the window (OSC to a port of this test, LSL off) are saved; the
/// console started again on the same settings file runs them again, and they reach a real UDP socket;
/// stopped, they stay stopped at the next start.
#[test]
fn lab_outputs_are_saved_and_started_again_at_the_next_start() {
    let dir = std::env::temp_dir().join(format!("vestnav-ui-lab-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let path = dir.join("console.json");
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    socket.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let target = socket.local_addr().unwrap();
    let fake = Fake::default();

    let mut h = console_at(&fake, &path);
    h.get_by_label("View").click();
    h.run_steps(2);
    h.get_by_label("Lab outputs (LSL, OSC)…").click();
    h.run_steps(4);
    assert!(h.state().lab_window.open, "the window opened");
    h.get_by_label("LSL streams (markers, position, heading, vest)").click();
    h.get_by_label("OSC to").click();
    h.run_steps(2);
    // Each field's text replaced: focused, all selected, typed over.
    for (label, text) in
        [("HOST:PORT", target.to_string()), ("Stream names start with", "labtest".to_owned())]
    {
        h.get_by_label(label).focus();
        h.run_steps(1);
        h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
        h.run_steps(1);
        h.get_by_label(label).type_text(&text);
        h.run_steps(1);
    }
    h.get_by_label("Start").click();
    assert!(settle(&mut h, |c| c.station.lab_status().is_some()), "{}", notices(h.state()));
    drop(h);
    let (saved, _) = Config::load(&path);
    let expected = LabSettings {
        on: true,
        lsl: false,
        osc: true,
        osc_target: target.to_string(),
        stream_prefix: "labtest".into(),
    };
    assert_eq!(saved.lab, expected, "the choices and that they ran, in the file");

    // The next start runs them again, says so, and the messages arrive.
    let mut h = console_at(&fake, &path);
    assert!(settle(&mut h, |c| c.station.lab_status().is_some()), "{}", notices(h.state()));
    let want = LabConfig { lsl: false, osc: Some(target), stream_prefix: "labtest".into() };
    assert_eq!(h.state().station.lab_config(), Some(want));
    assert!(notices(h.state()).contains("lab outputs started again"), "{}", notices(h.state()));
    h.state().station.lab().marker("restored", 1.0);
    // Vest events go out too: read until the marker (the socket's timeout ends a wait for nothing).
    let mut buf = [0u8; 512];
    loop {
        let n = socket.recv(&mut buf).unwrap();
        let text = String::from_utf8_lossy(&buf[..n]);
        if text.starts_with("/vestnav/marker") {
            assert!(text.contains("restored"), "{text:?}");
            break;
        }
    }
    // The window shows the restored choices.
    h.get_by_label("View").click();
    h.run_steps(2);
    h.get_by_label("Lab outputs (LSL, OSC)…").click();
    h.run_steps(4);
    assert!(h.state().lab_window.open, "the window opened");
    assert!(h.query_all_by_label_contains(&format!("OSC to {target}:")).count() >= 1, "its status line");
    assert!(h.query_by_label("Restart").is_some(), "running, as the window shows");
    h.get_by_label("Stop").click();
    h.run_steps(2);
    assert!(h.state().station.lab_status().is_none());
    drop(h);
    assert!(!Config::load(&path).0.lab.on, "stopped: saved as off");
    let mut h = console_at(&fake, &path);
    h.run_steps(5);
    assert!(!h.state().lab_window.busy() && h.state().station.lab_config().is_none(), "nothing restarted");
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Saved as on with LSL, and liblsl is not there (`VESTNAV_LIBLSL` names a file that does not exist; set
/// for a child run of this test, the environment being the process's): nothing starts, the console says
/// so in its status line and the Lab status says what was tried and how to install liblsl.
#[test]
fn saved_lsl_without_liblsl_is_not_started_and_said() {
    const CHILD: &str = "VESTNAV_TEST_LAB_CHILD";
    if std::env::var_os(CHILD).is_none() {
        let out = std::process::Command::new(std::env::current_exe().unwrap())
            .args(["--exact", "saved_lsl_without_liblsl_is_not_started_and_said", "--nocapture"])
            .env(CHILD, "1")
            .env("VESTNAV_LIBLSL", "/nonexistent/vestnav-test/liblsl.so")
            .output()
            .unwrap();
        let text =
            format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        assert!(out.status.success() && text.contains("1 passed"), "{text}");
        return;
    }
    let dir = std::env::temp_dir().join(format!("vestnav-ui-lab-missing-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let path = dir.join("console.json");
    let cfg = Config {
        lab: LabSettings { on: true, lsl: true, osc: true, ..LabSettings::default() },
        ..Config::default()
    };
    cfg.save(&path).unwrap();
    let fake = Fake::default();
    let mut h = console_at(&fake, &path);
    assert!(settle(&mut h, |c| !c.lab_window.busy()), "the start ended");
    h.run_steps(2);
    let status = h.state().station.lab_status().unwrap();
    let LslState::Missing { why } = &status.lsl else { panic!("{status:?}") };
    assert!(why.contains("/nonexistent/vestnav-test/liblsl.so"), "{why}");
    assert!(!h.state().station.lab().is_on(), "nothing runs, OSC neither");
    let said = notices(h.state());
    assert!(said.contains("lab outputs saved as on were NOT started"), "{said}");
    assert!(
        h.query_all_by_label_contains("lab outputs saved as on were NOT started").count() >= 1,
        "shown (status line and banner)"
    );
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}
