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
    let mut h = egui_kittest::Harness::builder()
        .with_size(egui::vec2(600.0, 400.0))
        .build_ui_state(|ui, (w, s): &mut (LabWindow, Station)| w.ui(ui.ctx(), s), (window, station));
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
