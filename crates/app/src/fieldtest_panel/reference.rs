//! The Field tests panel's reference and accuracy test: the operator gives the truth (a typed position in
//! any form core's parser reads, a GPX waypoint, or the average of N minutes of good fixes) with its stated
//! uncertainty; the station's field tests measure against it (`FieldTests::set_reference`, the accuracy
//! test, the drift and cone tests "against the reference"). This view only enters the reference and draws
//! what the station computed: the rows are `vestnav_report::accuracy::accuracy_rows`, the sheet
//! `AccuracyReport::figure`, the CLI's own.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

use vestnav_core::accuracy::{AccuracyStats, Reference};
use vestnav_core::fieldtest_live::{FieldTests, MAX_ACCURACY_TARGET_S, MAX_AVERAGING_S, Phase};
use vestnav_report::accuracy::{AccuracyReport, accuracy_rows};
use vestnav_report::fieldtest::Source;
use vestnav_station::fieldtests::{typed_reference, waypoint_reference};

use super::{FieldTestPanel, phase_text};
use crate::file_dialog::{Browse, DialogSpec, Mode, path_field, resolve};

/// How the reference is given.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Form {
    /// A typed position (decimal, DMS, UTM, MGRS).
    Typed,
    /// A waypoint of a GPX file.
    Waypoint,
    /// The average of minutes of good fixes.
    Averaged,
}

/// The examples under the position field.
pub const POSITION_HINT: &str =
    "42.3573, -71.1010 · 42°21'26.3\"N 71°06'03.6\"W · 19T 327588 4691263 · 19TCG2758891263";

/// What the operator is typing for the reference.
#[derive(Debug, Clone)]
pub struct ReferenceForm {
    /// How the reference is given.
    pub form: Form,
    /// The typed position.
    pub text: String,
    /// The GPX file, as typed (relative to the files folder).
    pub gpx_path: String,
    /// The waypoint's name (blank: the file's only waypoint).
    pub waypoint: String,
    browse: Browse,
    /// The stated horizontal uncertainty (1 sigma) [m].
    pub uncertainty_m: f64,
    /// Whether the height below is given.
    pub use_height: bool,
    /// Height above mean sea level [m].
    pub height_m: f64,
    /// Why the last reference was refused.
    pub error: Option<String>,
    /// The GPX file being read on its own thread (`fieldtest-gpx`): the file and, once read, the result.
    pending: Option<(PathBuf, PendingReference)>,
}

/// A waypoint reference being read: filled by the reading thread, taken by the view.
type PendingReference = Arc<Mutex<Option<Result<Reference, String>>>>;

impl Default for ReferenceForm {
    fn default() -> Self {
        Self {
            form: Form::Typed,
            text: String::new(),
            gpx_path: String::new(),
            waypoint: String::new(),
            browse: Browse::default(),
            uncertainty_m: 0.02,
            use_height: false,
            height_m: 0.0,
            error: None,
            pending: None,
        }
    }
}

const GPX: DialogSpec =
    DialogSpec { mode: Mode::Open, title: "Reference waypoint (GPX)", filter: ("GPX", &["gpx"]) };

impl ReferenceForm {
    /// The reference section: what is set, and the form to set another.
    pub fn ui(&mut self, t: &mut FieldTests, ui: &mut egui::Ui, base: &Path) {
        self.take_pending(t);
        egui::CollapsingHeader::new("Reference (the truth)").default_open(true).show(ui, |ui| {
            ui.horizontal_wrapped(|ui| match t.reference() {
                Some(r) => {
                    let height = r.height_m.map_or_else(String::new, |h| format!(", height {h:.3} m"));
                    ui.label(format!("Reference: {}{height}", r.describe()));
                    if ui.button("Clear reference").clicked() {
                        // Clearing cannot be refused.
                        let _ = t.set_reference(None);
                    }
                }
                None => {
                    ui.weak("No reference: the tests measure precision (scatter about the receiver's own fixes) only.");
                }
            });
            ui.horizontal(|ui| {
                ui.radio_value(&mut self.form, Form::Typed, "Typed position");
                ui.radio_value(&mut self.form, Form::Waypoint, "GPX waypoint");
                ui.radio_value(&mut self.form, Form::Averaged, "Average of good fixes");
            });
            match self.form {
                Form::Typed => {
                    ui.horizontal(|ui| {
                        let name = ui.label("position");
                        ui.add(egui::TextEdit::singleline(&mut self.text).hint_text(POSITION_HINT).desired_width(380.0))
                            .labelled_by(name.id);
                    });
                    self.stated_ui(ui);
                    if ui.button("Set reference").clicked() {
                        let h = self.use_height.then_some(self.height_m);
                        self.apply(t, typed_reference(&self.text, self.uncertainty_m, h));
                    }
                }
                Form::Waypoint => {
                    path_field(ui, &mut self.gpx_path, &mut self.browse, GPX, base, "surveyed.gpx");
                    ui.horizontal(|ui| {
                        let name = ui.label("waypoint");
                        ui.add(
                            egui::TextEdit::singleline(&mut self.waypoint)
                                .hint_text("its name (blank: the file's only waypoint)"),
                        )
                        .labelled_by(name.id);
                    });
                    self.stated_ui(ui);
                    let reading = self.pending.is_some();
                    if ui.add_enabled(!reading, egui::Button::new("Set reference")).clicked() {
                        match resolve(&self.gpx_path, base) {
                            Some(path) => self.read_waypoint(path, ui.ctx().clone()),
                            None => self.error = Some("give the GPX file".to_string()),
                        }
                    }
                    if let Some((path, _)) = &self.pending {
                        ui.weak(format!("reading {}…", path.display()));
                    }
                }
                Form::Averaged => averaging_ui(t, ui),
            }
            if let Some(e) = &self.error {
                ui.colored_label(ui.visuals().error_fg_color, e);
            }
        });
    }

    /// The stated uncertainty and height of a typed or waypoint reference.
    fn stated_ui(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let name = ui.label("stated uncertainty (1σ)");
            ui.add(
                egui::DragValue::new(&mut self.uncertainty_m).range(0.0..=100.0).speed(0.001).suffix(" m"),
            )
            .labelled_by(name.id);
            ui.checkbox(&mut self.use_height, "height above mean sea level");
            ui.add_enabled(
                self.use_height,
                egui::DragValue::new(&mut self.height_m).range(-500.0..=9000.0).speed(0.01).suffix(" m"),
            );
        });
    }

    /// Reads the waypoint of the GPX file at `path` on a short-lived thread (`fieldtest-gpx`): the file may
    /// be large, slow or hostile (its size limit and the FIFO refusal are `vestnav-files`'), and the view
    /// never waits for it. The result is applied by [`Self::take_pending`] at a later frame.
    fn read_waypoint(&mut self, path: PathBuf, ctx: egui::Context) {
        let h = self.use_height.then_some(self.height_m);
        let (name, u) = (self.waypoint.clone(), self.uncertainty_m);
        let slot: PendingReference = Arc::default();
        let filled = slot.clone();
        let file = path.clone();
        let spawned = std::thread::Builder::new().name("fieldtest-gpx".into()).spawn(move || {
            let r = waypoint_reference(&file, Some(&name), u, h);
            *filled.lock().unwrap_or_else(PoisonError::into_inner) = Some(r);
            ctx.request_repaint();
        });
        match spawned {
            Ok(_) => {
                self.error = None;
                self.pending = Some((path, slot));
            }
            Err(e) => self.error = Some(format!("cannot start reading {}: {e}", path.display())),
        }
    }

    /// Applies the waypoint read on its thread, once it is there (every frame; never waits).
    pub fn take_pending(&mut self, t: &mut FieldTests) {
        let Some((_, slot)) = &self.pending else { return };
        let done = slot.lock().unwrap_or_else(PoisonError::into_inner).take();
        if let Some(r) = done {
            self.pending = None;
            self.apply(t, r);
        }
    }

    /// Whether a GPX file is being read.
    pub fn reading(&self) -> bool {
        self.pending.is_some()
    }

    fn apply(&mut self, t: &mut FieldTests, r: Result<vestnav_core::accuracy::Reference, String>) {
        self.error = r.and_then(|r| t.set_reference(Some(r))).err();
    }
}

/// The averaging of a reference: window, Start / Use now / Cancel, progress.
fn averaging_ui(t: &mut FieldTests, ui: &mut egui::Ui) {
    ui.label(
        "Leave the receiver still on the point: good fixes (3-D, or corrected) are averaged. An averaged \
         reference hides the receiver's own bias: against it, the figures are precision.",
    );
    ui.horizontal(|ui| {
        let running = t.averaging.phase == Phase::Running;
        let mut minutes = t.averaging.target_s / 60.0;
        let name = ui.label("average over");
        ui.add_enabled(
            !running,
            egui::DragValue::new(&mut minutes).range(0.1..=MAX_AVERAGING_S / 60.0).speed(0.1).suffix(" min"),
        )
        .labelled_by(name.id);
        t.averaging.target_s = minutes * 60.0;
        if running {
            if ui.button("Use now").clicked() {
                t.finish_averaging();
            }
            if ui.button("Cancel").clicked() {
                t.cancel_averaging();
            }
            let frac = (t.averaging.elapsed_s() / t.averaging.target_s).clamp(0.0, 1.0) as f32;
            ui.add(egui::ProgressBar::new(frac).desired_width(200.0).text(format!(
                "{} good fixes, {:.0} / {:.0} s",
                t.averaging.fixes(),
                t.averaging.elapsed_s(),
                t.averaging.target_s
            )));
        } else if ui.add_enabled(t.latest().is_some(), egui::Button::new("Start averaging")).clicked() {
            t.start_averaging();
        }
        if t.averaging.skipped > 0 {
            ui.weak(format!("({} fixes not good enough, left out)", t.averaging.skipped));
        }
    });
    if let Some(e) = &t.averaging.error {
        ui.colored_label(ui.visuals().warn_fg_color, e);
    }
}

/// The statistics of a test against the reference, as rows (nothing without a reference).
pub fn against_ui(ui: &mut egui::Ui, id: &str, label: &str, against: Option<&Result<AccuracyStats, String>>) {
    match against {
        Some(Ok(s)) => {
            ui.strong(label);
            stats_grid(ui, id, s);
        }
        Some(Err(e)) => {
            ui.colored_label(ui.visuals().warn_fg_color, format!("{label}: no statistics ({e})"));
        }
        None => {}
    }
}

fn stats_grid(ui: &mut egui::Ui, id: &str, s: &AccuracyStats) {
    egui::Grid::new(id).striped(true).show(ui, |ui| {
        for (name, value) in accuracy_rows(s) {
            ui.label(name);
            ui.monospace(value);
            ui.end_row();
        }
    });
    for w in &s.warnings {
        ui.colored_label(ui.visuals().warn_fg_color, format!("Warning: {w}"));
    }
}

/// The accuracy test's report (`None` without a reference): `vestnav fieldtest accuracy --json`'s.
pub fn accuracy_report(t: &FieldTests) -> Option<AccuracyReport> {
    let r = t.reference()?;
    let stats = match (&t.accuracy.stats, &t.accuracy.error) {
        (Some(s), _) => Ok(s.clone()),
        (None, e) => Err(e.clone().unwrap_or_else(|| "no fixes recorded".to_string())),
    };
    Some(AccuracyReport::new(
        Source::live(),
        t.earth,
        r.clone(),
        stats,
        &t.accuracy.recording().accuracy_samples(),
    ))
}

impl FieldTestPanel {
    pub(super) fn accuracy_ui(&mut self, t: &mut FieldTests, ui: &mut egui::Ui) {
        ui.label(
            "Stand the receiver on the reference (a surveyed marker), press Start and wait: every fix is \
             measured against the reference.",
        );
        ui.horizontal(|ui| {
            let mut minutes = t.accuracy.target_s / 60.0;
            let name = ui.label("duration target");
            ui.add_enabled(
                t.accuracy.phase != Phase::Running,
                egui::DragValue::new(&mut minutes)
                    .range(0.5..=MAX_ACCURACY_TARGET_S / 60.0)
                    .speed(0.1)
                    .suffix(" min"),
            )
            .labelled_by(name.id);
            t.accuracy.target_s = minutes * 60.0;
            if t.accuracy.phase == Phase::Running {
                if ui.button("Stop").clicked() {
                    t.stop_accuracy();
                }
            } else {
                let label =
                    if t.accuracy.phase == Phase::Idle { "Start accuracy test" } else { "Start again" };
                let can = t.latest().is_some() && t.reference().is_some();
                if ui.add_enabled(can, egui::Button::new(label)).clicked() {
                    // Enabled only with a reference: cannot be refused.
                    let _ = t.start_accuracy();
                }
            }
            let frac = (t.accuracy.elapsed_s() / t.accuracy.target_s).clamp(0.0, 1.0) as f32;
            ui.add(egui::ProgressBar::new(frac).desired_width(200.0).text(format!(
                "{:.0} / {:.0} s",
                t.accuracy.elapsed_s(),
                t.accuracy.target_s
            )));
            let phase = phase_text(&t.accuracy.phase);
            if matches!(t.accuracy.phase, Phase::Ended(_)) {
                ui.colored_label(ui.visuals().warn_fg_color, phase);
            } else {
                ui.label(phase);
            }
        });
        if t.reference().is_none() {
            ui.colored_label(ui.visuals().warn_fg_color, "Set a reference above first.");
        }
        if let Some(clock) = t.accuracy.recording().clock() {
            ui.label(format!("time base: {}", clock.describe()));
        }
        if let Some(e) = &t.accuracy.error {
            ui.colored_label(ui.visuals().error_fg_color, e);
        }
        if let Some(s) = &t.accuracy.stats {
            ui.strong(format!("{} fixes over {:.0} s against the reference", s.fixes, s.duration_s));
            stats_grid(ui, "fieldtest-accuracy-stats", s);
        }
        self.export_and_plots(t, ui);
    }
}
