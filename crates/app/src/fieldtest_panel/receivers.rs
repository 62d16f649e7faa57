//! The Field tests panel's **Compare receivers**: more GPS sources beside the primary one in this session
//! (`vestnav_station::receivers`: each on its own reader thread; guidance keeps the primary). The operator
//! adds a source in `--gps`'s text form (the one [`GpsSourceSpec`](vestnav_device::gps::GpsSourceSpec)
//! the primary takes) and removes it, through the station's `Command`s as a remote operator does; the
//! view draws the station's comparison — a row per receiver with its status (said once, in its row), its
//! fixes and recording, its difference from the primary at the epochs matched by receiver time and, with a
//! reference set, its accuracy against it — and the sheet `vestnav fieldtest compare --png` draws
//! (`CompareReport::figure`, the same code for the same fixes).

use std::sync::mpsc::{Receiver, TryRecvError};
use std::time::{Duration, Instant};

use vestnav_core::accuracy::Comparison;
use vestnav_report::Figure;
use vestnav_report::accuracy::CompareReport;
use vestnav_report::fieldtest::Source;
use vestnav_station::Station;
use vestnav_station::command::Command;
use vestnav_station::receivers::{MAX_COMPARED, ReceiverSeverity, primary_name};

use crate::sim_panel::figure_grid;

/// The examples under the source field.
pub const SOURCE_HINT: &str = "serial:/dev/ttyUSB1@9600 · gpsd://localhost:2947 · replay:walk.nmea@1 · sim";

/// What the operator is typing, and the cached sheet.
#[derive(Default)]
pub struct ReceiversView {
    /// The source to add, in `--gps`'s text form.
    pub spec: String,
    /// Why the last source was refused.
    pub error: Option<String>,
    /// The sheet and the comparison revision it was drawn from
    /// ([`Receivers::comparison_revision`](vestnav_station::receivers::Receivers::comparison_revision)).
    figure: Option<(u64, Figure)>,
    /// The sheet being drawn on a thread of its own, for that revision (at the cap five receivers of a day's
    /// fixes: 432,000 points to convert, never on a frame).
    drawing: Option<(u64, Receiver<Figure>)>,
}

impl ReceiversView {
    /// The section: the form to add a source, the table of receivers and the sheet.
    pub fn ui(&mut self, station: &mut Station, ui: &mut egui::Ui) {
        ui.label(
            "More receivers beside the GPS source in use (the primary, which guidance keeps): epochs are matched \
             by the receivers' UTC time, each one's distance from the primary is shown, and each one against the \
             reference when one is set. Each receiver's sentences are recorded beside the session log \
             (SESSION.rxN.nmea) for `vestnav fieldtest compare`.",
        );
        ui.horizontal(|ui| {
            let name = ui.label("source");
            ui.add(egui::TextEdit::singleline(&mut self.spec).hint_text(SOURCE_HINT).desired_width(360.0))
                .labelled_by(name.id);
            let room = station.receivers().sources().len() < MAX_COMPARED;
            if ui.add_enabled(room, egui::Button::new("Add receiver")).clicked() {
                // The command a remote operator and `vestnav station --compare-gps` send: one path.
                self.error = station.apply(Command::AddReceiver { spec: self.spec.clone() }).err();
                if self.error.is_none() {
                    self.spec.clear();
                }
            }
        });
        if let Some(e) = &self.error {
            ui.colored_label(ui.visuals().error_fg_color, e);
        }
        if station.receivers().sources().is_empty() {
            ui.weak("No receiver beside the primary: add one above.");
            return;
        }
        let remove = table(station, ui);
        if let Some(number) = remove {
            self.error = station.apply(Command::RemoveReceiver { number }).err();
            self.figure = None;
            return;
        }
        let Some(Ok(cmp)) = station.receivers().comparison() else {
            if let Some(Err(e)) = station.receivers().comparison() {
                ui.weak(format!("No comparison yet: {e}"));
            }
            return;
        };
        for w in &cmp.warnings {
            ui.colored_label(ui.visuals().warn_fg_color, format!("Warning: {w}"));
        }
        self.turn_drawing(station, ui.ctx());
        if let Some((_, figure)) = &self.figure {
            egui::ScrollArea::vertical()
                .id_salt("receivers-sheet")
                .show(ui, |ui| figure_grid(ui, "receivers-sheet", figure, 260.0));
        }
    }
}

impl ReceiversView {
    /// Takes a sheet drawn, and starts drawing the station's newest comparison when the sheet shown is of
    /// an older one and no drawing is under way: the comparison is cloned once per revision and the fixes
    /// are handed over shared ([`Receivers::tracks`](vestnav_station::receivers::Receivers::tracks)).
    fn turn_drawing(&mut self, station: &Station, ctx: &egui::Context) {
        if let Some((rev, rx)) = &self.drawing {
            match rx.try_recv() {
                Ok(figure) => {
                    self.figure = Some((*rev, figure));
                    self.drawing = None;
                }
                Err(TryRecvError::Empty) => ctx.request_repaint_after(Duration::from_millis(100)),
                Err(TryRecvError::Disconnected) => self.drawing = None,
            }
        }
        let rev = station.receivers().comparison_revision();
        if self.drawing.is_some() || self.figure.as_ref().is_some_and(|(r, _)| *r == rev) {
            return;
        }
        let Some(Ok(cmp)) = station.receivers().comparison() else { return };
        let primary = primary_name(station.gps_source());
        let tracks = station.receivers().tracks(&primary);
        let (cmp, earth, reference) =
            (cmp.clone(), station.field_tests.earth, station.field_tests.reference().cloned());
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        let ctx = ctx.clone();
        let spawned = std::thread::Builder::new().name("receivers-sheet".into()).spawn(move || {
            let report = CompareReport {
                test: "compare".into(),
                sources: tracks.iter().map(|_| Source::live()).collect(),
                earth,
                reference_point: reference,
                comparison: cmp,
                tracks: tracks.iter().map(|(_, t)| t.to_vec()).collect(),
            };
            let _ = tx.send(report.figure());
            ctx.request_repaint();
        });
        match spawned {
            Ok(_) => self.drawing = Some((rev, rx)),
            // No thread: the sheet is drawn here, once per comparison, as before.
            Err(_) => {
                if let Some(Ok(c)) = station.receivers().comparison() {
                    self.figure = Some((rev, report(station, c).figure()));
                }
            }
        }
    }
}

/// The report `vestnav fieldtest compare` writes, for the station's live receivers.
pub fn report(station: &Station, cmp: &Comparison) -> CompareReport {
    let primary = primary_name(station.gps_source());
    let receivers = station.receivers().receivers(&primary);
    CompareReport {
        test: "compare".into(),
        sources: receivers.iter().map(|_| Source::live()).collect(),
        earth: station.field_tests.earth,
        reference_point: station.field_tests.reference().cloned(),
        comparison: cmp.clone(),
        tracks: receivers.into_iter().map(|r| r.samples).collect(),
    }
}

/// The receivers' table; returns the number of the comparison source whose Remove was pressed.
fn table(station: &Station, ui: &mut egui::Ui) -> Option<usize> {
    let now = Instant::now();
    let r = station.receivers();
    let cmp = r.comparison().and_then(|c| c.as_ref().ok());
    let mut remove = None;
    let recorded = |s: Option<vestnav_device::gps::record::RecordingStatus>| match s {
        Some(s) if s.error.is_some() => s.error.unwrap_or_default(),
        Some(s) => format!(
            "{} ({} sentences)",
            s.path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
            s.sentences
        ),
        None => "not recorded (no session log)".to_owned(),
    };
    let against = |k: usize| {
        cmp.and_then(|c| c.against_reference.get(k).cloned().flatten()).map_or_else(
            || "—".to_owned(),
            |s| format!("{:.3} / {:.3} m, bias {:.3} m", s.cep50_m, s.cep95_m, s.bias_m),
        )
    };
    if let Some(c) = cmp {
        ui.label(format!("{} epochs matched within {} s", c.matched_epochs, c.tolerance_s));
    }
    egui::Grid::new("receivers-table").striped(true).show(ui, |ui| {
        for h in [
            "receiver",
            "",
            "status",
            "fixes",
            "recording",
            "mean east / north from 1",
            "RMS / P95 / max from 1",
            "CEP50 / CEP95 against the reference",
        ] {
            ui.strong(h);
        }
        ui.end_row();
        ui.label(primary_name(station.gps_source()));
        ui.label("");
        // The primary's state is the GPS panel's: said there, not twice.
        ui.weak("primary (state: GPS panel)");
        ui.label(r.primary_fixes().to_string());
        ui.label(recorded(r.primary_recording()));
        ui.label("—");
        ui.label("—");
        ui.label(against(0));
        ui.end_row();
        for (k, s) in r.sources().iter().enumerate() {
            ui.label(&s.name);
            if ui.button(format!("Remove receiver {}", s.number)).clicked() {
                remove = Some(s.number);
            }
            if let Some(status) = station.receiver_status(k, now) {
                match status.severity() {
                    ReceiverSeverity::Error => {
                        ui.colored_label(ui.visuals().error_fg_color, status.to_string())
                    }
                    ReceiverSeverity::Warning => {
                        ui.colored_label(ui.visuals().warn_fg_color, status.to_string())
                    }
                    ReceiverSeverity::Normal => ui.label(status.to_string()),
                };
            } else {
                ui.label("");
            }
            ui.label(s.fixes().to_string());
            ui.label(recorded(s.recording()));
            match cmp.and_then(|c| c.differences.get(k)) {
                Some(d) if cmp.is_some_and(|c| c.matched_epochs > 0) => {
                    ui.label(format!("{:+.3} / {:+.3} m", d.mean_en_m[0], d.mean_en_m[1]));
                    ui.label(format!("{:.3} / {:.3} / {:.3} m", d.rms_m, d.p95_m, d.max_m));
                }
                _ => {
                    ui.label("—");
                    ui.label("—");
                }
            }
            ui.label(against(k + 1));
            ui.end_row();
        }
    });
    remove
}
