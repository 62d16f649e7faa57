//! `vestnav study run`: one session of a study protocol on a vest, from a terminal — the station's trial
//! runner (`vestnav_station::study`) with no window. The operator types what the wearer reported after each
//! stimulus (a label such as `T5` or a pattern's name), or `p` (pause), `r` (resume), `a` (abort), `stop`
//! (STOP ALL), `e` (end the navigation trial under way); a simulated wearer (`--wearer sim:P`) answers by
//! itself for demos and tests. Navigation trials walk their route under the station's guidance (`--gps`;
//! `--gps sim` walks each trial's route with the built-in simulator).
//!
//! Every finished trial is already in the results CSV (fsynced) when the next starts; the JSON is written at
//! the end. SIGINT (Ctrl-C), SIGTERM and SIGHUP stop the vest first through the stop path, then the session
//! ends with the trial under way recorded as stopped and the results kept.
#![allow(clippy::print_stdout)] // the prompts and the summary on stdout are this command's interface

use std::io::BufRead as _;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use vestnav_device::wtcu::LinkState;
use vestnav_station::command::Command;
use vestnav_station::hardware::Hardware;
use vestnav_station::sources::{GpsSourceConfig, VestSourceConfig, parse_gps_spec, parse_vest_spec};
use vestnav_station::stop::StopPath;
use vestnav_station::study::wearer::{SimulatedWearer, WearerSpec};
use vestnav_station::study::{StudyCommand, StudyPhase, Timing};
use vestnav_station::{Liveness, RouteStart, Station, StationOptions, StationSettings};

/// `vestnav study run` arguments.
#[derive(Debug, clap::Args)]
pub struct StudyRunArgs {
    /// The study protocol (TOML; `vestnav study check` validates it).
    #[arg(value_name = "PROTOCOL.toml")]
    pub protocol: PathBuf,
    /// Participant id (its place in the protocol's participant list orders a Latin square).
    #[arg(long, value_name = "ID")]
    pub participant: String,
    /// Session id.
    #[arg(long, value_name = "ID")]
    pub session: String,
    /// The vest: emulated, or serial:PATH (a WTCU on a serial or Bluetooth SPP port).
    #[arg(long, value_name = "SPEC", value_parser = parse_vest_spec)]
    pub vest: VestSourceConfig,
    /// A GPS (as `vestnav station --gps`), recorded in the session log beside the trials.
    #[arg(long, value_name = "SPEC", value_parser = parse_gps_spec)]
    pub gps: Option<GpsSourceConfig>,
    /// Folder of the results (a new CSV and JSON; an existing file is never overwritten).
    #[arg(long, value_name = "DIR", default_value = ".")]
    pub out: PathBuf,
    /// Where the session log goes (a new JSON Lines file, with every marker).
    #[arg(long, value_name = "DIR")]
    pub log_dir: Option<PathBuf>,
    /// A simulated wearer answers instead of the terminal: `sim:P[:SEED[:RT_MS]]` reports a 4-neighbour of the
    /// true tactor with probability P, else the true one; response times uniform in [0.5, 1.5] x `RT_MS`
    /// (default 800 ms).
    #[arg(long, value_name = "SPEC", value_parser = SimulatedWearer::parse_spec)]
    pub wearer: Option<WearerSpec>,
    /// Lab Streaming Layer streams (markers, position, heading, vest traffic) named vestnav-…; needs liblsl
    /// (`pip install pylsl` carries it; docs/study.md). The markers are stamped on liblsl's clock, as the
    /// results file's times are then.
    #[arg(long)]
    pub lsl: bool,
    /// Open Sound Control messages to HOST:PORT over UDP (docs/study.md).
    #[arg(long, value_name = "HOST:PORT", value_parser = vestnav_station::lab::parse_osc_target)]
    pub osc: Option<std::net::SocketAddr>,
    /// Inter-trial interval [ms] (the protocol's `iti_ms` wins when it has one).
    #[arg(long, value_name = "MS", default_value_t = 1000)]
    pub iti_ms: u32,
    /// How long feedback is shown at least in feedback blocks [ms] (the protocol's `feedback_ms` wins).
    #[arg(long, value_name = "MS", default_value_t = 1000)]
    pub feedback_ms: u32,
    /// Record a trial as no response after this many seconds from stimulus onset (default: wait; the
    /// protocol's `response_timeout_s` wins).
    #[arg(long, value_name = "SECONDS")]
    pub response_timeout: Option<f64>,
    /// With --gps sim and --vest emulated: navigation trials' simulated wearer walks where the trial's cues
    /// steer them (as `vestnav station --sim-follows-vest`) instead of along the route.
    #[arg(long)]
    pub sim_follows_vest: bool,
}

/// How long the vest has to become ready before the session is given up.
const VEST_READY_WITHIN: Duration = Duration::from_secs(10);

/// Runs one session (see the module doc).
pub fn run(a: &StudyRunArgs) -> anyhow::Result<()> {
    if a.iti_ms > 60_000 || a.feedback_ms > 60_000 {
        anyhow::bail!("--iti-ms and --feedback-ms: at most 60000");
    }
    if let Some(t) = a.response_timeout
        && !(t.is_finite() && (0.1..=3600.0).contains(&t))
    {
        anyhow::bail!("--response-timeout {t}: between 0.1 and 3600 seconds");
    }
    let stop = StopPath::default();
    let interrupted = Arc::new(AtomicBool::new(false));
    #[cfg(unix)]
    {
        let flag = interrupted.clone();
        stop.set_closer(Some(Box::new(move || flag.store(true, Ordering::SeqCst))));
        vestnav_station::stop::exit_on_signals(stop.clone(), || {}).context("cannot watch for signals")?;
    }
    let mut station = open_station(a, stop, &interrupted)?;
    station
        .apply(Command::Study(StudyCommand::Load {
            protocol: a.protocol.clone(),
            participant: a.participant.clone(),
            session: a.session.clone(),
            out_dir: a.out.clone(),
        }))
        .map_err(|e| anyhow::anyhow!(e))?;
    if let Some(v) = station.study_view() {
        eprintln!(
            "vestnav study: {} · participant {} · session {} · {} trials · results {}",
            v.protocol,
            v.participant,
            v.session,
            v.trials,
            v.results_csv.display()
        );
        if a.wearer.is_none() {
            if v.choices.is_empty() {
                eprintln!("e end the trial · p pause · r resume · a abort · stop STOP ALL");
            } else {
                eprintln!("answers: {} · p pause · r resume · a abort · stop STOP ALL", v.choices.join(" "));
            }
        }
    }
    if let Some(p) = station.log_path() {
        eprintln!("vestnav study: session log {}", p.display());
    }
    station.apply(Command::Study(StudyCommand::Start)).map_err(|e| anyhow::anyhow!(e))?;
    let input = if a.wearer.is_none() { Some(stdin_lines()) } else { None };
    let mut wearer = a.wearer.map(SimulatedWearer::from_spec).transpose().map_err(|e| anyhow::anyhow!(e))?;
    let mut loop_state = Prompter::default();
    loop {
        station.pump(|_| {});
        if interrupted.load(Ordering::SeqCst) {
            break;
        }
        let Some(view) = station.study_view() else { break };
        if view.phase.is_over() {
            break;
        }
        loop_state.show(&view, &station);
        if let Some(w) = &mut wearer {
            loop_state.simulate(w, &view, &mut station);
        }
        if let Some(rx) = &input {
            match rx.try_recv() {
                Ok(line) => typed(&line, &mut station),
                Err(mpsc::TryRecvError::Disconnected) if !loop_state.said_eof => {
                    loop_state.said_eof = true;
                    eprintln!(
                        "vestnav study: standard input closed; `a` can no longer be typed (Ctrl-C ends)"
                    );
                }
                Err(_) => {}
            }
        }
        let nap = station.study_wake_in().unwrap_or(Duration::from_millis(20)).min(Duration::from_millis(20));
        std::thread::sleep(nap.max(Duration::from_millis(1)));
    }
    // The vest first (STOP ALL and close), then the session's end is recorded.
    station.shutdown();
    let view = station.study_view();
    if let Some(v) = &view {
        summary(&station, v);
    }
    if interrupted.load(Ordering::SeqCst) {
        eprintln!("vestnav study: interrupted; the vest was stopped and the results are kept");
        std::process::exit(130);
    }
    Ok(())
}

/// The station of a session: the vest (and GPS) connected, the lab outputs and the timing asked for; returns
/// once the vest is ready.
fn open_station(a: &StudyRunArgs, stop: StopPath, interrupted: &AtomicBool) -> anyhow::Result<Station> {
    let mut settings = StationSettings::default();
    // A perception study: the vest plays the protocol's stimuli only.
    settings.guidance.auto = false;
    settings.sim_follows_vest = a.sim_follows_vest;
    let mut station = Station::new(
        Box::new(Hardware::default()),
        StationOptions {
            settings,
            gps: a.gps.clone(),
            vest: Some(a.vest.clone()),
            log_dir: a.log_dir.clone(),
            waker: None,
            liveness: Some(Liveness { view: None, ..Liveness::default() }),
            stop,
            route: RouteStart::default(),
        },
    );
    let lab = vestnav_station::lab::LabConfig { lsl: a.lsl, osc: a.osc, ..Default::default() };
    if lab.any() {
        // Asked for on the command line: a lab output that cannot start ends the run before anything moves.
        station.set_lab(Some(&lab)).context("lab outputs")?;
        if let Some(s) = station.lab_status() {
            eprintln!("vestnav study: {}", s.summary());
        }
    }
    station.set_study_timing(Timing {
        iti_s: f64::from(a.iti_ms) / 1000.0,
        feedback_s: f64::from(a.feedback_ms) / 1000.0,
        response_timeout_s: a.response_timeout,
        ..Timing::default()
    });
    station.connect_vest();
    if a.gps.is_some() {
        station.connect_gps(Vec::new());
    }
    wait_for_vest(&mut station, interrupted)?;
    Ok(station)
}

/// Pumps the station until the vest is ready (or fails to be).
fn wait_for_vest(station: &mut Station, interrupted: &AtomicBool) -> anyhow::Result<()> {
    let start = Instant::now();
    loop {
        station.pump(|_| {});
        if station.vest.state == Some(LinkState::Ready) {
            return Ok(());
        }
        if interrupted.load(Ordering::SeqCst) || start.elapsed() > VEST_READY_WITHIN {
            anyhow::bail!(
                "vest not ready within {} s: {}{}",
                VEST_READY_WITHIN.as_secs(),
                station.vest.label(),
                station.vest.lost.as_ref().map(|l| format!(" ({l})")).unwrap_or_default()
            );
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// What the terminal was last told, so each change is said once.
#[derive(Default)]
struct Prompter {
    /// (trial, phase) last shown.
    shown: Option<(usize, StudyPhase)>,
    /// The block whose timing was shown last.
    block_shown: Option<String>,
    /// Rows already reported.
    rows: usize,
    /// Error last shown.
    error: Option<String>,
    /// The trial the simulated wearer answers, and when.
    answer_at: Option<(usize, Instant, String)>,
    said_eof: bool,
}

impl Prompter {
    fn show(&mut self, v: &vestnav_station::study::StudyView, station: &Station) {
        if v.rows > self.rows {
            self.rows = v.rows;
            if let Some(n) = v.navigation.as_ref().filter(|_| v.last.is_none()) {
                println!(
                    "  walked {:.0} m of a {:.0} m route in {:.0} s; cross-track RMS {}; {} cues; {} missed waypoints",
                    n.path_m,
                    n.route_m,
                    n.elapsed_s,
                    n.cross_track_rms_m.map_or_else(|| "-".to_owned(), |x| format!("{x:.1} m")),
                    n.cues,
                    n.missed_waypoints
                );
            }
            if let Some(l) = &v.last {
                let mark = if l.correct { "correct" } else { "wrong" };
                if v.phase == StudyPhase::Feedback {
                    println!("  feedback: {} was {} ({mark}; {:.0} ms)", l.response, l.answer, l.rt_ms);
                }
            }
        }
        if v.error != self.error {
            if let Some(e) = &v.error {
                eprintln!("vestnav study: {e}");
            }
            self.error.clone_from(&v.error);
        }
        let key = (v.trial, v.phase);
        if self.shown == Some(key) {
            return;
        }
        self.shown = Some(key);
        if matches!(v.phase, StudyPhase::Presenting | StudyPhase::Navigating)
            && self.block_shown.as_deref() != Some(v.block_name.as_str())
        {
            // A block begins: the timing its trials run under (block > protocol > these options).
            if let Some(t) = &v.timing {
                println!("block {}: {}", v.block_name, t.describe(v.task));
            }
            self.block_shown = Some(v.block_name.clone());
        }
        match v.phase {
            StudyPhase::Presenting => {
                let training = if v.training { " training" } else { "" };
                println!("trial {}/{} [{}{training}]: stimulus on", v.trial + 1, v.trials, v.block_name);
            }
            StudyPhase::AwaitingResponse => println!("  answer?"),
            StudyPhase::Navigating => {
                let training = if v.training { " training" } else { "" };
                let (route, setup) = v.navigation.as_ref().map_or((String::new(), String::new()), |n| {
                    (format!("{}/{}", n.route, n.condition), n.setup.clone())
                });
                println!(
                    "trial {}/{} [{}{training}]: walk {route} ({setup})",
                    v.trial + 1,
                    v.trials,
                    v.block_name
                );
            }
            StudyPhase::Paused => {
                let stop = station.stop_alarm(Instant::now()).map(|a| vestnav_station::stop_alarm_text(&a));
                println!(
                    "paused at trial {}/{} (r resumes){}",
                    v.trial + 1,
                    v.trials,
                    stop.unwrap_or_default()
                );
            }
            _ => {}
        }
    }

    /// The simulated wearer answers each trial once, its response time after the stimulus started.
    fn simulate(
        &mut self,
        w: &mut SimulatedWearer,
        v: &vestnav_station::study::StudyView,
        station: &mut Station,
    ) {
        let waiting = matches!(v.phase, StudyPhase::Presenting | StudyPhase::AwaitingResponse);
        if !waiting {
            self.answer_at = None;
            return;
        }
        let Some(t) = station.study().and_then(|s| s.current()).cloned() else { return };
        if self.answer_at.as_ref().is_none_or(|(n, _, _)| *n != v.trial) {
            let (answer, rt_s) = w.respond(&t.answer, &v.choices);
            self.answer_at = Some((v.trial, Instant::now() + Duration::from_secs_f64(rt_s), answer));
        }
        if let Some((_, at, answer)) = &self.answer_at
            && Instant::now() >= *at
        {
            let answer = answer.clone();
            if let Err(e) = station.apply(Command::Study(StudyCommand::Respond { answer })) {
                eprintln!("vestnav study: {e}");
            }
        }
    }
}

/// One typed line: a response, or a command.
fn typed(line: &str, station: &mut Station) {
    let cmd = match line.trim() {
        "" => return,
        "p" | "pause" => Command::Study(StudyCommand::Pause),
        "r" | "resume" => Command::Study(StudyCommand::Resume),
        "a" | "abort" => Command::Study(StudyCommand::Abort),
        "e" | "end" => Command::Study(StudyCommand::EndTrial),
        "stop" => Command::StopAll,
        answer => Command::Study(StudyCommand::Respond { answer: answer.to_owned() }),
    };
    if let Err(e) = station.apply(cmd) {
        eprintln!("vestnav study: {e}");
    }
}

/// Lines of standard input, read on their own thread.
fn stdin_lines() -> mpsc::Receiver<String> {
    let (tx, rx) = mpsc::channel();
    let _ = std::thread::Builder::new().name("study-stdin".into()).spawn(move || {
        for line in std::io::stdin().lock().lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

/// The session's end: how it ended, core's analysis of the rows recorded, the files.
fn summary(station: &Station, v: &vestnav_station::study::StudyView) {
    let rows = station.study().map(|s| s.rows().to_vec()).unwrap_or_default();
    println!("session {}: {} of {} trials recorded", v.phase.name(), rows.len(), v.trials);
    for line in vestnav_core::study::analyze(&rows).summary_lines() {
        println!("  {line}");
    }
    println!("results: {}", v.results_csv.display());
    if let Some(j) = &v.results_json {
        println!("results: {}", j.display());
    }
    if let Some(e) = &v.error {
        println!("note: {e}");
    }
}
