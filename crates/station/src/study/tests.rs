//! The runner's state machine on a scripted clock and vest: the markers of one trial in the documented
//! vocabulary, pause and STOP ALL in each phase, a response timeout, a refusal, feedback's replay, and the
//! rows written at once.

use std::path::PathBuf;

use vestnav_core::study::Outcome;
use vestnav_device::wtcu::{CommandKind, CommandOrigin, Limits, VestCommand, VestEvent};

use super::*;

/// The station as a script: a clock the test moves, the markers and commands recorded.
#[derive(Default)]
struct Script {
    now: f64,
    markers: Vec<(String, f64)>,
    sent: Vec<VestCommand>,
    refuse: Option<String>,
    stops: usize,
    /// The route a navigation trial gets, and the trials started and ended.
    route: Option<NavRoute>,
    nav_starts: usize,
    nav_ends: usize,
}

impl StudyIo for Script {
    fn now_s(&self) -> f64 {
        self.now
    }
    fn marker(&mut self, text: &str, at_s: f64) {
        self.markers.push((text.to_owned(), at_s));
    }
    fn send(&mut self, command: VestCommand) -> Result<(), String> {
        if let Some(r) = &self.refuse {
            return Err(r.clone());
        }
        self.sent.push(command);
        Ok(())
    }
    fn stop_vest(&mut self) {
        self.stops += 1;
    }
    fn hold_guidance(&mut self) {}
    fn start_navigation(&mut self, _: &Stimulus) -> Result<NavRoute, String> {
        self.nav_starts += 1;
        let route = self.route.clone().ok_or_else(|| "no route in this script".to_owned())?;
        Ok(NavRoute { start_s: self.now, ..route })
    }
    fn end_navigation(&mut self) {
        self.nav_ends += 1;
    }
}

impl Script {
    fn names(&self) -> Vec<&str> {
        self.markers.iter().map(|(m, _)| m.split(' ').next().unwrap_or("")).collect()
    }
    fn plays(&self) -> usize {
        self.sent.iter().filter(|c| matches!(c, VestCommand::Play(_))).count()
    }
    /// Moves the clock by `dt_s` and gives the runner its turn.
    fn after(&mut self, r: &mut StudyRunner, dt_s: f64) {
        self.now += dt_s;
        r.turn(self);
    }
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("vestnav-runner-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// T5 then T6, 300 ms each; `feedback` in the one block.
fn runner(name: &str, feedback: bool, timing: Timing) -> (StudyRunner, PathBuf) {
    let d = dir(name);
    let p = d.join("p.toml");
    std::fs::write(
        &p,
        format!(
            "name = \"two\"\ntask = \"localization\"\norder = \"blocked\"\n[localization]\n\
             stimuli = [\"T5\", \"T6\"]\non_ms = 300\n[[block]]\nname = \"b\"\nfeedback = {feedback}\n\
             repetitions = 1\n"
        ),
    )
    .unwrap();
    let r = StudyRunner::load(&p, "P1", "S1", &d, &Limits::default(), timing).unwrap();
    (r, d)
}

const TIMING: Timing =
    Timing { iti_s: 0.5, feedback_s: 0.4, response_timeout_s: None, time_limit_s: DEFAULT_TIME_LIMIT_S };

#[test]
fn one_trial_speaks_the_marker_vocabulary_and_writes_its_row_at_once() {
    let (mut r, d) = runner("markers", false, TIMING);
    let mut io = Script { now: 10.0, ..Script::default() };
    assert!(r.command(StudyCommand::Respond { answer: "T5".into() }, &mut io).is_err(), "not started");
    r.command(StudyCommand::Start, &mut io).unwrap();
    assert_eq!(r.phase(), StudyPhase::Presenting);
    assert_eq!(r.view().presented.as_deref(), Some("T5"));
    io.after(&mut r, 0.31);
    assert_eq!(r.phase(), StudyPhase::AwaitingResponse);
    io.now += 0.2;
    r.command(StudyCommand::Respond { answer: "t4".into() }, &mut io).unwrap();
    let texts: Vec<&str> = io.markers.iter().map(|(m, _)| m.as_str()).collect();
    assert_eq!(
        texts,
        [
            "session_start two P1 S1",
            "trial_start 1 b",
            "stimulus_on T5 0x0020",
            "stimulus_off T5",
            "response T4 0 510.0",
            "trial_end 1 answered",
        ]
    );
    // The row is in the file before the next step.
    let rows = vestnav_core::study::record::read_csv_file(&r.view().results_csv).unwrap();
    assert_eq!(rows.len(), 1);
    approx::assert_relative_eq!(rows[0].rt_ms.unwrap(), 510.0, epsilon = 1e-6);
    approx::assert_relative_eq!(rows[0].stimulus_on_s.unwrap(), 10.0);
    assert_eq!((rows[0].correct, rows[0].response.as_deref()), (Some(false), Some("T4")));
    // The interval, then trial 2; its response ends the session.
    assert_eq!(r.phase(), StudyPhase::Interval);
    io.after(&mut r, 0.49);
    assert_eq!(r.phase(), StudyPhase::Interval);
    io.after(&mut r, 0.02);
    assert_eq!(r.phase(), StudyPhase::Presenting);
    r.command(StudyCommand::Respond { answer: "T6".into() }, &mut io).unwrap();
    // Answered while it plays: the end waits for the stimulus.
    assert_eq!(r.phase(), StudyPhase::Interval);
    io.after(&mut r, 0.31);
    assert_eq!(r.phase(), StudyPhase::Finished);
    assert_eq!(&io.names()[io.names().len() - 3..], ["trial_end", "stimulus_off", "session_end"]);
    assert_eq!(io.markers.last().unwrap().0, "session_end completed");
    assert!(r.view().results_json.is_some_and(|p| p.exists()));
    // Intensity, then the pattern, per stimulus.
    assert!(matches!(io.sent[0], VestCommand::SetIntensity { level: 255, .. }));
    assert_eq!(io.plays(), 2);
    let _ = std::fs::remove_dir_all(d);
}

#[test]
fn pause_during_a_trial_records_it_and_resume_presents_it_again() {
    let (mut r, d) = runner("pause", false, TIMING);
    let mut io = Script::default();
    r.command(StudyCommand::Start, &mut io).unwrap();
    io.now += 0.1;
    r.command(StudyCommand::Pause, &mut io).unwrap();
    assert_eq!(r.phase(), StudyPhase::Paused);
    assert_eq!(r.rows()[0].outcome, Outcome::Aborted);
    // Nothing is presented while paused, however long.
    io.after(&mut r, 100.0);
    assert_eq!((r.phase(), io.plays()), (StudyPhase::Paused, 1));
    assert!(r.command(StudyCommand::Pause, &mut io).is_err());
    r.command(StudyCommand::Resume, &mut io).unwrap();
    io.after(&mut r, 0.6);
    assert_eq!((r.phase(), io.plays()), (StudyPhase::Presenting, 2));
    assert_eq!(r.current().unwrap().answer, "T5");
    r.command(StudyCommand::Respond { answer: "T5".into() }, &mut io).unwrap();
    assert_eq!(r.rows()[1].notes, "presented again after a pause");
    assert_eq!(r.rows()[1].trial, 0);
    let _ = std::fs::remove_dir_all(d);
}

#[test]
fn stop_all_in_each_phase_pauses_and_only_a_trial_under_way_is_recorded_stopped() {
    let (mut r, d) = runner("stop", false, TIMING);
    let mut io = Script::default();
    let halted = VestEvent::Halted { reason: "STOP ALL: automatic cues halted until resumed".into() };
    r.command(StudyCommand::Start, &mut io).unwrap();
    io.now += 0.1;
    r.vest_event(&halted, &mut io);
    assert_eq!(r.phase(), StudyPhase::Paused);
    assert_eq!(r.rows()[0].outcome, Outcome::Stopped);
    assert!(r.view().error.unwrap().contains("STOP ALL"));
    assert_eq!(&io.names()[io.names().len() - 3..], ["stop_all", "stimulus_off", "trial_end"]);
    // Another STOP while paused is marked, nothing more.
    r.vest_event(&halted, &mut io);
    assert_eq!((r.rows().len(), io.names().last().copied()), (1, Some("stop_all")));
    r.command(StudyCommand::Resume, &mut io).unwrap();
    io.after(&mut r, 0.6);
    r.command(StudyCommand::Respond { answer: "T5".into() }, &mut io).unwrap();
    // In the interval: paused, no row.
    r.vest_event(&halted, &mut io);
    assert_eq!((r.phase(), r.rows().len()), (StudyPhase::Paused, 2));
    io.after(&mut r, 5.0);
    assert_eq!(io.plays(), 2, "never presented again without Resume");
    r.command(StudyCommand::Abort, &mut io).unwrap();
    assert_eq!(r.phase(), StudyPhase::Aborted);
    assert_eq!(io.markers.last().unwrap().0, "session_end aborted");
    let _ = std::fs::remove_dir_all(d);
}

#[test]
fn a_refused_stimulus_pauses_and_resume_goes_on_with_the_next() {
    let (mut r, d) = runner("refuse", false, TIMING);
    let mut io = Script::default();
    r.command(StudyCommand::Start, &mut io).unwrap();
    // The unit's NAK (no origin) for the PLAY.
    let nak = VestEvent::Rejected { kind: CommandKind::Play, origin: None, reason: "duty cycle".into() };
    // Guidance's refusals are not the study's.
    let auto = VestEvent::Rejected {
        kind: CommandKind::Play,
        origin: Some(CommandOrigin::Guidance),
        reason: "halted".into(),
    };
    r.vest_event(&auto, &mut io);
    assert_eq!(r.phase(), StudyPhase::Presenting);
    r.vest_event(&nak, &mut io);
    assert_eq!(r.phase(), StudyPhase::Paused);
    assert_eq!(r.rows()[0].outcome, Outcome::Refused);
    assert!(r.view().error.unwrap().contains("duty cycle"));
    r.command(StudyCommand::Resume, &mut io).unwrap();
    io.after(&mut r, 0.6);
    assert_eq!(r.current().unwrap().answer, "T6");
    // Not sent at all (no vest): refused at once.
    let (mut r, d2) = runner("refuse-now", false, TIMING);
    let mut io = Script { refuse: Some("no vest connected".into()), ..Script::default() };
    r.command(StudyCommand::Start, &mut io).unwrap();
    assert_eq!((r.phase(), r.rows()[0].outcome), (StudyPhase::Paused, Outcome::Refused));
    assert!(!io.names().contains(&"stimulus_on"));
    let _ = std::fs::remove_dir_all(d);
    let _ = std::fs::remove_dir_all(d2);
}

#[test]
fn no_response_in_time_and_feedback_replays_the_correct_stimulus() {
    let timing = Timing { response_timeout_s: Some(2.0), ..TIMING };
    let (mut r, d) = runner("timeout", true, timing);
    let mut io = Script::default();
    r.command(StudyCommand::Start, &mut io).unwrap();
    io.after(&mut r, 0.31);
    io.after(&mut r, 1.0);
    assert_eq!(r.phase(), StudyPhase::AwaitingResponse);
    io.after(&mut r, 0.7);
    assert_eq!(r.rows()[0].outcome, Outcome::NoResponse);
    assert_eq!(r.phase(), StudyPhase::Interval);
    io.after(&mut r, 0.5);
    // Trial 2 (T6), answered wrongly while it plays: feedback, then the replay once it has ended.
    r.command(StudyCommand::Respond { answer: "T2".into() }, &mut io).unwrap();
    assert_eq!(r.phase(), StudyPhase::Feedback);
    assert!(io.names().contains(&"feedback"));
    assert_eq!(io.plays(), 2);
    io.after(&mut r, 0.31);
    assert_eq!(io.plays(), 3, "the replay");
    assert!(matches!(io.sent.last(), Some(VestCommand::Play(p)) if p.frames[0].mask.contains(6)));
    // Feedback lasts the replay's length and a margin (0.5 s), more than the feedback time (0.4 s).
    io.after(&mut r, 0.45);
    assert_eq!(r.phase(), StudyPhase::Feedback);
    io.after(&mut r, 0.1);
    assert_eq!(r.phase(), StudyPhase::Finished);
    let _ = std::fs::remove_dir_all(d);
}

/// One route (due north along the meridian 0° from the equator, 0.001° of latitude) under two conditions.
fn nav_runner(name: &str) -> (StudyRunner, PathBuf, Script) {
    nav_runner_with(name, "[[block]]\nname = \"b\"\nrepetitions = 1\n")
}

/// [`nav_runner`] with these `[[block]]` tables.
fn nav_runner_with(name: &str, blocks: &str) -> (StudyRunner, PathBuf, Script) {
    use vestnav_core::geo::LatLon;
    let d = dir(name);
    std::fs::write(d.join("r.gpx"), "a file; the script loads no route").unwrap();
    let p = d.join("nav.toml");
    let cond = |n: &str| {
        format!(
            "[[condition]]\nname = \"{n}\"\nstrategy = \"bearing\"\nheading = \"cog\"\ncue_set = \"walking\"\n\
             cue_interval_s = 3.0\n"
        )
    };
    std::fs::write(
        &p,
        format!(
            "name = \"nav\"\ntask = \"navigation\"\norder = \"blocked\"\niti_ms = 500\n[navigation]\n\
             routes = [\"r.gpx\"]\ntime_limit_s = 60.0\n{}{}{blocks}",
            cond("a"),
            cond("b")
        ),
    )
    .unwrap();
    let timing = Timing { iti_s: 9.0, ..TIMING };
    let r = StudyRunner::load(&p, "P1", "S1", &d, &Limits::default(), timing).unwrap();
    let (a, b) = (LatLon::new(0.0, 0.0), LatLon::new(0.001, 0.0));
    let route = NavRoute {
        start_s: 0.0,
        name: "r".into(),
        polyline: vec![a, b],
        waypoints: vec![(a, 5.0), (b, 5.0)],
    };
    (r, d, Script { route: Some(route), ..Script::default() })
}

/// WGS-84 at the equator: metres per degree of latitude (the meridian radius of curvature a(1 - e²)) and of
/// longitude (the equatorial radius a), closed forms.
fn equator_m_per_deg() -> (f64, f64) {
    let a = 6_378_137.0;
    let f = 1.0 / 298.257_223_563;
    let e2 = f * (2.0 - f);
    (a * (1.0 - e2) * std::f64::consts::PI / 180.0, a * std::f64::consts::PI / 180.0)
}

#[test]
fn a_navigation_trial_measures_the_walk_and_ends_at_arrival_by_the_operator_or_the_time_limit() {
    use vestnav_core::geo::LatLon;
    let (mut r, d, mut io) = nav_runner("nav");
    // The protocol's iti_ms wins over the station's 9 s.
    r.command(StudyCommand::Start, &mut io).unwrap();
    assert_eq!((r.phase(), io.nav_starts), (StudyPhase::Navigating, 1));
    assert!(r.command(StudyCommand::Respond { answer: "x".into() }, &mut io).is_err());
    // Walk 3 m east, then 4 m west of the route, then on it at its end.
    let (lat_m, lon_m) = equator_m_per_deg();
    let at = |north_m: f64, east_m: f64| LatLon::new(north_m / lat_m, east_m / lon_m);
    let walk = [at(0.0, 3.0), at(40.0, -4.0), at(110.0, 0.0)];
    io.now += 20.0;
    r.navigation_tick(&NavTick { positions: walk.to_vec(), cues: 3, finished: false }, &mut io);
    let v = r.view().navigation.unwrap();
    assert_eq!((v.route.as_str(), v.condition.as_str(), v.cues, v.fixes), ("r", "a", 3, 3));
    approx::assert_relative_eq!(v.cross_track_m.unwrap(), 0.0, epsilon = 1e-6);
    approx::assert_relative_eq!(v.elapsed_s, 20.0);
    io.now += 5.0;
    r.navigation_tick(&NavTick { positions: Vec::new(), cues: 1, finished: true }, &mut io);
    assert_eq!((r.phase(), io.nav_ends), (StudyPhase::Interval, 1));
    let row = &r.rows()[0];
    assert_eq!((row.outcome, row.stimulus.as_str()), (Outcome::Completed, "r/a"));
    approx::assert_relative_eq!(row.completion_s.unwrap(), 25.0);
    // The route up to the last waypoint's 5 m arrival circle.
    approx::assert_relative_eq!(row.route_m.unwrap(), 0.001 * lat_m - 5.0, max_relative = 1e-6);
    approx::assert_relative_eq!(row.cross_track_rms_m.unwrap(), (25.0f64 / 3.0).sqrt(), max_relative = 1e-4);
    let path = 7.0f64.hypot(40.0) + 4.0f64.hypot(70.0);
    approx::assert_relative_eq!(row.path_m.unwrap(), path, max_relative = 1e-4);
    assert_eq!((row.cues, row.stops, row.missed_waypoints), (Some(4), Some(0), Some(0)));
    // Trial 2 after the protocol's 0.5 s: the operator ends it; every waypoint but the first missed.
    io.after(&mut r, 0.51);
    assert_eq!((r.phase(), io.nav_starts), (StudyPhase::Navigating, 2));
    r.navigation_tick(&NavTick { positions: vec![at(0.0, 0.0)], cues: 0, finished: false }, &mut io);
    r.command(StudyCommand::EndTrial, &mut io).unwrap();
    let row = &r.rows()[1];
    assert_eq!((row.outcome, row.completion_s, row.missed_waypoints), (Outcome::Ended, None, Some(1)));
    assert!(row.notes.contains("operator"), "{}", row.notes);
    assert_eq!(r.phase(), StudyPhase::Finished);
    assert!(r.command(StudyCommand::EndTrial, &mut io).is_err());
    let names = io.names();
    assert_eq!(names.iter().filter(|m| **m == "navigation_start").count(), 2);
    assert_eq!(names.iter().filter(|m| **m == "arrived").count(), 1);
    let _ = std::fs::remove_dir_all(d);
}

#[test]
fn stop_all_ends_a_walk_as_stopped_and_the_time_limit_as_ended() {
    let (mut r, d, mut io) = nav_runner("navstop");
    let halted = VestEvent::Halted { reason: "STOP ALL".into() };
    r.command(StudyCommand::Start, &mut io).unwrap();
    io.now += 1.0;
    r.vest_event(&halted, &mut io);
    assert_eq!((r.phase(), io.nav_ends), (StudyPhase::Paused, 1));
    let row = &r.rows()[0];
    assert_eq!((row.outcome, row.stops), (Outcome::Stopped, Some(1)));
    // Resume walks the same route and condition again; the protocol's 60 s limit ends it.
    r.command(StudyCommand::Resume, &mut io).unwrap();
    io.after(&mut r, 0.51);
    assert_eq!((r.phase(), io.nav_starts), (StudyPhase::Navigating, 2));
    assert_eq!(r.current().unwrap().index, 0);
    io.after(&mut r, 59.9);
    assert_eq!(r.phase(), StudyPhase::Navigating);
    io.after(&mut r, 0.2);
    let row = &r.rows()[1];
    assert_eq!((row.trial, row.outcome), (0, Outcome::Ended));
    assert!(row.notes.contains("time limit"), "{}", row.notes);
    // Abort during a walk stops the vest and records the walk as aborted.
    io.after(&mut r, 0.51);
    assert_eq!(r.phase(), StudyPhase::Navigating);
    r.command(StudyCommand::Abort, &mut io).unwrap();
    assert_eq!((io.stops, r.rows()[2].outcome, io.nav_ends), (1, Outcome::Aborted, 3));
    let _ = std::fs::remove_dir_all(d);

    // A route the station cannot load: refused, paused with the reason.
    let (mut r, d, mut io) = nav_runner("navrefused");
    io.route = None;
    r.command(StudyCommand::Start, &mut io).unwrap();
    assert_eq!(r.phase(), StudyPhase::Paused);
    assert_eq!(r.rows()[0].outcome, Outcome::Refused);
    assert!(r.view().error.unwrap().contains("navigation not started"));
    let _ = std::fs::remove_dir_all(d);
}

/// Moves the clock in 10 ms steps (whole milliseconds, no drift) up to `until_s`, the runner's turn at each.
fn step_to(io: &mut Script, r: &mut StudyRunner, until_s: f64) {
    let mut ms = (io.now * 1000.0).round() as i64;
    while (ms as f64) / 1000.0 < until_s - 1e-9 {
        ms += 10;
        io.now = ms as f64 / 1000.0;
        r.turn(io);
    }
}

/// `dt_s` is `expected_s` on a clock turned every 10 ms: not before it, at most one step after.
fn assert_took(dt_s: f64, expected_s: f64, what: &str) {
    assert!(dt_s >= expected_s - 1e-9 && dt_s < expected_s + 0.0101, "{what}: {dt_s} s, not {expected_s} s");
}

/// When each marker whose text starts with `prefix` was stamped, in order.
fn times(io: &Script, prefix: &str) -> Vec<f64> {
    io.markers.iter().filter(|(m, _)| m.starts_with(prefix)).map(|(_, t)| *t).collect()
}

/// Issue 25's follow-up: each block's timing keys rule its own trials. The protocol states the intended
/// timing; the clock says what the runner did. Block "fast": no-response after 1 s, 200 ms between
/// trials. Block "slow": no timeout (the station sets none), feedback 1.5 s, the protocol's ITI (700 ms).
#[test]
fn each_block_runs_under_its_own_timing_keys() {
    let d = dir("blocktiming");
    let p = d.join("p.toml");
    std::fs::write(
        &p,
        "name = \"blocks\"\ntask = \"localization\"\norder = \"blocked\"\niti_ms = 700\n\
         [localization]\nstimuli = [\"T5\"]\non_ms = 300\n\
         [[block]]\nname = \"fast\"\nrepetitions = 2\nresponse_timeout_s = 1.0\niti_ms = 200\n\
         [[block]]\nname = \"slow\"\nrepetitions = 2\nfeedback = true\nfeedback_ms = 1500\n",
    )
    .unwrap();
    let mut r = StudyRunner::load(&p, "P1", "S1", &d, &Limits::default(), TIMING).unwrap();
    let mut io = Script::default();
    // What a view shows of the first block, before anything runs.
    let v = r.view().timing.unwrap();
    assert_eq!((v.response_timeout_s, v.iti_s, v.feedback_s), (Some(1.0), 0.2, 0.4));
    assert_eq!(v.describe(Task::Localization), "ITI 200 ms · feedback 400 ms · no-response after 1 s");
    r.command(StudyCommand::Start, &mut io).unwrap();
    // Block "fast": nobody answers. Each trial ends as no-response 1 s after its onset, the next starts
    // 200 ms later.
    step_to(&mut io, &mut r, 0.99);
    assert_eq!((r.phase(), r.rows().len()), (StudyPhase::AwaitingResponse, 0));
    step_to(&mut io, &mut r, 3.0);
    let (on, end) = (times(&io, "stimulus_on"), times(&io, "trial_end"));
    assert_eq!(r.rows()[..2].iter().map(|row| row.outcome).collect::<Vec<_>>(), [Outcome::NoResponse; 2]);
    for i in 0..2 {
        assert_took(end[i] - on[i], 1.0, &format!("trial {i}: no-response"));
    }
    assert_took(on[1] - end[0], 0.2, "ITI in block fast");
    // After the fast block's last trial its own 200 ms, then block "slow", which waits for the response.
    assert_took(on[2] - end[1], 0.2, "ITI after block fast's last trial");
    assert_eq!(r.current().unwrap().block_name, "slow");
    assert_eq!(r.view().timing.unwrap().response_timeout_s, None);
    step_to(&mut io, &mut r, on[2] + 60.0);
    assert_eq!((r.phase(), r.rows().len()), (StudyPhase::AwaitingResponse, 2), "block slow waits");
    r.command(StudyCommand::Respond { answer: "T5".into() }, &mut io).unwrap();
    let answered = io.now;
    // Correct: feedback for the block's 1.5 s (not the station's 0.4 s), then the protocol's 700 ms ITI.
    step_to(&mut io, &mut r, answered + 1.49);
    assert_eq!(r.phase(), StudyPhase::Feedback);
    step_to(&mut io, &mut r, answered + 1.51);
    assert_eq!(r.phase(), StudyPhase::Interval);
    step_to(&mut io, &mut r, answered + 3.0);
    assert_took(times(&io, "stimulus_on")[3] - answered, 2.2, "feedback 1.5 s + ITI 0.7 s");
    assert_eq!(r.phase(), StudyPhase::AwaitingResponse);
    // The rows say which timing each trial ran under.
    let rows = vestnav_core::study::record::read_csv_file(&r.view().results_csv).unwrap();
    assert_eq!(rows[0].response_timeout_s, Some(1.0));
    assert_eq!((rows[0].iti_ms, rows[0].feedback_ms), (Some(200), None));
    assert_eq!(
        (rows[2].response_timeout_s, rows[2].iti_ms, rows[2].feedback_ms),
        (None, Some(700), Some(1500))
    );
    let _ = std::fs::remove_dir_all(d);
}

/// The station's defaults serve what neither level sets; a protocol's key wins over the default, a block's
/// over both.
#[test]
fn block_keys_win_over_the_protocols_which_win_over_the_stations() {
    let d = dir("whowins");
    let p = d.join("p.toml");
    std::fs::write(
        &p,
        "name = \"w\"\ntask = \"localization\"\nresponse_timeout_s = 5.0\n[localization]\nstimuli = [\"T1\"]\n\
         [[block]]\nname = \"a\"\nrepetitions = 1\nresponse_timeout_s = 2.0\n[[block]]\nname = \"b\"\nrepetitions = 1\n",
    )
    .unwrap();
    let station = Timing { response_timeout_s: Some(9.0), ..TIMING };
    let r = StudyRunner::load(&p, "P1", "S1", &d, &Limits::default(), station).unwrap();
    let by_block: Vec<Timing> = r.plan().iter().map(|t| r.timing_of(t)).collect();
    assert_eq!(by_block.iter().map(|t| t.response_timeout_s).collect::<Vec<_>>(), [Some(2.0), Some(5.0)]);
    // Neither level sets the ITI or the feedback: the station's.
    assert!(by_block.iter().all(|t| (t.iti_s, t.feedback_s) == (TIMING.iti_s, TIMING.feedback_s)));
    let _ = std::fs::remove_dir_all(d);
}

#[test]
fn a_navigation_blocks_time_limit_ends_its_walks_and_the_next_block_takes_the_protocols() {
    let blocks = "[[block]]\nname = \"practice\"\nrepetitions = 1\ntime_limit_s = 20.0\n\
                  [[block]]\nname = \"test\"\nrepetitions = 1\n";
    let (mut r, d, mut io) = nav_runner_with("navblocks", blocks);
    r.command(StudyCommand::Start, &mut io).unwrap();
    approx::assert_relative_eq!(r.view().navigation.unwrap().time_limit_s, 20.0);
    step_to(&mut io, &mut r, 19.99);
    assert_eq!(r.phase(), StudyPhase::Navigating);
    // Both practice walks (two conditions) end at the block's 20 s; 0.5 s apart (the protocol's iti_ms).
    step_to(&mut io, &mut r, 41.5);
    let ends = times(&io, "trial_end");
    let starts = times(&io, "navigation_start");
    assert_eq!(ends.len(), 2);
    for i in 0..2 {
        assert_took(ends[i] - starts[i], 20.0, &format!("walk {i}"));
        assert_eq!(r.rows()[i].outcome, Outcome::Ended);
    }
    // The test block: the protocol's 60 s.
    assert_eq!(r.current().unwrap().block_name, "test");
    approx::assert_relative_eq!(r.view().navigation.unwrap().time_limit_s, 60.0);
    step_to(&mut io, &mut r, starts[2] + 59.9);
    assert_eq!((r.phase(), r.rows().len()), (StudyPhase::Navigating, 2));
    step_to(&mut io, &mut r, starts[2] + 60.1);
    assert_eq!(r.rows()[2].outcome, Outcome::Ended);
    assert_eq!((r.rows()[0].time_limit_s, r.rows()[2].time_limit_s), (Some(20.0), Some(60.0)));
    let _ = std::fs::remove_dir_all(d);
}
