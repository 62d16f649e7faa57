//! The Lab outputs window (View menu): turns the local station's LSL streams and OSC messages on and off
//! and shows their state — liblsl's version and the streams, or why LSL is missing and how to install it,
//! and the counts of what went out. The outputs start on a short-lived `vestnav-lab-start` thread (finding
//! liblsl may ask Python for its folders, an OSC host name is resolved), never in a frame. The study tab
//! shows the same status.
//!
//! The choices last started or stopped are the settings' `lab` ([`LabSettings`]): outputs that ran when the
//! console closed are started again at the next start ([`LabWindow::restore`]); when they cannot start
//! (liblsl missing, a bad OSC target) nothing runs and the console says so.

use std::sync::mpsc::{Receiver, TryRecvError, channel};

use egui::{Color32, RichText};
use vestnav_station::Station;
use vestnav_station::lab::{LabConfig, LabError, LabOutputs, LabStatus, LslState, parse_osc_target};

pub use crate::config::LabSettings;

/// What the start thread hands back: the configuration and its outputs (or why they did not start), or
/// why the OSC target is not one.
type Started = Result<(LabConfig, Result<LabOutputs, LabError>), String>;

/// The window's state.
pub struct LabWindow {
    /// Whether the window is open.
    pub open: bool,
    lsl: bool,
    osc_on: bool,
    osc_text: String,
    prefix: String,
    /// The choices last started (with `on`) or stopped (without): what the settings keep.
    applied: LabSettings,
    /// Outputs being started; `true` when they are the saved ones restored at start.
    starting: Option<(bool, Receiver<Started>)>,
    /// Why the last Apply was refused (a bad OSC target).
    error: Option<String>,
}

impl Default for LabWindow {
    fn default() -> Self {
        Self::from_settings(&LabSettings::default())
    }
}

/// The status in a few coloured lines.
pub fn status_ui(ui: &mut egui::Ui, status: Option<&LabStatus>) {
    let Some(s) = status else {
        ui.label("Lab outputs off.");
        return;
    };
    let bad = ui.visuals().error_fg_color;
    match &s.lsl {
        LslState::Off => {
            ui.label("LSL off");
        }
        LslState::On { version, library, streams } => {
            ui.label(
                RichText::new(format!("LSL on (liblsl {version})")).color(Color32::from_rgb(60, 160, 60)),
            )
            .on_hover_text(library.as_str());
            ui.label(format!("streams: {}", streams.join(", ")));
        }
        LslState::Missing { why } => {
            ui.label(RichText::new("LSL MISSING: liblsl is not installed").color(bad).strong());
            ui.label(why.as_str());
        }
        LslState::Failed { why } => {
            ui.label(RichText::new(format!("LSL FAILED: {why}")).color(bad).strong());
        }
    }
    if let Some(o) = &s.osc {
        ui.label(format!("OSC to {}: {} sent, {} errors", o.target, o.sent, o.errors));
    }
    ui.label(format!(
        "{} markers, {} positions, {} headings, {} vest events, {} dropped",
        s.markers, s.positions, s.headings, s.vest, s.dropped
    ));
    if let Some(e) = &s.error {
        ui.label(RichText::new(format!("last error: {e}")).color(bad));
    }
}

impl LabWindow {
    /// The window with the saved choices in its fields (nothing started: see [`Self::restore`]).
    pub fn from_settings(saved: &LabSettings) -> Self {
        Self {
            open: false,
            lsl: saved.lsl,
            osc_on: saved.osc,
            osc_text: saved.osc_target.clone(),
            prefix: saved.stream_prefix.clone(),
            applied: saved.clone(),
            starting: None,
            error: None,
        }
    }

    /// The choices to save: those last started (`on`) or stopped.
    pub fn settings(&self) -> &LabSettings {
        &self.applied
    }

    /// Starts the saved outputs again when they ran when the console last closed; [`Self::poll`] says
    /// how that went.
    pub fn restore(&mut self, station: &mut Station) {
        if self.applied.on {
            self.start(station, true);
        }
    }

    /// Puts outputs that finished starting in force (every frame, open or not). For the outputs restored
    /// at start it returns what to tell the operator: `Ok` with what runs, `Err` with why nothing does.
    pub fn poll(&mut self, station: &mut Station) -> Option<Result<String, String>> {
        let (restoring, rx) = self.starting.as_ref()?;
        let restoring = *restoring;
        let started = match rx.try_recv() {
            Ok(r) => r,
            Err(TryRecvError::Empty) => return None,
            Err(TryRecvError::Disconnected) => Err("the start thread ended".to_owned()),
        };
        self.starting = None;
        let outcome = match started {
            Ok((cfg, outputs)) => match station.install_lab(&cfg, outputs) {
                Ok(()) => Ok(station.lab_status().map_or_else(String::new, |s| s.summary())),
                // The station's lab status shows it in full (what was tried, how to install liblsl).
                Err(e) => Err(e.to_string()),
            },
            Err(e) => {
                self.error = Some(e.clone());
                Err(e)
            }
        };
        restoring.then_some(outcome)
    }

    /// Whether outputs are being started (the view turns until they are).
    pub fn busy(&self) -> bool {
        self.starting.is_some()
    }

    /// Starts what the fields ask for on the `vestnav-lab-start` thread (`restoring`: the saved outputs at
    /// start).
    fn start(&mut self, station: &mut Station, restoring: bool) {
        self.error = None;
        self.applied = LabSettings {
            on: true,
            lsl: self.lsl,
            osc: self.osc_on,
            osc_target: self.osc_text.clone(),
            stream_prefix: self.prefix.clone(),
        };
        // The old outlets go first: two never share a name.
        let _ = station.set_lab(None);
        if !self.lsl && !self.osc_on {
            self.applied.on = false;
            return;
        }
        let (tx, rx) = channel();
        let (lsl, osc, prefix) = (self.lsl, self.osc_on.then(|| self.osc_text.clone()), self.prefix.clone());
        let spawned = std::thread::Builder::new().name("vestnav-lab-start".into()).spawn(move || {
            let started = match osc.as_deref().map(parse_osc_target).transpose() {
                Ok(osc) => {
                    let cfg = LabConfig { lsl, osc, stream_prefix: prefix };
                    let outputs = LabOutputs::start(&cfg);
                    Ok((cfg, outputs))
                }
                Err(e) => Err(format!("OSC target {e}")),
            };
            let _ = tx.send(started);
        });
        match spawned {
            Ok(_) => self.starting = Some((restoring, rx)),
            Err(e) => self.error = Some(format!("cannot start: {e}")),
        }
    }

    /// Draws the window.
    pub fn ui(&mut self, ctx: &egui::Context, station: &mut Station) {
        if !self.open {
            return;
        }
        let mut open = self.open;
        egui::Window::new("Lab outputs").open(&mut open).default_width(420.0).show(ctx, |ui| {
            ui.checkbox(&mut self.lsl, "LSL streams (markers, position, heading, vest)");
            ui.horizontal(|ui| {
                ui.checkbox(&mut self.osc_on, "OSC to");
                let label = ui.label("HOST:PORT");
                ui.add_enabled(
                    self.osc_on,
                    egui::TextEdit::singleline(&mut self.osc_text)
                        .hint_text("HOST:PORT")
                        .desired_width(160.0),
                )
                .labelled_by(label.id);
            });
            ui.horizontal(|ui| {
                let label = ui.label("Stream names start with");
                ui.add(egui::TextEdit::singleline(&mut self.prefix).desired_width(140.0))
                    .labelled_by(label.id);
            });
            ui.horizontal(|ui| {
                let on = station.lab_config().is_some();
                if ui
                    .add_enabled(!self.busy(), egui::Button::new(if on { "Restart" } else { "Start" }))
                    .clicked()
                {
                    self.start(station, false);
                }
                if ui.add_enabled(on && !self.busy(), egui::Button::new("Stop")).clicked() {
                    let _ = station.set_lab(None);
                    self.applied.on = false;
                }
                if self.busy() {
                    ui.spinner();
                    ui.label("starting…");
                }
            });
            if let Some(e) = &self.error {
                ui.label(RichText::new(e.as_str()).color(ui.visuals().error_fg_color));
            }
            ui.separator();
            status_ui(ui, station.lab_status().as_ref());
        });
        self.open = open;
    }
}
