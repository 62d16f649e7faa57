//! The study runner: one session of a study protocol (`vestnav_core::study`) run on the station's vest,
//! driven by [`StudyCommand`]s and shown as a [`StudyView`].
//!
//! The runner is a state machine the station owns and turns in [`crate::Station::pump`] on the station's
//! own thread: no thread of its own, no lock. It reaches the world through [`StudyIo`] only — the session
//! clock, the markers, the vest through the same manual path as an operator's cue (the unit's limits
//! apply; a refusal comes back as a vest event), and the stop path. It is never on the way of STOP ALL:
//! it *observes* every STOP ALL (the operator's key, a network command served straight to the stop path,
//! a signal, a stalled thread) through the vest worker's `Halted` event, after the vest was stopped.
//!
//! One trial: `trial_start` → the stimulus is handed to the vest (`stimulus_on`, the response time's
//! origin) → it plays for its length (`Presenting`) → `stimulus_off` → the operator enters what the
//! wearer reported (`AwaitingResponse`; a response during `Presenting` is taken too) → the row is
//! appended to the results CSV and fsynced → with feedback: the correct answer shown and, after a wrong
//! answer, the stimulus played again (`Feedback`) → the inter-trial interval (`Interval`) → the next.
//! Pause, STOP ALL and a refusal all land in `Paused`; only the operator's Resume presents again.
//! A navigation trial walks a route instead (module `navigation`): `Navigating` until the last waypoint,
//! the operator's End trial or the time limit.
//!
//! Every trial runs under its block's timing ([`Timing::for_block`]: the block's keys, else the protocol's,
//! else the station's): its response timeout, its feedback, the interval after it, its time limit.

mod navigation;
pub mod results;
mod station;
pub use navigation::{DEFAULT_TIME_LIMIT_S, NavRoute, NavTick, NavView};
pub use station::StudySlot;
pub mod wearer;

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use vestnav_core::study::{Outcome, PlannedTrial, Protocol, Stimulus, Task, TrialRecord};
use vestnav_core::vest::Pattern;
use vestnav_device::wtcu::{CommandKind, CommandOrigin, Limits, VestEvent};

use results::ResultsFile;

/// What an operator can ask of the study runner (through [`crate::command::Command::Study`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
// Inside `Command`'s own `type` tag: `{"type":"study","action":"respond","answer":"T2"}`.
#[serde(tag = "action", rename_all = "snake_case")]
pub enum StudyCommand {
    /// Loads a protocol for one participant and session; results go in `out_dir`.
    Load {
        /// The protocol file (TOML).
        protocol: PathBuf,
        /// Participant id (as in the protocol's participant list, if it has one).
        participant: String,
        /// Session id.
        session: String,
        /// Folder of the results (CSV and JSON).
        out_dir: PathBuf,
    },
    /// Starts the loaded session.
    Start,
    /// What the wearer reported for the current trial (one of [`StudyView::choices`]).
    Respond {
        /// The choice's label.
        answer: String,
    },
    /// Pauses (a trial under way is recorded as aborted and presented again after Resume).
    Pause,
    /// Goes on after a pause, a STOP ALL or a refused stimulus.
    Resume,
    /// Ends the navigation trial under way before its last waypoint (recorded as `ended`).
    EndTrial,
    /// Ends the session: every row so far kept, the trial under way recorded as aborted.
    Abort,
    /// Forgets the session (aborting it first if it runs).
    Unload,
}

impl StudyCommand {
    /// The command in a few words, for notices and the session log.
    pub fn describe(&self) -> String {
        match self {
            Self::Load { protocol, participant, session, .. } => {
                format!("study load {} for {participant} session {session}", protocol.display())
            }
            Self::Start => "study start".to_owned(),
            Self::Respond { answer } => format!("study response {answer}"),
            Self::Pause => "study pause".to_owned(),
            Self::Resume => "study resume".to_owned(),
            Self::EndTrial => "study end trial".to_owned(),
            Self::Abort => "study abort".to_owned(),
            Self::Unload => "study unload".to_owned(),
        }
    }
}

/// Where a session is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StudyPhase {
    /// Loaded, not started.
    Ready,
    /// The stimulus plays.
    Presenting,
    /// Waiting for the operator to enter the wearer's response.
    AwaitingResponse,
    /// The correct answer is shown (and replayed on the vest after a wrong answer).
    Feedback,
    /// A navigation trial: the wearer walks the route under guidance.
    Navigating,
    /// The pause between two trials.
    Interval,
    /// Paused by the operator, a STOP ALL or a refused stimulus ([`StudyView::error`] says which); nothing
    /// is presented until Resume.
    Paused,
    /// Every trial run.
    Finished,
    /// Ended by the operator.
    Aborted,
    /// Ended because the program stopped the vest to exit (a signal).
    Stopped,
}

impl StudyPhase {
    /// Whether the session has ended.
    pub fn is_over(self) -> bool {
        matches!(self, Self::Finished | Self::Aborted | Self::Stopped)
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ready => "ready",
            Self::Presenting => "presenting",
            Self::AwaitingResponse => "awaiting response",
            Self::Feedback => "feedback",
            Self::Navigating => "navigating",
            Self::Interval => "interval",
            Self::Paused => "paused",
            Self::Finished => "finished",
            Self::Aborted => "aborted",
            Self::Stopped => "stopped",
        }
    }
}

/// The latest answered trial.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LastAnswer {
    /// What the wearer reported.
    pub response: String,
    /// The correct answer.
    pub answer: String,
    /// Whether they are the same.
    pub correct: bool,
    /// Response time from stimulus onset [ms].
    pub rt_ms: f64,
}

/// What a view shows of the session.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyView {
    /// The protocol's name.
    pub protocol: String,
    /// Participant id.
    pub participant: String,
    /// Session id.
    pub session: String,
    /// The task kind.
    pub task: Task,
    /// Where the session is.
    pub phase: StudyPhase,
    /// The trial under way or next (0-based; equal to `trials` when all are done).
    pub trial: usize,
    /// Trials in the session.
    pub trials: usize,
    /// The block of that trial.
    pub block_name: String,
    /// Whether that block is training.
    pub training: bool,
    /// Whether that block gives feedback.
    pub feedback: bool,
    /// The answers the operator can enter.
    pub choices: Vec<String>,
    /// The stimulus playing now (label), while it plays.
    pub presented: Option<String>,
    /// The latest answered trial.
    pub last: Option<LastAnswer>,
    /// The results file rows are appended to.
    pub results_csv: PathBuf,
    /// The JSON of every row, once the session has ended.
    pub results_json: Option<PathBuf>,
    /// Why the session is paused or what went wrong (a refusal, a STOP ALL, a file that cannot be written).
    pub error: Option<String>,
    /// Rows written so far.
    pub rows: usize,
    /// The navigation trial under way, or the last one run.
    #[serde(default)]
    pub navigation: Option<NavView>,
    /// The timing of that trial's block ([`Timing::for_block`]: the block's keys, else the protocol's,
    /// else the station's).
    #[serde(default)]
    pub timing: Option<Timing>,
}

/// What the runner needs of the station: the session clock, the markers, the vest.
pub trait StudyIo {
    /// The session clock [s] (the LSL clock when LSL is on).
    fn now_s(&self) -> f64;
    /// One marker of the documented vocabulary, timestamped `at_s`.
    fn marker(&mut self, text: &str, at_s: f64);
    /// Sends a command to the vest through the operator's manual path; `Err` when it was not sent.
    fn send(&mut self, command: vestnav_device::wtcu::VestCommand) -> Result<(), String>;
    /// STOP ALL through the stop path (a stimulus under way when the operator aborts).
    fn stop_vest(&mut self);
    /// Turns automatic guidance cues off (a perception study must feel only its stimuli).
    fn hold_guidance(&mut self);
    /// Starts a navigation trial through the station's own commands: the stimulus's route loaded (the one
    /// route loader), its condition applied to guidance's settings, automatic cues on. `Err`: not started.
    fn start_navigation(&mut self, stimulus: &Stimulus) -> Result<NavRoute, String>;
    /// Ends a navigation trial's guidance: automatic cues off, the operator's own settings back.
    fn end_navigation(&mut self);
}

/// A trial's timing. The station holds the defaults (the station's settings, `vestnav study run`'s
/// options); [`Timing::for_block`] turns them into the timing a block's trials run under, each value set by
/// the block's key, else the protocol's, else the default (block > protocol > station).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    /// Inter-trial interval: the pause after a trial, before the next [s].
    pub iti_s: f64,
    /// How long feedback is shown at least [s].
    pub feedback_s: f64,
    /// A trial with no response after this long from stimulus onset is recorded as no response
    /// (`None`: wait for the operator).
    pub response_timeout_s: Option<f64>,
    /// A navigation trial not ended by arrival or the operator ends after this long [s].
    #[serde(default = "default_time_limit_s")]
    pub time_limit_s: f64,
}

fn default_time_limit_s() -> f64 {
    DEFAULT_TIME_LIMIT_S
}

impl Timing {
    /// This timing with `keys` in place of the values they set (the keys win).
    #[must_use]
    pub fn with_keys(self, keys: &vestnav_core::study::TimingKeys) -> Self {
        Self {
            iti_s: keys.iti_ms.map_or(self.iti_s, |ms| f64::from(ms) / 1000.0),
            feedback_s: keys.feedback_ms.map_or(self.feedback_s, |ms| f64::from(ms) / 1000.0),
            response_timeout_s: keys.response_timeout_s.or(self.response_timeout_s),
            time_limit_s: keys.time_limit_s.unwrap_or(self.time_limit_s),
        }
    }

    /// The timing the trials of `protocol`'s block `block` (0-based) run under, these defaults serving
    /// the keys neither the block nor the protocol sets. The one place a trial's timing is decided: the
    /// runner, the views and `vestnav study run` all take it from here.
    #[must_use]
    pub fn for_block(self, protocol: &Protocol, block: usize) -> Self {
        self.with_keys(&protocol.block_timing(block))
    }

    /// In words for a view: `ITI 1000 ms · feedback 1000 ms · no-response after 3 s` (`waits for the
    /// response` without a timeout; the time limit for a navigation block instead of the last two).
    pub fn describe(&self, task: Task) -> String {
        let iti = format!("ITI {:.0} ms", self.iti_s * 1000.0);
        if task == Task::Navigation {
            return format!("{iti} · time limit {} s", self.time_limit_s);
        }
        let wait = self
            .response_timeout_s
            .map_or_else(|| "waits for the response".to_owned(), |t| format!("no-response after {t} s"));
        format!("{iti} · feedback {:.0} ms · {wait}", self.feedback_s * 1000.0)
    }
}

impl Default for Timing {
    fn default() -> Self {
        Self { iti_s: 1.0, feedback_s: 1.0, response_timeout_s: None, time_limit_s: DEFAULT_TIME_LIMIT_S }
    }
}

/// The trial under way.
#[derive(Debug, Clone)]
struct Running {
    /// When its stimulus was handed to the vest (session clock).
    on_s: Option<f64>,
    /// Whether the unit acknowledged the stimulus's PLAY (a refusal after it is not the stimulus's).
    acked: bool,
    /// A note for its row.
    note: String,
}

/// One session being run (see the module doc).
pub struct StudyRunner {
    protocol: Protocol,
    participant: String,
    session: String,
    plan: Vec<PlannedTrial>,
    choices: Vec<String>,
    /// The station's timing, serving the keys neither a block nor the protocol sets.
    defaults: Timing,
    /// The timing of the trial presented last ([`Timing::for_block`] of its block): its response timeout,
    /// its feedback, the interval after it, its time limit.
    timing: Timing,
    /// The planned trial under way or next.
    at: usize,
    phase: StudyPhase,
    /// When the phase ends (`Presenting`, `AwaitingResponse` with a timeout, `Feedback`, `Interval`).
    until_s: Option<f64>,
    running: Option<Running>,
    /// A note for the next presentation of trial `at` (presented again after a pause or a stop).
    again: Option<String>,
    /// The stimulus playing: when it ends (session clock) and its label, for `stimulus_off`.
    playing: Option<(f64, String)>,
    /// The feedback replay due when the stimulus has ended.
    replay: Option<vestnav_core::study::Stimulus>,
    results: ResultsFile,
    /// The JSON, once written.
    json: Option<PathBuf>,
    rows: Vec<TrialRecord>,
    last: Option<LastAnswer>,
    error: Option<String>,
    /// The navigation trial under way (kept after it for the view).
    nav: Option<navigation::NavRun>,
}

impl std::fmt::Debug for StudyRunner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StudyRunner")
            .field("protocol", &self.protocol.name)
            .field("phase", &self.phase)
            .field("at", &self.at)
            .finish_non_exhaustive()
    }
}

/// Ends of a session, as `session_end`'s word.
fn end_word(phase: StudyPhase) -> &'static str {
    match phase {
        StudyPhase::Finished => "completed",
        StudyPhase::Stopped => "stopped",
        _ => "aborted",
    }
}

impl StudyRunner {
    /// Loads `protocol` for `participant`: the protocol is read and validated, its stimuli checked against
    /// `limits` (the unit's when it identified itself), the trials planned, and a new results file created
    /// in `out_dir` (never over an existing one).
    pub fn load(
        protocol: &std::path::Path,
        participant: &str,
        session: &str,
        out_dir: &std::path::Path,
        limits: &Limits,
        timing: Timing,
    ) -> Result<Self, String> {
        let participant = participant.trim();
        let session = session.trim();
        for (what, id) in [("participant", participant), ("session", session)] {
            if id.is_empty() || id.chars().count() > 64 || id.chars().any(char::is_control) {
                return Err(format!("{what} id {id:?}: 1 to 64 characters, none of them control characters"));
            }
        }
        let p = Protocol::load(protocol).map_err(|e| e.to_string())?;
        p.check_stimuli(|pattern: &Pattern| {
            limits.check_pattern(&pattern.frames, pattern.repeats).map_err(|e| e.to_string())
        })
        .map_err(|e| e.to_string())?;
        navigation::check_conditions(&p)?;
        let plan = vestnav_core::study::plan(&p, participant).map_err(|e| e.to_string())?;
        if plan.is_empty() {
            return Err(format!("{}: the protocol plans no trial", protocol.display()));
        }
        let results = ResultsFile::create(out_dir, &p.name, participant, session)?;
        let choices = p.choices();
        let first = timing.for_block(&p, plan[0].block);
        Ok(Self {
            protocol: p,
            participant: participant.to_owned(),
            session: session.to_owned(),
            plan,
            choices,
            defaults: timing,
            timing: first,
            at: 0,
            phase: StudyPhase::Ready,
            until_s: None,
            running: None,
            again: None,
            playing: None,
            replay: None,
            results,
            json: None,
            rows: Vec::new(),
            last: None,
            error: None,
            nav: None,
        })
    }

    /// Where the session is.
    pub fn phase(&self) -> StudyPhase {
        self.phase
    }

    /// Every row written so far.
    pub fn rows(&self) -> &[TrialRecord] {
        &self.rows
    }

    /// The planned trials.
    pub fn plan(&self) -> &[PlannedTrial] {
        &self.plan
    }

    /// The trial under way or next, if any is left.
    pub fn current(&self) -> Option<&PlannedTrial> {
        self.plan.get(self.at)
    }

    /// The timing planned trial `t`'s block runs under (block > protocol > station, [`Timing::for_block`]).
    pub fn timing_of(&self, t: &PlannedTrial) -> Timing {
        self.defaults.for_block(&self.protocol, t.block)
    }

    /// The session clock instant the runner next needs a turn at, if it waits for time (a view that sleeps
    /// between events wakes by then).
    pub fn next_deadline_s(&self) -> Option<f64> {
        match (self.until_s, self.playing.as_ref().map(|p| p.0)) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// What a view shows.
    pub fn view(&self) -> StudyView {
        let t = self.plan.get(self.at.min(self.plan.len().saturating_sub(1)));
        StudyView {
            protocol: self.protocol.name.clone(),
            participant: self.participant.clone(),
            session: self.session.clone(),
            task: self.protocol.task,
            phase: self.phase,
            trial: self.at,
            trials: self.plan.len(),
            block_name: t.map(|t| t.block_name.clone()).unwrap_or_default(),
            training: t.is_some_and(|t| t.training),
            feedback: t.is_some_and(|t| t.feedback),
            choices: self.choices.clone(),
            presented: (self.phase == StudyPhase::Presenting)
                .then(|| t.map(|t| t.stimulus.label()))
                .flatten(),
            last: self.last.clone(),
            results_csv: self.results.csv_path().to_path_buf(),
            results_json: self.json.clone(),
            error: self.error.clone(),
            rows: self.rows.len(),
            navigation: self.nav.as_ref().map(navigation::NavRun::view),
            timing: t.map(|t| self.timing_of(t)),
        }
    }

    /// Applies one command; `Err` says why it was refused (nothing changed then).
    pub fn command(&mut self, cmd: StudyCommand, io: &mut dyn StudyIo) -> Result<(), String> {
        let now = io.now_s();
        match cmd {
            StudyCommand::Load { .. } | StudyCommand::Unload => {
                Err("load and unload are the station's (a session is loaded already)".to_owned())
            }
            StudyCommand::Start => {
                if self.phase != StudyPhase::Ready {
                    return Err(format!("study start refused: the session is {}", self.phase.name()));
                }
                io.hold_guidance();
                let text =
                    format!("session_start {} {} {}", self.protocol.name, self.participant, self.session);
                io.marker(&text, now);
                self.present(io);
                Ok(())
            }
            StudyCommand::Respond { answer } => self.respond(&answer, io),
            StudyCommand::EndTrial => self.end_navigation_trial("ended by the operator", io),
            StudyCommand::Pause => match self.phase {
                StudyPhase::Presenting | StudyPhase::AwaitingResponse | StudyPhase::Navigating => {
                    io.marker("pause", now);
                    self.end_trial(Outcome::Aborted, "paused during the trial", io);
                    self.again = Some("presented again after a pause".to_owned());
                    self.pause(None);
                    Ok(())
                }
                StudyPhase::Feedback | StudyPhase::Interval => {
                    io.marker("pause", now);
                    self.pause(None);
                    Ok(())
                }
                p => Err(format!("study pause refused: the session is {}", p.name())),
            },
            StudyCommand::Resume => {
                if self.phase != StudyPhase::Paused {
                    return Err(format!("study resume refused: the session is {}", self.phase.name()));
                }
                io.marker("resume", now);
                self.error = None;
                io.hold_guidance();
                let from = self.playing.as_ref().map_or(now, |p| p.0.max(now));
                self.next_or_finish(from, io);
                Ok(())
            }
            StudyCommand::Abort => {
                if self.phase.is_over() {
                    return Err(format!("study abort refused: the session is {}", self.phase.name()));
                }
                if matches!(
                    self.phase,
                    StudyPhase::Presenting | StudyPhase::Feedback | StudyPhase::Navigating
                ) {
                    io.stop_vest();
                }
                io.marker("abort", now);
                self.end(StudyPhase::Aborted, "aborted by the operator", io);
                Ok(())
            }
        }
    }

    /// Ends the session because the program exits (the vest was stopped by the exit path): the trial under
    /// way recorded as stopped, the JSON written.
    pub fn exit(&mut self, io: &mut dyn StudyIo) {
        if !self.phase.is_over() && self.phase != StudyPhase::Ready {
            io.marker("stop_all", io.now_s());
            self.end(StudyPhase::Stopped, "the program exited (STOP ALL)", io);
        }
    }

    /// The runner's turn: phases that end with time.
    pub fn turn(&mut self, io: &mut dyn StudyIo) {
        let now = io.now_s();
        if self.playing.as_ref().is_some_and(|(end, _)| now >= *end) {
            self.stimulus_off(now, io);
        }
        if self.until_s.is_none_or(|u| now < u) {
            return;
        }
        self.until_s = None;
        match self.phase {
            StudyPhase::Presenting => {
                self.phase = StudyPhase::AwaitingResponse;
                let on = self.running.as_ref().and_then(|r| r.on_s).unwrap_or(now);
                self.until_s = self.timing.response_timeout_s.map(|t| on + t);
            }
            StudyPhase::AwaitingResponse => {
                self.end_trial(Outcome::NoResponse, "no response within the time limit", io);
                self.at += 1;
                self.next_or_finish(now, io);
            }
            StudyPhase::Feedback => match self.replay.take() {
                Some(stimulus) => self.replay(&stimulus, now, io),
                None => self.next_or_finish(now, io),
            },
            StudyPhase::Interval => self.present(io),
            StudyPhase::Navigating => {
                // The trial's time limit (a refusal is impossible in this phase).
                let _ = self.end_navigation_trial("the trial's time limit passed", io);
            }
            _ => {}
        }
    }

    /// A vest event the station received: STOP ALL (from any source), and the unit's answer to the stimulus.
    pub fn vest_event(&mut self, ev: &VestEvent, io: &mut dyn StudyIo) {
        match ev {
            VestEvent::Halted { reason } => self.stopped(reason, io),
            VestEvent::Acked { kind: CommandKind::Play, .. } => {
                if let Some(r) = &mut self.running {
                    r.acked = true;
                }
            }
            VestEvent::Rejected { kind: CommandKind::Play | CommandKind::SetIntensity, origin, reason }
                if *origin != Some(CommandOrigin::Guidance) =>
            {
                // A command cancelled by STOP ALL is the stop's business (its Halted event comes first).
                let trial_on = matches!(self.phase, StudyPhase::Presenting | StudyPhase::AwaitingResponse);
                if trial_on && !reason.contains("STOP ALL") && self.running.as_ref().is_some_and(|r| !r.acked)
                {
                    self.refused(reason, io);
                }
            }
            _ => {}
        }
    }

    fn stopped(&mut self, reason: &str, io: &mut dyn StudyIo) {
        let now = io.now_s();
        match self.phase {
            StudyPhase::Presenting | StudyPhase::AwaitingResponse | StudyPhase::Navigating => {
                io.marker("stop_all", now);
                self.stimulus_off(now, io);
                if let Some(n) = &mut self.nav {
                    n.stopped();
                }
                let n = self.at + 1;
                self.end_trial(Outcome::Stopped, &format!("stopped ({reason})"), io);
                self.again = Some("presented again after STOP ALL".to_owned());
                self.pause(Some(format!(
                    "STOP ALL during trial {n}: recorded as stopped; Resume presents it again"
                )));
            }
            StudyPhase::Feedback | StudyPhase::Interval => {
                io.marker("stop_all", now);
                self.stimulus_off(now, io);
                self.replay = None;
                self.pause(Some("STOP ALL between trials; Resume goes on".to_owned()));
            }
            StudyPhase::Paused => {
                io.marker("stop_all", now);
                self.stimulus_off(now, io);
            }
            _ => {}
        }
    }

    fn refused(&mut self, reason: &str, io: &mut dyn StudyIo) {
        // Never played: no `stimulus_off`.
        self.playing = None;
        let n = self.at + 1;
        let what = if self.phase == StudyPhase::Navigating {
            reason.to_owned()
        } else {
            format!("the vest refused the stimulus ({reason})")
        };
        self.end_trial(Outcome::Refused, &format!("stimulus refused: {reason}"), io);
        self.at += 1;
        self.pause(Some(format!(
            "trial {n}: {what}; recorded as refused; Resume goes on with the next trial"
        )));
    }

    fn pause(&mut self, why: Option<String>) {
        self.phase = StudyPhase::Paused;
        self.until_s = None;
        self.running = None;
        self.replay = None;
        if why.is_some() {
            self.error = why;
        }
    }

    fn respond(&mut self, answer: &str, io: &mut dyn StudyIo) -> Result<(), String> {
        if !matches!(self.phase, StudyPhase::Presenting | StudyPhase::AwaitingResponse) {
            return Err(format!("response refused: the session is {}", self.phase.name()));
        }
        let answer = answer.trim();
        let Some(choice) = self.choices.iter().find(|c| c.eq_ignore_ascii_case(answer)).cloned() else {
            return Err(format!("response {answer:?} is not one of {}", self.choices.join(", ")));
        };
        let now = io.now_s();
        let Some(t) = self.plan.get(self.at).cloned() else {
            return Err("response refused: no trial under way".to_owned());
        };
        let on = self.running.as_ref().and_then(|r| r.on_s);
        let rt_ms = on.map(|on| (now - on) * 1000.0);
        let correct = choice == t.answer;
        io.marker(&format!("response {choice} {} {:.1}", u8::from(correct), rt_ms.unwrap_or(f64::NAN)), now);
        // What follows waits for the stimulus's end when the wearer answered while it played.
        let free = self.playing.as_ref().map_or(now, |p| p.0.max(now));
        self.last = Some(LastAnswer {
            response: choice.clone(),
            answer: t.answer.clone(),
            correct,
            rt_ms: rt_ms.unwrap_or(0.0),
        });
        let note = self.running.as_ref().map(|r| r.note.clone()).unwrap_or_default();
        let mut row = self.record(&t, Outcome::Answered, note);
        row.response = Some(choice);
        row.correct = Some(correct);
        row.response_s = Some(now);
        row.rt_ms = rt_ms;
        self.write_row(row, io);
        self.running = None;
        self.at += 1;
        if t.feedback {
            io.marker(&format!("feedback {}", t.answer), now);
            self.phase = StudyPhase::Feedback;
            if correct {
                self.until_s = Some(free + self.timing.feedback_s);
            } else {
                // The correct stimulus again once the first has ended, so the wearer feels where it was.
                self.replay = Some(t.stimulus.clone());
                self.until_s = Some(free);
            }
        } else {
            self.next_or_finish(free, io);
        }
        Ok(())
    }

    /// Plays the feedback replay; feedback lasts until it has ended (and at least the feedback time).
    fn replay(&mut self, stimulus: &vestnav_core::study::Stimulus, now: f64, io: &mut dyn StudyIo) {
        let mut hold = self.timing.feedback_s;
        if let Some(p) = stimulus.pattern() {
            hold = hold.max(f64::from(p.total_ms()) / 1000.0 + 0.2);
            if let Err(e) = send_stimulus(stimulus, p, io) {
                self.error = Some(format!("feedback replay not sent: {e}"));
            }
        }
        self.until_s = Some(now + hold);
    }

    /// The stimulus has ended (played out, or stopped).
    fn stimulus_off(&mut self, at: f64, io: &mut dyn StudyIo) {
        if let Some((_, label)) = self.playing.take() {
            io.marker(&format!("stimulus_off {label}"), at);
        }
    }

    /// After a trial (or a resume): the interval from `from` before trial `at`, or the end (once the
    /// stimulus has ended).
    fn next_or_finish(&mut self, from: f64, io: &mut dyn StudyIo) {
        if self.at >= self.plan.len() && self.playing.is_none() {
            self.end(StudyPhase::Finished, "", io);
        } else {
            self.phase = StudyPhase::Interval;
            let iti = if self.at < self.plan.len() { self.timing.iti_s } else { 0.0 };
            self.until_s = Some(from + iti);
        }
    }

    /// Presents trial `at`.
    fn present(&mut self, io: &mut dyn StudyIo) {
        let Some(t) = self.plan.get(self.at).cloned() else {
            self.end(StudyPhase::Finished, "", io);
            return;
        };
        let note = self.again.take().unwrap_or_default();
        self.timing = self.timing_of(&t);
        let now = io.now_s();
        io.marker(&format!("trial_start {} {}", t.index + 1, t.block_name), now);
        self.nav = None;
        if matches!(t.stimulus, Stimulus::Navigation { .. }) {
            self.start_navigation(&t, note, io);
            return;
        }
        let Some(pattern) = t.stimulus.pattern() else {
            // Refused at load; a plan never gets here with one.
            self.running = Some(Running { on_s: None, acked: false, note });
            self.refused("the stimulus is no vest pattern", io);
            return;
        };
        let mask = t.stimulus.mask();
        let length_s = f64::from(pattern.total_ms()) / 1000.0;
        self.running = Some(Running { on_s: None, acked: false, note });
        match send_stimulus(&t.stimulus, pattern, io) {
            Ok(()) => {
                let on = io.now_s();
                io.marker(&format!("stimulus_on {} 0x{:04x}", t.stimulus.label(), mask.0), on);
                if let Some(r) = &mut self.running {
                    r.on_s = Some(on);
                }
                self.phase = StudyPhase::Presenting;
                self.until_s = Some(on + length_s);
                self.playing = Some((on + length_s, t.stimulus.label()));
                self.error = None;
            }
            Err(e) => {
                self.phase = StudyPhase::Presenting;
                self.refused(&e, io);
            }
        }
    }

    /// Records the trial under way (`at`) with `outcome` and no response.
    fn end_trial(&mut self, outcome: Outcome, why: &str, io: &mut dyn StudyIo) {
        let Some(t) = self.plan.get(self.at).cloned() else { return };
        let mut note = self.running.as_ref().map(|r| r.note.clone()).unwrap_or_default();
        if !why.is_empty() {
            if !note.is_empty() {
                note.push_str("; ");
            }
            note.push_str(why);
        }
        self.write_row(self.record(&t, outcome, note), io);
        self.running = None;
        if self.phase == StudyPhase::Navigating {
            io.end_navigation();
            // Until another phase is set: nothing runs.
            self.phase = StudyPhase::Interval;
        }
    }

    /// A row for planned trial `t`, with what the trial under way knows.
    fn record(&self, t: &PlannedTrial, outcome: Outcome, notes: String) -> TrialRecord {
        let on = self.running.as_ref().and_then(|r| r.on_s);
        let mut r =
            TrialRecord::new(&self.participant, &self.session, &self.protocol.name, self.protocol.task);
        r.block = t.block;
        r.block_name.clone_from(&t.block_name);
        r.trial = t.index;
        r.training = t.training;
        r.feedback = t.feedback;
        r.stimulus = t.stimulus.label();
        r.answer.clone_from(&t.answer);
        r.stimulus_on_s = on;
        r.outcome = outcome;
        r.notes = notes;
        if let Some(n) = &self.nav {
            n.fill(&mut r);
        }
        // The timing this trial ran under.
        let timing = self.timing_of(t);
        let ms = |s: f64| (s * 1000.0).round() as u32;
        r.iti_ms = Some(ms(timing.iti_s));
        r.feedback_ms = t.feedback.then(|| ms(timing.feedback_s));
        if self.protocol.task == Task::Navigation {
            r.time_limit_s = Some(timing.time_limit_s);
        } else {
            r.response_timeout_s = timing.response_timeout_s;
        }
        r
    }

    /// Appends `row` to the results file (fsynced) and marks the trial's end.
    fn write_row(&mut self, row: TrialRecord, io: &mut dyn StudyIo) {
        let now = io.now_s();
        io.marker(&format!("trial_end {} {}", row.trial + 1, row.outcome.name()), now);
        if let Err(e) = self.results.append(&row) {
            self.error = Some(e);
        }
        self.rows.push(row);
    }

    /// Ends the session: the trial under way recorded, `session_end`, the JSON.
    fn end(&mut self, phase: StudyPhase, why: &str, io: &mut dyn StudyIo) {
        // Aborted or exiting: the vest was stopped.
        self.stimulus_off(io.now_s(), io);
        self.replay = None;
        if self.running.is_some() {
            let outcome = if phase == StudyPhase::Stopped { Outcome::Stopped } else { Outcome::Aborted };
            self.end_trial(outcome, why, io);
        }
        self.phase = phase;
        self.until_s = None;
        io.marker(&format!("session_end {}", end_word(phase)), io.now_s());
        match self.results.write_json(&self.rows) {
            Ok(p) => self.json = Some(p),
            Err(e) => self.error = Some(e),
        }
    }
}

/// Hands a stimulus to the vest: its intensity, then its pattern.
fn send_stimulus(s: &Stimulus, pattern: Pattern, io: &mut dyn StudyIo) -> Result<(), String> {
    if let Some(level) = s.intensity() {
        io.send(vestnav_device::wtcu::VestCommand::SetIntensity { mask: s.mask(), level })?;
    }
    io.send(vestnav_device::wtcu::VestCommand::Play(pattern))
}

#[cfg(test)]
mod tests;
