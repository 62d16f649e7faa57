//! The study runner on a WTCU served on a real PTY (the device crate's emulated unit): a whole localization
//! session through `vestnav study run` with a simulated wearer, checked against the wearer's confusion model
//! in closed form; and, on an in-process station, STOP ALL from the stop path during a trial, abort, a
//! stimulus the unit refuses at run time and a results file that exists already.

#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use vestnav_core::study::info::ConfusionMatrix;
use vestnav_core::study::{Outcome, TrialRecord};
use vestnav_device::wtcu::emulator::{PtyEmulator, UnitConfig};
use vestnav_device::wtcu::engine::EngineConfig;
use vestnav_device::wtcu::{CommandKind, Limits, LinkState};
use vestnav_station::command::Command as StationCommand;
use vestnav_station::hardware::Hardware;
use vestnav_station::sources::VestSourceConfig;
use vestnav_station::study::wearer::{SimulatedWearer, confusion_model};
use vestnav_station::study::{StudyCommand, StudyPhase, Timing};
use vestnav_station::{Station, StationOptions, StationSettings};

fn tempdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("vestnav-study-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// The JSON at `path` holds `rows` (times equal to the last bits a JSON float round trip may change).
fn same_rows(path: &Path, rows: &[TrialRecord]) {
    let json: Vec<TrialRecord> = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    assert_eq!(json.len(), rows.len());
    for (j, r) in json.iter().zip(rows) {
        let close = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(a), Some(b)) => (a - b).abs() <= 1e-12 * a.abs().max(1.0),
            (a, b) => a == b,
        };
        assert!(close(j.stimulus_on_s, r.stimulus_on_s) && close(j.response_s, r.response_s));
        assert!(close(j.rt_ms, r.rt_ms));
        let times =
            |t: &TrialRecord| TrialRecord { stimulus_on_s: None, response_s: None, rt_ms: None, ..t.clone() };
        assert_eq!(times(j), times(r));
    }
}

/// Every tactor 5 times, 20 ms each, no feedback: 80 trials.
const LOCALIZATION_16X5: &str = r#"
name = "loc16"
task = "localization"
participants = ["P01"]
order = "random"
seed = 11
[localization]
on_ms = 20
intensity = 200
[[block]]
name = "test"
feedback = false
repetitions = 5
"#;

/// The 16 tactor labels.
fn tactors() -> Vec<String> {
    (0..16).map(vestnav_core::vest::tactor_label).collect()
}

/// Information transfer [bits] of `pairs` (stimulus, response), maximum-likelihood, by core's estimator.
fn it_of(pairs: &[(String, String)]) -> f64 {
    ConfusionMatrix::from_pairs(&tactors(), pairs.iter().map(|(s, r)| (s.as_str(), r.as_str()))).it_bits()
}

#[test]
fn a_localization_session_gives_the_confusion_models_percent_correct_and_information_transfer() {
    const P: f64 = 0.2;
    let dir = tempdir("loc16");
    let protocol = write(&dir, "loc16.toml", LOCALIZATION_16X5);
    let unit = PtyEmulator::spawn(UnitConfig::default()).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_vestnav"))
        .args(["study", "run"])
        .arg(&protocol)
        .args(["--participant", "P01", "--session", "S1", "--vest"])
        .arg(format!("serial:{}", unit.path()))
        .arg("--out")
        .arg(&dir)
        .args(["--wearer", "sim:0.2:2026:5", "--iti-ms", "40", "--feedback-ms", "10"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let csv = dir.join("loc16_P01_S1.csv");
    assert!(stdout.contains(&format!("results: {}", csv.display())), "{stdout}");
    let rows = vestnav_core::study::record::read_csv_file(&csv).unwrap();
    assert_eq!(rows.len(), 80);
    assert!(rows.iter().all(|r| r.outcome == Outcome::Answered && r.rt_ms.is_some_and(|rt| rt > 0.0)));
    // Every tactor 5 times, and the JSON beside the CSV holds the same rows.
    for t in tactors() {
        assert_eq!(rows.iter().filter(|r| r.stimulus == t).count(), 5, "{t}");
    }
    same_rows(&dir.join("loc16_P01_S1.json"), &rows);
    // The unit played every stimulus: 80 cues accepted.
    assert_eq!(presentations(&unit), 80);

    // The closed form: the model's confusion probabilities, as counts in exact proportion (every
    // probability of p = 0.2 spread over 2, 3 or 4 neighbours is a multiple of 1/60000), give core's
    // estimator the model's mutual information with equally likely stimuli.
    let model = confusion_model(P, &tactors());
    let counts: Vec<Vec<u64>> =
        model.iter().map(|row| row.iter().map(|p| (p * 60_000.0).round() as u64).collect()).collect();
    assert!(counts.iter().all(|r| r.iter().sum::<u64>() == 60_000));
    let it_model = ConfusionMatrix::from_counts(counts).it_bits();
    // Sampling error of an 80-trial session, from 400 sessions of the same model (same design, other
    // seeds): the MLE of IT is biased upward at this size (core's info doc), so the band is asymmetric.
    let mut devs: Vec<f64> = (0..400u64)
        .map(|seed| {
            let mut w = SimulatedWearer::new(P, 10_000 + seed, 1.0).unwrap();
            let pairs: Vec<(String, String)> = (0..80)
                .map(|i| {
                    let s = vestnav_core::vest::tactor_label(i % 16);
                    let r = w.respond(&s, &tactors()).0;
                    (s, r)
                })
                .collect();
            it_of(&pairs) - it_model
        })
        .collect();
    devs.sort_by(f64::total_cmp);
    let (lo, hi) = (devs[1] - 0.05, devs[398] + 0.05);
    // The session's own estimate, as `vestnav study analyze` and the console report it.
    let analysis = vestnav_core::study::analyze(&rows);
    let it = analysis.it_bits.unwrap();
    assert!(
        (it_model + lo..=it_model + hi).contains(&it),
        "IT {it:.3} bits; model {it_model:.3} bits, 80-trial band [{:.3}, {:.3}]",
        it_model + lo,
        it_model + hi
    );
    eprintln!(
        "IT {it:.3} bits (model {it_model:.3}, band [{:.3}, {:.3}]); percent correct {:.1}",
        it_model + lo,
        it_model + hi,
        analysis.percent_correct.unwrap()
    );
    // Percent correct: Binomial(80, 1 - p), 4 standard deviations.
    let correct = analysis.percent_correct.unwrap() / 100.0;
    assert_eq!(analysis.answered, 80);
    let sd = (P * (1.0 - P) / 80.0).sqrt();
    assert!((correct - (1.0 - P)).abs() < 4.0 * sd, "{correct}");
    // Sanity of the closed form itself: 4 bits minus what the confusions cost, and less than perfect.
    assert!((2.5..3.5).contains(&it_model), "{it_model}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// How many cues (PLAY and FIRE) the unit accepted: its own count, which neither wraps like a sequence
/// number nor forgets like its bounded history of tactor changes.
fn presentations(unit: &PtyEmulator) -> u64 {
    let accepted = unit.view().accepted;
    [CommandKind::Play, CommandKind::Fire].iter().map(|k| accepted.get(k).copied().unwrap_or(0)).sum()
}

/// A station on the PTY unit, the vest ready, no automatic cues.
fn station_on(unit: &PtyEmulator) -> Station {
    let mut settings = StationSettings::default();
    settings.guidance.auto = false;
    let mut s = Station::new(
        Box::new(Hardware::default()),
        StationOptions {
            settings,
            vest: Some(VestSourceConfig::Serial { port: unit.path().to_owned() }),
            liveness: None,
            ..StationOptions::default()
        },
    );
    s.set_study_timing(Timing {
        iti_s: 0.02,
        feedback_s: 0.02,
        response_timeout_s: None,
        ..Timing::default()
    });
    s.connect_vest();
    pump_until(&mut s, Duration::from_secs(5), |s| s.vest.state == Some(LinkState::Ready));
    s
}

/// Pumps (as a view's turns) until `done` or `within` passed; returns whether `done` held.
fn pump_until(s: &mut Station, within: Duration, mut done: impl FnMut(&Station) -> bool) -> bool {
    let end = Instant::now() + within;
    while Instant::now() < end {
        s.pump(|_| {});
        if done(s) {
            return true;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    false
}

fn phase(s: &Station) -> Option<StudyPhase> {
    s.study_view().map(|v| v.phase)
}

fn study(s: &mut Station, c: StudyCommand) -> Result<(), String> {
    s.apply(StationCommand::Study(c))
}

fn load(s: &mut Station, protocol: &Path, out: &Path) {
    study(
        s,
        StudyCommand::Load {
            protocol: protocol.to_owned(),
            participant: "P01".into(),
            session: "S1".into(),
            out_dir: out.to_owned(),
        },
    )
    .unwrap();
}

#[test]
fn stop_all_from_the_stop_path_is_recorded_pauses_and_abort_keeps_every_row() {
    let dir = tempdir("stop");
    // One long stimulus, so STOP ALL lands while it plays.
    let protocol = write(
        &dir,
        "long.toml",
        "name = \"long\"\ntask = \"localization\"\norder = \"blocked\"\n[localization]\nstimuli = [\"T5\", \"T6\"]\n\
         on_ms = 1500\n[[block]]\nname = \"test\"\nrepetitions = 2\n",
    );
    // A results file of the same name exists: it must survive untouched.
    let existing = write(&dir, "long_P01_S1.csv", "precious\n");
    let unit = PtyEmulator::spawn(UnitConfig::default()).unwrap();
    let mut s = station_on(&unit);
    load(&mut s, &protocol, &dir);
    let csv = s.study_view().unwrap().results_csv;
    assert_eq!(csv, dir.join("long_P01_S1-2.csv"));
    assert_eq!(std::fs::read_to_string(&existing).unwrap(), "precious\n");

    study(&mut s, StudyCommand::Start).unwrap();
    assert!(pump_until(&mut s, Duration::from_secs(2), |_| !unit.view().tactors_on.is_empty()));
    assert_eq!(phase(&s), Some(StudyPhase::Presenting));
    // STOP ALL as the network bridge and the signal handler give it: straight to the stop path, not
    // through the station's command.
    s.stop_path().stop_all();
    assert!(pump_until(&mut s, Duration::from_secs(2), |s| phase(s) == Some(StudyPhase::Paused)));
    assert!(
        pump_until(&mut s, Duration::from_secs(1), |_| unit.view().tactors_on.is_empty()),
        "vest stopped"
    );
    let view = s.study_view().unwrap();
    assert!(view.error.as_deref().is_some_and(|e| e.contains("STOP ALL")), "{view:?}");
    // Never presented again without Resume.
    let played = presentations(&unit);
    pump_until(&mut s, Duration::from_millis(400), |_| false);
    assert_eq!(phase(&s), Some(StudyPhase::Paused));
    assert!(unit.view().tactors_on.is_empty());
    assert_eq!(presentations(&unit), played);
    let rows = vestnav_core::study::record::read_csv_file(&csv).unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!((rows[0].outcome, rows[0].stimulus.as_str()), (Outcome::Stopped, "T5"));
    assert!(rows[0].stimulus_on_s.is_some() && rows[0].response.is_none());

    // Resume presents the stopped trial again; the wearer answers; then the operator aborts mid-trial.
    study(&mut s, StudyCommand::Resume).unwrap();
    assert!(pump_until(&mut s, Duration::from_secs(2), |s| phase(s) == Some(StudyPhase::Presenting)));
    assert_eq!(s.study().unwrap().current().unwrap().answer, "T5");
    assert!(study(&mut s, StudyCommand::Respond { answer: "nowhere".into() }).is_err());
    study(&mut s, StudyCommand::Respond { answer: "t6".into() }).unwrap();
    // The next trial waits for this stimulus's end (1.5 s) and the interval.
    assert_eq!(phase(&s), Some(StudyPhase::Interval));
    assert!(pump_until(&mut s, Duration::from_secs(4), |s| phase(s) == Some(StudyPhase::Presenting)));
    study(&mut s, StudyCommand::Abort).unwrap();
    assert_eq!(phase(&s), Some(StudyPhase::Aborted));
    assert!(pump_until(&mut s, Duration::from_secs(1), |_| unit.view().tactors_on.is_empty()), "abort stops");
    let rows = vestnav_core::study::record::read_csv_file(&csv).unwrap();
    let outcomes: Vec<_> = rows.iter().map(|r| (r.trial, r.outcome, r.correct)).collect();
    assert_eq!(
        outcomes,
        vec![(0, Outcome::Stopped, None), (0, Outcome::Answered, Some(false)), (1, Outcome::Aborted, None)]
    );
    assert_eq!(rows[1].response.as_deref(), Some("T6"));
    same_rows(&csv.with_extension("json"), &rows);
    assert_eq!(std::fs::read_to_string(&existing).unwrap(), "precious\n");
    drop(s);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_stimulus_the_unit_refuses_at_run_time_is_recorded_as_refused() {
    let dir = tempdir("refused");
    // The same tactor three times, 200 ms each; the unit allows 300 ms of it per 10 s (duty cycle), which
    // only the second presentation exceeds: no check at load can see it.
    let protocol = write(
        &dir,
        "duty.toml",
        "name = \"duty\"\ntask = \"localization\"\norder = \"blocked\"\n[localization]\nstimuli = [\"T0\"]\n\
         on_ms = 200\n[[block]]\nname = \"test\"\nrepetitions = 3\n",
    );
    let limits = Limits { max_duty_on_ms: 300, ..Limits::default() };
    let unit = PtyEmulator::spawn(EngineConfig { limits, ..EngineConfig::default() }).unwrap();
    let mut s = station_on(&unit);
    load(&mut s, &protocol, &dir);
    study(&mut s, StudyCommand::Start).unwrap();
    assert!(pump_until(&mut s, Duration::from_secs(2), |s| phase(s) == Some(StudyPhase::Presenting)));
    study(&mut s, StudyCommand::Respond { answer: "T0".into() }).unwrap();
    let paused = pump_until(&mut s, Duration::from_secs(3), |s| phase(s) == Some(StudyPhase::Paused));
    assert!(paused, "{:?} {:?} {:?}", s.study_view(), s.vest.last_reply, unit.view().log);
    let view = s.study_view().unwrap();
    assert!(view.error.as_deref().is_some_and(|e| e.contains("refused")), "{view:?}");
    let rows = vestnav_core::study::record::read_csv_file(&view.results_csv).unwrap();
    assert_eq!(rows.iter().map(|r| r.outcome).collect::<Vec<_>>(), vec![Outcome::Answered, Outcome::Refused]);
    assert!(rows[1].notes.contains("refused"), "{}", rows[1].notes);
    // Resume goes on with the next trial (refused again while the duty window lasts), never replaying the
    // refused one by itself.
    assert_eq!(view.trial, 2);
    study(&mut s, StudyCommand::Unload).unwrap();
    assert!(s.study_view().is_none());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ctrl_c_stops_the_vest_and_keeps_the_results() {
    let dir = tempdir("sigint");
    let protocol = write(&dir, "loc16.toml", LOCALIZATION_16X5);
    let unit = PtyEmulator::spawn(UnitConfig::default()).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_vestnav"))
        .args(["study", "run"])
        .arg(&protocol)
        .args(["--participant", "P01", "--session", "S1", "--vest"])
        .arg(format!("serial:{}", unit.path()))
        .arg("--out")
        .arg(&dir)
        // Slow answers: the signal lands while a trial waits for one.
        .args(["--wearer", "sim:0.2:3:800", "--iti-ms", "100"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let csv = dir.join("loc16_P01_S1.csv");
    let end = Instant::now() + Duration::from_secs(20);
    while vestnav_core::study::record::read_csv_file(&csv).map_or(0, |r| r.len()) < 2 {
        assert!(Instant::now() < end, "two trials within 20 s");
        std::thread::sleep(Duration::from_millis(5));
    }
    // The third stimulus played and its answer (at least 400 ms after it) not given yet: a trial is under way.
    while presentations(&unit) < 3 {
        assert!(Instant::now() < end, "a third stimulus within 20 s");
        std::thread::sleep(Duration::from_millis(2));
    }
    vestnav_device::testkit::send_signal(child.id(), 2).unwrap();
    let status = child.wait().unwrap();
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert_eq!(status.code(), Some(130), "{err}");
    assert!(err.contains("STOP ALL acknowledged by the unit"), "{err}");
    assert!(unit.view().tactors_on.is_empty());
    let rows = vestnav_core::study::record::read_csv_file(&csv).unwrap();
    assert!(rows.len() >= 3, "{rows:?}");
    let last = rows.last().unwrap();
    assert_eq!(last.outcome, Outcome::Stopped, "{last:?}");
    assert!(rows[..rows.len() - 1].iter().all(|r| r.outcome == Outcome::Answered));
    same_rows(&csv.with_extension("json"), &rows);
    let _ = std::fs::remove_dir_all(&dir);
}
