//! The console's Study tab driving a remote station through a real Mosquitto (`remote.rs`'s broker and
//! `vestnav station` processes with their units on PTYs): a localization protocol loaded on the station,
//! started, a trial answered on the back-view grid, and the row the station wrote to its own results file.

#![cfg(unix)]

use std::time::{Duration, Instant};

use egui_kittest::kittest::Queryable as _;
use vestnav_app::console::{Console, ConsoleOptions, Tab};
use vestnav_device::wtcu::CommandKind;
use vestnav_station::study::{StudyPhase, StudyView};

use crate::remote::{Broker, StationProc, click, in_contact, run_until_shown, temp_dir, wait_for};

/// The study as alpha last published it to the console's fleet.
fn alpha_study(c: &Console) -> Option<StudyView> {
    let fleet = c.remote.as_ref()?.fleet()?;
    fleet.station("alpha")?.state?.station.study
}

fn turn_until(h: &mut egui_kittest::Harness<'_, Console>, what: &str, ok: impl Fn(&Console) -> bool) {
    let until = Instant::now() + Duration::from_secs(10);
    while !ok(h.state()) {
        assert!(Instant::now() < until, "timed out waiting for {what}: {:?}", alpha_study(h.state()));
        std::thread::sleep(Duration::from_millis(20));
        h.run_steps(1);
    }
}

#[test]
fn the_study_tab_runs_a_trial_on_a_remote_station() {
    let _t = crate::timing_exclusive();
    let dir = temp_dir("study");
    // Two single tactors in blocked order (T5 first), the fixture the console's own Study tests run.
    let protocol = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/study/two-tactors.toml");
    let results = dir.join("results");
    std::fs::create_dir_all(&results).unwrap();
    let broker = Broker::start(&dir);
    let alpha = StationProc::spawn(&broker, "alpha");

    let cfg = vestnav_app::config::Config {
        map_tiles: false,
        guidance_auto: false,
        auto_connect: false,
        ..vestnav_app::config::Config::default()
    };
    let mut console = Console::new(
        Box::new(vestnav_station::hardware::Hardware::default()),
        ConsoleOptions { cfg, ..ConsoleOptions::default() },
    );
    let panel = vestnav_app::remote_panel::RemotePanel::connect(
        &broker.client("operator"),
        "operator",
        console.station.stop_path().clone(),
    )
    .unwrap();
    wait_for("alpha in contact with a ready vest", Duration::from_secs(30), || {
        in_contact(panel.fleet().unwrap(), "alpha")
    });
    console.remote = Some(panel);
    // The station picked in the Stations window (its Drive button, `remote.rs`) is the one the tab offers.
    console.remote.as_mut().unwrap().drive.selected = Some("alpha".into());
    console.tab = Tab::Study;
    console.side_open = false;
    let mut h = egui_kittest::Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
    h.run_steps(3);
    click(&mut h, "alpha (driven)", 0);
    h.run_steps(2);
    assert!(h.query_by_label_contains("the path is its").is_some(), "the tab says whose disk the path is on");

    // The protocol and the results folder on alpha's disk (this machine's here), then Load.
    h.state_mut().study.protocol = protocol.display().to_string();
    h.state_mut().study.participant = "P07".into();
    h.state_mut().study.out_dir = results.display().to_string();
    h.run_steps(2);
    click(&mut h, "Load", 0);
    h.run_steps(1);
    turn_until(&mut h, "the study loaded on alpha", |c| {
        alpha_study(c).is_some_and(|v| v.phase == StudyPhase::Ready && v.trials == 2)
    });
    run_until_shown(&mut h, "Trial 1/2", "alpha's study shown in the tab");

    let t0 = Instant::now();
    click(&mut h, "Start", 0);
    h.run_steps(1);
    turn_until(&mut h, "alpha awaiting the response", |c| {
        alpha_study(c).is_some_and(|v| v.phase == StudyPhase::AwaitingResponse)
    });
    let unit = &alpha.unit;
    assert!(
        !unit.received_after(CommandKind::Fire, t0).is_empty()
            || !unit.received_after(CommandKind::Play, t0).is_empty(),
        "the stimulus reached alpha's vest"
    );
    // Blocked order: T5 first. The wearer reports it right.
    h.run_steps(2);
    click(&mut h, "T5", 0);
    h.run_steps(1);
    turn_until(&mut h, "alpha's record of the answer", |c| {
        alpha_study(c).is_some_and(|v| v.rows == 1 && v.last.is_some())
    });
    let v = alpha_study(h.state()).unwrap();
    let last = v.last.unwrap();
    assert_eq!((last.response.as_str(), last.answer.as_str(), last.correct), ("T5", "T5", true));

    // The row in the station's own results file, read back independently of the station's view.
    assert!(v.results_csv.starts_with(&results), "{}", v.results_csv.display());
    let rows = vestnav_core::study::record::read_csv_file(&v.results_csv).unwrap();
    assert_eq!(rows.len(), 1, "{rows:?}");
    let row = &rows[0];
    assert_eq!((row.participant.as_str(), row.stimulus.as_str(), row.answer.as_str()), ("P07", "T5", "T5"));
    assert_eq!((row.response.as_deref(), row.correct), (Some("T5"), Some(true)));

    h.state_mut().shutdown();
    drop(h);
    alpha.quit();
    drop(broker);
    let _ = std::fs::remove_dir_all(&dir);
}
