//! The Lab outputs window (View menu): turns the local station's LSL streams and OSC messages on and off
//! and shows their state — liblsl's version and the streams, or why LSL is missing and how to install it,
//! and the counts of what went out. The outputs start on a short-lived `vestnav-lab-start` thread (finding
//! liblsl may ask Python for its folders), never in a frame. The study tab shows the same status.

use std::sync::mpsc::{Receiver, TryRecvError, channel};

use egui::{Color32, RichText};
use vestnav_station::Station;
use vestnav_station::lab::{LabConfig, LabError, LabOutputs, LabStatus, LslState, parse_osc_target};

/// The window's state (not saved: lab outputs are turned on per session).
pub struct LabWindow {
    /// Whether the window is open.
    pub open: bool,
    lsl: bool,
    osc_on: bool,
    osc_text: String,
    prefix: String,
    /// Outputs being started, with the configuration they are for.
    starting: Option<(LabConfig, Receiver<Result<LabOutputs, LabError>>)>,
    /// Why the last Apply was refused (a bad OSC target).
    error: Option<String>,
}

impl Default for LabWindow {
    fn default() -> Self {
        Self {
            open: false,
            lsl: true,
            osc_on: false,
            osc_text: "127.0.0.1:9000".to_owned(),
            prefix: "vestnav".to_owned(),
            starting: None,
            error: None,
        }
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
    /// Puts outputs that finished starting in force (every frame, open or not).
    pub fn poll(&mut self, station: &mut Station) {
        let Some((cfg, rx)) = &self.starting else { return };
        let started = match rx.try_recv() {
            Ok(r) => r,
            Err(TryRecvError::Empty) => return,
            Err(TryRecvError::Disconnected) => Err(LabError::Thread("the start thread ended".to_owned())),
        };
        // An error is shown through the station's lab status.
        let _ = station.install_lab(cfg, started);
        self.starting = None;
    }

    /// Whether outputs are being started (the view turns until they are).
    pub fn busy(&self) -> bool {
        self.starting.is_some()
    }

    fn apply(&mut self, station: &mut Station) {
        self.error = None;
        let osc = if self.osc_on {
            match parse_osc_target(&self.osc_text) {
                Ok(a) => Some(a),
                Err(e) => {
                    self.error = Some(format!("OSC target {e}"));
                    return;
                }
            }
        } else {
            None
        };
        let cfg = LabConfig { lsl: self.lsl, osc, stream_prefix: self.prefix.clone() };
        // The old outlets go first: two never share a name.
        let _ = station.set_lab(None);
        if !cfg.any() {
            return;
        }
        let (tx, rx) = channel();
        let thread_cfg = cfg.clone();
        match std::thread::Builder::new()
            .name("vestnav-lab-start".into())
            .spawn(move || tx.send(LabOutputs::start(&thread_cfg)))
        {
            Ok(_) => self.starting = Some((cfg, rx)),
            Err(e) => self.error = Some(format!("cannot start: {e}")),
        }
    }

    /// Draws the window.
    pub fn ui(&mut self, ctx: &egui::Context, station: &mut Station) {
        self.poll(station);
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
                    self.apply(station);
                }
                if ui.add_enabled(on && !self.busy(), egui::Button::new("Stop")).clicked() {
                    let _ = station.set_lab(None);
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
