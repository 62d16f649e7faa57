//! The Study tab: run a study protocol on the station's trial runner, and look at the results.
//!
//! **Run.** The operator picks a protocol (a typed path, Browse… or Recent; it is checked as
//! `vestnav study check` checks it — the file's own line-numbered error is shown and the file is only
//! read), the participant (from the protocol's list or typed), the session and the results folder, then
//! Load, Start, Pause, Resume and Abort (Abort asks first). While the study runs, the operator clicks on
//! the large 4x4 back view (localization) or the pattern list what the wearer reported; a navigation trial
//! shows its route, condition, elapsed time, cross-track error and cues, and an End trial button. Everything shown —
//! trial n/N, block, training or test, phase, the feedback, the last response time, the results file, the
//! lab outputs — is the station's own report ([`vestnav_station::command::Snapshot`]'s `study` and `lab`),
//! never what this tab sent: the runner lives in the station (`vestnav_station::study`), and this tab only
//! sends it [`StudyCommand`]s through [`Command::Study`], to the console's own station or to the remote
//! station driven from the Stations window. STOP ALL stays in the top bar, above this tab and its Abort
//! question; the runner records a trial stopped by it as stopped and pauses (its reason shown in red) until
//! Resume.
//!
//! The stimulus being presented is not shown before the response: the operator records what the wearer
//! says without knowing the answer. The right answer shows with the feedback in feedback blocks.
//!
//! **Analysis** ([`analysis`]): a results CSV's numbers and the figures of `vestnav_report::study`, the
//! same PNGs as `vestnav study analyze --figures`.

pub mod analysis;
mod launch;

pub use launch::StudyLaunch;

use std::path::{Path, PathBuf};
use std::time::Instant;

use egui::{Color32, RichText, vec2};
use vestnav_core::study::{Protocol, Task};
use vestnav_core::vest::TACTOR_COUNT;
use vestnav_station::Station;
use vestnav_station::command::Command;
use vestnav_station::lab::LabStatus;
use vestnav_station::study::{StudyCommand, StudyPhase, StudyView};

use crate::file_dialog::{self, Browse, DialogSpec, Mode, RecentFiles, RecentKind};
use crate::remote_panel::RemotePanel;
use crate::vest_panel::{GridCell, back_view_grid};

/// Which station the tab drives.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum Target {
    /// The console's own station.
    #[default]
    Local,
    /// The remote station of this name, driven from the Stations window.
    Remote(String),
}

/// What the tab shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum View {
    /// Load and run a protocol.
    #[default]
    Run,
    /// Numbers and figures of a results file.
    Analysis,
}

/// A protocol file as the check found it.
#[derive(Debug, Clone)]
pub struct Checked {
    /// The file checked.
    pub path: PathBuf,
    /// What it holds, or the check's error (naming the file and the line).
    pub result: Result<Summary, String>,
}

/// The few facts of a valid protocol the tab shows.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Summary {
    /// Its name.
    pub name: String,
    /// Its task.
    pub task: Task,
    /// The participants it lists (may be empty: then typed).
    pub participants: Vec<String>,
    /// The sessions it foresees (may be empty).
    pub sessions: Vec<String>,
    /// Trials per participant.
    pub trials: usize,
    /// Its blocks' names.
    pub blocks: Vec<String>,
}

/// Reads and validates the protocol at `path` (`Protocol::load`: the file is only read, an error names the
/// file and the line). Its stimuli are checked against the unit's limits by the station when it loads it
/// (the unit's own limits, which only the station knows); a refusal there shows under the controls.
pub fn check_protocol(path: &Path) -> Checked {
    let result = Protocol::load(path)
        .map(|p| Summary {
            trials: p.trials_per_participant(),
            name: p.name,
            task: p.task,
            participants: p.participants,
            sessions: p.sessions,
            blocks: p.blocks.into_iter().map(|b| b.name).collect(),
        })
        .map_err(|e| e.to_string());
    Checked { path: path.to_path_buf(), result }
}

/// The Study tab's own state (the study's state is the station's).
pub struct StudyPanel {
    /// Run or Analysis.
    pub view: View,
    /// The station driven.
    pub target: Target,
    /// The protocol's path as typed or chosen.
    pub protocol: String,
    protocol_browse: Browse,
    /// The last check of the protocol file.
    pub checked: Option<Checked>,
    /// The participant's id.
    pub participant: String,
    /// The session's id.
    pub session: String,
    /// The results folder as typed or chosen.
    pub out_dir: String,
    out_browse: Browse,
    /// The local station's refusal of the last command (a remote one's shows in the drive's list).
    pub refused: Option<String>,
    /// The Abort question is open.
    pub confirm_abort: bool,
    /// The Analysis view.
    pub analysis: analysis::AnalysisView,
    /// The simulated wearer of `--study-wearer`, answering on the console's own station.
    demo: Option<launch::Demo>,
}

impl Default for StudyPanel {
    fn default() -> Self {
        Self {
            view: View::Run,
            target: Target::Local,
            protocol: String::new(),
            protocol_browse: Browse::default(),
            checked: None,
            participant: String::new(),
            session: "1".to_owned(),
            out_dir: "study".to_owned(),
            out_browse: Browse::default(),
            refused: None,
            confirm_abort: false,
            analysis: analysis::AnalysisView::default(),
            demo: None,
        }
    }
}

/// The phase in the operator's words, and whether it is an alarm.
fn phase_words(phase: StudyPhase) -> (&'static str, bool) {
    match phase {
        StudyPhase::Ready => ("READY: press Start", false),
        StudyPhase::Presenting => ("PRESENTING: the vest plays the stimulus", false),
        StudyPhase::AwaitingResponse => ("AWAITING RESPONSE: click what the wearer reports", false),
        StudyPhase::Navigating => ("NAVIGATING: the wearer walks the route under guidance", false),
        StudyPhase::Feedback => ("FEEDBACK", false),
        StudyPhase::Interval => ("INTERVAL: the next trial follows", false),
        StudyPhase::Paused => ("PAUSED: nothing is presented until Resume", false),
        StudyPhase::Finished => ("FINISHED: every trial done", false),
        StudyPhase::Aborted => ("ABORTED: the trials so far are kept", true),
        StudyPhase::Stopped => ("STOPPED: the program stopped the vest to exit; the session ended", true),
    }
}

/// Whether a session is under way (loaded and not over): a new one cannot be loaded then.
fn under_way(phase: StudyPhase) -> bool {
    !phase.is_over()
}

impl StudyPanel {
    /// Draws the tab: the console's own `station`, the `remote` stations (when connected), the operator's
    /// `recent` files; `lab_open` opens the Lab outputs window.
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        station: &mut Station,
        remote: Option<&mut RemotePanel>,
        recent: &mut RecentFiles,
        lab_open: &mut bool,
        now: Instant,
    ) {
        ui.horizontal(|ui| {
            ui.selectable_value(&mut self.view, View::Run, RichText::new("Run").strong());
            ui.selectable_value(&mut self.view, View::Analysis, RichText::new("Analysis").strong());
            ui.separator();
            self.target_ui(ui, remote.as_deref());
        });
        ui.separator();
        if self.view == View::Analysis {
            self.analysis.ui(ui, recent);
            return;
        }
        // The state shown: the station's own report, as of this frame (a remote one's as last heard).
        let (study, lab, stale) = match &self.target {
            Target::Local => {
                let s = station.snapshot(now);
                (s.study, s.lab, None)
            }
            Target::Remote(name) => {
                let Some(r) = remote.as_deref() else {
                    self.target = Target::Local;
                    return;
                };
                let view = r.stations().station(name);
                let stale = view.as_ref().is_none_or(|v| v.is_stale(now, r.stations().stale_after()));
                let state = view.as_ref().and_then(|v| v.state.as_ref());
                let age = view.as_ref().map_or_else(
                    || "no contact yet".to_owned(),
                    |v| v.contact_label(now, r.stations().stale_after()),
                );
                (
                    state.and_then(|m| m.station.study.clone()),
                    state.and_then(|m| m.station.lab.clone()),
                    stale.then_some(age),
                )
            }
        };
        let mut send = None;
        egui::ScrollArea::vertical().auto_shrink([false, false]).show(ui, |ui| {
            if let Some(age) = &stale {
                ui.label(
                    RichText::new(format!("STALE ({age}): the study state shown may no longer be true"))
                        .strong()
                        .color(ui.visuals().error_fg_color),
                );
            }
            ui.horizontal_top(|ui| {
                ui.vertical(|ui| {
                    ui.set_width(ui.available_width().min(460.0));
                    send = self.setup_ui(ui, study.as_ref(), recent);
                    ui.separator();
                    lab_ui(ui, lab.as_ref(), self.target == Target::Local, lab_open);
                });
                ui.separator();
                ui.vertical(|ui| {
                    if let Some(c) = self.session_ui(ui, study.as_ref()) {
                        send = Some(c);
                    }
                });
            });
            if let Some(c) = self.sent_outcome_ui(ui, remote.as_deref(), now) {
                send = Some(c);
            }
        });
        if self.confirm_abort
            && let Some(c) = self.abort_question(ui.ctx(), study.as_ref())
        {
            send = Some(c);
        }
        if let Some(command) = send {
            self.send(command, station, remote);
        }
    }

    /// The station picker: this console's, or the remote station driven from the Stations window.
    fn target_ui(&mut self, ui: &mut egui::Ui, remote: Option<&RemotePanel>) {
        let driven = remote.and_then(|r| r.drive.selected.clone());
        if let Target::Remote(name) = &self.target
            && driven.as_deref() != Some(name.as_str())
        {
            // The Stations window stopped driving it: back to this console's station.
            self.target = Target::Local;
        }
        ui.label("Station:");
        ui.selectable_value(&mut self.target, Target::Local, "this console's");
        match driven {
            Some(name) => {
                let label = format!("{name} (driven)");
                ui.selectable_value(&mut self.target, Target::Remote(name), label)
                    .on_hover_text("The remote station picked to drive in the Stations window");
            }
            None if remote.is_some() => {
                ui.label(RichText::new("(drive a station in the Stations window to run its study)").weak());
            }
            None => {}
        }
    }

    /// The protocol's path field, Recent, Check, and the check's outcome.
    fn protocol_ui(&mut self, ui: &mut egui::Ui, recent: &mut RecentFiles, base: &Path) {
        let remote = self.target != Target::Local;
        ui.heading("Protocol");
        let spec =
            DialogSpec { mode: Mode::Open, title: "Open a study protocol", filter: ("TOML", &["toml"]) };
        let mut chosen = file_dialog::path_field(
            ui,
            &mut self.protocol,
            &mut self.protocol_browse,
            spec,
            base,
            "protocol.toml",
        );
        ui.horizontal(|ui| {
            if let Some(p) = file_dialog::recent_menu(ui, recent, RecentKind::Protocols) {
                self.protocol = p.display().to_string();
                chosen = Some(p);
            }
            if ui.button("Check").on_hover_text("Check the file as `vestnav study check` does").clicked() {
                chosen = file_dialog::resolve(&self.protocol, base);
            }
        });
        if let Some(p) = chosen {
            self.checked = Some(check_protocol(&p));
            if let Some(Checked { result: Ok(s), .. }) = &self.checked {
                recent.push(RecentKind::Protocols, &p);
                if self.participant.is_empty()
                    && let Some(first) = s.participants.first()
                {
                    self.participant.clone_from(first);
                }
            }
        }
        let resolved = file_dialog::resolve(&self.protocol, base);
        let checked = self.checked.as_ref().filter(|c| Some(&c.path) == resolved.as_ref()).map(|c| &c.result);
        match checked {
            Some(Ok(s)) => {
                ui.label(
                    RichText::new(format!(
                        "OK: {} — {}, {} trials per participant, blocks: {}",
                        s.name,
                        s.task.name(),
                        s.trials,
                        s.blocks.join(", ")
                    ))
                    .color(Color32::from_rgb(40, 160, 60)),
                );
            }
            Some(Err(e)) => {
                ui.label(RichText::new(e).strong().color(ui.visuals().error_fg_color));
            }
            None if remote => {
                ui.label(
                    RichText::new("A remote station reads the protocol from its own disk: the path is its.")
                        .small()
                        .weak(),
                );
            }
            None => {}
        }
    }

    /// Protocol, participant, session, results folder and Load. Returns the command to send.
    fn setup_ui(
        &mut self,
        ui: &mut egui::Ui,
        study: Option<&StudyView>,
        recent: &mut RecentFiles,
    ) -> Option<StudyCommand> {
        let base = recent.base();
        let remote = self.target != Target::Local;
        self.protocol_ui(ui, recent, &base);
        let resolved = file_dialog::resolve(&self.protocol, &base);
        let checked = self.checked.as_ref().filter(|c| Some(&c.path) == resolved.as_ref()).map(|c| &c.result);
        ui.horizontal(|ui| {
            let label = ui.label("Participant");
            ui.add(egui::TextEdit::singleline(&mut self.participant).desired_width(120.0).hint_text("P01"))
                .labelled_by(label.id);
            if let Some(Ok(s)) = checked
                && !s.participants.is_empty()
            {
                egui::ComboBox::from_id_salt("study-participants")
                    .selected_text("from the protocol")
                    .show_ui(ui, |ui| {
                        for p in &s.participants {
                            ui.selectable_value(&mut self.participant, p.clone(), p);
                        }
                    })
                    .response
                    .labelled_by(label.id);
            }
        });
        ui.horizontal(|ui| {
            let label = ui.label("Session");
            ui.add(egui::TextEdit::singleline(&mut self.session).desired_width(80.0)).labelled_by(label.id);
            if let Some(Ok(s)) = checked
                && !s.sessions.is_empty()
            {
                egui::ComboBox::from_id_salt("study-sessions")
                    .selected_text("from the protocol")
                    .show_ui(ui, |ui| {
                        for p in &s.sessions {
                            ui.selectable_value(&mut self.session, p.clone(), p);
                        }
                    })
                    .response
                    .labelled_by(label.id);
            }
        });
        ui.label("Results folder");
        let spec =
            DialogSpec { mode: Mode::Folder, title: "Folder for the study's results", filter: ("", &[]) };
        file_dialog::path_field(ui, &mut self.out_dir, &mut self.out_browse, spec, &base, "study");
        let busy = study.is_some_and(|v| under_way(v.phase));
        let ok = (remote || matches!(checked, Some(Ok(_))))
            && !self.participant.trim().is_empty()
            && !self.session.trim().is_empty();
        let out = file_dialog::resolve(&self.out_dir, &base);
        let load = ui
            .add_enabled(ok && !busy && out.is_some(), egui::Button::new(RichText::new("Load").strong()))
            .on_hover_text("The station plans this participant's trials; Start runs them")
            .on_disabled_hover_text(if busy {
                "A session is under way: abort it first"
            } else {
                "Check a valid protocol and give the participant, the session and the results folder"
            });
        if load.clicked()
            && let (Some(protocol), Some(out_dir)) = (resolved, out)
        {
            return Some(StudyCommand::Load {
                protocol,
                participant: self.participant.trim().to_owned(),
                session: self.session.trim().to_owned(),
                out_dir,
            });
        }
        None
    }

    /// The running session as the station reports it: controls, trial, phase, answer grid, feedback.
    fn session_ui(&mut self, ui: &mut egui::Ui, study: Option<&StudyView>) -> Option<StudyCommand> {
        let Some(v) = study else {
            ui.label(RichText::new("No study loaded on the station.").size(18.0).weak());
            return None;
        };
        let mut send = None;
        ui.label(
            RichText::new(format!("{} · participant {} · session {}", v.protocol, v.participant, v.session))
                .strong(),
        );
        ui.horizontal(|ui| {
            let big = |t: &str| RichText::new(t).size(18.0).strong();
            let p = v.phase;
            if ui.add_enabled(p == StudyPhase::Ready, egui::Button::new(big("Start"))).clicked() {
                send = Some(StudyCommand::Start);
            }
            let running = matches!(
                p,
                StudyPhase::Presenting
                    | StudyPhase::AwaitingResponse
                    | StudyPhase::Navigating
                    | StudyPhase::Feedback
                    | StudyPhase::Interval
            );
            if ui.add_enabled(running, egui::Button::new(big("Pause"))).clicked() {
                send = Some(StudyCommand::Pause);
            }
            if ui.add_enabled(p == StudyPhase::Paused, egui::Button::new(big("Resume"))).clicked() {
                send = Some(StudyCommand::Resume);
            }
            if ui.add_enabled(under_way(p), egui::Button::new(big("Abort…"))).clicked() {
                self.confirm_abort = true;
            }
            if ui
                .add_enabled(!under_way(p) || p == StudyPhase::Ready, egui::Button::new("Unload"))
                .on_hover_text("Close this session on the station (its results stay on disk)")
                .clicked()
            {
                send = Some(StudyCommand::Unload);
            }
        });
        let trial = if v.trials == 0 { 0 } else { (v.trial + 1).min(v.trials) };
        let kind = if v.training { "training" } else { "test" };
        let feedback = if v.feedback { "with feedback" } else { "no feedback" };
        ui.label(
            RichText::new(format!(
                "Trial {trial}/{} · block {} · {kind}, {feedback}",
                v.trials, v.block_name
            ))
            .size(20.0)
            .strong(),
        );
        // The timing this trial runs under (its block's keys, else the protocol's, else the station's).
        if let Some(t) = &v.timing {
            ui.label(RichText::new(format!("Timing: {}", t.describe(v.task))).weak());
        }
        let (words, alarm) = phase_words(v.phase);
        let color = if alarm { ui.visuals().error_fg_color } else { ui.visuals().strong_text_color() };
        ui.label(RichText::new(words).size(20.0).strong().color(color));
        if v.presented.is_some() {
            ui.label(
                RichText::new("STIMULUS ON: the vest plays it now")
                    .color(Color32::from_rgb(250, 170, 20))
                    .strong(),
            );
        }
        if let Some(e) = &v.error {
            ui.label(RichText::new(e).strong().color(ui.visuals().error_fg_color));
        }
        ui.add_space(6.0);
        if let Some(c) = navigation_ui(ui, v) {
            send = Some(c);
        }
        if let Some(answer) = answer_ui(ui, v) {
            send = Some(StudyCommand::Respond { answer });
        }
        ui.add_space(6.0);
        feedback_ui(ui, v);
        ui.label(format!("Results: {}", v.results_csv.display()));
        if (v.phase.is_over() || v.phase == StudyPhase::Paused)
            && v.results_csv.is_file()
            && ui.button("Analyse these results").clicked()
        {
            self.analysis.open(v.results_csv.clone());
            self.view = View::Analysis;
        }
        send
    }

    /// "Abort the session?": the command on the frame the operator says Abort.
    fn abort_question(&mut self, ctx: &egui::Context, study: Option<&StudyView>) -> Option<StudyCommand> {
        let Some(v) = study.filter(|v| under_way(v.phase)) else {
            self.confirm_abort = false;
            return None;
        };
        let mut answer = None;
        let modal = egui::Modal::new(egui::Id::unique("vestnav-study-abort")).show(ctx, |ui| {
            ui.label(RichText::new("Abort the session?").strong());
            ui.label(format!(
                "Trial {} of {} ends as aborted; the trials so far stay in {}.",
                (v.trial + 1).min(v.trials),
                v.trials,
                v.results_csv.display()
            ));
            ui.horizontal(|ui| {
                if ui.button("Abort session").clicked() {
                    answer = Some(true);
                }
                if ui.button("Go on").clicked() {
                    answer = Some(false);
                }
            });
        });
        if answer.is_none() && modal.should_close() {
            answer = Some(false);
        }
        match answer {
            Some(abort) => {
                self.confirm_abort = false;
                abort.then_some(StudyCommand::Abort)
            }
            None => None,
        }
    }

    /// The local station's refusal, or the remote station's answer to the last command sent to it.
    fn sent_outcome_ui(
        &mut self,
        ui: &mut egui::Ui,
        remote: Option<&RemotePanel>,
        now: Instant,
    ) -> Option<StudyCommand> {
        match &self.target {
            Target::Local => {
                if let Some(e) = &self.refused {
                    ui.label(
                        RichText::new(format!("refused: {e}")).strong().color(ui.visuals().error_fg_color),
                    );
                }
            }
            Target::Remote(name) => {
                let r = remote?;
                let view = r.stations().station(name);
                if let Some(s) = r.drive.sent.iter().rev().find(|s| s.to == *name) {
                    let (text, bad) =
                        crate::remote_drive::outcome(s, view.as_ref(), &r.stations().sender_for(name), now);
                    let line = RichText::new(format!("{}: {text}", s.what));
                    ui.label(if bad { line.color(ui.visuals().error_fg_color) } else { line });
                }
            }
        }
        None
    }

    /// Sends `command` to the console's own station.
    fn send_local(&mut self, command: StudyCommand, station: &mut Station) {
        // The results folder named here is made here (the station writes into an existing one).
        if let StudyCommand::Load { out_dir, .. } = &command
            && let Err(e) = std::fs::create_dir_all(out_dir)
        {
            self.refused = Some(format!("results folder {}: {e}", out_dir.display()));
            return;
        }
        self.refused = station.apply(Command::Study(command)).err();
    }

    /// Sends `command` to the station driven.
    fn send(&mut self, command: StudyCommand, station: &mut Station, remote: Option<&mut RemotePanel>) {
        match &self.target {
            Target::Local => self.send_local(command, station),
            Target::Remote(_) => {
                if let Some(r) = remote {
                    r.send_to_driven(Command::Study(command));
                }
            }
        }
    }
}

/// A navigation trial: the route and condition, the elapsed time against the limit, the cross-track error and
/// its RMS, the distance walked and the cues, as the runner measured them at its last turn; the End trial
/// button while the wearer walks. Returns the command clicked.
fn navigation_ui(ui: &mut egui::Ui, v: &StudyView) -> Option<StudyCommand> {
    let n = v.navigation.as_ref()?;
    let walking = v.phase == StudyPhase::Navigating;
    let head = if walking { "Walking" } else { "Last walk" };
    ui.label(
        RichText::new(format!("{head}: route {} · condition {}", n.route, n.condition)).size(18.0).strong(),
    );
    ui.label(&n.setup);
    let m = |x: Option<f64>| x.map_or_else(|| "–".to_owned(), |x| format!("{x:+.1} m"));
    ui.label(
        RichText::new(format!(
            "elapsed {:.0} s of {:.0} s · cross-track {} (RMS {}) · walked {:.0} of {:.0} m · {} cues · {} \
             waypoints not reached · {} fixes",
            n.elapsed_s,
            n.time_limit_s,
            m(n.cross_track_m),
            n.cross_track_rms_m.map_or_else(|| "–".to_owned(), |x| format!("{x:.1} m")),
            n.path_m,
            n.route_m,
            n.cues,
            n.missed_waypoints,
            n.fixes
        ))
        .size(16.0),
    );
    let end = ui
        .add_enabled(walking, egui::Button::new(RichText::new("End trial").size(18.0).strong()))
        .on_hover_text("End this walk now (recorded as ended, with what was measured so far)");
    end.clicked().then_some(StudyCommand::EndTrial)
}

/// The answer buttons: the 4x4 back view for a localization study whose choices are the 16 tactors, else
/// one large button per choice. Enabled while the station takes a response. Returns the choice clicked.
fn answer_ui(ui: &mut egui::Ui, v: &StudyView) -> Option<String> {
    let taking = matches!(v.phase, StudyPhase::Presenting | StudyPhase::AwaitingResponse);
    // In feedback, the response and the right answer are marked on the choices.
    let marks = v.last.as_ref().filter(|_| v.feedback && v.phase == StudyPhase::Feedback);
    let mark = |choice: &str| {
        marks.and_then(|l| {
            if l.answer == choice {
                Some(Color32::from_rgb(60, 180, 80))
            } else if l.response == choice {
                Some(Color32::from_rgb(230, 80, 60))
            } else {
                None
            }
        })
    };
    let mut clicked = None;
    // Localization: the first 16 choices are the tactors (row-major from the wearer's upper left on the
    // back view); any further ones are the tactor sets the protocol presents.
    let rest = if v.task == Task::Localization && v.choices.len() >= TACTOR_COUNT {
        let side = ((ui.available_width() - 40.0) / 4.0).clamp(56.0, 110.0);
        let size = vec2(side, side * 0.75);
        let cell = back_view_grid(ui, "study-grid", size, taking, |i| {
            let choice = v.choices.get(i).cloned().unwrap_or_default();
            GridCell {
                fill: mark(&choice),
                hover: format!("the wearer reports {choice} (row {}, column {})", i / 4 + 1, i % 4 + 1),
                text: choice,
            }
        });
        clicked = cell.and_then(|i| v.choices.get(i).cloned());
        &v.choices[TACTOR_COUNT..]
    } else {
        ui.label(RichText::new("What the wearer reports:").small());
        &v.choices[..]
    };
    ui.horizontal_wrapped(|ui| {
        for c in rest {
            let text = RichText::new(c).size(20.0).strong();
            let b = match mark(c) {
                Some(fill) => egui::Button::new(text.color(Color32::BLACK)).fill(fill),
                None => egui::Button::new(text),
            };
            if ui.add_enabled(taking, b.min_size(vec2(140.0, 56.0))).clicked() {
                clicked = Some(c.clone());
            }
        }
    });
    clicked
}

/// The last response: correct or not and the right answer (in feedback blocks), and its response time.
fn feedback_ui(ui: &mut egui::Ui, v: &StudyView) {
    let Some(l) = &v.last else {
        ui.label(RichText::new("No response yet.").weak());
        return;
    };
    if v.feedback {
        let (text, color) = if l.correct {
            (format!("CORRECT: {}", l.answer), Color32::from_rgb(40, 160, 60))
        } else {
            (
                format!("INCORRECT: reported {}, the answer was {}", l.response, l.answer),
                ui.visuals().error_fg_color,
            )
        };
        ui.label(RichText::new(text).size(22.0).strong().color(color));
    } else {
        ui.label(format!("Last response: {} (no feedback in this block)", l.response));
    }
    ui.label(RichText::new(format!("Response time {:.0} ms", l.rt_ms)).size(16.0));
}

/// The lab outputs as the station reports them (the Lab outputs window's own lines: LSL on, missing and
/// how to install it, or failed; OSC; the counts), and the button to that window for this console's
/// station.
fn lab_ui(ui: &mut egui::Ui, lab: Option<&LabStatus>, local: bool, lab_open: &mut bool) {
    ui.horizontal(|ui| {
        ui.heading("Lab outputs");
        if local && ui.button("Lab outputs…").on_hover_text("Turn LSL and OSC on or off").clicked() {
            *lab_open = true;
        }
    });
    crate::lab_window::status_ui(ui, lab);
}
