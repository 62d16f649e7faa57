//! The Stations window with no broker reachable: it says so where the operator looks, and its STOP ALL
//! says what happened to the order (queued; each station stops itself when its operator link times out).
//! The window against a real broker and three stations is `tests/integration/remote.rs`.
#![allow(clippy::unwrap_used)]

use std::time::{Duration, Instant};

use egui_kittest::kittest::Queryable as _;
use vestnav_app::remote_panel::RemotePanel;
use vestnav_remote::BrokerConfig;
use vestnav_station::stop::StopPath;

#[test]
fn without_a_broker_the_window_says_so_and_stop_all_says_what_became_of_it() {
    // A loopback port nothing listens on, held for the whole test.
    let refusing = vestnav_device::testkit::RefusingPort::bind().unwrap();
    let port = refusing.port();
    let config = BrokerConfig {
        url: format!("mqtt://127.0.0.1:{port}"),
        insecure_plaintext_loopback: true,
        ..BrokerConfig::default()
    };
    let panel = RemotePanel::connect(&config, "operator", StopPath::default()).unwrap();
    let until = Instant::now() + Duration::from_secs(5);
    while panel.fleet().unwrap().broker_status().1.is_none() {
        assert!(Instant::now() < until, "the refused connection is reported");
        std::thread::sleep(Duration::from_millis(10));
    }
    // The console's own station (no devices started): what the drive controls would send.
    let local = vestnav_station::Station::new(
        Box::new(vestnav_station::hardware::Hardware::default()),
        vestnav_station::StationOptions::default(),
    );
    let mut h = egui_kittest::Harness::builder().with_size(egui::vec2(1000.0, 500.0)).build_ui_state(
        |ui, (p, local): &mut (RemotePanel, vestnav_station::Station)| p.ui(ui.ctx(), local, &[]),
        (panel, local),
    );
    h.run_steps(2);
    assert!(h.query_by_label_contains("broker NOT connected").is_some());
    assert!(h.query_by_label_contains("No station has published").is_some());
    h.get_by_label("STOP ALL stations").click();
    h.run_steps(2);
    assert!(
        h.query_by_label_contains("STOP ALL: not connected to the broker: queued").is_some(),
        "the operator is told the order is only queued"
    );
}

/// The Broker window: a password file others can read is refused at Connect with its reason where the
/// operator looks, nothing connects; the settings edited are the console's (saved with them).
#[test]
#[cfg(unix)]
fn the_broker_window_refuses_a_password_file_others_can_read() {
    use std::os::unix::fs::PermissionsExt as _;
    type State =
        (vestnav_app::broker_settings::BrokerWindow, vestnav_app::config::Config, Option<RemotePanel>);
    let dir = std::env::temp_dir().join(format!("vestnav-broker-window-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let pw = dir.join("password");
    std::fs::write(&pw, "secret\n").unwrap();
    std::fs::set_permissions(&pw, std::fs::Permissions::from_mode(0o644)).unwrap();
    let cfg = vestnav_app::config::Config {
        broker: BrokerConfig {
            url: "mqtts://127.0.0.1:8883".into(),
            user: Some("operator".into()),
            password_file: Some(pw.clone()),
            ..BrokerConfig::default()
        },
        ..vestnav_app::config::Config::default()
    };
    let mut window = vestnav_app::broker_settings::BrokerWindow::default();
    window.open = true;
    let mut h = egui_kittest::Harness::builder().with_size(egui::vec2(900.0, 700.0)).build_ui_state(
        |ui, (w, cfg, remote): &mut State| {
            w.ui(ui.ctx(), cfg, remote, || RemotePanel::new(StopPath::default(), None));
        },
        (window, cfg, None),
    );
    h.run_steps(2);
    assert!(h.query_by_label_contains("not connected").is_some());
    h.get_by_label("Connect").click();
    h.run_steps(2);
    let want = format!("{}: readable by group or others (mode 644)", pw.display());
    assert!(h.query_by_label_contains(&want).is_some(), "the refusal names the file and the fix");
    assert!(h.state().2.is_none(), "nothing connected");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The Stations window with no broker: a station on this machine's ports is added from the form (an
/// emulated vest and the simulated GPS here), listed as this machine's, reaches a ready vest; a wrong vest
/// form is refused with its reason; Remove takes the station off the list and off the stop path.
#[test]
fn a_local_station_is_added_from_the_form_and_removed() {
    use egui::accesskit::Role;
    let stop = StopPath::default();
    let local = vestnav_station::Station::new(
        Box::new(vestnav_station::hardware::Hardware::default()),
        vestnav_station::StationOptions::default(),
    );
    let mut h = egui_kittest::Harness::builder().with_size(egui::vec2(1300.0, 700.0)).build_ui_state(
        |ui, (p, local): &mut (RemotePanel, vestnav_station::Station)| p.ui(ui.ctx(), local, &[]),
        (RemotePanel::new(stop.clone(), None), local),
    );
    h.run_steps(2);
    assert!(h.query_by_label_contains("no broker").is_some());
    assert!(h.query_by_label_contains("No station yet").is_some());
    h.get_by_label_contains("Add a station on this machine").click();
    h.run_steps(2);
    let fill = |h: &mut egui_kittest::Harness<'_, (RemotePanel, vestnav_station::Station)>,
                texts: [&str; 3]| {
        for (i, text) in texts.into_iter().enumerate() {
            h.get_all_by_role(Role::TextInput).nth(i).unwrap().focus();
            h.run_steps(1);
            h.get_all_by_role(Role::TextInput).nth(i).unwrap().type_text(text);
            h.run_steps(1);
        }
        h.get_by_label("Add station").click();
        h.run_steps(2);
    };
    fill(&mut h, ["charlie", "emulated", "sim"]);
    assert!(h.query_by_label_contains("charlie (this machine)").is_some(), "the station is listed");
    let until = Instant::now() + Duration::from_secs(10);
    while !h
        .state()
        .0
        .stations()
        .station("charlie")
        .and_then(|v| v.state)
        .is_some_and(|s| s.station.vest_link == Some(vestnav_device::wtcu::LinkState::Ready))
    {
        assert!(Instant::now() < until, "charlie's vest comes up");
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(stop.len(), 1, "its vest is on the console's stop path");
    fill(&mut h, ["delta", "bluetooth", "sim"]);
    assert!(
        h.query_by_label_contains("Add station: --vest \"bluetooth\": expected emulated | serial:PATH")
            .is_some(),
        "the wrong vest form is refused with its reason"
    );
    h.get_by_label("Remove").click();
    h.run_steps(2);
    assert!(h.query_by_label_contains("charlie (this machine)").is_none());
    assert!(stop.is_empty(), "the removed station's vest left the stop path");
}
