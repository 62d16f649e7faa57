//! The Stations window with no broker reachable: it says so where the operator looks, and its STOP ALL
//! says what happened to the order (queued; each station stops itself when its operator link times out).
//! The window against a real broker and three stations is `tests/integration/remote.rs`.
#![allow(clippy::unwrap_used)]

use std::time::{Duration, Instant};

use egui_kittest::kittest::Queryable as _;
use vestnav_app::remote_panel::RemotePanel;
use vestnav_remote::BrokerConfig;

#[test]
fn without_a_broker_the_window_says_so_and_stop_all_says_what_became_of_it() {
    // A loopback port nothing listens on (bound, read, released).
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let config = BrokerConfig {
        url: format!("mqtt://127.0.0.1:{port}"),
        insecure_plaintext_loopback: true,
        ..BrokerConfig::default()
    };
    let panel = RemotePanel::connect(&config, "operator").unwrap();
    let until = Instant::now() + Duration::from_secs(5);
    while panel.fleet().broker_status().1.is_none() {
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
    let mut h = egui_kittest::Harness::builder()
        .with_size(egui::vec2(900.0, 700.0))
        .build_ui_state(|ui, (w, cfg, remote): &mut State| w.ui(ui.ctx(), cfg, remote), (window, cfg, None));
    h.run_steps(2);
    assert!(h.query_by_label_contains("not connected").is_some());
    h.get_by_label("Connect").click();
    h.run_steps(2);
    let want = format!("{}: readable by group or others (mode 644)", pw.display());
    assert!(h.query_by_label_contains(&want).is_some(), "the refusal names the file and the fix");
    assert!(h.state().2.is_none(), "nothing connected");
    let _ = std::fs::remove_dir_all(&dir);
}
