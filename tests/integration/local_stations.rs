//! Several stations on one machine, no broker (issue 24): two more vests on their own PTYs, started from
//! the console's Stations window beside its own station. Each is driven alone (a FIRE reaches its vest
//! only; its Stop stops its vest only), the console's STOP ALL — its stop path, which every local station
//! joins — reaches every vest with no station thread in the way, and removing a station or closing the
//! window stops its vest.

use std::time::{Duration, Instant};

use egui_kittest::kittest::Queryable as _;
use vestnav_app::remote_panel::RemotePanel;
use vestnav_device::wtcu::{CommandKind, LinkState};
use vestnav_remote::LocalStationConfig;
use vestnav_station::hardware::Hardware;
use vestnav_station::sources::{VestSourceConfig, parse_gps_spec};
use vestnav_station::stop::StopPath;

use crate::remote::{Unit, click, run_until_shown, wait_for};

fn config(name: &str, unit: &Unit) -> LocalStationConfig {
    LocalStationConfig {
        name: name.into(),
        vest: VestSourceConfig::Serial { port: unit.path.clone() },
        gps: parse_gps_spec("sim").unwrap(),
        log_dir: None,
    }
}

/// Turns the window until `ok`, for at most 10 s; on time-out, says what the window and the station show.
fn step_until(
    h: &mut egui_kittest::Harness<'_, (RemotePanel, vestnav_station::Station)>,
    what: &str,
    mut ok: impl FnMut() -> bool,
) {
    let until = Instant::now() + Duration::from_secs(10);
    while !ok() {
        if Instant::now() >= until {
            let panel = &h.state().0;
            let views: Vec<_> = panel
                .stations()
                .stations()
                .into_iter()
                .map(|v| (v.name.clone(), v.state.map(|s| s.station.vest_link), v.events))
                .collect();
            panic!("timed out waiting for {what}; the stations: {views:?}");
        }
        std::thread::sleep(Duration::from_millis(5));
        h.run_steps(1);
    }
}

fn ready(panel: &RemotePanel, name: &str) -> bool {
    panel
        .stations()
        .station(name)
        .and_then(|v| v.state)
        .is_some_and(|s| s.station.vest_link == Some(LinkState::Ready))
}

#[test]
fn two_local_stations_are_driven_alone_and_stopped_together() {
    let _t = crate::timing_exclusive();
    let (a, b) = (Unit::spawn(), Unit::spawn());
    let stop = StopPath::default();
    let mut panel = RemotePanel::new(stop.clone(), None);
    for (name, unit) in [("alpha", &a), ("bravo", &b)] {
        panel.stations_mut().add_local(config(name, unit), Box::new(Hardware::default())).unwrap();
    }
    let again = panel.stations_mut().add_local(config("alpha", &a), Box::new(Hardware::default()));
    assert!(again.unwrap_err().contains("already called \"alpha\""), "a second alpha is refused");
    let bad = panel.stations_mut().add_local(config("a/b", &a), Box::new(Hardware::default()));
    assert!(bad.unwrap_err().starts_with("station name"), "a name that is not a topic level is refused");
    for n in ["alpha", "bravo"] {
        wait_for(&format!("{n}'s vest ready"), Duration::from_secs(20), || ready(&panel, n));
    }
    assert_eq!(stop.len(), 2, "both vests are on the console's stop path");

    // The window: rows for both, marked as this machine's; drive alpha, fire T5.
    let local = vestnav_station::Station::new(
        Box::new(Hardware::default()),
        vestnav_station::StationOptions::default(),
    );
    let mut h = egui_kittest::Harness::builder().with_size(egui::vec2(1400.0, 900.0)).build_ui_state(
        |ui, (p, local): &mut (RemotePanel, vestnav_station::Station)| p.ui(ui.ctx(), local, &[]),
        (panel, local),
    );
    h.run_steps(2);
    assert!(h.query_by_label_contains("alpha (this machine)").is_some());
    assert!(h.query_by_label_contains("bravo (this machine)").is_some());
    assert!(h.query_by_label_contains("no broker").is_some(), "the window says there is no broker");
    click(&mut h, "Drive", 0);
    h.run_steps(2);
    assert!(h.query_by_label_contains("Driving alpha").is_some());
    let t0 = Instant::now();
    click(&mut h, "T5", 0);
    h.run_steps(2);
    wait_for("the FIRE at alpha's vest", Duration::from_secs(5), || {
        !a.received_after(CommandKind::Fire, t0).is_empty()
    });
    run_until_shown(&mut h, "applied", "alpha's answer shown in the window");
    std::thread::sleep(Duration::from_millis(200));
    assert!(b.received_after(CommandKind::Fire, t0).is_empty(), "bravo's vest got no FIRE");

    // bravo's own Stop: its vest only.
    let t1 = Instant::now();
    click(&mut h, "Stop", 1);
    step_until(&mut h, "STOP ALL at bravo's vest", || !b.received_after(CommandKind::StopAll, t1).is_empty());
    std::thread::sleep(Duration::from_millis(200));
    assert!(
        a.received_after(CommandKind::StopAll, t1).is_empty(),
        "alpha's vest was not stopped by bravo's Stop"
    );

    // The console's STOP ALL is its stop path: both vests, straight from this thread, timed at the units.
    let t2 = Instant::now();
    stop.stop_all();
    wait_for("STOP ALL at both vests", Duration::from_secs(5), || {
        !a.received_after(CommandKind::StopAll, t2).is_empty()
            && !b.received_after(CommandKind::StopAll, t2).is_empty()
    });
    for (n, u) in [("alpha", &a), ("bravo", &b)] {
        let ms = (u.received_after(CommandKind::StopAll, t2)[0] - t2).as_secs_f64() * 1e3;
        println!("local station {n}: stop path to STOP_ALL at the unit {ms:.1} ms");
    }

    // Remove alpha: its vest stops, its port closes, it leaves the path and the list.
    let t3 = Instant::now();
    click(&mut h, "Remove", 0);
    h.run_steps(2);
    wait_for("alpha's vest stopped at removal", Duration::from_secs(5), || {
        !a.received_after(CommandKind::StopAll, t3).is_empty()
    });
    assert_eq!(stop.len(), 1, "alpha left the stop path");
    assert!(h.query_by_label_contains("alpha (this machine)").is_none());

    // Closing the window (dropping it) ends bravo the same way.
    let t4 = Instant::now();
    drop(h);
    wait_for("bravo's vest stopped at the end", Duration::from_secs(5), || {
        !b.received_after(CommandKind::StopAll, t4).is_empty()
    });
    assert!(stop.is_empty(), "no vest left on the path");
}
