//! The console's Study tab driven with `egui_kittest` on the emulated vest (behind a transport that records
//! every command the unit receives): a protocol checked and loaded, a trial started, the wearer's answer
//! clicked on the back-view grid and the station's runner taking it; a broken protocol's line-numbered
//! error, the file untouched; STOP ALL over the Abort question.
#![allow(clippy::unwrap_used)]

mod common;

use common::click_at;
use common::console::*;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;
use std::path::{Path, PathBuf};
use vestnav_app::config::Config;
use vestnav_app::console::{Console, Tab};
use vestnav_device::wtcu::Request;
use vestnav_station::study::{StudyPhase, StudyView};

/// A localization protocol of two single tactors, blocked order (T5 first), one block with feedback: the
/// fixture the remote Study test loads too.
const TWO_TACTORS: &str = include_str!("../../../tests/data/study/two-tactors.toml");

fn study_console(fake: &Fake) -> Harness<'static, Console> {
    let mut h = harness_with(fake, Config { map_tiles: false, guidance_auto: false, ..Config::default() });
    // The side panel's own grid is out of the way: the labels T0..T15 are the Study grid's.
    h.state_mut().side_open = false;
    h.state_mut().tab = Tab::Study;
    h.run_steps(2);
    h
}

fn view(c: &Console) -> Option<StudyView> {
    c.station.study_view()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Types the protocol's path and checks it with the tab's Check button.
fn check(h: &mut Harness<'static, Console>, path: &Path) {
    h.state_mut().study.protocol = path.display().to_string();
    h.run_steps(1);
    h.get_by_label("Check").click();
    h.run_steps(2);
}

/// Sets the results folder under `dir` and loads the checked protocol with the tab's Load button.
fn load(h: &mut Harness<'static, Console>, dir: &Path) {
    h.state_mut().study.out_dir = dir.join("results").display().to_string();
    h.run_steps(1);
    h.get_by_label("Load").click();
    settle(h, |c| view(c).is_some());
    h.run_steps(2);
}

/// Starts the loaded study with the tab's Start button and turns until the first response is awaited.
fn start(h: &mut Harness<'static, Console>) {
    h.get_by_label("Start").click();
    settle(h, |c| view(c).is_some_and(|v| v.phase == StudyPhase::AwaitingResponse));
    h.run_steps(2);
}

/// The tactor index of the one FIRE or pattern frame the unit was sent last (the vest's own truth of
/// what was presented).
fn presented_tactor(fake: &Fake) -> Option<usize> {
    fake.sent().iter().rev().find_map(|r| match r {
        Request::Fire { mask, .. } => mask.indices().next(),
        Request::Play { frames, .. } => frames.iter().find_map(|f| f.mask.indices().next()),
        _ => None,
    })
}

#[test]
fn a_loaded_protocol_runs_a_trial_and_takes_the_answer_clicked_on_the_grid() {
    let fake = Fake::default();
    let mut h = study_console(&fake);
    let dir = test_dir("study-run");
    let protocol = write(&dir, "two.toml", TWO_TACTORS);
    check(&mut h, &protocol);
    assert!(h.query_by_label_contains("OK: two-tactors").is_some(), "the check passed");
    assert_eq!(h.state().study.participant, "P07", "the protocol's participant proposed");
    load(&mut h, &dir);
    let v = view(h.state()).unwrap_or_else(|| panic!("not loaded: {:?}", h.state().study.refused));
    assert_eq!((v.phase, v.trials), (StudyPhase::Ready, 2));
    assert!(h.query_by_label_contains("Trial 1/2").is_some());
    assert!(h.query_by_label_contains("READY").is_some());
    start(&mut h);
    assert_eq!(view(h.state()).unwrap().phase, StudyPhase::AwaitingResponse);
    // The protocol sets no timing: the station's defaults (docs/study.md: 1000 ms, 1000 ms, no timeout).
    assert!(
        h.query_by_label("Timing: ITI 1000 ms · feedback 1000 ms · waits for the response").is_some(),
        "the trial's timing is shown"
    );
    // Blocked order: the protocol's first stimulus, T5 (index 5), reached the unit.
    let presented = presented_tactor(&fake).expect("the unit was sent a stimulus");
    assert_eq!(presented, 5, "{:?}", fake.sent());
    // The wearer (wrongly) reports the tactor to the right of it: T6.
    h.get_by_label("T6").click();
    settle(&mut h, |c| view(c).is_some_and(|v| v.last.is_some()));
    let v = view(h.state()).unwrap();
    let last = v.last.clone().expect("the runner took the answer");
    assert_eq!((last.response.as_str(), last.answer.as_str(), last.correct), ("T6", "T5", false));
    assert!(last.rt_ms > 0.0);
    h.run_steps(2);
    assert!(
        h.query_by_label_contains("INCORRECT: reported T6, the answer was T5").is_some(),
        "feedback shown in a feedback block"
    );
    // The row is on disk at once.
    let rows = vestnav_core::study::record::read_csv_file(&v.results_csv).unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0].response.as_deref(), Some("T6"));
    assert_eq!(rows[0].correct, Some(false));
    assert!(v.results_csv.starts_with(dir.join("results")));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_broken_protocol_shows_its_line_and_is_not_touched() {
    let fake = Fake::default();
    let mut h = study_console(&fake);
    let dir = test_dir("study-broken");
    // One line names an order that does not exist.
    let broken = TWO_TACTORS.replace("order = \"blocked\"", "order = \"sideways\"");
    let line = 1 + broken.lines().position(|l| l == "order = \"sideways\"").unwrap();
    let protocol = write(&dir, "broken.toml", &broken);
    let before =
        (std::fs::read(&protocol).unwrap(), std::fs::metadata(&protocol).unwrap().modified().unwrap());
    check(&mut h, &protocol);
    let at_line = format!("{}:{line}:", protocol.display());
    assert!(
        h.query_by_label_contains(&at_line).is_some(),
        "the error names the file and line {line}: {:?}",
        h.state().study.checked.as_ref().map(|c| c.result.clone())
    );
    h.state_mut().study.participant = "P07".into();
    h.run_steps(2);
    assert!(disabled(&h, "Load"), "a broken protocol cannot be loaded");
    let after =
        (std::fs::read(&protocol).unwrap(), std::fs::metadata(&protocol).unwrap().modified().unwrap());
    assert_eq!(before, after, "the file was only read");
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "nothing written beside it");
    assert!(view(h.state()).is_none());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn stop_all_acts_over_the_abort_question_and_the_trial_shows_as_stopped() {
    let fake = Fake::default();
    let mut h = study_console(&fake);
    let dir = test_dir("study-stop");
    let protocol = write(&dir, "two.toml", TWO_TACTORS);
    check(&mut h, &protocol);
    load(&mut h, &dir);
    start(&mut h);
    h.get_by_label("Abort…").click();
    h.run_steps(2);
    assert!(h.query_by_label("Abort the session?").is_some(), "the question is open");
    fake.sent.lock().unwrap().clear();
    // A real pointer click on STOP ALL while the modal's backdrop covers the window.
    let stop = h.get_by_label("STOP ALL").rect().center();
    click_at(&mut h, stop);
    settle(&mut h, |c| view(c).is_some_and(|v| v.phase == StudyPhase::Paused));
    assert!(fake.sent().contains(&Request::StopAll), "the unit was sent STOP ALL: {:?}", fake.sent());
    let v = view(h.state()).unwrap();
    assert_eq!(v.phase, StudyPhase::Paused);
    let why = v.error.clone().unwrap_or_default();
    assert!(why.contains("STOP ALL during trial 1") && why.contains("stopped"), "{why}");
    h.get_by_label("Go on").click();
    h.run_steps(2);
    assert!(h.query_by_label("Abort the session?").is_none());
    assert!(h.query_by_label_contains("PAUSED").is_some());
    assert!(h.query_by_label_contains("STOP ALL during trial 1").is_some(), "the stopped trial is shown");
    // The row of the stopped trial is on disk, as stopped.
    let rows = vestnav_core::study::record::read_csv_file(&v.results_csv).unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0].outcome, vestnav_core::study::Outcome::Stopped);
    assert!(!disabled(&h, "Resume"), "Resume is the way on");
    assert!(disabled(&h, "T5"), "no answer is taken while stopped");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Eight answered test trials of four tactors, six of them correct (counted by hand: 75 %), response
/// times 400..=1100 ms in 100 ms steps (median 750 ms).
fn results_rows() -> Vec<vestnav_core::study::TrialRecord> {
    use vestnav_core::study::{Outcome, Task, TrialRecord};
    let answers = ["T0", "T1", "T2", "T3", "T0", "T1", "T2", "T3"];
    let responses = ["T0", "T1", "T2", "T3", "T1", "T1", "T2", "T2"];
    (0..8)
        .map(|k| {
            let mut r = TrialRecord::new("P01", "S1", "four", Task::Localization);
            r.block_name = "test".into();
            r.trial = k;
            r.stimulus = answers[k].into();
            r.answer = answers[k].into();
            r.response = Some(responses[k].into());
            r.correct = Some(answers[k] == responses[k]);
            r.stimulus_on_s = Some(k as f64 * 3.0);
            r.rt_ms = Some(400.0 + 100.0 * k as f64);
            r.response_s = Some(k as f64 * 3.0 + r.rt_ms.unwrap() / 1000.0);
            r.outcome = Outcome::Answered;
            r
        })
        .collect()
}

#[test]
fn the_analysis_view_shows_a_results_file_and_saves_the_same_figures_as_the_report() {
    let fake = Fake::default();
    let mut h = study_console(&fake);
    let dir = test_dir("study-analysis");
    let rows = results_rows();
    let csv = write(&dir, "four.csv", &vestnav_core::study::write_csv(&rows));
    h.get_by_label("Analysis").click();
    h.run_steps(2);
    h.state_mut().study.analysis.path = csv.display().to_string();
    h.run_steps(1);
    h.get_by_label("Analyse").click();
    settle(&mut h, |c| !c.study.analysis.is_running());
    h.run_steps(2);
    assert!(h.state().study.analysis.error.is_none(), "{:?}", h.state().study.analysis.error);
    assert!(
        h.query_by_label_contains("Percent correct: 75.0 % (6 of 8 answered test trials)").is_some(),
        "the numbers are shown"
    );
    assert!(h.query_by_label_contains("Information transfer:").is_some());
    assert!(h.query_by_label_contains("median 750 ms").is_some());
    // The report's own figures for the same rows, written independently of the console.
    let reference = dir.join("reference");
    std::fs::create_dir_all(&reference).unwrap();
    let analysis = vestnav_core::study::analyze(&vestnav_core::study::record::read_csv_file(&csv).unwrap());
    let mut expected: Vec<PathBuf> = vestnav_report::study::figures(&analysis, &reference).unwrap();
    expected.sort();
    let mut shown = h.state().study.analysis.figure_names();
    shown.sort();
    let names: Vec<String> =
        expected.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert!(!names.is_empty());
    assert_eq!(shown, names, "every figure of the report is shown");
    // Save figures… into a new folder: the same PNGs, byte for byte.
    let saved = dir.join("saved");
    h.state_mut().study.analysis.save_dir = saved.display().to_string();
    h.run_steps(1);
    h.get_by_label("Save figures…").click();
    settle(&mut h, |c| !c.study.analysis.is_saving() && c.study.analysis.save_status.is_some());
    assert!(
        matches!(h.state().study.analysis.save_status, Some(Ok(_))),
        "{:?}",
        h.state().study.analysis.save_status
    );
    for (p, name) in expected.iter().zip(&names) {
        assert_eq!(std::fs::read(p).unwrap(), std::fs::read(saved.join(name)).unwrap(), "{name}");
    }
    // A second save asks before it replaces them, and Cancel leaves them.
    h.get_by_label("Save figures…").click();
    h.run_steps(2);
    assert!(h.query_by_label_contains("*.png?").is_some(), "asked before replacing");
    h.get_by_label("Cancel").click();
    h.run_steps(2);
    assert!(h.query_by_label_contains("*.png?").is_none());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Pattern identification: two named cues, one block with feedback, blocked order.
const TWO_PATTERNS: &str = r#"name = "two-cues"
task = "pattern-id"
participants = ["P02"]
order = "blocked"
seed = 3

[[pattern]]
name = "left"
cue = "turn left"
on_ms = 100

[[pattern]]
name = "right"
cue = "turn right"
on_ms = 100

[[block]]
name = "practice"
training = true
feedback = true
repetitions = 1
"#;

#[test]
fn a_pattern_study_takes_the_answer_clicked_in_the_pattern_list() {
    let fake = Fake::default();
    let mut h = study_console(&fake);
    let dir = test_dir("study-patterns");
    let protocol = write(&dir, "cues.toml", TWO_PATTERNS);
    check(&mut h, &protocol);
    load(&mut h, &dir);
    start(&mut h);
    assert!(fake.sent().iter().any(|r| matches!(r, Request::Play { .. })), "a pattern reached the unit");
    // Blocked order: the first pattern is "left"; the wearer says so.
    h.get_by_label("left").click();
    settle(&mut h, |c| view(c).is_some_and(|v| v.last.is_some()));
    let last = view(h.state()).unwrap().last.unwrap();
    assert_eq!((last.response.as_str(), last.answer.as_str(), last.correct), ("left", "left", true));
    h.run_steps(2);
    assert!(h.query_by_label_contains("CORRECT: left").is_some());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `vestnav --study P --study-wearer sim:0` (the documentation's Study screenshot): the tab opens with the
/// protocol checked, the study is loaded and started, and the simulated wearer (confusing nothing) answers
/// each trial, also while the operator looks at the map; the results file the station wrote has its rows,
/// every one correct. Without a wearer the protocol is only checked and proposed: nothing is loaded.
#[test]
fn a_study_named_at_start_opens_the_tab_and_a_simulated_wearer_answers() {
    use vestnav_app::console::{ConsoleOptions, DeviceOverrides};
    use vestnav_app::study_panel::StudyLaunch;
    let dir = test_dir("study-launch");
    let protocol = write(&dir, "two.toml", TWO_TACTORS);
    let open = |wearer| {
        let fake = Fake::default();
        let cfg = Config { map_tiles: false, guidance_auto: false, ..Config::default() };
        let out_dir = Some(dir.join("results"));
        let study = Some(StudyLaunch { protocol: protocol.clone(), wearer, out_dir });
        let console = Console::new(
            Box::new(fake.clone()),
            ConsoleOptions {
                cfg,
                devices: DeviceOverrides { study, ..DeviceOverrides::default() },
                ..ConsoleOptions::default()
            },
        );
        let h = Harness::builder()
            .with_size(egui::vec2(1400.0, 900.0))
            .build_ui_state(|ui, c: &mut Console| c.ui(ui), console);
        (fake, h)
    };
    let (_fake, mut h) = open(None);
    h.run_steps(2);
    assert_eq!(h.state().tab, Tab::Study);
    assert!(h.query_by_label_contains("OK: two-tactors").is_some(), "the protocol checked");
    assert_eq!(h.state().study.participant, "P07");
    assert!(view(h.state()).is_none(), "nothing loaded: Load is the operator's");
    drop(h);

    let spec = vestnav_station::study::wearer::SimulatedWearer::parse_spec("sim:0:1:20").unwrap();
    let (fake, mut h) = open(Some(spec));
    h.run_steps(2);
    assert_eq!(h.state().tab, Tab::Study);
    // The operator turns to the map: the wearer goes on answering.
    h.state_mut().tab = Tab::Map;
    let until = std::time::Instant::now() + std::time::Duration::from_secs(20);
    while !view(h.state()).is_some_and(|v| v.phase == StudyPhase::Finished) {
        assert!(std::time::Instant::now() < until, "{:?} {:?}", view(h.state()), h.state().study.refused);
        h.step();
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    let v = view(h.state()).unwrap();
    assert!(v.results_csv.starts_with(dir.join("results")), "{}", v.results_csv.display());
    let rows = vestnav_core::study::record::read_csv_file(&v.results_csv).unwrap();
    let answers: Vec<_> =
        rows.iter().map(|r| (r.answer.as_str(), r.response.as_deref(), r.correct)).collect();
    assert_eq!(answers, [("T5", Some("T5"), Some(true)), ("T10", Some("T10"), Some(true))]);
    assert!(presented_tactor(&fake).is_some(), "the stimuli reached the unit");
    drop(h);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Issue 25, End trial: the documentation's navigation protocol (`docs/study/navigation.toml`: the demo
/// route under four conditions, a 900 s limit) on the built-in GPS simulator and the emulated vest; the
/// operator ends the first walk with the tab's End trial a few fixes in. Truth: the protocol's meaning of
/// an ended trial (`ended`: a navigation trial ended before its last waypoint, by the operator or its time
/// limit), read from the results file's own header and row: `ended`, well short of the limit, no
/// completion time, waypoints left unreached.
#[test]
fn end_trial_ends_the_walk_and_its_row_says_ended() {
    let dir = test_dir("study-end-trial");
    let mut h = real_harness(None);
    settle(&mut h, |c| c.station.vest.is_live() && c.station.gps.fix.is_some());
    h.state_mut().side_open = false;
    h.state_mut().tab = Tab::Study;
    h.run_steps(2);
    let protocol = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/study/navigation.toml");
    check(&mut h, &protocol);
    assert!(h.query_by_label_contains("OK: strategy-comparison").is_some(), "the protocol checked");
    load(&mut h, &dir);
    assert!(h.query_by_label("End trial").is_none(), "no walk yet, no End trial");
    h.get_by_label("Start").click();
    settle(&mut h, |c| view(c).is_some_and(|v| v.phase == StudyPhase::Navigating));
    // The simulator walks the trial's route from its start: a few fixes measured, then the operator ends it.
    settle(&mut h, |c| view(c).and_then(|v| v.navigation).is_some_and(|n| n.fixes >= 2));
    h.run_steps(2);
    assert!(h.query_by_label_contains("Walking: route").is_some(), "the walk is shown");
    assert!(!disabled(&h, "End trial"), "End trial is offered while the wearer walks");
    h.get_by_label("End trial").click();
    settle(&mut h, |c| view(c).is_some_and(|v| v.rows == 1));
    let v = view(h.state()).unwrap();
    assert_eq!(v.phase, StudyPhase::Interval, "the pause before the next walk");
    h.run_steps(2);
    assert!(h.query_by_label_contains("Last walk: route").is_some(), "the walk ended is shown as the last");
    assert!(disabled(&h, "End trial"), "nothing left to end");

    // The results file, read back: one row, ended, with the walk measured so far.
    let rows = vestnav_core::study::record::read_csv_file(&v.results_csv).unwrap();
    assert_eq!(rows.len(), 1, "one row, the walk ended: {rows:?}");
    let row = &rows[0];
    assert_eq!(row.outcome, vestnav_core::study::Outcome::Ended);
    assert_eq!(row.outcome.name(), "ended");
    let text = std::fs::read_to_string(&v.results_csv).unwrap();
    assert!(text.lines().nth(1).is_some_and(|l| l.split(',').any(|f| f == "ended")), "{text}");
    assert_eq!(row.completion_s, None, "ended before the last waypoint: no completion time");
    assert!(row.missed_waypoints.is_some_and(|m| m >= 1), "waypoints left unreached: {row:?}");
    let (path_m, route_m) = (row.path_m.unwrap(), row.route_m.unwrap());
    assert!(path_m < route_m, "walked {path_m} m of a {route_m} m route");
    std::fs::remove_dir_all(&dir).unwrap();
}
